//! `snerf bake`, `snerf inspect`, `snerf render`, `snerf export-gltf`: from a trained run to a
//! baked asset file and what can be done with one.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_asset::render::{self as asset_render, Camera};
use snerf_asset::{Asset, LayeredAsset};
use snerf_baker::bake::{bake, BakeOptions};
use snerf_baker::layers::{bake_layered, Layer, LayeredBake};
use snerf_trainer::{eval, train};

use crate::args::{bar, parse_size, peak_rss_mb, pj, DataOpts};
use snerf_stylize::layers::LayersRecord;
use snerf_trainer::run_dir::RunDir;
use snerf_files::guard::{check_output, Input};

#[derive(Args, Debug)]
pub struct BakeArgs {
    /// A run directory (from `snerf train` or `snerf stylize`). A run stylized after several
    /// paintings (`snerf stylize --style A --style B`) bakes into one asset: the geometry once,
    /// from its first layer, and each layer's colour (every layer must share that geometry).
    pub run: PathBuf,
    /// The asset file to write (written to a temporary file, then renamed).
    #[arg(long)]
    pub out: PathBuf,
    /// The run's dataset (default: the one recorded in RUN/config.json or the stylization's
    /// source run); its training cameras decide which blocks are visible.
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Voxels per axis of the baked grid (192: the built-in object at 128² in 18 MB, 0.6 dB
    /// below the field; 256: 34 MB, 0.1 dB; see BENCH.md).
    #[arg(long, default_value_t = BakeOptions::default().res, value_parser = crate::args::int_in::<u32>(16, 2048, ""))]
    pub resolution: u32,
    /// Voxels per block edge (blocks are the unit of storage and streaming).
    #[arg(long, default_value_t = BakeOptions::default().block, value_parser = crate::args::int_in::<u32>(4, 64, ""))]
    pub block: u32,
    /// Time samples (keyframes) of a dynamic scene, evenly spaced over its time range.
    #[arg(long, default_value_t = BakeOptions::default().keyframes, value_parser = crate::args::int_in::<usize>(1, 1024, ""))]
    pub keyframes: usize,
    /// A 4D run: bake the one instant at time T (the data's time units, as its frames carry
    /// them) as a static asset instead of the animation: a pose to place in an engine or
    /// export with `export-gltf`, and the static frame a 4D asset's size is compared with.
    /// Faithfulness is then measured against the field at T from the held-out cameras.
    #[arg(long, value_name = "T", value_parser = crate::args::finite_f32)]
    pub at_time: Option<f32>,
    /// Keep a block when some voxel reaches this opacity over one march step.
    #[arg(long, default_value_t = BakeOptions::default().min_alpha, value_parser = crate::args::unit_f32)]
    pub min_alpha: f32,
    /// Dynamic scenes: a cell stores another of its sampled blocks only while that removes
    /// more than this visible RMS difference per voxel (opacity, seen colour).
    #[arg(long, default_value_t = BakeOptions::default().reuse_tolerance, value_parser = crate::args::unit_f32)]
    pub reuse_tolerance: f32,
    /// Dynamic scenes: largest asset size as a multiple of one static frame of the scene;
    /// the cells that change most over time get the blocks.
    #[arg(long, default_value_t = BakeOptions::default().time_budget, value_parser = crate::args::positive_f32)]
    pub time_budget: f32,
    /// Dynamic scenes: cells may show one reference time sample moved by an offset instead
    /// of a block of their own, so playback moves a moving part instead of blending two
    /// blocks (`snerf_baker::motion`; file version 5, with sparse grids). `--motion false`: the block codebook
    /// alone (version 1 files, for readers from before motion).
    #[arg(long, default_value_t = BakeOptions::default().motion, action = clap::ArgAction::Set, value_name = "BOOL")]
    pub motion: bool,
    /// With motion: reference time samples to try, spread evenly from the fullest; the one
    /// whose moves leave the least error is kept (1: the fullest alone; each costs a search).
    #[arg(long, default_value_t = BakeOptions::default().motion_references, value_parser = crate::args::int_in::<usize>(1, 64, ""))]
    pub motion_references: usize,
    /// Dynamic scenes: measure "one static frame" (the unit of --time-budget and of the
    /// asset's "× one static frame") as static bakes at the time samples (--at-time) keep it,
    /// each sample's visibility tested with every camera at that time, instead of with each
    /// view at its own time. What the bake keeps is the same; it costs one visibility pass
    /// per keyframe, and matters where an instant hides what another exposes.
    #[arg(long, default_value_t = BakeOptions::default().static_frame_per_sample, action = clap::ArgAction::Set, value_name = "BOOL")]
    pub static_frame_per_sample: bool,
    /// Training views for the visibility test (0 keeps hidden blocks too).
    #[arg(long, default_value_t = BakeOptions::default().visibility_views, value_parser = crate::args::int_in::<usize>(0, 100000, ""))]
    pub visibility_views: usize,
    /// Held-out views on which to measure what baking loses (0: skip).
    #[arg(long, default_value_t = 8, value_parser = crate::args::int_in::<usize>(0, 10000, ""))]
    pub eval_views: usize,
    /// The scene's world up direction (an axis like +z or x,y,z). Default: the mean up of
    /// the training cameras, stored by `snerf train`. Every viewer keeps it upright and the
    /// preview orbit turns around it.
    #[arg(long, value_parser = crate::args::direction)]
    pub up: Option<[f32; 3]>,
    /// Bake at each of these resolutions (e.g. 128,192,256) instead of --resolution: --out is
    /// then a directory with res-N/asset.snerf and res-N/bake.json per resolution, sweep.json,
    /// and report/ (faithfulness and test-PSNR drop against file size).
    #[arg(long, value_delimiter = ',', value_parser = crate::args::int_in::<u32>(16, 2048, ""))]
    pub sweep: Vec<u32>,
    #[command(flatten)]
    pub opts: DataOpts,
}

impl BakeArgs {
    /// The command line's defaults for baking `run` into `out` (what `snerf bake RUN --out
    /// OUT` would use): callers such as the demo start from these instead of restating them.
    pub fn defaults(run: &Path, out: &Path) -> BakeArgs {
        #[derive(clap::Parser)]
        struct Cmd {
            #[command(flatten)]
            bake: BakeArgs,
        }
        let cmd: Cmd = clap::Parser::parse_from([std::ffi::OsStr::new("bake"), run.as_os_str(), "--out".as_ref(), out.as_os_str()]);
        cmd.bake
    }
}

pub fn bake_cmd(a: &BakeArgs) -> Result<Value> {
    let wall = Instant::now();
    if let Some(record) = LayersRecord::read(&a.run)? {
        return bake_layers(a, &record, wall);
    }
    let data_path = match &a.data {
        Some(d) => d.clone(),
        None => RunDir::new(&a.run).dataset()?,
    };
    let data = a.opts.load(&data_path)?;
    crate::args::guard_run_output("--out", &a.out, &a.run, Some(&data.root))?;
    let (model, pool) = RunDir::new(&a.run).load_model()?;
    if model.space.dynamic && a.opts.force_static {
        bail!("{}: a 4D run; --static only changes how its data loads, the field still moves. Bake one instant with --at-time T", a.run.display());
    }
    if let Some(t) = a.at_time {
        let (lo, hi) = model.space.time_range;
        if !model.space.dynamic {
            bail!("--at-time {t}: {} is a static run (its field has no time)", a.run.display());
        }
        if !(lo..=hi).contains(&t) {
            bail!("--at-time {t}: outside {}'s time range {lo}..{hi}", a.run.display());
        }
    }
    if !a.sweep.is_empty() {
        return sweep(a, &data, &model, &pool);
    }
    bake_one(a, a.resolution, &a.out, &data, &model, &pool, wall)
}

/// `snerf bake --sweep`: one bake per resolution, each as a plain bake would write it, and
/// the sweep's summary and pictures (what each resolution costs in size and in dB).
fn sweep(a: &BakeArgs, data: &snerf_trainer::data::Dataset, model: &train::Model, pool: &snerf_trainer::render::WorkspacePool) -> Result<Value> {
    let wall = Instant::now();
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot create", a.out.display()))?;
    let mut res = a.sweep.clone();
    res.sort_unstable();
    res.dedup();
    let mut bakes = Vec::new();
    let doc = |bakes: &[Value]| {
        json!({ "command": "bake sweep", "run": pj(&a.run), "out": pj(&a.out), "resolutions": res, "bakes": bakes, "seconds": wall.elapsed().as_secs_f64() })
    };
    for &r in &res {
        eprintln!("sweep: resolution {r}");
        let dir = a.out.join(format!("res-{r}"));
        std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
        let v = bake_one(a, r, &dir.join("asset.snerf"), data, model, pool, Instant::now())?;
        snerf_files::write_json_atomic(&dir.join("bake.json"), &v)?;
        bakes.push(v);
        // after every resolution, so a long sweep shows its progress on disk
        snerf_files::write_json_atomic(&a.out.join(snerf_report::sources::SWEEP), &doc(&bakes))?;
    }
    let mut v = doc(&bakes);
    let source = snerf_report::Source::bakes(&label(&a.run), &a.out, bakes);
    let title = format!("{}: bake sweep {:?}", label(&a.run), res);
    let report = a.out.join("report");
    snerf_report::write_report(&[source], &report, &snerf_report::Options { title, compare: None, svg: true })?;
    v["report"] = pj(&report);
    eprintln!("sweep of {} resolutions in {:.1} s; pictures in {}", res.len(), wall.elapsed().as_secs_f64(), report.display());
    Ok(v)
}

fn label(run: &Path) -> String {
    let p = std::fs::canonicalize(run).unwrap_or_else(|_| run.to_path_buf());
    p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "run".into())
}

