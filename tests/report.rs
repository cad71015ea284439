//! `snerf report`, `snerf compare`, `snerf bake --sweep` and the reports `snerf train` and
//! `snerf stylize` keep in their run directories, on real short runs: every plotted number
//! is the recorded one, and the pictures show axes and one line per run.
mod common;
use common::{ok, snerf};

use std::path::Path;

use serde_json::Value;
use snerf_files::ScratchDir;

/// This test's directory: removed when it passes, kept (and named) when it fails.
fn tmp(name: &str) -> ScratchDir {
    ScratchDir::new("snerf-report", name).unwrap()
}

fn read(p: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))).unwrap()
}

/// The report's points of `metric` for `run` on plot `id`.
fn points(report: &Value, id: &str, run: &str, metric: &str) -> Vec<[f64; 2]> {
    let plot = report["plots"].as_array().unwrap().iter().find(|p| p["id"] == id).unwrap_or_else(|| panic!("no plot {id}"));
    let s = plot["series"].as_array().unwrap().iter().find(|s| s["run"] == run && s["metric"] == metric);
    let s = s.unwrap_or_else(|| panic!("plot {id}: no series {run}/{metric}"));
    s["points"].as_array().unwrap().iter().map(|p| [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()]).collect()
}

/// Equal as recorded (both sides went through the same JSON encoder).
fn same(a: &[[f64; 2]], b: &[[f64; 2]], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: {a:?} vs {b:?}");
    assert!(!a.is_empty(), "{what}: nothing plotted");
    for (p, q) in a.iter().zip(b) {
        for k in 0..2 {
            assert!((p[k] - q[k]).abs() <= 1e-12 * p[k].abs().max(1.0), "{what}: {p:?} vs {q:?}");
        }
    }
}

/// (x, y) pairs recomputed from a list of records.
fn recorded(list: &Value, x: &str, y: &str) -> Vec<[f64; 2]> {
    list.as_array().unwrap().iter().filter_map(|r| Some([r[x].as_f64()?, r[y].as_f64()?])).collect()
}

const PALETTE: [[u8; 3]; 10] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [188, 189, 34],
    [23, 190, 207],
    [0, 0, 128],
];

/// Pixels of each palette colour in a PNG.
fn colour_counts(png: &Path) -> ([usize; 10], image::RgbImage) {
    let img = image::open(png).unwrap_or_else(|e| panic!("{}: {e}", png.display())).to_rgb8();
    let mut n = [0usize; 10];
    for p in img.pixels() {
        if let Some(i) = PALETTE.iter().position(|c| *c == p.0) {
            n[i] += 1;
        }
    }
    (n, img)
}

/// Lines present: palette colours with enough pixels to be a line, not a stray pixel.
fn lines(png: &Path) -> Vec<usize> {
    let (n, _) = colour_counts(png);
    (0..10).filter(|&i| n[i] >= 60).collect()
}

/// A long black vertical run (the y axis) and a long black horizontal run (the x axis).
fn has_axes(png: &Path) {
    let img = image::open(png).unwrap().to_rgb8();
    let (w, h) = img.dimensions();
    let dark = |x: u32, y: u32| img.get_pixel(x, y).0.iter().all(|&c| c < 40);
    let longest = |len: u32, at: &dyn Fn(u32) -> bool| {
        let (mut best, mut cur) = (0, 0);
        for i in 0..len {
            cur = if at(i) { cur + 1 } else { 0 };
            best = best.max(cur);
        }
        best
    };
    let col = (0..w).map(|x| longest(h, &|y| dark(x, y))).max().unwrap();
    let row = (0..h).map(|y| longest(w, &|x| dark(x, y))).max().unwrap();
    assert!(col > h / 2, "{}: no y axis (longest dark column {col} of {h})", png.display());
    assert!(row > w / 2, "{}: no x axis (longest dark row {row} of {w})", png.display());
}

fn style_png(p: &Path) {
    let img = image::RgbImage::from_fn(64, 64, |x, y| image::Rgb([(x * 4) as u8, 40, (y * 4) as u8]));
    img.save(p).unwrap();
}

