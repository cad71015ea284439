// The march as a fragment shader over a full-screen triangle, one fragment per pixel: the
// web page's WebGL2 renderer, which runs it translated to GLSL ES 3.00 (viewer/stream
// src/glsl.rs). WebGL2 has no storage buffers, so the grid is an r32uint 2D texture (entry i
// at texel (i % width, i / width)), and the output goes to two render targets (rgba32float:
// RGB and opacity; r32float: depth), one pair per view (P.view.z is 0, P.view.w the width).
//
// Rows: pixel (x, y) of the image (y down, as the CPU reference and the compute shader count
// it) is the fragment at @builtin(position) (x + 0.5, y + 0.5). WGSL's framebuffer origin is
// the top left, GL's the bottom left (the translation keeps gl_FragCoord as it is), so on
// WebGL2 image row y is the target's row y counted from the bottom: reading the target back
// (readPixels, bottom row first) gives the image's rows top first, in the CPU reference's
// order, and presenting it flips it.
//
// A fragment shader cannot read the target it writes, so the silhouette pass (P.frames.w >
// 0) reads the first pass's output as textures (binding 3: its rgba, whose .a is the
// opacity `on_silhouette` looks at around each pixel; binding 4: its depth) and writes every
// pixel: the first pass's value where the pixel is no silhouette pixel.

@group(0) @binding(1) var grid: texture_2d<u32>;
@group(0) @binding(3) var first_rgba: texture_2d<f32>;
@group(0) @binding(4) var first_depth: texture_2d<f32>;

fn grid_at(i: u32) -> u32 {
    let w = textureDimensions(grid).x;
    return textureLoad(grid, vec2<i32>(vec2<u32>(i % w, i / w)), 0).x;
}

fn cover_at(x: u32, y: u32) -> f32 {
    return textureLoad(first_rgba, vec2<i32>(vec2<u32>(x, y)), 0).w;
}

@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32((i << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(i & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

struct Out {
    @location(0) rgba: vec4<f32>,
    @location(1) depth: f32,
}

@fragment
fn fs(@builtin(position) pos: vec4<f32>) -> Out {
    let x = u32(pos.x);
    let y = u32(pos.y);
    let side = P.frames.w;
    if (side == 0u) {
        let p = render_at(x, y, 0.5, 0.5);
        return Out(vec4<f32>(p.rgb, p.opacity), p.depth);
    }
    if (!on_silhouette(x, y)) {
        let at = vec2<i32>(vec2<u32>(x, y));
        return Out(textureLoad(first_rgba, at, 0), textureLoad(first_depth, at, 0).x);
    }
    let p = pixel_mean(x, y, side);
    return Out(vec4<f32>(p.rgb, p.opacity), p.depth);
}
