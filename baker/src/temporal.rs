//! Compact time for dynamic bakes: a per-cell codebook of blocks over the time samples.
//!
//! Every cell of a dynamic bake has one evaluated block per time sample. Most cells look the
//! same (as far as any camera can tell) at every sample, and the ones that move — a mouth, an
//! eyelid, a brow — go back and forth between a few states. So each cell stores a small set
//! of its sampled blocks, and every sample's indirection entry points at the stored block
//! closest to what the field holds there. The format is unchanged (a frame's cell may point
//! at any block); playback lerps between the blocks of the two samples around t, so it is
//! continuous in t, and every renderer that reads keyframes plays it.
//!
//! Which blocks to store: one per cell first (its medoid over time: the block with the least
//! total error against all samples), then, greedily over the whole scene, the addition that
//! removes the most error, until a size budget (a multiple of one static frame) is spent or
//! no addition removes more than the tolerance.
//!
//! Error between two blocks of a cell: over the apron-inclusive voxels,
//! Σ w·[(α_a − α_b)² + max(α_a, α_b)²·Σ_channels (c_a − c_b)²], with α the opacity over one
//! march step and w the voxel's visibility (the larger of the two samples'): how much light
//! from outside the grid reaches the voxel along the best of the 6 axis directions, from the
//! sample's own densities. Colour buried inside an opaque object is never seen, whatever the
//! field puts there, and must not cost storage.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use rayon::prelude::*;

/// Transmittance from outside the grid to every voxel (before its own density), the best of
/// the 6 axis directions. `s` is each voxel's optical depth over one step, index
/// `(z·res + y)·res + x`. Returns the optical depth in front of each voxel (min over
/// directions): visibility = exp(-result).
pub fn optical_depth_in_front(s: &[f32], res: usize) -> Vec<f32> {
    let plane = res * res;
    assert_eq!(s.len(), plane * res);
    let mut best = vec![f32::INFINITY; s.len()];
    // ±x: rows are contiguous
    best.par_chunks_mut(res).zip(s.par_chunks(res)).for_each(|(b, s)| {
        let mut cum = 0.0f32;
        for x in 0..res {
            b[x] = b[x].min(cum);
            cum += s[x];
        }
        cum = 0.0;
        for x in (0..res).rev() {
            b[x] = b[x].min(cum);
            cum += s[x];
        }
    });
    // ±y: within each z slab
    best.par_chunks_mut(plane).zip(s.par_chunks(plane)).for_each(|(b, s)| {
        let mut cum = vec![0.0f32; res];
        for y in 0..res {
            for x in 0..res {
                let i = y * res + x;
                b[i] = b[i].min(cum[x]);
                cum[x] += s[i];
            }
        }
        cum.fill(0.0);
        for y in (0..res).rev() {
            for x in 0..res {
                let i = y * res + x;
                b[i] = b[i].min(cum[x]);
                cum[x] += s[i];
            }
        }
    });
    // ±z: slab by slab, each (x, y) column carrying its own sum
    let mut cum = vec![0.0f32; plane];
    for dir in 0..2 {
        cum.fill(0.0);
        for k in 0..res {
            let z = if dir == 0 { k } else { res - 1 - k };
            let (b, sl) = (&mut best[z * plane..(z + 1) * plane], &s[z * plane..(z + 1) * plane]);
            b.par_iter_mut().zip(sl.par_iter()).zip(cum.par_iter_mut()).for_each(|((b, &s), c)| {
                *b = b.min(*c);
                *c += s;
            });
        }
    }
    best
}

