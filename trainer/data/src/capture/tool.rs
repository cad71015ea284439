//! Running COLMAP and ffmpeg as child processes: finding the binary (with a message that says how
//! to install it), reading the progress lines they print, and stopping the child when the user
//! presses Ctrl-C. Their log is kept, so a failure can show its last lines.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use anyhow::{anyhow, bail, Result};

use super::Event;

/// The environment variable that names a COLMAP binary other than `colmap` on PATH.
pub const COLMAP_ENV: &str = "SNERF_COLMAP";

/// The setup step that installs COLMAP (and ffmpeg), named in every "not found" message.
pub const SETUP_HINT: &str =
    "run the setup step `bash scripts/setup-capture.sh` (as root: installs Debian's colmap and ffmpeg), \
     or `apt-get install colmap`";

/// `$SNERF_COLMAP`, else `colmap` on PATH.
pub fn find_colmap() -> Result<PathBuf> {
    if let Some(p) = std::env::var_os(COLMAP_ENV).filter(|p| !p.is_empty()) {
        let p = PathBuf::from(p);
        if p.is_file() {
            return Ok(p);
        }
        bail!(
            "${COLMAP_ENV} = {}: no such file; unset it to use `colmap` from PATH, or {SETUP_HINT}",
            p.display()
        );
    }
    on_path("colmap").ok_or_else(|| {
        anyhow!("COLMAP is not installed (no `colmap` on PATH, ${COLMAP_ENV} unset): {SETUP_HINT}")
    })
}

/// The first executable file called `name` in a PATH folder.
pub fn on_path(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|d| d.join(name))
        .find(|p| is_executable(p))
}

fn is_executable(p: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(p)
        .map(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
        .unwrap_or(false)
}

/// Runs `cmd`, feeding each output line (stdout and stderr, split at `\n` and `\r`) to `line`,
/// which may report progress. Fails with the last lines of the log when the child fails, and
/// kills the child and fails with `Interrupted` when Ctrl-C was pressed. Returns the whole log.
pub fn run(
    what: &str,
    mut cmd: Command,
    progress: &mut dyn FnMut(Event),
    line: &mut dyn FnMut(&str, &mut dyn FnMut(Event)),
) -> Result<String> {
    // COLMAP links Qt; without a display it must not try to open one.
    cmd.env("QT_QPA_PLATFORM", "offscreen");
    cmd.stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let program = cmd.get_program().to_string_lossy().into_owned();
    let mut child = cmd
        .spawn()
        .map_err(|e| anyhow!("{what}: cannot start {program}: {e}"))?;
    let (tx, rx) = mpsc::channel::<String>();
    let mut readers = Vec::new();
    for stream in [
        child
            .stdout
            .take()
            .map(|s| Box::new(s) as Box<dyn Read + Send>),
        child
            .stderr
            .take()
            .map(|s| Box::new(s) as Box<dyn Read + Send>),
    ]
    .into_iter()
    .flatten()
    {
        let tx = tx.clone();
        readers.push(std::thread::spawn(move || split_lines(stream, &tx)));
    }
    drop(tx);
    let mut log = String::new();
    loop {
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(l) => {
                line(&l, progress);
                log.push_str(&l);
                log.push('\n');
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
        }
        if snerf_files::interrupt::requested() {
            let _ = child.kill();
            let _ = child.wait();
            return Err(snerf_files::interrupt::Interrupted(format!(
                "{what} stopped; nothing was written"
            ))
            .into());
        }
    }
    for r in readers {
        let _ = r.join();
    }
    let status = child
        .wait()
        .map_err(|e| anyhow!("{what}: waiting for {program}: {e}"))?;
    if !status.success() {
        bail!(
            "{what} failed ({program} exited with {status}); its last output:\n{}",
            tail(&log, 15)
        );
    }
    Ok(log)
}

/// The last `n` non-empty lines of a log.
pub fn tail(log: &str, n: usize) -> String {
    let lines: Vec<&str> = log.lines().filter(|l| !l.trim().is_empty()).collect();
    lines[lines.len().saturating_sub(n)..].join("\n")
}

fn split_lines(mut r: Box<dyn Read + Send>, tx: &mpsc::Sender<String>) {
    let mut buf = [0u8; 8192];
    let mut cur = Vec::new();
    loop {
        let n = match r.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        for &b in &buf[..n] {
            if b == b'\n' || b == b'\r' {
                if !cur.is_empty() {
                    let _ = tx.send(String::from_utf8_lossy(&cur).into_owned());
                    cur.clear();
                }
            } else {
                cur.push(b);
            }
        }
    }
    if !cur.is_empty() {
        let _ = tx.send(String::from_utf8_lossy(&cur).into_owned());
    }
}

/// `[i/n]` in a COLMAP progress line after `prefix` ("Processed file [3/40]").
pub fn bracket_count(line: &str, prefix: &str) -> Option<(u64, u64)> {
    let rest = line.trim_start().strip_prefix(prefix)?.trim_start();
    let inner = rest.strip_prefix('[')?;
    let inner = &inner[..inner.find(']')?];
    let first = inner.split(',').next()?;
    let (a, b) = first.split_once('/')?;
    Some((a.trim().parse().ok()?, b.trim().parse().ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn colmap_progress_lines_parse() {
        assert_eq!(
            bracket_count("Processed file [3/40]", "Processed file"),
            Some((3, 40))
        );
        assert_eq!(
            bracket_count("Matching image [12/40] in 3.2s", "Matching image"),
            Some((12, 40))
        );
        assert_eq!(
            bracket_count("Matching block [2/3, 1/3] in 9s", "Matching block"),
            Some((2, 3))
        );
        assert_eq!(
            bracket_count("Undistorting image [5/9]", "Undistorting image"),
            Some((5, 9))
        );
        assert_eq!(bracket_count("Processed file", "Processed file"), None);
        assert_eq!(bracket_count("Features: 1941", "Processed file"), None);
    }
}
