//! The web viewer end to end: a real server on loopback (the code `snerf serve` runs), the
//! real page in headless Chromium (driven by `tests/web/page.mjs` through playwright-core),
//! WebTransport with the token from the URL fragment, the asset received byte for byte
//! (SHA-256 computed by the page), and the page's WebGPU frame against the CPU reference
//! renderer (`snerf render`) at the same pose.
//!
//! Needs `/usr/bin/chromium` (or SNERF_CHROMIUM) and playwright-core under
//! target/test-assets/playwright (`.ci/run` installs both). Without them the tests say so and
//! pass, unless SNERF_REQUIRE_BROWSER=1 (CI), where they fail.

mod common;

use common::*;
use sha2::{Digest, Sha256};
use snerf_asset::Asset;
use snerf_stream::{Limits, ServeOptions, ServerHandle};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::atomic::Ordering;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// (node, chromium, playwright-core dir), or None after saying why (panics under CI).
fn browser() -> Option<(PathBuf, PathBuf, PathBuf)> {
    let chromium = std::env::var_os("SNERF_CHROMIUM")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/usr/bin/chromium"));
    let pw = root().join("target/test-assets/playwright/node_modules/playwright-core");
    let node = Command::new("node").arg("--version").output().is_ok();
    let missing = if !chromium.exists() {
        Some(format!("no Chromium at {}", chromium.display()))
    } else if !pw.join("package.json").exists() {
        Some(format!("no playwright-core at {}", pw.display()))
    } else if !node {
        Some("no node".to_string())
    } else {
        None
    };
    match missing {
        None => Some((PathBuf::from("node"), chromium, pw)),
        Some(why) => {
            if std::env::var("SNERF_REQUIRE_BROWSER").as_deref() == Ok("1") {
                panic!("SNERF_REQUIRE_BROWSER=1 but {} (.ci/run installs it)", why);
            }
            eprintln!("skipping the web viewer test: {} (.ci/run installs chromium and playwright-core)", why);
            None
        }
    }
}

fn start(dir: &Path, state: &Path) -> ServerHandle {
    start_with(dir, state, Limits::default())
}

fn start_with(dir: &Path, state: &Path, limits: Limits) -> ServerHandle {
    let mut o = ServeOptions::new(dir, "127.0.0.1:0".parse().unwrap());
    o.state_dir = Some(state.to_path_buf());
    o.limits = limits;
    o.quiet = std::env::var_os("SNERF_STREAM_LOG").is_none();
    o.web = Some("127.0.0.1:0".parse().unwrap());
    snerf_stream::spawn(o).unwrap()
}

/// Run page.mjs; its JSON report.
fn page(b: &(PathBuf, PathBuf, PathBuf), args: &[&str]) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web/page.mjs");
    let out = Command::new(&b.0)
        .arg(&script)
        .arg(&b.2)
        .args(args)
        .env("SNERF_CHROMIUM", &b.1)
        .output()
        .expect("run node");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "page.mjs failed: {}", stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(stdout.trim()).unwrap_or_else(|e| panic!("page report {:?}: {} (stderr: {})", stdout, e, stderr))
}

fn cam_json(c: &snerf_asset::Camera) -> String {
    serde_json::json!({
        "c2w": c.c2w, "fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy,
        "width": c.width, "height": c.height,
    })
    .to_string()
}

fn fragment(pairs: &[(&str, &str)]) -> String {
    let enc = |s: &str| -> String {
        s.bytes()
            .map(|b| match b {
                b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' => (b as char).to_string(),
                _ => format!("%{:02X}", b),
            })
            .collect()
    };
    pairs.iter().map(|(k, v)| format!("{}={}", k, enc(v))).collect::<Vec<_>>().join("&")
}

/// Mean absolute difference per channel between the page's RGBA floats and a CPU frame.
fn mean_abs_diff(rgba: &[serde_json::Value], cpu: &snerf_asset::Frame) -> [f64; 3] {
    let px = (cpu.width * cpu.height) as usize;
    assert_eq!(rgba.len(), px * 4, "page frame size");
    let mut d = [0f64; 3];
    for i in 0..px {
        for c in 0..3 {
            let g = rgba[4 * i + c].as_f64().unwrap().clamp(0.0, 1.0);
            d[c] += (g - cpu.rgb[3 * i + c] as f64).abs();
        }
    }
    d.map(|x| x / px as f64)
}

