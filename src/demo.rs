//! `snerf demo`: the product's front door — the whole path on built-in data, ending in
//! pictures a person can look at (a turntable and a contact sheet) and a JSON summary.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_trainer::data::LoadOptions;
use snerf_trainer::{checkpoint, eval, train};

use crate::cli;

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Output directory (data/, run/, turntable/, contact_sheet.png, summary.json).
    #[arg(long, default_value = "demo-out")]
    pub out: PathBuf,
    /// Built-in scene: object, room, outdoor or avatar.
    #[arg(long, default_value = "object")]
    pub scene: String,
    /// Minutes of training.
    #[arg(long, default_value_t = 1.5)]
    pub minutes: f64,
    /// Image size of the generated views.
    #[arg(long, default_value = "128x128")]
    pub size: String,
    /// Training views to generate.
    #[arg(long, default_value_t = 100)]
    pub views: usize,
    /// Turntable frames.
    #[arg(long, default_value_t = 24)]
    pub frames: usize,
}

const MARKER: &str = "snerf-demo.json";

fn prepare_dir(out: &Path) -> Result<()> {
    if out.exists() {
        let empty = std::fs::read_dir(out).map(|mut d| d.next().is_none()).unwrap_or(false);
        if !empty && !out.join(MARKER).exists() {
            bail!("{}: exists and is not a snerf demo directory; choose another --out", out.display());
        }
        // A previous demo: start its run afresh (its data is regenerated below too).
        for sub in ["run", "data", "turntable"] {
            let p = out.join(sub);
            if p.exists() {
                std::fs::remove_dir_all(&p).with_context(|| format!("{}: cannot clear", p.display()))?;
            }
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    checkpoint::write_json_atomic(&out.join(MARKER), &json!({ "snerf_demo": 1 }))
}

pub fn demo(a: &DemoArgs, quiet: bool) -> Result<Value> {
    let t0 = Instant::now();
    anyhow::ensure!(a.minutes.is_finite() && a.minutes > 0.0, "--minutes must be positive");
    prepare_dir(&a.out)?;
    let data_dir = a.out.join("data");
    let run_dir = a.out.join("run");
    eprintln!("[1/4] generating the '{}' scene", a.scene);
    let scene = cli::scene(&cli::SceneArgs {
        name: a.scene.clone(),
        out: data_dir.clone(),
        views: Some(a.views),
        test_views: Some(20),
        size: Some(a.size.clone()),
        supersample: None,
        seed: 0,
        path: "sphere".into(),
    })?;
    let data = snerf_trainer::data::load(&data_dir, &LoadOptions::default())?;
    eprintln!("[2/4] training for {:.1} minutes", a.minutes);
    let cfg = train::TrainConfig::for_dataset(&data);
    let opts = snerf_trainer::run::RunOptions {
        dir: run_dir.clone(),
        steps: None,
        seconds: Some(a.minutes * 60.0),
        curve_pixels: 16384,
        checkpoint_every: 30.0,
    };
    let trained = cli::train_run(&data, cfg, &opts, false, quiet)?;
    eprintln!("[3/4] evaluating on {} held-out views", data.test.len());
    let (model, pool) = cli::load_model(&run_dir)?;
    let has_alpha = train::views_have_alpha(&data.train);
    let eval_dir = run_dir.join("eval");
    std::fs::create_dir_all(&eval_dir)?;
    let report = eval::evaluate(&model, &pool, &data.test, has_alpha, Some(&eval_dir))?;
    eprintln!("      test PSNR {:.2} dB, SSIM {:.4}", report.mean_psnr, report.mean_ssim);
    eprintln!("[4/4] rendering a {}-frame turntable", a.frames);
    let frames = cli::turntable(&model, &pool, &data, a.frames, &a.out.join("turntable"))?;
    let sheet = a.out.join("contact_sheet.png");
    contact_sheet(&eval_dir, &report, &frames, &sheet)?;
    let summary = json!({
        "command": "demo",
        "scene": scene,
        "train": trained,
        "eval": { "mean_psnr": report.mean_psnr, "mean_ssim": report.mean_ssim, "views": report.views.len() },
        "turntable": a.out.join("turntable"),
        "contact_sheet": sheet,
        "wall_seconds": t0.elapsed().as_secs_f64(),
    });
    checkpoint::write_json_atomic(&a.out.join("summary.json"), &summary)?;
    eprintln!(
        "done in {:.0} s: test PSNR {:.2} dB. Look at {} (top: prediction | truth | depth; below: turntable)",
        t0.elapsed().as_secs_f64(),
        report.mean_psnr,
        sheet.display()
    );
    Ok(summary)
}

/// Top: three evaluation triptychs (prediction | truth | depth); below: turntable frames.
fn contact_sheet(eval_dir: &Path, report: &eval::EvalReport, frames: &[PathBuf], out: &Path) -> Result<()> {
    let mut rows: Vec<image::RgbImage> = Vec::new();
    let n = report.views.len();
    for i in [0, n / 2, n.saturating_sub(1)].into_iter().take(n.min(3)) {
        let p = eval_dir.join(format!("{}.png", report.views[i].name));
        rows.push(image::open(&p).with_context(|| format!("{}: cannot read", p.display()))?.to_rgb8());
    }
    let tiles: Vec<image::RgbImage> =
        frames.iter().map(|f| image::open(f).map(|i| i.to_rgb8())).collect::<Result<_, _>>()?;
    let width = rows.iter().map(|r| r.width()).max().unwrap_or(0);
    let (tw, th) = tiles.first().map(|t| (t.width(), t.height())).unwrap_or((1, 1));
    let per_row = (width / tw.max(1)).max(1) as usize;
    let tile_rows = tiles.len().div_ceil(per_row);
    let height: u32 = rows.iter().map(|r| r.height()).sum::<u32>() + tile_rows as u32 * th;
    let mut sheet = image::RgbImage::from_pixel(width.max(tw), height.max(1), image::Rgb([24, 24, 24]));
    let mut y = 0;
    for r in &rows {
        image::imageops::overlay(&mut sheet, r, 0, y as i64);
        y += r.height();
    }
    for (i, t) in tiles.iter().enumerate() {
        let (cx, cy) = ((i % per_row) as u32 * tw, y + (i / per_row) as u32 * th);
        image::imageops::overlay(&mut sheet, t, cx as i64, cy as i64);
    }
    checkpoint::write_png_atomic(out, &sheet)
}
