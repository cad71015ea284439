//! The training loop: random rays across all training views, fused forward/backward on rayon
//! workers (one gradient buffer per worker), Adam, occupancy refreshes, a learning-rate decay
//! over the run's budget (steps or minutes, whichever ends first), and the curve of test
//! PSNR against seconds that `metrics.json` records.

use std::time::Instant;

use anyhow::Result;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use snerf_data::{Dataset, SceneKind, View};

use crate::adam::Adam;
use crate::appearance::Appearance;
use crate::field::{Field, FieldConfig};
use crate::occupancy::Occupancy;
use crate::render::{density_batch, train_chunk_with, Backward, ChunkStats, RayTask, WorkspacePool};
use crate::rng::Rng;
use crate::space::SceneSpace;

// Where the training step's PSNR has always been found; the formula lives with the metrics.
pub use crate::metrics::mse_to_psnr;
// `train::Model` is the path every user of a trained model names; the type lives below
// training, where evaluation and checkpoints reach it without depending on the trainer.
pub use crate::model::Model;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    /// Rays in the first step; later steps adapt the ray count so that a step carries about
    /// `batch_samples` samples (as Instant-NGP does): early steps through unpruned space are
    /// then as quick as later ones, and the occupancy grid prunes sooner in wall time.
    pub batch_rays: usize,
    pub batch_samples: usize,
    pub max_batch_rays: usize,
    pub chunk_rays: usize,
    pub lr_planes: f32,
    pub lr_mlp: f32,
    /// Learning rate at the end of the budget, as a fraction of the start.
    pub lr_final: f32,
    pub occupancy_res: usize,
    pub steps_per_diagonal: usize,
    /// Refresh the occupancy grid every this many steps.
    pub occupancy_every: u64,
    /// Weight of the distortion loss (0 = off; on for forward-facing and unbounded scenes).
    pub distortion: f32,
    /// Weight of the total-variation loss on the spatial planes (0 = off; 1e-3 for static
    /// objects (on the dynamic avatar it cost 1.1 dB and 20% speed, so it is off there):
    /// +1.4 dB held-out PSNR on 2CylinderEngine at 2000 steps, see BENCH.md).
    #[serde(default)]
    pub tv: f32,
    /// Keep the geometry fixed: the planes, the decoder's shared hidden layer and its density
    /// output do not move; only the colour/feature outputs and the view MLP learn (SNeRF's
    /// "appearance only" ablation).
    #[serde(default)]
    pub freeze_geometry: bool,
    /// Keep the view-dependence MLP fixed. Stylization sets it: per-view stylized targets
    /// disagree in detail, and a free view MLP learns that disagreement as view-dependent
    /// colour, which is exactly the flicker between viewpoints SNeRF exists to remove.
    #[serde(default)]
    pub freeze_view: bool,
    pub seed: u64,
    pub field: FieldConfig,
    /// Rays per silhouette pixel (a square number, up to [`MAX_PIXEL_RAYS`]): such a pixel
    /// is trained and rendered as the mean of rays stratified over its square, the way the
    /// views were made (a supersampling renderer, a camera sensor). 4 for static objects;
    /// 1 (one ray through the centre) elsewhere and in checkpoints from before it existed.
    #[serde(default = "one")]
    pub pixel_rays: usize,
    /// Where `pixel_rays` > 1: the training views' median pixel footprint at the scene's
    /// centre (world units, `silhouette::median_footprint`), recorded so the baked asset's
    /// renderers know which display pixels are as coarse as the ones the edges were learnt
    /// from. Absent in runs from before it existed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixel_footprint: Option<f32>,
    /// Draw each training ray anywhere in its pixel's square instead of through its centre
    /// (silhouette pixels keep their `pixel_rays` stratified rays). Set while stylizing: a
    /// painted view's pixel is the paint over its square, and a field fitted only at pixel
    /// centres is free between them, where a new view's rays fall (docs/stylize-notebook.md §5s, §5u).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub area_rays: bool,
    /// Weight of K-Planes' temporal-smoothness prior on the time planes (mean squared second
    /// difference along t, [`Field::time_priors_backward`]); 0 = off, and in runs from before
    /// it existed.
    #[serde(default)]
    pub time_smooth: f32,
    /// Weight of K-Planes' sparse-transients prior on the time planes (mean |1 − value|).
    #[serde(default)]
    pub time_sparse: f32,
    /// Per-photo colour transforms learnt with the field (`appearance`): the weight of their
    /// pull toward identity; 0 = off.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub appearance: f32,
    /// Carve the occupancy grid along the lines of sight of the capture's sparse points
    /// ([`crate::free_space`]) when the run starts; only COLMAP models with `points3D.bin`
    /// have them, every other dataset is untouched. On by default for COLMAP datasets; off
    /// in runs from before it existed.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub sparse_carving: bool,
}

