//! Which plots a set of sources gives, with the exact numbers of their records.
//!
//! Every point is a pair of numbers copied from a record (no unit conversion, no
//! smoothing): the axes format them for reading, `report.json` keeps them as they were.

use std::collections::BTreeMap;

use serde_json::Value;

use crate::model::{HLine, Plot, Series, Table};
use crate::sources::{Source, SourceKind};

fn num(v: &Value) -> Option<f64> {
    v.as_f64().filter(|x| x.is_finite())
}

fn fmt(v: Option<f64>, digits: usize) -> String {
    v.map(|x| format!("{x:.digits$}")).unwrap_or_else(|| "—".into())
}

/// Colours by line owner: a run keeps its colour on every plot.
#[derive(Default)]
struct Colors(BTreeMap<String, usize>, usize);

impl Colors {
    fn of(&mut self, run: &str) -> usize {
        if let Some(&c) = self.0.get(run) {
            return c;
        }
        let c = self.1;
        self.1 += 1;
        self.0.insert(run.to_string(), c);
        c
    }
}

fn series(run: &str, metric: &str, label: String, color: usize, dashed: bool, markers: bool, points: Vec<[f64; 2]>) -> Series {
    Series { run: run.into(), metric: metric.into(), label, color, dashed, markers, points }
}

/// (x, y) pairs of a list of objects, skipping entries where either is missing.
fn pairs(list: &Value, x: &str, y: &str) -> Vec<[f64; 2]> {
    list.as_array().into_iter().flatten().filter_map(|p| Some([num(&p[x])?, num(&p[y])?])).collect()
}

/// One training curve, as the plots need it (a train run, or one run of a quality benchmark).
struct Curve {
    run: String,
    test: Vec<[f64; 2]>,
    train: Vec<[f64; 2]>,
    throughput: Vec<[f64; 2]>,
    /// (training seconds, SSIM) where an evaluation measured it.
    ssim: Option<[f64; 2]>,
    steps: Option<f64>,
}

fn curves(sources: &[Source]) -> Vec<Curve> {
    let mut out = Vec::new();
    // two benchmarks (a baseline and a new build) hold the same model names
    let benchmarks = sources.iter().filter(|s| s.kind == SourceKind::Quality).count();
    for s in sources {
        match s.kind {
            SourceKind::Train => {
                let m = &s.data["metrics"];
                let ssim = num(&s.data["eval"]["report"]["mean_ssim"]).zip(num(&m["train_seconds"])).map(|(v, t)| [t, v]);
                out.push(Curve {
                    run: s.label.clone(),
                    test: pairs(&m["curve"], "train_seconds", "test_psnr"),
                    train: pairs(&m["curve"], "train_seconds", "train_psnr"),
                    throughput: pairs(&m["curve"], "train_seconds", "samples_per_second"),
                    ssim,
                    steps: num(&m["step"]),
                });
            }
            SourceKind::Quality => {
                for model in s.data["models"].as_array().into_iter().flatten() {
                    for r in model["runs"].as_array().into_iter().flatten() {
                        let mut name = format!("{} ({} s)", model["model"].as_str().unwrap_or("?"), fmt(num(&r["seconds"]), 0));
                        if benchmarks > 1 {
                            name = format!("{}: {name}", s.label);
                        }
                        let test: Vec<[f64; 2]> =
                            r["curve"].as_array().into_iter().flatten().filter_map(|p| Some([num(&p[0])?, num(&p[1])?])).collect();
                        let ssim = num(&r["eval_ssim"]).zip(test.last().map(|p| p[0])).map(|(v, t)| [t, v]);
                        out.push(Curve { run: name, test, train: Vec::new(), throughput: Vec::new(), ssim, steps: None });
                    }
                }
            }
            _ => {}
        }
    }
    out
}

/// All plots the sources give, in reading order; empty plots are left out.
pub fn build(sources: &[Source]) -> Vec<Plot> {
    let mut colors = Colors::default();
    let mut plots = Vec::new();
    plots.extend(training_plots(sources, &mut colors));
    plots.extend(stylize_plots(sources, &mut colors));
    plots.extend(bake_plots(sources, &mut colors));
    plots.retain(|p| !p.is_empty());
    plots
}

