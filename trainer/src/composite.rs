//! Volume compositing along one ray, forward and backward, in the numerically stable form.
//!
//! Per sample k: optical depth s_k = clamp(σ_k δ_k, 0, S_MAX), opacity α_k = -expm1(-s_k),
//! transmittance T_k = exp(-Σ_{j<k} s_j) (a running *sum*, never a product of (1-α)),
//! weight w_k = T_k α_k. A per-sample vector v_k of `V` channels composites to V = Σ w_k v_k,
//! and the light that passes everything is T_N = exp(-Σ s_j).
//!
//! Backward, given G = dL/dV and g_T = dL/dT_N:
//!   dL/dv_k = w_k G
//!   dL/ds_k = T_{k+1} <G, v_k> - Σ_{i>k} w_i <G, v_i> - T_N g_T
//! (the middle term is a suffix sum, accumulated back to front), and dL/dσ_k = δ_k dL/ds_k
//! where s_k is not clamped. Everything stays finite for σ in [0, 1e30], δ in [0, 1e30].

/// Optical depth per sample is clamped here, at the same value as every other marcher (the
/// baked renderers must composite exactly like the trainer): exp(-S_MAX) is 0 in f32, and
/// the clamp keeps σδ finite when both are huge (1e10 * 1e30 overflows f32).
pub const S_MAX: f32 = snerf_geometry::march::MAX_OPTICAL_DEPTH;

/// Channel count of the composited vector: rgb (3) + features (4) + 1 (opacity, "acc").
pub const V: usize = 8;

/// Forward results for one ray, kept for the backward pass.
#[derive(Clone, Debug, Default)]
pub struct RayComposite {
    /// Composited vector Σ w_k v_k.
    pub value: [f32; V],
    /// Transmittance after the last sample.
    pub t_final: f32,
}

/// Clamped optical depth of one sample; non-finite or negative input counts as 0 (σ from a
/// diverged field must not poison a ray) except +inf which is "fully opaque".
#[inline]
pub fn optical_depth(sigma: f32, delta: f32) -> f32 {
    let s = sigma * delta;
    if s.is_nan() || s <= 0.0 {
        0.0
    } else if s >= S_MAX {
        S_MAX
    } else {
        s
    }
}

/// Weights w_k and transmittances T_k (before sample k) of one ray.
pub fn weights(sigma: &[f32], delta: &[f32], w: &mut Vec<f32>, trans: &mut Vec<f32>) -> f32 {
    w.clear();
    trans.clear();
    let mut acc_depth = 0.0f32;
    for (&sg, &dl) in sigma.iter().zip(delta) {
        let s = optical_depth(sg, dl);
        let t = (-acc_depth).exp();
        let alpha = -(-s).exp_m1();
        trans.push(t);
        w.push(t * alpha);
        acc_depth += s;
    }
    (-acc_depth).exp()
}

/// Composite `v` (n samples x V channels, row per sample) with densities and step lengths.
pub fn forward(sigma: &[f32], delta: &[f32], v: &[[f32; V]]) -> RayComposite {
    let mut out = RayComposite::default();
    let mut acc_depth = 0.0f32;
    for k in 0..sigma.len() {
        let s = optical_depth(sigma[k], delta[k]);
        let wk = (-acc_depth).exp() * -(-s).exp_m1();
        for c in 0..V {
            out.value[c] += wk * v[k][c];
        }
        acc_depth += s;
    }
    out.t_final = (-acc_depth).exp();
    out
}

/// Backward of [`forward`]: writes dL/dσ_k into `d_sigma` and dL/dv_k into `d_v`.
/// `grad_w` (empty, or one per sample) adds a loss term's gradient with respect to the
/// weights w_k themselves (the distortion loss). `scratch` holds per-sample depths
/// (reused across calls to avoid allocation).
#[allow(clippy::too_many_arguments)]
pub fn backward(
    sigma: &[f32],
    delta: &[f32],
    v: &[[f32; V]],
    grad_value: &[f32; V],
    grad_t_final: f32,
    grad_w: &[f32],
    d_sigma: &mut [f32],
    d_v: &mut [[f32; V]],
    scratch: &mut Vec<f32>,
) {
    let n = sigma.len();
    // Prefix depths, accumulated front to back exactly as in `forward` (walking back by
    // subtraction would lose the small depths in front of a clamped, huge one).
    scratch.clear();
    let mut prefix = 0.0f32;
    for k in 0..n {
        scratch.push(prefix);
        prefix += optical_depth(sigma[k], delta[k]);
    }
    let t_final = (-prefix).exp();
    let mut suffix = 0.0f32; // Σ_{i>k} w_i <G, v_i>
    for k in (0..n).rev() {
        let s = optical_depth(sigma[k], delta[k]);
        let t_before = (-scratch[k]).exp();
        let t_after = (-(scratch[k] + s)).exp();
        let wk = t_before * -(-s).exp_m1();
        // gv = dL/dw_k: through the composited value, plus any direct weight term.
        let mut gv = if grad_w.is_empty() { 0.0 } else { grad_w[k] };
        for c in 0..V {
            gv += grad_value[c] * v[k][c];
            d_v[k][c] = wk * grad_value[c];
        }
        let ds = t_after * gv - suffix - t_final * grad_t_final;
        let sg = sigma[k] * delta[k];
        // Where the clamp in `optical_depth` is active the derivative is 0.
        d_sigma[k] = if (0.0..S_MAX).contains(&sg) { delta[k] * ds } else { 0.0 };
        suffix += wk * gv;
    }
}

/// The distortion loss of mip-NeRF 360 (Barron et al. 2022) for one ray, which pulls each
/// ray's weight together into as short a stretch as possible (no fog, no floaters):
///   L = Σ_ij w_i w_j |m_i - m_j| + 1/3 Σ_i w_i² l_i
/// for interval midpoints m_i (increasing) and lengths l_i. Returns L and writes dL/dw_i,
/// both in O(n) with prefix sums.
pub fn distortion(w: &[f32], mid: &[f32], len: &[f32], grad_w: &mut [f32]) -> f32 {
    let n = w.len();
    let (tot_w, tot_wm) = w.iter().zip(mid).fold((0.0f32, 0.0f32), |(a, b), (&wi, &mi)| (a + wi, b + wi * mi));
    let (mut below_w, mut below_wm) = (0.0f32, 0.0f32);
    let mut loss = 0.0f32;
    for i in 0..n {
        let (wi, mi) = (w[i], mid[i]);
        let above_w = tot_w - below_w - wi;
        let above_wm = tot_wm - below_wm - wi * mi;
        // Σ_j w_j |m_i - m_j|
        let spread = mi * below_w - below_wm + above_wm - mi * above_w;
        loss += wi * spread + wi * wi * len[i] / 3.0;
        grad_w[i] = 2.0 * spread + 2.0 * wi * len[i] / 3.0;
        below_w += wi;
        below_wm += wi * mi;
    }
    loss
}
