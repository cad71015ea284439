//! `snerf bench`: benchmarks that print numbers (recorded in BENCH.md).

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use serde_json::{json, Value};
use snerf_trainer::data::LoadOptions;
use snerf_trainer::render::PHASES;
use snerf_trainer::train::{StepStats, TrainConfig, Trainer};

mod capture_depth;
mod publish;
mod quality;
mod snerf_grid;
mod style_metric;
mod web;
mod web_switch;

#[derive(Subcommand, Debug)]
pub enum BenchCmd {
    /// End-to-end training throughput (gradient-carrying samples per second) and where the
    /// time goes, after a warm-up so the occupancy grid has settled.
    Train(BenchTrainArgs),
    /// One `arbitrary` stylization (tract-onnx) against onnxruntime on the same model, shapes
    /// and thread count, side by side (onnxruntime from `pip install onnxruntime`).
    Stylize(BenchStylizeArgs),
    /// QUIC streaming on loopback: fetch throughput against a plain TCP copy of the same
    /// bytes, and time to the first view.
    Stream(BenchStreamArgs),
    /// Held-out quality over many real glTF models (train for each budget, score, compare
    /// with a baseline build): table, quality.json and curves.svg.
    Quality(quality::BenchQualityArgs),
    /// The SNeRF loop over many real models × paintings (realistic field, `snerf stylize`,
    /// `snerf consistency` for each pair) scored against the stylization bars, with the
    /// spread: table, snerf.json and snerf.md.
    Snerf(snerf_grid::BenchSnerfArgs),
    /// Whether the weight-free style distance separates unpainted from painted on many real
    /// models × paintings: each model's style ring, realistic and stylized frame by frame,
    /// scored against each painting (no SNeRF loop): table, style-metric.json and .md.
    StyleMetric(style_metric::BenchStyleMetricArgs),
    /// Viewer frame time through wgpu (lavapipe when there is no GPU) against the CPU
    /// reference renderer at the same size, in the same run.
    View(BenchViewArgs),
    /// What `snerf report` costs: the whole report of the runs given, and one redraw of a
    /// run's own report as `snerf train` does it at each curve point, projected onto a
    /// 5-minute training run.
    Report(BenchReportArgs),
    /// The web viewer's bars beside the native client on loopback, one run: navigation to
    /// first frame on WebGPU and on WebGL2 against the native first view; the asset's transfer
    /// by `snerf fetch`, the page over WebTransport and the page over HTTPS requests (MB/s and
    /// ratios); frame time in headless Chromium on both renderers, flat and on an emulated
    /// Quest 3 at its per-eye size, against wgpu (lavapipe without a GPU). Needs Chromium,
    /// Node.js and playwright-core/iwer (`bash .ci/run` installs them).
    Web(web::BenchWebArgs),
    /// Switch latency between the styles of a multi-style asset on loopback: in headless
    /// Chromium, key press -> first repainted frame and -> complete view, each switch sending
    /// the new style's colour part only; beside it the page opening the style whole, and the
    /// native client's switch by colour and whole fetch. Needs Chromium, Node.js and
    /// playwright-core (`bash .ci/run` installs them).
    WebSwitch(web_switch::BenchWebSwitchArgs),
    /// A published scene (`snerf publish`) behind a real CDN edge on loopback (caddy origin,
    /// varnish edge): object sizes compared, N simulated viewers through the edge (byte-identical,
    /// p50/p99 times, origin requests per viewer, hit ratio), and the same viewers against
    /// `snerf serve`. Needs caddy and varnish (`bash .ci/run` installs them).
    Publish(publish::BenchPublishArgs),
    /// A capture's geometry against the depth sensor that filmed it (the castel sequence of
    /// visp-images-data): the metres per COLMAP unit, each point's depth against the sensor's,
    /// and whether one scale holds for every camera.
    CaptureDepth(capture_depth::BenchCaptureDepthArgs),
}

#[derive(Args, Debug)]
pub struct BenchReportArgs {
    /// Runs and records, as for `snerf report` (e.g. a directory holding 10 runs).
    #[arg(required = true)]
    pub paths: Vec<PathBuf>,
    /// Repetitions of each measurement (the median is reported).
    #[arg(long, default_value_t = 5, value_parser = crate::args::int_in::<usize>(1, 1000, ""))]
    pub reps: usize,
}

