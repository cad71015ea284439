//! `snerf stylize-image`, `snerf stylize`, `snerf consistency`: image stylizers alone, the
//! SNeRF loop on a trained run, and the paper's consistency evaluation.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::ProgressBar;
use serde_json::{json, Value};
use snerf_stylize::consistency::{self, MethodScores, PathGeometry, StyleMeters, StyleTargets};
use snerf_stylize::fusion::Read;
use snerf_stylize::layers::{LayerPlan, LayersRecord, TimeSplit, LAYER_DEFAULTS};
use snerf_stylize::paintings;
use snerf_stylize::snerf_loop::{self, Progress, RoundRecord, StylizeOptions};
use snerf_stylize::temporal::{TemporalScores, TimePath};
use snerf_stylize::stylizer::{self, Image, Stylizer, StylizerOptions};
use snerf_trainer::checkpoint;

use crate::args::{bar, DataOpts};
use snerf_trainer::run_dir::RunDir;
use snerf_files::guard::{check_output, Input};

const STYLIZER_HELP: &str = "Stylizer: arbitrary (default; Magenta arbitrary stylization, any picture is a style), \
preset:N (one of 26 built-in styles, N in 0..26; no style image needed), onnx:FILE (any image-to-image ONNX \
model), gatys (the paper's optimization of the view itself, on the MobileNetV2 features of the installed Magenta \
style network, or on VGG-16 with --gatys-weights), color (colour-statistics transfer, no \
model). The pretrained models come from `bash scripts/setup-models.sh` into $SNERF_MODELS.";

#[derive(Args, Debug, Clone)]
pub struct StylizerArgs {
    #[arg(long, default_value = "arbitrary", help = STYLIZER_HELP)]
    pub stylizer: String,
    /// Style strength in [0,1] (arbitrary: blends the style embedding with the content's own).
    #[arg(long, default_value_t = 1.0, value_parser = crate::args::unit_f32)]
    pub strength: f32,
    /// Gatys: use VGG-16 (the paper's network) instead of the installed MobileNetV2 features;
    /// weights as safetensors in torchvision's layout (features.N.weight/bias). Get them in Python: torchvision.models.vgg16(weights="IMAGENET1K_V1").features.state_dict(),
    /// saved with safetensors.torch.save_file.
    #[arg(long)]
    pub gatys_weights: Option<PathBuf>,
    /// Gatys: optimization steps per image.
    #[arg(long, default_value_t = 100, value_parser = crate::args::int_in::<usize>(1, 100000, ""))]
    pub gatys_steps: usize,
    /// Model directory (default $SNERF_MODELS or ~/.cache/snerf/models).
    #[arg(long)]
    pub models: Option<PathBuf>,
}

impl StylizerArgs {
    pub fn options(&self) -> StylizerOptions {
        StylizerOptions {
            strength: self.strength.clamp(0.0, 1.0),
            models_dir: self.models.clone(),
            gatys_weights: self.gatys_weights.clone(),
            gatys_steps: self.gatys_steps,
            ..StylizerOptions::default()
        }
    }

    /// The stylizer, with its style image (None for presets).
    pub fn build(&self, style: Option<&Path>) -> Result<Box<dyn Stylizer>> {
        let needs_style = !self.stylizer.starts_with("preset:") && !self.stylizer.starts_with("onnx:");
        if needs_style && style.is_none() {
            bail!("--stylizer {} needs --style IMAGE", self.stylizer);
        }
        stylizer::from_spec(&self.stylizer, style, &self.options())
    }

    /// The networks of the style distances, those that are installed.
    pub fn meters(&self) -> StyleMeters {
        StyleMeters::open(&self.options())
    }
}

#[derive(Args, Debug)]
pub struct StylizeImageArgs {
    /// The content image (PNG, JPEG or WebP).
    pub content: PathBuf,
    /// The style image (PNG, JPEG or WebP), or `painting:KEY` for a painting installed by
    /// `bash scripts/setup-styles.sh` (vangogh, renoir, kandinsky, greatwave, cassatt, bazille).
    #[arg(long)]
    pub style: Option<PathBuf>,
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub s: StylizerArgs,
}

pub fn read_image(path: &Path) -> Result<Image> {
    let img = image::open(path).with_context(|| format!("{}: cannot read image", path.display()))?.to_rgb32f();
    Ok(Image { width: img.width() as usize, height: img.height() as usize, data: img.into_raw() })
}

pub fn to_rgb8(img: &Image) -> image::RgbImage {
    let bytes = img.data.iter().map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8).collect();
    image::RgbImage::from_raw(img.width as u32, img.height as u32, bytes).expect("image size")
}

