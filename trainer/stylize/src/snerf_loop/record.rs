//! The run's record (`stylize.json`): its options, and what every trained round measured,
//! as it measured it. Nothing is chosen on these figures: every round's field is the run's
//! next field.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use snerf_trainer::run_dir::RunDir;

use super::options::StylizeOptions;
use crate::style_metric::StyleScore;

/// The run's record; its name is part of the run directory's layout ([`RunDir`]).
pub const STATE_FILE: &str = RunDir::STYLIZE_RECORD;

/// The loop a record was written by. Records of another loop are read, but not resumed:
/// without it (a dozen options to reproduce earlier runs, rounds that could be discarded),
/// 2 (the paper's loop stepped its targets by 1/t, and the one-pass variant was the default).
pub const LOOP_VERSION: u32 = 3;

/// One finished round.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RoundRecord {
    pub round: usize,
    /// Wall seconds since the run started (summed over resumes), measurement excluded.
    pub wall_seconds: f64,
    pub render_seconds: f64,
    /// Seconds in the stylizer, fusion and targets.
    pub stylize_seconds: f64,
    /// Training views the stylizer painted this round (all of them every round in the
    /// paper's loop; only in round 1 in the one-pass variant).
    #[serde(default)]
    pub stylized_views: Option<usize>,
    pub train_seconds: f64,
    /// PSNR of the field against this round's targets (training rays).
    pub fit_psnr: f64,
    /// Distance of the field's renders to the style (Magenta style embeddings); None when
    /// the embedding model is not installed.
    pub style_distance: Option<f64>,
    /// Warped-frame MSE along the loop's path, frames (i, i+1) and (i, i+7).
    pub short_range: Option<f64>,
    pub long_range: Option<f64>,
    /// The weight-free style distance (`style_metric`) of the ring's scene pixels.
    #[serde(default)]
    pub style_swd: Option<StyleScore>,
    /// The Gram style distance (`style_gram`) of the same frames.
    #[serde(default)]
    pub style_gram: Option<f64>,
    /// Which frames the scores above were measured on (`PathGeometry::description`).
    #[serde(default)]
    pub measured_on: Option<String>,
    /// Fraction of scene pixels whose target took other views' colours.
    #[serde(default)]
    pub fused_fraction: Option<f64>,
    /// The step of this round's running mean.
    #[serde(default)]
    pub target_step: Option<f32>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StylizeState {
    pub options: StylizeOptions,
    pub rounds_done: usize,
    pub records: Vec<RoundRecord>,
    /// `LOOP_VERSION` of the loop that wrote the record (absent: an earlier release's).
    #[serde(default)]
    pub loop_version: u32,
    /// The snerf release that wrote the record.
    #[serde(default)]
    pub release: Option<String>,
}

pub fn state_path(dir: &Path) -> PathBuf {
    RunDir::new(dir).stylize_record()
}

impl StylizeState {
    pub fn new(options: &StylizeOptions) -> StylizeState {
        StylizeState {
            options: options.clone(),
            rounds_done: 0,
            records: Vec::new(),
            loop_version: LOOP_VERSION,
            release: Some(env!("CARGO_PKG_VERSION").into()),
        }
    }

    /// The record in `dir`, if there is one (an unreadable one is an error naming the file).
    pub fn read(dir: &Path) -> Result<Option<StylizeState>> {
        let path = state_path(dir);
        let Ok(bytes) = std::fs::read(&path) else { return Ok(None) };
        let state = serde_json::from_slice(&bytes).with_context(|| format!("{}: not a stylization state file", path.display()))?;
        Ok(Some(state))
    }

    /// The record in `dir` to go on with `asked`: refused when an earlier release wrote it or
    /// its options differ (more or fewer rounds extend or end the same run).
    pub fn resume(dir: &Path, asked: &StylizeOptions) -> Result<Option<StylizeState>> {
        let Some(mut state) = StylizeState::read(dir)? else { return Ok(None) };
        if state.loop_version != LOOP_VERSION {
            bail!(
                "{}: written by an earlier snerf release (before {}), whose loop had other options; its figures still read \
                 (`snerf consistency`, `snerf report`), but it cannot be resumed: stylize into another --out",
                state_path(dir).display(),
                env!("CARGO_PKG_VERSION")
            );
        }
        let differ = differing_options(&state.options, asked);
        if !differ.is_empty() {
            bail!(
                "{}: holds a stylization run with other options ({}); choose another --out or repeat the same options to resume",
                dir.display(),
                differ.join("; ")
            );
        }
        state.options.rounds = asked.rounds;
        Ok(Some(state))
    }
}

/// "--option: recorded recorded, asked asked" for each option in which `asked` differs from
/// `recorded` (the rounds aside), in the command line's terms.
pub fn differing_options(recorded: &StylizeOptions, asked: &StylizeOptions) -> Vec<String> {
    let (Ok(serde_json::Value::Object(a)), Ok(serde_json::Value::Object(b))) = (serde_json::to_value(recorded), serde_json::to_value(asked)) else {
        return vec!["options".into()];
    };
    let null = serde_json::Value::Null;
    let cli_name = |k: &str| if k == "source_run" { "the source run".to_string() } else { format!("--{}", k.replace('_', "-")) };
    let cli_value = |k: &str, v: &serde_json::Value| match v {
        serde_json::Value::Null if k == "seed" => "source".to_string(),
        serde_json::Value::String(s) => s.clone(),
        other => other.to_string(),
    };
    a.iter()
        .filter(|(k, v)| k.as_str() != "rounds" && b.get(*k) != Some(*v))
        .map(|(k, v)| format!("{}: {} recorded, {} asked", cli_name(k), cli_value(k, v), cli_value(k, b.get(k).unwrap_or(&null))))
        .collect()
}

/// Progress callbacks, so the command line can draw bars without this crate knowing how.
pub trait Progress {
    /// `round` 0 is the work before the first round (rendering the measurement path).
    fn phase(&mut self, round: usize, rounds: usize, phase: &str, total: u64);
    fn tick(&mut self, done: u64, message: &str);
    fn round_done(&mut self, record: &RoundRecord);
}

/// A progress sink that says nothing (tests).
pub struct Quiet;
impl Progress for Quiet {
    fn phase(&mut self, _: usize, _: usize, _: &str, _: u64) {}
    fn tick(&mut self, _: u64, _: &str) {}
    fn round_done(&mut self, _: &RoundRecord) {}
}
