//! Cameras: pinhole rays, look-at, the one orbit every turntable and start view uses, and
//! the scene's up direction.
//!
//! Camera-to-world matrices are 3 rows of [R | t] in the OpenGL convention (x right, y up,
//! looking down -z), as in nerfstudio / Blender `transform_matrix` files.

use serde::{Deserialize, Serialize};

use crate::vec::{add, cross, dot, norm, normalize, scale, sub, Vec3};

pub type C2w = [[f32; 4]; 3];

/// Camera position (the translation column).
pub fn position(c2w: &C2w) -> Vec3 {
    [c2w[0][3], c2w[1][3], c2w[2][3]]
}
/// Camera up axis in world space (the second column).
pub fn up_axis(c2w: &C2w) -> Vec3 {
    [c2w[0][1], c2w[1][1], c2w[2][1]]
}
/// Viewing direction in world space (minus the third column), unit.
pub fn forward_axis(c2w: &C2w) -> Vec3 {
    normalize([-c2w[0][2], -c2w[1][2], -c2w[2][2]])
}

/// A pinhole camera with its image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pinhole {
    pub c2w: C2w,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub width: u32,
    pub height: u32,
}

impl Pinhole {
    /// Square pixels, principal point at the centre, vertical field of view `fov_y` degrees.
    pub fn from_fov(c2w: C2w, width: u32, height: u32, fov_y: f32) -> Pinhole {
        let f = 0.5 * height as f32 / (0.5 * fov_y.to_radians()).tan();
        Pinhole { c2w, fx: f, fy: f, cx: 0.5 * width as f32, cy: 0.5 * height as f32, width, height }
    }

    /// The camera of one eye given as WebXR does: a column-major OpenGL projection matrix
    /// (possibly asymmetric) and the eye's pose, for a `width` x `height` image. The one
    /// per-eye projection both the native `--stereo` view and the web viewer's immersive
    /// mode use (`viewer/stream/web/xr.js` `eyeCamera` is this, in JavaScript; its test
    /// compares the two).
    pub fn from_projection(proj: &[f32; 16], c2w: C2w, width: u32, height: u32) -> Pinhole {
        let (w, h) = (width as f32, height as f32);
        Pinhole {
            c2w,
            fx: proj[0] * w / 2.0,
            fy: proj[5] * h / 2.0,
            cx: w / 2.0 * (1.0 - proj[8]),
            cy: h / 2.0 * (1.0 + proj[9]),
            width,
            height,
        }
    }

    /// World origin and unit world direction through the centre of pixel (px, py).
    pub fn ray(&self, px: u32, py: u32) -> (Vec3, Vec3) {
        self.ray_at(px, py, 0.5, 0.5)
    }

    /// World origin and unit world direction through the point (sx, sy) of pixel (px, py)'s
    /// square (pixel units from its corner; (0.5, 0.5) is the centre, as [`Pinhole::ray`]).
    pub fn ray_at(&self, px: u32, py: u32, sx: f32, sy: f32) -> (Vec3, Vec3) {
        let dc = [(px as f32 + sx - self.cx) / self.fx, -(py as f32 + sy - self.cy) / self.fy, -1.0];
        (position(&self.c2w), camera_dir_to_world(&self.c2w, dc))
    }
}

/// A symmetric OpenGL perspective projection (column-major): vertical field of view `fov_y`
/// degrees, aspect width/height, depth range [near, far].
pub fn perspective(fov_y: f32, aspect: f32, near: f32, far: f32) -> [f32; 16] {
    let f = 1.0 / (0.5 * fov_y.to_radians()).tan();
    let mut m = [0.0; 16];
    m[0] = f / aspect;
    m[5] = f;
    m[10] = (far + near) / (near - far);
    m[11] = -1.0;
    m[14] = 2.0 * far * near / (near - far);
    m
}

/// The two eyes of a head pose `c2w` for a side-by-side display: each moved by ∓ipd/2 along
/// the head's right axis, each with `proj`, through `Pinhole::from_projection`.
pub fn stereo_eyes(c2w: C2w, ipd: f32, proj: &[f32; 16], eye_width: u32, height: u32) -> (Pinhole, Pinhole) {
    let right = normalize([c2w[0][0], c2w[1][0], c2w[2][0]]);
    let eye = |s: f32| {
        let mut m = c2w;
        for (r, row) in m.iter_mut().enumerate() {
            row[3] += s * 0.5 * ipd * right[r];
        }
        Pinhole::from_projection(proj, m, eye_width, height)
    };
    (eye(-1.0), eye(1.0))
}