pub fn stylize_image_cmd(a: &StylizeImageArgs) -> Result<Value> {
    let style = a.style.as_deref().map(paintings::resolve_style).transpose()?;
    let mut inputs = vec![Input::File(&a.content)];
    if let Some(s) = &style {
        inputs.push(Input::File(s));
    }
    check_output("--out", &a.out, &inputs)?;
    let content = read_image(&a.content)?;
    let t0 = Instant::now();
    let s = a.s.build(style.as_deref())?;
    let load = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let out = snerf_loop::stylize_at(s.as_ref(), &content, 0)?;
    let secs = t1.elapsed().as_secs_f64();
    checkpoint::write_png_atomic(&a.out, &to_rgb8(&out))?;
    eprintln!("{} -> {} with {} ({:.2} s; model load {:.2} s)", a.content.display(), a.out.display(), s.name(), secs, load);
    Ok(json!({ "command": "stylize-image", "stylizer": s.name(), "out": crate::args::pj(&a.out), "seconds": secs, "load_seconds": load }))
}

/// The library's defaults are the command line's.
fn defaults() -> StylizeOptions {
    StylizeOptions::default()
}

/// A lowercase option value as the serde enum of the same name.
fn option_enum<T: serde::de::DeserializeOwned>(what: &str, v: &str) -> Result<T> {
    serde_json::from_value(Value::String(v.to_string())).map_err(|e| anyhow::anyhow!("{what} {v}: {e}"))
}

#[derive(Args, Debug)]
pub struct StylizeArgs {
    /// A trained (realistic) run directory.
    pub run: PathBuf,
    /// The style image (PNG, JPEG or WebP), or `painting:KEY` for a painting installed by
    /// `bash scripts/setup-styles.sh` (vangogh, renoir, kandinsky, greatwave, cassatt, bazille).
    /// Given more than once, each style is a layer of one asset: OUT/layers/NAME/ is an
    /// appearance-only stylization per style (NAME: the painting's key or the file's stem),
    /// OUT/layers.json lists them, and `snerf bake OUT` writes one asset with the geometry
    /// once and a colour part per style.
    #[arg(long)]
    pub style: Vec<PathBuf>,
    /// The stylized run directory (resumes when it holds a run with the same options).
    #[arg(long)]
    pub out: PathBuf,
    /// The run's dataset (default: the one recorded in RUN/config.json).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Rounds of render -> stylize -> train (the paper uses 5; 1 is the one-shot baseline).
    #[arg(long, default_value_t = defaults().rounds, value_parser = crate::args::int_in::<usize>(1, 100, ""))]
    pub rounds: usize,
    /// Training steps per round, on average: the run trains ROUNDS × this many steps, in
    /// proportion to 1/t over the rounds (most in round 1). Default 300; with several
    /// --style 100 (a layer learns colour only).
    #[arg(long, value_parser = crate::args::int_in::<u64>(1, 10000000, ""))]
    pub steps_per_round: Option<u64>,
    /// Longer side of the images handed to the stylizer (0: the training resolution).
    #[arg(long, default_value_t = 0, value_parser = crate::args::int_in::<usize>(0, 4096, "0 = the training resolution; the stylizer holds the whole image in memory"))]
    pub style_res: usize,
    /// Use this many training views, evenly spaced (0: all). Default all; with several
    /// --style 24 (a layer's colour sits on a fixed geometry that fewer views cover).
    #[arg(long, value_parser = crate::args::int_in::<usize>(0, 100000, ""))]
    pub views: Option<usize>,
    /// Freeze density and the shared layers; stylize colour only (the paper's ablation; always
    /// on with several --style).
    #[arg(long)]
    pub appearance_only: bool,
    /// Frames of the loop's own path for the per-round warp errors (0: skip the per-round
    /// measurement); the per-round style distances are scored on 8 more frames, 45° apart
    /// around the whole orbit. Nothing is selected on these: `snerf consistency` scores
    /// another path. Default 16; with several --style 0 (`snerf consistency OUT/layers/NAME`
    /// scores a layer afterwards).
    #[arg(long, value_parser = crate::args::int_in::<usize>(0, 1000, ""))]
    pub consistency_frames: Option<usize>,
    /// Fusion: each surface point takes the colour its nearest painter gave it, and each
    /// consensus step takes the per-pixel median over a view and this many nearest training
    /// views, reprojected through the field's depth; 0: no fusion at all (each view trains
    /// on its own stylization).
    #[arg(long, default_value_t = defaults().fuse_views, value_parser = crate::args::int_in::<usize>(0, 32, ""))]
    pub fuse_views: usize,
    /// What the stylizer paints: render (the default, the paper's loop: the current field's
    /// renders, every round, each round's targets moved toward them by 1/t²) or realistic (the
    /// realistic field's renders, once; later rounds reconcile those stylizations across
    /// views: the one-pass variant). BENCH.md §5 measures both.
    #[arg(long, default_value = snerf_loop::DEFAULT_CONTENT.as_str(), value_parser = ["render", "realistic"])]
    pub content: String,
    /// Seed of the rays each training step draws (default: the realistic run's own): run two
    /// seeds to see how far the figures move with it.
    #[arg(long)]
    pub seed: Option<u64>,
    #[command(flatten)]
    pub s: StylizerArgs,
    #[command(flatten)]
    pub opts: DataOpts,
}

