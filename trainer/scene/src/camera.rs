//! Camera paths for each scene kind: which poses (and, for dynamic scenes, which times) the
//! train and test views use.

use crate::math::Rng;
use glam::{vec3, Vec3};
use snerf_geometry::camera::{look_at, C2w};
use crate::{CameraPath, SceneKind};
use std::f32::consts::{PI, TAU};

#[derive(Clone, Debug)]
pub struct View {
    pub c2w: C2w,
    pub time: Option<f32>,
}

/// Layout of cameras for one scene.
#[derive(Clone, Copy, Debug)]
pub enum Layout {
    /// Around an object at `radius`; `front_only` restricts to the front (+z) hemisphere
    /// for faces.
    Around {
        radius: f32,
        target: Vec3,
        front_only: bool,
    },
    /// Forward-facing grid looking down -z.
    Forward { centre: Vec3, target: Vec3, spread: Vec3 },
    /// On a circle around the centre, slightly above the ground.
    Ring {
        radius: f32,
        height: f32,
        target: Vec3,
    },
}

/// A camera at `eye` looking at `target`, upright in the scene's +y.
fn look(eye: Vec3, target: Vec3) -> C2w {
    look_at(eye.into(), target.into(), [0.0, 1.0, 0.0])
}

fn on_sphere(target: Vec3, radius: f32, azim: f32, elev: f32) -> C2w {
    let d = vec3(elev.cos() * azim.sin(), elev.sin(), elev.cos() * azim.cos());
    look(target + d * radius, target)
}

/// Train times spread uniformly over [0, 1] with jitter; test times midway between train times.
pub fn times(n_train: usize, n_test: usize, rng: &mut Rng) -> (Vec<f32>, Vec<f32>) {
    if n_train <= 1 {
        return (
            vec![0.0; n_train],
            (0..n_test)
                .map(|j| (j as f32 + 0.5) / n_test.max(1) as f32)
                .collect(),
        );
    }
    let step = 1.0 / (n_train - 1) as f32;
    let train: Vec<f32> = (0..n_train)
        .map(|i| {
            let j = if i == 0 || i == n_train - 1 {
                0.0
            } else {
                rng.range(-0.2, 0.2) * step
            };
            (i as f32 * step + j).clamp(0.0, 1.0)
        })
        .collect();
    let test = (0..n_test)
        .map(|j| {
            let k = ((j as f32 + 0.5) / n_test as f32 * (n_train - 1) as f32).floor() as usize;
            let k = k.min(n_train - 2);
            0.5 * (train[k] + train[k + 1])
        })
        .collect();
    (train, test)
}

