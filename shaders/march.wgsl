// Ray march of a baked snerf asset, one ray per pixel. A transcription of
// baker/asset/src/render.rs (the CPU reference renderer): same camera ray, same
// world -> model -> march-space mapping, same sample lattice and empty-cell jumps, same
// trilinear decode, same compositing, then the view MLP once per pixel (deferred).
//
// This file is the march itself, shared by every target; `snerf_geometry::march::march_shader`
// composes one variant from it (only the variant a scene needs is built). It prepends the
// variant constants:
//   const KIND: u32        0 object, 1 forward (NDC), 2 unbounded (MERF contraction)
//   const DYNAMIC: bool    blend two keyframes (4D assets)
//   const DIFFUSE: bool    a diffuse asset: zero features and view MLP, neither computed;
//                          the atlas holds density and RGB only (one u32 a voxel)
//   const BLOCK: u32       voxels per block edge (without apron)
//   const WG: u32          workgroup edge
// and appends one atlas access snippet (atlas_load.wgsl or atlas_filter.wgsl) that defines
//   fn atlas_interp(origin: vec3<u32>, l: vec3<f32>) -> Vals   (codes/255, not decoded)
// and one target snippet, which holds the resources that differ per target and the entry
// points: march_compute.wgsl (the compute shader of the native viewer and the WebGPU page:
// storage buffers) or march_fragment.wgsl (a fragment shader, translated to GLSL ES 3.00 for
// the WebGL2 page: textures). It defines
//   fn grid_at(i: u32) -> u32              indirection grid entry i (all keyframes)
//   fn cover_at(x: u32, y: u32) -> f32     the first pass's opacity at pixel (x, y) of this view

struct Params {
    // camera: rows of c2w = [R | t]; intrinsics fx, fy, cx, cy
    c2w0: vec4<f32>,
    c2w1: vec4<f32>,
    c2w2: vec4<f32>,
    intr: vec4<f32>,
    // width, height, x offset of this view in the output, output row stride (pixels)
    view: vec4<u32>,
    // model = scale * rot * (world - center)
    rot0: vec4<f32>,
    rot1: vec4<f32>,
    rot2: vec4<f32>,
    center_scale: vec4<f32>,
    // forward only: ndc fx, fy, width, height
    ndc0: vec4<f32>,
    // ndc near, ndc xy_extent, march step, t_terminate
    march: vec4<f32>,
    // logit_min, logit_max, keyframe blend weight w, grid offset of the motion reference
    // keyframe (bits of a u32; motion.rs)
    dens: vec4<f32>,
    // background rgb; w: 1 where a dynamic asset blends colour by density (header
    // colour_by_density), else 0
    background: vec4<f32>,
    // res, grid cells per axis, atlas blocks per row (x), atlas blocks per column (y)
    grid: vec4<u32>,
    // grid offset of keyframe k0, of keyframe k1 (in entries), k0 == k1, pass: 0 draws one
    // ray through every pixel's centre; s > 1 draws the silhouette pixels of that first pass
    // again as the mean of s x s rays (render.rs `render`)
    frames: vec4<u32>,
    // 1 / atlas texture size (hardware filtering only)
    inv_tex: vec4<f32>,
}

struct Vals {
    a: vec4<f32>, // density, r, g, b
    b: vec4<f32>, // features 0..3
}

struct Sample {
    ok: bool,
    v: Vals,
}

@group(0) @binding(0) var<uniform> P: Params;
// binding 1 (the indirection grids of all keyframes: EMPTY or the packed atlas position of
// the block, read by `grid_at`) comes with the target snippet
// view MLP weights transposed to input-major vec4 rows (see gpu.rs `mlp_gpu_layout`)
@group(0) @binding(2) var<uniform> mlp: array<vec4<f32>, 225>;
// bindings 3, 4 and 8 (output, the first pass's opacity) come with the target snippet,
// bindings 5..7 (atlas textures, sampler) with the atlas snippet

const EMPTY: u32 = 0xffffffffu;
// MAX_OPTICAL_DEPTH, UNBOUNDED_NEAR, UNBOUNDED_FAR, NDC_MIN_DZ, MAX_ITERS, COVER_EMPTY and
// COVER_FULL are prepended from snerf_geometry (the one definition the trainer and the CPU
// reference use).
const PI: f32 = 3.14159265358979;

// ---- compositing state (render.rs `Accum`) ----
var<private> acc_rgb: vec3<f32>;
var<private> acc_feat: vec4<f32>;
var<private> acc_w: f32;
var<private> acc_depth: f32;
var<private> acc_optical: f32;
var<private> acc_trans: f32;