fn training_plots(sources: &[Source], colors: &mut Colors) -> Vec<Plot> {
    let curves = curves(sources);
    let mut psnr = Plot::new("psnr", "Held-out PSNR (solid) and train PSNR (dashed) against training time", "training seconds (log)", "PSNR (dB)", true);
    psnr.table.header = ["run", "steps", "training s", "held-out PSNR", "best held-out", "train PSNR", "train − held-out"].map(String::from).to_vec();
    let mut tput = Plot::new("throughput", "Training throughput", "training seconds (log)", "samples/s", true);
    tput.table.header = ["run", "training s", "samples/s (last)", "samples/s (mean)"].map(String::from).to_vec();
    let mut ssim = Plot::new("ssim", "Held-out SSIM at the end of training", "training seconds (log)", "SSIM", true);
    ssim.table.header = ["run", "training s", "SSIM"].map(String::from).to_vec();
    for c in &curves {
        let col = colors.of(&c.run);
        let last_test = c.test.last().copied();
        let last_train = c.train.last().copied();
        let best = c.test.iter().map(|p| p[1]).fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))));
        let short = c.test.len() <= 1;
        psnr.series.push(series(&c.run, "test_psnr", c.run.clone(), col, false, short, c.test.clone()));
        if !c.train.is_empty() {
            psnr.series.push(series(&c.run, "train_psnr", format!("{} train", c.run), col, true, short, c.train.clone()));
        }
        psnr.table.rows.push(vec![
            c.run.clone(),
            fmt(c.steps, 0),
            fmt(last_test.or(last_train).map(|p| p[0]), 1),
            fmt(last_test.map(|p| p[1]), 2),
            fmt(best, 2),
            fmt(last_train.map(|p| p[1]), 2),
            fmt(last_train.zip(last_test).map(|(a, b)| a[1] - b[1]), 2),
        ]);
        if !c.throughput.is_empty() {
            tput.series.push(series(&c.run, "samples_per_second", c.run.clone(), col, false, c.throughput.len() <= 1, c.throughput.clone()));
            let mean = c.throughput.iter().map(|p| p[1]).sum::<f64>() / c.throughput.len() as f64;
            let last = c.throughput.last().copied();
            tput.table.rows.push(vec![c.run.clone(), fmt(last.map(|p| p[0]), 1), fmt(last.map(|p| p[1]), 0), format!("{mean:.0}")]);
        }
        if let Some(p) = c.ssim {
            ssim.series.push(series(&c.run, "ssim", c.run.clone(), col, false, true, vec![p]));
            ssim.table.rows.push(vec![c.run.clone(), format!("{:.1}", p[0]), format!("{:.4}", p[1])]);
        }
    }
    vec![psnr, ssim, tput]
}

/// The per-frame baseline and the realistic field's floor, from `consistency.json`.
/// The style distances a record may carry, the one the stylization bars use first: the
/// weight-free distance (colour and texture statistics, which no stylizer aims at), then the
/// Gram distance (which only `gatys` optimizes), then the Magenta embedding's (older records).
const STYLE_KEYS: [&str; 3] = ["style_swd", "style_gram", "style_distance"];

/// A record's value of `key`; for `style_swd`, its total (colour + texture), and for
/// `style_swd.color` or `style_swd.texture` that part.
fn value_of(v: &Value, key: &str) -> Option<f64> {
    if let Some(part) = key.strip_prefix("style_swd.") {
        num(&v["style_swd"][part])
    } else if key == "style_swd" {
        num(&v[key]["total"])
    } else {
        num(&v[key])
    }
}

/// The first of `STYLE_KEYS` that any of `records` carries.
fn style_key(records: &Value) -> &'static str {
    STYLE_KEYS.into_iter().find(|k| records.as_array().into_iter().flatten().any(|r| value_of(r, k).is_some())).unwrap_or("style_distance")
}