/// A layered stylize run (`snerf_stylize::layers`) into one multi-style asset
/// (`snerf_baker::layers::bake_layered`), with a line per style and its faithfulness.
fn bake_layers(a: &BakeArgs, record: &LayersRecord, wall: Instant) -> Result<Value> {
    if !a.sweep.is_empty() {
        bail!("--sweep bakes one style; bake a layer's own run (RUN/layers/NAME) to sweep it");
    }
    let dirs: Vec<PathBuf> = record.layers.iter().map(|l| LayersRecord::dir(&a.run, &l.name)).collect();
    for (l, d) in record.layers.iter().zip(&dirs) {
        if !RunDir::new(d).checkpoint().exists() {
            bail!("{}: layer {:?} has no checkpoint (its stylization has not finished; run the same `snerf stylize` again)", d.display(), l.name);
        }
    }
    let data_path = match &a.data {
        Some(d) => d.clone(),
        None => RunDir::new(&dirs[0]).dataset()?,
    };
    let data = a.opts.load(&data_path)?;
    crate::args::guard_run_output("--out", &a.out, &a.run, Some(&data.root))?;
    let bg = eval::eval_background(train::views_have_alpha(&data.train));
    let loaded = dirs.iter().map(|d| RunDir::new(d).load_model()).collect::<Result<Vec<_>>>()?;
    let layers: Vec<Layer> = record
        .layers
        .iter()
        .zip(dirs.iter().zip(&loaded))
        .map(|(l, (dir, (model, pool)))| Layer { name: &l.name, dir, source: &l.source, model, pool })
        .collect();
    let pb = bar(1, "{spinner} {msg} {bar:30} {pos}/{len} [{elapsed}]");
    let first = record.layers[0].name.clone();
    let baked = bake_layered(&layers, &data.train, bg, &bake_options(a, a.resolution), &|what, done, total| {
        pb.set_message(format!("{first}: {what}"));
        pb.set_length(total);
        pb.set_position(done);
    })?;
    pb.finish_and_clear();
    let LayeredBake { asset: layered, report, seconds } = baked;
    layered.write(&a.out)?;
    let file_bytes = std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0);
    let summary = layered.summary(file_bytes);
    let geometry = file_bytes - summary.styles.iter().map(|s| s.bytes).sum::<u64>();
    eprintln!(
        "baked {} style layers of {} -> {}: {:.2} MB, geometry {:.2} MB ({} blocks of {}³ at {}³), {:.1} s, peak memory {:.0} MB",
        layered.layers.len(),
        a.run.display(),
        a.out.display(),
        file_bytes as f64 / 1e6,
        geometry as f64 / 1e6,
        report.atlas_blocks,
        a.block,
        a.resolution,
        wall.elapsed().as_secs_f64(),
        peak_rss_mb().unwrap_or(f64::NAN)
    );
    let mut faith = Vec::new();
    for ((s, secs), ((m, p), asset)) in summary.styles.iter().zip(&seconds).zip(loaded.iter().zip(&layered.layers)) {
        let f = if a.eval_views > 0 {
            let views = if data.test.is_empty() { &data.train } else { &data.test };
            Some(snerf_baker::faithfulness::measure(m, p, asset, views, a.eval_views)?)
        } else {
            None
        };
        eprintln!(
            "  style {:<12} {:>9} bytes ({:.3} of the file), baked in {:.1} s{}",
            s.name,
            s.bytes,
            s.bytes as f64 / file_bytes.max(1) as f64,
            secs,
            f.as_ref().map(|f| format!(", baked vs field {:.2} dB", f.mean_baked_vs_field)).unwrap_or_default()
        );
        faith.push(f);
    }
    Ok(json!({
        "command": "bake",
        "run": pj(&a.run),
        "out": pj(&a.out),
        "bake_seconds": wall.elapsed().as_secs_f64(),
        "layer_seconds": seconds,
        "peak_rss_mb": peak_rss_mb(),
        "report": report,
        "asset": summary,
        "faithfulness": faith,
    }))
}

