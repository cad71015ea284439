// The march as a compute shader, one invocation per pixel (the native viewer, and the web
// page on WebGPU): the grid, the outputs and the first pass's opacity are storage buffers,
// every view of a frame in one buffer (P.view: origin x and row stride).

// indirection grids of all keyframes: EMPTY or the packed atlas position of the block
@group(0) @binding(1) var<storage, read> grid: array<u32>;
@group(0) @binding(3) var<storage, read_write> out_rgba: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> out_depth: array<f32>;
// the first pass's opacity, which the silhouette pass reads around each pixel (out_rgba
// cannot serve: the silhouette pass rewrites it while neighbours still read)
@group(0) @binding(8) var<storage, read_write> cover: array<f32>;

fn grid_at(i: u32) -> u32 {
    return grid[i];
}

fn cover_at(x: u32, y: u32) -> f32 {
    return cover[y * P.view.w + P.view.z + x];
}

@compute @workgroup_size(WG, WG, 1)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let width = P.view.x;
    let height = P.view.y;
    if (gid.x >= width || gid.y >= height) {
        return;
    }
    let idx = gid.y * P.view.w + P.view.z + gid.x;
    let side = P.frames.w;
    if (side == 0u) {
        let p = render_at(gid.x, gid.y, 0.5, 0.5);
        out_rgba[idx] = vec4<f32>(p.rgb, p.opacity);
        out_depth[idx] = p.depth;
        cover[idx] = p.opacity;
        return;
    }
    // the silhouette pass rewrites only the silhouette pixels
    if (!on_silhouette(gid.x, gid.y)) {
        return;
    }
    let p = pixel_mean(gid.x, gid.y, side);
    out_rgba[idx] = vec4<f32>(p.rgb, p.opacity);
    out_depth[idx] = p.depth;
}
