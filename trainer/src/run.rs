//! A training run on disk: `RUN/checkpoint.snerfck` (atomic, resumable), `RUN/metrics.json`
//! (test PSNR against training seconds — the users' "error against run time"), and
//! `RUN/config.json`. The run stops at whichever budget ends first (steps or seconds),
//! counting what a resumed run had already done.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::json;
use snerf_data::Dataset;

use crate::checkpoint;
use crate::eval::sampled_psnr;
use crate::run_dir::RunDir;
use crate::train::{CurvePoint, StepStats, TrainConfig, Trainer};

/// When to measure test PSNR (training seconds); after the last, every 60 s.
pub const EVAL_AT: [f64; 12] = [2.0, 5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 90.0, 120.0, 180.0, 240.0];

#[derive(Clone, Debug)]
pub struct RunOptions {
    pub dir: PathBuf,
    pub steps: Option<u64>,
    pub seconds: Option<f64>,
    /// Held-out pixels (a fixed random sample across the test views) scored for the curve;
    /// `snerf eval` scores whole images.
    pub curve_pixels: usize,
    /// Also write a checkpoint at least this often (seconds of training).
    pub checkpoint_every: f64,
}

/// Start a new run or resume the one in `dir`. Hold `DirLock::acquire(dir)` around the
/// whole run so no other process trains into the same directory.
pub fn open(data: &Dataset, cfg: TrainConfig, dir: &Path, resume: bool) -> Result<Trainer> {
    let ck = RunDir::new(dir).checkpoint();
    if resume && !ck.exists() {
        anyhow::bail!(
            "{}: nothing to resume (no {}); drop --resume to start a new run there",
            dir.display(),
            checkpoint::FILE_NAME
        );
    }
    if resume {
        let c = checkpoint::load(&ck)?;
        anyhow::ensure!(
            c.model.space.kind == data.kind && c.model.space.dynamic == data.dynamic,
            "{}: checkpoint is for a {:?}{} scene, the data is {:?}{}",
            ck.display(),
            c.model.space.kind,
            if c.model.space.dynamic { " dynamic" } else { "" },
            data.kind,
            if data.dynamic { " dynamic" } else { "" }
        );
        let mut t = Trainer::from_parts(data, c.cfg, c.model, c.adam)?;
        t.step = c.step;
        t.train_seconds = c.train_seconds;
        t.samples_seen = c.samples_seen;
        t.curve = c.curve;
        return Ok(t);
    }
    if !resume && ck.exists() {
        anyhow::bail!(
            "{}: a run already exists here; pass --resume to continue it or choose another --out",
            dir.display()
        );
    }
    Trainer::new(data, cfg)
}

fn progress(t: &Trainer, o: &RunOptions) -> f64 {
    let a = o.steps.map(|s| t.step as f64 / s.max(1) as f64).unwrap_or(0.0);
    let b = o.seconds.map(|s| t.train_seconds / s.max(1e-9)).unwrap_or(0.0);
    a.max(b)
}

/// Steps after which a run that has not met the scene once stops (its cameras miss the
/// scene's bounds, or every pixel is empty).
const BLIND_STEPS: u64 = 50;

