//! The preview orbit of a capture: the closed camera path a turntable, the baked asset and
//! every viewer start from, chosen from the training cameras alone. Pure geometry on views
//! and a `snerf_geometry::Space`, so `space` can record it when it maps a scene, and the
//! path renderers above (`camera_path`) can walk it, without either depending on the other.

use snerf_data::{SceneKind, View};
use snerf_geometry::camera::{forward_axis, horizontal, mean_up, position};
use snerf_geometry::vec::{add, cross, dot, norm, normalize, scale, sub, Vec3};
use snerf_geometry::{Orbit, Space};

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