fn accum_reset() {
    acc_rgb = vec3<f32>(0.0);
    acc_feat = vec4<f32>(0.0);
    acc_w = 0.0;
    acc_depth = 0.0;
    acc_optical = 0.0;
    acc_trans = 1.0;
}

// -expm1(-s) for s >= 0 without cancellation for tiny s.
fn one_minus_exp_neg(s: f32) -> f32 {
    if (s < 1.0e-3) {
        return s * (1.0 - s * (0.5 - s * (1.0 / 6.0)));
    }
    return 1.0 - exp(-s);
}

// Add one sample; true when the ray should stop.
fn accum_add(v: Vals, delta: f32, t: f32) -> bool {
    let sigma = exp(v.a.x);
    let sd = min(max(sigma * delta, 0.0), MAX_OPTICAL_DEPTH);
    let alpha = one_minus_exp_neg(sd);
    let w = acc_trans * alpha;
    acc_rgb += w * v.a.yzw;
    if (!DIFFUSE) {
        acc_feat += w * v.b;
    }
    acc_w += w;
    acc_depth += w * t;
    acc_optical += sd;
    acc_trans = exp(-acc_optical);
    return acc_trans < P.march.w;
}

// ---- atlas ----
// Grid entries hold the block's place in the atlas texture, in blocks, packed 10 bits per
// axis (the host packs them; no per-sample integer division).
fn block_origin(blk: u32) -> vec3<u32> {
    let e = BLOCK + 2u;
    return vec3<u32>(blk & 1023u, (blk >> 10u) & 1023u, blk >> 20u) * e;
}

// Trilinear values of one stored block, decoded (density as logit).
fn interpolate(blk: u32, l: vec3<f32>) -> Vals {
    let raw = atlas_interp(block_origin(blk), l);
    var o: Vals;
    o.a = raw.a;
    o.a.x = P.dens.x + raw.a.x * (P.dens.y - P.dens.x);
    o.b = raw.b;
    return o;
}

fn empty_vals() -> Vals {
    var o: Vals;
    o.a = vec4<f32>(P.dens.x, 0.0, 0.0, 0.0);
    o.b = vec4<f32>(0.0);
    return o;
}

// ---- motion (baker/asset/src/motion.rs) ----
// A motion entry (bit 31 set, bit 30 clear; packed atlas positions use bits 0..29) shows the
// reference keyframe (its grid at entry offset P.dens.w, as bits) moved by three signed
// 10-bit offsets in quarter voxels.
fn is_motion(e: u32) -> bool {
    return (e & 0xc0000000u) == 0x80000000u;
}

fn motion_offset(e: u32) -> vec3<f32> {
    // each field shifted to the top bits, then an arithmetic shift back sign-extends it
    // (no integer select: GLSL ES 3.00, the WebGL2 target, has none)
    let q = bitcast<vec3<i32>>(vec3<u32>(e << 22u, e << 12u, e << 2u)) >> vec3<u32>(22u);
    return vec3<f32>(q) / 4.0;
}

// Where one side reads: a block entry (packed, or EMPTY) and the block-local coordinate.
struct Fetch {
    e: u32,
    l: vec3<f32>,
}

// sample.rs `sample_moved`, up to the fetch: the reference's block and local coordinate at
// the voxel position of (cell c, l) moved by d (EMPTY outside the grid or in an empty cell).
fn moved(c: vec3<u32>, l: vec3<f32>, d: vec3<f32>) -> Fetch {
    var f: Fetch;
    f.e = EMPTY;
    let v = l + 0.5 + vec3<f32>(c * BLOCK) - 1.0 + d;
    let r = locate(v / f32(P.grid.x) * 2.0 - 1.0);
    if (r.ok) {
        f.e = grid_at(bitcast<u32>(P.dens.w) + r.cell);
        f.l = r.l;
    }
    return f;
}