/// The bake's options from the command line, at `res` voxels per axis.
fn bake_options(a: &BakeArgs, res: u32) -> BakeOptions {
    BakeOptions {
        res,
        block: a.block,
        keyframes: a.keyframes,
        min_alpha: a.min_alpha,
        visibility_views: a.visibility_views,
        reuse_tolerance: a.reuse_tolerance,
        time_budget: a.time_budget,
        motion: a.motion,
        motion_references: a.motion_references,
        up: a.up,
        at_time: a.at_time,
        static_frame_per_sample: a.static_frame_per_sample,
    }
}

/// One bake of `model` at `res` voxels per axis into `out`; the bake's JSON summary.
fn bake_one(
    a: &BakeArgs,
    res: u32,
    out: &Path,
    data: &snerf_trainer::data::Dataset,
    model: &train::Model,
    pool: &snerf_trainer::render::WorkspacePool,
    wall: Instant,
) -> Result<Value> {
    let bg = eval::eval_background(train::views_have_alpha(&data.train));
    let opts = bake_options(a, res);
    let pb = bar(1, "{spinner} {msg} {bar:30} {pos}/{len} [{elapsed}]");
    let (asset, report) = bake(model, pool, &data.train, bg, &opts, &|what, done, total| {
        pb.set_message(what.to_string());
        pb.set_length(total);
        pb.set_position(done);
    })?;
    pb.finish_and_clear();
    let bake_seconds = wall.elapsed().as_secs_f64();
    asset.write(out)?;
    let file_bytes = std::fs::metadata(out).map(|m| m.len()).unwrap_or(0);
    let summary = asset.summary(file_bytes);
    let faith = if a.eval_views > 0 {
        let views = if data.test.is_empty() { &data.train } else { &data.test };
        // a frozen instant is compared with the field at that instant
        let frozen = a.at_time.map(|t| snerf_baker::bake::at_time(views, t));
        Some(snerf_baker::faithfulness::measure(model, pool, &asset, frozen.as_deref().unwrap_or(views), a.eval_views)?)
    } else {
        None
    };
    eprintln!(
        "baked {} -> {}: {:.2} MB, {} blocks of {}³ at {}³, {:.1} s, peak memory {:.0} MB",
        a.run.display(),
        out.display(),
        file_bytes as f64 / 1e6,
        report.atlas_blocks,
        a.block,
        res,
        bake_seconds,
        peak_rss_mb().unwrap_or(f64::NAN)
    );
    if asset.is_dynamic() {
        eprintln!(
            "4D: {} time samples, {:.2}x one static frame ({:.2} MB), {} of {} cells change, {} blocks beyond one per cell",
            asset.num_frames(),
            summary.size_vs_static_frame,
            summary.static_frame_bytes as f64 / 1e6,
            summary.cells_changing,
            summary.cells_occupied_any_frame,
            report.extra_blocks
        );
        if let Some(r) = report.motion_reference {
            eprintln!(
                "motion: {} entries show time sample {} moved ({:.1} s of search); {} entries blend two blocks in playback",
                report.motion_entries, r, report.seconds_motion, report.blended_entries
            );
        }
    }
    if asset.is_dynamic() && report.motion_reference.is_none() && summary.size_vs_static_frame > a.time_budget as f64 * 1.005 {
        eprintln!(
            "note: over --time-budget {}: one block for each of the {} cells occupied at some time, plus {} grids, already costs this much",
            a.time_budget,
            summary.cells_occupied_any_frame,
            asset.num_frames()
        );
    }
    if let Some(f) = &faith {
        let times: Vec<String> = f.views.iter().filter_map(|v| v.time).map(|t| format!("{t:.3}")).collect();
        if !times.is_empty() {
            eprintln!("faithfulness at the held-out views' own times: {}", times.join(", "));
        }
        eprintln!(
            "faithfulness on {} views: baked vs field {:.2} dB; test PSNR field {:.2} dB, baked {:.2} dB (drop {:.2} dB; baking itself {:.2} dB, drawing silhouettes unlike the field {:.2} dB)",
            f.views.len(),
            f.mean_baked_vs_field,
            f.mean_field_vs_truth,
            f.mean_baked_vs_truth,
            f.drop_db,
            f.bake_loss_db,
            f.drop_db - f.bake_loss_db
        );
    }
    Ok(json!({
        "command": "bake",
        "run": pj(&a.run),
        "out": pj(out),
        "at_time": a.at_time,
        "bake_seconds": bake_seconds,
        "peak_rss_mb": peak_rss_mb(),
        "report": report,
        "asset": summary,
        "faithfulness": faith,
    }))
}

