//! The steps of one round, each on its own: render → stylize → targets (fuse, running
//! mean) → train → measure (`snerf_loop`'s module doc says why each is what it is).

use std::time::Instant;

use anyhow::{bail, Context, Result};
use snerf_data::View;
use snerf_trainer::checkpoint;
use snerf_trainer::eval::render_camera;
use snerf_trainer::train::{mse_to_psnr, Model, Trainer};

use super::consensus::{self, Kept};
use super::partial::{self, Partial};
use super::{field_views, style_distance_of, unpremultiply, Carry, Content, Progress, Setup};
use crate::colour_offsets::ColourOffsets;
use crate::fusion::{self, Read, ViewGeometry};
use crate::palette;
use crate::style_metric::StyleScore;
use crate::stylize_view::stylize_region;
use crate::stylizer::Image;

/// The field's renders of the training views.
pub struct Rendered {
    /// Over the background (what a viewer sees; what the stylizer is given).
    pub shown: Vec<Image>,
    /// The field's own colour, before the background (with a silhouette; else `shown`).
    pub colour: Vec<Image>,
    pub geoms: Vec<ViewGeometry>,
}

/// A round's targets, ready to train on, and what making them took.
pub struct Prepared {
    pub targets: Vec<Image>,
    /// The field's colours and geometry at the training views when this round rendered them
    /// (the first colour calibration measures them).
    pub shown: Option<(Vec<Image>, Vec<ViewGeometry>)>,
    pub render_seconds: f64,
    pub stylize_seconds: f64,
    pub stylized_views: Option<usize>,
    pub fused_fraction: Option<f64>,
    /// A resumed round: the step it continues from, its training seconds and wall time so far.
    pub first_step: u64,
    pub trained_before: f64,
    pub loss_ema: Option<f64>,
    pub wall_before: f64,
}

impl Prepared {
    pub fn resumed(targets: Vec<Image>, p: Partial) -> Prepared {
        Prepared {
            targets,
            shown: None,
            render_seconds: p.render_seconds,
            stylize_seconds: p.stylize_seconds,
            stylized_views: p.stylized_views,
            fused_fraction: None,
            first_step: p.steps_done,
            trained_before: p.train_seconds,
            loss_ema: p.loss_ema,
            wall_before: p.round_wall,
        }
    }
}

/// Steps 1–3: render, stylize, fuse, step the running mean.
pub fn prepare(s: &Setup, trainer: &Trainer, carry: &mut Carry, round: usize, progress: &mut dyn Progress) -> Result<Prepared> {
    let t0 = Instant::now();
    let rendered = render_views(s, &trainer.model, &trainer.pool, round, progress);
    let render_seconds = t0.elapsed().as_secs_f64();
    let t0 = Instant::now();
    let (stylized, fresh) = stylize_views(s, carry, &rendered, round, progress)?;
    let (fused, fused_fraction) = fuse(s, carry, &stylized, fresh, &rendered.geoms, round)?;
    let targets = running_mean(s, carry, &rendered, fused, round)?;
    let stylize_seconds = t0.elapsed().as_secs_f64();
    write_round_sheet(&s.out.join("rounds").join(format!("round_{round}.png")), &rendered.shown, &stylized, &targets)?;
    Ok(Prepared {
        targets,
        shown: Some((rendered.colour, rendered.geoms)),
        render_seconds,
        stylize_seconds,
        stylized_views: Some(if fresh { stylized.len() } else { 0 }),
        fused_fraction,
        first_step: 0,
        trained_before: 0.0,
        loss_ema: None,
        wall_before: 0.0,
    })
}

/// Step 1: the current field's renders of the training views.
pub fn render_views(s: &Setup, model: &Model, pool: &snerf_trainer::render::WorkspacePool, round: usize, progress: &mut dyn Progress) -> Rendered {
    progress.phase(round, s.opts.rounds, "render", s.views.len() as u64);
    let mut out = Rendered { shown: Vec::new(), colour: Vec::new(), geoms: Vec::new() };
    for (i, v) in s.views.iter().enumerate() {
        let r = render_camera(model, pool, &v.c2w, &v.intrinsics, v.time, s.bg);
        out.geoms.push(ViewGeometry::from_render(&model.space, &v.c2w, &v.intrinsics, v.time, &r.depth, &r.opacity));
        let shown = Image { width: r.width, height: r.height, data: r.rgb };
        out.colour.push(if s.has_alpha { unpremultiply(r.width, r.height, &shown.data, &r.opacity, s.bg) } else { shown.clone() });
        out.shown.push(shown);
        progress.tick(i as u64 + 1, "");
    }
    out
}

