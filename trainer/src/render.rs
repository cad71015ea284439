//! Fused per-chunk volume rendering: march -> encode -> decode -> composite -> view MLP, and
//! for training the whole backward pass in the same workspace, so a chunk of rays never
//! leaves one core's cache and nothing is allocated per step.
//!
//! Rays are marched in *waves*: every live ray of the chunk takes up to `WAVE` more samples,
//! the wave is evaluated as one batch, and rays whose transmittance fell below
//! `T_TERMINATE` stop (early ray termination without evaluating what lies behind a surface,
//! including the never-seen inside of solid objects).

use crate::composite::{self, V};
use crate::field::{activate, activate_backward, Field, OUT};
use crate::occupancy::{MarchState, Occupancy, Sample};
use crate::space::{Ray, SceneSpace};
use crate::view_mlp::{ViewCache, ViewLayout, VOUT};

/// Samples a live ray takes per wave.
pub const WAVE: usize = 24;
/// Rays stop once transmittance is below this.
pub const T_TERMINATE: f32 = 1.0e-4;

/// One ray to render, with what it should look like when training.
#[derive(Clone, Copy, Debug)]
pub struct RayTask {
    pub ray: Option<Ray>,
    /// Background colour behind the field.
    pub bg: [f32; 3],
    /// Target colour (training only).
    pub target: [f32; 3],
    pub jitter: f32,
}

/// What a rendered ray looks like.
#[derive(Clone, Copy, Debug, Default)]
pub struct RayResult {
    pub rgb: [f32; 3],
    /// Expected depth along the march-space ray, normalized by opacity (0 when empty).
    pub depth: f32,
    pub opacity: f32,
    pub samples: u32,
}

/// Per-thread scratch memory, reused across chunks and steps.
#[derive(Default)]
pub struct Workspace {
    samples: Vec<Sample>,
    sample_time: Vec<f32>,
    /// Where each sample is read in the planes when the field has a deformation
    /// ([`Field::warp`]); empty otherwise.
    warped: Vec<[f32; 3]>,
    sample_ray: Vec<u32>,
    sigma: Vec<f32>,
    /// Activated rgb + features per sample (computed once in the forward pass).
    vals: Vec<[f32; 7]>,
    /// Plane lookups per sample, recorded for the backward pass (training only).
    hits: Vec<crate::field::PlaneHit>,
    feat: Vec<f32>,
    hid: Vec<f32>,
    out: Vec<f32>,
    d_out: Vec<f32>,
    d_hid: Vec<f32>,
    d_feat: Vec<f32>,
    ray_samples: Vec<Vec<u32>>,
    states: Vec<MarchState>,
    depth_sum: Vec<f32>,
    live: Vec<u32>,
    // per-ray compositing scratch
    c_sigma: Vec<f32>,
    c_delta: Vec<f32>,
    c_v: Vec<[f32; V]>,
    c_dsigma: Vec<f32>,
    c_dv: Vec<[f32; V]>,
    c_scratch: Vec<f32>,
    c_w: Vec<f32>,
    c_gw: Vec<f32>,
    c_mid: Vec<f32>,
    c_len: Vec<f32>,
    /// Parameter gradient accumulated by this thread.
    pub grad: Vec<f32>,
    /// One flag per plane cell (C floats) whose gradient this thread touched.
    pub touched: Vec<u8>,
    /// Per-photo colour transforms the training loss sees (none: off) and their gradient.
    pub appearance: crate::appearance::ChunkAppearance,
}

/// Statistics of one processed chunk.
#[derive(Clone, Copy, Debug, Default)]
pub struct ChunkStats {
    pub loss_sum: f64,
    pub distortion_sum: f64,
    pub samples: u64,
    pub rays: u64,
    /// Pixels the rays make up (each pixel's loss term is the mean of its rays).
    pub pixels: u64,
    /// Nanoseconds per phase (see [`PHASES`]), summed over threads.
    pub ns: [u64; 6],
}

/// Names of the timed phases in [`ChunkStats::ns`].
pub const PHASES: [&str; 6] = ["march", "encode", "decode", "composite+view", "decode backward", "encode backward"];

impl ChunkStats {
    pub fn merge(self, b: ChunkStats) -> ChunkStats {
        let mut ns = self.ns;
        for i in 0..6 {
            ns[i] += b.ns[i];
        }
        ChunkStats {
            loss_sum: self.loss_sum + b.loss_sum,
            distortion_sum: self.distortion_sum + b.distortion_sum,
            samples: self.samples + b.samples,
            rays: self.rays + b.rays,
            pixels: self.pixels + b.pixels,
            ns,
        }
    }
}

