//! Where the field lives. World coordinates (whatever the capture used) map to a *model*
//! space by a similarity, rays are marched in *march* space, and sample points map on to the
//! field's *grid* space [-1,1]³ in one of three ways, chosen by the scene kind:
//!
//! - object: march = model = world box of interest scaled to [-1,1]³; grid = model.
//! - forward: march = LLFF NDC of the model ray (t ∈ [0,1]); grid = NDC with an x/y margin.
//! - unbounded: march = model (central region [-1,1]³); grid = MERF contraction / 2, which
//!   maps all of space into the grid, so no separate background model is needed.

use serde::{Deserialize, Serialize};

use crate::contract::{contract, uncontract};
use crate::kind::SceneKind;
use crate::march::{box_hit, UNBOUNDED_FAR, UNBOUNDED_NEAR};
use crate::ndc::Ndc;
use crate::vec::{add, mat_t_vec, mat_vec, normalize, scale, sub, Rows3, Vec3, IDENTITY};

/// World -> model: model = scale · rot · (world - center). Stored in checkpoints and baked
/// asset headers.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Space {
    pub center: Vec3,
    /// Row-major, orthonormal.
    pub rot: Rows3,
    pub scale: f32,
    /// NDC of the reference camera: present exactly for forward-facing scenes.
    pub ndc: Option<Ndc>,
}

/// A ray in march space: points o + t·d for t in [t0, t1].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MarchRay {
    pub o: Vec3,
    pub d: Vec3,
    pub t0: f32,
    pub t1: f32,
}

impl Space {
    pub fn identity() -> Space {
        Space { center: [0.0; 3], rot: IDENTITY, scale: 1.0, ndc: None }
    }

    #[inline]
    pub fn to_model(&self, p: Vec3) -> Vec3 {
        scale(mat_vec(&self.rot, sub(p, self.center)), self.scale)
    }
    /// Inverse of [`Space::to_model`] (rot is orthonormal).
    #[inline]
    pub fn to_world(&self, m: Vec3) -> Vec3 {
        add(mat_t_vec(&self.rot, scale(m, 1.0 / self.scale)), self.center)
    }
    /// A world direction in model space (unit).
    #[inline]
    pub fn dir_to_model(&self, d: Vec3) -> Vec3 {
        normalize(mat_vec(&self.rot, d))
    }
    /// A model direction in world space (rotation only; no scale).
    #[inline]
    pub fn dir_to_world(&self, d: Vec3) -> Vec3 {
        mat_t_vec(&self.rot, d)
    }

    /// The world ray (origin, direction) in march space, clipped to where it can meet the
    /// field; None when it cannot (misses the object box, points away in NDC, not finite).
    pub fn march_ray(&self, kind: SceneKind, ow: Vec3, dw: Vec3) -> Option<MarchRay> {
        if !ow.iter().chain(dw.iter()).all(|x| x.is_finite()) {
            return None;
        }
        let o = self.to_model(ow);
        let d = self.dir_to_model(dw);
        match kind {
            SceneKind::Object => {
                let (t0, t1) = box_hit(o, d, 1.0)?;
                Some(MarchRay { o, d, t0: t0.max(0.0), t1 })
            }
            SceneKind::Unbounded => Some(MarchRay { o, d, t0: UNBOUNDED_NEAR, t1: UNBOUNDED_FAR }),
            SceneKind::Forward => {
                let (o, d) = self.ndc.as_ref()?.project_ray(o, d)?;
                Some(MarchRay { o, d, t0: 0.0, t1: 1.0 })
            }
        }
    }

    /// March-space point to grid coordinates in [-1,1]³.
    #[inline]
    pub fn march_to_grid(&self, kind: SceneKind, p: Vec3) -> Vec3 {
        match (kind, self.ndc.as_ref()) {
            (SceneKind::Object, _) => p,
            (SceneKind::Forward, Some(n)) => n.to_grid(p),
            (SceneKind::Forward, None) => p,
            (SceneKind::Unbounded, _) => contract(p).map(|x| x * 0.5),
        }
    }

    /// Grid point back to march space; unbounded grid points on the outer shell map to very
    /// far (but finite) points.
    pub fn grid_to_march(&self, kind: SceneKind, g: Vec3) -> Vec3 {
        match (kind, self.ndc.as_ref()) {
            (SceneKind::Object, _) => g,
            (SceneKind::Forward, Some(n)) => n.from_grid(g),
            (SceneKind::Forward, None) => g,
            (SceneKind::Unbounded, _) => uncontract(g.map(|x| x * 2.0)),
        }
    }

    /// March-space point to world space (undoes NDC for forward-facing scenes).
    pub fn march_to_world(&self, kind: SceneKind, p: Vec3) -> Vec3 {
        let m = match (kind, self.ndc.as_ref()) {
            (SceneKind::Forward, Some(n)) => n.unproject(p),
            _ => p,
        };
        self.to_world(m)
    }

    /// Grid point to world: object identity; forward NDC inverse; unbounded inverse
    /// contraction.
    pub fn grid_to_world(&self, kind: SceneKind, g: Vec3) -> Vec3 {
        self.march_to_world(kind, self.grid_to_march(kind, g))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn space(kind: SceneKind) -> Space {
        let (c, s) = (0.3f32.cos(), 0.3f32.sin());
        Space {
            center: [0.5, -1.0, 2.0],
            rot: [[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]],
            scale: 0.4,
            ndc: (kind == SceneKind::Forward)
                .then_some(Ndc { fx: 60.0, fy: 60.0, width: 64.0, height: 48.0, near: 1.0, xy_extent: 1.25 }),
        }
    }

    /// For every kind: a world point on a camera ray, taken to the grid and back, is where
    /// it was (the round trip every consumer of the grid relies on).
    #[test]
    fn world_grid_round_trip_for_every_kind() {
        for kind in [SceneKind::Object, SceneKind::Forward, SceneKind::Unbounded] {
            let sp = space(kind);
            let ow = sp.to_world([0.05, 0.02, 3.0]);
            let dw = sp.dir_to_world(normalize([0.1, -0.05, -1.0]));
            let r = sp.march_ray(kind, ow, dw).unwrap_or_else(|| panic!("{kind:?} ray"));
            for f in [0.1f32, 0.5, 0.9] {
                let t = r.t0 + f * (r.t1.min(50.0) - r.t0);
                let p = add(r.o, scale(r.d, t));
                let w = sp.march_to_world(kind, p);
                let g = sp.march_to_grid(kind, p);
                let w2 = sp.grid_to_world(kind, g);
                let tol = 1e-3 * crate::vec::norm(sub(w, ow)).max(1.0);
                assert!(crate::vec::norm(sub(w, w2)) < tol, "{kind:?} t={t}: {w:?} vs {w2:?}");
                // and the world point lies on the world ray
                let along = crate::vec::dot(sub(w, ow), dw);
                assert!(crate::vec::norm(sub(add(ow, scale(dw, along)), w)) < tol, "{kind:?}: off the ray");
            }
        }
    }
}
