//! `snerf bench web-switch FILE`: switch latency between the styles of a multi-style asset on
//! loopback. A real `snerf serve` (library) serves FILE; headless Chromium
//! (`viewer/stream/tests/web/switch.mjs`) opens its first style, waits for the whole asset,
//! then presses keys 2 and 1 in turn, `--reps` switches, each by the new style's colour part
//! (PROTOCOL.md, "Style switches"): press -> first frame with new colour drawn, and -> the
//! complete view (the first frame drawn after the last record), with the bytes received. Beside
//! it, in the same run: the page opening the second style whole, as a switch did before
//! (navigation -> first frame, -> complete view); and the native client (`snerf_stream`'s
//! QUIC client, no drawing): the same switch by colour (call -> first record written, -> all
//! written and the SHA-256 checked) and the whole style fetched. The page draws with WebGPU on
//! SwiftShader (no GPU): its frame times weigh in its latencies; the native client's do not
//! include a frame.

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use super::web::{browser, fmt_spread, load_average, stats, urlencode};

#[derive(Args, Debug)]
pub struct BenchWebSwitchArgs {
    /// A multi-style asset file (format version 3, two styles or more).
    pub asset: PathBuf,
    /// Switches in the page (keys 2, 1, 2, …) and by the native client.
    #[arg(long, default_value_t = 4, value_parser = crate::args::int_in::<usize>(1, 100, ""))]
    pub reps: usize,
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

pub fn run(a: &BenchWebSwitchArgs) -> Result<Value> {
    let (chromium, pw) = browser()?;
    let layered = snerf_asset::LayeredAsset::read(&a.asset)?;
    let names = layered.names();
    if names.len() < 2 {
        bail!("{}: one style; a switch needs two", a.asset.display());
    }
    let part: Vec<u64> = layered.style_bytes().iter().map(|s| s.bytes).collect();
    let whole: Vec<u64> = (0..2).map(|i| layered.clone().into_style(i).map(|s| s.to_bytes().len() as u64)).collect::<Result<_>>()?;
    let stem = snerf_stream::server::asset_name(&a.asset);
    let style_name = |i: usize| format!("{stem}.{}", names[i]);
    let load_start = load_average();
    let t0 = Instant::now();
    let (state, server) = super::web::loopback_server(&a.asset, "snerf-bench-web-switch")?;
    let r = measure(a, &chromium, &pw, &server, &style_name, &state);
    server.shutdown();
    let _ = std::fs::remove_dir_all(&state);
    let (page, native) = r?;
    let load_end = load_average();
    let sws = page["switches"].as_array().cloned().unwrap_or_default();
    let times = |k: &str| -> Vec<f64> {
        sws.iter().filter_map(|s| Some(s[k].as_f64()? - s["pressAt"].as_f64()?)).collect()
    };
    let (first, complete, welcome) = (times("firstFrameAt"), times("completeAt"), times("welcomeAt"));
    let bytes: Vec<f64> = sws.iter().filter_map(|s| s["bytes"].as_f64()).collect();
    let reload = &page["reload"];
    let la = |l: Option<[f64; 3]>| l.map(|l| format!("{:.2} {:.2} {:.2}", l[0], l[1], l[2])).unwrap_or_else(|| "?".into());
    let ms = |v: &[f64]| fmt_spread(v, 0);
    let nat = |k: &str| -> Vec<f64> { native.iter().filter_map(|n| n[k].as_f64()).collect() };
    let summary = format!(
        "machine: {} cores; load average (1/5/15 min) {} at the start, {} at the end; {:.0} s\n\
         {} styles {}; colour part {} / {} bytes, whole style {} / {} bytes\n\
         page (headless Chromium, WebGPU on SwiftShader, loopback), {} switches by colour, ms median [min-max]:\n\
         \x20 press -> welcome {}, -> first repainted frame {}, -> complete view {}; bytes {}\n\
         page opening the other style whole (as a switch did before): -> first frame {:.0} ms, -> complete view {:.0} ms, {} bytes\n\
         native client (QUIC, no drawing), {} switches by colour: -> first record written {} ms, -> all written and checked {} ms; whole style fetched {} ms\n",
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(0),
        la(load_start),
        la(load_end),
        t0.elapsed().as_secs_f64(),
        a.asset.display(),
        names.join(", "),
        part[0],
        part[1],
        whole[0],
        whole[1],
        sws.len(),
        ms(&welcome),
        ms(&first),
        ms(&complete),
        fmt_spread(&bytes, 0),
        reload["firstFrameMs"].as_f64().unwrap_or(f64::NAN),
        reload["completeMs"].as_f64().unwrap_or(f64::NAN),
        reload["bytes"],
        native.len(),
        ms(&nat("first_record_ms")),
        ms(&nat("complete_ms")),
        ms(&nat("fetch_ms")),
    );
    eprint!("{summary}");
    Ok(json!({
        "command": "bench web-switch",
        "asset": a.asset.display().to_string(),
        "styles": names,
        "colour_part_bytes": part,
        "whole_style_bytes": whole,
        "page": {
            "press_to_welcome_ms": stats(&welcome),
            "press_to_first_repainted_frame_ms": stats(&first),
            "press_to_complete_view_ms": stats(&complete),
            "bytes": bytes,
            "switches": sws,
            "whole_style_reload": reload,
            "adapter": page["adapter"],
            "backend": page["backend"],
        },
        "native": native,
        "machine": { "load_average_start": load_start, "load_average_end": load_end, "wall_s": t0.elapsed().as_secs_f64() },
        "summary": summary,
    }))
}

fn measure(
    a: &BenchWebSwitchArgs,
    chromium: &std::path::Path,
    pw: &std::path::Path,
    server: &snerf_stream::ServerHandle,
    style_name: &dyn Fn(usize) -> String,
    state: &std::path::Path,
) -> Result<(Value, Vec<Value>)> {
    let web = server.web().ok_or_else(|| anyhow!("the web viewer did not start"))?.clone();
    let url = |name: &str| format!("{}#token={}&asset={}", web.url(), urlencode(server.token()), urlencode(name));
    let keys: Vec<&str> = (0..a.reps).map(|i| if i % 2 == 0 { "2" } else { "1" }).collect();
    let out = Command::new("node")
        .arg(root().join("viewer/stream/tests/web/switch.mjs"))
        .arg(pw)
        .arg(url(&style_name(0)))
        .arg(keys.join(","))
        .arg(url(&style_name(1)))
        .env("SNERF_CHROMIUM", chromium)
        .output()
        .context("running node (is Node.js installed?)")?;
    if !out.status.success() {
        bail!("switch.mjs failed: {}", String::from_utf8_lossy(&out.stderr));
    }
    let page: Value = serde_json::from_slice(&out.stdout).with_context(|| format!("switch.mjs output: {}", String::from_utf8_lossy(&out.stdout)))?;
    if let Some(e) = page["error"].as_str() {
        bail!("the page failed: {e}");
    }
    // The native client: the first style fetched whole once, then switched by colour in turn,
    // and the other style fetched whole each time (the old way).
    let (pin, token) = (server.fingerprint().to_string(), server.token().to_string());
    let file = state.join("held.snerf");
    snerf_stream::fetch_blocking(&server.url(&style_name(0)), &pin, &token, &file)?;
    let mut held = snerf_asset::Asset::read(&file)?;
    let first = snerf_asset::LayeredAsset::read(&a.asset)?.names()[0].clone();
    let mut info = snerf_stream::plan::ServedAsset::load_style(&style_name(0), &a.asset, Some(&first))?.info();
    // made once, as the page makes its own while idle after the stream
    let mut recolour = snerf_asset::Recolour::new(&held);
    let mut native = Vec::new();
    for i in 0..a.reps {
        let to = style_name(if i % 2 == 0 { 1 } else { 0 });
        let sw = snerf_stream::restyle::switch_style_blocking(&server.url(&to), &pin, &token, &mut held, &info, None, &mut recolour)?;
        let t = Instant::now();
        let whole = state.join(format!("whole{i}.snerf"));
        snerf_stream::fetch_blocking(&server.url(&to), &pin, &token, &whole)?;
        let fetch_ms = t.elapsed().as_secs_f64() * 1e3;
        let _ = std::fs::remove_file(&whole);
        native.push(json!({
            "to": to, "bytes": sw.bytes, "records": sw.records,
            "welcome_ms": sw.welcome.as_secs_f64() * 1e3,
            "first_record_ms": sw.first_record.as_secs_f64() * 1e3,
            "complete_ms": sw.complete.as_secs_f64() * 1e3,
            "fetch_ms": fetch_ms,
        }));
        info = sw.info;
    }
    Ok((page, native))
}
