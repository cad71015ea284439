//! `onnx:FILE`: any image-to-image ONNX model with one image input (how a GAN stylizer such
//! as ArcaneGAN is plugged in for avatars).
//!
//! The input's layout is read from its declared shape: `[N,3,H,W]` is NCHW, `[N,H,W,3]` is
//! NHWC. A fixed H and W means the view is resized to them; symbolic H and W mean the view
//! runs at its own size, reflect-padded to a multiple of 32 (what U-Net-like generators
//! need). Pixel range is [0,1] unless the spec says `?range=-1,1` or `?range=0,255`; the
//! output is read in the same range and layout, cropped and resized back to the view.
//! Strength blends with the content in pixel space.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Result};
use tract_onnx::prelude::*;
use tract_onnx::tract_hir::infer::Factoid;
use tract_onnx::tract_hir::internal::DimLike;

use super::image_ops::{blend, clamp01, crop, from_chw, reflect_pad, resize, to_chw};
use super::tract_plans::{load_onnx, ShapePlans};
use super::{Image, Stylizer, StylizerOptions};

/// Views are padded to a multiple of this for models with symbolic spatial sizes.
pub const PAD_MULTIPLE: usize = 32;

/// The pixel range a model expects and produces.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValueRange {
    ZeroOne,
    MinusOneOne,
    Zero255,
}

impl ValueRange {
    fn to_model(self, v: f32) -> f32 {
        match self {
            ValueRange::ZeroOne => v,
            ValueRange::MinusOneOne => v * 2.0 - 1.0,
            ValueRange::Zero255 => v * 255.0,
        }
    }

    fn to_unit(self, v: f32) -> f32 {
        match self {
            ValueRange::ZeroOne => v,
            ValueRange::MinusOneOne => (v + 1.0) * 0.5,
            ValueRange::Zero255 => v / 255.0,
        }
    }
}

