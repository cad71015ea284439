//! Free-space carving from a capture's sparse points. COLMAP keeps, for every sparse point,
//! the photos it was matched in; each such observation is a line of sight, so the segment
//! from that camera's centre to the point is empty. Cells of the occupancy grid that enough
//! of these segments cross are carved for good (`Occupancy::allowed`, the mask silhouette
//! carving uses), so training cannot park fog in front of the surfaces (a fresh capture's field
//! is fog that rays neither skip nor stop in) and rendering skips those cells.
//!
//! Sparse points are noisy and few, and a carved cell never comes back, so every rule errs
//! towards keeping a cell:
//! - a segment stops [`CarveRules::margin`] of the point's distance before it (COLMAP's
//!   depths stray by a few percent: on castel, against a depth sensor, the median
//!   observation is 3.8% off);
//! - a cell holding a point, or next to one (its 26 neighbours), is never carved;
//! - a cell is carved only when [`CarveRules::min_segments`] segments from at least
//!   [`CarveRules::min_cameras`] cameras cross it, so one bad match cannot cut a tunnel.
//!
//! A segment is walked along the same march-space ray the renderer would follow from that
//! camera (box, NDC or contraction, by scene kind), so the cells it marks are the cells
//! rays actually pass through; only what lies inside the grid is marked.

use rayon::prelude::*;
use serde::Serialize;
use snerf_data::{SceneKind, TrackedPoint};

use crate::occupancy::Occupancy;
use crate::space::{dot, norm, scale, sub, SceneSpace, Vec3};

/// How conservatively to carve (see the module notes).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CarveRules {
    /// Fraction of the camera-to-point distance left uncarved in front of the point.
    pub margin: f32,
    pub min_segments: u32,
    pub min_cameras: u32,
}

impl Default for CarveRules {
    fn default() -> CarveRules {
        CarveRules { margin: 0.1, min_segments: 3, min_cameras: 2 }
    }
}

/// What carving did, for the run's log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct CarveStats {
    pub points: usize,
    pub segments: usize,
    /// Cells holding a point or next to one (never carved).
    pub protected_cells: usize,
    /// Cells crossed by at least one segment.
    pub crossed_cells: usize,
    /// Cells newly carved (were allowed before).
    pub carved_cells: usize,
    /// Fraction of all cells still allowed afterwards.
    pub allowed_fraction: f32,
}

/// Carve the cells that the segments from `cameras[i]` (world centres) to the points seen by
/// camera `i` cross, by `rules`. Only ever clears `occ.allowed`.
pub fn carve(occ: &mut Occupancy, space: &SceneSpace, cameras: &[Vec3], points: &[TrackedPoint], rules: CarveRules) -> CarveStats {
    let res = occ.res;
    let n = res * res * res;
    let mut protected = vec![false; n];
    for p in points {
        let Some(c) = space.world_to_march(p.xyz).and_then(|m| occ.cell(&space.to_grid(m))) else { continue };
        let (x, y, z) = ((c / (res * res)) as i64, ((c / res) % res) as i64, (c % res) as i64);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let (a, b, e) = (x + dx, y + dy, z + dz);
                    let r = res as i64;
                    if (0..r).contains(&a) && (0..r).contains(&b) && (0..r).contains(&e) {
                        protected[((a * r + b) * r + e) as usize] = true;
                    }
                }
            }
        }
    }
    let segments: Vec<(u32, usize)> = points.iter().enumerate().flat_map(|(pi, p)| p.seen_by.iter().map(move |&v| (v, pi))).filter(|(v, _)| (*v as usize) < cameras.len()).collect();
    // Per-cell segment count and a 64-bit camera set (camera index mod 64: distinct cameras
    // may share a bit, which only undercounts them).
    let occ_ref = &*occ;
    // one chunk of segments a thread, so at most that many pairs of full-grid counters exist
    let per_thread = segments.len().div_ceil(rayon::current_num_threads()).max(1);
    let (count, cams) = segments
        .par_chunks(per_thread)
        .fold(
            || (vec![0u32; n], vec![0u64; n]),
            |(mut count, mut cams), chunk| {
                for &(v, pi) in chunk {
                    walk_segment(occ_ref, space, cameras[v as usize], points[pi].xyz, rules.margin, |c| {
                        count[c] = count[c].saturating_add(1);
                        cams[c] |= 1u64 << (v % 64);
                    });
                }
                (count, cams)
            },
        )
        .reduce(
            || (vec![0u32; n], vec![0u64; n]),
            |(mut c1, mut m1), (c2, m2)| {
                for i in 0..n {
                    c1[i] = c1[i].saturating_add(c2[i]);
                    m1[i] |= m2[i];
                }
                (c1, m1)
            },
        );
    let mut stats = CarveStats { points: points.len(), segments: segments.len(), ..CarveStats::default() };
    for i in 0..n {
        if protected[i] {
            stats.protected_cells += 1;
        }
        if count[i] > 0 {
            stats.crossed_cells += 1;
        }
        if !protected[i] && count[i] >= rules.min_segments && cams[i].count_ones() >= rules.min_cameras && occ.allowed[i] {
            occ.allowed[i] = false;
            stats.carved_cells += 1;
        }
    }
    occ.refresh_bits();
    stats.allowed_fraction = occ.allowed.iter().filter(|&&a| a).count() as f32 / n.max(1) as f32;
    stats
}

/// Call `mark` once for each grid cell the march-space ray from `cam` towards `point` passes
/// through before it is within `margin` of the point's distance (world units).
pub fn walk_segment(occ: &Occupancy, space: &SceneSpace, cam: Vec3, point: Vec3, margin: f32, mut mark: impl FnMut(usize)) {
    let along = sub(point, cam);
    let dist = norm(along);
    // (a NaN distance fails the finite test too)
    if !dist.is_finite() || dist <= 0.0 {
        return;
    }
    let dir = scale(along, 1.0 / dist);
    let Some(ray) = space.world_ray(cam, dir, None) else { return };
    let stop = dist * (1.0 - margin);
    // Half the marcher's step: much finer than a cell, so no crossed cell is skipped.
    let affine = space.kind != SceneKind::Unbounded;
    let gspeed = if affine { crate::occupancy::grid_speed(space, &ray) } else { 1.0 };
    let mut t = ray.t0;
    let mut last = usize::MAX;
    let mut guard = 0usize;
    while t < ray.t1 && guard < 1 << 20 {
        guard += 1;
        let p = [ray.o[0] + t * ray.d[0], ray.o[1] + t * ray.d[1], ray.o[2] + t * ray.d[2]];
        // Distance travelled from the camera, in world units (undoes NDC for forward scenes).
        let w = space.march_point_to_world(p);
        let s = dot(sub(w, cam), dir);
        if s >= stop {
            break;
        }
        // A forward scene's march starts on the near plane, which can lie behind a camera
        // that stands in front of it: that part of the ray is not on the segment.
        if s < 0.0 {
            let dt = if affine { occ.step / gspeed } else { crate::occupancy::unbounded_dt(occ.step, p) };
            t += 0.5 * dt;
            continue;
        }
        if let Some(c) = occ.cell(&space.to_grid(p)) {
            if c != last {
                mark(c);
                last = c;
            }
        }
        let dt = if affine { occ.step / gspeed } else { crate::occupancy::unbounded_dt(occ.step, p) };
        t += 0.5 * dt;
    }
}
