//! Camera paths for turntables and novel-view sequences, derived from the training cameras.
//! The path itself is `snerf_geometry::Orbit` (one definition for the trainer, the baked
//! asset and every viewer); its parameters for a capture are chosen in `crate::orbit`. This
//! module walks the path and renders it, so it sits with the run files, above evaluation.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use snerf_data::{Dataset, View};
pub use snerf_geometry::look_at;

use crate::eval;
use crate::model::Model;
// Where the baker's tests and older callers find the preview orbit; it is pure geometry, so
// it lives below `space` (which records it) rather than here.
pub use crate::orbit::preview_orbit;
use crate::png::write_png_atomic;
use crate::render::WorkspacePool;
use crate::space::SceneSpace;
use crate::train::views_have_alpha;

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
        write_png_atomic(&f, &img)?;
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

