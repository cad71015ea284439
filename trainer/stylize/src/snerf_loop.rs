//! Algorithm 1 of SNeRF: starting from a field trained on realistic views, repeat T rounds of
//! (1) render every training view from the current field, (2) stylize each render on its own
//! with an image stylizer, (3) train the field on random rays across the stylized views.
//!
//! A feed-forward stylizer repaints every view from scratch each round, so its views
//! disagree about the same surface point and a field trained on them memorizes that
//! disagreement, round after round. Two things anchor the targets (DESIGN: "targets that
//! move less each round"): (2a) `fusion` makes each target the median of what the view and
//! its nearest views (reprojected through the current field's depth) painted at the same
//! surface point, so the field is asked for one colour per point; (2b) the target is a
//! damped step from the current render toward that fused stylization
//! (`render + β_t × (fused − render)`), the render taken before its background is laid
//! under it (`unpremultiply`): a target is a surface colour, and a render composited over
//! the eval background would whiten the silhouette's rim a little more every round
//! (BENCH.md §5g).
//!
//! Why the published loop does not converge, and what does. Write a round as the iteration
//! `x_{t+1} = x_t + β_t (T(x_t) − x_t)`, where `x` is the field's renders of the training
//! views and `T(x) = fuse(stylize(content), depth(x))`. With the content being the current
//! render (`Content::Render`, Algorithm 1 as published), `T` depends on the field's colours,
//! and a feed-forward stylizer is no contraction: it adds new texture to whatever it is
//! given, so `T(T(x))` has more of it than `T(x)`, there is no fixed point to approach, and
//! every round adds detail the views disagree on (the warp error and the style distance
//! grow round after round; BENCH.md §5b). The loop converges when `T` stops depending on
//! the field's colours:
//!
//! - `Content::Realistic`: the stylizer paints the realistic field's renders, once. `T` then
//!   depends on the field only through the depth that fusion reprojects with, which
//!   stylization moves little, so the rounds approach one fixed set of targets instead of
//!   chasing a moving one; a deterministic stylizer gives the same targets on a resumed run.
//! - `StepSchedule::Harmonic` (`β_t = β / t`): with `β = 1` the first round takes the whole
//!   step (the field takes the style at once) and round `t`'s target is the running mean
//!   of the first `t` fused targets (a Mann iteration with harmonic steps), so what still
//!   changes from round to round (the fusion through a slightly different depth) is
//!   averaged away instead of accumulated, and each round moves the field by O(1/t).
//! - `LrSchedule::Run`: the learning rate decays once over all rounds instead of restarting
//!   every round, so later rounds refine instead of re-fitting.
//!
//! With those three alone (BENCH.md §5b) the warp error of round 5 is still 6–42% above
//! round 1's (against 3–5× with the published loop): the targets are fixed, and the field,
//! under-fitted after round 1, keeps fitting more of the disagreement they still hold.
//! `RoundSteps::Harmonic` (most of the steps in round 1) flattened that curve only by making
//! round 1 worse; it became the default with `StepFrom::Targets` (below).
//!
//! - `Targets::Consensus` (the default) removes that last source: each round fuses the
//!   previous round's *fused* targets again, through the current (better) depth, instead of
//!   the raw stylizations. Fusion is a per-pixel median over a view and its reprojected
//!   neighbours; iterated, it is a consensus over the view graph: texture the views agree
//!   on is a fixed point of it and stays, texture they disagree on is pulled toward what the
//!   neighbours painted, a little more each round. The targets therefore become more
//!   consistent round by round, and so does the field fitted to them (BENCH.md §5c: round
//!   5 below round 1 on warp error and style distance).
//! - `Fusion::Owner` (the default) is how the first round fuses the fresh stylizations: each
//!   surface point takes what the nearest view that sees it painted (`fusion::fuse_owner`),
//!   instead of the median of five views' different strokes. Those targets already agree
//!   wherever the geometry is right, so the consensus rounds that follow have only seams and
//!   misregistration left to reconcile and average little of the painting away (BENCH.md
//!   §5h: round 5's warp error 2–27% above a median start's, its style distance to the
//!   painting 8–30% below; the ratio to per-frame stylization below 1 on every pair measured).
//! - `fusion::Read::Nearest` (the default): fusion copies the pixel a surface point falls in
//!   instead of mixing four. A bilinear read blurs a little, and the consensus rounds
//!   compound it: the targets lost 30% of their lightness contrast over five rounds, and
//!   round 5's style distance ended above round 1's on 3 of 9 pairs. Copying, round 5 is no
//!   worse than round 1 on every pair, for a warp error about twice as large (still a fifth
//!   of per-frame stylization's; BENCH.md §5i).
//!
//! - `StepFrom::Targets` (the default) takes the harmonic step from the previous round's
//!   *target* instead of the field's render, so round t's target is the running mean of the
//!   first t fused targets, as the harmonic step intends, made of the stylizer's pixels alone.
//!   Stepped from the render, every target was part field: the field's reconstruction (a
//!   little blurred, and short of the painting's rarest colours, which are few pixels) went
//!   back into the targets and compounded, so round 5's targets covered less of the painting's
//!   palette than round 1's, and the field fitted to them less again (BENCH.md §5n). That
//!   blur was also part of why the warp error fell over the rounds: targets that no longer
//!   fade leave round 1, which fits them least, the least detail and the lowest warp error.
//! - `RoundSteps::Harmonic` (the default) therefore spends the training steps as the targets
//!   move: in proportion to the step 1/t, most of them in round 1, where the style is taken;
//!   later rounds, whose targets change by O(1/t), refine. Round 1 is then as sharp as the
//!   targets allow and the rounds after it only reconcile, so round 5 ends below round 1
//!   on the warp errors again (BENCH.md §5n).
//! - `plane_tv` (the CLI's `--tv`, 0 by default): the stylizing trainer does not inherit the
//!   realistic field's total-variation smoothing of its planes. That weight was chosen for
//!   held-out PSNR on unseen views; a stylized field has to hold the stylizer's pixel-scale
//!   strokes, and the smoothing filled in the dark gaps between them (the darks are most of
//!   the palette SNeRF's views miss; BENCH.md §5o). Consistency comes from the targets.
//! - `ViewColour::Diffuse` (the CLI's `--view-colour`, the default): the stylized field's
//!   colour does not depend on the viewing direction. The view MLP is frozen while stylizing
//!   (a free one learns the views' disagreement as view-dependent colour), but frozen it
//!   still adds the residual the realistic field learnt, now computed from painted colours.
//!   On the fields measured that residual is close to a constant offset (−0.10 to +0.04),
//!   and the diffuse colour is bounded to (0, 1): a positive offset keeps the field from the
//!   painting's darkest darks, a negative one from its brightest colours (BENCH.md §5p). A
//!   painting has no highlights that move with the viewer, so the output layer is zeroed.
//!
//! - `Palette::Keep` (the CLI's `--palette`, the default): the consensus is to reconcile the
//!   views, not to change which colours the scene has, but the iterated median narrows the
//!   targets' colour distribution (an extreme colour survives only where most neighbours read
//!   it, and reprojection misregisters thin strokes by about a pixel), so the style distance
//!   of round 5 ended above round 1's on most pairs that failed the convergence bar. Before
//!   each consensus round the previous targets are mapped, per Oklab channel, onto the
//!   distribution of the first fused stylizations (`palette`); the median then reconciles
//!   (BENCH.md §5q).
//!
//! - `Rays::Area` (the CLI's `--rays`, the default): while stylizing, each training ray
//!   crosses its pixel anywhere in the pixel's square instead of at its centre. Fitted only
//!   at the centres, the field is free between them, and a new view's rays fall between
//!   them: the stylized field matched the stylizer on its training views (1.012×) and lost
//!   7–9% of the style on views between them, and most of its remaining warp error was
//!   there (BENCH.md §5s). A painted pixel is the paint over its square, so the field is
//!   asked for that; the warp errors fall by about half. Alone it costs palette: the field's
//!   colours average over the square, and its renders miss more of the painting's colours.
//! - `ColourFit::Compensate` (the CLI's `--colour-fit compensate`) gives that palette
//!   back. A field fitted to painted views shows a narrower colour distribution than its
//!   targets (a stroke's darkest dark is a few pixels, which the field, shared between views
//!   and rays, reaches in part), with area rays more so. The targets are mapped, per Oklab
//!   channel and quantile, by what the field's renders of the training views fell short of
//!   the targets it last trained on (`palette::compensated`, an iterative-learning step),
//!   recalibrated at the start of every round and halfway through the first, so the field
//!   shows the targets' distribution. The map is monotone and a function of the colour
//!   alone, so colours the views agree on stay in agreement; the targets a round keeps for
//!   the next round's step are the fused ones (BENCH.md §5u).
//! - `ColourFit::Joint` (the CLI's `--colour-fit`, the default) makes up the shortfall per
//!   colour instead of per channel (`colour_offsets`). Matching each channel's distribution
//!   kept each channel's spread, but not which colours go together: over the consensus
//!   rounds the field lost the painting's joint colours (a red stroke on green shown a
//!   little green), and round 5's style distance ended up to 17% above round 1's. Each
//!   target colour is moved by what the field showed short of it, averaged over the pixels
//!   of that colour, with gains `1/k` (still a function of the colour alone). It is
//!   recalibrated after every equal share of the training steps
//!   (`StylizeOptions::calibration_interval`), not once a round: calibrated once in round 1,
//!   which holds most of the steps, the field took more of the painting's colours in the
//!   rounds after it, with more contrast, and the warp errors of round 5 ended up to 13%
//!   above round 1's (BENCH.md §5v).
//!
//! - `KeepRounds::Better` (the CLI's `--keep-rounds`, the default): a round's field is kept only
//!   when the per-round measurement finds it no worse than the last kept field on both warp
//!   errors and on the style distance; otherwise the next round trains from the kept field.
//!   With all of the above, the rounds after the first still ended above round 1 on style on
//!   8 of 26 pairs, by 0.5–9.4%, the field fitting the targets' pixel-scale strokes more
//!   closely round by round (BENCH.md §5v, §5w). A round that loses style or consistency has
//!   not done what the rounds after the first are for, and the run's last field was the one a
//!   user got. The discarded field's scores stay in the round's record.
//!
//! Runs recorded before these options resume as they were.
//!
//! The paper's own way out, an optimizing stylizer started from the render (`gatys` with
//! `Content::Render`), does not converge here either (BENCH.md §5d): Adam's normalized steps
//! move every pixel by about the learning rate whatever the gradient, so each round's
//! stylization of an already stylized render adds fresh pixel-scale texture, and the warp
//! error doubles over five rounds. `gatys` on the fixed realistic content behaves like the
//! feed-forward stylizers above.
//!
//! A stylization run lives in its own directory (`SRUN`): `checkpoint.snerfck` (the field,
//! loadable by every command that takes a run), `stylize.json` (options, the source run, and
//! one record per finished round: wall time, fit, style distance, consistency) and
//! `rounds/round_N.png` (renders beside their stylized targets). Both files are replaced
//! atomically after each round, so a killed run resumes at its last finished round. Ctrl-C
//! (with `snerf_files::interrupt` installed) stops between training steps and saves the round
//! so far in `partial/` (field, optimizer, stylized targets, step), from which the same
//! command continues that round. The directory is locked while a run uses it.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use snerf_data::{Dataset, View};
use snerf_trainer::checkpoint;
use snerf_trainer::eval::{eval_background, render_camera};
use snerf_trainer::render::WorkspacePool;
use snerf_trainer::run_dir::RunDir;
use snerf_trainer::train::{mse_to_psnr, views_have_alpha, Model, Trainer};

