//! Empty-space skipping: an occupancy grid over grid space [-1,1]³ and the ray marcher that
//! uses it. Each cell keeps a running max of the optical depth a typical step would see
//! there (decayed at every refresh, as in Instant-NGP), plus a permanent mask from silhouette
//! carving (object scenes with alpha: a cell that projects onto transparent background in
//! some training view is empty for good).
//!
//! Sampling: fixed steps along the ray in grid units (so sample density matches the field's
//! resolution), snapped to a per-ray jittered lattice; empty cells are jumped over to their
//! exit in one go where the grid mapping is affine.

use serde::{Deserialize, Serialize};
use snerf_data::SceneKind;

use crate::space::{Ray, SceneSpace, Vec3};

/// Optical depth per typical step above which a cell counts as occupied.
pub const OCCUPIED_DEPTH: f32 = 1.0e-3;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Occupancy {
    pub res: usize,
    /// Base step length in grid units.
    pub step: f32,
    /// Running max of σ·δ_typical per cell.
    pub depth: Vec<f32>,
    /// false = carved away for good.
    pub allowed: Vec<bool>,
    /// Derived: allowed && depth > OCCUPIED_DEPTH (kept as bytes for the marcher's hot loop).
    #[serde(skip)]
    pub occ: Vec<u8>,
}

/// One sample produced by the marcher.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sample {
    pub g: Vec3,
    /// Step length in march space (what σ integrates over).
    pub delta: f32,
    /// Ray parameter (depth along the march-space ray).
    pub t: f32,
}

/// Per-ray marching state, so a ray can be continued wave by wave.
#[derive(Clone, Copy, Debug, Default)]
pub struct MarchState {
    pub t: f32,
    pub done: bool,
}

impl Occupancy {
    pub fn new(res: usize, steps_per_diagonal: usize) -> Occupancy {
        let n = res * res * res;
        let mut o = Occupancy {
            res,
            step: 2.0 * 3f32.sqrt() / steps_per_diagonal as f32,
            depth: vec![f32::MAX; n],
            allowed: vec![true; n],
            occ: Vec::new(),
        };
        o.refresh_bits();
        o
    }

    pub fn refresh_bits(&mut self) {
        self.occ = self.depth.iter().zip(&self.allowed).map(|(&d, &a)| (a && d > OCCUPIED_DEPTH) as u8).collect();
    }

    pub fn occupied_fraction(&self) -> f32 {
        self.occ.iter().map(|&b| b as usize).sum::<usize>() as f32 / self.occ.len().max(1) as f32
    }

    /// Cell index of a grid point, `None` outside [-1,1]³.
    #[inline]
    pub fn cell(&self, g: &Vec3) -> Option<usize> {
        let r = self.res as f32;
        let mut idx = 0usize;
        for a in 0..3 {
            let u = (g[a] + 1.0) * 0.5 * r;
            if !(u >= 0.0 && u < r) {
                return None;
            }
            idx = idx * self.res + u as usize;
        }
        Some(idx)
    }

    /// Centre of cell `i` in grid coordinates.
    pub fn cell_center(&self, i: usize) -> Vec3 {
        let r = self.res;
        let (x, y, z) = (i / (r * r), (i / r) % r, i % r);
        let f = |k: usize| (k as f32 + 0.5) / r as f32 * 2.0 - 1.0;
        [f(x), f(y), f(z)]
    }

    /// Typical step length (march space) at a grid point: what σ is multiplied by there.
    #[inline]
    pub fn typical_delta(&self, space: &SceneSpace, g: &Vec3) -> f32 {
        match space.kind {
            SceneKind::Object => self.step,
            SceneKind::Forward => self.step,
            SceneKind::Unbounded => {
                let p = space.grid_to_march(*g);
                unbounded_dt(self.step, p)
            }
        }
    }

