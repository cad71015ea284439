//! `snerf demo`: the product's front door — the whole path on built-in data, ending in
//! pictures a person can look at (a turntable and a contact sheet) and a JSON summary.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_trainer::data::LoadOptions;
use snerf_trainer::{checkpoint, eval, train};

use crate::args::{pj, DataOpts};
use snerf_trainer::run_dir::RunDir;

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Output directory (data/, run/, turntable/, contact_sheet.png, summary.json).
    #[arg(long, default_value = "demo-out")]
    pub out: PathBuf,
    /// Built-in scene: object, room, outdoor or avatar.
    #[arg(long, default_value = "object")]
    pub scene: String,
    /// Minutes of training.
    #[arg(long, default_value_t = 1.5, value_parser = crate::args::positive)]
    pub minutes: f64,
    /// Image size of the generated views.
    #[arg(long, default_value = "128x128")]
    pub size: String,
    /// Training views to generate.
    #[arg(long, default_value_t = 100, value_parser = crate::args::int_in::<usize>(1, 10000, ""))]
    pub views: usize,
    /// Turntable frames.
    #[arg(long, default_value_t = 24, value_parser = crate::args::int_in::<usize>(1, 3600, ""))]
    pub frames: usize,
    /// Stylizer for the SNeRF step (preset:N needs no style image; `color` needs no model).
    #[arg(long, default_value = "preset:0")]
    pub stylizer: String,
    /// Style image for stylizers that take one (arbitrary, color, gatys).
    #[arg(long)]
    pub style: Option<PathBuf>,
    /// SNeRF rounds (render -> stylize -> train).
    #[arg(long, default_value_t = 3, value_parser = crate::args::int_in::<usize>(1, 100, ""))]
    pub rounds: usize,
    /// Training steps per SNeRF round.
    #[arg(long, default_value_t = 150, value_parser = crate::args::int_in::<u64>(1, 10000000, ""))]
    pub steps_per_round: u64,
    /// Do not open the viewer at the end (it opens when a display and a terminal are present).
    #[arg(long)]
    pub no_view: bool,
}

const MARKER: &str = "snerf-demo.json";

/// Frames of the novel path on which consistency is measured (per round and at the end).
const CONSISTENCY_FRAMES: usize = 16;

