//! `snerf bench snerf`: the SNeRF loop over many real models × paintings, scored against the
//! stylization bars, with the spread. For every model (glTF/GLB under the given directories,
//! one variant per name, as `bench quality`) a 128² set is rendered and a realistic field
//! trained with the defaults; for every painting the run is stylized (`snerf stylize`) and
//! measured (`snerf consistency`). Per pair: SNeRF ÷ per-frame stylization (short- and
//! long-range warp error, weight-free style distance), last round ÷ round 1 of the per-round
//! record (convergence), and how much farther the realistic field is from the painting than
//! per-frame stylization (separation). Each step is a child `snerf` process; finished steps are
//! reused when the command is repeated. Writes `snerf.json` and `snerf.md`; exits non-zero when
//! a pair failed (after scoring the others).

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde_json::{json, Value};

use super::quality::{s, select_models, snerf_json};
use crate::args::pj;
use snerf_trainer::run_dir::RunDir;

#[derive(Args, Debug)]
pub struct BenchSnerfArgs {
    /// Directories searched (recursively) for .gltf and .glb models.
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Output directory (data/, runs/, stylized/, snerf.json, snerf.md).
    #[arg(long)]
    pub out: PathBuf,
    /// Styles, comma-separated: `painting:KEY` or image files.
    #[arg(long, value_delimiter = ',', default_value = "painting:vangogh,painting:renoir,painting:kandinsky")]
    pub styles: Vec<String>,
    #[command(flatten)]
    pub grid: ModelGrid,
    /// Seconds of realistic training per model.
    #[arg(long, default_value_t = 90.0, value_parser = crate::args::positive)]
    pub seconds: f64,
    /// Train each model's realistic field for this many steps instead of --seconds: training
    /// repeats bit for bit, so the whole grid then gives the same figures on another run on
    /// this machine (a wall-clock budget stops at a different step under another load).
    #[arg(long, value_parser = crate::args::int_in::<u64>(1, 10000000, ""))]
    pub steps: Option<u64>,
    /// Flags passed to every `snerf stylize` (the short settings BENCH.md §5 uses by default).
    #[arg(long, allow_hyphen_values = true, default_value = "--views 16 --rounds 5 --steps-per-round 100 --consistency-frames 12")]
    pub stylize_flags: String,
    /// Frames of the novel path `snerf consistency` scores.
    #[arg(long, default_value_t = 24, value_parser = crate::args::int_in::<usize>(2, 1000, ""))]
    pub frames: usize,
}

/// Which models a grid takes and the data rendered from each (shared by `bench snerf` and
/// `bench style-metric`, so the two reuse each other's data and realistic fields).
#[derive(Args, Clone, Debug)]
pub struct ModelGrid {
    /// Only models whose name contains one of these (comma-separated).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// At most this many models (0: all), taken in name order.
    #[arg(long, default_value_t = 0)]
    pub limit: usize,
    /// Image side of the generated views.
    #[arg(long, default_value_t = 128, value_parser = crate::args::int_in::<u32>(16, 1024, ""))]
    pub size: u32,
    /// Training views per model.
    #[arg(long, default_value_t = 100, value_parser = crate::args::int_in::<usize>(2, 1000, ""))]
    pub views: usize,
}

/// How long each realistic field trains: `--steps` when given, else `--seconds`.
#[derive(Clone, Copy, Debug)]
pub(super) enum Budget {
    Steps(u64),
    Seconds(f64),
}

impl BenchSnerfArgs {
    fn budget(&self) -> Budget {
        self.steps.map(Budget::Steps).unwrap_or(Budget::Seconds(self.seconds))
    }
}

impl Budget {
    /// Whether a run's `metrics.json` shows the budget trained.
    fn spent(self, metrics: &Value) -> bool {
        match self {
            Budget::Steps(n) => metrics["step"].as_u64().is_some_and(|k| k >= n),
            Budget::Seconds(t) => metrics["train_seconds"].as_f64().is_some_and(|done| done >= t - 1.0),
        }
    }

    /// The `snerf train` flags that ask for it.
    fn train_args(self) -> [String; 2] {
        match self {
            Budget::Steps(n) => ["--steps".into(), n.to_string()],
            Budget::Seconds(t) => ["--minutes".into(), format!("{}", t / 60.0)],
        }
    }