fn references(s: &Source, field: &str, what: &str) -> Vec<HLine> {
    let mut out = Vec::new();
    for m in s.data["consistency"]["methods"].as_array().into_iter().flatten() {
        let name = m["method"].as_str().unwrap_or("");
        let role = if name.starts_with("Per-frame") {
            0
        } else if name.starts_with("Realistic") {
            1
        } else {
            continue;
        };
        if let Some(y) = value_of(m, field) {
            let who = if role == 0 { "per-frame stylization" } else { "realistic field" };
            out.push(HLine { run: s.label.clone(), label: format!("{}: {who}{what}", s.label), y, role });
        }
    }
    out
}

fn stylize_plots(sources: &[Source], colors: &mut Colors) -> Vec<Plot> {
    let mut fit = Plot::new("stylize_fit", "Fit to the stylized views per round", "wall seconds", "fit PSNR (dB)", false);
    let mut style = Plot::new("stylize_style", "Style distance to the painting per round (lower: nearer)", "wall seconds", "style distance", false);
    let mut cons = Plot::new("stylize_consistency", "Consistency error per round (short range solid, long range dashed)", "wall seconds", "warped-frame MSE", false);
    // The weight-free distance's two parts, apart: a round can paint the strokes nearer the
    // painting while losing some of its palette, and the total alone hides that trade.
    let mut terms = Plot::new(
        "stylize_style_terms",
        "Style distance in two parts per round: palette coverage solid, texture dashed (lower: nearer)",
        "wall seconds",
        "× the painting's own variation",
        false,
    );
    terms.table.header = ["run", "round", "wall s", "palette coverage", "texture"].map(String::from).to_vec();
    fit.table.header = ["run", "round", "wall s", "fit PSNR"].map(String::from).to_vec();
    style.table.header = ["run", "round", "wall s", "style distance"].map(String::from).to_vec();
    cons.table.header = ["run", "round", "wall s", "short range", "long range"].map(String::from).to_vec();
    for s in sources.iter().filter(|s| s.kind == SourceKind::Stylize) {
        let col = colors.of(&s.label);
        let recs = &s.data["state"]["records"];
        let run = &s.label;
        // The distance the convergence bar is judged on, where the records have it.
        let key = style_key(recs);
        let points = |key: &str| recs.as_array().into_iter().flatten().filter_map(|r| Some([num(&r["wall_seconds"])?, value_of(r, key)?])).collect::<Vec<_>>();
        let style_points = points(key);
        fit.series.push(series(run, "fit_psnr", run.clone(), col, false, true, pairs(recs, "wall_seconds", "fit_psnr")));
        style.series.push(series(run, key, run.clone(), col, false, true, style_points));
        let (colour, texture) = (points("style_swd.color"), points("style_swd.texture"));
        if !colour.is_empty() || !texture.is_empty() {
            terms.series.push(series(run, "style_swd.color", format!("{run} palette"), col, false, true, colour));
            terms.series.push(series(run, "style_swd.texture", format!("{run} texture"), col, true, true, texture));
        }
        cons.series.push(series(run, "short_range", run.clone(), col, false, true, pairs(recs, "wall_seconds", "short_range")));
        cons.series.push(series(run, "long_range", format!("{run} long range"), col, true, true, pairs(recs, "wall_seconds", "long_range")));
        for r in recs.as_array().into_iter().flatten() {
            let round = fmt(num(&r["round"]), 0);
            let head = |round: String| vec![run.clone(), round, fmt(num(&r["wall_seconds"]), 1)];
            fit.table.rows.push([head(round.clone()), vec![fmt(num(&r["fit_psnr"]), 2)]].concat());
            // a round whose field was discarded (`--keep-rounds better`): the curves follow the
            // kept field, the tables also say what the discarded one measured
            let discarded = Some(&r["discarded"]).filter(|d| d.is_object()).map(|d| (format!("{round} (discarded)"), d));
            for (round, v) in std::iter::once((round, r)).chain(discarded) {
                if value_of(v, key).is_some() {
                    style.table.rows.push([head(round.clone()), vec![fmt(value_of(v, key), 4)]].concat());
                }
                if v["style_swd"].is_object() {
                    terms.table.rows.push([head(round.clone()), vec![fmt(value_of(v, "style_swd.color"), 4), fmt(value_of(v, "style_swd.texture"), 4)]].concat());
                }
                if num(&v["short_range"]).is_some() || num(&v["long_range"]).is_some() {
                    cons.table.rows.push([head(round), vec![fmt(num(&v["short_range"]), 5), fmt(num(&v["long_range"]), 5)]].concat());
                }
            }
        }
        style.hlines.extend(references(s, key, ""));
        // per-frame stylization's parts only: the unstylized field's palette term is several
        // times larger and would flatten the rounds' curves into the axis
        for (part, what) in [("style_swd.color", ", palette"), ("style_swd.texture", ", texture")] {
            for h in references(s, part, what).into_iter().filter(|h| h.role == 0) {
                let y = fmt(Some(h.y), 4);
                let (c, t) = if part.ends_with("color") { (y, String::new()) } else { (String::new(), y) };
                terms.table.rows.push(vec![h.label.clone(), "—".into(), "—".into(), c, t]);
                terms.hlines.push(h);
            }
        }
        cons.hlines.extend(references(s, "short_range", ", short range"));
        cons.hlines.extend(references(s, "long_range", ", long range"));
    }
    for p in [&mut style, &mut cons] {
        for h in &p.hlines {
            p.table.rows.push(vec![h.label.clone(), "—".into(), "—".into(), fmt(Some(h.y), 5)]);
        }
        if p.id == "stylize_consistency" {
            for r in p.table.rows.iter_mut().filter(|r| r.len() == 4) {
                r.push(String::new());
            }
        }
    }
    vec![fit, style, terms, cons]
}

