//! Command-line interface: argument parsing and one function per subcommand.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::{json, Value};
use snerf_trainer::data::{self, Dataset, LoadOptions, SceneKind};
use snerf_files::guard::{check_output, Input};
use snerf_trainer::{checkpoint, eval, run, train};

#[derive(Parser, Debug)]
#[command(
    name = "snerf",
    version,
    about = "Stylized radiance fields: capture -> train -> stylize -> bake -> view",
    long_about = "snerf learns a radiance field from posed views (transforms.json, LLFF, COLMAP, or its own \
                  generated scenes), fast on a CPU.\n\nStart with `snerf demo --out demo` for the whole path on \
                  built-in data. Every command takes --json to print a machine-readable summary on stdout."
)]
pub struct Cli {
    /// Print a JSON summary of the result on stdout (progress goes to stderr).
    #[arg(long, global = true)]
    pub json: bool,
    /// Worker threads (default: all cores).
    #[arg(long, global = true, value_parser = crate::args::threads)]
    pub threads: Option<usize>,
    #[command(subcommand)]
    pub cmd: Cmd,
}

#[derive(Subcommand, Debug)]
pub enum Cmd {
    /// Write a multi-view dataset (nerf_synthetic layout) from a built-in scene or a glTF file.
    Scene(SceneArgs),
    /// Describe a dataset: format, detected scene kind (and why), splits, image sizes.
    Data(DataArgs),
    /// Train a radiance field on a dataset.
    Train(TrainArgs),
    /// Score a trained run on held-out views: PSNR, SSIM, side-by-side images and depth.
    Eval(EvalArgs),
    /// Render a turntable of a trained run.
    Turntable(TurntableArgs),
    /// Stylize one image with a stylizer (arbitrary, preset:N, onnx:FILE, gatys, color).
    StylizeImage(crate::stylize_cmd::StylizeImageArgs),
    /// SNeRF: alternate render -> stylize -> train on a trained run, for a given number of rounds.
    Stylize(crate::stylize_cmd::StylizeArgs),
    /// The paper's cross-view consistency of a stylized run against per-frame stylization.
    Consistency(crate::stylize_cmd::ConsistencyArgs),
    /// Bake a run into a sparse-grid asset file (.snerf) for real-time viewing and streaming.
    Bake(crate::bake_cmd::BakeArgs),
    /// Say what is inside a baked asset file: sizes per part, occupancy, frames.
    Inspect(crate::bake_cmd::InspectArgs),
    /// Render a baked asset along a camera path to PNG frames (CPU reference renderer).
    Render(crate::bake_cmd::RenderArgs),
    /// Export a baked asset as a binary glTF mesh (marching cubes, baked colours, world units).
    ExportGltf(crate::bake_cmd::ExportGltfArgs),
    /// Show a baked asset in a window (wgpu): orbit/fly controls, stereo, 4D playback; also
    /// streams from `snerf serve` (quic://HOST:PORT/ASSET) and draws blocks as they arrive.
    View(crate::view_cmd::ViewArgs),
    /// Serve baked assets over QUIC (TLS 1.3, self-signed certificate pinned by clients, token).
    Serve(crate::stream_cmd::ServeArgs),
    /// Download a baked asset from `snerf serve` (resumable, checksum-verified).
    Fetch(crate::stream_cmd::FetchArgs),
    /// Error against run time, as pictures: plots, report.md, report.html and report.json from
    /// train runs, stylize runs, bakes and `bench quality` outputs.
    #[command(long_about = crate::report_cmd::REPORT_HELP)]
    Report(crate::report_cmd::ReportArgs),
    /// Two runs of the same data side by side: curves on one axis, differences at equal times.
    Compare(crate::report_cmd::CompareArgs),
    /// The whole path on built-in data: scene -> train -> eval -> turntable + contact sheet.
    Demo(crate::demo::DemoArgs),
    /// Benchmarks that print numbers (see BENCH.md).
    #[command(subcommand)]
    Bench(crate::bench::BenchCmd),
}