/// Splits `FILE?range=A,B` into the file and its range (default [0,1]).
pub fn parse_file_and_range(rest: &str) -> Result<(&str, ValueRange)> {
    let Some((file, query)) = rest.rsplit_once("?range=") else {
        return Ok((rest, ValueRange::ZeroOne));
    };
    let range = match query.replace(' ', "").as_str() {
        "0,1" => ValueRange::ZeroOne,
        "-1,1" => ValueRange::MinusOneOne,
        "0,255" => ValueRange::Zero255,
        other => bail!("stylizer onnx:{rest}: unknown range {other:?}; use ?range=0,1, ?range=-1,1 or ?range=0,255"),
    };
    Ok((file, range))
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Layout {
    Nchw,
    Nhwc,
}

/// What the model's input declares.
#[derive(Clone, Copy, Debug)]
struct InputSpec {
    layout: Layout,
    /// Fixed (height, width), or None when symbolic.
    fixed: Option<(usize, usize)>,
}

pub struct OnnxFileStylizer {
    path: PathBuf,
    plans: ShapePlans,
    input: InputSpec,
    range: ValueRange,
    strength: f32,
}

impl OnnxFileStylizer {
    pub fn new(path: &Path, range: ValueRange, opts: &StylizerOptions) -> Result<OnnxFileStylizer> {
        opts.validate()?;
        if !path.is_file() {
            bail!("ONNX model {} does not exist or is not a file", path.display());
        }
        let model = load_onnx(path)?;
        let input = inspect_input(&model).map_err(|e| anyhow!("ONNX model {}: {e}", path.display()))?;
        if model.output_outlets()?.is_empty() {
            bail!("ONNX model {} has no outputs", path.display());
        }
        Ok(OnnxFileStylizer {
            path: path.to_path_buf(),
            plans: ShapePlans::from_model(model, path),
            input,
            range,
            strength: opts.strength,
        })
    }

    fn run_image(&self, img: &Image) -> Result<(Vec<usize>, Vec<f32>)> {
        let (h, w) = (img.height, img.width);
        let mut data = match self.input.layout {
            Layout::Nchw => to_chw(img),
            Layout::Nhwc => img.data.clone(),
        };
        for v in &mut data {
            *v = self.range.to_model(*v);
        }
        let shape = match self.input.layout {
            Layout::Nchw => vec![1, 3, h, w],
            Layout::Nhwc => vec![1, h, w, 3],
        };
        let out = self.plans.run(&[(shape, &data)])?;
        out.into_iter().next().ok_or_else(|| anyhow!("ONNX model {} returned no output", self.path.display()))
    }

    /// Reads the model output back as an image, in the input's layout where it fits.
    fn output_image(&self, shape: &[usize], mut values: Vec<f32>) -> Result<Image> {
        let bad = || anyhow!("ONNX model {}: output shape {shape:?} is not one RGB image ([1,3,H,W] or [1,H,W,3])", self.path.display());
        if shape.len() != 4 || shape[0] != 1 {
            return Err(bad());
        }
        let layout = match (shape[1] == 3, shape[3] == 3) {
            (true, true) => self.input.layout,
            (true, false) => Layout::Nchw,
            (false, true) => Layout::Nhwc,
            (false, false) => return Err(bad()),
        };
        for v in &mut values {
            *v = self.range.to_unit(*v);
        }
        Ok(match layout {
            Layout::Nchw => from_chw(&values, shape[3], shape[2]),
            Layout::Nhwc => Image { width: shape[2], height: shape[1], data: values },
        })
    }
}

impl Stylizer for OnnxFileStylizer {
    fn name(&self) -> String {
        format!("onnx:{}", self.path.display())
    }

    fn stylize(&self, content: &Image) -> Result<Image> {
        // The model input, and the part of it that holds the view.
        let (input, (vw, vh)) = match self.input.fixed {
            Some((h, w)) => (resize(content, w, h), (w, h)),
            None => {
                let (pw, ph) = (content.width.div_ceil(PAD_MULTIPLE) * PAD_MULTIPLE, content.height.div_ceil(PAD_MULTIPLE) * PAD_MULTIPLE);
                (reflect_pad(content, pw, ph), (content.width, content.height))
            }
        };
        let (shape, values) = self.run_image(&input)?;
        let out = self.output_image(&shape, values)?;
        // Models may change resolution (e.g. 2x); crop the view's share proportionally.
        let cw = (vw * out.width).div_ceil(input.width).min(out.width).max(1);
        let ch = (vh * out.height).div_ceil(input.height).min(out.height).max(1);
        let mut out = resize(&crop(&out, 0, 0, cw, ch), content.width, content.height);
        // NaN survives clamp (f32::clamp keeps NaN), so the finite guard still sees it.
        clamp01(&mut out);
        Ok(if self.strength >= 1.0 { out } else { blend(content, &out, self.strength) })
    }
}

/// Checks there is exactly one rank-4 float input with 3 channels in a known place.
fn inspect_input(model: &InferenceModel) -> Result<InputSpec> {
    let outlets = model.input_outlets()?;
    let describe = |o: &OutletId| -> String {
        let fact = model.outlet_fact(*o).map(|f| f.format_dt_shape()).unwrap_or_default();
        format!("{} {fact}", model.node(o.node).name)
    };
    if outlets.len() != 1 {
        let list: Vec<String> = outlets.iter().map(describe).collect();
        bail!(
            "has {} inputs ({}); onnx: needs a model with exactly one image input",
            outlets.len(),
            list.join(", ")
        );
    }
    let fact = model.outlet_fact(outlets[0])?;
    let name = describe(&outlets[0]);
    if let Some(dt) = fact.datum_type.concretize() {
        if dt != f32::datum_type() {
            bail!("input {name} is {dt:?}; onnx: needs a float32 image input");
        }
    }
    let rank = fact.shape.rank().concretize();
    if rank != Some(4) {
        let r = rank.map(|r| r.to_string()).unwrap_or_else(|| "unknown".into());
        bail!("input {name} has rank {r}; onnx: needs a rank-4 image input, NCHW [1,3,H,W] or NHWC [1,H,W,3]");
    }
    let dim = |i: usize| -> Option<usize> {
        fact.shape.dim(i).and_then(|d| d.concretize()).and_then(|d| d.to_usize().ok())
    };
    if let Some(n) = dim(0) {
        if n != 1 {
            bail!("input {name} has batch size {n}; onnx: needs batch size 1 (or a symbolic batch)");
        }
    }
    let layout = match (dim(1), dim(3)) {
        (Some(3), _) => Layout::Nchw,
        (_, Some(3)) => Layout::Nhwc,
        _ => bail!("input {name}: cannot tell the layout, neither dimension 1 (NCHW) nor dimension 3 (NHWC) is 3 channels"),
    };
    let (hi, wi) = match layout {
        Layout::Nchw => (2, 3),
        Layout::Nhwc => (1, 2),
    };
    let fixed = match (dim(hi), dim(wi)) {
        (Some(h), Some(w)) if h > 0 && w > 0 => Some((h, w)),
        _ => None,
    };
    Ok(InputSpec { layout, fixed })
}
