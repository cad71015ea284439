//! Field -> baked asset, SNeRG style.
//!
//! 1. Candidates: coarse blocks that overlap an occupied cell of the trainer's occupancy grid
//!    (dilated by one cell, so thin surfaces on a cell border are not lost).
//! 2. Evaluate the field on every voxel of each candidate block plus its one-voxel apron
//!    (the apron is evaluated, not copied, so neighbouring blocks interpolate seamlessly), and
//!    keep the block if some voxel is opaque enough to matter at the march step.
//! 3. Visibility: a kept block must be in front of (or at) the surface some training camera
//!    sees: its corners are depth-tested against the field's depth in (a subset of) the
//!    training views. Blocks buried inside objects are dropped.
//! 4. Quantize to 8 bits (density as a logit over a range fitted to the march step).
//!
//! Dynamic scenes: one indirection grid per time sample; each cell stores a small codebook
//! of its sampled blocks and every sample points at the closest stored one (`temporal`),
//! within a size budget relative to one static frame.

use std::time::Instant;

use anyhow::{bail, Result};
use rayon::prelude::*;
use serde::Serialize;
use snerf_asset::header::{DensityRange, Header, Keyframe, March, Orbit};
use snerf_asset::mlp::ViewMlp;
use snerf_asset::chunk::CHUNK_HEADER_LEN;
use snerf_asset::mlp::MLP_FLOATS;
use snerf_asset::quantize::{decode_voxel, encode_voxel};
use snerf_asset::Asset;
use snerf_data::{SceneKind, View};
use snerf_trainer::eval::render_camera;
use snerf_geometry::unbounded_dt;
use snerf_trainer::render::{values_batch, WorkspacePool};
use snerf_trainer::space::{dot, norm, sub, Vec3};
use snerf_trainer::train::Model;

use crate::motion;
use crate::temporal::{self, CellSamples};

/// Largest grid per axis the time codebook's visibility is computed on (finer bakes pool
/// voxels into it, so its memory stays under 2 × 64 MiB).
const VISIBILITY_RES: usize = 256;

/// Sentinel of an empty indirection cell (the asset format's).
const EMPTY: u32 = u32::MAX;

#[derive(Clone, Debug)]
pub struct BakeOptions {
    /// Voxels per axis of the fine grid (192: the built-in object at 128² in 18 MB, 0.6 dB
    /// below the field; 256: 34 MB, 0.1 dB; see BENCH.md).
    pub res: u32,
    /// Voxels per block edge (without the apron).
    pub block: u32,
    /// Time samples (keyframes) for dynamic scenes (ignored for static ones).
    pub keyframes: usize,
    /// A block is kept when some voxel's opacity over one march step reaches this.
    pub min_alpha: f32,
    /// Training views used for the visibility test (0: skip the test).
    pub visibility_views: usize,
    /// Dynamic scenes: a cell stores another of its sampled blocks only while that removes
    /// more than this visible RMS difference per voxel of one block (opacity over one step,
    /// and colour/features weighted by opacity and visibility; `temporal`).
    pub reuse_tolerance: f32,
    /// Dynamic scenes: the asset may be at most this many times one static frame (its mean
    /// blocks per sample plus one grid) in size; the cells that change most get the blocks.
    /// Default 2.4: a 4D asset may be 2.5× a static frame, and the bytes up to that buy
    /// fidelity at no cost in playback (BENCH.md §6, "4D: motion": up to +1.3 dB against the
    /// field on seven animated models, the walker's playback ratio unchanged).
    pub time_budget: f32,
    /// The scene's world up direction, overriding the one the training cameras imply.
    pub up: Option<[f32; 3]>,
    /// Dynamic scenes: cells may show the reference sample moved instead of a block of their
    /// own (`motion`); playback then moves what moves instead of blending. On by default:
    /// better against the field on six animated models at equal size (BENCH.md §6).
    pub motion: bool,
    /// With motion: how many reference samples to try (evenly spread from the fullest); the
    /// one that leaves the least motion error is kept.
    pub motion_references: usize,
    /// Dynamic scenes: bake the one instant at this time (the data's time units) as a static
    /// asset instead of the animation: a pose to place in an engine, and the "one static
    /// frame" a 4D asset's size is measured against. The views' own times are ignored; the
    /// visibility test looks at the scene at this time from every view's camera.
    pub at_time: Option<f32>,
    /// Dynamic scenes: count "one static frame" (the unit of `time_budget` and the header's
    /// `static_frame_blocks`) as static bakes at the samples' times (`at_time`) keep it,
    /// testing each sample's visibility with every camera looking at the scene at that time.
    /// Off, the count uses the bake's own visibility (each view at its own time, the union
    /// kept for every sample), which also keeps blocks some other instant exposes (a body's
    /// inside where a limb was) and so can overstate the frame. What the bake keeps is the
    /// same either way; on costs one visibility pass per keyframe.
    pub static_frame_per_sample: bool,
}