#[derive(Args, Debug)]
pub struct SceneArgs {
    /// object | room | outdoor | avatar | gltf:<file.gltf|file.glb>
    pub name: String,
    /// Output dataset directory (replaced only if empty or a previous snerf dataset).
    #[arg(long)]
    pub out: PathBuf,
    /// Training views (default depends on the scene).
    #[arg(long, value_parser = crate::args::int_in::<usize>(1, 100000, ""))]
    pub views: Option<usize>,
    /// Held-out test views.
    #[arg(long, value_parser = crate::args::int_in::<usize>(1, 100000, ""))]
    pub test_views: Option<usize>,
    /// Image size WxH, e.g. 128x128.
    #[arg(long)]
    pub size: Option<String>,
    /// Supersampling per axis for anti-aliasing (4 = 16 samples per pixel).
    #[arg(long, value_parser = crate::args::int_in::<u32>(1, 16, ""))]
    pub supersample: Option<u32>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Cameras: sphere (train spread over a sphere, test on an orbit) or orbit.
    #[arg(long, default_value = "sphere")]
    pub path: String,
}

#[derive(Args, Debug, Clone, Default)]
pub struct DataOpts {
    /// Override the detected scene kind: object | forward | unbounded.
    #[arg(long)]
    pub kind: Option<String>,
    /// Treat the scene as static even if frames carry times.
    #[arg(long = "static")]
    pub force_static: bool,
    /// Integer image downscale factor.
    #[arg(long, value_parser = crate::args::int_in::<u32>(1, 64, ""))]
    pub downscale: Option<u32>,
    /// For LLFF/COLMAP/single-file data: every n-th image is held out for testing.
    #[arg(long, value_parser = crate::args::int_in::<usize>(2, 100000, ""))]
    pub holdout_every: Option<usize>,
}

impl DataOpts {
    pub fn load(&self, path: &Path) -> Result<Dataset> {
        let kind = match self.kind.as_deref() {
            None => None,
            Some(k) => Some(parse_kind(k)?),
        };
        let opts = LoadOptions {
            kind,
            dynamic: if self.force_static { Some(false) } else { None },
            holdout_every: self.holdout_every,
            downscale: self.downscale,
        };
        data::load(path, &opts)
    }
}

fn parse_kind(k: &str) -> Result<SceneKind> {
    Ok(match k {
        "object" => SceneKind::Object,
        "forward" => SceneKind::Forward,
        "unbounded" => SceneKind::Unbounded,
        _ => bail!("unknown scene kind '{k}' (use object, forward or unbounded)"),
    })
}

#[derive(Args, Debug)]
pub struct DataArgs {
    pub data: PathBuf,
    #[command(flatten)]
    pub opts: DataOpts,
}

