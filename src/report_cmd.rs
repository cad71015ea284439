//! `snerf report` and `snerf compare`: error against run time, as pictures (the work is in
//! the snerf-report crate, which also keeps a running job's own report: `snerf_report::live`).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_files::guard::{check_output, Input};
use snerf_report::{pages, Source};

use crate::args::pj;

pub const REPORT_HELP: &str = "Reads the records of any runs given (kind told from the files present): training runs \
(RUN/metrics.json, and RUN/eval/eval.json for SSIM), stylization runs (SRUN/stylize.json, and SRUN/consistency.json for \
the per-frame baseline and the realistic field's floor), bakes (the --json output of `snerf bake`, or the directory of \
`snerf bake --sweep`), and `snerf bench quality` outputs (quality.json). A directory holding none of these is searched \
one level down. Writes into --out one PNG and one SVG per plot, report.md, report.html (self-contained: pictures \
inlined) and report.json (every plotted number, as recorded):\n\
- held-out PSNR against training seconds (log axis; train PSNR dashed, so over-fitting shows), SSIM where measured, \
samples/s against time;\n\
- per stylization round: fit, style distance, short/long-range consistency error against wall time, with the baseline \
and floor as horizontal lines;\n\
- per bake resolution: faithfulness (dB against the field) and test-PSNR drop against file size.";

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Runs and records: run directories, bake summaries, sweep or benchmark directories.
    #[arg(required = true)]
    pub paths: Vec<PathBuf>,
    /// Output directory (report.md, report.html, report.json, PNG and SVG plots).
    #[arg(long)]
    pub out: PathBuf,
    /// Compare the two runs given: under each plot, B − A at equal times.
    #[arg(long)]
    pub compare: bool,
    /// Heading of the report (default: "snerf report").
    #[arg(long)]
    pub title: Option<String>,
}

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// Run A (the reference).
    pub a: PathBuf,
    /// Run B (differences are B − A).
    pub b: PathBuf,
    /// Output directory (as for `snerf report`).
    #[arg(long)]
    pub out: PathBuf,
}

/// Every file the sources were read from, and each run's own files: never an output.
fn guard(out: &Path, sources: &[Source]) -> Result<()> {
    let mut inputs: Vec<PathBuf> = sources.iter().flat_map(|s| s.files.iter().cloned()).collect();
    for s in sources.iter().filter(|s| s.path.is_dir()) {
        inputs.extend(snerf_trainer::run_dir::RunDir::new(&s.path).files());
    }
    let inputs: Vec<Input> = inputs.iter().map(|f| Input::File(f)).collect();
    check_output("--out", out, &inputs)?;
    // the files a report writes, one by one (an input could be named like one)
    let plots = snerf_report::plots::build(sources);
    let names = [pages::JSON, pages::MD, pages::HTML].map(String::from).into_iter().chain(plots.iter().flat_map(|p| [format!("{}.png", p.id), format!("{}.svg", p.id)]));
    for n in names {
        check_output("--out", &out.join(n), &inputs)?;
    }
    Ok(())
}

fn summary(out: &Path, sources: &[Source], w: &snerf_report::Written, seconds: f64) -> Value {
    json!({
        "command": "report",
        "out": pj(out),
        "sources": sources.iter().map(|s| json!({ "kind": s.kind, "label": s.label, "path": pj(&s.path) })).collect::<Vec<_>>(),
        "plots": w.json["plots"].as_array().map(|a| a.iter().map(|p| p["id"].clone()).collect::<Vec<_>>()),
        "files": w.files.iter().map(pj).collect::<Vec<_>>(),
        "compare": w.json["compare"],
        "seconds": seconds,
    })
}

pub fn report_cmd(a: &ReportArgs, quiet: bool) -> Result<Value> {
    let t0 = Instant::now();
    let sources = snerf_report::load_all(&a.paths)?;
    let compare = if a.compare {
        if sources.len() != 2 {
            bail!("--compare takes two runs; {} given ({})", sources.len(), sources.iter().map(|s| s.label.as_str()).collect::<Vec<_>>().join(", "));
        }
        if sources[0].kind != sources[1].kind {
            bail!("--compare takes two runs of one kind; {} is {:?}, {} is {:?}", sources[0].label, sources[0].kind, sources[1].label, sources[1].kind);
        }
        Some((sources[0].label.clone(), sources[1].label.clone()))
    } else {
        None
    };
    guard(&a.out, &sources)?;
    let title = a.title.clone().unwrap_or_else(|| if compare.is_some() { format!("{} against {}", sources[1].label, sources[0].label) } else { "snerf report".into() });
    let w = snerf_report::write_report(&sources, &a.out, &pages::Options { title, compare, svg: true })?;
    let seconds = t0.elapsed().as_secs_f64();
    if !quiet {
        eprintln!("report of {} source(s) in {} ({:.2} s): open {}", sources.len(), a.out.display(), seconds, a.out.join(pages::HTML).display());
    }
    Ok(summary(&a.out, &sources, &w, seconds))
}

pub fn compare_cmd(a: &CompareArgs, quiet: bool) -> Result<Value> {
    let mut v = report_cmd(&ReportArgs { paths: vec![a.a.clone(), a.b.clone()], out: a.out.clone(), compare: true, title: None }, quiet)?;
    v["command"] = json!("compare");
    Ok(v)
}