#[derive(Args, Debug)]
pub struct BenchStylizeArgs {
    /// View side in pixels (the view is SIZE x SIZE).
    #[arg(long, default_value_t = 384, value_parser = crate::args::int_in::<usize>(16, 4096, ""))]
    pub size: usize,
    #[arg(long, default_value_t = 5, value_parser = crate::args::int_in::<usize>(1, 1000, ""))]
    pub reps: usize,
}

#[derive(Args, Debug)]
pub struct BenchStreamArgs {
    /// A baked asset file.
    pub asset: PathBuf,
    /// Rounds of each measurement (the best is reported).
    #[arg(long, default_value_t = 3, value_parser = crate::args::int_in::<usize>(1, 1000, ""))]
    pub rounds: usize,
}

#[derive(Args, Debug)]
pub struct BenchTrainArgs {
    pub data: PathBuf,
    /// Steps before measuring (the first steps march through unpruned space).
    #[arg(long, default_value_t = 150, value_parser = crate::args::int_in::<u64>(0, 10000000, ""))]
    pub warmup: u64,
    /// Steps measured.
    #[arg(long, default_value_t = 50, value_parser = crate::args::int_in::<u64>(1, 10000000, ""))]
    pub steps: u64,
    /// CPU peak in GFLOP/s used for the utilization figure (default: 2 cores x 2.6 GHz x
    /// 32 f32 FLOP per cycle — two 256-bit FMA pipes, as on this machine's Zen 4 cores).
    #[arg(long, default_value_t = 166.4, value_parser = crate::args::positive)]
    pub peak_gflops: f64,
    /// Train with a deformation (`snerf train --deform`; dynamic scenes only).
    #[arg(long)]
    pub deform: bool,
}