/// Where world point `p` lands in a pinhole camera (`c2w`, focal lengths and principal point
/// in pixels): continuous pixel coordinates (pixel x covers [x, x+1)) and the distance from
/// the camera centre; None behind the camera. The inverse of [`Pinhole::ray`].
pub fn project(c2w: &C2w, fx: f32, fy: f32, cx: f32, cy: f32, p: Vec3) -> Option<(f32, f32, f32)> {
    let m = c2w;
    let d = sub(p, position(m));
    // camera axes are the columns of the rotation
    let xc = dot(d, [m[0][0], m[1][0], m[2][0]]);
    let yc = dot(d, [m[0][1], m[1][1], m[2][1]]);
    let zc = dot(d, [m[0][2], m[1][2], m[2][2]]);
    if zc >= -1e-6 {
        return None;
    }
    Some((cx + fx * xc / -zc, cy + fy * -yc / -zc, norm(d)))
}

/// A camera-space direction in world space (unit).
pub fn camera_dir_to_world(c2w: &C2w, dc: Vec3) -> Vec3 {
    let m = c2w;
    normalize([
        m[0][0] * dc[0] + m[0][1] * dc[1] + m[0][2] * dc[2],
        m[1][0] * dc[0] + m[1][1] * dc[1] + m[1][2] * dc[2],
        m[2][0] * dc[0] + m[2][1] * dc[1] + m[2][2] * dc[2],
    ])
}

/// Camera-to-world looking from `eye` at `target` with `up` as close to the image's up as
/// the view allows.
pub fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> C2w {
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

/// The scene's up direction from its cameras: the mean of their up axes. People hold
/// cameras upright, and Blender/nerf_synthetic (+z up), nerfstudio and COLMAP-derived (+y
/// or -y up) captures all agree with this where a fixed axis would be wrong for some.
/// Falls back to +y when the cameras' ups cancel out.
pub fn mean_up<'a>(c2ws: impl IntoIterator<Item = &'a C2w>) -> Vec3 {
    let s = c2ws.into_iter().fold([0.0; 3], |a, m| add(a, up_axis(m)));
    if norm(s) > 1e-6 {
        normalize(s)
    } else {
        [0.0, 1.0, 0.0]
    }
}

/// A unit vector perpendicular to `up`, the same for every capture of one scene up to the
/// scene's own rotation about `up` (used as the direction of an orbit's first frame).
pub fn horizontal(up: Vec3, hint: Vec3) -> Vec3 {
    let h = sub(hint, scale(up, dot(hint, up)));
    if norm(h) > 1e-4 {
        normalize(h)
    } else {
        normalize(cross(up, [0.3, 0.1, 0.9]))
    }
}

/// A closed camera path, defined once for every turntable, preview and start view: the
/// trainer's field turntable, `snerf render` of a baked asset, the demo and the viewers all
/// evaluate this, so they see the scene from the same places.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "path", rename_all = "lowercase")]
pub enum Orbit {
    /// Objects and unbounded scenes: a circle around `center` at `elevation` radians above
    /// the plane ⟂ `up`, starting in direction `start` (unit, ⟂ up), looking at the centre.
    Around { center: Vec3, up: Vec3, start: Vec3, radius: f32, elevation: f32 },
    /// Forward-facing scenes: an ellipse around `center` in the plane spanned by `right`
    /// and `up` (radii `rx`, `ry`), looking at `target`.
    Ellipse { center: Vec3, right: Vec3, up: Vec3, target: Vec3, rx: f32, ry: f32 },
}

impl Orbit {
    /// The world up direction of the path (what a viewer keeps upright).
    pub fn up(&self) -> Vec3 {
        match *self {
            Orbit::Around { up, .. } | Orbit::Ellipse { up, .. } => up,
        }
    }

    /// Camera `i` of `n` on the path.
    pub fn c2w(&self, i: usize, n: usize) -> C2w {
        let a = std::f32::consts::TAU * i as f32 / n.max(1) as f32;
        match *self {
            Orbit::Around { center, up, start, radius, elevation } => {
                let side = cross(up, start);
                let horiz = add(scale(start, a.cos()), scale(side, a.sin()));
                let dir = add(scale(horiz, elevation.cos()), scale(up, elevation.sin()));
                look_at(add(center, scale(dir, radius)), center, up)
            }
            Orbit::Ellipse { center, right, up, target, rx, ry } => {
                let eye = add(center, add(scale(right, rx * a.cos()), scale(up, ry * a.sin())));
                look_at(eye, target, up)
            }
        }
    }

