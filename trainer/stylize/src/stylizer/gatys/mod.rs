//! `gatys`: the SNeRF paper's own image stylizer (Gatys et al. 2016): optimise the view's
//! pixels so its features at one layer keep the content and its Gram matrices at several
//! layers match the style's. Networks, losses and their backward passes are written here in
//! Rust; pixels are updated with Adam, starting from the content (the render, in the SNeRF
//! loop), and kept in [0, 1].
//!
//! Features come from one of two ImageNet-trained networks (`net::FeatureNet`):
//! - by default the MobileNetV2 trunk of Magenta's style network, read from the
//!   `arbitrary_predict.onnx` that `scripts/setup-models.sh` installs (`mobilenet`), so the
//!   stylizer runs wherever `arbitrary` does;
//! - VGG-16, the paper's network, from a user-supplied safetensors file (`GATYS_HELP`).

mod gemm;
mod layers;
pub mod mobilenet;
pub mod net;
mod objective;
mod vgg;
mod weights;

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{bail, Result};

pub use layers::{Conv3x3, Planes};
pub use mobilenet::MobileNet;
pub use net::{FeatureNet, Trace};
pub use objective::{gram, style_grams, Objective};
pub use vgg::{Vgg, IMAGENET_MEAN, IMAGENET_STD, TAPS};
pub use weights::{VggWeights, CONV_INDICES, CONV_NAMES, VGG16_WIDTHS};

use super::image_ops::{fit_longer_side, resize};
use super::model_files::{model_path, ARBITRARY_PREDICT};
use super::{Image, Stylizer, StylizerOptions};

/// How a user gets VGG-16 weights for `gatys` (for `--help` texts and error messages).
pub const GATYS_HELP: &str = "\
By default the gatys stylizer uses the MobileNetV2 features of the Magenta style network that
`bash scripts/setup-models.sh` installs. For the paper's VGG-16 features it needs
ImageNet-trained VGG-16 convolution weights in a safetensors file,
in torchvision's layout (features.0.weight [64,3,3,3], features.0.bias [64], ... up to
features.17 = conv4_1; keys without the `features.` prefix work too). To make one (Python,
once, with network access):

    pip install torch torchvision safetensors
    python -c \"import torchvision, safetensors.torch as st; \\
      f = torchvision.models.vgg16(weights='IMAGENET1K_V1').features.state_dict(); \\
      st.save_file({k: v.float().contiguous() for k, v in f.items() if int(k.split('.')[0]) <= 17}, 'vgg16_features.safetensors')\"

then pass the file with --gatys-weights vgg16_features.safetensors (about 7 MB for the
layers used). Float32, float16 and bfloat16 tensors are accepted.";

/// Content and style weights of the objective (both losses are relative errors; see
/// `objective`).
pub const CONTENT_WEIGHT: f64 = 1.0;
pub const STYLE_WEIGHT: f64 = 5.0;
/// Adam step size in pixel units ([0, 1] range).
pub const LEARNING_RATE: f32 = 0.02;

/// HWC image -> planar `[3, h, w]`.
pub fn planes_from_image(img: &Image) -> Planes {
    Planes { c: 3, h: img.height, w: img.width, data: super::image_ops::to_chw(img) }
}

/// Planar `[3, h, w]` -> HWC image.
pub fn image_from_planes(p: &Planes) -> Image {
    super::image_ops::from_chw(&p.data, p.w, p.h)
}

/// Adam on the pixels of `start`, projected to [0, 1] after each step. Returns the result
/// and the loss before each step.
pub fn optimize(objective: &Objective, start: &Planes, steps: usize, lr: f32) -> (Planes, Vec<f64>) {
    optimize_shifted(&[(0, 0, objective)], start, steps, lr)
}

/// The pixel offsets whose crops `optimize_shifted` cycles through.
pub const JITTER: [(usize, usize); 4] = [(0, 0), (1, 1), (0, 1), (1, 0)];