/// One voxel's term of the error (module doc), times 255: codes `a` shown where the field
/// holds codes `b`, seen with visibility `w` (0..=255). Shared by the codebook and motion.
#[inline]
pub fn voxel_error(alpha: &[f32; 256], a: &[u8], b: &[u8], w: u8) -> f32 {
    let (aa, ab) = (alpha[a[0] as usize], alpha[b[0] as usize]);
    let m = aa.max(ab);
    let mut c2 = 0i32;
    for c in 1..8 {
        let d = a[c] as i32 - b[c] as i32;
        c2 += d * d;
    }
    w as f32 * ((aa - ab) * (aa - ab) + m * m * c2 as f32 * (1.0 / (255.0 * 255.0)))
}

/// One cell's samples: the quantized block (8 channels per voxel) and per-voxel visibility
/// (0..=255) of every time sample at which the cell holds a block.
pub struct CellSamples {
    /// Sample (frame) indices that hold a block, ascending.
    pub frames: Vec<usize>,
    pub blocks: Vec<Vec<u8>>,
    pub vis: Vec<Vec<u8>>,
    /// Opacity over one step of each density code at this cell.
    pub alpha: [f32; 256],
}

impl CellSamples {
    /// Error of showing block `a` where the field holds block `b` (see the module doc).
    pub fn error(&self, a: usize, b: usize) -> f32 {
        let (ba, bb) = (&self.blocks[a], &self.blocks[b]);
        let (va, vb) = (&self.vis[a], &self.vis[b]);
        let mut e = 0.0f32;
        for (i, (pa, pb)) in ba.chunks_exact(8).zip(bb.chunks_exact(8)).enumerate() {
            let w = va[i].max(vb[i]);
            if w == 0 {
                continue;
            }
            e += voxel_error(&self.alpha, pa, pb, w);
        }
        e / 255.0
    }

    /// Symmetric matrix of pairwise errors, row-major n×n.
    pub fn errors(&self) -> Vec<f32> {
        let n = self.frames.len();
        let mut m = vec![0.0f32; n * n];
        for a in 0..n {
            for b in a + 1..n {
                let e = self.error(a, b);
                m[a * n + b] = e;
                m[b * n + a] = e;
            }
        }
        m
    }
}

/// A cell's codebook: which of its samples are stored, and for every sample the stored one
/// that stands for it (both as indices into `CellSamples::frames`), or `MOTION`.
#[derive(Clone, Debug)]
pub struct Codebook {
    pub stored: Vec<usize>,
    pub assign: Vec<usize>,
    /// Remaining error (sum over samples).
    pub error: f32,
}

struct State {
    n: usize,
    m: Vec<f32>,
    stored: Vec<usize>,
    cur: Vec<f32>,
    cur_from: Vec<usize>,
}

