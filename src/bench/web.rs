//! `snerf bench web ASSET`: the web viewer's bars beside the native client, in one run on
//! loopback. A real `snerf serve` (library) serves the asset; headless Chromium
//! (playwright-core, `scripts/bench-web.mjs`, one fresh browser per job) loads the page:
//!
//! - first drawn frame: navigation -> first frame and -> complete view, on WebGPU and on
//!   WebGL2 (Chromium without WebGPU), beside `snerf bench stream`'s native first view;
//! - transfer: the same asset fetched by `snerf fetch`'s client (QUIC), by the page over
//!   WebTransport and by the page over HTTPS requests (no `window.WebTransport`), in MB/s
//!   (10^6 bytes/s) and as ratios;
//! - frame time: flat at `--size` on both renderers beside `snerf bench view`'s wgpu frame
//!   time (lavapipe without a GPU), and the immersive mode on an emulated Quest 3 (iwer) at
//!   its per-eye size, render scale pinned at 1, on both renderers, beside the native
//!   side-by-side stereo frame.
//!
//! Repeated measurements are interleaved (native, then the page's, in each repetition) so
//! that both sides see the same load; medians and min–max are reported. The machine's load
//! average is read at the start and the end: on a shared machine, timings are only
//! comparable within one run.

use anyhow::{anyhow, bail, ensure, Context, Result};
use clap::Args;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct BenchWebArgs {
    /// A baked asset file (use one big enough that the transfer dominates: tens of MB).
    pub asset: PathBuf,
    /// Frame size WxH of the flat frame-time comparison.
    #[arg(long, default_value = "1280x720")]
    pub size: String,
    /// Per-eye size of the immersive comparison (Meta Quest 3: 1832x1920), or "none".
    #[arg(long, default_value = "1832x1920")]
    pub eye: String,
    /// Flat frames timed on each side (median reported).
    #[arg(long, default_value_t = 3, value_parser = crate::args::int_in::<usize>(1, 1000, ""))]
    pub frames: usize,
    /// Immersive frames timed per renderer after the first (which compiles the shader and is
    /// reported apart; median reported). SwiftShader marches a Quest 3 frame in tens of
    /// seconds: keep this small.
    #[arg(long, default_value_t = 2, value_parser = crate::args::int_in::<usize>(1, 1000, ""))]
    pub xr_frames: usize,
    /// Repetitions of the first-frame and transfer measurements (median and min–max reported).
    #[arg(long, default_value_t = 3, value_parser = crate::args::int_in::<usize>(1, 100, ""))]
    pub reps: usize,
    /// Renderers measured in the browser: webgpu, webgl2 or both (comma-separated).
    #[arg(long, default_value = "webgpu,webgl2", value_delimiter = ',', value_parser = ["webgpu", "webgl2"])]
    pub backends: Vec<String>,
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// (chromium, playwright-core's directory) or a clear error saying how to get them.
pub(super) fn browser() -> Result<(PathBuf, PathBuf)> {
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

/// One job of scripts/bench-web.mjs in a fresh browser; its JSON.
fn page_job(chromium: &Path, pw: &Path, job: &Value) -> Result<Value> {
    let out = Command::new("node")
        .arg(root().join("scripts/bench-web.mjs"))
        .arg(pw)
        .arg(job.to_string())
        .env("SNERF_CHROMIUM", chromium)
        .output()
        .context("running node (is Node.js installed?)")?;
    if !out.status.success() {
        bail!("scripts/bench-web.mjs ({}) failed: {}", job["mode"], String::from_utf8_lossy(&out.stderr));
    }
    serde_json::from_slice(&out.stdout).with_context(|| format!("bench-web.mjs output: {}", String::from_utf8_lossy(&out.stdout)))
}

/// The 1-, 5- and 15-minute load averages (Linux), to say how loaded the machine was.
pub(super) fn load_average() -> Option<[f64; 3]> {
    let s = std::fs::read_to_string("/proc/loadavg").ok()?;
    let v: Vec<f64> = s.split_whitespace().take(3).filter_map(|x| x.parse().ok()).collect();
    (v.len() == 3).then(|| [v[0], v[1], v[2]])
}

/// Median (the mean of the middle two of an even count), min and max.
fn spread(xs: &[f64]) -> (f64, f64, f64) {
    let mut s: Vec<f64> = xs.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    s.sort_by(f64::total_cmp);
    let n = s.len();
    let m = if n % 2 == 1 { s[n / 2] } else { 0.5 * (s[n / 2 - 1] + s[n / 2]) };
    (m, s[0], s[n - 1])
}

pub(super) fn stats(xs: &[f64]) -> Value {
    let (m, lo, hi) = spread(xs);
    json!({ "runs": xs, "median": m, "min": lo, "max": hi })
}

/// "median [min–max]" with `d` decimals.
pub(super) fn fmt_spread(xs: &[f64], d: usize) -> String {
    let (m, lo, hi) = spread(xs);
    if xs.len() < 2 {
        return format!("{m:.d$}");
    }
    format!("{m:.d$} [{lo:.d$}–{hi:.d$}]")
}

const MB: f64 = 1e6;

pub fn run(a: &BenchWebArgs) -> Result<Value> {
    let (chromium, pw) = browser()?;
    let (w, h) = crate::args::parse_size(&a.size)?;
    let eye = if a.eye == "none" { None } else { Some(crate::args::parse_size(&a.eye)?) };
    ensure!(!a.backends.is_empty(), "--backends: name webgpu, webgl2 or both");
    let backends: Vec<&str> = ["webgpu", "webgl2"].into_iter().filter(|b| a.backends.iter().any(|x| x == b)).collect();
    let load_start = load_average();
    let t_start = Instant::now();
    let asset = snerf_asset::Asset::read(&a.asset)?;
    let size = std::fs::metadata(&a.asset)?.len() as f64;
    let (state, server) = loopback_server(&a.asset, "snerf-bench-web")?;
    let result = measure(a, &chromium, &pw, &server, &asset, &state, (w, h), eye, &backends, size);
    server.shutdown();
    let _ = std::fs::remove_dir_all(&state);
    let mut v = result?;
    let load_end = load_average();
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(0);
    let machine = json!({
        "cores": cores,
        "load_average_start": load_start,
        "load_average_end": load_end,
        "browser": v["browser"].as_str().map(|s| format!("Chromium {s}")),
        "wall_s": t_start.elapsed().as_secs_f64(),
    });
    let la = |l: Option<[f64; 3]>| l.map(|l| format!("{:.2} {:.2} {:.2}", l[0], l[1], l[2])).unwrap_or_else(|| "?".into());
    let head = format!(
        "machine: {} cores; Chromium {} headless; load average (1/5/15 min) {} at the start, {} at the end; {:.0} s\n",
        cores,
        v["browser"].as_str().unwrap_or("Chromium"),
        la(load_start),
        la(load_end),
        t_start.elapsed().as_secs_f64()
    );
    let summary = head + v["summary"].as_str().unwrap_or("");
    eprint!("{summary}");
    v["machine"] = machine;
    v["summary"] = summary.into();
    Ok(v)
}

#[allow(clippy::too_many_arguments)]
fn measure(
    a: &BenchWebArgs,
    chromium: &Path,
    pw: &Path,
    server: &snerf_stream::ServerHandle,
    asset: &snerf_asset::Asset,
    state: &Path,
    (w, h): (u32, u32),
    eye: Option<(u32, u32)>,
    backends: &[&str],
    size: f64,
) -> Result<Value> {
    let web = server.web().ok_or_else(|| anyhow!("the web viewer did not start"))?.clone();
    let name = snerf_stream::server::asset_name(&a.asset);
    let cam_of = |w: u32, h: u32| {
        let cam = snerf_asset::orbit(&asset.header, 1, 0, w, h, 40.0);
        json!({ "c2w": cam.c2w, "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy, "width": w, "height": h }).to_string()
    };
    let url = |extra: &[(&str, &str)]| -> String {
        let mut pairs = vec![("token", server.token()), ("asset", name.as_str())];
        pairs.extend_from_slice(extra);
        format!("{}#{}", web.url(), pairs.iter().map(|(k, v)| format!("{}={}", k, urlencode(v))).collect::<Vec<_>>().join("&"))
    };
    let mut browser_version = Value::Null;
    let mut adapters = serde_json::Map::new();

    // 1. First drawn frame: the page as a user opens it (adaptive scale), each renderer in a
    // fresh browser, interleaved with the native client's first view. The flat frame time is
    // taken once per renderer, in the first repetition.
    let flat_url = url(&[]);
    let cam = cam_of(w, h);
    let mut first: serde_json::Map<String, Value> = serde_json::Map::new();
    let mut flat_frame: serde_json::Map<String, Value> = serde_json::Map::new();
    let mut native_first = Vec::new();
    let mut native_complete = Vec::new();
    let mut page_runs: Vec<Vec<Value>> = vec![Vec::new(); backends.len()];
    for rep in 0..a.reps {
        for (i, b) in backends.iter().enumerate() {
            eprintln!("bench web: first frame, {b}, {}/{} ...", rep + 1, a.reps);
            let frames = if rep == 0 { a.frames } else { 0 };
            let r = page_job(chromium, pw, &json!({ "mode": "flat", "url": flat_url, "backend": b, "frames": frames, "cam": cam }))?;
            browser_version = r["browserVersion"].clone();
            let f = r["flat"].clone();
            adapters.insert(b.to_string(), f["adapter"].clone());
            if rep == 0 {
                flat_frame.insert(b.to_string(), json!({ "median_ms": spread(&nums(&f["frameTimes"])).0, "frames_ms": f["frameTimes"] }));
            }
            page_runs[i].push(f);
        }
        eprintln!("bench web: native first view {}/{} ...", rep + 1, a.reps);
        let s = snerf_stream::bench::run(&a.asset, &snerf_stream::bench::BenchOptions { rounds: 1, ..Default::default() })?;
        native_first.push(s.first_view.as_secs_f64() * 1e3);
        native_complete.push(s.complete.as_secs_f64() * 1e3);
    }
    let app_js = page_runs.first().and_then(|r| r.first()).and_then(|r| r["appJsSha256"].as_str()).unwrap_or("?").to_string();
    // the page the numbers belong to: app.js is embedded in the server at build time
    let mut t = format!("asset: {} ({:.2} MB); page app.js SHA-256 {}\n", a.asset.display(), size / MB, app_js);
    t += &format!("first drawn frame, navigation -> first frame; -> complete view (ms, median [min–max] of {}):\n", a.reps);
    for (i, b) in backends.iter().enumerate() {
        let runs = &page_runs[i];
        let ff: Vec<f64> = runs.iter().map(|r| num(&r["firstFrameAt"])).collect();
        let cv: Vec<f64> = runs.iter().map(|r| num(&r["completeAt"])).collect();
        let f0 = &runs[0]["firstFrame"];
        t += &format!(
            "  {:<7} {} ({}x{}, {} blocks in, over {}); complete {}\n",
            label(b),
            fmt_spread(&ff, 0),
            f0["width"],
            f0["height"],
            f0["blocks"],
            runs[0]["transport"].as_str().unwrap_or("?"),
            fmt_spread(&cv, 0)
        );
        first.insert(
            b.to_string(),
            json!({
                "first_frame_ms": stats(&ff),
                "complete_ms": stats(&cv),
                "adapter": runs[0]["adapter"],
                "transport": runs[0]["transport"],
                "app_js_sha256": runs[0]["appJsSha256"],
                "first_frame": runs.iter().map(|r| r["firstFrame"].clone()).collect::<Vec<_>>(),
                "marks": runs.iter().map(|r| r["marks"].clone()).collect::<Vec<_>>(),
            }),
        );
    }
    t += &format!("  native  {} (first view, snerf bench stream); complete {}\n", fmt_spread(&native_first, 0), fmt_spread(&native_complete, 0));
    first.insert("native".into(), json!({ "first_view_ms": stats(&native_first), "complete_ms": stats(&native_complete) }));

    // 2. Transfer: `snerf fetch`'s client (the same function the command runs) against the
    // server the page uses, then the page over WebTransport and over HTTPS requests, per
    // repetition. The page's URL carries a tiny fixed camera so that its redraws as blocks
    // arrive cost little on SwiftShader; its rate runs from the session being ready to the
    // last record read off a stream, the native one from connect to the last chunk received.
    let small = cam_of(64, 48);
    let xfer_url = url(&[("cam", &small)]);
    let qurl = server.url(&name);
    let fetched = state.join("fetched.snerf");
    let (mut native, mut wt, mut https) = (Vec::new(), Vec::new(), Vec::new());
    let mut page_transfer = Vec::new();
    for rep in 0..a.reps {
        eprintln!("bench web: transfer {}/{} (snerf fetch, WebTransport, HTTPS) ...", rep + 1, a.reps);
        let _ = std::fs::remove_file(&fetched);
        let _ = std::fs::remove_file(snerf_stream::part_path(&fetched));
        let st = snerf_stream::fetch_blocking(&qurl, server.fingerprint(), server.token(), &fetched)?;
        ensure!(std::fs::metadata(&fetched)?.len() as f64 == size, "snerf fetch wrote a file of another size");
        native.push(size / MB / st.transfer.as_secs_f64());
        let r = page_job(chromium, pw, &json!({ "mode": "transfer", "urls": { "webtransport": xfer_url, "https": xfer_url } }))?;
        let x = &r["transfer"];
        wt.push(size / MB / (num(&x["webtransport"]["transferMs"]) / 1e3));
        https.push(size / MB / (num(&x["https"]["transferMs"]) / 1e3));
        page_transfer.push(x.clone());
    }
    let ratios = |a: &[f64], b: &[f64]| -> Value {
        let per_rep: Vec<f64> = a.iter().zip(b).map(|(x, y)| x / y).collect();
        json!({ "of_medians": spread(a).0 / spread(b).0, "per_rep": stats(&per_rep) })
    };
    let rt = |a: &[f64], b: &[f64]| {
        let per_rep: Vec<f64> = a.iter().zip(b).map(|(x, y)| x / y).collect();
        let (_, lo, hi) = spread(&per_rep);
        if per_rep.len() < 2 {
            format!("{:.3}", spread(a).0 / spread(b).0)
        } else {
            format!("{:.3} (per repetition {lo:.3}–{hi:.3})", spread(a).0 / spread(b).0)
        }
    };
    t += &format!("transfer of {:.2} MB, MB/s (10^6 B/s), median [min–max] of {} (the page with a fixed 64x48 camera, WebGPU):\n", size / MB, a.reps);
    t += &format!("  snerf fetch (QUIC)   {}\n", fmt_spread(&native, 1));
    t += &format!("  page, WebTransport   {}\n", fmt_spread(&wt, 1));
    t += &format!("  page, HTTPS requests {}\n", fmt_spread(&https, 1));
    t += &format!("  HTTPS / WebTransport {}; HTTPS / snerf fetch {}; WebTransport / snerf fetch {}\n", rt(&https, &wt), rt(&https, &native), rt(&wt, &native));
    let transfer = json!({
        "bytes": size,
        "unit": "MB/s (10^6 bytes per second)",
        "native_fetch_mb_s": stats(&native),
        "webtransport_mb_s": stats(&wt),
        "https_mb_s": stats(&https),
        "https_over_webtransport": ratios(&https, &wt),
        "https_over_native": ratios(&https, &native),
        "webtransport_over_native": ratios(&wt, &native),
        "page": page_transfer,
    });

    // 3. Immersive mode at the headset's per-eye size, each renderer in a fresh browser.
    let mut xr = serde_json::Map::new();
    if let Some((ew, eh)) = eye {
        let xr_url = url(&[("xrscale", "1")]);
        for b in backends {
            eprintln!("bench web: immersive 2 x {ew}x{eh}, {b}, {} frames ...", a.xr_frames);
            let r = page_job(chromium, pw, &json!({ "mode": "xr", "url": xr_url, "backend": b, "frames": a.xr_frames, "eyeW": ew, "eyeH": eh }))?;
            xr.insert(b.to_string(), r["xr"].clone());
        }
    }

    // 4. The native frame times, flat and side-by-side stereo at the eye size.
    eprintln!("bench web: native frame time ...");
    let mut vo = snerf_viewer::BenchOptions { width: w, height: h, frames: a.frames, cpu_frames: 1, ..Default::default() };
    if let Some(e) = eye {
        vo.stereo = true;
        vo.stereo_size = e;
    }
    let native_view = snerf_viewer::bench_view_with(asset, &vo)?;
    t += &format!("frame {w}x{h}, median of {} (ms):", a.frames);
    for b in backends {
        let m = spread(&nums(&flat_frame[*b]["frames_ms"])).0;
        t += &format!(" {} {:.0} ({:.2}x native);", label(b), m, m / native_view.gpu_median_ms);
    }
    t += &format!(" native {:.0} ({})\n", native_view.gpu_median_ms, native_view.adapter);
    flat_frame.insert("native".into(), json!({ "median_ms": native_view.gpu_median_ms, "adapter": native_view.adapter }));
    flat_frame.insert("size".into(), json!([w, h]));
    let mut quest = Value::Null;
    if let (Some((ew, eh)), Some(ns)) = (eye, native_view.stereo.as_ref()) {
        t += &format!("immersive 2 x {ew}x{eh} (Quest 3 per eye, xrscale=1), march time, median of {} after the first (ms):", a.xr_frames);
        let mut q = serde_json::Map::new();
        for b in backends {
            let x = &xr[*b];
            let m = spread(&nums(&x["steadyMs"])).0;
            t += &format!(
                " {} {:.0} ({:.2}x native; first march {:.0}, Enter VR -> first frame {:.0});",
                label(b),
                m,
                m / ns.gpu_median_ms,
                num(&x["firstMarchMs"]),
                num(&x["firstFrameMs"])
            );
            q.insert(b.to_string(), json!({ "frame_ms": stats(&nums(&x["steadyMs"])), "median_ms": m, "first_march_ms": x["firstMarchMs"], "enter_vr_to_first_frame_ms": x["firstFrameMs"], "scale": x["scale"], "eyes": x["eyes"], "adapter": x["adapter"], "over_native": m / ns.gpu_median_ms }));
        }
        t += &format!(" native side by side {:.0}\n", ns.gpu_median_ms);
        q.insert("native_side_by_side_ms".into(), json!(ns.gpu_median_ms));
        q.insert("eye".into(), json!([ew, eh]));
        quest = Value::Object(q);
    }
    Ok(json!({
        "command": "bench web",
        "asset": crate::args::pj(&a.asset),
        "asset_bytes": size,
        "reps": a.reps,
        "frames": a.frames,
        "xr_frames": a.xr_frames,
        "browser": browser_version,
        "browser_adapters": adapters,
        "native_adapter": native_view.adapter,
        "first_frame": first,
        "transfer": transfer,
        "flat_frame": flat_frame,
        "quest3": quest,
        "page_xr": xr,
        "native_view": native_view,
        "summary": t,
    }))
}

fn label(b: &str) -> &'static str {
    if b == "webgl2" {
        "WebGL2"
    } else {
        "WebGPU"
    }
}

fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or(f64::NAN)
}

fn nums(v: &Value) -> Vec<f64> {
    v.as_array().map(|a| a.iter().map(num).collect()).unwrap_or_default()
}

pub(super) fn urlencode(s: &str) -> String {
    s.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' => (b as char).to_string(),
            _ => format!("%{:02X}", b),
        })
        .collect()
}

/// A `snerf serve` of `asset` with its web page, on loopback only (the server, its page and
/// every client stay on 127.0.0.1), and the scratch folder (`prefix-PID`) holding its state.
pub(super) fn loopback_server(asset: &std::path::Path, prefix: &str) -> Result<(std::path::PathBuf, snerf_stream::ServerHandle)> {
    let state = std::env::temp_dir().join(format!("{prefix}-{}", std::process::id()));
    std::fs::create_dir_all(&state)?;
    let mut o = snerf_stream::ServeOptions::new(asset, "127.0.0.1:0".parse()?);
    o.state_dir = Some(state.join("state"));
    o.quiet = true;
    o.web = Some("127.0.0.1:0".parse()?);
    let server = snerf_stream::spawn(o)?;
    Ok((state, server))
}