    pub(super) fn to_json(self) -> Value {
        match self {
            Budget::Steps(n) => json!({ "steps": n }),
            Budget::Seconds(t) => json!({ "seconds": t }),
        }
    }
}

/// The bars (BENCH.md §5): SNeRF ÷ per-frame on the mean and on every pair, convergence and
/// separation on every pair.
pub const MEAN_SHORT: f64 = 0.35;
pub const MEAN_LONG: f64 = 0.5;
pub const MEAN_STYLE: f64 = 1.0;
pub const PAIR_SHORT: f64 = 0.5;
pub const PAIR_LONG: f64 = 0.7;
pub const SEPARATION: f64 = 1.5;
/// The style bar on the independent measure (the Gram distance on ImageNet features, which
/// neither the loop nor the default stylizer aims at): SNeRF ≤ 1.1× per-frame's, mean.
pub const MEAN_GRAM: f64 = 1.1;

/// A style argument's short name: `painting:KEY` -> KEY, a file -> its stem.
pub(super) fn style_name(style: &str) -> String {
    match style.strip_prefix(snerf_stylize::paintings::STYLE_PREFIX) {
        Some(k) => k.to_string(),
        None => std::path::Path::new(style).file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| style.to_string()),
    }
}

/// The numbers of one pair, read from `snerf consistency`'s JSON.
pub fn pair_scores(c: &Value) -> Result<Value> {
    let methods = c["methods"].as_array().context("no methods")?;
    let (real, per_frame, snerf) = match methods.as_slice() {
        [r, p, .., s] => (r, p, s),
        _ => bail!("fewer than three methods"),
    };
    let f = |v: &Value, k: &str| -> Result<f64> {
        match k {
            "style" => v["style_swd"]["total"].as_f64(),
            _ => v[k].as_f64(),
        }
        .with_context(|| format!("missing {k}"))
    };
    let ratio = |a: &Value, b: &Value, k: &str| -> Result<f64> { Ok(f(a, k)? / f(b, k)?) };
    let rounds = c["rounds"].as_array().context("no per-round record")?;
    let (first, last) = (rounds.first().context("no rounds")?, rounds.last().context("no rounds")?);
    // What the last round trained measured, as measured (a record of an earlier release that
    // discarded the round carries the kept field's scores, and what it trained under
    // `discarded`).
    let trained = if last["discarded"].is_object() { &last["discarded"] } else { last };
    let gram = |a: &Value, b: &Value| part_ratio(a, b, &["style_gram"]);
    Ok(json!({
        "snerf_over_per_frame": {
            "short_range": ratio(snerf, per_frame, "short_range")?,
            "long_range": ratio(snerf, per_frame, "long_range")?,
            "style": ratio(snerf, per_frame, "style")?,
            "gram": gram(snerf, per_frame),
        },
        "last_over_first_round": {
            "rounds": rounds.len(),
            "short_range": ratio(trained, first, "short_range")?,
            "long_range": ratio(trained, first, "long_range")?,
            "style": ratio(trained, first, "style")?,
        },
        // rounds in which the stylizer painted (the paper's loop: every one)
        "stylizer_rounds": rounds.iter().filter(|r| r["stylized_views"].as_u64().is_some_and(|n| n > 0)).count(),
        // which frames the scores are on: the ratios above on `snerf consistency`'s path, the
        // rounds on the loop's own
        "path": c["path"].clone(),
        "rounds_measured_on": first["measured_on"].clone(),
        // what the style's change over the rounds is made of, and what the Gram distance on
        // ImageNet features says of it (readouts: the bar is on the weight-free total)
        "style_parts_last_over_first": {
            "colour": part_ratio(last, first, &["style_swd", "color"]),
            "texture": part_ratio(last, first, &["style_swd", "texture"]),
            "gram": part_ratio(last, first, &["style_gram"]),
        },
        "separation": ratio(real, per_frame, "style")?,
        "gram_separation": gram(real, per_frame),
        // share of the painting's colours a view has nothing within a JND of (a readout)
        "palette_missed": { "per_frame": per_frame["style_swd"]["missed"].as_f64(), "snerf": snerf["style_swd"]["missed"].as_f64() },
        // what the last targets allow (a field that held them exactly; absent in older records)
        "targets_carried_over_per_frame": c["targets_carried_over_per_frame"].clone(),
    }))
}

