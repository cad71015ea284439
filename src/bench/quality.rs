//! `snerf bench quality`: held-out quality over many real models, as a user would meet them.
//! Every glTF/GLB model found under the given directories (one variant per model name) is
//! rendered into a 128² set (100 train / 20 held-out views), trained once per time budget
//! with the defaults, and scored: held-out PSNR at 10/30/60/300 s of training, `snerf eval`
//! PSNR and SSIM at the end, train PSNR and the train-test gap, samples/s and peak memory.
//! Each step is a child `snerf` process (so peak memory is the run's own, and one model that
//! fails does not stop the rest); finished steps are reused when the command is repeated.
//! Animated models are rendered as monocular sequences (one camera, at its own time, per
//! training view; held-out views at times between them) and also report the worst held-out
//! view and the held-out PSNR against animation time.
//! Writes `quality.json`, `quality.md` and `curves.svg` (held-out PSNR against training time),
//! and for animated models `time.svg` (held-out PSNR against animation time).

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context, Result};
use clap::Args;
use serde_json::{json, Value};

use crate::args::pj;
use snerf_trainer::run_dir::RunDir;

#[derive(Args, Debug)]
pub struct BenchQualityArgs {
    /// Directories searched (recursively) for .gltf and .glb models.
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Output directory (data/, runs/, quality.json, quality.md, curves.svg).
    #[arg(long)]
    pub out: PathBuf,
    /// Training budgets in seconds, one run per budget (e.g. 60,300).
    #[arg(long, value_delimiter = ',', default_value = "60", value_parser = crate::args::positive)]
    pub seconds: Vec<f64>,
    /// Image side of the generated views.
    #[arg(long, default_value_t = 128, value_parser = crate::args::int_in::<u32>(16, 1024, ""))]
    pub size: u32,
    /// Training views per model.
    #[arg(long, default_value_t = 100, value_parser = crate::args::int_in::<usize>(2, 1000, ""))]
    pub views: usize,
    /// Held-out views per model.
    #[arg(long, default_value_t = 20, value_parser = crate::args::int_in::<usize>(1, 1000, ""))]
    pub test_views: usize,
    /// At most this many models (0: all), taken in name order.
    #[arg(long, default_value_t = 0)]
    pub limit: usize,
    /// Only models whose name contains one of these (comma-separated).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// A quality.json from another build: print the per-model difference at each budget.
    #[arg(long)]
    pub baseline: Option<PathBuf>,
    /// Extra flags passed to every `snerf train` (e.g. "--tv 0.01"), for comparing settings.
    #[arg(long, allow_hyphen_values = true)]
    pub train_flags: Option<String>,
}

/// Training seconds at which the held-out curve is reported.
const AT: [f64; 4] = [10.0, 30.0, 60.0, 300.0];

/// Models under `dirs`, one per name: `Foo-glTF/Foo.gltf`, `Foo-glTF-Binary/Foo.glb`, ... are
/// variants of one model `Foo`; the plain glTF (then GLB) variant is taken.
pub fn find_models(dirs: &[PathBuf]) -> Result<Vec<(String, PathBuf)>> {
    fn walk(d: &Path, out: &mut Vec<PathBuf>) {
        let Ok(rd) = std::fs::read_dir(d) else { return };
        let mut entries: Vec<_> = rd.flatten().map(|e| e.path()).collect();
        entries.sort();
        for p in entries {
            if p.is_dir() {
                walk(&p, out);
            } else if matches!(p.extension().and_then(|e| e.to_str()), Some("gltf" | "glb")) {
                out.push(p);
            }
        }
    }
    let mut files = Vec::new();
    for d in dirs {
        if !d.is_dir() {
            bail!("{}: not a directory", d.display());
        }
        walk(d, &mut files);
    }
    let rank = |p: &Path| {
        let parent = p.parent().and_then(|q| q.file_name()).map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
        let variant = if parent.ends_with("-glTF") { 0 } else if parent.ends_with("-glTF-Binary") { 1 } else if parent.ends_with("-glTF-Embedded") { 2 } else { 3 };
        (variant, p.to_path_buf())
    };
    let mut by_name: std::collections::BTreeMap<String, PathBuf> = Default::default();
    for f in files {
        // `Foo-glTF*/Foo.gltf` is model Foo; otherwise the folder names it too
        // (`oculus-touch-v3/left.glb` is model oculus-touch-v3-left).
        let stem = f.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
        let parent = f.parent().and_then(|q| q.file_name()).map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
        let name = if parent.contains("glTF") || parent.is_empty() { stem } else { format!("{parent}-{stem}") };
        let name: String = name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect();
        match by_name.get(&name) {
            Some(prev) if rank(prev) <= rank(&f) => {}
            _ => {
                by_name.insert(name, f);
            }
        }
    }
    Ok(by_name.into_iter().collect())
}