fn is_zero(x: &f32) -> bool {
    *x == 0.0
}

fn one() -> usize {
    1
}

impl TrainConfig {
    /// Defaults that suit the dataset: plane resolution follows image resolution, time planes
    /// only for dynamic scenes.
    pub fn for_dataset(data: &Dataset) -> TrainConfig {
        let max_dim = data.train.iter().map(|v| v.intrinsics.width.max(v.intrinsics.height)).max().unwrap_or(128);
        let finest = match (data.kind, data.dynamic, pixels_across_box(data)) {
            // A static object: one plane cell per pixel that the views see across the scene's
            // box (the median view). Finer cells than the views sample are constrained by no
            // single pixel, only by how pixels of different views happen to overlap, and the
            // field fills them with detail that fits the training views and no other (on
            // unseen models: train 43.7 dB against held-out 37.9 dB at two cells per pixel).
            // An animated object's spatial planes are seen by every view at every time, so the
            // same rule holds for them.
            (SceneKind::Object, _, Some(px)) => ((px / 16.0).ceil() as u32 * 16).clamp(64, 512),
            // About two plane cells per pixel across the object / the contracted inner cube;
            // forward-facing NDC spans exactly the image, so one cell per pixel.
            _ => {
                let per_pixel = if data.kind == SceneKind::Forward { 1 } else { 2 };
                (per_pixel * max_dim).next_power_of_two().clamp(128, 512)
            }
        };
        let resolutions = vec![finest / 8, finest / 4, finest / 2, finest];
        let time_resolutions = if data.dynamic { time_levels(finest_time_resolution(data)) } else { Vec::new() };
        TrainConfig {
            batch_rays: 4096,
            batch_samples: 1 << 16,
            max_batch_rays: 16384,
            chunk_rays: 64,
            lr_planes: 0.04,
            lr_mlp: 0.01,
            lr_final: 0.1,
            occupancy_res: 64,
            steps_per_diagonal: 512,
            occupancy_every: 16,
            distortion: if data.kind == SceneKind::Object { 0.0 } else { 0.01 },
            tv: if data.kind == SceneKind::Object && !data.dynamic { 1e-3 } else { 0.0 },
            freeze_geometry: false,
            freeze_view: false,
            seed: 0,
            field: FieldConfig { resolutions, time_resolutions, hidden: 32, deform: None, colour_head: false },
            // Objects on transparent film, static or animated: forward and unbounded scenes
            // were not re-measured.
            pixel_rays: if data.kind == SceneKind::Object { 4 } else { 1 },
            pixel_footprint: if data.kind == SceneKind::Object { train_pixel_footprint(data) } else { None },
            area_rays: false,
            // K-Planes' weights for its monocular (D-NeRF) scenes.
            time_smooth: if data.dynamic { TIME_SMOOTH } else { 0.0 },
            time_sparse: if data.dynamic { TIME_SPARSE } else { 0.0 },
            appearance: 0.0,
            // Captures: COLMAP's sparse points are there to be used (BENCH.md §2d: on both
            // ViSP captures, fewer samples per pixel and higher held-out PSNR at equal steps).
            sparse_carving: data.format == "colmap",
        }
    }
}

impl TrainConfig {
    /// Add a deformation ([`crate::deform`]) to a dynamic scene's field, its knots over time
    /// following the time planes' finest resolution.
    pub fn enable_deform(&mut self) -> Result<()> {
        anyhow::ensure!(self.field.dynamic(), "a deformation applies to dynamic scenes only");
        let finest = self.field.time_resolutions.iter().copied().max().unwrap_or(4);
        self.field.deform = Some(crate::deform::DeformConfig::for_time_resolution(finest));
        Ok(())
    }