#[test]
fn page_streams_by_webtransport_and_renders_like_the_cpu_reference() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web");
    let state = TempDir::new("web-state");
    let asset = static_asset(32, 8, 0.8, 11);
    let bytes = write_asset(&asset, dir.path(), "scene");
    // A second asset so the listing shows more than one.
    write_asset(&dynamic_asset(16, 8, 0.9, 2, 3), dir.path(), "moving");
    let h = start(dir.path(), state.path());
    let web = h.web().expect("web viewer started").clone();
    // The pose of `snerf render --path orbit --frames 1 --size 64x48`.
    let cam = snerf_asset::orbit(&asset.header, 1, 0, 64, 48, 40.0);
    let url = format!(
        "{}#{}",
        web.url(),
        fragment(&[("token", h.token()), ("asset", "scene"), ("cam", &cam_json(&cam))])
    );
    let r = page(&b, &[&url, "done"]);
    assert_eq!(r["error"], serde_json::Value::Null, "page error: {}", r["error"]);
    assert_eq!(r["state"], "done");
    // The listing: names, sizes, kinds.
    let listing = r["listing"].as_array().unwrap();
    let names: Vec<&str> = listing.iter().map(|e| e["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["moving", "scene"]);
    assert_eq!(listing[1]["size"], bytes.len() as u64);
    assert_eq!(listing[1]["kind"], "object");
    // Byte-identical: the page's SHA-256 of the rebuilt file is the file's.
    let sha = snerf_stream::proto::to_hex(&Sha256::digest(&bytes));
    assert_eq!(r["sha256"], sha.as_str());
    assert_eq!(r["chunks"], r["asset"]["chunks"]);
    // The same image as the CPU reference.
    let cpu = snerf_asset::render(&Asset::from_bytes(&bytes).unwrap(), &cam, 0.0);
    let fr = &r["lastRender"];
    assert_eq!(fr["complete"], true);
    assert_eq!((fr["width"].as_u64(), fr["height"].as_u64()), (Some(64), Some(48)));
    let d = mean_abs_diff(fr["rgba"].as_array().unwrap(), &cpu);
    eprintln!("web vs CPU reference: mean |diff| per channel {:?} (adapter {})", d, r["adapter"]);
    assert!(d.iter().all(|&x| x <= 2.0 / 255.0), "mean |diff| {:?} > 2/255", d);
    // The image is not trivially empty (the comparison means something).
    let lit = cpu.rgb.iter().filter(|&&v| v > 0.05).count();
    assert!(lit > cpu.rgb.len() / 10, "the test image is almost black");
    assert!(h.stats().bytes_sent.load(Ordering::Relaxed) >= bytes.len() as u64 - 16);
    h.shutdown();
}

#[test]
fn wrong_token_missing_token_and_another_origin_get_nothing() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-refuse");
    let state = TempDir::new("web-refuse-state");
    write_asset(&static_asset(16, 8, 0.9, 5), dir.path(), "scene");
    let h = start(dir.path(), state.path());
    let web = h.web().unwrap().clone();
    // Wrong token: the server closes the session (unauthorized) before sending anything.
    let wrong = "0".repeat(64);
    let url = format!("{}#{}", web.url(), fragment(&[("token", &wrong), ("asset", "scene")]));
    let r = page(&b, &[&url, "done"]);
    assert_eq!(r["state"], "error");
    assert_eq!(r["listing"], serde_json::Value::Null);
    assert_eq!(r["asset"], serde_json::Value::Null);
    assert_eq!(r["bytes"], 0);
    assert!(h.stats().unauthorized.load(Ordering::Relaxed) >= 1);
    // No token: the page does not even connect.
    let r = page(&b, &[&format!("{}#asset=scene", web.url()), "done"]);
    assert_eq!(r["state"], "error");
    assert!(r["error"].as_str().unwrap().contains("token"), "{}", r["error"]);
    // A page of another origin: the CONNECT is refused (403).
    let before = h.stats().unauthorized.load(Ordering::Relaxed);
    let wt = format!("https://127.0.0.1:{}/snerf/1", web.addr.port());
    let r = page(&b, &["-", "-", &wt, web.cert_hash.as_deref().unwrap()]);
    eprintln!("another origin: {}", r);
    assert_eq!(r["connected"], false, "{}", r);
    assert!(h.stats().unauthorized.load(Ordering::Relaxed) > before);
    assert_eq!(h.stats().bytes_sent.load(Ordering::Relaxed), 0);
    assert_eq!(h.stats().streams_started.load(Ordering::Relaxed), 0);
    h.shutdown();
}

