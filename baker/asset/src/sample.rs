//! Point queries: grid point -> (cell, block-local coordinate) -> trilinear voxel values,
//! and blending between keyframes for dynamic assets. The renderer uses the split pieces
//! (`locate`, `TimeSlot`) so it can tell "empty" from "outside" and skip cheaply.

use crate::asset::{Asset, EMPTY};
use crate::quantize::CHANNELS;

/// Where a grid point falls: its cell and its continuous coordinate inside that cell's
/// stored (apron-padded) block, in voxel units with voxel centres at integers.
#[derive(Clone, Copy, Debug)]
pub struct Loc {
    pub cell: usize,
    pub local: [f32; 3],
}

/// What a keyframe shows in a cell (`Asset::source`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Source {
    Empty,
    Block(u32),
    /// The reference keyframe moved by this many voxels.
    Motion([f32; 3]),
}

/// Which keyframes a time falls between, and how far: value = (1-w)*k0 + w*k1.
pub use snerf_geometry::TimeSlot;

impl Asset {
    /// Cell and block-local coordinate of grid point `g`; None outside [-1,1]^3 (or NaN).
    #[inline]
    pub fn locate(&self, g: [f32; 3]) -> Option<Loc> {
        let res = self.header.res as usize;
        let b = self.header.block as usize;
        let gd = self.grid_dim();
        let mut cell = [0usize; 3];
        let mut local = [0.0f32; 3];
        for a in 0..3 {
            if !(g[a] >= -1.0 && g[a] <= 1.0) {
                return None;
            }
            // v: voxel-space position, voxel i spans [i, i+1) with its centre at i + 0.5.
            let v = (g[a] + 1.0) * 0.5 * res as f32;
            let vi = (v as usize).min(res - 1);
            let c = (vi / b).min(gd - 1);
            cell[a] = c;
            // Stored block starts at global voxel c*b - 1 (the apron); centre-aligned coords.
            local[a] = v - 0.5 - (c * b) as f32 + 1.0;
        }
        Some(Loc { cell: (cell[2] * gd + cell[1]) * gd + cell[0], local })
    }

    /// Atlas block of `cell` in `frame`; None if empty, not arrived, or out of range.
    #[inline]
    pub fn block_at(&self, frame: usize, cell: usize) -> Option<u32> {
        let e = *self.grids.get(frame)?.get(cell)?;
        if e == EMPTY || !*self.present.get(e as usize)? {
            return None;
        }
        Some(e)
    }

