//! Crash-safe file replacement: readers see the old file or the new one, never a torn one,
//! and no temp file outlives the write that made it.
//!
//! Temp files are named `.NAME.PID.snerf-tmp` beside their target. A failed write removes its
//! temp file; Ctrl-C removes every live one (see `interrupt`); a temp file left by a process
//! that was killed outright is removed by the next snerf process that writes into the same
//! directory (`sweep_stale`), once its PID is no longer running.

use std::collections::HashSet;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use anyhow::{anyhow, Context, Result};
use serde::Serialize;

const SUFFIX: &str = ".snerf-tmp";

/// Temp paths that exist right now (removed by the Ctrl-C handler before it exits).
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Directories already swept by this process (one sweep each is enough).
static SWEPT: Mutex<Option<HashSet<PathBuf>>> = Mutex::new(None);

/// The directory a path lives in (`.` for a bare file name).
pub fn parent_dir(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A temp path beside `path`, unique to this process: `.NAME.PID.snerf-tmp`.
pub fn temp_path(path: &Path) -> Result<PathBuf> {
    let name = path
        .file_name()
        .ok_or_else(|| anyhow!("{}: not a file path", path.display()))?;
    let mut tmp = std::ffi::OsString::from(".");
    tmp.push(name);
    tmp.push(format!(".{}{SUFFIX}", std::process::id()));
    Ok(parent_dir(path).join(tmp))
}

/// A temp file or directory that is removed when dropped, unless `keep` was called (after it
/// was renamed into place). While it lives, Ctrl-C removes it too.
pub struct TempPath {
    path: PathBuf,
    armed: bool,
}

impl TempPath {
    /// Claim the temp path for `target` (removing a leftover of this same process first).
    pub fn for_target(target: &Path) -> Result<TempPath> {
        sweep_stale(&parent_dir(target));
        let path = temp_path(target)?;
        remove_any(&path);
        LIVE.lock().unwrap_or_else(|e| e.into_inner()).push(path.clone());
        Ok(TempPath { path, armed: true })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The temp path has been renamed into place: nothing to remove any more.
    pub fn keep(mut self) {
        self.armed = false;
        forget(&self.path);
    }
}

impl Drop for TempPath {
    fn drop(&mut self) {
        if self.armed {
            remove_any(&self.path);
            forget(&self.path);
        }
    }
}

fn forget(path: &Path) {
    let mut live = LIVE.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(i) = live.iter().position(|p| p == path) {
        live.swap_remove(i);
    }
}

fn remove_any(path: &Path) {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_dir() => {
            let _ = std::fs::remove_dir_all(path);
        }
        Ok(_) => {
            let _ = std::fs::remove_file(path);
        }
        Err(_) => {}
    }
}

/// Remove every live temp path of this process (the Ctrl-C handler, just before exit).
pub fn remove_live_temps() {
    let live = std::mem::take(&mut *LIVE.lock().unwrap_or_else(|e| e.into_inner()));
    for p in live {
        remove_any(&p);
    }
}

/// The PID in a snerf temp name (`.NAME.PID.snerf-tmp`, or the older checkpoint temp
/// `checkpoint.snerfck.PID.tmp`), if `name` is one.
fn temp_owner(name: &str) -> Option<u32> {
    let stem = if let Some(s) = name.strip_suffix(SUFFIX).filter(|_| name.starts_with('.')) {
        s
    } else if name.starts_with("checkpoint.snerfck.") {
        name.strip_suffix(".tmp")?
    } else {
        return None;
    };
    stem.rsplit_once('.')?.1.parse().ok()
}

fn process_alive(pid: u32) -> bool {
    pid == std::process::id() || Path::new(&format!("/proc/{pid}")).exists()
}

/// Remove snerf temp files and directories in `dir` whose process is gone. Runs once per
/// directory per process; does nothing where `/proc` cannot tell which processes run.
/// Returns how many it removed.
pub fn sweep_stale(dir: &Path) -> usize {
    if !Path::new("/proc/self").exists() {
        return 0;
    }
    let key = std::fs::canonicalize(dir).unwrap_or_else(|_| dir.to_path_buf());
    {
        let mut swept = SWEPT.lock().unwrap_or_else(|e| e.into_inner());
        if !swept.get_or_insert_with(HashSet::new).insert(key) {
            return 0;
        }
    }
    let Ok(entries) = std::fs::read_dir(dir) else { return 0 };
    let mut removed = 0;
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(pid) = name.to_str().and_then(temp_owner) else { continue };
        if !process_alive(pid) {
            remove_any(&e.path());
            removed += 1;
        }
    }
    removed
}

/// Write `bytes` to a temp file beside `path`, fsync it, rename it over `path`, then fsync
/// the directory (best effort) so the rename itself is durable. On any error the temp file
/// is removed and `path` is untouched.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |f| f.write_all(bytes))
}

/// Like `write_atomic`, with the content streamed by `fill`.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut std::io::BufWriter<std::fs::File>) -> std::io::Result<()>,
) -> Result<()> {
    let tmp = TempPath::for_target(path)?;
    let result = (|| -> std::io::Result<()> {
        let f = std::fs::File::create(tmp.path())?;
        let mut w = std::io::BufWriter::new(f);
        fill(&mut w)?;
        let f = w.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(tmp.path(), path)?;
        Ok(())
    })();
    result.map_err(|e| anyhow!("{}: cannot write: {}", path.display(), e))?;
    tmp.keep();
    if let Ok(d) = std::fs::File::open(parent_dir(path)) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Pretty JSON with a trailing newline, atomically.
pub fn write_json_atomic(path: &Path, value: &impl Serialize) -> Result<()> {
    let mut bytes =
        serde_json::to_vec_pretty(value).with_context(|| format!("{}: cannot encode", path.display()))?;
    bytes.push(b'\n');
    write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(tag: &str) -> crate::ScratchDir {
        crate::ScratchDir::new("snerf-files", tag).unwrap()
    }

    #[test]
    fn failed_write_leaves_no_temp_and_keeps_the_old_file() {
        let d = scratch("fail");
        let p = d.join("a.json");
        std::fs::write(&p, b"old").unwrap();
        let r = write_atomic_with(&p, |w| {
            w.write_all(b"partial")?;
            Err(std::io::Error::other("disk full"))
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        let names: Vec<_> = std::fs::read_dir(&d).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names.len(), 1, "left behind: {names:?}");
        write_atomic(&p, b"new").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"new");
        // (other tests write in parallel: look only at this directory's temp paths)
        assert!(!LIVE.lock().unwrap().iter().any(|t| t.starts_with(&d)));
    }

    #[test]
    fn stale_temps_of_dead_processes_are_swept_others_kept() {
        let d = scratch("sweep");
        // PIDs above the kernel's pid_max (4194304) can never be running.
        let dead = d.join(".x.snerf.4999999.snerf-tmp");
        let dead_dir = d.join(".data.4999998.snerf-tmp");
        let old_ckpt = d.join("checkpoint.snerfck.4999997.tmp");
        let mine = d.join(format!(".y.{}.snerf-tmp", std::process::id()));
        let user = d.join("notes.4999999.tmp");
        let user2 = d.join("photo.4999999.snerf-tmp"); // no leading dot: not ours
        for p in [&dead, &old_ckpt, &mine, &user, &user2] {
            std::fs::write(p, b"x").unwrap();
        }
        std::fs::create_dir_all(dead_dir.join("train")).unwrap();
        assert_eq!(sweep_stale(&d), 3);
        assert!(!dead.exists() && !dead_dir.exists() && !old_ckpt.exists());
        assert!(mine.exists() && user.exists() && user2.exists());
    }
}