mod consensus;
mod partial;

use crate::colour_offsets::ColourOffsets;
use crate::consistency::{self, PathGeometry, StyleMeters};
use crate::fusion::{self, ViewGeometry};
use crate::palette;
use crate::stylizer::{Image, StyleEmbedder, Stylizer};

/// The run's record; its name is part of the run directory's layout ([`RunDir`]).
pub const STATE_FILE: &str = RunDir::STYLIZE_RECORD;

/// What a stylization run was asked to do (fixed for the life of the run directory).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StylizeOptions {
    /// The realistic run this one starts from.
    pub source_run: PathBuf,
    pub data: PathBuf,
    pub style: PathBuf,
    pub stylizer: String,
    pub strength: f32,
    pub rounds: usize,
    pub steps_per_round: u64,
    /// Longer side of the image handed to the stylizer (0: the training resolution).
    pub style_res: usize,
    /// Train on this many training views, evenly spaced (0: all of them).
    pub views: usize,
    pub appearance_only: bool,
    /// Frames of the novel path used for the per-round consistency measurement (0: skip).
    pub consistency_frames: usize,
    /// Neighbouring training views each target is fused with (0: no fusion).
    #[serde(default)]
    pub fuse_views: usize,
    /// Step from the current render toward the (fused) stylized target, in (0, 1].
    #[serde(default = "full_step")]
    pub target_step: f32,
    /// What the stylizer paints each round (runs recorded before this option: `Render`).
    #[serde(default)]
    pub content: Content,
    /// How the target step changes with the round (before this option: `Constant`).
    #[serde(default)]
    pub step_schedule: StepSchedule,
    /// How the learning rate decays (before this option: `Round`).
    #[serde(default)]
    pub lr_schedule: LrSchedule,
    /// How the training steps are spread over the rounds (before this option: `Equal`).
    #[serde(default)]
    pub round_steps: RoundSteps,
    /// What each round fuses (before this option: `Once`).
    #[serde(default)]
    pub targets: Targets,
    /// How fresh stylizations are fused (before this option: `Median`).
    #[serde(default)]
    pub fusion: Fusion,
    /// How fusion reads the other views' colours (before this option: `Bilinear`).
    #[serde(default)]
    pub fusion_read: fusion::Read,
    /// What of each view the stylizer is given (absent in a `stylize.json` written before
    /// this option: the whole view, as those runs were made).
    #[serde(default)]
    pub region: Region,
    /// Where a round's damped step toward the fused stylization starts (before this option:
    /// `Render`).
    #[serde(default)]
    pub step_from: StepFrom,
    /// Weight of the total-variation loss on the field's planes while stylizing (absent in a
    /// `stylize.json` written before this option: None, the realistic run's own weight).
    #[serde(default)]
    pub plane_tv: Option<f32>,
    /// Whether the stylized field's colour may depend on the viewing direction (before this
    /// option: `Source`).
    #[serde(default)]
    pub view_colour: ViewColour,
    /// Whether the consensus rounds may narrow the targets' colours (before this option:
    /// `Free`).
    #[serde(default)]
    pub palette: Palette,
    /// Seed of the rays each training step draws (None: the realistic run's own seed, as runs
    /// made before this option). Which of the painting's rarest colours the field ends a round
    /// holding depends on the ray sequence, so two seeds show how far a figure moves with it
    /// (BENCH.md §5q).
    #[serde(default)]
    pub seed: Option<u64>,
    /// Where each training ray crosses its pixel (before this option: `Centre`).
    #[serde(default)]
    pub rays: Rays,
    /// Whether the targets make up for the colours the field falls short of (before this
    /// option: `Plain`).
    #[serde(default)]
    pub colour_fit: ColourFit,
    /// Which rounds' fields the run keeps (before this option: `Every`).
    #[serde(default)]
    pub keep_rounds: KeepRounds,
}

/// Which rounds' fields a run keeps, judged by the per-round measurement (with a novel path:
/// `consistency_frames` > 1; without one every round is kept).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum KeepRounds {
    /// Every round's field, whatever it measures.
    #[default]
    Every,
    /// A round's field only when it is no worse than the last kept field on any of the
    /// round's measures: the short- and long-range warp errors and the weight-free style
    /// distance. Otherwise the field is discarded (the record keeps what it measured) and
    /// the next round trains from the kept one. Round 1, which takes the style, is always
    /// kept. The rounds after it are there to reconcile the views without losing the style;
    /// a round that loses either is a step that did not descend, and a descent method does
    /// not take it (BENCH.md §5x).
    Better,
}

