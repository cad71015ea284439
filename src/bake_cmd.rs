//! `snerf bake`, `snerf inspect`, `snerf render`, `snerf export-gltf`: from a trained run to a
//! baked asset file and what can be done with one.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_asset::render::{self as asset_render, Camera};
use snerf_asset::Asset;
use snerf_baker::bake::{bake, BakeOptions};
use snerf_trainer::{eval, train};

use crate::cli::{bar, load_model, parse_size, DataOpts};

#[derive(Args, Debug)]
pub struct BakeArgs {
    /// A run directory (from `snerf train` or `snerf stylize`).
    pub run: PathBuf,
    /// The asset file to write (written to a temporary file, then renamed).
    #[arg(long)]
    pub out: PathBuf,
    /// The run's dataset (default: the one recorded in RUN/config.json or the stylization's
    /// source run); its training cameras decide which blocks are visible.
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Voxels per axis of the baked grid.
    #[arg(long, default_value_t = 256)]
    pub resolution: u32,
    /// Voxels per block edge (blocks are the unit of storage and streaming).
    #[arg(long, default_value_t = 8)]
    pub block: u32,
    /// Keyframes of a dynamic scene, evenly spaced over its time range.
    #[arg(long, default_value_t = 12)]
    pub keyframes: usize,
    /// Keep a block when some voxel reaches this opacity over one march step.
    #[arg(long, default_value_t = 0.005)]
    pub min_alpha: f32,
    /// Training views for the visibility test (0 keeps hidden blocks too).
    #[arg(long, default_value_t = 32)]
    pub visibility_views: usize,
    /// Held-out views on which to measure what baking loses (0: skip).
    #[arg(long, default_value_t = 8)]
    pub eval_views: usize,
    #[command(flatten)]
    pub opts: DataOpts,
}

/// The dataset a run was trained on, from its config.json (or, for a stylization run, from
/// its options).
pub fn run_dataset(run: &Path) -> Result<PathBuf> {
    let cfg = run.join("config.json");
    if let Ok(bytes) = std::fs::read(&cfg) {
        let v: Value = serde_json::from_slice(&bytes).with_context(|| format!("{}: not JSON", cfg.display()))?;
        if let Some(root) = v.pointer("/dataset/root").and_then(|r| r.as_str()) {
            return Ok(PathBuf::from(root));
        }
    }
    let st = run.join(snerf_stylize::snerf_loop::STATE_FILE);
    if let Ok(bytes) = std::fs::read(&st) {
        let v: Value = serde_json::from_slice(&bytes).with_context(|| format!("{}: not JSON", st.display()))?;
        if let Some(root) = v.pointer("/options/data").and_then(|r| r.as_str()) {
            return Ok(PathBuf::from(root));
        }
    }
    bail!("{}: cannot tell which dataset this run used (no config.json or stylize.json); pass --data", run.display())
}

/// Peak resident memory of this process so far (Linux), in MB.
pub fn peak_rss_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

