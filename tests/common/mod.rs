//! What the command-line tests share: the binary under test and how its output is judged.
#![allow(dead_code)] // each test binary uses what it needs

use std::process::{Command, Output};

/// The `snerf` binary, on two worker threads.
pub fn snerf() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_snerf"));
    c.env("RAYON_NUM_THREADS", "2");
    c
}

/// A command that must succeed with a JSON summary on stdout.
pub fn ok(out: Output) -> serde_json::Value {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "command failed: {stderr}");
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("stdout is not JSON ({e}): {}", String::from_utf8_lossy(&out.stdout)))
}

/// A command that must fail, without a panic, with every one of `needles` in its error.
pub fn fails(out: Output, needles: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!out.status.success(), "expected failure, got success: {stderr}");
    assert_ne!(out.status.code(), Some(101), "must not panic: {stderr}");
    assert!(!stderr.contains("panicked"), "must not panic: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "error should mention {n:?}: {stderr}");
    }
    stderr
}

/// Whether Chromium, playwright-core, iwer and node are here for `test` (a browser test);
/// panics when `SNERF_REQUIRE_BROWSER=1` and one is missing.
pub fn have_browser(test: &str) -> bool {
    let chromium = std::env::var_os("SNERF_CHROMIUM").map(std::path::PathBuf::from).unwrap_or_else(|| std::path::PathBuf::from("/usr/bin/chromium"));
    let pw = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("target/test-assets/playwright/node_modules");
    let why = if !chromium.exists() {
        format!("no Chromium at {}", chromium.display())
    } else if !pw.join("playwright-core/package.json").exists() || !pw.join("iwer/build/iwer.min.js").exists() {
        format!("no playwright-core and iwer under {}", pw.display())
    } else if Command::new("node").arg("--version").output().is_err() {
        "no node".to_string()
    } else {
        return true;
    };
    if std::env::var("SNERF_REQUIRE_BROWSER").as_deref() == Ok("1") {
        panic!("SNERF_REQUIRE_BROWSER=1 but {why} (.ci/run installs it)");
    }
    eprintln!("skipping {test}: {why} (.ci/run installs chromium, playwright-core and iwer)");
    false
}