// sample.rs `sample_slot`: None when every side involved is empty; two motion entries move
// the reference by the interpolated offset and read it once. Motion only changes where a
// side reads, through one `moved` site, so SIMD lanes that disagree (and a rasterizer that
// runs every branch under a mask) still run at most two block fetches and one move.
fn sample_cell(loc: Loc) -> Sample {
    var s: Sample;
    let a = grid_at(P.frames.x + loc.cell);
    var b = a;
    let w = P.dens.z;
    if (DYNAMIC && w != 0.0 && P.frames.z == 0u) {
        b = grid_at(P.frames.y + loc.cell);
    }
    s.ok = a != EMPTY || b != EMPTY;
    if (!s.ok) {
        return s;
    }
    var fa: Fetch;
    fa.e = a;
    fa.l = loc.l;
    var fb = fa;
    fb.e = b;
    // one side only: a static asset, equal entries, or two motion entries (moved once)
    var one = !DYNAMIC || a == b;
    if (DYNAMIC) {
        let ma = is_motion(a);
        let mb = is_motion(b);
        if (ma || mb) {
            // which offset: both moving (and different): the interpolated one; else the side's
            var d = motion_offset(select(b, a, ma));
            if (ma && mb && !one) {
                d = (1.0 - w) * d + w * motion_offset(b);
                one = true;
            }
            let f = moved(loc.c, loc.l, d);
            if (ma) {
                fa = f;
            } else {
                fb = f;
            }
        }
    }
    var va = empty_vals();
    if (fa.e != EMPTY) {
        va = interpolate(fa.e, fa.l);
    }
    if (one) {
        s.v = va;
        return s;
    }
    var vb = empty_vals();
    if (fb.e != EMPTY) {
        vb = interpolate(fb.e, fb.l);
    }
    // sample.rs `blend`: the logit by w; colour and features by w, or by density share
    var wc = w;
    if (P.background.w != 0.0) {
        wc = blend_weight(va.a.x, vb.a.x, w);
    }
    s.v.a = (1.0 - wc) * va.a + wc * vb.a;
    s.v.a.x = (1.0 - w) * va.a.x + w * vb.a.x;
    s.v.b = (1.0 - wc) * va.b + wc * vb.b;
    return s;
}

// sample.rs `blend_weight`: side b's colour weight when the sides weigh (1 - w) exp(la) and
// w exp(lb), as a logistic that neither overflows nor divides by zero.
fn blend_weight(la: f32, lb: f32, w: f32) -> f32 {
    let x = clamp(lb - la + log(max(w, 1.0e-30)) - log(max(1.0 - w, 1.0e-30)), -80.0, 80.0);
    return 1.0 / (1.0 + exp(-x));
}

struct Loc {
    ok: bool,
    cell: u32,
    // the cell's coordinates (motion reads the voxel position back from them)
    c: vec3<u32>,
    l: vec3<f32>,
}

// sample.rs `locate`: cell and block-local coordinate of grid point g.
fn locate(g: vec3<f32>) -> Loc {
    var r: Loc;
    r.ok = false;
    if (!(g.x >= -1.0 && g.x <= 1.0 && g.y >= -1.0 && g.y <= 1.0 && g.z >= -1.0 && g.z <= 1.0)) {
        return r;
    }
    let res = P.grid.x;
    let gd = P.grid.y;
    let v = (g + vec3<f32>(1.0)) * 0.5 * f32(res);
    let vi = min(vec3<u32>(v), vec3<u32>(res - 1u));
    let c = min(vi / BLOCK, vec3<u32>(gd - 1u));
    r.ok = true;
    r.c = c;
    r.cell = (c.z * gd + c.y) * gd + c.x;
    r.l = v - 0.5 - vec3<f32>(c * BLOCK) + 1.0;
    return r;
}

// ---- geometry ----
// NaN and ±inf both fail (no isfinite in WGSL).
fn finite3(a: vec3<f32>) -> bool {
    return all(abs(a) < vec3<f32>(3.0e38));
}

fn norm3(a: vec3<f32>) -> f32 {
    return sqrt(a.x * a.x + a.y * a.y + a.z * a.z);
}

fn normalize3(a: vec3<f32>) -> vec3<f32> {
    let n = norm3(a);
    if (n > 0.0) {
        return a / n;
    }
    return vec3<f32>(0.0, 0.0, -1.0);
}

fn rot_vec(v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(
        P.rot0.x * v.x + P.rot0.y * v.y + P.rot0.z * v.z,
        P.rot1.x * v.x + P.rot1.y * v.y + P.rot1.z * v.z,
        P.rot2.x * v.x + P.rot2.y * v.y + P.rot2.z * v.z,
    );
}

// One axis of the slab test; d == 0: inside the slab for all t, or never (render.rs).
struct Span {
    ok: bool,
    t0: f32,
    t1: f32,
}

