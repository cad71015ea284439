//! The radiance field: multi-scale factorized feature planes (K-Planes style) and a small
//! decoder MLP to the deferred, bakeable outputs of SNeRG — density σ, diffuse RGB and a
//! 4-channel specular feature per point. View dependence is *not* here: it lives in the
//! per-ray [`crate::view_mlp`], which runs once per ray on the composited outputs.
//!
//! Encoding at grid point g ∈ [-1,1]³ (and time τ ∈ [0,1] for dynamic fields):
//!   feature_l = Π_p bilerp(plane_{l,p}, (g_a, g_b))      (Hadamard product over planes)
//! with planes xy, xz, yz (+ xt, yt, zt when the scene is dynamic: static scenes carry no
//! time planes at all). Levels are concatenated: L levels x C channels. Planes are stored
//! channel-last so one bilinear corner is one contiguous run of C = 8 floats (one AVX lane set).
//!
//! Decoder: h = relu(W1 f + b1), o = W2 h + b2, then σ = exp(o0) (truncated), rgb and features
//! = sigmoid(o1..7). The decoder runs on whole batches of samples with `matrixmultiply`.
//!
//! A dynamic field may also carry a [`crate::deform`]ation (off unless asked for): the planes
//! are then read at the deformed point g + offset(g, τ), so the spatial planes hold a
//! canonical shape; [`Field::warp`] is the one place that applies it, for training,
//! rendering and baking alike.
//!
//! All parameters (planes, decoder, view MLP, deformation) live in one flat `Vec<f32>` so the
//! optimizer, checkpoints and per-thread gradient buffers are single contiguous arrays.

use serde::{Deserialize, Serialize};

// `field::Rng` is where the generator lived before it had a module of its own; users still
// name it here.
pub use crate::rng::Rng;
use crate::deform::{Deform, DeformConfig};
use crate::view_mlp::ViewLayout;

/// Channels per plane and level.
pub const C: usize = 8;
/// Decoder outputs: σ, diffuse rgb (3), specular features (4).
pub const OUT: usize = 8;
/// Plane axes: x=0, y=1, z=2, t=3. Static fields use the first three.
pub const PLANE_AXES: [(usize, usize); 6] = [(0, 1), (0, 2), (1, 2), (0, 3), (1, 3), (2, 3)];
/// Pre-activation clamp for σ = exp(o): beyond it σ saturates and its gradient is 0.
pub const SIGMA_LOGIT_MAX: f32 = 15.0;
pub const SIGMA_LOGIT_MIN: f32 = -30.0;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FieldConfig {
    /// Spatial plane resolution per level.
    pub resolutions: Vec<u32>,
    /// Time resolution per level; empty for a static field (no time planes are allocated).
    pub time_resolutions: Vec<u32>,
    /// Decoder hidden width (multiple of 4).
    pub hidden: usize,
    /// A deformation (canonical field + motion) of a dynamic field; absent: none, and in runs
    /// from before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deform: Option<DeformConfig>,
    /// A hidden layer of the colour outputs' own (`ColourHead`): a style layer learns colour
    /// through it while the density's hidden layer and the planes stay frozen. Absent in
    /// realistic runs and in runs from before it existed.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub colour_head: bool,
}