pub fn bake_cmd(a: &BakeArgs) -> Result<Value> {
    let wall = Instant::now();
    let data_path = match &a.data {
        Some(d) => d.clone(),
        None => run_dataset(&a.run)?,
    };
    let data = a.opts.load(&data_path)?;
    let (model, pool) = load_model(&a.run)?;
    let bg = eval::eval_background(train::views_have_alpha(&data.train));
    let opts = BakeOptions {
        res: a.resolution,
        block: a.block,
        keyframes: a.keyframes,
        min_alpha: a.min_alpha,
        visibility_views: a.visibility_views,
        ..Default::default()
    };
    let pb = bar(1, "{spinner} {msg} {bar:30} {pos}/{len} [{elapsed}]");
    let (asset, report) = bake(&model, &pool, &data.train, bg, &opts, &|what, done, total| {
        pb.set_message(what.to_string());
        pb.set_length(total);
        pb.set_position(done);
    })?;
    pb.finish_and_clear();
    let bake_seconds = wall.elapsed().as_secs_f64();
    asset.write(&a.out)?;
    let file_bytes = std::fs::metadata(&a.out).map(|m| m.len()).unwrap_or(0);
    let summary = asset.summary(file_bytes);
    let faith = if a.eval_views > 0 {
        let views = if data.test.is_empty() { &data.train } else { &data.test };
        Some(snerf_baker::faithfulness::measure(&model, &pool, &asset, views, a.eval_views)?)
    } else {
        None
    };
    eprintln!(
        "baked {} -> {}: {:.2} MB, {} blocks of {}³ at {}³, {:.1} s, peak memory {:.0} MB",
        a.run.display(),
        a.out.display(),
        file_bytes as f64 / 1e6,
        report.atlas_blocks,
        a.block,
        a.resolution,
        bake_seconds,
        peak_rss_mb().unwrap_or(f64::NAN)
    );
    if let Some(f) = &faith {
        eprintln!(
            "faithfulness on {} views: baked vs field {:.2} dB; test PSNR field {:.2} dB, baked {:.2} dB (drop {:.2} dB)",
            f.views.len(),
            f.mean_baked_vs_field,
            f.mean_field_vs_truth,
            f.mean_baked_vs_truth,
            f.drop_db
        );
    }
    Ok(json!({
        "command": "bake",
        "run": a.run,
        "out": a.out,
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
    let asset = Asset::read(&a.file)?;
    let bytes = std::fs::metadata(&a.file).map(|m| m.len()).unwrap_or(0);
    let s = serde_json::to_value(asset.summary(bytes))?;
    if !quiet {
        eprintln!("{}", serde_json::to_string_pretty(&s)?);
    }
    Ok(json!({ "command": "inspect", "file": a.file, "summary": s }))
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A baked asset file (.snerf).
    pub file: PathBuf,
    /// `orbit`, or a JSON file: a list of cameras {"c2w": 3x4 rows (OpenGL convention),
    /// "fx", "fy", "cx", "cy", "width", "height", optional "time"}.
    #[arg(long, default_value = "orbit")]
    pub path: String,
    /// Frames on the orbit (dynamic assets play their time once around).
    #[arg(long, default_value_t = 24)]
    pub frames: usize,
    /// Image size WxH for the orbit.
    #[arg(long, default_value = "256x256")]
    pub size: String,
    /// Output directory for frame_NNN.png and preview.png.
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(serde::Deserialize)]
struct PathCamera {
    c2w: [[f32; 4]; 3],
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    width: u32,
    height: u32,
    #[serde(default)]
    time: Option<f32>,
}

/// The cameras (and times) of `--path`.
pub fn render_path(asset: &Asset, path: &str, frames: usize, size: (u32, u32)) -> Result<Vec<(Camera, f32)>> {
    let (t0, t1) = asset.header.time_range.map(|r| (r[0], r[1])).unwrap_or((0.0, 0.0));
    if path == "orbit" {
        let n = frames.max(1);
        return Ok((0..n)
            .map(|i| {
                let cam = asset_render::orbit(&asset.header, n, i, size.0, size.1, 40f32.to_radians());
                (cam, t0 + (t1 - t0) * i as f32 / n.max(2) as f32)
            })
            .collect());
    }
    let p = Path::new(path);
    let bytes = std::fs::read(p).with_context(|| format!("--path {path}: cannot read (use `orbit` or a JSON camera file)"))?;
    let cams: Vec<PathCamera> = serde_json::from_slice(&bytes).with_context(|| format!("{path}: not a JSON list of cameras"))?;
    if cams.is_empty() {
        bail!("{path}: no cameras");
    }
    cams.into_iter()
        .enumerate()
        .map(|(i, c)| {
            if !(1..=8192).contains(&c.width) || !(1..=8192).contains(&c.height) {
                bail!("{path}: camera {i}: size {}x{} out of range", c.width, c.height);
            }
            let cam = Camera { c2w: c.c2w, fx: c.fx, fy: c.fy, cx: c.cx, cy: c.cy, width: c.width, height: c.height };
            Ok((cam, c.time.unwrap_or(t0)))
        })
        .collect()
}

pub fn render_cmd(a: &RenderArgs) -> Result<Value> {
    let asset = Asset::read(&a.file)?;
    let cams = render_path(&asset, &a.path, a.frames, parse_size(&a.size)?)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot create", a.out.display()))?;
    let pb = bar(cams.len() as u64, "{spinner} rendering {bar:30} {pos}/{len} [{elapsed}]");
    let t0 = Instant::now();
    let mut frames = Vec::new();
    let mut files = Vec::new();
    for (i, (cam, time)) in cams.iter().enumerate() {
        let f = asset_render::render(&asset, cam, *time);
        let file = a.out.join(format!("frame_{i:03}.png"));
        asset_render::write_png(&f, &file)?;
        files.push(file);
        frames.push(f);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let preview = a.out.join("preview.png");
    asset_render::contact_strip(&frames[..frames.len().min(8)], &preview)?;
    eprintln!("rendered {} frames in {:.1} s ({:.0} ms/frame, CPU reference) -> {}", frames.len(), secs, secs * 1e3 / frames.len() as f64, a.out.display());
    Ok(json!({
        "command": "render",
        "file": a.file,
        "frames": files,
        "preview": preview,
        "seconds": secs,
        "renderer": "cpu-reference",
    }))
}
