//! The command line's top: the subcommand enum, composed of the argument structs each
//! command module owns, and the dispatch to their functions. No command module imports this
//! one; they share only `args`, so the modules of `src/` import one way: `cli` at the top,
//! `demo` below it (it runs the whole path, so it calls the other commands' entry points
//! with their own arguments), the command modules below that, and `args` and the library
//! crates at the bottom.

use anyhow::Result;
use clap::{Parser, Subcommand};

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
    /// Photos or a video in, a posed dataset out, with COLMAP (features, matching, mapping,
    /// undistortion); see --help.
    #[command(long_about = crate::capture_cmd::CAPTURE_HELP)]
    Capture(crate::capture_cmd::CaptureArgs),
    /// Write a multi-view dataset (nerf_synthetic layout) from a built-in scene or a glTF file.
    Scene(crate::scene_cmd::SceneArgs),
    /// Describe a dataset: format, detected scene kind (and why), splits, image sizes.
    Data(crate::train_cmd::DataArgs),
    /// Train a radiance field on a dataset.
    Train(crate::train_cmd::TrainArgs),
    /// Score a trained run on held-out views: PSNR, SSIM, side-by-side images and depth.
    Eval(crate::train_cmd::EvalArgs),
    /// Render a turntable of a trained run.
    Turntable(crate::train_cmd::TurntableArgs),
    /// Stylize one image with a stylizer (arbitrary, preset:N, onnx:FILE, gatys, color).
    StylizeImage(crate::stylize_cmd::StylizeImageArgs),
    /// SNeRF: alternate render -> stylize -> train on a trained run, for a given number of rounds.
    Stylize(Box<crate::stylize_cmd::StylizeArgs>),
    /// The paper's cross-view consistency of a stylized run against per-frame stylization.
    Consistency(crate::stylize_cmd::ConsistencyArgs),
    /// Bake a run into a sparse-grid asset file (.snerf) for real-time viewing and streaming.
    Bake(crate::bake_cmd::BakeArgs),
    /// Say what is inside a baked asset file: sizes per part, occupancy, frames.
    Inspect(crate::bake_cmd::InspectArgs),
    /// Render a baked asset along a camera path to PNG frames (CPU reference renderer).
    Render(crate::bake_cmd::RenderArgs),
    /// Export a baked asset as binary glTF: a mesh (marching cubes, baked colours, world units) or Gaussian splats (KHR_gaussian_splatting, --format splats).
    ExportGltf(crate::bake_cmd::ExportGltfArgs),
    /// Show a baked asset in a window (wgpu): orbit/fly controls, stereo, 4D playback; also
    /// streams from `snerf serve` (quic://HOST:PORT/ASSET) and draws blocks as they arrive.
    View(crate::view_cmd::ViewArgs),
    /// Serve baked assets over QUIC (TLS 1.3, self-signed certificate pinned by clients, token).
    Serve(crate::stream_cmd::ServeArgs),
    /// Download a baked asset from `snerf serve` or a published manifest URL (resumable,
    /// checksum-verified).
    Fetch(crate::stream_cmd::FetchArgs),
    /// Write baked assets as a content-addressed static layout (manifest + immutable objects
    /// + the web viewer) that any HTTP host or CDN serves; clients order their own fetches.
    Publish(crate::stream_cmd::PublishArgs),
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

pub fn dispatch(cli: Cli) -> Result<()> {
    if let Some(n) = cli.threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().ok();
    }
    let summary = match cli.cmd {
        Cmd::Capture(a) => crate::capture_cmd::capture_cmd(&a, cli.threads)?,
        Cmd::Scene(a) => crate::scene_cmd::scene(&a)?,
        Cmd::Data(a) => crate::train_cmd::data_cmd(&a, cli.json)?,
        Cmd::Train(a) => crate::train_cmd::train_cmd(&a, cli.json)?,
        Cmd::Eval(a) => crate::train_cmd::eval_cmd(&a)?,
        Cmd::Turntable(a) => crate::train_cmd::turntable_cmd(&a)?,
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
        Cmd::Publish(a) => crate::stream_cmd::publish_cmd(&a)?,
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
