//! Image files in: PNG decoding to RGBA8 (8/16-bit, gray/RGB/RGBA), the size checks against the
//! intrinsics the format declared, integer box-filter downscaling, and parallel loading of a
//! whole split with rayon.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Result};
use rayon::prelude::*;

use crate::{Intrinsics, View};

/// Extensions recognised as images when listing a folder (only PNG can be decoded).
const IMAGE_EXTS: &[&str] = &[
    "png", "jpg", "jpeg", "exr", "bmp", "tif", "tiff", "webp", "gif", "hdr",
];

/// How a view's intrinsics follow from its image file.
#[derive(Clone, Copy, Debug)]
pub(crate) enum CameraSpec {
    /// Intrinsics for an image of exactly `width x height`; another size is an error.
    Exact(Intrinsics),
    /// Intrinsics given for a reference size; scaled by `file width / reference width` to the
    /// file's size (LLFF focal, `images_N` folders). The aspect ratio must agree.
    Scaled(Intrinsics),
    /// Focal length from the horizontal (and optionally vertical) field of view in radians;
    /// principal point at the centre (Blender synthetic).
    Fov {
        angle_x: f64,
        angle_y: Option<f64>,
        distortion: [f32; 4],
    },
    /// Focal lengths in pixels, optional principal point (centre when absent), size from the file.
    Focal {
        fx: f64,
        fy: f64,
        cx: Option<f64>,
        cy: Option<f64>,
        distortion: [f32; 4],
    },
}

/// A view whose pose is known and whose image has not been read yet.
#[derive(Clone, Debug)]
pub(crate) struct PendingView {
    pub path: PathBuf,
    pub camera: CameraSpec,
    pub c2w: [[f32; 4]; 3],
    pub time: Option<f32>,
    /// Where the view was declared, for messages ("transforms.json frame 3").
    pub origin: String,
}

/// Errors unless `path` has a PNG extension.
pub(crate) fn check_png_extension(path: &Path) -> Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("png") => Ok(()),
        Some(e) => bail!(
            "{}: unsupported image format '.{e}': this build reads PNG only (convert the images to PNG)",
            path.display()
        ),
        None => bail!("{}: image file has no extension (expected .png)", path.display()),
    }
}

pub(crate) fn is_image_file(path: &Path) -> bool {
    path.is_file()
        && path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| IMAGE_EXTS.contains(&e.to_ascii_lowercase().as_str()))
            .unwrap_or(false)
}

/// Sorted image files in `dir`; errors for an unreadable folder and for non-PNG images.
pub(crate) fn list_images(dir: &Path) -> Result<Vec<PathBuf>> {
    let rd = std::fs::read_dir(dir)
        .map_err(|e| anyhow!("{}: cannot list image folder: {e}", dir.display()))?;
    let mut out = Vec::new();
    for entry in rd {
        let p = entry
            .map_err(|e| anyhow!("{}: cannot list image folder: {e}", dir.display()))?
            .path();
        if is_image_file(&p) {
            check_png_extension(&p)?;
            out.push(p);
        }
    }
    out.sort();
    Ok(out)
}

/// Decodes an image file into (width, height, RGBA8).
pub(crate) fn read_rgba(path: &Path) -> Result<(u32, u32, Vec<u8>)> {
    check_png_extension(path)?;
    if !path.is_file() {
        bail!("{}: image file not found", path.display());
    }
    let img = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| anyhow!("{}: cannot open image: {e}", path.display()))?
        .decode()
        .map_err(|e| anyhow!("{}: cannot decode image: {e}", path.display()))?;
    let rgba = img.to_rgba8();
    let (w, h) = rgba.dimensions();
    if w == 0 || h == 0 {
        bail!("{}: image is empty ({w}x{h})", path.display());
    }
    Ok((w, h, rgba.into_raw()))
}

