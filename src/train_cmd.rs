//! `snerf data`, `snerf train`, `snerf eval` and `snerf turntable`: a dataset described, a
//! field trained on it, scored on held-out views and shown on an orbit (the work is in
//! snerf-trainer; a run directory's layout is `snerf_trainer::run_dir::RunDir`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_files::guard::{check_output, Input};
use snerf_report::live::{LiveReport, RUN_REPORT_DIR};
use snerf_trainer::data::{self, Dataset};
use snerf_trainer::run_dir::RunDir;
use snerf_trainer::{checkpoint, eval, run, train};

use crate::args::{bar, guard_run_output, peak_rss_mb, pj, DataOpts};

#[derive(Args, Debug)]
pub struct DataArgs {
    pub data: PathBuf,
    #[command(flatten)]
    pub opts: DataOpts,
}

#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Dataset: a directory or transforms.json (Blender/nerfstudio), LLFF or COLMAP.
    pub data: PathBuf,
    /// Run directory (checkpoint, metrics.json, config.json).
    #[arg(long)]
    pub out: PathBuf,
    /// Stop after this many steps in total (a resumed run counts its earlier steps).
    #[arg(long, value_parser = crate::args::int_in::<u64>(1, 1000000000000, ""))]
    pub steps: Option<u64>,
    /// Stop after this many minutes of training in total (default 5 when --steps is absent).
    #[arg(long, value_parser = crate::args::positive)]
    pub minutes: Option<f64>,
    /// Continue the run in --out from its last checkpoint.
    #[arg(long)]
    pub resume: bool,
    /// Fixed rays per step (default: adapt the ray count to --batch-samples).
    #[arg(long, value_parser = crate::args::int_in::<usize>(64, 1048576, ""))]
    pub batch: Option<usize>,
    /// Samples per step the ray count adapts to.
    #[arg(long, value_parser = crate::args::int_in::<usize>(1024, 16777216, ""))]
    pub batch_samples: Option<usize>,
    /// Held-out pixels (random, fixed) scored for the PSNR-vs-time curve in metrics.json.
    #[arg(long, default_value_t = 16384, value_parser = crate::args::int_in::<usize>(0, 16777216, ""))]
    pub curve_pixels: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Learning rate of the feature planes (Adam).
    #[arg(long, value_parser = crate::args::positive_f32)]
    pub lr_planes: Option<f32>,
    /// Learning rate of the decoder and view MLP (Adam).
    #[arg(long, value_parser = crate::args::positive_f32)]
    pub lr_mlp: Option<f32>,
    /// Learning rate at the end of the budget, as a fraction of the starting rate (the rate
    /// decays exponentially in between; default 0.1).
    #[arg(long, value_parser = crate::args::positive_f32)]
    pub lr_final: Option<f32>,
    /// Weight of the distortion loss (default 0.01 for forward/unbounded scenes, 0 for objects).
    #[arg(long, value_parser = crate::args::non_negative_f32)]
    pub distortion: Option<f32>,
    /// Weight of the total-variation loss on the feature planes (default 1e-3 for static objects, 0 otherwise).
    #[arg(long, value_parser = crate::args::non_negative_f32)]
    pub tv: Option<f32>,
    /// Finest plane resolution (levels are /8, /4, /2, /1 of it).
    #[arg(long, value_parser = crate::args::int_in::<u32>(16, 4096, ""))]
    pub resolution: Option<u32>,
    /// Finest time-plane resolution of a dynamic scene (levels are /4, /2, /1, /1 of it;
    /// default: from the data, about 3 training views per time cell, at most the distinct times).
    #[arg(long, value_parser = crate::args::int_in::<u32>(4, 1024, ""))]
    pub time_resolution: Option<u32>,
    /// Weight of the temporal-smoothness prior on the time planes (mean squared second
    /// difference along time, as in K-Planes; default 0.1 for dynamic scenes).
    #[arg(long, value_parser = crate::args::non_negative_f32)]
    pub time_smooth: Option<f32>,
    /// Weight of the sparse-transients prior on the time planes (mean |1 - value|, as in
    /// K-Planes; default 1e-4 for dynamic scenes).
    #[arg(long, value_parser = crate::args::non_negative_f32)]
    pub time_sparse: Option<f32>,
    /// Dynamic scenes: add a deformation, a canonical shape and how it moves (a low-rank
    /// motion basis, smooth in space and slow in time; the time planes stay for appearance
    /// changes). Off by default.
    #[arg(long)]
    pub deform: bool,
    /// The deformation's basis grid: cells per axis over the scene's box (implies --deform;
    /// default 16).
    #[arg(long, value_parser = crate::args::int_in::<u32>(2, 128, ""))]
    pub deform_grid: Option<u32>,
    /// The deformation's motion modes, independent motions of the body (implies --deform;
    /// default 8).
    #[arg(long, value_parser = crate::args::int_in::<u32>(1, 32, ""))]
    pub deform_modes: Option<u32>,
    /// The deformation's knots over the animation, where each mode's coefficient is set
    /// (implies --deform; default half the finest time-plane resolution, at least 4).
    #[arg(long, value_parser = crate::args::int_in::<u32>(2, 1024, ""))]
    pub deform_knots: Option<u32>,
    /// Per-photo appearance: learn a 3×4 affine colour transform per training photo
    /// (exposure, white balance) with the field, pulled toward identity with this weight; 0 =
    /// off (the default). Held-out photos and every render use the field's own colours.
    #[arg(long, value_parser = crate::args::non_negative_f32)]
    pub appearance: Option<f32>,
    /// Rays per silhouette pixel: 1, 4, 9 or 16 (default 4 for objects, static or animated, 1 otherwise).
    /// A pixel whose neighbourhood is partly covered is trained and rendered as the mean of
    /// rays spread over its square, as the views were rendered; 1 is one ray through its centre.
    #[arg(long, value_parser = crate::args::int_in::<usize>(1, 16, ""))]
    pub pixel_rays: Option<usize>,
    /// Free-space carving for COLMAP captures (`snerf capture` output): each sparse point's
    /// observations are lines of sight, and occupancy cells that several of them cross
    /// (stopping 10% short of the point, never next to a point) are marked empty for good, so
    /// the field cannot grow fog there and rendering skips them. Only COLMAP models with a
    /// points3D.bin beside the images.bin/.txt the poses come from have the points; every
    /// other dataset is unaffected. Default: on
    /// for COLMAP datasets (fewer samples per pixel and higher held-out PSNR on both ViSP
    /// captures, BENCH.md §2d); `--sparse-carving false` turns it off.
    #[arg(long, value_name = "BOOL", num_args = 0..=1, default_missing_value = "true")]
    pub sparse_carving: Option<bool>,
    /// Write a checkpoint at least every this many seconds of training (a killed run loses
    /// at most this much).
    #[arg(long, default_value_t = 30.0, value_parser = crate::args::non_negative)]
    pub checkpoint_every: f64,
    #[command(flatten)]
    pub opts: DataOpts,
}

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Run directory written by `snerf train`.
    pub run: PathBuf,
    /// The dataset it was trained on.
    pub data: PathBuf,
    /// Where to write side-by-side images (default RUN/eval).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Which split to score: test, val or train.
    #[arg(long, default_value = "test")]
    pub split: String,
    #[command(flatten)]
    pub opts: DataOpts,
}