/// Step 2: the images the round fuses, and whether they are fresh stylizations (else the
/// last round's consensus). `Content::Render` paints this round's renders; `Realistic`
/// paints the realistic field's renders in the first round (or a resumed run whose
/// consensus is gone) and goes on with the consensus after.
fn stylize_views(s: &Setup, carry: &mut Carry, rendered: &Rendered, round: usize, progress: &mut dyn Progress) -> Result<(Vec<Image>, bool)> {
    if s.opts.content == Content::Render {
        return Ok((stylize_all(s, &rendered.shown, round, progress)?, true));
    }
    if carry.consensus.is_none() && round > 1 && s.opts.fuse_views > 0 {
        carry.consensus = consensus::load(s.out, Kept::Consensus, round - 1, s.views.len())?;
    }
    if let Some(c) = &carry.consensus {
        return Ok((c.clone(), false));
    }
    let (model, pool) = &s.realistic;
    let content: Vec<Image> = s
        .views
        .iter()
        .map(|v| {
            let r = render_camera(model, pool, &v.c2w, &v.intrinsics, v.time, s.bg);
            Image { width: r.width, height: r.height, data: r.rgb }
        })
        .collect();
    Ok((stylize_all(s, &content, round, progress)?, true))
}

/// Each image stylized on its own; a view with a silhouette in its object's box.
fn stylize_all(s: &Setup, images: &[Image], round: usize, progress: &mut dyn Progress) -> Result<Vec<Image>> {
    progress.phase(round, s.opts.rounds, "stylize", images.len() as u64);
    let mut out = Vec::with_capacity(images.len());
    for (i, (img, v)) in images.iter().zip(&s.views).enumerate() {
        let mask: Option<Vec<bool>> = s.has_alpha.then(|| v.rgba.chunks_exact(4).map(|p| p[3] >= 128).collect());
        let painted = stylize_region(s.stylizer, img, mask.as_deref(), s.opts.style_res)
            .with_context(|| format!("round {round}: stylizing training view {}", v.path.display()))?;
        out.push(painted);
        progress.tick(i as u64 + 1, "");
    }
    Ok(out)
}

/// Step 3a: fresh stylizations give each surface point its nearest painter's colour, and
/// the first fusion's colour distribution is kept (`palette`); a consensus
/// (`Content::Realistic`, rounds 2…) is reconciled again (`reconcile`) and kept for the next
/// round.
fn fuse(s: &Setup, carry: &mut Carry, stylized: &[Image], fresh: bool, geoms: &[ViewGeometry], round: usize) -> Result<(Vec<Image>, Option<f64>)> {
    if s.opts.fuse_views == 0 {
        return Ok((stylized.to_vec(), None));
    }
    let (fused, fraction) = if fresh { fusion::fuse_owner(stylized, geoms, Read::Nearest) } else { reconcile(s, carry, stylized, geoms)? };
    let fused = consensus::quantize(fused);
    // the palette the rounds keep: the first fusion of fresh stylizations
    if round == 1 || (fresh && s.opts.content == Content::Realistic) {
        let q = palette::Quantiles::of(&fused, geoms);
        palette::save(s.out, &q)?;
        carry.palette = Some(q);
    }
    if s.opts.content == Content::Realistic {
        consensus::save(s.out, Kept::Consensus, round, &fused)?;
        carry.consensus = Some(fused.clone());
    }
    Ok((fused, Some(fraction)))
}

/// One consensus step: the targets mapped back onto the first fusion's colour distribution,
/// then each pixel the median of what its view and `fuse_views` neighbours hold at that
/// surface point (through the current depth; read as `Content::consensus_read` says). Texture the views agree on is a fixed point;
/// texture they disagree on moves toward what the neighbours hold.
fn reconcile(s: &Setup, carry: &mut Carry, targets: &[Image], geoms: &[ViewGeometry]) -> Result<(Vec<Image>, f64)> {
    if carry.palette.is_none() {
        carry.palette = Some(palette::load(s.out)?);
    }
    let kept = palette::map_onto(targets, geoms, carry.palette.as_ref().expect("loaded above"));
    Ok(fusion::fuse(&kept, geoms, s.opts.fuse_views, s.opts.content.consensus_read()))
}

