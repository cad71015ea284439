//! What a stylization run is asked to do, and the schedule that follows from it: the step of
//! each round's running mean, the training steps of each round, the learning-rate decay and
//! when the colour offsets are recalibrated.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::fusion::Read;

/// What a stylization run was asked to do (fixed for the life of the run directory). Its
/// `Default` is the command line's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StylizeOptions {
    /// The realistic run this one starts from.
    pub source_run: PathBuf,
    pub data: PathBuf,
    pub style: PathBuf,
    pub stylizer: String,
    pub strength: f32,
    pub rounds: usize,
    /// Training steps per round on average (the run trains `rounds ×` this many).
    pub steps_per_round: u64,
    /// Longer side of the image handed to the stylizer (0: the training resolution).
    pub style_res: usize,
    /// Train on this many training views, evenly spaced (0: all of them).
    pub views: usize,
    pub appearance_only: bool,
    /// Frames of the loop's own path for the per-round measurement (0: skip it).
    pub consistency_frames: usize,
    /// Neighbouring views each consensus step takes the median over (0: no fusion at all).
    pub fuse_views: usize,
    /// What the stylizer paints each round.
    pub content: Content,
    /// Seed of the rays each training step draws (None: the realistic run's own).
    pub seed: Option<u64>,
    /// The longer image side the run's dataset is loaded with (`--max-size`; the caller
    /// loads it, and `snerf consistency` loads it the same way): every round renders, paints
    /// and trains on all its views at this size, so a round's time grows with their pixels.
    /// None: the loader's own cap (runs recorded before this option).
    #[serde(default)]
    pub max_size: Option<u32>,
}

/// The default `StylizeOptions::max_size`: 512 px on the longer side. The default five rounds
/// render every training view 13 times (each round's painting and the colour calibrations),
/// so a photo capture at the loader's cap spends nearly all its time rendering: a 36-photo
/// product spin at 946×491 took 56 minutes on 2 cores (BENCH.md §2d); at 512 px a view has
/// under a third of the pixels. Synthetic 800² renders are painted at 512²; 512² and smaller
/// data is untouched.
pub const DEFAULT_MAX_SIZE: u32 = 512;

/// The image the stylizer is given for each training view.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Content {
    /// The current field's render, every round: the paper's loop (the default).
    Render,
    /// The realistic field's renders, stylized once; later rounds reconcile those
    /// stylizations across views (the one-pass variant).
    Realistic,
}

/// The default `Content`: the paper's loop (BENCH.md §5 compares the two).
pub const DEFAULT_CONTENT: Content = Content::Render;

impl Default for Content {
    fn default() -> Content {
        DEFAULT_CONTENT
    }
}

impl Content {
    /// As the command line and `stylize.json` spell it.
    pub const fn as_str(self) -> &'static str {
        match self {
            Content::Render => "render",
            Content::Realistic => "realistic",
        }
    }

    /// How the consensus step reads the other views' colours (`fusion::Read`): the paper's
    /// loop mixes the four pixels around a point (a small blur each round, which the next
    /// round's fresh painting restores), the one-pass variant copies the pixel (its
    /// consensus compounds over the rounds on one stylization, with no fresh painting to
    /// restore what a blur takes).
    pub const fn consensus_read(self) -> Read {
        match self {
            Content::Render => Read::Bilinear,
            Content::Realistic => Read::Nearest,
        }
    }
}

impl Default for StylizeOptions {
    fn default() -> StylizeOptions {
        StylizeOptions {
            source_run: PathBuf::new(),
            data: PathBuf::new(),
            style: PathBuf::new(),
            stylizer: "arbitrary".into(),
            strength: 1.0,
            rounds: 5,
            steps_per_round: 300,
            style_res: 0,
            views: 0,
            appearance_only: false,
            consistency_frames: 16,
            fuse_views: 4,
            content: Content::default(),
            seed: None,
            max_size: Some(DEFAULT_MAX_SIZE),
        }
    }
}

impl StylizeOptions {
    /// The step of round `round`'s targets toward the round's fused images (1-based). The
    /// paper's loop (`Content::Render`): `1/t²`, so what the stylizer can still change after
    /// round t is bounded by `Σ_{k>t} 1/k² < 1/t`, whatever it paints (`snerf_loop`'s module
    /// doc says why). The one-pass variant: `1/t`, the running mean of the rounds'
    /// consensus images.
    pub fn step_of_round(&self, round: usize) -> f32 {
        let t = round.max(1) as f32;
        match self.content {
            Content::Render => 1.0 / (t * t),
            Content::Realistic => 1.0 / t,
        }
    }

    /// Training steps of round `round` (1-based), in proportion to `1/t` (the same total as
    /// `steps_per_round` every round; at least 1): most of them in round 1, where the style
    /// is taken, and later rounds, whose targets move less and less, refine.
    pub fn steps_of_round(&self, round: usize) -> u64 {
        let rounds = self.rounds.max(1);
        let total = self.steps_per_round.max(1) * rounds as u64;
        let h: f64 = (1..=rounds).map(|t| 1.0 / t as f64).sum();
        // cumulative shares, rounded, so the rounds add up to the total exactly
        let upto = |t: usize| ((1..=t).map(|k| 1.0 / k as f64).sum::<f64>() / h * total as f64).round() as u64;
        let t = round.clamp(1, rounds);
        (upto(t) - upto(t - 1)).max(1)
    }

    /// Learning-rate progress in [0, 1] of step `s` of round `round`: one decay over the
    /// whole run, so later rounds move the field less.
    pub fn lr_progress(&self, round: usize, s: u64) -> f64 {
        let before: u64 = (1..round.max(1)).map(|t| self.steps_of_round(t)).sum();
        let total: u64 = (1..=self.rounds.max(1)).map(|t| self.steps_of_round(t)).sum();
        (before + s) as f64 / total.max(1) as f64
    }

    /// Training steps between colour-offset calibrations: as many as the last round takes,
    /// and at most half the first round's (round 1 has no field of its own to measure until
    /// it has trained, and is calibrated at least once within it).
    pub fn calibration_interval(&self) -> u64 {
        self.steps_of_round(self.rounds).min(self.steps_of_round(1) / 2).max(1)
    }

    /// Whether the targets are recalibrated before step `s` of a round is taken (a round
    /// that starts training after round 1 is calibrated at its start anyway).
    pub fn calibrates_at(&self, s: u64) -> bool {
        s > 0 && s.is_multiple_of(self.calibration_interval())
    }
}
