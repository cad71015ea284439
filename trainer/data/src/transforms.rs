//! `transforms.json` in: Blender synthetic (`camera_angle_x`, `transforms_{train,val,test}.json`)
//! and nerfstudio (`fl_x fl_y cx cy w h`, `k1 k2 p1 p2`, `camera_model`, intrinsics at top level
//! or per frame, `train_filenames`/`val_filenames`/`test_filenames` splits). Frames carry an
//! OpenGL camera-to-world `transform_matrix` and an optional D-NeRF `time`. The snerf extension
//! keys `scene_kind` and `aabb` are read as hints.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Result};
use serde::Deserialize;

use crate::images::{self, CameraSpec, PendingView};
use crate::{holdout_split, Intrinsics, LoadOptions, RawDataset, SceneKind};

#[derive(Deserialize, Default, Clone, Debug)]
struct CameraKeys {
    camera_angle_x: Option<f64>,
    camera_angle_y: Option<f64>,
    fl_x: Option<f64>,
    fl_y: Option<f64>,
    cx: Option<f64>,
    cy: Option<f64>,
    w: Option<f64>,
    h: Option<f64>,
    k1: Option<f64>,
    k2: Option<f64>,
    k3: Option<f64>,
    k4: Option<f64>,
    p1: Option<f64>,
    p2: Option<f64>,
    camera_model: Option<String>,
}

impl CameraKeys {
    /// Per-frame keys win over the file's top-level keys.
    fn over(&self, top: &CameraKeys) -> CameraKeys {
        CameraKeys {
            camera_angle_x: self.camera_angle_x.or(top.camera_angle_x),
            camera_angle_y: self.camera_angle_y.or(top.camera_angle_y),
            fl_x: self.fl_x.or(top.fl_x),
            fl_y: self.fl_y.or(top.fl_y),
            cx: self.cx.or(top.cx),
            cy: self.cy.or(top.cy),
            w: self.w.or(top.w),
            h: self.h.or(top.h),
            k1: self.k1.or(top.k1),
            k2: self.k2.or(top.k2),
            k3: self.k3.or(top.k3),
            k4: self.k4.or(top.k4),
            p1: self.p1.or(top.p1),
            p2: self.p2.or(top.p2),
            camera_model: self
                .camera_model
                .clone()
                .or_else(|| top.camera_model.clone()),
        }
    }
}

#[derive(Deserialize, Debug)]
struct Frame {
    file_path: String,
    /// `None` entries are NaN / Infinity / null in the file.
    transform_matrix: Vec<Vec<Option<f64>>>,
    time: Option<f64>,
    #[serde(flatten)]
    camera: CameraKeys,
}

#[derive(Deserialize, Debug)]
struct TransformsFile {
    #[serde(flatten)]
    camera: CameraKeys,
    frames: Vec<Frame>,
    scene_kind: Option<String>,
    aabb: Option<Vec<Vec<f64>>>,
    train_filenames: Option<Vec<String>>,
    val_filenames: Option<Vec<String>>,
    test_filenames: Option<Vec<String>>,
}