impl FieldConfig {
    pub fn levels(&self) -> usize {
        self.resolutions.len()
    }
    pub fn dynamic(&self) -> bool {
        !self.time_resolutions.is_empty()
    }
    pub fn planes(&self) -> usize {
        if self.dynamic() {
            6
        } else {
            3
        }
    }
    pub fn input_dim(&self) -> usize {
        self.levels() * C
    }
    /// Floating-point operations per sample of this field as (forward, backward), counting a
    /// fused multiply-add as 2: what `snerf bench train` divides by to report how close the
    /// field's code runs to the machine's peak. It follows the code, so it changes with it:
    /// - encode: per level and plane, a bilinear lookup (4 corners x C FMAs) and the C
    ///   multiplies of the Hadamard product over planes;
    /// - decode: the two dense layers (input x hidden and hidden x OUT FMAs);
    /// - backward: the decoder's weight and input gradients (twice its forward), the
    ///   encoder's scatter (as its forward) and, per plane, the product rule's 3 operations a
    ///   channel.
    pub fn flops_per_sample(&self) -> (f64, f64) {
        let planes = self.planes() as f64;
        let levels = self.levels() as f64;
        let (inp, h, out) = (self.input_dim() as f64, self.hidden as f64, OUT as f64);
        let c = C as f64;
        let enc = levels * planes * (4.0 * c * 2.0 + c);
        let mut dec = 2.0 * (inp * h + h * out);
        if self.colour_head {
            dec += 2.0 * inp * h;
        }
        let mut fwd = enc + dec;
        let mut bwd = 2.0 * dec + enc + levels * planes * c * 3.0;
        if let Some(d) = &self.deform {
            // warp: 8 corners x 3K FMAs and the K coefficients; backward: twice that, and
            // per plane the 4 corners' differences for the two derivatives (2 x 4C FMAs).
            let k = d.modes as f64;
            let warp = 8.0 * 3.0 * k * 2.0 + 3.0 * k;
            fwd += warp;
            bwd += 2.0 * warp + levels * planes * (2.0 * 4.0 * c * 2.0);
        }
        (fwd, bwd)
    }
    pub fn validate(&self) -> anyhow::Result<()> {
        anyhow::ensure!(!self.resolutions.is_empty(), "field needs at least one level");
        anyhow::ensure!(
            self.resolutions.iter().all(|&r| (2..=4096).contains(&r)),
            "plane resolutions must be in 2..=4096, got {:?}",
            self.resolutions
        );
        anyhow::ensure!(
            self.time_resolutions.is_empty() || self.time_resolutions.len() == self.resolutions.len(),
            "time resolutions must be empty (static) or one per level"
        );
        anyhow::ensure!(
            self.time_resolutions.iter().all(|&r| (2..=1024).contains(&r)),
            "time resolutions must be in 2..=1024"
        );
        anyhow::ensure!(self.hidden >= 4 && self.hidden.is_multiple_of(4), "hidden width must be a multiple of 4");
        if let Some(d) = &self.deform {
            anyhow::ensure!(self.dynamic(), "a deformation needs a dynamic field (time planes)");
            d.validate()?;
        }
        Ok(())
    }
}

/// One plane's place in the parameter vector.
#[derive(Clone, Copy, Debug)]
pub struct PlaneRef {
    pub offset: usize,
    /// Resolution along the plane's first and second axis.
    pub ru: usize,
    pub rv: usize,
    pub axes: (usize, usize),
}

/// Offsets of every parameter group in the flat parameter vector.
#[derive(Clone, Debug)]
pub struct Layout {
    /// planes[level][plane]
    pub planes: Vec<Vec<PlaneRef>>,
    /// End of the plane parameters (they start at 0): the optimizer gives them their own rate.
    pub plane_end: usize,
    pub w1: usize,
    pub b1: usize,
    pub w2: usize,
    pub b2: usize,
    pub view: ViewLayout,
    /// The deformation's parameters, after the view MLP's (absent: none).
    pub deform: Option<Deform>,
    /// The colour head's hidden layer (W1c, then b1c), after everything else (absent: none),
    /// so adding one to a trained field moves no other parameter.
    pub colour: Option<ColourHead>,
    pub total: usize,
    pub input: usize,
    pub hidden: usize,
}

impl Layout {
    pub fn new(cfg: &FieldConfig) -> Layout {
        let mut off = 0;
        let mut planes = Vec::new();
        for l in 0..cfg.levels() {
            let r = cfg.resolutions[l] as usize;
            let mut level = Vec::new();
            for &axes in PLANE_AXES.iter().take(cfg.planes()) {
                let rv = if axes.1 == 3 { cfg.time_resolutions[l] as usize } else { r };
                level.push(PlaneRef { offset: off, ru: r, rv, axes });
                off += r * rv * C;
            }
            planes.push(level);
        }
        let plane_end = off;
        let input = cfg.input_dim();
        let hidden = cfg.hidden;
        let w1 = off;
        off += hidden * input;
        let b1 = off;
        off += hidden;
        let w2 = off;
        off += OUT * hidden;
        let b2 = off;
        off += OUT;
        let view = ViewLayout::new(off);
        off = view.end;
        let deform = cfg.deform.as_ref().map(|d| Deform::new(d, off));
        if let Some(d) = &deform {
            off = d.end;
        }
        let colour = cfg.colour_head.then(|| {
            let head = ColourHead { w1: off, b1: off + hidden * input };
            off = head.b1 + hidden;
            head
        });
        Layout { planes, plane_end, w1, b1, w2, b2, view, deform, colour, total: off, input, hidden }
    }

    /// Hidden values a sample keeps between the decoder's forward and backward passes: the
    /// shared layer's, then the colour head's (if any).
    pub fn hid_width(&self) -> usize {
        if self.colour.is_some() {
            2 * self.hidden
        } else {
            self.hidden
        }
    }
}

/// Where a colour head's parameters sit. With it, the decoder is
///   h = relu(W1 f + b1),  h_c = relu(W1c f + b1c),
///   σ-logit = W2[0] · h + b2[0],  colour outputs = W2[1..] h_c + b2[1..],
/// so the colour is a function of the frozen plane features as rich as the density's, while
/// nothing the density reads changes. It starts as a copy of (W1, b1): the field's outputs
/// are unchanged until it learns.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ColourHead {
    pub w1: usize,
    pub b1: usize,
}

