//! A baked asset as a mesh for engines: marching cubes over the baked voxels' opacity, vertex
//! colours from the baked diffuse colour, positions mapped back to the capture's world
//! coordinates (metres, Y-up for glTF-sourced scenes), one mesh per keyframe for 4D assets.
//! `surface_agreement` checks the mesh against the field's own depth.

use std::collections::HashMap;
use std::path::Path;

use anyhow::Result;
use serde::Serialize;
use snerf_asset::quantize::decode_density;
use snerf_asset::{Asset, EMPTY};

use crate::gltf_export::{write_glb, write_glb_frames, FlipbookOptions, GlbStats, GltfOptions};
use crate::marching_cubes::{extract_blocks, Mesh};

/// The opacity of one voxel (over one voxel's length) read straight from the atlas; 0 for
/// empty cells and outside the grid. Lattice index i is voxel i - 1: a border of empty
/// points closes the surface.
fn voxel_alpha(asset: &Asset, frame: usize, idx: [usize; 3], voxel_len: f32) -> f32 {
    let res = asset.header.res as usize;
    if idx.iter().any(|&i| i == 0 || i > res) {
        return 0.0;
    }
    let v = idx.map(|i| i - 1);
    let b = asset.header.block as usize;
    let g = asset.grid_dim();
    let cell = [v[0] / b, v[1] / b, v[2] / b];
    let blk = asset.grids[frame][(cell[2] * g + cell[1]) * g + cell[0]];
    if blk == EMPTY || !asset.present.get(blk as usize).copied().unwrap_or(false) {
        return 0.0;
    }
    let bb = b + 2;
    let l = [0, 1, 2].map(|a| v[a] % b + 1);
    let off = blk as usize * asset.block_bytes() + ((l[2] * bb + l[1]) * bb + l[0]) * 8;
    let sigma = decode_density(asset.atlas[off], &asset.header.density).exp();
    1.0 - (-sigma * voxel_len).exp()
}

/// The largest one-voxel opacity anywhere in the atlas: an iso level above it finds no surface.
pub fn max_voxel_alpha(asset: &Asset) -> f32 {
    let code = asset.atlas.iter().step_by(8).copied().max().unwrap_or(0);
    let sigma = decode_density(code, &asset.header.density).exp();
    1.0 - (-sigma * 2.0 / asset.header.res as f32).exp()
}

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Grid point -> world point (the one mapping every client uses, in `snerf_asset::render`).
pub fn grid_to_world(asset: &Asset, g: [f32; 3]) -> [f32; 3] {
    snerf_asset::render::grid_to_world(&asset.header, g)
}

/// Marching cubes over one keyframe at opacity level `iso`, in world coordinates.
pub fn asset_mesh(asset: &Asset, frame: usize, iso: f32) -> Mesh {
    let res = asset.header.res as usize;
    let b = asset.header.block as usize;
    let g = asset.grid_dim();
    let voxel_len = 2.0 / res as f32;
    // lattice blocks (of b cells) touching an occupied asset cell: c and c + 1 per axis
    let mut blocks = std::collections::BTreeSet::new();
    for (c, &blk) in asset.grids[frame].iter().enumerate() {
        if blk == EMPTY {
            continue;
        }
        let cell = [c % g, (c / g) % g, c / (g * g)];
        for k in 0..8 {
            blocks.insert([cell[0] + (k & 1), cell[1] + ((k >> 1) & 1), cell[2] + ((k >> 2) & 1)]);
        }
    }
    let blocks: Vec<[usize; 3]> = blocks.into_iter().collect();
    let dims = [res + 2; 3];
    // lattice point i sits at voxel centre i - 1
    let origin = [-1.0 - 0.5 * voxel_len; 3];
    let mut mesh = extract_blocks(
        dims,
        origin,
        voxel_len,
        b,
        &blocks,
        |i, j, k| voxel_alpha(asset, frame, [i, j, k], voxel_len),
        |p| match asset.sample(frame, p) {
            Some(v) => [v[1], v[2], v[3]].map(|c| srgb_to_linear(c.clamp(0.0, 1.0))),
            None => [0.5; 3],
        },
        iso,
    );
    // to world; normals follow the mapped triangles (the map is not linear in general)
    for p in &mut mesh.positions {
        *p = grid_to_world(asset, *p);
    }
    recompute_normals(&mut mesh);
    mesh
}