#[derive(Args, Debug)]
pub struct InspectArgs {
    /// A baked asset file (.snerf).
    pub file: PathBuf,
}

pub fn inspect_cmd(a: &InspectArgs, quiet: bool) -> Result<Value> {
    let bytes = std::fs::metadata(&a.file).map(|m| m.len()).unwrap_or(0);
    let layered = std::fs::read(&a.file).is_ok_and(|b| snerf_asset::layers::is_layered(&b));
    let sum = if layered { LayeredAsset::read(&a.file)?.summary(bytes) } else { Asset::read(&a.file)?.summary(bytes) };
    let s = serde_json::to_value(&sum)?;
    if !quiet && !sum.styles.is_empty() {
        eprintln!("{}: {:.2} MB, {} styles over one geometry, {} frame(s)", a.file.display(), bytes as f64 / 1e6, sum.styles.len(), sum.frames);
    } else if !quiet {
        eprintln!(
            "{}: {:.2} MB, {:.2}x one static frame ({:.2} MB), {} frame(s)",
            a.file.display(),
            bytes as f64 / 1e6,
            sum.size_vs_static_frame,
            sum.static_frame_bytes as f64 / 1e6,
            sum.frames
        );
    }
    if !quiet {
        if let (Some(secs), Some(r)) = (sum.animation_seconds, &sum.bytes_per_second) {
            eprintln!(
                "animation {:.3} s: {:.0} bytes/s (header {:.0}, mlp {:.0}, grids {:.0}, blocks {:.0}); {} of {} cells change over time",
                secs, r.total, r.header, r.mlp, r.grids, r.blocks, sum.cells_changing, sum.cells_occupied_any_frame
            );
        }
        if !sum.styles.is_empty() {
            let styles: u64 = sum.styles.iter().map(|s| s.bytes).sum();
            eprintln!("{} styles; shared geometry {} bytes", sum.styles.len(), bytes - styles);
            for st in &sum.styles {
                eprintln!(
                    "  {:<12} {:>10} bytes ({:.3} of the file){}",
                    st.name,
                    st.bytes,
                    st.bytes as f64 / bytes.max(1) as f64,
                    st.source.as_deref().map(|s| format!("  after {s}")).unwrap_or_default()
                );
            }
        }
        eprintln!("{}", serde_json::to_string_pretty(&s)?);
    }
    Ok(json!({ "command": "inspect", "file": pj(&a.file), "summary": s }))
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A baked asset file (.snerf).
    pub file: PathBuf,
    /// `orbit` (the asset's preview orbit, upright about the scene's up), or a nerfstudio
    /// `camera_path.json` (camera_to_world, fov; an optional per-camera "time" for 4D assets).
    /// Every render writes the path it used to OUT/camera_path.json.
    #[arg(long, default_value = "orbit")]
    pub path: String,
    /// Frames on the orbit (dynamic assets play their time once around).
    #[arg(long, default_value_t = 24, value_parser = crate::args::int_in::<usize>(1, 10000, ""))]
    pub frames: usize,
    /// Image size WxH for the orbit.
    #[arg(long, default_value = "256x256")]
    pub size: String,
    /// Output directory for frame_NNN.png and preview.png.
    #[arg(long)]
    pub out: PathBuf,
    /// Render through the viewer's GPU shaders (wgpu; lavapipe without a GPU). Without any
    /// adapter it says so and falls back to the CPU reference renderer.
    #[arg(long)]
    pub gpu: bool,
    /// The style to draw, by name, of an asset with several (`snerf inspect` lists them;
    /// default: the first).
    #[arg(long)]
    pub style: Option<String>,
}

