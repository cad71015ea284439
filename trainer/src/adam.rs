//! Adam with a learning rate per parameter range (planes learn faster than MLP weights).
//! Gradients are summed from the per-thread buffers inside the update (one pass over memory,
//! buffers zeroed on the way) and sanitized: NaN counts as 0 and magnitudes are capped so
//! that g² stays finite in f32 — one exploding ray must not freeze or poison the field.
//!
//! Feature planes are updated *lazily*: only cells (C consecutive floats) that some thread
//! marked as touched in this step are read and written. A step touches a fraction of the
//! planes, and the dense update was memory-bound (18% of a step at 2 M parameters).

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

/// Raw pointers to the per-thread gradient (and flag) buffers, shared by the parallel
/// update. Every parallel block touches a disjoint index range of every buffer.
#[derive(Clone, Copy)]
struct Shared(*mut f32);
// SAFETY: the pointers are only dereferenced inside the update functions, at indices that
// no two parallel blocks share, while the `&mut` borrows they came from are held.
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}
#[derive(Clone, Copy)]
struct SharedFlags(*mut u8);
// SAFETY: as for `Shared`.
unsafe impl Send for SharedFlags {}
unsafe impl Sync for SharedFlags {}

impl Adam {
    pub fn new(n: usize) -> Adam {
        Adam { beta1: 0.9, beta2: 0.99, eps: 1e-15, step: 0, m: vec![0.0; n], v: vec![0.0; n] }
    }

    /// Start a step: advances the bias-correction counter once for all ranges.
    pub fn begin_step(&mut self) {
        self.step += 1;
    }

    #[inline]
    fn step_size(&self, lr: f32) -> f32 {
        let t = self.step.clamp(1, 1 << 20) as i32;
        lr * (1.0 - self.beta2.powi(t)).sqrt() / (1.0 - self.beta1.powi(t))
    }

    #[inline]
    fn apply(&self, p: &mut f32, m: &mut f32, v: &mut f32, g: f32, step: f32) {
        let g = sanitize(g);
        *m = self.beta1 * *m + (1.0 - self.beta1) * g;
        *v = self.beta2 * *v + (1.0 - self.beta2) * g * g;
        *p -= step * *m / (v.sqrt() + self.eps);
    }

    /// Dense update of `params[range]` with learning rate `lr`.
    pub fn update_dense(&mut self, params: &mut [f32], grads: &mut [&mut Vec<f32>], range: std::ops::Range<usize>, lr: f32) {
        // The raw-pointer reads below rely on these bounds; checked here, once per call, so
        // this safe function cannot touch memory outside any buffer whatever it is given.
        assert!(range.end <= params.len() && range.end <= self.m.len(), "Adam range {range:?} beyond {} parameters", params.len().min(self.m.len()));
        assert!(grads.iter().all(|g| g.len() >= range.end), "a gradient buffer is shorter than the update range {range:?}");
        let step = self.step_size(lr);
        let bufs: Vec<Shared> = grads.iter_mut().map(|g| Shared(g.as_mut_ptr())).collect();
        let start = range.start;
        let this = Adam { m: Vec::new(), v: Vec::new(), ..*self };
        const BLOCK: usize = 1 << 12;
        params[range.clone()]
            .par_chunks_mut(BLOCK)
            .zip(self.m[range.clone()].par_chunks_mut(BLOCK))
            .zip(self.v[range].par_chunks_mut(BLOCK))
            .enumerate()
            .for_each(|(bi, ((p, m), v))| {
                let off = start + bi * BLOCK;
                for i in 0..p.len() {
                    let mut g = 0.0f32;
                    for b in &bufs {
                        // SAFETY: off+i < range.end <= every buffer's length (asserted above), and
                        // only this parallel block uses index off+i.
                        unsafe {
                            let slot = b.0.add(off + i);
                            g += *slot;
                            *slot = 0.0;
                        }
                    }
                    this.apply(&mut p[i], &mut m[i], &mut v[i], g, step);
                }
            });
    }

    /// Lazy update of `params[0..cells*cell]`: only cells flagged in some `flags` buffer.
    /// Flags and the gradients of updated cells are reset.
    pub fn update_cells(
        &mut self,
        params: &mut [f32],
        grads: &mut [&mut Vec<f32>],
        flags: &mut [&mut Vec<u8>],
        cell: usize,
        lr: f32,
    ) -> usize {
        let cells = flags.first().map(|f| f.len()).unwrap_or(0);
        // Bounds for the raw-pointer accesses below, checked once per call (see update_dense).
        assert!(flags.iter().all(|f| f.len() == cells), "flag buffers of different lengths");
        assert!(cells * cell <= params.len() && cells * cell <= self.m.len(), "{cells} cells of {cell} beyond {} parameters", params.len().min(self.m.len()));
        assert!(grads.iter().all(|g| g.len() >= cells * cell), "a gradient buffer is shorter than {cells} cells of {cell}");
        let step = self.step_size(lr);
        let bufs: Vec<Shared> = grads.iter_mut().map(|g| Shared(g.as_mut_ptr())).collect();
        let fl: Vec<SharedFlags> = flags.iter_mut().map(|f| SharedFlags(f.as_mut_ptr())).collect();
        let this = Adam { m: Vec::new(), v: Vec::new(), ..*self };
        const BLOCK: usize = 1 << 10; // cells per parallel block
        params[..cells * cell]
            .par_chunks_mut(BLOCK * cell)
            .zip(self.m[..cells * cell].par_chunks_mut(BLOCK * cell))
            .zip(self.v[..cells * cell].par_chunks_mut(BLOCK * cell))
            .enumerate()
            .map(|(bi, ((p, m), v))| {
                let mut updated = 0usize;
                for j in 0..p.len() / cell {
                    let ci = bi * BLOCK + j;
                    let mut hit = false;
                    for f in &fl {
                        // SAFETY: ci < cells = every flag buffer's length (asserted above), and
                        // cell ci belongs to this parallel block only.
                        unsafe {
                            let s = f.0.add(ci);
                            hit |= *s != 0;
                            *s = 0;
                        }
                    }
                    if !hit {
                        continue;
                    }
                    updated += 1;
                    for c in 0..cell {
                        let k = j * cell + c;
                        let mut g = 0.0f32;
                        for b in &bufs {
                            // SAFETY: ci*cell + c < cells*cell <= every gradient buffer's
                            // length (asserted above); cell ci belongs to this block only.
                            unsafe {
                                let slot = b.0.add(ci * cell + c);
                                g += *slot;
                                *slot = 0.0;
                            }
                        }
                        this.apply(&mut p[k], &mut m[k], &mut v[k], g, step);
                    }
                }
                updated
            })
            .sum()
    }
}
