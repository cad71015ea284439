//! An exclusive lock on a directory (a run), so two processes never train or stylize into
//! the same place. It is an OS file lock on `DIR/.snerf-lock`: the kernel releases it when the
//! process exits for any reason, so a killed run never leaves a stale lock behind.

use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

pub const LOCK_FILE: &str = ".snerf-lock";

/// Held for as long as it lives.
#[derive(Debug)]
pub struct DirLock {
    _file: File,
    pub path: PathBuf,
}

impl DirLock {
    /// Create `dir` if needed and lock it; fails at once (naming the holder's PID) when
    /// another process holds it.
    pub fn acquire(dir: &Path) -> Result<DirLock> {
        std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
        let path = dir.join(LOCK_FILE);
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .with_context(|| format!("{}: cannot open the lock file", path.display()))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                let mut holder = String::new();
                let _ = file.read_to_string(&mut holder);
                let holder = holder.trim();
                bail!(
                    "{}: in use by another snerf process{}; wait for it to finish or choose another directory",
                    dir.display(),
                    if holder.is_empty() { String::new() } else { format!(" (pid {holder})") }
                );
            }
            Err(TryLockError::Error(e)) => {
                return Err(e).with_context(|| format!("{}: cannot lock", path.display()))
            }
        }
        // Who holds it, for the message above (the lock itself is what counts).
        let _ = file.set_len(0);
        let _ = file.rewind();
        let _ = write!(file, "{}", std::process::id());
        let _ = file.flush();
        Ok(DirLock { _file: file, path })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn second_lock_on_a_directory_fails_and_the_first_release_frees_it() {
        let d = crate::ScratchDir::new("snerf-lock", "second").unwrap();
        let a = DirLock::acquire(&d).unwrap();
        let e = DirLock::acquire(&d).unwrap_err().to_string();
        assert!(e.contains("in use by another snerf process"), "{e}");
        assert!(e.contains(&std::process::id().to_string()), "{e}");
        drop(a);
        let _b = DirLock::acquire(&d).unwrap();
    }
}
