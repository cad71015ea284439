//! Motion for dynamic bakes: every cell at every time sample may show the reference sample
//! moved by an offset (`snerf_asset::motion`) instead of a block of its own. This is a video
//! codec's motion compensation, applied to voxel blocks: a body that moves as a whole (a
//! skinned figure walking) is stored once, and between samples playback moves it by the
//! interpolated offset instead of blending two blocks (which draws a limb twice, half-faded).
//!
//! The search is block matching: for each cell and sample, the offset whose moved reference
//! block differs least from the field's block there (the codebook's visibility-weighted error,
//! `temporal::CellSamples`). Samples are solved outward from the reference, each cell trying
//! the offsets its neighbourhood had one sample closer to the reference (motion is continuous
//! in time, and a part entering a cell came from a neighbour), then a local search in whole
//! voxels and a refinement in quarter voxels. What motion cannot explain (appearance,
//! shape change) is left to the codebook, which weighs each stored block against it.

use rayon::prelude::*;
use snerf_asset::motion::MOTION_MAX;

use crate::temporal::{voxel_error, CellSamples};

/// The reference sample's codes on the whole fine grid (8 channels a voxel; empty voxels
/// code 0: the lowest density, zero colour), for reading moved blocks.
pub struct RefVolume {
    res: usize,
    codes: Vec<u8>,
}

impl RefVolume {
    /// Scatter the blocks the reference frame keeps (interior voxels) into a dense volume.
    pub fn new(cells: &[usize], samples: &[CellSamples], reference: usize, res: usize, b: usize) -> RefVolume {
        let g = res / b;
        let bb = b + 2;
        let mut codes = vec![0u8; res * res * res * 8];
        for (i, &c) in cells.iter().enumerate() {
            let Some(j) = samples[i].frames.iter().position(|&f| f == reference) else { continue };
            let blk = &samples[i].blocks[j];
            let (cx, cy, cz) = (c % g, (c / g) % g, c / (g * g));
            for z in 0..b {
                for y in 0..b {
                    let src = (((z + 1) * bb + y + 1) * bb + 1) * 8;
                    let dst = (((cz * b + z) * res + cy * b + y) * res + cx * b) * 8;
                    codes[dst..dst + b * 8].copy_from_slice(&blk[src..src + b * 8]);
                }
            }
        }
        RefVolume { res, codes }
    }

    /// Codes at integer voxel `p` (zero outside the grid).
    #[inline]
    fn at(&self, p: [i32; 3]) -> &[u8] {
        const ZERO: [u8; 8] = [0; 8];
        let r = self.res as i32;
        if p.iter().any(|&x| x < 0 || x >= r) {
            return &ZERO;
        }
        let i = ((p[2] as usize * self.res + p[1] as usize) * self.res + p[0] as usize) * 8;
        &self.codes[i..i + 8]
    }

    /// The codes of the apron-inclusive block of `cell` read at an offset of `d` voxels
    /// (trilinear on the codes, as every renderer interpolates them).
    pub fn moved_block(&self, cell: usize, b: usize, d: [f32; 3]) -> Vec<u8> {
        let m = Move::new(self.res / b, cell, b, d);
        let bb = b + 2;
        let mut out = vec![0u8; bb * bb * bb * 8];
        for z in 0..bb {
            for y in 0..bb {
                for x in 0..bb {
                    let o = ((z * bb + y) * bb + x) * 8;
                    out[o..o + 8].copy_from_slice(&m.read(self, [x, y, z]));
                }
            }
        }
        out
    }
}

/// One cell's block read from the reference at an offset: the whole-voxel part and the
/// trilinear weights of the rest.
struct Move {
    /// Global voxel of the block's first (apron) voxel, offset included.
    origin: [i32; 3],
    w: [f32; 3],
    whole: bool,
}

impl Move {
    fn new(g: usize, cell: usize, b: usize, d: [f32; 3]) -> Move {
        let c = [cell % g, (cell / g) % g, cell / (g * g)];
        let fl = d.map(f32::floor);
        let w = [d[0] - fl[0], d[1] - fl[1], d[2] - fl[2]];
        Move {
            origin: std::array::from_fn(|a| (c[a] * b) as i32 - 1 + fl[a] as i32),
            w,
            whole: w.iter().all(|&x| x == 0.0),
        }
    }