    /// Reject settings no run can use (a hand-edited or foreign checkpoint, a bad flag), so
    /// they fail with a message instead of a panic deep inside a step.
    pub fn validate(&self) -> Result<()> {
        let pos = |name: &str, v: f32| {
            anyhow::ensure!(v.is_finite() && v > 0.0, "training setting {name} must be a positive number (is {v})");
            Ok(())
        };
        let nonneg = |name: &str, v: f32| {
            anyhow::ensure!(v.is_finite() && v >= 0.0, "training setting {name} must be a number >= 0 (is {v})");
            Ok(())
        };
        let count = |name: &str, v: usize, max: usize| {
            anyhow::ensure!((1..=max).contains(&v), "training setting {name} must be in 1..={max} (is {v})");
            Ok(())
        };
        pos("lr_planes", self.lr_planes)?;
        pos("lr_mlp", self.lr_mlp)?;
        pos("lr_final", self.lr_final)?;
        nonneg("distortion", self.distortion)?;
        nonneg("tv", self.tv)?;
        nonneg("time_smooth", self.time_smooth)?;
        nonneg("time_sparse", self.time_sparse)?;
        count("batch_rays", self.batch_rays, 1 << 20)?;
        count("max_batch_rays", self.max_batch_rays, 1 << 20)?;
        anyhow::ensure!(self.batch_samples <= 1 << 24, "training setting batch_samples must be at most {} (is {})", 1 << 24, self.batch_samples);
        count("chunk_rays", self.chunk_rays, 1 << 16)?;
        count("occupancy_res", self.occupancy_res, 1024)?;
        count("steps_per_diagonal", self.steps_per_diagonal, 1 << 16)?;
        count("occupancy_every", self.occupancy_every as usize, 1 << 20)?;
        count("pixel_rays", self.pixel_rays, MAX_PIXEL_RAYS)?;
        let side = (self.pixel_rays as f64).sqrt().round() as usize;
        anyhow::ensure!(side * side == self.pixel_rays, "training setting pixel_rays must be a square number: 1, 4, 9 or 16 (is {})", self.pixel_rays);
        let f = &self.field;
        anyhow::ensure!(!f.resolutions.is_empty() && f.resolutions.len() <= 8, "training setting field.resolutions must have 1..=8 levels");
        for &r in f.resolutions.iter().chain(&f.time_resolutions) {
            count("a plane resolution", r as usize, 4096)?;
        }
        anyhow::ensure!(
            f.time_resolutions.is_empty() || f.time_resolutions.len() == f.resolutions.len(),
            "training setting field.time_resolutions must be empty or have one entry per level"
        );
        anyhow::ensure!(f.hidden >= 4 && f.hidden <= 1024 && f.hidden.is_multiple_of(4), "training setting field.hidden must be a multiple of 4 in 4..=1024 (is {})", f.hidden);
        if let Some(d) = &f.deform {
            anyhow::ensure!(!f.time_resolutions.is_empty(), "training setting field.deform needs a dynamic scene (time planes)");
            d.validate().map_err(|e| anyhow::anyhow!("training setting field.deform: {e}"))?;
        }
        Ok(())
    }
}

/// Default weight of the temporal-smoothness prior on dynamic scenes (K-Planes, D-NeRF scenes).
pub const TIME_SMOOTH: f32 = 0.1;
/// Default weight of the sparse-transients prior on dynamic scenes (K-Planes, D-NeRF scenes).
pub const TIME_SPARSE: f32 = 1e-4;

/// Training views a time cell of the finest time planes should hold (see
/// [`finest_time_resolution`]).
pub const VIEWS_PER_TIME_CELL: usize = 3;

/// The finest time-plane resolution for a dynamic dataset: the static rule's principle
/// applied to time. A cell is no finer than the data constrain it: no finer than the
/// distinct training times (a cell between two instants is seen by no camera), and holding
/// about [`VIEWS_PER_TIME_CELL`] training views, so that what a time cell stores is pinned by
/// cameras from several directions rather than fitted to one or two of them (a monocular
/// sequence has one camera per instant). Clamped to 4..=64.
pub fn finest_time_resolution(data: &Dataset) -> u32 {
    let mut times: Vec<f32> = data.train.iter().filter_map(|v| v.time).collect();
    times.sort_by(f32::total_cmp);
    times.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    let cells = (data.train.len() / VIEWS_PER_TIME_CELL).min(times.len());
    (cells as u32).clamp(4, 64)
}

/// Time resolutions of the four levels from the finest: /4, /2, /1, /1 (at least 4).
pub fn time_levels(finest: u32) -> Vec<u32> {
    vec![(finest / 4).max(4), (finest / 2).max(4), finest.max(2), finest.max(2)]
}

/// Most rays a training pixel may take (a 4x4 grid).
pub use snerf_geometry::silhouette::MAX_PIXEL_RAYS;

/// One bit per pixel of `views` (in order, row-major): the pixel's 3x3 neighbourhood holds
/// both covered and uncovered alpha, i.e. it lies on a silhouette. There the colour is the
/// coverage-weighted mean over the pixel's square (what a supersampling renderer or a camera
/// sensor records), which no single ray through the centre of a sharp edge can return.
pub fn silhouette_mask(views: &[View]) -> Vec<u64> {
    let total: usize = views.iter().map(|v| (v.intrinsics.width * v.intrinsics.height) as usize).sum();
    let mut bits = vec![0u64; total.div_ceil(64)];
    let mut base = 0usize;
    for v in views {
        let (w, h) = (v.intrinsics.width as usize, v.intrinsics.height as usize);
        for y in 0..h {
            for x in 0..w {
                let (lo, hi) = snerf_geometry::silhouette::min_max_3x3(w, h, x, y, |i| v.rgba[i * 4 + 3]);
                if lo < 255 && hi > 0 {
                    let p = base + y * w + x;
                    bits[p / 64] |= 1 << (p % 64);
                }
            }
        }
        base += w * h;
    }
    bits
}