/// An unbounded or forward-facing asset: random thin blocks in the cells within `radius` of
/// the grid centre (unbounded: contracted space, the far field is the grid's outer shell;
/// forward: NDC space of a reference camera).
fn kind_asset(kind: snerf_asset::Kind, res: u32, block: u32, radius: f32, seed: u64) -> Asset {
    use snerf_asset::{AssetBuilder, Header, Kind, Ndc};
    let mut h = Header::new(kind, res, block);
    h.background = [0.2, 0.3, 0.4];
    if kind == Kind::Forward {
        h.space.ndc = Some(Ndc { fx: 60.0, fy: 60.0, width: 100.0, height: 80.0, near: 1.0, xy_extent: 1.3 });
    }
    let g = h.grid_dim();
    let bb = h.block_bytes();
    let mut b = AssetBuilder::new(h, mlp()).unwrap();
    let mut rng = Rng(seed | 1);
    let mut buf = vec![0u8; bb];
    let c = |i: usize| -1.0 + (i as f32 + 0.5) * 2.0 / g as f32;
    for z in 0..g {
        for y in 0..g {
            for x in 0..g {
                if (c(x).powi(2) + c(y).powi(2) + c(z).powi(2)).sqrt() < radius {
                    rng.fill(&mut buf);
                    // Unbounded: thin densities (codes 0..63) so the far shell shows through.
                    if kind == Kind::Unbounded {
                        for v in buf.chunks_mut(8) {
                            v[0] &= 63;
                        }
                    }
                    b.set_block(0, [x, y, z], &buf).unwrap();
                }
            }
        }
    }
    b.finish().unwrap()
}

/// Stream `name` into the page with the orbit's first camera at `time`; check the page's
/// frame against the CPU reference. Returns the page's report.
fn check_render(b: &(PathBuf, PathBuf, PathBuf), h: &ServerHandle, asset: &Asset, name: &str, time: f32) -> serde_json::Value {
    let cam = snerf_asset::orbit(&asset.header, 1, 0, 48, 32, 40.0);
    let url = format!(
        "{}#{}",
        h.web().unwrap().url(),
        fragment(&[("token", h.token()), ("asset", name), ("cam", &cam_json(&cam)), ("time", &time.to_string())])
    );
    let r = page(b, &[&url, "done"]);
    assert_eq!(r["error"], serde_json::Value::Null, "{}: page error: {}", name, r["error"]);
    let cpu = snerf_asset::render(asset, &cam, time);
    // The picture has content (a match of two blank images would mean nothing).
    let bg = &asset.header.background;
    let shown = cpu.rgb.chunks(3).filter(|p| (0..3).any(|c| (p[c] - bg[c]).abs() > 0.02)).count();
    assert!(shown * 10 > cpu.rgb.len() / 3, "{}: only {} pixels differ from the background", name, shown);
    let d = mean_abs_diff(r["lastRender"]["rgba"].as_array().unwrap(), &cpu);
    eprintln!("{} at t={}: web vs CPU reference mean |diff| {:?}", name, time, d);
    assert!(d.iter().all(|&x| x <= 2.0 / 255.0), "{} at t={}: mean |diff| {:?} > 2/255", name, time, d);
    r
}

