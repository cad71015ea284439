//! Where the field lives. World coordinates (whatever the capture used) map to a *model*
//! space, rays are marched there, and sample points map on to the field's *grid* space
//! [-1,1]³ in one of three ways, chosen by the scene kind (and nothing else is switched on):
//!
//! - object: model = world box of interest scaled to [-1,1]³; grid = model. No contraction.
//! - forward: LLFF normalized device coordinates (poses recentred, near plane at 1);
//!   rays are straight lines in NDC with t ∈ [0,1]; grid = NDC with a little x/y margin.
//! - unbounded: model = world scaled so the central region is [-1,1]³, then the L∞
//!   contraction of MERF (identity inside, (2 - 1/|x|∞) outside) maps all space into
//!   [-2,2]³; grid = contraction / 2. No separate background model is needed.

use serde::{Deserialize, Serialize};
use snerf_data::{Dataset, Intrinsics, SceneKind, View};
pub use snerf_geometry::camera::{forward_axis as c2w_forward, position as c2w_position};
pub use snerf_geometry::march::{UNBOUNDED_FAR, UNBOUNDED_NEAR};
pub use snerf_geometry::vec::{add, cross, dot, mat_vec, norm, normalize, scale, sub, Vec3, IDENTITY};
pub use snerf_geometry::{box_hit, contract, uncontract, Ndc, Orbit, Space};

/// The mapping world -> model -> grid for one scene, and where to look at it from.
/// Stored in checkpoints (JSON; `frame`'s fields sit at the top level as they always have).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneSpace {
    pub kind: SceneKind,
    pub dynamic: bool,
    /// model = scale · rot · (world - center) (before NDC for forward scenes).
    #[serde(flatten)]
    pub frame: Space,
    /// Time range of the training frames; times outside it are clamped by the field.
    pub time_range: (f32, f32),
    /// The capture's preview orbit around its up direction (from the training cameras);
    /// bakes carry it so every client's turntable and start view match the trainer's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orbit: Option<Orbit>,
}

/// A ray in model (march) space.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub o: Vec3,
    pub d: Vec3,
    pub t0: f32,
    pub t1: f32,
    /// Unit world direction (what the view MLP sees).
    pub dir: Vec3,
    pub time: f32,
}

impl SceneSpace {
    /// Choose the mapping from the dataset: its kind, its box hint, or its camera layout.
    pub fn from_dataset(data: &Dataset) -> anyhow::Result<SceneSpace> {
        let views: Vec<&View> = data.train.iter().collect();
        anyhow::ensure!(!views.is_empty(), "{}: no training views", data.root.display());
        let times: Vec<f32> = views.iter().filter_map(|v| v.time).collect();
        let time_range = if data.dynamic && !times.is_empty() {
            let lo = times.iter().cloned().fold(f32::INFINITY, f32::min);
            let hi = times.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
            (lo, hi)
        } else {
            (0.0, 1.0)
        };
        let identity = IDENTITY;
        let (center, rot, scale, ndc) = match data.kind {
            SceneKind::Object | SceneKind::Unbounded => {
                let (center, half) = match data.aabb {
                    Some((lo, hi)) => {
                        let c = scale(add(lo, hi), 0.5);
                        let h = (0..3).map(|i| (hi[i] - lo[i]) * 0.5).fold(0.0f32, f32::max);
                        (c, h)
                    }
                    None => estimate_region(&views),
                };
                anyhow::ensure!(half.is_finite() && half > 0.0, "{}: degenerate scene box", data.root.display());
                (center, identity, 1.0 / half, None)
            }
            SceneKind::Forward => {
                let (center, rot) = average_pose(&views);
                // Near bound: from the data (LLFF), else from the box hint, else from the
                // spread of the cameras (content is assumed well beyond it).
                let near = match (data.near_far, data.aabb) {
                    (Some((n, _)), _) => n,
                    (None, Some((lo, hi))) => {
                        // nearest box corner depth along the mean viewing direction
                        let fwd = [-rot[2][0], -rot[2][1], -rot[2][2]];
                        let mut best = f32::INFINITY;
                        for i in 0..8 {
                            let p = [
                                if i & 1 == 0 { lo[0] } else { hi[0] },
                                if i & 2 == 0 { lo[1] } else { hi[1] },
                                if i & 4 == 0 { lo[2] } else { hi[2] },
                            ];
                            best = best.min(dot(sub(p, center), fwd));
                        }
                        best.max(1e-3)
                    }
                    (None, None) => {
                        let spread = views.iter().map(|v| norm(sub(position(v), center))).fold(0.0f32, f32::max);
                        (spread * 10.0).max(1e-3)
                    }
                };
                // LLFF convention: scale so the nearest content sits at depth 1/0.75.
                let s = 1.0 / (near * 0.75);
                let v0 = views[0].intrinsics;
                let ndc = Ndc { fx: v0.fx, fy: v0.fy, width: v0.width as f32, height: v0.height as f32, near: 1.0, xy_extent: 1.25 };
                (center, rot, s, Some(ndc))
            }
        };
        let frame = Space { center, rot, scale, ndc };
        let orbit = Some(crate::orbit::preview_orbit(data.kind, &frame, &views, None));
        Ok(SceneSpace { kind: data.kind, dynamic: data.dynamic, frame, time_range, orbit })
    }

