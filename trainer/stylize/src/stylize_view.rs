//! Stylizing one view as the loop and the per-frame baseline both do it: at a chosen
//! resolution, or only the object's box. The loop and the scoring modules share it, so it
//! imports neither (the scoring modules never import the loop they score).

use anyhow::{bail, Result};

use crate::stylizer::image_ops::crop;
use crate::stylizer::{Image, Stylizer};

/// Stylize at a chosen resolution: resize so the longer side is `res`, stylize, resize back
/// (0: as it is).
pub fn stylize_at(stylizer: &dyn Stylizer, img: &Image, res: usize) -> Result<Image> {
    let long = img.width.max(img.height);
    if res == 0 || res == long {
        return check_output(stylizer, img, stylizer.stylize(img)?);
    }
    let s = res as f32 / long as f32;
    let (w, h) = (((img.width as f32 * s).round() as usize).max(1), ((img.height as f32 * s).round() as usize).max(1));
    let up = resize(img, w, h);
    let out = check_output(stylizer, &up, stylizer.stylize(&up)?)?;
    Ok(resize(&out, img.width, img.height))
}

/// `stylize_at`, or with a mask (true = object), only the object's box: the mask's bounding
/// box grown by 1/16 of the view's longer side, painted at the whole view's scale
/// (`Stylizer::stylize_crop`); the view outside the box keeps its own pixels. A feed-forward
/// stylizer normalizes its features over its whole input, and an object's view is mostly
/// empty background, which would otherwise set how the object is painted. An empty mask, or
/// a box that fills the view, is the whole view.
pub fn stylize_region(stylizer: &dyn Stylizer, img: &Image, mask: Option<&[bool]>, res: usize) -> Result<Image> {
    let (w, h) = (img.width, img.height);
    let Some(mask) = mask else { return stylize_at(stylizer, img, res) };
    let Some((x0, y0, x1, y1)) = object_box(mask, w, h) else { return stylize_at(stylizer, img, res) };
    let part = crop(img, x0, y0, x1 - x0, y1 - y0);
    // `res` scales the view (and so the crop) before painting, as `stylize_at` does
    let long = w.max(h);
    let view_long = if res == 0 { long } else { res };
    let k = view_long as f32 / long as f32;
    let scaled = (view_long != long)
        .then(|| resize(&part, ((part.width as f32 * k).round() as usize).max(1), ((part.height as f32 * k).round() as usize).max(1)));
    let input = scaled.as_ref().unwrap_or(&part);
    let painted = check_output(stylizer, input, stylizer.stylize_crop(input, view_long)?)?;
    let painted = if painted.width == part.width && painted.height == part.height { painted } else { resize(&painted, part.width, part.height) };
    let mut out = img.clone();
    for y in y0..y1 {
        let row = (y - y0) * part.width * 3;
        out.data[(y * w + x0) * 3..(y * w + x1) * 3].copy_from_slice(&painted.data[row..row + part.width * 3]);
    }
    Ok(out)
}

/// The mask's bounding box with a margin of 1/16 of the longer side, as (x0, y0, x1, y1);
/// None when it is empty or fills the view.
fn object_box(mask: &[bool], w: usize, h: usize) -> Option<(usize, usize, usize, usize)> {
    let mut b = (w, h, 0, 0);
    for (p, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        let (x, y) = (p % w, p / w);
        b = (b.0.min(x), b.1.min(y), b.2.max(x + 1), b.3.max(y + 1));
    }
    let margin = w.max(h).div_ceil(16);
    let (x0, y0, x1, y1) = (b.0.saturating_sub(margin), b.1.saturating_sub(margin), (b.2 + margin).min(w), (b.3 + margin).min(h));
    (x1 > x0 && y1 > y0 && !(x1 - x0 == w && y1 - y0 == h)).then_some((x0, y0, x1, y1))
}

fn check_output(stylizer: &dyn Stylizer, input: &Image, out: Image) -> Result<Image> {
    if out.width != input.width || out.height != input.height || out.data.len() != out.width * out.height * 3 {
        bail!(
            "stylizer {} returned a {}x{} image for a {}x{} view",
            stylizer.name(),
            out.width,
            out.height,
            input.width,
            input.height
        );
    }
    if out.data.iter().any(|x| !x.is_finite()) {
        bail!("stylizer {} returned NaN or Inf for a {}x{} view", stylizer.name(), input.width, input.height);
    }
    Ok(out)
}

/// Bilinear resize of an RGB float image (the scoring modules resize the style picture with
/// it, so their figures stay comparable from release to release).
pub fn resize(img: &Image, w: usize, h: usize) -> Image {
    let buf: image::ImageBuffer<image::Rgb<f32>, Vec<f32>> =
        image::ImageBuffer::from_raw(img.width as u32, img.height as u32, img.data.clone()).expect("image size");
    let out = image::imageops::resize(&buf, w as u32, h as u32, image::imageops::FilterType::Triangle);
    Image { width: w, height: h, data: out.into_raw() }
}