/// `files`: (split, path) as found by `source::locate`; split "all" means one file to hold out from.
pub(crate) fn load(files: &[(String, PathBuf)], opts: &LoadOptions) -> Result<RawDataset> {
    let parsed: Vec<(String, PathBuf, TransformsFile)> = files
        .iter()
        .map(|(split, p)| Ok((split.clone(), p.clone(), read_file(p)?)))
        .collect::<Result<_>>()?;
    let (_, first_path, _) = &parsed[0];
    let root = json_dir(first_path);

    let blender = parsed
        .iter()
        .all(|(_, _, f)| f.camera.camera_angle_x.is_some() && f.camera.fl_x.is_none());
    let format = if blender { "blender" } else { "nerfstudio" };

    let mut kind_hint = None;
    let mut aabb = None;
    for (_, p, f) in &parsed {
        if let Some(k) = &f.scene_kind {
            kind_hint = Some(SceneKind::parse(k).ok_or_else(|| {
                anyhow!(
                    "{}: scene_kind '{k}' is not one of object, forward, unbounded",
                    p.display()
                )
            })?);
        }
        if let Some(b) = &f.aabb {
            aabb = Some(parse_aabb(b, p)?);
        }
    }

    let mut train = Vec::new();
    let mut val = Vec::new();
    let mut test = Vec::new();
    let has_val_or_test = parsed.iter().any(|(s, _, _)| s == "val" || s == "test");
    for (split, path, file) in &parsed {
        let pending = pending_views(path, file)?;
        match split.as_str() {
            "train" if has_val_or_test => train.extend(pending),
            "val" => val.extend(pending),
            "test" => test.extend(pending),
            _ => {
                if let Some(lists) = filename_lists(file) {
                    for (pv, f) in pending.into_iter().zip(&file.frames) {
                        let name = normalize_name(&f.file_path);
                        if lists[0].contains(&name) {
                            train.push(pv);
                        } else if lists[1].contains(&name) {
                            val.push(pv);
                        } else if lists[2].contains(&name) {
                            test.push(pv);
                        }
                    }
                    if train.is_empty() {
                        bail!(
                            "{}: train_filenames matches no frame's file_path",
                            path.display()
                        );
                    }
                } else {
                    let (tr, te) = holdout_split(pending, opts);
                    train.extend(tr);
                    test.extend(te);
                }
            }
        }
    }
    if train.is_empty() {
        bail!(
            "{}: no training views (holdout_every = {:?} leaves none)",
            first_path.display(),
            opts.holdout_every
        );
    }
    let reduce = images::Reduce::new(opts.downscale.unwrap_or(1), opts);
    Ok(RawDataset {
        root,
        format: format.to_string(),
        train: images::load_views(train, &reduce)?,
        val: images::load_views(val, &reduce)?,
        test: images::load_views(test, &reduce)?,
        pose_file: first_path.clone(),
        kind_hint,
        near_far: None,
        aabb,
    })
}

/// The folder a json file sits in ("." for a bare file name).
fn json_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

fn read_file(path: &Path) -> Result<TransformsFile> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow!("{}: cannot read: {e}", path.display()))?;
    let text = non_finite_to_null(&text);
    let file: TransformsFile = serde_json::from_str(&text)
        .map_err(|e| anyhow!("{}: malformed transforms JSON: {e}", path.display()))?;
    if file.frames.is_empty() {
        bail!(
            "{}: no frames (the \"frames\" list is empty)",
            path.display()
        );
    }
    Ok(file)
}

/// Python's json writes NaN / Infinity / -Infinity, which JSON lacks; read them as null so that
/// the pose check can name the frame instead of failing as a syntax error.
fn non_finite_to_null(text: &str) -> String {
    if !(text.contains("NaN") || text.contains("Infinity")) {
        return text.to_string();
    }
    let mut out = String::with_capacity(text.len());
    let mut in_str = false;
    let mut escaped = false;
    let mut rest = text;
    while let Some(c) = rest.chars().next() {
        if in_str {
            if escaped {
                escaped = false;
            } else if c == '\\' {
                escaped = true;
            } else if c == '"' {
                in_str = false;
            }
        } else if c == '"' {
            in_str = true;
        } else {
            let mut replaced = false;
            for tok in ["-Infinity", "Infinity", "NaN"] {
                if rest.starts_with(tok) {
                    out.push_str("null");
                    rest = &rest[tok.len()..];
                    replaced = true;
                    break;
                }
            }
            if replaced {
                continue;
            }
        }
        out.push(c);
        rest = &rest[c.len_utf8()..];
    }
    out
}

fn normalize_name(s: &str) -> String {
    s.trim_start_matches("./").to_string()
}

fn filename_lists(file: &TransformsFile) -> Option<[Vec<String>; 3]> {
    let tr = file.train_filenames.as_ref()?;
    let norm = |v: &Option<Vec<String>>| {
        v.iter()
            .flatten()
            .map(|s| normalize_name(s))
            .collect::<Vec<_>>()
    };
    Some([
        tr.iter().map(|s| normalize_name(s)).collect(),
        norm(&file.val_filenames),
        norm(&file.test_filenames),
    ])
}