#[test]
fn report_of_real_train_stylize_and_bake_runs() {
    let d = tmp("all");
    let data = d.join("data");
    ok(snerf()
        .args(["--json", "scene", "object", "--out"])
        .arg(&data)
        .args(["--views", "12", "--test-views", "3", "--size", "32x32", "--supersample", "1"])
        .output()
        .unwrap());
    let (a, b) = (d.join("run-a"), d.join("run-b"));
    // Three seconds each, not a step count: the curve is measured at 2 s and at the end, so
    // both runs cover a common span of time however fast the machine is (two runs of a few
    // steps each could end before their first measurement and share no time to compare at).
    let ta = ok(snerf().args(["--json", "train"]).arg(&data).arg("--out").arg(&a).args(["--minutes", "0.05"]).output().unwrap());
    ok(snerf().args(["--json", "train"]).arg(&data).arg("--out").arg(&b).args(["--minutes", "0.05", "--lr-planes", "0.02"]).output().unwrap());
    ok(snerf().args(["--json", "eval"]).arg(&a).arg(&data).output().unwrap());
    // the run's own report, written by `snerf train` as it went and at the end
    assert!(ta["report"]["writes"].as_u64().unwrap() >= 1, "{}", ta["report"]);
    let own = read(&a.join("report/report.json"));
    let ma = read(&a.join("metrics.json"));
    same(&points(&own, "psnr", "run-a", "test_psnr"), &recorded(&ma["curve"], "train_seconds", "test_psnr"), "run-a own report");
    assert_eq!(lines(&a.join("report/psnr.png")), vec![0], "one run, one colour");

    let style = d.join("style.png");
    style_png(&style);
    let srun = d.join("styl");
    ok(snerf()
        .args(["--json", "stylize"])
        .arg(&a)
        .arg("--out")
        .arg(&srun)
        .arg("--style")
        .arg(&style)
        .args(["--stylizer", "color", "--rounds", "2", "--steps-per-round", "8", "--consistency-frames", "9"])
        .output()
        .unwrap());
    assert!(srun.join("report/stylize_fit.png").exists(), "snerf stylize draws its rounds");
    ok(snerf().args(["--json", "consistency"]).arg(&srun).arg(&data).args(["--frames", "9"]).output().unwrap());
    let sweep = d.join("sweep");
    let sw = ok(snerf()
        .args(["--json", "bake"])
        .arg(&a)
        .arg("--out")
        .arg(&sweep)
        .args(["--sweep", "24,32", "--eval-views", "2", "--visibility-views", "4"])
        .output()
        .unwrap());
    assert_eq!(sw["bakes"].as_array().unwrap().len(), 2);
    for r in [24, 32] {
        assert!(sweep.join(format!("res-{r}/asset.snerf")).is_file());
        assert_eq!(read(&sweep.join(format!("res-{r}/bake.json")))["report"]["res"], r);
    }

    let out = d.join("report");
    let v = ok(snerf().args(["--json", "report"]).arg(&a).arg(&b).arg(&srun).arg(&sweep).arg("--out").arg(&out).output().unwrap());
    assert_eq!(v["command"], "report");
    assert_eq!(v["sources"].as_array().unwrap().len(), 4);
    let rep = read(&out.join("report.json"));

    // every plotted number is the recorded one
    let mb = read(&b.join("metrics.json"));
    for (run, m) in [("run-a", &ma), ("run-b", &mb)] {
        same(&points(&rep, "psnr", run, "test_psnr"), &recorded(&m["curve"], "train_seconds", "test_psnr"), run);
        same(&points(&rep, "psnr", run, "train_psnr"), &recorded(&m["curve"], "train_seconds", "train_psnr"), run);
        same(&points(&rep, "throughput", run, "samples_per_second"), &recorded(&m["curve"], "train_seconds", "samples_per_second"), run);
    }
    let ev = read(&a.join("eval/eval.json"));
    same(&points(&rep, "ssim", "run-a", "ssim"), &[[ma["train_seconds"].as_f64().unwrap(), ev["report"]["mean_ssim"].as_f64().unwrap()]], "ssim");
    let st = read(&srun.join("stylize.json"));
    assert_eq!(st["records"].as_array().unwrap().len(), 2);
    same(&points(&rep, "stylize_fit", "styl", "fit_psnr"), &recorded(&st["records"], "wall_seconds", "fit_psnr"), "fit");
    same(&points(&rep, "stylize_consistency", "styl", "short_range"), &recorded(&st["records"], "wall_seconds", "short_range"), "short");
    same(&points(&rep, "stylize_consistency", "styl", "long_range"), &recorded(&st["records"], "wall_seconds", "long_range"), "long");
    let cons = read(&srun.join("consistency.json"));
    assert!(cons["temporal"].is_null(), "a static scene has no temporal flicker to score");
    let hl = &rep["plots"].as_array().unwrap().iter().find(|p| p["id"] == "stylize_consistency").unwrap()["hlines"];
    for m in cons["methods"].as_array().unwrap().iter().filter(|m| m["method"].as_str().unwrap().starts_with("Per-frame") || m["method"].as_str().unwrap().starts_with("Realistic")) {
        for f in ["short_range", "long_range"] {
            let y = m[f].as_f64().unwrap();
            assert!(hl.as_array().unwrap().iter().any(|h| h["y"].as_f64() == Some(y)), "{f} of {} drawn as a line: {hl}", m["method"]);
        }
    }
    let bakes: Vec<Value> = [24, 32].iter().map(|r| read(&sweep.join(format!("res-{r}/bake.json")))).collect();
    let size_vs = |y: &str| bakes.iter().map(|b| [b["asset"]["bytes"]["total"].as_f64().unwrap(), b["faithfulness"][y].as_f64().unwrap()]).collect::<Vec<_>>();
    same(&points(&rep, "bake_faithfulness", "sweep", "mean_baked_vs_field"), &size_vs("mean_baked_vs_field"), "faithfulness");
    same(&points(&rep, "bake_drop", "sweep", "drop_db"), &size_vs("drop_db"), "drop");

    // the pictures: axes, and one colour per run (run-a 0, run-b 1, styl 2, sweep 3)
    for id in ["psnr", "throughput", "ssim", "stylize_fit", "stylize_consistency", "bake_faithfulness", "bake_drop"] {
        has_axes(&out.join(format!("{id}.png")));
        let svg = std::fs::read_to_string(out.join(format!("{id}.svg"))).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("<text"), "{id}.svg");
    }
    assert_eq!(lines(&out.join("psnr.png")), vec![0, 1], "two training runs, two lines");
    assert_eq!(lines(&out.join("throughput.png")), vec![0, 1]);
    assert_eq!(lines(&out.join("stylize_consistency.png")), vec![2]);
    assert_eq!(lines(&out.join("bake_faithfulness.png")), vec![3]);
    // the baseline and the floor are drawn
    let img = image::open(out.join("stylize_consistency.png")).unwrap().to_rgb8();
    for c in [[90u8, 90, 90], [170, 170, 170]] {
        assert!(img.pixels().filter(|p| p.0 == c).count() > 100, "reference line {c:?} missing");
    }
    // the page is self-contained: every picture inlined, nothing fetched
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    let nplots = rep["plots"].as_array().unwrap().len();
    assert_eq!(html.matches("src=\"data:image/png;base64,").count(), nplots);
    assert_eq!(html.matches("src=\"").count(), nplots);
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("](psnr.png)") && md.contains("| run-a |"), "{md}");

    // two runs compared at equal times
    let cmp_dir = d.join("cmp");
    let c = ok(snerf().args(["--json", "compare"]).arg(&a).arg(&b).arg("--out").arg(&cmp_dir).output().unwrap());
    assert_eq!(c["command"], "compare");
    let rows: Vec<&Value> = c["compare"].as_array().unwrap().iter().filter(|x| x["plot"] == "psnr").flat_map(|x| x["rows"].as_array().unwrap()).filter(|r| r["metric"] == "test_psnr").collect();
    assert!(!rows.is_empty(), "{c}");
    let pa = recorded(&ma["curve"], "train_seconds", "test_psnr");
    let pb = recorded(&mb["curve"], "train_seconds", "test_psnr");
    let end = pa.last().unwrap()[0].min(pb.last().unwrap()[0]);
    for r in &rows {
        let (x, va, vb) = (r["x"].as_f64().unwrap(), r["a"].as_f64().unwrap(), r["b"].as_f64().unwrap());
        assert!(x <= end, "no extrapolation: {r}");
        assert!((r["b_minus_a"].as_f64().unwrap() - (vb - va)).abs() < 1e-9);
        if let Some(p) = pa.iter().find(|p| p[0] == x) {
            assert_eq!(p[1], va, "at A's own time, A's recorded value");
        }
        if let Some(p) = pb.iter().find(|p| p[0] == x) {
            assert_eq!(p[1], vb, "at B's own time, B's recorded value");
        }
    }
    assert_eq!(lines(&cmp_dir.join("psnr.png")), vec![0, 1]);

    // outputs never overwrite inputs; unknown inputs are named
    let bad = snerf().arg("report").arg(&a).arg("--out").arg(a.join("metrics.json")).output().unwrap();
    assert!(!bad.status.success());
    let e = snerf().arg("report").arg(d.join("nothing")).arg("--out").arg(d.join("r2")).output().unwrap();
    assert!(!e.status.success() && String::from_utf8_lossy(&e.stderr).contains("nothing"));
}