/// Step 3b: round t's target is the last round's plus `step_of_round(t)` of the way to this
/// round's fused images: 1/t² of the way to the fresh stylization in the paper's loop
/// (`Content::Render`), 1/t to the consensus in the one-pass variant (the running mean). In
/// the paper's loop the stepped targets are reconciled across views once more
/// (`reconcile`), as the one-pass variant's consensus is: each round's fresh stylization
/// brings texture the views do not yet agree on. A resumed run reads the last round's
/// targets back; without them, the field's colours stand for them.
fn running_mean(s: &Setup, carry: &mut Carry, rendered: &Rendered, fused: Vec<Image>, round: usize) -> Result<Vec<Image>> {
    if round == 1 {
        return Ok(fused);
    }
    if carry.previous.is_none() {
        carry.previous = consensus::load(s.out, Kept::Targets, round - 1, s.views.len())?;
    }
    let previous = carry.previous.as_ref().unwrap_or(&rendered.colour);
    let step = s.opts.step_of_round(round);
    let mean: Vec<Image> = previous.iter().zip(&fused).map(|(p, f)| fusion::step_toward(p, f, step)).collect();
    if s.opts.content == Content::Render && s.opts.fuse_views > 0 {
        return Ok(consensus::quantize(reconcile(s, carry, &mean, &rendered.geoms)?.0));
    }
    Ok(consensus::quantize(mean))
}

/// What training a round took.
pub struct Trained {
    pub seconds: f64,
    pub loss_ema: Option<f64>,
}

/// Step 4: train on random rays across the targets, moved by the colour offsets, which are
/// recalibrated at the round's start (round 1: once there is a field to measure) and every
/// `calibration_interval` steps. Ctrl-C saves the round so far.
pub fn train(s: &Setup, trainer: &mut Trainer, p: &mut Prepared, round: usize, t_round: Instant, progress: &mut dyn Progress) -> Result<Trained> {
    let steps = s.opts.steps_of_round(round);
    let first_calibration = s.opts.calibration_interval();
    let train_on = if round > 1 || p.first_step > 0 {
        calibrated(s, trainer, &p.targets, round == 1 && p.first_step <= first_calibration, p.shown.take())?
    } else {
        p.targets.clone()
    };
    set_targets(s, trainer, &train_on)?;
    progress.phase(round, s.opts.rounds, "train", steps);
    let t0 = Instant::now();
    let mut loss_ema = p.loss_ema;
    for step in p.first_step..steps {
        if step > p.first_step && s.opts.calibrates_at(step) {
            let c = calibrated(s, trainer, &p.targets, round == 1 && step == first_calibration, None)?;
            set_targets(s, trainer, &c)?;
        }
        if snerf_files::interrupt::requested() {
            let seconds = p.trained_before + t0.elapsed().as_secs_f64();
            return Err(save_interrupted(s, trainer, p, round, step, seconds, loss_ema, t_round));
        }
        let st = trainer.step(s.opts.lr_progress(round, step));
        if !st.loss.is_finite() {
            bail!("round {round}: training diverged at step {step} (loss {}); {} keeps the last finished round", st.loss, s.out.display());
        }
        let l = loss_ema.map(|l| 0.9 * l + 0.1 * st.loss).unwrap_or(st.loss);
        loss_ema = Some(l);
        if step % 5 == 0 || step + 1 == steps {
            progress.tick(step + 1, &format!("fit {:.2} dB", mse_to_psnr(l)));
        }
    }
    Ok(Trained { seconds: p.trained_before + t0.elapsed().as_secs_f64(), loss_ema })
}

/// The round so far in `partial/`, and the error that says how to go on.
#[allow(clippy::too_many_arguments)]
fn save_interrupted(s: &Setup, trainer: &Trainer, p: &Prepared, round: usize, step: u64, seconds: f64, loss_ema: Option<f64>, t_round: Instant) -> anyhow::Error {
    let saved = Partial {
        round,
        steps_done: step,
        render_seconds: p.render_seconds,
        stylize_seconds: p.stylize_seconds,
        stylized_views: p.stylized_views,
        train_seconds: seconds,
        loss_ema,
        round_wall: p.wall_before + t_round.elapsed().as_secs_f64(),
    };
    if let Err(e) = partial::save(s.out, &saved, trainer, &p.targets) {
        return e;
    }
    let steps = s.opts.steps_of_round(round);
    snerf_files::interrupt::Interrupted(format!("round {round} saved at step {step} of {steps} in {}; run the same command again to continue it", s.out.display())).into()
}