    /// The codes the moved block holds at block-local voxel `v` (apron-inclusive).
    #[inline]
    fn read(&self, vol: &RefVolume, v: [usize; 3]) -> [u8; 8] {
        let p: [i32; 3] = std::array::from_fn(|a| self.origin[a] + v[a] as i32);
        let mut out = [0u8; 8];
        if self.whole {
            out.copy_from_slice(vol.at(p));
            return out;
        }
        let mut acc = [0.0f32; 8];
        for corner in 0..8 {
            let s = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let mut wt = 1.0;
            for a in 0..3 {
                wt *= if s[a] == 1 { self.w[a] } else { 1.0 - self.w[a] };
            }
            if wt == 0.0 {
                continue;
            }
            let v = vol.at([p[0] + s[0] as i32, p[1] + s[1] as i32, p[2] + s[2] as i32]);
            for ch in 0..8 {
                acc[ch] += wt * v[ch] as f32;
            }
        }
        for ch in 0..8 {
            out[ch] = acc[ch].round().clamp(0.0, 255.0) as u8;
        }
        out
    }
}

impl RefVolume {
    /// `moved_error(alpha, moved_block(cell, b, d), Some((target, vis)))` without building
    /// the block, reading only voxels someone sees, and giving up (returning a value above
    /// `bound`) once the sum passes `bound`: the search's inner loop.
    pub fn error_at(&self, cell: usize, b: usize, d: [f32; 3], alpha: &[f32; 256], target: &[u8], vis: &[u8], bound: f32) -> f32 {
        let m = Move::new(self.res / b, cell, b, d);
        let bb = b + 2;
        let limit = bound * 255.0;
        let mut e = 0.0f32;
        for z in 0..bb {
            for y in 0..bb {
                for x in 0..bb {
                    let i = (z * bb + y) * bb + x;
                    if vis[i] == 0 {
                        continue;
                    }
                    e += voxel_error(alpha, &m.read(self, [x, y, z]), &target[i * 8..i * 8 + 8], vis[i]);
                }
            }
            if e > limit {
                return e / 255.0;
            }
        }
        e / 255.0
    }
}

/// Error of showing `moved` where the field holds `target` (visibility `vis`, per voxel):
/// `CellSamples::error`'s measure with the target's visibility. `target` None: the field is
/// transparent there (every voxel counted as seen).
pub fn moved_error(alpha: &[f32; 256], moved: &[u8], target: Option<(&[u8], &[u8])>) -> f32 {
    let mut e = 0.0f32;
    for (i, pm) in moved.chunks_exact(8).enumerate() {
        let (w, pt): (u8, &[u8]) = match target {
            Some((t, v)) => (v[i], &t[i * 8..i * 8 + 8]),
            None => (255, &[0; 8]),
        };
        if w == 0 {
            continue;
        }
        e += voxel_error(alpha, pm, pt, w);
    }
    e / 255.0
}

/// Offsets (voxels) and their errors, per candidate cell and per entry of its
/// `CellSamples::frames`: the best motion found for the cell at that sample. The reference
/// sample's own entry is (0, 0).
pub struct Motion {
    pub offset: Vec<Vec<[f32; 3]>>,
    pub error: Vec<Vec<f32>>,
}