// The lookups of the planes and of the deformation's grid clamp the same way.
use crate::deform::corner;

#[inline(always)]
fn plane_coord(g: &[f32; 3], t: f32, axis: usize, res: usize) -> (usize, f32) {
    if axis == 3 {
        corner(t * (res - 1) as f32, res)
    } else {
        corner((g[axis] + 1.0) * 0.5 * (res - 1) as f32, res)
    }
}

/// Bilinear lookup of one plane: returns the C-vector and the four corner (index, weight) pairs.
#[inline(always)]
fn bilerp(params: &[f32], p: &PlaneRef, g: &[f32; 3], t: f32) -> ([f32; C], [usize; 4], [f32; 4]) {
    let (iu, fu) = plane_coord(g, t, p.axes.0, p.ru);
    let (iv, fv) = plane_coord(g, t, p.axes.1, p.rv);
    let base = p.offset + (iv * p.ru + iu) * C;
    let idx = [base, base + C, base + p.ru * C, base + p.ru * C + C];
    let wts = [(1.0 - fu) * (1.0 - fv), fu * (1.0 - fv), (1.0 - fu) * fv, fu * fv];
    let mut out = [0.0f32; C];
    for k in 0..4 {
        let v = &params[idx[k]..idx[k] + C];
        for c in 0..C {
            out[c] += wts[k] * v[c];
        }
    }
    (out, idx, wts)
}

/// One recorded plane lookup: lower corner index, row stride to the next corner row,
/// bilinear weights of the 4 corners and the interpolated value.
#[derive(Clone, Copy, Debug, Default)]
pub struct PlaneHit {
    pub idx: u32,
    pub row: u32,
    pub wts: [f32; 4],
    pub val: [f32; C],
}

#[derive(Clone, Debug)]
pub struct Field {
    pub cfg: FieldConfig,
    pub layout: Layout,
    pub params: Vec<f32>,
}

impl Field {
    pub fn new(cfg: FieldConfig, seed: u64) -> anyhow::Result<Field> {
        cfg.validate()?;
        let layout = Layout::new(&cfg);
        let mut params = vec![0.0f32; layout.total];
        let mut rng = Rng::new(seed);
        // Spatial planes start in [0.1, 0.5] (products of three stay small and positive);
        // time planes start at 1 so a dynamic field begins as its static counterpart.
        for level in &layout.planes {
            for p in level {
                let n = p.ru * p.rv * C;
                let dst = &mut params[p.offset..p.offset + n];
                if p.axes.1 == 3 {
                    dst.fill(1.0);
                } else {
                    for x in dst.iter_mut() {
                        *x = 0.1 + 0.4 * rng.uniform();
                    }
                }
            }
        }
        let (inp, hid) = (layout.input, layout.hidden);
        let s1 = (6.0 / inp as f32).sqrt();
        for x in &mut params[layout.w1..layout.w1 + hid * inp] {
            *x = s1 * (2.0 * rng.uniform() - 1.0);
        }
        let s2 = (3.0 / hid as f32).sqrt();
        for x in &mut params[layout.w2..layout.w2 + OUT * hid] {
            *x = s2 * (2.0 * rng.uniform() - 1.0);
        }
        layout.view.init(&mut params, &mut rng);
        if let Some(d) = &layout.deform {
            d.init(&mut params, &mut rng);
        }
        Ok(Field { cfg, layout, params })
    }

    /// Where point g at time τ is read in the planes: g itself, or with a deformation its
    /// canonical point g + offset(g, τ). Every evaluation of the field at (g, τ) goes through
    /// here (training, rendering, occupancy, baking).
    #[inline]
    pub fn warp(&self, g: &[f32; 3], t: f32) -> [f32; 3] {
        match &self.layout.deform {
            Some(d) => d.warp(&self.params, g, t),
            None => *g,
        }
    }

