//! Viewer cameras: the start view of an asset, orbit/fly controls, stereo eye offsets and
//! pose files (a JSON list of camera-to-world matrices + times, e.g. a recorded head path).

use anyhow::{anyhow, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

use snerf_asset::{Camera, Header};
use snerf_geometry::camera::horizontal;
use snerf_geometry::vec::{add, cross, dot, norm, normalize, scale as mul, sub};

pub type V3 = [f32; 3];

/// Pinhole intrinsics for a `width` x `height` image with vertical field of view `fov_y`
/// degrees, and a camera-to-world matrix.
pub fn camera_from_c2w(c2w: [[f32; 4]; 3], width: u32, height: u32, fov_y: f32) -> Camera {
    Camera::from_fov(c2w, width, height, fov_y)
}

/// The viewer's start camera: the asset's orbit start view (object/unbounded: the orbit's
/// first frame, upright about the scene's up; forward: the mean capture pose).
pub fn initial_camera(h: &Header, width: u32, height: u32, fov_y: f32) -> Camera {
    camera_from_c2w(h.orbit().start_c2w(), width, height, fov_y)
}

/// Left/right eye cameras for a side-by-side display: `snerf_geometry::camera::stereo_eyes`
/// (the per-eye projection the web viewer's immersive mode uses too) with a symmetric
/// projection of `fov_y` for an `eye_width` x `height` image per eye.
pub fn stereo_pair(
    c2w: [[f32; 4]; 3],
    ipd: f32,
    eye_width: u32,
    height: u32,
    fov_y: f32,
) -> (Camera, Camera) {
    let proj = snerf_geometry::camera::perspective(fov_y, eye_width as f32 / height.max(1) as f32, 0.01, 100.0);
    snerf_geometry::camera::stereo_eyes(c2w, ipd, &proj, eye_width, height)
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

/// Read a pose file: a nerfstudio `camera_path.json` (what `snerf render` and turntables
/// write), or a list `[{"c2w": [[..4], [..4], [..4]], "time": 0.5}, ...]`.
pub fn load_poses(path: impl AsRef<Path>) -> Result<Vec<PoseSample>> {
    let path = path.as_ref();
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow!("{}: cannot read pose file: {}", path.display(), e))?;
    let cams = snerf_geometry::camera_path::parse(&text, (1, 1), 60.0)
        .map_err(|e| anyhow!("{}: {}", path.display(), e))?;
    Ok(cams
        .iter()
        .map(|c| PoseSample { c2w: c.cam.c2w.to_vec(), time: c.time })
        .collect())
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
    /// Start at `initial_camera`'s view of the asset, upright about the asset's up.
    pub fn new(h: &Header) -> Controller {
        let o = h.orbit();
        let up = normalize(o.up());
        let (eye, target) = o.start();
        let back = normalize(sub(eye, target));
        let back0 = horizontal(up, back);
        let right0 = normalize(cross(up, back0));
        let pitch = dot(back, up).clamp(-1.0, 1.0).asin();
        let dist = norm(sub(eye, target)).max(1e-6);
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