fn slab(o: f32, d: f32, span: Span) -> Span {
    var r = span;
    if (d == 0.0) {
        r.ok = r.ok && abs(o) <= 1.0;
        return r;
    }
    let inv = 1.0 / d;
    let a0 = (-1.0 - o) * inv;
    let b0 = (1.0 - o) * inv;
    r.t0 = max(r.t0, min(a0, b0));
    r.t1 = min(r.t1, max(a0, b0));
    return r;
}

// Slab test against [-1,1]^3 (render.rs `box_hit`): hit when t1 > max(t0, 0).
fn box_hit(o: vec3<f32>, d: vec3<f32>) -> Span {
    var s = Span(true, -3.0e38, 3.0e38);
    s = slab(o.x, d.x, s);
    s = slab(o.y, d.y, s);
    s = slab(o.z, d.z, s);
    s.ok = s.ok && s.t1 > max(s.t0, 0.0);
    return s;
}

fn axis_exit(g: f32, gd: f32, r: f32, best: f32) -> f32 {
    if (gd == 0.0) {
        return best;
    }
    let u = (g + 1.0) * 0.5 * r;
    let k = clamp(floor(u), 0.0, r - 1.0);
    let bound = select(k, k + 1.0, gd > 0.0);
    return min(best, (bound / r * 2.0 - 1.0 - g) / gd);
}

// Distance along the ray from grid point g to the exit of its indirection cell.
fn cell_exit(g: vec3<f32>, gdir: vec3<f32>) -> f32 {
    let r = f32(P.grid.y);
    var best = 3.0e38;
    best = axis_exit(g.x, gdir.x, r, best);
    best = axis_exit(g.y, gdir.y, r, best);
    best = axis_exit(g.z, gdir.z, r, best);
    return max(best, 0.0);
}

// Straight-line march (object, forward): samples at t_base + (i + 0.5) dt, empty cells
// jumped to the last lattice point before their exit.
fn march_affine(go: vec3<f32>, gdir: vec3<f32>, t_base: f32, t_end: f32, dt: f32, delta: f32, i_start: u32) {
    var i = i_start;
    for (var it = 0u; it < MAX_ITERS; it++) {
        let t = t_base + (f32(i) + 0.5) * dt;
        if (!(t < t_end)) {
            break;
        }
        let g = go + t * gdir;
        let loc = locate(g);
        if (!loc.ok) {
            i += 1u;
            continue;
        }
        let s = sample_cell(loc);
        if (s.ok) {
            if (accum_add(s.v, delta, t)) {
                break;
            }
            i += 1u;
        } else {
            let exit = t + cell_exit(g, gdir);
            let j = floor((exit - t_base) / dt - 0.5);
            if (j >= 4.0e9) {
                break;
            }
            if (j > f32(i + 1u)) {
                i = u32(j);
            } else {
                i = i + 1u;
            }
        }
    }
}

fn contract(p: vec3<f32>) -> vec3<f32> {
    let m = max(abs(p.x), max(abs(p.y), abs(p.z)));
    if (m <= 1.0) {
        return p;
    }
    let onm = abs(p) == vec3<f32>(m);
    let edge = (2.0 - 1.0 / m) * sign(p);
    return select(p / m, edge, onm);
}

fn unbounded_dt(p: vec3<f32>) -> f32 {
    let m = max(max(abs(p.x), max(abs(p.y), abs(p.z))), 1.0);
    return min(2.0 * P.march.z * m * m, UNBOUNDED_FAR);
}

fn march_unbounded(o: vec3<f32>, d: vec3<f32>) {
    var t = UNBOUNDED_NEAR + 0.5 * unbounded_dt(o + UNBOUNDED_NEAR * d);
    for (var it = 0u; it < MAX_ITERS; it++) {
        if (!(t < UNBOUNDED_FAR)) {
            break;
        }
        let p = o + t * d;
        let dt = unbounded_dt(p);
        let c = contract(p);
        let loc = locate(c * 0.5);
        if (loc.ok) {
            let s = sample_cell(loc);
            if (s.ok) {
                if (accum_add(s.v, dt, t)) {
                    break;
                }
            }
        }
        t += dt;
    }
}

