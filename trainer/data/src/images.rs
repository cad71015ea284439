//! Image files in: decoding PNG (8/16-bit, gray/RGB/RGBA), JPEG and WebP to RGBA8 with the EXIF
//! orientation applied, the size checks against the intrinsics the format declared, the two
//! size reductions, a cache of reduced images, and parallel loading of a whole split with rayon.
//!
//! Formats: PNG, JPEG and WebP, recognised by content (a `.jpg` that holds PNG bytes still
//! loads). These are what cameras, phones, COLMAP, LLFF and nerfstudio captures write; EXR,
//! TIFF, HEIC and the rest are refused with a message that names the file. JPEG and WebP carry
//! an EXIF Orientation tag when a phone was held sideways: the pixels are rotated/flipped as the
//! tag says before anything else, because that is the picture the photographer saw and what
//! nerfstudio and COLMAP-via-ffmpeg pipelines see. When that makes the image disagree with a
//! declared size that the stored (unrotated) pixels match, the error says so.
//!
//! Size: `downscale` (`--downscale N`) is an integer box filter (crop to a multiple of N, mean
//! of each N×N block), or the `images_N/` folder when the dataset has one. `max_size`
//! (`--max-size PX`, default [`DEFAULT_MAX_SIZE`]) then caps the longer side: a 4000×3000 phone
//! photo is 48 MB of RGBA8 per view and far more pixels than a field trained on two cores can
//! use, so images are resized once at load with a Catmull-Rom (bicubic) filter that widens to
//! the reduction (antialiased), in premultiplied alpha when the image is translucent; the
//! intrinsics scale with the exact width and height ratios. 1600 px follows nerfstudio's own
//! automatic downscale; synthetic data (800×800) is untouched.
//!
//! Memory: each view is decoded, reduced and its full-size buffers dropped inside one rayon
//! task, so at most one full-size image per rayon thread (= cores) is alive at a time, never
//! the whole dataset at full size.
//!
//! Cache: a reduced image whose original had at least [`CACHE_MIN_PIXELS`] pixels is written to
//! `${XDG_CACHE_HOME:-$HOME/.cache}/snerf/images/` (or `LoadOptions::cache_dir`) as a small
//! header plus PNG, keyed by the file's absolute path, size and modification time and by the
//! reduction asked for, so the second load of a phone capture decodes a small PNG instead of
//! the full JPEG. A cache folder rather than `images_N/` beside the data: the dataset folder may
//! be read-only or shared, a `--max-size` reduction is not an integer factor, and an edited or
//! replaced photo changes the key so a stale copy is never used. Entries are never evicted
//! (delete the folder to reclaim space); a cache that cannot be written is reported once and
//! loading goes on without it.

use std::path::{Path, PathBuf};
use std::sync::Once;

use anyhow::{anyhow, bail, Result};
use image::imageops::FilterType;
use image::{DynamicImage, ImageDecoder, ImageFormat};
use rayon::prelude::*;

use crate::{Intrinsics, View};

/// Default cap on the longer image side in pixels (`LoadOptions::max_size`).
pub const DEFAULT_MAX_SIZE: u32 = 1600;

/// Originals smaller than this (pixels) are not cached: decoding them costs about what decoding
/// the cached copy would, and small test datasets should not write into the user's cache.
pub const CACHE_MIN_PIXELS: u64 = 1 << 20;

/// Extensions recognised as images when listing a folder.
const IMAGE_EXTS: &[&str] = &[
    "png", "jpg", "jpeg", "webp", "exr", "bmp", "tif", "tiff", "gif", "hdr", "heic", "heif", "avif",
];

/// The extensions of the formats this crate decodes.
pub(crate) const READABLE_EXTS: &[&str] = &["png", "jpg", "jpeg", "webp"];

const FORMATS_MSG: &str = "snerf reads PNG, JPEG and WebP (convert the images to one of these)";

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

/// Errors unless `path` has the extension of a format this crate reads.
pub(crate) fn check_image_extension(path: &Path) -> Result<()> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some(e) if READABLE_EXTS.contains(&e) => Ok(()),
        Some(e) => bail!(
            "{}: unsupported image format '.{e}': {FORMATS_MSG}",
            path.display()
        ),
        None => bail!(
            "{}: image file has no extension (expected .png, .jpg, .jpeg or .webp)",
            path.display()
        ),
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