/// The asset of `file`, as style `style` of a multi-style asset (default: its first).
pub fn read_style(file: &Path, style: Option<&str>) -> Result<Asset> {
    let Some(name) = style else { return Asset::read(file) };
    let layered = std::fs::read(file).is_ok_and(|b| snerf_asset::layers::is_layered(&b));
    if !layered {
        bail!("{}: --style {name}: this asset holds one style (no named styles)", file.display());
    }
    let l = LayeredAsset::read(file)?;
    let i = l.styles.iter().position(|s| s.name == name);
    match i {
        Some(i) => l.into_style(i),
        None => bail!("{}: no style {name:?} (it has {})", file.display(), l.names().join(", ")),
    }
}

/// The cameras (and times) of `--path`.
pub fn render_path(asset: &Asset, path: &str, frames: usize, size: (u32, u32)) -> Result<Vec<(Camera, f32)>> {
    let (t0, t1) = asset.header.time_range.map(|r| (r[0], r[1])).unwrap_or((0.0, 0.0));
    if path == "orbit" {
        let n = frames.max(1);
        return Ok((0..n)
            .map(|i| {
                let cam = asset_render::orbit(&asset.header, n, i, size.0, size.1, 40.0);
                (cam, t0 + (t1 - t0) * i as f32 / n.max(2) as f32)
            })
            .collect());
    }
    let text = std::fs::read_to_string(path).with_context(|| format!("--path {path}: cannot read (use `orbit` or a camera_path.json)"))?;
    let cams = snerf_geometry::camera_path::parse(&text, size, 40.0).map_err(|e| anyhow::anyhow!("{path}: {e}"))?;
    Ok(cams.iter().map(|c| (c.cam, c.time.unwrap_or(t0))).collect())
}

