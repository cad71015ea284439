// Window presentation: a full-screen triangle that copies the ray marcher's output
// buffer (linear RGB in [0,1], row-major) to the swapchain image, one texel per pixel,
// so the window shows exactly what the headless path returns. The web viewer presents with
// it too (served as /present.wgsl), also per eye into one side-by-side canvas: the viewport's
// origin comes in size.zw so that pixel (x, y) of the viewport reads element (x, y).

struct Screen {
    size: vec4<u32>, // width, height (of the output buffer), viewport origin x, y
}

@group(0) @binding(0) var<uniform> S: Screen;
@group(0) @binding(1) var<storage, read> pixels: array<vec4<f32>>;

@vertex
fn vs(@builtin(vertex_index) i: u32) -> @builtin(position) vec4<f32> {
    let x = f32((i << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(i & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

@fragment
fn fs(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let x = min(u32(pos.x) - S.size.z, S.size.x - 1u);
    let y = min(u32(pos.y) - S.size.w, S.size.y - 1u);
    let c = pixels[y * S.size.x + x];
    return vec4<f32>(c.rgb, 1.0);
}
