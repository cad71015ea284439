//! A style distance from deep features: Gram matrices (Gatys et al. 2016) of an
//! ImageNet-trained network's activations, pooled over a scene's pixels, compared with the
//! painting's.
//!
//! Why it is recorded beside the weight-free one (`style_metric`): Gram matrices of a
//! classifier's features are what the style-transfer literature calls style (which local
//! features occur together, whatever their exact pixels), and they are what `gatys`
//! minimizes, so the record can say how far each round is from the painting in those terms.
//!
//! What it does not do (measured, docs/stylize-notebook.md §5e, §5f): on 128² object views it does not
//! separate `arbitrary`'s per-frame stylization from the unstylized scene. With whole views
//! painted, the per-frame output is *farther* from the painting than the realistic field on
//! all nine model × painting pairs measured (realistic ÷ per-frame 0.42–0.84), at every
//! painting scale tried (½× to 2.8× the frames' footprint): the fine, high-contrast grain
//! and halo the network paints around an object on an empty background raise every tap's
//! activations, which raw Grams weigh above which features co-occur. With the object's box
//! painted (the loop paints the object's box) it is 0.95–1.48. Read it as "how far in Gram
//! terms", not as "how painted".
//!
//! The network is the MobileNetV2 trunk of Magenta's style prediction network
//! (`stylizer::gatys::MobileNet`, from `arbitrary_predict.onnx`, which the setup step
//! installs). What this does and does not share with the stylizers:
//! - `arbitrary` aims at the 100-d *embedding* at the end of that network (the
//!   `style_distance` of the consistency record); its transform network was trained
//!   against VGG Gram losses. This metric reads neither: it takes second-order statistics
//!   at the four early taps (1/2 .. 1/16 resolution), so it is independent of `arbitrary`,
//!   `preset:N` and `color`.
//! - `gatys` (on its default MobileNetV2 features) *minimizes* exactly these Grams, so for
//!   `gatys` this distance is not independent; use the weight-free one for it.
//!
//! Distance: for each tap, the Frobenius norm of the Gram difference divided by the
//! painting's Gram norm (a relative error, as in the Gatys objective), averaged over the
//! taps. Masks restrict each tap to feature positions whose whole stride block is scene;
//! deeper taps still see some background through their receptive fields (a framed photo on
//! white and on black differs by about 0.07 masked, 0.25 unmasked), so callers composite
//! every set of frames on the same background first (`PathGeometry::style_gram`). Images are compared at the same pixel footprint
//! (the painting resized so its longer side matches the frames').

use std::sync::Arc;

use anyhow::{bail, Result};

use crate::stylizer::gatys::{planes_from_image, FeatureNet, MobileNet, Planes};
use crate::stylizer::{model_path, Image, StylizerOptions, ARBITRARY_PREDICT};

/// Pooled Gram matrices of one image or a set of frames, one per tap (`c × c`, row-major).
#[derive(Clone, Debug)]
pub struct Grams {
    pub taps: Vec<Vec<f64>>,
    /// Feature positions pooled per tap (0: the tap saw no scene pixel).
    pub positions: Vec<usize>,
}

/// The feature network, loaded once and shared.
#[derive(Clone)]
pub struct GramMetric {
    net: Arc<MobileNet>,
}

impl GramMetric {
    /// Loads the network from the installed style model (errors name the file).
    pub fn open(opts: &StylizerOptions) -> Result<GramMetric> {
        Ok(GramMetric { net: Arc::new(MobileNet::load(&model_path(ARBITRARY_PREDICT, opts)?)?) })
    }

    pub fn with_net(net: Arc<MobileNet>) -> GramMetric {
        GramMetric { net }
    }