/// Where the stylizing trainer's rays cross their pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Rays {
    /// Through the pixel's centre, as the realistic field trains.
    #[default]
    Centre,
    /// Anywhere in the pixel's square (`TrainConfig::area_rays`): a painted view's pixel is
    /// the paint over its square, so the field cannot put one colour at the centre the
    /// training ray sees and another between centres, where a new view's rays fall.
    Area,
}

/// Whether the targets the field trains on make up for the colours it falls short of.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ColourFit {
    /// The targets as fused and stepped.
    #[default]
    Plain,
    /// The targets mapped, per Oklab channel, so that the field shows their colour
    /// distribution (`palette::compensated`), recalibrated against the field's renders at
    /// the start of every round and halfway through the first.
    Compensate,
    /// The targets moved by an offset per colour that makes up what the field showed short
    /// of them at the training views (`colour_offsets`), recalibrated at the start of every
    /// round and every `StylizeOptions::calibration_interval` steps within a round.
    Joint,
}

/// What the consensus rounds do to the targets' colour distribution (`Targets::Consensus`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Palette {
    /// The median alone: iterated, it narrows the distribution (the tails survive only where
    /// most neighbours read them) and the painting's extreme colours fade round by round.
    #[default]
    Free,
    /// Before each consensus round the previous targets are mapped onto the colour
    /// distribution of the first fused stylizations (`palette`), then the median reconciles.
    Keep,
}

/// What the stylized field keeps of the realistic field's view-dependent colour (the view
/// MLP's specular residual; the MLP is frozen while stylizing either way).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ViewColour {
    /// The realistic field's view MLP, frozen: it goes on adding the residual the realistic
    /// field learnt, now computed from the painted colours.
    #[default]
    Source,
    /// None: the view MLP's output layer is zeroed, so the stylized field is diffuse. A
    /// painting has no highlights that move with the viewer, and the kept residual, close to
    /// a constant offset, cut off the painting's darkest or brightest colours (BENCH.md §5p).
    Diffuse,
}

/// Where round t's target step `β_t × (fused − start)` starts from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StepFrom {
    /// The current field's render of the view (round 1 always: there is no earlier target).
    #[default]
    Render,
    /// The previous round's training target: with harmonic steps, round t's target is the
    /// running mean of the first t fused targets, made of the stylizer's pixels alone. Started
    /// from the render, the field's reconstruction (a little blurred, and short of the
    /// painting's rarest colours) is mixed back into every target and compounds round after
    /// round (BENCH.md §5n).
    Targets,
}

/// What each round's fusion starts from (with `Content::Realistic` and fusion on).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Targets {
    /// The stylizations of the realistic renders, every round.
    #[default]
    Once,
    /// The previous round's fused targets: every round reprojects each view's target into its
    /// neighbours through the current depth and takes the median again, so texture the views
    /// disagree on is reconciled a little more each round instead of being fitted.
    Consensus,
}

/// How a round fuses fresh stylizations (every round with `Targets::Once`, the first round
/// with `Targets::Consensus`, whose later rounds take the median of the previous consensus).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Fusion {
    /// The per-channel median of a view's colour and its `fuse_views` nearest views' colours
    /// at the same surface point (`fusion::fuse`).
    #[default]
    Median,
    /// Each surface point takes the colour the nearest view that sees it painted there
    /// (`fusion::fuse_owner`): one painting's strokes per point instead of a blend of five.
    Owner,
}

/// Training steps of each round; the run's total is `rounds × steps_per_round` either way.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RoundSteps {
    /// `steps_per_round` every round.
    #[default]
    Equal,
    /// In proportion to 1/t, as the harmonic target step: most of the budget goes to round 1,
    /// where the style is taken; later rounds, whose targets change by O(1/t), refine.
    Harmonic,
}

/// What of a view the stylizer paints.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Region {
    /// The whole view.
    #[default]
    View,
    /// Views with a silhouette (bounded objects): the object's box, with a margin of 1/16 of
    /// the view, at the scale the whole view would be painted at (`Stylizer::stylize_crop`).
    /// A feed-forward stylizer normalizes its features over its whole input; an object view
    /// is mostly empty background, so over the whole view the background's statistics set
    /// how the object is painted (a bright halo, grain at the silhouette; BENCH.md §5f).
    /// Views without a silhouette, and boxes that fill the view, are painted whole.
    Object,
}

/// The image the stylizer is given for each training view.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Content {
    /// The current field's render, every round (Algorithm 1 as published).
    #[default]
    Render,
    /// The realistic field's render, stylized once: every round fuses the same stylizations
    /// (through the current field's depth), so the loop's operator stops depending on the
    /// field's colours.
    Realistic,
}

/// The step of round t (1-based) from the render toward the fused stylization.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StepSchedule {
    /// `target_step` every round.
    #[default]
    Constant,
    /// `target_step / t`: with step 1 the target is the running mean of the rounds' fused
    /// stylizations (a Mann iteration with harmonic steps).
    Harmonic,
}

/// The learning rate's exponential decay (`lr_final^progress`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LrSchedule {
    /// Decays over each round and starts again at the full rate in the next.
    #[default]
    Round,
    /// Decays once over all rounds, so later rounds move the field less.
    Run,
}

impl StylizeOptions {
    /// The target step of round `round` (1-based).
    pub fn step_of_round(&self, round: usize) -> f32 {
        match self.step_schedule {
            StepSchedule::Constant => self.target_step,
            StepSchedule::Harmonic => self.target_step / round.max(1) as f32,
        }
    }

    /// Whether the targets are recalibrated (`ColourFit`) before step `s` of round `round`
    /// (1-based) is taken; a round that starts training is calibrated anyway (but round 1,
    /// which has no field of its own to measure until its first calibration here).
    pub fn calibrates_at(&self, round: usize, s: u64) -> bool {
        match self.colour_fit {
            ColourFit::Plain => false,
            ColourFit::Compensate => round == 1 && s == self.steps_of_round(1) / 2,
            ColourFit::Joint => s > 0 && s.is_multiple_of(self.calibration_interval()),
        }
    }

    /// The step of round 1 at which the targets are first calibrated (`u64::MAX`: never).
    pub fn first_calibration(&self) -> u64 {
        (1..self.steps_of_round(1)).find(|&s| self.calibrates_at(1, s)).unwrap_or(u64::MAX)
    }

    /// `ColourFit::Joint`: training steps between calibrations, as many as the last round
    /// takes, and at most half the first round's (so that round 1, which has no field to
    /// measure until it has trained, is calibrated at least once). The field's shortfall
    /// changes with the steps it takes, not with the rounds, so it is measured after every
    /// equal share of them: with `RoundSteps::Harmonic` (most of the steps in round 1) and 5
    /// rounds, round 1 is calibrated five times within it at the default 300 steps a round
    /// (four at 100 or 200: the rounding decides), and round 5 once, at its start.
    pub fn calibration_interval(&self) -> u64 {
        self.steps_of_round(self.rounds).min(self.steps_of_round(1) / 2).max(1)
    }

    /// Training steps of round `round` (1-based); at least 1.
    pub fn steps_of_round(&self, round: usize) -> u64 {
        let n = self.steps_per_round.max(1);
        match self.round_steps {
            RoundSteps::Equal => n,
            RoundSteps::Harmonic => {
                let rounds = self.rounds.max(1);
                let total = n * rounds as u64;
                let h: f64 = (1..=rounds).map(|t| 1.0 / t as f64).sum();
                // cumulative shares, rounded, so the rounds add up to the total exactly
                let upto = |t: usize| ((1..=t).map(|k| 1.0 / k as f64).sum::<f64>() / h * total as f64).round() as u64;
                let t = round.clamp(1, rounds);
                (upto(t) - upto(t - 1)).max(1)
            }
        }
    }