/// The cameras of a render as a nerfstudio camera_path.json.
fn camera_path_json(cams: &[(Camera, f32)], dynamic: bool) -> String {
    let path: Vec<snerf_geometry::camera_path::PathCamera> = cams
        .iter()
        .map(|(c, t)| snerf_geometry::camera_path::PathCamera { cam: *c, time: dynamic.then_some(*t) })
        .collect();
    snerf_geometry::camera_path::to_json(&path, 24.0)
}

/// Pixels one `snerf render` may produce in all (frames x width x height): 2^28, a thousand
/// 512² frames. The GPU path holds every frame in memory before writing.
const MAX_RENDER_PIXELS: u64 = 1 << 28;

pub fn render_cmd(a: &RenderArgs) -> Result<Value> {
    let asset = read_style(&a.file, a.style.as_deref())?;
    let cams = render_path(&asset, &a.path, a.frames, parse_size(&a.size)?)?;
    let pixels: u64 = cams.iter().map(|(c, _)| c.width as u64 * c.height as u64).sum();
    if pixels > MAX_RENDER_PIXELS {
        bail!(
            "{} frames of {} pixels in all is more than one render may produce ({} Mpixel); render fewer or smaller frames",
            cams.len(),
            pixels,
            MAX_RENDER_PIXELS >> 20
        );
    }
    check_output("--out", &a.out, &[Input::File(&a.file)])?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot create", a.out.display()))?;
    let t0 = Instant::now();
    let (frames, renderer) = if a.gpu {
        let (frames, by) = snerf_viewer::render_frames_or_cpu(&asset, &cams)?;
        match by {
            snerf_viewer::RenderedBy::Gpu(info) => (frames, format!("gpu: {info}")),
            snerf_viewer::RenderedBy::Cpu(why) => {
                eprintln!("{why}");
                (frames, "cpu-reference (no GPU adapter)".to_string())
            }
        }
    } else {
        // Each frame is written as soon as it is rendered; only the preview's are kept.
        let pb = bar(cams.len() as u64, "{spinner} rendering {bar:30} {pos}/{len} [{elapsed}]");
        let mut kept = Vec::new();
        for (i, (cam, time)) in cams.iter().enumerate() {
            let f = asset_render::render(&asset, cam, *time);
            asset_render::write_png(&f, frame_file(&a.out, i))?;
            if kept.len() < 8 {
                kept.push(f);
            }
            pb.inc(1);
        }
        pb.finish_and_clear();
        (kept, "cpu-reference".to_string())
    };
    if a.gpu {
        for (i, f) in frames.iter().enumerate() {
            asset_render::write_png(f, frame_file(&a.out, i))?;
        }
    }
    let files: Vec<PathBuf> = (0..cams.len()).map(|i| frame_file(&a.out, i)).collect();
    let secs = t0.elapsed().as_secs_f64();
    let preview = a.out.join("preview.png");
    asset_render::contact_strip(&frames[..frames.len().min(8)], &preview)?;
    let path_file = a.out.join("camera_path.json");
    snerf_files::atomic::write_atomic(&path_file, camera_path_json(&cams, asset.header.is_dynamic()).as_bytes())?;
    eprintln!("rendered {} frames in {:.1} s ({:.0} ms/frame, {renderer}) -> {}", cams.len(), secs, secs * 1e3 / cams.len() as f64, a.out.display());
    Ok(json!({
        "command": "render",
        "file": pj(&a.file),
        "frames": files.iter().map(pj).collect::<Vec<_>>(),
        "preview": pj(&preview),
        "camera_path": pj(&path_file),
        "seconds": secs,
        "renderer": renderer,
        "style": a.style,
    }))
}

