//! Adam with a learning rate per parameter range (planes learn faster than MLP weights).
//! Gradients are summed from the per-thread buffers inside the update (one pass over memory,
//! buffers zeroed on the way) and sanitized: NaN counts as 0 and magnitudes are capped so
//! that g² stays finite in f32 — one exploding ray must not freeze or poison the field.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// |g| cap: g² = 1e30 still fits in f32.
pub const GRAD_CAP: f32 = 1.0e15;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Adam {
    pub beta1: f32,
    pub beta2: f32,
    pub eps: f32,
    pub step: u64,
    pub m: Vec<f32>,
    pub v: Vec<f32>,
}

#[inline]
pub fn sanitize(g: f32) -> f32 {
    if g.is_nan() {
        0.0
    } else {
        g.clamp(-GRAD_CAP, GRAD_CAP)
    }
}

impl Adam {
    pub fn new(n: usize) -> Adam {
        Adam { beta1: 0.9, beta2: 0.99, eps: 1e-15, step: 0, m: vec![0.0; n], v: vec![0.0; n] }
    }

    /// One update. `ranges` = (end index, learning rate) in increasing order covering all
    /// parameters; `grads` are per-thread gradient buffers, summed and zeroed here.
    pub fn update(&mut self, params: &mut [f32], grads: &mut [&mut Vec<f32>], ranges: &[(usize, f32)]) {
        self.step += 1;
        let (b1, b2, eps) = (self.beta1, self.beta2, self.eps);
        let bc1 = 1.0 - b1.powi(self.step.min(1 << 20) as i32);
        let bc2 = 1.0 - b2.powi(self.step.min(1 << 20) as i32);
        const BLOCK: usize = 1 << 14;
        let mut start = 0;
        for &(end, lr) in ranges {
            let step = lr * bc2.sqrt() / bc1;
            let n = end - start;
            let p = &mut params[start..end];
            let m = &mut self.m[start..end];
            let v = &mut self.v[start..end];
            let gptrs: Vec<usize> = grads.iter_mut().map(|g| g[start..end].as_mut_ptr() as usize).collect();
            p.par_chunks_mut(BLOCK)
                .zip(m.par_chunks_mut(BLOCK))
                .zip(v.par_chunks_mut(BLOCK))
                .enumerate()
                .for_each(|(bi, ((p, m), v))| {
                    let off = bi * BLOCK;
                    let len = p.len();
                    debug_assert!(off + len <= n);
                    for (i, ((p, m), v)) in p.iter_mut().zip(m.iter_mut()).zip(v.iter_mut()).enumerate() {
                        let mut g = 0.0f32;
                        for &gp in &gptrs {
                            // SAFETY: each block touches a disjoint index range of every buffer.
                            let slot = unsafe { &mut *(gp as *mut f32).add(off + i) };
                            g += *slot;
                            *slot = 0.0;
                        }
                        let g = sanitize(g);
                        *m = b1 * *m + (1.0 - b1) * g;
                        *v = b2 * *v + (1.0 - b2) * g * g;
                        *p -= step * *m / (v.sqrt() + eps);
                    }
                });
            start = end;
        }
    }
}
