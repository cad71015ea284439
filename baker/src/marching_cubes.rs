//! Marching cubes over a scalar field sampled on a regular lattice.
//!
//! The field is given as a closure `density(i, j, k)` over lattice points
//! `origin + spacing * (i, j, k)` for `i < dims[0]`, `j < dims[1]`, `k < dims[2]`, so callers
//! never need a dense copy of their (possibly 512³) lattice. A point is *inside* when
//! `density > iso`; the surface separates inside from outside points and its triangles wind
//! counter-clockwise when seen from outside (front faces point toward lower density).
//!
//! * Vertices sit on lattice edges and are shared by every cell (and every parallel brick)
//!   touching that edge, so the mesh is closed wherever the inside region does not touch the
//!   lattice boundary (pad the field with an outside layer to close it everywhere).
//! * Normals are the normalized negative density gradient (central differences on the lattice,
//!   one-sided at its border) interpolated along the edge; where the gradient vanishes they fall
//!   back to the edge direction from its inside to its outside end.
//! * Colours come from `color(position)`, evaluated once per (deduplicated) vertex.
//! * Work is split into bricks processed in parallel with rayon; the output order depends only
//!   on the inputs, never on the thread count.
//!
//! Tables: corners and edges use Paul Bourke's classic numbering (corner 0 at (0,0,0), 1 at
//! (1,0,0), 2 at (1,1,0), 3 at (0,1,0), 4..7 the same at z = 1; edges 0..3 around z = 0, 4..7
//! around z = 1, 8..11 the vertical ones), and `EDGE_TABLE` equals Bourke's edge table. The
//! triangle table is *generated* (the generator is in this file's tests, which check the tables
//! below against it): on each cube face the iso-line segments are fixed by the face's corner
//! signs alone (on an ambiguous face the two inside corners are cut off separately), the
//! segments are chained into closed loops, and each loop is triangulated with the least total
//! diagonal length among triangulations that never join two vertices lying on one cube face.
//! Because a face's segments depend only on that face, the two cells sharing a face always
//! agree: the surface has no cracks (including the ambiguous cases where the classic 15-case
//! table can leave holes) and every edge is shared by exactly two triangles. At most 5
//! triangles per cell, as in the classic table.

use rayon::prelude::*;
use std::collections::HashMap;

/// A triangle mesh with per-vertex attributes; `indices` holds 3 vertex indices per triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    pub positions: Vec<[f32; 3]>,
    /// Unit length, pointing toward lower density (out of the surface).
    pub normals: Vec<[f32; 3]>,
    /// Whatever `color(position)` returned (the glTF exporter treats it as linear RGB in [0, 1]).
    pub colors: Vec<[f32; 3]>,
    pub indices: Vec<u32>,
}

impl Mesh {
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
    pub fn is_empty(&self) -> bool {
        self.indices.is_empty()
    }
}

/// Marching cubes over the whole lattice (`dims` lattice points per axis).
///
/// Every lattice point is evaluated about once (neighbouring z-slabs both evaluate the plane
/// they share, and gradient look-ups just outside a slab call `density` again). For sparse fields prefer
/// [`extract_blocks`], which evaluates only the listed blocks.
pub fn extract(
    dims: [usize; 3],
    origin: [f32; 3],
    spacing: f32,
    density: impl Fn(usize, usize, usize) -> f32 + Sync,
    color: impl Fn([f32; 3]) -> [f32; 3] + Sync,
    iso: f32,
) -> Mesh {
    if dims.iter().any(|&d| d < 2) {
        return Mesh::default();
    }
    let cells = [dims[0] - 1, dims[1] - 1, dims[2] - 1];
    // z-slabs: enough of them to balance the pool, few enough that the shared planes (read
    // by two slabs) stay a small overhead, and bounded in memory (~8M points per slab).
    let threads = rayon::current_num_threads().max(1);
    let plane = dims[0] * dims[1];
    let mem_cap = (8usize << 20) / plane.max(1);
    let layers = (cells[2] / (threads * 4))
        .clamp(4, 32)
        .min(mem_cap.max(1))
        .max(1);
    let bricks: Vec<Brick> = (0..cells[2])
        .step_by(layers)
        .map(|z0| Brick {
            lo: [0, 0, z0],
            hi: [cells[0], cells[1], (z0 + layers).min(cells[2])],
        })
        .collect();
    run(dims, origin, spacing, &density, &color, iso, &bricks)
}

/// Marching cubes restricted to coarse blocks of `block`³ cells.
///
/// `blocks` lists block coordinates `(bx, by, bz)`; block `b` covers cells
/// `b * block .. (b + 1) * block` (clipped to the lattice), i.e. lattice points
/// `b * block ..= (b + 1) * block`. Only listed blocks are evaluated and meshed, so the caller
/// must list every block whose `(block + 1)³` corner points include an inside point (for a
/// sparse grid: its occupied blocks, with a one-block margin if occupancy is per point rather
/// than per cell). Duplicates and out-of-range blocks are ignored; the output is the same
/// whatever the order of `blocks`. Vertices on faces shared by two blocks are merged, so the
/// result matches [`extract`] up to vertex order.
#[allow(clippy::too_many_arguments)]
pub fn extract_blocks(
    dims: [usize; 3],
    origin: [f32; 3],
    spacing: f32,
    block: usize,
    blocks: &[[usize; 3]],
    density: impl Fn(usize, usize, usize) -> f32 + Sync,
    color: impl Fn([f32; 3]) -> [f32; 3] + Sync,
    iso: f32,
) -> Mesh {
    assert!(block > 0, "block size must be positive");
    if dims.iter().any(|&d| d < 2) {
        return Mesh::default();
    }
    let cells = [dims[0] - 1, dims[1] - 1, dims[2] - 1];
    let mut list: Vec<[usize; 3]> = blocks
        .iter()
        .copied()
        .filter(|b| (0..3).all(|a| b[a].saturating_mul(block) < cells[a]))
        .collect();
    list.sort_unstable_by_key(|b| (b[2], b[1], b[0]));
    list.dedup();
    let bricks: Vec<Brick> = list
        .iter()
        .map(|b| {
            let lo = [b[0] * block, b[1] * block, b[2] * block];
            Brick {
                lo,
                hi: [
                    (lo[0] + block).min(cells[0]),
                    (lo[1] + block).min(cells[1]),
                    (lo[2] + block).min(cells[2]),
                ],
            }
        })
        .collect();
    run(dims, origin, spacing, &density, &color, iso, &bricks)
}

/// Cells `lo..hi` per axis (lattice points `lo..=hi`).
#[derive(Clone, Copy, Debug)]
struct Brick {
    lo: [usize; 3],
    hi: [usize; 3],
}

#[derive(Default)]
struct BrickOut {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    /// Global edge key, or `u64::MAX` for vertices inside the brick (not shared with others).
    shared_keys: Vec<u64>,
    indices: Vec<u32>,
}