/// The training views' median pixel footprint at the scene's centre (world units).
pub fn train_pixel_footprint(data: &Dataset) -> Option<f32> {
    views_pixel_footprint(&data.train, SceneSpace::from_dataset(data).ok()?.frame.center)
}

/// The median pixel footprint of `views` at the scene's centre `centre` (world units).
pub fn views_pixel_footprint(views: &[View], centre: [f32; 3]) -> Option<f32> {
    snerf_geometry::silhouette::median_footprint(views.iter().map(|v| (snerf_geometry::camera::position(&v.c2w), v.intrinsics.fx)), centre)
}

/// How many pixels the scene's box spans across in the median training view: the finest detail
/// the views sample. None where it does not apply (forward-facing NDC spans the image; an
/// unbounded scene's inner cube is seen from inside) or cannot be told.
pub fn pixels_across_box(data: &Dataset) -> Option<f32> {
    if data.kind != SceneKind::Object {
        return None;
    }
    let space = SceneSpace::from_dataset(data).ok()?;
    let side = 2.0 / space.frame.scale;
    let mut px: Vec<f32> = data
        .train
        .iter()
        .map(|v| {
            let d = crate::space::norm(crate::space::sub(crate::space::position(v), space.frame.center));
            side * v.intrinsics.fx.max(v.intrinsics.fy) / d
        })
        .filter(|p| p.is_finite() && *p > 0.0)
        .collect();
    if px.is_empty() {
        return None;
    }
    px.sort_by(f32::total_cmp);
    Some(px[px.len() / 2])
}

/// One point of the error-against-time curve.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CurvePoint {
    pub step: u64,
    /// Training time only (evaluations excluded).
    pub train_seconds: f64,
    /// PSNR on a fixed sample of the training views' pixels, measured exactly as
    /// `test_psnr` is on the held-out views, so the two differ only by what was seen in
    /// training. (Runs from before it was measured hold the batch loss's PSNR here.)
    pub train_psnr: f64,
    pub test_psnr: Option<f64>,
    /// The PSNR of the last step's batch loss: random pixels under random backgrounds with
    /// jittered samples, before the step's update. It reads about 3 dB above `train_psnr`
    /// on objects, so it is no measure of the train−test gap.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub loss_psnr: Option<f64>,
    pub samples_per_second: f64,
}

pub struct Trainer {
    pub cfg: TrainConfig,
    pub model: Model,
    pub adam: Adam,
    pub step: u64,
    pub train_seconds: f64,
    pub samples_seen: u64,
    pub curve: Vec<CurvePoint>,
    pub pool: WorkspacePool,
    /// Rays in the next step (adapted to `batch_samples`).
    pub rays_next: usize,
    rng: Rng,
    views: Vec<View>,
    has_alpha: bool,
    /// Cumulative pixel counts, for uniform sampling of pixels across views.
    cum_pixels: Vec<usize>,
    /// One bit per training pixel (indexed like `cum_pixels`): on a silhouette (see
    /// [`silhouette_mask`]), where the pixel is rendered as the mean of `pixel_rays` rays.
    edge: Vec<u64>,
    /// Per-photo colour transforms (`cfg.appearance` > 0) and the photo of each ray of a step.
    pub appearance: Option<Appearance>,
    task_images: Vec<u32>,
    /// What free-space carving did when this run started (`cfg.sparse_carving` and a dataset
    /// with sparse points).
    pub sparse_carve: Option<crate::free_space::CarveStats>,
}

/// Statistics of one step.
#[derive(Clone, Copy, Debug, Default)]
pub struct StepStats {
    pub loss: f64,
    pub samples: u64,
    pub seconds: f64,
    /// Wall time of the parallel ray work, of the optimizer, and per-phase thread time.
    pub chunk_seconds: f64,
    pub adam_seconds: f64,
    pub phase_ns: [u64; 6],
}

impl StepStats {
    pub fn psnr(&self) -> f64 {
        mse_to_psnr(self.loss)
    }
}

/// True when any training image has transparent pixels (a bounded object on no background).
pub fn views_have_alpha(views: &[View]) -> bool {
    views.iter().any(|v| v.rgba.chunks_exact(4).any(|p| p[3] < 255))
}

impl Trainer {
    pub fn new(data: &Dataset, cfg: TrainConfig) -> Result<Trainer> {
        let (pixel_rays, pixel_footprint) = (cfg.pixel_rays, cfg.pixel_footprint);
        let space = SceneSpace::from_dataset(data)?;
        let field = Field::new(cfg.field.clone(), cfg.seed)?;
        let occ = Occupancy::new(cfg.occupancy_res, cfg.steps_per_diagonal);
        let adam = Adam::new(field.params.len());
        let mut t = Trainer::from_parts(data, cfg, Model { space, field, occ, pixel_rays, pixel_footprint }, adam)?;
        if t.model.space.kind == SceneKind::Object && t.has_alpha {
            t.carve();
        }
        if t.cfg.sparse_carving {
            t.sparse_carve = t.carve_free_space(data)?;
        }
        Ok(t)
    }

