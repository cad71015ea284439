//! Viewer cameras: the start view of an asset, orbit/fly controls, stereo eye offsets and
//! pose files (a JSON list of camera-to-world matrices + times, e.g. a recorded head path).

use anyhow::{anyhow, ensure, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

use snerf_asset::render::model_to_world;
use snerf_asset::{Camera, Header, Kind};

pub type V3 = [f32; 3];

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn mul(a: V3, s: f32) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn normalize(a: V3) -> V3 {
    let n = dot(a, a).sqrt();
    if n > 0.0 && n.is_finite() {
        mul(a, 1.0 / n)
    } else {
        [0.0, 0.0, -1.0]
    }
}
/// rot^T v: model direction -> world direction.
fn model_dir(h: &Header, v: V3) -> V3 {
    let r = &h.space.rot;
    [
        r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2],
        r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
        r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2],
    ]
}

/// Pinhole intrinsics for a `width` x `height` image with vertical field of view `fov_y`
/// degrees, and a camera-to-world matrix.
pub fn camera_from_c2w(c2w: [[f32; 4]; 3], width: u32, height: u32, fov_y: f32) -> Camera {
    let f = 0.5 * height as f32 / (0.5 * fov_y.to_radians()).tan();
    Camera {
        c2w,
        fx: f,
        fy: f,
        cx: 0.5 * width as f32,
        cy: 0.5 * height as f32,
        width,
        height,
    }
}

/// The viewer's start camera: `snerf_asset::orbit` frame 0 (object/unbounded: 3 model units
/// out at 30° elevation looking at the centre; forward: the reference camera).
pub fn initial_camera(h: &Header, width: u32, height: u32, fov_y: f32) -> Camera {
    snerf_asset::orbit(h, 1, 0, width, height, fov_y)
}

/// Left/right eye cameras: `c2w` moved by ∓ipd/2 along its right axis (first column);
/// each eye gets its own `eye_width` x `height` image.
pub fn stereo_pair(
    c2w: [[f32; 4]; 3],
    ipd: f32,
    eye_width: u32,
    height: u32,
    fov_y: f32,
) -> (Camera, Camera) {
    let right = normalize([c2w[0][0], c2w[1][0], c2w[2][0]]);
    let shift = |s: f32| {
        let mut m = c2w;
        for (r, row) in m.iter_mut().enumerate() {
            row[3] += s * 0.5 * ipd * right[r];
        }
        camera_from_c2w(m, eye_width, height, fov_y)
    };
    (shift(-1.0), shift(1.0))
}

/// One entry of a pose file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseSample {
    /// Camera-to-world, OpenGL convention (x right, y up, looking down -z); 3 or 4 rows of 4.
    pub c2w: Vec<[f32; 4]>,
    /// Asset time for this pose (optional: playback time is used when absent).
    #[serde(default)]
    pub time: Option<f32>,
}

impl PoseSample {
    pub fn c2w3(&self) -> [[f32; 4]; 3] {
        [self.c2w[0], self.c2w[1], self.c2w[2]]
    }
}

/// Read a pose file: `[{"c2w": [[..4], [..4], [..4]], "time": 0.5}, ...]`.
pub fn load_poses(path: impl AsRef<Path>) -> Result<Vec<PoseSample>> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow!("{}: cannot read pose file: {}", path.display(), e))?;
    let poses: Vec<PoseSample> = serde_json::from_str(&text).map_err(|e| {
        anyhow!(
            "{}: not a pose file (JSON list of {{c2w, time}}): {}",
            path.display(),
            e
        )
    })?;
    ensure!(
        !poses.is_empty(),
        "{}: pose file has no poses",
        path.display()
    );
    for (i, p) in poses.iter().enumerate() {
        ensure!(
            p.c2w.len() == 3 || p.c2w.len() == 4,
            "{}: pose {} has {} rows (need 3 or 4 rows of 4)",
            path.display(),
            i,
            p.c2w.len()
        );
        ensure!(
            p.c2w.iter().flatten().all(|x| x.is_finite()) && p.time.is_none_or(|t| t.is_finite()),
            "{}: pose {} has non-finite values",
            path.display(),
            i
        );
    }
    Ok(poses)
}

