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
    assert!(!stderr.contains("panicked"), "must not panic: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "error should mention {n:?}: {stderr}");
    }
    stderr
}
