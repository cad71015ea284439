//! CPU reference renderer: the ground truth the GPU shader is checked against, written to
//! march exactly like the trainer (same model/NDC/contraction mapping, same sample lattice
//! t0 + (i+0.5)·dt, same stable compositing), only reading baked voxels instead of the field.
//!
//! Per ray: world ray -> model ray -> march space (object: model; forward: NDC; unbounded:
//! model with growing steps) -> grid point per sample -> trilinear voxel values ->
//! front-to-back compositing with T = exp(-Σσδ) -> view MLP once on the composited values.
//! Silhouette pixels of assets trained that way: a second pass, the mean of sub-pixel rays
//! (`render`, `snerf_geometry::silhouette`).

use anyhow::{anyhow, ensure, Result};
use rayon::prelude::*;
use std::path::Path;

use crate::asset::Asset;
use crate::atomic::write_atomic;
use crate::header::{Header, Kind};
use crate::mlp::ViewMlp;
use crate::quantize::quantize_unit;
use crate::sample::TimeSlot;

pub use snerf_geometry::march::{MAX_ITERS, MAX_OPTICAL_DEPTH, UNBOUNDED_FAR, UNBOUNDED_NEAR};
pub use snerf_geometry::ndc::NDC_MIN_DZ;
pub use snerf_geometry::{contract, unbounded_dt};
use snerf_geometry::silhouette::{mean_of_rays, mixed_coverage, subpixel_grid};
use snerf_geometry::vec::norm;
use snerf_geometry::{box_hit, MarchRay};

/// A pinhole camera. c2w is camera-to-world (OpenGL: x right, y up, looking down -z),
/// rows of [R | t].
pub use snerf_geometry::Pinhole as Camera;

/// A rendered image: rgb is row-major H x W x 3; depth (march-space ray parameter,
/// opacity-normalized, 0 where empty) and opacity are H x W.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<f32>,
    pub depth: Vec<f32>,
    pub opacity: Vec<f32>,
}

/// One ray's result.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelResult {
    pub rgb: [f32; 3],
    pub depth: f32,
    pub opacity: f32,
    /// Non-empty samples composited (for tests and performance counters).
    pub samples: u32,
}

type V3 = [f32; 3];

/// World origin and unit world direction of pixel (px, py), through the pixel centre.
pub fn camera_ray(cam: &Camera, px: u32, py: u32) -> (V3, V3) {
    cam.ray(px, py)
}

/// Front-to-back compositing state.
struct Accum {
    /// Σ w · (rgb, feat)
    vals: [f32; 7],
    acc: f32,
    depth: f32,
    optical: f32,
    trans: f32,
    samples: u32,
}

impl Accum {
    fn new() -> Accum {
        Accum { vals: [0.0; 7], acc: 0.0, depth: 0.0, optical: 0.0, trans: 1.0, samples: 0 }
    }
    /// Add one sample; returns true when the ray should stop (T below t_terminate).
    #[inline]
    fn add(&mut self, v: &[f32; 8], delta: f32, t: f32, t_terminate: f32) -> bool {
        let sigma = v[0].exp();
        // max/min (not clamp) so NaN becomes 0 rather than propagating.
        let sd = (sigma * delta).max(0.0).min(MAX_OPTICAL_DEPTH);
        let alpha = -(-sd).exp_m1();
        let w = self.trans * alpha;
        for c in 0..7 {
            self.vals[c] += w * v[c + 1];
        }
        self.acc += w;
        self.depth += w * t;
        self.optical += sd;
        self.trans = (-self.optical).exp();
        self.samples += 1;
        self.trans < t_terminate
    }
}