/// Sorted image files in `dir`; errors for an unreadable folder and for images in a format this
/// crate cannot read (skipping them would silently pair the wrong poses with the rest).
pub(crate) fn list_images(dir: &Path) -> Result<Vec<PathBuf>> {
    let rd = std::fs::read_dir(dir)
        .map_err(|e| anyhow!("{}: cannot list image folder: {e}", dir.display()))?;
    let mut out = Vec::new();
    for entry in rd {
        let p = entry
            .map_err(|e| anyhow!("{}: cannot list image folder: {e}", dir.display()))?
            .path();
        if is_image_file(&p) {
            check_image_extension(&p)?;
            out.push(p);
        }
    }
    out.sort();
    Ok(out)
}

/// A decoded image with its EXIF orientation applied.
pub(crate) struct Decoded {
    pub img: DynamicImage,
    /// The orientation swapped width and height (90/270° rotations).
    pub transposed: bool,
}

/// Decodes a PNG, JPEG or WebP file (format from its content) and applies its EXIF orientation.
pub(crate) fn decode(path: &Path) -> Result<Decoded> {
    check_image_extension(path)?;
    if !path.is_file() {
        bail!("{}: image file not found", path.display());
    }
    let reader = image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| anyhow!("{}: cannot open image: {e}", path.display()))?;
    match reader.format() {
        Some(ImageFormat::Png | ImageFormat::Jpeg | ImageFormat::WebP) => {}
        Some(f) => bail!(
            "{}: unsupported image format ({}): {FORMATS_MSG}",
            path.display(),
            f.extensions_str().first().copied().unwrap_or("unknown")
        ),
        // Unreachable after the extension check (the extension supplies a format when the
        // content is unrecognised), kept so a future caller without that check still gets a
        // message naming the file.
        None => bail!(
            "{}: cannot decode image: not a PNG, JPEG or WebP file",
            path.display()
        ),
    }
    let mut decoder = reader
        .into_decoder()
        .map_err(|e| anyhow!("{}: cannot decode image: {e}", path.display()))?;
    // A malformed EXIF block is not worth refusing the pixels for: treat it as upright.
    let orientation = decoder
        .orientation()
        .unwrap_or(image::metadata::Orientation::NoTransforms);
    let mut img = DynamicImage::from_decoder(decoder)
        .map_err(|e| anyhow!("{}: cannot decode image: {e}", path.display()))?;
    img.apply_orientation(orientation);
    let transposed = matches!(
        orientation,
        image::metadata::Orientation::Rotate90
            | image::metadata::Orientation::Rotate270
            | image::metadata::Orientation::Rotate90FlipH
            | image::metadata::Orientation::Rotate270FlipH
    );
    if img.width() == 0 || img.height() == 0 {
        bail!(
            "{}: image is empty ({}x{})",
            path.display(),
            img.width(),
            img.height()
        );
    }
    Ok(Decoded { img, transposed })
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