#[inline]
fn lap(t: &mut std::time::Instant) -> u64 {
    let now = std::time::Instant::now();
    let d = now.duration_since(*t).as_nanos() as u64;
    *t = now;
    d
}

impl Workspace {
    /// A workspace whose gradient buffer fits `params` parameters.
    pub fn new(params: usize) -> Workspace {
        Workspace { grad: vec![0.0; params], touched: vec![0; params / crate::field::C], ..Default::default() }
    }

    fn reset(&mut self, n_rays: usize) {
        self.samples.clear();
        self.sample_time.clear();
        self.warped.clear();
        self.sample_ray.clear();
        self.sigma.clear();
        self.vals.clear();
        if self.ray_samples.len() < n_rays {
            self.ray_samples.resize_with(n_rays, Vec::new);
        }
        for r in &mut self.ray_samples[..n_rays] {
            r.clear();
        }
        self.states.clear();
        self.depth_sum.clear();
        self.depth_sum.resize(n_rays, 0.0);
        self.live.clear();
    }

    /// March and evaluate the field on all rays of the chunk (forward only), wave by wave.
    fn forward_field(
        &mut self,
        field: &Field,
        space: &SceneSpace,
        occ: &Occupancy,
        tasks: &[RayTask],
        record: bool,
        ns: &mut [u64; 6],
    ) {
        let nh = field.hits_per_point();
        let mut clock = std::time::Instant::now();
        self.reset(tasks.len());
        for (i, task) in tasks.iter().enumerate() {
            match task.ray {
                Some(r) => {
                    self.states.push(occ.start(space, &r, task.jitter));
                    self.live.push(i as u32);
                }
                None => self.states.push(MarchState { t: 0.0, done: true }),
            }
        }
        let (inp, h) = (field.layout.input, field.layout.hid_width());
        let log_terminate = -T_TERMINATE.ln();
        while !self.live.is_empty() {
            let start = self.samples.len();
            for &ri in &self.live {
                let ri = ri as usize;
                let ray = tasks[ri].ray.as_ref().unwrap();
                let before = self.samples.len();
                occ.march(space, ray, &mut self.states[ri], WAVE, &mut self.samples);
                for k in before..self.samples.len() {
                    self.ray_samples[ri].push(k as u32);
                    self.sample_ray.push(ri as u32);
                    self.sample_time.push(ray.time);
                }
            }
            let end = self.samples.len();
            ns[0] += lap(&mut clock);
            if end == start {
                break;
            }
            let n = end - start;
            self.feat.resize(end * inp, 0.0);
            self.hid.resize(end * h, 0.0);
            self.out.resize(end * OUT, 0.0);
            let deformed = field.layout.deform.is_some();
            if deformed {
                for k in start..end {
                    self.warped.push(field.warp(&self.samples[k].g, self.sample_time[k]));
                }
            }
            let (samples, warped) = (&self.samples, &self.warped);
            let at = |k: usize| if deformed { &warped[k] } else { &samples[k].g };
            const AHEAD: usize = 6;
            for k in start..(start + AHEAD).min(end) {
                field.prefetch(at(k), self.sample_time[k]);
            }
            if record {
                self.hits.resize(end * nh, Default::default());
            }
            for k in start..end {
                if k + AHEAD < end {
                    field.prefetch(at(k + AHEAD), self.sample_time[k + AHEAD]);
                }
                let (g, t) = (at(k), self.sample_time[k]);
                let feat = &mut self.feat[k * inp..(k + 1) * inp];
                if record {
                    field.encode_recorded(g, t, feat, &mut self.hits[k * nh..(k + 1) * nh]);
                } else {
                    field.encode(g, t, feat);
                }
            }
            ns[1] += lap(&mut clock);
            field.decode_forward(
                n,
                &self.feat[start * inp..end * inp],
                &mut self.hid[start * h..end * h],
                &mut self.out[start * OUT..end * OUT],
            );
            for k in start..end {
                let (sg, v) = activate(&self.out[k * OUT..(k + 1) * OUT]);
                self.sigma.push(sg);
                self.vals.push(v);
                let ri = self.sample_ray[k] as usize;
                self.depth_sum[ri] += composite::optical_depth(sg, self.samples[k].delta);
            }
            let (states, depth_sum) = (&self.states, &self.depth_sum);
            self.live.retain(|&ri| !states[ri as usize].done && depth_sum[ri as usize] < log_terminate);
            ns[2] += lap(&mut clock);
        }
    }