/// Progress bars for the rounds, and the run's report redrawn after each round.
struct Bars {
    pb: ProgressBar,
    quiet: bool,
    out: PathBuf,
    live: snerf_report::live::LiveReport,
}

impl Progress for Bars {
    fn phase(&mut self, round: usize, rounds: usize, phase: &str, total: u64) {
        self.pb.set_length(total);
        self.pb.set_position(0);
        // Round 0: the work before the first round (the measurement path's renders).
        self.pb.set_prefix(if round == 0 { phase.to_string() } else { format!("round {round}/{rounds} {phase:<8}") });
    }
    fn tick(&mut self, done: u64, message: &str) {
        self.pb.set_position(done);
        if !message.is_empty() {
            self.pb.set_message(message.to_string());
        }
    }
    fn round_done(&mut self, r: &RoundRecord) {
        if !self.quiet {
            self.say(format!(
                "round {}: {:.0} s (render {:.0} s, stylize {:.0} s{}, train {:.0} s), fit {:.2} dB, style distance {} (Gram {}, embedding {}), consistency short {} long {}",
                r.round,
                r.wall_seconds,
                r.render_seconds,
                r.stylize_seconds,
                r.stylized_views.map(|n| format!(", {n} views painted")).unwrap_or_default(),
                r.train_seconds,
                r.fit_psnr,
                fmt_opt(r.style_swd.map(|s| s.total), 4),
                fmt_opt(r.style_gram, 4),
                fmt_opt(r.style_distance, 3),
                fmt_opt(r.short_range, 5),
                fmt_opt(r.long_range, 5)
            ));
        }
        // stylize.json on disk holds the rounds before this one (it is rewritten after this call)
        let mut state: Value = std::fs::read(snerf_loop::state_path(&self.out))
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or_else(|| json!({ "records": [] }));
        let mut records: Vec<Value> = state["records"].as_array().cloned().unwrap_or_default();
        records.retain(|x| x["round"].as_u64().is_some_and(|n| (n as usize) < r.round));
        records.push(serde_json::to_value(r).unwrap_or(Value::Null));
        state["records"] = Value::Array(records);
        self.live.stylize(&self.out, state);
    }
}

impl Bars {
    /// A line above the bar; on standard error when the bar is hidden (output not on a
    /// terminal), so a log of the run still has one line per round.
    fn say(&self, line: String) {
        if self.pb.is_hidden() {
            eprintln!("{line}");
        } else {
            self.pb.println(line);
        }
    }
}

fn fmt_opt(v: Option<f64>, digits: usize) -> String {
    v.map(|x| format!("{x:.digits$}")).unwrap_or_else(|| "n/a".into())
}

pub fn stylize_cmd(a: &StylizeArgs, quiet: bool) -> Result<Value> {
    if a.style.len() > 1 {
        return stylize_layers(a, quiet);
    }
    stylize_one(a, a.style.first().map(PathBuf::as_path), &a.out, a.appearance_only, a.plan(false), quiet)
}

impl StylizeArgs {
    /// Views, steps and measurement frames: as given, else the single-style defaults, or a
    /// layer's (`layers::LAYER_DEFAULTS`) when `layer`.
    fn plan(&self, layer: bool) -> LayerPlan {
        let d = if layer {
            LAYER_DEFAULTS
        } else {
            LayerPlan { views: defaults().views, steps_per_round: defaults().steps_per_round, consistency_frames: defaults().consistency_frames }
        };
        LayerPlan {
            views: self.views.unwrap_or(d.views),
            steps_per_round: self.steps_per_round.unwrap_or(d.steps_per_round),
            consistency_frames: self.consistency_frames.unwrap_or(d.consistency_frames),
        }
    }
}