fn frame_file(dir: &Path, i: usize) -> PathBuf {
    dir.join(format!("frame_{i:03}.png"))
}

#[derive(Args, Debug)]
pub struct ExportGltfArgs {
    /// A baked asset file (.snerf).
    pub file: PathBuf,
    /// The .glb to write (binary glTF 2.0; written to a temporary file, then renamed).
    #[arg(long)]
    pub out: PathBuf,
    /// What to write: `mesh` (the default: a marching-cubes surface with vertex colours, which
    /// every glTF reader draws and which serves as a collision or preview proxy) or `splats`
    /// (3D Gaussian splats with KHR_gaussian_splatting: keeps soft, thin and semi-transparent
    /// matter and the stylized look, for engines that read the extension).
    #[arg(long, value_enum, default_value_t = ExportFormat::Mesh)]
    pub format: ExportFormat,
    /// Splats only: keep at most this many (merging the flattest regions first, then leaving
    /// out the faintest splats). Default: as many as the merge tolerance leaves.
    #[arg(long)]
    pub max_splats: Option<usize>,
    /// Splats only: spherical-harmonics degree of the colour, 0 to 3 (default: 0 for a diffuse
    /// asset, 1 for a view-dependent one, fitted to its view MLP by least squares).
    #[arg(long)]
    pub sh_degree: Option<u32>,
    /// Surface level: opacity of one voxel in (0,1). Lower keeps thinner, fainter matter.
    #[arg(long, default_value_t = 0.5, value_parser = crate::args::unit_f32)]
    pub iso: f32,
    /// Also measure how well the mesh agrees with this run's depth (the run the asset was
    /// baked from): median distance from the field's surface points to the mesh, in voxels.
    #[arg(long)]
    pub check: Option<PathBuf>,
    /// The dataset for --check (default: the run's).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Validate the file with the Khronos glTF validator (node + npm gltf-validator).
    #[arg(long)]
    pub validate: bool,
    /// The style to export, by name, of an asset with several (default: the first).
    #[arg(long)]
    pub style: Option<String>,
    #[command(flatten)]
    pub opts: DataOpts,
}

/// `export-gltf --format`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportFormat {
    Mesh,
    Splats,
}

pub fn export_gltf_cmd(a: &ExportGltfArgs) -> Result<Value> {
    if a.format == ExportFormat::Splats {
        return export_splats_cmd(a);
    }
    if a.max_splats.is_some() || a.sh_degree.is_some() {
        bail!("--max-splats and --sh-degree apply to --format splats only");
    }
    if !(a.iso > 0.0 && a.iso < 1.0) {
        bail!("--iso {}: must be an opacity in (0,1)", a.iso);
    }
    let mut inputs = vec![Input::File(&a.file)];
    let check_files = a.check.as_deref().map(|r| RunDir::new(r).files()).unwrap_or_default();
    inputs.extend(check_files.iter().map(|f| Input::File(f)));
    check_output("--out", &a.out, &inputs)?;
    let t0 = Instant::now();
    let asset = read_style(&a.file, a.style.as_deref())?;
    let (report, meshes) = snerf_baker::mesh_export::export_glb(&asset, a.iso, &a.out)?;
    let secs = t0.elapsed().as_secs_f64();
    eprintln!(
        "{} -> {}: {} frame(s), {} vertices, {} triangles, {:.2} MB in {:.1} s",
        a.file.display(),
        a.out.display(),
        report.frames,
        report.vertices,
        report.triangles,
        report.bytes as f64 / 1e6,
        secs
    );
    let agreement = match &a.check {
        Some(run) => Some(surface_agreement(&asset, &meshes[0], run, a.data.as_deref(), &a.opts)?),
        None => None,
    };
    let validation = if a.validate { Some(validate_glb(&a.out)?) } else { None };
    Ok(json!({
        "command": "export-gltf",
        "file": pj(&a.file),
        "out": pj(&a.out),
        "report": report,
        "seconds": secs,
        "surface_agreement": agreement,
        "validation": validation,
    }))
}