#[test]
fn a_4d_asset_at_two_times_an_unbounded_and_a_forward_scene_render_like_the_cpu_reference() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-kinds");
    let state = TempDir::new("web-kinds-state");
    let moving = Asset::from_bytes(&write_asset(&dynamic_asset(16, 8, 0.9, 3, 21), dir.path(), "moving")).unwrap();
    let outdoor = Asset::from_bytes(&write_asset(&kind_asset(snerf_asset::Kind::Unbounded, 32, 8, 0.9, 4), dir.path(), "outdoor")).unwrap();
    let front = Asset::from_bytes(&write_asset(&kind_asset(snerf_asset::Kind::Forward, 32, 8, 0.9, 6), dir.path(), "front")).unwrap();
    let h = start(dir.path(), state.path());
    // Between keyframes 0 and 1 (blended), and between 1 and 2: different images.
    let cam = snerf_asset::orbit(&moving.header, 1, 0, 48, 32, 40.0);
    let (a, c) = (snerf_asset::render(&moving, &cam, 0.5), snerf_asset::render(&moving, &cam, 1.75));
    assert!(a.rgb.iter().zip(&c.rgb).any(|(x, y)| (x - y).abs() > 0.05), "the two times look the same");
    check_render(&b, &h, &moving, "moving", 0.5);
    check_render(&b, &h, &moving, "moving", 1.75);
    // As the baker's time codebook writes them: frame 3's cells point at frame 1's blocks.
    let mut cyc = dynamic_asset(16, 8, 0.9, 4, 33);
    cyc.grids[3] = cyc.grids[1].clone();
    let cycle = Asset::from_bytes(&write_asset(&cyc, dir.path(), "cycle")).unwrap();
    check_render(&b, &h, &cycle, "cycle", 2.5);
    let r = check_render(&b, &h, &outdoor, "outdoor", 0.0);
    let kinds: Vec<&str> = r["listing"].as_array().unwrap().iter().map(|e| e["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["object", "forward", "object", "unbounded"]);
    check_render(&b, &h, &front, "front", 0.0);
    h.shutdown();
}

#[test]
fn first_frame_comes_before_the_whole_asset_under_a_small_send_budget() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-progressive");
    let state = TempDir::new("web-progressive-state");
    let asset = static_asset(64, 8, 0.95, 9);
    write_asset(&asset, dir.path(), "big");
    // One data stream at a time and the smallest send window: the small parts go first and
    // are acknowledged before any block is sent.
    let limits = Limits {
        send_budget: 64 * 1024,
        max_streams: 1,
        batch_bytes: 16 * 1024,
        ..Limits::default()
    };
    let h = start_with(dir.path(), state.path(), limits);
    let r = check_render(&b, &h, &asset, "big", 0.0);
    let total = asset.header.atlas_blocks as u64;
    let first = &r["firstFrame"];
    eprintln!("first frame after {} ms with {} of {} blocks", r["firstFrameMs"], first["blocks"], total);
    assert_eq!(first["complete"], false, "{}", first);
    assert!(first["blocks"].as_u64().unwrap() < total, "{}", first);
    assert!(r["frames"].as_u64().unwrap() >= 2);
    h.shutdown();
}

/// One HTTP/1.1 request over `s`; the whole response as text.
async fn get<S: tokio::io::AsyncRead + tokio::io::AsyncWrite + Unpin>(mut s: S, host: &str, path: &str) -> String {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    s.write_all(format!("GET {path} HTTP/1.1\r\nHost: {host}\r\n\r\n").as_bytes()).await.unwrap();
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out).await;
    String::from_utf8_lossy(&out).into_owned()
}