fn parse_aabb(b: &[Vec<f64>], path: &Path) -> Result<([f32; 3], [f32; 3])> {
    let bad = || {
        anyhow!(
            "{}: aabb must be [[minx,miny,minz],[maxx,maxy,maxz]] with finite min <= max",
            path.display()
        )
    };
    if b.len() != 2
        || b.iter()
            .any(|r| r.len() != 3 || r.iter().any(|v| !v.is_finite()))
    {
        return Err(bad());
    }
    if (0..3).any(|i| b[0][i] > b[1][i]) {
        return Err(bad());
    }
    let f = |r: &Vec<f64>| [r[0] as f32, r[1] as f32, r[2] as f32];
    Ok((f(&b[0]), f(&b[1])))
}

/// Image path of a frame: relative to the json's folder, `.png` appended when the path has no
/// image extension (Blender writes "./train/r_0").
fn image_path(dir: &Path, file_path: &str) -> PathBuf {
    let p = dir.join(file_path);
    let has_image_ext = p
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| {
            [
                "png", "jpg", "jpeg", "exr", "bmp", "tif", "tiff", "webp", "gif", "hdr",
            ]
            .contains(&e.to_ascii_lowercase().as_str())
        })
        .unwrap_or(false);
    if has_image_ext {
        return p;
    }
    // Blender writes `file_path` without an extension and means PNG; a converted copy of such a
    // dataset holds JPEG or WebP under the same names, so those are tried when no PNG exists.
    // When none exists the PNG name is kept, for the "not found" message.
    let with = |ext: &str| {
        let mut s = p.clone().into_os_string();
        s.push(".");
        s.push(ext);
        PathBuf::from(s)
    };
    images::READABLE_EXTS
        .iter()
        .map(|e| with(e))
        .find(|c| c.is_file())
        .unwrap_or_else(|| with("png"))
}

fn pending_views(path: &Path, file: &TransformsFile) -> Result<Vec<PendingView>> {
    let dir = json_dir(path);
    let fname = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let with_time = file.frames.iter().filter(|f| f.time.is_some()).count();
    if with_time != 0 && with_time != file.frames.len() {
        bail!(
            "{}: {with_time} of {} frames have a \"time\"; either all frames or none must",
            path.display(),
            file.frames.len()
        );
    }
    file.frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let what = format!("frame {i} ('{}')", f.file_path);
            let c2w = parse_matrix(&f.transform_matrix, path, &what)?;
            let time = match f.time {
                Some(t) if !(t.is_finite() && (-1e-6..=1.0 + 1e-6).contains(&t)) => {
                    bail!("{}: {what}: time {t} is outside [0, 1]", path.display())
                }
                Some(t) => Some(t.clamp(0.0, 1.0) as f32),
                None => None,
            };
            let camera = camera_spec(&f.camera.over(&file.camera), path, &what)?;
            let img = image_path(&dir, &f.file_path);
            images::check_image_extension(&img)?;
            Ok(PendingView {
                path: img,
                camera,
                c2w,
                time,
                origin: format!("{fname} {what}"),
            })
        })
        .collect()
}

fn parse_matrix(m: &[Vec<Option<f64>>], path: &Path, what: &str) -> Result<[[f32; 4]; 3]> {
    let rows_ok = (m.len() == 3 || m.len() == 4) && m.iter().all(|r| r.len() == 4);
    if !rows_ok {
        bail!(
            "{}: {what}: transform_matrix must be 4x4 (or 3x4)",
            path.display()
        );
    }
    if m.iter().flatten().any(|v| v.is_none()) {
        bail!(
            "{}: {what}: pose contains NaN or Inf (transform_matrix)",
            path.display()
        );
    }
    let v = |r: usize, c: usize| m[r][c].unwrap();
    if m.len() == 4 {
        let last = [v(3, 0), v(3, 1), v(3, 2), v(3, 3)];
        if last.iter().any(|x| !x.is_finite()) {
            bail!(
                "{}: {what}: pose contains NaN or Inf (transform_matrix)",
                path.display()
            );
        }
        if (last[0].abs() + last[1].abs() + last[2].abs() + (last[3] - 1.0).abs()) > 1e-4 {
            bail!(
                "{}: {what}: transform_matrix last row is {last:?}, expected [0, 0, 0, 1]",
                path.display()
            );
        }
    }
    let rows: [[f64; 4]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| v(r, c)));
    crate::pose::rigid_c2w(rows, path, what)
}