/// Ray-parameter distance from grid point `g` to the exit of its indirection cell along
/// grid-space direction `gd` (0 if already on the boundary).
#[inline]
fn cell_exit(g: V3, gd: V3, cells: usize) -> f32 {
    let r = cells as f32;
    let mut best = f32::INFINITY;
    for a in 0..3 {
        if gd[a] == 0.0 {
            continue;
        }
        let u = (g[a] + 1.0) * 0.5 * r;
        let k = u.floor().clamp(0.0, r - 1.0);
        let bound = if gd[a] > 0.0 { k + 1.0 } else { k };
        let s = (bound / r * 2.0 - 1.0 - g[a]) / gd[a];
        if s < best {
            best = s;
        }
    }
    best.max(0.0)
}

/// March a ray that is a straight line in grid space (object, forward): grid point at t is
/// go + t·gd; samples at t_i = t_base + (i+0.5)·dt while t_i < t_end, starting at lattice
/// index `i_start`. Empty cells are jumped over to the last lattice point before their exit,
/// so exactly the same non-empty positions are sampled as by a plain step-by-step march.
#[allow(clippy::too_many_arguments)]
fn march_affine(
    asset: &Asset,
    slot: &TimeSlot,
    go: V3,
    gd: V3,
    t_base: f32,
    t_end: f32,
    dt: f32,
    delta: f32,
    i_start: usize,
    acc: &mut Accum,
) {
    let t_term = asset.header.march.t_terminate;
    let cells = asset.grid_dim();
    let mut i = i_start;
    for _ in 0..MAX_ITERS as usize {
        let t = t_base + (i as f32 + 0.5) * dt;
        if !(t < t_end) {
            break;
        }
        let g = [go[0] + t * gd[0], go[1] + t * gd[1], go[2] + t * gd[2]];
        let Some(loc) = asset.locate(g) else {
            i += 1;
            continue;
        };
        match asset.sample_slot(slot, &loc) {
            Some(v) => {
                if acc.add(&v, delta, t, t_term) {
                    break;
                }
                i += 1;
            }
            None => {
                let exit = t + cell_exit(g, gd, cells);
                let j = ((exit - t_base) / dt - 0.5).floor();
                // `as usize` saturates (inf -> MAX, NaN -> 0); max() guarantees progress.
                i = (j as usize).max(i + 1);
            }
        }
    }
}

/// Unbounded: step length re-evaluated at every sample (t += dt(p)), first sample at
/// t0 + dt(t0)/2; grid point = contract(p)/2.
fn march_unbounded(asset: &Asset, slot: &TimeSlot, o: V3, d: V3, acc: &mut Accum) {
    let step = asset.header.march.step;
    let t_term = asset.header.march.t_terminate;
    let at = |t: f32| [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]];
    let mut t = UNBOUNDED_NEAR + 0.5 * unbounded_dt(step, at(UNBOUNDED_NEAR));
    for _ in 0..MAX_ITERS as usize {
        if !(t < UNBOUNDED_FAR) {
            break;
        }
        let p = at(t);
        let dt = unbounded_dt(step, p);
        let c = contract(p);
        if let Some(loc) = asset.locate([c[0] * 0.5, c[1] * 0.5, c[2] * 0.5]) {
            if let Some(v) = asset.sample_slot(slot, &loc) {
                if acc.add(&v, dt, t, t_term) {
                    break;
                }
            }
        }
        t += dt;
    }
}

/// Render one world-space ray (origin `ow`, direction `dw`, normalized here) at `time`.
pub fn render_ray(asset: &Asset, ow: V3, dw: V3, time: f32) -> PixelResult {
    let h = &asset.header;
    let dw = snerf_geometry::vec::normalize(dw);
    let mut acc = Accum::new();
    if let Some(r) = h.space.march_ray(h.kind, ow, dw) {
        let slot = asset.time_slot(time);
        let step = h.march.step;
        match (h.kind, h.space.ndc) {
            (Kind::Object, _) => march_affine(asset, &slot, r.o, r.d, r.t0, r.t1, step, step, 0, &mut acc),
            (Kind::Forward, Some(n)) => march_forward(asset, &slot, &r, &n, &mut acc),
            (Kind::Forward, None) => {}
            (Kind::Unbounded, _) => march_unbounded(asset, &slot, r.o, r.d, &mut acc),
        }
    }
    shade(asset, &acc, dw)
}