fn bake_plots(sources: &[Source], colors: &mut Colors) -> Vec<Plot> {
    let mut faith = Plot::new("bake_faithfulness", "Baked asset against the field", "file size (bytes)", "baked vs field (dB)", false);
    let mut drop = Plot::new("bake_drop", "Held-out PSNR that baking costs", "file size (bytes)", "test PSNR drop (dB)", false);
    let header = ["run", "resolution", "file MB", "baked vs field (dB)", "test PSNR drop (dB)", "bake s"].map(String::from).to_vec();
    faith.table.header = header.clone();
    drop.table.header = header;
    for s in sources.iter().filter(|s| s.kind == SourceKind::Bake) {
        let col = colors.of(&s.label);
        let mut bakes: Vec<&Value> = s.data["bakes"].as_array().into_iter().flatten().collect();
        bakes.sort_by(|a, b| num(&a["asset"]["bytes"]["total"]).partial_cmp(&num(&b["asset"]["bytes"]["total"])).unwrap_or(std::cmp::Ordering::Equal));
        let point = |b: &Value, y: &str| Some([num(&b["asset"]["bytes"]["total"])?, num(&b["faithfulness"][y])?]);
        let f: Vec<[f64; 2]> = bakes.iter().filter_map(|b| point(b, "mean_baked_vs_field")).collect();
        let d: Vec<[f64; 2]> = bakes.iter().filter_map(|b| point(b, "drop_db")).collect();
        faith.series.push(series(&s.label, "mean_baked_vs_field", s.label.clone(), col, false, true, f));
        drop.series.push(series(&s.label, "drop_db", s.label.clone(), col, false, true, d));
        for b in bakes {
            let row = vec![
                s.label.clone(),
                fmt(num(&b["report"]["res"]).or(num(&b["asset"]["res"])), 0),
                fmt(num(&b["asset"]["bytes"]["total"]).map(|x| x / 1e6), 2),
                fmt(num(&b["faithfulness"]["mean_baked_vs_field"]), 2),
                fmt(num(&b["faithfulness"]["drop_db"]), 2),
                fmt(num(&b["bake_seconds"]), 1),
            ];
            faith.table.rows.push(row.clone());
            drop.table.rows.push(row);
        }
    }
    // one table serves both plots
    drop.table = Table::default();
    vec![faith, drop, time_plot(sources, colors)]
}

