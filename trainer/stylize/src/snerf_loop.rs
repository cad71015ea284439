//! SNeRF's stylization loop (Algorithm 1 of the paper). Starting from a field trained on
//! realistic views, each round
//!
//! 1. **renders** every training view from the current field (`steps::render_views`),
//! 2. **stylizes** views with an image stylizer (`steps::stylize_views`; an object's views
//!    in the object's box, `stylize_view::stylize_region`): with `Content::Render` (the
//!    default, the paper's loop) the current field's renders, every round; with
//!    `Content::Realistic` (the one-pass variant) the realistic field's renders, in round 1
//!    only,
//! 3. makes the **targets** (`steps::fuse`, `steps::running_mean`): fresh stylizations give
//!    every surface point the colour its nearest painter gave it (`fusion::fuse_owner`,
//!    reprojected through the field's depth); round t's target is the last round's moved
//!    toward this round's fused images by `StylizeOptions::step_of_round` (1/t² in the
//!    paper's loop, 1/t in the one-pass variant). A consensus step reconciles the views
//!    (`steps::reconcile`: the per-pixel median over a view and its neighbours, after
//!    mapping the colours back onto the first fusion's distribution, `palette`): with
//!    `Render` on the stepped targets each round, with `Realistic` on the previous round's
//!    fused images, which are round t's,
//! 4. **trains** the field on random rays across the targets (`steps::train`), most of the
//!    steps in round 1 (`StylizeOptions::steps_of_round`, in proportion to 1/t) under one
//!    learning-rate decay over the whole run, the targets moved by the colour offsets the
//!    field falls short of (`colour_offsets`, recalibrated every
//!    `StylizeOptions::calibration_interval` steps),
//! 5. **measures** the field on the loop's own path (`steps::measure`): warp errors and style
//!    distances, recorded as measured, with the frames they were measured on. Nothing is
//!    selected on them: every round's field is the next round's start and the last one is
//!    the run's. `snerf consistency` scores another path.
//!
//! **Why it converges.** Write a round as `x_t = C(x_{t−1} + a_t (S(x_{t−1}) − x_{t−1}))`,
//! where x is the targets, S renders the field trained on them, stylizes the renders and
//! fuses them, and C is the consensus step. A feed-forward stylizer has no fixed point: it
//! adds texture to whatever it is given, its own output included. So the paper's full step
//! (`a_t = 1`) adds detail the views disagree on every round, and so does a running mean
//! (`a_t = 1/t`): its steps shrink, but they add up without bound (Σ 1/t diverges), and
//! measured, the long-range warp error crept up round after round (BENCH.md §5). With
//! `a_t = 1/t²` the stylizer's say is summable: whatever it paints, it can move a target
//! value by at most `Σ_{k>t} 1/k² < 1/t` after round t, so the targets settle (a Cauchy
//! sequence) whatever the stylizer does, while every round still paints the current field
//! and adds, in a shrinking dose, what the earlier rounds' paintings missed. The consensus
//! step is a fixed point for texture the views agree on and pulls texture they disagree on
//! toward the neighbours', so the settling targets grow more consistent round by round; it
//! reads the neighbours bilinearly (`Content::consensus_read`), a small blur each round that
//! the next round's fresh painting restores (read pixel by pixel, the warp errors rose for
//! two rounds before they fell; BENCH.md §5b). The field follows them: its training steps
//! shrink with 1/t and its learning rate decays over the run. The rounds' scores are not
//! guaranteed to fall: a painting whose colours the blur takes can end a little farther
//! from the style than round 1 (BENCH.md §5e names the pairs). An optimizing stylizer
//! whose steps shrink as the render approaches the style (L-BFGS on `gatys`) would have a
//! fixed point of its own; at about 12 s a 256² view for 100 steps on 2 cores it is not the
//! default.
//!
//! With `Content::Realistic`, S depends on the field only through the depth the fusion
//! reprojects with, so the rounds approach one set of targets (a running mean, steps 1/t,
//! of repeated consensus steps on one stylization); the stylizer runs once. BENCH.md §5
//! measures the two side by side.
//!
//! The stylizing trainer: the view MLP's output is zeroed (a painting has no highlights that
//! move with the viewer, so the stylized field is diffuse), no total-variation smoothing of
//! the planes (the field has to hold pixel-scale strokes), and each ray crosses its pixel
//! anywhere in the pixel's square (a painted pixel is the paint over its square).
//!
//! A run lives in its own directory (`SRUN`): `checkpoint.snerfck` (the field),
//! `stylize.json` (options and one record per round), `rounds/round_N.png` (renders,
//! stylizations and targets), and what the next round needs (`targets/`, `consensus/`,
//! `colour_offsets.json`). Files are replaced atomically after each round, so a killed run
//! resumes at its last finished round; Ctrl-C saves the round so far in `partial/`.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use snerf_data::{Dataset, View};
use snerf_trainer::checkpoint::{self, Checkpoint};
use snerf_trainer::eval::{eval_background, render_camera};
use snerf_trainer::render::WorkspacePool;
use snerf_trainer::run_dir::RunDir;
use snerf_trainer::train::{mse_to_psnr, views_have_alpha, Model, Trainer};

