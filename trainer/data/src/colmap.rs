//! COLMAP sparse models in, text and binary: `cameras.{txt,bin}` (SIMPLE_PINHOLE, PINHOLE,
//! SIMPLE_RADIAL, RADIAL, OPENCV) and `images.{txt,bin}` (world-to-camera quaternion and
//! translation in OpenCV axes, converted to OpenGL camera-to-world). Images are read from the
//! `images/` folder next to `sparse/` (or `images_N` for a downscale of N when present).
//! Binary reads are bounded: every count is checked against the bytes left before allocating.
//! `points3D.bin`, when present, gives the depth bounds (`colmap_points`).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Result};

use crate::colmap_points::{near_far, read_points_bin, BoundCamera};
use crate::images::{self, CameraSpec, PendingView};
use crate::pose::{quat_to_mat, rigid_c2w, w2c_opencv_to_c2w_opengl};
use crate::{holdout_split, Intrinsics, LoadOptions, RawDataset};

/// Camera models by COLMAP id: (id, name, number of parameters).
const MODELS: &[(i32, &str, usize)] = &[
    (0, "SIMPLE_PINHOLE", 3),
    (1, "PINHOLE", 4),
    (2, "SIMPLE_RADIAL", 4),
    (3, "RADIAL", 5),
    (4, "OPENCV", 8),
    (5, "OPENCV_FISHEYE", 8),
    (6, "FULL_OPENCV", 12),
    (7, "FOV", 5),
    (8, "SIMPLE_RADIAL_FISHEYE", 4),
    (9, "RADIAL_FISHEYE", 5),
    (10, "THIN_PRISM_FISHEYE", 12),
    (11, "RAD_TAN_THIN_PRISM_FISHEYE", 16),
];
const SUPPORTED: &str = "SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV";

#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Camera {
    pub model: String,
    pub width: u64,
    pub height: u64,
    pub params: Vec<f64>,
}

#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Image {
    /// The id points3D tracks refer to.
    pub id: u32,
    pub qvec: [f64; 4],
    pub tvec: [f64; 3],
    pub camera_id: u32,
    pub name: String,
}