/// 4D bakes: bytes per second of animation against fidelity at the held-out views' own times
/// (between the time samples), one point per bake (e.g. per `--time-budget`).
fn time_plot(sources: &[Source], colors: &mut Colors) -> Plot {
    let mut p = Plot::new("bake_4d", "4D bakes: size per second of animation against fidelity at held-out times", "MB per second of animation (log)", "baked vs field at held-out times (dB)", true);
    p.table.header = ["run", "time samples", "× static frame", "MB/s", "baked vs field (dB)", "blended entries"].map(String::from).to_vec();
    for s in sources.iter().filter(|s| s.kind == SourceKind::Bake) {
        let mut bakes: Vec<&Value> = s.data["bakes"].as_array().into_iter().flatten().filter(|b| num(&b["asset"]["bytes_per_second"]["total"]).is_some()).collect();
        if bakes.is_empty() {
            continue;
        }
        bakes.sort_by(|a, b| num(&a["asset"]["bytes_per_second"]["total"]).partial_cmp(&num(&b["asset"]["bytes_per_second"]["total"])).unwrap_or(std::cmp::Ordering::Equal));
        let pts: Vec<[f64; 2]> = bakes.iter().filter_map(|b| Some([num(&b["asset"]["bytes_per_second"]["total"])? / 1e6, num(&b["faithfulness"]["mean_baked_vs_field"])?])).collect();
        p.series.push(series(&s.label, "mean_baked_vs_field", s.label.clone(), colors.of(&s.label), false, true, pts));
        for b in bakes {
            p.table.rows.push(vec![
                s.label.clone(),
                fmt(num(&b["asset"]["frames"]), 0),
                fmt(num(&b["asset"]["size_vs_static_frame"]), 2),
                fmt(num(&b["asset"]["bytes_per_second"]["total"]).map(|x| x / 1e6), 2),
                fmt(num(&b["faithfulness"]["mean_baked_vs_field"]), 2),
                fmt(num(&b["report"]["blended_entries"]), 0),
            ]);
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;
    use std::path::Path;

    fn record(round: u32, wall: f64, swd: Option<f64>, gram: f64) -> Value {
        let mut r = json!({ "round": round, "wall_seconds": wall, "fit_psnr": 30.0, "short_range": 0.003, "long_range": 0.008, "style_gram": gram, "style_distance": 8.0 });
        if let Some(t) = swd {
            r["style_swd"] = json!({ "total": t, "color": t / 4.0, "texture": 3.0 * t / 4.0 });
        }
        r
    }

    fn method(name: &str, swd: f64, gram: f64) -> Value {
        json!({ "method": name, "short_range": 0.01, "long_range": 0.02, "style_swd": { "total": swd, "color": swd / 2.0, "texture": swd / 2.0 }, "style_gram": gram, "style_distance": 8.0 })
    }

    /// The style plot shows the weight-free distance the convergence bar is judged on (Gram
    /// and the embedding only for records without it), reference lines included.
    #[test]
    fn style_plot_shows_the_weight_free_distance_where_recorded() {
        let state = json!({ "records": [record(1, 10.0, Some(0.30), 0.50), record(2, 20.0, Some(0.29), 0.48)] });
        let cons = json!({ "methods": [method("Realistic field (no stylization)", 0.6, 0.9), method("Per-frame image stylization", 0.35, 0.7), method("SNeRF, 2 rounds", 0.29, 0.48)] });
        let old = json!({ "records": [record(1, 12.0, None, 0.44)] });
        let sources = [Source::stylize("new", Path::new("new"), state, Some(cons)), Source::stylize("old", Path::new("old"), old, None)];
        let plots = build(&sources);
        let style = plots.iter().find(|p| p.id == "stylize_style").unwrap();
        let new = style.series.iter().find(|s| s.run == "new").unwrap();
        assert_eq!(new.metric, "style_swd");
        assert_eq!(new.points, vec![[10.0, 0.30], [20.0, 0.29]]);
        let old = style.series.iter().find(|s| s.run == "old").unwrap();
        assert_eq!((old.metric.as_str(), old.points.clone()), ("style_gram", vec![[12.0, 0.44]]));
        let refs: Vec<(usize, f64)> = style.hlines.iter().map(|h| (h.role, h.y)).collect();
        assert_eq!(refs, vec![(1, 0.6), (0, 0.35)]);
        assert!(style.table.rows.iter().any(|r| r[0] == "new" && r[3] == "0.2900"), "{:?}", style.table.rows);
        // its two parts, apart, for the runs that record them (the old run has none)
        let terms = plots.iter().find(|p| p.id == "stylize_style_terms").unwrap();
        let part = |metric: &str| terms.series.iter().find(|s| s.run == "new" && s.metric == metric).unwrap().points.clone();
        assert_eq!(part("style_swd.color"), vec![[10.0, 0.30 / 4.0], [20.0, 0.29 / 4.0]]);
        assert_eq!(part("style_swd.texture"), vec![[10.0, 3.0 * 0.30 / 4.0], [20.0, 3.0 * 0.29 / 4.0]]);
        assert!(terms.series.iter().all(|s| s.run != "old"));
        assert_eq!(terms.table.rows[1], vec!["new", "2", "20.0", "0.0725", "0.2175"]);
        // per-frame stylization's parts as reference lines; the realistic field's are left out
        let refs: Vec<(usize, f64)> = terms.hlines.iter().map(|h| (h.role, h.y)).collect();
        assert_eq!(refs, vec![(0, 0.175), (0, 0.175)]);
    }

    /// A round whose field was discarded: the curves follow the kept field, the tables also
    /// give what the discarded one measured.
    #[test]
    fn a_discarded_round_is_plotted_as_kept_and_tabled_as_measured() {
        let mut second = record(2, 20.0, Some(0.30), 0.50);
        second["discarded"] = json!({ "short_range": 0.004, "long_range": 0.007, "style_swd": { "total": 0.31, "color": 0.1, "texture": 0.21 } });
        let state = json!({ "records": [record(1, 10.0, Some(0.30), 0.50), second] });
        let plots = build(&[Source::stylize("s", Path::new("s"), state, None)]);
        let plot = |id: &str| plots.iter().find(|p| p.id == id).unwrap();
        assert_eq!(plot("stylize_style").series[0].points, vec![[10.0, 0.30], [20.0, 0.30]]);
        assert_eq!(plot("stylize_consistency").series[0].points, vec![[10.0, 0.003], [20.0, 0.003]]);
        let rows = |id: &str| plot(id).table.rows.clone();
        assert_eq!(rows("stylize_style")[2], vec!["s", "2 (discarded)", "20.0", "0.3100"]);
        assert_eq!(rows("stylize_style_terms")[2], vec!["s", "2 (discarded)", "20.0", "0.1000", "0.2100"]);
        assert_eq!(rows("stylize_consistency")[2], vec!["s", "2 (discarded)", "20.0", "0.00400", "0.00700"]);
        assert_eq!(rows("stylize_fit").len(), 2, "one fit per round");
    }

    /// 4D bakes at several budgets: one curve of MB per second of animation against the
    /// fidelity at held-out times; static bakes are not on it.
    #[test]
    fn four_d_bakes_plot_rate_against_held_out_time_fidelity() {
        let bake = |total: Option<f64>, x: f64, db: f64| {
            json!({ "report": { "res": 192, "blended_entries": 7 }, "asset": { "frames": 24, "size_vs_static_frame": x, "bytes": { "total": 1e6 * x }, "bytes_per_second": total.map(|t| json!({ "total": t })) }, "faithfulness": { "mean_baked_vs_field": db, "drop_db": 0.5 } })
        };
        let four_d = Source::bakes("skin", Path::new("skin"), vec![bake(Some(3.0e6), 2.5, 31.0), bake(Some(1.8e6), 1.5, 28.0)]);
        let still = Source::bakes("still", Path::new("still"), vec![bake(None, 1.0, 35.0)]);
        let plots = build(&[four_d, still]);
        let p = plots.iter().find(|p| p.id == "bake_4d").unwrap();
        assert_eq!(p.series.len(), 1);
        assert_eq!(p.series[0].points, vec![[1.8, 28.0], [3.0, 31.0]]);
        assert_eq!(p.table.rows[0], vec!["skin", "24", "1.50", "1.80", "28.00", "7"]);
        // static bakes alone: no such plot
        let plots = build(&[Source::bakes("still", Path::new("still"), vec![bake(None, 1.0, 35.0)])]);
        assert!(plots.iter().all(|p| p.id != "bake_4d"));
    }
}
