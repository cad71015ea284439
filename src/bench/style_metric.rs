//! `snerf bench style-metric`: is the weight-free style distance worth reading on these models
//! and paintings? A style distance can steer the loop and judge it only if it ranks an
//! unpainted scene well farther from the painting than a painted one. For every model (as
//! `bench snerf`: a 128² set and a realistic field, reused when there) the style ring of
//! `snerf consistency` is rendered once; for every painting the ring is stylized frame by frame
//! as `snerf consistency`'s per-frame baseline paints it (`arbitrary`, the object's box), and
//! both are scored against the painting. Separation = realistic ÷ per-frame (bar ≥ 1.5 on every
//! pair). No SNeRF loop runs, so a grid of many paintings costs seconds a pair. Writes
//! `style-metric.json` and `style-metric.md`; `--save-frames` also writes the ring's frames.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_stylize::consistency::PathGeometry;
use snerf_stylize::style_metric::StyleScore;
use snerf_stylize::stylizer::{self, Image, StylizerOptions};
use snerf_stylize::paintings;
use snerf_trainer::run_dir::RunDir;

use super::quality::select_models;
use super::snerf_grid::{realistic, style_name, Budget, ModelGrid, SEPARATION};
use crate::args::{pj, DataOpts};

#[derive(Args, Clone, Debug)]
pub struct BenchStyleMetricArgs {
    /// Directories searched (recursively) for .gltf and .glb models.
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Output directory (data/, runs/, style-metric.json, style-metric.md; frames/ with
    /// --save-frames).
    #[arg(long)]
    pub out: PathBuf,
    /// Styles, comma-separated: `painting:KEY` or image files (default: every painting
    /// `bash scripts/setup-styles.sh` installs, the six and the fifteen held out).
    #[arg(long, value_delimiter = ',')]
    pub styles: Vec<String>,
    #[command(flatten)]
    pub grid: ModelGrid,
    /// Training steps of each realistic field (by steps, so the grid repeats; shared with
    /// `bench snerf --steps` when OUT is the same directory).
    #[arg(long, default_value_t = 2000, value_parser = crate::args::int_in::<u64>(1, 10000000, ""))]
    pub steps: u64,
    /// Also write the ring's frames as PNGs: frames/MODEL/realistic_K.png, mask_K.png and
    /// frames/MODEL/STYLE/per_frame_K.png.
    #[arg(long)]
    pub save_frames: bool,
}

/// One model's ring scored against every style.
fn one_model(a: &BenchStyleMetricArgs, name: &str, data: &Path, run: &Path) -> Result<Vec<Value>> {
    let data = DataOpts::default().load(data)?;
    let (model, pool) = RunDir::new(run).load_model()?;
    // 2 path frames (the least a path holds); only the ring is scored
    let path = PathGeometry::new(&model, &pool, &data, 2)?;
    let masks = path.masks();
    let by_box = path.has_silhouette();
    let frames_dir = a.out.join("frames").join(name);
    if a.save_frames {
        std::fs::create_dir_all(&frames_dir).with_context(|| format!("{}: cannot create", frames_dir.display()))?;
        let ring = path.realistic.iter().zip(&masks).skip(path.path_frames);
        for (k, (frame, m)) in ring.enumerate() {
            stylizer::save_png(&frames_dir.join(format!("realistic_{k}.png")), frame)?;
            let data = m.iter().flat_map(|&v| [if v { 1.0 } else { 0.0 }; 3]).collect();
            stylizer::save_png(&frames_dir.join(format!("mask_{k}.png")), &Image { width: frame.width, height: frame.height, data })?;
        }
    }
    // the Gram distance on ImageNet features: the style measure neither the loop nor the
    // default stylizer aims at (absent without the installed model)
    let gram = snerf_stylize::style_gram::GramMetric::open(&StylizerOptions::default()).ok();
    let mut rows = Vec::new();
    for style in &a.styles {
        let sname = style_name(style);
        eprintln!("      × {sname}");
        let row = (|| -> Result<Value> {
            let file = paintings::resolve_style(Path::new(style))?;
            let st = stylizer::from_spec("arbitrary", Some(&file), &StylizerOptions::default())?;
            let style_img = stylizer::load_style_image(&file)?;
            let reference = path.style_reference(&style_img);
            // the path's frames stay realistic: only the ring is scored
            let per_frame = path.stylize_frames(st.as_ref(), by_box, 0, path.path_frames)?;
            if a.save_frames {
                let dir = frames_dir.join(&sname);
                std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot create", dir.display()))?;
                for (k, frame) in path.ring_part(&per_frame).iter().enumerate() {
                    stylizer::save_png(&dir.join(format!("per_frame_{k}.png")), frame)?;
                }
            }
            let real = path.style_score(&path.realistic, &reference);
            let pf = path.style_score(&per_frame, &reference);
            let mut row = json!({ "realistic": real, "per_frame": pf, "separation": real.total / pf.total });
            if let Some(g) = &gram {
                let grams = g.reference(&style_img, path.intr.width as usize, path.intr.height as usize)?;
                let (gr, gp) = (path.style_gram(&path.realistic, g, &grams)?, path.style_gram(&per_frame, g, &grams)?);
                row["gram"] = json!({ "realistic": gr, "per_frame": gp, "separation": gr / gp });
            }
            Ok(row)
        })();
        let mut v = json!({ "model": name, "style": sname });
        match row {
            Ok(r) => v.as_object_mut().unwrap().extend(r.as_object().unwrap().clone()),
            Err(e) => v["error"] = json!(format!("{e:#}")),
        }
        rows.push(v);
    }
    Ok(rows)
}

/// The table, and a line with the spread and how many pairs meet the bar.
pub fn table(pairs: &[Value]) -> String {
    let mut md = String::from("| model × style | realistic: colour + texture | per-frame: colour + texture | separation | Gram separation |\n|---|---|---|---|---|\n");
    let score = |v: &Value| serde_json::from_value::<StyleScore>(v.clone()).ok();
    let mut seps = Vec::new();
    for p in pairs {
        let name = format!("{} × {}", p["model"].as_str().unwrap_or("?"), p["style"].as_str().unwrap_or("?"));
        match (score(&p["realistic"]), score(&p["per_frame"]), p["separation"].as_f64()) {
            (Some(r), Some(f), Some(s)) => {
                seps.push(s);
                let mark = |s: f64| if s >= SEPARATION { "" } else { "**" };
                let g = p["gram"]["separation"].as_f64();
                let gram = g.map(|g| format!("{}{g:.2}{}", mark(g), mark(g))).unwrap_or_else(|| "—".into());
                md.push_str(&format!("| {name} | {:.4} + {:.4} | {:.4} + {:.4} | {}{s:.2}{} | {gram} |\n", r.color, r.texture, f.color, f.texture, mark(s), mark(s)));
            }
            _ => {
                let e: String = p["error"].as_str().unwrap_or("?").chars().take(100).collect();
                md.push_str(&format!("| {name} | failed: {e} | | |\n"));
            }
        }
    }
    if !seps.is_empty() {
        let mean = seps.iter().sum::<f64>() / seps.len() as f64;
        let lo = seps.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = seps.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let met = seps.iter().filter(|&&s| s >= SEPARATION).count();
        md.push_str(&format!(
            "\nSeparation over {} pairs: mean {mean:.2} (min {lo:.2}, max {hi:.2}); at least {SEPARATION}× on {met} of {}.\n",
            seps.len(),
            seps.len()
        ));
        let grams: Vec<f64> = pairs.iter().filter_map(|p| p["gram"]["separation"].as_f64()).collect();
        if !grams.is_empty() {
            let lo = grams.iter().copied().fold(f64::INFINITY, f64::min);
            let mean = grams.iter().sum::<f64>() / grams.len() as f64;
            let met = grams.iter().filter(|&&s| s >= SEPARATION).count();
            md.push_str(&format!("Gram separation over {} pairs: mean {mean:.2} (min {lo:.2}); at least {SEPARATION}× on {met} of {}.\n", grams.len(), grams.len()));
        }
        md.push_str(&spread(pairs, "model"));
        md.push_str(&spread(pairs, "style"));
    }
    md
}

/// Min, median and max separation per value of `key` ("model" or "style"), in first-seen
/// order: which models or paintings the distance finds hard, not only the grid's extremes.
fn spread(pairs: &[Value], key: &str) -> String {
    let mut groups: Vec<(String, Vec<f64>)> = Vec::new();
    for p in pairs {
        let (Some(name), Some(s)) = (p[key].as_str(), p["separation"].as_f64()) else { continue };
        match groups.iter_mut().find(|(n, _)| n == name) {
            Some((_, v)) => v.push(s),
            None => groups.push((name.to_string(), vec![s])),
        }
    }
    let mut md = format!("\n| {key} | pairs | min | median | max |\n|---|---|---|---|---|\n");
    for (name, mut v) in groups {
        v.sort_by(|a, b| a.total_cmp(b));
        let n = v.len();
        let median = if n % 2 == 1 { v[n / 2] } else { 0.5 * (v[n / 2 - 1] + v[n / 2]) };
        md.push_str(&format!("| {name} | {n} | {:.2} | {median:.2} | {:.2} |\n", v[0], v[n - 1]));
    }
    md
}

pub fn run(a: &BenchStyleMetricArgs) -> Result<Value> {
    let models = select_models(&a.dirs, &a.grid.only, a.grid.limit)?;
    let mut a = a.clone();
    if a.styles.is_empty() {
        a.styles = paintings::all().map(|p| format!("{}{}", paintings::STYLE_PREFIX, p.key)).collect();
    }
    let a = &a;
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot create", a.out.display()))?;
    eprintln!("{} models × {} styles", models.len(), a.styles.len());
    let budget = Budget::Steps(a.steps);
    let mut pairs = Vec::new();
    for (i, (name, file)) in models.iter().enumerate() {
        eprintln!("[{}/{}] {name}: realistic field", i + 1, models.len());
        match realistic(&a.out, &a.grid, budget, name, file).and_then(|(data, run)| one_model(a, name, &data, &run)) {
            Ok(rows) => pairs.extend(rows),
            Err(e) => {
                eprintln!("      failed: {e:#}");
                pairs.extend(a.styles.iter().map(|st| json!({ "model": name, "style": style_name(st), "error": format!("{e:#}") })));
            }
        }
        let doc = json!({ "command": "bench style-metric", "realistic_training": budget.to_json(), "pairs": pairs });
        snerf_files::write_json_atomic(&a.out.join("style-metric.json"), &doc)?;
    }
    let md = table(&pairs);
    snerf_files::write_atomic(&a.out.join("style-metric.md"), md.as_bytes())?;
    eprintln!("{md}");
    Ok(json!({ "command": "bench style-metric", "out": pj(&a.out), "pairs": pairs, "table": md }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_marks_the_pairs_below_the_bar_and_counts_them() {
        let s = |c: f64, t: f64| json!({ "total": c + t, "color": c, "texture": t });
        let pairs = [
            json!({ "model": "m", "style": "a", "realistic": s(4.0, 2.0), "per_frame": s(1.0, 1.0), "separation": 3.0 }),
            json!({ "model": "m", "style": "b", "realistic": s(1.5, 1.0), "per_frame": s(1.0, 1.0), "separation": 1.2 }),
            json!({ "model": "n", "style": "a", "error": "no such file" }),
        ];
        let md = table(&pairs);
        assert!(md.contains("| m × a | 4.0000 + 2.0000 | 1.0000 + 1.0000 | 3.00 | — |"), "{md}");
        assert!(md.contains("| m × b | 1.5000 + 1.0000 | 1.0000 + 1.0000 | **1.20** | — |"), "{md}");
        assert!(md.contains("| n × a | failed: no such file |"), "{md}");
        assert!(md.contains("Separation over 2 pairs: mean 2.10 (min 1.20, max 3.00); at least 1.5× on 1 of 2."), "{md}");
        // the spread per model and per style (a failed pair has no separation)
        assert!(md.contains("| m | 2 | 1.20 | 2.10 | 3.00 |"), "{md}");
        assert!(md.contains("| a | 1 | 3.00 | 3.00 | 3.00 |") && md.contains("| b | 1 | 1.20 | 1.20 | 1.20 |"), "{md}");
        assert!(!md.contains("| n |"), "{md}");
    }
}