/// Orbit + fly camera. The eye sits at `target + dist · dir(yaw, pitch)` and looks at the
/// target; orbiting moves the eye around the target, flying and panning move both.
#[derive(Clone, Debug)]
pub struct Controller {
    pub target: V3,
    pub dist: f32,
    pub yaw: f32,
    pub pitch: f32,
    up: V3,
    back0: V3,
    right0: V3,
    home: (V3, f32, f32, f32),
}

impl Controller {
    /// Start at `initial_camera`'s view of the asset.
    pub fn new(h: &Header) -> Controller {
        let up = normalize(model_dir(h, [0.0, 1.0, 0.0]));
        let back0 = normalize(model_dir(h, [0.0, 0.0, 1.0]));
        let right0 = normalize(model_dir(h, [1.0, 0.0, 0.0]));
        let s = h.space.scale.max(1e-12);
        let (target, dist, pitch) = match h.kind {
            Kind::Forward => {
                let eye = model_to_world(h, [0.0; 3]);
                let dist = 1.0 / s;
                (sub(eye, mul(back0, dist)), dist, 0.0)
            }
            Kind::Object | Kind::Unbounded => {
                (model_to_world(h, [0.0; 3]), 3.0 / s, 30f32.to_radians())
            }
        };
        Controller {
            target,
            dist,
            yaw: 0.0,
            pitch,
            up,
            back0,
            right0,
            home: (target, dist, 0.0, pitch),
        }
    }

    fn dir(&self) -> V3 {
        let (cp, sp) = (self.pitch.cos(), self.pitch.sin());
        let (cy, sy) = (self.yaw.cos(), self.yaw.sin());
        add(
            add(mul(self.back0, cp * cy), mul(self.right0, cp * sy)),
            mul(self.up, sp),
        )
    }

    pub fn eye(&self) -> V3 {
        add(self.target, mul(self.dir(), self.dist))
    }

    pub fn forward(&self) -> V3 {
        mul(self.dir(), -1.0)
    }

    /// Camera-to-world: columns right, up, back (= -forward), eye.
    pub fn c2w(&self) -> [[f32; 4]; 3] {
        let back = self.dir();
        let mut right = cross(self.up, back);
        if dot(right, right) < 1e-12 {
            right = self.right0;
        }
        let right = normalize(right);
        let up = cross(back, right);
        let e = self.eye();
        [
            [right[0], up[0], back[0], e[0]],
            [right[1], up[1], back[1], e[1]],
            [right[2], up[2], back[2], e[2]],
        ]
    }

    pub fn reset(&mut self) {
        (self.target, self.dist, self.yaw, self.pitch) = self.home;
    }

    const MAX_PITCH: f32 = 1.55;

    /// Rotate the eye around the target (left drag); dx, dy in pixels.
    pub fn orbit(&mut self, dx: f32, dy: f32) {
        self.yaw -= dx * 0.005;
        self.pitch = (self.pitch + dy * 0.005).clamp(-Self::MAX_PITCH, Self::MAX_PITCH);
    }

    /// Turn the view around the eye (fly mouse look).
    pub fn look(&mut self, dx: f32, dy: f32) {
        let eye = self.eye();
        self.yaw -= dx * 0.003;
        self.pitch = (self.pitch + dy * 0.003).clamp(-Self::MAX_PITCH, Self::MAX_PITCH);
        self.target = sub(eye, mul(self.dir(), self.dist));
    }

    /// Move target and eye in the view plane (pan), dx, dy in pixels.
    pub fn pan(&mut self, dx: f32, dy: f32) {
        let m = self.c2w();
        let right = [m[0][0], m[1][0], m[2][0]];
        let up = [m[0][1], m[1][1], m[2][1]];
        let k = self.dist * 0.0015;
        self.target = add(self.target, add(mul(right, -dx * k), mul(up, dy * k)));
    }

    /// Zoom: scale the eye-target distance (positive = closer).
    pub fn zoom(&mut self, steps: f32) {
        self.dist = (self.dist * 0.9f32.powf(steps)).clamp(1e-4, 1e6);
    }

    /// Fly: move by (right, up, forward) in units of the current distance.
    pub fn fly(&mut self, right: f32, up: f32, forward: f32) {
        let m = self.c2w();
        let r = [m[0][0], m[1][0], m[2][0]];
        let f = self.forward();
        let d = add(add(mul(r, right), mul(self.up, up)), mul(f, forward));
        self.target = add(self.target, mul(d, self.dist));
    }
}