/// Forward-facing: NeRF's ndc_rays on the model ray, then an affine march over t in [0,1]
/// restricted to where the grid ray is inside [-1,1]^3 (outside samples contribute nothing).
fn march_forward(asset: &Asset, slot: &TimeSlot, r: &MarchRay, n: &crate::header::Ndc, acc: &mut Accum) {
    let (go, gd) = (n.to_grid(r.o), n.to_grid(r.d));
    if !go.iter().chain(gd.iter()).all(|x| x.is_finite()) {
        return;
    }
    let speed = norm(gd);
    let dt = asset.header.march.step / speed;
    let delta = dt * norm(r.d);
    if !(dt > 0.0 && dt.is_finite() && delta.is_finite()) {
        return;
    }
    let Some((tb0, tb1)) = box_hit(go, gd, 1.0) else { return };
    // First lattice index at or just before the box entry (outside points are skipped).
    let i_start = ((tb0.max(0.0) / dt - 0.5).floor().max(0.0)) as usize;
    march_affine(asset, slot, go, gd, 0.0, tb1.min(r.t1), dt, delta, i_start, acc);
}

/// Final pixel colour: diffuse + opacity·specular + T·background, clamped to [0,1].
fn shade(asset: &Asset, acc: &Accum, dw: V3) -> PixelResult {
    let bg = asset.header.background;
    // a diffuse asset's MLP is zero (validated): its specular term is 0 without running it
    let spec = if acc.acc > 0.0 && !asset.header.diffuse { asset.mlp.forward(&ViewMlp::input(&acc.vals, dw)) } else { [0.0; 3] };
    let rgb = [0, 1, 2].map(|c| (acc.vals[c] + acc.acc * spec[c] + acc.trans * bg[c]).max(0.0).min(1.0));
    let depth = if acc.acc > 1e-6 { acc.depth / acc.acc } else { 0.0 };
    PixelResult { rgb, depth, opacity: acc.acc, samples: acc.samples }
}

/// One pixel (centre at px+0.5, py+0.5).
pub fn render_pixel(asset: &Asset, cam: &Camera, px: u32, py: u32, time: f32) -> PixelResult {
    let (o, d) = camera_ray(cam, px, py);
    render_ray(asset, o, d, time)
}

/// One pixel as the mean of `k` rays on its sub-pixel grid (`silhouette::subpixel_grid`).
pub fn render_pixel_mean(asset: &Asset, cam: &Camera, px: u32, py: u32, time: f32, k: usize) -> PixelResult {
    let rays: Vec<PixelResult> = subpixel_grid(k)
        .into_iter()
        .map(|(sx, sy)| {
            let (o, d) = cam.ray_at(px, py, sx, sy);
            render_ray(asset, o, d, time)
        })
        .collect();
    let (rgb, opacity, depth) = mean_of_rays(&rays.iter().map(|r| (r.rgb, r.opacity, r.depth)).collect::<Vec<_>>());
    PixelResult { rgb, depth, opacity, samples: rays.iter().map(|r| r.samples).sum() }
}

