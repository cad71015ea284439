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
        let app = dir.join(crate::appearance::FILE_NAME);
        if t.appearance.is_some() && app.exists() {
            let a = crate::appearance::Appearance::load(&app)?;
            anyhow::ensure!(
                Some(&a.names) == t.appearance.as_ref().map(|x| &x.names),
                "{}: its photos are not the dataset's training photos",
                app.display()
            );
            t.appearance = Some(a);
        }
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
    // the training views' own sample, at its own seed: what the trainer fits, measured as the
    // held-out views are
    let train_pixels = crate::eval::sample_pixels(t.views(), opts.curve_pixels, 0x7a19);
    let has_alpha = t.has_alpha();
    let mut next_eval = next_eval_after(t.train_seconds);
    let mut last_ckpt = t.train_seconds;
    let mut recent = StepStats::default();
    let measure = |t: &mut Trainer, last: &StepStats| {
        let test_psnr =
            (!pixels.is_empty()).then(|| sampled_psnr(&t.model, &t.pool, &data.test, has_alpha, &pixels));
        let train_psnr = if train_pixels.is_empty() {
            last.psnr()
        } else {
            sampled_psnr(&t.model, &t.pool, t.views(), has_alpha, &train_pixels)
        };
        t.curve.push(CurvePoint {
            step: t.step,
            train_seconds: t.train_seconds,
            train_psnr,
            loss_psnr: Some(last.psnr()),
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
    if let Some(a) = &t.appearance {
        checkpoint::write_json_atomic(&opts.dir.join(crate::appearance::FILE_NAME), &serde_json::to_value(a)?)?;
    }
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

// A training run written and read back through `RunDir`: here rather than in `run_dir`, which
// sits below `run` and must not name it.
#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::Value;

    fn tmp(tag: &str) -> snerf_files::ScratchDir {
        snerf_files::ScratchDir::new("snerf-run-dir", tag).unwrap()
    }

    /// A four-view Blender-style dataset of a grey disc on a transparent background, seen
    /// from the four sides: small enough to train a few steps in a unit test.
    fn write_tiny_dataset(dir: &Path) {
        let img = image::RgbaImage::from_fn(16, 16, |x, y| {
            let (dx, dy) = (x as f32 - 7.5, y as f32 - 7.5);
            if dx * dx + dy * dy < 25.0 {
                image::Rgba([128, 128, 128, 255])
            } else {
                image::Rgba([0, 0, 0, 0])
            }
        });
        for split in ["train", "test"] {
            std::fs::create_dir_all(dir.join(split)).unwrap();
            let frames: Vec<Value> = (0..4)
                .map(|i| {
                    let a = i as f32 * std::f32::consts::FRAC_PI_2;
                    let eye = [4.0 * a.sin(), 0.5, 4.0 * a.cos()];
                    let m = snerf_geometry::look_at(eye, [0.0; 3], [0.0, 1.0, 0.0]);
                    let file = format!("{split}/r_{i}");
                    img.save(dir.join(format!("{file}.png"))).unwrap();
                    serde_json::json!({ "file_path": file, "transform_matrix": [m[0], m[1], m[2], [0.0, 0.0, 0.0, 1.0]] })
                })
                .collect();
            let doc = serde_json::json!({ "camera_angle_x": 0.7, "frames": frames });
            std::fs::write(dir.join(format!("transforms_{split}.json")), doc.to_string()).unwrap();
        }
    }

    #[test]
    fn a_trained_run_gives_back_its_dataset_and_model() {
        let d = tmp("trained");
        let data_dir = d.join("data");
        write_tiny_dataset(&data_dir);
        let data = crate::data::load(&data_dir, &Default::default()).unwrap();
        let mut cfg = TrainConfig::for_dataset(&data);
        cfg.field.resolutions = vec![8, 16];
        cfg.batch_rays = 256;
        cfg.batch_samples = 0;
        let opts = RunOptions { dir: d.join("run"), steps: Some(3), seconds: None, curve_pixels: 64, checkpoint_every: 1e9 };
        let mut t = open(&data, cfg, &opts.dir, false).unwrap();
        run(&mut t, &data, &opts, &mut |_, _, _| {}).unwrap();
        // Three steps end long before the first scheduled evaluation, yet the curve has
        // both ends: after the first step and at the last.
        let steps: Vec<u64> = t.curve.iter().map(|c| c.step).collect();
        assert_eq!(steps, [1, 3], "curve points");

        let dir = RunDir::new(&opts.dir);
        for f in [dir.checkpoint(), dir.config(), dir.metrics()] {
            assert!(f.is_file(), "{} was not written", f.display());
        }
        assert_eq!(dir.dataset().unwrap(), data.root);
        let (model, _pool) = dir.load_model().unwrap();
        assert_eq!(model.field.params, t.model.field.params);
        assert_eq!(model.space.kind, data.kind);

        // A dataset given by a relative path is recorded absolute, so the run finds it from
        // any working directory.
        let mut rel = data.clone();
        rel.root = PathBuf::from("datasets/some-scene");
        save(&t, &rel, &opts).unwrap();
        let config: Value = serde_json::from_slice(&std::fs::read(dir.config()).unwrap()).unwrap();
        let recorded = PathBuf::from(config["dataset"]["root"].as_str().unwrap());
        assert!(recorded.is_absolute() && recorded.ends_with("datasets/some-scene"), "{}", recorded.display());
        assert_eq!(dir.dataset().unwrap(), recorded);
        // A run recorded before that (a relative path that is not there) gets a clear error.
        let mut old = config.clone();
        old["dataset"]["root"] = "datasets/some-scene".into();
        std::fs::write(dir.config(), serde_json::to_vec(&old).unwrap()).unwrap();
        let e = format!("{:#}", dir.dataset().unwrap_err());
        assert!(e.contains("relative path datasets/some-scene") && e.contains("--data"), "{e}");
    }
}