/// Lattice offset of the edge's first point and its axis, per Bourke edge number.
const EDGE_LOC: [([usize; 3], usize); 12] = [
    ([0, 0, 0], 0),
    ([1, 0, 0], 1),
    ([0, 1, 0], 0),
    ([0, 0, 0], 1),
    ([0, 0, 1], 0),
    ([1, 0, 1], 1),
    ([0, 1, 1], 0),
    ([0, 0, 1], 1),
    ([0, 0, 0], 2),
    ([1, 0, 0], 2),
    ([1, 1, 0], 2),
    ([0, 1, 0], 2),
];
/// Corner offsets, Bourke numbering.
const CORNER: [[usize; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [1, 1, 1],
    [0, 1, 1],
];

/// Cube configuration from the inside flags of its two lattice columns: index `a | c << 4`,
/// `a` at x = i and `c` at x = i + 1, each with bit `dy + 2 dz` for the point at (dy, dz).
const CFG_OF_COLUMNS: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut v = 0;
    while v < 256 {
        let mut corner = 0;
        while corner < 8 {
            let [dx, dy, dz] = CORNER[corner];
            if (v >> (4 * dx + dy + 2 * dz)) & 1 == 1 {
                t[v] |= 1 << corner;
            }
            corner += 1;
        }
        v += 1;
    }
    t
};

#[allow(clippy::too_many_arguments)]
fn run<D, C>(
    dims: [usize; 3],
    origin: [f32; 3],
    spacing: f32,
    density: &D,
    color: &C,
    iso: f32,
    bricks: &[Brick],
) -> Mesh
where
    D: Fn(usize, usize, usize) -> f32 + Sync,
    C: Fn([f32; 3]) -> [f32; 3] + Sync,
{
    let outs: Vec<BrickOut> = bricks
        .par_iter()
        .map(|b| process_brick(dims, origin, spacing, density, iso, *b))
        .collect();
    let total_v: usize = outs.iter().map(|o| o.positions.len()).sum();
    let total_i: usize = outs.iter().map(|o| o.indices.len()).sum();
    let mut mesh = Mesh {
        positions: Vec::with_capacity(total_v),
        normals: Vec::with_capacity(total_v),
        colors: Vec::new(),
        indices: Vec::with_capacity(total_i),
    };
    let mut shared: HashMap<u64, u32> = HashMap::new();
    let mut remap: Vec<u32> = Vec::new();
    for out in &outs {
        remap.clear();
        for (v, &key) in out.shared_keys.iter().enumerate() {
            let next = mesh.positions.len() as u32;
            let id = if key == u64::MAX {
                next
            } else {
                *shared.entry(key).or_insert(next)
            };
            if id == next {
                mesh.positions.push(out.positions[v]);
                mesh.normals.push(out.normals[v]);
            }
            remap.push(id);
        }
        mesh.indices
            .extend(out.indices.iter().map(|&i| remap[i as usize]));
    }
    drop(outs);
    mesh.colors = mesh.positions.par_iter().map(|&p| color(p)).collect();
    mesh
}

fn process_brick<D>(
    dims: [usize; 3],
    origin: [f32; 3],
    spacing: f32,
    density: &D,
    iso: f32,
    b: Brick,
) -> BrickOut
where
    D: Fn(usize, usize, usize) -> f32 + Sync,
{
    let n = [
        b.hi[0] - b.lo[0] + 1,
        b.hi[1] - b.lo[1] + 1,
        b.hi[2] - b.lo[2] + 1,
    ];
    let mut dens = vec![0.0f32; n[0] * n[1] * n[2]];
    let mut inside = vec![0u8; dens.len()];
    // Inside points per x row, to skip rows of cells that are all inside or all outside.
    let mut row_inside = vec![0usize; n[1] * n[2]];
    let rows = dens
        .chunks_exact_mut(n[0])
        .zip(inside.chunks_exact_mut(n[0]))
        .zip(row_inside.iter_mut());
    for (r, ((drow, irow), count)) in rows.enumerate() {
        let (j, k) = (b.lo[1] + r % n[1], b.lo[2] + r / n[1]);
        let mut c = 0;
        for (i, (d, f)) in drow.iter_mut().zip(irow.iter_mut()).enumerate() {
            *d = density(b.lo[0] + i, j, k);
            *f = (*d > iso) as u8;
            c += *f as usize;
        }
        *count = c;
    }
    let mut out = BrickOut::default();
    let total: usize = row_inside.iter().sum();
    if total == 0 || total == dens.len() {
        return out;
    }
    let idx = |i: usize, j: usize, k: usize| (k * n[1] + j) * n[0] + i;
    // Density at a global lattice point, from the brick buffer when possible.
    let at = |p: [usize; 3]| -> f32 {
        if (0..3).all(|a| p[a] >= b.lo[a] && p[a] <= b.hi[a]) {
            dens[idx(p[0] - b.lo[0], p[1] - b.lo[1], p[2] - b.lo[2])]
        } else {
            density(p[0], p[1], p[2])
        }
    };
    // Density gradient per lattice step (central differences, one-sided at the lattice border).
    let grad = |p: [usize; 3]| -> [f32; 3] {
        let mut g = [0.0f32; 3];
        for a in 0..3 {
            let (mut lo, mut hi) = (p, p);
            if p[a] > 0 {
                lo[a] -= 1;
            }
            if p[a] + 1 < dims[a] {
                hi[a] += 1;
            }
            let span = (hi[a] - lo[a]) as f32;
            if span > 0.0 {
                g[a] = (at(hi) - at(lo)) / span;
            }
        }
        g
    };
    let plane = n[0] * n[1];
    // Vertex ids of x/y edges on the planes below and above the current cell layer, and of the
    // z edges between them.
    let mut xy_lo = vec![0u32; plane * 2];
    let mut xy_hi = vec![0u32; plane * 2];
    let mut z_mid = vec![0u32; plane];
    // Slots hold vertex id + 1 and are never cleared: ids grow, so an entry is current when it
    // was made during this cell layer (z edges, top plane) or the one before (bottom plane,
    // whose x/y edges the previous layer created as its top plane).
    let mut start_cur = 0u32;
    let stride = [1u64, dims[0] as u64, (dims[0] * dims[1]) as u64];
    for ck in 0..n[2] - 1 {
        let start_prev = std::mem::replace(&mut start_cur, out.positions.len() as u32);
        for cj in 0..n[1] - 1 {
            let rows = [(cj, ck), (cj + 1, ck), (cj, ck + 1), (cj + 1, ck + 1)]
                .map(|(j, k)| row_inside[k * n[1] + j]);
            if rows.iter().all(|&c| c == 0) || rows.iter().all(|&c| c == n[0]) {
                continue;
            }
            // The 4 inside flags of lattice column i: bit 0 (j, k), 1 (j+1, k), 2 (j, k+1),
            // 3 (j+1, k+1); a cell's configuration is two neighbouring columns.
            let rows = [
                idx(0, cj, ck),
                idx(0, cj + 1, ck),
                idx(0, cj, ck + 1),
                idx(0, cj + 1, ck + 1),
            ]
            .map(|s| &inside[s..s + n[0]]);
            let column =
                |i: usize| rows[0][i] | rows[1][i] << 1 | rows[2][i] << 2 | rows[3][i] << 3;
            let mut next = column(0);
            for ci in 0..n[0] - 1 {
                let (a, c) = (next, column(ci + 1));
                next = c;
                if a == c && (a == 0 || a == 15) {
                    continue;
                }
                let row = &TRI_TABLE[CFG_OF_COLUMNS[(a | c << 4) as usize] as usize];
                let mut t = 0;
                while row[t] != X {
                    let e = row[t] as usize;
                    let (o, axis) = EDGE_LOC[e];
                    let (li, lj, lk) = (ci + o[0], cj + o[1], ck + o[2]);
                    let (slot, since) = match (axis, o[2]) {
                        (2, _) => (&mut z_mid[lj * n[0] + li], start_cur),
                        (_, 0) => (&mut xy_lo[(lj * n[0] + li) * 2 + axis], start_prev),
                        _ => (&mut xy_hi[(lj * n[0] + li) * 2 + axis], start_cur),
                    };
                    if *slot <= since {
                        *slot = out.positions.len() as u32 + 1;
                        let p0 = [b.lo[0] + li, b.lo[1] + lj, b.lo[2] + lk];
                        let mut p1 = p0;
                        p1[axis] += 1;
                        let (d0, d1) = (dens[idx(li, lj, lk)], at(p1));
                        let mut s = (iso - d0) / (d1 - d0);
                        s = if s.is_finite() {
                            s.clamp(0.0, 1.0)
                        } else {
                            0.5
                        };
                        let mut pos = [0.0f32; 3];
                        for a in 0..3 {
                            let f = p0[a] as f32 + if a == axis { s } else { 0.0 };
                            pos[a] = origin[a] + spacing * f;
                        }
                        let (g0, g1) = (grad(p0), grad(p1));
                        let mut nrm = [0.0f32; 3];
                        for a in 0..3 {
                            nrm[a] = -(g0[a] + (g1[a] - g0[a]) * s);
                        }
                        let nrm = normalize(nrm)
                            .or_else(|| normalize([-g0[0], -g0[1], -g0[2]]))
                            .or_else(|| normalize([-g1[0], -g1[1], -g1[2]]))
                            .unwrap_or_else(|| {
                                // Edge direction from its inside end to its outside end.
                                let mut v = [0.0; 3];
                                v[axis] = if d0 > iso { 1.0 } else { -1.0 };
                                v
                            });
                        out.positions.push(pos);
                        out.normals.push(nrm);
                        // Shared with another brick when the edge lies on a brick face.
                        let on_face =
                            (0..3).any(|a| a != axis && (p0[a] == b.lo[a] || p0[a] == b.hi[a]));
                        out.shared_keys.push(if on_face {
                            (p0[0] as u64 * stride[0]
                                + p0[1] as u64 * stride[1]
                                + p0[2] as u64 * stride[2])
                                * 3
                                + axis as u64
                        } else {
                            u64::MAX
                        });
                    }
                    out.indices.push(*slot - 1);
                    t += 1;
                }
            }
        }
        std::mem::swap(&mut xy_lo, &mut xy_hi);
    }
    out
}