    /// Where a viewer opens: (eye, target). Around: frame 0 of the orbit; Ellipse: the
    /// centre of the ellipse (the mean capture pose) looking at the target.
    pub fn start(&self) -> (Vec3, Vec3) {
        match *self {
            Orbit::Around { center, .. } => (position(&self.c2w(0, 1)), center),
            Orbit::Ellipse { center, target, .. } => (center, target),
        }
    }

    /// The start view as a camera-to-world matrix.
    pub fn start_c2w(&self) -> C2w {
        let (eye, target) = self.start();
        look_at(eye, target, self.up())
    }

    /// `n` cameras around the path.
    pub fn path(&self, n: usize) -> Vec<C2w> {
        (0..n).map(|i| self.c2w(i, n)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_projection_matrix_gives_the_pinhole_it_describes() {
        let c2w = [[1.0, 0.0, 0.0, 0.5], [0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 2.0]];
        // Symmetric: the same camera as from_fov.
        let p = perspective(60.0, 4.0 / 3.0, 0.1, 100.0);
        let a = Pinhole::from_projection(&p, c2w, 64, 48);
        let b = Pinhole::from_fov(c2w, 64, 48, 60.0);
        for (x, y) in [(a.fx, b.fx), (a.fy, b.fy), (a.cx, b.cx), (a.cy, b.cy)] {
            assert!((x - y).abs() < 1e-4, "{x} vs {y}");
        }
        // An asymmetric frustum (glFrustum l, r, b, t at near n): its corners land on the
        // image corners.
        let (l, r, bt, t, n, f) = (-0.3f32, 0.5f32, -0.2f32, 0.4f32, 0.5f32, 50.0f32);
        let mut m = [0.0f32; 16];
        m[0] = 2.0 * n / (r - l);
        m[5] = 2.0 * n / (t - bt);
        m[8] = (r + l) / (r - l);
        m[9] = (t + bt) / (t - bt);
        m[10] = -(f + n) / (f - n);
        m[11] = -1.0;
        m[14] = -2.0 * f * n / (f - n);
        let id = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
        let c = Pinhole::from_projection(&m, id, 80, 60);
        let (x, y, _) = project(&id, c.fx, c.fy, c.cx, c.cy, [l, t, -n]).unwrap();
        assert!(x.abs() < 1e-3 && y.abs() < 1e-3, "top-left corner at ({x}, {y})");
        let (x, y, _) = project(&id, c.fx, c.fy, c.cx, c.cy, [r, bt, -n]).unwrap();
        assert!((x - 80.0).abs() < 1e-3 && (y - 60.0).abs() < 1e-3, "bottom-right corner at ({x}, {y})");
        // Stereo eyes: an IPD apart along the head's right axis, the same intrinsics.
        let (le, re) = stereo_eyes(c2w, 0.064, &p, 64, 48);
        assert!((re.c2w[0][3] - le.c2w[0][3] - 0.064).abs() < 1e-6 && le.fx == a.fx);
    }

    #[test]
    fn orbit_is_upright_and_looks_at_the_centre() {
        for up in [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], normalize([0.2, 0.9, -0.1])] {
            let start = horizontal(up, [1.0, 0.0, 0.0]);
            let o = Orbit::Around { center: [1.0, 2.0, 3.0], up, start, radius: 4.0, elevation: 0.5 };
            for m in o.path(7) {
                let eye = position(&m);
                assert!((norm(sub(eye, [1.0, 2.0, 3.0])) - 4.0).abs() < 1e-4);
                assert!((dot(sub(eye, [1.0, 2.0, 3.0]), up) / 4.0 - 0.5f32.sin()).abs() < 1e-4);
                // image x axis is horizontal: no roll
                assert!(dot([m[0][0], m[1][0], m[2][0]], up).abs() < 1e-5);
                assert!(dot(up_axis(&m), up) > 0.0);
            }
        }
        let ups = [look_at([0.0, -3.0, 1.0], [0.0; 3], [0.0, 0.0, 1.0]), look_at([3.0, 0.0, 1.0], [0.0; 3], [0.0, 0.0, 1.0])];
        let u = mean_up(ups.iter());
        // project is the inverse of ray: a point on a pixel's ray lands in that pixel's centre
        let cam = Pinhole::from_fov(ups[0], 32, 24, 50.0);
        let (o, d) = cam.ray(7, 5);
        let (x, y, dist) = project(&cam.c2w, cam.fx, cam.fy, cam.cx, cam.cy, add(o, scale(d, 2.5))).unwrap();
        assert!((x - 7.5).abs() < 1e-3 && (y - 5.5).abs() < 1e-3 && (dist - 2.5).abs() < 1e-4, "{x} {y} {dist}");
        assert!(u[2] > 0.9, "{u:?}");
    }
}
