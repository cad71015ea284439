//! Scene kind and dynamics detection. Rule, used when neither `LoadOptions` nor the file's
//! `scene_kind` hint decides: Forward if every viewing direction is within
//! [`FORWARD_MAX_ANGLE_DEG`] of the mean direction; otherwise Object if more than
//! [`OBJECT_MIN_TRANSPARENT`] of the training pixels have alpha < 255; otherwise Unbounded.
//! A dataset whose folder holds `backdrop.json` (a capture before a plain backdrop, see
//! [`crate::backdrop`]) is an object: its backdrop is keyed out as it loads.
//! Dynamic: frames carry times that are not all equal. The reason lands in
//! `Dataset::detection_note`.

use anyhow::{bail, Result};

use crate::{Dataset, LoadOptions, RawDataset, SceneKind, View};

pub const FORWARD_MAX_ANGLE_DEG: f32 = 40.0;
pub const OBJECT_MIN_TRANSPARENT: f64 = 0.01;

/// Largest angle (degrees) between a view's direction and the mean direction of all views;
/// 180 when the directions cancel out (cameras all around).
pub fn max_view_angle_deg(views: &[&View]) -> f32 {
    let mut mean = [0.0f64; 3];
    let dirs: Vec<[f64; 3]> = views
        .iter()
        .map(|v| {
            let d = v.forward().map(|x| x as f64);
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-12);
            d.map(|x| x / n)
        })
        .collect();
    for d in &dirs {
        for i in 0..3 {
            mean[i] += d[i];
        }
    }
    let n = (mean[0] * mean[0] + mean[1] * mean[1] + mean[2] * mean[2]).sqrt();
    if dirs.is_empty() || n < 1e-6 * dirs.len() as f64 {
        return 180.0;
    }
    let mean = mean.map(|x| x / n);
    dirs.iter()
        .map(|d| {
            (d[0] * mean[0] + d[1] * mean[1] + d[2] * mean[2])
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees() as f32
        })
        .fold(0.0, f32::max)
}

/// Fraction of pixels with alpha < 255 over the given views.
pub fn transparent_fraction(views: &[&View]) -> f64 {
    let (mut total, mut clear) = (0usize, 0usize);
    for v in views {
        total += v.rgba.len() / 4;
        clear += v.rgba.chunks_exact(4).filter(|p| p[3] < 255).count();
    }
    if total == 0 {
        0.0
    } else {
        clear as f64 / total as f64
    }
}

/// The detection rule on poses (all views) and alpha (training views), with its reason.
pub fn detect_kind(all: &[&View], train: &[&View]) -> (SceneKind, String) {
    let angle = max_view_angle_deg(all);
    if angle <= FORWARD_MAX_ANGLE_DEG {
        return (
            SceneKind::Forward,
            format!("forward: all view directions within {angle:.1} deg of their mean (<= {FORWARD_MAX_ANGLE_DEG})"),
        );
    }
    let frac = transparent_fraction(train);
    if frac > OBJECT_MIN_TRANSPARENT {
        (
            SceneKind::Object,
            format!(
                "object: views spread {angle:.1} deg from their mean (> {FORWARD_MAX_ANGLE_DEG}) and {:.1}% of \
                 training pixels are transparent (> {:.0}%)",
                frac * 100.0,
                OBJECT_MIN_TRANSPARENT * 100.0
            ),
        )
    } else {
        (
            SceneKind::Unbounded,
            format!(
                "unbounded: views spread {angle:.1} deg from their mean (> {FORWARD_MAX_ANGLE_DEG}) and only {:.2}% \
                 of training pixels are transparent (<= {:.0}%)",
                frac * 100.0,
                OBJECT_MIN_TRANSPARENT * 100.0
            ),
        )
    }
}

/// Applies overrides, hints and detection to a loaded dataset.
/// `backdrop`: the note when a plain backdrop was keyed out (the scene is then an object).
pub(crate) fn finish(raw: RawDataset, opts: &LoadOptions, backdrop: Option<String>) -> Result<Dataset> {
    let all: Vec<&View> = raw.train.iter().chain(&raw.val).chain(&raw.test).collect();
    let train: Vec<&View> = raw.train.iter().collect();
    let (kind, kind_note) = if let Some(k) = opts.kind {
        (k, format!("{k}: set by the caller"))
    } else if let Some(k) = raw.kind_hint {
        (
            k,
            format!("{k}: scene_kind hint in {}", raw.pose_file.display()),
        )
    } else if let Some(note) = backdrop {
        (SceneKind::Object, format!("object: {note}"))
    } else {
        detect_kind(&all, &train)
    };
    let times: Vec<f32> = all.iter().filter_map(|v| v.time).collect();
    let varies = times.iter().any(|&t| t != times[0]);
    let (dynamic, dyn_note) = match opts.dynamic {
        Some(true) if times.is_empty() => bail!(
            "{}: a dynamic scene was requested but the frames carry no \"time\"",
            raw.pose_file.display()
        ),
        Some(d) => (d, format!("dynamic={d}: set by the caller")),
        None if varies => (
            true,
            format!("dynamic: {} frames carry times that differ", times.len()),
        ),
        None if !times.is_empty() => (false, "static: all frame times are equal".to_string()),
        None => (false, "static: frames carry no time".to_string()),
    };
    Ok(Dataset {
        root: raw.root,
        format: raw.format,
        train: raw.train,
        val: raw.val,
        test: raw.test,
        kind,
        dynamic,
        near_far: raw.near_far,
        aabb: raw.aabb,
        detection_note: format!("{kind_note}; {dyn_note}"),
        pose_file: raw.pose_file,
    })
}