/// Several `--style`: one appearance-only stylization per style in OUT/layers/NAME/ (each a
/// whole stylized run, resumable as one), recorded in OUT/layers.json (`snerf_stylize::layers`).
fn stylize_layers(a: &StylizeArgs, quiet: bool) -> Result<Value> {
    let specs: Vec<String> = a
        .style
        .iter()
        .map(|p| p.to_str().map(str::to_string).ok_or_else(|| anyhow::anyhow!("--style {}: not a UTF-8 name; rename it", p.display())))
        .collect::<Result<_>>()?;
    let mut record = LayersRecord::new(&absolute(&a.run), &specs)?;
    // before anything is written: OUT is never the run, inside it or inside its dataset
    let data_path = match &a.data {
        Some(d) => d.clone(),
        None => RunDir::new(&a.run).dataset()?,
    };
    check_output("--out", &a.out, &[Input::Tree(&a.run), Input::Tree(&data_path)])?;
    if !a.appearance_only {
        eprintln!("{} styles as layers of one asset share one geometry: stylizing with --appearance-only", specs.len());
    }
    let plan = a.plan(true);
    if !quiet {
        eprintln!(
            "each layer: {} rounds × {} steps on {} views, per-round measurement {}",
            a.rounds,
            plan.steps_per_round,
            if plan.views == 0 { "all".to_string() } else { plan.views.to_string() },
            if plan.consistency_frames > 1 { format!("on {} frames", plan.consistency_frames) } else { "off".into() }
        );
    }
    let mut layers = Vec::new();
    for i in 0..record.layers.len() {
        let (name, spec) = (record.layers[i].name.clone(), a.style[i].clone());
        let dir = LayersRecord::dir(&a.out, &name);
        if !quiet {
            eprintln!("layer {}/{}: {name} ({}) -> {}", i + 1, specs.len(), spec.display(), dir.display());
        }
        std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
        let t0 = Instant::now();
        let v = stylize_one(a, Some(&spec), &dir, true, plan, quiet)?;
        let secs = t0.elapsed().as_secs_f64();
        record.layers[i].seconds = Some(secs);
        // after every layer: a record on disk names what is done
        record.write(&a.out)?;
        let state: snerf_loop::StylizeState = serde_json::from_value(v["state"].clone())?;
        let split = TimeSplit::of(&state, secs);
        if !quiet {
            eprintln!("layer {name}: {}", split.line());
        }
        layers.push(json!({ "name": name, "dir": crate::args::pj(&dir), "seconds": secs, "time": split, "state": v["state"] }));
    }
    if !quiet {
        let secs: Vec<String> = record.layers.iter().map(|l| format!("{} {:.0} s", l.name, l.seconds.unwrap_or(0.0))).collect();
        eprintln!("{} style layers in {} ({}); bake them into one asset with `snerf bake {}`", layers.len(), a.out.display(), secs.join(", "), a.out.display());
    }
    Ok(json!({ "command": "stylize", "out": crate::args::pj(&a.out), "plan": plan, "layers": layers, "record": record }))
}

/// One stylization of `a.run` after `style` into `out`.
fn stylize_one(a: &StylizeArgs, style: Option<&Path>, out: &Path, appearance_only: bool, plan: LayerPlan, quiet: bool) -> Result<Value> {
    let data_path = match &a.data {
        Some(d) => d.clone(),
        None => RunDir::new(&a.run).dataset()?,
    };
    // the loop renders every view many times a run: its own cap unless --max-size says; a run
    // recorded before the cap existed resumes at the size it was painted at (the loader's)
    let recorded = snerf_loop::StylizeState::read(out)?.map(|s| s.options.max_size);
    let max_size = match (a.opts.max_size, recorded) {
        (Some(asked), _) => Some(asked),
        (None, Some(recorded)) => recorded,
        (None, None) => defaults().max_size,
    };
    let data = DataOpts { max_size, ..a.opts.clone() }.load(&data_path)?;
    let style = style.map(paintings::resolve_style).transpose()?;
    // stylize.json records these paths, and JSON holds UTF-8 only: refuse now, not after a round.
    let out = &out.to_path_buf();
    for (what, p) in [("RUN", Some(&a.run)), ("--out", Some(out)), ("--style", style.as_ref()), ("--data", Some(&data_path))] {
        if let Some(p) = p.filter(|p| p.to_str().is_none()) {
            bail!("{what} {}: the stylized run records this path, and its JSON holds UTF-8 names only; rename it", p.display());
        }
    }
    // The stylized run is a run of its own: never the realistic run's directory (its
    // checkpoint would be overwritten), never inside the dataset.
    let mut inputs = vec![Input::Tree(&a.run), Input::Tree(&data.root)];
    if let Some(s) = &style {
        inputs.push(Input::File(s));
    }
    check_output("--out", out, &inputs)?;
    let ck_path = RunDir::new(&a.run).checkpoint();
    if !ck_path.exists() {
        bail!("{}: no checkpoint here; run `snerf train` first", a.run.display());
    }
    let source = checkpoint::load(&ck_path)?;
    let stylizer = a.s.build(style.as_deref())?;
    let style_img = match &style {
        Some(p) => stylizer::load_style_image(p)?,
        None => style_reference(stylizer.as_ref())?,
    };
    let meters = a.s.meters();
    let opts = StylizeOptions {
        source_run: absolute(&a.run),
        data: absolute(&data_path),
        style: style.as_deref().map(absolute).unwrap_or_default(),
        stylizer: a.s.stylizer.clone(),
        strength: a.s.strength,
        rounds: a.rounds,
        steps_per_round: plan.steps_per_round,
        style_res: a.style_res,
        views: plan.views,
        appearance_only,
        consistency_frames: plan.consistency_frames,
        fuse_views: a.fuse_views,
        content: option_enum("--content", &a.content)?,
        seed: a.seed,
        max_size,
    };
    let wall = Instant::now();
    let mut bars = Bars {
        pb: bar(1, "{spinner} {prefix} {bar:30} {pos}/{len} [{elapsed}] {msg}"),
        quiet,
        out: out.clone(),
        live: snerf_report::live::LiveReport::new(),
    };
    let state = snerf_loop::run(&opts, &data, &source, stylizer.as_ref(), &meters, &style_img, out, &mut bars)?;
    bars.pb.finish_and_clear();
    bars.live.stylize(out, serde_json::to_value(&state)?);
    if !quiet {
        eprintln!(
            "stylized run in {} ({} rounds, {:.0} s); per-round images in {}",
            out.display(),
            state.rounds_done,
            wall.elapsed().as_secs_f64(),
            out.join("rounds").display()
        );
    }
    Ok(json!({
        "command": "stylize",
        "out": crate::args::pj(out),
        "state": state,
        "wall_seconds": wall.elapsed().as_secs_f64(),
        "report": { "dir": crate::args::pj(out.join(snerf_report::live::RUN_REPORT_DIR)), "writes": bars.live.writes, "seconds": bars.live.seconds },
    }))
}