    /// Learning-rate progress in [0, 1] of step `s` of round `round` (1-based).
    pub fn lr_progress(&self, round: usize, s: u64) -> f64 {
        let n = self.steps_of_round(round).max(1);
        match self.lr_schedule {
            LrSchedule::Round => s as f64 / n as f64,
            LrSchedule::Run => {
                let before: u64 = (1..round.max(1)).map(|t| self.steps_of_round(t)).sum();
                let total: u64 = (1..=self.rounds.max(1)).map(|t| self.steps_of_round(t)).sum();
                (before + s) as f64 / total.max(1) as f64
            }
        }
    }
}

fn full_step() -> f32 {
    1.0
}

/// One finished round: the users' "error against run time".
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RoundRecord {
    pub round: usize,
    /// Wall seconds since the run started (summed over resumes).
    pub wall_seconds: f64,
    pub render_seconds: f64,
    pub stylize_seconds: f64,
    pub train_seconds: f64,
    /// PSNR of the field against this round's stylized targets (training rays).
    pub fit_psnr: f64,
    /// Distance of the field's renders to the style (Magenta style embeddings); lower = more
    /// stylized. None when the embedding model is not installed.
    pub style_distance: Option<f64>,
    /// Warped-frame MSE along the novel path, frames (i, i+1) and (i, i+7).
    pub short_range: Option<f64>,
    pub long_range: Option<f64>,
    /// The weight-free style distance (`style_metric`) of the scene pixels of the style ring
    /// (`consistency::STYLE_RING`) to the style picture; None without a consistency path.
    #[serde(default)]
    pub style_swd: Option<crate::style_metric::StyleScore>,
    /// The Gram style distance (`style_gram`) of the same frames; None without a path or
    /// without the model.
    #[serde(default)]
    pub style_gram: Option<f64>,
    /// Fraction of scene pixels whose target took other views' colours (median: fused with at
    /// least one neighbour; owner: painted by another view).
    #[serde(default)]
    pub fused_fraction: Option<f64>,
    /// The target step this round used (`StylizeOptions::step_of_round`).
    #[serde(default)]
    pub target_step: Option<f32>,
    /// `KeepRounds::Better`: what this round's field measured when it was discarded (None: kept).
    /// The scores above are then those of the field the round ends with, the kept one.
    #[serde(default)]
    pub discarded: Option<RoundScores>,
}

/// What the per-round measurement says of one field.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RoundScores {
    pub style_distance: Option<f64>,
    pub short_range: Option<f64>,
    pub long_range: Option<f64>,
    pub style_swd: Option<crate::style_metric::StyleScore>,
    pub style_gram: Option<f64>,
}

impl RoundScores {
    /// Whether a field scoring `self` may replace one scoring `kept` (`KeepRounds::Better`): no
    /// worse on either warp error or on the weight-free style distance. A measure either
    /// field lacks does not count (no path: every round is kept).
    pub fn no_worse_than(&self, kept: &RoundScores) -> bool {
        self.worse_than(kept).is_empty()
    }

    /// The measures on which `self` is worse than `kept` (names as a person reads them).
    pub fn worse_than(&self, kept: &RoundScores) -> Vec<&'static str> {
        let worse = |a: Option<f64>, b: Option<f64>| matches!((a, b), (Some(a), Some(b)) if a > b);
        [
            ("short-range warp error", worse(self.short_range, kept.short_range)),
            ("long-range warp error", worse(self.long_range, kept.long_range)),
            ("style distance", worse(self.style_swd.map(|s| s.total), kept.style_swd.map(|s| s.total))),
        ]
        .into_iter()
        .filter_map(|(name, w)| w.then_some(name))
        .collect()
    }
}

impl RoundRecord {
    /// What the field this round trained measured, kept or not.
    pub fn trained(&self) -> RoundScores {
        self.discarded.unwrap_or_else(|| self.scores())
    }

