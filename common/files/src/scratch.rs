//! Scratch directories for tests: `$TMPDIR/<prefix>-<pid>-<name>`, removed when the value is
//! dropped, so a test that passes leaves nothing behind; dropped while the thread panics (a
//! failing test) the directory is kept and its path printed to stderr, to be looked at.

use std::ffi::OsStr;
use std::ops::Deref;
use std::path::{Path, PathBuf};

/// A directory removed on drop unless the thread is panicking. Derefs to its `Path`, so
/// `dir.join(..)`, `&dir` for a `&Path` and `.arg(&dir)` work as on a `PathBuf`.
#[derive(Debug)]
pub struct ScratchDir(PathBuf);

impl ScratchDir {
    /// A fresh, empty `$TMPDIR/<prefix>-<pid>-<name>` (one left by this process is emptied).
    pub fn new(prefix: &str, name: &str) -> std::io::Result<ScratchDir> {
        let d = std::env::temp_dir().join(format!("{prefix}-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d)?;
        Ok(ScratchDir(d))
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("kept {} for inspection (dropped while panicking)", self.0.display());
        } else if let Err(e) = std::fs::remove_dir_all(&self.0) {
            if e.kind() != std::io::ErrorKind::NotFound {
                eprintln!("warning: {}: cannot remove: {e}", self.0.display());
            }
        }
    }
}

impl Deref for ScratchDir {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for ScratchDir {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<OsStr> for ScratchDir {
    fn as_ref(&self) -> &OsStr {
        self.0.as_os_str()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn removed_when_dropped_and_kept_when_dropped_by_a_panic() {
        let d = ScratchDir::new("snerf-scratch", "drop").unwrap();
        std::fs::write(d.join("a"), b"x").unwrap();
        let p = d.to_path_buf();
        drop(d);
        assert!(!p.exists());
        let kept = std::thread::spawn(|| {
            let d = ScratchDir::new("snerf-scratch", "panic").unwrap();
            std::fs::write(d.join("a"), b"x").unwrap();
            std::panic::panic_any(d.to_path_buf());
        });
        let p = *kept.join().unwrap_err().downcast::<PathBuf>().unwrap();
        assert!(p.join("a").is_file());
        std::fs::remove_dir_all(&p).unwrap();
    }
}
