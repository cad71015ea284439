//! Per-image appearance: a 3×4 affine colour transform per training photo (NeRF-W's and
//! nerfacto's per-image appearance, in its smallest form), learnt jointly with the field.
//!
//! Real photos of one scene differ in exposure and white balance from shot to shot; a field
//! that must reproduce every photo's colours exactly spends capacity on those differences and
//! bakes them into view-dependent colour (floaters, colour shifts between viewpoints). Here the
//! training loss compares `A_i · rgb + b_i` with photo `i`'s pixel, where `rgb` is the field's
//! colour and `(A_i | b_i)` photo `i`'s transform: identity at the start, pulled back toward
//! identity by an L2 penalty of weight `weight` on `(A_i | b_i) − (I | 0)`, so the field keeps
//! the photos' common colour and each transform only explains what differs. Held-out photos,
//! renders, bakes and stylization all use the field's own colour (the identity transform):
//! nothing is fitted on a held-out photo.
//!
//! Parameters live here, outside the field's parameter vector, with their own Adam state; the
//! training chunk reads them and adds its gradients through [`ChunkAppearance`]. A run keeps
//! them in `RUN/appearance.json` (names, transforms, optimizer state).

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

/// A 3×4 affine colour transform, row-major: `out_c = Σ_j a[4c + j] x_j + a[4c + 3]`.
pub type Affine = [f32; 12];

/// The transform that changes nothing.
pub const IDENTITY: Affine = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];

/// Adam's learning rate for the transforms (scaled by the run's schedule, like the field's).
pub const LR: f32 = 2e-3;

/// File name inside a run directory.
pub const FILE_NAME: &str = "appearance.json";

/// `a · x`.
pub fn apply(a: &Affine, x: &[f32; 3]) -> [f32; 3] {
    [0, 1, 2].map(|c| a[4 * c] * x[0] + a[4 * c + 1] * x[1] + a[4 * c + 2] * x[2] + a[4 * c + 3])
}

/// Backward of [`apply`]: adds dL/da to `da` and returns dL/dx for the output gradient `d_out`.
pub fn backward(a: &Affine, x: &[f32; 3], d_out: &[f32; 3], da: &mut Affine) -> [f32; 3] {
    let mut dx = [0.0f32; 3];
    for c in 0..3 {
        for j in 0..3 {
            da[4 * c + j] += d_out[c] * x[j];
            dx[j] += a[4 * c + j] * d_out[c];
        }
        da[4 * c + 3] += d_out[c];
    }
    dx
}

/// What one training worker needs of the transforms: a copy of them (none: appearance is off
/// and every colour is compared as it is), the photo of each ray of the current chunk, and the
/// gradient this worker has added per photo.
#[derive(Clone, Debug, Default)]
pub struct ChunkAppearance {
    transforms: Vec<Affine>,
    image_of: Vec<u32>,
    grad: Vec<Affine>,
}

impl ChunkAppearance {
    /// Start a step: these transforms (empty: off), gradients zeroed.
    pub fn begin(&mut self, transforms: &[Affine]) {
        self.transforms.clear();
        self.transforms.extend_from_slice(transforms);
        self.grad.clear();
        self.grad.resize(transforms.len(), [0.0; 12]);
    }

    /// The training photo of each ray of the next chunk.
    pub fn set_images(&mut self, images: &[u32]) {
        self.image_of.clear();
        self.image_of.extend_from_slice(images);
    }

    /// Gradient per photo added since [`ChunkAppearance::begin`].
    pub fn grad(&self) -> &[Affine] {
        &self.grad
    }

    /// One pixel's squared error (summed over channels) between the field's colour `rgb`,
    /// as ray `ri`'s photo saw it, and `target`; returns it with dL/drgb for the loss
    /// `scale · error`, adding dL/d(transform) to the photo's gradient.
    pub fn pixel(&mut self, ri: usize, rgb: &[f32; 3], target: &[f32; 3], scale: f32) -> (f64, [f32; 3]) {
        let mut loss = 0.0f64;
        if self.transforms.is_empty() {
            let mut d = [0.0f32; 3];
            for c in 0..3 {
                let e = rgb[c] - target[c];
                loss += (e * e) as f64;
                d[c] = 2.0 * e * scale;
            }
            return (loss, d);
        }
        let i = self.image_of[ri] as usize;
        let a = &self.transforms[i];
        let out = apply(a, rgb);
        let mut d_out = [0.0f32; 3];
        for c in 0..3 {
            let e = out[c] - target[c];
            loss += (e * e) as f64;
            d_out[c] = 2.0 * e * scale;
        }
        (loss, backward(a, rgb, &d_out, &mut self.grad[i]))
    }
}