#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Dataset: a directory or transforms.json (Blender/nerfstudio), LLFF or COLMAP.
    pub data: PathBuf,
    /// Run directory (checkpoint, metrics.json, config.json).
    #[arg(long)]
    pub out: PathBuf,
    /// Stop after this many steps in total (a resumed run counts its earlier steps).
    #[arg(long, value_parser = crate::args::int_in::<u64>(1, 1000000000000, ""))]
    pub steps: Option<u64>,
    /// Stop after this many minutes of training in total (default 5 when --steps is absent).
    #[arg(long, value_parser = crate::args::positive)]
    pub minutes: Option<f64>,
    /// Continue the run in --out from its last checkpoint.
    #[arg(long)]
    pub resume: bool,
    /// Fixed rays per step (default: adapt the ray count to --batch-samples).
    #[arg(long, value_parser = crate::args::int_in::<usize>(64, 1048576, ""))]
    pub batch: Option<usize>,
    /// Samples per step the ray count adapts to.
    #[arg(long, value_parser = crate::args::int_in::<usize>(1024, 16777216, ""))]
    pub batch_samples: Option<usize>,
    /// Held-out pixels (random, fixed) scored for the PSNR-vs-time curve in metrics.json.
    #[arg(long, default_value_t = 16384, value_parser = crate::args::int_in::<usize>(0, 16777216, ""))]
    pub curve_pixels: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Learning rate of the feature planes (Adam).
    #[arg(long, value_parser = crate::args::positive_f32)]
    pub lr_planes: Option<f32>,
    /// Learning rate of the decoder and view MLP (Adam).
    #[arg(long, value_parser = crate::args::positive_f32)]
    pub lr_mlp: Option<f32>,
    /// Weight of the distortion loss (default 0.01 for forward/unbounded scenes, 0 for objects).
    #[arg(long, value_parser = crate::args::non_negative_f32)]
    pub distortion: Option<f32>,
    /// Weight of the total-variation loss on the feature planes (default 1e-3 for static objects, 0 otherwise).
    #[arg(long, value_parser = crate::args::non_negative_f32)]
    pub tv: Option<f32>,
    /// Finest plane resolution (levels are /8, /4, /2, /1 of it).
    #[arg(long, value_parser = crate::args::int_in::<u32>(16, 4096, ""))]
    pub resolution: Option<u32>,
    /// Write a checkpoint at least every this many seconds of training (a killed run loses
    /// at most this much).
    #[arg(long, default_value_t = 30.0, value_parser = crate::args::non_negative)]
    pub checkpoint_every: f64,
    #[command(flatten)]
    pub opts: DataOpts,
}

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// Run directory written by `snerf train`.
    pub run: PathBuf,
    /// The dataset it was trained on.
    pub data: PathBuf,
    /// Where to write side-by-side images (default RUN/eval).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Which split to score: test, val or train.
    #[arg(long, default_value = "test")]
    pub split: String,
    #[command(flatten)]
    pub opts: DataOpts,
}

#[derive(Args, Debug)]
pub struct TurntableArgs {
    pub run: PathBuf,
    pub data: PathBuf,
    #[arg(long)]
    pub out: PathBuf,
    #[arg(long, default_value_t = 36, value_parser = crate::args::int_in::<usize>(1, 3600, ""))]
    pub frames: usize,
    #[command(flatten)]
    pub opts: DataOpts,
}

/// The subcommand's name, for the JSON error object.
pub fn command_name(cmd: &Cmd) -> String {
    let dbg = format!("{cmd:?}");
    let variant = dbg.split(['(', ' ', '{']).next().unwrap_or("");
    let mut name = String::new();
    for (i, c) in variant.chars().enumerate() {
        if c.is_uppercase() && i > 0 {
            name.push('-');
        }
        name.extend(c.to_lowercase());
    }
    name
}

/// A path as a JSON string. JSON holds UTF-8 only; a path that is not is written lossily
/// rather than failing after the work is done.
pub fn pj(p: impl AsRef<Path>) -> Value {
    Value::String(p.as_ref().to_string_lossy().into_owned())
}

/// The files of a run directory that no command may overwrite through an `--out`.
pub fn run_files(run: &Path) -> Vec<PathBuf> {
    [checkpoint::FILE_NAME, "metrics.json", "config.json", snerf_stylize::snerf_loop::STATE_FILE]
        .iter()
        .map(|f| run.join(f))
        .collect()
}

/// `check_output` with a run's files and a dataset tree as the inputs.
pub fn guard_run_output(flag: &str, out: &Path, run: &Path, data_root: Option<&Path>) -> Result<()> {
    let files = run_files(run);
    let mut inputs: Vec<Input> = files.iter().map(|f| Input::File(f)).collect();
    if let Some(d) = data_root {
        inputs.push(Input::Tree(d));
    }
    check_output(flag, out, &inputs)
}