    /// Grams pooled over `images`, each with an optional mask (true = scene pixel).
    pub fn grams(&self, images: &[(&Image, Option<&[bool]>)]) -> Result<Grams> {
        let taps = self.net.taps();
        let mut sums: Vec<Vec<f64>> = Vec::with_capacity(taps);
        let mut positions = vec![0usize; taps];
        for (img, mask) in images {
            let min = self.net.min_side();
            if img.width < min || img.height < min {
                bail!("style Gram distance: a {} image is too small, it needs at least {min}x{min} pixels", img.size_text());
            }
            let trace = self.net.forward(&planes_from_image(img));
            for t in 0..taps {
                let f = trace.tap(t);
                if sums.len() <= t {
                    sums.push(vec![0.0; f.c * f.c]);
                }
                let keep = tap_mask(f, img.width, img.height, *mask);
                positions[t] += accumulate_gram(f, &keep, &mut sums[t]);
            }
        }
        let taps = sums
            .into_iter()
            .zip(&positions)
            .map(|(s, &n)| s.into_iter().map(|v| v / n.max(1) as f64).collect())
            .collect();
        Ok(Grams { taps, positions })
    }

    /// The painting's Grams at the frames' pixel footprint: resized so its longer side equals
    /// the frames' longer side.
    pub fn reference(&self, style: &Image, view_width: usize, view_height: usize) -> Result<Grams> {
        let long = view_width.max(view_height);
        let s = long as f32 / style.width.max(style.height) as f32;
        let min = self.net.min_side();
        let (w, h) = (((style.width as f32 * s).round() as usize).max(min), ((style.height as f32 * s).round() as usize).max(min));
        self.grams(&[(&crate::stylize_view::resize(style, w, h), None)])
    }
}

/// Which feature positions of a tap count: those whose stride block of input pixels is all
/// scene (`None` = all).
fn tap_mask(f: &Planes, width: usize, height: usize, mask: Option<&[bool]>) -> Vec<bool> {
    let Some(mask) = mask else { return vec![true; f.h * f.w] };
    let (sy, sx) = (height.div_ceil(f.h), width.div_ceil(f.w));
    let mut keep = vec![false; f.h * f.w];
    for y in 0..f.h {
        for x in 0..f.w {
            let (y0, x0) = (y * sy, x * sx);
            let (y1, x1) = ((y0 + sy).min(height), (x0 + sx).min(width));
            keep[y * f.w + x] = y0 < y1 && x0 < x1 && (y0..y1).all(|yy| (x0..x1).all(|xx| mask[yy * width + xx]));
        }
    }
    keep
}

/// Adds `Σ f f^T` over the kept positions to `sum`; returns how many positions were kept.
fn accumulate_gram(f: &Planes, keep: &[bool], sum: &mut [f64]) -> usize {
    let n = f.h * f.w;
    let kept: Vec<usize> = (0..n).filter(|&p| keep[p]).collect();
    if kept.is_empty() {
        return 0;
    }
    // Gather the kept columns (c × k) once, then a plain f32 product per pair of channels,
    // summed in f64.
    let c = f.c;
    let cols: Vec<Vec<f32>> = (0..c).map(|ch| kept.iter().map(|&p| f.data[ch * n + p]).collect()).collect();
    for i in 0..c {
        for j in i..c {
            let dot: f64 = cols[i].iter().zip(&cols[j]).map(|(a, b)| (*a as f64) * (*b as f64)).sum();
            sum[i * c + j] += dot;
            if i != j {
                sum[j * c + i] += dot;
            }
        }
    }
    kept.len()
}

/// Mean over taps of `|G_a − G_b| / |G_b|` (Frobenius norms; `b` is the reference). Taps
/// with no position on either side are left out; NaN when none is left.
pub fn distance(a: &Grams, b: &Grams) -> f64 {
    let mut sum = 0.0;
    let mut n = 0;
    for t in 0..a.taps.len().min(b.taps.len()) {
        if a.positions[t] == 0 || b.positions[t] == 0 {
            continue;
        }
        let diff: f64 = a.taps[t].iter().zip(&b.taps[t]).map(|(x, y)| (x - y) * (x - y)).sum();
        let norm: f64 = b.taps[t].iter().map(|y| y * y).sum();
        sum += (diff / norm.max(1e-30)).sqrt();
        n += 1;
    }
    if n == 0 {
        f64::NAN
    } else {
        sum / n as f64
    }
}