    /// Prefetch the plane cells a point will read. Plane lookups are cache misses by nature
    /// (random rays over megabytes of planes); issuing a point's misses ahead of its math
    /// lets them overlap.
    #[inline]
    pub fn prefetch(&self, g: &[f32; 3], t: f32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            for level in &self.layout.planes {
                for p in level {
                    let (iu, _) = plane_coord(g, t, p.axes.0, p.ru);
                    let (iv, _) = plane_coord(g, t, p.axes.1, p.rv);
                    let base = p.offset + (iv * p.ru + iu) * C;
                    for off in [base, base + C, base + p.ru * C, base + p.ru * C + C] {
                        if off < self.params.len() {
                            // SAFETY: `off` is in bounds (checked), so `add` stays inside the
                            // allocation; a prefetch has no architectural effect.
                            unsafe { _mm_prefetch::<_MM_HINT_T0>(self.params.as_ptr().add(off) as *const i8) };
                        }
                    }
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = (g, t);
    }

    /// Encode one point: writes `input_dim` features into `out`.
    #[inline]
    pub fn encode(&self, g: &[f32; 3], t: f32, out: &mut [f32]) {
        for (l, level) in self.layout.planes.iter().enumerate() {
            let mut acc = [1.0f32; C];
            for p in level {
                let (v, _, _) = bilerp(&self.params, p, g, t);
                for c in 0..C {
                    acc[c] *= v[c];
                }
            }
            out[l * C..(l + 1) * C].copy_from_slice(&acc);
        }
    }

    /// Number of plane lookups per point (levels x planes): the length of one point's
    /// [`PlaneHit`] record.
    pub fn hits_per_point(&self) -> usize {
        self.cfg.levels() * self.cfg.planes()
    }

    /// [`encode`] that also records each plane lookup (corners, weights, value), so the
    /// backward pass scatters gradients without reading the planes again: the planes are
    /// megabytes and every lookup is a cache miss, the record is read back sequentially.
    #[inline]
    pub fn encode_recorded(&self, g: &[f32; 3], t: f32, out: &mut [f32], hits: &mut [PlaneHit]) {
        let mut h = 0;
        for (l, level) in self.layout.planes.iter().enumerate() {
            let mut acc = [1.0f32; C];
            for p in level {
                let (v, idx, wts) = bilerp(&self.params, p, g, t);
                for c in 0..C {
                    acc[c] *= v[c];
                }
                hits[h] = PlaneHit { idx: idx[0] as u32, row: (idx[2] - idx[0]) as u32, wts, val: v };
                h += 1;
            }
            out[l * C..(l + 1) * C].copy_from_slice(&acc);
        }
    }

    /// Backward of [`encode`]: scatters dL/d(features) into the plane gradients;
    /// `touched[cell]` is set for every plane cell (C floats) that receives gradient.
    pub fn encode_backward(&self, g: &[f32; 3], t: f32, d_feat: &[f32], grad: &mut [f32], touched: &mut [u8]) {
        let mut hits = [PlaneHit::default(); 6 * 16];
        let n = self.hits_per_point();
        let mut feat = vec![0.0; self.layout.input];
        self.encode_recorded(g, t, &mut feat, &mut hits[..n]);
        self.encode_backward_recorded(&hits[..n], d_feat, grad, touched);
    }

    /// Backward of [`encode_recorded`] from its record.
    #[inline]
    pub fn encode_backward_recorded(&self, hits: &[PlaneHit], d_feat: &[f32], grad: &mut [f32], touched: &mut [u8]) {
        self.encode_backward_inner::<false>(hits, d_feat, grad, touched, &[0.0; 3]);
    }

    /// [`Field::encode_backward_recorded`] that also returns dL/dg, the gradient with respect
    /// to the point `g` the record was made at (what a deformation needs): the spatial
    /// planes' bilinear derivatives, 0 along an axis where g lies outside [-1,1] (the lookup
    /// clamps to the border there).
    #[inline]
    pub fn encode_backward_recorded_dg(&self, hits: &[PlaneHit], d_feat: &[f32], grad: &mut [f32], touched: &mut [u8], g: &[f32; 3]) -> [f32; 3] {
        self.encode_backward_inner::<true>(hits, d_feat, grad, touched, g)
    }

    #[inline(always)]
    fn encode_backward_inner<const DG: bool>(&self, hits: &[PlaneHit], d_feat: &[f32], grad: &mut [f32], touched: &mut [u8], g: &[f32; 3]) -> [f32; 3] {
        // dL/dg per axis and channel, summed over channels once at the end (vector work)
        let mut d_gc = [[0.0f32; C]; 3];
        let np = self.cfg.planes();
        for (l, level_hits) in hits.chunks_exact(np).enumerate() {
            let df = &d_feat[l * C..(l + 1) * C];
            // d plane_k = df ⊙ Π_{q≠k} val_q, via prefix and suffix products.
            let mut prefix = [1.0f32; C];
            let mut suffix = [[1.0f32; C]; 7];
            for k in (0..np).rev() {
                for c in 0..C {
                    suffix[k][c] = suffix[k + 1][c] * level_hits[k].val[c];
                }
            }
            for (k, hit) in level_hits.iter().enumerate() {
                let mut d = [0.0f32; C];
                for c in 0..C {
                    d[c] = df[c] * prefix[c] * suffix[k + 1][c];
                    prefix[c] *= hit.val[c];
                }
                let base = hit.idx as usize;
                let row = hit.row as usize;
                if DG {
                    // val = Σ w_j v_j with w from (fu, fv); its derivatives along u and v, and
                    // u = (g_a + 1) / 2 (res - 1) on a spatial axis (a time plane's v is τ)
                    let p = &self.layout.planes[l][k];
                    let (fu, fv) = (hit.wts[1] + hit.wts[3], hit.wts[2] + hit.wts[3]);
                    let v0 = &self.params[base..base + C];
                    let v1 = &self.params[base + C..base + 2 * C];
                    let v2 = &self.params[base + row..base + row + C];
                    let v3 = &self.params[base + row + C..base + row + 2 * C];
                    let (a, b) = p.axes;
                    let su = 0.5 * (p.ru - 1) as f32;
                    for c in 0..C {
                        d_gc[a][c] += su * d[c] * ((1.0 - fv) * (v1[c] - v0[c]) + fv * (v3[c] - v2[c]));
                    }
                    if b != 3 {
                        let sv = 0.5 * (p.rv - 1) as f32;
                        for c in 0..C {
                            d_gc[b][c] += sv * d[c] * ((1.0 - fu) * (v2[c] - v0[c]) + fu * (v3[c] - v1[c]));
                        }
                    }
                }
                for (j, off) in [0, C, row, row + C].into_iter().enumerate() {
                    let w = hit.wts[j];
                    touched[(base + off) / C] = 1;
                    let dst = &mut grad[base + off..base + off + C];
                    for c in 0..C {
                        dst[c] += w * d[c];
                    }
                }
            }
        }
        // outside [-1,1] along an axis the lookup holds the border: no gradient there
        [0, 1, 2].map(|a| if DG && g[a].abs() < 1.0 { d_gc[a].iter().sum() } else { 0.0 })
    }

    /// Total-variation regularizer on the spatial planes (as in K-Planes): the mean squared
    /// difference between neighbouring cells, times `weight`; its gradient is added to
    /// `grad` and every cell is marked in `touched`. Smooth planes generalize to novel views
    /// instead of memorizing the training views. Returns the loss.
    ///
    /// (Regularizing only the cells a step touched keeps Adam lazy, but measured 0.3 dB
    /// worse on 2CylinderEngine at 2000 steps and no faster end to end, so it is not done.)
    pub fn tv_backward(&self, weight: f32, grad: &mut [f32], touched: &mut [u8]) -> f32 {
        use rayon::prelude::*;
        let mut loss = 0.0f64;
        for level in &self.layout.planes {
            for p in level.iter().filter(|p| p.axes.1 != 3) {
                let (ru, rv) = (p.ru, p.rv);
                let w = weight / (((ru - 1) * rv + ru * (rv - 1)) * C) as f32;
                let plane = &self.params[p.offset..p.offset + ru * rv * C];
                let cell = |u: usize, v: usize| -> &[f32] { &plane[(v * ru + u) * C..(v * ru + u + 1) * C] };
                // Each cell's gradient depends only on its 4 neighbours, so rows are
                // independent: one parallel task per row, each writing only its own row.
                loss += grad[p.offset..p.offset + ru * rv * C]
                    .par_chunks_mut(ru * C)
                    .enumerate()
                    .map(|(v, g_row)| {
                        let mut row_loss = 0.0f32;
                        for u in 0..ru {
                            let x = cell(u, v);
                            let mut g = [0.0f32; C];
                            let mut diff = |other: &[f32], counts: bool| {
                                for c in 0..C {
                                    let d = x[c] - other[c];
                                    g[c] += d;
                                    if counts {
                                        row_loss += d * d;
                                    }
                                }
                            };
                            // right and down pairs carry the loss; left and up only gradient
                            if u + 1 < ru {
                                diff(cell(u + 1, v), true);
                            }
                            if v + 1 < rv {
                                diff(cell(u, v + 1), true);
                            }
                            if u > 0 {
                                diff(cell(u - 1, v), false);
                            }
                            if v > 0 {
                                diff(cell(u, v - 1), false);
                            }
                            let dst = &mut g_row[u * C..(u + 1) * C];
                            for c in 0..C {
                                dst[c] += 2.0 * w * g[c];
                            }
                        }
                        (w * row_loss) as f64
                    })
                    .sum::<f64>();
                touched[p.offset / C..p.offset / C + ru * rv].fill(1);
            }
        }
        loss as f32
    }

    /// K-Planes' two priors on the time planes (xt, yt, zt), as in that paper: temporal
    /// smoothness, the mean squared second difference along t (`smooth`: motion is
    /// continuous, so a time cell seen by few cameras borrows from its neighbours instead of
    /// fitting those cameras alone), and sparse transients, the mean |1 − value| (`sparse`:
    /// time planes start at 1, the static field, and move only where the scene changes).
    /// Each plane's means are weighted and summed over planes and levels; the gradient is
    /// added to `grad`, every time-plane cell is marked in `touched`. Returns the loss.
    pub fn time_priors_backward(&self, smooth: f32, sparse: f32, grad: &mut [f32], touched: &mut [u8]) -> f32 {
        let mut loss = 0.0f64;
        for level in &self.layout.planes {
            for p in level.iter().filter(|p| p.axes.1 == 3) {
                let (ru, rv) = (p.ru, p.rv);
                let n = ru * rv * C;
                let plane = &self.params[p.offset..p.offset + n];
                let g = &mut grad[p.offset..p.offset + n];
                if sparse > 0.0 {
                    let w = sparse / n as f32;
                    for (gi, &x) in g.iter_mut().zip(plane) {
                        let d = x - 1.0;
                        loss += (w * d.abs()) as f64;
                        // subgradient 0 at 1: an untouched time plane stays where it started
                        *gi += if d > 0.0 { w } else if d < 0.0 { -w } else { 0.0 };
                    }
                }
                if smooth > 0.0 && rv >= 3 {
                    let w = smooth / (ru * (rv - 2) * C) as f32;
                    // cell (u, v) at (v * ru + u) * C: v is the time index
                    for v in 1..rv - 1 {
                        for k in 0..ru * C {
                            let (a, b, c) = ((v - 1) * ru * C + k, v * ru * C + k, (v + 1) * ru * C + k);
                            let s = plane[a] - 2.0 * plane[b] + plane[c];
                            loss += (w * s * s) as f64;
                            g[a] += 2.0 * w * s;
                            g[b] -= 4.0 * w * s;
                            g[c] += 2.0 * w * s;
                        }
                    }
                }
                touched[p.offset / C..p.offset / C + ru * rv].fill(1);
            }
        }
        loss as f32
    }

    /// Decoder forward on `n` samples: `feat` is n x input (row per sample); writes the
    /// post-ReLU hidden values `hid` (n x `Layout::hid_width`: the shared layer, then the
    /// colour head's) and the raw outputs `out` (n x OUT).
    pub fn decode_forward(&self, n: usize, feat: &[f32], hid: &mut [f32], out: &mut [f32]) {
        let l = &self.layout;
        let (inp, h, hw) = (l.input, l.hidden, l.hid_width());
        let p = &self.params;
        let mut layer = |w1: usize, b1: usize, col: usize| {
            for r in 0..n {
                hid[r * hw + col..r * hw + col + h].copy_from_slice(&p[b1..b1 + h]);
            }
            // hid (n x h) += feat (n x inp) * W1^T (inp x h); W1 is stored h x inp.
            gemm(1.0, Mat(feat, n, inp, inp, 1), Mat(&p[w1..w1 + h * inp], inp, h, 1, inp), 1.0, &mut hid[col..], (hw, 1));
            for r in 0..n {
                for x in &mut hid[r * hw + col..r * hw + col + h] {
                    *x = x.max(0.0);
                }
            }
        };
        layer(l.w1, l.b1, 0);
        if let Some(c) = l.colour {
            layer(c.w1, c.b1, h);
        }
        let b2 = &p[l.b2..l.b2 + OUT];
        for r in 0..n {
            out[r * OUT..(r + 1) * OUT].copy_from_slice(b2);
        }
        let w2 = &p[l.w2..l.b2];
        match l.colour {
            None => gemm(1.0, Mat(hid, n, h, hw, 1), Mat(w2, h, OUT, 1, h), 1.0, out, (OUT, 1)),
            Some(_) => {
                // σ from the shared layer, the colour outputs from the colour head's
                gemm(1.0, Mat(hid, n, h, hw, 1), Mat(w2, h, 1, 1, h), 1.0, out, (OUT, 1));
                gemm(1.0, Mat(&hid[h..], n, h, hw, 1), Mat(&w2[h..], h, OUT - 1, 1, h), 1.0, &mut out[1..], (OUT, 1));
            }
        }
    }

    /// dW2 and db2 (the output layer) from the hidden values each output row reads.
    fn output_layer_grad(&self, n: usize, hid: &[f32], d_out: &[f32], grad: &mut [f32]) {
        let l = &self.layout;
        let (h, hw) = (l.hidden, l.hid_width());
        match l.colour {
            // dW2 (OUT x h) += d_out^T (OUT x n) * hid (n x h)
            None => gemm(1.0, Mat(d_out, OUT, n, 1, OUT), Mat(hid, n, h, hw, 1), 1.0, &mut grad[l.w2..l.b2], (h, 1)),
            Some(_) => {
                gemm(1.0, Mat(d_out, 1, n, 1, OUT), Mat(hid, n, h, hw, 1), 1.0, &mut grad[l.w2..l.w2 + h], (h, 1));
                gemm(1.0, Mat(&d_out[1..], OUT - 1, n, 1, OUT), Mat(&hid[h..], n, h, hw, 1), 1.0, &mut grad[l.w2 + h..l.b2], (h, 1));
            }
        }
        for r in 0..n {
            for k in 0..OUT {
                grad[l.b2 + k] += d_out[r * OUT + k];
            }
        }
    }

    /// dL/d(hidden values) (n x hid_width, into `d_hid`), masked by their ReLU: the shared
    /// layer's from every output row (only σ's with a colour head), the colour head's from
    /// the colour rows.
    fn hidden_grad(&self, n: usize, hid: &[f32], d_out: &[f32], d_hid: &mut [f32]) {
        let l = &self.layout;
        let (h, hw) = (l.hidden, l.hid_width());
        let w2 = &self.params[l.w2..l.b2];
        match l.colour {
            // d_hid (n x h) = d_out (n x OUT) * W2 (OUT x h)
            None => gemm(1.0, Mat(d_out, n, OUT, OUT, 1), Mat(w2, OUT, h, h, 1), 0.0, d_hid, (hw, 1)),
            Some(_) => {
                gemm(1.0, Mat(d_out, n, 1, OUT, 1), Mat(w2, 1, h, h, 1), 0.0, d_hid, (hw, 1));
                gemm(1.0, Mat(&d_out[1..], n, OUT - 1, OUT, 1), Mat(&w2[h..], OUT - 1, h, h, 1), 0.0, &mut d_hid[h..], (hw, 1));
            }
        }
        for (d, &x) in d_hid[..n * hw].iter_mut().zip(&hid[..n * hw]) {
            if x <= 0.0 {
                *d = 0.0;
            }
        }
    }

    /// dW1 and db1 of the hidden layer whose values are column `col` of `d_hid`.
    fn hidden_layer_grad(&self, n: usize, feat: &[f32], d_hid: &[f32], col: usize, (w1, b1): (usize, usize), grad: &mut [f32]) {
        let l = &self.layout;
        let (inp, h, hw) = (l.input, l.hidden, l.hid_width());
        // dW1 (h x inp) += d_hid^T (h x n) * feat (n x inp)
        gemm(1.0, Mat(&d_hid[col..], h, n, 1, hw), Mat(feat, n, inp, inp, 1), 1.0, &mut grad[w1..w1 + h * inp], (inp, 1));
        for r in 0..n {
            for j in 0..h {
                grad[b1 + j] += d_hid[r * hw + col + j];
            }
        }
    }

    /// The backward pass of what learns while the geometry is frozen: the output layer
    /// (dW2, db2) and, when the field has one, the colour head (dW1c, db1c). `d_hid` is
    /// scratch (n x hid_width).
    pub fn decode_backward_output(&self, n: usize, feat: &[f32], hid: &[f32], d_out: &[f32], d_hid: &mut [f32], grad: &mut [f32]) {
        self.output_layer_grad(n, hid, d_out, grad);
        if let Some(c) = self.layout.colour {
            self.hidden_grad(n, hid, d_out, d_hid);
            self.hidden_layer_grad(n, feat, d_hid, self.layout.hidden, (c.w1, c.b1), grad);
        }
    }

    /// Decoder backward on `n` samples. `d_out` (n x OUT) is dL/d(raw outputs); `d_hid` is
    /// scratch (n x hid_width); accumulates weight gradients into `grad` and writes
    /// dL/d(features) into `d_feat` (n x input).
    #[allow(clippy::too_many_arguments)]
    pub fn decode_backward(
        &self,
        n: usize,
        feat: &[f32],
        hid: &[f32],
        d_out: &[f32],
        d_hid: &mut [f32],
        d_feat: &mut [f32],
        grad: &mut [f32],
    ) {
        let l = &self.layout;
        let (inp, h, hw) = (l.input, l.hidden, l.hid_width());
        let p = &self.params;
        self.output_layer_grad(n, hid, d_out, grad);
        self.hidden_grad(n, hid, d_out, d_hid);
        self.hidden_layer_grad(n, feat, d_hid, 0, (l.w1, l.b1), grad);
        // d_feat (n x inp) = d_hid (n x h) * W1 (h x inp), plus the colour head's
        gemm(1.0, Mat(d_hid, n, h, hw, 1), Mat(&p[l.w1..l.b1], h, inp, inp, 1), 0.0, d_feat, (inp, 1));
        if let Some(c) = l.colour {
            self.hidden_layer_grad(n, feat, d_hid, h, (c.w1, c.b1), grad);
            gemm(1.0, Mat(&d_hid[h..], n, h, hw, 1), Mat(&p[c.w1..c.b1], h, inp, inp, 1), 1.0, d_feat, (inp, 1));
        }
    }

    /// This field with a colour head (`ColourHead`) started as a copy of its shared hidden
    /// layer, so it renders exactly as before; itself when it has one already.
    pub fn with_colour_head(&self) -> anyhow::Result<Field> {
        if self.layout.colour.is_some() {
            return Ok(self.clone());
        }
        let cfg = FieldConfig { colour_head: true, ..self.cfg.clone() };
        let layout = Layout::new(&cfg);
        let mut params = self.params.clone();
        let c = layout.colour.expect("a colour head was asked for");
        debug_assert_eq!(params.len(), c.w1);
        params.extend_from_slice(&self.params[self.layout.w1..self.layout.b1 + self.layout.hidden]);
        anyhow::ensure!(params.len() == layout.total, "colour head layout: {} parameters for {}", params.len(), layout.total);
        Ok(Field { cfg, layout, params })
    }
}

/// A strided matrix view for [`gemm`]: data, rows, columns, row stride, column stride.
struct Mat<'a>(&'a [f32], usize, usize, usize, usize);

/// c (m x n) = alpha * a (m x k) * b (k x n) + beta * c, all strided, via `matrixmultiply`.
/// Checks every extent against its slice first, so the one `unsafe` call cannot read or
/// write out of bounds.
fn gemm(alpha: f32, a: Mat, b: Mat, beta: f32, c: &mut [f32], (rsc, csc): (usize, usize)) {
    let (m, k, n) = (a.1, a.2, b.2);
    assert_eq!(b.1, k, "inner dimensions differ");
    let last = |rows: usize, cols: usize, rs: usize, cs: usize| {
        if rows == 0 || cols == 0 {
            0
        } else {
            (rows - 1) * rs + (cols - 1) * cs + 1
        }
    };
    assert!(last(m, k, a.3, a.4) <= a.0.len() && last(k, n, b.3, b.4) <= b.0.len());
    assert!(last(m, n, rsc, csc) <= c.len());
    // SAFETY: extents checked above; a, b and c are distinct borrows.
    unsafe {
        matrixmultiply::sgemm(
            m, k, n, alpha,
            a.0.as_ptr(), a.3 as isize, a.4 as isize,
            b.0.as_ptr(), b.3 as isize, b.4 as isize,
            beta, c.as_mut_ptr(), rsc as isize, csc as isize,
        );
    }
}

/// Raw decoder outputs to (σ, [rgb, features]).
#[inline]
pub fn activate(o: &[f32]) -> (f32, [f32; 7]) {
    let sigma = o[0].clamp(SIGMA_LOGIT_MIN, SIGMA_LOGIT_MAX).exp();
    let mut v = [0.0f32; 7];
    for c in 0..7 {
        v[c] = sigmoid(o[c + 1]);
    }
    (sigma, v)
}

/// Backward of [`activate`]: given σ, the activated values and their gradients, writes
/// dL/d(raw outputs).
#[inline]
pub fn activate_backward(o: &[f32], sigma: f32, v: &[f32], d_sigma: f32, d_v: &[f32], d_o: &mut [f32]) {
    d_o[0] = if o[0] > SIGMA_LOGIT_MIN && o[0] < SIGMA_LOGIT_MAX { d_sigma * sigma } else { 0.0 };
    for c in 0..7 {
        d_o[c + 1] = d_v[c] * v[c] * (1.0 - v[c]);
    }
}

#[inline]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flops_per_sample_match_a_hand_count() {
        // Static, 2 levels, hidden 16: 6 plane lookups of 4 corners x 8 channels (FMA = 2)
        // plus 8 products each = 6 x 72 = 432; decoder (16 x 16 + 16 x 8) FMAs = 768.
        let cfg = FieldConfig { resolutions: vec![16, 32], time_resolutions: vec![], hidden: 16, deform: None, colour_head: false };
        assert_eq!(cfg.flops_per_sample(), (432.0 + 768.0, 2.0 * 768.0 + 432.0 + 6.0 * 8.0 * 3.0));
        // Dynamic, 1 level, hidden 8: 6 planes x 72 = 432; decoder (8 x 8 + 8 x 8) FMAs = 256.
        let cfg = FieldConfig { resolutions: vec![8], time_resolutions: vec![4], hidden: 8, deform: None, colour_head: false };
        assert_eq!(cfg.flops_per_sample(), (432.0 + 256.0, 2.0 * 256.0 + 432.0 + 6.0 * 8.0 * 3.0));
    }
}