/// Poses for `n_train` train and `n_test` test views.
pub fn poses(
    layout: Layout,
    path: CameraPath,
    n_train: usize,
    n_test: usize,
    rng: &mut Rng,
) -> (Vec<C2w>, Vec<C2w>) {
    match layout {
        Layout::Around {
            radius,
            target,
            front_only,
        } => {
            let orbit = |n: usize, phase: f32, elev: f32| -> Vec<C2w> {
                (0..n)
                    .map(|i| {
                        let a = (i as f32 + phase) / n.max(1) as f32;
                        let azim = if front_only {
                            (a - 0.5) * 0.75 * PI
                        } else {
                            a * TAU
                        };
                        let e = elev + 0.12 * (a * TAU * 2.0).sin();
                        on_sphere(target, radius, azim, e)
                    })
                    .collect()
            };
            match path {
                CameraPath::Orbit => (orbit(n_train, 0.0, 0.45), orbit(n_test, 0.5, 0.45)),
                CameraPath::Sphere => {
                    let train = (0..n_train)
                        .map(|i| {
                            // Stratified in sin(elevation) over [-25, 85] degrees (mostly the
                            // upper hemisphere), golden-angle azimuth with jitter.
                            let (lo, hi) = if front_only {
                                ((-20f32).to_radians().sin(), 45f32.to_radians().sin())
                            } else {
                                ((-25f32).to_radians().sin(), 85f32.to_radians().sin())
                            };
                            let s = lo + (hi - lo) * ((i as f32 + rng.f32()) / n_train as f32);
                            let elev = s.asin();
                            let azim = if front_only {
                                if rng.f32() < 0.1 {
                                    rng.range(-PI, PI)
                                } else {
                                    rng.range(-0.55, 0.55) * PI
                                }
                            } else {
                                i as f32 * 2.399_963 + rng.range(-0.3, 0.3)
                            };
                            on_sphere(target, radius * rng.range(0.95, 1.05), azim, elev)
                        })
                        .collect();
                    // Test views: a smooth novel path (good for cross-view consistency).
                    (train, orbit(n_test, 0.5, 0.5))
                }
            }
        }
        Layout::Forward {
            centre,
            target,
            spread,
        } => {
            let grid = |n: usize, rng: &mut Rng, jitter: f32| -> Vec<C2w> {
                let cols = (n as f32).sqrt().ceil().max(1.0) as usize;
                let rows = n.div_ceil(cols).max(1);
                (0..n)
                    .map(|i| {
                        let (c, r) = (i % cols, i / cols);
                        let fx = if cols > 1 {
                            c as f32 / (cols - 1) as f32 - 0.5
                        } else {
                            0.0
                        };
                        let fy = if rows > 1 {
                            r as f32 / (rows - 1) as f32 - 0.5
                        } else {
                            0.0
                        };
                        let j = |rng: &mut Rng| rng.range(-jitter, jitter);
                        let eye = centre
                            + vec3(
                                (fx + j(rng)) * spread.x,
                                (0.0 - fy + j(rng)) * spread.y,
                                j(rng) * spread.z,
                            );
                        let tg = target + vec3(j(rng) * 0.3, j(rng) * 0.3, 0.0);
                        look(eye, tg)
                    })
                    .collect()
            };
            let train = grid(n_train, rng, 0.12);
            // Test views: in between grid positions (a small spiral inside the grid).
            let test = (0..n_test)
                .map(|i| {
                    let a = (i as f32 + 0.5) / n_test.max(1) as f32;
                    let r = 0.35 * (0.4 + 0.6 * a);
                    let eye = centre
                        + vec3(
                            (a * TAU).cos() * r * spread.x,
                            (a * TAU).sin() * r * spread.y,
                            0.0,
                        );
                    look(eye, target)
                })
                .collect();
            (train, test)
        }
        Layout::Ring {
            radius,
            height,
            target,
        } => {
            let at = |a: f32, r: f32, h: f32| {
                look(vec3(a.sin() * r, h, a.cos() * r), target)
            };
            let train = (0..n_train)
                .map(|i| {
                    let a = (i as f32
                        + if path == CameraPath::Orbit {
                            0.0
                        } else {
                            rng.f32()
                        })
                        / n_train as f32
                        * TAU;
                    let (r, h) = if path == CameraPath::Orbit {
                        (radius, height)
                    } else {
                        (
                            radius * rng.range(0.9, 1.1),
                            height + rng.range(-0.15, 0.25),
                        )
                    };
                    at(a, r, h)
                })
                .collect();
            let test = (0..n_test)
                .map(|i| {
                    at(
                        (i as f32 + 0.5) / n_test.max(1) as f32 * TAU,
                        radius,
                        height + 0.05,
                    )
                })
                .collect();
            (train, test)
        }
    }
}

pub fn layout_for(kind: SceneKind, dynamic_face: bool) -> Layout {
    match kind {
        SceneKind::Object => Layout::Around {
            radius: 4.0,
            target: Vec3::default(),
            front_only: dynamic_face,
        },
        SceneKind::Forward => Layout::Forward {
            centre: vec3(0.0, 0.0, 0.0),
            target: vec3(0.0, -0.25, -6.0),
            spread: vec3(0.8, 0.5, 0.2),
        },
        SceneKind::Unbounded => Layout::Ring {
            radius: 3.6,
            height: -0.4,
            target: vec3(0.0, -0.2, 0.0),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn test_times_are_held_out() {
        let mut rng = Rng::new(3);
        let (tr, te) = times(20, 7, &mut rng);
        assert_eq!(tr[0], 0.0);
        assert_eq!(tr[19], 1.0);
        for w in tr.windows(2) {
            assert!(w[1] > w[0]);
        }
        for t in te {
            assert!(
                tr.iter().all(|x| (x - t).abs() > 1e-3),
                "{t} equals a train time"
            );
            assert!((0.0..=1.0).contains(&t));
        }
    }

    #[test]
    fn cameras_look_at_target() {
        let mut rng = Rng::new(1);
        let (tr, te) = poses(
            layout_for(SceneKind::Object, false),
            CameraPath::Sphere,
            30,
            5,
            &mut rng,
        );
        for c2w in tr.iter().chain(te.iter()) {
            let m = crate::raster::c2w_matrix(c2w);
            let eye = m.w_axis.truncate();
            let fwd = -m.z_axis.truncate();
            assert!((eye.length() - 4.0).abs() < 0.3);
            assert!(fwd.dot((-eye).normalize_or(Vec3::Y)) > 0.999);
            assert!(
                (m.x_axis.truncate().cross(m.y_axis.truncate()) - m.z_axis.truncate()).length() < 1e-4,
                "right-handed"
            );
        }
    }
}