impl State {
    fn new(m: Vec<f32>, n: usize) -> State {
        // medoid: least total error against every sample
        let medoid = (0..n)
            .min_by(|&a, &b| {
                let sa: f32 = m[a * n..(a + 1) * n].iter().sum();
                let sb: f32 = m[b * n..(b + 1) * n].iter().sum();
                sa.total_cmp(&sb)
            })
            .unwrap_or(0);
        if n == 0 {
            return State { n, m, stored: Vec::new(), cur: Vec::new(), cur_from: Vec::new() };
        }
        let cur = m[medoid * n..(medoid + 1) * n].to_vec();
        State { n, m, stored: vec![medoid], cur, cur_from: vec![medoid; n] }
    }
    /// With motion: the cell starts from its motion (error `motion[k]` at sample k, no
    /// block stored) plus the block `required` must store (the reference sample's).
    fn with_motion(m: Vec<f32>, n: usize, motion: &[f32], required: Option<usize>) -> State {
        let mut st = State { n, m, stored: Vec::new(), cur: motion.to_vec(), cur_from: vec![MOTION; n] };
        if let Some(j) = required {
            st.add(j);
            // the required block is the sample itself (motion by zero would read it anyway,
            // but the reference's own grid must hold blocks)
            st.cur[j] = 0.0;
            st.cur_from[j] = j;
        }
        st
    }
    /// The best addition and the error it removes.
    fn best(&self) -> Option<(usize, f32)> {
        (0..self.n)
            .filter(|j| !self.stored.contains(j))
            .map(|j| {
                let row = &self.m[j * self.n..(j + 1) * self.n];
                (j, self.cur.iter().zip(row).map(|(&c, &e)| (c - e).max(0.0)).sum::<f32>())
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }
    fn add(&mut self, j: usize) {
        self.stored.push(j);
        for k in 0..self.n {
            let e = self.m[j * self.n + k];
            if e < self.cur[k] {
                self.cur[k] = e;
                self.cur_from[k] = j;
            }
        }
    }
}

#[derive(PartialEq)]
struct Gain(f32, usize);
impl Eq for Gain {}
impl PartialOrd for Gain {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Gain {
    fn cmp(&self, o: &Self) -> Ordering {
        self.0.total_cmp(&o.0).then(o.1.cmp(&self.1))
    }
}

/// `Codebook::assign` of a sample shown by motion (`motion`) rather than a stored block.
pub const MOTION: usize = usize::MAX;

/// Choose every cell's codebook: one block per cell, then up to `extra` more blocks in all,
/// each the one that removes the most error, while it removes at least `min_gain`.
pub fn choose(cells: &[CellSamples], extra: usize, min_gain: f32) -> Vec<Codebook> {
    choose_with(cells, extra, min_gain, None)
}

/// `choose`, where each cell may also show a sample by motion: `motion` holds, per cell,
/// the motion error of each sample and the sample that must be stored (the reference's; at
/// most one). Cells start from motion instead of their medoid, and `extra` counts every
/// block beyond the required ones.
pub fn choose_with(cells: &[CellSamples], extra: usize, min_gain: f32, motion: Option<(&[Vec<f32>], &[Option<usize>])>) -> Vec<Codebook> {
    let mut states: Vec<State> = cells
        .par_iter()
        .enumerate()
        .map(|(i, c)| {
            let n = c.frames.len();
            let m = if n > 1 { c.errors() } else { vec![0.0; n * n] };
            match motion {
                Some((err, req)) => State::with_motion(m, n, &err[i], req[i]),
                None => State::new(m, n),
            }
        })
        .collect();
    let mut heap: BinaryHeap<Gain> = states
        .iter()
        .enumerate()
        .filter_map(|(i, s)| s.best().map(|(_, g)| Gain(g, i)))
        .collect();
    let mut added = 0;
    while added < extra {
        let Some(Gain(g, i)) = heap.pop() else { break };
        // (a NaN gain stops too)
        if g.is_nan() || g < min_gain || g <= 0.0 {
            break;
        }
        // the gain may be stale only if the cell changed since, which it did not (each cell
        // is in the heap once)
        let Some((j, _)) = states[i].best() else { continue };
        states[i].add(j);
        added += 1;
        if let Some((_, g)) = states[i].best() {
            heap.push(Gain(g, i));
        }
    }
    states
        .into_iter()
        .map(|s| Codebook { error: s.cur.iter().sum(), stored: s.stored, assign: s.cur_from })
        .collect()
}

/// Entries playback fetches two blocks for: (cell, sample) pairs where the cell points at
/// two different non-empty blocks in this sample and the next.
/// Two motion entries are one fetch (the offset is interpolated), so they do not count.
pub fn blended_entries(grids: &[Vec<u32>], empty: u32) -> usize {
    use snerf_asset::motion::is_motion;
    let two = |a: u32, b: u32| a != b && a != empty && b != empty && !(is_motion(a) && is_motion(b));
    grids.windows(2).map(|w| w[0].iter().zip(&w[1]).filter(|p| two(*p.0, *p.1)).count()).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn optical_depth_in_front_is_the_best_axis_prefix_sum() {
        let res = 5;
        let s: Vec<f32> = (0..res * res * res).map(|i| ((i * 37) % 11) as f32 * 0.1).collect();
        let d = optical_depth_in_front(&s, res);
        let at = |x: usize, y: usize, z: usize| s[(z * res + y) * res + x];
        for z in 0..res {
            for y in 0..res {
                for x in 0..res {
                    let sums = [
                        (0..x).map(|k| at(k, y, z)).sum::<f32>(),
                        (x + 1..res).map(|k| at(k, y, z)).sum(),
                        (0..y).map(|k| at(x, k, z)).sum(),
                        (y + 1..res).map(|k| at(x, k, z)).sum(),
                        (0..z).map(|k| at(x, y, k)).sum(),
                        (z + 1..res).map(|k| at(x, y, k)).sum(),
                    ];
                    let want = sums.iter().copied().fold(f32::INFINITY, f32::min);
                    let got = d[(z * res + y) * res + x];
                    assert!((got - want).abs() < 1e-5, "({x},{y},{z}): {got} vs {want}");
                }
            }
        }
    }

    /// A one-voxel "block" of density code `d` and colour `c`, fully visible.
    fn cell(states: &[(u8, u8)]) -> CellSamples {
        let mut alpha = [0.0f32; 256];
        for (i, a) in alpha.iter_mut().enumerate() {
            *a = i as f32 / 255.0;
        }
        CellSamples {
            frames: (0..states.len()).collect(),
            blocks: states.iter().map(|&(d, c)| vec![d, c, c, c, 0, 0, 0, 0]).collect(),
            vis: states.iter().map(|_| vec![255]).collect(),
            alpha,
        }
    }

    #[test]
    fn error_ignores_what_no_one_sees() {
        let mut c = cell(&[(255, 10), (255, 200)]);
        assert!(c.error(0, 1) > 0.1);
        c.vis = vec![vec![0], vec![0]];
        assert_eq!(c.error(0, 1), 0.0);
        // transparent voxels' colour does not matter either
        let c = cell(&[(0, 10), (0, 200)]);
        assert_eq!(c.error(0, 1), 0.0);
    }

    #[test]
    fn codebook_keeps_the_states_that_matter_within_budget() {
        // a cell that never changes, and one that toggles between two states (A A B A B A)
        let still = cell(&[(200, 50); 6]);
        let toggling = cell(&[(255, 0), (255, 0), (255, 250), (255, 0), (255, 250), (255, 0)]);
        // no budget: one block per cell, the toggling cell shows its majority state
        let b = choose(&[cell(&[(200, 50); 6]), cell(&[(255, 0), (255, 0), (255, 250), (255, 0), (255, 250), (255, 0)])], 0, 0.0);
        assert_eq!(b[0].stored.len(), 1);
        assert_eq!(b[1].stored.len(), 1);
        assert!(b[1].error > 0.0);
        assert_eq!(b[1].assign.iter().map(|&j| toggling.blocks[j][1]).collect::<Vec<_>>(), vec![0; 6]);
        // budget of several blocks: only the toggling cell takes one, and then is exact
        let b = choose(&[still, toggling], 5, 1e-6);
        assert_eq!(b[0].stored.len(), 1);
        assert_eq!(b[1].stored.len(), 2);
        assert_eq!(b[1].error, 0.0);
        let shown: Vec<u8> = b[1].assign.iter().map(|&j| [0u8, 0, 250, 0, 250, 0][j]).collect();
        assert_eq!(shown, vec![0, 0, 250, 0, 250, 0]);
    }

    #[test]
    fn blended_entries_count_cells_pointing_at_two_blocks_across_a_sample_boundary() {
        let e = u32::MAX;
        // cell 0 keeps its block, cell 1 changes (counted), cell 2 appears (one side empty:
        // one fetch), cell 3 changes twice over three samples (counted twice)
        let grids = [vec![1, 2, e, 5], vec![1, 3, 4, 6], vec![1, 3, 4, 5]];
        assert_eq!(blended_entries(&grids, e), 3);
        assert_eq!(blended_entries(&grids[..1], e), 0);
    }
}