fn march_forward(o_in: vec3<f32>, d: vec3<f32>) {
    if (d.z >= -NDC_MIN_DZ) {
        return;
    }
    let near = P.march.x;
    let t = -(near + o_in.z) / d.z;
    let o = o_in + t * d;
    let ax = -P.ndc0.x / (P.ndc0.z * 0.5);
    let ay = -P.ndc0.y / (P.ndc0.w * 0.5);
    let o_ndc = vec3<f32>(ax * o.x / o.z, ay * o.y / o.z, 1.0 + 2.0 * near / o.z);
    let d_ndc = vec3<f32>(ax * (d.x / d.z - o.x / o.z), ay * (d.y / d.z - o.y / o.z), -2.0 * near / o.z);
    let e = P.march.y;
    let go = vec3<f32>(o_ndc.x / e, o_ndc.y / e, o_ndc.z);
    let gdir = vec3<f32>(d_ndc.x / e, d_ndc.y / e, d_ndc.z);
    if (!(finite3(go) && finite3(gdir))) {
        return;
    }
    let speed = norm3(gdir);
    let dt = P.march.z / speed;
    let delta = dt * norm3(d_ndc);
    if (!(dt > 0.0 && dt < 3.0e38 && delta < 3.0e38)) {
        return;
    }
    let h = box_hit(go, gdir);
    if (!h.ok) {
        return;
    }
    let i_start = u32(max(floor(max(h.t0, 0.0) / dt - 0.5), 0.0));
    march_affine(go, gdir, 0.0, min(h.t1, 1.0), dt, delta, i_start);
}

// ---- deferred view MLP (mlp.rs): 34 -> 16 -> 16 -> 3, relu, relu, linear ----
// Weights input-major in vec4 rows: input i of a layer adds x_i * (4 vec4 = 16 units),
// in the same order as the CPU's per-unit dot products (bias first, then i = 0, 1, ...).
const M_W1: u32 = 0u;   // 34 inputs x 4 vec4
const M_B1: u32 = 136u; // 4 vec4
const M_W2: u32 = 140u; // 16 inputs x 4 vec4
const M_B2: u32 = 204u; // 4 vec4
const M_W3: u32 = 208u; // 16 inputs x 1 vec4 (3 outputs + 0)
const M_B3: u32 = 224u; // 1 vec4

struct Hidden {
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
    d: vec4<f32>,
}

fn hidden_bias(base: u32) -> Hidden {
    return Hidden(mlp[base], mlp[base + 1u], mlp[base + 2u], mlp[base + 3u]);
}

// h += x * (weights of input row `row` of a 16-unit layer at `base`)
fn hidden_add(h: Hidden, x: f32, base: u32, row: u32) -> Hidden {
    let k = base + row * 4u;
    return Hidden(h.a + mlp[k] * x, h.b + mlp[k + 1u] * x, h.c + mlp[k + 2u] * x, h.d + mlp[k + 3u] * x);
}

fn hidden_add4(h: Hidden, x: vec4<f32>, base: u32, row: u32) -> Hidden {
    var r = hidden_add(h, x.x, base, row);
    r = hidden_add(r, x.y, base, row + 1u);
    r = hidden_add(r, x.z, base, row + 2u);
    r = hidden_add(r, x.w, base, row + 3u);
    return r;
}

fn relu(h: Hidden) -> Hidden {
    let z = vec4<f32>(0.0);
    return Hidden(max(h.a, z), max(h.b, z), max(h.c, z), max(h.d, z));
}

fn out_add4(o: vec4<f32>, x: vec4<f32>, row: u32) -> vec4<f32> {
    let k = M_W3 + row;
    var r = o + mlp[k] * x.x;
    r = r + mlp[k + 1u] * x.y;
    r = r + mlp[k + 2u] * x.z;
    r = r + mlp[k + 3u] * x.w;
    return r;
}

fn view_mlp(dir: vec3<f32>) -> vec3<f32> {
    var h = hidden_bias(M_B1);
    h = hidden_add(h, acc_rgb.x, M_W1, 0u);
    h = hidden_add(h, acc_rgb.y, M_W1, 1u);
    h = hidden_add(h, acc_rgb.z, M_W1, 2u);
    h = hidden_add4(h, acc_feat, M_W1, 3u);
    h = hidden_add(h, dir.x, M_W1, 7u);
    h = hidden_add(h, dir.y, M_W1, 8u);
    h = hidden_add(h, dir.z, M_W1, 9u);
    var row = 10u;
    for (var o = 0u; o < 4u; o++) {
        let arg = f32(1u << o) * PI * dir;
        let sn = sin(arg);
        let cs = cos(arg);
        h = hidden_add(h, sn.x, M_W1, row);
        h = hidden_add(h, cs.x, M_W1, row + 1u);
        h = hidden_add(h, sn.y, M_W1, row + 2u);
        h = hidden_add(h, cs.y, M_W1, row + 3u);
        h = hidden_add(h, sn.z, M_W1, row + 4u);
        h = hidden_add(h, cs.z, M_W1, row + 5u);
        row += 6u;
    }
    let h1 = relu(h);
    var g = hidden_bias(M_B2);
    g = hidden_add4(g, h1.a, M_W2, 0u);
    g = hidden_add4(g, h1.b, M_W2, 4u);
    g = hidden_add4(g, h1.c, M_W2, 8u);
    g = hidden_add4(g, h1.d, M_W2, 12u);
    let h2 = relu(g);
    var o = mlp[M_B3];
    o = out_add4(o, h2.a, 0u);
    o = out_add4(o, h2.b, 4u);
    o = out_add4(o, h2.c, 8u);
    o = out_add4(o, h2.d, 12u);
    return o.xyz;
}

