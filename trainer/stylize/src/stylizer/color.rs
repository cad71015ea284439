//! `color`: weight-free colour-statistics transfer, for fast tests and previews.
//!
//! A full covariance match in RGB (the Monge-Kantorovich linear map, Pitie & Kokaram 2007):
//! the content's colours are moved by the affine map `x -> mu_s + T (x - mu_c)` with
//! `T = C_c^-1/2 (C_c^1/2 C_s C_c^1/2)^1/2 C_c^-1/2`, the map of least displacement that
//! gives the content the style's mean and covariance. Unlike per-channel matching (or
//! Reinhard's log-space lab) it also transfers correlations between channels, and its mean
//! is matched exactly in RGB (up to clamping to [0, 1]). Deterministic and O(pixels).

use anyhow::Result;

use super::{Image, Stylizer};

type Mat3 = [[f64; 3]; 3];

/// Content covariance eigenvalues are floored at this (std 0.01) before inverting, so flat
/// or nearly flat views stay finite.
const EIGEN_FLOOR: f64 = 1e-4;

/// Per-channel mean and the 3x3 colour covariance of an image.
pub fn mean_and_covariance(img: &Image) -> ([f64; 3], Mat3) {
    let n = (img.width * img.height).max(1) as f64;
    let mut mean = [0.0f64; 3];
    for px in img.data.chunks_exact(3) {
        for c in 0..3 {
            mean[c] += px[c] as f64;
        }
    }
    mean.iter_mut().for_each(|m| *m /= n);
    let mut cov = [[0.0f64; 3]; 3];
    for px in img.data.chunks_exact(3) {
        let d = [px[0] as f64 - mean[0], px[1] as f64 - mean[1], px[2] as f64 - mean[2]];
        for i in 0..3 {
            for j in 0..3 {
                cov[i][j] += d[i] * d[j];
            }
        }
    }
    cov.iter_mut().flatten().for_each(|v| *v /= n);
    (mean, cov)
}

/// The colour map for `content` towards the style statistics, at `strength`.
fn transfer_map(content: &Image, style_mean: &[f64; 3], style_cov: &Mat3, strength: f32) -> (Mat3, [f64; 3]) {
    let (mc, cc) = mean_and_covariance(content);
    let c_half = sym_power(&cc, 0.5);
    let c_inv_half = sym_power(&cc, -0.5);
    let middle = sym_power(&mul(&mul(&c_half, style_cov), &c_half), 0.5);
    let t_full = mul(&mul(&c_inv_half, &middle), &c_inv_half);
    // Interpolate the map itself: strength 0 is the identity, 1 the full transfer.
    let s = strength as f64;
    let mut t = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            let id = if i == j { 1.0 } else { 0.0 };
            t[i][j] = id + s * (t_full[i][j] - id);
        }
    }
    // x' = t (x - mc) + (mc + s (ms - mc)) = t x + offset
    let mut offset = [0.0; 3];
    for i in 0..3 {
        let target = mc[i] + s * (style_mean[i] - mc[i]);
        offset[i] = target - (0..3).map(|j| t[i][j] * mc[j]).sum::<f64>();
    }
    (t, offset)
}

/// Gives `content` the colour mean and covariance of `style` (blended by `strength`).
pub fn color_transfer(content: &Image, style: &Image, strength: f32) -> Image {
    let (ms, cs) = mean_and_covariance(style);
    apply(content, &ms, &cs, strength)
}

fn apply(content: &Image, style_mean: &[f64; 3], style_cov: &Mat3, strength: f32) -> Image {
    let (t, offset) = transfer_map(content, style_mean, style_cov, strength);
    let mut data = Vec::with_capacity(content.data.len());
    for px in content.data.chunks_exact(3) {
        for i in 0..3 {
            let v = offset[i] + (0..3).map(|j| t[i][j] * px[j] as f64).sum::<f64>();
            data.push(v.clamp(0.0, 1.0) as f32);
        }
    }
    Image { width: content.width, height: content.height, data }
}

/// `color` for one style image (its statistics computed once).
pub struct ColorStylizer {
    style_mean: [f64; 3],
    style_cov: Mat3,
    strength: f32,
}

impl ColorStylizer {
    pub fn new(style: &Image, strength: f32) -> ColorStylizer {
        let (style_mean, style_cov) = mean_and_covariance(style);
        ColorStylizer { style_mean, style_cov, strength: strength.clamp(0.0, 1.0) }
    }
}

impl Stylizer for ColorStylizer {
    fn name(&self) -> String {
        "color".into()
    }

    fn stylize(&self, content: &Image) -> Result<Image> {
        Ok(apply(content, &self.style_mean, &self.style_cov, self.strength))
    }
}

fn mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut c = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            c[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    c
}

/// `m^p` for a symmetric positive semi-definite 3x3 matrix. For negative powers the
/// eigenvalues are floored at `EIGEN_FLOOR` (a colour direction the content barely uses is
/// not blown up); for positive powers only rounding noise below zero is removed.
fn sym_power(m: &Mat3, p: f64) -> Mat3 {
    let (vals, vecs) = snerf_geometry::sym3::sym3_eigen(*m);
    let floor = if p < 0.0 { EIGEN_FLOOR } else { 0.0 };
    let mut out = [[0.0; 3]; 3];
    for k in 0..3 {
        let l = vals[k].max(floor).powf(p);
        for i in 0..3 {
            for j in 0..3 {
                out[i][j] += vecs[i][k] * l * vecs[j][k];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_roundtrip() {
        let m = [[0.04, 0.01, 0.0], [0.01, 0.03, 0.005], [0.0, 0.005, 0.02]];
        let h = sym_power(&m, 0.5);
        let back = mul(&h, &h);
        for i in 0..3 {
            for j in 0..3 {
                assert!((back[i][j] - m[i][j]).abs() < 1e-9, "{back:?}");
            }
        }
    }
}