    /// Trilinear interpolation inside one stored block. Interpolates the 8-bit codes and
    /// decodes once: decoding is affine, so this equals interpolating decoded values.
    #[inline]
    pub fn interpolate(&self, block: u32, local: [f32; 3]) -> [f32; CHANNELS] {
        let b = self.header.block as usize;
        let e = b + 2;
        let bb = self.block_bytes();
        let Some(data) = self.atlas.get(block as usize * bb..(block as usize + 1) * bb) else {
            return self.empty_values();
        };
        let mut i0 = [0usize; 3];
        let mut w = [0.0f32; 3];
        for a in 0..3 {
            let f = local[a].floor().clamp(0.0, b as f32);
            i0[a] = f as usize;
            w[a] = (local[a] - f).clamp(0.0, 1.0);
        }
        let mut acc = [0.0f32; CHANNELS];
        for corner in 0..8 {
            let (dx, dy, dz) = (corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
            let wt = (if dx == 1 { w[0] } else { 1.0 - w[0] })
                * (if dy == 1 { w[1] } else { 1.0 - w[1] })
                * (if dz == 1 { w[2] } else { 1.0 - w[2] });
            let off = (((i0[2] + dz) * e + (i0[1] + dy)) * e + (i0[0] + dx)) * CHANNELS;
            let v = &data[off..off + CHANNELS];
            for c in 0..CHANNELS {
                acc[c] += wt * v[c] as f32;
            }
        }
        let d = self.header.density;
        let mut out = [0.0f32; CHANNELS];
        out[0] = d.logit_min + acc[0] / 255.0 * (d.logit_max - d.logit_min);
        for c in 1..CHANNELS {
            out[c] = acc[c] / 255.0;
        }
        out
    }

    /// What an empty cell counts as when blending keyframes: lowest density, zero colour.
    pub fn empty_values(&self) -> [f32; CHANNELS] {
        let mut v = [0.0f32; CHANNELS];
        v[0] = self.header.density.logit_min;
        v
    }

    /// (logit, r, g, b, f0..f3) at grid point `g` of `frame`; None outside the grid or in an
    /// empty / not-yet-arrived cell.
    pub fn sample(&self, frame: usize, g: [f32; 3]) -> Option<[f32; CHANNELS]> {
        let loc = self.locate(g)?;
        let b = self.block_at(frame, loc.cell)?;
        Some(self.interpolate(b, loc.local))
    }

    /// The keyframes around time `t` (clamped at both ends; static assets: frame 0).
    pub fn time_slot(&self, t: f32) -> TimeSlot {
        snerf_geometry::time_slot(self.header.frames.as_deref().unwrap_or(&[]), |k| k.time, t)
    }

    /// What frame `frame` shows in `cell`: nothing, a block of its own, or the reference
    /// keyframe moved (`motion`). A block not yet arrived counts as nothing.
    #[inline]
    pub fn source(&self, frame: usize, cell: usize) -> Source {
        let Some(&e) = self.grids.get(frame).and_then(|g| g.get(cell)) else { return Source::Empty };
        if let Some(d) = crate::motion::motion_offset(e) {
            if self.header.motion_ref.is_some() {
                return Source::Motion(d);
            }
            return Source::Empty;
        }
        match self.block_at(frame, cell) {
            Some(b) => Source::Block(b),
            None => Source::Empty,
        }
    }

    /// The reference keyframe's values at the voxel-space position of `loc` moved by `d`
    /// voxels (empty values outside the grid or in an empty cell of the reference).
    pub fn sample_moved(&self, loc: &Loc, d: [f32; 3]) -> [f32; CHANNELS] {
        let Some(r) = self.header.motion_ref else { return self.empty_values() };
        let b = self.header.block as usize;
        let gd = self.grid_dim();
        let cell = [loc.cell % gd, (loc.cell / gd) % gd, loc.cell / (gd * gd)];
        // back to the grid point: local = v - 0.5 - c·b + 1 (see `locate`)
        let res = self.header.res as f32;
        let g: [f32; 3] = std::array::from_fn(|a| {
            let v = loc.local[a] + 0.5 + (cell[a] * b) as f32 - 1.0 + d[a];
            v / res * 2.0 - 1.0
        });
        match self.locate(g) {
            Some(l) => match self.block_at(r as usize, l.cell) {
                Some(blk) => self.interpolate(blk, l.local),
                None => self.empty_values(),
            },
            None => self.empty_values(),
        }
    }

    /// Does a motion entry of `cell` with offset `d` read any block of the reference? (The
    /// cell moved by `d` overlaps at most 8 reference cells.)
    pub fn motion_reads_a_block(&self, cell: usize, d: [f32; 3]) -> bool {
        let Some(r) = self.header.motion_ref else { return false };
        let b = self.header.block as i64;
        let gd = self.grid_dim() as i64;
        let c = [cell as i64 % gd, (cell as i64 / gd) % gd, cell as i64 / (gd * gd)];
        // the cell's points have voxel positions in [c·b, (c+1)·b); moved, each is read from
        // the reference cell holding it (trilinear through that block's apron)
        let lo: [i64; 3] = std::array::from_fn(|a| ((c[a] * b) as f32 + d[a]).floor() as i64).map(|v| v.div_euclid(b));
        let hi: [i64; 3] = std::array::from_fn(|a| (((c[a] + 1) * b) as f32 + d[a]).ceil() as i64 - 1).map(|v| v.div_euclid(b));
        for z in lo[2].max(0)..=hi[2].min(gd - 1) {
            for y in lo[1].max(0)..=hi[1].min(gd - 1) {
                for x in lo[0].max(0)..=hi[0].min(gd - 1) {
                    if self.block_at(r as usize, ((z * gd + y) * gd + x) as usize).is_some() {
                        return true;
                    }
                }
            }
        }
        false
    }

    #[inline]
    fn source_values(&self, s: Source, loc: &Loc) -> [f32; CHANNELS] {
        match s {
            Source::Empty => self.empty_values(),
            Source::Block(b) => self.interpolate(b, loc.local),
            Source::Motion(d) => self.sample_moved(loc, d),
        }
    }

    /// Values at a located point for a time slot; None when every side involved is empty.
    #[inline]
    pub fn sample_slot(&self, slot: &TimeSlot, loc: &Loc) -> Option<[f32; CHANNELS]> {
        let a = self.source(slot.k0, loc.cell);
        if slot.w == 0.0 || slot.k0 == slot.k1 {
            return (a != Source::Empty).then(|| self.source_values(a, loc));
        }
        let b = self.source(slot.k1, loc.cell);
        let w = slot.w;
        match (a, b) {
            (Source::Empty, Source::Empty) => return None,
            // Same block on both sides (shared, unchanged): no blend needed.
            (Source::Block(x), Source::Block(y)) if x == y => return Some(self.interpolate(x, loc.local)),
            // Both sides move the reference: move it by the interpolated offset, read once.
            (Source::Motion(da), Source::Motion(db)) => {
                // equal entries read as one side (no lerp rounding), like the shader
                let d = if da == db { da } else { std::array::from_fn(|i| (1.0 - w) * da[i] + w * db[i]) };
                return Some(self.sample_moved(loc, d));
            }
            _ => {}
        }
        let va = self.source_values(a, loc);
        let vb = self.source_values(b, loc);
        Some(self.blend(va, vb, w))
    }

    /// Two keyframes' values at one point, `w` of the way from `va` to `vb`. The density's
    /// logit always blends linearly. The colour and features blend by the same `w`, or, where
    /// the header says `colour_by_density`, by each side's share of the density
    /// ((1 − w)·σa against w·σb, σ = exp(logit)): `blend_weight`.
    #[inline]
    pub fn blend(&self, va: [f32; CHANNELS], vb: [f32; CHANNELS], w: f32) -> [f32; CHANNELS] {
        let wc = if self.header.colour_by_density { blend_weight(va[0], vb[0], w) } else { w };
        let mut out = [0.0f32; CHANNELS];
        out[0] = (1.0 - w) * va[0] + w * vb[0];
        for c in 1..CHANNELS {
            out[c] = (1.0 - wc) * va[c] + wc * vb[c];
        }
        out
    }

    /// Like `sample`, at time `t` for dynamic assets: lerp of the two keyframes around t.
    pub fn sample_at_time(&self, t: f32, g: [f32; 3]) -> Option<[f32; CHANNELS]> {
        let loc = self.locate(g)?;
        self.sample_slot(&self.time_slot(t), &loc)
    }

    /// Is `cell` empty at this time slot (no block on any side that contributes)?
    #[inline]
    pub fn cell_empty(&self, slot: &TimeSlot, cell: usize) -> bool {
        self.source(slot.k0, cell) == Source::Empty
            && (slot.w == 0.0 || slot.k0 == slot.k1 || self.source(slot.k1, cell) == Source::Empty)
    }
}

/// The colour weight of side b when the two sides weigh (1 − w)·exp(la) and w·exp(lb):
/// the logistic of lb − la + ln w − ln(1 − w), its logarithms and argument bounded so that
/// nothing overflows or divides by zero on any GPU (w = 0 gives under 1e-20, w = 1 gives 1,
/// equal logits give w). shaders/march.wgsl `blend_weight` is the same.
#[inline]
pub fn blend_weight(la: f32, lb: f32, w: f32) -> f32 {
    const TINY: f32 = 1.0e-30;
    let x = (lb - la + w.max(TINY).ln() - (1.0 - w).max(TINY).ln()).clamp(-80.0, 80.0);
    1.0 / (1.0 + (-x).exp())
}