/// `a ÷ b` of the number at `path` in both, if both have it (older records may not).
fn part_ratio(a: &Value, b: &Value, path: &[&str]) -> Option<f64> {
    let get = |v: &Value| path.iter().fold(v, |v, k| &v[*k]).as_f64();
    Some(get(a)? / get(b)?).filter(|r| r.is_finite())
}

/// Mean, min and max of `xs`.
fn spread(xs: &[f64]) -> (f64, f64, f64) {
    let mean = xs.iter().sum::<f64>() / xs.len().max(1) as f64;
    let lo = xs.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (mean, lo, hi)
}

/// Every bar over the scored pairs: value, whether it is met, and how many pairs meet it.
pub fn bars(pairs: &[Value]) -> Value {
    let col = |group: &str, k: &str| -> Vec<f64> { pairs.iter().filter_map(|p| p["scores"][group][k].as_f64()).collect() };
    let n = pairs.iter().filter(|p| p["scores"].is_object()).count();
    let (short, long, style) = (col("snerf_over_per_frame", "short_range"), col("snerf_over_per_frame", "long_range"), col("snerf_over_per_frame", "style"));
    let sep: Vec<f64> = pairs.iter().filter_map(|p| p["scores"]["separation"].as_f64()).collect();
    let gram = col("snerf_over_per_frame", "gram");
    let gram_sep: Vec<f64> = pairs.iter().filter_map(|p| p["scores"]["gram_separation"].as_f64()).collect();
    let conv: Vec<f64> = pairs
        .iter()
        .filter_map(|p| {
            let r = &p["scores"]["last_over_first_round"];
            Some(r["short_range"].as_f64()?.max(r["long_range"].as_f64()?).max(r["style"].as_f64()?))
        })
        .collect();
    let (ms, ml, mst) = (spread(&short).0, spread(&long).0, spread(&style).0);
    let pair_ok = pairs.iter().filter(|p| p["scores"]["snerf_over_per_frame"]["short_range"].as_f64().is_some_and(|x| x <= PAIR_SHORT) && p["scores"]["snerf_over_per_frame"]["long_range"].as_f64().is_some_and(|x| x <= PAIR_LONG)).count();
    json!({
        "pairs": n,
        "ratios": { "mean_short_range": ms, "mean_long_range": ml, "mean_style": mst, "pairs_within": pair_ok,
                    "met": n > 0 && ms <= MEAN_SHORT && ml <= MEAN_LONG && mst <= MEAN_STYLE && pair_ok == n },
        "convergence": { "pairs_met": conv.iter().filter(|&&x| x <= 1.0).count(), "worst": spread(&conv).2, "met": n > 0 && conv.iter().all(|&x| x <= 1.0) },
        "separation": { "pairs_met": sep.iter().filter(|&&x| x >= SEPARATION).count(), "min": spread(&sep).1, "met": n > 0 && sep.iter().all(|&x| x >= SEPARATION) },
        "gram": { "mean": spread(&gram).0, "max": spread(&gram).2, "met": !gram.is_empty() && spread(&gram).0 <= MEAN_GRAM,
                  "separation_pairs_met": gram_sep.iter().filter(|&&x| x >= SEPARATION).count(), "separation_min": spread(&gram_sep).1 },
    })
}