fn recompute_normals(mesh: &mut Mesh) {
    let mut n = vec![[0.0f32; 3]; mesh.positions.len()];
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| mesh.positions[i as usize]);
        let e1 = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let e2 = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let f = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
        for &i in t {
            for k in 0..3 {
                n[i as usize][k] += f[k];
            }
        }
    }
    for (dst, src) in mesh.normals.iter_mut().zip(&n) {
        let l = (src[0] * src[0] + src[1] * src[1] + src[2] * src[2]).sqrt();
        if l > 0.0 && l.is_finite() {
            *dst = src.map(|x| x / l);
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct ExportReport {
    pub frames: usize,
    pub vertices: usize,
    pub triangles: usize,
    pub bytes: u64,
    pub iso: f32,
}

/// Write `asset` as a GLB: one mesh, or a flipbook of keyframe meshes for 4D assets.
pub fn export_glb(asset: &Asset, iso: f32, path: &Path) -> Result<(ExportReport, Vec<Mesh>)> {
    let opts = GltfOptions { name: "snerf".into(), iso: Some(iso), ..GltfOptions::default() };
    // a frame with motion entries is meshed as the blocks it shows (`frame_as_static`)
    let meshes: Vec<Mesh> = (0..asset.num_frames())
        .map(|f| match asset.header.motion_ref {
            Some(_) => asset.frame_as_static(f).map(|s| asset_mesh(&s, 0, iso)),
            None => Ok(asset_mesh(asset, f, iso)),
        })
        .collect::<Result<_>>()?;
    let stats: GlbStats = if asset.is_dynamic() {
        let times: Vec<f32> = (0..asset.num_frames()).map(|f| asset.header.frame_time(f)).collect();
        let opts = GltfOptions { animation: Some(FlipbookOptions::default()), ..opts };
        write_glb_frames(&meshes, &times, &opts, path)?
    } else {
        write_glb(&meshes[0], &opts, path)?
    };
    Ok((
        ExportReport {
            frames: meshes.len(),
            vertices: meshes.iter().map(|m| m.vertex_count()).sum(),
            triangles: meshes.iter().map(|m| m.triangle_count()).sum(),
            bytes: stats.bytes,
            iso,
        },
        meshes,
    ))
}

/// Distance from each point to the nearest triangle of `mesh` (brute force over the
/// triangles in nearby cells of a hash grid with cell size `cell`); points farther than
/// 3 cells from every triangle get `f32::INFINITY`.
pub fn distances_to_mesh(mesh: &Mesh, points: &[[f32; 3]], cell: f32) -> Vec<f32> {
    let key = |p: [f32; 3]| p.map(|x| (x / cell).floor() as i64);
    let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
    for (ti, t) in mesh.indices.chunks_exact(3).enumerate() {
        let v = [t[0], t[1], t[2]].map(|i| mesh.positions[i as usize]);
        let lo = key([0, 1, 2].map(|a| v[0][a].min(v[1][a]).min(v[2][a])));
        let hi = key([0, 1, 2].map(|a| v[0][a].max(v[1][a]).max(v[2][a])));
        if (0..3).any(|a| hi[a] - lo[a] > 64) {
            continue; // a huge triangle (far contraction shell): not a surface to check
        }
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    grid.entry([x, y, z]).or_default().push(ti as u32);
                }
            }
        }
    }
    points
        .iter()
        .map(|&p| {
            let k = key(p);
            let mut best = f32::INFINITY;
            for dx in -3..=3 {
                for dy in -3..=3 {
                    for dz in -3..=3 {
                        if let Some(ts) = grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                            for &ti in ts {
                                let t = &mesh.indices[ti as usize * 3..ti as usize * 3 + 3];
                                let v = [t[0], t[1], t[2]].map(|i| mesh.positions[i as usize]);
                                best = best.min(point_triangle_distance(p, v));
                            }
                        }
                    }
                }
            }
            best
        })
        .collect()
}

/// Euclidean distance from `p` to triangle `t` (Ericson, Real-Time Collision Detection 5.1.5).
pub fn point_triangle_distance(p: [f32; 3], t: [[f32; 3]; 3]) -> f32 {
    let sub = |a: [f32; 3], b: [f32; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let dot = |a: [f32; 3], b: [f32; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let (a, b, c) = (t[0], t[1], t[2]);
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let closest = (|| {
        let (d1, d2) = (dot(ab, ap), dot(ac, ap));
        if d1 <= 0.0 && d2 <= 0.0 {
            return a;
        }
        let bp = sub(p, b);
        let (d3, d4) = (dot(ab, bp), dot(ac, bp));
        if d3 >= 0.0 && d4 <= d3 {
            return b;
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            let v = d1 / (d1 - d3);
            return [a[0] + v * ab[0], a[1] + v * ab[1], a[2] + v * ab[2]];
        }
        let cp = sub(p, c);
        let (d5, d6) = (dot(ab, cp), dot(ac, cp));
        if d6 >= 0.0 && d5 <= d6 {
            return c;
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            let w = d2 / (d2 - d6);
            return [a[0] + w * ac[0], a[1] + w * ac[1], a[2] + w * ac[2]];
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            return [b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]), b[2] + w * (c[2] - b[2])];
        }
        let denom = 1.0 / (va + vb + vc);
        let (v, w) = (vb * denom, vc * denom);
        [0, 1, 2].map(|i| a[i] + ab[i] * v + ac[i] * w)
    })();
    let d = sub(p, closest);
    dot(d, d).sqrt()
}