#[derive(Args, Debug)]
pub struct TurntableArgs {
    pub run: PathBuf,
    pub data: PathBuf,
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 36, value_parser = crate::args::int_in::<usize>(1, 3600, ""))]
    pub frames: usize,
    #[command(flatten)]
    pub opts: DataOpts,
}

/// `snerf data`: the dataset's summary.
pub fn data_cmd(a: &DataArgs, quiet: bool) -> Result<Value> {
    let d = a.opts.load(&a.data)?;
    let s = data::summary(&d);
    if !quiet {
        eprintln!("{}", serde_json::to_string_pretty(&s)?);
    }
    Ok(s)
}

pub fn train_cmd(a: &TrainArgs, quiet: bool) -> Result<Value> {
    let data = a.opts.load(&a.data)?;
    check_output("--out", &a.out, &[Input::Tree(&data.root), Input::Tree(&a.data)])?;
    let mut cfg = train::TrainConfig::for_dataset(&data);
    cfg.seed = a.seed;
    if let Some(b) = a.batch {
        cfg.batch_rays = b;
        cfg.batch_samples = 0;
    }
    if let Some(b) = a.batch_samples {
        cfg.batch_samples = b;
    }
    if let Some(lr) = a.lr_planes {
        cfg.lr_planes = lr;
    }
    if let Some(lr) = a.lr_mlp {
        cfg.lr_mlp = lr;
    }
    if let Some(f) = a.lr_final {
        cfg.lr_final = f;
    }
    if let Some(d) = a.distortion {
        cfg.distortion = d;
    }
    if let Some(t) = a.tv {
        cfg.tv = t;
    }
    if let Some(r) = a.resolution {
        cfg.field.resolutions = vec![r / 8, r / 4, r / 2, r].into_iter().map(|x| x.max(2)).collect();
    }
    if let Some(k) = a.pixel_rays {
        cfg.pixel_rays = k;
    }
    if let Some(w) = a.appearance {
        cfg.appearance = w;
    }
    if let Some(c) = a.sparse_carving {
        cfg.sparse_carving = c;
    }
    if let Some(t) = a.time_resolution {
        anyhow::ensure!(cfg.field.dynamic(), "--time-resolution applies to dynamic scenes only; {} is static", a.data.display());
        cfg.field.time_resolutions = train::time_levels(t);
    }
    if a.deform || a.deform_grid.is_some() || a.deform_modes.is_some() || a.deform_knots.is_some() {
        cfg.enable_deform().with_context(|| format!("--deform: {}", a.data.display()))?;
        let d = cfg.field.deform.as_mut().expect("enable_deform sets it");
        d.resolution = a.deform_grid.unwrap_or(d.resolution);
        d.modes = a.deform_modes.unwrap_or(d.modes);
        d.time_resolution = a.deform_knots.unwrap_or(d.time_resolution);
    }
    if let Some(w) = a.time_smooth {
        cfg.time_smooth = w;
    }
    if let Some(w) = a.time_sparse {
        cfg.time_sparse = w;
    }
    let seconds = match (a.steps, a.minutes) {
        (None, None) => Some(300.0),
        (_, m) => m.map(|m| m * 60.0),
    };
    let opts = run::RunOptions {
        dir: a.out.clone(),
        steps: a.steps,
        seconds,
        curve_pixels: a.curve_pixels,
        checkpoint_every: a.checkpoint_every,
    };
    let given = a.given_settings();
    train_run_checked(&data, cfg, &opts, a.resume, quiet, &given)
}

