//! The photos COLMAP sees, and later the trainer: listed from the input folder in name order,
//! then copied or converted into the capture's work folder. A PNG or JPEG that is upright (no
//! EXIF rotation) and within the size cap is copied byte for byte; anything else (a rotated
//! phone JPEG, WebP, PGM/PPM, or a photo larger than the cap) is decoded, turned upright,
//! reduced and written as PNG (JPEG at quality 95 for JPEG input), because COLMAP ignores the
//! EXIF orientation that snerf's loader applies, and the loader reads PNG, JPEG and WebP only.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Result};
use image::imageops::FilterType;
use image::{DynamicImage, ImageDecoder, ImageFormat};
use rayon::prelude::*;

/// Extensions taken from a photo folder (other files are ignored; hidden files too).
pub const PHOTO_EXTS: &[&str] = &["jpg", "jpeg", "png", "webp", "pgm", "ppm", "pnm"];

/// What happened to one photo.
#[derive(Clone, Debug)]
pub struct Staged {
    /// The file the user gave.
    pub source: PathBuf,
    /// Its name in the dataset's `images/` (what COLMAP calls the image).
    pub name: String,
    /// Re-encoded (rotated, reduced or converted) rather than copied.
    pub converted: bool,
}

/// The photos in `dir`, sorted by name; an error when there are fewer than `min`.
pub fn list(dir: &Path, min: usize) -> Result<Vec<PathBuf>> {
    let rd = std::fs::read_dir(dir)
        .map_err(|e| anyhow!("{}: cannot list the photo folder: {e}", dir.display()))?;
    let mut out = Vec::new();
    for entry in rd {
        let p = entry
            .map_err(|e| anyhow!("{}: cannot list the photo folder: {e}", dir.display()))?
            .path();
        let hidden = p
            .file_name()
            .and_then(|n| n.to_str())
            .is_some_and(|n| n.starts_with('.'));
        if p.is_file() && !hidden && ext_of(&p).is_some_and(|e| PHOTO_EXTS.contains(&e.as_str())) {
            out.push(p);
        }
    }
    out.sort();
    if out.len() < min {
        bail!(
            "{}: {} photo(s) found ({}), at least {min} are needed for poses",
            dir.display(),
            out.len(),
            PHOTO_EXTS.join(", ")
        );
    }
    Ok(out)
}

fn ext_of(p: &Path) -> Option<String> {
    p.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
}

/// The names the photos get in `images/`: the file name when copied, `STEM.png` / `STEM.jpg`
/// when converted; two photos that would share a name keep their whole original name in front.
fn target_name(src: &Path, converted_ext: Option<&str>, taken: &mut Vec<String>) -> String {
    let file = src.file_name().and_then(|n| n.to_str()).unwrap_or("photo");
    let stem = src.file_stem().and_then(|n| n.to_str()).unwrap_or("photo");
    let mut name = match converted_ext {
        None => file.to_string(),
        Some(e) => format!("{stem}.{e}"),
    };
    if taken.contains(&name) {
        name = match converted_ext {
            None => format!("{}-{file}", taken.len()),
            Some(e) => format!("{file}.{e}"),
        };
    }
    taken.push(name.clone());
    name
}

/// How a photo must be treated, from its header (no pixels decoded).
struct Probe {
    format: ImageFormat,
    upright: bool,
    width: u32,
    height: u32,
}

fn probe(p: &Path) -> Result<Probe> {
    let reader = image::ImageReader::open(p)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| anyhow!("{}: cannot open photo: {e}", p.display()))?;
    let format = reader.format().ok_or_else(|| {
        anyhow!(
            "{}: not a photo snerf can read (JPEG, PNG, WebP or PGM/PPM)",
            p.display()
        )
    })?;
    let mut dec = reader
        .into_decoder()
        .map_err(|e| anyhow!("{}: cannot decode photo: {e}", p.display()))?;
    let upright = matches!(
        dec.orientation(),
        Ok(image::metadata::Orientation::NoTransforms) | Err(_)
    );
    let (width, height) = dec.dimensions();
    if width == 0 || height == 0 {
        bail!("{}: photo is empty ({width}x{height})", p.display());
    }
    Ok(Probe {
        format,
        upright,
        width,
        height,
    })
}

