//! The layout of a run directory, in one place. `snerf train --out RUN` writes
//! `RUN/checkpoint.snerfck`, `RUN/config.json` and `RUN/metrics.json`; `snerf eval` writes
//! `RUN/eval/` with its record `eval.json`; `snerf stylize --out SRUN` writes a checkpoint and
//! `SRUN/stylize.json`. Every command that reads a run (eval, turntable, stylize, bake,
//! report, the benchmarks) goes through [`RunDir`] rather than joining these names itself,
//! so a missing piece is reported the same way everywhere: by the directory and the file.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde_json::Value;

use crate::checkpoint;
use crate::model::Model;
use crate::render::WorkspacePool;

/// A training or stylization run's directory.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RunDir {
    path: PathBuf,
}

impl RunDir {
    /// The field, its optimizer state and settings (`checkpoint` module).
    pub const CHECKPOINT: &'static str = checkpoint::FILE_NAME;
    /// Training settings, the scene space and the dataset's summary.
    pub const CONFIG: &'static str = "config.json";
    /// The test-PSNR-against-time curve.
    pub const METRICS: &'static str = "metrics.json";
    /// Where `snerf eval` writes its images by default.
    pub const EVAL_DIR: &'static str = "eval";
    /// `snerf eval`'s record, in its output directory.
    pub const EVAL_RECORD: &'static str = "eval.json";
    /// A stylization run's per-round record (written by snerf-stylize).
    pub const STYLIZE_RECORD: &'static str = "stylize.json";

    pub fn new(path: impl Into<PathBuf>) -> RunDir {
        RunDir { path: path.into() }
    }
    pub fn path(&self) -> &Path {
        &self.path
    }
    pub fn checkpoint(&self) -> PathBuf {
        self.path.join(Self::CHECKPOINT)
    }
    pub fn config(&self) -> PathBuf {
        self.path.join(Self::CONFIG)
    }
    pub fn metrics(&self) -> PathBuf {
        self.path.join(Self::METRICS)
    }
    pub fn eval_dir(&self) -> PathBuf {
        self.path.join(Self::EVAL_DIR)
    }
    /// The record of an evaluation into the default directory.
    pub fn eval_record(&self) -> PathBuf {
        self.eval_dir().join(Self::EVAL_RECORD)
    }
    pub fn stylize_record(&self) -> PathBuf {
        self.path.join(Self::STYLIZE_RECORD)
    }

    /// The files of the run that no command may overwrite through an `--out`.
    pub fn files(&self) -> Vec<PathBuf> {
        vec![self.checkpoint(), self.metrics(), self.config(), self.stylize_record()]
    }

    /// The dataset the run was trained on: `dataset.root` of config.json, or for a
    /// stylization run the `options.data` of its record.
    pub fn dataset(&self) -> Result<PathBuf> {
        if !self.path.is_dir() {
            bail!("{}: no such run directory (expected the --out of `snerf train` or `snerf stylize`)", self.path.display());
        }
        for (file, pointer) in [(self.config(), "/dataset/root"), (self.stylize_record(), "/options/data")] {
            if let Ok(bytes) = std::fs::read(&file) {
                let v: Value = serde_json::from_slice(&bytes).with_context(|| format!("{}: not JSON", file.display()))?;
                if let Some(root) = v.pointer(pointer).and_then(|r| r.as_str()) {
                    let root = PathBuf::from(root);
                    // Runs trained before roots were recorded absolute hold the path as it
                    // was typed, relative to a working directory this command may not share.
                    if root.is_relative() && !root.exists() {
                        bail!(
                            "{}: the run records its dataset as the relative path {}, which is not found from here (run from the directory it was trained in, or pass --data)",
                            self.path.display(),
                            root.display()
                        );
                    }
                    return Ok(root);
                }
            }
        }
        bail!(
            "{}: cannot tell which dataset this run used (no {} or {}); pass --data",
            self.path.display(),
            Self::CONFIG,
            Self::STYLIZE_RECORD
        )
    }

    /// The run's field as a renderable model, with a workspace pool sized for it.
    pub fn load_model(&self) -> Result<(Model, WorkspacePool)> {
        let path = self.checkpoint();
        if !path.exists() {
            bail!("{}: no checkpoint here (expected {}); run `snerf train` first", self.path.display(), path.display());
        }
        let ck = checkpoint::load(&path)?;
        let pool = WorkspacePool::new(ck.model.field.params.len());
        Ok((ck.model, pool))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(tag: &str) -> snerf_files::ScratchDir {
        snerf_files::ScratchDir::new("snerf-run-dir", tag).unwrap()
    }

    #[test]
    fn a_missing_checkpoint_or_directory_is_named_in_the_error() {
        let d = tmp("missing");
        let Err(e) = RunDir::new(&d).load_model() else { panic!("a model from an empty directory") };
        let e = format!("{e:#}");
        assert!(e.contains(&RunDir::new(&d).checkpoint().display().to_string()), "{e}");
        let e = format!("{:#}", RunDir::new(&d).dataset().unwrap_err());
        assert!(e.contains(&d.display().to_string()) && e.contains(RunDir::CONFIG), "{e}");
        let gone = d.join("no-such-run");
        let e = format!("{:#}", RunDir::new(&gone).dataset().unwrap_err());
        assert!(e.contains(&gone.display().to_string()), "{e}");
    }
}