impl TrainArgs {
    /// The training settings this command line sets explicitly: (flag, where the setting
    /// lives in the config's JSON form), so a resumed run can refuse ones that differ.
    fn given_settings(&self) -> Vec<(&'static str, &'static str)> {
        [
            ("--resolution", "/field/resolutions", self.resolution.is_some()),
            ("--lr-planes", "/lr_planes", self.lr_planes.is_some()),
            ("--lr-mlp", "/lr_mlp", self.lr_mlp.is_some()),
            ("--lr-final", "/lr_final", self.lr_final.is_some()),
            ("--distortion", "/distortion", self.distortion.is_some()),
            ("--tv", "/tv", self.tv.is_some()),
            ("--pixel-rays", "/pixel_rays", self.pixel_rays.is_some()),
            ("--appearance", "/appearance", self.appearance.is_some()),
            ("--sparse-carving", "/sparse_carving", self.sparse_carving.is_some()),
            ("--time-resolution", "/field/time_resolutions", self.time_resolution.is_some()),
            ("--time-smooth", "/time_smooth", self.time_smooth.is_some()),
            ("--time-sparse", "/time_sparse", self.time_sparse.is_some()),
            ("--deform", "/field/deform", self.deform),
            ("--deform-grid", "/field/deform", self.deform_grid.is_some()),
            ("--deform-modes", "/field/deform", self.deform_modes.is_some()),
            ("--deform-knots", "/field/deform", self.deform_knots.is_some()),
            ("--batch", "/batch_rays", self.batch.is_some()),
            ("--batch-samples", "/batch_samples", self.batch_samples.is_some()),
            ("--seed", "/seed", self.seed != 0),
        ]
        .into_iter()
        .filter(|g| g.2)
        .map(|(flag, ptr, _)| (flag, ptr))
        .collect()
    }
}