/// `planes` without its first `dy` rows and `dx` columns.
pub fn crop(p: &Planes, dy: usize, dx: usize) -> Planes {
    if dy == 0 && dx == 0 {
        return p.clone();
    }
    let (h, w) = (p.h - dy, p.w - dx);
    let mut out = Planes::zeros(p.c, h, w);
    for c in 0..p.c {
        for y in 0..h {
            let src = (c * p.h + y + dy) * p.w + dx;
            out.data[(c * h + y) * w..(c * h + y + 1) * w].copy_from_slice(&p.data[src..src + w]);
        }
    }
    out
}

/// Adam as in `optimize`, step `k` evaluating objective `k mod n` on the image cropped by
/// that objective's offset (its gradient is zero on the cropped-off rows and columns).
///
/// Why: a stride-2 first layer (MobileNetV2's stem) sees even and odd pixels through
/// different kernel taps, so its input gradient carries a checkerboard that Adam turns into
/// a pixel-level grid the network itself is nearly blind to. Shifting the sampling grid by
/// one pixel from step to step averages that parity out.
pub fn optimize_shifted(objectives: &[(usize, usize, &Objective)], start: &Planes, steps: usize, lr: f32) -> (Planes, Vec<f64>) {
    let (b1, b2, eps) = (0.9f32, 0.999f32, 1e-8f32);
    let mut x = start.clone();
    let mut m = vec![0.0f32; x.data.len()];
    let mut v = vec![0.0f32; x.data.len()];
    let mut losses = Vec::with_capacity(steps);
    let (h, w) = (x.h, x.w);
    for step in 1..=steps {
        let (dy, dx, objective) = objectives[(step - 1) % objectives.len()];
        let (loss, gc) = objective.loss_and_grad(&crop(&x, dy, dx));
        losses.push(loss);
        let (c1, c2) = (1.0 - b1.powi(step as i32), 1.0 - b2.powi(step as i32));
        for c in 0..x.c {
            for y in 0..h {
                for xx in 0..w {
                    let i = (c * h + y) * w + xx;
                    let g = if y >= dy && xx >= dx { gc.data[(c * gc.h + y - dy) * gc.w + xx - dx] } else { 0.0 };
                    m[i] = b1 * m[i] + (1.0 - b1) * g;
                    v[i] = b2 * v[i] + (1.0 - b2) * g * g;
                    let update = lr * (m[i] / c1) / ((v[i] / c2).sqrt() + eps);
                    x.data[i] = (x.data[i] - update).clamp(0.0, 1.0);
                }
            }
        }
    }
    (x, losses)
}

/// `gatys` for one style image.
pub struct GatysStylizer {
    net: Arc<dyn FeatureNet>,
    grams: Vec<Vec<f32>>,
    strength: f32,
    steps: usize,
    content_size: usize,
}

impl GatysStylizer {
    /// `gatys` as `from_spec` builds it: VGG-16 from `opts.gatys_weights` when given, else
    /// the MobileNetV2 features of the installed Magenta style network.
    pub fn from_options(style: &Image, opts: &StylizerOptions) -> Result<GatysStylizer> {
        match &opts.gatys_weights {
            Some(w) => Self::from_file(w, style, opts),
            None => Self::with_net(Arc::new(MobileNet::load(&model_path(ARBITRARY_PREDICT, opts)?)?), style, opts),
        }
    }

    /// Loads the VGG-16 weights file (errors name it and the problem) and prepares the style.
    pub fn from_file(weights: &Path, style: &Image, opts: &StylizerOptions) -> Result<GatysStylizer> {
        Self::new(VggWeights::load(weights)?, style, opts)
    }

    /// VGG-16 features with these weights.
    pub fn new(weights: VggWeights, style: &Image, opts: &StylizerOptions) -> Result<GatysStylizer> {
        Self::with_net(Arc::new(Vgg::new(weights)), style, opts)
    }