pub fn dispatch(cli: Cli) -> Result<()> {
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().ok();
    }
    let summary = match cli.cmd {
        Cmd::Scene(a) => scene(&a)?,
        Cmd::Data(a) => {
            let d = a.opts.load(&a.data)?;
            let s = data::summary(&d);
            if !cli.json {
                eprintln!("{}", serde_json::to_string_pretty(&s)?);
            }
            s
        }
        Cmd::Train(a) => train_cmd(&a, cli.json)?,
        Cmd::Eval(a) => eval_cmd(&a)?,
        Cmd::Turntable(a) => turntable_cmd(&a)?,
        Cmd::StylizeImage(a) => crate::stylize_cmd::stylize_image_cmd(&a)?,
        Cmd::Stylize(a) => crate::stylize_cmd::stylize_cmd(&a, cli.json)?,
        Cmd::Consistency(a) => crate::stylize_cmd::consistency_cmd(&a, cli.json)?,
        Cmd::Bake(a) => crate::bake_cmd::bake_cmd(&a)?,
        Cmd::Inspect(a) => crate::bake_cmd::inspect_cmd(&a, cli.json)?,
        Cmd::Render(a) => crate::bake_cmd::render_cmd(&a)?,
        Cmd::ExportGltf(a) => crate::bake_cmd::export_gltf_cmd(&a)?,
        Cmd::View(a) => crate::view_cmd::view_cmd(&a)?,
        Cmd::Serve(a) => crate::stream_cmd::serve_cmd(&a, cli.json)?,
        Cmd::Fetch(a) => crate::stream_cmd::fetch_cmd(&a)?,
        Cmd::Report(a) => crate::report_cmd::report_cmd(&a, cli.json)?,
        Cmd::Compare(a) => crate::report_cmd::compare_cmd(&a, cli.json)?,
        Cmd::Demo(a) => crate::demo::demo(&a, cli.json)?,
        Cmd::Bench(b) => crate::bench::run(&b)?,
    };
    if cli.json && !summary.is_null() {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    }
    Ok(())
}

pub fn bar(len: u64, template: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(ProgressStyle::with_template(template).unwrap().progress_chars("=> "));
    pb
}

pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s.split_once(['x', 'X']).with_context(|| format!("--size '{s}': expected WxH, e.g. 128x128"))?;
    let w: u32 = w.trim().parse().with_context(|| format!("--size '{s}': bad width"))?;
    let h: u32 = h.trim().parse().with_context(|| format!("--size '{s}': bad height"))?;
    if !(8..=8192).contains(&w) || !(8..=8192).contains(&h) {
        bail!("--size '{s}': width and height must be in 8..=8192");
    }
    Ok((w, h))
}

pub fn scene(a: &SceneArgs) -> Result<Value> {
    let source = snerf_scene::Source::parse(&a.name)?;
    if let snerf_scene::Source::Gltf(f) = &source {
        check_output("--out", &a.out, &[Input::Tree(f)])?;
    }
    let mut spec = snerf_scene::SceneSpec::default_for(source);
    if let Some(v) = a.views {
        spec.train_views = v;
    }
    if let Some(v) = a.test_views {
        spec.test_views = v;
    }
    if let Some(s) = &a.size {
        (spec.width, spec.height) = parse_size(s)?;
    }
    if let Some(s) = a.supersample {
        spec.supersample = s;
    }
    spec.seed = a.seed;
    spec.path = match a.path.as_str() {
        "sphere" => snerf_scene::CameraPath::Sphere,
        "orbit" => snerf_scene::CameraPath::Orbit,
        p => bail!("--path '{p}': use sphere or orbit"),
    };
    let pb = bar((spec.train_views + spec.test_views) as u64, "{spinner} rendering views {bar:30} {pos}/{len} [{elapsed}]");
    let out = snerf_scene::write_dataset(&spec, &a.out, &|done, total| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    })?;
    pb.finish_and_clear();
    eprintln!("wrote {} ({} train + {} test views)", a.out.display(), spec.train_views, spec.test_views);
    Ok(out)
}