/// The style a stylizer without a style image (a preset, a GAN) paints in, as a picture:
/// its stylization of a neutral image of soft colour noise. Style distances for such
/// stylizers are measured against this.
pub fn style_reference(stylizer: &dyn Stylizer) -> Result<Image> {
    let n = 256;
    let mut data = Vec::with_capacity(n * n * 3);
    for y in 0..n {
        for x in 0..n {
            let (fx, fy) = (x as f32 / n as f32, y as f32 / n as f32);
            for c in 0..3 {
                let ph = c as f32 * 2.1;
                data.push(0.5 + 0.25 * ((fx * 11.0 + ph).sin() * (fy * 7.0 - ph).cos()) + 0.1 * ((fx + fy) * 37.0 + ph).sin());
            }
        }
    }
    snerf_loop::stylize_at(stylizer, &Image { width: n, height: n, data }, 0)
}

fn absolute(p: &Path) -> PathBuf {
    std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf())
}

#[derive(Args, Debug)]
pub struct ConsistencyArgs {
    /// A stylized run (from `snerf stylize`).
    pub srun: PathBuf,
    /// The dataset (default: the stylized run's).
    pub data: Option<PathBuf>,
    /// A one-round stylized run to compare against (`snerf stylize --rounds 1`).
    #[arg(long)]
    pub one_round: Option<PathBuf>,
    /// Frames of the evaluation path (5° apart) the warp errors are measured on. The style
    /// distances are scored on 8 more frames, 45° apart around the whole orbit. The path
    /// and its orbit are 15° higher (or lower) and 1.15× as far as the loop's own path, so
    /// no frame is one the loop measured itself on.
    #[arg(long, default_value_t = 24, value_parser = crate::args::int_in::<usize>(2, 1000, ""))]
    pub frames: usize,
    /// Score this camera path instead (nerfstudio's camera_path.json, as `snerf render
    /// --path` reads it; one image size): every camera a frame, the style distances on 8 of
    /// them evenly spaced.
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Score the loop's own path (its per-round measurement's frames) instead of the
    /// evaluation path: what the rounds measured, for comparison.
    #[arg(long, conflicts_with = "path")]
    pub loop_path: bool,
    /// Where to write consistency.json, consistency.md and consistency.png (default: SRUN).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also write every frame as PNGs in OUT/frames/: realistic_NN, per_frame_NN, snerf_NN,
    /// and mask_NN (the scene pixels); NN below --frames is the path, the 8 after it the
    /// style ring the style distances pool.
    #[arg(long)]
    pub save_frames: bool,
    /// Animated (4D) scenes: also score temporal flicker on this many instants spread over the
    /// animation, seen from one camera held still: the change between neighbouring instants on
    /// the pixels the realistic frames show still (0: skip; 1 is refused).
    #[arg(long, default_value_t = 12, value_parser = crate::args::int_in::<usize>(0, 1000, ""))]
    pub time_frames: usize,
    #[command(flatten)]
    pub opts: DataOpts,
}