/// The Markdown table and the bar lines.
pub fn table(pairs: &[Value], bars: &Value) -> String {
    let mut md = String::from("| model × style | SNeRF ÷ per-frame: short / long / style / Gram | last ÷ first round: short / long / style | separation: style / Gram | stylizer rounds | loop s |\n|---|---|---|---|---|---|\n");
    for p in pairs {
        let name = format!("{} × {}", p["model"].as_str().unwrap_or("?"), p["style"].as_str().unwrap_or("?"));
        if let Some(e) = p["error"].as_str() {
            let short: String = e.chars().take(100).collect();
            md.push_str(&format!("| {name} | failed: {short} | | | | |\n"));
            continue;
        }
        let sc = &p["scores"];
        let g = |group: &str, k: &str| sc[group][k].as_f64().unwrap_or(f64::NAN);
        md.push_str(&format!(
            "| {name} | {:.3} / {:.3} / {:.2} / {:.2} | {:.3} / {:.3} / {:.4} | {:.2} / {:.2} | {} of {} | {:.0} |\n",
            g("snerf_over_per_frame", "short_range"),
            g("snerf_over_per_frame", "long_range"),
            g("snerf_over_per_frame", "style"),
            g("snerf_over_per_frame", "gram"),
            g("last_over_first_round", "short_range"),
            g("last_over_first_round", "long_range"),
            g("last_over_first_round", "style"),
            sc["separation"].as_f64().unwrap_or(f64::NAN),
            sc["gram_separation"].as_f64().unwrap_or(f64::NAN),
            sc["stylizer_rounds"],
            sc["last_over_first_round"]["rounds"],
            p["loop_seconds"].as_f64().unwrap_or(f64::NAN),
        ));
    }
    let col = |group: &str, k: &str| -> Vec<f64> { pairs.iter().filter_map(|p| p["scores"][group][k].as_f64()).collect() };
    let fmt = |xs: Vec<f64>| {
        if xs.is_empty() {
            return "—".to_string();
        }
        let (m, lo, hi) = spread(&xs);
        format!("{m:.3} ({lo:.3}…{hi:.3})")
    };
    let n = bars["pairs"].as_u64().unwrap_or(0);
    let yes = |b: &Value| if b["met"].as_bool() == Some(true) { "met" } else { "NOT met" };
    md.push_str(&format!(
        "\nOver {n} pairs, mean (min…max): SNeRF ÷ per-frame short {}, long {}, style {}, Gram {}; separation {}, Gram {}.\n",
        fmt(col("snerf_over_per_frame", "short_range")),
        fmt(col("snerf_over_per_frame", "long_range")),
        fmt(col("snerf_over_per_frame", "style")),
        fmt(col("snerf_over_per_frame", "gram")),
        fmt(pairs.iter().filter_map(|p| p["scores"]["separation"].as_f64()).collect()),
        fmt(pairs.iter().filter_map(|p| p["scores"]["gram_separation"].as_f64()).collect()),
    ));
    if let Some(path) = pairs.iter().find_map(|p| p["scores"]["path"].as_str()) {
        md.push_str(&format!("Ratios scored on {path}; rounds measured on {}.\n", pairs.iter().find_map(|p| p["scores"]["rounds_measured_on"].as_str()).unwrap_or("the loop's path")));
    }
    let missed = |k: &str| -> Vec<f64> { pairs.iter().filter_map(|p| p["scores"]["palette_missed"][k].as_f64()).map(|x| 100.0 * x).collect() };
    let (pf_missed, sn_missed) = (missed("per_frame"), missed("snerf"));
    if !sn_missed.is_empty() {
        md.push_str(&format!(
            "Painting colours a view misses by more than a just-noticeable difference, % (mean (min…max)): per-frame {}, SNeRF {}.\n",
            fmt(pf_missed),
            fmt(sn_missed)
        ));
    }
    let parts = |k: &str| -> Vec<f64> { pairs.iter().filter_map(|p| p["scores"]["style_parts_last_over_first"][k].as_f64()).collect() };
    let (colour, texture, gram) = (parts("colour"), parts("texture"), parts("gram"));
    if !colour.is_empty() {
        let rises = |xs: &[f64]| xs.iter().filter(|&&x| x > 1.0).count();
        md.push_str(&format!(
            "Last ÷ first round by the style's parts, mean (min…max), pairs above 1: colour {} {}, texture {} {}; Gram distance on ImageNet features {} {} (readouts, not bars).\n",
            fmt(colour.clone()),
            rises(&colour),
            fmt(texture.clone()),
            rises(&texture),
            fmt(gram.clone()),
            rises(&gram),
        ));
    }
    md.push_str(&format!(
        "- Ratios (mean ≤ {MEAN_SHORT} / {MEAN_LONG} / {MEAN_STYLE}, every pair ≤ {PAIR_SHORT} / {PAIR_LONG}): {} ({} of {n} pairs within)\n",
        yes(&bars["ratios"]),
        bars["ratios"]["pairs_within"]
    ));
    md.push_str(&format!(
        "- Convergence (the last round trained, as measured, at least as good as round 1 on all three, every pair; nothing discarded): {} ({} of {n}; worst axis {:.4})\n",
        yes(&bars["convergence"]),
        bars["convergence"]["pairs_met"],
        bars["convergence"]["worst"].as_f64().unwrap_or(f64::NAN)
    ));
    md.push_str(&format!(
        "- Separation (realistic ≥ {SEPARATION}× farther than per-frame, every pair): {} ({} of {n}; lowest {:.2})\n",
        yes(&bars["separation"]),
        bars["separation"]["pairs_met"],
        bars["separation"]["min"].as_f64().unwrap_or(f64::NAN)
    ));
    md.push_str(&format!(
        "- Style on the independent measure (Gram, SNeRF ÷ per-frame mean ≤ {MEAN_GRAM}): {} (mean {:.3}, max {:.3}); Gram separation ≥ {SEPARATION} on {} of {n} (lowest {:.2})\n",
        yes(&bars["gram"]),
        bars["gram"]["mean"].as_f64().unwrap_or(f64::NAN),
        bars["gram"]["max"].as_f64().unwrap_or(f64::NAN),
        bars["gram"]["separation_pairs_met"],
        bars["gram"]["separation_min"].as_f64().unwrap_or(f64::NAN),
    ));
    md
}