fn normalize(v: [f32; 3]) -> Option<[f32; 3]> {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if l.is_finite() && l > 1e-20 {
        Some([v[0] / l, v[1] / l, v[2] / l])
    } else {
        None
    }
}

/// Terminator in [`TRI_TABLE`] rows.
const X: u8 = u8::MAX;

/// Edges cut by the surface, bit `e` for Bourke edge `e`, indexed by the cube configuration
/// (bit `c` set when corner `c` is inside). Identical to Bourke's `edgeTable`.
#[cfg_attr(not(test), allow(dead_code))]
pub(crate) const EDGE_TABLE: [u16; 256] = [
    0x000, 0x109, 0x203, 0x30a, 0x406, 0x50f, 0x605, 0x70c, 0x80c, 0x905, 0xa0f, 0xb06, 0xc0a,
    0xd03, 0xe09, 0xf00, 0x190, 0x099, 0x393, 0x29a, 0x596, 0x49f, 0x795, 0x69c, 0x99c, 0x895,
    0xb9f, 0xa96, 0xd9a, 0xc93, 0xf99, 0xe90, 0x230, 0x339, 0x033, 0x13a, 0x636, 0x73f, 0x435,
    0x53c, 0xa3c, 0xb35, 0x83f, 0x936, 0xe3a, 0xf33, 0xc39, 0xd30, 0x3a0, 0x2a9, 0x1a3, 0x0aa,
    0x7a6, 0x6af, 0x5a5, 0x4ac, 0xbac, 0xaa5, 0x9af, 0x8a6, 0xfaa, 0xea3, 0xda9, 0xca0, 0x460,
    0x569, 0x663, 0x76a, 0x066, 0x16f, 0x265, 0x36c, 0xc6c, 0xd65, 0xe6f, 0xf66, 0x86a, 0x963,
    0xa69, 0xb60, 0x5f0, 0x4f9, 0x7f3, 0x6fa, 0x1f6, 0x0ff, 0x3f5, 0x2fc, 0xdfc, 0xcf5, 0xfff,
    0xef6, 0x9fa, 0x8f3, 0xbf9, 0xaf0, 0x650, 0x759, 0x453, 0x55a, 0x256, 0x35f, 0x055, 0x15c,
    0xe5c, 0xf55, 0xc5f, 0xd56, 0xa5a, 0xb53, 0x859, 0x950, 0x7c0, 0x6c9, 0x5c3, 0x4ca, 0x3c6,
    0x2cf, 0x1c5, 0x0cc, 0xfcc, 0xec5, 0xdcf, 0xcc6, 0xbca, 0xac3, 0x9c9, 0x8c0, 0x8c0, 0x9c9,
    0xac3, 0xbca, 0xcc6, 0xdcf, 0xec5, 0xfcc, 0x0cc, 0x1c5, 0x2cf, 0x3c6, 0x4ca, 0x5c3, 0x6c9,
    0x7c0, 0x950, 0x859, 0xb53, 0xa5a, 0xd56, 0xc5f, 0xf55, 0xe5c, 0x15c, 0x055, 0x35f, 0x256,
    0x55a, 0x453, 0x759, 0x650, 0xaf0, 0xbf9, 0x8f3, 0x9fa, 0xef6, 0xfff, 0xcf5, 0xdfc, 0x2fc,
    0x3f5, 0x0ff, 0x1f6, 0x6fa, 0x7f3, 0x4f9, 0x5f0, 0xb60, 0xa69, 0x963, 0x86a, 0xf66, 0xe6f,
    0xd65, 0xc6c, 0x36c, 0x265, 0x16f, 0x066, 0x76a, 0x663, 0x569, 0x460, 0xca0, 0xda9, 0xea3,
    0xfaa, 0x8a6, 0x9af, 0xaa5, 0xbac, 0x4ac, 0x5a5, 0x6af, 0x7a6, 0x0aa, 0x1a3, 0x2a9, 0x3a0,
    0xd30, 0xc39, 0xf33, 0xe3a, 0x936, 0x83f, 0xb35, 0xa3c, 0x53c, 0x435, 0x73f, 0x636, 0x13a,
    0x033, 0x339, 0x230, 0xe90, 0xf99, 0xc93, 0xd9a, 0xa96, 0xb9f, 0x895, 0x99c, 0x69c, 0x795,
    0x49f, 0x596, 0x29a, 0x393, 0x099, 0x190, 0xf00, 0xe09, 0xd03, 0xc0a, 0xb06, 0xa0f, 0x905,
    0x80c, 0x70c, 0x605, 0x50f, 0x406, 0x30a, 0x203, 0x109, 0x000,
];

