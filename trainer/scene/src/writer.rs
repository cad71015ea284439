//! Writing a dataset: render all views in parallel, write PNGs and the transforms_*.json
//! files into a temporary sibling directory, then move it into place only on success.

use crate::camera::{layout_for, poses, times, Layout, View};
use crate::math::Rng;
use glam::vec3;
use crate::procedural::{Built, Content};
use crate::raster::{c2w_matrix, camera, focal, render};
use crate::{build_scene, SceneSpec, Source};
use anyhow::{bail, Context, Result};
use rayon::prelude::*;
use serde_json::{json, Value};
use snerf_files::atomic::TempPath;
use snerf_files::guard::{self, Ownership};
use std::path::Path;
use std::time::Instant;

/// Refuse to replace a directory unless this command provably wrote all of it.
fn check_replaceable(dir: &Path) -> Result<()> {
    match guard::ownership(dir)? {
        Ownership::Missing | Ownership::Empty | Ownership::Owned => Ok(()),
        Ownership::Foreign(why) => bail!(
            "{} exists and snerf cannot replace it: {why}. `snerf scene` replaces only a dataset it \
             wrote itself and nobody changed since; move it away or choose another --out",
            dir.display()
        ),
    }
}

fn file_name(p: &Path) -> String {
    p.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_else(|| "dataset".into())
}

struct Job {
    split: &'static str,
    index: usize,
    view: View,
}

pub fn write(spec: &SceneSpec, out_dir: &Path, progress: &dyn Fn(usize, usize)) -> Result<Value> {
    let t0 = Instant::now();
    if spec.width == 0 || spec.height == 0 || spec.width > 16384 || spec.height > 16384 {
        bail!(
            "image size {}x{} is out of range (1..=16384)",
            spec.width,
            spec.height
        );
    }
    if spec.train_views == 0 {
        bail!("at least one train view is needed");
    }
    if spec.test_views == 0 {
        bail!("at least one test view is needed (training scores itself on held-out views)");
    }
    if spec.supersample == 0 || spec.supersample > 16 {
        bail!("supersample must be in 1..=16 (got {})", spec.supersample);
    }
    check_replaceable(out_dir)?;
    let built = build_scene(&spec.source, spec.seed)?;
    let dynamic = built.is_dynamic();

    // Cameras and times.
    let mut rng = Rng::new(spec.seed);
    let layout = match (&spec.source, built.kind) {
        (Source::Avatar, _) => Layout::Around {
            radius: 4.0,
            target: vec3(0.0, 0.0, 0.0),
            front_only: true,
        },
        (_, k) => layout_for(k, false),
    };
    let (train_p, test_p) = poses(
        layout,
        spec.path,
        spec.train_views,
        spec.test_views,
        &mut rng,
    );
    let (train_t, test_t) = if dynamic {
        let (a, b) = times(spec.train_views, spec.test_views, &mut rng);
        (
            a.into_iter().map(Some).collect(),
            b.into_iter().map(Some).collect(),
        )
    } else {
        (vec![None; spec.train_views], vec![None; spec.test_views])
    };
    let mut jobs = Vec::new();
    for (i, (c2w, time)) in train_p.into_iter().zip(train_t).enumerate() {
        jobs.push(Job {
            split: "train",
            index: i,
            view: View { c2w, time },
        });
    }
    for (i, (c2w, time)) in test_p.into_iter().zip(test_t).enumerate() {
        jobs.push(Job {
            split: "test",
            index: i,
            view: View { c2w, time },
        });
    }

    // Render into a temp directory beside the output; it is removed on failure or Ctrl-C.
    let tmp = TempPath::for_target(out_dir)?;
    write_into(tmp.path(), spec, &built, &jobs, progress)?;
    guard::write_manifest(tmp.path(), "snerf scene")?;

    // Move into place: old dataset aside, new one in, old one removed. Ownership is checked
    // again: the user may have added files while the views rendered.
    check_replaceable(out_dir)?;
    let old = TempPath::for_target(&out_dir.with_file_name(format!("{}.old", file_name(out_dir))))?;
    let had_old = out_dir.exists();
    if had_old {
        std::fs::rename(out_dir, old.path())
            .with_context(|| format!("cannot move the old {} aside", out_dir.display()))?;
    }
    if let Err(e) = std::fs::rename(tmp.path(), out_dir) {
        if had_old {
            let _ = std::fs::rename(old.path(), out_dir);
        }
        return Err(e).with_context(|| format!("cannot move the new dataset to {}", out_dir.display()));
    }
    tmp.keep();
    drop(old); // removes the old dataset

    let triangles = match &built.content {
        Content::Static(g) => g.tris.len(),
        Content::Dynamic(f) => f(0.0).map(|g| g.tris.len()).unwrap_or(0),
    };
    let mut summary = json!({
        "scene": spec.source.name(),
        "kind": built.kind.as_str(),
        "dynamic": dynamic,
        "train_views": spec.train_views,
        "test_views": spec.test_views,
        "val_views": spec.test_views,
        "width": spec.width,
        "height": spec.height,
        "supersample": spec.supersample,
        "camera_angle_x": built.fov_x,
        "triangles": triangles,
        "seconds": t0.elapsed().as_secs_f64(),
        "out_dir": out_dir.display().to_string(),
        "warnings": built.warnings,
    });
    for (k, v) in &built.info {
        summary[k.as_str()] = v.clone();
    }
    Ok(summary)
}

