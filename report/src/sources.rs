//! The records a report is drawn from, and how their kind is told from the files present.
//!
//! - a training run: a directory with `metrics.json` (and `eval/eval.json` when `snerf eval`
//!   scored it: SSIM), or the `--json` output of `snerf train`;
//! - a stylization run: a directory with `stylize.json` (and `consistency.json` when
//!   `snerf consistency` measured the per-frame baseline and the realistic floor);
//! - a bake: the `--json` output of `snerf bake`, or a directory with `sweep.json` from
//!   `snerf bake --sweep`;
//! - a quality benchmark: a directory with `quality.json`, or that file.
//!
//! A directory holding none of these is searched one level down, so `snerf report runs/`
//! takes every run under `runs/`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::Serialize;
use serde_json::{json, Value};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SourceKind {
    Train,
    Stylize,
    Bake,
    Quality,
}

/// One run (or benchmark) as read from disk, with the record files it came from.
#[derive(Clone, Debug)]
pub struct Source {
    pub kind: SourceKind,
    /// The name in legends and tables (unique within a report).
    pub label: String,
    pub path: PathBuf,
    /// The files read.
    pub files: Vec<PathBuf>,
    /// The records, as read: train `{metrics, eval}`, stylize `{state, consistency}`,
    /// bake `{bakes: [bake summary, ...]}`, quality: the `quality.json` document.
    pub data: Value,
}

pub const METRICS: &str = "metrics.json";
/// `snerf eval`'s record of a run, in its default place.
pub const EVAL: &str = "eval/eval.json";
pub const STYLIZE: &str = "stylize.json";
pub const CONSISTENCY: &str = "consistency.json";
pub const SWEEP: &str = "sweep.json";
pub const QUALITY: &str = "quality.json";

fn read_json(p: &Path) -> Result<Value> {
    let bytes = std::fs::read(p).with_context(|| format!("{}: cannot read", p.display()))?;
    serde_json::from_slice(&bytes).with_context(|| format!("{}: not JSON", p.display()))
}

fn name_of(p: &Path) -> String {
    let p = if p.file_name().is_none() { std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf()) } else { p.to_path_buf() };
    p.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| p.display().to_string())
}

impl Source {
    /// A training run from its metrics record (as `metrics.json` holds it) and, when
    /// measured, its `eval.json`. Used by `snerf train` itself while it runs.
    pub fn train(label: &str, path: &Path, metrics: Value, eval: Option<Value>) -> Source {
        Source { kind: SourceKind::Train, label: label.into(), path: path.into(), files: Vec::new(), data: json!({ "metrics": metrics, "eval": eval }) }
    }

    /// A stylization run from its state record (as `stylize.json` holds it) and, when
    /// measured, its `consistency.json`.
    pub fn stylize(label: &str, path: &Path, state: Value, consistency: Option<Value>) -> Source {
        Source { kind: SourceKind::Stylize, label: label.into(), path: path.into(), files: Vec::new(), data: json!({ "state": state, "consistency": consistency }) }
    }

    /// One or more bakes of a run (each the JSON summary `snerf bake --json` prints).
    pub fn bakes(label: &str, path: &Path, bakes: Vec<Value>) -> Source {
        Source { kind: SourceKind::Bake, label: label.into(), path: path.into(), files: Vec::new(), data: json!({ "bakes": bakes }) }
    }
}

/// Read one path given on the command line: one source, or (for a directory of runs)
/// several.
pub fn load(path: &Path) -> Result<Vec<Source>> {
    if path.is_dir() {
        if let Some(s) = load_dir(path)? {
            return Ok(vec![s]);
        }
        let mut children: Vec<PathBuf> = std::fs::read_dir(path)
            .with_context(|| format!("{}: cannot list", path.display()))?
            .flatten()
            .map(|e| e.path())
            .collect();
        children.sort();
        let mut out = Vec::new();
        for c in children {
            if c.is_dir() {
                if let Some(s) = load_dir(&c)? {
                    out.push(s);
                }
            } else if c.extension().is_some_and(|e| e == "json") {
                // a bake summary saved beside the runs; other JSON files are not records
                if let Ok(Some(s)) = load_file(&c) {
                    out.push(s);
                }
            }
        }
        if out.is_empty() {
            bail!(
                "{}: no run here (expected {METRICS}, {STYLIZE}, {SWEEP} or {QUALITY} in it or in a directory under it)",
                path.display()
            );
        }
        return Ok(out);
    }
    if !path.exists() {
        bail!("{}: no such file or directory", path.display());
    }
    match load_file(path)? {
        Some(s) => Ok(vec![s]),
        None => bail!(
            "{}: not a record snerf report reads (a run's {METRICS} or {STYLIZE}, a bake summary from `snerf bake --json`, {SWEEP} or {QUALITY})",
            path.display()
        ),
    }
}