/// Triangles per configuration: up to 5 triples of Bourke edge numbers, terminated by `X`;
/// counter-clockwise seen from outside (toward lower density).
const TRI_TABLE: [[u8; 16]; 256] = [
    [X, X, X, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 8, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [0, 9, 1, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [1, 3, 9, 3, 8, 9, X, X, X, X, X, X, X, X, X, X],
    [1, 10, 2, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 8, 1, 10, 2, X, X, X, X, X, X, X, X, X, X],
    [0, 9, 2, 9, 10, 2, X, X, X, X, X, X, X, X, X, X],
    [2, 3, 10, 3, 9, 10, 3, 8, 9, X, X, X, X, X, X, X],
    [2, 11, 3, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [0, 2, 8, 2, 11, 8, X, X, X, X, X, X, X, X, X, X],
    [0, 9, 1, 2, 11, 3, X, X, X, X, X, X, X, X, X, X],
    [1, 2, 9, 2, 8, 9, 2, 11, 8, X, X, X, X, X, X, X],
    [1, 10, 3, 10, 11, 3, X, X, X, X, X, X, X, X, X, X],
    [0, 1, 8, 1, 11, 8, 1, 10, 11, X, X, X, X, X, X, X],
    [0, 9, 3, 9, 10, 3, 10, 11, 3, X, X, X, X, X, X, X],
    [8, 9, 11, 9, 10, 11, X, X, X, X, X, X, X, X, X, X],
    [4, 8, 7, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 4, 3, 7, 4, X, X, X, X, X, X, X, X, X, X],
    [0, 9, 1, 4, 8, 7, X, X, X, X, X, X, X, X, X, X],
    [1, 3, 9, 3, 7, 9, 7, 4, 9, X, X, X, X, X, X, X],
    [1, 10, 2, 4, 8, 7, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 4, 3, 7, 4, 1, 10, 2, X, X, X, X, X, X, X],
    [0, 9, 2, 9, 10, 2, 4, 8, 7, X, X, X, X, X, X, X],
    [2, 3, 10, 3, 7, 10, 7, 4, 10, 4, 9, 10, X, X, X, X],
    [2, 11, 3, 4, 8, 7, X, X, X, X, X, X, X, X, X, X],
    [0, 11, 4, 0, 2, 11, 11, 7, 4, X, X, X, X, X, X, X],
    [0, 9, 1, 2, 11, 3, 4, 8, 7, X, X, X, X, X, X, X],
    [1, 2, 9, 2, 7, 9, 2, 11, 7, 7, 4, 9, X, X, X, X],
    [1, 10, 3, 10, 11, 3, 4, 8, 7, X, X, X, X, X, X, X],
    [0, 1, 4, 1, 10, 4, 10, 11, 4, 11, 7, 4, X, X, X, X],
    [0, 9, 3, 9, 10, 3, 10, 11, 3, 4, 8, 7, X, X, X, X],
    [4, 9, 7, 9, 10, 7, 10, 11, 7, X, X, X, X, X, X, X],
    [4, 5, 9, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 8, 4, 5, 9, X, X, X, X, X, X, X, X, X, X],
    [0, 4, 1, 4, 5, 1, X, X, X, X, X, X, X, X, X, X],
    [1, 8, 5, 1, 3, 8, 8, 4, 5, X, X, X, X, X, X, X],
    [1, 10, 2, 4, 5, 9, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 8, 1, 10, 2, 4, 5, 9, X, X, X, X, X, X, X],
    [0, 5, 2, 0, 4, 5, 5, 10, 2, X, X, X, X, X, X, X],
    [2, 3, 10, 3, 4, 10, 3, 8, 4, 4, 5, 10, X, X, X, X],
    [2, 11, 3, 4, 5, 9, X, X, X, X, X, X, X, X, X, X],
    [0, 2, 8, 2, 11, 8, 4, 5, 9, X, X, X, X, X, X, X],
    [0, 4, 1, 4, 5, 1, 2, 11, 3, X, X, X, X, X, X, X],
    [1, 2, 5, 2, 11, 5, 11, 8, 5, 8, 4, 5, X, X, X, X],
    [1, 10, 3, 10, 11, 3, 4, 5, 9, X, X, X, X, X, X, X],
    [0, 1, 8, 1, 11, 8, 1, 10, 11, 4, 5, 9, X, X, X, X],
    [0, 4, 3, 4, 10, 3, 4, 5, 10, 10, 11, 3, X, X, X, X],
    [4, 5, 8, 5, 11, 8, 5, 10, 11, X, X, X, X, X, X, X],
    [5, 9, 7, 9, 8, 7, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 9, 3, 7, 9, 7, 5, 9, X, X, X, X, X, X, X],
    [0, 8, 1, 8, 5, 1, 8, 7, 5, X, X, X, X, X, X, X],
    [1, 3, 5, 3, 7, 5, X, X, X, X, X, X, X, X, X, X],
    [1, 10, 2, 5, 9, 7, 9, 8, 7, X, X, X, X, X, X, X],
    [0, 3, 9, 3, 7, 9, 7, 5, 9, 1, 10, 2, X, X, X, X],
    [0, 8, 2, 8, 7, 2, 7, 5, 2, 5, 10, 2, X, X, X, X],
    [2, 3, 10, 3, 7, 10, 7, 5, 10, X, X, X, X, X, X, X],
    [2, 11, 3, 5, 9, 7, 9, 8, 7, X, X, X, X, X, X, X],
    [0, 2, 9, 2, 7, 9, 2, 11, 7, 7, 5, 9, X, X, X, X],
    [0, 8, 1, 8, 5, 1, 8, 7, 5, 2, 11, 3, X, X, X, X],
    [1, 2, 5, 2, 11, 5, 11, 7, 5, X, X, X, X, X, X, X],
    [1, 10, 3, 10, 11, 3, 5, 9, 7, 9, 8, 7, X, X, X, X],
    [0, 7, 9, 0, 10, 7, 0, 1, 10, 10, 11, 7, 7, 5, 9, X],
    [0, 10, 3, 0, 7, 10, 0, 8, 7, 7, 5, 10, 10, 11, 3, X],
    [5, 10, 7, 10, 11, 7, X, X, X, X, X, X, X, X, X, X],
    [5, 6, 10, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 8, 5, 6, 10, X, X, X, X, X, X, X, X, X, X],
    [0, 9, 1, 5, 6, 10, X, X, X, X, X, X, X, X, X, X],
    [1, 3, 9, 3, 8, 9, 5, 6, 10, X, X, X, X, X, X, X],
    [1, 5, 2, 5, 6, 2, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 8, 1, 5, 2, 5, 6, 2, X, X, X, X, X, X, X],
    [0, 9, 2, 9, 5, 2, 5, 6, 2, X, X, X, X, X, X, X],
    [2, 3, 6, 3, 8, 6, 8, 9, 6, 9, 5, 6, X, X, X, X],
    [2, 11, 3, 5, 6, 10, X, X, X, X, X, X, X, X, X, X],
    [0, 2, 8, 2, 11, 8, 5, 6, 10, X, X, X, X, X, X, X],
    [0, 9, 1, 2, 11, 3, 5, 6, 10, X, X, X, X, X, X, X],
    [1, 2, 9, 2, 8, 9, 2, 11, 8, 5, 6, 10, X, X, X, X],
    [1, 6, 3, 1, 5, 6, 6, 11, 3, X, X, X, X, X, X, X],
    [0, 1, 8, 1, 5, 8, 5, 6, 8, 6, 11, 8, X, X, X, X],
    [0, 9, 3, 9, 6, 3, 9, 5, 6, 6, 11, 3, X, X, X, X],
    [5, 6, 9, 6, 8, 9, 6, 11, 8, X, X, X, X, X, X, X],
    [4, 8, 7, 5, 6, 10, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 4, 3, 7, 4, 5, 6, 10, X, X, X, X, X, X, X],
    [0, 9, 1, 4, 8, 7, 5, 6, 10, X, X, X, X, X, X, X],
    [1, 3, 9, 3, 7, 9, 7, 4, 9, 5, 6, 10, X, X, X, X],
    [1, 5, 2, 5, 6, 2, 4, 8, 7, X, X, X, X, X, X, X],
    [0, 3, 4, 3, 7, 4, 1, 5, 2, 5, 6, 2, X, X, X, X],
    [0, 9, 2, 9, 5, 2, 5, 6, 2, 4, 8, 7, X, X, X, X],
    [2, 3, 6, 3, 9, 6, 3, 7, 9, 7, 4, 9, 9, 5, 6, X],
    [2, 11, 3, 4, 8, 7, 5, 6, 10, X, X, X, X, X, X, X],
    [0, 11, 4, 0, 2, 11, 11, 7, 4, 5, 6, 10, X, X, X, X],
    [0, 9, 1, 2, 11, 3, 4, 8, 7, 5, 6, 10, X, X, X, X],
    [1, 2, 9, 2, 7, 9, 2, 11, 7, 7, 4, 9, 5, 6, 10, X],
    [1, 6, 3, 1, 5, 6, 6, 11, 3, 4, 8, 7, X, X, X, X],
    [0, 1, 4, 1, 11, 4, 1, 5, 11, 5, 6, 11, 11, 7, 4, X],
    [0, 9, 3, 9, 6, 3, 9, 5, 6, 6, 11, 3, 4, 8, 7, X],
    [4, 9, 7, 9, 11, 7, 9, 5, 11, 5, 6, 11, X, X, X, X],
    [4, 6, 9, 6, 10, 9, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 8, 4, 6, 9, 6, 10, 9, X, X, X, X, X, X, X],
    [0, 4, 1, 4, 6, 1, 6, 10, 1, X, X, X, X, X, X, X],
    [1, 3, 10, 3, 4, 10, 3, 8, 4, 4, 6, 10, X, X, X, X],
    [1, 9, 2, 9, 6, 2, 9, 4, 6, X, X, X, X, X, X, X],
    [0, 3, 8, 1, 9, 2, 9, 6, 2, 9, 4, 6, X, X, X, X],
    [0, 4, 2, 4, 6, 2, X, X, X, X, X, X, X, X, X, X],
    [2, 3, 6, 3, 8, 6, 8, 4, 6, X, X, X, X, X, X, X],
    [2, 11, 3, 4, 6, 9, 6, 10, 9, X, X, X, X, X, X, X],
    [0, 2, 8, 2, 11, 8, 4, 6, 9, 6, 10, 9, X, X, X, X],
    [0, 4, 1, 4, 6, 1, 6, 10, 1, 2, 11, 3, X, X, X, X],
    [1, 4, 10, 1, 11, 4, 1, 2, 11, 11, 8, 4, 4, 6, 10, X],
    [1, 9, 3, 9, 4, 3, 4, 6, 3, 6, 11, 3, X, X, X, X],
    [0, 1, 8, 1, 6, 8, 1, 9, 6, 9, 4, 6, 6, 11, 8, X],
    [0, 4, 3, 4, 6, 3, 6, 11, 3, X, X, X, X, X, X, X],
    [4, 6, 8, 6, 11, 8, X, X, X, X, X, X, X, X, X, X],
    [6, 10, 7, 10, 9, 7, 9, 8, 7, X, X, X, X, X, X, X],
    [0, 3, 9, 3, 7, 9, 7, 6, 9, 6, 10, 9, X, X, X, X],
    [0, 8, 1, 8, 6, 1, 8, 7, 6, 6, 10, 1, X, X, X, X],
    [1, 3, 10, 3, 7, 10, 7, 6, 10, X, X, X, X, X, X, X],
    [1, 9, 2, 9, 8, 2, 8, 7, 2, 7, 6, 2, X, X, X, X],
    [0, 3, 9, 3, 7, 9, 7, 6, 9, 6, 2, 9, 2, 1, 9, X],
    [0, 8, 2, 8, 7, 2, 7, 6, 2, X, X, X, X, X, X, X],
    [2, 3, 6, 3, 7, 6, X, X, X, X, X, X, X, X, X, X],
    [2, 11, 3, 6, 10, 7, 10, 9, 7, 9, 8, 7, X, X, X, X],
    [0, 2, 9, 2, 7, 9, 2, 11, 7, 7, 6, 9, 6, 10, 9, X],
    [0, 8, 1, 8, 6, 1, 8, 7, 6, 6, 10, 1, 2, 11, 3, X],
    [1, 7, 10, 1, 2, 7, 2, 11, 7, 7, 6, 10, X, X, X, X],
    [1, 9, 3, 9, 6, 3, 9, 8, 6, 8, 7, 6, 6, 11, 3, X],
    [0, 1, 9, 6, 11, 7, X, X, X, X, X, X, X, X, X, X],
    [0, 6, 3, 0, 8, 6, 8, 7, 6, 6, 11, 3, X, X, X, X],
    [6, 11, 7, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [6, 7, 11, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 8, 6, 7, 11, X, X, X, X, X, X, X, X, X, X],
    [0, 9, 1, 6, 7, 11, X, X, X, X, X, X, X, X, X, X],
    [1, 3, 9, 3, 8, 9, 6, 7, 11, X, X, X, X, X, X, X],
    [1, 10, 2, 6, 7, 11, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 8, 1, 10, 2, 6, 7, 11, X, X, X, X, X, X, X],
    [0, 9, 2, 9, 10, 2, 6, 7, 11, X, X, X, X, X, X, X],
    [2, 3, 10, 3, 9, 10, 3, 8, 9, 6, 7, 11, X, X, X, X],
    [2, 6, 3, 6, 7, 3, X, X, X, X, X, X, X, X, X, X],
    [0, 2, 8, 2, 6, 8, 6, 7, 8, X, X, X, X, X, X, X],
    [0, 9, 1, 2, 6, 3, 6, 7, 3, X, X, X, X, X, X, X],
    [1, 2, 9, 2, 6, 9, 6, 7, 9, 7, 8, 9, X, X, X, X],
    [1, 10, 3, 10, 6, 3, 6, 7, 3, X, X, X, X, X, X, X],
    [0, 1, 8, 1, 6, 8, 1, 10, 6, 6, 7, 8, X, X, X, X],
    [0, 9, 3, 9, 10, 3, 10, 6, 3, 6, 7, 3, X, X, X, X],
    [6, 7, 10, 7, 9, 10, 7, 8, 9, X, X, X, X, X, X, X],
    [4, 8, 6, 8, 11, 6, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 4, 3, 11, 4, 11, 6, 4, X, X, X, X, X, X, X],
    [0, 9, 1, 4, 8, 6, 8, 11, 6, X, X, X, X, X, X, X],
    [1, 3, 9, 3, 6, 9, 3, 11, 6, 6, 4, 9, X, X, X, X],
    [1, 10, 2, 4, 8, 6, 8, 11, 6, X, X, X, X, X, X, X],
    [0, 3, 4, 3, 11, 4, 11, 6, 4, 1, 10, 2, X, X, X, X],
    [0, 9, 2, 9, 10, 2, 4, 8, 6, 8, 11, 6, X, X, X, X],
    [2, 3, 10, 3, 4, 10, 3, 11, 4, 11, 6, 4, 4, 9, 10, X],
    [2, 6, 3, 6, 4, 3, 4, 8, 3, X, X, X, X, X, X, X],
    [0, 2, 4, 2, 6, 4, X, X, X, X, X, X, X, X, X, X],
    [0, 9, 1, 2, 6, 3, 6, 4, 3, 4, 8, 3, X, X, X, X],
    [1, 2, 9, 2, 6, 9, 6, 4, 9, X, X, X, X, X, X, X],
    [1, 10, 3, 10, 6, 3, 6, 4, 3, 4, 8, 3, X, X, X, X],
    [0, 1, 4, 1, 10, 4, 10, 6, 4, X, X, X, X, X, X, X],
    [0, 9, 3, 9, 10, 3, 10, 6, 3, 6, 4, 3, 4, 8, 3, X],
    [4, 9, 6, 9, 10, 6, X, X, X, X, X, X, X, X, X, X],
    [4, 5, 9, 6, 7, 11, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 8, 4, 5, 9, 6, 7, 11, X, X, X, X, X, X, X],
    [0, 4, 1, 4, 5, 1, 6, 7, 11, X, X, X, X, X, X, X],
    [1, 8, 5, 1, 3, 8, 8, 4, 5, 6, 7, 11, X, X, X, X],
    [1, 10, 2, 4, 5, 9, 6, 7, 11, X, X, X, X, X, X, X],
    [0, 3, 8, 1, 10, 2, 4, 5, 9, 6, 7, 11, X, X, X, X],
    [0, 5, 2, 0, 4, 5, 5, 10, 2, 6, 7, 11, X, X, X, X],
    [2, 3, 10, 3, 4, 10, 3, 8, 4, 4, 5, 10, 6, 7, 11, X],
    [2, 6, 3, 6, 7, 3, 4, 5, 9, X, X, X, X, X, X, X],
    [0, 2, 8, 2, 6, 8, 6, 7, 8, 4, 5, 9, X, X, X, X],
    [0, 4, 1, 4, 5, 1, 2, 6, 3, 6, 7, 3, X, X, X, X],
    [1, 2, 5, 2, 8, 5, 2, 6, 8, 6, 7, 8, 8, 4, 5, X],
    [1, 10, 3, 10, 6, 3, 6, 7, 3, 4, 5, 9, X, X, X, X],
    [0, 1, 8, 1, 6, 8, 1, 10, 6, 6, 7, 8, 4, 5, 9, X],
    [0, 4, 3, 4, 10, 3, 4, 5, 10, 10, 6, 3, 6, 7, 3, X],
    [4, 5, 8, 5, 10, 8, 10, 6, 8, 6, 7, 8, X, X, X, X],
    [5, 9, 6, 9, 8, 6, 8, 11, 6, X, X, X, X, X, X, X],
    [0, 3, 9, 3, 6, 9, 3, 11, 6, 6, 5, 9, X, X, X, X],
    [0, 8, 1, 8, 11, 1, 11, 6, 1, 6, 5, 1, X, X, X, X],
    [1, 11, 5, 1, 3, 11, 11, 6, 5, X, X, X, X, X, X, X],
    [1, 10, 2, 5, 9, 6, 9, 8, 6, 8, 11, 6, X, X, X, X],
    [0, 3, 9, 3, 6, 9, 3, 11, 6, 6, 5, 9, 1, 10, 2, X],
    [0, 8, 2, 8, 5, 2, 8, 11, 5, 11, 6, 5, 5, 10, 2, X],
    [2, 3, 10, 3, 5, 10, 3, 11, 5, 11, 6, 5, X, X, X, X],
    [2, 6, 3, 6, 9, 3, 6, 5, 9, 9, 8, 3, X, X, X, X],
    [0, 2, 9, 2, 6, 9, 6, 5, 9, X, X, X, X, X, X, X],
    [0, 8, 1, 8, 6, 1, 8, 3, 6, 3, 2, 6, 6, 5, 1, X],
    [1, 2, 5, 2, 6, 5, X, X, X, X, X, X, X, X, X, X],
    [1, 10, 3, 10, 6, 3, 6, 9, 3, 6, 5, 9, 9, 8, 3, X],
    [0, 6, 9, 0, 1, 6, 1, 10, 6, 6, 5, 9, X, X, X, X],
    [0, 8, 3, 5, 10, 6, X, X, X, X, X, X, X, X, X, X],
    [5, 10, 6, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [5, 7, 10, 7, 11, 10, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 8, 5, 7, 10, 7, 11, 10, X, X, X, X, X, X, X],
    [0, 9, 1, 5, 7, 10, 7, 11, 10, X, X, X, X, X, X, X],
    [1, 3, 9, 3, 8, 9, 5, 7, 10, 7, 11, 10, X, X, X, X],
    [1, 5, 2, 5, 7, 2, 7, 11, 2, X, X, X, X, X, X, X],
    [0, 3, 8, 1, 5, 2, 5, 7, 2, 7, 11, 2, X, X, X, X],
    [0, 9, 2, 9, 5, 2, 5, 7, 2, 7, 11, 2, X, X, X, X],
    [2, 5, 11, 2, 8, 5, 2, 3, 8, 8, 9, 5, 5, 7, 11, X],
    [2, 10, 3, 10, 7, 3, 10, 5, 7, X, X, X, X, X, X, X],
    [0, 2, 8, 2, 5, 8, 2, 10, 5, 5, 7, 8, X, X, X, X],
    [0, 9, 1, 2, 10, 3, 10, 7, 3, 10, 5, 7, X, X, X, X],
    [1, 2, 9, 2, 7, 9, 2, 10, 7, 10, 5, 7, 7, 8, 9, X],
    [1, 5, 3, 5, 7, 3, X, X, X, X, X, X, X, X, X, X],
    [0, 1, 8, 1, 5, 8, 5, 7, 8, X, X, X, X, X, X, X],
    [0, 9, 3, 9, 7, 3, 9, 5, 7, X, X, X, X, X, X, X],
    [5, 7, 9, 7, 8, 9, X, X, X, X, X, X, X, X, X, X],
    [4, 8, 5, 8, 11, 5, 11, 10, 5, X, X, X, X, X, X, X],
    [0, 3, 4, 3, 11, 4, 11, 10, 4, 10, 5, 4, X, X, X, X],
    [0, 9, 1, 4, 8, 5, 8, 11, 5, 11, 10, 5, X, X, X, X],
    [1, 3, 9, 3, 4, 9, 3, 11, 4, 11, 10, 4, 10, 5, 4, X],
    [1, 5, 2, 5, 8, 2, 5, 4, 8, 8, 11, 2, X, X, X, X],
    [0, 3, 4, 3, 11, 4, 11, 1, 4, 11, 2, 1, 1, 5, 4, X],
    [0, 9, 2, 9, 5, 2, 5, 8, 2, 5, 4, 8, 8, 11, 2, X],
    [2, 3, 11, 4, 9, 5, X, X, X, X, X, X, X, X, X, X],
    [2, 10, 3, 10, 4, 3, 10, 5, 4, 4, 8, 3, X, X, X, X],
    [0, 10, 4, 0, 2, 10, 10, 5, 4, X, X, X, X, X, X, X],
    [0, 9, 1, 2, 10, 3, 10, 4, 3, 10, 5, 4, 4, 8, 3, X],
    [1, 2, 9, 2, 4, 9, 2, 10, 4, 10, 5, 4, X, X, X, X],
    [1, 4, 3, 1, 5, 4, 4, 8, 3, X, X, X, X, X, X, X],
    [0, 1, 4, 1, 5, 4, X, X, X, X, X, X, X, X, X, X],
    [0, 9, 3, 9, 5, 3, 5, 4, 3, 4, 8, 3, X, X, X, X],
    [4, 9, 5, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [4, 7, 9, 7, 10, 9, 7, 11, 10, X, X, X, X, X, X, X],
    [0, 3, 8, 4, 7, 9, 7, 10, 9, 7, 11, 10, X, X, X, X],
    [0, 4, 1, 4, 11, 1, 4, 7, 11, 11, 10, 1, X, X, X, X],
    [1, 3, 10, 3, 4, 10, 3, 8, 4, 4, 7, 10, 7, 11, 10, X],
    [1, 9, 2, 9, 7, 2, 9, 4, 7, 7, 11, 2, X, X, X, X],
    [0, 3, 8, 1, 9, 2, 9, 7, 2, 9, 4, 7, 7, 11, 2, X],
    [0, 7, 2, 0, 4, 7, 7, 11, 2, X, X, X, X, X, X, X],
    [2, 4, 11, 2, 3, 4, 3, 8, 4, 4, 7, 11, X, X, X, X],
    [2, 10, 3, 10, 9, 3, 9, 4, 3, 4, 7, 3, X, X, X, X],
    [0, 2, 8, 2, 7, 8, 2, 10, 7, 10, 9, 7, 9, 4, 7, X],
    [0, 4, 1, 4, 10, 1, 4, 7, 10, 7, 3, 10, 3, 2, 10, X],
    [1, 2, 10, 4, 7, 8, X, X, X, X, X, X, X, X, X, X],
    [1, 9, 3, 9, 4, 3, 4, 7, 3, X, X, X, X, X, X, X],
    [0, 1, 8, 1, 7, 8, 1, 9, 7, 9, 4, 7, X, X, X, X],
    [0, 4, 3, 4, 7, 3, X, X, X, X, X, X, X, X, X, X],
    [4, 7, 8, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [8, 11, 9, 11, 10, 9, X, X, X, X, X, X, X, X, X, X],
    [0, 3, 9, 3, 10, 9, 3, 11, 10, X, X, X, X, X, X, X],
    [0, 8, 1, 8, 11, 1, 11, 10, 1, X, X, X, X, X, X, X],
    [1, 3, 10, 3, 11, 10, X, X, X, X, X, X, X, X, X, X],
    [1, 9, 2, 9, 8, 2, 8, 11, 2, X, X, X, X, X, X, X],
    [0, 3, 9, 3, 11, 9, 11, 2, 9, 2, 1, 9, X, X, X, X],
    [0, 8, 2, 8, 11, 2, X, X, X, X, X, X, X, X, X, X],
    [2, 3, 11, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [2, 10, 3, 10, 9, 3, 9, 8, 3, X, X, X, X, X, X, X],
    [0, 2, 9, 2, 10, 9, X, X, X, X, X, X, X, X, X, X],
    [0, 8, 1, 8, 10, 1, 8, 3, 10, 3, 2, 10, X, X, X, X],
    [1, 2, 10, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [1, 9, 3, 9, 8, 3, X, X, X, X, X, X, X, X, X, X],
    [0, 1, 9, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [0, 8, 3, X, X, X, X, X, X, X, X, X, X, X, X, X],
    [X, X, X, X, X, X, X, X, X, X, X, X, X, X, X, X],
];

#[cfg(test)]
mod tests {
    use super::*;

    const EDGES: [[usize; 2]; 12] = [
        [0, 1],
        [1, 2],
        [2, 3],
        [3, 0],
        [4, 5],
        [5, 6],
        [6, 7],
        [7, 4],
        [0, 4],
        [1, 5],
        [2, 6],
        [3, 7],
    ];
    /// Cube faces as corner cycles, with outward normals.
    const FACES: [([usize; 4], [i32; 3]); 6] = [
        ([0, 1, 2, 3], [0, 0, -1]),
        ([4, 5, 6, 7], [0, 0, 1]),
        ([0, 1, 5, 4], [0, -1, 0]),
        ([3, 2, 6, 7], [0, 1, 0]),
        ([0, 3, 7, 4], [-1, 0, 0]),
        ([1, 2, 6, 5], [1, 0, 0]),
    ];
    fn sub(a: [i32; 3], b: [i32; 3]) -> [i32; 3] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }
    fn cross(a: [i32; 3], b: [i32; 3]) -> [i32; 3] {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }
    fn dot(a: [i32; 3], b: [i32; 3]) -> i32 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }
    /// Corner position, scaled by 4 so face centres and edge midpoints are integers.
    fn corner(c: usize) -> [i32; 3] {
        CORNER[c].map(|x| x as i32 * 4)
    }
    fn mid(e: usize) -> [i32; 3] {
        let [a, b] = EDGES[e];
        let (pa, pb) = (corner(a), corner(b));
        [
            (pa[0] + pb[0]) / 2,
            (pa[1] + pb[1]) / 2,
            (pa[2] + pb[2]) / 2,
        ]
    }
    fn edge_of(a: usize, b: usize) -> usize {
        EDGES
            .iter()
            .position(|e| (e[0] == a && e[1] == b) || (e[0] == b && e[1] == a))
            .unwrap()
    }

    /// The table generator: face segments -> oriented loops -> triangle fans.
    fn generate() -> ([u16; 256], [[u8; 16]; 256]) {
        let mut et = [0u16; 256];
        let mut tt = [[X; 16]; 256];
        for cfg in 0..256usize {
            let inside = |c: usize| cfg >> c & 1 == 1;
            for (e, [a, b]) in EDGES.iter().enumerate() {
                if inside(*a) != inside(*b) {
                    et[cfg] |= 1 << e;
                }
            }
            // next[a] = b: the surface boundary runs from edge a to edge b across some face.
            let mut next = [usize::MAX; 12];
            for (fc, n) in FACES.iter() {
                let fe: Vec<usize> = (0..4).map(|m| edge_of(fc[m], fc[(m + 1) % 4])).collect();
                let crossing: Vec<usize> = (0..4)
                    .filter(|&m| inside(fc[m]) != inside(fc[(m + 1) % 4]))
                    .collect();
                // (edge, edge, in-face direction toward the outside part of the face)
                let mut segs: Vec<(usize, usize, [i32; 3])> = vec![];
                if crossing.len() == 2 {
                    let (mut o, mut i, mut no, mut ni) = ([0; 3], [0; 3], 0, 0);
                    for &c in fc {
                        let p = corner(c);
                        let (acc, cnt) = if inside(c) {
                            (&mut i, &mut ni)
                        } else {
                            (&mut o, &mut no)
                        };
                        for k in 0..3 {
                            acc[k] += p[k];
                        }
                        *cnt += 1;
                    }
                    let m = [
                        o[0] * ni - i[0] * no,
                        o[1] * ni - i[1] * no,
                        o[2] * ni - i[2] * no,
                    ];
                    segs.push((fe[crossing[0]], fe[crossing[1]], m));
                } else if crossing.len() == 4 {
                    // Ambiguous face: cut off each inside corner on its own.
                    let mut center = [0; 3];
                    for &c in fc {
                        for (x, y) in center.iter_mut().zip(corner(c)) {
                            *x += y / 4;
                        }
                    }
                    for m in 0..4 {
                        if inside(fc[m]) {
                            segs.push((fe[(m + 3) % 4], fe[m], sub(center, corner(fc[m]))));
                        }
                    }
                }
                for (a, b, m) in segs {
                    // Boundary orientation induced by the outward surface normal: m x n_face.
                    let d = dot(sub(mid(b), mid(a)), cross(m, *n));
                    assert_ne!(d, 0);
                    let (a, b) = if d > 0 { (a, b) } else { (b, a) };
                    assert_eq!(next[a], usize::MAX);
                    next[a] = b;
                }
            }
            let (mut seen, mut w) = ([false; 12], 0);
            for s in 0..12 {
                if next[s] == usize::MAX || seen[s] {
                    continue;
                }
                let mut lp = vec![];
                let mut e = s;
                while !seen[e] {
                    seen[e] = true;
                    lp.push(e);
                    e = next[e];
                }
                assert_eq!(e, s, "open loop in configuration {cfg}");
                for v in triangulate(&lp).unwrap_or_else(|| {
                    panic!("configuration {cfg}: loop {lp:?} cannot be triangulated")
                }) {
                    tt[cfg][w] = v as u8;
                    w += 1;
                }
            }
            assert!(w <= 15);
        }
        (et, tt)
    }

    fn faces_of(e: usize) -> impl Iterator<Item = usize> {
        (0..6)
            .filter(move |&f| (0..4).any(|m| edge_of(FACES[f].0[m], FACES[f].0[(m + 1) % 4]) == e))
    }
    fn share_face(a: usize, b: usize) -> bool {
        faces_of(a).any(|f| faces_of(b).any(|g| g == f))
    }

    /// Triangulates a loop of edge vertices (keeping its orientation) with the least total
    /// diagonal length, never drawing a diagonal between two vertices on one cube face: the
    /// cell across that face could draw the same diagonal, and the edge would then be shared
    /// by four triangles.
    fn triangulate(lp: &[usize]) -> Option<Vec<usize>> {
        const INF: i64 = i64::MAX / 4;
        let n = lp.len();
        let weight = |i: usize, j: usize| -> Option<i64> {
            if j == i + 1 || (i == 0 && j == n - 1) {
                Some(0)
            } else if share_face(lp[i], lp[j]) {
                None
            } else {
                let d = sub(mid(lp[i]), mid(lp[j]));
                Some(dot(d, d) as i64)
            }
        };
        let mut cost = vec![vec![INF; n]; n];
        let mut split = vec![vec![usize::MAX; n]; n];
        for i in 0..n - 1 {
            cost[i][i + 1] = 0;
        }
        for len in 2..n {
            for i in 0..n - len {
                let j = i + len;
                let Some(w) = weight(i, j) else { continue };
                for k in i + 1..j {
                    if cost[i][k] < INF
                        && cost[k][j] < INF
                        && cost[i][k] + cost[k][j] + w < cost[i][j]
                    {
                        cost[i][j] = cost[i][k] + cost[k][j] + w;
                        split[i][j] = k;
                    }
                }
            }
        }
        if cost[0][n - 1] >= INF {
            return None;
        }
        let mut out = vec![];
        let mut stack = vec![(0, n - 1)];
        while let Some((i, j)) = stack.pop() {
            if j > i + 1 {
                let k = split[i][j];
                out.extend([lp[i], lp[k], lp[j]]);
                stack.push((k, j));
                stack.push((i, k));
            }
        }
        Some(out)
    }

    #[test]
    fn tables_match_generator() {
        let (et, tt) = generate();
        assert_eq!(et, EDGE_TABLE);
        assert_eq!(tt, TRI_TABLE);
        // Bourke's first entries, and a single inside corner faces away from it.
        assert_eq!(&EDGE_TABLE[..4], &[0x000, 0x109, 0x203, 0x30a]);
        let t = TRI_TABLE[1];
        let nrm = cross(
            sub(mid(t[1] as usize), mid(t[0] as usize)),
            sub(mid(t[2] as usize), mid(t[0] as usize)),
        );
        assert!(dot(nrm, [1, 1, 1]) > 0);
    }

    #[test]
    fn single_cube_edges_and_sharing() {
        // A 3x3x3 lattice with one inside point in the middle: an octahedron-like closed mesh.
        let m = extract(
            [3, 3, 3],
            [0.0; 3],
            1.0,
            |i, j, k| if (i, j, k) == (1, 1, 1) { 1.0 } else { 0.0 },
            |_| [1.0; 3],
            0.5,
        );
        assert_eq!(m.vertex_count(), 6);
        assert_eq!(m.triangle_count(), 8);
    }
}