#[test]
fn the_page_routes_serve_the_composed_shader_with_strict_headers_and_check_the_host() {
    let dir = TempDir::new("web-http");
    let state = TempDir::new("web-http-state");
    write_asset(&static_asset(16, 8, 0.9, 5), dir.path(), "scene");
    let h = start(dir.path(), state.path());
    let web = h.web().unwrap().clone();
    assert!(!web.https && web.url().starts_with("http://127.0.0.1:"));
    let host = format!("127.0.0.1:{}", web.addr.port());
    let rt = runtime();
    let tcp = || rt.block_on(tokio::net::TcpStream::connect(web.addr)).unwrap();
    let page = rt.block_on(get(tcp(), &host, "/"));
    assert!(page.starts_with("HTTP/1.1 200"), "{page}");
    assert!(page.contains("Content-Security-Policy: default-src 'none'; script-src 'self';"), "{page}");
    assert!(page.contains("src=\"/app.js\""), "{page}");
    // The shader the page runs is the one the native viewer composes.
    let wgsl = rt.block_on(get(tcp(), &host, "/march.wgsl?kind=2&dynamic=1&block=8"));
    let body = wgsl.split_once("\r\n\r\n").unwrap().1;
    assert_eq!(body, snerf_geometry::march::march_shader(2, true, 8, false));
    assert!(rt.block_on(get(tcp(), &host, "/march.wgsl?kind=7&dynamic=1&block=8")).starts_with("HTTP/1.1 400"));
    let cfg = rt.block_on(get(tcp(), &host, "/config.json"));
    let cfg: serde_json::Value = serde_json::from_str(cfg.split_once("\r\n\r\n").unwrap().1).unwrap();
    assert_eq!(cfg["webtransport"], format!("https://{host}/snerf/1"));
    assert_eq!(cfg["cert_hash"].as_str().unwrap().len(), 64);
    // Another name for this address (DNS rebinding) and unknown paths are refused.
    assert!(rt.block_on(get(tcp(), &format!("evil.example:{}", web.addr.port()), "/")).starts_with("HTTP/1.1 421"));
    assert!(rt.block_on(get(tcp(), &host, "/../../etc/passwd")).starts_with("HTTP/1.1 404"));
    h.shutdown();
}

#[test]
fn with_cert_and_key_the_page_is_served_over_https_with_that_certificate() {
    let dir = TempDir::new("web-https");
    let state = TempDir::new("web-https-state");
    write_asset(&static_asset(16, 8, 0.9, 5), dir.path(), "scene");
    let ck = rcgen::generate_simple_self_signed(vec!["localhost".to_string()]).unwrap();
    std::fs::write(state.join("c.pem"), ck.cert.pem()).unwrap();
    std::fs::write(state.join("k.pem"), ck.signing_key.serialize_pem()).unwrap();
    let mut o = ServeOptions::new(dir.path(), "127.0.0.1:0".parse().unwrap());
    o.state_dir = Some(state.path().to_path_buf());
    o.cert = Some(state.join("c.pem"));
    o.key = Some(state.join("k.pem"));
    o.quiet = true;
    o.web = Some("127.0.0.1:0".parse().unwrap());
    let h = snerf_stream::spawn(o).unwrap();
    let web = h.web().unwrap().clone();
    assert!(web.https && web.url().starts_with("https://") && web.cert_hash.is_none());
    let pin = snerf_stream::tls::parse_pin(h.fingerprint()).unwrap();
    let mut cfg = rustls::ClientConfig::builder_with_provider(snerf_stream::tls::provider())
        .with_protocol_versions(&[&rustls::version::TLS13])
        .unwrap()
        .dangerous()
        .with_custom_certificate_verifier(std::sync::Arc::new(snerf_stream::tls::PinVerifier::new(pin)))
        .with_no_client_auth();
    cfg.alpn_protocols = vec![b"http/1.1".to_vec()];
    let rt = runtime();
    let page = rt.block_on(async {
        let tcp = tokio::net::TcpStream::connect(web.addr).await.unwrap();
        let name = rustls::pki_types::ServerName::try_from("localhost").unwrap();
        let tls = tokio_rustls::TlsConnector::from(std::sync::Arc::new(cfg)).connect(name, tcp).await.unwrap();
        get(tls, &format!("localhost:{}", web.addr.port()), "/").await
    });
    assert!(page.starts_with("HTTP/1.1 200") && page.contains("src=\"/app.js\""), "{page}");
    // Plain HTTP gets no page from a TLS port.
    let plain = rt.block_on(async { get(tokio::net::TcpStream::connect(web.addr).await.unwrap(), "localhost", "/").await });
    assert!(!plain.contains("HTTP/1.1 200"), "{plain}");
    h.shutdown();
}
