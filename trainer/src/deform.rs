//! Deformation of a dynamic field: a canonical shape and how it moves (D-NeRF, Nerfies,
//! 4D-GS). A point g of the grid at time τ is looked up in the canonical field at
//!
//!   g' = g + offset(g, τ),   offset(g, τ) = Σ_k c_k(τ) B_k(g)      (k < K modes)
//!
//! a low-rank motion basis: each mode is a 3-vector field B_k, trilinear on a coarse
//! `resolution`³ grid over the scene's box, times one coefficient c_k(τ), linear in a 1D table
//! of `time_resolution` knots over the animation.
//!
//! The principle: motion is **low-frequency in time and smooth in space**. A skinned body
//! moves as a few rigid parts blended at their joints, so its displacement field is smooth
//! over the box and varies slowly between frames. Both are built into the representation
//! rather than asked of it by a prior: a coarse grid cannot put two different motions one
//! pixel apart, and a short table cannot make a cell of the body jump between neighbouring
//! frames, so what a camera sees at one instant moves the shape at its neighbouring instants
//! too, where held-out frames lie. The rank K bounds how many independent motions the body
//! has (a handful of bones moving in concert). A per-point MLP (D-NeRF) or time planes
//! decoded by a head (4D-GS) express more, but cost a network evaluation per sample on the
//! CPU's hot path and give up the hard smoothness; this costs one trilinear lookup of a grid
//! that stays in cache (8 corners x 3K floats) and two table reads per sample. The grid of
//! per-cell basis vectors and the per-time coefficients are also exactly what a bake can ship
//! (per-block offsets from a motion basis).
//!
//! Offsets are in grid units ([-1,1] spans the box); the canonical field is the spatial
//! planes (xy, xz, yz). The time planes stay: they carry what motion cannot explain
//! (appearance changes, shapes appearing), under K-Planes' priors.
//!
//! Initialization: c = 0, so a run starts as the plain time-conditioned field (no motion).
//! The first three modes start as the unit translations along x, y and z (the same vector in
//! every cell), the others small random: a shift of the whole body is then three numbers per
//! knot from the first step, which Adam's bounded steps reach in tens of steps, where a
//! small random basis would need its coefficients to grow large first (the gradient of B is
//! c, so B learns local motion once c moves).

use serde::{Deserialize, Serialize};

use crate::rng::Rng;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DeformConfig {
    /// Basis grid resolution per axis.
    pub resolution: u32,
    /// Motion modes K.
    pub modes: u32,
    /// Knots of the coefficient table over the animation (τ ∈ [0,1]).
    pub time_resolution: u32,
}

/// Default grid resolution: 16 cells across the box (about 6 pixels a cell at 96 pixels
/// across it), coarse against the field's finest planes.
pub const DEFAULT_RESOLUTION: u32 = 16;
/// Default number of modes.
pub const DEFAULT_MODES: u32 = 8;

impl DeformConfig {
    /// The deformation for a dataset whose finest time planes have `finest_time` cells: half
    /// as many knots (each holding about twice the training views of a time cell: motion is
    /// lower-frequency than what the time planes may store), at least 4.
    pub fn for_time_resolution(finest_time: u32) -> DeformConfig {
        DeformConfig { resolution: DEFAULT_RESOLUTION, modes: DEFAULT_MODES, time_resolution: (finest_time / 2).max(4) }
    }

    pub fn validate(&self) -> anyhow::Result<()> {
        anyhow::ensure!((2..=128).contains(&self.resolution), "deformation grid resolution must be in 2..=128 (is {})", self.resolution);
        anyhow::ensure!((1..=32).contains(&self.modes), "deformation modes must be in 1..=32 (is {})", self.modes);
        anyhow::ensure!((2..=1024).contains(&self.time_resolution), "deformation time resolution must be in 2..=1024 (is {})", self.time_resolution);
        Ok(())
    }

    /// Parameters it adds: the basis grid and the coefficient table.
    pub fn params(&self) -> usize {
        let r = self.resolution as usize;
        r * r * r * self.modes as usize * 3 + self.time_resolution as usize * self.modes as usize
    }
}

/// Where the deformation lives in the field's flat parameter vector: the basis grid (cell
/// (i, j, k) at `basis + ((k * r + j) * r + i) * 3K`, mode-major 3-vectors) then the
/// coefficient table (knot j at `coeffs + j * K`).
#[derive(Clone, Copy, Debug)]
pub struct Deform {
    pub basis: usize,
    pub coeffs: usize,
    pub end: usize,
    pub res: usize,
    pub modes: usize,
    pub times: usize,
}

/// Most modes (a fixed-size scratch array holds the coefficients).
const MAX_MODES: usize = 32;

/// Continuous cell coordinate u ∈ [0, res − 1] to the lower corner index and the fraction
/// towards the next one (for the planes' lookups and this grid's). Out-of-range and NaN
/// coordinates clamp to the border.
#[inline(always)]
pub(crate) fn corner(u: f32, res: usize) -> (usize, f32) {
    let max = (res - 1) as f32;
    let u = if u >= 0.0 { u.min(max) } else { 0.0 }; // NaN lands here too
    let i = (u as usize).min(res - 2);
    (i, u - i as f32)
}