/// `train_run`, refusing a resume whose explicit settings differ from the run's own (a
/// resumed run keeps the settings it was started with; ignoring a flag silently would lie).
pub fn train_run_checked(
    data: &Dataset,
    cfg: train::TrainConfig,
    opts: &run::RunOptions,
    resume: bool,
    quiet: bool,
    given: &[(&'static str, &'static str)],
) -> Result<Value> {
    if resume && !given.is_empty() {
        if let Ok(c) = checkpoint::load(&RunDir::new(&opts.dir).checkpoint()) {
            let theirs = serde_json::to_value(&c.cfg)?;
            let ours = serde_json::to_value(&cfg)?;
            for (flag, ptr) in given {
                let (a, b) = (ours.pointer(ptr), theirs.pointer(ptr));
                if a != b {
                    bail!(
                        "{flag} asks for {} but the run in {} was trained with {}; a resumed run keeps its \
                         settings (drop {flag}, or start a new run with another --out)",
                        a.cloned().unwrap_or(Value::Null),
                        opts.dir.display(),
                        b.cloned().unwrap_or(Value::Null)
                    );
                }
            }
        }
    }
    train_run(data, cfg, opts, resume, quiet)
}

/// Train (or resume) with a progress bar; returns the run summary.
pub fn train_run(data: &Dataset, cfg: train::TrainConfig, opts: &run::RunOptions, resume: bool, quiet: bool) -> Result<Value> {
    let wall = Instant::now();
    let out = &opts.dir;
    let _lock = snerf_files::DirLock::acquire(out)?;
    let mut trainer = run::open(data, cfg, out, resume)?;
    if !quiet {
        eprintln!(
            "training {} ({:?}{}, {} train views, {} parameters, {:.1}% of space occupied after carving)",
            data.root.display(),
            trainer.model.space.kind,
            if data.dynamic { ", dynamic" } else { "" },
            data.train.len(),
            trainer.model.field.params.len(),
            100.0 * trainer.model.occ.occupied_fraction()
        );
        if let Some(c) = &trainer.sparse_carve {
            eprintln!(
                "free-space carving: {} sparse points, {} lines of sight, {} cells carved ({:.1}% of the grid stays allowed)",
                c.points,
                c.segments,
                c.carved_cells,
                100.0 * c.allowed_fraction
            );
        }
    }
    let pb = bar(1000, "{spinner} {bar:30} {percent:>3}% [{elapsed}<{eta}] {msg}");
    let mut ema: Option<(f64, f64)> = None;
    // RUN/report/ is redrawn whenever the curve gains a point (2, 5, 10, ... s, then every
    // minute), so a user looking at a running job sees its curve.
    let mut live = LiveReport::new();
    let mut drawn = trainer.curve.len();
    run::run(&mut trainer, data, opts, &mut |t, s, p| {
        if t.curve.len() != drawn {
            drawn = t.curve.len();
            live.train(out, run::metrics_json(t));
        }
        let sps = s.samples as f64 / s.seconds.max(1e-9);
        let e = ema.map(|(l, r)| (0.9 * l + 0.1 * s.loss, 0.9 * r + 0.1 * sps)).unwrap_or((s.loss, sps));
        ema = Some(e);
        pb.set_position((p * 1000.0) as u64);
        if t.step % 5 == 0 {
            pb.set_message(format!(
                "step {} loss {:.5} psnr {:.2} dB {:.2} M samples/s",
                t.step,
                e.0,
                train::mse_to_psnr(e.0),
                e.1 / 1e6
            ));
        }
    })?;
    pb.finish_and_clear();
    let metrics = run::metrics_json(&trainer);
    live.train(out, metrics.clone());
    let last = trainer.curve.last();
    if !quiet {
        eprintln!(
            "trained {} steps in {:.1} s ({:.2} M samples/s); test PSNR {} -> {}",
            trainer.step,
            trainer.train_seconds,
            trainer.samples_seen as f64 / trainer.train_seconds.max(1e-9) / 1e6,
            last.and_then(|c| c.test_psnr).map(|p| format!("{p:.2} dB")).unwrap_or("n/a".into()),
            out.display()
        );
    }
    Ok(json!({
        "command": "train",
        "run": pj(out),
        "peak_rss_mb": peak_rss_mb(),
        "wall_seconds": wall.elapsed().as_secs_f64(),
        "report": { "dir": pj(out.join(RUN_REPORT_DIR)), "writes": live.writes, "seconds": live.seconds },
        // The last curve point: held-out PSNR (fixed held-out pixels), the training batch's
        // PSNR at that step (after the per-photo colour transforms, when on) and their gap.
        "held_out_psnr": last.and_then(|c| c.test_psnr),
        "train_psnr": last.map(|c| c.train_psnr),
        "train_minus_held_out_db": last.and_then(|c| c.test_psnr.map(|t| c.train_psnr - t)),
        "appearance": trainer.appearance.as_ref().map(|a| a.summary()["max_distance_from_identity"].clone()),
        "sparse_carving": trainer.sparse_carve,
        "metrics": metrics,
    }))
}