/// Temporal flicker of an animated scene (`temporal`); `None` for static scenes or
/// `--time-frames 0`.
fn temporal_flicker(
    a: &ConsistencyArgs,
    data: &snerf_trainer::data::Dataset,
    realistic: (&snerf_trainer::train::Model, &snerf_trainer::render::WorkspacePool),
    stylized: (&snerf_trainer::train::Model, &snerf_trainer::render::WorkspacePool),
    stylizer: &dyn snerf_stylize::stylizer::Stylizer,
    by_box: bool,
    style_res: usize,
) -> Result<Option<TemporalScores>> {
    if !data.dynamic || a.time_frames < 2 {
        return Ok(None);
    }
    let path = TimePath::evaluation(realistic.0, realistic.1, data, a.time_frames)?;
    TemporalScores::measure(&path, stylized.0, stylized.1, stylizer, by_box, style_res).map(Some)
}

/// The path scored as a field that held the run's last training targets exactly would show
/// it (`PathGeometry::carried`), reading the targets by copying a pixel and bilinearly: the
/// bound the targets put on the field, whatever its fit. The training views' surface points
/// come from the stylized field's depth, as the last round fused through it. Empty when the
/// run did not keep its targets (or they do not match the dataset's views).
#[allow(clippy::too_many_arguments)]
fn carried_targets(
    srun: &Path,
    state: &snerf_loop::StylizeState,
    data: &snerf_trainer::data::Dataset,
    (model, pool): (&snerf_trainer::train::Model, &snerf_trainer::render::WorkspacePool),
    path: &PathGeometry,
    base: &[Image],
    meters: &StyleMeters,
    style: &StyleTargets,
) -> Result<Vec<MethodScores>> {
    let Some((views, targets)) = snerf_loop::last_round_targets(srun, state, data)? else { return Ok(Vec::new()) };
    if views.iter().zip(&targets).any(|(v, t)| (v.intrinsics.width as usize, v.intrinsics.height as usize) != (t.width, t.height)) {
        return Ok(Vec::new());
    }
    let (_, geoms) = snerf_loop::field_views(model, pool, &views, path.bg, path.has_silhouette());
    [(Read::Nearest, "Last targets carried, copied pixels"), (Read::Bilinear, "Last targets carried, bilinear")]
        .into_iter()
        .map(|(read, name)| MethodScores::of(name, path, &path.carried(base, &targets, &geoms, read), meters, style))
        .collect()
}

/// The path `snerf consistency` scores: `--path`, `--loop-path`, or the evaluation path.
fn scored_path(a: &ConsistencyArgs, realistic: &snerf_trainer::train::Model, pool: &snerf_trainer::render::WorkspacePool, data: &snerf_trainer::data::Dataset) -> Result<PathGeometry> {
    if let Some(file) = &a.path {
        let text = std::fs::read_to_string(file).with_context(|| format!("--path {}: cannot read", file.display()))?;
        let first = data.test.first().unwrap_or(&data.train[0]).intrinsics;
        let fov = 2.0 * (0.5 * first.height as f32 / first.fy).atan().to_degrees();
        let cams = snerf_geometry::camera_path::parse(&text, (first.width, first.height), fov).map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))?;
        return PathGeometry::from_cameras(realistic, pool, data, &cams, &file.display().to_string());
    }
    if a.loop_path {
        return PathGeometry::new(realistic, pool, data, a.frames);
    }
    PathGeometry::evaluation(realistic, pool, data, a.frames)
}

