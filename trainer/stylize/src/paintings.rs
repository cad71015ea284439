//! Real paintings for styles in tests and benchmarks: public-domain works, one tile of each,
//! taken by `scripts/setup-styles.sh` from Debian's `gcompris-qt-data` (the `paintings`
//! puzzle; the WebMuseum's scans, packaged under GPL-3.0-or-later) and checked by SHA-256
//! here as there.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use sha2::{Digest, Sha256};

/// The command that fetches the paintings.
pub const SETUP_COMMAND: &str = "bash scripts/setup-styles.sh";

#[derive(Clone, Copy, Debug)]
pub struct Painting {
    /// Short name used by tests and benchmarks.
    pub key: &'static str,
    pub file: &'static str,
    pub title: &'static str,
    pub sha256: &'static str,
}

/// The same files and hashes as `scripts/setup-styles.sh`.
pub const PAINTINGS: [Painting; 3] = [
    Painting {
        key: "vangogh",
        file: "gogh_auvert_3.webp",
        title: "Vincent van Gogh, Village Street in Auvers (1890)",
        sha256: "1aefb708e7c36a0e4c7c718e8cd2fd37d8321d7a4018d916f149314e4d4bfb98",
    },
    Painting {
        key: "renoir",
        file: "renoir-moulin_de_la_galette-2.webp",
        title: "Pierre-Auguste Renoir, Bal du moulin de la Galette (1876)",
        sha256: "297bdebac908b464b7b76a3555cbfa2192816bc660859dadc6041caae5f55617",
    },
    Painting {
        key: "kandinsky",
        file: "kandinky_3.webp",
        title: "Wassily Kandinsky, Composition VIII (1923)",
        sha256: "f9518aa6512a0e454a22e850f77d43ed7509e8a098fb5dad5ad22c10fd32e51b",
    },
];

/// `$SNERF_STYLES`, else `${XDG_CACHE_HOME:-$HOME/.cache}/snerf/styles` (as setup-styles.sh).
pub fn styles_dir() -> PathBuf {
    if let Some(dir) = std::env::var_os("SNERF_STYLES").filter(|d| !d.is_empty()) {
        return PathBuf::from(dir);
    }
    let cache = std::env::var_os("XDG_CACHE_HOME").filter(|d| !d.is_empty()).map(PathBuf::from).unwrap_or_else(|| {
        let home = std::env::var_os("HOME").map(PathBuf::from).unwrap_or_else(|| ".".into());
        home.join(".cache")
    });
    cache.join("snerf").join("styles")
}

/// The painting with this key.
pub fn by_key(key: &str) -> Result<Painting> {
    PAINTINGS.iter().copied().find(|p| p.key == key).with_context(|| {
        format!("no painting {key:?}; known: {}", PAINTINGS.iter().map(|p| p.key).collect::<Vec<_>>().join(", "))
    })
}

/// Path of an installed painting in `dir`, its SHA-256 verified. Errors name the file and
/// say how to install it.
pub fn verified_path(dir: &Path, p: &Painting) -> Result<PathBuf> {
    let path = dir.join(p.file);
    let bytes = std::fs::read(&path).with_context(|| format!("{}: painting not installed; run `{SETUP_COMMAND}`", path.display()))?;
    let got = format!("{:x}", Sha256::digest(&bytes));
    if got != p.sha256 {
        bail!("{}: SHA-256 {got}, expected {}; run `{SETUP_COMMAND}` again", path.display(), p.sha256);
    }
    Ok(path)
}

/// Whether every painting is installed in `dir` (presence only; `verified_path` checks).
pub fn all_installed(dir: &Path) -> bool {
    PAINTINGS.iter().all(|p| dir.join(p.file).is_file())
}