    /// Gather ray `ri`'s samples into the compositing scratch arrays.
    fn gather(&mut self, ri: usize) {
        self.c_sigma.clear();
        self.c_delta.clear();
        self.c_v.clear();
        for &k in &self.ray_samples[ri] {
            let k = k as usize;
            self.c_sigma.push(self.sigma[k]);
            self.c_delta.push(self.samples[k].delta);
            let mut v = [1.0f32; V];
            v[..7].copy_from_slice(&self.vals[k]);
            self.c_v.push(v);
        }
    }
}

/// Final colour from the composited vector: diffuse + opacity * specular + T_N * background.
#[inline]
fn shade(value: &[f32; V], t_final: f32, spec: &[f32; VOUT], bg: &[f32; 3]) -> [f32; 3] {
    let acc = value[7];
    [0, 1, 2].map(|c| value[c] + acc * spec[c] + t_final * bg[c])
}

/// Fixed sub-pixel positions of `k` rays: one home, shared with the asset's renderers.
pub use snerf_geometry::silhouette::subpixel_grid;

/// Colour of ray `ri` of the chunk (forward only, after `forward_field`).
fn ray_colour(field: &Field, ws: &mut Workspace, ri: usize, ray: &Ray, bg: &[f32; 3]) -> [f32; 3] {
    ws.gather(ri);
    let comp = composite::forward(&ws.c_sigma, &ws.c_delta, &ws.c_v);
    let (spec, _) = field.layout.view.forward(&field.params, ViewLayout::input(&comp.value, &ray.dir));
    shade(&comp.value, comp.t_final, &spec, bg)
}

/// Render rays without gradients.
pub fn render_chunk(
    field: &Field,
    space: &SceneSpace,
    occ: &Occupancy,
    tasks: &[RayTask],
    ws: &mut Workspace,
    results: &mut [RayResult],
) {
    ws.forward_field(field, space, occ, tasks, false, &mut [0; 6]);
    let view: &ViewLayout = &field.layout.view;
    for (ri, task) in tasks.iter().enumerate() {
        let Some(ray) = task.ray else {
            results[ri] = RayResult { rgb: task.bg, depth: 0.0, opacity: 0.0, samples: 0 };
            continue;
        };
        ws.gather(ri);
        let comp = composite::forward(&ws.c_sigma, &ws.c_delta, &ws.c_v);
        let (spec, _) = view.forward(&field.params, ViewLayout::input(&comp.value, &ray.dir));
        // expected depth
        let mut depth = 0.0f32;
        composite::weights(&ws.c_sigma, &ws.c_delta, &mut ws.c_dsigma, &mut ws.c_scratch);
        for (j, &k) in ws.ray_samples[ri].iter().enumerate() {
            depth += ws.c_dsigma[j] * ws.samples[k as usize].t;
        }
        let acc = comp.value[7];
        results[ri] = RayResult {
            rgb: shade(&comp.value, comp.t_final, &spec, &task.bg),
            depth: if acc > 1e-6 { depth / acc } else { 0.0 },
            opacity: acc,
            samples: ws.ray_samples[ri].len() as u32,
        };
    }
}

/// One training chunk: forward, mean-squared-error loss against the targets, and the full
/// backward into `ws.grad`. `loss_scale` multiplies dL/dcolour (1 / (3 * batch pixels)).
/// `distortion` > 0 adds that weight times the distortion loss of every ray (normalized
/// grid-space distances; a pixel of k rays weighs each by 1/k), which clears fog in
/// forward-facing and unbounded scenes. `groups` splits the tasks into pixels (consecutive
/// rays sharing one target, compared with their mean colour); empty means a ray per pixel.
#[allow(clippy::too_many_arguments)]
pub fn train_chunk(
    field: &Field,
    space: &SceneSpace,
    occ: &Occupancy,
    tasks: &[RayTask],
    ws: &mut Workspace,
    loss_scale: f32,
    distortion: f32,
    groups: &[u16],
) -> ChunkStats {
    train_chunk_with(field, space, occ, tasks, ws, loss_scale, distortion, groups, Backward::Full)
}

