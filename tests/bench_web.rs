//! `snerf bench web` end to end at tiny sizes: a small real asset, the page in headless
//! Chromium on both renderers and both transports, the native client beside it. Checks that
//! every measurement the web viewer's bars need is present and sane (positive, finite, the
//! renderer and transport asked for); never a wall-clock value.
//!
//! Needs /usr/bin/chromium (or SNERF_CHROMIUM), Node.js, and playwright-core and iwer under
//! target/test-assets/playwright (`.ci/run` installs them); skips with a message without
//! them, unless SNERF_REQUIRE_BROWSER=1 (CI), where it fails.

mod common;
use common::{ok, snerf};
use std::path::{Path, PathBuf};

use serde_json::Value;
use snerf_files::ScratchDir;


/// A small real asset: scene -> train -> bake, in `d`.
fn bake_small(d: &Path) -> PathBuf {
    let ds = d.join("ds");
    ok(snerf()
        .args(["--json", "scene", "object", "--out"])
        .arg(&ds)
        .args(["--views", "6", "--test-views", "2", "--size", "16x16", "--supersample", "1"])
        .output()
        .unwrap());
    let run = d.join("run");
    ok(snerf().args(["--json", "train"]).arg(&ds).arg("--out").arg(&run).args(["--steps", "2"]).output().unwrap());
    let file = d.join("a.snerf");
    ok(snerf()
        .args(["--json", "bake"])
        .arg(&run)
        .arg("--out")
        .arg(&file)
        .args(["--resolution", "32", "--eval-views", "0", "--visibility-views", "4"])
        .output()
        .unwrap());
    file
}

fn pos(v: &Value, what: &str) -> f64 {
    let x = v.as_f64().unwrap_or_else(|| panic!("{what}: not a number: {v}"));
    assert!(x.is_finite() && x > 0.0, "{what}: {x}");
    x
}

/// {runs, median, min, max}: `n` positive runs, min <= median <= max.
fn spread(v: &Value, n: usize, what: &str) {
    let runs = v["runs"].as_array().unwrap_or_else(|| panic!("{what}: no runs: {v}"));
    assert_eq!(runs.len(), n, "{what}: {v}");
    for r in runs {
        pos(r, what);
    }
    let (m, lo, hi) = (pos(&v["median"], what), pos(&v["min"], what), pos(&v["max"], what));
    assert!(lo <= m && m <= hi, "{what}: {v}");
}

#[test]
fn bench_web_measures_first_frame_transfer_and_quest3_frame_on_both_renderers() {
    if !common::have_browser("the bench web test") {
        return;
    }
    let d = ScratchDir::new("snerf-bench-web", "tiny").unwrap();
    let file = bake_small(&d);
    let v = ok(snerf()
        .args(["--json", "bench", "web"])
        .arg(&file)
        .args(["--size", "32x24", "--eye", "40x48", "--frames", "1", "--xr-frames", "1", "--reps", "2"])
        .output()
        .unwrap());
    assert_eq!(v["command"], "bench web");
    // The machine the numbers were taken on, and how loaded it was.
    assert!(v["machine"]["cores"].as_u64().unwrap() >= 1, "{}", v["machine"]);
    if Path::new("/proc/loadavg").exists() {
        assert_eq!(v["machine"]["load_average_start"].as_array().map(|a| a.len()), Some(3), "{}", v["machine"]);
        assert_eq!(v["machine"]["load_average_end"].as_array().map(|a| a.len()), Some(3), "{}", v["machine"]);
    }
    assert!(v["machine"]["browser"].as_str().is_some_and(|s| !s.is_empty()), "{}", v["machine"]);
    // First frame: both renderers, over WebTransport, beside the native first view.
    let ff = &v["first_frame"];
    for b in ["webgpu", "webgl2"] {
        spread(&ff[b]["first_frame_ms"], 2, &format!("{b} first frame"));
        spread(&ff[b]["complete_ms"], 2, &format!("{b} complete"));
        assert_eq!(ff[b]["transport"], "webtransport", "{b}");
        // the page measured, named by what the server served
        assert!(ff[b]["app_js_sha256"].as_str().is_some_and(|h| h.len() == 64 && h.bytes().all(|c| c.is_ascii_hexdigit())), "{b}: {}", ff[b]);
        assert!(ff[b]["adapter"].as_str().is_some_and(|s| !s.is_empty()), "{b}: {}", ff[b]);
        // the complete view comes no earlier than the first frame
        assert!(pos(&ff[b]["complete_ms"]["median"], b) >= pos(&ff[b]["first_frame_ms"]["min"], b), "{b}: {}", ff[b]);
    }
    spread(&ff["native"]["first_view_ms"], 2, "native first view");
    // Transfer: three clients, MB/s, ratios between them.
    let t = &v["transfer"];
    assert_eq!(t["bytes"].as_f64().unwrap(), std::fs::metadata(&file).unwrap().len() as f64);
    for k in ["native_fetch_mb_s", "webtransport_mb_s", "https_mb_s"] {
        spread(&t[k], 2, k);
    }
    for k in ["https_over_webtransport", "https_over_native", "webtransport_over_native"] {
        pos(&t[k]["of_medians"], k);
        spread(&t[k]["per_rep"], 2, k);
    }
    let pages = t["page"].as_array().unwrap();
    assert_eq!(pages.len(), 2);
    for p in pages {
        assert_eq!(p["webtransport"]["transport"], "webtransport", "{p}");
        assert_eq!(p["https"]["transport"], "https", "{p}");
    }
    // Flat frame time on both renderers and natively.
    let f = &v["flat_frame"];
    for b in ["webgpu", "webgl2", "native"] {
        pos(&f[b]["median_ms"], b);
    }
    assert_eq!(f["size"], serde_json::json!([32, 24]));
    // Quest 3 (here a small eye): both renderers, immersive, and the native stereo frame.
    let q = &v["quest3"];
    assert_eq!(q["eye"], serde_json::json!([40, 48]));
    pos(&q["native_side_by_side_ms"], "native stereo");
    for b in ["webgpu", "webgl2"] {
        pos(&q[b]["median_ms"], b);
        pos(&q[b]["enter_vr_to_first_frame_ms"], b);
        pos(&q[b]["first_march_ms"], b);
        spread(&q[b]["frame_ms"], q[b]["frame_ms"]["runs"].as_array().map_or(0, |r| r.len().max(1)), b);
        let eyes = q[b]["eyes"].as_array().unwrap_or_else(|| panic!("{b}: {}", q[b]));
        assert_eq!(eyes.len(), 2, "{b}: {}", q[b]);
        for e in eyes {
            // viewport [x, y, w, h]: each eye at the size asked for
            assert_eq!((&e[2], &e[3]), (&serde_json::json!(40), &serde_json::json!(48)), "{b}: {}", q[b]);
        }
        assert_eq!(q[b]["scale"], 1, "{b}: xrscale=1 pins the render scale");
    }
    let s = v["summary"].as_str().unwrap();
    for k in ["load average", "WebGPU", "WebGL2", "native", "HTTPS / WebTransport", "HTTPS / snerf fetch", "immersive 2 x 40x48"] {
        assert!(s.contains(k), "summary lacks {k:?}:\n{s}");
    }
}
