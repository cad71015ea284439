//! The deferred view-dependence MLP of SNeRG: runs once per *ray* (not per sample) on the
//! composited diffuse colour, the composited 4-channel feature and the viewing direction,
//! and returns a specular RGB residual. Tiny (2 hidden layers of 16) so the baked viewer can
//! run it per pixel in a shader; the baker stores exactly these weights.
//!
//! Input (VIN = 34): diffuse rgb (3), features (4), direction (3), and sin/cos of the
//! direction at 4 octaves (24).

use crate::rng::Rng;
use snerf_geometry::view_mlp::{dense, encode};

pub const VIN: usize = snerf_geometry::view_mlp::INPUTS;
pub const VH: usize = snerf_geometry::view_mlp::HIDDEN;
pub const VOUT: usize = snerf_geometry::view_mlp::OUTPUTS;

#[derive(Clone, Copy, Debug)]
pub struct ViewLayout {
    pub w1: usize,
    pub b1: usize,
    pub w2: usize,
    pub b2: usize,
    pub w3: usize,
    pub b3: usize,
    pub end: usize,
}

/// Activations kept for the backward pass.
#[derive(Clone, Copy, Debug)]
pub struct ViewCache {
    pub x: [f32; VIN],
    pub h1: [f32; VH],
    pub h2: [f32; VH],
}

impl ViewLayout {
    pub fn new(start: usize) -> ViewLayout {
        let w1 = start;
        let b1 = w1 + VH * VIN;
        let w2 = b1 + VH;
        let b2 = w2 + VH * VH;
        let w3 = b2 + VH;
        let b3 = w3 + VOUT * VH;
        ViewLayout { w1, b1, w2, b2, w3, b3, end: b3 + VOUT }
    }

    pub fn init(&self, params: &mut [f32], rng: &mut Rng) {
        let s1 = (6.0 / VIN as f32).sqrt();
        for x in &mut params[self.w1..self.b1] {
            *x = s1 * (2.0 * rng.uniform() - 1.0);
        }
        let s2 = (6.0 / VH as f32).sqrt();
        for x in &mut params[self.w2..self.b2] {
            *x = s2 * (2.0 * rng.uniform() - 1.0);
        }
        // A new field starts purely diffuse.
        self.make_diffuse(params);
    }

    /// Zero the last layer, so the MLP adds nothing whatever its input: the field's colour
    /// no longer depends on the viewing direction (while the layer stays frozen).
    pub fn make_diffuse(&self, params: &mut [f32]) {
        params[self.w3..self.end].fill(0.0);
    }

    /// Assemble the MLP input from composited diffuse rgb + features and a unit direction.
    pub fn input(diffuse_feat: &[f32], dir: &[f32; 3]) -> [f32; VIN] {
        let mut df = [0.0f32; 7];
        df.copy_from_slice(&diffuse_feat[..7]);
        encode(&df, *dir)
    }

    pub fn forward(&self, p: &[f32], x: [f32; VIN]) -> ([f32; VOUT], ViewCache) {
        let mut h1 = [0.0f32; VH];
        dense(&p[self.w1..self.b1], &p[self.b1..self.w2], &x, &mut h1, true);
        let mut h2 = [0.0f32; VH];
        dense(&p[self.w2..self.b2], &p[self.b2..self.w3], &h1, &mut h2, true);
        let mut out = [0.0f32; VOUT];
        dense(&p[self.w3..self.b3], &p[self.b3..self.end], &h2, &mut out, false);
        (out, ViewCache { x, h1, h2 })
    }

    /// Accumulates weight gradients into `grad`; returns dL/d(diffuse rgb, features).
    pub fn backward(&self, p: &[f32], cache: &ViewCache, d_out: &[f32; VOUT], grad: &mut [f32]) -> [f32; 7] {
        let mut d_h2 = [0.0f32; VH];
        for k in 0..VOUT {
            grad[self.b3 + k] += d_out[k];
            for i in 0..VH {
                grad[self.w3 + k * VH + i] += d_out[k] * cache.h2[i];
                d_h2[i] += d_out[k] * p[self.w3 + k * VH + i];
            }
        }
        let mut d_h1 = [0.0f32; VH];
        for j in 0..VH {
            if cache.h2[j] <= 0.0 {
                continue;
            }
            let g = d_h2[j];
            grad[self.b2 + j] += g;
            for i in 0..VH {
                grad[self.w2 + j * VH + i] += g * cache.h1[i];
                d_h1[i] += g * p[self.w2 + j * VH + i];
            }
        }
        let mut d_x = [0.0f32; 7];
        for j in 0..VH {
            if cache.h1[j] <= 0.0 {
                continue;
            }
            let g = d_h1[j];
            grad[self.b1 + j] += g;
            for i in 0..VIN {
                grad[self.w1 + j * VIN + i] += g * cache.x[i];
            }
            for i in 0..7 {
                d_x[i] += g * p[self.w1 + j * VIN + i];
            }
        }
        d_x
    }
}