/// The transforms of every training photo and their optimizer state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Appearance {
    /// Weight of the pull toward identity (per photo, on the squared distance of its 12
    /// numbers from identity's, added to the batch's mean squared error).
    pub weight: f32,
    /// The training photos' file names, in the order of the transforms.
    pub names: Vec<String>,
    pub transforms: Vec<Affine>,
    m: Vec<Affine>,
    v: Vec<Affine>,
    steps: u64,
}

impl Appearance {
    pub fn new(names: Vec<String>, weight: f32) -> Appearance {
        let n = names.len();
        Appearance { weight, names, transforms: vec![IDENTITY; n], m: vec![[0.0; 12]; n], v: vec![[0.0; 12]; n], steps: 0 }
    }

    /// One Adam step at learning rate `lr` on the sum of the workers' gradients (added in
    /// the order given, so a run is reproducible) plus the pull toward identity.
    pub fn step<'a>(&mut self, grads: impl IntoIterator<Item = &'a [Affine]>, lr: f32) {
        let n = self.transforms.len();
        let mut g = vec![[0.0f32; 12]; n];
        for w in grads {
            for (gi, wi) in g.iter_mut().zip(w) {
                for k in 0..12 {
                    gi[k] += wi[k];
                }
            }
        }
        const B1: f32 = 0.9;
        const B2: f32 = 0.99;
        const EPS: f32 = 1e-8;
        self.steps += 1;
        let c1 = 1.0 - B1.powi(self.steps.min(1 << 20) as i32);
        let c2 = 1.0 - B2.powi(self.steps.min(1 << 20) as i32);
        for i in 0..n {
            for k in 0..12 {
                let gk = g[i][k] + 2.0 * self.weight * (self.transforms[i][k] - IDENTITY[k]);
                self.m[i][k] = B1 * self.m[i][k] + (1.0 - B1) * gk;
                self.v[i][k] = B2 * self.v[i][k] + (1.0 - B2) * gk * gk;
                self.transforms[i][k] -= lr * (self.m[i][k] / c1) / ((self.v[i][k] / c2).sqrt() + EPS);
            }
        }
    }

    /// Per photo: its mean gain (mean of the diagonal), its offset (mean of b) and its
    /// distance from identity (Frobenius norm of the 12 differences).
    pub fn summary(&self) -> serde_json::Value {
        let rows: Vec<_> = self
            .names
            .iter()
            .zip(&self.transforms)
            .map(|(name, a)| {
                let dist = (0..12).map(|k| (a[k] - IDENTITY[k]).powi(2)).sum::<f32>().sqrt();
                serde_json::json!({
                    "image": name,
                    "gain": (a[0] + a[5] + a[10]) / 3.0,
                    "offset": (a[3] + a[7] + a[11]) / 3.0,
                    "distance_from_identity": dist,
                })
            })
            .collect();
        let max = self
            .transforms
            .iter()
            .map(|a| (0..12).map(|k| (a[k] - IDENTITY[k]).powi(2)).sum::<f32>().sqrt())
            .fold(0.0f32, f32::max);
        serde_json::json!({ "weight": self.weight, "photos": rows.len(), "max_distance_from_identity": max, "per_photo": rows })
    }

    /// Read `path` (a run's `appearance.json`), checking it holds one transform per name.
    pub fn load(path: &std::path::Path) -> Result<Appearance> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}: cannot read", path.display()))?;
        let a: Appearance = serde_json::from_str(&text).with_context(|| format!("{}: not an appearance record", path.display()))?;
        let n = a.names.len();
        anyhow::ensure!(
            a.transforms.len() == n && a.m.len() == n && a.v.len() == n,
            "{}: {} photo names but {} transforms",
            path.display(),
            n,
            a.transforms.len()
        );
        Ok(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Finite differences of the per-pixel loss against the transform's 12 numbers and the
    /// colour's 3, through [`ChunkAppearance::pixel`] (the function training calls).
    #[test]
    fn pixel_gradient_matches_finite_differences() {
        let a: Affine = [1.1, 0.05, -0.02, 0.03, -0.04, 0.9, 0.07, -0.05, 0.02, 0.01, 1.2, 0.1];
        let rgb = [0.3f32, 0.6, 0.45];
        let target = [0.5f32, 0.4, 0.7];
        let scale = 0.7f32;
        let loss = |a: &Affine, rgb: &[f32; 3]| {
            let mut w = ChunkAppearance::default();
            w.begin(&[IDENTITY, *a]);
            w.set_images(&[1]);
            scale as f64 * w.pixel(0, rgb, &target, scale).0
        };
        let mut w = ChunkAppearance::default();
        w.begin(&[IDENTITY, a]);
        w.set_images(&[1]);
        let (_, d_rgb) = w.pixel(0, &rgb, &target, scale);
        assert_eq!(w.grad()[0], [0.0; 12], "another photo's transform got a gradient");
        let da = w.grad()[1];
        let h = 1e-3f32;
        for k in 0..12 {
            let (mut p, mut m) = (a, a);
            p[k] += h;
            m[k] -= h;
            let fd = (loss(&p, &rgb) - loss(&m, &rgb)) / (2.0 * h as f64);
            assert!((fd - da[k] as f64).abs() < 1e-3 * (1.0 + fd.abs()), "d/da[{k}]: analytic {} fd {fd}", da[k]);
        }
        for j in 0..3 {
            let (mut p, mut m) = (rgb, rgb);
            p[j] += h;
            m[j] -= h;
            let fd = (loss(&a, &p) - loss(&a, &m)) / (2.0 * h as f64);
            assert!((fd - d_rgb[j] as f64).abs() < 1e-3 * (1.0 + fd.abs()), "d/drgb[{j}]: analytic {} fd {fd}", d_rgb[j]);
        }
    }

    /// Off (no transforms), a pixel's loss and gradient are the plain squared error's.
    #[test]
    fn off_is_the_plain_squared_error() {
        let mut w = ChunkAppearance::default();
        w.begin(&[]);
        let (l, d) = w.pixel(0, &[0.2, 0.5, 0.9], &[0.1, 0.5, 1.0], 0.5);
        assert!((l - 0.02).abs() < 1e-6, "{l}");
        assert!((d[0] - 0.1).abs() < 1e-6 && d[1] == 0.0 && (d[2] + 0.1).abs() < 1e-6, "{d:?}");
    }

    /// The optimizer recovers a photo's exposure and white balance from pixels of a fixed
    /// colour field, and the pull toward identity leaves a photo without data at identity.
    #[test]
    fn steps_recover_a_known_colour_change() {
        let truth: Affine = [1.3, 0.0, 0.0, -0.05, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.8, 0.04];
        let mut app = Appearance::new(vec!["a.jpg".into(), "b.jpg".into()], 1e-4);
        let colours: Vec<[f32; 3]> =
            (0..64).map(|i| [(i % 4) as f32 / 4.0 + 0.1, (i / 4 % 4) as f32 / 4.0 + 0.1, (i / 16) as f32 / 4.0 + 0.1]).collect();
        let mut w = ChunkAppearance::default();
        for _ in 0..2000 {
            w.begin(&app.transforms);
            w.set_images(&vec![0; colours.len()]);
            for (ri, c) in colours.iter().enumerate() {
                w.pixel(ri, c, &apply(&truth, c), 1.0 / 64.0);
            }
            app.step([w.grad()], 0.01);
        }
        for k in 0..12 {
            assert!((app.transforms[0][k] - truth[k]).abs() < 0.02, "{k}: {:?}", app.transforms[0]);
            assert!((app.transforms[1][k] - IDENTITY[k]).abs() < 1e-6, "{k}: {:?}", app.transforms[1]);
        }
    }
}
