//! Camera paths for turntables and novel-view sequences, derived from the training cameras.

use snerf_data::{SceneKind, View};

use crate::space::{add, cross, norm, normalize, position, scale, sub, SceneSpace, Vec3};

/// Camera-to-world (OpenGL convention) looking from `eye` at `target`.
pub fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> [[f32; 4]; 3] {
    let back = normalize(sub(eye, target));
    let mut right = cross(up, back);
    if norm(right) < 1e-6 {
        right = cross([1.0, 0.0, 0.0], back);
    }
    let right = normalize(right);
    let up = cross(back, right);
    [
        [right[0], up[0], back[0], eye[0]],
        [right[1], up[1], back[1], eye[1]],
        [right[2], up[2], back[2], eye[2]],
    ]
}

/// `n` cameras on a closed path that suits the scene: an orbit around the centre at the
/// training cameras' mean distance and elevation (object, unbounded), or a small circle in
/// front of the mean pose looking at the scene (forward-facing).
pub fn orbit(space: &SceneSpace, views: &[View], n: usize) -> Vec<[[f32; 4]; 3]> {
    let mean_up = normalize(views.iter().fold([0.0; 3], |a, v| add(a, [v.c2w[0][1], v.c2w[1][1], v.c2w[2][1]])));
    match space.kind {
        SceneKind::Forward => {
            let c = views.iter().fold([0.0; 3], |a, v| add(a, position(v)));
            let c = scale(c, 1.0 / views.len() as f32);
            let fwd = normalize(views.iter().fold([0.0; 3], |a, v| add(a, [-v.c2w[0][2], -v.c2w[1][2], -v.c2w[2][2]])));
            let spread = views.iter().map(|v| norm(sub(position(v), c))).fold(0.0f32, f32::max).max(1e-3);
            // look at a point at the near-content depth: 1/(0.75 scale) is the near bound
            let depth = 1.0 / (0.75 * space.scale) * 2.0;
            let target = add(c, scale(fwd, depth));
            let right = normalize(cross(fwd, mean_up));
            let up = cross(right, fwd);
            (0..n)
                .map(|i| {
                    let a = i as f32 / n as f32 * std::f32::consts::TAU;
                    let eye = add(c, add(scale(right, spread * a.cos()), scale(up, 0.6 * spread * a.sin())));
                    look_at(eye, target, mean_up)
                })
                .collect()
        }
        _ => {
            let center = space.center;
            let rel: Vec<Vec3> = views.iter().map(|v| sub(position(v), center)).collect();
            let radius = rel.iter().map(|r| norm(*r)).sum::<f32>() / rel.len() as f32;
            let height = rel.iter().map(|r| crate::space::dot(*r, mean_up)).sum::<f32>() / rel.len() as f32;
            let elev = (height / radius).clamp(-0.9, 0.9).asin();
            // objects look best from a little above; unbounded scenes keep the capture height
            let elev = if space.kind == SceneKind::Object { elev.max(0.35) } else { elev };
            let e1 = normalize(cross(mean_up, [0.3, 0.1, 0.9]));
            let e2 = cross(mean_up, e1);
            (0..n)
                .map(|i| {
                    let a = i as f32 / n as f32 * std::f32::consts::TAU;
                    let horiz = add(scale(e1, a.cos()), scale(e2, a.sin()));
                    let dir = add(scale(horiz, elev.cos()), scale(mean_up, elev.sin()));
                    look_at(add(center, scale(dir, radius)), center, mean_up)
                })
                .collect()
        }
    }
}