impl Default for BakeOptions {
    fn default() -> Self {
        BakeOptions {
            res: 192,
            block: 8,
            keyframes: 24,
            min_alpha: 0.005,
            visibility_views: 32,
            reuse_tolerance: 0.01,
            time_budget: 2.4,
            up: None,
            motion: true,
            motion_references: 3,
            at_time: None,
            static_frame_per_sample: false,
        }
    }
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct BakeReport {
    pub res: u32,
    pub block: u32,
    pub frames: usize,
    /// Blocks overlapping occupied space (per frame, summed).
    pub candidate_blocks: usize,
    /// Candidates with no voxel above `min_alpha`.
    pub dropped_transparent: usize,
    /// Candidates no training camera can see.
    pub dropped_invisible: usize,
    /// (cell, sample) entries served by a block sampled at another time.
    pub shared_blocks: usize,
    /// Blocks each sample keeps (visible to some view at that view's own time).
    pub frame_blocks: Vec<usize>,
    /// Blocks a static bake at each sample's time keeps: `frame_blocks`, or with
    /// `static_frame_per_sample` those of them the cameras see at that time.
    pub static_blocks: Vec<usize>,
    /// Estimated size of one static frame: mean kept blocks, one grid, header and MLP.
    pub static_frame_bytes: u64,
    /// Blocks stored beyond one per cell (dynamic scenes).
    pub extra_blocks: usize,
    /// (cell, sample) pairs whose cell points at another non-empty block in the next sample:
    /// where playback between the two fetches and blends two blocks.
    pub blended_entries: usize,
    /// What the codebook leaves unexplained (sum of `temporal` errors over cells and samples).
    pub codebook_error: f64,
    pub seconds_codebook: f64,
    /// With motion: the reference sample, the (cell, sample) entries shown by motion, and the
    /// seconds the search took.
    pub motion_reference: Option<usize>,
    /// The references tried and the motion error each left (sum over cells and samples).
    pub motion_candidates: Vec<(usize, f64)>,
    pub motion_entries: usize,
    pub seconds_motion: f64,
    pub atlas_blocks: usize,
    pub density_range: [f32; 2],
    pub seconds_visibility: f64,
    pub seconds_evaluate: f64,
    pub seconds_total: f64,
}

/// Bake a model. `views` are the training views (cameras for the visibility test); `bg` is
/// the background colour the asset is shown over.
pub fn bake(
    model: &Model,
    pool: &WorkspacePool,
    views: &[View],
    bg: [f32; 3],
    opts: &BakeOptions,
    progress: &(dyn Fn(&str, u64, u64) + Sync),
) -> Result<(Asset, BakeReport)> {
    let t_all = Instant::now();
    let (res, b) = (opts.res, opts.block);
    if !(4..=64).contains(&b) || res % b != 0 || res < b || res > 2048 {
        bail!("--resolution {res} with --block {b}: the resolution must be a multiple of the block (4..=64), at most 2048");
    }
    let g = (res / b) as usize;
    let space = &model.space;
    let step = model.occ.step;
    // Density range: the smallest code must be negligible over a whole ray of steps; the
    // largest is where a single step is already opaque.
    let logit_min = (1.0e-5f32 / step).ln();
    let logit_max = (30.0f32 / step).ln().min(snerf_trainer::field::SIGMA_LOGIT_MAX);
    let range = DensityRange { logit_min, logit_max };
    let dynamic = space.dynamic && opts.at_time.is_none();
    let frames = if dynamic { opts.keyframes.max(2) } else { 1 };
    let field_times: Vec<f32> = match opts.at_time {
        Some(t) if space.dynamic => vec![space.field_time(Some(t))],
        _ => (0..frames).map(|f| if dynamic { f as f32 / (frames - 1) as f32 } else { 0.0 }).collect(),
    };
    // A frozen instant: every camera looks at the scene at that time.
    let frozen: Vec<View>;
    let views = match opts.at_time {
        Some(t) if space.dynamic => {
            frozen = at_time(views, t);
            &frozen[..]
        }
        _ => views,
    };

    let mut report = BakeReport { res, block: b, frames, ..Default::default() };
    report.density_range = [logit_min, logit_max];

    let candidates = candidate_cells(model, g);
    let per_sample = dynamic && opts.static_frame_per_sample && opts.visibility_views > 0;
    let t0 = Instant::now();
    let visible = if opts.visibility_views > 0 {
        visible_cells(model, pool, views, bg, opts.visibility_views, g, &candidates, progress)
    } else {
        candidates.clone()
    };
    report.seconds_visibility = t0.elapsed().as_secs_f64();

    let bb = (b + 2) as usize;
    let block_voxels = bb * bb * bb;
    let cells: Vec<usize> = (0..g * g * g).filter(|&c| candidates[c]).collect();
    // Per candidate cell: the block the field holds at every sample that keeps one, with its
    // voxels' visibility (dynamic scenes only).
    let mut samples: Vec<CellSamples> = cells
        .iter()
        .map(|&c| {
            let (cx, cy, cz) = (c % g, (c / g) % g, c / (g * g));
            let centre = [cx, cy, cz].map(|k| -1.0 + (k as f32 + 0.5) * 2.0 / g as f32);
            let delta = march_delta(space.kind, step, &centre, space);
            let alpha = std::array::from_fn(|code| {
                let logit = decode_voxel(&[code as u8, 0, 0, 0, 0, 0, 0, 0], &range)[0];
                -(-(logit.exp() * delta).min(80.0)).exp_m1()
            });
            CellSamples { frames: Vec::new(), blocks: Vec::new(), vis: Vec::new(), alpha }
        })
        .collect();
    let t0 = Instant::now();
    for (f, &tau) in field_times.iter().enumerate() {
        report.candidate_blocks += cells.len();
        // what a static bake at this sample's time would call visible
        let visible_now = per_sample.then(|| {
            let tv = Instant::now();
            let (lo, hi) = space.time_range;
            let v = visible_cells(model, pool, &at_time(views, lo + tau * (hi - lo)), bg, opts.visibility_views, g, &candidates, progress);
            report.seconds_visibility += tv.elapsed().as_secs_f64();
            v
        });
        // Evaluate candidate blocks in parallel.
        let done = std::sync::atomic::AtomicU64::new(0);
        let blocks: Vec<Evaluated> = cells
            .par_iter()
            .map(|&c| {
                let r = pool.with(|ws| {
                    let pts = block_points(c, g, b as usize, res as usize);
                    let vals = block_values(model, model, &pts, tau, ws);
                    // keep if some interior voxel is opaque enough over one march step
                    let mut max_alpha = 0.0f32;
                    for z in 1..bb - 1 {
                        for y in 1..bb - 1 {
                            for x in 1..bb - 1 {
                                let k = (z * bb + y) * bb + x;
                                let delta = march_delta(space.kind, step, &pts[k], space);
                                max_alpha = max_alpha.max(1.0 - (-vals[k][0].exp() * delta).exp());
                            }
                        }
                    }
                    if max_alpha < opts.min_alpha {
                        return Evaluated::Transparent;
                    }
                    if !visible[c] {
                        return Evaluated::Hidden;
                    }
                    let mut bytes = Vec::with_capacity(block_voxels * 8);
                    for v in &vals {
                        bytes.extend_from_slice(&encode_voxel(v[0], [v[1], v[2], v[3]], [v[4], v[5], v[6], v[7]], &range));
                    }
                    Evaluated::Kept(bytes)
                });
                let n = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                if n.is_multiple_of(64) {
                    progress(&format!("bake frame {}/{frames}", f + 1), n, cells.len() as u64);
                }
                r
            })
            .collect();
        let kept: Vec<Option<Vec<u8>>> = blocks
            .into_iter()
            .map(|blk| match blk {
                Evaluated::Transparent => {
                    report.dropped_transparent += 1;
                    None
                }
                Evaluated::Hidden => {
                    report.dropped_invisible += 1;
                    None
                }
                Evaluated::Kept(bytes) => Some(bytes),
            })
            .collect();
        let count = kept.iter().filter(|k| k.is_some()).count();
        report.frame_blocks.push(count);
        report.static_blocks.push(match &visible_now {
            Some(v) => kept.iter().zip(&cells).filter(|(k, &c)| k.is_some() && v[c]).count(),
            None => count,
        });
        let vis = if dynamic { visibility(&cells, &kept, &samples, res as usize, b as usize) } else { Vec::new() };
        for (i, blk) in kept.into_iter().enumerate() {
            if let Some(bytes) = blk {
                samples[i].frames.push(f);
                samples[i].blocks.push(bytes);
                samples[i].vis.push(vis.get(i).cloned().unwrap_or_default());
            }
        }
    }
    report.seconds_evaluate = t0.elapsed().as_secs_f64();

    // One static frame: the mean blocks a sample keeps, one grid, header and MLP.
    let block_chunk = (CHUNK_HEADER_LEN + 8 + block_voxels * 8) as f64;
    let grid_chunk = (CHUNK_HEADER_LEN + 4 + 4 * g * g * g) as f64;
    let fixed = 4096.0 + (CHUNK_HEADER_LEN + 4 * MLP_FLOATS) as f64;
    let mean_blocks = report.static_blocks.iter().sum::<usize>() as f64 / frames as f64;
    report.static_frame_bytes = (fixed + grid_chunk + mean_blocks * block_chunk) as u64;
    // The grids' bytes: a motion asset stores each as its occupied cells where that is
    // smaller (`Asset::sparse_grids`; about the blocks the sample keeps), others densely.
    let grids_bytes: f64 = if dynamic && opts.motion {
        let dense = snerf_asset::asset::dense_grid_bytes(g * g * g);
        report.frame_blocks.iter().map(|&n| (CHUNK_HEADER_LEN + dense.min(snerf_asset::asset::sparse_grid_bytes(n))) as f64).sum()
    } else {
        frames as f64 * grid_chunk
    };
    let with_time = samples.iter().filter(|s| !s.frames.is_empty()).count();
    let t0 = Instant::now();
    progress("time codebook", 0, 1);
    let extra = if frames > 1 {
        let budget = opts.time_budget as f64 * report.static_frame_bytes as f64 - fixed - grids_bytes;
        ((budget / block_chunk).floor() - with_time as f64).max(0.0) as usize
    } else {
        0
    };
    let min_gain = opts.reuse_tolerance * opts.reuse_tolerance * block_voxels as f32;
    let motion = if dynamic && opts.motion {
        let t = Instant::now();
        progress("motion search", 0, 1);
        // the fullest sample: every part that is ever there is most likely there too
        // Candidates: the fullest sample (every part that is ever there is most likely there
        // too) and others spread evenly over the time range from it; the one whose moves
        // leave the least error over all cells and samples is the reference.
        let fullest = (0..frames).max_by_key(|&f| (report.frame_blocks[f], usize::MAX - f.abs_diff(frames / 2))).unwrap_or(0);
        let n = opts.motion_references.clamp(1, frames);
        let mut best: Option<(f64, usize, motion::RefVolume, motion::Motion)> = None;
        for k in 0..n {
            let candidate = (fullest + k * frames / n) % frames;
            progress(&format!("motion search, reference {}/{n}", k + 1), k as u64, n as u64);
            let vol = motion::RefVolume::new(&cells, &samples, candidate, res as usize, b as usize);
            let found = motion::search(&cells, &samples, &vol, candidate, frames, b as usize);
            let total: f64 = found.error.iter().flatten().map(|&e| e as f64).sum();
            report.motion_candidates.push((candidate, total));
            if best.as_ref().is_none_or(|x| total < x.0) {
                best = Some((total, candidate, vol, found));
            }
        }
        let Some((_, reference, vol, found)) = best else { bail!("no motion reference among {frames} samples") };
        report.seconds_motion = t.elapsed().as_secs_f64();
        report.motion_reference = Some(reference);
        Some((reference, vol, found))
    } else {
        None
    };
    let books = match &motion {
        Some((reference, _, found)) => {
            let required: Vec<Option<usize>> = samples.iter().map(|s| s.frames.iter().position(|f| f == reference)).collect();
            let base = required.iter().flatten().count();
            let budget = opts.time_budget as f64 * report.static_frame_bytes as f64 - fixed - grids_bytes;
            let extra = ((budget / block_chunk).floor() - base as f64).max(0.0) as usize;
            temporal::choose_with(&samples, extra, min_gain, Some((&found.error, &required)))
        }
        None => temporal::choose(&samples, extra, min_gain),
    };
    report.seconds_codebook = t0.elapsed().as_secs_f64();

    // Atlas: every cell's first block (its medoid over time) in cell order, then the extra
    // ones in the order they were chosen per cell: a client streaming the file in order has
    // the whole scene at its most typical state first.
    let mut atlas: Vec<u8> = Vec::new();
    let mut grids: Vec<Vec<u32>> = vec![vec![EMPTY; g * g * g]; frames];
    let mut index: Vec<Vec<u32>> = books.iter().map(|bk| vec![EMPTY; bk.assign.len()]).collect();
    for pass in 0..2 {
        for (i, bk) in books.iter().enumerate() {
            let stored = if pass == 0 { &bk.stored[..bk.stored.len().min(1)] } else { bk.stored.get(1..).unwrap_or(&[]) };
            for &j in stored {
                index[i][j] = (atlas.len() / (block_voxels * 8)) as u32;
                atlas.extend_from_slice(&samples[i].blocks[j]);
            }
        }
    }
    for (i, bk) in books.iter().enumerate() {
        for (k, &j) in bk.assign.iter().enumerate() {
            if j == temporal::MOTION {
                let d = motion.as_ref().map_or([0.0; 3], |m| m.2.offset[i][k]);
                grids[samples[i].frames[k]][cells[i]] = snerf_asset::motion::motion_entry(d);
                report.motion_entries += 1;
                continue;
            }
            grids[samples[i].frames[k]][cells[i]] = index[i][j];
            if j != k {
                report.shared_blocks += 1;
            }
        }
        report.codebook_error += bk.error as f64;
    }
    report.extra_blocks = books.iter().map(|bk| bk.stored.len().saturating_sub(1)).sum();
    report.blended_entries = temporal::blended_entries(&grids, EMPTY);
    drop(samples);
    let atlas_blocks = atlas.len() / (block_voxels * 8);
    if atlas_blocks == 0 {
        bail!("nothing to bake: no block of the field is both opaque (alpha >= {}) and visible", opts.min_alpha);
    }
    report.atlas_blocks = atlas_blocks;

    let mut header = Header::new(space.kind, res, b);
    header.space = space.frame;
    header.view = space.orbit.map(|o| match opts.up {
        Some(up) => reorient(o, up),
        None => o,
    });
    header.floor = header.view.and_then(|o| floor_height(&header, &grids[0], o.up()));
    header.atlas_blocks = atlas_blocks as u32;
    header.density = range;
    header.march = March { step, t_terminate: snerf_trainer::render::T_TERMINATE };
    header.background = bg;
    // The asset's renderers draw silhouette pixels as the field was trained to be drawn, for
    // cameras whose pixels are about as coarse as the training views' (their median
    // footprint at the scene's centre).
    header.pixel_rays = model.pixel_rays as u32;
    if header.pixel_rays > 1 {
        // the run's own record; runs from before it: the views given here (their training
        // views, unless the bake was pointed at another dataset)
        header.train_pixel = model.pixel_footprint.or_else(|| snerf_trainer::train::views_pixel_footprint(views, header.space.center));
    }
    if dynamic {
        let (lo, hi) = space.time_range;
        header.time_range = Some([lo, hi]);
        header.frames = Some(field_times.iter().map(|&u| Keyframe { time: lo + u * (hi - lo) }).collect());
    }
    let view = &model.field.layout.view;
    let mlp = ViewMlp::from_flat(&model.field.params[view.w1..view.end])?;
    let diffuse = mlp.output_is_zero();
    header.motion_ref = motion.as_ref().map(|m| m.0 as u32);
    if dynamic {
        header.static_frame_blocks = Some(mean_blocks as f32);
        header.colour_by_density = true;
    }
    let mut asset = Asset { header, mlp, grids, present: vec![true; atlas_blocks], atlas };
    if diffuse {
        // A zero output layer (a diffuse stylized field) adds nothing whatever the features
        // and the direction: the asset is diffuse and its file leaves both out.
        asset.make_diffuse();
    }
    asset.validate()?;
    report.seconds_total = t_all.elapsed().as_secs_f64();
    Ok((asset, report))
}

/// `views` with their cameras looking at the scene at time `t` (a frozen instant of a 4D run).
pub fn at_time(views: &[View], t: f32) -> Vec<View> {
    views.iter().map(|v| View { time: Some(t), ..v.clone() }).collect()
}

/// Visibility (0..=255) of every voxel of every kept block of one sample: the light from
/// outside the grid that reaches the voxel along the best axis direction, through this
/// sample's kept blocks (`temporal::optical_depth_in_front`).
fn visibility(cells: &[usize], kept: &[Option<Vec<u8>>], samples: &[CellSamples], res: usize, b: usize) -> Vec<Vec<u8>> {
    let g = res / b;
    let bb = b + 2;
    // Optical depth over one step of every voxel (interior voxels of kept blocks), on a grid
    // of at most VISIBILITY_RES³: k³ voxels pool into one cell holding their mean times k
    // (the depth a ray crossing the cell meets).
    let k = res.div_ceil(VISIBILITY_RES);
    let vr = res.div_ceil(k);
    let mut s = vec![0.0f32; vr * vr * vr];
    for (i, blk) in kept.iter().enumerate() {
        let Some(bytes) = blk else { continue };
        let c = cells[i];
        let (cx, cy, cz) = (c % g, (c / g) % g, c / (g * g));
        for z in 1..=b {
            for y in 1..=b {
                for x in 1..=b {
                    let a = samples[i].alpha[bytes[((z * bb + y) * bb + x) * 8] as usize];
                    let (gx, gy, gz) = (cx * b + x - 1, cy * b + y - 1, cz * b + z - 1);
                    s[((gz / k) * vr + gy / k) * vr + gx / k] += -(1.0 - a).max(1e-30).ln() / (k * k) as f32;
                }
            }
        }
    }
    let front = temporal::optical_depth_in_front(&s, vr);
    kept.par_iter()
        .enumerate()
        .map(|(i, blk)| {
            if blk.is_none() {
                return Vec::new();
            }
            let c = cells[i];
            let base = [c % g, (c / g) % g, c / (g * g)].map(|k| (k * b) as isize - 1);
            let at = |k: usize, a: usize| (base[a] + k as isize).clamp(0, res as isize - 1) as usize;
            let mut v = Vec::with_capacity(bb * bb * bb);
            for z in 0..bb {
                for y in 0..bb {
                    for x in 0..bb {
                        let d = front[((at(z, 2) / k) * vr + at(y, 1) / k) * vr + at(x, 0) / k];
                        v.push((255.0 * (-d).exp()).round() as u8);
                    }
                }
            }
            v
        })
        .collect()
}

/// Grid points of the voxels of the block at coarse cell `c` (index (z*g + y)*g + x), apron
/// included, in the asset's voxel order (x fastest).
pub(crate) fn block_points(c: usize, g: usize, b: usize, res: usize) -> Vec<Vec3> {
    let (cx, cy, cz) = (c % g, (c / g) % g, c / (g * g));
    let bb = b + 2;
    let mut pts = Vec::with_capacity(bb * bb * bb);
    for z in 0..bb {
        for y in 0..bb {
            for x in 0..bb {
                let idx = [cx * b + x, cy * b + y, cz * b + z];
                pts.push(idx.map(|i| -1.0 + (i as f32 - 0.5) * 2.0 / res as f32));
            }
        }
    }
    pts
}

/// `model`'s values (density logit, RGB, features) at `pts` at field time `tau`, with the
/// density of points `occupancy`'s grid marks empty set to the floor: the trainer never
/// samples those cells, so whatever density the field holds there was never seen (or
/// corrected) by training; baked, it would show up as floaters.
pub(crate) fn block_values(model: &Model, occupancy: &Model, pts: &[Vec3], tau: f32, ws: &mut snerf_trainer::render::Workspace) -> Vec<[f32; 8]> {
    let times = vec![tau; pts.len()];
    let mut vals = vec![[0.0f32; 8]; pts.len()];
    values_batch(&model.field, pts, &times, ws, &mut vals);
    let occ = &occupancy.occ;
    for (p, v) in pts.iter().zip(vals.iter_mut()) {
        if occ.cell(p).is_some_and(|i| occ.occ[i] == 0) {
            v[0] = snerf_trainer::field::SIGMA_LOGIT_MIN;
        }
    }
    vals
}

/// What became of one candidate block.
enum Evaluated {
    Transparent,
    Hidden,
    Kept(Vec<u8>),
}

/// Height along `up` (world units, from the world origin) of the scene's floor: the lowest
/// occupied cells — the 1st percentile of their centres' heights, so a stray floater below
/// does not count — among those in the central region (all of an object; the inner cube of
/// an unbounded scene, whose outer shell reaches far below any floor a person stands on).
pub fn floor_height(h: &Header, grid: &[u32], up: [f32; 3]) -> Option<f32> {
    let g = h.grid_dim();
    let mut heights: Vec<f32> = Vec::new();
    for (c, &b) in grid.iter().enumerate() {
        if b == snerf_asset::EMPTY {
            continue;
        }
        let centre = [c % g, (c / g) % g, c / (g * g)].map(|i| -1.0 + (i as f32 + 0.5) * 2.0 / g as f32);
        if h.kind == snerf_geometry::SceneKind::Unbounded && centre.iter().any(|x| x.abs() > 0.5) {
            continue;
        }
        let w = h.space.grid_to_world(h.kind, centre);
        let y = dot(w, up);
        if y.is_finite() {
            heights.push(y);
        }
    }
    if heights.is_empty() {
        return None;
    }
    heights.sort_by(|a, b| a.total_cmp(b));
    Some(heights[heights.len() / 100])
}

/// The orbit turned upright about `up` (a user's `--up`): same centre and radius, the first
/// frame on the same side, elevation measured from the new horizontal plane.
pub fn reorient(o: Orbit, up: [f32; 3]) -> Orbit {
    use snerf_geometry::camera::horizontal;
    use snerf_geometry::vec::{add, cross, normalize, scale};
    let up = normalize(up);
    match o {
        Orbit::Around { center, start, radius, elevation, up: old } => {
            let eye_dir = add(scale(start, elevation.cos()), scale(old, elevation.sin()));
            let elevation = dot(eye_dir, up).clamp(-1.0, 1.0).asin();
            Orbit::Around { center, up, start: horizontal(up, eye_dir), radius, elevation }
        }
        Orbit::Ellipse { center, right: old_right, target, rx, ry, .. } => {
            let fwd = normalize(sub(target, center));
            let r = cross(fwd, up);
            let right = if norm(r) > 1e-3 { normalize(r) } else { old_right };
            Orbit::Ellipse { center, right, up: cross(right, fwd), target, rx, ry }
        }
    }
}

/// The march-space step length at a grid point (what σ multiplies there).
fn march_delta(kind: SceneKind, step: f32, g: &Vec3, space: &snerf_trainer::space::SceneSpace) -> f32 {
    match kind {
        SceneKind::Unbounded => unbounded_dt(step, space.grid_to_march(*g)),
        _ => step,
    }
}

/// Coarse cells (index (z*g + y)*g + x) overlapping an occupied occupancy cell, dilated by
/// one occupancy cell.
fn candidate_cells(model: &Model, g: usize) -> Vec<bool> {
    let occ = &model.occ;
    let r = occ.res;
    let mut out = vec![false; g * g * g];
    for i in 0..r * r * r {
        if occ.occ[i] == 0 {
            continue;
        }
        // occupancy index is (x*r + y)*r + z
        let (x, y, z) = (i / (r * r), (i / r) % r, i % r);
        let span = |k: usize| {
            // grid extent of the dilated cell, as coarse-cell indices
            let lo = ((k as f32 - 1.0) / r as f32 * g as f32).floor().max(0.0) as usize;
            let hi = (((k + 2) as f32 / r as f32 * g as f32).ceil() as usize).min(g);
            lo..hi
        };
        for cz in span(z) {
            for cy in span(y) {
                for cx in span(x) {
                    out[(cz * g + cy) * g + cx] = true;
                }
            }
        }
    }
    out
}

/// Candidate cells some training camera sees: a cell is visible when one of its corners or
/// its centre projects into a view no farther from the camera than the surface the field
/// shows there (plus half a cell), or onto a pixel the field leaves uncovered.
#[allow(clippy::too_many_arguments)]
fn visible_cells(
    model: &Model,
    pool: &WorkspacePool,
    views: &[View],
    bg: [f32; 3],
    max_views: usize,
    g: usize,
    candidates: &[bool],
    progress: &(dyn Fn(&str, u64, u64) + Sync),
) -> Vec<bool> {
    let space = &model.space;
    let picked: Vec<&View> = if views.len() <= max_views {
        views.iter().collect()
    } else {
        (0..max_views).map(|i| &views[i * views.len() / max_views]).collect()
    };
    let cells: Vec<usize> = (0..g * g * g).filter(|&c| candidates[c]).collect();
    // world-space probe points of each cell: 8 corners and the centre
    let probes: Vec<[Vec3; 9]> = cells
        .iter()
        .map(|&c| {
            let (cx, cy, cz) = (c % g, (c / g) % g, c / (g * g));
            let at = |fx: f32, fy: f32, fz: f32| {
                let gp = [cx as f32 + fx, cy as f32 + fy, cz as f32 + fz].map(|u| -1.0 + u * 2.0 / g as f32);
                space.march_point_to_world(space.grid_to_march(gp))
            };
            let mut p = [[0.0f32; 3]; 9];
            for k in 0..8 {
                p[k] = at((k & 1) as f32, ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32);
            }
            p[8] = at(0.5, 0.5, 0.5);
            p
        })
        .collect();
    let mut seen = vec![false; cells.len()];
    for (vi, v) in picked.iter().enumerate() {
        progress("visibility", vi as u64, picked.len() as u64);
        let r = render_camera(model, pool, &v.c2w, &v.intrinsics, v.time, bg);
        let (w, h) = (r.width, r.height);
        let k = &v.intrinsics;
        let m = &v.c2w;
        let o = [m[0][3], m[1][3], m[2][3]];
        // distance to the surface per pixel (infinite where the field leaves it uncovered)
        let surf: Vec<f32> = (0..w * h)
            .into_par_iter()
            .map(|p| {
                if r.opacity[p] < 0.5 {
                    return f32::INFINITY;
                }
                let (x, y) = (p % w, p / w);
                match space.ray(m, k, x as f32 + 0.5, y as f32 + 0.5, v.time) {
                    Some(ray) => norm(sub(space.march_to_world(&ray, r.depth[p]), o)),
                    None => f32::INFINITY,
                }
            })
            .collect();
        seen.par_iter_mut().zip(&probes).for_each(|(s, pr)| {
            if *s {
                return;
            }
            let half = norm(sub(pr[0], pr[7])) * 0.5;
            for p in pr {
                let d = sub(*p, o);
                let xc = dot(d, [m[0][0], m[1][0], m[2][0]]);
                let yc = dot(d, [m[0][1], m[1][1], m[2][1]]);
                let zc = dot(d, [m[0][2], m[1][2], m[2][2]]);
                if zc >= -1e-6 {
                    continue;
                }
                let (u, vv) = (k.cx + k.fx * xc / -zc, k.cy + k.fy * yc / zc);
                if !(u >= 0.0 && vv >= 0.0 && u < w as f32 && vv < h as f32) {
                    continue;
                }
                let px = vv as usize * w + u as usize;
                if norm(d) <= surf[px] + half {
                    *s = true;
                    return;
                }
            }
        });
    }
    let mut out = vec![false; g * g * g];
    for (&c, s) in cells.iter().zip(seen) {
        out[c] = s;
    }
    out
}