/// Trilinear corners of g ∈ [-1,1]³ on a r³ grid: 8 (flat cell index, weight); outside the
/// box the border holds.
#[inline(always)]
fn corners(g: &[f32; 3], r: usize) -> [(usize, f32); 8] {
    let mut i = [0usize; 3];
    let mut f = [0f32; 3];
    for a in 0..3 {
        (i[a], f[a]) = corner((g[a] + 1.0) * 0.5 * (r - 1) as f32, r);
    }
    let mut out = [(0usize, 0f32); 8];
    for (n, o) in out.iter_mut().enumerate() {
        let (dx, dy, dz) = (n & 1, (n >> 1) & 1, (n >> 2) & 1);
        let w = if dx == 1 { f[0] } else { 1.0 - f[0] }
            * if dy == 1 { f[1] } else { 1.0 - f[1] }
            * if dz == 1 { f[2] } else { 1.0 - f[2] };
        *o = (((i[2] + dz) * r + i[1] + dy) * r + i[0] + dx, w);
    }
    out
}

/// Linear knot of τ ∈ [0,1] in a table of n: (lower knot, fraction). Clamped.
#[inline(always)]
fn knot(t: f32, n: usize) -> (usize, f32) {
    corner(t * (n - 1) as f32, n)
}

impl Deform {
    pub fn new(cfg: &DeformConfig, offset: usize) -> Deform {
        let (res, modes, times) = (cfg.resolution as usize, cfg.modes as usize, cfg.time_resolution as usize);
        let basis = offset;
        let coeffs = basis + res * res * res * modes * 3;
        Deform { basis, coeffs, end: coeffs + times * modes, res, modes, times }
    }

    /// Start values: modes 0-2 the unit translations, the others uniform in ±0.1;
    /// coefficients 0 (no motion).
    pub fn init(&self, params: &mut [f32], rng: &mut Rng) {
        let m3 = self.modes * 3;
        for cell in params[self.basis..self.coeffs].chunks_exact_mut(m3) {
            for (j, x) in cell.iter_mut().enumerate() {
                let (k, a) = (j / 3, j % 3);
                *x = if k < 3 { if k == a { 1.0 } else { 0.0 } } else { 0.1 * (2.0 * rng.uniform() - 1.0) };
            }
        }
        params[self.coeffs..self.end].fill(0.0);
    }

    #[inline(always)]
    fn coeffs_at(&self, params: &[f32], t: f32) -> ([f32; MAX_MODES], usize, f32) {
        let (j, f) = knot(t, self.times);
        let a = &params[self.coeffs + j * self.modes..self.coeffs + (j + 1) * self.modes];
        let b = &params[self.coeffs + (j + 1) * self.modes..self.coeffs + (j + 2) * self.modes];
        let mut c = [0f32; MAX_MODES];
        for k in 0..self.modes {
            c[k] = a[k] + f * (b[k] - a[k]);
        }
        (c, j, f)
    }

    /// The basis at g: Σ_corners w B(corner), all K modes' 3-vectors (3K floats).
    #[inline(always)]
    fn basis_at(&self, params: &[f32], g: &[f32; 3]) -> [f32; 3 * MAX_MODES] {
        let m3 = self.modes * 3;
        let mut q = [0f32; 3 * MAX_MODES];
        for (cell, w) in corners(g, self.res) {
            let b = &params[self.basis + cell * m3..self.basis + (cell + 1) * m3];
            for (qj, bj) in q[..m3].iter_mut().zip(b) {
                *qj += w * bj;
            }
        }
        q
    }

    /// The deformed point g + offset(g, τ).
    #[inline]
    pub fn warp(&self, params: &[f32], g: &[f32; 3], t: f32) -> [f32; 3] {
        let (c, _, _) = self.coeffs_at(params, t);
        let q = self.basis_at(params, g);
        let mut o = *g;
        for k in 0..self.modes {
            for a in 0..3 {
                o[a] += c[k] * q[k * 3 + a];
            }
        }
        o
    }

    /// Backward of [`Deform::warp`] given dL/dg' (`d_warp`): accumulates the basis and
    /// coefficient gradients into `grad` (g itself is a sample position, not learnt).
    #[inline]
    pub fn warp_backward(&self, params: &[f32], g: &[f32; 3], t: f32, d_warp: &[f32; 3], grad: &mut [f32]) {
        let (c, j, f) = self.coeffs_at(params, t);
        let m3 = self.modes * 3;
        // dL/dB_k(corner) = w c_k d_warp: one 3K-vector s scaled per corner
        let mut s = [0f32; 3 * MAX_MODES];
        for k in 0..self.modes {
            for a in 0..3 {
                s[k * 3 + a] = c[k] * d_warp[a];
            }
        }
        for (cell, w) in corners(g, self.res) {
            let gb = &mut grad[self.basis + cell * m3..self.basis + (cell + 1) * m3];
            for (gj, sj) in gb.iter_mut().zip(&s[..m3]) {
                *gj += w * sj;
            }
        }
        // dL/dc_k = B_k(g) · d_warp
        let q = self.basis_at(params, g);
        let mut dc = [0f32; MAX_MODES];
        for k in 0..self.modes {
            dc[k] = q[k * 3] * d_warp[0] + q[k * 3 + 1] * d_warp[1] + q[k * 3 + 2] * d_warp[2];
        }
        let (lo, hi) = (self.coeffs + j * self.modes, self.coeffs + (j + 1) * self.modes);
        for k in 0..self.modes {
            grad[lo + k] += (1.0 - f) * dc[k];
            grad[hi + k] += f * dc[k];
        }
    }

    /// The learnt offset at g and τ (grid units), e.g. to compare with a known motion.
    pub fn offset(&self, params: &[f32], g: &[f32; 3], t: f32) -> [f32; 3] {
        let w = self.warp(params, g, t);
        [w[0] - g[0], w[1] - g[1], w[2] - g[2]]
    }
}