    /// The identity mapping: world = model, with `kind`'s grid mapping (a unit box for
    /// objects, the contraction for unbounded scenes). For tests and synthetic setups.
    pub fn identity(kind: SceneKind, dynamic: bool) -> SceneSpace {
        SceneSpace { kind, dynamic, frame: Space::identity(), time_range: (0.0, 1.0), orbit: None }
    }

    /// World point to model point.
    #[inline]
    pub fn to_model(&self, p: Vec3) -> Vec3 {
        self.frame.to_model(p)
    }

    /// Model point back to world (inverse of [`SceneSpace::to_model`]).
    pub fn to_world(&self, m: Vec3) -> Vec3 {
        self.frame.to_world(m)
    }

    /// March-space point to grid coordinates in [-1,1]³.
    #[inline]
    pub fn to_grid(&self, p: Vec3) -> Vec3 {
        self.frame.march_to_grid(self.kind, p)
    }

    /// Grid point back to march space (for occupancy and baking); unbounded grid points on
    /// the outer shell map to very far (but finite) points.
    pub fn grid_to_march(&self, g: Vec3) -> Vec3 {
        self.frame.grid_to_march(self.kind, g)
    }

    /// Normalized time for the field: training time range mapped to [0,1], clamped.
    #[inline]
    pub fn field_time(&self, t: Option<f32>) -> f32 {
        if !self.dynamic {
            return 0.0;
        }
        let t = t.unwrap_or(0.0);
        let (lo, hi) = self.time_range;
        let u = if hi > lo { (t - lo) / (hi - lo) } else { 0.0 };
        if u.is_nan() {
            0.0
        } else {
            u.clamp(0.0, 1.0)
        }
    }

    /// The ray through pixel (px, py) (pixel centres at +0.5) of a camera, in march space.
    /// `None` when it cannot meet the field (misses the box, or points away in NDC).
    pub fn ray(&self, c2w: &[[f32; 4]; 3], k: &Intrinsics, px: f32, py: f32, time: Option<f32>) -> Option<Ray> {
        let (xu, yu) = undistort((px - k.cx) / k.fx, (py - k.cy) / k.fy, &k.distortion);
        // OpenGL camera: x right, y up, looking down -z.
        let dw = snerf_geometry::camera::camera_dir_to_world(c2w, [xu, -yu, -1.0]);
        let ow = [c2w[0][3], c2w[1][3], c2w[2][3]];
        self.world_ray(ow, dw, time)
    }

    pub fn world_ray(&self, ow: Vec3, dw: Vec3, time: Option<f32>) -> Option<Ray> {
        let r = self.frame.march_ray(self.kind, ow, dw)?;
        Some(Ray { o: r.o, d: r.d, t0: r.t0, t1: r.t1, dir: dw, time: self.field_time(time) })
    }
}

impl SceneSpace {
    /// The world point at march parameter `t` along `ray` (e.g. a rendered expected depth):
    /// undoes the NDC projection for forward-facing scenes.
    pub fn march_to_world(&self, ray: &Ray, t: f32) -> Vec3 {
        self.march_point_to_world(add(ray.o, scale(ray.d, t)))
    }

    /// A world point in march space (inverse of [`SceneSpace::march_point_to_world`]); `None`
    /// for a forward scene's point that is not in front of the reference camera's plane,
    /// which NDC cannot hold.
    pub fn world_to_march(&self, p: Vec3) -> Option<Vec3> {
        let m = self.to_model(p);
        match (self.kind, self.frame.ndc.as_ref()) {
            (SceneKind::Forward, Some(n)) => {
                // (a NaN depth is refused too)
                if m[2].is_nan() || m[2] >= -1e-6 {
                    return None;
                }
                // NeRF's ndc_rays applied to a point: the projection `Ndc::unproject` undoes.
                let (ax, ay) = (-n.fx / (n.width * 0.5), -n.fy / (n.height * 0.5));
                Some([ax * m[0] / m[2], ay * m[1] / m[2], 1.0 + 2.0 * n.near / m[2]])
            }
            _ => Some(m),
        }
    }