pub(super) fn snerf_json(args: &[String]) -> Result<Value> {
    let exe = std::env::current_exe().context("cannot find the snerf executable")?;
    let out = Command::new(exe).arg("--json").args(args).output().context("cannot run snerf")?;
    let v: Value = serde_json::from_slice(&out.stdout).unwrap_or(Value::Null);
    if !out.status.success() {
        let err = v["error"].as_str().map(str::to_string).unwrap_or_else(|| String::from_utf8_lossy(&out.stderr).trim().to_string());
        bail!("snerf {}: {err}", args.first().map(String::as_str).unwrap_or(""));
    }
    Ok(v)
}

pub(super) fn s(p: &Path) -> String {
    p.to_string_lossy().to_string()
}

/// Held-out PSNR of a run's curve at `t` seconds (the last point measured at or before it).
fn psnr_at(curve: &[Value], t: f64) -> Option<f64> {
    curve
        .iter()
        .filter(|c| c["train_seconds"].as_f64().is_some_and(|x| x <= t + 0.5))
        .filter_map(|c| c["test_psnr"].as_f64())
        .next_back()
}

fn one_model(a: &BenchQualityArgs, name: &str, file: &Path) -> Result<Value> {
    let data = a.out.join("data").join(name);
    if !data.join("transforms_train.json").exists() {
        let size = format!("{}x{}", a.size, a.size);
        snerf_json(&[
            "scene".into(),
            format!("gltf:{}", s(file)),
            "--out".into(),
            s(&data),
            "--size".into(),
            size,
            "--views".into(),
            a.views.to_string(),
            "--test-views".into(),
            a.test_views.to_string(),
        ])?;
    }
    let info = snerf_json(&["data".into(), s(&data)])?;
    let dynamic = info["dynamic"].as_bool() == Some(true);
    let mut runs = Vec::new();
    for &secs in &a.seconds {
        let run = a.out.join("runs").join(format!("{name}-{secs}s"));
        let metrics_path = RunDir::new(&run).metrics();
        let done = std::fs::read(&metrics_path)
            .ok()
            .and_then(|b| serde_json::from_slice::<Value>(&b).ok())
            .filter(|m| m["train_seconds"].as_f64().is_some_and(|t| t >= secs - 1.0));
        let mut peak = None;
        if done.is_none() {
            let mut args = vec!["train".to_string(), s(&data), "--out".into(), s(&run), "--minutes".into(), format!("{}", secs / 60.0)];
            if RunDir::new(&run).checkpoint().exists() {
                args.push("--resume".into());
            }
            if let Some(f) = &a.train_flags {
                args.extend(f.split_whitespace().map(str::to_string));
            }
            let t = snerf_json(&args)?;
            peak = t["peak_rss_mb"].as_f64();
        }
        let metrics: Value = serde_json::from_slice(&std::fs::read(&metrics_path).with_context(|| format!("{}: missing", metrics_path.display()))?)?;
        let test = snerf_json(&["eval".into(), s(&run), s(&data)])?;
        let train = snerf_json(&["eval".into(), s(&run), s(&data), "--split".into(), "train".into(), "--out".into(), s(&run.join("eval-train"))])?;
        let curve = metrics["curve"].as_array().cloned().unwrap_or_default();
        let test_psnr = test["report"]["mean_psnr"].as_f64();
        let train_psnr = train["report"]["mean_psnr"].as_f64();
        let views = test["report"]["views"].as_array().cloned().unwrap_or_default();
        let worst = views.iter().filter_map(|v| v["psnr"].as_f64()).reduce(f64::min);
        // an animated model: held-out PSNR against the held-out view's time, in time order
        let mut by_time: Vec<(f64, f64)> = views.iter().filter_map(|v| Some((v["time"].as_f64()?, v["psnr"].as_f64()?))).collect();
        by_time.sort_by(|a, b| a.0.total_cmp(&b.0));
        runs.push(json!({
            "seconds": secs,
            "run": pj(&run),
            "psnr_at": AT.iter().filter(|&&t| t <= secs + 0.5).map(|&t| json!({ "t": t, "psnr": psnr_at(&curve, t) })).collect::<Vec<_>>(),
            "eval_psnr": test_psnr,
            "eval_ssim": test["report"]["mean_ssim"].as_f64(),
            "eval_worst_psnr": worst,
            "psnr_by_time": by_time.iter().map(|&(t, p)| json!([t, p])).collect::<Vec<_>>(),
            "train_psnr": train_psnr,
            "gap": train_psnr.zip(test_psnr).map(|(a, b)| a - b),
            "samples_per_second": metrics["samples_per_second"].as_f64(),
            "peak_rss_mb": peak,
            "curve": curve.iter().map(|c| json!([c["train_seconds"], c["test_psnr"]])).collect::<Vec<_>>(),
        }));
    }
    Ok(json!({ "model": name, "file": pj(file), "dynamic": dynamic, "runs": runs }))
}