/// The run in `dir`, if it holds one.
fn load_dir(dir: &Path) -> Result<Option<Source>> {
    let label = name_of(dir);
    let metrics = dir.join(METRICS);
    if metrics.is_file() {
        let m = read_json(&metrics)?;
        let eval_path = dir.join(EVAL);
        let eval = eval_path.is_file().then(|| read_json(&eval_path)).transpose()?;
        let mut s = Source::train(&label, dir, m, eval);
        s.files.push(metrics);
        if s.data["eval"].is_object() {
            s.files.push(eval_path);
        }
        return Ok(Some(s));
    }
    let state = dir.join(STYLIZE);
    if state.is_file() {
        let st = read_json(&state)?;
        let cpath = dir.join(CONSISTENCY);
        let c = cpath.is_file().then(|| read_json(&cpath)).transpose()?;
        let mut s = Source::stylize(&label, dir, st, c);
        s.files.push(state);
        if s.data["consistency"].is_object() {
            s.files.push(cpath);
        }
        return Ok(Some(s));
    }
    let sweep = dir.join(SWEEP);
    if sweep.is_file() {
        return Ok(Some(sweep_source(&label, dir, &sweep, read_json(&sweep)?)?));
    }
    let quality = dir.join(QUALITY);
    if quality.is_file() {
        let q = read_json(&quality)?;
        return Ok(Some(Source { kind: SourceKind::Quality, label, path: dir.into(), files: vec![quality], data: q }));
    }
    Ok(None)
}

fn sweep_source(label: &str, path: &Path, file: &Path, v: Value) -> Result<Source> {
    let bakes = v["bakes"].as_array().cloned().with_context(|| format!("{}: no \"bakes\" list", file.display()))?;
    let mut s = Source::bakes(label, path, bakes);
    s.files.push(file.into());
    Ok(s)
}

/// A record file: by its name when it is one of the run files, else by the `command` it
/// records. `None`: JSON, but no record of a kind this crate draws.
fn load_file(file: &Path) -> Result<Option<Source>> {
    let fname = file.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let dir = file.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if [METRICS, STYLIZE, SWEEP, QUALITY].contains(&fname.as_str()) {
        return load_dir(dir);
    }
    let v = read_json(file)?;
    let label = name_of(file);
    let mut s = match v["command"].as_str() {
        Some("bake") => Source::bakes(&label, file, vec![v]),
        Some("bake sweep") => return sweep_source(&label, file, file, v).map(Some),
        Some("bench quality") => Source { kind: SourceKind::Quality, label, path: file.into(), files: Vec::new(), data: v },
        Some("train") if v["metrics"].is_object() => Source::train(&label, file, v["metrics"].clone(), None),
        Some("stylize") if v["state"].is_object() => Source::stylize(&label, file, v["state"].clone(), None),
        _ => return Ok(None),
    };
    s.files.push(file.into());
    Ok(Some(s))
}

/// Load every path and give the sources distinct labels (`a/run` and `b/run` rather than
/// two `run`s).
pub fn load_all(paths: &[PathBuf]) -> Result<Vec<Source>> {
    let mut out = Vec::new();
    for p in paths {
        out.extend(load(p)?);
    }
    unique_labels(&mut out);
    Ok(out)
}

pub fn unique_labels(sources: &mut [Source]) {
    let dup = |s: &[Source], i: usize| s.iter().enumerate().any(|(j, o)| j != i && o.label == s[i].label);
    let dups: Vec<usize> = (0..sources.len()).filter(|&i| dup(sources, i)).collect();
    for i in dups {
        let parent = sources[i].path.parent().map(name_of).unwrap_or_default();
        if !parent.is_empty() {
            sources[i].label = format!("{parent}/{}", sources[i].label);
        }
    }
    for i in 0..sources.len() {
        let n = sources[..i].iter().filter(|o| o.label == sources[i].label).count();
        if n > 0 {
            sources[i].label = format!("{} #{}", sources[i].label, n + 1);
        }
    }
}