    pub fn with_net(net: Arc<dyn FeatureNet>, style: &Image, opts: &StylizerOptions) -> Result<GatysStylizer> {
        opts.validate()?;
        if opts.gatys_steps == 0 {
            bail!("stylizer gatys needs at least one optimisation step");
        }
        let style = fit_longer_side(style, opts.style_size);
        check_size(&style, "style image", net.min_side())?;
        let grams = style_grams(net.as_ref(), &planes_from_image(&style));
        Ok(GatysStylizer { net, grams, strength: opts.strength, steps: opts.gatys_steps, content_size: opts.content_size })
    }

    /// The feature network's name (`mobilenet_v2` or `vgg16`).
    pub fn features(&self) -> &str {
        self.net.name()
    }

    /// Stylizes and also returns the loss before each step (for tests and reports).
    pub fn stylize_with_losses(&self, content: &Image) -> Result<(Image, Vec<f64>)> {
        check_size(content, "view", self.net.min_side())?;
        if self.strength == 0.0 {
            return Ok((content.clone(), Vec::new()));
        }
        // Optimise at most at content_size on the longer side (never upscaled).
        let work = if content.width.max(content.height) > self.content_size {
            fit_longer_side(content, self.content_size)
        } else {
            content.clone()
        };
        let start = planes_from_image(&work);
        let style_weight = STYLE_WEIGHT * self.strength as f64;
        // One objective per sampling offset, each with the content target of its own crop.
        let objectives: Vec<(usize, usize, Objective)> = JITTER
            .iter()
            .map(|&(dy, dx)| (dy, dx, Objective::new(self.net.as_ref(), &crop(&start, dy, dx), &self.grams, CONTENT_WEIGHT, style_weight)))
            .collect();
        let refs: Vec<(usize, usize, &Objective)> = objectives.iter().map(|(dy, dx, o)| (*dy, *dx, o)).collect();
        let (out, losses) = optimize_shifted(&refs, &start, self.steps, LEARNING_RATE);
        Ok((resize(&image_from_planes(&out), content.width, content.height), losses))
    }
}

impl Stylizer for GatysStylizer {
    fn name(&self) -> String {
        "gatys".into()
    }

    fn stylize(&self, content: &Image) -> Result<Image> {
        Ok(self.stylize_with_losses(content)?.0)
    }
}

/// The networks downsample before their last tap, so smaller images leave it empty.
fn check_size(img: &Image, what: &str, min: usize) -> Result<()> {
    if img.width < min || img.height < min {
        bail!("stylizer gatys: the {what} is {}, it needs at least {min}x{min} pixels", img.size_text());
    }
    Ok(())
}

/// Seconds per optimisation step (mean of `steps` after one warm-up) on a `size x size`
/// view with `weights`; for the benchmark numbers in reports.
pub fn step_time(weights: VggWeights, size: usize, steps: usize) -> f64 {
    net_step_time(&Vgg::new(weights), size, steps)
}

/// Seconds per optimisation step of any feature network (see `step_time`).
pub fn net_step_time(vgg: &dyn FeatureNet, size: usize, steps: usize) -> f64 {
    let img = Planes { c: 3, h: size, w: size, data: (0..3 * size * size).map(|i| (i % 97) as f32 / 97.0).collect() };
    let style = Planes { c: 3, h: size, w: size, data: (0..3 * size * size).map(|i| (i % 31) as f32 / 31.0).collect() };
    let grams = style_grams(vgg, &style);
    let obj = Objective::new(vgg, &img, &grams, CONTENT_WEIGHT, STYLE_WEIGHT);
    let _ = obj.loss_and_grad(&img);
    let t0 = Instant::now();
    let _ = optimize(&obj, &img, steps.max(1), LEARNING_RATE);
    t0.elapsed().as_secs_f64() / steps.max(1) as f64
}