pub fn eval_cmd(a: &EvalArgs) -> Result<Value> {
    let data = a.opts.load(&a.data)?;
    let (model, pool) = RunDir::new(&a.run).load_model()?;
    let views = match a.split.as_str() {
        "test" => &data.test,
        "val" => &data.val,
        "train" => &data.train,
        s => bail!("--split '{s}': use test, val or train"),
    };
    if views.is_empty() {
        bail!("{}: the {} split is empty", a.data.display(), a.split);
    }
    let out = a.out.clone().unwrap_or_else(|| RunDir::new(&a.run).eval_dir());
    guard_run_output("--out", &out, &a.run, Some(&data.root))?;
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;
    let has_alpha = train::views_have_alpha(&data.train);
    let report = eval::evaluate(&model, &pool, views, has_alpha, Some(&out))?;
    if !(report.mean_psnr.is_finite() && report.mean_ssim.is_finite()) {
        bail!("{}: the field renders non-finite colours (PSNR {}, SSIM {}); the run diverged", a.run.display(), report.mean_psnr, report.mean_ssim);
    }
    eprintln!(
        "{} {} views: PSNR {:.2} dB, SSIM {:.4} ({:.1} s); images in {}",
        a.split,
        report.views.len(),
        report.mean_psnr,
        report.mean_ssim,
        report.seconds,
        out.display()
    );
    let v = json!({ "command": "eval", "run": pj(&a.run), "split": a.split, "report": report, "images": pj(&out) });
    checkpoint::write_json_atomic(&out.join(RunDir::EVAL_RECORD), &v)?;
    Ok(v)
}

pub fn turntable_cmd(a: &TurntableArgs) -> Result<Value> {
    let data = a.opts.load(&a.data)?;
    guard_run_output("--out", &a.out, &a.run, Some(&data.root))?;
    let (model, pool) = RunDir::new(&a.run).load_model()?;
    let frames = turntable(&model, &pool, &data, a.frames, &a.out)?;
    Ok(json!({ "command": "turntable", "frames": frames.iter().map(pj).collect::<Vec<_>>(), "out": pj(&a.out) }))
}

/// `snerf_trainer::camera_path::render_turntable` with a progress bar.
pub fn turntable(model: &train::Model, pool: &snerf_trainer::render::WorkspacePool, data: &Dataset, n: usize, out: &Path) -> Result<Vec<PathBuf>> {
    let pb = bar(n.max(1) as u64, "{spinner} turntable {bar:30} {pos}/{len} [{elapsed}]");
    let files = snerf_trainer::camera_path::render_turntable(model, pool, data, n, out, &mut |done, _| pb.set_position(done as u64))?;
    pb.finish_and_clear();
    Ok(files)
}