mod consensus;
mod options;
mod partial;
mod record;
mod steps;

pub use crate::stylize_view::{resize, stylize_at, stylize_region};
pub use options::{Content, StylizeOptions, DEFAULT_CONTENT, DEFAULT_MAX_SIZE};
pub use record::{differing_options, state_path, Progress, Quiet, RoundRecord, StylizeState, LOOP_VERSION, STATE_FILE};

use crate::consistency::{PathGeometry, StyleMeters, StyleTargets};
use crate::fusion::ViewGeometry;
use crate::palette;
use crate::stylizer::{Image, StyleEmbedder, Stylizer};

/// What every round reads and none changes.
struct Setup<'a> {
    opts: &'a StylizeOptions,
    data: &'a Dataset,
    out: &'a Path,
    stylizer: &'a dyn Stylizer,
    /// The training views the rounds paint and train on.
    views: Vec<View>,
    has_alpha: bool,
    bg: [f32; 3],
    /// The realistic field (the one-pass variant paints its renders).
    realistic: (Model, WorkspacePool),
    /// The loop's own path with the style picture prepared on it (None: no per-round
    /// measurement).
    path: Option<(PathGeometry, StyleTargets)>,
    meters: &'a StyleMeters,
    /// Without a path, the style embedding the held-out views are scored against.
    style_embedding: Option<Vec<f32>>,
}

/// What a round hands to the next (the loop's state besides the field; each part is also
/// on disk, so a resumed run reads it back).
#[derive(Default)]
struct Carry {
    /// The last round's targets: the running mean the next round steps from.
    previous: Option<Vec<Image>>,
    /// `Content::Realistic`: the last round's fused targets, which the next fuses again.
    consensus: Option<Vec<Image>>,
    /// `Content::Realistic`: the colour distribution of the first fusion.
    palette: Option<palette::Quantiles>,
}