/// `export-gltf --format splats`: the asset as Gaussian splats (`snerf_baker::splats`).
fn export_splats_cmd(a: &ExportGltfArgs) -> Result<Value> {
    if a.max_splats == Some(0) {
        bail!("--max-splats 0: a splat file needs at least one splat");
    }
    if a.check.is_some() {
        bail!("--check measures the mesh's surface; it does not apply to --format splats yet");
    }
    check_output("--out", &a.out, &[Input::File(&a.file)])?;
    let t0 = Instant::now();
    let asset = read_style(&a.file, a.style.as_deref())?;
    if a.sh_degree.is_some_and(|d| d > 3) {
        bail!("--sh-degree {}: KHR_gaussian_splatting stores degrees 0 to 3", a.sh_degree.unwrap_or(0));
    }
    let opts = snerf_baker::splats::SplatOptions { max_splats: a.max_splats, sh_degree: a.sh_degree, ..Default::default() };
    let report = snerf_baker::splat_gltf::export_splats(&asset, &opts, &a.out).with_context(|| format!("{}", a.file.display()))?;
    let secs = t0.elapsed().as_secs_f64();
    let asset_bytes = std::fs::metadata(&a.file).map(|m| m.len()).unwrap_or(0);
    eprintln!(
        "{} -> {}: {} splats (from {} voxels, SH degree {}), {:.2} MB, {:.1} bytes/splat, {:.2}x the asset, in {:.1} s",
        a.file.display(),
        a.out.display(),
        report.splats,
        report.conversion.voxels,
        report.sh_degree,
        report.bytes as f64 / 1e6,
        report.bytes_per_splat,
        report.bytes as f64 / asset_bytes.max(1) as f64,
        secs
    );
    let validation = if a.validate { Some(validate_glb(&a.out)?) } else { None };
    Ok(json!({
        "command": "export-gltf",
        "format": "splats",
        "file": pj(&a.file),
        "out": pj(&a.out),
        "splats": report.splats,
        "bytes": report.bytes,
        "bytes_per_splat": report.bytes_per_splat,
        "asset_bytes": asset_bytes,
        "size_ratio": report.bytes as f64 / asset_bytes.max(1) as f64,
        "report": report,
        "seconds": secs,
        "validation": validation,
    }))
}

/// The field's surface against the exported mesh (`snerf_baker::checks`), on the run's
/// held-out views.
fn surface_agreement(asset: &Asset, mesh: &snerf_baker::marching_cubes::Mesh, run: &Path, data: Option<&Path>, opts: &DataOpts) -> Result<Value> {
    let data_path = match data {
        Some(d) => d.to_path_buf(),
        None => RunDir::new(run).dataset()?,
    };
    let data = opts.load(&data_path)?;
    let (model, pool) = RunDir::new(run).load_model()?;
    let views = if data.test.is_empty() { &data.train } else { &data.test };
    let s = snerf_baker::checks::surface_agreement(asset, mesh, &model, &pool, views).with_context(|| format!("{}", run.display()))?;
    eprintln!(
        "mesh vs field depth over {} surface points: median {:.2} voxels, 90th percentile {:.2} voxels",
        s.points, s.median_voxels, s.p90_voxels
    );
    Ok(serde_json::to_value(s)?)
}

/// Run the Khronos glTF validator (`snerf_baker::checks::validate_glb`) and print its counts.
pub fn validate_glb(path: &Path) -> Result<Value> {
    let report = snerf_baker::checks::validate_glb(path)?;
    eprintln!(
        "glTF validator: {} errors, {} warnings",
        report.pointer("/numErrors").or(report.pointer("/issues/numErrors")).unwrap_or(&json!("?")),
        report.pointer("/numWarnings").or(report.pointer("/issues/numWarnings")).unwrap_or(&json!("?"))
    );
    Ok(report)
}