struct Px {
    rgb: vec3<f32>,
    opacity: f32,
    depth: f32,
}

// One ray through the point (sx, sy) of pixel (x, y)'s square: render.rs `render_ray`.
fn render_at(x: u32, y: u32, sx: f32, sy: f32) -> Px {
    accum_reset();
    // render.rs `camera_ray` (Pinhole::ray_at)
    let dc = vec3<f32>(
        (f32(x) + sx - P.intr.z) / P.intr.x,
        -(f32(y) + sy - P.intr.w) / P.intr.y,
        -1.0,
    );
    let ow = vec3<f32>(P.c2w0.w, P.c2w1.w, P.c2w2.w);
    let dw = normalize3(normalize3(vec3<f32>(
        P.c2w0.x * dc.x + P.c2w0.y * dc.y + P.c2w0.z * dc.z,
        P.c2w1.x * dc.x + P.c2w1.y * dc.y + P.c2w1.z * dc.z,
        P.c2w2.x * dc.x + P.c2w2.y * dc.y + P.c2w2.z * dc.z,
    )));
    let o = rot_vec(ow - P.center_scale.xyz) * P.center_scale.w;
    let d = normalize3(rot_vec(dw));
    if (KIND == 0u) {
        let h = box_hit(o, d);
        if (h.ok) {
            march_affine(o, d, max(h.t0, 0.0), h.t1, P.march.z, P.march.z, 0u);
        }
    } else if (KIND == 1u) {
        march_forward(o, d);
    } else {
        march_unbounded(o, d);
    }
    // render.rs `shade` (a diffuse asset's view MLP is zero: render.rs skips it too)
    var spec = vec3<f32>(0.0);
    if (!DIFFUSE && acc_w > 0.0) {
        spec = view_mlp(dw);
    }
    let diffuse = acc_rgb;
    let rgb = clamp(diffuse + acc_w * spec + acc_trans * P.background.xyz, vec3<f32>(0.0), vec3<f32>(1.0));
    var depth = 0.0;
    if (acc_w > 1.0e-6) {
        depth = acc_depth / acc_w;
    }
    return Px(rgb, acc_w, depth);
}

// snerf_geometry::silhouette::mixed_coverage on the first pass's opacity of this view.
fn on_silhouette(x: u32, y: u32) -> bool {
    let width = P.view.x;
    let height = P.view.y;
    var lo = cover_at(x, y);
    var hi = lo;
    for (var yy = max(y, 1u) - 1u; yy < min(y + 2u, height); yy = yy + 1u) {
        for (var xx = max(x, 1u) - 1u; xx < min(x + 2u, width); xx = xx + 1u) {
            let a = cover_at(xx, yy);
            lo = min(lo, a);
            hi = max(hi, a);
        }
    }
    return lo < COVER_FULL && hi > COVER_EMPTY;
}

// snerf_geometry::silhouette::mean_of_rays over subpixel_grid(side * side): a silhouette
// pixel of the second pass.
fn pixel_mean(x: u32, y: u32, side: u32) -> Px {
    var rgb = vec3<f32>(0.0);
    var opacity = 0.0;
    var depth = 0.0;
    let n = side * side;
    for (var j = 0u; j < n; j = j + 1u) {
        let p = render_at(x, y, (f32(j % side) + 0.5) / f32(side), (f32(j / side) + 0.5) / f32(side));
        rgb = rgb + p.rgb;
        opacity = opacity + p.opacity;
        depth = depth + p.depth * p.opacity;
    }
    if (opacity > 1.0e-6) {
        depth = depth / opacity;
    } else {
        depth = 0.0;
    }
    return Px(rgb / f32(n), opacity / f32(n), depth);
}