fn set_targets(s: &Setup, trainer: &mut Trainer, targets: &[Image]) -> Result<()> {
    trainer.set_views(s.views.iter().zip(targets).map(|(v, t)| stylized_view(v, t)).collect())
}

/// The training view with its colours replaced by the target; alpha is kept, so a bounded
/// object keeps its silhouette (its inside geometry is still free to change).
fn stylized_view(v: &View, s: &Image) -> View {
    let mut out = v.clone();
    for (px, rgb) in out.rgba.chunks_exact_mut(4).zip(s.data.chunks_exact(3)) {
        for c in 0..3 {
            px[c] = (rgb[c].clamp(0.0, 1.0) * 255.0).round() as u8;
        }
    }
    out
}

/// `targets` moved by the colour offsets the field falls short of (`colour_offsets`): the
/// field's shortfall at the training views (`shown` when the round rendered them) added to
/// the run's last offsets with gain 1/k, unless the field has trained on nothing but the
/// targets as they are (`as_they_are`: round 1 until its first calibration).
fn calibrated(s: &Setup, trainer: &Trainer, targets: &[Image], as_they_are: bool, shown: Option<(Vec<Image>, Vec<ViewGeometry>)>) -> Result<Vec<Image>> {
    let (shown, geoms) = shown.unwrap_or_else(|| field_views(&trainer.model, &trainer.pool, &s.views, s.bg, s.has_alpha));
    let last = if as_they_are { None } else { ColourOffsets::load(s.out)? };
    let offsets = last.unwrap_or_default().step(targets, &shown, &geoms);
    offsets.save(s.out)?;
    Ok(consensus::quantize(offsets.apply(targets, &geoms)))
}

/// What the per-round measurement says of a field, and on which frames.
pub struct Scores {
    pub style_distance: Option<f64>,
    pub short_range: Option<f64>,
    pub long_range: Option<f64>,
    pub style_swd: Option<StyleScore>,
    pub style_gram: Option<f64>,
    pub measured_on: Option<String>,
}

/// Step 5: the field on the loop's own path (warp errors) and ring (style distances); without
/// a path, the embedding distance of held-out views.
pub fn measure(s: &Setup, trainer: &Trainer, round: usize, progress: &mut dyn Progress) -> Result<Scores> {
    progress.phase(round, s.opts.rounds, "measure", 1);
    if let Some((path, targets)) = &s.path {
        let frames = path.render(&trainer.model, &trainer.pool);
        let style = s.meters.score(path, &frames, targets)?;
        return Ok(Scores {
            style_distance: style.embedding,
            short_range: Some(path.warp_error(&frames, 1)),
            long_range: Some(path.warp_error(&frames, 7)),
            style_swd: Some(style.swd),
            style_gram: style.gram,
            measured_on: Some(path.description.clone()),
        });
    }
    let embedder = s.meters.embedder.as_ref().zip(s.style_embedding.as_deref());
    let d = embedder.map(|(e, st)| style_distance_of(&trainer.model, &trainer.pool, s.data, s.bg, e, st)).transpose()?;
    let on = d.map(|_| "up to 4 held-out views".to_string());
    Ok(Scores { style_distance: d, short_range: None, long_range: None, style_swd: None, style_gram: None, measured_on: on })
}

/// `rounds/round_N.png`: up to 4 views: render, the stylizer's output, the training target.
fn write_round_sheet(path: &std::path::Path, renders: &[Image], stylized: &[Image], targets: &[Image]) -> Result<()> {
    let n = renders.len().min(4);
    let picked: Vec<usize> = (0..n).map(|i| i * renders.len() / n.max(1)).collect();
    let rows: Vec<Vec<&Image>> = vec![
        picked.iter().map(|&i| &renders[i]).collect(),
        picked.iter().map(|&i| &stylized[i]).collect(),
        picked.iter().map(|&i| &targets[i]).collect(),
    ];
    checkpoint::write_png_atomic(path, &crate::consistency::grid_image(&rows))
}