pub(crate) fn load(model_dir: &Path, opts: &LoadOptions) -> Result<RawDataset> {
    let (cams_path, cameras) = if model_dir.join("cameras.bin").is_file() {
        let p = model_dir.join("cameras.bin");
        let c = read_cameras_bin(&read_bytes(&p)?).map_err(|e| anyhow!("{}: {e}", p.display()))?;
        (p, c)
    } else {
        let p = model_dir.join("cameras.txt");
        let c = read_cameras_txt(&read_text(&p)?).map_err(|e| anyhow!("{}: {e}", p.display()))?;
        (p, c)
    };
    let (imgs_path, mut imgs) = if model_dir.join("images.bin").is_file() {
        let p = model_dir.join("images.bin");
        let i = read_images_bin(&read_bytes(&p)?).map_err(|e| anyhow!("{}: {e}", p.display()))?;
        (p, i)
    } else {
        let p = model_dir.join("images.txt");
        let i = read_images_txt(&read_text(&p)?).map_err(|e| anyhow!("{}: {e}", p.display()))?;
        (p, i)
    };
    if imgs.is_empty() {
        bail!("{}: no registered images", imgs_path.display());
    }
    imgs.sort_by(|a, b| a.name.cmp(&b.name));

    let root = dataset_root(model_dir);
    let s = opts.downscale.unwrap_or(1).max(1);
    let base = root.join("images");
    let (img_dir, software_downscale, scaled) = match root.join(format!("images_{s}")) {
        d if s > 1 && d.is_dir() => (d, 1, true),
        _ => (base, s, false),
    };
    if !img_dir.is_dir() {
        bail!(
            "{}: image folder not found (COLMAP images go in images/ next to sparse/)",
            img_dir.display()
        );
    }

    let mut intr: HashMap<u32, Intrinsics> = HashMap::new();
    for (&id, cam) in &cameras {
        intr.insert(
            id,
            intrinsics(cam).map_err(|e| anyhow!("{}: camera {id}: {e}", cams_path.display()))?,
        );
    }
    let mut pending = Vec::with_capacity(imgs.len());
    let mut bound_cams = Vec::with_capacity(imgs.len());
    for img in &imgs {
        let what = format!("image '{}'", img.name);
        let k = *intr.get(&img.camera_id).ok_or_else(|| {
            anyhow!(
                "{}: {what} uses camera {} which {} does not define",
                imgs_path.display(),
                img.camera_id,
                cams_path.display()
            )
        })?;
        let r = quat_to_mat(img.qvec).ok_or_else(|| {
            anyhow!(
                "{}: {what}: quaternion is zero, NaN or Inf",
                imgs_path.display()
            )
        })?;
        if img.tvec.iter().any(|v| !v.is_finite()) {
            bail!("{}: {what}: pose contains NaN or Inf", imgs_path.display());
        }
        let c2w = rigid_c2w(w2c_opencv_to_c2w_opengl(&r, img.tvec), &imgs_path, &what)?;
        bound_cams.push(BoundCamera {
            r,
            t: img.tvec,
            tan_half: [
                k.width as f64 / (2.0 * k.fx as f64),
                k.height as f64 / (2.0 * k.fy as f64),
            ],
        });
        let path = img_dir.join(&img.name);
        images::check_image_extension(&path)?;
        pending.push(PendingView {
            path,
            camera: if scaled {
                CameraSpec::Scaled(k)
            } else {
                CameraSpec::Exact(k)
            },
            c2w,
            time: None,
            origin: format!("{} camera {}", cams_path.display(), img.camera_id),
        });
    }
    // Depth bounds from the sparse points, when the model has them (see colmap_points).
    let points_path = model_dir.join("points3D.bin");
    let near_far = if points_path.is_file() {
        let pts = read_points_bin(&read_bytes(&points_path)?)
            .map_err(|e| anyhow!("{}: {e}", points_path.display()))?;
        near_far(&pts.iter().map(|p| p.xyz).collect::<Vec<_>>(), &bound_cams)
    } else {
        None
    };
    let (train, test) = holdout_split(pending, opts);
    let reduce = images::Reduce::new(software_downscale, opts);
    if train.is_empty() {
        bail!(
            "{}: no training views (holdout_every = {:?} leaves none)",
            imgs_path.display(),
            opts.holdout_every
        );
    }
    Ok(RawDataset {
        root,
        format: "colmap".into(),
        train: images::load_views(train, &reduce)?,
        val: Vec::new(),
        test: images::load_views(test, &reduce)?,
        pose_file: imgs_path,
        kind_hint: None,
        near_far,
        aabb: None,
    })
}

/// The folder holding `images/`: the model dir, or its parent / grandparent (`sparse/0`).
fn dataset_root(model_dir: &Path) -> PathBuf {
    let mut cands = vec![model_dir.to_path_buf()];
    if let Some(p) = model_dir.parent() {
        cands.push(p.to_path_buf());
        if let Some(g) = p.parent() {
            cands.push(g.to_path_buf());
        }
    }
    cands
        .iter()
        .find(|c| c.join("images").is_dir())
        .cloned()
        .unwrap_or_else(|| match model_dir.file_name().and_then(|n| n.to_str()) {
            Some("sparse") => model_dir.parent().unwrap_or(model_dir).to_path_buf(),
            _ if model_dir
                .parent()
                .and_then(|p| p.file_name())
                .and_then(|n| n.to_str())
                == Some("sparse") =>
            {
                model_dir
                    .parent()
                    .and_then(Path::parent)
                    .unwrap_or(model_dir)
                    .to_path_buf()
            }
            _ => model_dir.to_path_buf(),
        })
}

fn read_bytes(p: &Path) -> Result<Vec<u8>> {
    std::fs::read(p).map_err(|e| anyhow!("{}: cannot read: {e}", p.display()))
}

fn read_text(p: &Path) -> Result<String> {
    std::fs::read_to_string(p).map_err(|e| anyhow!("{}: cannot read: {e}", p.display()))
}

