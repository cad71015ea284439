// Atlas access by hardware trilinear filtering (optional, `GpuOptions::hardware_filter`):
// two rgba8unorm 3D textures, one filtered fetch each. The 1-voxel apron keeps the
// filter inside the block. Cheaper, but filter weights are fixed point on most GPUs
// (8 bits on lavapipe), so it matches the CPU reference less closely.

@group(0) @binding(5) var atlas0: texture_3d<f32>;
@group(0) @binding(6) var atlas1: texture_3d<f32>;
@group(0) @binding(7) var atlas_sampler: sampler;

fn atlas_interp(origin: vec3<u32>, l: vec3<f32>) -> Vals {
    let lc = clamp(l, vec3<f32>(0.0), vec3<f32>(f32(BLOCK) + 1.0));
    let uvw = (vec3<f32>(origin) + lc + 0.5) * P.inv_tex.xyz;
    var o: Vals;
    o.a = textureSampleLevel(atlas0, atlas_sampler, uvw, 0.0);
    o.b = textureSampleLevel(atlas1, atlas_sampler, uvw, 0.0);
    return o;
}