/// Train until the budget is spent, measuring the curve and checkpointing on the way.
/// Ctrl-C (with `snerf_files::interrupt` installed) saves a checkpoint and returns
/// `Interrupted`; a diverged loss returns an error and keeps the last good checkpoint.
pub fn run(
    t: &mut Trainer,
    data: &Dataset,
    opts: &RunOptions,
    on_step: &mut dyn FnMut(&Trainer, &StepStats, f64),
) -> Result<()> {
    std::fs::create_dir_all(&opts.dir).with_context(|| format!("{}: cannot create run directory", opts.dir.display()))?;
    let pixels = crate::eval::sample_pixels(&data.test, opts.curve_pixels, 0x7e57);
    let has_alpha = t.has_alpha();
    let mut next_eval = next_eval_after(t.train_seconds);
    let mut last_ckpt = t.train_seconds;
    let mut recent = StepStats::default();
    let measure = |t: &mut Trainer, last: &StepStats| {
        let test_psnr =
            (!pixels.is_empty()).then(|| sampled_psnr(&t.model, &t.pool, &data.test, has_alpha, &pixels));
        t.curve.push(CurvePoint {
            step: t.step,
            train_seconds: t.train_seconds,
            train_psnr: last.psnr(),
            test_psnr,
            samples_per_second: last.samples as f64 / last.seconds.max(1e-9),
        });
    };
    let _graceful = snerf_files::interrupt::Graceful::enter();
    let first_step = t.step;
    loop {
        let p = progress(t, opts);
        if p >= 1.0 {
            break;
        }
        if snerf_files::interrupt::requested() {
            measure(t, &recent);
            save(t, data, opts)?;
            return Err(snerf_files::interrupt::Interrupted(format!(
                "checkpoint saved at step {} ({:.1} s of training) in {}; continue with --resume",
                t.step,
                t.train_seconds,
                opts.dir.display()
            ))
            .into());
        }
        let s = t.step(p);
        recent = s;
        if !s.loss.is_finite() {
            anyhow::bail!(
                "training diverged at step {} (loss {}); lower the learning rates (--lr-planes, --lr-mlp). \
                 {} keeps the last good checkpoint, if any",
                t.step,
                s.loss,
                opts.dir.display()
            );
        }
        if t.samples_seen == 0 && t.step >= first_step + BLIND_STEPS {
            anyhow::bail!(
                "{} steps without a single sample inside the scene's bounds: no training ray meets the \
                 scene (check the camera poses and scale of {})",
                t.step - first_step,
                data.root.display()
            );
        }
        on_step(t, &s, progress(t, opts));
        // A fresh run is also measured after its first step, so the curve always starts
        // where training started: a run shorter than the first scheduled evaluation still
        // shows what it gained.
        if t.train_seconds >= next_eval || t.curve.is_empty() {
            measure(t, &s);
            next_eval = next_eval_after(t.train_seconds);
        }
        if t.train_seconds - last_ckpt >= opts.checkpoint_every {
            save(t, data, opts)?;
            last_ckpt = t.train_seconds;
        }
    }
    if t.curve.last().map(|c| c.step) != Some(t.step) {
        measure(t, &recent);
    }
    save(t, data, opts)
}

fn next_eval_after(s: f64) -> f64 {
    EVAL_AT.iter().cloned().find(|&e| e > s).unwrap_or(((s / 60.0).floor() + 1.0) * 60.0)
}

/// Checkpoint + metrics.json + config.json, each written atomically.
pub fn save(t: &Trainer, data: &Dataset, opts: &RunOptions) -> Result<()> {
    let dir = RunDir::new(&opts.dir);
    checkpoint::save(t, &dir.checkpoint())?;
    checkpoint::write_json_atomic(&dir.metrics(), &metrics_json(t))?;
    let mut dataset = snerf_data::summary(data);
    // Later commands (`snerf stylize RUN`, `bake`, `eval`) find the dataset through this
    // record from wherever they run, so a path given relative to the training's working
    // directory is recorded absolute.
    if let Ok(root) = std::path::absolute(&data.root) {
        dataset["root"] = json!(root.display().to_string());
    }
    checkpoint::write_json_atomic(
        &dir.config(),
        &json!({
            "train": t.cfg,
            "space": t.model.space,
            "dataset": dataset,
            "parameters": t.model.field.params.len(),
        }),
    )
}

pub fn metrics_json(t: &Trainer) -> serde_json::Value {
    json!({
        "step": t.step,
        "train_seconds": t.train_seconds,
        "samples_seen": t.samples_seen,
        "samples_per_second": t.samples_seen as f64 / t.train_seconds.max(1e-9),
        "occupied_fraction": t.model.occ.occupied_fraction(),
        "curve": t.curve,
    })
}