/// A whole image, rows in parallel: one ray through every pixel's centre, then, for an
/// asset whose field was trained that way (`header.pixel_rays_for(cam)` > 1: the field's
/// rule, for cameras whose pixels are about as coarse as the training views'), every
/// silhouette pixel (`silhouette::mixed_coverage` of the first pass's opacity) again as the
/// mean over its square. The march shader does the same in two passes.
pub fn render(asset: &Asset, cam: &Camera, time: f32) -> Frame {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut px: Vec<PixelResult> = (0..cam.height)
        .into_par_iter()
        .flat_map_iter(|y| (0..cam.width).map(move |x| render_pixel(asset, cam, x, y, time)))
        .collect();
    let k = asset.header.pixel_rays_for(cam) as usize;
    if k > 1 {
        let opacity: Vec<f32> = px.iter().map(|p| p.opacity).collect();
        let edge: Vec<usize> = (0..w * h).filter(|&p| mixed_coverage(&opacity, w, h, p % w, p / w)).collect();
        let means: Vec<PixelResult> =
            edge.par_iter().map(|&p| render_pixel_mean(asset, cam, (p % w) as u32, (p / w) as u32, time, k)).collect();
        for (&p, m) in edge.iter().zip(means) {
            px[p] = m;
        }
    }
    Frame {
        width: cam.width,
        height: cam.height,
        rgb: px.iter().flat_map(|p| p.rgb).collect(),
        depth: px.iter().map(|p| p.depth).collect(),
        opacity: px.iter().map(|p| p.opacity).collect(),
    }
}

fn to_png_bytes(img: image::RgbImage) -> Result<Vec<u8>> {
    let mut buf = std::io::Cursor::new(Vec::new());
    img.write_to(&mut buf, image::ImageFormat::Png).map_err(|e| anyhow!("PNG encoding failed: {}", e))?;
    Ok(buf.into_inner())
}

fn frame_image(frame: &Frame) -> Result<image::RgbImage> {
    let n = frame.width as usize * frame.height as usize * 3;
    ensure!(frame.rgb.len() == n, "frame has {} rgb values for {}x{}", frame.rgb.len(), frame.width, frame.height);
    let data: Vec<u8> = frame.rgb.iter().map(|&v| quantize_unit(v)).collect();
    image::RgbImage::from_raw(frame.width, frame.height, data).ok_or_else(|| anyhow!("bad frame size"))
}

/// Save a frame's colour as PNG (atomically).
pub fn write_png(frame: &Frame, path: impl AsRef<Path>) -> Result<()> {
    let path = path.as_ref();
    let img = frame_image(frame).map_err(|e| anyhow!("{}: {:#}", path.display(), e))?;
    write_atomic(path, &to_png_bytes(img)?)
}

/// Up to 8 frames side by side in one PNG: a cheap animated-preview stand-in.
pub fn contact_strip(frames: &[Frame], path: impl AsRef<Path>) -> Result<()> {
    let path = path.as_ref();
    let frames = &frames[..frames.len().min(8)];
    ensure!(!frames.is_empty(), "{}: no frames for the contact strip", path.display());
    let w: u32 = frames.iter().map(|f| f.width).sum();
    let h = frames.iter().map(|f| f.height).max().unwrap_or(0);
    let mut canvas = image::RgbImage::new(w, h);
    let mut x0 = 0;
    for f in frames {
        let img = frame_image(f).map_err(|e| anyhow!("{}: {:#}", path.display(), e))?;
        image::imageops::replace(&mut canvas, &img, x0 as i64, 0);
        x0 += f.width;
    }
    write_atomic(path, &to_png_bytes(canvas)?)
}

/// Model point -> world point (inverse of model = scale·rot·(world - center)).
pub fn model_to_world(h: &Header, m: V3) -> V3 {
    h.space.to_world(m)
}

/// Grid point -> model -> world: object identity; forward NDC inverse; unbounded inverse
/// contraction (clamped so points at the far shell stay finite).
pub fn grid_to_world(h: &Header, g: [f32; 3]) -> [f32; 3] {
    h.space.grid_to_world(h.kind, g)
}

/// Camera `i` of `n` on the asset's preview orbit ([`Header::orbit`]: from the capture's
/// cameras, around the scene's own up direction). `fov_y` is the vertical field of view in
/// degrees.
pub fn orbit(h: &Header, n: usize, i: usize, width: u32, height: u32, fov_y: f32) -> Camera {
    Camera::from_fov(h.orbit().c2w(i, n), width, height, fov_y)
}