/// Renders one model's views (`size`² pixels, `views` of them) into `out/data/NAME` and trains
/// its realistic field into `out/runs/NAME` for `budget`; both are reused when already there.
/// Returns (dataset, run).
pub(super) fn realistic(out: &std::path::Path, grid: &ModelGrid, budget: Budget, name: &str, file: &std::path::Path) -> Result<(PathBuf, PathBuf)> {
    for shared in ["data", "runs"] {
        no_dangling_link(&out.join(shared))?;
    }
    let data = out.join("data").join(name);
    if !data.join("transforms_train.json").exists() {
        let size = format!("{0}x{0}", grid.size);
        snerf_json(&["scene".into(), format!("gltf:{}", s(file)), "--out".into(), s(&data), "--size".into(), size, "--views".into(), grid.views.to_string()])?;
    }
    let run = out.join("runs").join(name);
    let done = std::fs::read(RunDir::new(&run).metrics()).ok().and_then(|b| serde_json::from_slice::<Value>(&b).ok()).is_some_and(|m| budget.spent(&m));
    if !done {
        let mut args = vec!["train".to_string(), s(&data), "--out".into(), s(&run)];
        args.extend(budget.train_args());
        if RunDir::new(&run).checkpoint().exists() {
            args.push("--resume".into());
        }
        snerf_json(&args)?;
    }
    Ok((data, run))
}

/// `out/data` and `out/runs` may be links to another benchmark's (to reuse its fields); one
/// whose target is gone would otherwise surface as "File exists" from a command deep inside.
fn no_dangling_link(p: &std::path::Path) -> Result<()> {
    let is_link = p.symlink_metadata().is_ok_and(|m| m.file_type().is_symlink());
    if is_link && !p.exists() {
        let target = std::fs::read_link(p).map(|t| t.display().to_string()).unwrap_or_default();
        bail!("{}: a symbolic link to {target}, which does not exist", p.display());
    }
    Ok(())
}

/// Stylizes `run` with `style` and scores it (each step reused when already there).
fn one_pair(a: &BenchSnerfArgs, run: &std::path::Path, model: &str, style: &str) -> Result<Value> {
    let srun = a.out.join("stylized").join(format!("{model}--{}", style_name(style)));
    let cons = srun.join("consistency.json");
    let scored = std::fs::read(&cons).ok().and_then(|b| serde_json::from_slice::<Value>(&b).ok()).is_some_and(|c| {
        // scored on this path, under today's pixel rule (older records are scored again)
        c["frames"].as_u64() == Some(a.frames as u64) && c["warp_pixels"].as_str() == Some(snerf_stylize::consistency::WARP_PIXELS)
    });
    if !scored {
        // `snerf stylize` resumes a run with the same options and does nothing once it is done
        let mut args = vec!["stylize".to_string(), s(run), "--style".into(), style.to_string(), "--out".into(), s(&srun)];
        args.extend(a.stylize_flags.split_whitespace().map(str::to_string));
        snerf_json(&args)?;
        snerf_json(&["consistency".into(), s(&srun), "--frames".into(), a.frames.to_string()])?;
    }
    let c: Value = serde_json::from_slice(&std::fs::read(&cons).with_context(|| format!("{}: cannot read", cons.display()))?).with_context(|| format!("{}: not JSON", cons.display()))?;
    let st: Value = serde_json::from_slice(&std::fs::read(srun.join("stylize.json")).with_context(|| format!("{}: cannot read stylize.json", srun.display()))?)?;
    let loop_seconds = st["records"].as_array().and_then(|r| r.last()).and_then(|r| r["wall_seconds"].as_f64());
    Ok(json!({ "srun": pj(&srun), "scores": pair_scores(&c).with_context(|| format!("{}", cons.display()))?, "loop_seconds": loop_seconds }))
}