pub fn train_cmd(a: &TrainArgs, quiet: bool) -> Result<Value> {
    let data = a.opts.load(&a.data)?;
    check_output("--out", &a.out, &[Input::Tree(&data.root), Input::Tree(&a.data)])?;
    let mut cfg = train::TrainConfig::for_dataset(&data);
    cfg.seed = a.seed;
    if let Some(b) = a.batch {
        cfg.batch_rays = b;
        cfg.batch_samples = 0;
    }
    if let Some(b) = a.batch_samples {
        cfg.batch_samples = b;
    }
    if let Some(lr) = a.lr_planes {
        cfg.lr_planes = lr;
    }
    if let Some(lr) = a.lr_mlp {
        cfg.lr_mlp = lr;
    }
    if let Some(d) = a.distortion {
        cfg.distortion = d;
    }
    if let Some(t) = a.tv {
        cfg.tv = t;
    }
    if let Some(r) = a.resolution {
        cfg.field.resolutions = vec![r / 8, r / 4, r / 2, r].into_iter().map(|x| x.max(2)).collect();
    }
    let seconds = match (a.steps, a.minutes) {
        (None, None) => Some(300.0),
        (_, m) => m.map(|m| m * 60.0),
    };
    let opts = run::RunOptions {
        dir: a.out.clone(),
        steps: a.steps,
        seconds,
        curve_pixels: a.curve_pixels,
        checkpoint_every: a.checkpoint_every,
    };
    let given = a.given_settings();
    train_run_checked(&data, cfg, &opts, a.resume, quiet, &given)
}

impl TrainArgs {
    /// The training settings this command line sets explicitly: (flag, where the setting
    /// lives in the config's JSON form), so a resumed run can refuse ones that differ.
    fn given_settings(&self) -> Vec<(&'static str, &'static str)> {
        [
            ("--resolution", "/field/resolutions", self.resolution.is_some()),
            ("--lr-planes", "/lr_planes", self.lr_planes.is_some()),
            ("--lr-mlp", "/lr_mlp", self.lr_mlp.is_some()),
            ("--distortion", "/distortion", self.distortion.is_some()),
            ("--tv", "/tv", self.tv.is_some()),
            ("--batch", "/batch_rays", self.batch.is_some()),
            ("--batch-samples", "/batch_samples", self.batch_samples.is_some()),
            ("--seed", "/seed", self.seed != 0),
        ]
        .into_iter()
        .filter(|g| g.2)
        .map(|(flag, ptr, _)| (flag, ptr))
        .collect()
    }
}

/// `train_run`, refusing a resume whose explicit settings differ from the run's own (a
/// resumed run keeps the settings it was started with; ignoring a flag silently would lie).
pub fn train_run_checked(
    data: &Dataset,
    cfg: train::TrainConfig,
    opts: &run::RunOptions,
    resume: bool,
    quiet: bool,
    given: &[(&'static str, &'static str)],
) -> Result<Value> {
    if resume && !given.is_empty() {
        if let Ok(c) = checkpoint::load(&run::checkpoint_path(&opts.dir)) {
            let theirs = serde_json::to_value(&c.cfg)?;
            let ours = serde_json::to_value(&cfg)?;
            for (flag, ptr) in given {
                let (a, b) = (ours.pointer(ptr), theirs.pointer(ptr));
                if a != b {
                    bail!(
                        "{flag} asks for {} but the run in {} was trained with {}; a resumed run keeps its \
                         settings (drop {flag}, or start a new run with another --out)",
                        a.cloned().unwrap_or(Value::Null),
                        opts.dir.display(),
                        b.cloned().unwrap_or(Value::Null)
                    );
                }
            }
        }
    }
    train_run(data, cfg, opts, resume, quiet)
}