/// How far a training chunk's backward pass goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backward {
    /// Into every parameter (planes, decoder, view MLP, deformation).
    Full,
    /// Into what learns while the geometry is frozen (`TrainConfig::freeze_geometry`): the
    /// decoder's output layer (whose colour rows and biases learn), the colour head (if the
    /// field has one), the view MLP and the photos' colour transforms. The shared hidden layer, the planes and the deformation
    /// get no gradient: their learning rate is zero then, and the pass through them (the
    /// larger part of a step's backward) would be thrown away.
    OutputLayer,
}

/// [`train_chunk`] with the backward pass cut at `backward`. The gradients it does compute
/// are the full pass's, bit for bit (trainer/tests/gradients.rs).
#[allow(clippy::too_many_arguments)]
pub fn train_chunk_with(
    field: &Field,
    space: &SceneSpace,
    occ: &Occupancy,
    tasks: &[RayTask],
    ws: &mut Workspace,
    loss_scale: f32,
    distortion: f32,
    groups: &[u16],
    backward: Backward,
) -> ChunkStats {
    let pixels = if groups.is_empty() { tasks.len() } else { groups.len() };
    let mut stats = ChunkStats { rays: tasks.len() as u64, pixels: pixels as u64, ..Default::default() };
    // the planes' corners are recorded only for a backward pass into the planes
    ws.forward_field(field, space, occ, tasks, backward == Backward::Full, &mut stats.ns);
    let mut clock = std::time::Instant::now();
    let n = ws.samples.len();
    stats.samples = n as u64;
    let (inp, h) = (field.layout.input, field.layout.hid_width());
    ws.d_out.clear();
    ws.d_out.resize(n * OUT, 0.0);
    let view = field.layout.view;
    // Pixel groups: `groups[g]` consecutive rays make one pixel (none given: one ray each).
    let mut group_end = 0usize;
    let mut next_group = groups.iter();
    let mut k = 1usize;
    let mut d_mean = [0.0f32; 3];
    for (ri, task) in tasks.iter().enumerate() {
        // A pixel is the mean of its k rays: its loss is (mean - target)^2, so each ray's
        // colour gradient is 2 (mean - target) / k.
        if ri == group_end {
            k = next_group.next().map_or(1, |&g| g.max(1) as usize).min(tasks.len() - ri);
            group_end = ri + k;
            if k > 1 {
                let mut m = [0.0f32; 3];
                for (j, t) in tasks[ri..group_end].iter().enumerate() {
                    let rgb = match t.ray {
                        Some(r) => ray_colour(field, ws, ri + j, &r, &t.bg),
                        None => t.bg,
                    };
                    for c in 0..3 {
                        m[c] += rgb[c] / k as f32;
                    }
                }
                let (e, d_m) = ws.appearance.pixel(ri, &m, &task.target, loss_scale);
                stats.loss_sum += e;
                d_mean = d_m;
            }
        }
        let Some(ray) = task.ray else {
            if k == 1 {
                stats.loss_sum += ws.appearance.pixel(ri, &task.bg, &task.target, loss_scale).0;
            }
            continue;
        };
        ws.gather(ri);
        let comp = composite::forward(&ws.c_sigma, &ws.c_delta, &ws.c_v);
        let (spec, cache): ([f32; VOUT], ViewCache) =
            view.forward(&field.params, ViewLayout::input(&comp.value, &ray.dir));
        let rgb = shade(&comp.value, comp.t_final, &spec, &task.bg);
        // dL/dcolour through the photo's colour transform (`d_mean`: a pixel's dL/dmean)
        let d_rgb = if k == 1 {
            let (e, d) = ws.appearance.pixel(ri, &rgb, &task.target, loss_scale);
            stats.loss_sum += e;
            d
        } else {
            d_mean.map(|d| d / k as f32)
        };
        let acc = comp.value[7];
        // colour = value[0..3] + acc * spec + T_N * bg
        let d_spec = [0, 1, 2].map(|c| d_rgb[c] * acc);
        let d_x = view.backward(&field.params, &cache, &d_spec, &mut ws.grad);
        let mut g = [0.0f32; V];
        for c in 0..3 {
            g[c] = d_rgb[c] + d_x[c];
        }
        g[3..7].copy_from_slice(&d_x[3..7]);
        g[7] = (0..3).map(|c| d_rgb[c] * spec[c]).sum();
        let g_t: f32 = (0..3).map(|c| d_rgb[c] * task.bg[c]).sum();
        let m = ws.c_sigma.len();
        ws.c_dsigma.resize(m, 0.0);
        ws.c_dv.resize(m, [0.0; V]);
        ws.c_gw.clear();
        if distortion > 0.0 && m > 1 {
            // positions along the ray in grid units / grid diagonal (so s ∈ [0, ~1])
            let norm = 1.0 / (2.0 * 3f32.sqrt());
            ws.c_mid.clear();
            ws.c_len.clear();
            let mut s_acc = 0.0f32;
            let mut prev = ws.samples[ws.ray_samples[ri][0] as usize].g;
            for &k in &ws.ray_samples[ri] {
                let g = ws.samples[k as usize].g;
                s_acc += crate::space::norm(crate::space::sub(g, prev)) * norm;
                prev = g;
                ws.c_mid.push(s_acc);
                ws.c_len.push(occ.step * norm);
            }
            composite::weights(&ws.c_sigma, &ws.c_delta, &mut ws.c_w, &mut ws.c_scratch);
            ws.c_gw.resize(m, 0.0);
            let l = composite::distortion(&ws.c_w, &ws.c_mid, &ws.c_len, &mut ws.c_gw);
            stats.distortion_sum += l as f64;
            let scale = distortion * 3.0 * loss_scale / k as f32;
            for gw in ws.c_gw.iter_mut() {
                *gw *= scale;
            }
        }
        composite::backward(
            &ws.c_sigma,
            &ws.c_delta,
            &ws.c_v,
            &g,
            g_t,
            &ws.c_gw,
            &mut ws.c_dsigma,
            &mut ws.c_dv,
            &mut ws.c_scratch,
        );
        for (j, &k) in ws.ray_samples[ri].iter().enumerate() {
            let k = k as usize;
            let o = &ws.out[k * OUT..(k + 1) * OUT];
            let v = &ws.c_v[j];
            activate_backward(o, ws.c_sigma[j], &v[..7], ws.c_dsigma[j], &ws.c_dv[j][..7], &mut ws.d_out[k * OUT..(k + 1) * OUT]);
        }
    }
    stats.ns[3] += lap(&mut clock);
    if n > 0 && backward == Backward::OutputLayer {
        ws.d_hid.resize(n * h, 0.0);
        field.decode_backward_output(n, &ws.feat[..n * inp], &ws.hid[..n * h], &ws.d_out, &mut ws.d_hid, &mut ws.grad);
        stats.ns[4] += lap(&mut clock);
    } else if n > 0 {
        ws.d_hid.resize(n * h, 0.0);
        ws.d_feat.resize(n * inp, 0.0);
        field.decode_backward(n, &ws.feat[..n * inp], &ws.hid[..n * h], &ws.d_out, &mut ws.d_hid, &mut ws.d_feat, &mut ws.grad);
        stats.ns[4] += lap(&mut clock);
        let nh = field.hits_per_point();
        const AHEAD: usize = 4;
        for k in 0..n {
            if k + AHEAD < n {
                let ahead = &ws.hits[(k + AHEAD) * nh..(k + AHEAD + 1) * nh];
                prefetch_grad(ahead, &ws.grad);
                if field.layout.deform.is_some() {
                    // the backward through a deformation reads the planes' corners again
                    prefetch_grad(ahead, &field.params);
                }
            }
            let (hits, d_feat) = (&ws.hits[k * nh..(k + 1) * nh], &ws.d_feat[k * inp..(k + 1) * inp]);
            match &field.layout.deform {
                None => field.encode_backward_recorded(hits, d_feat, &mut ws.grad, &mut ws.touched),
                Some(d) => {
                    // through the canonical point back to the motion that put it there
                    let d_g = field.encode_backward_recorded_dg(hits, d_feat, &mut ws.grad, &mut ws.touched, &ws.warped[k]);
                    d.warp_backward(&field.params, &ws.samples[k].g, ws.sample_time[k], &d_g, &mut ws.grad);
                }
            }
        }
        stats.ns[5] += lap(&mut clock);
    }
    stats
}