/// Decodes, turns upright (EXIF) and reduces so the longer side is at most `max_size`.
fn decode_upright(p: &Path, max_size: u32) -> Result<DynamicImage> {
    let reader = image::ImageReader::open(p)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| anyhow!("{}: cannot open photo: {e}", p.display()))?;
    let mut dec = reader
        .into_decoder()
        .map_err(|e| anyhow!("{}: cannot decode photo: {e}", p.display()))?;
    let orientation = dec
        .orientation()
        .unwrap_or(image::metadata::Orientation::NoTransforms);
    let mut img = DynamicImage::from_decoder(dec)
        .map_err(|e| anyhow!("{}: cannot decode photo: {e}", p.display()))?;
    img.apply_orientation(orientation);
    if let Some((w, h)) = crate::images::capped_size(img.width(), img.height(), max_size) {
        img = img.resize_exact(w, h, FilterType::CatmullRom);
    }
    // 16-bit and float images become 8-bit: COLMAP and the loader both work in 8 bits.
    Ok(match img {
        DynamicImage::ImageLuma8(_) | DynamicImage::ImageRgb8(_) | DynamicImage::ImageRgba8(_) => {
            img
        }
        DynamicImage::ImageLuma16(_)
        | DynamicImage::ImageLumaA8(_)
        | DynamicImage::ImageLumaA16(_) => DynamicImage::ImageLuma8(img.to_luma8()),
        other if other.color().has_alpha() => DynamicImage::ImageRgba8(other.to_rgba8()),
        other => DynamicImage::ImageRgb8(other.to_rgb8()),
    })
}

/// Copies or converts each photo into `dir` (in parallel). Every photo must be readable: a corrupt one is named in the error rather than
/// silently left out of the capture.
pub fn stage(photos: &[PathBuf], dir: &Path, max_size: u32) -> Result<Vec<Staged>> {
    std::fs::create_dir_all(dir).map_err(|e| anyhow!("{}: cannot create: {e}", dir.display()))?;
    let probes: Vec<Probe> = photos.par_iter().map(|p| probe(p)).collect::<Result<_>>()?;
    let mut taken = Vec::new();
    let plan: Vec<(String, bool)> = photos
        .iter()
        .zip(&probes)
        .map(|(p, pr)| {
            let copy = pr.upright
                && matches!(pr.format, ImageFormat::Png | ImageFormat::Jpeg)
                && (max_size == 0 || pr.width.max(pr.height) <= max_size);
            let ext = match (copy, pr.format) {
                (true, _) => None,
                (false, ImageFormat::Jpeg) => Some("jpg"),
                (false, _) => Some("png"),
            };
            (target_name(p, ext, &mut taken), !copy)
        })
        .collect();
    photos
        .par_iter()
        .zip(&plan)
        .map(|(src, (name, convert))| {
            let dst = dir.join(name);
            if *convert {
                let img = decode_upright(src, max_size)?;
                let fmt = if name.ends_with(".jpg") {
                    ImageFormat::Jpeg
                } else {
                    ImageFormat::Png
                };
                write_image(&img, &dst, fmt)?;
            } else {
                std::fs::copy(src, &dst).map_err(|e| {
                    anyhow!("{}: cannot copy to {}: {e}", src.display(), dst.display())
                })?;
            }
            Ok(Staged {
                source: src.clone(),
                name: name.clone(),
                converted: *convert,
            })
        })
        .collect()
}

fn write_image(img: &DynamicImage, dst: &Path, fmt: ImageFormat) -> Result<()> {
    let file =
        std::fs::File::create(dst).map_err(|e| anyhow!("{}: cannot create: {e}", dst.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let r = if fmt == ImageFormat::Jpeg {
        let enc = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut w, 95);
        match img {
            DynamicImage::ImageRgba8(_) => img.to_rgb8().write_with_encoder(enc),
            _ => img.write_with_encoder(enc),
        }
    } else {
        img.write_to(&mut w, ImageFormat::Png)
    };
    r.map_err(|e| anyhow!("{}: cannot write: {e}", dst.display()))?;
    use std::io::Write;
    w.flush()
        .map_err(|e| anyhow!("{}: cannot write: {e}", dst.display()))
}