    /// A march-space point (model space, or NDC for forward-facing scenes) in world space.
    pub fn march_point_to_world(&self, p: Vec3) -> Vec3 {
        self.frame.march_to_world(self.kind, p)
    }
}

/// OpenCV radial-tangential undistortion of normalized image coordinates (Newton steps).
pub fn undistort(xd: f32, yd: f32, k: &[f32; 4]) -> (f32, f32) {
    if k.iter().all(|&c| c == 0.0) {
        return (xd, yd);
    }
    let (k1, k2, p1, p2) = (k[0], k[1], k[2], k[3]);
    let (mut x, mut y) = (xd, yd);
    for _ in 0..10 {
        let r2 = x * x + y * y;
        let rad = 1.0 + k1 * r2 + k2 * r2 * r2;
        let fx = x * rad + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - xd;
        let fy = y * rad + 2.0 * p2 * x * y + p1 * (r2 + 2.0 * y * y) - yd;
        let drad_dx = 2.0 * x * (k1 + 2.0 * k2 * r2);
        let drad_dy = 2.0 * y * (k1 + 2.0 * k2 * r2);
        let fx_x = rad + x * drad_dx + 2.0 * p1 * y + 6.0 * p2 * x;
        let fx_y = x * drad_dy + 2.0 * p1 * x + 2.0 * p2 * y;
        let fy_x = y * drad_dx + 2.0 * p2 * y + 2.0 * p1 * x;
        let fy_y = rad + y * drad_dy + 2.0 * p2 * x + 6.0 * p1 * y;
        let det = fx_x * fy_y - fx_y * fy_x;
        if det.abs() < 1e-12 {
            break;
        }
        let dx = (fx * fy_y - fy * fx_y) / det;
        let dy = (fy * fx_x - fx * fy_x) / det;
        x -= dx;
        y -= dy;
        if dx.abs() < 1e-7 && dy.abs() < 1e-7 {
            break;
        }
    }
    (x, y)
}

pub fn position(v: &View) -> Vec3 {
    c2w_position(&v.c2w)
}

fn forward_axis(v: &View) -> Vec3 {
    c2w_forward(&v.c2w)
}

/// Centre of interest = the point nearest to all optical axes (least squares); half size =
/// what the cameras see around it (median of distance * tan(half field of view)).
fn estimate_region(views: &[&View]) -> (Vec3, f32) {
    let mut a = [[0.0f64; 3]; 3];
    let mut b = [0.0f64; 3];
    for v in views {
        let o = position(v);
        let d = forward_axis(v);
        // (I - d d^T) c = (I - d d^T) o
        for i in 0..3 {
            for j in 0..3 {
                let m = if i == j { 1.0 } else { 0.0 } - (d[i] * d[j]) as f64;
                a[i][j] += m;
                b[i] += m * o[j] as f64;
            }
        }
    }
    let c = solve3(a, b).unwrap_or_else(|| {
        let mut m = [0.0f32; 3];
        for v in views {
            m = add(m, position(v));
        }
        scale(m, 1.0 / views.len() as f32)
    });
    let mut sizes: Vec<f32> = views
        .iter()
        .map(|v| {
            let half_fov = (0.5 * v.intrinsics.width.min(v.intrinsics.height) as f32 / v.intrinsics.fx).atan();
            norm(sub(position(v), c)) * half_fov.tan()
        })
        .collect();
    sizes.sort_by(|x, y| x.total_cmp(y));
    (c, sizes[sizes.len() / 2])
}

fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<Vec3> {
    let det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
        + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
    if det.abs() < 1e-9 {
        return None;
    }
    let mut x = [0.0f32; 3];
    for (k, xk) in x.iter_mut().enumerate() {
        let mut m = a;
        for i in 0..3 {
            m[i][k] = b[i];
        }
        let dk = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        *xk = (dk / det) as f32;
    }
    Some(x)
}

/// Mean camera pose (LLFF's poses_avg): centre = mean position, axes from the mean
/// viewing direction and up vector. Returns (centre, world->model rotation rows).
fn average_pose(views: &[&View]) -> (Vec3, [[f32; 3]; 3]) {
    let mut c = [0.0f32; 3];
    let mut back = [0.0f32; 3];
    let mut up = [0.0f32; 3];
    for v in views {
        c = add(c, position(v));
        back = add(back, [v.c2w[0][2], v.c2w[1][2], v.c2w[2][2]]);
        up = add(up, [v.c2w[0][1], v.c2w[1][1], v.c2w[2][1]]);
    }
    let c = scale(c, 1.0 / views.len() as f32);
    let z = normalize(back);
    let x = normalize(cross(up, z));
    let y = cross(z, x);
    (c, [x, y, z])
}