fn write_into(
    tmp: &Path,
    spec: &SceneSpec,
    built: &Built,
    jobs: &[Job],
    progress: &dyn Fn(usize, usize),
) -> Result<()> {
    for d in ["train", "test"] {
        std::fs::create_dir_all(tmp.join(d))
            .with_context(|| format!("cannot create {}", tmp.join(d).display()))?;
    }
    let (w, h) = (spec.width, spec.height);
    let total = jobs.len();
    progress(0, total);
    let (tx, rx) = std::sync::mpsc::channel::<()>();
    let res: Result<()> = std::thread::scope(|s| {
        let worker = s.spawn(move || {
            jobs.par_iter()
                .try_for_each_with(tx, |tx, job| -> Result<()> {
                    let cam = camera(job.view.c2w, w, h, built.fov_x);
                    let frame = match &built.content {
                        Content::Static(g) => render(&built.look, g, &cam, spec.supersample),
                        Content::Dynamic(f) => {
                            let g = f(job.view.time.unwrap_or(0.0))?;
                            render(&built.look, &g, &cam, spec.supersample)
                        }
                    };
                    let path = tmp.join(job.split).join(format!("r_{:03}.png", job.index));
                    image::save_buffer(&path, &frame.rgba, w, h, image::ExtendedColorType::Rgba8)
                        .with_context(|| format!("cannot write {}", path.display()))?;
                    let _ = tx.send(());
                    Ok(())
                })
        });
        let mut done = 0;
        while rx.recv().is_ok() {
            done += 1;
            progress(done, total);
        }
        worker
            .join()
            .map_err(|_| anyhow::anyhow!("a render worker panicked"))?
    });
    res?;

    let fov = built.fov_x;
    let fl = focal(w, fov);
    let frames = |split: &str| -> Vec<Value> {
        jobs.iter()
            .filter(|j| j.split == split)
            .map(|j| {
                let mut f = json!({
                    "file_path": format!("{}/r_{:03}.png", j.split, j.index),
                    "transform_matrix": c2w_matrix(&j.view.c2w).transpose().to_cols_array_2d(),
                });
                if let Some(t) = j.view.time {
                    f["time"] = json!(t);
                }
                f
            })
            .collect()
    };
    for (file, split) in [
        ("transforms_train.json", "train"),
        ("transforms_val.json", "test"),
        ("transforms_test.json", "test"),
    ] {
        let doc = json!({
            "camera_angle_x": fov,
            "fl_x": fl,
            "fl_y": fl,
            "cx": w as f32 * 0.5,
            "cy": h as f32 * 0.5,
            "w": w,
            "h": h,
            "scene_kind": built.kind.as_str(),
            "aabb": [built.aabb[0].to_array(), built.aabb[1].to_array()],
            "frames": frames(split),
        });
        let path = tmp.join(file);
        std::fs::write(&path, serde_json::to_string_pretty(&doc)?)
            .with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}