fn fmt(v: Option<f64>, d: usize) -> String {
    v.map(|x| format!("{x:.d$}")).unwrap_or_else(|| "—".into())
}

fn mean_spread(xs: &[f64]) -> String {
    if xs.is_empty() {
        return "—".into();
    }
    let mean = xs.iter().sum::<f64>() / xs.len() as f64;
    let (lo, hi) = xs.iter().fold((f64::MAX, f64::MIN), |(l, h), &x| (l.min(x), h.max(x)));
    format!("{mean:.2} ({lo:.2}…{hi:.2})")
}

/// The Markdown table: one row per model and budget, then the mean with its range.
fn table(models: &[Value], baseline: Option<&Value>) -> String {
    let mut md = String::from("| model | budget | PSNR@10s | @30s | @60s | @300s | eval PSNR | worst view | SSIM | train PSNR | gap | samples/s | peak MB |");
    if baseline.is_some() {
        md.push_str(" Δ eval vs baseline |");
    }
    md.push('\n');
    md.push_str(&"|---".repeat(13 + baseline.is_some() as usize));
    md.push_str("|\n");
    // per budget: (eval PSNR, gap, Δ vs baseline, worst view) of every model
    type Columns = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);
    let mut per_budget: std::collections::BTreeMap<i64, Columns> = Default::default();
    for m in models {
        let name = m["model"].as_str().unwrap_or("?");
        if let Some(e) = m["error"].as_str() {
            let short: String = e.chars().take(100).collect();
            md.push_str(&format!("| {name} | skipped: {short}{} |\n", if e.len() > short.len() { "…" } else { "" }));
            continue;
        }
        for r in m["runs"].as_array().into_iter().flatten() {
            let secs = r["seconds"].as_f64().unwrap_or(0.0);
            let at = |t: f64| r["psnr_at"].as_array().and_then(|a| a.iter().find(|p| p["t"].as_f64() == Some(t))).and_then(|p| p["psnr"].as_f64());
            let base = baseline.and_then(|b| {
                b["models"].as_array()?.iter().find(|x| x["model"] == m["model"])?["runs"]
                    .as_array()?
                    .iter()
                    .find(|x| x["seconds"].as_f64() == Some(secs))?["eval_psnr"]
                    .as_f64()
            });
            let eval = r["eval_psnr"].as_f64();
            let entry = per_budget.entry(secs as i64).or_default();
            if let Some(e) = eval {
                entry.0.push(e);
            }
            if let Some(g) = r["gap"].as_f64() {
                entry.1.push(g);
            }
            if let Some(w) = r["eval_worst_psnr"].as_f64() {
                entry.3.push(w);
            }
            if let Some(d) = eval.zip(base).map(|(a, b)| a - b) {
                entry.2.push(d);
            }
            md.push_str(&format!(
                "| {name} | {secs:.0} s | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                fmt(at(10.0), 2),
                fmt(at(30.0), 2),
                fmt(at(60.0), 2),
                fmt(at(300.0), 2),
                fmt(eval, 2),
                fmt(r["eval_worst_psnr"].as_f64(), 2),
                fmt(r["eval_ssim"].as_f64(), 4),
                fmt(r["train_psnr"].as_f64(), 2),
                fmt(r["gap"].as_f64(), 2),
                r["samples_per_second"].as_f64().map(|x| format!("{:.2} M", x / 1e6)).unwrap_or("—".into()),
                fmt(r["peak_rss_mb"].as_f64(), 0),
            ));
            if baseline.is_some() {
                md.push_str(&format!(" {} |", eval.zip(base).map(|(a, b)| format!("{:+.2}", a - b)).unwrap_or("—".into())));
            }
            md.push('\n');
        }
    }
    md.push('\n');
    for (secs, (evals, gaps, deltas, worst)) in &per_budget {
        md.push_str(&format!(
            "{secs} s over {} models: eval PSNR mean (min…max) {}; worst view {}; train−test gap {}{}\n",
            evals.len(),
            mean_spread(evals),
            mean_spread(worst),
            mean_spread(gaps),
            if deltas.is_empty() { String::new() } else { format!("; Δ vs baseline {}", mean_spread(deltas)) }
        ));
    }
    md
}