/// Start or resume a stylization run in `out`. `source` is the realistic run's checkpoint.
#[allow(clippy::too_many_arguments)]
pub fn run(
    opts: &StylizeOptions,
    data: &Dataset,
    source: &Checkpoint,
    stylizer: &dyn Stylizer,
    meters: &StyleMeters,
    style: &Image,
    out: &Path,
    progress: &mut dyn Progress,
) -> Result<StylizeState> {
    anyhow::ensure!(opts.rounds >= 1 && opts.steps_per_round >= 1, "a stylization needs at least one round of at least one step");
    let _lock = snerf_files::DirLock::acquire(out)?;
    let _graceful = snerf_files::interrupt::Graceful::enter();
    std::fs::create_dir_all(out.join("rounds")).with_context(|| format!("{}: cannot create", out.display()))?;
    let ck_path = RunDir::new(out).checkpoint();
    let (mut state, mut trainer) = match StylizeState::resume(out, opts)? {
        Some(s) if s.rounds_done > 0 => (s, trainer_from(checkpoint::load(&ck_path)?, data, opts)?),
        Some(s) => (s, trainer_from(source.clone(), data, opts)?),
        None => (StylizeState::new(opts), trainer_from(source.clone(), data, opts)?),
    };
    let setup = Setup::new(opts, data, source, stylizer, meters, style, out, progress)?;
    let mut carry = Carry::default();
    let mut wall = state.records.last().map(|r| r.wall_seconds).unwrap_or(0.0);
    for round in state.rounds_done + 1..=opts.rounds {
        let t_round = Instant::now();
        let mut prepared = match partial::load(out, round, data, opts)? {
            Some(resumed) => {
                trainer = resumed.trainer;
                steps::Prepared::resumed(resumed.targets, resumed.saved)
            }
            None => steps::prepare(&setup, &trainer, &mut carry, round, progress)?,
        };
        let trained = steps::train(&setup, &mut trainer, &mut prepared, round, t_round, progress)?;
        wall += prepared.wall_before + t_round.elapsed().as_secs_f64();
        let scores = steps::measure(&setup, &trainer, round, progress)?;
        let record = RoundRecord {
            round,
            wall_seconds: wall,
            render_seconds: prepared.render_seconds,
            stylize_seconds: prepared.stylize_seconds,
            stylized_views: prepared.stylized_views,
            train_seconds: trained.seconds,
            fit_psnr: mse_to_psnr(trained.loss_ema.unwrap_or(1.0)),
            style_distance: scores.style_distance,
            short_range: scores.short_range,
            long_range: scores.long_range,
            style_swd: scores.style_swd,
            style_gram: scores.style_gram,
            measured_on: scores.measured_on,
            fused_fraction: prepared.fused_fraction,
            target_step: Some(opts.step_of_round(round)),
        };
        progress.round_done(&record);
        carry.previous = Some(consensus::quantize(prepared.targets));
        finish_round(out, &mut state, record, &trainer, &carry)?;
    }
    Ok(state)
}

/// Saves a finished round: the field first (a kill between the writes leaves the record a
/// round behind a newer field, and the resumed run repeats that round from it; the other
/// order could claim a round whose field was never saved), the targets the next round steps
/// from, then the record.
fn finish_round(out: &Path, state: &mut StylizeState, record: RoundRecord, trainer: &Trainer, carry: &Carry) -> Result<()> {
    let round = record.round;
    state.records.push(record);
    state.rounds_done = round;
    checkpoint::save(trainer, &RunDir::new(out).checkpoint())?;
    if let Some(p) = &carry.previous {
        consensus::save(out, consensus::Kept::Targets, round, p)?;
    }
    checkpoint::write_json_atomic(&state_path(out), state)?;
    partial::clear(out);
    Ok(())
}

impl<'a> Setup<'a> {
    #[allow(clippy::too_many_arguments)]
    fn new(
        opts: &'a StylizeOptions,
        data: &'a Dataset,
        source: &Checkpoint,
        stylizer: &'a dyn Stylizer,
        meters: &'a StyleMeters,
        style: &Image,
        out: &'a Path,
        progress: &mut dyn Progress,
    ) -> Result<Setup<'a>> {
        let realistic = source.model.clone();
        let pool = WorkspacePool::new(realistic.field.params.len());
        let has_alpha = views_have_alpha(&data.train);
        // The geometry of the loop's path comes from the realistic field, once.
        let path = if opts.consistency_frames > 1 {
            let total = (opts.consistency_frames + crate::consistency::STYLE_RING) as u64;
            progress.phase(0, opts.rounds, "measure path", total);
            let p = PathGeometry::new_with_progress(&realistic, &pool, data, opts.consistency_frames, &mut |done, _| progress.tick(done as u64, ""))?;
            let targets = meters.targets(&p, style)?;
            Some((p, targets))
        } else {
            None
        };
        let style_embedding = meters.embedder.as_ref().map(|e| e.embed(style)).transpose()?;
        Ok(Setup {
            opts,
            data,
            out,
            stylizer,
            views: pick_views(&data.train, opts.views),
            has_alpha,
            bg: eval_background(has_alpha),
            realistic: (realistic, pool),
            path,
            meters,
            style_embedding,
        })
    }
}