    /// Start marching a ray: jitter in [0,1) shifts the sample lattice (stratified sampling).
    pub fn start(&self, space: &SceneSpace, ray: &Ray, jitter: f32) -> MarchState {
        let dt = self.dt_at(space, ray, ray.t0);
        MarchState { t: ray.t0 + jitter * dt, done: false }
    }

    #[inline]
    fn dt_at(&self, space: &SceneSpace, ray: &Ray, t: f32) -> f32 {
        match space.kind {
            SceneKind::Unbounded => {
                let p = [ray.o[0] + t * ray.d[0], ray.o[1] + t * ray.d[1], ray.o[2] + t * ray.d[2]];
                unbounded_dt(self.step, p)
            }
            _ => self.step / grid_speed(space, ray),
        }
    }

    /// Append up to `max` occupied samples of `ray` to `out`, continuing from `state`.
    pub fn march(&self, space: &SceneSpace, ray: &Ray, state: &mut MarchState, max: usize, out: &mut Vec<Sample>) {
        if state.done {
            return;
        }
        let affine = space.kind != SceneKind::Unbounded;
        let speed = if affine { grid_speed(space, ray) } else { 1.0 };
        let dlen = crate::space::norm(ray.d);
        let mut t = state.t;
        let mut taken = 0;
        // A hard cap on loop iterations guards against a degenerate step.
        let mut guard = 0usize;
        while taken < max {
            guard += 1;
            if t >= ray.t1 || guard > 1 << 16 {
                state.done = true;
                break;
            }
            let p = [ray.o[0] + t * ray.d[0], ray.o[1] + t * ray.d[1], ray.o[2] + t * ray.d[2]];
            let g = space.to_grid(p);
            let dt = if affine { self.step / speed } else { unbounded_dt(self.step, p) };
            match self.cell(&g) {
                Some(c) if self.occ[c] != 0 => {
                    out.push(Sample { g, delta: dt * dlen, t });
                    taken += 1;
                    t += dt;
                }
                Some(_) if affine || (p[0].abs().max(p[1].abs()).max(p[2].abs()) <= 1.0) => {
                    // Jump to the cell's exit, staying on the ray's sample lattice.
                    let gd = grid_dir(space, ray);
                    let exit = self.cell_exit(&g, &gd);
                    let n = (exit / dt).ceil().max(1.0);
                    t += n * dt;
                }
                _ => t += dt,
            }
        }
        state.t = t;
    }

    /// Ray parameter distance to leave the current cell (grid-space direction `gd`).
    #[inline]
    fn cell_exit(&self, g: &Vec3, gd: &Vec3) -> f32 {
        let r = self.res as f32;
        let mut best = f32::INFINITY;
        for a in 0..3 {
            if gd[a] == 0.0 {
                continue;
            }
            let u = (g[a] + 1.0) * 0.5 * r;
            let k = u.floor();
            let bound = if gd[a] > 0.0 { k + 1.0 } else { k };
            let gb = bound / r * 2.0 - 1.0;
            let s = (gb - g[a]) / gd[a];
            if s < best {
                best = s;
            }
        }
        best.max(0.0)
    }
}

pub use snerf_geometry::unbounded_dt;

/// Grid-space direction of a ray (affine kinds; inside the unit cube for unbounded).
#[inline]
fn grid_dir(space: &SceneSpace, ray: &Ray) -> Vec3 {
    match space.kind {
        SceneKind::Object => ray.d,
        SceneKind::Forward => {
            let e = space.frame.ndc.map(|n| 1.0 / n.xy_extent).unwrap_or(1.0);
            [ray.d[0] * e, ray.d[1] * e, ray.d[2]]
        }
        SceneKind::Unbounded => [ray.d[0] * 0.5, ray.d[1] * 0.5, ray.d[2] * 0.5],
    }
}

/// Grid units travelled per unit of ray parameter.
#[inline]
pub(crate) fn grid_speed(space: &SceneSpace, ray: &Ray) -> f32 {
    crate::space::norm(grid_dir(space, ray)).max(1e-12)
}