/// Every run's points of `key` ([x, PSNR] pairs), one labelled line per model and budget.
fn lines_of(models: &[Value], key: &str) -> Vec<(String, Vec<(f64, f64)>)> {
    let mut lines = Vec::new();
    for m in models {
        for run in m["runs"].as_array().into_iter().flatten() {
            let pts: Vec<(f64, f64)> = run[key]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|p| Some((p[0].as_f64()?, p[1].as_f64()?)))
                .filter(|(_, p)| p.is_finite())
                .collect();
            if !pts.is_empty() {
                let label = format!("{} ({:.0} s)", m["model"].as_str().unwrap_or("?"), run["seconds"].as_f64().unwrap_or(0.0));
                lines.push((label, pts));
            }
        }
    }
    lines
}

/// Held-out PSNR against training seconds (log axis), one line per model and budget.
fn curves_svg(models: &[Value]) -> String {
    let lines = lines_of(models, "curve").into_iter().map(|(n, p)| (n, p.into_iter().filter(|(t, _)| *t > 0.0).collect())).collect();
    let x_axis = XAxis { label: "training seconds (log)", ticks: &[1.0, 2.0, 5.0, 10.0, 30.0, 60.0, 120.0, 300.0, 600.0], log: true };
    plot_svg(lines, &x_axis)
}

/// Animated models: held-out PSNR against the held-out view's animation time (0..1), one
/// line per model and budget: where in the animation the field holds and where it breaks.
fn time_svg(models: &[Value]) -> String {
    let x_axis = XAxis { label: "animation time of the held-out view", ticks: &[0.0, 0.2, 0.4, 0.6, 0.8, 1.0], log: false };
    plot_svg(lines_of(models, "psnr_by_time"), &x_axis)
}

struct XAxis<'a> {
    label: &'a str,
    /// First and last are the axis' ends.
    ticks: &'a [f64],
    log: bool,
}

