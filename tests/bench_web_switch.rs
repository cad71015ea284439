//! `snerf bench web-switch` end to end on a tiny two-style asset: every number the switch
//! latency bar needs is there and sane (positive, finite), and each switch, in the page and by
//! the native client, received exactly the new style's colour part and a 4-byte index per
//! record; never a wall-clock value.
//!
//! Needs /usr/bin/chromium (or SNERF_CHROMIUM), Node.js and playwright-core and iwer under
//! target/test-assets/playwright (`.ci/run` installs them); skips with a message without
//! them, unless SNERF_REQUIRE_BROWSER=1 (CI), where it fails.

mod common;
use std::process::Command;

use serde_json::Value;
use snerf_asset::{AssetBuilder, Header, Kind, LayeredAsset, StyleInfo, ViewMlp};
use snerf_files::ScratchDir;


/// Two styles on one small ball: the second's colours the first's inverted.
fn two_styles() -> LayeredAsset {
    let mut h = Header::new(Kind::Object, 32, 8);
    h.background = [0.0; 3];
    let mut mlp = ViewMlp::zeros();
    mlp.b3 = vec![0.01, -0.02, 0.03];
    let mut b = AssetBuilder::new(h.clone(), mlp).unwrap();
    let g = h.grid_dim();
    let mut seed = 7u64;
    for z in 0..g {
        for y in 0..g {
            for x in 0..g {
                let c = [x, y, z].map(|i| -1.0 + (i as f32 + 0.5) * 2.0 / g as f32);
                if (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt() < 0.8 {
                    let blk: Vec<u8> = (0..h.block_bytes())
                        .map(|_| {
                            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                            (seed >> 56) as u8
                        })
                        .collect();
                    b.set_block(0, [x, y, z], &blk).unwrap();
                }
            }
        }
    }
    let warm = b.finish().unwrap();
    let mut cold = warm.clone();
    for v in cold.atlas.chunks_exact_mut(8) {
        for c in &mut v[1..] {
            *c = 255 - *c;
        }
    }
    let info = |n: &str| StyleInfo { name: n.into(), source: None, swatch: [0.5; 3] };
    LayeredAsset::new(vec![info("warm"), info("cold")], vec![warm, cold]).unwrap()
}

#[test]
fn bench_web_switch_reports_each_switchs_bytes_and_latencies() {
    if !common::have_browser("the bench web-switch test") {
        return;
    }
    let d = ScratchDir::new("snerf-bench-web-switch", "t").unwrap();
    let file = d.join("scene.snerf");
    let layered = two_styles();
    layered.write(&file).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_snerf"))
        .args(["--json", "bench", "web-switch"])
        .arg(&file)
        .args(["--reps", "2"])
        .output()
        .unwrap();
    assert!(out.status.success(), "command failed: {}", String::from_utf8_lossy(&out.stderr));
    let v: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["command"], "bench web-switch");
    let r = &v;
    let records = layered.header().atlas_blocks as u64 + 1;
    let want = |to: usize| layered.style_bytes()[to].bytes + 4 * records;
    let page = &r["page"];
    let bytes: Vec<u64> = page["bytes"].as_array().unwrap().iter().map(|b| b.as_f64().unwrap() as u64).collect();
    assert_eq!(bytes, [want(1), want(0)], "the page's switches: cold, then warm");
    for k in ["press_to_welcome_ms", "press_to_first_repainted_frame_ms", "press_to_complete_view_ms"] {
        let runs = page[k]["runs"].as_array().unwrap();
        assert_eq!(runs.len(), 2, "{k}");
        assert!(runs.iter().all(|x| x.as_f64().is_some_and(|x| x.is_finite() && x > 0.0)), "{k}: {runs:?}");
    }
    let reload = &page["whole_style_reload"];
    assert!(reload["firstFrameMs"].as_f64().is_some_and(|x| x > 0.0) && reload["completeMs"].as_f64().is_some_and(|x| x > 0.0), "{reload}");
    // the whole style's records: the file but its preamble, and a 4-byte index a chunk
    let whole = layered.clone().into_style(1).unwrap().to_bytes();
    let chunks = snerf_asset::chunks(&whole).unwrap().len() as u64;
    assert_eq!(reload["bytes"].as_u64(), Some(whole.len() as u64 - 16 + 4 * chunks));
    let native = r["native"].as_array().unwrap();
    assert_eq!(native.len(), 2);
    for (n, to) in native.iter().zip([1, 0]) {
        assert_eq!(n["bytes"].as_u64(), Some(want(to)), "{n}");
        for k in ["first_record_ms", "complete_ms", "fetch_ms"] {
            assert!(n[k].as_f64().is_some_and(|x| x.is_finite() && x > 0.0), "{k}: {n}");
        }
    }
    assert!(r["summary"].as_str().unwrap().contains("first repainted frame"));
}
