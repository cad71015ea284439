//! Style layers: the colour of another appearance-only stylization of the same geometry,
//! baked onto an asset already baked from the first (`snerf_asset::layers` stores them as one
//! multi-style asset).
//!
//! The geometry (which blocks are kept, every voxel's density, the occupancy that floors
//! density in cells training never sampled) is the first layer's bake; a further layer is only
//! evaluated at the voxels of that asset's blocks, for its colour, features and view MLP.
//! Its own density there must give the same 8-bit codes: a layer stylized with
//! `--appearance-only` from the same run has its density frozen bit for bit, anything else
//! is refused ("trained on another geometry") instead of drawing one style's colours on
//! another's surface.

use anyhow::{bail, Result};
use rayon::prelude::*;
use snerf_asset::mlp::ViewMlp;
use snerf_asset::quantize::{encode_density, encode_voxel, CHANNELS};
use snerf_asset::{Asset, EMPTY};
use snerf_trainer::render::WorkspacePool;
use snerf_trainer::train::Model;

use crate::bake::{block_points, block_values};

/// How a layer's density compared with the geometry it was baked onto.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct LayerReport {
    pub blocks: usize,
    pub voxels: usize,
    /// Voxels whose density code differs from the geometry's (0 for a frozen geometry).
    pub density_mismatches: usize,
    pub seconds: f64,
}

/// `geometry` (baked from `geometry_model`) with `model`'s colours, features and view MLP:
/// the single-style asset of this layer. Fails, counting the voxels, when `model`'s density
/// is not the geometry's.
pub fn bake_colour(model: &Model, pool: &WorkspacePool, geometry_model: &Model, geometry: &Asset) -> Result<(Asset, LayerReport)> {
    let t0 = std::time::Instant::now();
    let h = &geometry.header;
    let (g, b, res) = (h.grid_dim(), h.block as usize, h.res as usize);
    let nb = h.atlas_blocks as usize;
    // each block's cell and field time: where it is first used
    let mut origin: Vec<Option<(usize, f32)>> = vec![None; nb];
    for (f, grid) in geometry.grids.iter().enumerate() {
        let tau = match h.time_range {
            Some([lo, hi]) if hi > lo => (h.frame_time(f) - lo) / (hi - lo),
            _ => 0.0,
        };
        for (c, &e) in grid.iter().enumerate() {
            if e != EMPTY && origin[e as usize].is_none() {
                origin[e as usize] = Some((c, tau));
            }
        }
    }
    let bb = h.block_bytes();
    let mut asset = geometry.clone();
    asset.header.diffuse = false;
    let view = &model.field.layout.view;
    asset.mlp = ViewMlp::from_flat(&model.field.params[view.w1..view.end])?;
    let mismatches: Vec<usize> = asset
        .atlas
        .par_chunks_exact_mut(bb)
        .zip(origin.par_iter())
        .map(|(blk, o)| {
            let Some((c, tau)) = *o else { return 0 };
            let pts = block_points(c, g, b, res);
            let vals = pool.with(|ws| block_values(model, geometry_model, &pts, tau, ws));
            let mut bad = 0;
            for (v, val) in blk.chunks_exact_mut(CHANNELS).zip(&vals) {
                if encode_density(val[0], &h.density) != v[0] {
                    bad += 1;
                }
                let code = v[0];
                v.copy_from_slice(&encode_voxel(val[0], [val[1], val[2], val[3]], [val[4], val[5], val[6], val[7]], &h.density));
                v[0] = code;
            }
            bad
        })
        .collect();
    let report = LayerReport {
        blocks: nb,
        voxels: nb * bb / CHANNELS,
        density_mismatches: mismatches.iter().sum(),
        seconds: t0.elapsed().as_secs_f64(),
    };
    if report.density_mismatches > 0 {
        bail!(
            "{} of {} voxels' density differs from the geometry's (first in block {})",
            report.density_mismatches,
            report.voxels,
            mismatches.iter().position(|&m| m > 0).unwrap_or(0)
        );
    }
    if asset.mlp.output_is_zero() {
        asset.make_diffuse();
    }
    asset.validate()?;
    Ok((asset, report))
}