pub fn consistency_cmd(a: &ConsistencyArgs, quiet: bool) -> Result<Value> {
    anyhow::ensure!(a.time_frames != 1, "--time-frames 1: flicker compares neighbouring instants, so it needs 2 or more (0 skips it)");
    let t0 = Instant::now();
    let st_path = snerf_loop::state_path(&a.srun);
    let state: snerf_loop::StylizeState = serde_json::from_slice(
        &std::fs::read(&st_path).with_context(|| format!("{}: not a stylized run (no {})", a.srun.display(), snerf_loop::STATE_FILE))?,
    )
    .with_context(|| format!("{}: unreadable", st_path.display()))?;
    let o = &state.options;
    // the size the run painted at, unless --max-size says otherwise
    let data = DataOpts { max_size: a.opts.max_size.or(o.max_size), ..a.opts.clone() }.load(a.data.as_ref().unwrap_or(&o.data))?;
    let (realistic, pool) = RunDir::new(&o.source_run).load_model()?;
    let (stylized, spool) = RunDir::new(&a.srun).load_model()?;
    let sargs = StylizerArgs {
        stylizer: o.stylizer.clone(),
        strength: o.strength,
        gatys_weights: None,
        gatys_steps: 100,
        models: None,
    };
    let has_style = !o.style.as_os_str().is_empty();
    let style_path = has_style.then_some(o.style.as_path());
    let stylizer = sargs.build(style_path)?;
    let meters = sargs.meters();
    let style_img = match style_path {
        Some(p) => stylizer::load_style_image(p)?,
        None => style_reference(stylizer.as_ref())?,
    };

    let pb = bar(if data.dynamic && a.time_frames >= 2 { 5 } else { 4 }, "{spinner} consistency {bar:30} {pos}/{len} [{elapsed}] {msg}");
    pb.set_message("realistic geometry");
    let path = scored_path(a, &realistic, &pool, &data)?;
    let targets = meters.targets(&path, &style_img)?;
    pb.inc(1);
    pb.set_message("per-frame baseline");
    // painted as the run painted its training views: with `--region object`, the object's
    // box (the realistic field's silhouette in each frame)
    let by_box = path.has_silhouette();
    let per_frame = path.stylize_frames(stylizer.as_ref(), by_box, o.style_res, 0)?;
    pb.inc(1);
    pb.set_message("SNeRF");
    let snerf_frames = path.render(&stylized, &spool);
    pb.inc(1);
    // The unstylized field is the floor of the warp error (resampling, aliasing) and shows
    // how far from the style the scene starts.
    let mut methods = vec![
        MethodScores::of("Realistic field (no stylization)", &path, &path.realistic, &meters, &targets)?,
        MethodScores::of("Per-frame image stylization", &path, &per_frame, &meters, &targets)?,
    ];
    let mut one_round_frames = None;
    if let Some(r1) = &a.one_round {
        let (m1, p1) = RunDir::new(r1).load_model()?;
        let frames = path.render(&m1, &p1);
        methods.push(MethodScores::of("SNeRF, 1 round", &path, &frames, &meters, &targets)?);
        one_round_frames = Some(frames);
    }
    methods.push(MethodScores::of(&format!("SNeRF, {} rounds", state.rounds_done), &path, &snerf_frames, &meters, &targets)?);
    pb.set_message("targets carried to the path");
    let carried = carried_targets(&a.srun, &state, &data, (&stylized, &spool), &path, &snerf_frames, &meters, &targets)?;
    pb.inc(1);
    pb.set_message("temporal flicker");
    let temporal = temporal_flicker(a, &data, (&realistic, &pool), (&stylized, &spool), stylizer.as_ref(), by_box, o.style_res)?;
    if temporal.is_some() {
        pb.inc(1);
    }
    pb.finish_and_clear();

    let out = a.out.clone().unwrap_or_else(|| a.srun.clone());
    check_output("--out", &out, &[Input::Tree(&data.root)])?;
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;
    let table = consistency::markdown_table(&methods);
    let pf = &methods[1];
    let sn = methods.last().unwrap();
    let ratios = json!({
        "short_range": sn.short_range / pf.short_range,
        "long_range": sn.long_range / pf.long_range,
        "style_distance": sn.style_distance.zip(pf.style_distance).map(|(a, b)| a / b),
        "style_swd": sn.style_swd.total / pf.style_swd.total,
        "style_gram": sn.style_gram.zip(pf.style_gram).map(|(a, b)| a / b),
    });
    // The style metric is only worth reading when it separates the unstylized scene from a
    // stylized one: the realistic field must be well farther from the style than per-frame.
    let realistic_over_per_frame = methods[0].style_swd.total / pf.style_swd.total;
    let gram_realistic_over_per_frame = methods[0].style_gram.zip(pf.style_gram).map(|(a, b)| a / b);
    // contact sheet: style | realistic | per-frame | (1 round) | SNeRF, for two frames far apart
    let far = (path.path_frames - 1).min(7.max(path.path_frames / 2));
    let style_tile = &style_img;
    let mut rows = Vec::new();
    for &i in &[0usize, far] {
        let mut row: Vec<&Image> = vec![style_tile, &path.realistic[i], &per_frame[i]];
        if let Some(f) = &one_round_frames {
            row.push(&f[i]);
        }
        row.push(&snerf_frames[i]);
        rows.push(row);
    }
    checkpoint::write_png_atomic(&out.join("consistency.png"), &consistency::grid_image(&rows))?;
    if a.save_frames {
        let dir = out.join("frames");
        std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
        for (name, frames) in [("realistic", &path.realistic), ("per_frame", &per_frame), ("snerf", &snerf_frames)] {
            for (i, f) in frames.iter().enumerate() {
                stylizer::save_png(&dir.join(format!("{name}_{i:02}.png")), f)?;
            }
        }
        for (i, m) in path.masks().iter().enumerate() {
            let data = m.iter().flat_map(|&v| [if v { 1.0 } else { 0.0 }; 3]).collect();
            stylizer::save_png(&dir.join(format!("mask_{i:02}.png")), &Image { width: path.intr.width as usize, height: path.intr.height as usize, data })?;
        }
    }
    let separation = |r: f64| if r >= 1.5 { "valid: at least 1.5×" } else { "below 1.5×: this distance does not tell much on this pair" };
    let gram_line = match (sn.style_gram.zip(pf.style_gram), gram_realistic_over_per_frame) {
        (Some((g_sn, g_pf)), Some(r)) => format!(
            "Gram style distance (Gram matrices of ImageNet MobileNetV2 features at 1/2..1/16 resolution, same frames; \
             not independent for `gatys`, which minimizes it): SNeRF / per-frame {:.3}×; it separates the realistic field \
             from per-frame stylization by {r:.2}× ({}).\n\n",
            g_sn / g_pf,
            separation(r)
        ),
        _ => String::new(),
    };
    // each carried read against per-frame stylization: short range, long range, style
    let carried_ratios: Vec<[f64; 3]> =
        carried.iter().map(|m| [m.short_range / pf.short_range, m.long_range / pf.long_range, m.style_swd.total / pf.style_swd.total]).collect();
    let carried_md = if carried.is_empty() {
        String::new()
    } else {
        let line = |(m, r): (&MethodScores, &[f64; 3])| {
            format!("- {}: short-range {:.3}×, long-range {:.3}×, style distance {:.3}× of per-frame\n", m.method, r[0], r[1], r[2])
        };
        format!(
            "What the last round's training targets allow: the path as a field that held them exactly would show it \
             (every surface point the colour its owner view gives it in the targets, as the targets were fused), \
             scored as above:\n\n{}\n",
            carried.iter().zip(&carried_ratios).map(line).collect::<String>()
        )
    };
    let md = format!(
        "# Cross-view consistency\n\nStylizer `{}`, style `{}`, painting {} (the per-frame baseline too); {}; warped-frame MSE (RGB in [0,1]) over non-occluded \
         pixels at least a pixel from the silhouette (a silhouette pixel is part background), with flow from the realistic field's depth; {:.0}% of pixels covered.\n\n{}\n\
         SNeRF / per-frame: short-range {:.3}×, long-range {:.3}×, style distance {:.3}×.\n\n\
         Style distance, between the scene pixels of the 8 ring frames and the style picture: colour (how far, in Oklab, \
         each of the painting's colours is from the nearest in each frame) + texture (sliced Wasserstein over contrast-normalized 5×5 patches \
         at 3 scales), each in units of the same distance between the painting's two halves; it separates the realistic field from per-frame \
         stylization by {:.2}× ({}).\n\n{gram_line}{carried_md}Contact sheet `consistency.png`: style | realistic | per-frame{} | SNeRF, frames 0 and {far}.\n",
        o.stylizer,
        if has_style { o.style.display().to_string() } else { "its own (reference: its stylization of a neutral image)".into() },
        if by_box { "the object's box in each view" } else { "whole views" },
        path.description,
        100.0 * path.coverage(),
        table,
        sn.short_range / pf.short_range,
        sn.long_range / pf.long_range,
        sn.style_swd.total / pf.style_swd.total,
        realistic_over_per_frame,
        separation(realistic_over_per_frame),
        if one_round_frames.is_some() { " | 1 round" } else { "" },
    );
    let md = match &temporal {
        Some(t) => format!("{md}\n{}", t.markdown()),
        None => md,
    };
    std::fs::write(out.join("consistency.md"), &md).with_context(|| format!("{}: cannot write", out.display()))?;
    let v = json!({
        "command": "consistency",
        "srun": crate::args::pj(&a.srun),
        "frames": path.path_frames,
        "path": path.description,
        "coverage": path.coverage(),
        "warp_pixels": consistency::WARP_PIXELS,
        "methods": methods,
        "snerf_over_per_frame": ratios,
        "targets_carried": carried,
        "targets_carried_over_per_frame": carried_ratios.iter().map(|r| json!({"short_range": r[0], "long_range": r[1], "style_swd": r[2]})).collect::<Vec<_>>(),
        "style_metric_realistic_over_per_frame": realistic_over_per_frame,
        "style_gram_realistic_over_per_frame": gram_realistic_over_per_frame,
        "rounds": state.records,
        "temporal": temporal,
        "seconds": t0.elapsed().as_secs_f64(),
        "table": table,
    });
    checkpoint::write_json_atomic(&out.join("consistency.json"), &v)?;
    if out == a.srun {
        // the run's report gains the per-frame baseline and the realistic floor
        let st: Value = serde_json::to_value(&state)?;
        snerf_report::live::LiveReport::new().stylize(&a.srun, st);
    }
    if !quiet {
        eprintln!("{md}");
    }
    Ok(v)
}
