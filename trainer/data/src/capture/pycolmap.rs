//! The pycolmap backend: the same phases as Debian's `colmap` (features, matching, mapping,
//! undistortion) through PyPI's `pycolmap` (COLMAP 4.x), driven by a small Python script that
//! ships inside the binary (`pycolmap_driver.py`) and runs under the Python of the setup step's
//! virtual environment. On the same 40 real frames it mapped 5.7× faster than Debian's COLMAP
//! 3.8 at the same registration (BENCH.md §2d), and its mapper takes a random seed, so a
//! capture on one thread repeats exactly (on several, the order in which threads finish still
//! changes the mapping: the same 24 photos gave reprojection errors of 0.366 and 0.354 px on
//! two threads, 0.380 px twice on one).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use serde_json::Value;

use super::{tool, Event};

/// The environment variable that names a Python with pycolmap, instead of the setup step's.
pub const PYTHON_ENV: &str = "SNERF_PYCOLMAP";

/// Where `scripts/setup-capture.sh` puts its virtual environment (the workspace's target/).
const VENV_PYTHON: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../target/capture-venv/bin/python"
);

const DRIVER: &str = include_str!("pycolmap_driver.py");

/// A Python that imports pycolmap, and pycolmap's version.
#[derive(Clone, Debug)]
pub struct Pycolmap {
    pub python: PathBuf,
    pub version: String,
}

/// `$SNERF_PYCOLMAP`, else the setup step's virtual environment, if it imports pycolmap.
/// `Err` explains why not (a named Python that fails is an error, not a fallback).
pub fn find() -> Result<Pycolmap> {
    let (python, named) = match std::env::var_os(PYTHON_ENV).filter(|p| !p.is_empty()) {
        Some(p) => (PathBuf::from(p), true),
        None => (PathBuf::from(VENV_PYTHON), false),
    };
    if !python.is_file() {
        bail!(
            "{}{}: no such file; {}",
            if named {
                format!("${PYTHON_ENV} = ")
            } else {
                String::new()
            },
            python.display(),
            tool::SETUP_HINT
        );
    }
    let out = Command::new(&python)
        .args(["-c", "import pycolmap; print(pycolmap.__version__)"])
        .output()
        .with_context(|| format!("{}: cannot run", python.display()))?;
    if !out.status.success() {
        bail!(
            "{}: cannot import pycolmap ({}); {}",
            python.display(),
            String::from_utf8_lossy(&out.stderr)
                .lines()
                .last()
                .unwrap_or("")
                .trim(),
            tool::SETUP_HINT
        );
    }
    let version = format!("pycolmap {}", String::from_utf8_lossy(&out.stdout).trim());
    Ok(Pycolmap { python, version })
}

impl Pycolmap {
    /// Runs one step of the driver (`args["step"]`: "map" or "undistort") in `work`,
    /// forwarding its phases and progress; returns its log and the wall seconds of each phase.
    pub fn run(
        &self,
        work: &Path,
        args: &Value,
        progress: &mut dyn FnMut(Event),
    ) -> Result<(String, Vec<(String, f64)>)> {
        let script = work.join("pycolmap_driver.py");
        std::fs::write(&script, DRIVER)
            .with_context(|| format!("{}: cannot write", script.display()))?;
        let mut cmd = Command::new(&self.python);
        cmd.arg(&script).arg(args.to_string());
        let mut times: Vec<(String, Instant)> = Vec::new();
        let log = tool::run(
            &format!("pycolmap {}", args["step"].as_str().unwrap_or("")),
            cmd,
            progress,
            &mut |l, p| {
                if let Some(rest) = l.strip_prefix("snerf-phase ") {
                    let mut it = rest.split_whitespace();
                    let name = it.next().unwrap_or("").to_string();
                    let total = it.next().and_then(|t| t.parse().ok()).unwrap_or(0);
                    times.push((name.clone(), Instant::now()));
                    p(Event::Phase { name, total });
                } else if let Some(k) = l
                    .strip_prefix("snerf-done ")
                    .and_then(|k| k.trim().parse().ok())
                {
                    p(Event::Done(k));
                }
            },
        );
        let end = Instant::now();
        let seconds = times
            .iter()
            .enumerate()
            .map(|(i, (name, t))| {
                (
                    name.clone(),
                    times
                        .get(i + 1)
                        .map_or(end, |n| n.1)
                        .duration_since(*t)
                        .as_secs_f64(),
                )
            })
            .collect();
        log.map(|l| (l, seconds))
    }
}
