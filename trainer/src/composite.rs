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

/// Optical depth per sample is clamped here: exp(-S_MAX) is 0 in f32 already, and the clamp
/// keeps σδ finite when both are huge (1e10 * 1e30 overflows f32).
pub const S_MAX: f32 = 1.0e4;

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
/// `scratch` holds per-sample depths (reused across calls to avoid allocation).
#[allow(clippy::too_many_arguments)]
pub fn backward(
    sigma: &[f32],
    delta: &[f32],
    v: &[[f32; V]],
    grad_value: &[f32; V],
    grad_t_final: f32,
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
        let mut gv = 0.0f32;
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