    /// Free-space carving from the dataset's sparse points (none: nothing happens).
    fn carve_free_space(&mut self, data: &Dataset) -> Result<Option<crate::free_space::CarveStats>> {
        let Some(tracks) = snerf_data::sparse_tracks(data)? else { return Ok(None) };
        let cameras: Vec<[f32; 3]> = self.views.iter().map(|v| v.origin()).collect();
        let m = &mut self.model;
        Ok(Some(crate::free_space::carve(&mut m.occ, &m.space, &cameras, &tracks.points, crate::free_space::CarveRules::default())))
    }

    /// Rebuild a trainer around saved state (resume) and the dataset's training views.
    pub fn from_parts(data: &Dataset, cfg: TrainConfig, mut model: Model, adam: Adam) -> Result<Trainer> {
        anyhow::ensure!(!data.train.is_empty(), "{}: no training views", data.root.display());
        cfg.validate()?;
        model.pixel_rays = cfg.pixel_rays; // the model renders as it is trained
        let views = data.train.clone();
        let mut cum = Vec::with_capacity(views.len());
        let mut total = 0usize;
        for v in &views {
            total += (v.intrinsics.width * v.intrinsics.height) as usize;
            cum.push(total);
        }
        let has_alpha = views_have_alpha(&views);
        let pool = WorkspacePool::new(model.field.params.len());
        let edge = silhouette_mask(&views);
        let appearance = (cfg.appearance > 0.0).then(|| Appearance::new(view_names(&views), cfg.appearance));
        Ok(Trainer {
            rng: Rng::new(cfg.seed ^ 0x5eed),
            rays_next: cfg.batch_rays.max(1),
            cfg,
            model,
            adam,
            step: 0,
            train_seconds: 0.0,
            samples_seen: 0,
            curve: Vec::new(),
            pool,
            views,
            has_alpha,
            cum_pixels: cum,
            edge,
            appearance,
            task_images: Vec::new(),
            sparse_carve: None,
        })
    }

    pub fn has_alpha(&self) -> bool {
        self.has_alpha
    }

    /// The views it trains on (the dataset's, or targets given by [`Trainer::set_views`]).
    pub fn views(&self) -> &[View] {
        &self.views
    }

    /// Replace the training targets (same cameras or new ones), e.g. with stylized renders:
    /// the model and optimizer state carry on.
    pub fn set_views(&mut self, views: Vec<View>) -> Result<()> {
        anyhow::ensure!(!views.is_empty(), "no training views");
        let mut total = 0usize;
        self.cum_pixels = views
            .iter()
            .map(|v| {
                total += (v.intrinsics.width * v.intrinsics.height) as usize;
                total
            })
            .collect();
        self.has_alpha = views_have_alpha(&views);
        self.edge = silhouette_mask(&views);
        self.views = views;
        self.appearance = None; // new targets are not the photos the transforms were fitted to
        Ok(())
    }

    /// Silhouette carving: a cell whose projection falls on transparent background (alpha 0
    /// in a window covering the cell) in a training view is empty when that view was taken.
    /// A static scene's cell is then empty for good. A dynamic scene's cell is empty for good
    /// only if such views come at least every [`Trainer::carve_time_gap`] over the whole
    /// animation: the space-time visual hull of the views within that time, whose union over
    /// time holds every place the object goes. A limb that holds a cell for longer than that
    /// is seen there by every view of those times, which leaves a longer gap. (Carving a cell
    /// because one view at another time saw it empty carved every limb out of the poses it
    /// swings to.)
    pub fn carve(&mut self) {
        let occ = &self.model.occ;
        let space = &self.model.space;
        let res = occ.res;
        let cell_world = 2.0 / res as f32 / space.frame.scale * 0.87; // half-diagonal of a cell
        let mut views: Vec<&View> = self.views.iter().collect();
        let gap = self.carve_time_gap();
        // in time order, so a cell's proofs arrive in time order
        views.sort_by(|a, b| a.time.unwrap_or(0.0).total_cmp(&b.time.unwrap_or(0.0)));
        let (t0, t1) = (views[0].time.unwrap_or(0.0), views[views.len() - 1].time.unwrap_or(0.0));
        let allowed: Vec<bool> = (0..res * res * res)
            .into_par_iter()
            .map(|i| {
                let pw = space.to_world(space.grid_to_march(occ.cell_center(i)));
                let mut last_empty = t0;
                for v in &views {
                    if !matches!(cell_seen(v, &pw, cell_world), Seen::Empty) {
                        continue;
                    }
                    let Some(gap) = gap else { return false };
                    let t = v.time.unwrap_or(0.0);
                    if t - last_empty > gap {
                        return true;
                    }
                    last_empty = t;
                }
                // static: never seen empty; dynamic: a view saw it empty often enough
                gap.is_none_or(|gap| t1 - last_empty > gap)
            })
            .collect();
        self.model.occ.allowed = allowed;
        self.model.occ.refresh_bits();
    }