/// Pinhole intrinsics + OpenCV distortion of a supported model.
fn intrinsics(c: &Camera) -> Result<Intrinsics> {
    let p = &c.params;
    let (fx, fy, cx, cy, d) = match c.model.as_str() {
        "SIMPLE_PINHOLE" => (p[0], p[0], p[1], p[2], [0.0; 4]),
        "PINHOLE" => (p[0], p[1], p[2], p[3], [0.0; 4]),
        "SIMPLE_RADIAL" => (p[0], p[0], p[1], p[2], [p[3], 0.0, 0.0, 0.0]),
        "RADIAL" => (p[0], p[0], p[1], p[2], [p[3], p[4], 0.0, 0.0]),
        "OPENCV" => (p[0], p[1], p[2], p[3], [p[4], p[5], p[6], p[7]]),
        m => bail!("unsupported camera model {m} (supported: {SUPPORTED})"),
    };
    if p.iter().any(|v| !v.is_finite()) || fx <= 0.0 || fy <= 0.0 {
        bail!(
            "bad {} parameters {p:?} (need finite values and positive focal)",
            c.model
        );
    }
    if c.width == 0 || c.height == 0 || c.width > 1 << 20 || c.height > 1 << 20 {
        bail!("bad image size {}x{}", c.width, c.height);
    }
    Ok(Intrinsics {
        width: c.width as u32,
        height: c.height as u32,
        fx: fx as f32,
        fy: fy as f32,
        cx: cx as f32,
        cy: cy as f32,
        distortion: d.map(|v| v as f32),
    })
}

fn check_supported(model: &str) -> Result<()> {
    if SUPPORTED.split(", ").any(|m| m == model) {
        Ok(())
    } else {
        bail!("unsupported camera model {model} (supported: {SUPPORTED})")
    }
}

/// Lines that are neither empty nor comments, with 1-based line numbers.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

fn num<T: std::str::FromStr>(tok: Option<&str>, line: usize, what: &str) -> Result<T> {
    let t = tok.ok_or_else(|| anyhow!("line {line}: missing {what}"))?;
    t.parse()
        .map_err(|_| anyhow!("line {line}: bad {what} '{t}'"))
}

/// `CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]`
pub(crate) fn read_cameras_txt(text: &str) -> Result<HashMap<u32, Camera>> {
    let mut out = HashMap::new();
    for (ln, line) in data_lines(text) {
        let mut it = line.split_whitespace();
        let id: u32 = num(it.next(), ln, "camera id")?;
        let model = it
            .next()
            .ok_or_else(|| anyhow!("line {ln}: missing camera model"))?
            .to_string();
        check_supported(&model).map_err(|e| anyhow!("line {ln}: camera {id}: {e}"))?;
        let width: u64 = num(it.next(), ln, "width")?;
        let height: u64 = num(it.next(), ln, "height")?;
        let params = it
            .map(|t| num::<f64>(Some(t), ln, "parameter"))
            .collect::<Result<Vec<_>>>()?;
        let want = MODELS
            .iter()
            .find(|m| m.1 == model)
            .map(|m| m.2)
            .unwrap_or(0);
        if params.len() != want {
            bail!(
                "line {ln}: camera {id}: {model} needs {want} parameters, found {}",
                params.len()
            );
        }
        out.insert(
            id,
            Camera {
                model,
                width,
                height,
                params,
            },
        );
    }
    if out.is_empty() {
        bail!("no cameras");
    }
    Ok(out)
}

/// Pairs of lines: `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`, then the 2D points (skipped;
/// the points line may be empty).
pub(crate) fn read_images_txt(text: &str) -> Result<Vec<Image>> {
    let mut out = Vec::new();
    let mut lines = text.lines().enumerate();
    while let Some((i, line)) = lines.next() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let ln = i + 1;
        let toks: Vec<&str> = line.split_whitespace().collect();
        if toks.len() < 10 {
            bail!(
                "line {ln}: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, found {} fields",
                toks.len()
            );
        }
        let f = |k: usize, what: &str| num::<f64>(Some(toks[k]), ln, what);
        let qvec = [f(1, "QW")?, f(2, "QX")?, f(3, "QY")?, f(4, "QZ")?];
        let tvec = [f(5, "TX")?, f(6, "TY")?, f(7, "TZ")?];
        let camera_id: u32 = num(Some(toks[8]), ln, "camera id")?;
        let name = toks[9..].join(" ");
        out.push(Image {
            id: num(Some(toks[0]), ln, "image id")?,
            qvec,
            tvec,
            camera_id,
            name,
        });
        lines.next(); // POINTS2D line
    }
    Ok(out)
}