fn prepare_dir(out: &Path) -> Result<()> {
    if out.exists() {
        let empty = std::fs::read_dir(out).map(|mut d| d.next().is_none()).unwrap_or(false);
        if !empty && !out.join(MARKER).exists() {
            bail!("{}: exists and is not a snerf demo directory; choose another --out", out.display());
        }
        // A previous demo: start its run afresh (its data is regenerated below too).
        for sub in ["run", "data", "turntable", "stylized", "baked_turntable"] {
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
    eprintln!("[1/8] generating the '{}' scene", a.scene);
    let scene = crate::scene_cmd::scene(&crate::scene_cmd::SceneArgs {
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
    eprintln!("[2/8] training for {:.1} minutes", a.minutes);
    let cfg = train::TrainConfig::for_dataset(&data);
    let opts = snerf_trainer::run::RunOptions {
        dir: run_dir.clone(),
        steps: None,
        seconds: Some(a.minutes * 60.0),
        curve_pixels: 16384,
        checkpoint_every: 30.0,
    };
    let trained = crate::train_cmd::train_run(&data, cfg, &opts, false, quiet)?;
    eprintln!("[3/8] evaluating on {} held-out views", data.test.len());
    let (model, pool) = RunDir::new(&run_dir).load_model()?;
    let has_alpha = train::views_have_alpha(&data.train);
    let eval_dir = RunDir::new(&run_dir).eval_dir();
    std::fs::create_dir_all(&eval_dir)?;
    let report = eval::evaluate(&model, &pool, &data.test, has_alpha, Some(&eval_dir))?;
    eprintln!("      test PSNR {:.2} dB, SSIM {:.4}", report.mean_psnr, report.mean_ssim);
    // as `snerf eval` records it, so the report finds the SSIM
    checkpoint::write_json_atomic(
        &RunDir::new(&run_dir).eval_record(),
        &json!({ "command": "eval", "run": pj(&run_dir), "split": "test", "report": report, "images": pj(&eval_dir) }),
    )?;
    eprintln!("[4/8] rendering a {}-frame turntable", a.frames);
    let frames = crate::train_cmd::turntable(&model, &pool, &data, a.frames, &a.out.join("turntable"))?;

    // SNeRF: stylize the field (the stylizer falls back to colour transfer when the
    // pretrained models are not installed, and says so)
    let srun = a.out.join("stylized");
    let mut stylizer = a.stylizer.clone();
    let mut style = a.style.clone();
    let needs_models = stylizer == "arbitrary" || stylizer.starts_with("preset:");
    if needs_models && snerf_stylize::stylizer::from_spec(&stylizer, style.as_deref(), &Default::default()).is_err() {
        eprintln!(
            "      note: the pretrained stylizer models are not installed ({}); using the colour-transfer stylizer",
            snerf_stylize::stylizer::SETUP_COMMAND
        );
        stylizer = "color".into();
    }
    if stylizer == "color" && style.is_none() {
        let p = a.out.join("style.png");
        checkpoint::write_png_atomic(&p, &demo_style_image())?;
        style = Some(p);
    }
    let loop_text = match snerf_stylize::snerf_loop::DEFAULT_CONTENT {
        snerf_stylize::snerf_loop::Content::Render => format!("{} rounds of render -> stylize ({stylizer}) -> train", a.rounds),
        snerf_stylize::snerf_loop::Content::Realistic => {
            format!("the realistic views stylized once ({stylizer}), then {} rounds of render -> fuse -> train", a.rounds)
        }
    };
    eprintln!("[5/8] SNeRF: {loop_text}");
    let s_args = |rounds: usize, out: PathBuf| crate::stylize_cmd::StylizeArgs {
        run: run_dir.clone(),
        style: style.clone().into_iter().collect(),
        out,
        data: Some(data_dir.clone()),
        rounds,
        steps_per_round: Some(a.steps_per_round),
        style_res: 0,
        views: Some(0),
        appearance_only: false,
        // as many frames as the consistency step below, so the per-round curve and the
        // per-frame baseline are measured on the same path
        consistency_frames: Some(CONSISTENCY_FRAMES),
        fuse_views: snerf_stylize::snerf_loop::StylizeOptions::default().fuse_views,
        content: snerf_stylize::snerf_loop::DEFAULT_CONTENT.as_str().into(),
        seed: None,
        s: crate::stylize_cmd::StylizerArgs {
            stylizer: stylizer.clone(),
            strength: 1.0,
            gatys_weights: None,
            gatys_steps: 100,
            models: None,
        },
        opts: DataOpts::default(),
    };
    let stylized = crate::stylize_cmd::stylize_cmd(&s_args(a.rounds, srun.clone()), quiet)?;
    eprintln!("[6/8] consistency: SNeRF against stylizing each novel view on its own");
    let consistency = crate::stylize_cmd::consistency_cmd(
        &crate::stylize_cmd::ConsistencyArgs {
            srun: srun.clone(),
            data: Some(data_dir.clone()),
            one_round: None,
            frames: CONSISTENCY_FRAMES,
            path: None,
            loop_path: false,
            out: None,
            save_frames: false,
            time_frames: 12,
            opts: DataOpts::default(),
        },
        true,
    )?;
    if let Some(t) = consistency.get("table").and_then(|t| t.as_str()) {
        eprintln!("{t}");
    }
    let (smodel, spool) = RunDir::new(&srun).load_model()?;
    let sframes = crate::train_cmd::turntable(&smodel, &spool, &data, a.frames, &srun.join("turntable"))?;

    eprintln!("[7/8] baking the stylized field and rendering the baked asset");
    let asset_path = a.out.join("stylized.snerf");
    let baked = crate::bake_cmd::bake_cmd(&crate::bake_cmd::BakeArgs {
        data: Some(data_dir.clone()),
        eval_views: 4,
        ..crate::bake_cmd::BakeArgs::defaults(&srun, &asset_path)
    })?;
    let rendered = crate::bake_cmd::render_cmd(&crate::bake_cmd::RenderArgs {
        file: asset_path.clone(),
        path: "orbit".into(),
        frames: 8,
        size: a.size.clone(),
        out: a.out.join("baked_turntable"),
        gpu: false,
        style: None,
    })?;
    eprintln!("[8/8] exporting a glTF mesh");
    let glb = a.out.join("stylized.glb");
    // A short or weak training run may have no voxel as opaque as the usual level: then
    // take half the densest voxel's opacity, and say so.
    let max_alpha = snerf_baker::mesh_export::max_voxel_alpha(&snerf_asset::Asset::read(&asset_path)?);
    let iso = if max_alpha > 0.5 { 0.5 } else { (max_alpha * 0.5).max(1e-4) };
    if iso < 0.5 {
        eprintln!("      the densest voxel is only {max_alpha:.3} opaque: the mesh uses iso level {iso:.4}");
    }
    let export = |out: &Path, format| {
        crate::bake_cmd::export_gltf_cmd(&crate::bake_cmd::ExportGltfArgs {
            file: asset_path.clone(),
            out: out.to_path_buf(),
            format,
            max_splats: None,
            sh_degree: None,
            iso,
            check: None,
            data: None,
            validate: false,
            style: None,
            opts: DataOpts::default(),
        })
    };
    let exported = export(&glb, crate::bake_cmd::ExportFormat::Mesh)?;
    // the same asset as Gaussian splats (KHR_gaussian_splatting), for engines that draw them
    let splats_glb = a.out.join("stylized_splats.glb");
    let exported_splats = export(&splats_glb, crate::bake_cmd::ExportFormat::Splats)?;
    // error against run time: the training curve, the rounds, the bake, as pictures
    let bake_json = a.out.join("bake.json");
    checkpoint::write_json_atomic(&bake_json, &baked)?;
    let sources = snerf_report::load_all(&[run_dir.clone(), srun.clone(), bake_json])?;
    let plots = snerf_report::plots::build(&sources);
    let title = format!("snerf demo: the '{}' scene", a.scene);
    snerf_report::write_plots(&sources, &plots, &a.out, &snerf_report::Options { title, compare: None, svg: true })?;
    let sheet = a.out.join("contact_sheet.png");
    let consistency_png = srun.join("consistency.png");
    contact_sheet(&eval_dir, &report, &[&frames, &sframes], &consistency_png, &plots, &sheet)?;
    let summary = json!({
        "command": "demo",
        "scene": scene,
        "train": trained,
        "eval": { "mean_psnr": report.mean_psnr, "mean_ssim": report.mean_ssim, "views": report.views.len() },
        "turntable": pj(a.out.join("turntable")),
        "stylize": stylized,
        "consistency": consistency,
        "bake": baked,
        "baked_render": rendered,
        "gltf": exported,
        "gltf_splats": exported_splats,
        "contact_sheet": pj(&sheet),
        "report": pj(a.out.join(snerf_report::pages::HTML)),
        "wall_seconds": t0.elapsed().as_secs_f64(),
    });
    checkpoint::write_json_atomic(&a.out.join("summary.json"), &summary)?;
    eprintln!(
        "done in {:.0} s: test PSNR {:.2} dB; stylized, baked ({}) and exported ({}, {}).\n\
         Look at {} (prediction | truth | depth beside the training curve; the realistic and the stylized turntables; the \
         stylization rounds; style | realistic | per-frame | SNeRF) and {}.\n\
         View the baked asset: snerf view {}",
        t0.elapsed().as_secs_f64(),
        report.mean_psnr,
        asset_path.display(),
        glb.display(),
        splats_glb.display(),
        sheet.display(),
        a.out.join(snerf_report::pages::HTML).display(),
        asset_path.display()
    );
    let display = std::env::var_os("DISPLAY").is_some() || std::env::var_os("WAYLAND_DISPLAY").is_some();
    if !a.no_view && !quiet && display && std::io::IsTerminal::is_terminal(&std::io::stdin()) {
        eprintln!("opening the viewer (Esc closes it; H lists the keys)");
        let view = crate::view_cmd::ViewArgs {
            asset: asset_path.display().to_string(),
            pin: None,
            token: Default::default(),
            size: "1280x720".into(),
            fov: 50.0,
            stereo: false,
            ipd: 0.064,
            poses: None,
            no_vsync: false,
            frames: None,
            screenshot: None,
            loop_seconds: 4.0,
        };
        if let Err(e) = crate::view_cmd::view_cmd(&view) {
            eprintln!("the viewer could not open ({e:#}); run: snerf view {}", asset_path.display());
        }
    }
    Ok(summary)
}

/// A warm, stripy picture to use as the style when no style image is given.
fn demo_style_image() -> image::RgbImage {
    image::RgbImage::from_fn(256, 256, |x, y| {
        let (fx, fy) = (x as f32 / 256.0, y as f32 / 256.0);
        let w = ((fx * 9.0 + (fy * 7.0).sin() * 1.5).sin() * 0.5 + 0.5) * 0.8 + 0.2 * fy;
        let c = |a: [f32; 3], b: [f32; 3]| [0, 1, 2].map(|i| ((a[i] * (1.0 - w) + b[i] * w) * 255.0) as u8);
        image::Rgb(c([0.95, 0.75, 0.2], [0.15, 0.25, 0.6]))
    })
}

/// The contact sheet, full width everywhere: the evaluation triptychs (prediction | truth |
/// depth) beside the training curve; the realistic and the stylized turntables; the
/// per-round stylization curves side by side; the consistency sheet. Its width is the
/// consistency sheet's (or eight turntable frames), so the turntables fill whole rows.
fn contact_sheet(
    eval_dir: &Path,
    report: &eval::EvalReport,
    turntables: &[&[PathBuf]],
    consistency: &Path,
    plots: &[snerf_report::Plot],
    out: &Path,
) -> Result<()> {
    let bg = image::Rgb([255, 255, 255]);
    let plot = |id: &str| plots.iter().find(|p| p.id == id);
    let mut triptychs: Vec<image::RgbImage> = Vec::new();
    let n = report.views.len();
    for i in [0, n / 2, n.saturating_sub(1)].into_iter().take(n.min(3)) {
        let p = eval_dir.join(format!("{}.png", report.views[i].name));
        triptychs.push(image::open(&p).with_context(|| format!("{}: cannot read", p.display()))?.to_rgb8());
    }
    // small views are scaled up so the first band is as tall as a readable plot
    let sum_h: u32 = triptychs.iter().map(|t| t.height()).sum();
    if sum_h > 0 && sum_h < 320 {
        for t in triptychs.iter_mut() {
            let (w, h) = (t.width() * 320 / sum_h, t.height() * 320 / sum_h);
            *t = image::imageops::resize(t, w.max(1), h.max(1), image::imageops::FilterType::Triangle);
        }
    }
    let consistency_img = image::open(consistency).ok().map(|c| c.to_rgb8());
    let tiles: Vec<Vec<image::RgbImage>> = turntables
        .iter()
        .map(|frames| frames.iter().map(|f| image::open(f).map(|i| i.to_rgb8())).collect::<Result<Vec<_>, _>>())
        .collect::<Result<_, _>>()?;
    let (tw, th) = tiles.iter().flatten().next().map(|t| (t.width(), t.height())).unwrap_or((128, 128));
    let trip_w = triptychs.iter().map(|t| t.width()).max().unwrap_or(0);
    let width = consistency_img.as_ref().map(|c| c.width()).unwrap_or(8 * tw).max(trip_w + 320).max(tw);
    let mut bands: Vec<image::RgbImage> = Vec::new();
    // 1: triptychs | training curve
    let trip_h: u32 = triptychs.iter().map(|t| t.height()).sum::<u32>().max(320);
    let mut band = image::RgbImage::from_pixel(width, trip_h, bg);
    let mut y = 0;
    for t in &triptychs {
        image::imageops::overlay(&mut band, t, 0, y as i64);
        y += t.height();
    }
    if let Some(p) = plot("psnr") {
        image::imageops::overlay(&mut band, &snerf_report::draw::rgb(p, width - trip_w, trip_h)?, trip_w as i64, 0);
    }
    bands.push(band);
    // 2: turntables in whole rows: as few rows as the frames need at their size, the
    // frames scaled so a row spans the sheet (a short last row is centred)
    for frames in &tiles {
        let n = frames.len().max(1) as u32;
        let rows = (n * tw).div_ceil(width).max(1);
        let per_row = n.div_ceil(rows) as usize;
        let (tw, th) = (width / per_row as u32, (th * width / per_row as u32 / tw.max(1)).max(1));
        let scaled: Vec<image::RgbImage> = frames
            .iter()
            .map(|t| if t.dimensions() == (tw, th) { t.clone() } else { image::imageops::resize(t, tw, th, image::imageops::FilterType::Triangle) })
            .collect();
        let frames = &scaled;
        let nrows = frames.len().div_ceil(per_row) as u32;
        let mut block = image::RgbImage::from_pixel(width, (nrows * th).max(1), image::Rgb([24, 24, 24]));
        for (i, t) in frames.iter().enumerate() {
            let row = i / per_row;
            let in_row = (frames.len() - row * per_row).min(per_row) as u32;
            let x0 = (width - in_row * tw) / 2;
            image::imageops::overlay(&mut block, t, (x0 + (i % per_row) as u32 * tw) as i64, (row as u32 * th) as i64);
        }
        bands.push(block);
    }
    // 3: the stylization rounds, side by side
    let round_plots: Vec<&snerf_report::Plot> =
        ["stylize_consistency", "stylize_style", "stylize_fit"].iter().filter_map(|id| plot(id)).filter(|p| !p.is_empty()).take(2).collect();
    if !round_plots.is_empty() {
        let h = 320;
        let mut band = image::RgbImage::from_pixel(width, h, bg);
        let w = width / round_plots.len() as u32;
        for (i, p) in round_plots.iter().enumerate() {
            let wi = if i + 1 == round_plots.len() { width - w * i as u32 } else { w };
            image::imageops::overlay(&mut band, &snerf_report::draw::rgb(p, wi, h)?, (w * i as u32) as i64, 0);
        }
        bands.push(band);
    }
    // 4: style | realistic | per-frame | SNeRF
    if let Some(c) = consistency_img {
        let mut band = image::RgbImage::from_pixel(width, c.height(), bg);
        image::imageops::overlay(&mut band, &c, ((width - c.width()) / 2) as i64, 0);
        bands.push(band);
    }
    let h: u32 = bands.iter().map(|b| b.height()).sum();
    let mut sheet = image::RgbImage::from_pixel(width, h.max(1), bg);
    let mut y = 0;
    for b in &bands {
        image::imageops::overlay(&mut sheet, b, 0, y as i64);
        y += b.height();
    }
    checkpoint::write_png_atomic(out, &sheet)
}