/// Train (or resume) with a progress bar; returns the run summary.
pub fn train_run(data: &Dataset, cfg: train::TrainConfig, opts: &run::RunOptions, resume: bool, quiet: bool) -> Result<Value> {
    let wall = Instant::now();
    let out = &opts.dir;
    let _lock = snerf_files::DirLock::acquire(out)?;
    let mut trainer = run::open(data, cfg, out, resume)?;
    if !quiet {
        eprintln!(
            "training {} ({:?}{}, {} train views, {} parameters, {:.1}% of space occupied after carving)",
            data.root.display(),
            trainer.model.space.kind,
            if data.dynamic { ", dynamic" } else { "" },
            data.train.len(),
            trainer.model.field.params.len(),
            100.0 * trainer.model.occ.occupied_fraction()
        );
    }
    let pb = bar(1000, "{spinner} {bar:30} {percent:>3}% [{elapsed}<{eta}] {msg}");
    let mut ema: Option<(f64, f64)> = None;
    // RUN/report/ is redrawn whenever the curve gains a point (2, 5, 10, ... s, then every
    // minute), so a user looking at a running job sees its curve.
    let mut live = crate::report_cmd::LiveReport::new();
    let mut drawn = trainer.curve.len();
    run::run(&mut trainer, data, opts, &mut |t, s, p| {
        if t.curve.len() != drawn {
            drawn = t.curve.len();
            live.train(out, run::metrics_json(t));
        }
        let sps = s.samples as f64 / s.seconds.max(1e-9);
        let e = ema.map(|(l, r)| (0.9 * l + 0.1 * s.loss, 0.9 * r + 0.1 * sps)).unwrap_or((s.loss, sps));
        ema = Some(e);
        pb.set_position((p * 1000.0) as u64);
        if t.step % 5 == 0 {
            pb.set_message(format!(
                "step {} loss {:.5} psnr {:.2} dB {:.2} M samples/s",
                t.step,
                e.0,
                train::mse_to_psnr(e.0),
                e.1 / 1e6
            ));
        }
    })?;
    pb.finish_and_clear();
    let metrics = run::metrics_json(&trainer);
    live.train(out, metrics.clone());
    let last = trainer.curve.last();
    if !quiet {
        eprintln!(
            "trained {} steps in {:.1} s ({:.2} M samples/s); test PSNR {} -> {}",
            trainer.step,
            trainer.train_seconds,
            trainer.samples_seen as f64 / trainer.train_seconds.max(1e-9) / 1e6,
            last.and_then(|c| c.test_psnr).map(|p| format!("{p:.2} dB")).unwrap_or("n/a".into()),
            out.display()
        );
    }
    Ok(json!({
        "command": "train",
        "run": pj(out),
        "peak_rss_mb": crate::bake_cmd::peak_rss_mb(),
        "wall_seconds": wall.elapsed().as_secs_f64(),
        "report": { "dir": pj(out.join(crate::report_cmd::RUN_REPORT_DIR)), "writes": live.writes, "seconds": live.seconds },
        "metrics": metrics,
    }))
}

/// Load a run's checkpoint as a renderable model.
pub fn load_model(run_dir: &Path) -> Result<(train::Model, snerf_trainer::render::WorkspacePool)> {
    let path = run::checkpoint_path(run_dir);
    if !path.exists() {
        bail!("{}: no checkpoint here (expected {}); run `snerf train` first", run_dir.display(), path.display());
    }
    let ck = checkpoint::load(&path)?;
    let pool = snerf_trainer::render::WorkspacePool::new(ck.model.field.params.len());
    Ok((ck.model, pool))
}

