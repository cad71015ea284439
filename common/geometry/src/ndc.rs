//! LLFF normalized device coordinates for forward-facing scenes: rays become straight lines
//! with t ∈ [0,1] from the near plane to infinity (NeRF's `ndc_rays`).

use serde::{Deserialize, Serialize};

use crate::vec::{add, scale, Vec3};

/// NDC of the (recentred) reference camera.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ndc {
    pub fx: f32,
    pub fy: f32,
    pub width: f32,
    pub height: f32,
    pub near: f32,
    /// x/y margin: NDC x,y of rays from off-centre cameras exceed ±1 a little; the grid
    /// spans ±xy_extent.
    pub xy_extent: f32,
}

/// Rays pointing this little towards -z never reach the NDC volume.
pub const NDC_MIN_DZ: f32 = 1.0e-6;
/// NDC z is clamped here when going back to model space: z_ndc → 1 is infinitely far, and
/// 0.999 is 2000 near-plane distances, the same "far" the unbounded march stops at.
pub const NDC_MAX_Z: f32 = 0.999;

impl Ndc {
    fn axes(&self) -> (f32, f32) {
        (-self.fx / (self.width * 0.5), -self.fy / (self.height * 0.5))
    }

    /// A model-space ray (origin `o`, unit direction `d`) in NDC: origin on the near plane,
    /// direction such that t ∈ [0,1] covers near..infinity. None if it points away.
    pub fn project_ray(&self, o: Vec3, d: Vec3) -> Option<(Vec3, Vec3)> {
        if !(d[2] < -NDC_MIN_DZ) {
            return None;
        }
        // Shift the origin to the near plane z = -near, then project.
        let t = -(self.near + o[2]) / d[2];
        let o = add(o, scale(d, t));
        let (ax, ay) = self.axes();
        let o_ndc = [ax * o[0] / o[2], ay * o[1] / o[2], 1.0 + 2.0 * self.near / o[2]];
        let d_ndc = [ax * (d[0] / d[2] - o[0] / o[2]), ay * (d[1] / d[2] - o[1] / o[2]), -2.0 * self.near / o[2]];
        Some((o_ndc, d_ndc))
    }

    /// An NDC point back to model space (z_ndc clamped at [`NDC_MAX_Z`]).
    pub fn unproject(&self, p: Vec3) -> Vec3 {
        // z_ndc = 1 + 2 near / z  =>  z = 2 near / (z_ndc - 1)
        let z = 2.0 * self.near / (p[2].min(NDC_MAX_Z) - 1.0);
        let (ax, ay) = self.axes();
        [p[0] * z / ax, p[1] * z / ay, z]
    }

    /// NDC point to grid coordinates (x, y divided by the margin).
    #[inline]
    pub fn to_grid(&self, p: Vec3) -> Vec3 {
        [p[0] / self.xy_extent, p[1] / self.xy_extent, p[2]]
    }
    #[inline]
    pub fn from_grid(&self, g: Vec3) -> Vec3 {
        [g[0] * self.xy_extent, g[1] * self.xy_extent, g[2]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_on_a_projected_ray_unproject_onto_the_model_ray() {
        let n = Ndc { fx: 60.0, fy: 55.0, width: 64.0, height: 48.0, near: 1.0, xy_extent: 1.25 };
        let o = [0.1, -0.05, 0.2];
        let d = crate::vec::normalize([0.2, 0.1, -1.0]);
        let (on, dn) = n.project_ray(o, d).unwrap();
        for t in [0.0, 0.3, 0.9] {
            let m = n.unproject(add(on, scale(dn, t)));
            // m must lie on the line o + s d
            let s = (m[2] - o[2]) / d[2];
            for i in 0..3 {
                assert!((o[i] + s * d[i] - m[i]).abs() < 1e-4, "t={t}: {m:?}");
            }
            let g = n.to_grid(add(on, scale(dn, t)));
            assert_eq!(n.from_grid(g).map(|x| (x * 1e4).round()), add(on, scale(dn, t)).map(|x| (x * 1e4).round()));
        }
        assert!(n.project_ray(o, [0.0, 0.0, 1.0]).is_none());
    }
}
