//! Camera paths for turntables and novel-view sequences, derived from the training cameras.
//! The path itself is `snerf_geometry::Orbit` (one definition for the trainer, the baked
//! asset and every viewer); this module only chooses its parameters from a capture.

use snerf_data::{SceneKind, View};
pub use snerf_geometry::look_at;
use snerf_geometry::camera::{forward_axis, horizontal, mean_up, position};
use snerf_geometry::vec::{add, cross, dot, norm, normalize, scale, sub, Vec3};
use snerf_geometry::{Orbit, Space};

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use snerf_data::Dataset;

use crate::render::WorkspacePool;
use crate::space::SceneSpace;
use crate::train::{views_have_alpha, Model};
use crate::{checkpoint, eval};

/// The preview orbit of a capture: around its centre at the cameras' mean distance and
/// elevation, upright about the cameras' mean up (or `up` when given) — objects from at
/// least 20° above; forward-facing scenes: a small ellipse in front of the mean pose
/// looking at the near content.
pub fn preview_orbit(kind: SceneKind, frame: &Space, views: &[&View], up: Option<Vec3>) -> Orbit {
    let up = up.map(normalize).unwrap_or_else(|| mean_up(views.iter().map(|v| &v.c2w)));
    let n = views.len().max(1) as f32;
    match kind {
        SceneKind::Forward => {
            let c = scale(views.iter().fold([0.0; 3], |a, v| add(a, position(&v.c2w))), 1.0 / n);
            let fwd = normalize(views.iter().fold([0.0; 3], |a, v| add(a, forward_axis(&v.c2w))));
            let spread = views.iter().map(|v| norm(sub(position(&v.c2w), c))).fold(0.0f32, f32::max).max(1e-3);
            // look at a point at twice the near-content depth (1/(0.75 scale) is the near bound)
            let depth = 1.0 / (0.75 * frame.scale) * 2.0;
            let right = normalize(cross(fwd, up));
            let up_in_plane = cross(right, fwd);
            Orbit::Ellipse { center: c, right, up: up_in_plane, target: add(c, scale(fwd, depth)), rx: spread, ry: 0.6 * spread }
        }
        SceneKind::Object | SceneKind::Unbounded => {
            let center = frame.center;
            let rel: Vec<Vec3> = views.iter().map(|v| sub(position(&v.c2w), center)).collect();
            let radius = (rel.iter().map(|r| norm(*r)).sum::<f32>() / n).max(1e-6);
            let height = rel.iter().map(|r| dot(*r, up)).sum::<f32>() / n;
            let elev = (height / radius).clamp(-0.9, 0.9).asin();
            // objects look best from a little above; unbounded scenes keep the capture height
            let elevation = if kind == SceneKind::Object { elev.max(0.35) } else { elev };
            // First frame: the first training camera's side of the scene, so the same
            // capture in any world frame starts from the same place.
            let start = horizontal(up, rel.first().copied().unwrap_or([0.3, 0.1, 0.9]));
            Orbit::Around { center, up, start, radius, elevation }
        }
    }
}

/// `n` cameras on a closed path that suits the scene (its stored preview orbit, or one
/// derived from `views` for spaces saved without it).
pub fn orbit(space: &SceneSpace, views: &[View], n: usize) -> Vec<[[f32; 4]; 3]> {
    let o = space.orbit.unwrap_or_else(|| {
        let refs: Vec<&View> = views.iter().collect();
        preview_orbit(space.kind, &space.frame, &refs, None)
    });
    o.path(n)
}

/// Render `n` frames of the preview orbit of `data` into `out/frame_NNN.png` (dynamic scenes
/// play their time once around) and write the path as nerfstudio's `out/camera_path.json`,
/// so `snerf render --path` of a baked asset (or nerfstudio) renders the same cameras.
/// `on_frame(done, total)` is called after each frame. Returns the frame files.
pub fn render_turntable(
    model: &Model,
    pool: &WorkspacePool,
    data: &Dataset,
    n: usize,
    out: &Path,
    on_frame: &mut dyn FnMut(usize, usize),
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let cams = orbit(&model.space, &data.train, n.max(1));
    let k = data.test.first().unwrap_or(&data.train[0]).intrinsics;
    let bg = eval::eval_background(views_have_alpha(&data.train));
    let time_of = |i: usize| data.dynamic.then(|| i as f32 / cams.len().max(2) as f32);
    let mut files = Vec::new();
    for (i, c2w) in cams.iter().enumerate() {
        let r = eval::render_camera(model, pool, c2w, &k, time_of(i), bg);
        let img = eval::side_by_side(&[&r.rgb], r.width, r.height);
        let f = out.join(format!("frame_{i:03}.png"));
        checkpoint::write_png_atomic(&f, &img)?;
        files.push(f);
        on_frame(i + 1, cams.len());
    }
    let path: Vec<snerf_geometry::camera_path::PathCamera> = cams
        .iter()
        .enumerate()
        .map(|(i, c2w)| snerf_geometry::camera_path::PathCamera {
            cam: snerf_geometry::Pinhole { c2w: *c2w, fx: k.fx, fy: k.fy, cx: k.cx, cy: k.cy, width: k.width, height: k.height },
            time: time_of(i),
        })
        .collect();
    snerf_files::atomic::write_atomic(&out.join("camera_path.json"), snerf_geometry::camera_path::to_json(&path, 24.0).as_bytes())?;
    Ok(files)
}