/// Decode the field at many grid points, in batches of 1024; `f(k, raw_outputs)` sees each
/// point's raw decoder outputs (OUT values). A deformed field is read at its warped points
/// ([`Field::warp`]), so occupancy and the baker see the field that renders.
fn decode_points(field: &Field, points: &[[f32; 3]], times: &[f32], ws: &mut Workspace, mut f: impl FnMut(usize, &[f32])) {
    let (inp, h) = (field.layout.input, field.layout.hid_width());
    const B: usize = 1024;
    for (bi, chunk) in points.chunks(B).enumerate() {
        let n = chunk.len();
        ws.feat.resize(n * inp, 0.0);
        ws.hid.resize(n * h, 0.0);
        ws.out.resize(n * OUT, 0.0);
        for (k, g) in chunk.iter().enumerate() {
            let t = times[bi * B + k];
            field.encode(&field.warp(g, t), t, &mut ws.feat[k * inp..(k + 1) * inp]);
        }
        field.decode_forward(n, &ws.feat[..n * inp], &mut ws.hid[..n * h], &mut ws.out[..n * OUT]);
        for k in 0..n {
            f(bi * B + k, &ws.out[k * OUT..(k + 1) * OUT]);
        }
    }
}

/// σ at many grid points (occupancy refresh): forward only, in batches.
pub fn density_batch(field: &Field, points: &[[f32; 3]], times: &[f32], ws: &mut Workspace, out: &mut [f32]) {
    decode_points(field, points, times, ws, |i, o| out[i] = activate(o).0);
}

