// Atlas access by texel loads + manual trilinear (the default): exactly render.rs's
// `interpolate` — the 8 corner codes weighted in f32 in the same order, divided by 255.
// One rg32uint 3D texture: a voxel's 8 channel bytes, little-endian, in .x (channels
// 0..3) and .y (channels 4..7), so one load fetches a whole voxel. A diffuse asset's is
// r32uint (channels 0..3 alone; its features are zero and never read).

@group(0) @binding(5) var atlas: texture_3d<u32>;

fn codes(v: u32) -> vec4<f32> {
    return vec4<f32>(vec4<u32>(v, v >> 8u, v >> 16u, v >> 24u) & vec4<u32>(255u));
}

fn atlas_interp(origin: vec3<u32>, l: vec3<f32>) -> Vals {
    let f = clamp(floor(l), vec3<f32>(0.0), vec3<f32>(f32(BLOCK)));
    let w = clamp(l - f, vec3<f32>(0.0), vec3<f32>(1.0));
    let base = vec3<i32>(origin + vec3<u32>(f));
    var s0 = vec4<f32>(0.0);
    var s1 = vec4<f32>(0.0);
    for (var corner = 0u; corner < 8u; corner++) {
        let dx = corner & 1u;
        let dy = (corner >> 1u) & 1u;
        let dz = (corner >> 2u) & 1u;
        let wx = select(1.0 - w.x, w.x, dx == 1u);
        let wy = select(1.0 - w.y, w.y, dy == 1u);
        let wz = select(1.0 - w.z, w.z, dz == 1u);
        let wt = wx * wy * wz;
        let t = textureLoad(atlas, base + vec3<i32>(vec3<u32>(dx, dy, dz)), 0);
        s0 += wt * codes(t.x);
        if (!DIFFUSE) {
            s1 += wt * codes(t.y);
        }
    }
    var o: Vals;
    o.a = s0 / 255.0;
    o.b = s1 / 255.0;
    return o;
}