/// A little-endian reader that never reads past the end and reports where it ran out.
struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8]> {
        if self.remaining() < n {
            bail!(
                "truncated file: {what} at byte {} needs {n} bytes, {} left",
                self.pos,
                self.remaining()
            );
        }
        let s = &self.buf[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn remaining(&self) -> usize {
        self.buf.len() - self.pos
    }
    fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap()))
    }
    fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(8, what)?.try_into().unwrap()))
    }
    /// A count of records of at least `min_size` bytes each, checked against the bytes left.
    fn count(&mut self, min_size: usize, what: &str) -> Result<usize> {
        let at = self.pos;
        let n = self.u64(what)?;
        let fits = (n as u128) * (min_size as u128) <= self.remaining() as u128;
        if !fits {
            bail!(
                "corrupt or truncated file: {what} = {n} at byte {at}, but only {} bytes follow",
                self.remaining()
            );
        }
        Ok(n as usize)
    }
}

/// u64 count; per camera: i32 id, i32 model id, u64 width, u64 height, f64 params[].
pub(crate) fn read_cameras_bin(buf: &[u8]) -> Result<HashMap<u32, Camera>> {
    let mut r = Reader { buf, pos: 0 };
    let n = r.count(24, "number of cameras")?;
    let mut out = HashMap::with_capacity(n);
    for _ in 0..n {
        let id = r.i32("camera id")? as u32;
        let model_id = r.i32("camera model id")?;
        let (name, nparams) = match MODELS.iter().find(|m| m.0 == model_id) {
            Some(m) => (m.1, m.2),
            None => {
                bail!("camera {id}: unknown camera model id {model_id} (supported: {SUPPORTED})")
            }
        };
        check_supported(name).map_err(|e| anyhow!("camera {id}: {e}"))?;
        let width = r.u64("camera width")?;
        let height = r.u64("camera height")?;
        let params = (0..nparams)
            .map(|_| r.f64("camera parameter"))
            .collect::<Result<Vec<_>>>()?;
        out.insert(
            id,
            Camera {
                model: name.to_string(),
                width,
                height,
                params,
            },
        );
    }
    if out.is_empty() {
        bail!("no cameras");
    }
    Ok(out)
}

/// u64 count; per image: u32 id, f64 qvec[4], f64 tvec[3], u32 camera id, NUL-terminated name,
/// u64 number of 2D points, then (f64 x, f64 y, i64 point3D id) per point (skipped).
pub(crate) fn read_images_bin(buf: &[u8]) -> Result<Vec<Image>> {
    let mut r = Reader { buf, pos: 0 };
    // id + 7 doubles + camera id + empty name's NUL + point count.
    let n = r.count(4 + 56 + 4 + 1 + 8, "number of images")?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let id = r.u32("image id")?;
        let mut q = [0.0; 4];
        for v in &mut q {
            *v = r.f64("image quaternion")?;
        }
        let mut t = [0.0; 3];
        for v in &mut t {
            *v = r.f64("image translation")?;
        }
        let camera_id = r.u32("image camera id")?;
        let rest = &r.buf[r.pos..];
        let len = rest.iter().position(|&b| b == 0).ok_or_else(|| {
            anyhow!(
                "truncated file: image name at byte {} has no terminating NUL",
                r.pos
            )
        })?;
        let name = String::from_utf8_lossy(&rest[..len]).into_owned();
        r.pos += len + 1;
        let npts = r.count(24, &format!("number of 2D points of image '{name}'"))?;
        r.take(npts * 24, "2D points")?;
        out.push(Image {
            id,
            qvec: q,
            tvec: t,
            camera_id,
            name,
        });
    }
    Ok(out)
}