/// Everything the baker stores, at many grid points: the density logit (clamped to the
/// field's range, so σ = exp(logit)) and the 7 activated values (diffuse rgb, 4 features).
pub fn values_batch(field: &Field, points: &[[f32; 3]], times: &[f32], ws: &mut Workspace, out: &mut [[f32; 8]]) {
    decode_points(field, points, times, ws, |i, o| {
        let (_, v) = activate(o);
        out[i][0] = o[0].clamp(crate::field::SIGMA_LOGIT_MIN, crate::field::SIGMA_LOGIT_MAX);
        out[i][1..].copy_from_slice(&v);
    });
}

/// Prefetch the cells (of the gradient, or of the parameters) a recorded point's backward
/// will touch.
#[inline]
fn prefetch_grad(hits: &[crate::field::PlaneHit], grad: &[f32]) {
    #[cfg(target_arch = "x86_64")]
    for h in hits {
        let base = h.idx as usize;
        for off in [base, base + h.row as usize] {
            if off < grad.len() {
                // SAFETY: prefetch of an in-bounds address; it has no architectural effect.
                unsafe {
                    std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                        grad.as_ptr().add(off) as *const i8,
                    )
                };
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (hits, grad);
}

/// One workspace per rayon worker thread; a task locks the one of the thread it runs on,
/// so locks are never contended and gradient buffers are per thread. (A caller outside the
/// pool shares slot 0: correct, merely serialized.)
pub struct WorkspacePool {
    pub slots: Vec<std::sync::Mutex<Workspace>>,
}

impl WorkspacePool {
    pub fn new(grad_len: usize) -> WorkspacePool {
        let n = rayon::current_num_threads().max(1);
        let slots = (0..n)
            .map(|_| std::sync::Mutex::new(Workspace::new(grad_len)))
            .collect();
        WorkspacePool { slots }
    }

    /// Workspace `i` (of [`WorkspacePool::len`]): for work whose sums must not depend on
    /// which thread ran what (training's gradients). Callers give each parallel task its own
    /// index, so these locks are not contended either.
    pub fn with_slot<R>(&self, i: usize, f: impl FnOnce(&mut Workspace) -> R) -> R {
        let mut ws = self.slots[i].lock().unwrap_or_else(|e| e.into_inner());
        f(&mut ws)
    }

    /// Number of workspaces (the rayon threads when the pool was made).
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// Whether the pool has no workspace (never: `new` makes at least one).
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// The calling thread's workspace.
    pub fn with<R>(&self, f: impl FnOnce(&mut Workspace) -> R) -> R {
        let i = rayon::current_thread_index().unwrap_or(0).min(self.slots.len() - 1);
        let mut ws = self.slots[i].lock().unwrap_or_else(|e| e.into_inner());
        f(&mut ws)
    }

    /// Every thread's gradient buffer and touched-cell flags.
    pub fn grads(&mut self) -> (Vec<&mut Vec<f32>>, Vec<&mut Vec<u8>>) {
        self.slots
            .iter_mut()
            .map(|m| {
                let ws = m.get_mut().unwrap_or_else(|e| e.into_inner());
                (&mut ws.grad, &mut ws.touched)
            })
            .unzip()
    }
}