/// Intrinsics for an image of `w x h` as decoded (orientation applied, before any reduction).
/// `transposed`: the EXIF orientation swapped the sides, which a size mismatch then mentions.
fn resolve_intrinsics(
    spec: &CameraSpec,
    w: u32,
    h: u32,
    pv: &PendingView,
    transposed: bool,
) -> Result<Intrinsics> {
    let p = pv.path.display();
    let hint = if transposed {
        " (after the 90° rotation its EXIF Orientation tag asks for; the poses were probably \
         computed on the unrotated pixels: remove the tag, e.g. `exiftool -Orientation= FILE`, \
         or rotate the pixels and fix the camera)"
    } else {
        ""
    };
    Ok(match *spec {
        CameraSpec::Exact(k) => {
            if (k.width, k.height) != (w, h) {
                bail!(
                    "{p}: image is {w}x{h}{hint} but {} declares {}x{}",
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
                    "{p}: image is {w}x{h}{hint}, which does not have the aspect ratio of the \
                     {}x{} declared by {}",
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

/// The size whose longer side is `max_size`, or `None` when the image already fits (or
/// `max_size` is 0, no cap).
pub(crate) fn capped_size(w: u32, h: u32, max_size: u32) -> Option<(u32, u32)> {
    let long = w.max(h);
    if max_size == 0 || long <= max_size {
        return None;
    }
    let s = max_size as f64 / long as f64;
    let w2 = ((w as f64 * s).round() as u32).clamp(1, max_size);
    let h2 = ((h as f64 * s).round() as u32).clamp(1, max_size);
    Some((w2, h2))
}

/// Resizes RGBA8 to `w2 x h2` with an antialiased Catmull-Rom filter. Translucent images are
/// filtered premultiplied (the filter assumes it), so the colour of fully transparent pixels
/// does not bleed into the object's silhouette.
pub(crate) fn resize_rgba(w: u32, h: u32, rgba: Vec<u8>, w2: u32, h2: u32) -> Vec<u8> {
    let filter = FilterType::CatmullRom;
    if rgba.chunks_exact(4).all(|p| p[3] == 255) {
        let img = image::RgbaImage::from_raw(w, h, rgba).expect("rgba buffer size");
        return image::imageops::resize(&img, w2, h2, filter).into_raw();
    }
    let mut f = image::Rgba32FImage::new(w, h);
    for (d, s) in f.pixels_mut().zip(rgba.chunks_exact(4)) {
        let a = s[3] as f32 / 255.0;
        d.0 = [
            s[0] as f32 / 255.0 * a,
            s[1] as f32 / 255.0 * a,
            s[2] as f32 / 255.0 * a,
            a,
        ];
    }
    drop(rgba);
    let small = image::imageops::resize(&f, w2, h2, filter);
    let mut out = Vec::with_capacity((w2 * h2 * 4) as usize);
    for p in small.pixels() {
        let a = p.0[3].clamp(0.0, 1.0);
        let un = |c: f32| {
            if a > 0.0 {
                ((c / a).clamp(0.0, 1.0) * 255.0).round() as u8
            } else {
                0
            }
        };
        out.extend([
            un(p.0[0]),
            un(p.0[1]),
            un(p.0[2]),
            (a * 255.0).round() as u8,
        ]);
    }
    out
}

/// How a split's images are reduced at load, and where reduced copies are cached.
#[derive(Clone, Debug)]
pub(crate) struct Reduce {
    /// Integer box downscale (1 = none).
    pub downscale: u32,
    /// Cap on the longer side after the downscale (0 = none).
    pub max_size: u32,
    /// Where reduced copies go; `None` disables the cache.
    pub cache_dir: Option<PathBuf>,
}

impl Reduce {
    pub fn new(downscale: u32, opts: &crate::LoadOptions) -> Reduce {
        Reduce {
            downscale: downscale.max(1),
            max_size: opts.max_size.unwrap_or(DEFAULT_MAX_SIZE),
            cache_dir: opts.cache_dir.clone().or_else(default_cache_dir),
        }
    }
}

/// `${XDG_CACHE_HOME:-$HOME/.cache}/snerf/images` (the rule the model cache follows).
pub fn default_cache_dir() -> Option<PathBuf> {
    let base = match std::env::var_os("XDG_CACHE_HOME") {
        Some(x) if !x.is_empty() => PathBuf::from(x),
        _ => PathBuf::from(std::env::var_os("HOME").filter(|h| !h.is_empty())?).join(".cache"),
    };
    Some(base.join("snerf").join("images"))
}

/// Bumped when the decode or reduction changes what a cache entry would hold.
const CACHE_MAGIC: &[u8; 8] = b"SNIMGC01";

/// 64-bit FNV-1a: stable across Rust versions and runs, unlike `DefaultHasher`.
fn fnv1a(bytes: &[u8], mut h: u64) -> u64 {
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x100_0000_01b3);
    }
    h
}

/// The cache file for `path` under `r`, or `None` when the file cannot be stat'ed.
fn cache_path(path: &Path, r: &Reduce, dir: &Path) -> Option<PathBuf> {
    let abs = std::fs::canonicalize(path).ok()?;
    let meta = std::fs::metadata(&abs).ok()?;
    let mtime = meta
        .modified()
        .ok()?
        .duration_since(std::time::UNIX_EPOCH)
        .ok()?;
    let mut h = fnv1a(CACHE_MAGIC, 0xcbf2_9ce4_8422_2325);
    h = fnv1a(abs.as_os_str().as_encoded_bytes(), h);
    for v in [
        meta.len(),
        mtime.as_secs(),
        mtime.subsec_nanos() as u64,
        r.downscale as u64,
        r.max_size as u64,
    ] {
        h = fnv1a(&v.to_le_bytes(), h);
    }
    let stem = abs
        .file_stem()
        .map(|s| {
            s.to_string_lossy().replace(
                |c: char| !c.is_ascii_alphanumeric() && c != '-' && c != '_',
                "_",
            )
        })
        .unwrap_or_default();
    Some(dir.join(format!("{stem}-{h:016x}.snimg")))
}

/// A cached entry: (original oriented width, height, reduced width, height, RGBA8), or `None`
/// for a miss or an unreadable entry (which is then rewritten).
fn read_cache(p: &Path) -> Option<(u32, u32, u32, u32, Vec<u8>)> {
    let bytes = std::fs::read(p).ok()?;
    if bytes.len() < 16 || &bytes[..8] != CACHE_MAGIC {
        return None;
    }
    let ow = u32::from_le_bytes(bytes[8..12].try_into().ok()?);
    let oh = u32::from_le_bytes(bytes[12..16].try_into().ok()?);
    let img = image::load_from_memory_with_format(&bytes[16..], ImageFormat::Png).ok()?;
    let rgba = img.into_rgba8();
    let (w, h) = rgba.dimensions();
    Some((ow, oh, w, h, rgba.into_raw()))
}

fn write_cache(p: &Path, ow: u32, oh: u32, w: u32, h: u32, rgba: &[u8]) {
    let result = (|| -> Result<()> {
        std::fs::create_dir_all(snerf_files::atomic::parent_dir(p))?;
        let mut bytes = Vec::with_capacity(rgba.len() / 2);
        bytes.extend_from_slice(CACHE_MAGIC);
        bytes.extend_from_slice(&ow.to_le_bytes());
        bytes.extend_from_slice(&oh.to_le_bytes());
        // Fast compression: the entry is read back by this machine, size matters less than time.
        let enc = image::codecs::png::PngEncoder::new_with_quality(
            &mut bytes,
            image::codecs::png::CompressionType::Fast,
            image::codecs::png::FilterType::Adaptive,
        );
        image::ImageEncoder::write_image(enc, rgba, w, h, image::ExtendedColorType::Rgba8)?;
        snerf_files::write_atomic(p, &bytes)
    })();
    if let Err(e) = result {
        static WARN: Once = Once::new();
        WARN.call_once(|| {
            eprintln!(
                "warning: cannot write the downscaled-image cache ({}): {e:#}; loading goes on \
                 without it",
                p.display()
            )
        });
    }
}

/// One view's image at training size, with the decoded size its camera is checked against.
struct Loaded {
    orig: (u32, u32),
    transposed: bool,
    size: (u32, u32),
    rgba: Vec<u8>,
}

/// Reads the cache first when a reduction may apply; otherwise decodes, reduces, and caches.
fn load_one(pv: &PendingView, r: &Reduce) -> Result<Loaded> {
    let may_reduce = r.downscale > 1 || r.max_size > 0;
    let cache = match &r.cache_dir {
        Some(dir) if may_reduce => cache_path(&pv.path, r, dir),
        _ => None,
    };
    if let Some((ow, oh, w, h, rgba)) = cache.as_deref().and_then(read_cache) {
        // `transposed` only feeds an error hint, and an entry is only written after the size
        // checks passed, so false is exact enough here.
        return Ok(Loaded {
            orig: (ow, oh),
            transposed: false,
            size: (w, h),
            rgba,
        });
    }
    let d = decode(&pv.path)?;
    let transposed = d.transposed;
    let rgba = d.img.into_rgba8();
    let (w, h) = rgba.dimensions();
    let mut rgba = rgba.into_raw();
    let s = r.downscale;
    if w < s || h < s {
        bail!(
            "{}: image {w}x{h} is smaller than the downscale factor {s}",
            pv.path.display()
        );
    }
    let (mut cw, mut ch) = (w, h);
    if s > 1 {
        let (w2, h2, small) = downscale_box(w, h, &rgba, s);
        (cw, ch, rgba) = (w2, h2, small);
    }
    if let Some((w2, h2)) = capped_size(cw, ch, r.max_size) {
        rgba = resize_rgba(cw, ch, rgba, w2, h2);
        (cw, ch) = (w2, h2);
    }
    let reduced = (cw, ch) != (w, h);
    if let Some(p) = cache.filter(|_| reduced && (w as u64 * h as u64) >= CACHE_MIN_PIXELS) {
        // Written only for images whose size agrees with their camera, so a cached entry never
        // skips that check.
        if resolve_intrinsics(&pv.camera, w, h, pv, transposed).is_ok() {
            write_cache(&p, w, h, cw, ch, &rgba);
        }
    }
    Ok(Loaded {
        orig: (w, h),
        transposed,
        size: (cw, ch),
        rgba,
    })
}

/// Reads every pending view's image in parallel (one full-size image per rayon thread at a
/// time), checks its size against its camera, and reduces it as `r` says.
pub(crate) fn load_views(pending: Vec<PendingView>, r: &Reduce) -> Result<Vec<View>> {
    pending
        .into_par_iter()
        .map(|pv| {
            let l = load_one(&pv, r)?;
            let (w, h) = l.orig;
            let mut k = resolve_intrinsics(&pv.camera, w, h, &pv, l.transposed)?;
            if r.downscale > 1 {
                k = k.downscaled(r.downscale);
            }
            if (k.width, k.height) != l.size {
                k = k.resized(l.size.0, l.size.1);
            }
            Ok(View {
                path: pv.path,
                intrinsics: k,
                c2w: pv.c2w,
                time: pv.time,
                rgba: l.rgba,
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