/// Integer box-filter downscale of RGBA8 by `s`; the image is cropped to a multiple of `s`.
pub(crate) fn downscale_box(w: u32, h: u32, rgba: &[u8], s: u32) -> (u32, u32, Vec<u8>) {
    if s <= 1 {
        return (w, h, rgba.to_vec());
    }
    let (w2, h2) = (w / s, h / s);
    let n = s * s;
    let mut out = vec![0u8; (w2 * h2 * 4) as usize];
    for y in 0..h2 {
        for x in 0..w2 {
            let mut acc = [0u32; 4];
            for dy in 0..s {
                let row = ((y * s + dy) * w + x * s) as usize * 4;
                for dx in 0..s as usize {
                    for c in 0..4 {
                        acc[c] += rgba[row + dx * 4 + c] as u32;
                    }
                }
            }
            let o = ((y * w2 + x) * 4) as usize;
            for c in 0..4 {
                out[o + c] = ((acc[c] + n / 2) / n) as u8;
            }
        }
    }
    (w2, h2, out)
}

/// Intrinsics for an image of `w x h` as read from disk (before any downscale).
fn resolve_intrinsics(spec: &CameraSpec, w: u32, h: u32, pv: &PendingView) -> Result<Intrinsics> {
    let p = pv.path.display();
    Ok(match *spec {
        CameraSpec::Exact(k) => {
            if (k.width, k.height) != (w, h) {
                bail!(
                    "{p}: image is {w}x{h} but {} declares {}x{}",
                    pv.origin,
                    k.width,
                    k.height
                );
            }
            k
        }
        CameraSpec::Scaled(k) => {
            let s = w as f64 / k.width as f64;
            let expect_h = k.height as f64 * s;
            if (h as f64 - expect_h).abs() > 1.0 + 0.01 * expect_h {
                bail!(
                    "{p}: image is {w}x{h}, which does not have the aspect ratio of the {}x{} \
                     declared by {}",
                    k.width,
                    k.height,
                    pv.origin
                );
            }
            let s = s as f32;
            Intrinsics {
                width: w,
                height: h,
                fx: k.fx * s,
                fy: k.fy * s,
                cx: k.cx * s,
                cy: k.cy * s,
                distortion: k.distortion,
            }
        }
        CameraSpec::Fov {
            angle_x,
            angle_y,
            distortion,
        } => {
            let fx = 0.5 * w as f64 / (0.5 * angle_x).tan();
            let fy = angle_y
                .map(|a| 0.5 * h as f64 / (0.5 * a).tan())
                .unwrap_or(fx);
            Intrinsics {
                width: w,
                height: h,
                fx: fx as f32,
                fy: fy as f32,
                cx: w as f32 * 0.5,
                cy: h as f32 * 0.5,
                distortion,
            }
        }
        CameraSpec::Focal {
            fx,
            fy,
            cx,
            cy,
            distortion,
        } => Intrinsics {
            width: w,
            height: h,
            fx: fx as f32,
            fy: fy as f32,
            cx: cx.unwrap_or(w as f64 * 0.5) as f32,
            cy: cy.unwrap_or(h as f64 * 0.5) as f32,
            distortion,
        },
    })
}

/// Reads every pending view's image in parallel, checks its size, applies the downscale.
pub(crate) fn load_views(pending: Vec<PendingView>, downscale: u32) -> Result<Vec<View>> {
    let s = downscale.max(1);
    pending
        .into_par_iter()
        .map(|pv| {
            let (w, h, rgba) = read_rgba(&pv.path)?;
            let k = resolve_intrinsics(&pv.camera, w, h, &pv)?;
            if w < s || h < s {
                bail!(
                    "{}: image {w}x{h} is smaller than the downscale factor {s}",
                    pv.path.display()
                );
            }
            let (k, rgba) = if s > 1 {
                let (_, _, small) = downscale_box(w, h, &rgba, s);
                (k.downscaled(s), small)
            } else {
                (k, rgba)
            };
            Ok(View {
                path: pv.path,
                intrinsics: k,
                c2w: pv.c2w,
                time: pv.time,
                rgba,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_downscale_averages_and_crops() {
        // 5x2 image, s = 2 -> 2x1 (last column cropped).
        let mut px = Vec::new();
        for y in 0..2u8 {
            for x in 0..5u8 {
                px.extend([x * 10 + y, 100, 200, 255]);
            }
        }
        let (w, h, out) = downscale_box(5, 2, &px, 2);
        assert_eq!((w, h), (2, 1));
        // Mean of 0,1,10,11 = 5.5 -> 6 (rounded); of 20,21,30,31 = 25.5 -> 26.
        assert_eq!(&out[..4], &[6, 100, 200, 255]);
        assert_eq!(out[4], 26);
    }
}