/// A line chart of PSNR (dB) against `x_axis`.
fn plot_svg(lines: Vec<(String, Vec<(f64, f64)>)>, x_axis: &XAxis) -> String {
    let (w, h, l, r, t, b) = (900.0, 560.0, 60.0, 220.0, 20.0, 50.0);
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for (_, pts) in &lines {
        for &(_, p) in pts {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    if lines.is_empty() || lo > hi {
        return String::from("<svg xmlns=\"http://www.w3.org/2000/svg\"/>");
    }
    let (lo, hi) = ((lo - 1.0).floor(), (hi + 1.0).ceil());
    let f = |s: f64| if x_axis.log { s.max(x_axis.ticks[0]).ln() } else { s };
    let (t0, t1) = (f(x_axis.ticks[0]), f(*x_axis.ticks.last().unwrap_or(&1.0)));
    let x = |s: f64| l + (f(s) - t0) / (t1 - t0) * (w - l - r);
    let y = |p: f64| t + (hi - p) / (hi - lo) * (h - t - b);
    let mut svg = format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n");
    for &s in x_axis.ticks {
        svg.push_str(&format!("<line x1=\"{0:.1}\" y1=\"{t}\" x2=\"{0:.1}\" y2=\"{1:.1}\" stroke=\"#ddd\"/><text x=\"{0:.1}\" y=\"{2:.1}\" text-anchor=\"middle\">{s}</text>\n", x(s), h - b, h - b + 16.0));
    }
    let mut p = lo;
    while p <= hi {
        svg.push_str(&format!("<line x1=\"{l}\" y1=\"{0:.1}\" x2=\"{1:.1}\" y2=\"{0:.1}\" stroke=\"#ddd\"/><text x=\"{2:.1}\" y=\"{3:.1}\" text-anchor=\"end\">{p}</text>\n", y(p), w - r, l - 6.0, y(p) + 4.0));
        p += if hi - lo > 20.0 { 5.0 } else { 1.0 };
    }
    svg.push_str(&format!("<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{}</text>\n", (l + w - r) / 2.0, h - 8.0, x_axis.label));
    svg.push_str(&format!("<text x=\"14\" y=\"{:.1}\" transform=\"rotate(-90 14 {:.1})\" text-anchor=\"middle\">held-out PSNR (dB)</text>\n", h / 2.0, h / 2.0));
    for (i, (label, pts)) in lines.iter().enumerate() {
        let hue = (i * 137) % 360;
        let poly: Vec<String> = pts.iter().map(|&(s, p)| format!("{:.1},{:.1}", x(s), y(p))).collect();
        svg.push_str(&format!("<polyline fill=\"none\" stroke=\"hsl({hue},70%,40%)\" stroke-width=\"1.5\" points=\"{}\"/>\n", poly.join(" ")));
        let ly = t + 14.0 * i as f64 + 10.0;
        svg.push_str(&format!("<line x1=\"{0:.1}\" y1=\"{ly:.1}\" x2=\"{1:.1}\" y2=\"{ly:.1}\" stroke=\"hsl({hue},70%,40%)\" stroke-width=\"2\"/><text x=\"{2:.1}\" y=\"{3:.1}\">{label}</text>\n", w - r + 8.0, w - r + 24.0, w - r + 28.0, ly + 4.0));
    }
    svg.push_str("</svg>\n");
    svg
}

/// The models under `dirs` whose name contains one of `only` (all when empty), at most
/// `limit` of them (0: all); an error when none is left.
pub(super) fn select_models(dirs: &[PathBuf], only: &[String], limit: usize) -> Result<Vec<(String, PathBuf)>> {
    let mut models = find_models(dirs)?;
    if !only.is_empty() {
        models.retain(|(n, _)| only.iter().any(|o| n.contains(o.as_str())));
    }
    if limit > 0 {
        models.truncate(limit);
    }
    if models.is_empty() {
        bail!("no .gltf or .glb models under {}", dirs.iter().map(|d| d.display().to_string()).collect::<Vec<_>>().join(", "));
    }
    Ok(models)
}

pub fn run(a: &BenchQualityArgs) -> Result<Value> {
    let models = select_models(&a.dirs, &a.only, a.limit)?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot create", a.out.display()))?;
    let baseline: Option<Value> = match &a.baseline {
        Some(p) => Some(serde_json::from_slice(&std::fs::read(p).with_context(|| format!("{}: cannot read", p.display()))?).with_context(|| format!("{}: not JSON", p.display()))?),
        None => None,
    };
    eprintln!("{} models, budgets {:?} s each", models.len(), a.seconds);
    let mut results = Vec::new();
    for (i, (name, file)) in models.iter().enumerate() {
        eprintln!("[{}/{}] {name}", i + 1, models.len());
        let r = one_model(a, name, file).unwrap_or_else(|e| {
            eprintln!("      skipped: {e:#}");
            json!({ "model": name, "file": pj(file), "error": format!("{e:#}") })
        });
        results.push(r);
        // written after every model, so a long benchmark shows its progress on disk
        let doc = json!({ "command": "bench quality", "size": a.size, "views": a.views, "test_views": a.test_views, "train_flags": a.train_flags, "models": results });
        snerf_files::write_json_atomic(&a.out.join("quality.json"), &doc)?;
    }
    let md = table(&results, baseline.as_ref());
    snerf_files::write_atomic(&a.out.join("quality.md"), md.as_bytes())?;
    snerf_files::write_atomic(&a.out.join("curves.svg"), curves_svg(&results).as_bytes())?;
    if results.iter().any(|m| m["dynamic"].as_bool() == Some(true)) {
        snerf_files::write_atomic(&a.out.join("time.svg"), time_svg(&results).as_bytes())?;
    }
    eprintln!("{md}");
    Ok(json!({ "command": "bench quality", "out": pj(&a.out), "models": results, "table": md }))
}