fn camera_spec(k: &CameraKeys, path: &Path, what: &str) -> Result<CameraSpec> {
    let p = path.display();
    if let Some(model) = &k.camera_model {
        if !matches!(model.to_ascii_uppercase().as_str(), "PINHOLE" | "OPENCV") {
            bail!("{p}: {what}: unsupported camera model '{model}' (supported: PINHOLE, OPENCV)");
        }
    }
    for (name, v) in [("k3", k.k3), ("k4", k.k4)] {
        if v.is_some_and(|v| v != 0.0) {
            bail!("{p}: {what}: distortion coefficient {name} is not supported (only k1 k2 p1 p2)");
        }
    }
    let dist = [k.k1, k.k2, k.p1, k.p2].map(|v| v.unwrap_or(0.0) as f32);
    if dist.iter().any(|v| !v.is_finite()) {
        bail!("{p}: {what}: distortion coefficients must be finite");
    }
    let positive = |name: &str, v: f64| -> Result<f64> {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            bail!("{p}: {what}: {name} must be a positive finite number, got {v}")
        }
    };
    let size = match (k.w, k.h) {
        (Some(w), Some(h)) => {
            let (w, h) = (positive("w", w)?, positive("h", h)?);
            if w.fract() != 0.0 || h.fract() != 0.0 || w > 1e6 || h > 1e6 {
                bail!("{p}: {what}: w and h must be whole pixel counts, got {w} x {h}");
            }
            Some((w as u32, h as u32))
        }
        (None, None) => None,
        _ => bail!("{p}: {what}: only one of w and h is given"),
    };
    let (fx, fy) = if let Some(fx) = k.fl_x {
        let fx = positive("fl_x", fx)?;
        (Some(fx), Some(positive("fl_y", k.fl_y.unwrap_or(fx))?))
    } else if let Some(ax) = k.camera_angle_x {
        let ax = positive("camera_angle_x", ax)?;
        if ax >= std::f64::consts::PI {
            bail!("{p}: {what}: camera_angle_x {ax} must be below pi radians");
        }
        if let Some(ay) = k.camera_angle_y {
            if !(ay.is_finite() && ay > 0.0 && ay < std::f64::consts::PI) {
                bail!("{p}: {what}: camera_angle_y {ay} must be in (0, pi) radians");
            }
        }
        match size {
            None => {
                return Ok(CameraSpec::Fov {
                    angle_x: ax,
                    angle_y: k.camera_angle_y,
                    distortion: dist,
                })
            }
            Some((w, h)) => {
                let fx = 0.5 * w as f64 / (0.5 * ax).tan();
                let fy = k
                    .camera_angle_y
                    .map(|a| 0.5 * h as f64 / (0.5 * a).tan())
                    .unwrap_or(fx);
                (Some(fx), Some(fy))
            }
        }
    } else {
        bail!("{p}: {what}: no focal length (need fl_x or camera_angle_x)");
    };
    let (fx, fy) = (fx.unwrap(), fy.unwrap());
    for (name, v) in [("cx", k.cx), ("cy", k.cy)] {
        if v.is_some_and(|v| !v.is_finite()) {
            bail!("{p}: {what}: {name} must be finite");
        }
    }
    Ok(match size {
        Some((w, h)) => CameraSpec::Exact(Intrinsics {
            width: w,
            height: h,
            fx: fx as f32,
            fy: fy as f32,
            cx: k.cx.unwrap_or(w as f64 * 0.5) as f32,
            cy: k.cy.unwrap_or(h as f64 * 0.5) as f32,
            distortion: dist,
        }),
        None => CameraSpec::Focal {
            fx,
            fy,
            cx: k.cx,
            cy: k.cy,
            distortion: dist,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_tokens_become_null_outside_strings() {
        let s = r#"{"a": [NaN, -Infinity, Infinity], "b": "NaN \" Infinity"}"#;
        assert_eq!(
            non_finite_to_null(s),
            r#"{"a": [null, null, null], "b": "NaN \" Infinity"}"#
        );
    }

    #[test]
    fn image_path_appends_png() {
        let d = Path::new("/d");
        assert_eq!(
            image_path(d, "./train/r_0"),
            Path::new("/d/./train/r_0.png")
        );
        assert_eq!(image_path(d, "images/a.PNG"), Path::new("/d/images/a.PNG"));
        assert_eq!(image_path(d, "images/a.jpg"), Path::new("/d/images/a.jpg"));
    }
}
