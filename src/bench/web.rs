//! `snerf bench web ASSET`: the web viewer beside the native client, in one run on loopback.
//! A real `snerf serve` (library) serves the asset; headless Chromium (playwright-core,
//! `scripts/bench-web.mjs`) loads the page and reports navigation to first rendered frame,
//! to complete view, the WebTransport download rate and the frame time at a size, and the
//! immersive mode's frame time on an emulated Quest 3 at its per-eye size; the native side is
//! `snerf bench stream`'s QUIC fetch and first view, and `snerf bench view`'s wgpu frame time
//! (lavapipe without a GPU) at the same sizes. Ratios are within this one run.

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::process::Command;

#[derive(Args, Debug)]
pub struct BenchWebArgs {
    /// A baked asset file.
    pub asset: PathBuf,
    /// Frame size WxH of the flat frame-time comparison.
    #[arg(long, default_value = "1280x720")]
    pub size: String,
    /// Per-eye size of the immersive comparison (Meta Quest 3: 1832x1920), or "none".
    #[arg(long, default_value = "1832x1920")]
    pub eye: String,
    /// Frames timed on each side (median reported).
    #[arg(long, default_value_t = 5, value_parser = crate::args::int_in::<usize>(1, 1000, ""))]
    pub frames: usize,
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// (chromium, playwright-core's directory) or a clear error saying how to get them.
fn browser() -> Result<(PathBuf, PathBuf)> {
    let chromium = std::env::var_os("SNERF_CHROMIUM").map(PathBuf::from).unwrap_or_else(|| "/usr/bin/chromium".into());
    let pw = root().join("target/test-assets/playwright");
    if !chromium.exists() {
        bail!("no Chromium at {} (apt-get install chromium, or set SNERF_CHROMIUM)", chromium.display());
    }
    if !pw.join("node_modules/playwright-core/package.json").exists() || !pw.join("node_modules/iwer/build/iwer.min.js").exists() {
        bail!("no playwright-core and iwer under {} (bash .ci/run installs them)", pw.display());
    }
    Ok((chromium, pw))
}

pub fn run(a: &BenchWebArgs) -> Result<Value> {
    let (chromium, pw) = browser()?;
    let (w, h) = crate::args::parse_size(&a.size)?;
    let eye = if a.eye == "none" { None } else { Some(crate::args::parse_size(&a.eye)?) };
    let asset = snerf_asset::Asset::read(&a.asset)?;
    let state = std::env::temp_dir().join(format!("snerf-bench-web-{}", std::process::id()));
    let mut o = snerf_stream::ServeOptions::new(&a.asset, "127.0.0.1:0".parse()?);
    o.state_dir = Some(state.clone());
    o.quiet = true;
    o.web = Some("127.0.0.1:0".parse()?);
    let server = snerf_stream::spawn(o)?;
    let web = server.web().ok_or_else(|| anyhow!("the web viewer did not start"))?.clone();
    let name = snerf_stream::server::asset_name(&a.asset);
    let cam = snerf_asset::orbit(&asset.header, 1, 0, w, h, 40.0);
    let cam_json = json!({ "c2w": cam.c2w, "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy, "width": w, "height": h }).to_string();
    let frag = |pairs: &[(&str, &str)]| -> String {
        pairs.iter().map(|(k, v)| format!("{}={}", k, urlencode(v))).collect::<Vec<_>>().join("&")
    };
    let flat = format!("{}#{}", web.url(), frag(&[("token", server.token()), ("asset", &name)]));
    let xr = match eye {
        Some(_) => format!("{}#{}", web.url(), frag(&[("token", server.token()), ("asset", &name), ("xrscale", "1")])),
        None => "-".into(),
    };
    let (ew, eh) = eye.unwrap_or((0, 0));
    eprintln!("bench web: Chromium on {} ...", web.url());
    let out = Command::new("node")
        .arg(root().join("scripts/bench-web.mjs"))
        .arg(&pw)
        .args([&flat, &xr, &a.frames.to_string(), &ew.to_string(), &eh.to_string(), &cam_json])
        .env("SNERF_CHROMIUM", &chromium)
        .output()
        .context("running node (is Node.js installed?)")?;
    if !out.status.success() {
        bail!("scripts/bench-web.mjs failed: {}", String::from_utf8_lossy(&out.stderr));
    }
    let page: Value = serde_json::from_slice(&out.stdout).context("bench-web.mjs output")?;
    server.shutdown();
    let _ = std::fs::remove_dir_all(&state);
    // The native side, same machine, same run.
    eprintln!("bench web: native QUIC fetch ...");
    let stream = snerf_stream::bench::run(&a.asset, &snerf_stream::bench::BenchOptions { rounds: 1, ..Default::default() })?;
    eprintln!("bench web: native frame time ...");
    let mut vo = snerf_viewer::BenchOptions { width: w, height: h, frames: a.frames, cpu_frames: 1, ..Default::default() };
    if let Some(e) = eye {
        vo.stereo = true;
        vo.stereo_size = e;
    }
    let native = snerf_viewer::bench_view_with(&asset, &vo)?;
    let f = |v: &Value, k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    let pf = &page["flat"];
    let size = std::fs::metadata(&a.asset)?.len() as f64;
    // From the session being ready to the last record read off a stream.
    let wt_mb_s = size / (1 << 20) as f64 / ((f(pf, "downloadedAt") - f(pf, "connectedAt")) / 1e3);
    let native_mb_s = size / (1 << 20) as f64 / stream.quic_transfer.as_secs_f64();
    let web_frame = f(pf, "frameMs");
    let xr_frame = f(&page["xr"], "frameMsMedian");
    let native_stereo = native.stereo.as_ref().map(|s| s.gpu_median_ms);
    let mut t = String::new();
    t += &format!("asset: {} ({:.2} MiB), browser adapter {}, native adapter {}\n", a.asset.display(), size / (1 << 20) as f64, pf["adapter"], native.adapter);
    t += &format!(
        "navigation -> first rendered frame: {:.0} ms ({}x{}, {} blocks in); -> complete view {:.0} ms\n",
        f(pf, "firstFrameAt"),
        pf["firstFrame"]["width"],
        pf["firstFrame"]["height"],
        pf["firstFrame"]["blocks"],
        f(pf, "completeAt")
    );
    t += &format!("native first view (snerf bench stream): {:.0} ms; complete {:.0} ms\n", stream.first_view.as_secs_f64() * 1e3, stream.complete.as_secs_f64() * 1e3);
    t += &format!("download: WebTransport {:.1} MiB/s, native QUIC fetch {:.1} MiB/s (ratio {:.2})\n", wt_mb_s, native_mb_s, wt_mb_s / native_mb_s);
    t += &format!("frame {}x{}: Chromium {:.1} ms, native {:.1} ms (ratio {:.2})\n", w, h, web_frame, native.gpu_median_ms, web_frame / native.gpu_median_ms);
    if let (Some(ns), Some((ew, eh))) = (native_stereo, eye) {
        t += &format!(
            "immersive 2 x {}x{}: Chromium (emulated Quest 3) {:.1} ms, native side-by-side {:.1} ms (ratio {:.2}); Enter VR -> first immersive frame {:.0} ms\n",
            ew, eh, xr_frame, ns, xr_frame / ns, f(&page["xr"], "firstFrameMs")
        );
    }
    eprint!("{t}");
    Ok(json!({
        "command": "bench web",
        "asset": crate::args::pj(&a.asset),
        "page": page,
        "native_stream": stream.to_string(),
        "native_view": native,
        "webtransport_mib_s": wt_mb_s,
        "native_fetch_mib_s": native_mb_s,
        "download_ratio": wt_mb_s / native_mb_s,
        "frame_ratio": web_frame / native.gpu_median_ms,
        "xr_frame_ratio": native_stereo.map(|n| xr_frame / n),
        "summary": t,
    }))
}

fn urlencode(s: &str) -> String {
    s.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' => (b as char).to_string(),
            _ => format!("%{:02X}", b),
        })
        .collect()
}
