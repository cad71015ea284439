//! LLFF in: `poses_bounds.npy` (N x 17: a row-major 3x5 matrix of [down, right, backwards]
//! rotation columns, translation and [H, W, focal], then near and far) with sorted images in
//! `images/` (or `images_N` for a downscale of N).

use std::path::Path;

use anyhow::{bail, Result};

use crate::images::{self, CameraSpec, PendingView};
use crate::{holdout_split, npy, Intrinsics, LoadOptions, RawDataset};

/// One row of `poses_bounds.npy` -> (OpenGL c2w as f64 rows, H, W, focal, near, far).
pub(crate) fn parse_row(row: &[f64]) -> ([[f64; 4]; 3], f64, f64, f64, f64, f64) {
    let m = |r: usize, c: usize| row[r * 5 + c];
    // LLFF columns [down, right, back] -> OpenGL [right, up, back] = [col1, -col0, col2].
    let c2w = std::array::from_fn(|r| [m(r, 1), -m(r, 0), m(r, 2), m(r, 3)]);
    (c2w, m(0, 4), m(1, 4), m(2, 4), row[15], row[16])
}

pub(crate) fn load(dir: &Path, opts: &LoadOptions) -> Result<RawDataset> {
    let npy_path = dir.join("poses_bounds.npy");
    let arr = npy::read(&npy_path)?;
    if arr.shape.len() != 2 || arr.shape[1] != 17 {
        bail!(
            "{}: expected shape (N, 17), found {:?}",
            npy_path.display(),
            arr.shape
        );
    }
    let n = arr.shape[0];
    if n == 0 {
        bail!("{}: no poses (shape (0, 17))", npy_path.display());
    }
    let s = opts.downscale.unwrap_or(1).max(1);
    let (img_dir, software_downscale) = match dir.join(format!("images_{s}")) {
        d if s > 1 && d.is_dir() => (d, 1),
        _ => (dir.join("images"), s),
    };
    if !img_dir.is_dir() {
        bail!(
            "{}: image folder not found (LLFF needs images/ next to poses_bounds.npy)",
            img_dir.display()
        );
    }
    let files = images::list_images(&img_dir)?;
    if files.is_empty() {
        bail!("{}: no images found", img_dir.display());
    }
    if files.len() != n {
        bail!(
            "{}: {} images but {} has {n} poses",
            img_dir.display(),
            files.len(),
            npy_path.display()
        );
    }
    let mut near = f64::INFINITY;
    let mut far = f64::NEG_INFINITY;
    let mut pending = Vec::with_capacity(n);
    for (i, (row, file)) in arr.data.chunks_exact(17).zip(files).enumerate() {
        let what = format!("row {i}");
        let (c2w, h, w, f, nr, fr) = parse_row(row);
        let c2w = crate::pose::rigid_c2w(c2w, &npy_path, &what)?;
        let ok = |v: f64| v.is_finite() && v > 0.0;
        if !(ok(h) && ok(w) && ok(f)) || h.fract() != 0.0 || w.fract() != 0.0 || h > 1e6 || w > 1e6
        {
            bail!(
                "{}: {what}: bad [H, W, focal] = [{h}, {w}, {f}]",
                npy_path.display()
            );
        }
        if !(nr.is_finite() && fr.is_finite() && nr > 0.0 && fr > nr) {
            bail!(
                "{}: {what}: bad bounds near {nr}, far {fr} (need 0 < near < far)",
                npy_path.display()
            );
        }
        near = near.min(nr);
        far = far.max(fr);
        let k = Intrinsics {
            width: w as u32,
            height: h as u32,
            fx: f as f32,
            fy: f as f32,
            cx: (w * 0.5) as f32,
            cy: (h * 0.5) as f32,
            distortion: [0.0; 4],
        };
        pending.push(PendingView {
            path: file,
            camera: CameraSpec::Scaled(k),
            c2w,
            time: None,
            origin: format!("{} {what}", npy_path.display()),
        });
    }
    let (train, test) = holdout_split(pending, opts);
    let reduce = images::Reduce::new(software_downscale, opts);
    if train.is_empty() {
        bail!(
            "{}: no training views (holdout_every = {:?} leaves none)",
            npy_path.display(),
            opts.holdout_every
        );
    }
    Ok(RawDataset {
        root: dir.to_path_buf(),
        format: "llff".into(),
        train: images::load_views(train, &reduce)?,
        val: Vec::new(),
        test: images::load_views(test, &reduce)?,
        pose_file: npy_path,
        kind_hint: None,
        near_far: Some((near as f32, far as f32)),
        aabb: None,
    })
}