/// A trainer on `ck`'s field with the stylizing settings (module doc); the optimizer
/// starts afresh (its moments belong to the realistic targets).
fn trainer_from(ck: Checkpoint, data: &Dataset, opts: &StylizeOptions) -> Result<Trainer> {
    let mut cfg = ck.cfg.clone();
    cfg.freeze_geometry = opts.appearance_only;
    cfg.freeze_view = true;
    cfg.seed = opts.seed.unwrap_or(cfg.seed);
    cfg.tv = 0.0;
    cfg.area_rays = true;
    let mut model = ck.model;
    if opts.appearance_only {
        // colour learns through a hidden layer of its own over the frozen features
        // (`snerf_trainer::field::ColourHead`): a linear map of the density's hidden layer
        // alone stays visibly farther from the painting (BENCH.md, "Style layers")
        model.field = model.field.with_colour_head()?;
        cfg.field = model.field.cfg.clone();
    }
    let view = model.field.layout.view;
    view.make_diffuse(&mut model.field.params);
    let adam = snerf_trainer::adam::Adam::new(model.field.params.len());
    let mut t = Trainer::from_parts(data, cfg, model, adam)?;
    t.step = ck.step;
    t.train_seconds = ck.train_seconds;
    t.samples_seen = ck.samples_seen;
    t.curve = ck.curve;
    Ok(t)
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
/// belong to (None: the run kept none).
pub fn last_round_targets(out: &Path, state: &StylizeState, data: &Dataset) -> Result<Option<(Vec<View>, Vec<Image>)>> {
    if state.rounds_done == 0 || state.loop_version != LOOP_VERSION {
        return Ok(None);
    }
    let views = pick_views(&data.train, state.options.views);
    Ok(consensus::load(out, consensus::Kept::Targets, state.rounds_done, views.len())?.map(|t| (views, t)))
}

/// Style distance of the model's renders of (up to) 4 held-out views, averaged.
pub fn style_distance_of(model: &Model, pool: &WorkspacePool, data: &Dataset, bg: [f32; 3], embedder: &StyleEmbedder, style_embedding: &[f32]) -> Result<f64> {
    let views = if data.test.is_empty() { &data.train } else { &data.test };
    let picked = pick_views(views, 4);
    let mut sum = 0.0;
    for v in &picked {
        let r = render_camera(model, pool, &v.c2w, &v.intrinsics, v.time, bg);
        let img = Image { width: r.width, height: r.height, data: r.rgb };
        sum += crate::consistency::embedding_distance(&embedder.embed(&img)?, style_embedding);
    }
    Ok(sum / picked.len().max(1) as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A rim pixel rendered over the eval background gives back the surface's own colour, so
    /// a target step there does not carry the background into the target.
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
    }

    /// A refused resume names the options as the command line spells them; a record an
    /// earlier release wrote is read but not resumed.
    #[test]
    fn resumes_refuse_other_options_and_earlier_releases() {
        let dir = snerf_files::ScratchDir::new("snerf-sloop-unit", "resume").unwrap();
        let recorded = StylizeOptions { rounds: 5, steps_per_round: 300, ..StylizeOptions::default() };
        let asked = StylizeOptions { rounds: 7, steps_per_round: 100, seed: Some(3), ..recorded.clone() };
        let mut d = differing_options(&recorded, &asked);
        d.sort();
        assert_eq!(d, ["--seed: source recorded, 3 asked", "--steps-per-round: 300 recorded, 100 asked"]);
        assert!(differing_options(&recorded, &StylizeOptions { rounds: 9, ..recorded.clone() }).is_empty(), "more rounds extend the same run");
        checkpoint::write_json_atomic(&state_path(&dir), &StylizeState::new(&recorded)).unwrap();
        let e = StylizeState::resume(&dir, &asked).unwrap_err();
        assert!(format!("{e:#}").contains("--steps-per-round: 300 recorded, 100 asked"), "{e:#}");
        let s = StylizeState::resume(&dir, &StylizeOptions { rounds: 9, ..recorded.clone() }).unwrap().unwrap();
        assert_eq!(s.options.rounds, 9);
        // an earlier release's record (its options had --keep-rounds, --palette, ...)
        let old = serde_json::json!({
            "options": { "source_run": "run", "data": "data", "style": "s.png", "stylizer": "arbitrary", "strength": 1.0,
                "rounds": 5, "steps_per_round": 300, "style_res": 0, "views": 0, "appearance_only": false,
                "consistency_frames": 16, "fuse_views": 4, "content": "realistic", "keep_rounds": "better", "palette": "keep" },
            "rounds_done": 2,
            "records": [{ "round": 1, "wall_seconds": 1.0, "render_seconds": 0.1, "stylize_seconds": 0.2, "train_seconds": 0.5,
                "fit_psnr": 30.0, "style_distance": null, "short_range": 0.01, "long_range": 0.02,
                "discarded": { "short_range": 0.5 } }],
        });
        checkpoint::write_json_atomic(&state_path(&dir), &old).unwrap();
        let read = StylizeState::read(&dir).unwrap().unwrap();
        assert_eq!((read.loop_version, read.records[0].short_range), (0, Some(0.01)), "an earlier release's record reads");
        let e = StylizeState::resume(&dir, &read.options).unwrap_err();
        assert!(format!("{e:#}").contains("earlier snerf release"), "{e:#}");
    }

    /// The schedule: target steps 1/t² (the paper's loop, the default) or 1/t (the one-pass
    /// variant's running mean), training steps in proportion to 1/t, one learning-rate
    /// decay, and calibrations spread over the steps.
    #[test]
    fn the_schedule_follows_the_running_mean() {
        let o = StylizeOptions { rounds: 5, steps_per_round: 100, ..StylizeOptions::default() };
        assert_eq!(o.content, Content::Render, "the paper's loop is the default");
        assert_eq!((1..=5).map(|r| o.step_of_round(r)).collect::<Vec<_>>(), [1.0, 0.25, 1.0 / 9.0, 1.0 / 16.0, 1.0 / 25.0]);
        let one_pass = StylizeOptions { content: Content::Realistic, ..o.clone() };
        assert_eq!((1..=5).map(|r| one_pass.step_of_round(r)).collect::<Vec<_>>(), [1.0, 0.5, 1.0 / 3.0, 0.25, 0.2]);
        assert_eq!((1..=5).map(|r| one_pass.steps_of_round(r)).collect::<Vec<_>>(), (1..=5).map(|r| o.steps_of_round(r)).collect::<Vec<_>>());
        let steps: Vec<u64> = (1..=5).map(|r| o.steps_of_round(r)).collect();
        assert_eq!(steps, [219, 109, 73, 55, 44]);
        assert_eq!(steps.iter().sum::<u64>(), 500);
        let all: Vec<f64> = (1..=5).flat_map(|t| (0..steps[t - 1]).map(move |s| (t, s))).map(|(t, s)| o.lr_progress(t, s)).collect();
        assert_eq!(all[0], 0.0);
        assert!(all.windows(2).all(|w| w[1] > w[0]), "one decay, continuous across rounds");
        assert!((all[all.len() - 1] - 499.0 / 500.0).abs() < 1e-12);
        assert_eq!(o.calibration_interval(), 44);
        assert_eq!((1..steps[0]).filter(|&s| o.calibrates_at(s)).collect::<Vec<_>>(), [44, 88, 132, 176]);
        let one = StylizeOptions { rounds: 1, ..o };
        assert_eq!(one.calibration_interval(), 50, "one round: halfway");
    }
}