pub fn eval_cmd(a: &EvalArgs) -> Result<Value> {
    let data = a.opts.load(&a.data)?;
    let (model, pool) = load_model(&a.run)?;
    let views = match a.split.as_str() {
        "test" => &data.test,
        "val" => &data.val,
        "train" => &data.train,
        s => bail!("--split '{s}': use test, val or train"),
    };
    if views.is_empty() {
        bail!("{}: the {} split is empty", a.data.display(), a.split);
    }
    let out = a.out.clone().unwrap_or_else(|| a.run.join("eval"));
    guard_run_output("--out", &out, &a.run, Some(&data.root))?;
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;
    let has_alpha = train::views_have_alpha(&data.train);
    let report = eval::evaluate(&model, &pool, views, has_alpha, Some(&out))?;
    if !(report.mean_psnr.is_finite() && report.mean_ssim.is_finite()) {
        bail!("{}: the field renders non-finite colours (PSNR {}, SSIM {}); the run diverged", a.run.display(), report.mean_psnr, report.mean_ssim);
    }
    eprintln!(
        "{} {} views: PSNR {:.2} dB, SSIM {:.4} ({:.1} s); images in {}",
        a.split,
        report.views.len(),
        report.mean_psnr,
        report.mean_ssim,
        report.seconds,
        out.display()
    );
    let v = json!({ "command": "eval", "run": pj(&a.run), "split": a.split, "report": report, "images": pj(&out) });
    checkpoint::write_json_atomic(&out.join("eval.json"), &v)?;
    Ok(v)
}

pub fn turntable_cmd(a: &TurntableArgs) -> Result<Value> {
    let data = a.opts.load(&a.data)?;
    guard_run_output("--out", &a.out, &a.run, Some(&data.root))?;
    let (model, pool) = load_model(&a.run)?;
    let frames = turntable(&model, &pool, &data, a.frames, &a.out)?;
    Ok(json!({ "command": "turntable", "frames": frames.iter().map(pj).collect::<Vec<_>>(), "out": pj(&a.out) }))
}

/// Render `n` frames on an orbit into `out/frame_NNN.png`; returns the file names.
pub fn turntable(
    model: &train::Model,
    pool: &snerf_trainer::render::WorkspacePool,
    data: &Dataset,
    n: usize,
    out: &Path,
) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let cams = snerf_trainer::camera_path::orbit(&model.space, &data.train, n.max(1));
    let k = data.test.first().unwrap_or(&data.train[0]).intrinsics;
    let bg = eval::eval_background(train::views_have_alpha(&data.train));
    let pb = bar(cams.len() as u64, "{spinner} turntable {bar:30} {pos}/{len} [{elapsed}]");
    let mut files = Vec::new();
    for (i, c2w) in cams.iter().enumerate() {
        // dynamic scenes play their time once around the orbit
        let time = data.dynamic.then(|| i as f32 / cams.len().max(2) as f32);
        let r = eval::render_camera(model, pool, c2w, &k, time, bg);
        let img = eval::side_by_side(&[&r.rgb], r.width, r.height);
        let f = out.join(format!("frame_{i:03}.png"));
        checkpoint::write_png_atomic(&f, &img)?;
        files.push(f);
        pb.inc(1);
    }
    pb.finish_and_clear();
    // The path itself, as nerfstudio's camera_path.json: `snerf render --path` of a baked
    // asset (or nerfstudio) renders the same cameras.
    let path: Vec<snerf_geometry::camera_path::PathCamera> = cams
        .iter()
        .enumerate()
        .map(|(i, c2w)| snerf_geometry::camera_path::PathCamera {
            cam: snerf_geometry::Pinhole { c2w: *c2w, fx: k.fx, fy: k.fy, cx: k.cx, cy: k.cy, width: k.width, height: k.height },
            time: data.dynamic.then(|| i as f32 / cams.len().max(2) as f32),
        })
        .collect();
    snerf_files::atomic::write_atomic(&out.join("camera_path.json"), snerf_geometry::camera_path::to_json(&path, 24.0).as_bytes())?;
    Ok(files)
}