/// Search every cell's motion at every sample it holds a block at (module doc).
pub fn search(cells: &[usize], samples: &[CellSamples], vol: &RefVolume, reference: usize, frames: usize, b: usize) -> Motion {
    let g = vol.res / b;
    let index: std::collections::HashMap<usize, usize> = cells.iter().enumerate().map(|(i, &c)| (c, i)).collect();
    // best offset per (candidate cell, frame), None where the cell holds no block
    let mut best: Vec<Vec<Option<([f32; 3], f32)>>> = vec![vec![None; frames]; cells.len()];
    for i in 0..cells.len() {
        if samples[i].frames.contains(&reference) {
            best[i][reference] = Some(([0.0; 3], 0.0));
        }
    }
    let order: Vec<(usize, usize)> =
        (reference + 1..frames).map(|k| (k, k - 1)).chain((0..reference).rev().map(|k| (k, k + 1))).collect();
    for (k, prev) in order {
        let solved: Vec<Option<([f32; 3], f32)>> = (0..cells.len())
            .into_par_iter()
            .map(|i| {
                let s = &samples[i];
                let j = s.frames.iter().position(|&f| f == k)?;
                let target = (&s.blocks[j][..], &s.vis[j][..]);
                let c = cells[i];
                let cc = [c % g, (c / g) % g, c / (g * g)];
                // predictors: no motion, and the neighbourhood's offsets one sample closer
                let mut cand: Vec<[f32; 3]> = vec![[0.0; 3]];
                for dz in -1i32..=1 {
                    for dy in -1i32..=1 {
                        for dx in -1i32..=1 {
                            let n = [cc[0] as i32 + dx, cc[1] as i32 + dy, cc[2] as i32 + dz];
                            if n.iter().any(|&x| x < 0 || x >= g as i32) {
                                continue;
                            }
                            let nc = (n[2] as usize * g + n[1] as usize) * g + n[0] as usize;
                            if let Some(&ni) = index.get(&nc) {
                                if let Some((d, _)) = best[ni][prev] {
                                    if !cand.contains(&d) {
                                        cand.push(d);
                                    }
                                }
                            }
                        }
                    }
                }
                let err = |d: [f32; 3], bound: f32| vol.error_at(c, b, d, &s.alpha, target.0, target.1, bound);
                let mut scored: Vec<([f32; 3], f32)> = cand.into_iter().map(|d| (d, err(d, f32::INFINITY))).collect();
                scored.sort_by(|a, b| a.1.total_cmp(&b.1));
                let mut top = scored[0];
                // whole-voxel search around the two best predictors, then quarter voxels
                for &(start, _) in scored.iter().take(2) {
                    let start = start.map(f32::round);
                    for dz in -2..=2 {
                        for dy in -2..=2 {
                            for dx in -2..=2 {
                                let d = [start[0] + dx as f32, start[1] + dy as f32, start[2] + dz as f32];
                                if d.iter().any(|x| x.abs() > MOTION_MAX) {
                                    continue;
                                }
                                let e = err(d, top.1);
                                if e < top.1 {
                                    top = (d, e);
                                }
                            }
                        }
                    }
                }
                for step in [0.5f32, 0.25] {
                    let centre = top.0;
                    for dz in -1..=1 {
                        for dy in -1..=1 {
                            for dx in -1..=1 {
                                let d = [centre[0] + dx as f32 * step, centre[1] + dy as f32 * step, centre[2] + dz as f32 * step];
                                if d.iter().any(|x| x.abs() > MOTION_MAX) {
                                    continue;
                                }
                                let e = err(d, top.1);
                                if e < top.1 {
                                    top = (d, e);
                                }
                            }
                        }
                    }
                }
                Some(top)
            })
            .collect();
        for (i, r) in solved.into_iter().enumerate() {
            best[i][k] = r;
        }
    }
    let offset = samples.iter().enumerate().map(|(i, s)| s.frames.iter().map(|&f| best[i][f].map_or([0.0; 3], |x| x.0)).collect()).collect();
    let error = samples.iter().enumerate().map(|(i, s)| s.frames.iter().map(|&f| best[i][f].map_or(f32::INFINITY, |x| x.1)).collect()).collect();
    Motion { offset, error }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4³-cell grid (block 4, res 16) holding a dense ball at `centre` (voxels), quantized
    /// like a bake: density code 255 inside, colour varying in space.
    fn ball(centre: [f32; 3], res: usize, b: usize) -> (Vec<usize>, Vec<CellSamples>) {
        let g = res / b;
        let bb = b + 2;
        let mut alpha = [0.0f32; 256];
        for (i, a) in alpha.iter_mut().enumerate() {
            *a = i as f32 / 255.0;
        }
        let mut cells = Vec::new();
        let mut samples = Vec::new();
        for c in 0..g * g * g {
            let cc = [c % g, (c / g) % g, c / (g * g)];
            let mut blk = vec![0u8; bb * bb * bb * 8];
            let mut any = false;
            for z in 0..bb {
                for y in 0..bb {
                    for x in 0..bb {
                        let p = [(cc[0] * b + x) as f32 - 0.5, (cc[1] * b + y) as f32 - 0.5, (cc[2] * b + z) as f32 - 0.5];
                        let r2: f32 = (0..3).map(|a| (p[a] - centre[a]).powi(2)).sum();
                        if r2 < 9.0 {
                            let o = ((z * bb + y) * bb + x) * 8;
                            blk[o] = 255;
                            blk[o + 1] = (40.0 + 20.0 * (p[0] - centre[0])) as u8;
                            blk[o + 2] = (120.0 + 25.0 * (p[1] - centre[1])) as u8;
                            blk[o + 3] = (90.0 + 15.0 * (p[2] - centre[2])) as u8;
                            any |= (1..=b).contains(&x) && (1..=b).contains(&y) && (1..=b).contains(&z);
                        }
                    }
                }
            }
            if any {
                cells.push(c);
                samples.push(CellSamples { frames: vec![0], blocks: vec![blk], vis: vec![vec![255; bb * bb * bb]], alpha });
            }
        }
        (cells, samples)
    }

    #[test]
    fn the_fused_error_equals_the_error_of_the_moved_block() {
        let (res, b) = (16, 4);
        let (cells, samples) = ball([8.0, 7.5, 8.2], res, b);
        let vol = RefVolume::new(&cells, &samples, 0, res, b);
        let (_, other) = ball([9.0, 6.5, 7.7], res, b);
        let s = &other[0];
        let c = cells[0];
        for d in [[0.0, 0.0, 0.0], [1.0, -1.0, 0.0], [0.25, 0.5, -0.75], [-2.5, 1.25, 3.0]] {
            let want = moved_error(&s.alpha, &vol.moved_block(c, b, d), Some((&s.blocks[0], &s.vis[0])));
            let got = vol.error_at(c, b, d, &s.alpha, &s.blocks[0], &s.vis[0], f32::INFINITY);
            assert!((got - want).abs() <= 1e-4 * (1.0 + want), "{d:?}: {got} vs {want}");
            // with a bound below the error it stops early, above the bound
            if want > 0.0 {
                assert!(vol.error_at(c, b, d, &s.alpha, &s.blocks[0], &s.vis[0], want * 0.5) > want * 0.5);
            }
        }
    }

    #[test]
    fn block_matching_recovers_a_known_translation() {
        // the ball at sample 0 (the reference) and moved by (1.5, -1, 0.75) voxels at sample 1:
        // a cell at sample 1 shows the reference at v + d with d the opposite move
        let (res, b) = (16, 4);
        let centre = [7.5f32, 8.0, 8.5];
        let mv = [1.5f32, -1.0, 0.75];
        let (c0, s0) = ball(centre, res, b);
        let (c1, s1) = ball([centre[0] + mv[0], centre[1] + mv[1], centre[2] + mv[2]], res, b);
        // merge into one list of cells with samples at frames 0 and 1
        let mut cells: Vec<usize> = c0.iter().chain(&c1).copied().collect();
        cells.sort();
        cells.dedup();
        let mut samples: Vec<CellSamples> = cells
            .iter()
            .map(|_| CellSamples { frames: vec![], blocks: vec![], vis: vec![], alpha: s0[0].alpha })
            .collect();
        for (f, (cs, ss)) in [(0usize, (&c0, &s0)), (1, (&c1, &s1))] {
            for (c, s) in cs.iter().zip(ss.iter()) {
                let i = cells.iter().position(|x| x == c).unwrap();
                samples[i].frames.push(f);
                samples[i].blocks.push(s.blocks[0].clone());
                samples[i].vis.push(s.vis[0].clone());
            }
        }
        let vol = RefVolume::new(&cells, &samples, 0, res, b);
        let m = search(&cells, &samples, &vol, 0, 2, b);
        let mut checked = 0;
        for (i, s) in samples.iter().enumerate() {
            if let Some(k) = s.frames.iter().position(|&f| f == 1) {
                let d = m.offset[i][k];
                for a in 0..3 {
                    assert!((d[a] + mv[a]).abs() <= 0.25, "cell {}: offset {d:?}, moved {mv:?}", cells[i]);
                }
                checked += 1;
            }
        }
        assert!(checked >= 4, "{checked} cells checked");
    }
}
