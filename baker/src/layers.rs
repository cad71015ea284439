//! Style layers: the colour of another appearance-only stylization of the same geometry,
//! baked onto an asset already baked from the first (`snerf_asset::layers` stores them as one
//! multi-style asset).
//!
//! The geometry (which blocks are kept, every voxel's density, the occupancy that floors
//! density in cells training never sampled) is the first layer's bake; a further layer is only
//! evaluated at the voxels of that asset's blocks, for its colour, features and view MLP
//! (a dynamic geometry's block at the time sample it was taken from: the time codebook shares
//! blocks among frames, so that need not be the first frame showing it).
//! Its own density there must give the same 8-bit codes: a layer stylized with
//! `--appearance-only` from the same run has its density frozen bit for bit, anything else
//! is refused ("trained on another geometry") instead of drawing one style's colours on
//! another's surface.

use anyhow::{bail, ensure, Result};
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
    ensure!(h.motion_ref.is_none(), "style layers need a geometry of blocks only; bake it with --motion false");
    let (g, b, res) = (h.grid_dim(), h.block as usize, h.res as usize);
    let nb = h.atlas_blocks as usize;
    // each block's uses: (cell, field time) of every frame that points at it, in frame order.
    // A dynamic geometry's time codebook shares a block among frames, and the block holds the
    // field at the one sample it was taken from, which need not be the first frame using it.
    let mut uses: Vec<Vec<(usize, f32)>> = vec![Vec::new(); nb];
    for (f, grid) in geometry.grids.iter().enumerate() {
        let tau = match h.time_range {
            Some([lo, hi]) if hi > lo => (h.frame_time(f) - lo) / (hi - lo),
            _ => 0.0,
        };
        for (c, &e) in grid.iter().enumerate() {
            if e != EMPTY {
                uses[e as usize].push((c, tau));
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
        .zip(uses.par_iter())
        .map(|(blk, u)| {
            // the layer at the first use whose density gives the block's codes (its sample),
            // else at the use that came closest
            let mut best: Option<(usize, Vec<[f32; 8]>)> = None;
            for &(c, tau) in u {
                let pts = block_points(c, g, b, res);
                let vals = pool.with(|ws| block_values(model, geometry_model, &pts, tau, ws));
                let bad = blk.chunks_exact(CHANNELS).zip(&vals).filter(|(v, val)| encode_density(val[0], &h.density) != v[0]).count();
                let done = bad == 0;
                if best.as_ref().is_none_or(|(b, _)| bad < *b) {
                    best = Some((bad, vals));
                }
                if done {
                    break;
                }
            }
            let Some((bad, vals)) = best else { return 0 };
            for (v, val) in blk.chunks_exact_mut(CHANNELS).zip(&vals) {
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

/// One style layer to bake: its name, the painting it came from and its trained field.
pub struct Layer<'a> {
    pub name: &'a str,
    /// Where the layer's run is, for messages.
    pub dir: &'a std::path::Path,
    pub source: &'a str,
    pub model: &'a Model,
    pub pool: &'a WorkspacePool,
}

/// A multi-style bake: the asset, the first layer's bake report (the geometry's), and each
/// layer's bake time in seconds (the first's includes the geometry).
pub struct LayeredBake {
    pub asset: snerf_asset::LayeredAsset,
    pub report: crate::bake::BakeReport,
    pub seconds: Vec<f64>,
}

/// Every layer of an appearance-only stylization as one multi-style asset: the first layer
/// baked as usual (it fixes the geometry), every further layer's colour baked onto it
/// (`bake_colour`). A layer whose density is not the first's is refused by name.
pub fn bake_layered(
    layers: &[Layer],
    views: &[snerf_trainer::data::View],
    bg: [f32; 3],
    opts: &crate::bake::BakeOptions,
    progress: &(dyn Fn(&str, u64, u64) + Sync),
) -> Result<LayeredBake> {
    let Some(first) = layers.first() else { bail!("no style layers to bake") };
    let t0 = std::time::Instant::now();
    // a multi-style asset holds blocks only (motion entries are for one style: FORMAT.md)
    let opts = &crate::bake::BakeOptions { motion: false, ..opts.clone() };
    let (geometry, report) = crate::bake::bake(first.model, first.pool, views, bg, opts, progress)?;
    let mut seconds = vec![t0.elapsed().as_secs_f64()];
    let mut assets = vec![geometry];
    for l in &layers[1..] {
        let (asset, lr) = bake_colour(l.model, l.pool, first.model, &assets[0]).map_err(|e| {
            anyhow::anyhow!(
                "{}: layer {:?} was trained on another geometry than layer {:?} ({:#}); stylize every layer from the same run with --appearance-only",
                l.dir.display(),
                l.name,
                first.name,
                e
            )
        })?;
        seconds.push(lr.seconds);
        assets.push(asset);
    }
    let styles = layers
        .iter()
        .zip(&assets)
        .map(|(l, a)| snerf_asset::StyleInfo { name: l.name.to_string(), source: Some(l.source.to_string()), swatch: snerf_asset::layers::swatch(a) })
        .collect();
    Ok(LayeredBake { asset: snerf_asset::LayeredAsset::new(styles, assets)?, report, seconds })
}