    /// The longest time a dynamic scene's cell may go without a view that saw it empty and
    /// still be carved: one cell of the finest time planes, the shortest change the field
    /// can hold. `None` for a static scene.
    fn carve_time_gap(&self) -> Option<f32> {
        let finest = self.cfg.field.time_resolutions.iter().copied().max()?;
        let times = self.views.iter().filter_map(|v| v.time);
        let (lo, hi) = times.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), t| (lo.min(t), hi.max(t)));
        Some(if hi > lo { (hi - lo) / (finest.max(2) - 1) as f32 } else { 0.0 })
    }

    /// About `n` rays for random pixels across all training views, and the pixel groups
    /// they make: a pixel on a silhouette gets `pixel_rays` rays (stratified over its
    /// square), any other one ray through its centre.
    fn sample_tasks(&mut self, n: usize) -> (Vec<RayTask>, Vec<u16>) {
        let total = *self.cum_pixels.last().unwrap();
        let side = (self.cfg.pixel_rays as f32).sqrt().round() as usize;
        let mut tasks = Vec::with_capacity(n + side * side);
        let mut groups = Vec::with_capacity(n);
        self.task_images.clear();
        while tasks.len() < n {
            let p = self.rng.below(total);
            let vi = self.cum_pixels.partition_point(|&c| c <= p);
            let v = &self.views[vi];
            let local = p - if vi == 0 { 0 } else { self.cum_pixels[vi - 1] };
            let w = v.intrinsics.width as usize;
            let (x, y) = (local % w, local / w);
            let px = &v.rgba[local * 4..local * 4 + 4];
            let a = px[3] as f32 / 255.0;
            let bg = if self.has_alpha {
                [self.rng.uniform(), self.rng.uniform(), self.rng.uniform()]
            } else {
                [0.0; 3]
            };
            let target = [0, 1, 2].map(|c| px[c] as f32 / 255.0 * a + bg[c] * (1.0 - a));
            if side < 2 || self.edge[p / 64] >> (p % 64) & 1 == 0 {
                let (ox, oy) = if self.cfg.area_rays { (self.rng.uniform(), self.rng.uniform()) } else { (0.5, 0.5) };
                let ray = self.model.space.ray(&v.c2w, &v.intrinsics, x as f32 + ox, y as f32 + oy, v.time);
                tasks.push(RayTask { ray, bg, target, jitter: self.rng.uniform() });
                self.task_images.push(vi as u32);
                groups.push(1);
                continue;
            }
            for j in 0..side * side {
                let sx = ((j % side) as f32 + self.rng.uniform()) / side as f32;
                let sy = ((j / side) as f32 + self.rng.uniform()) / side as f32;
                let ray = self.model.space.ray(&v.c2w, &v.intrinsics, x as f32 + sx, y as f32 + sy, v.time);
                tasks.push(RayTask { ray, bg, target, jitter: self.rng.uniform() });
                self.task_images.push(vi as u32);
            }
            groups.push((side * side) as u16);
        }
        (tasks, groups)
    }

    /// Learning-rate multiplier at `progress` in [0,1] of the budget (exponential decay).
    pub fn lr_scale(&self, progress: f64) -> f32 {
        let warm = ((self.step + 1) as f32 / 16.0).min(1.0);
        warm * self.cfg.lr_final.powf(progress.clamp(0.0, 1.0) as f32)
    }

    /// One optimization step.
    pub fn step(&mut self, progress: f64) -> StepStats {
        let t0 = Instant::now();
        let (tasks, groups) = self.sample_tasks(self.rays_next);
        let loss_scale = 1.0 / (3.0 * groups.len() as f32);
        let model = &self.model;
        let pool = &self.pool;
        let distortion = self.cfg.distortion;
        let transforms = self.appearance.as_ref().map_or(&[][..], |a| &a.transforms[..]);
        let task_images = &self.task_images;
        let backward = if self.cfg.freeze_geometry { Backward::OutputLayer } else { Backward::Full };
        // chunks of about `chunk_rays` rays that never split a pixel's rays
        let mut chunks = Vec::new();
        let (mut start, mut g0) = (0usize, 0usize);
        let mut t = 0usize;
        for (g, &size) in groups.iter().enumerate() {
            t += size as usize;
            if t - start >= self.cfg.chunk_rays || g + 1 == groups.len() {
                chunks.push((start..t, g0..g + 1));
                (start, g0) = (t, g + 1);
            }
        }
        // Chunk k adds its gradients into workspace k mod n, in chunk order, and the
        // workspaces are added in slot order (by Adam) and their statistics here: float
        // addition is not associative, so letting the thread that happened to run a chunk
        // choose its buffer made two runs of the same command differ in the last bits, which
        // Adam's normalized steps grew into visibly different fields (docs/stylize-notebook.md §5k). The
        // fixed split gives up work stealing: a thread that draws the cheaper chunks waits
        // at the end of the step, about 7% of throughput on 2 cores (same section). More
        // workspaces than threads, stolen whole, did not measurably win that back and
        // cost the optimizer a pass over every extra buffer.
        let n = pool.len();
        let stats = (0..n)
            .into_par_iter()
            .map(|slot| {
                pool.with_slot(slot, |ws| {
                    ws.appearance.begin(transforms);
                    chunks.iter().skip(slot).step_by(n).fold(ChunkStats::default(), |acc, (tr, gr)| {
                        ws.appearance.set_images(&task_images[tr.clone()]);
                        acc.merge(train_chunk_with(&model.field, &model.space, &model.occ, &tasks[tr.clone()], ws, loss_scale, distortion, &groups[gr.clone()], backward))
                    })
                })
            })
            .collect::<Vec<_>>()
            .into_iter()
            .fold(ChunkStats::default(), ChunkStats::merge);
        let t_chunks = t0.elapsed().as_secs_f64();
        let s = self.lr_scale(progress);
        let (mut grads, mut flags) = self.pool.grads();
        if self.cfg.tv > 0.0 {
            self.model.field.tv_backward(self.cfg.tv, grads[0], flags[0]);
        }
        if self.cfg.time_smooth > 0.0 || self.cfg.time_sparse > 0.0 {
            self.model.field.time_priors_backward(self.cfg.time_smooth, self.cfg.time_sparse, grads[0], flags[0]);
        }
        let params = &mut self.model.field.params;
        let plane_end = self.model.field.layout.plane_end;
        self.adam.begin_step();
        // A zero learning rate leaves a parameter exactly where it is, while the optimizer
        // still consumes (and clears) its gradient buffers.
        let l = &self.model.field.layout;
        let total = params.len();
        let lr = self.cfg.lr_mlp * s;
        let (sigma_row_end, b2, view) = (l.w2 + l.hidden, l.b2, l.view.w1..l.view.end);
        let geometry = if self.cfg.freeze_geometry { 0.0 } else { 1.0 };
        let view_lr = if self.cfg.freeze_view { 0.0 } else { lr };
        self.adam.update_cells(params, &mut grads, &mut flags, crate::field::C, self.cfg.lr_planes * s * geometry);
        // decoder: shared hidden layer + density row | colour rows | density bias | colour biases
        self.adam.update_dense(params, &mut grads, plane_end..sigma_row_end, lr * geometry);
        self.adam.update_dense(params, &mut grads, sigma_row_end..b2, lr);
        self.adam.update_dense(params, &mut grads, b2..b2 + 1, lr * geometry);
        self.adam.update_dense(params, &mut grads, b2 + 1..view.start, lr);
        self.adam.update_dense(params, &mut grads, view.start..view.end, view_lr);
        // the deformation (what moves the geometry), then the colour head (colour only)
        let deform_end = l.colour.map_or(total, |c| c.w1);
        self.adam.update_dense(params, &mut grads, view.end..deform_end, lr * geometry);
        self.adam.update_dense(params, &mut grads, deform_end..total, lr);
        if let Some(a) = &mut self.appearance {
            let slots: Vec<_> = self.pool.slots.iter().map(|w| w.lock().unwrap_or_else(|e| e.into_inner())).collect();
            a.step(slots.iter().map(|w| w.appearance.grad()), crate::appearance::LR * s);
        }
        let t_adam = t0.elapsed().as_secs_f64() - t_chunks;
        self.step += 1;
        // a frozen geometry's density does not move: its occupancy stays as it is
        let refresh = self.step.is_multiple_of(self.cfg.occupancy_every) || (self.step < 64 && self.step.is_multiple_of(4));
        if refresh && !self.cfg.freeze_geometry {
            self.update_occupancy();
        }
        let secs = t0.elapsed().as_secs_f64();
        self.train_seconds += secs;
        self.samples_seen += stats.samples;
        if self.cfg.batch_samples > 0 {
            let per_ray = stats.samples as f64 / stats.rays.max(1) as f64;
            let want = (self.cfg.batch_samples as f64 / per_ray.max(1.0)) as usize;
            self.rays_next = want.clamp(256, self.cfg.max_batch_rays.max(256));
        }
        StepStats {
            loss: stats.loss_sum / (3.0 * stats.pixels.max(1) as f64),
            samples: stats.samples,
            seconds: secs,
            chunk_seconds: t_chunks,
            adam_seconds: t_adam,
            phase_ns: stats.ns,
        }
    }

    /// Re-measure density in a rotating quarter of the cells (all of them while warming up)
    /// at jittered points and random times; early on the measurement replaces the stored
    /// value so free space is pruned within the first few dozen steps, later it is a decayed
    /// running max so thin surfaces are not lost to one unlucky sample.
    pub fn update_occupancy(&mut self) {
        let warm = self.step < 256;
        let stride: usize = if warm { 1 } else { 4 };
        let phase = ((self.step / self.cfg.occupancy_every) as usize) % stride;
        let occ = &self.model.occ;
        let res = occ.res;
        let n = res * res * res;
        let cell = 2.0 / res as f32;
        let cells: Vec<usize> = (phase..n).step_by(stride).filter(|&i| occ.allowed[i]).collect();
        let mut rng = Rng::new(self.rng.next_u64());
        let mut points = Vec::with_capacity(cells.len());
        let mut times = Vec::with_capacity(cells.len());
        for &i in &cells {
            let c = occ.cell_center(i);
            points.push([0, 1, 2].map(|a| c[a] + (rng.uniform() - 0.5) * cell));
            times.push(rng.uniform());
        }
        let mut sigma = vec![0.0f32; cells.len()];
        let field = &self.model.field;
        let pool = &self.pool;
        const B: usize = 4096;
        sigma.par_chunks_mut(B).enumerate().for_each(|(bi, out)| {
            let lo = bi * B;
            let hi = lo + out.len();
            pool.with(|ws| density_batch(field, &points[lo..hi], &times[lo..hi], ws, out));
        });
        let space = &self.model.space;
        let occ = &mut self.model.occ;
        for (j, &i) in cells.iter().enumerate() {
            let d = sigma[j] * occ.typical_delta(space, &points[j]);
            let d = if d.is_finite() { d } else { 0.0 };
            occ.depth[i] = if warm { d } else { (occ.depth[i] * 0.9).max(d) };
        }
        occ.refresh_bits();
        // Early on, the loss of a mostly transparent scene can push the density down
        // everywhere before the object forms; a grid that marks every cell empty then takes
        // no samples, and no gradient ever brings the density back. Re-open the cells that
        // carving kept, so the field goes on learning where the object is.
        if occ.occupied_fraction() == 0.0 && occ.allowed.iter().any(|&a| a) {
            occ.depth.fill(f32::MAX);
            occ.refresh_bits();
        }
    }
}

