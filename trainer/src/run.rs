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

pub fn checkpoint_path(dir: &Path) -> PathBuf {
    dir.join(checkpoint::FILE_NAME)
}

/// Start a new run or resume the one in `opts.dir`.
pub fn open(data: &Dataset, cfg: TrainConfig, dir: &Path, resume: bool) -> Result<Trainer> {
    let ck = checkpoint_path(dir);
    if resume && ck.exists() {
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

/// Train until the budget is spent, measuring the curve and checkpointing on the way.
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
    loop {
        let p = progress(t, opts);
        if p >= 1.0 {
            break;
        }
        let s = t.step(p);
        recent = s;
        on_step(t, &s, progress(t, opts));
        if t.train_seconds >= next_eval {
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
    checkpoint::save(t, &checkpoint_path(&opts.dir))?;
    checkpoint::write_json_atomic(&opts.dir.join("metrics.json"), &metrics_json(t))?;
    checkpoint::write_json_atomic(
        &opts.dir.join("config.json"),
        &json!({
            "train": t.cfg,
            "space": t.model.space,
            "dataset": snerf_data::summary(data),
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