pub fn run(a: &BenchSnerfArgs) -> Result<Value> {
    let models = select_models(&a.dirs, &a.grid.only, a.grid.limit)?;
    if a.styles.is_empty() {
        bail!("--styles is empty");
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot create", a.out.display()))?;
    eprintln!("{} models × {} styles", models.len(), a.styles.len());
    let mut pairs = Vec::new();
    for (i, (name, file)) in models.iter().enumerate() {
        eprintln!("[{}/{}] {name}: realistic field", i + 1, models.len());
        let run = realistic(&a.out, &a.grid, a.budget(), name, file).map(|(_, run)| run);
        for style in &a.styles {
            let mut p = json!({ "model": name, "style": style_name(style) });
            match run.as_ref().map_err(|e| anyhow::anyhow!("{e:#}")).and_then(|r| {
                eprintln!("      × {}", style_name(style));
                one_pair(a, r, name, style)
            }) {
                Ok(v) => p.as_object_mut().unwrap().extend(v.as_object().unwrap().clone()),
                Err(e) => {
                    eprintln!("      failed: {e:#}");
                    p["error"] = json!(format!("{e:#}"));
                }
            }
            pairs.push(p);
            // written after every pair, so a long benchmark shows its progress on disk
            let doc = json!({ "command": "bench snerf", "realistic_training": a.budget().to_json(), "stylize_flags": a.stylize_flags, "pairs": pairs, "bars": bars(&pairs) });
            snerf_files::write_json_atomic(&a.out.join("snerf.json"), &doc)?;
        }
    }
    let b = bars(&pairs);
    let md = table(&pairs, &b);
    snerf_files::write_atomic(&a.out.join("snerf.md"), md.as_bytes())?;
    eprintln!("{md}");
    // A grid with a pair missing is not a measurement of the grid: say so with the exit status
    // (every pair, failed ones with their error, is in snerf.json either way).
    if let Some(msg) = failed_pairs(&pairs) {
        bail!("{msg}; every pair's result is in {}", a.out.join("snerf.json").display());
    }
    Ok(json!({ "command": "bench snerf", "out": pj(&a.out), "pairs": pairs, "bars": b, "table": md }))
}

/// "N of M pairs failed (first: MODEL × STYLE: ERROR)", or None when none did.
fn failed_pairs(pairs: &[Value]) -> Option<String> {
    let failed: Vec<&Value> = pairs.iter().filter(|p| p.get("error").is_some()).collect();
    let first = failed.first()?;
    Some(format!(
        "{} of {} pairs failed (first: {} × {}: {})",
        failed.len(),
        pairs.len(),
        first["model"].as_str().unwrap_or("?"),
        first["style"].as_str().unwrap_or("?"),
        first["error"].as_str().unwrap_or("?")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_link_to_nothing_is_named() {
        let dir = snerf_files::ScratchDir::new("snerf-grid-link", "dangling").unwrap();
        std::fs::create_dir_all(dir.join("real")).unwrap();
        no_dangling_link(&dir.join("absent")).unwrap();
        std::os::unix::fs::symlink(dir.join("real"), dir.join("good")).unwrap();
        no_dangling_link(&dir.join("good")).unwrap();
        std::os::unix::fs::symlink(dir.join("gone"), dir.join("data")).unwrap();
        let e = no_dangling_link(&dir.join("data")).unwrap_err().to_string();
        assert!(e.contains("data: a symbolic link to") && e.contains("gone, which does not exist"), "{e}");
    }

    fn consistency(real: f64, pf: (f64, f64, f64), sn: (f64, f64, f64), r1: (f64, f64, f64), r5: (f64, f64, f64)) -> Value {
        let m = |s: f64, l: f64, st: f64| json!({ "short_range": s, "long_range": l, "style_swd": { "total": st, "color": 0.6 * st, "texture": 0.4 * st }, "style_gram": 2.0 * st });
        json!({
            "methods": [m(0.001, 0.002, real), m(pf.0, pf.1, pf.2), m(sn.0, sn.1, sn.2)],
            "rounds": [m(r1.0, r1.1, r1.2), m(0.0, 0.0, 0.0), m(r5.0, r5.1, r5.2)],
        })
    }

    #[test]
    fn scores_and_bars_follow_the_definitions() {
        let c = consistency(0.6, (0.01, 0.02, 0.3), (0.002, 0.005, 0.27), (0.004, 0.01, 0.28), (0.003, 0.008, 0.27));
        let s = pair_scores(&c).unwrap();
        assert!((s["snerf_over_per_frame"]["short_range"].as_f64().unwrap() - 0.2).abs() < 1e-12);
        assert!((s["snerf_over_per_frame"]["long_range"].as_f64().unwrap() - 0.25).abs() < 1e-12);
        assert!((s["snerf_over_per_frame"]["style"].as_f64().unwrap() - 0.9).abs() < 1e-12);
        assert!((s["last_over_first_round"]["long_range"].as_f64().unwrap() - 0.8).abs() < 1e-12);
        assert!((s["snerf_over_per_frame"]["gram"].as_f64().unwrap() - 0.9).abs() < 1e-12);
        // an earlier release's record whose last round was discarded: what that round
        // trained is scored, not the kept field's scores it carries
        let mut cd = c.clone();
        cd["rounds"][2]["discarded"] = json!({ "short_range": 0.002, "long_range": 0.01, "style_swd": { "total": 0.3 } });
        let sd = pair_scores(&cd).unwrap();
        assert!((sd["last_over_first_round"]["short_range"].as_f64().unwrap() - 0.5).abs() < 1e-12);
        assert!((sd["last_over_first_round"]["style"].as_f64().unwrap() - 0.3 / 0.28).abs() < 1e-12);
        assert!((s["separation"].as_f64().unwrap() - 2.0).abs() < 1e-12);
        for k in ["colour", "texture", "gram"] {
            assert!((s["style_parts_last_over_first"][k].as_f64().unwrap() - 0.27 / 0.28).abs() < 1e-12, "{k}");
        }
        let good = json!({ "model": "a", "style": "x", "scores": s });
        let b = bars(std::slice::from_ref(&good));
        assert_eq!((b["ratios"]["met"].as_bool(), b["convergence"]["met"].as_bool(), b["separation"]["met"].as_bool()), (Some(true), Some(true), Some(true)));
        // round 5 a hair worse on style, and the realistic field only 1.2× as far: both bars fail
        let c2 = consistency(0.36, (0.01, 0.02, 0.3), (0.002, 0.005, 0.27), (0.004, 0.01, 0.27), (0.003, 0.008, 0.2701));
        let bad = json!({ "model": "b", "style": "x", "scores": pair_scores(&c2).unwrap() });
        let failed = json!({ "model": "c", "style": "x", "error": "boom" });
        let pairs = [good, bad, failed];
        let b = bars(&pairs);
        assert_eq!(b["pairs"], 2);
        assert_eq!(b["convergence"]["met"], false);
        assert_eq!(b["convergence"]["pairs_met"], 1);
        assert_eq!(b["separation"]["pairs_met"], 1);
        assert_eq!(b["ratios"]["met"], true);
        let md = table(&pairs, &b);
        assert!(md.contains("| a × x | 0.200 / 0.250 / 0.90 / 0.90 |"), "{md}");
        assert!(md.contains("colour 0.982 (0.964…1.000) 1, texture 0.982 (0.964…1.000) 1; Gram"), "{md}");
        assert_eq!(failed_pairs(&pairs).as_deref(), Some("1 of 3 pairs failed (first: c × x: boom)"));
        assert_eq!(failed_pairs(&pairs[..2]), None);
        assert!(md.contains("c × x | failed: boom"), "{md}");
        assert!(md.contains("Separation") && md.contains("NOT met (1 of 2; lowest 1.20)"), "{md}");
    }

    #[test]
    fn style_names() {
        assert_eq!(style_name("painting:greatwave"), "greatwave");
        assert_eq!(style_name("/x/y/starry.png"), "starry");
    }
}