/// Each view's file name (for the per-photo records).
fn view_names(views: &[View]) -> Vec<String> {
    views.iter().map(|v| v.path.file_name().map_or_else(|| v.path.display().to_string(), |n| n.to_string_lossy().into_owned())).collect()
}

/// What a view shows of an occupancy cell.
enum Seen {
    /// Behind the camera, or its window not wholly inside the image.
    NotInFrame,
    /// Some pixel of the window covering the cell is not transparent.
    Covered,
    /// The whole window is transparent: the cell was empty when the view was taken.
    Empty,
}

/// What view `v` shows of the cell centred at world point `pw` (half-diagonal `cell_world`).
fn cell_seen(v: &View, pw: &[f32; 3], cell_world: f32) -> Seen {
    let k = &v.intrinsics;
    let c = &v.c2w;
    let rel = [pw[0] - c[0][3], pw[1] - c[1][3], pw[2] - c[2][3]];
    // camera coordinates = R^T rel
    let xc = c[0][0] * rel[0] + c[1][0] * rel[1] + c[2][0] * rel[2];
    let yc = c[0][1] * rel[0] + c[1][1] * rel[1] + c[2][1] * rel[2];
    let zc = c[0][2] * rel[0] + c[1][2] * rel[1] + c[2][2] * rel[2];
    if zc > -1e-3 {
        return Seen::NotInFrame;
    }
    let px = k.fx * xc / -zc + k.cx;
    let py = -k.fy * yc / -zc + k.cy;
    let r = (k.fx * cell_world / -zc + 1.0).ceil() as i64;
    let (w, h) = (k.width as i64, k.height as i64);
    let (x0, y0) = (px.floor() as i64, py.floor() as i64);
    // The window must lie fully inside the image to prove emptiness.
    if x0 - r < 0 || y0 - r < 0 || x0 + r >= w || y0 + r >= h {
        return Seen::NotInFrame;
    }
    let empty = (y0 - r..=y0 + r).all(|y| (x0 - r..=x0 + r).all(|x| v.rgba[((y * w + x) * 4 + 3) as usize] == 0));
    if empty {
        Seen::Empty
    } else {
        Seen::Covered
    }
}