    /// What the field this round ends with measured.
    pub fn scores(&self) -> RoundScores {
        RoundScores {
            style_distance: self.style_distance,
            short_range: self.short_range,
            long_range: self.long_range,
            style_swd: self.style_swd,
            style_gram: self.style_gram,
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct StylizeState {
    pub options: StylizeOptions,
    pub rounds_done: usize,
    pub records: Vec<RoundRecord>,
}

impl StylizeState {
    /// The round whose field the run holds: the last one not discarded (0: none yet).
    pub fn field_round(&self) -> usize {
        self.records.iter().rev().find(|r| r.discarded.is_none()).map(|r| r.round).unwrap_or(0)
    }
}

pub fn state_path(dir: &Path) -> PathBuf {
    RunDir::new(dir).stylize_record()
}

/// Progress callbacks, so the command line can draw bars without this crate knowing how.
pub trait Progress {
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

/// `ColourFit::Compensate` and `Joint`: `targets` made up for what the field, trained on
/// them, falls short of. What the field shows is measured on its renders of the training
/// views (`shown`, when the round has them; rendered here otherwise). The calibration builds
/// on the last one the run recorded, unless the field has trained on nothing but the targets
/// as they are (`as_they_are`: the first round until its first calibration), and records
/// its own.
/// - `Compensate`: the targets mapped so that the field shows their colour distribution per
///   Oklab channel (`palette::compensated`; what the field was trained on is the distribution
///   the last calibration asked for).
/// - `Joint`: the targets moved by the offsets per colour (`colour_offsets`), the field's
///   shortfall added with gain `1/k` at the run's k-th calibration.
fn compensate_targets(
    out: &Path,
    fit: ColourFit,
    trainer: &Trainer,
    views: &[View],
    bg: [f32; 3],
    has_alpha: bool,
    targets: &[Image],
    as_they_are: bool,
    shown: Option<(Vec<Image>, Vec<ViewGeometry>)>,
) -> Result<Vec<Image>> {
    let (shown, geoms) = shown.unwrap_or_else(|| field_views(&trainer.model, &trainer.pool, views, bg, has_alpha));
    if fit == ColourFit::Joint {
        let last = if as_they_are { None } else { ColourOffsets::load(out)? };
        let offsets = last.unwrap_or_default().step(targets, &shown, &geoms);
        offsets.save(out)?;
        return Ok(consensus::quantize(offsets.apply(targets, &geoms)));
    }
    let want = palette::Quantiles::of(targets, &geoms);
    let trained = match palette::load_trained(out)? {
        Some(t) if !as_they_are => t,
        _ => want.clone(),
    };
    let asked = palette::compensated(&want, &palette::Quantiles::of(&shown, &geoms), &trained);
    palette::save_trained(out, &asked)?;
    Ok(consensus::quantize(palette::map_onto(targets, &geoms, &asked)))
}

/// A field's colours at `views` (before the background is laid under them, where they have
/// a silhouette) and the surface points it shows there.
pub fn field_views(model: &Model, pool: &WorkspacePool, views: &[View], bg: [f32; 3], has_alpha: bool) -> (Vec<Image>, Vec<ViewGeometry>) {
    views
        .iter()
        .map(|v| {
            let r = render_camera(model, pool, &v.c2w, &v.intrinsics, v.time, bg);
            let g = ViewGeometry::from_render(&model.space, &v.c2w, &v.intrinsics, v.time, &r.depth, &r.opacity);
            let colour = if has_alpha { unpremultiply(r.width, r.height, &r.rgb, &r.opacity, bg) } else { Image { width: r.width, height: r.height, data: r.rgb } };
            (colour, g)
        })
        .unzip()
}

/// Training views the rounds use: all, or `n` evenly spaced.
pub fn pick_views(views: &[View], n: usize) -> Vec<View> {
    if n == 0 || n >= views.len() {
        return views.to_vec();
    }
    (0..n).map(|i| views[i * views.len() / n].clone()).collect()
}

/// The training targets of the run in `out`'s last finished round, with the views they
/// belong to, when the run kept them (`StepFrom::Targets` saves them for the next round);
/// None otherwise.
pub fn last_round_targets(out: &Path, state: &StylizeState, data: &Dataset) -> Result<Option<(Vec<View>, Vec<Image>)>> {
    if state.rounds_done == 0 || state.options.step_from != StepFrom::Targets {
        return Ok(None);
    }
    let views = pick_views(&data.train, state.options.views);
    Ok(consensus::load(out, consensus::Kept::Targets, state.rounds_done, views.len())?.map(|t| (views, t)))
}

/// "--option: recorded recorded, asked asked" for each option in which `asked` differs from
/// `recorded` (the rounds aside: more or fewer rounds extend or end the same run), in the
/// command line's terms, so the user can repeat the run's options.
fn differing_options(recorded: &StylizeOptions, asked: &StylizeOptions) -> Vec<String> {
    let (Ok(serde_json::Value::Object(a)), Ok(serde_json::Value::Object(b))) =
        (serde_json::to_value(recorded), serde_json::to_value(asked))
    else {
        return vec!["options".into()];
    };
    let null = serde_json::Value::Null;
    a.iter()
        .filter(|(k, v)| k.as_str() != "rounds" && b.get(*k) != Some(*v))
        .map(|(k, v)| format!("{}: {} recorded, {} asked", cli_name(k), cli_value(k, v), cli_value(k, b.get(k).unwrap_or(&null))))
        .collect()
}

/// The command-line spelling of a `StylizeOptions` field.
fn cli_name(field: &str) -> String {
    match field {
        "source_run" => "the source run".into(),
        "plane_tv" => "--tv".into(),
        _ => format!("--{}", field.replace('_', "-")),
    }
}

/// The command-line spelling of a recorded option value.
fn cli_value(field: &str, v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::Null if field == "plane_tv" || field == "seed" => "source".into(),
        serde_json::Value::String(s) => s.clone(),
        other => other.to_string(),
    }
}

/// Start or resume a stylization run in `out`. `source` is the realistic model.
#[allow(clippy::too_many_arguments)]
pub fn run(
    opts: &StylizeOptions,
    data: &Dataset,
    source: &snerf_trainer::checkpoint::Checkpoint,
    stylizer: &dyn Stylizer,
    meters: &StyleMeters,
    style: &Image,
    out: &Path,
    progress: &mut dyn Progress,
) -> Result<StylizeState> {
    anyhow::ensure!(opts.rounds >= 1 && opts.steps_per_round >= 1, "a stylization needs at least one round of at least one step");
    anyhow::ensure!(opts.target_step > 0.0 && opts.target_step <= 1.0, "the target step must be in (0, 1], not {}", opts.target_step);
    let _lock = snerf_files::DirLock::acquire(out)?;
    let _graceful = snerf_files::interrupt::Graceful::enter();
    std::fs::create_dir_all(out.join("rounds")).with_context(|| format!("{}: cannot create", out.display()))?;
    let ck_path = RunDir::new(out).checkpoint();
    // Resume when the directory holds a run with the same options.
    let (mut state, mut trainer) = match std::fs::read(state_path(out)) {
        Ok(bytes) => {
            let state: StylizeState = serde_json::from_slice(&bytes)
                .with_context(|| format!("{}: not a stylization state file", state_path(out).display()))?;
            // More (or fewer) rounds extend (or end) the same run; anything else is another run.
            let same = StylizeOptions { rounds: opts.rounds, ..state.options.clone() } == *opts;
            if !same {
                bail!(
                    "{}: holds a stylization run with other options ({}); choose another --out or \
                     repeat the same options to resume",
                    out.display(),
                    differing_options(&state.options, opts).join("; ")
                );
            }
            let ck = if state.rounds_done > 0 { checkpoint::load(&ck_path)? } else { source.clone() };
            let t = trainer_from(ck, data, opts)?;
            let mut state = state;
            state.options.rounds = opts.rounds;
            (state, t)
        }
        Err(_) => {
            let state = StylizeState { options: opts.clone(), rounds_done: 0, records: Vec::new() };
            (state, trainer_from(source.clone(), data, opts)?)
        }
    };
    let realistic = Model {
        space: source.model.space.clone(),
        field: source.model.field.clone(),
        occ: source.model.occ.clone(),
        pixel_rays: source.model.pixel_rays,
        pixel_footprint: source.model.pixel_footprint,
    };
    let realistic_pool = WorkspacePool::new(realistic.field.params.len());
    let views = pick_views(&data.train, opts.views);
    let has_alpha = views_have_alpha(&data.train);
    let bg = eval_background(has_alpha);
    // Without a path (no per-round consistency) the embedding distance of held-out views.
    let style_embedding = meters.embedder.as_ref().map(|e| e.embed(style)).transpose()?;
    // The geometry of the novel path comes from the realistic field, once.
    let path = if opts.consistency_frames > 1 {
        Some(PathGeometry::new(&realistic, &realistic_pool, data, opts.consistency_frames)?)
    } else {
        None
    };
    let style_targets = path.as_ref().map(|p| meters.targets(p, style)).transpose()?;
    // `Content::Realistic`: the stylizations of the realistic renders, made once per process
    // (the stylizers are deterministic, so a resumed run makes the same ones again); with
    // consensus targets, the last round's fused targets instead (saved, so a resumed run
    // reads them back). The flag says which: `opts.fusion` applies to fresh stylizations, a
    // consensus is fused by the median again.
    let mut fixed: Option<(Vec<Image>, bool)> = None;
    let consensus_on = opts.targets == Targets::Consensus && opts.content == Content::Realistic && opts.fuse_views > 0;
    let mut wall = state.records.last().map(|r| r.wall_seconds).unwrap_or(0.0);
    // the last round's training targets (with `StepFrom::Targets` only, so Some means it)
    let mut previous: Option<Vec<Image>> = None;
    // `Palette::Keep`: the colour distribution of the first fused stylizations (saved with them)
    let mut reference: Option<palette::Quantiles> = None;
    for round in state.rounds_done..opts.rounds {
        let t_round = Instant::now();
        let resumed = partial::load(out, round + 1, data, opts)?;
        // `ColourFit::Compensate`, `Joint`: what the field shows at the training views and their geometry,
        // when this round rendered them anyway
        let mut shown: Option<(Vec<Image>, Vec<ViewGeometry>)> = None;
        let (stylized, render_seconds, stylize_seconds, first_step, trained_before, mut loss_ema, fused_fraction) = match resumed {
            Some(p) => {
                let partial::Resumed { trainer: t, targets, saved: p } = p;
                trainer = t;
                wall += p.round_wall;
                (targets, p.render_seconds, p.stylize_seconds, p.steps_done, p.train_seconds, p.loss_ema, None)
            }
            None => {
                // (1) render the training views from the current field
                progress.phase(round + 1, opts.rounds, "render", views.len() as u64);
                let t0 = Instant::now();
                let mut renders = Vec::with_capacity(views.len());
                // with a silhouette: what the field paints at each pixel, before the background
                // is laid under it (without one, the renders themselves)
                let mut painted = Vec::new();
                let mut geoms = Vec::with_capacity(views.len());
                for (i, v) in views.iter().enumerate() {
                    let r = render_camera(&trainer.model, &trainer.pool, &v.c2w, &v.intrinsics, v.time, bg);
                    if opts.fuse_views > 0 {
                        geoms.push(ViewGeometry::from_render(&trainer.model.space, &v.c2w, &v.intrinsics, v.time, &r.depth, &r.opacity));
                    }
                    if has_alpha {
                        painted.push(unpremultiply(r.width, r.height, &r.rgb, &r.opacity, bg));
                    }
                    renders.push(Image { width: r.width, height: r.height, data: r.rgb });
                    progress.tick(i as u64 + 1, "");
                }
                let render_seconds = t0.elapsed().as_secs_f64();
                // (2) stylize each render independently (or the realistic renders, once)
                progress.phase(round + 1, opts.rounds, "stylize", views.len() as u64);
                let t0 = Instant::now();
                let (stylized, stylized_is_consensus) = match opts.content {
                    Content::Render => (stylize_all(stylizer, &renders, &views, opts, round + 1, progress)?, false),
                    Content::Realistic => {
                        if fixed.is_none() && consensus_on && round > 0 {
                            // A resumed run continues the consensus of the last round begun.
                            fixed = consensus::load(out, consensus::Kept::Consensus, round, views.len())?.map(|c| (c, true));
                        }
                        if fixed.is_none() {
                            let content: Vec<Image> = views
                                .iter()
                                .map(|v| {
                                    let r = render_camera(&realistic, &realistic_pool, &v.c2w, &v.intrinsics, v.time, bg);
                                    Image { width: r.width, height: r.height, data: r.rgb }
                                })
                                .collect();
                            fixed = Some((stylize_all(stylizer, &content, &views, opts, round + 1, progress)?, false));
                        }
                        fixed.clone().expect("stylized above")
                    }
                };
                // (2a) fuse each target with its neighbours; (2b) a damped step toward it
                let (fused, fused_fraction) = if opts.fuse_views > 0 {
                    // fresh stylizations by `opts.fusion`; a consensus by the median again
                    let (mut f, frac) = if opts.fusion == Fusion::Owner && !stylized_is_consensus {
                        fusion::fuse_owner(&stylized, &geoms, opts.fusion_read)
                    } else if stylized_is_consensus && opts.palette == Palette::Keep {
                        // the previous consensus, its colours put back where the first fusion had them
                        if reference.is_none() {
                            reference = Some(palette::load(out)?);
                        }
                        let kept = palette::map_onto(&stylized, &geoms, reference.as_ref().expect("loaded above"));
                        fusion::fuse(&kept, &geoms, opts.fuse_views, opts.fusion_read)
                    } else {
                        fusion::fuse(&stylized, &geoms, opts.fuse_views, opts.fusion_read)
                    };
                    if consensus_on {
                        // The next round fuses these again (through its own depth).
                        f = consensus::quantize(f);
                        if opts.palette == Palette::Keep && !stylized_is_consensus {
                            // the first fusion of fresh stylizations: the palette the rounds keep
                            let q = palette::Quantiles::of(&f, &geoms);
                            palette::save(out, &q)?;
                            reference = Some(q);
                        }
                        consensus::save(out, consensus::Kept::Consensus, round + 1, &f)?;
                        fixed = Some((f.clone(), true));
                    }
                    (f, Some(frac))
                } else {
                    (stylized.clone(), None)
                };
                let step = opts.step_of_round(round + 1);
                if opts.step_from == StepFrom::Targets && previous.is_none() && round > 0 {
                    // a resumed run steps from the targets its last finished round saved
                    previous = consensus::load(out, consensus::Kept::Targets, round, views.len())?;
                }
                let targets: Vec<Image> = if let Some(prev) = &previous {
                    consensus::quantize(prev.iter().zip(&fused).map(|(p, f)| fusion::step_toward(p, f, step)).collect())
                } else if step < 1.0 {
                    // A target is the colour of the surface alone (training lays a random
                    // background under it by the view's alpha), so the step starts from the
                    // field's own colour, not from its render over the eval background:
                    // otherwise every round would lay the background into the rims again.
                    let from = if has_alpha { &painted } else { &renders };
                    from.iter().zip(&fused).map(|(r, f)| fusion::step_toward(r, f, step)).collect()
                } else {
                    fused
                };
                let stylize_seconds = t0.elapsed().as_secs_f64();
                write_round_sheet(&out.join("rounds").join(format!("round_{}.png", round + 1)), &renders, &stylized, &targets)?;
                if opts.fuse_views > 0 {
                    shown = Some((if has_alpha { painted } else { renders }, geoms));
                }
                (targets, render_seconds, stylize_seconds, 0, 0.0, None, fused_fraction)
            }
        };
        // (3) train on random rays across the stylized views
        let steps = opts.steps_of_round(round + 1);
        // `ColourFit::Compensate` and `Joint` calibrate when a round starts training and where
        // `calibrates_at` says (the first round trains on its targets as they are until its
        // first calibration, where there is a field to measure)
        let compensate = opts.colour_fit != ColourFit::Plain && opts.fuse_views > 0;
        let first_calibration = opts.first_calibration();
        let train_on = if compensate && (round > 0 || first_step > 0) {
            // a first round resumed before its first calibration has trained on the targets as they are
            let as_they_are = round == 0 && first_step <= first_calibration;
            compensate_targets(out, opts.colour_fit, &trainer, &views, bg, has_alpha, &stylized, as_they_are, shown.take())?
        } else {
            stylized.clone()
        };
        trainer.set_views(views.iter().zip(&train_on).map(|(v, s)| stylized_view(v, s)).collect())?;
        progress.phase(round + 1, opts.rounds, "train", steps);
        let t0 = Instant::now();
        for s in first_step..steps {
            // (the step a resumed round starts at was calibrated above)
            if compensate && s > first_step && opts.calibrates_at(round + 1, s) {
                let as_they_are = round == 0 && s == first_calibration;
                let c = compensate_targets(out, opts.colour_fit, &trainer, &views, bg, has_alpha, &stylized, as_they_are, None)?;
                trainer.set_views(views.iter().zip(&c).map(|(v, s)| stylized_view(v, s)).collect())?;
            }
            if snerf_files::interrupt::requested() {
                let p = partial::Partial {
                    round: round + 1,
                    steps_done: s,
                    render_seconds,
                    stylize_seconds,
                    train_seconds: trained_before + t0.elapsed().as_secs_f64(),
                    loss_ema,
                    round_wall: t_round.elapsed().as_secs_f64(),
                };
                partial::save(out, &p, &trainer, &stylized)?;
                return Err(snerf_files::interrupt::Interrupted(format!(
                    "round {} saved at step {s} of {} in {}; run the same command again to continue it",
                    round + 1,
                    steps,
                    out.display()
                ))
                .into());
            }
            let st = trainer.step(opts.lr_progress(round + 1, s));
            if !st.loss.is_finite() {
                bail!("round {}: training diverged at step {s} (loss {}); {} keeps the last finished round", round + 1, st.loss, out.display());
            }
            let l = loss_ema.map(|l| 0.9 * l + 0.1 * st.loss).unwrap_or(st.loss);
            loss_ema = Some(l);
            if s % 5 == 0 || s + 1 == steps {
                progress.tick(s + 1, &format!("fit {:.2} dB", mse_to_psnr(l)));
            }
        }
        let train_seconds = trained_before + t0.elapsed().as_secs_f64();
        if opts.step_from == StepFrom::Targets {
            // the next round steps from these (saved below with the round)
            previous = Some(consensus::quantize(stylized.clone()));
        }
        // measure (not counted as round time)
        wall += t_round.elapsed().as_secs_f64();
        progress.phase(round + 1, opts.rounds, "measure", 1);
        let measured = match (&path, &style_targets) {
            (Some(p), Some(targets)) => {
                let frames = p.render(&trainer.model, &trainer.pool);
                let style = meters.score(p, &frames, targets)?;
                RoundScores {
                    style_distance: style.embedding,
                    short_range: Some(p.warp_error(&frames, 1)),
                    long_range: Some(p.warp_error(&frames, 7)),
                    style_swd: Some(style.swd),
                    style_gram: style.gram,
                }
            }
            _ => {
                let style = meters.embedder.as_ref().zip(style_embedding.as_deref());
                let d = style.map(|(e, s)| style_distance_of(&trainer.model, &trainer.pool, data, bg, e, s)).transpose()?;
                RoundScores { style_distance: d, short_range: None, long_range: None, style_swd: None, style_gram: None }
            }
        };
        // `KeepRounds::Better`: the last kept field's scores are the last record's (a discarded
        // round records the kept field's)
        let worse_than_kept = state.records.last().map(RoundRecord::scores).filter(|kept| opts.keep_rounds == KeepRounds::Better && !measured.no_worse_than(kept));
        let (scores, discarded) = match worse_than_kept {
            Some(kept) => (kept, Some(measured)),
            None => (measured, None),
        };
        let RoundScores { style_distance, short_range, long_range, style_swd, style_gram } = scores;
        let record = RoundRecord {
            round: round + 1,
            wall_seconds: wall,
            render_seconds,
            stylize_seconds,
            train_seconds,
            fit_psnr: mse_to_psnr(loss_ema.unwrap_or(1.0)),
            style_distance,
            short_range,
            long_range,
            style_swd,
            style_gram,
            fused_fraction,
            target_step: Some(opts.step_of_round(round + 1)),
            discarded,
        };
        progress.round_done(&record);
        state.records.push(record);
        state.rounds_done = round + 1;
        // The checkpoint goes first: a kill between the two writes leaves the state one round
        // behind a newer field, and the resumed run repeats that round from it (harmless);
        // the other order could claim a round whose field was never saved.
        if discarded.is_none() {
            checkpoint::save(&trainer, &ck_path)?;
        } else {
            // the next round trains from the kept field, as a run resumed here would
            trainer = trainer_from(checkpoint::load(&ck_path)?, data, opts)?;
        }
        if let Some(p) = &previous {
            consensus::save(out, consensus::Kept::Targets, round + 1, p)?;
        }
        checkpoint::write_json_atomic(&state_path(out), &state)?;
        partial::clear(out);
    }
    Ok(state)
}

/// The colour a render shows before its background: `(rgb − (1 − opacity) × bg) / opacity`,
/// where the opacity is above 1/255 (elsewhere the pixel has no colour of its own; the
/// render's is kept, and training gives such pixels alpha 0 anyway).
fn unpremultiply(width: usize, height: usize, rgb: &[f32], opacity: &[f32], bg: [f32; 3]) -> Image {
    let mut data = rgb.to_vec();
    for (px, &a) in data.chunks_exact_mut(3).zip(opacity) {
        if a > 1.0 / 255.0 {
            for c in 0..3 {
                px[c] = ((px[c] - (1.0 - a) * bg[c]) / a).clamp(0.0, 1.0);
            }
        }
    }
    Image { width, height, data }
}

/// Stylize each image on its own (round `round`, for messages and progress); with
/// `Region::Object`, each view's object box (its alpha above one half).
fn stylize_all(
    stylizer: &dyn Stylizer,
    images: &[Image],
    views: &[View],
    opts: &StylizeOptions,
    round: usize,
    progress: &mut dyn Progress,
) -> Result<Vec<Image>> {
    let mut out = Vec::with_capacity(images.len());
    for (i, r) in images.iter().enumerate() {
        let mask: Option<Vec<bool>> =
            (opts.region == Region::Object && views_have_alpha(std::slice::from_ref(&views[i]))).then(|| views[i].rgba.chunks_exact(4).map(|p| p[3] >= 128).collect());
        let s = stylize_region(stylizer, r, mask.as_deref(), opts.style_res)
            .with_context(|| format!("round {round}: stylizing training view {}", views[i].path.display()))?;
        out.push(s);
        progress.tick(i as u64 + 1, "");
    }
    Ok(out)
}

/// `stylize_at`, or with a mask (true = object), only the object's box: the mask's bounding
/// box grown by 1/16 of the view's longer side, painted at the whole view's scale
/// (`Stylizer::stylize_crop`); the view outside the box keeps its own pixels. An empty mask,
/// or a box that fills the view, is the whole view.
pub fn stylize_region(stylizer: &dyn Stylizer, img: &Image, mask: Option<&[bool]>, res: usize) -> Result<Image> {
    let (w, h) = (img.width, img.height);
    let Some(mask) = mask else { return stylize_at(stylizer, img, res) };
    let mut b = (w, h, 0, 0);
    for (p, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
        let (x, y) = (p % w, p / w);
        b = (b.0.min(x), b.1.min(y), b.2.max(x + 1), b.3.max(y + 1));
    }
    let margin = w.max(h).div_ceil(16);
    let (x0, y0, x1, y1) = (b.0.saturating_sub(margin), b.1.saturating_sub(margin), (b.2 + margin).min(w), (b.3 + margin).min(h));
    if x1 <= x0 || y1 <= y0 || (x1 - x0 == w && y1 - y0 == h) {
        return stylize_at(stylizer, img, res);
    }
    let part = crate::stylizer::image_ops::crop(img, x0, y0, x1 - x0, y1 - y0);
    // `res` scales the view (and so the crop) before painting, as `stylize_at` does
    let long = w.max(h);
    let view_long = if res == 0 { long } else { res };
    let k = view_long as f32 / long as f32;
    let scaled = (view_long != long)
        .then(|| resize(&part, ((part.width as f32 * k).round() as usize).max(1), ((part.height as f32 * k).round() as usize).max(1)));
    let input = scaled.as_ref().unwrap_or(&part);
    let painted = check_output(stylizer, input, stylizer.stylize_crop(input, view_long)?)?;
    let painted = if painted.width == part.width && painted.height == part.height { painted } else { resize(&painted, part.width, part.height) };
    let mut out = img.clone();
    for y in y0..y1 {
        let row = (y - y0) * part.width * 3;
        out.data[(y * w + x0) * 3..(y * w + x1) * 3].copy_from_slice(&painted.data[row..row + part.width * 3]);
    }
    Ok(out)
}

/// A trainer on the source field with the rounds' settings; the optimizer starts afresh
/// (its moments belong to the realistic targets).
fn trainer_from(ck: snerf_trainer::checkpoint::Checkpoint, data: &Dataset, opts: &StylizeOptions) -> Result<Trainer> {
    let mut cfg = ck.cfg.clone();
    cfg.freeze_geometry = opts.appearance_only;
    cfg.freeze_view = true;
    if let Some(seed) = opts.seed {
        cfg.seed = seed;
    }
    if let Some(tv) = opts.plane_tv {
        cfg.tv = tv;
    }
    cfg.area_rays = opts.rays == Rays::Area;
    let mut model = ck.model;
    if opts.view_colour == ViewColour::Diffuse {
        let view = model.field.layout.view;
        view.make_diffuse(&mut model.field.params);
    }
    let adam = snerf_trainer::adam::Adam::new(model.field.params.len());
    let mut t = Trainer::from_parts(data, cfg, model, adam)?;
    t.step = ck.step;
    t.train_seconds = ck.train_seconds;
    t.samples_seen = ck.samples_seen;
    t.curve = ck.curve;
    Ok(t)
}

/// Stylize at a chosen resolution: resize so the longer side is `res`, stylize, resize back.
pub fn stylize_at(stylizer: &dyn Stylizer, img: &Image, res: usize) -> Result<Image> {
    let long = img.width.max(img.height);
    if res == 0 || res == long {
        return check_output(stylizer, img, stylizer.stylize(img)?);
    }
    let s = res as f32 / long as f32;
    let (w, h) = (((img.width as f32 * s).round() as usize).max(1), ((img.height as f32 * s).round() as usize).max(1));
    let up = resize(img, w, h);
    let out = check_output(stylizer, &up, stylizer.stylize(&up)?)?;
    Ok(resize(&out, img.width, img.height))
}

fn check_output(stylizer: &dyn Stylizer, input: &Image, out: Image) -> Result<Image> {
    if out.width != input.width || out.height != input.height || out.data.len() != out.width * out.height * 3 {
        bail!(
            "stylizer {} returned a {}x{} image for a {}x{} view",
            stylizer.name(),
            out.width,
            out.height,
            input.width,
            input.height
        );
    }
    if out.data.iter().any(|x| !x.is_finite()) {
        bail!("stylizer {} returned NaN or Inf for a {}x{} view", stylizer.name(), input.width, input.height);
    }
    Ok(out)
}

/// Bilinear resize of an RGB float image.
pub fn resize(img: &Image, w: usize, h: usize) -> Image {
    let buf: image::ImageBuffer<image::Rgb<f32>, Vec<f32>> =
        image::ImageBuffer::from_raw(img.width as u32, img.height as u32, img.data.clone()).expect("image size");
    let out = image::imageops::resize(&buf, w as u32, h as u32, image::imageops::FilterType::Triangle);
    Image { width: w, height: h, data: out.into_raw() }
}

/// The training view with its colours replaced by the stylized image; alpha is kept, so a
/// bounded object keeps its silhouette (its inside geometry is still free to change).
fn stylized_view(v: &View, s: &Image) -> View {
    let mut out = v.clone();
    for (px, rgb) in out.rgba.chunks_exact_mut(4).zip(s.data.chunks_exact(3)) {
        for c in 0..3 {
            px[c] = (rgb[c].clamp(0.0, 1.0) * 255.0).round() as u8;
        }
    }
    out
}

/// Style distance of the model's renders of (up to) 4 held-out views, averaged.
pub fn style_distance_of(
    model: &Model,
    pool: &WorkspacePool,
    data: &Dataset,
    bg: [f32; 3],
    embedder: &StyleEmbedder,
    style_embedding: &[f32],
) -> Result<f64> {
    let views = if data.test.is_empty() { &data.train } else { &data.test };
    let picked = pick_views(views, 4);
    let mut sum = 0.0;
    for v in &picked {
        let r = render_camera(model, pool, &v.c2w, &v.intrinsics, v.time, bg);
        let img = Image { width: r.width, height: r.height, data: r.rgb };
        sum += consistency::embedding_distance(&embedder.embed(&img)?, style_embedding);
    }
    Ok(sum / picked.len().max(1) as f64)
}

/// `rounds/round_N.png`: up to 4 views: render, the stylizer's output, the training target.
fn write_round_sheet(path: &Path, renders: &[Image], stylized: &[Image], targets: &[Image]) -> Result<()> {
    let n = renders.len().min(4);
    let picked: Vec<usize> = (0..n).map(|i| i * renders.len() / n.max(1)).collect();
    let rows: Vec<Vec<&Image>> = vec![
        picked.iter().map(|&i| &renders[i]).collect(),
        picked.iter().map(|&i| &stylized[i]).collect(),
        picked.iter().map(|&i| &targets[i]).collect(),
    ];
    checkpoint::write_png_atomic(path, &consistency::grid_image(&rows))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rim pixel rendered over the eval background gives back the surface's own colour, so
    /// a damped target step there does not carry the background into the target.
    #[test]
    fn unpremultiply_recovers_the_surface_colour() {
        let bg = [1.0, 1.0, 1.0];
        let surface = [0.3f32, 0.2, 0.1];
        let opacity = [1.0f32, 0.6, 0.1, 0.0];
        let rgb: Vec<f32> = opacity.iter().flat_map(|&a| (0..3).map(move |c| surface[c] * a + bg[c] * (1.0 - a))).collect();
        let out = unpremultiply(4, 1, &rgb, &opacity, bg);
        assert_eq!((out.width, out.height), (4, 1));
        for p in 0..3 {
            for c in 0..3 {
                assert!((out.data[p * 3 + c] - surface[c]).abs() < 1e-5, "pixel {p}: {:?}", &out.data[p * 3..p * 3 + 3]);
            }
        }
        // no coverage: the render's colour is kept (training gives the pixel alpha 0)
        assert_eq!(&out.data[9..12], &rgb[9..12]);
        // a plain step from the composited render would have whitened the rim
        let target = fusion::step_toward(&Image { width: 4, height: 1, data: rgb.clone() }, &Image::filled(4, 1, surface), 0.5);
        assert!(target.data[4] > surface[1] + 0.05);
    }

    /// A refused resume names the options as the command line spells them.
    #[test]
    fn differing_options_speak_the_command_line() {
        let recorded: StylizeOptions = serde_json::from_value(serde_json::json!({
            "source_run": "run", "data": "data", "style": "s.png", "stylizer": "arbitrary", "strength": 1.0,
            "rounds": 5, "steps_per_round": 300, "style_res": 0, "views": 0, "appearance_only": false,
            "consistency_frames": 16,
        }))
        .unwrap();
        // the record predates --tv and --view-colour: it ran with the source's weight and MLP
        assert_eq!((recorded.plane_tv, recorded.view_colour), (None, ViewColour::Source));
        // and --keep-rounds: its last round's field was the run's, whatever it measured
        assert_eq!(recorded.keep_rounds, KeepRounds::Every);
        let asked = StylizeOptions { rounds: 7, plane_tv: Some(0.0), view_colour: ViewColour::Diffuse, steps_per_round: 100, ..recorded.clone() };
        let mut d = differing_options(&recorded, &asked);
        d.sort();
        assert_eq!(d, ["--steps-per-round: 300 recorded, 100 asked", "--tv: source recorded, 0.0 asked", "--view-colour: source recorded, diffuse asked"]);
        assert!(differing_options(&recorded, &StylizeOptions { rounds: 9, ..recorded.clone() }).is_empty(), "more rounds extend the same run");
        // the record predates --seed too: it trained with the source run's
        assert_eq!(differing_options(&recorded, &StylizeOptions { seed: Some(3), ..recorded.clone() }), ["--seed: source recorded, 3 asked"]);
    }

    /// A field may replace the kept one when it is no worse on every measure both have.
    #[test]
    fn a_field_replaces_the_kept_one_when_no_measure_is_worse() {
        let swd = |total| crate::style_metric::StyleScore { total, color: total / 2.0, texture: total / 2.0, missed: 0.1 };
        let kept = RoundScores { style_distance: Some(5.0), short_range: Some(0.01), long_range: Some(0.02), style_swd: Some(swd(2.0)), style_gram: None };
        assert!(kept.no_worse_than(&kept), "ties keep");
        let better = RoundScores { short_range: Some(0.009), long_range: Some(0.019), style_swd: Some(swd(1.9)), ..kept };
        assert!(better.no_worse_than(&kept));
        assert!(!kept.no_worse_than(&better));
        // one measure worse is enough to discard, whatever the others gained
        assert!(!RoundScores { style_swd: Some(swd(2.001)), short_range: Some(0.001), long_range: Some(0.001), ..kept }.no_worse_than(&kept));
        assert!(!RoundScores { short_range: Some(0.0101), ..better }.no_worse_than(&kept));
        assert!(!RoundScores { long_range: Some(0.0201), ..better }.no_worse_than(&kept));
        assert_eq!(RoundScores { long_range: Some(0.0201), style_swd: Some(swd(2.5)), ..better }.worse_than(&kept), ["long-range warp error", "style distance"]);
        // the embedding and Gram distances are readouts, not measures the rounds are kept by
        assert!(RoundScores { style_distance: Some(9.0), style_gram: Some(9.0), ..kept }.no_worse_than(&kept));
        // no path, nothing to compare: kept
        let none = RoundScores { style_distance: None, short_range: None, long_range: None, style_swd: None, style_gram: None };
        assert!(none.no_worse_than(&kept) && kept.no_worse_than(&none));
    }

    /// Where each colour fit recalibrates within the rounds' training steps.
    #[test]
    fn joint_calibrations_are_spread_over_the_steps() {
        let mut o: StylizeOptions = serde_json::from_value(serde_json::json!({
            "source_run": "run", "data": "data", "style": "s.png", "stylizer": "arbitrary", "strength": 1.0,
            "rounds": 5, "steps_per_round": 100, "style_res": 0, "views": 0, "appearance_only": false,
            "consistency_frames": 16, "round_steps": "harmonic",
        }))
        .unwrap();
        let within = |o: &StylizeOptions, r: usize| (1..o.steps_of_round(r)).filter(|&s| o.calibrates_at(r, s)).collect::<Vec<_>>();
        assert_eq!((1..=5).map(|r| o.steps_of_round(r)).collect::<Vec<_>>(), [219, 109, 73, 55, 44]);
        assert!((1..=5).all(|r| within(&o, r).is_empty()), "plain: never");
        o.colour_fit = ColourFit::Compensate;
        assert_eq!(within(&o, 1), [109]);
        assert!((2..=5).all(|r| within(&o, r).is_empty()), "compensate: halfway through round 1 only");
        o.colour_fit = ColourFit::Joint;
        assert_eq!(o.calibration_interval(), 44);
        assert_eq!(within(&o, 1), [44, 88, 132, 176]);
        assert_eq!(within(&o, 2), [44, 88]);
        assert_eq!(within(&o, 5), Vec::<u64>::new());
        assert_eq!(o.first_calibration(), 44);
        o.rounds = 1;
        assert_eq!(within(&o, 1), [50], "one round: halfway");
    }
}
