//! A round interrupted between training steps, saved so the same command continues it:
//! `SRUN/partial/` holds the field with its optimizer (`checkpoint.snerfck`), the round's
//! stylized targets (`target_NNN.png`, exactly the 8-bit colours the field trains on) and
//! `partial.json` (written last: without it the folder means nothing).

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use snerf_data::Dataset;
use snerf_trainer::checkpoint;
use snerf_trainer::run_dir::RunDir;
use snerf_trainer::train::Trainer;

use super::StylizeOptions;
use crate::stylizer::Image;

#[derive(Serialize, Deserialize)]
pub struct Partial {
    /// 1-based round this belongs to.
    pub round: usize,
    pub steps_done: u64,
    pub render_seconds: f64,
    pub stylize_seconds: f64,
    #[serde(default)]
    pub stylized_views: Option<usize>,
    pub train_seconds: f64,
    pub loss_ema: Option<f64>,
    /// Wall seconds the round had run before it was interrupted.
    pub round_wall: f64,
}

pub struct Resumed {
    pub trainer: Trainer,
    pub targets: Vec<Image>,
    pub saved: Partial,
}

fn dir(out: &Path) -> PathBuf {
    out.join("partial")
}

fn target_path(out: &Path, i: usize) -> PathBuf {
    dir(out).join(format!("target_{i:03}.png"))
}

/// Remove a saved partial round (after the round finished).
pub fn clear(out: &Path) {
    let _ = std::fs::remove_dir_all(dir(out));
}

pub fn save(out: &Path, p: &Partial, trainer: &Trainer, targets: &[Image]) -> Result<()> {
    clear(out);
    std::fs::create_dir_all(dir(out)).with_context(|| format!("{}: cannot create", dir(out).display()))?;
    checkpoint::save(trainer, &RunDir::new(dir(out)).checkpoint())?;
    for (i, t) in targets.iter().enumerate() {
        crate::stylizer::save_png(&target_path(out, i), t)?;
    }
    checkpoint::write_json_atomic(&dir(out).join("partial.json"), p)
}

/// The saved part of round `round`, if `out` holds one; a leftover of another round is removed.
pub fn load(out: &Path, round: usize, data: &Dataset, opts: &StylizeOptions) -> Result<Option<Resumed>> {
    let json = dir(out).join("partial.json");
    let Ok(bytes) = std::fs::read(&json) else { return Ok(None) };
    let p: Partial = serde_json::from_slice(&bytes).with_context(|| format!("{}: unreadable", json.display()))?;
    if p.round != round || p.steps_done >= opts.steps_of_round(round) {
        clear(out);
        return Ok(None);
    }
    let ck = checkpoint::load(&RunDir::new(dir(out)).checkpoint())?;
    let views = super::pick_views(&data.train, opts.views).len();
    let mut targets = Vec::with_capacity(views);
    for i in 0..views {
        let path = target_path(out, i);
        let img = image::open(&path).with_context(|| format!("{}: cannot read", path.display()))?.to_rgb32f();
        targets.push(Image { width: img.width() as usize, height: img.height() as usize, data: img.into_raw() });
    }
    let mut trainer = Trainer::from_parts(data, ck.cfg, ck.model, ck.adam)?;
    trainer.step = ck.step;
    trainer.train_seconds = ck.train_seconds;
    trainer.samples_seen = ck.samples_seen;
    trainer.curve = ck.curve;
    Ok(Some(Resumed { trainer, targets, saved: p }))
}