pub fn run(cmd: &BenchCmd) -> Result<Value> {
    match cmd {
        BenchCmd::Train(a) => train(a),
        BenchCmd::Stylize(a) => stylize(a),
        BenchCmd::View(a) => bench_view(a),
        BenchCmd::Stream(a) => bench_stream(&a.asset, a.rounds),
        BenchCmd::Quality(a) => quality::run(a),
        BenchCmd::Snerf(a) => snerf_grid::run(a),
        BenchCmd::StyleMetric(a) => style_metric::run(a),
        BenchCmd::Web(a) => web::run(a),
        BenchCmd::WebSwitch(a) => web_switch::run(a),
        BenchCmd::Publish(a) => publish::run(a),
        BenchCmd::Report(a) => report(a),
        BenchCmd::CaptureDepth(a) => capture_depth::run(a),
    }
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

fn report(a: &BenchReportArgs) -> Result<Value> {
    use std::time::Instant;
    let scratch = std::env::temp_dir().join(format!("snerf-bench-report-{}", std::process::id()));
    let result = (|| -> Result<Value> {
        // the whole command: read every record, draw, write the pages
        let mut whole = Vec::new();
        let mut sources = Vec::new();
        for _ in 0..a.reps {
            let t0 = Instant::now();
            sources = snerf_report::load_all(&a.paths)?;
            let opts = snerf_report::Options { title: "bench".into(), compare: None, svg: true };
            snerf_report::write_report(&sources, &scratch.join("all"), &opts)?;
            whole.push(t0.elapsed().as_secs_f64());
        }
        // one redraw of a training run's own report, as at each new curve point
        let train = sources.iter().find(|s| s.kind == snerf_report::SourceKind::Train);
        let mut live = snerf_report::live::LiveReport::new();
        let mut per_write = None;
        if let Some(s) = train {
            let run = scratch.join("run");
            std::fs::create_dir_all(&run)?;
            for _ in 0..a.reps {
                live.train(&run, s.data["metrics"].clone());
            }
            per_write = Some(live.seconds / live.writes.max(1) as f64);
        }
        // a 5-minute run gains a curve point at each of EVAL_AT up to 300 s, at 300 s, and at the end
        let writes_5min = snerf_trainer::run::EVAL_AT.iter().filter(|&&t| t < 300.0).count() + 2;
        let overhead = per_write.map(|w| w * writes_5min as f64 / 300.0);
        let v = json!({
            "command": "bench report",
            "sources": sources.len(),
            "plots": snerf_report::plots::build(&sources).len(),
            "report_seconds_median": median(whole.clone()),
            "report_seconds": whole,
            "run_redraw_seconds": per_write,
            "redraws_in_5_minutes": writes_5min,
            "overhead_of_5_minute_run": overhead,
        });
        eprintln!(
            "snerf report on {} sources: {:.3} s (median of {}); one redraw of a run's report {}; {} redraws add {} to a 5-minute training run",
            sources.len(),
            median(whole),
            a.reps,
            per_write.map(|w| format!("{:.3} s", w)).unwrap_or("n/a (no training run given)".into()),
            writes_5min,
            overhead.map(|o| format!("{:.3}%", 100.0 * o)).unwrap_or("n/a".into())
        );
        Ok(v)
    })();
    let _ = std::fs::remove_dir_all(&scratch);
    result
}

fn stylize(a: &BenchStylizeArgs) -> Result<Value> {
    use snerf_stylize::stylizer;
    let opts = stylizer::StylizerOptions::default();
    let tract = stylizer::bench_arbitrary(&opts, a.size, a.reps)?;
    let ort = stylizer::bench_onnxruntime(&stylizer::models_dir(&opts), tract.transform_shape.0.max(tract.transform_shape.1), a.reps, tract.threads);
    let ort_transform = ort.as_ref().and_then(|v| v.pointer("/transform_median_s")).and_then(|v| v.as_f64());
    eprintln!(
        "arbitrary {}x{}: tract whole stylization {:.3} s, transform network {:.3} s; onnxruntime transform {}; ratio {}",
        a.size,
        a.size,
        tract.stylize_median_s,
        tract.transform_median_s,
        ort_transform.map(|t| format!("{t:.3} s")).unwrap_or_else(|| "n/a (pip install onnxruntime)".into()),
        ort_transform.map(|t| format!("{:.2}x", tract.transform_median_s / t)).unwrap_or_else(|| "n/a".into()),
    );
    Ok(json!({ "command": "bench stylize", "tract": tract, "onnxruntime": ort }))
}

fn train(a: &BenchTrainArgs) -> Result<Value> {
    let data = snerf_trainer::data::load(&a.data, &LoadOptions::default())?;
    let mut cfg = TrainConfig::for_dataset(&data);
    if a.deform {
        cfg.enable_deform().with_context(|| format!("--deform: {}", a.data.display()))?;
    }
    let mut t = Trainer::new(&data, cfg)?;
    eprintln!("warming up for {} steps ...", a.warmup);
    for _ in 0..a.warmup {
        t.step(0.0);
    }
    let mut sum = StepStats::default();
    let mut rays = 0u64;
    for _ in 0..a.steps {
        rays += t.rays_next as u64;
        let s = t.step(0.0);
        sum.samples += s.samples;
        sum.seconds += s.seconds;
        sum.chunk_seconds += s.chunk_seconds;
        sum.adam_seconds += s.adam_seconds;
        for i in 0..6 {
            sum.phase_ns[i] += s.phase_ns[i];
        }
        sum.loss += s.loss / a.steps as f64;
    }
    let sps = sum.samples as f64 / sum.seconds;
    let thread_ns: u64 = sum.phase_ns.iter().sum();
    let (fwd, bwd) = t.model.field.cfg.flops_per_sample();
    let field_ns: u64 = sum.phase_ns[1] + sum.phase_ns[2] + sum.phase_ns[4] + sum.phase_ns[5];
    let threads = rayon::current_num_threads() as f64;
    let field_gflops = sum.samples as f64 * (fwd + bwd) / (field_ns as f64 * 1e-9 / threads);
    let phases: Vec<Value> = PHASES
        .iter()
        .zip(sum.phase_ns)
        .map(|(n, ns)| json!({ "phase": n, "share": ns as f64 / thread_ns.max(1) as f64 }))
        .collect();
    eprintln!(
        "{:.3} M gradient-carrying samples/s end to end ({} steps, {:.0} rays/step, {:.1} samples/ray, {:.1} ms/step)",
        sps / 1e6,
        a.steps,
        rays as f64 / a.steps as f64,
        sum.samples as f64 / rays as f64,
        1e3 * sum.seconds / a.steps as f64
    );
    eprintln!(
        "step time: ray work {:.1}%, optimizer {:.1}%, occupancy+sampling {:.1}%",
        100.0 * sum.chunk_seconds / sum.seconds,
        100.0 * sum.adam_seconds / sum.seconds,
        100.0 * (sum.seconds - sum.chunk_seconds - sum.adam_seconds) / sum.seconds
    );
    for p in &phases {
        eprintln!("  {:<16} {:5.1}% of thread time", p["phase"].as_str().unwrap(), 100.0 * p["share"].as_f64().unwrap());
    }
    eprintln!(
        "field: {:.0} FLOP/sample forward+backward, {:.1} GFLOP/s while in field phases = {:.1}% of {:.0} GFLOP/s peak",
        fwd + bwd,
        field_gflops / 1e9,
        100.0 * field_gflops / 1e9 / a.peak_gflops,
        a.peak_gflops
    );
    Ok(json!({
        "command": "bench train",
        "samples_per_second": sps,
        "steps": a.steps,
        "rays_per_step": rays as f64 / a.steps as f64,
        "ms_per_step": 1e3 * sum.seconds / a.steps as f64,
        "optimizer_share": sum.adam_seconds / sum.seconds,
        "phases": phases,
        "field_flops_per_sample": fwd + bwd,
        "field_gflops": field_gflops / 1e9,
        "peak_fraction": field_gflops / 1e9 / a.peak_gflops,
        "threads": threads,
        "train_psnr": snerf_trainer::train::mse_to_psnr(sum.loss),
    }))
}

#[derive(Args, Debug)]
pub struct BenchViewArgs {
    /// A baked asset file.
    pub asset: PathBuf,
    /// Frame size WxH.
    #[arg(long, default_value = "1280x720")]
    pub size: String,
    /// Frames timed on the GPU (median reported).
    #[arg(long, default_value_t = 10, value_parser = crate::args::int_in::<usize>(1, 10000, ""))]
    pub frames: usize,
    /// Also time stereo 2x(1920x1080), the VR case.
    #[arg(long)]
    pub stereo: bool,
    /// A 4D asset: also time its first time sample as a static asset of exactly that
    /// occupancy (`Asset::frame_as_static`), same cameras, and print the playback ratio.
    #[arg(long)]
    pub static_twin: bool,
}

fn bench_view(a: &BenchViewArgs) -> Result<Value> {
    let asset = snerf_asset::Asset::read(&a.asset)?;
    let (w, h) = crate::args::parse_size(&a.size)?;
    let opts = snerf_viewer::BenchOptions { width: w, height: h, frames: a.frames.max(1), stereo: a.stereo, ..Default::default() };
    let r = snerf_viewer::bench_view_with(&asset, &opts)?;
    eprintln!("{r}");
    let twin = if a.static_twin {
        anyhow::ensure!(asset.is_dynamic(), "{}: --static-twin needs a 4D asset", a.asset.display());
        let s = asset.frame_as_static(0)?;
        let t = snerf_viewer::bench_view_with(&s, &opts)?;
        eprintln!(
            "static twin (time sample 0 alone, {} of {} blocks): GPU median {:.1} ms; 4D playback / static = {:.2}",
            s.header.atlas_blocks, asset.header.atlas_blocks, t.gpu_median_ms, r.gpu_median_ms / t.gpu_median_ms
        );
        Some(json!({ "report": t, "ratio": r.gpu_median_ms / t.gpu_median_ms }))
    } else {
        None
    };
    Ok(json!({ "command": "bench view", "asset": crate::args::pj(&a.asset), "report": r, "static_twin": twin }))
}

fn bench_stream(asset: &std::path::Path, rounds: usize) -> Result<Value> {
    let r = snerf_stream::bench::run(asset, &snerf_stream::bench::BenchOptions { rounds: rounds.max(1), ..Default::default() })?;
    eprintln!("{r}");
    Ok(json!({ "command": "bench stream", "asset": crate::args::pj(asset), "report": r.to_string() }))
}
