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
    if std::env::var_os("SNERF_PAGE_LOG").is_some() {
        eprintln!("{}", stderr);
    }
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

fn base64_decode(s: &str) -> Vec<u8> {
    let val = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        _ => 63,
    } as u32;
    let b: Vec<u8> = s.bytes().filter(|&c| c != b'=').collect();
    let mut out = Vec::with_capacity(b.len() * 3 / 4);
    for ch in b.chunks(4) {
        let n = ch.iter().enumerate().fold(0u32, |a, (i, &c)| a | val(c) << (18 - 6 * i));
        out.extend_from_slice(&n.to_be_bytes()[1..ch.len()]);
    }
    out
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
    // Each entry has its start view as a thumbnail, the CPU reference's picture.
    let t = &listing[1]["thumb"];
    assert_eq!((t["width"].as_u64(), t["height"].as_u64()), (Some(64), Some(48)));
    let want = snerf_stream::thumbs::render(&dir.join("scene.snerf")).unwrap();
    assert_eq!(t["rgb"].as_str(), Some(want.rgb.as_str()));
    assert!(listing[0]["thumb"].is_object());
    // With an asset named, the listing is asked for only once the first frame is drawn (the
    // frame shows nothing of it; its session and thumbnails would take the CPU that frame's
    // shader compile needs).
    let marks = &r["marks"];
    let (listed, first) = (marks["listing"].as_f64().unwrap(), marks["firstFrame"].as_f64().unwrap());
    assert!(listed >= first, "listing asked for at {listed} ms, first frame at {first} ms");
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
    // What the canvas presents (shaders/present.wgsl, as in the native window) is that frame.
    let png = base64_decode(r["canvasPng"].as_str().expect("canvas screenshot"));
    let shot = image::load_from_memory(&png).unwrap().to_rgb8();
    if let Some(d) = std::env::var_os("SNERF_PAGE_DUMP") {
        shot.save(Path::new(&d).join("canvas.png")).unwrap();
        let cpu8: Vec<u8> = cpu.rgb.iter().map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8).collect();
        image::RgbImage::from_raw(64, 48, cpu8).unwrap().save(Path::new(&d).join("cpu.png")).unwrap();
    }
    assert_eq!(shot.dimensions(), (64, 48));
    let mut dc = [0f64; 3];
    for (i, p) in shot.pixels().enumerate() {
        for c in 0..3 {
            dc[c] += (p[c] as f64 / 255.0 - cpu.rgb[3 * i + c] as f64).abs() / (64.0 * 48.0);
        }
    }
    eprintln!("presented canvas vs CPU reference: mean |diff| per channel {:?}", dc);
    assert!(dc.iter().all(|&x| x <= 2.0 / 255.0), "canvas mean |diff| {:?} > 2/255", dc);
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
    // colour blended by density, as every dynamic bake is ("moving" above: as older ones)
    cyc.header.colour_by_density = true;
    let cycle = Asset::from_bytes(&write_asset(&cyc, dir.path(), "cycle")).unwrap();
    check_render(&b, &h, &cycle, "cycle", 2.5);
    // With motion (FORMAT.md "Motion"): a motion entry blended with a block (t = 0.5), and two
    // motion entries moving the reference by the interpolated offset (t = 2.5).
    let mut moved = motion_asset();
    moved.header.colour_by_density = true;
    let moved = Asset::from_bytes(&write_asset(&moved, dir.path(), "motion")).unwrap();
    // (the two blends draw this camera differently, so the page is seen to apply the key)
    let mut lerped = moved.clone();
    lerped.header.colour_by_density = false;
    let cam = snerf_asset::orbit(&moved.header, 1, 0, 48, 32, 40.0);
    let (x, y) = (snerf_asset::render(&moved, &cam, 0.5), snerf_asset::render(&lerped, &cam, 0.5));
    assert!(x.rgb.iter().zip(&y.rgb).any(|(p, q)| (p - q).abs() > 8.0 / 255.0), "blending by density changes nothing here");
    check_render(&b, &h, &moved, "motion", 0.5);
    check_render(&b, &h, &moved, "motion", 2.5);
    let r = check_render(&b, &h, &outdoor, "outdoor", 0.0);
    let kinds: Vec<&str> = r["listing"].as_array().unwrap().iter().map(|e| e["kind"].as_str().unwrap()).collect();
    assert_eq!(kinds, ["object", "forward", "object", "object", "unbounded"]);
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
    s.write_all(format!("GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n").as_bytes()).await.unwrap();
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out).await;
    String::from_utf8_lossy(&out).into_owned()
}

/// TLS over `tcp` that accepts only the certificate with SHA-256 `hash` (hex): what a browser
/// gets once a person has accepted that certificate.
async fn tls_over(tcp: tokio::net::TcpStream, hash: &str) -> std::io::Result<tokio_rustls::client::TlsStream<tokio::net::TcpStream>> {
    let pin = snerf_stream::tls::parse_pin(hash).unwrap();
    let mut cfg = rustls::ClientConfig::builder_with_provider(snerf_stream::tls::provider())
        .with_protocol_versions(&[&rustls::version::TLS13])
        .unwrap()
        .dangerous()
        .with_custom_certificate_verifier(std::sync::Arc::new(snerf_stream::tls::PinVerifier::new(pin)))
        .with_no_client_auth();
    cfg.alpn_protocols = vec![b"http/1.1".to_vec()];
    let name = rustls::pki_types::ServerName::try_from("localhost").unwrap();
    tokio_rustls::TlsConnector::from(std::sync::Arc::new(cfg)).connect(name, tcp).await
}

async fn try_tls_to(addr: std::net::SocketAddr, hash: &str) -> std::io::Result<tokio_rustls::client::TlsStream<tokio::net::TcpStream>> {
    tls_over(tokio::net::TcpStream::connect(addr).await?, hash).await
}

/// A TLS connection to the page (`tls_over`).
async fn tls_to(addr: std::net::SocketAddr, hash: &str) -> tokio_rustls::client::TlsStream<tokio::net::TcpStream> {
    try_tls_to(addr, hash).await.unwrap()
}

#[test]
fn the_page_routes_serve_the_composed_shader_over_https_with_strict_headers_and_check_the_host() {
    let dir = TempDir::new("web-http");
    let state = TempDir::new("web-http-state");
    write_asset(&static_asset(16, 8, 0.9, 5), dir.path(), "scene");
    let h = start(dir.path(), state.path());
    let web = h.web().unwrap().clone();
    // No certificate given: the page is HTTPS all the same, with the generated certificate.
    assert!(web.https && web.url().starts_with("https://127.0.0.1:"), "{}", web.url());
    let hash = web.cert_hash.clone().unwrap();
    let host = format!("127.0.0.1:{}", web.addr.port());
    let rt = runtime();
    let tls = || rt.block_on(tls_to(web.addr, &hash));
    let page = rt.block_on(get(tls(), &host, "/"));
    assert!(page.starts_with("HTTP/1.1 200"), "{page}");
    assert!(page.contains("Content-Security-Policy: default-src 'none'; script-src 'self';"), "{page}");
    assert!(page.contains("src=\"/app.js\""), "{page}");
    // The shader the page runs is the one the native viewer composes.
    let wgsl = rt.block_on(get(tls(), &host, "/march.wgsl?kind=2&dynamic=1&diffuse=1&block=8"));
    let body = wgsl.split_once("\r\n\r\n").unwrap().1;
    let variant = snerf_geometry::march::ShaderVariant { kind: 2, dynamic: true, diffuse: true, block: 8, hardware_filter: false };
    assert_eq!(body, snerf_geometry::march::march_shader(variant));
    assert!(rt.block_on(get(tls(), &host, "/march.wgsl?kind=7&dynamic=1&diffuse=0&block=8")).starts_with("HTTP/1.1 400"));
    let cfg = rt.block_on(get(tls(), &host, "/config.json"));
    let cfg: serde_json::Value = serde_json::from_str(cfg.split_once("\r\n\r\n").unwrap().1).unwrap();
    assert_eq!(cfg["webtransport"], format!("https://{host}/snerf/1"));
    assert_eq!(cfg["cert_hash"].as_str(), Some(hash.as_str()));
    // Another name for this address (DNS rebinding) and unknown paths are refused; the names
    // in the certificate are accepted.
    assert!(rt.block_on(get(tls(), &format!("evil.example:{}", web.addr.port()), "/")).starts_with("HTTP/1.1 421"));
    assert!(rt.block_on(get(tls(), &host, "/../../etc/passwd")).starts_with("HTTP/1.1 404"));
    assert!(rt.block_on(get(tls(), &format!("localhost:{}", web.addr.port()), "/")).starts_with("HTTP/1.1 200"));
    // Plain HTTP gets no page from the TLS port.
    let plain = rt.block_on(async { get(tokio::net::TcpStream::connect(web.addr).await.unwrap(), &host, "/").await });
    assert!(!plain.contains("HTTP/1.1 200"), "{plain}");
    // Keep-alive: three requests, one TLS handshake, answers in order.
    let answers = rt.block_on(async {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let mut s = tls_to(web.addr, &hash).await;
        let mut req = String::new();
        for p in ["/app.css", "/config.json"] {
            req += &format!("GET {p} HTTP/1.1\r\nHost: {host}\r\n\r\n");
        }
        req += &format!("HEAD /xr.js HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n");
        s.write_all(req.as_bytes()).await.unwrap();
        let mut out = Vec::new();
        let _ = s.read_to_end(&mut out).await;
        String::from_utf8_lossy(&out).into_owned()
    });
    assert_eq!(answers.matches("HTTP/1.1 200 OK").count(), 3, "{answers}");
    assert_eq!(answers.matches("Connection: keep-alive").count(), 2, "{answers}");
    assert!(answers.contains(snerf_stream::web::APP_CSS), "{answers}");
    assert!(answers.ends_with("Connection: close\r\n") || answers.ends_with("\r\n\r\n"), "HEAD has no body: {answers}");
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
    assert!(web.https && web.url().starts_with("https://") && web.cert_hash.is_none() && web.cert_names.is_empty());
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

/// A camera from the page's JSON ({c2w rows, fx, fy, cx, cy, width, height}).
fn cam_from_json(v: &serde_json::Value) -> snerf_asset::Camera {
    let f = |k: &str| v[k].as_f64().unwrap() as f32;
    let mut c2w = [[0f32; 4]; 3];
    for (i, row) in c2w.iter_mut().enumerate() {
        for (j, x) in row.iter_mut().enumerate() {
            *x = v["c2w"][i][j].as_f64().unwrap() as f32;
        }
    }
    snerf_asset::Camera {
        c2w,
        fx: f("fx"),
        fy: f("fy"),
        cx: f("cx"),
        cy: f("cy"),
        width: v["width"].as_u64().unwrap() as u32,
        height: v["height"].as_u64().unwrap() as u32,
    }
}

fn vec3(v: &serde_json::Value) -> [f64; 3] {
    [0, 1, 2].map(|i| v[i].as_f64().unwrap())
}

fn dist3(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// World position of an eye camera.
fn eye_pos(cam: &snerf_asset::Camera) -> [f64; 3] {
    [0, 1, 2].map(|i| cam.c2w[i][3] as f64)
}

/// World direction of a local-floor direction under the page's placement (rig at rest).
fn place_dir(place: &serde_json::Value, d: [f64; 3]) -> [f64; 3] {
    let b = |c: usize| vec3(&place["B"][c]);
    let (x, y, z) = (b(0), b(1), b(2));
    [0, 1, 2].map(|i| x[i] * d[0] + y[i] * d[1] + z[i] * d[2])
}

/// Every eye of a snapshot: its marched image against the CPU reference at the eye's camera,
/// and what the WebGL layer shows against the marched image. Returns the eye cameras.
fn check_eyes(snap: &serde_json::Value, asset: &Asset, what: &str) -> Vec<snerf_asset::Camera> {
    assert_eq!(snap["error"], serde_json::Value::Null, "{what}: {}", snap["error"]);
    let eyes = snap["eyes"].as_array().unwrap();
    assert_eq!(eyes.len(), 2, "{what}: both eyes are drawn");
    let mut cams = Vec::new();
    for (i, e) in eyes.iter().enumerate() {
        let cam = cam_from_json(&e["cam"]);
        // The intrinsics are the XR view's projection for this viewport, as the native
        // per-eye code (`Pinhole::from_projection`, what `snerf view --stereo` uses) reads it.
        let mut p = [0f32; 16];
        for (k, x) in e["projection"].as_array().unwrap().iter().enumerate() {
            p[k] = x.as_f64().unwrap() as f32;
        }
        let native = snerf_asset::Camera::from_projection(&p, cam.c2w, cam.width, cam.height);
        for (a, b) in [(cam.fx, native.fx), (cam.fy, native.fy), (cam.cx, native.cx), (cam.cy, native.cy)] {
            assert!((a - b).abs() < 1e-3, "{what} eye {i}: intrinsics {a} vs native {b}");
        }
        let cpu = snerf_asset::render(asset, &cam, snap["time"].as_f64().unwrap_or(0.0) as f32);
        let rgba: Vec<serde_json::Value> = e["rgba"].as_array().unwrap().clone();
        let d = mean_abs_diff(&rgba, &cpu);
        eprintln!("{what} eye {i} ({}x{}): marched vs CPU reference mean |diff| {:?}", cam.width, cam.height, d);
        assert!(d.iter().all(|&x| x <= 2.0 / 255.0), "{what} eye {i}: mean |diff| {:?} > 2/255", d);
        // The layer's pixels (GL rows bottom up) against the marched image.
        let gl: Vec<f64> = e["gl"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap() / 255.0).collect();
        let vp: Vec<u64> = e["viewport"].as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).collect();
        assert_eq!((vp[2], vp[3]), (cam.width as u64, cam.height as u64), "{what} eye {i}: render scale 1 under capture");
        let (w, h) = (vp[2] as usize, vp[3] as usize);
        let mut dg = 0f64;
        for y in 0..h {
            for x in 0..w {
                let src = 4 * ((h - 1 - y) * w + x);
                for c in 0..3 {
                    dg += (gl[4 * (y * w + x) + c] - rgba[src + c].as_f64().unwrap().clamp(0.0, 1.0)).abs();
                }
            }
        }
        dg /= (w * h * 3) as f64;
        eprintln!("{what} eye {i}: XR layer vs marched mean |diff| {dg}");
        assert!(dg <= 2.0 / 255.0, "{what} eye {i}: the XR layer shows something else ({dg})");
        cams.push(cam);
    }
    cams
}

/// iwer's build under the test assets, or None after saying why (panics under CI).
fn iwer(b: &(PathBuf, PathBuf, PathBuf)) -> Option<PathBuf> {
    let iwer = b.2.join("../iwer/build/iwer.min.js");
    if iwer.exists() {
        return Some(iwer);
    }
    assert!(std::env::var("SNERF_REQUIRE_BROWSER").as_deref() != Ok("1"), "no iwer at {} (.ci/run installs it)", iwer.display());
    eprintln!("skipping the immersive test: no iwer at {}", iwer.display());
    None
}

/// Run tests/web/xr.mjs on `url` with extra arguments; its JSON report.
fn xr_page(b: &(PathBuf, PathBuf, PathBuf), url: &str, extra: &[&str]) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web/xr.mjs");
    let out = Command::new(&b.0).arg(&script).arg(b.2.join("../..")).arg(url).args(extra).env("SNERF_CHROMIUM", &b.1).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    if std::env::var_os("SNERF_PAGE_LOG").is_some() {
        eprintln!("{stderr}");
    }
    assert!(out.status.success(), "xr.mjs failed: {stderr}");
    serde_json::from_str(String::from_utf8_lossy(&out.stdout).trim()).unwrap()
}

#[test]
fn immersive_mode_on_an_emulated_quest_3_draws_both_eyes_like_the_cpu_reference_and_follows_the_headset() {
    let Some(b) = browser() else { return };
    if iwer(&b).is_none() {
        return;
    }
    let dir = TempDir::new("web-xr");
    let state = TempDir::new("web-xr-state");
    let asset = static_asset(32, 8, 0.8, 11);
    write_asset(&asset, dir.path(), "scene");
    let h = start(dir.path(), state.path());
    let url = format!("{}#{}", h.web().unwrap().url(), fragment(&[("token", h.token()), ("asset", "scene"), ("capture", "1")]));
    let r = xr_page(&b, &url, &[]);
    let before = &r["before"];
    let cams0 = check_eyes(before, &asset, "before");
    eprintln!("first immersive frame {} ms after Enter VR", before["firstFrameMs"]);
    // The object is in view (the comparison means something).
    let cpu = snerf_asset::render(&asset, &cams0[0], 0.0);
    let bg = asset.header.background;
    let shown = cpu.rgb.chunks(3).filter(|p| (0..3).any(|c| (p[c] - bg[c]).abs() > 0.02)).count();
    assert!(shown * 20 > cpu.rgb.len() / 3, "the object is not in front of the user ({shown} pixels)");
    let place = &before["place"];
    let k = place["k"].as_f64().unwrap();
    // The eyes are an IPD apart (iwer's 63 mm), in world units.
    let sep = dist3(eye_pos(&cams0[0]), eye_pos(&cams0[1]));
    assert!((sep / k - 0.063).abs() < 1e-3, "eye separation {} m", sep / k);
    // An object floats at arm's length: its centre 0.6 m ahead of and 0.3 m below the head.
    let centre = vec3(&serde_json::json!(asset.header.space.center));
    let mid = [0, 1, 2].map(|i| (eye_pos(&cams0[0])[i] + eye_pos(&cams0[1])[i]) / 2.0);
    let want = (0.6f64.powi(2) + 0.3f64.powi(2)).sqrt();
    assert!((dist3(centre, mid) / k - want).abs() < 1e-3, "object at {} m", dist3(centre, mid) / k);
    // Moving the headset 30 cm right and 20 cm back moves both eyes by that, as placed.
    let cams1 = check_eyes(&r["moved"], &asset, "moved");
    let d = place_dir(place, [0.3, 0.0, 0.2]).map(|x| x * k);
    for (a, b_) in cams0.iter().zip(&cams1) {
        let moved = [0, 1, 2].map(|i| eye_pos(b_)[i] - eye_pos(a)[i]);
        assert!(dist3(moved, d) / k < 1e-3, "eye moved {:?}, expected {:?}", moved, d);
    }
    // Turning the head 90 degrees left: both eyes look along local-floor -x.
    let cams2 = check_eyes(&r["turned"], &asset, "turned");
    let left = place_dir(place, [-1.0, 0.0, 0.0]);
    for c in &cams2 {
        let fwd = [0, 1, 2].map(|i| -c.c2w[i][2] as f64);
        assert!(dist3(fwd, left) < 1e-3, "forward {:?}, expected {:?}", fwd, left);
    }
    assert!(r["turned"]["posesSent"].as_u64().unwrap() > before["posesSent"].as_u64().unwrap(), "head poses go to the server");
    // The left thumbstick pushed forward walks the user where the head looks (-x).
    let p0 = vec3(&r["turned"]["rig"]["p"]);
    let p1 = vec3(&r["walked"]["rig"]["p"]);
    let step = [p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]];
    let len = dist3(step, [0.0; 3]);
    assert!(len > 0.05 && -step[0] / len > 0.999, "walked {:?}", step);
    let cams3 = check_eyes(&r["walked"], &asset, "walked");
    let moved = [0, 1, 2].map(|i| eye_pos(&cams3[0])[i] - eye_pos(&cams2[0])[i]);
    assert!(dist3(moved, place_dir(place, step).map(|x| x * k)) / k < 1e-3, "the eyes follow the walk");
    // The right thumbstick snaps the turn by 30 degrees, once per push, about the head.
    let (y0, y1) = (r["walked"]["rig"]["yaw"].as_f64().unwrap(), r["snapped"]["rig"]["yaw"].as_f64().unwrap());
    assert!((y1 - y0 + std::f64::consts::FRAC_PI_6).abs() < 1e-6, "snap turn {} -> {}", y0, y1);
    let cams4 = check_eyes(&r["snapped"], &asset, "snapped");
    let mid = |c: &[snerf_asset::Camera]| [0, 1, 2].map(|i| (eye_pos(&c[0])[i] + eye_pos(&c[1])[i]) / 2.0);
    assert!(dist3(mid(&cams3), mid(&cams4)) / k < 1e-3, "the head stays put through a snap turn");
    // Grip held while the hand rises 20 cm: the scene rises with it (the eyes sink in it).
    let cams5 = check_eyes(&r["gripped"], &asset, "gripped");
    let moved = [0, 1, 2].map(|i| mid(&cams5)[i] - mid(&cams4)[i]);
    let want = place_dir(place, [0.0, -0.2, 0.0]).map(|x| x * k);
    assert!(dist3(moved, want) / k < 0.01, "grip drag moved the eyes {:?}, expected {:?}", moved, want);
    assert!(h.stats().pose_updates.load(Ordering::Relaxed) > 0);
    h.shutdown();
}

/// An unbounded scene whose inner ball (uniform cells, |p| < 1) is full of blocks, and whose
/// start view stands inside it, at (0, 0, 0.3) looking down -z: blocks all around the
/// viewer, all the same size.
fn inside_asset() -> Asset {
    let mut asset = kind_asset(snerf_asset::Kind::Unbounded, 96, 8, 0.5, 12);
    asset.header.view = Some(snerf_geometry::camera::Orbit::Around { center: [0.0; 3], up: [0.0, 1.0, 0.0], start: [0.0, 0.0, 1.0], radius: 0.3, elevation: 0.0 });
    asset
}

/// Whether a block's bounding sphere meets a pose's view cone: this test's own geometry.
fn in_cone(blk: &snerf_stream::plan::BlkEntry, p: &snerf_stream::Pose) -> bool {
    let d = [0, 1, 2].map(|i| (blk.centre[i] - p.eye[i]) as f64);
    let f = [0, 1, 2].map(|i| p.forward[i] as f64);
    let (ld, lf) = (dist3(d, [0.0; 3]), dist3(f, [0.0; 3]));
    if ld <= blk.radius as f64 {
        return true;
    }
    let ang = ((d[0] * f[0] + d[1] * f[1] + d[2] * f[2]) / (ld * lf)).clamp(-1.0, 1.0).acos();
    ang - (blk.radius as f64 / ld).min(1.0).asin() <= (p.fov_deg as f64 / 2.0).to_radians() + 1e-4
}

#[test]
fn the_blocks_in_view_arrive_first() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-inview");
    let state = TempDir::new("web-inview-state");
    let asset = inside_asset();
    let bytes = write_asset(&asset, dir.path(), "around");
    let limits = Limits { send_budget: 64 * 1024, max_streams: 1, batch_bytes: 16 * 1024, log_sends: true, ..Limits::default() };
    let h = start_with(dir.path(), state.path(), limits);
    // Inside the scene looking down -z: the page sends this pose in its hello.
    let cam = snerf_asset::Camera::from_fov([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.3]], 48, 48, 60.0);
    let url = format!("{}#{}", h.web().unwrap().url(), fragment(&[("token", h.token()), ("asset", "around"), ("cam", &cam_json(&cam))]));
    let r = page(&b, &[&url, "done"]);
    assert_eq!(r["error"], serde_json::Value::Null, "{}", r["error"]);
    let served = snerf_stream::plan::ServedAsset::from_bytes("around", dir.path(), bytes).unwrap();
    let log = h.stats().send_log.lock().unwrap().clone();
    let pose = log[0].pose.expect("the first batch was ordered for the hello's pose");
    assert!(pose.forward[2] < -0.99 && (pose.fov_deg - 60.0).abs() < 0.5, "{:?}", pose);
    let needed: std::collections::HashSet<u32> = served.blks.iter().filter(|b| in_cone(b, &pose)).map(|b| b.chunk).collect();
    assert!(needed.len() >= 4 && needed.len() * 3 < served.blks.len(), "{} of {} blocks in view", needed.len(), served.blks.len());
    // What the page received (chunk indices), stream by stream in the order it accepted the
    // streams, in order within each: the first |needed| are exactly those in view. (The page
    // reads streams concurrently, so where two are in flight their records may be applied
    // interleaved: the order blocks were applied can swap a batch's last block with the
    // next batch's first.)
    let applied: Vec<u32> = r["arrivals"].as_array().unwrap().iter().map(|x| x.as_u64().unwrap() as u32).collect();
    let streams: Vec<u64> = r["arrivalStreams"].as_array().unwrap().iter().map(|x| x.as_u64().unwrap()).collect();
    assert_eq!(applied.len(), served.blks.len());
    assert_eq!(streams.len(), applied.len());
    let mut by_stream: Vec<(u64, u32)> = streams.iter().copied().zip(applied.iter().copied()).collect();
    by_stream.sort_by_key(|a| a.0); // stable: keeps the order within a stream
    let arrivals: Vec<u32> = by_stream.iter().map(|a| a.1).collect();
    let first: std::collections::HashSet<u32> = arrivals[..needed.len()].iter().copied().collect();
    let first_applied: std::collections::HashSet<u32> = applied[..needed.len()].iter().copied().collect();
    eprintln!(
        "{} of {} blocks in view; the first {} received: {} of them in view ({} of the first applied)",
        needed.len(),
        served.blks.len(),
        needed.len(),
        first.intersection(&needed).count(),
        first_applied.intersection(&needed).count()
    );
    if first != needed {
        // Which side reordered: the server's send order, and the poses its batches were
        // ordered for (a later pose than the hello's would reorder what is left).
        let sent: Vec<u32> = log.iter().flat_map(|b| b.chunks.iter().copied()).collect();
        let sent_first: std::collections::HashSet<u32> = sent.iter().take(needed.len()).copied().collect();
        let mut poses: Vec<String> = log.iter().map(|b| format!("{:?}", b.pose)).collect();
        poses.dedup();
        eprintln!("server sent {} in view among its first {}; batch poses: {poses:?}", sent_first.intersection(&needed).count(), needed.len());
    }
    assert_eq!(first, needed);
    h.shutdown();
}

#[test]
fn the_head_pose_reorders_what_the_server_sends_next() {
    let Some(b) = browser() else { return };
    if iwer(&b).is_none() {
        return;
    }
    let dir = TempDir::new("web-xr-order");
    let state = TempDir::new("web-xr-order-state");
    let asset = inside_asset();
    let bytes = write_asset(&asset, dir.path(), "around");
    // Small batches, one stream at a time, a batch chosen only once the last is acknowledged,
    // paced at 150 kB/s: the stream lasts long enough to turn around in, and each batch
    // follows the latest pose.
    let limits = Limits {
        send_budget: 64 * 1024,
        max_streams: 1,
        batch_bytes: 16 * 1024,
        max_rate: Some(1.5e5),
        log_sends: true,
        ..Limits::default()
    };
    let h = start_with(dir.path(), state.path(), limits);
    let url = format!("{}#{}", h.web().unwrap().url(), fragment(&[("token", h.token()), ("asset", "around")]));
    let r = xr_page(&b, &url, &["192", "96", "early"]);
    eprintln!("{}", r);
    assert_eq!(r["end"]["state"], "done", "{}", r);
    assert_eq!(r["end"]["xr"]["error"], serde_json::Value::Null);
    let served = snerf_stream::plan::ServedAsset::from_bytes("around", dir.path(), bytes).unwrap();
    let chunk_block: std::collections::HashMap<u32, usize> = served.blks.iter().enumerate().map(|(i, b)| (b.chunk, i)).collect();
    let in_cone = |p: &snerf_stream::Pose, c: u32| in_cone(&served.blks[chunk_block[&c]], p);
    let log = h.stats().send_log.lock().unwrap().clone();
    let with_pose: Vec<_> = log.iter().filter_map(|b| b.pose.map(|p| (p, b.chunks.clone()))).collect();
    assert!(!with_pose.is_empty(), "no batch was ordered for a pose");
    let mut seen: Vec<[f32; 3]> = Vec::new();
    for (p, _) in &with_pose {
        if seen.last() != Some(&p.forward) {
            seen.push(p.forward);
        }
    }
    eprintln!("forwards the batches were ordered for: {:?}; {} pose updates, {} bad datagrams", seen, h.stats().pose_updates.load(Ordering::Relaxed), h.stats().bad_datagrams.load(Ordering::Relaxed));
    // The first batch ordered for the turned-around head: the last forward, reversed from
    // the one before it (the flat page's pose comes first, then the XR head's).
    assert!(seen.len() >= 2, "the head pose never changed the order");
    let (fa, fb) = (seen[seen.len() - 2], seen[seen.len() - 1]);
    let d: f32 = (0..3).map(|i| fa[i] * fb[i]).sum();
    assert!(d < -0.9, "the last two forwards {:?} -> {:?} are not a turn around", fa, fb);
    let turned = with_pose.iter().position(|(p, _)| p.forward == fb).unwrap();
    let pose = with_pose[turned].0;
    // Every block still unsent at the turn that the new view needs...
    let sent_before: std::collections::HashSet<u32> = log.iter().take_while(|b| b.pose.is_none_or(|p| p.forward != pose.forward)).flat_map(|b| b.chunks.clone()).collect();
    let needed: Vec<u32> = served.blks.iter().map(|b| b.chunk).filter(|c| !sent_before.contains(c) && in_cone(&pose, *c)).collect();
    let all_in = served.blks.iter().filter(|b| in_cone(&pose, b.chunk)).count();
    eprintln!("turned pose {:?}: {} blocks in its cone of {}, {} sent before", pose, all_in, served.blks.len(), sent_before.len());
    let after: Vec<u32> = with_pose[turned..].iter().flat_map(|(_, c)| c.clone()).collect();
    eprintln!("{} batches before the turn, {} blocks the turned view needs, {} sent after", turned, needed.len(), after.len());
    assert!(needed.len() >= 4, "the turned view needs too few unsent blocks ({}) to tell", needed.len());
    // ...is sent next, before any block it does not need.
    let next: std::collections::HashSet<u32> = after.iter().take(needed.len()).copied().collect();
    let hits = needed.iter().filter(|c| next.contains(c)).count();
    assert_eq!(hits, needed.len(), "of the next {} blocks sent, only {} are in the turned view", needed.len(), hits);
    // And the turn mattered: most of those blocks were not in the view before the turn.
    let first = with_pose[turned - 1].0;
    let also_before = needed.iter().filter(|&&c| in_cone(&first, c)).count();
    assert!(also_before * 2 < needed.len(), "{} of {} were in view before the turn too", also_before, needed.len());
    h.shutdown();
}

#[test]
fn traversal_names_and_malformed_messages_are_refused_while_another_page_downloads() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-malformed");
    let state = TempDir::new("web-malformed-state");
    let asset = static_asset(64, 8, 0.95, 9);
    let bytes = write_asset(&asset, dir.path(), "scene");
    // Paced so the download is still running while the probes come and go.
    let limits = Limits { max_rate: Some(1.0e6), ..Limits::default() };
    let h = start_with(dir.path(), state.path(), limits);
    let web = h.web().unwrap().url();
    let download = format!("{}#{}", web, fragment(&[("token", h.token()), ("asset", "scene")]));
    let probe = format!("{}#{}", web, fragment(&[("token", h.token())]));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web/refuse.mjs");
    let out = Command::new(&b.0).arg(&script).arg(b.2.join("../..")).args([&download, &probe, h.token()]).env("SNERF_CHROMIUM", &b.1).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "refuse.mjs failed: {stderr}");
    let r: serde_json::Value = serde_json::from_str(String::from_utf8_lossy(&out.stdout).trim()).unwrap();
    for p in r["probes"].as_array().unwrap() {
        eprintln!("{}: {}", p["name"], p["closed"]);
        assert_eq!(p["connected"], true, "{p}");
        assert_eq!((p["dataStreams"].as_u64(), p["dataBytes"].as_u64()), (Some(0), Some(0)), "{p}: data was sent");
        assert!(!p["control"].as_str().unwrap().contains("welcome"), "{p}: welcomed");
        assert!(p["closed"].as_str().unwrap() != "still open", "{p}: the session stayed open");
    }
    // The other page's download finished, byte for byte, and got every byte the server sent.
    let d = &r["download"];
    assert_eq!(d["state"], "done", "{d}");
    assert_eq!(d["sha256"], snerf_stream::proto::to_hex(&Sha256::digest(&bytes)).as_str());
    assert_eq!(h.stats().bytes_sent.load(Ordering::Relaxed), d["bytes"].as_u64().unwrap());
    assert!(h.stats().bad_datagrams.load(Ordering::Relaxed) <= 1);
    assert!(h.stats().protocol_errors.load(Ordering::Relaxed) >= 3);
    assert!(h.stats().unauthorized.load(Ordering::Relaxed) >= 1);
    h.shutdown();
}

#[test]
fn the_generated_certificate_is_rotated_and_pages_keep_connecting() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-rotate");
    let state = TempDir::new("web-rotate-state");
    let asset = static_asset(16, 8, 0.9, 5);
    let bytes = write_asset(&asset, dir.path(), "scene");
    let h = start_with(dir.path(), state.path(), Limits { web_cert_rotate: std::time::Duration::from_millis(3000), ..Limits::default() });
    // Rotation every 3 s. A rotation between the page's read of /config.json and its handshake
    // fails that handshake; the page then reads the new hash and tries again (up to 3 times),
    // which is what this test exercises whenever a rotation lands in that window.
    let web = h.web().unwrap().clone();
    let first = web.cert_hash.clone().unwrap();
    let host = format!("127.0.0.1:{}", web.addr.port());
    let rt = runtime();
    // A page connection made before the rotation: the one a page loaded from.
    let old = rt.block_on(tls_to(web.addr, &first));
    let t0 = std::time::Instant::now();
    while h.stats().cert_rotations.load(Ordering::Relaxed) == 0 {
        assert!(t0.elapsed().as_secs() < 30, "no rotation");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let now = web.current_cert_hash().unwrap();
    assert_ne!(now, first);
    // On that connection too, /config.json hands out the hash in force, not the connection's
    // own: the page pins it for the sessions it opens later (a resume, the listing).
    let cfg = rt.block_on(get(old, &host, "/config.json"));
    let cfg: serde_json::Value = serde_json::from_str(cfg.split_once("\r\n\r\n").expect("an answer on the old connection").1).unwrap();
    assert_ne!(cfg["cert_hash"].as_str().unwrap(), first, "the old connection hands out the old hash");
    // /config.json hands out the new hash, and a page connects with it.
    // (Over HTTPS pinned to the hash in force; a rotation in between is retried.)
    let cfg = (0..3)
        .find_map(|_| {
            let pin = web.current_cert_hash().unwrap();
            rt.block_on(async {
                let s = tokio::time::timeout(std::time::Duration::from_secs(2), try_tls_to(web.addr, &pin)).await.ok()?.ok()?;
                Some(get(s, &host, "/config.json").await)
            })
        })
        .expect("no TLS connection with the current certificate");
    let cfg: serde_json::Value = serde_json::from_str(cfg.split_once("\r\n\r\n").unwrap().1).unwrap();
    assert_ne!(cfg["cert_hash"].as_str().unwrap(), first);
    let url = format!("{}#{}", web.url(), fragment(&[("token", h.token()), ("asset", "scene")]));
    let r = page(&b, &[&url, "done"]);
    eprintln!("handshakes retried after a rotation: {}", r["rotationRetries"]);
    assert_eq!(r["error"], serde_json::Value::Null, "{}", r["error"]);
    assert_eq!(r["sha256"], snerf_stream::proto::to_hex(&Sha256::digest(&bytes)).as_str());
    h.shutdown();
}

#[test]
fn a_page_resumes_when_the_server_restarts_mid_stream() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-resume");
    let state = TempDir::new("web-resume-state");
    let asset = static_asset(64, 8, 0.95, 9);
    let bytes = write_asset(&asset, dir.path(), "scene");
    // Paced, so the server can be stopped with part of the asset sent.
    let a = start_with(dir.path(), state.path(), Limits { max_rate: Some(3.0e5), ..Limits::default() });
    let web = a.web().unwrap().clone();
    let url = format!("{}#{}", web.url(), fragment(&[("token", a.token()), ("asset", "scene")]));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web/page.mjs");
    let child = Command::new(&b.0)
        .arg(&script)
        .arg(&b.2)
        .args([url.as_str(), "done"])
        .env("SNERF_CHROMIUM", &b.1)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while a.stats().bytes_sent.load(Ordering::Relaxed) < bytes.len() as u64 / 3 {
        assert!(t0.elapsed().as_secs() < 120, "the download did not start");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let sent_a = a.stats().bytes_sent.load(Ordering::Relaxed);
    a.shutdown();
    // The same identity (state) and web port; the page reconnects and asks for the rest.
    let mut o = ServeOptions::new(dir.path(), "127.0.0.1:0".parse().unwrap());
    o.state_dir = Some(state.path().to_path_buf());
    o.quiet = true;
    o.web = Some(web.addr);
    let bsrv = snerf_stream::spawn(o).unwrap();
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "page.mjs failed: {stderr}");
    let r: serde_json::Value = serde_json::from_str(String::from_utf8_lossy(&out.stdout).trim()).unwrap();
    assert_eq!(r["error"], serde_json::Value::Null, "{}", r["error"]);
    assert_eq!(r["sha256"], snerf_stream::proto::to_hex(&Sha256::digest(&bytes)).as_str());
    assert!(r["resumes"].as_u64().unwrap() >= 1, "{}", r["resumes"]);
    assert_eq!(r["lastResume"]["resumed"], true);
    // The second server sends exactly the chunks the page did not hold when it resumed. (What
    // the first server wrote is not what the page holds: records still in flight, or not yet
    // read off their stream by a busy page, die with the first session.)
    let sent_b = bsrv.stats().bytes_sent.load(Ordering::Relaxed);
    let (held, sending) = (r["lastResume"]["held"].as_u64().unwrap(), r["lastResume"]["sending_chunks"].as_u64().unwrap());
    let chunks = r["asset"]["chunks"].as_u64().unwrap();
    eprintln!("first server sent {sent_a} bytes, the second {sent_b}, of {}; the page held {held} of {chunks} chunks and was sent {sending}", bytes.len());
    assert!(held >= 1, "the page held nothing when it resumed");
    assert_eq!(held + sending, chunks, "the second server did not send only the rest");
    assert!(sent_b < bytes.len() as u64, "the second server sent {sent_b} bytes: the whole asset");
    bsrv.shutdown();
}

/// Where the ray of pixel (x, y) of camera `cur` lands in the image of camera `old`: pixel
/// coordinates (x + 0.5, y + 0.5 at a pixel's centre), or None behind `old`. Directions only
/// (rotational reprojection): the two cameras' positions do not enter.
fn reproject_px(cur: &snerf_asset::Camera, old: &snerf_asset::Camera, x: usize, y: usize) -> Option<[f64; 2]> {
    let d = [(x as f64 + 0.5 - cur.cx as f64) / cur.fx as f64, -(y as f64 + 0.5 - cur.cy as f64) / cur.fy as f64, -1.0];
    let w: [f64; 3] = [0, 1, 2].map(|i| (0..3).map(|j| cur.c2w[i][j] as f64 * d[j]).sum());
    let e: [f64; 3] = [0, 1, 2].map(|j| (0..3).map(|i| old.c2w[i][j] as f64 * w[i]).sum());
    (e[2] < 0.0).then(|| [old.cx as f64 + old.fx as f64 * e[0] / -e[2], old.cy as f64 - old.fy as f64 * e[1] / -e[2]])
}

/// Bilinear sample (GL's: texel centres at +0.5) of an RGB frame at pixel coordinates `p`.
fn bilinear(f: &snerf_asset::Frame, p: [f64; 2], c: usize) -> f64 {
    let (w, h) = (f.width as usize, f.height as usize);
    let (x, y) = (p[0] - 0.5, p[1] - 0.5);
    let (x0, y0) = (x.floor(), y.floor());
    let (tx, ty) = (x - x0, y - y0);
    let at = |i: f64, j: f64| {
        let (i, j) = ((i as isize).clamp(0, w as isize - 1) as usize, (j as isize).clamp(0, h as isize - 1) as usize);
        (f.rgb[3 * (j * w + i) + c] as f64).clamp(0.0, 1.0)
    };
    (1.0 - ty) * ((1.0 - tx) * at(x0, y0) + tx * at(x0 + 1.0, y0)) + ty * ((1.0 - tx) * at(x0, y0 + 1.0) + tx * at(x0 + 1.0, y0 + 1.0))
}

/// The page held at its first march (`xrhold`: what it does while a march is in flight), the
/// head turned by 8° of yaw then 3° of pitch: the presented layer against the CPU reference
/// at the new eye cameras. `run(url, args)` runs tests/web/xr.mjs. Returns the page's backend.
fn check_turn_reprojected(run: &dyn Fn(&str, &[&str]) -> serde_json::Value, what: &str) -> String {
    let dir = TempDir::new("web-xr-warp");
    let state = TempDir::new("web-xr-warp-state");
    let asset = static_asset(32, 8, 0.8, 11);
    write_asset(&asset, dir.path(), "scene");
    let h = start(dir.path(), state.path());
    let url = format!("{}#{}", h.web().unwrap().url(), fragment(&[("token", h.token()), ("asset", "scene"), ("capture", "1"), ("xrhold", "1")]));
    let (yaw, pitch) = (8.0f64, 3.0f64);
    let r = run(&url, &["384", "192", "hold", &yaw.to_string(), &pitch.to_string()]);
    let before = &r["before"];
    // The march: like the CPU reference, and the layer showed it as it was at its own pose.
    let old_cams = check_eyes(before, &asset, &format!("{what} before the turn"));
    let held = &r["held"];
    assert_eq!((held["marches"].as_u64(), held["marchesNow"].as_u64()), (Some(1), Some(1)), "{what}: no second march: {held}");
    let place = &before["place"];
    let (ya, pa) = (yaw.to_radians(), pitch.to_radians());
    let want_fwd = place_dir(place, [-pa.cos() * ya.sin(), pa.sin(), -pa.cos() * ya.cos()]);
    for (i, old) in old_cams.iter().enumerate() {
        let e = &held["eyes"][i];
        let cur = cam_from_json(&e["cam"]);
        let fwd = [0, 1, 2].map(|k| -cur.c2w[k][2] as f64);
        assert!(dist3(fwd, want_fwd) < 1e-3, "{what} eye {i} presented at forward {fwd:?}, the head turned to {want_fwd:?}");
        let (w, hh) = (cur.width as usize, cur.height as usize);
        assert_eq!((w, hh), (old.width as usize, old.height as usize));
        let now = snerf_asset::render(&asset, &cur, 0.0);
        let then = snerf_asset::render(&asset, old, 0.0);
        // The new orientation seen from the old eye position: what rotation alone can reach.
        let mut turned = cur.clone();
        for k in 0..3 {
            turned.c2w[k][3] = old.c2w[k][3];
        }
        let rot = snerf_asset::render(&asset, &turned, 0.0);
        let gl: Vec<f64> = e["gl"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap() / 255.0).collect();
        // What the layer showed at the march, drawn again now: the old behaviour (no reprojection).
        let stale: Vec<f64> = before["eyes"][i]["gl"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap() / 255.0).collect();
        // Compared where the reprojection has the last image's own samples on all sides (the
        // rest is the edge clamp), over the pixels where the scene shows (not the black
        // background): n pixels, sums per channel of
        // |layer - CPU now|, |stale - CPU now|, |bilinear(CPU then) - CPU now| (what exact
        // rotational reprojection of an exact image would be off by: resampling, and the eye's
        // few-mm translation in the turn, which rotation leaves as it is) and
        // |layer - bilinear(CPU then)| (the reprojection itself).
        let (mut n, mut d_now, mut d_stale, mut d_ref, mut d_warp, mut d_rot) = (0usize, 0f64, 0f64, 0f64, 0f64, 0f64);
        for y in 0..hh {
            for x in 0..w {
                let Some(p) = reproject_px(&cur, old, x, y) else { continue };
                if p[0] < 0.5 || p[1] < 0.5 || p[0] > w as f64 - 0.5 || p[1] > hh as f64 - 0.5 {
                    continue;
                }
                let src = 4 * ((hh - 1 - y) * w + x); // GL rows bottom up
                let truth: Vec<f64> = (0..3).map(|c| (now.rgb[3 * (y * w + x) + c] as f64).clamp(0.0, 1.0)).collect();
                if truth.iter().all(|&t| t < 0.02) && (0..3).all(|c| bilinear(&then, p, c) < 0.02) {
                    continue;
                }
                n += 1;
                for c in 0..3 {
                    let warped = bilinear(&then, p, c);
                    d_now += (gl[src + c] - truth[c]).abs();
                    d_stale += (stale[src + c] - truth[c]).abs();
                    d_ref += (warped - truth[c]).abs();
                    d_warp += (gl[src + c] - warped).abs();
                    d_rot += (warped - (rot.rgb[3 * (y * w + x) + c] as f64).clamp(0.0, 1.0)).abs();
                }
            }
        }
        let m = (3 * n.max(1)) as f64;
        let (d_now, d_stale, d_ref, d_warp, d_rot) = (d_now / m, d_stale / m, d_ref / m, d_warp / m, d_rot / m);
        eprintln!(
            "{what} eye {i}: {n} pixels of the scene covered after a {yaw}° yaw, {pitch}° pitch turn; mean |diff| x255: presented vs CPU now {:.2}, \
             old behaviour vs CPU now {:.2}, bilinear CPU then vs CPU now {:.2} (vs CPU at the new rotation from the old eye position \
             {:.2}), presented vs bilinear CPU then {:.2}",
            d_now * 255.0, d_stale * 255.0, d_ref * 255.0, d_rot * 255.0, d_warp * 255.0
        );
        assert!(n * 20 > w * hh, "{what} eye {i}: the scene covers {n} pixels of the compared region");
        // The reprojection is the homography: the layer is the last image, resampled. Bound:
        // 8-bit quantization of the marched image (0.5/255) and of the layer (0.5/255), plus
        // the march against the CPU (check_eyes: ~1e-7) and GL's filter weights (0.5/255).
        assert!(d_warp <= 1.5 / 255.0, "{what} eye {i}: the layer is not the last image reprojected ({:.2}/255)", d_warp * 255.0);
        // Against the CPU reference at the new pose: no more than resampling the exact image
        // is off by, plus the quantization above.
        let bound = d_ref + 1.5 / 255.0;
        assert!(d_now <= bound, "{what} eye {i}: presented vs CPU now {:.2}/255 > {:.2}/255", d_now * 255.0, bound * 255.0);
        // The last image drawn as it was (the old behaviour) fails that comparison by far.
        assert!(d_stale > 2.0 * bound, "{what} eye {i}: without reprojection {:.2}/255, bound {:.2}/255: the turn does not show", d_stale * 255.0, bound * 255.0);
    }
    h.shutdown();
    r["held"]["backend"].as_str().unwrap_or_default().to_string()
}

#[test]
fn immersive_mode_after_a_head_turn_presents_the_scene_turned_by_it_before_the_next_march_completes() {
    let Some(b) = browser() else { return };
    if iwer(&b).is_none() {
        return;
    }
    let backend = check_turn_reprojected(&|url, args| xr_page(&b, url, args), "webgpu");
    assert_eq!(backend, "webgpu");
}

#[test]
fn without_webgpu_immersive_mode_after_a_head_turn_presents_the_scene_turned_by_it_too() {
    let Some(b) = browser() else { return };
    if iwer(&b).is_none() {
        return;
    }
    let run = |url: &str, args: &[&str]| {
        let all: Vec<&str> = std::iter::once(url).chain(args.iter().copied()).collect();
        run_without_webgpu(&b, "xr.mjs", &b.2.join("../.."), &all)
    };
    let backend = check_turn_reprojected(&run, "webgl2");
    assert_eq!(backend, "webgl2");
}

/// Run a page script (tests/web/page.mjs or xr.mjs, with its playwright argument) in a
/// Chromium without WebGPU (`SNERF_NO_WEBGPU=1`, see tests/web/launch.mjs: `requestAdapter()`
/// returns null there), so the page draws with its WebGL2 renderer. Its JSON report.
fn run_without_webgpu(b: &(PathBuf, PathBuf, PathBuf), script: &str, pw: &Path, args: &[&str]) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web").join(script);
    let out = Command::new(&b.0).arg(&script).arg(pw).args(args).env("SNERF_CHROMIUM", &b.1).env("SNERF_NO_WEBGPU", "1").output().expect("run node");
    let stderr = String::from_utf8_lossy(&out.stderr);
    if std::env::var_os("SNERF_PAGE_LOG").is_some() {
        eprintln!("{stderr}");
    }
    assert!(out.status.success(), "{} failed: {stderr}", script.display());
    let stdout = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(stdout.trim()).unwrap_or_else(|e| panic!("report {stdout:?}: {e} (stderr: {stderr})"))
}

/// `check_render` on the WebGL2 renderer: the page's frame (read back from its float render
/// target) and what its canvas presents, both against the CPU reference. Returns the report.
fn check_render_webgl(b: &(PathBuf, PathBuf, PathBuf), h: &ServerHandle, asset: &Asset, name: &str, time: f32) -> serde_json::Value {
    let cam = snerf_asset::orbit(&asset.header, 1, 0, 48, 32, 40.0);
    let url = format!(
        "{}#{}",
        h.web().unwrap().url(),
        fragment(&[("token", h.token()), ("asset", name), ("cam", &cam_json(&cam)), ("time", &time.to_string())])
    );
    let r = run_without_webgpu(b, "page.mjs", &b.2, &[&url, "done"]);
    assert_eq!(r["error"], serde_json::Value::Null, "{name}: page error: {}", r["error"]);
    assert_eq!(r["backend"], "webgl2", "{name}: drawn by {} ({})", r["backend"], r["adapter"]);
    let cpu = snerf_asset::render(asset, &cam, time);
    let bg = &asset.header.background;
    let shown = cpu.rgb.chunks(3).filter(|p| (0..3).any(|c| (p[c] - bg[c]).abs() > 0.02)).count();
    assert!(shown * 10 > cpu.rgb.len() / 3, "{name}: only {shown} pixels differ from the background");
    let fr = &r["lastRender"];
    assert_eq!((fr["complete"].as_bool(), fr["width"].as_u64(), fr["height"].as_u64()), (Some(true), Some(48), Some(32)), "{name}");
    let d = mean_abs_diff(fr["rgba"].as_array().unwrap(), &cpu);
    eprintln!("{name} at t={time}: WebGL2 ({}) vs CPU reference mean |diff| {d:?}", r["adapter"]);
    assert!(d.iter().all(|&x| x <= 2.0 / 255.0), "{name} at t={time}: mean |diff| {d:?} > 2/255");
    // The canvas (the blit of the target, flipped to the screen's rows) shows that frame.
    let png = base64_decode(r["canvasPng"].as_str().expect("canvas screenshot"));
    let shot = image::load_from_memory(&png).unwrap().to_rgb8();
    assert_eq!(shot.dimensions(), (48, 32), "{name}");
    let mut dc = [0f64; 3];
    for (i, p) in shot.pixels().enumerate() {
        for c in 0..3 {
            dc[c] += (p[c] as f64 / 255.0 - (cpu.rgb[3 * i + c] as f64).clamp(0.0, 1.0)).abs() / (48.0 * 32.0);
        }
    }
    eprintln!("{name}: presented WebGL2 canvas vs CPU reference mean |diff| {dc:?}");
    assert!(dc.iter().all(|&x| x <= 2.0 / 255.0), "{name}: canvas mean |diff| {dc:?} > 2/255");
    r
}

#[test]
fn without_webgpu_the_page_draws_with_webgl2_from_the_same_wgsl_like_the_cpu_reference() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-webgl");
    let state = TempDir::new("web-webgl-state");
    let put = |a: &Asset, name: &str| Asset::from_bytes(&write_asset(a, dir.path(), name)).unwrap();
    let scene = put(&static_asset(32, 8, 0.8, 11), "scene");
    let moving = put(&dynamic_asset(16, 8, 0.9, 3, 21), "moving");
    let outdoor = put(&kind_asset(snerf_asset::Kind::Unbounded, 32, 8, 0.9, 4), "outdoor");
    let front = put(&kind_asset(snerf_asset::Kind::Forward, 32, 8, 0.9, 6), "front");
    let mut d = static_asset(32, 8, 0.8, 13);
    d.make_diffuse();
    let flat = put(&d, "flat");
    // colour blended by density between keyframes, as every dynamic bake is ("moving": as older ones)
    let mut m = motion_asset();
    m.header.colour_by_density = true;
    let moved = put(&m, "motion");
    // A field trained with 2 x 2 rays a pixel: the silhouette pass (the fragment shader reads
    // the first pass's output as textures) redraws the silhouette pixels as their means.
    let mut e = static_asset(32, 8, 0.8, 17);
    e.header.pixel_rays = 4;
    let edges = put(&e, "edges");
    let h = start(dir.path(), state.path());
    for (asset, name, time) in [(&scene, "scene", 0.0), (&moving, "moving", 0.5), (&outdoor, "outdoor", 0.0), (&front, "front", 0.0), (&flat, "flat", 0.0), (&moved, "motion", 0.5), (&moved, "motion", 2.5)] {
        let r = check_render_webgl(&b, &h, asset, name, time);
        assert_eq!(r["lastFrame"]["pixelSides"], serde_json::json!([1]), "{name}");
    }
    // Where the browser has WebGPU (the default flags), the page takes it.
    let cam = snerf_asset::orbit(&scene.header, 1, 0, 48, 32, 40.0);
    let url = format!("{}#{}", h.web().unwrap().url(), fragment(&[("token", h.token()), ("asset", "scene"), ("cam", &cam_json(&cam))]));
    let r = page(&b, &[&url, "done"]);
    assert_eq!((r["error"].as_str(), r["backend"].as_str()), (None, Some("webgpu")), "{}", r["error"]);
    let r = check_render_webgl(&b, &h, &edges, "edges", 0.0);
    assert_eq!(r["lastFrame"]["pixelSides"], serde_json::json!([2]), "the silhouette pass did not run");
    // ...and it changes the picture (one ray a pixel would not pass for it).
    let cam = snerf_asset::orbit(&edges.header, 1, 0, 48, 32, 40.0);
    let mut one = edges.clone();
    one.header.pixel_rays = 1;
    let (means, centres) = (snerf_asset::render(&edges, &cam, 0.0), snerf_asset::render(&one, &cam, 0.0));
    let rgba = r["lastRender"]["rgba"].as_array().unwrap();
    let page = |i: usize, k: usize| rgba[4 * i + k].as_f64().unwrap().clamp(0.0, 1.0);
    let (mut changed, mut followed) = (0, 0);
    for i in 0..(48 * 32) {
        if (0..3).any(|k| (means.rgb[3 * i + k] - centres.rgb[3 * i + k]).abs() > 0.02) {
            changed += 1;
            followed += (0..3).all(|k| (page(i, k) - means.rgb[3 * i + k] as f64).abs() < 1.0 / 255.0) as usize;
        }
    }
    eprintln!("edges: {changed} pixels where the means differ from one ray a pixel; the WebGL2 frame has the means at {followed}");
    assert!(changed >= 20, "only {changed} pixels tell the silhouette pass apart");
    assert_eq!(followed, changed, "the WebGL2 frame's silhouette pixels are not the means");
    h.shutdown();
}

#[test]
fn without_webgpu_immersive_mode_draws_both_eyes_with_webgl2_like_the_cpu_reference() {
    let Some(b) = browser() else { return };
    if iwer(&b).is_none() {
        return;
    }
    let dir = TempDir::new("web-webgl-xr");
    let state = TempDir::new("web-webgl-xr-state");
    let asset = static_asset(32, 8, 0.8, 11);
    write_asset(&asset, dir.path(), "scene");
    let h = start(dir.path(), state.path());
    let url = format!("{}#{}", h.web().unwrap().url(), fragment(&[("token", h.token()), ("asset", "scene"), ("capture", "1")]));
    let r = run_without_webgpu(&b, "xr.mjs", &b.2.join("../.."), &[&url]);
    assert_eq!(r["page"]["error"], serde_json::Value::Null, "{}", r["page"]["error"]);
    assert_eq!(r["page"]["backend"], "webgl2");
    // Each eye's march against the CPU reference, and what the XR layer shows against it
    // (the renderer's canvas uploaded into the layer as on WebGPU), at the first pose and
    // after the head moved and turned.
    let cams0 = check_eyes(&r["before"], &asset, "webgl2 before");
    let cpu = snerf_asset::render(&asset, &cams0[0], 0.0);
    let shown = cpu.rgb.chunks(3).filter(|p| p.iter().any(|&v| v > 0.02)).count();
    assert!(shown * 20 > cpu.rgb.len() / 3, "the object is not in front of the user ({shown} pixels)");
    let cams1 = check_eyes(&r["moved"], &asset, "webgl2 moved");
    let cams2 = check_eyes(&r["turned"], &asset, "webgl2 turned");
    assert!(dist3(eye_pos(&cams0[0]), eye_pos(&cams1[0])) > 0.0 && cams2[0].c2w != cams1[0].c2w, "the eyes did not follow the headset");
    h.shutdown();
}

/// A TCP connection to `to` from the loopback address `from` (127.0.0.2: "another machine on
/// the same Wi-Fi").
async fn connect_from(from: &str, to: std::net::SocketAddr) -> tokio::net::TcpStream {
    let s = tokio::net::TcpSocket::new_v4().unwrap();
    s.bind(format!("{from}:0").parse().unwrap()).unwrap();
    s.connect(to).await.unwrap()
}

/// Whether the server has closed `s` (EOF or reset) within `wait`.
async fn closed_within(s: &mut tokio::net::TcpStream, wait: std::time::Duration) -> bool {
    use tokio::io::AsyncReadExt;
    let mut buf = [0u8; 4096];
    let t = tokio::time::Instant::now() + wait;
    loop {
        match tokio::time::timeout_at(t, s.read(&mut buf)).await {
            Err(_) => return false,
            Ok(Ok(0)) | Ok(Err(_)) => return true,
            Ok(Ok(_)) => continue,
        }
    }
}

#[test]
fn hostile_connections_from_another_address_do_not_lock_out_the_page() {
    use tokio::io::AsyncWriteExt;
    let b = browser();
    let dir = TempDir::new("web-hostile");
    let state = TempDir::new("web-hostile-state");
    let bytes = write_asset(&static_asset(16, 8, 0.9, 5), dir.path(), "scene");
    let h = start(dir.path(), state.path());
    let web = h.web().unwrap().clone();
    let limits = Limits::default();
    let (addr, hash) = (web.addr, web.cert_hash.clone().unwrap());
    let host = format!("127.0.0.1:{}", addr.port());
    let rt = runtime();
    // The attack, from 127.0.0.2: 100 idle connections, 40 that trickle a TLS ClientHello a few
    // bytes a second, 8 that send a 64 KiB header, and 8 that pipeline requests for the
    // largest file and never read.
    let attack = rt.block_on(async {
        let mut idle = Vec::new();
        for _ in 0..100 {
            idle.push(connect_from("127.0.0.2", addr).await);
        }
        let mut trickle = tokio::task::JoinSet::new();
        for _ in 0..40 {
            let mut s = connect_from("127.0.0.2", addr).await;
            trickle.spawn(async move {
                // A TLS record header claiming a long ClientHello, then a byte a second.
                let _ = s.write_all(&[0x16, 0x03, 0x01, 0x02, 0x00]).await;
                for _ in 0..30 {
                    tokio::time::sleep(std::time::Duration::from_millis(700)).await;
                    if s.write_all(&[0x01]).await.is_err() {
                        return true; // the server closed it
                    }
                }
                false
            });
        }
        let mut big = Vec::new();
        for _ in 0..8 {
            let mut s = tls_to_from("127.0.0.2", addr, &hash).await;
            let head = format!("GET / HTTP/1.1\r\nHost: {host}\r\nX-Pad: {}\r\n", "a".repeat(64 * 1024));
            let _ = s.write_all(head.as_bytes()).await;
            big.push(s);
        }
        // The fallback transport's endpoint: a POST whose announced body trickles in.
        for _ in 0..8 {
            let mut s = tls_to_from("127.0.0.2", addr, &hash).await;
            let head = format!("POST /snerf/1/http?part=data HTTP/1.1\r\nHost: {host}\r\nOrigin: https://{host}\r\nContent-Length: 60000\r\n\r\n");
            let _ = s.write_all(head.as_bytes()).await;
            trickle.spawn(async move {
                for _ in 0..30 {
                    tokio::time::sleep(std::time::Duration::from_millis(700)).await;
                    if s.write_all(b"{").await.is_err() || s.flush().await.is_err() {
                        return true;
                    }
                }
                false
            });
        }
        let mut deaf = Vec::new();
        for _ in 0..8 {
            let mut s = tls_to_from("127.0.0.2", addr, &hash).await;
            let req = format!("GET /march.wgsl?kind=2&dynamic=1&diffuse=0&block=8 HTTP/1.1\r\nHost: {host}\r\n\r\n").repeat(200);
            let _ = tokio::time::timeout(std::time::Duration::from_millis(200), s.write_all(req.as_bytes())).await;
            deaf.push(s);
        }
        (idle, trickle, big, deaf)
    });
    let (mut idle, mut trickle, mut big, _deaf) = attack;
    // The server holds at most its per-address cap of them (plus nothing else).
    let held = h.stats().page_conns.load(Ordering::Relaxed);
    assert!(held <= limits.page_conns_per_ip as u64, "{held} page connections held");
    assert!(h.stats().page_evicted.load(Ordering::Relaxed) >= 100, "evicted {}", h.stats().page_evicted.load(Ordering::Relaxed));
    // While the attack goes on, a client at 127.0.0.1 gets the page at once...
    let t0 = std::time::Instant::now();
    let page = rt.block_on(async { get(tls_to(addr, &hash).await, &host, "/").await });
    assert!(page.starts_with("HTTP/1.1 200"), "{page}");
    eprintln!("page under attack: {:?}", t0.elapsed());
    // ...and the real page in Chromium streams the asset byte for byte.
    if let Some(b) = &b {
        let url = format!("{}#{}", web.url(), fragment(&[("token", h.token()), ("asset", "scene")]));
        let r = page_of(b, &[&url, "done"]);
        assert_eq!(r["error"], serde_json::Value::Null, "page error: {}", r["error"]);
        let sha = snerf_stream::proto::to_hex(&Sha256::digest(&bytes));
        assert_eq!(r["sha256"], sha.as_str());
        // And over the fallback transport (a browser without WebTransport), still under attack.
        let r = run_page_env(b, "page.mjs", &[&url, "done"], &[("SNERF_NO_WEBTRANSPORT", "1")]);
        assert_eq!(r["error"], serde_json::Value::Null, "page error (over HTTPS): {}", r["error"]);
        assert_eq!((r["transport"].as_str(), r["sha256"].as_str()), (Some("https"), Some(sha.as_str())));
    }
    // Every hostile connection is closed by the server within the head timeout (plus the
    // write timeout for those that never read), whichever way it misbehaved.
    let within = limits.page_head_timeout + std::time::Duration::from_secs(2);
    rt.block_on(async {
        for s in idle.iter_mut() {
            assert!(closed_within(s, within).await, "an idle connection is still open");
        }
        while let Some(r) = trickle.join_next().await {
            assert!(r.unwrap(), "a trickling connection was kept for 20 s");
        }
        for s in big.iter_mut() {
            use tokio::io::AsyncReadExt;
            let mut out = Vec::new();
            let _ = tokio::time::timeout(within, s.read_to_end(&mut out)).await;
            let out = String::from_utf8_lossy(&out);
            assert!(out.is_empty() || out.starts_with("HTTP/1.1 431"), "{out}");
        }
    });
    let after = limits.page_write_timeout + std::time::Duration::from_secs(1);
    std::thread::sleep(after);
    assert_eq!(h.stats().page_conns.load(Ordering::Relaxed), 0, "connections left open");
    assert!(h.stats().page_timeouts.load(Ordering::Relaxed) > 0);
    h.shutdown();
}

/// `tls_to` from another loopback address.
async fn tls_to_from(from: &str, addr: std::net::SocketAddr, hash: &str) -> tokio_rustls::client::TlsStream<tokio::net::TcpStream> {
    tls_over(connect_from(from, addr).await, hash).await.unwrap()
}

/// `page` by another name (the report of page.mjs), for tests that also name a variable `page`.
fn page_of(b: &(PathBuf, PathBuf, PathBuf), args: &[&str]) -> serde_json::Value {
    page(b, args)
}

/// page.mjs (or another script) with extra environment for launch.mjs.
fn run_page_env(b: &(PathBuf, PathBuf, PathBuf), script: &str, args: &[&str], env: &[(&str, &str)]) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web").join(script);
    let mut c = Command::new(&b.0);
    c.arg(&script).arg(&b.2).args(args).env("SNERF_CHROMIUM", &b.1);
    for (k, v) in env {
        c.env(k, v);
    }
    let out = c.output().expect("run node");
    let stderr = String::from_utf8_lossy(&out.stderr);
    if std::env::var_os("SNERF_PAGE_LOG").is_some() {
        eprintln!("{stderr}");
    }
    assert!(out.status.success(), "{} failed: {stderr}", script.display());
    let stdout = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(stdout.trim()).unwrap_or_else(|e| panic!("report {stdout:?}: {e} (stderr: {stderr})"))
}

/// One request of snerf/1 over HTTPS: (status line, body).
async fn post_http(addr: std::net::SocketAddr, hash: &str, host: &str, origin: Option<&str>, query: &str, body: &[u8]) -> (String, Vec<u8>) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut s = tls_to(addr, hash).await;
    let mut head = format!("POST /snerf/1/http?{query} HTTP/1.1\r\nHost: {host}\r\nContent-Length: {}\r\nConnection: close\r\n", body.len());
    if let Some(o) = origin {
        head += &format!("Origin: {o}\r\n");
    }
    head += "\r\n";
    s.write_all(head.as_bytes()).await.unwrap();
    // A body over the server's limit is refused from its announced length, before it is read:
    // it is not sent (the server closes at once, and unread bytes would reset the connection
    // before the answer is read).
    if body.len() <= 64 * 1024 {
        s.write_all(body).await.unwrap();
    }
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out).await;
    let p = out.windows(4).position(|w| w == b"\r\n\r\n").expect("a response");
    let status = String::from_utf8_lossy(&out[..out.iter().position(|&c| c == b'\r').unwrap()]).into_owned();
    (status, out[p + 4..].to_vec())
}

#[test]
fn without_webtransport_the_page_streams_over_https_byte_for_byte_and_refusals_send_nothing() {
    let dir = TempDir::new("web-https-stream");
    let state = TempDir::new("web-https-stream-state");
    let asset = static_asset(32, 8, 0.8, 11);
    let bytes = write_asset(&asset, dir.path(), "scene");
    let h = start(dir.path(), state.path());
    let web = h.web().unwrap().clone();
    let (addr, hash) = (web.addr, web.cert_hash.clone().unwrap());
    let host = format!("127.0.0.1:{}", addr.port());
    let origin = format!("https://{host}");
    let hello = |token: &str| snerf_stream::proto::encode_frame(&serde_json::json!({"type": "hello", "version": 1, "token": token, "asset": "scene"}));
    let rt = runtime();
    // Refusals: wrong token, another origin, no origin, a body that does not decode, one too
    // large; none carries a byte of the asset.
    let cases: Vec<(Vec<u8>, Option<&str>, &str, &str)> = vec![
        (hello("0".repeat(64).as_str()), Some(origin.as_str()), "part=data", "HTTP/1.1 401"),
        (hello(h.token()), Some("https://evil.example"), "part=data", "HTTP/1.1 403"),
        (hello(h.token()), None, "part=data", "HTTP/1.1 403"),
        (b"\x05\x00\x00\x00{not".to_vec(), Some(origin.as_str()), "part=data", "HTTP/1.1 400"),
        (vec![b' '; 70 * 1024], Some(origin.as_str()), "part=data", "HTTP/1.1 413"),
        (hello(h.token()), Some(origin.as_str()), "part=everything", "HTTP/1.1 400"),
    ];
    for (body, o, q, want) in &cases {
        let (status, got) = rt.block_on(post_http(addr, &hash, &host, *o, q, body));
        assert!(status.starts_with(want), "{want}: got {status}");
        assert!(got.len() < 200 && !got.windows(4).any(|w| w == b"BLKS" || w == b"HEAD"), "{want}: {} bytes", got.len());
    }
    assert_eq!(h.stats().bytes_sent.load(Ordering::Relaxed), 0);
    // The right request gets the small parts first, as on a data stream.
    let (status, got) = rt.block_on(post_http(addr, &hash, &host, Some(&origin), "part=data", &hello(h.token())));
    assert!(status.starts_with("HTTP/1.1 200"), "{status}");
    assert_eq!(&got[4..8], b"HEAD", "the first record is the header");
    // The page in Chromium without WebTransport: byte-identical, and drawn like the CPU reference.
    if let Some(b) = browser() {
        let cam = snerf_asset::orbit(&asset.header, 1, 0, 64, 48, 40.0);
        let url = format!("{}#{}", web.url(), fragment(&[("token", h.token()), ("asset", "scene"), ("cam", &cam_json(&cam))]));
        let r = run_page_env(&b, "page.mjs", &[&url, "done"], &[("SNERF_NO_WEBTRANSPORT", "1")]);
        assert_eq!(r["error"], serde_json::Value::Null, "page error: {}", r["error"]);
        assert_eq!(r["transport"], "https");
        assert_eq!(r["sha256"], snerf_stream::proto::to_hex(&Sha256::digest(&bytes)).as_str());
        let cpu = snerf_asset::render(&Asset::from_bytes(&bytes).unwrap(), &cam, 0.0);
        let d = mean_abs_diff(r["lastRender"]["rgba"].as_array().unwrap(), &cpu);
        assert!(d.iter().all(|&x| x <= 2.0 / 255.0), "mean |diff| {d:?}");
        // The listing came the same way.
        assert_eq!(r["listing"].as_array().map(|l| l.len()), Some(1));
        // And with neither WebTransport nor WebGPU (a headset browser with WebGL2 alone).
        let r = run_page_env(&b, "page.mjs", &[&url, "done"], &[("SNERF_NO_WEBTRANSPORT", "1"), ("SNERF_NO_WEBGPU", "1")]);
        assert_eq!(r["error"], serde_json::Value::Null, "page error: {}", r["error"]);
        assert_eq!((r["transport"].as_str(), r["backend"].as_str()), (Some("https"), Some("webgl2")));
        assert_eq!(r["sha256"], snerf_stream::proto::to_hex(&Sha256::digest(&bytes)).as_str());
    }
    h.shutdown();
}

#[test]
fn a_restarted_server_keeps_the_certificate_a_headset_accepted() {
    let dir = TempDir::new("web-keep");
    let state = TempDir::new("web-keep-state");
    write_asset(&static_asset(16, 8, 0.9, 5), dir.path(), "scene");
    let a = start(dir.path(), state.path());
    let first = a.web().unwrap().cert_hash.clone().unwrap();
    a.shutdown();
    let b = start(dir.path(), state.path());
    assert_eq!(b.web().unwrap().cert_hash.as_deref(), Some(first.as_str()), "a new certificate means a new warning on the headset");
    b.shutdown();
    // Another state directory: another certificate.
    let other = TempDir::new("web-keep-other");
    let c = start(dir.path(), other.path());
    assert_ne!(c.web().unwrap().cert_hash.as_deref(), Some(first.as_str()));
    c.shutdown();
}

#[test]
fn a_still_view_is_redrawn_at_full_resolution_once_the_asset_is_in() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-refine");
    let state = TempDir::new("web-refine-state");
    write_asset(&static_asset(32, 8, 0.8, 11), dir.path(), "scene");
    let h = start(dir.path(), state.path());
    // No fixed camera: the page's own orbit view, drawn at the adaptive scale while blocks
    // arrive, then (nothing moving) once more at the canvas's full resolution.
    let url = format!("{}#{}", h.web().unwrap().url(), fragment(&[("token", h.token()), ("asset", "scene")]));
    let r = run_page_env(&b, "page.mjs", &[&url, "done"], &[("SNERF_WAIT_REFINED", "1")]);
    assert_eq!(r["error"], serde_json::Value::Null, "page error: {}", r["error"]);
    let f = &r["lastFrame"];
    assert_eq!((f["scale"].as_f64(), f["complete"].as_bool()), (Some(1.0), Some(true)), "{f}");
    // The first frame was smaller (it is marched at a fraction of the pixels).
    assert!(r["firstFrame"]["width"].as_u64().unwrap_or(0) < f["width"].as_u64().unwrap(), "{} vs {f}", r["firstFrame"]);
    h.shutdown();
}

/// A multi-style asset: the page lists its styles as swatches, streams `scene.cold` (that
/// style's single-style asset, byte for byte) and knows the styles its keys 1..9 switch to.
#[test]
fn the_page_lists_a_multi_style_assets_styles_and_streams_one() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-styles");
    let state = TempDir::new("web-styles-state");
    let file = dir.join("scene.snerf");
    two_styles().write(&file).unwrap();
    let cold = snerf_asset::LayeredAsset::read(&file).unwrap().into_style(1).unwrap().to_bytes();
    let h = start(dir.path(), state.path());
    let web = h.web().unwrap().clone();
    let url = format!("{}#{}", web.url(), fragment(&[("token", h.token()), ("asset", "scene.cold")]));
    let r = page(&b, &[&url, "done"]);
    assert_eq!(r["error"], serde_json::Value::Null, "page error: {}", r["error"]);
    assert_eq!(r["state"], "done");
    assert_eq!(r["sha256"], snerf_stream::proto::to_hex(&Sha256::digest(&cold)).as_str());
    let listed: Vec<&str> = r["listing"][0]["styles"].as_array().unwrap().iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert_eq!(listed, ["warm", "cold"]);
    assert_eq!(r["styles"], serde_json::json!(["scene.warm", "scene.cold"]));
    h.shutdown();
}

/// A style asked for in the page and added while it shows the asset: the page offers the
/// server's paintings (`ServeOptions::offer`), its button sends the choice, and what `snerf
/// serve --styles-dir` does once that layer is trained (the file written again with the
/// style appended, then `Announcer::styles_changed`) reaches the page, watching: it shows the
/// new swatch, its key switches to the style by colour alone, and the page rebuilds that
/// style's file byte for byte.
#[test]
fn a_style_added_while_the_page_shows_the_asset_gets_a_swatch_and_a_switch_by_colour() {
    use std::io::BufRead;
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-new-style");
    let state = TempDir::new("web-new-style-state");
    let file = dir.join("scene.snerf");
    let layered = two_styles();
    layered.write(&file).unwrap();
    let (tx, requests) = std::sync::mpsc::channel();
    let mut o = ServeOptions::new(dir.path(), "127.0.0.1:0".parse().unwrap());
    o.state_dir = Some(state.path().to_path_buf());
    o.quiet = std::env::var_os("SNERF_STREAM_LOG").is_none();
    o.web = Some("127.0.0.1:0".parse().unwrap());
    o.offer = Some(snerf_stream::server::Offer { asset: "scene".into(), paintings: vec!["green".into(), "warm".into()], requests: tx });
    let h = snerf_stream::spawn(o).unwrap();
    let web = h.web().unwrap().clone();
    let url = format!("{}#{}", web.url(), fragment(&[("token", h.token()), ("asset", "scene.warm")]));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web/newstyle.mjs");
    let mut node = Command::new(&b.0)
        .arg(&script)
        .arg(&b.2)
        .arg(&url)
        .env("SNERF_CHROMIUM", &b.1)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run node");
    let mut out = std::io::BufReader::new(node.stdout.take().unwrap()).lines();
    let first = out.next().and_then(Result::ok).unwrap_or_default();
    assert_eq!(first, "watching");
    // the page asked for the painting it was offered (warm, a style the asset has, is not)
    let asked = requests.recv_timeout(std::time::Duration::from_secs(60)).expect("the page asks for a painting");
    assert_eq!(asked, "green");
    // a third style: the first's colours halved
    let mut green = layered.layers[0].clone();
    for v in green.atlas.chunks_exact_mut(8) {
        for c in &mut v[1..] {
            *c /= 2;
        }
    }
    let (mut styles, mut layers) = (layered.styles.clone(), layered.layers.clone());
    styles.push(snerf_asset::StyleInfo { name: "green".into(), source: None, swatch: [0.2, 0.6, 0.2] });
    layers.push(green);
    let three = snerf_asset::LayeredAsset::new(styles, layers).unwrap();
    three.write(&file).unwrap();
    let want = three.clone().into_style(2).unwrap().to_bytes();
    assert_eq!(h.announcer().styles_changed("scene").unwrap(), 1, "the page's watching session is told");
    let rest: Vec<String> = out.map_while(Result::ok).collect();
    let status = node.wait().unwrap();
    let mut stderr = String::new();
    std::io::Read::read_to_string(&mut node.stderr.take().unwrap(), &mut stderr).unwrap();
    assert!(status.success(), "newstyle.mjs failed: {stderr}");
    let r: serde_json::Value = serde_json::from_str(rest.last().map(String::as_str).unwrap_or("")).unwrap_or_else(|e| panic!("page report: {e} ({stderr})"));
    assert_eq!(r["error"], serde_json::Value::Null, "page error: {}", r["error"]);
    assert_eq!(r["swatches"], serde_json::json!(["warm", "cold", "green"]));
    assert_eq!(r["offered"], serde_json::json!(["green"]), "what the page offered");
    assert_eq!(r["training"], "scene.green");
    assert_eq!(r["offeredAfter"], serde_json::json!([]), "nothing is offered once the asset has it");
    assert_eq!(r["styles"], serde_json::json!(["scene.warm", "scene.cold", "scene.green"]));
    let sw = &r["switches"][0];
    assert_eq!((&sw["state"], &sw["name"]), (&"done".into(), &"scene.green".into()), "{sw}");
    let records = three.header().atlas_blocks as u64 + 1;
    assert_eq!(sw["bytes"].as_u64(), Some(three.style_bytes()[2].bytes + 4 * records), "the colour part and an index per record: {sw}");
    assert_eq!(r["sha256"], snerf_stream::proto::to_hex(&Sha256::digest(&want)).as_str());
    h.shutdown();
}

/// Run switch.mjs (URL, then the keys pressed one switch after another); its JSON report.
fn switch_page(b: &(PathBuf, PathBuf, PathBuf), url: &str, keys: &str) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web/switch.mjs");
    let out = Command::new(&b.0).arg(&script).arg(&b.2).arg(url).arg(keys).env("SNERF_CHROMIUM", &b.1).output().expect("run node");
    let stderr = String::from_utf8_lossy(&out.stderr);
    if std::env::var_os("SNERF_PAGE_LOG").is_some() {
        eprintln!("{}", stderr);
    }
    assert!(out.status.success(), "switch.mjs failed: {}", stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(stdout.trim()).unwrap_or_else(|e| panic!("page report {:?}: {} (stderr: {})", stdout, e, stderr))
}

/// The same switch on a 4D asset (a two-style asset over a time codebook, as `snerf bake`
/// writes one from a 4D run stylized after two paintings): the page, showing an instant
/// between two keyframes, switches to the second style and draws that style's CPU reference
/// at that time.
#[test]
fn a_style_switch_on_a_4d_asset_draws_the_new_style_between_keyframes() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-switch-4d");
    let state = TempDir::new("web-switch-4d-state");
    // lerped between keyframes (every voxel's colour stored), and blended by density (every
    // dynamic bake: live interior voxels only, aprons from their block's interior)
    let mut cases = Vec::new();
    for (name, by_density) in [("moving", false), ("dense", true)] {
        let mut a = dynamic_asset(32, 8, 0.9, 3, 21);
        a.header.colour_by_density = by_density;
        let mut c = a.clone();
        for v in c.atlas.chunks_exact_mut(8) {
            for x in &mut v[1..] {
                *x = 255 - *x;
            }
        }
        let style = |name: &str| snerf_asset::StyleInfo { name: name.into(), source: None, swatch: [0.5; 3] };
        let layered = snerf_asset::LayeredAsset::new(vec![style("warm"), style("cold")], vec![a, c]).unwrap();
        layered.write(&dir.join(&format!("{name}.snerf"))).unwrap();
        let styles: Vec<Asset> = (0..2).map(|i| layered.clone().into_style(i).unwrap()).collect();
        cases.push((name, styles));
    }
    let h = start(dir.path(), state.path());
    let web = h.web().unwrap().clone();
    let time = 0.5;
    for (name, styles) in &cases {
        let cam = snerf_asset::orbit(&styles[0].header, 1, 0, 64, 48, 40.0);
        let url = format!("{}#{}", web.url(), fragment(&[("token", h.token()), ("asset", &format!("{name}.warm")), ("time", "0.5"), ("cam", &cam_json(&cam))]));
        let r = switch_page(&b, &url, "2");
        assert_eq!(r["error"], serde_json::Value::Null, "{name}: page error: {}", r["error"]);
        let sws = r["switches"].as_array().unwrap();
        assert_eq!(sws.len(), 1, "{sws:?}");
        assert_eq!(sws[0]["state"], "done", "{name}: {}", sws[0]);
        assert_eq!(r["asset"]["name"], format!("{name}.cold"));
        let fr = &r["lastRender"];
        assert_eq!(fr["complete"], true);
        let rgba = fr["rgba"].as_array().unwrap();
        let d = mean_abs_diff(rgba, &snerf_asset::render(&styles[1], &cam, time));
        let left = mean_abs_diff(rgba, &snerf_asset::render(&styles[0], &cam, time));
        eprintln!("{name}: 4D switch at t = {time}: mean |diff| {d:?} to the new style's CPU reference, {left:?} to the old one's");
        assert!(d.iter().all(|&x| x <= 2.0 / 255.0), "{name}: mean |diff| {:?} > 2/255", d);
        assert!(left.iter().any(|&x| x > 10.0 / 255.0), "{name}: the two styles' frames are too alike for the test to mean something: {left:?}");
    }
}

/// A style switch in the page (keys 2, 1, 2 on `scene.warm`): each streams only the new
/// style's colour part (the page's count and the server's: the style's SMLP and SCOL chunks
/// and a 4-byte index per record, well below the whole style), the page rebuilds the new
/// style's file byte for byte (its SHA-256), and its frame at a fixed camera is the CPU
/// reference's of the style it switched to, not of the one it left. Each switch fades from a
/// frame of the old style.
#[test]
fn a_style_switch_in_the_page_streams_only_the_colour_part_and_draws_the_new_style() {
    let Some(b) = browser() else { return };
    let dir = TempDir::new("web-switch");
    let state = TempDir::new("web-switch-state");
    let file = dir.join("scene.snerf");
    let layered = two_styles();
    layered.write(&file).unwrap();
    let styles: Vec<Asset> = (0..2).map(|i| layered.clone().into_style(i).unwrap()).collect();
    let whole: Vec<Vec<u8>> = styles.iter().map(|a| a.to_bytes()).collect();
    let part: Vec<u64> = layered.style_bytes().iter().map(|s| s.bytes).collect();
    let records = layered.header().atlas_blocks as u64 + 1;
    let h = start(dir.path(), state.path());
    let web = h.web().unwrap().clone();
    let cam = snerf_asset::orbit(&styles[0].header, 1, 0, 64, 48, 40.0);
    let url = format!("{}#{}", web.url(), fragment(&[("token", h.token()), ("asset", "scene.warm"), ("cam", &cam_json(&cam))]));
    let r = switch_page(&b, &url, "2,1,2");
    assert_eq!(r["error"], serde_json::Value::Null, "page error: {}", r["error"]);
    let sws = r["switches"].as_array().unwrap();
    assert_eq!(sws.len(), 3, "{sws:?}");
    let mut sent = 0;
    for (sw, to) in sws.iter().zip([1usize, 0, 1]) {
        assert_eq!(sw["state"], "done", "{sw}");
        assert_eq!(sw["name"], ["scene.warm", "scene.cold"][to]);
        let want = part[to] + 4 * records;
        assert_eq!(sw["bytes"].as_u64(), Some(want), "the page received the colour part and a 4-byte index per record: {sw}");
        assert_eq!(sw["records"].as_u64(), Some(records));
        assert!(want * 4 < whole[to].len() as u64 * 3, "{want} bytes is not well below the whole style's {}", whole[to].len());
        let t = |k: &str| sw[k].as_f64().unwrap_or_else(|| panic!("no {k} in {sw}"));
        assert!(t("pressAt") <= t("welcomeAt") && t("welcomeAt") <= t("firstRecordAt") && t("firstRecordAt") <= t("firstFrameAt"), "{sw}");
        assert!(t("firstFrameAt") <= t("completeAt"), "{sw}");
        sent += want;
    }
    // each switch faded from a frame of the old style (copied off the WebGPU canvas as drawn)
    assert_eq!(r["fadeShown"].as_u64(), Some(3));
    assert!(r["fadeMean"].as_f64().unwrap_or(0.0) > 1.0, "the fade holds an empty frame: {}", r["fadeMean"]);
    // the server's count: the first style whole, then the three colour parts
    let stats = h.stats();
    assert_eq!(stats.colour_bytes_sent.load(Ordering::Relaxed), sent);
    assert_eq!(stats.colour_records_sent.load(Ordering::Relaxed), 3 * records);
    assert_eq!(stats.bytes_sent.load(Ordering::Relaxed), whole[0].len() as u64 - 16 + 4 * r["asset"]["chunks"].as_u64().unwrap() + sent);
    // the page's file is the style it switched to, byte for byte, and so is its frame
    assert_eq!(r["sha256"], snerf_stream::proto::to_hex(&Sha256::digest(&whole[1])).as_str());
    assert_eq!(r["asset"]["name"], "scene.cold");
    let fr = &r["lastRender"];
    assert_eq!(fr["complete"], true);
    let rgba = fr["rgba"].as_array().unwrap();
    let d = mean_abs_diff(rgba, &snerf_asset::render(&styles[1], &cam, 0.0));
    let left = mean_abs_diff(rgba, &snerf_asset::render(&styles[0], &cam, 0.0));
    eprintln!("after the switches: mean |diff| per channel {d:?} to the new style's CPU reference, {left:?} to the old one's");
    assert!(d.iter().all(|&x| x <= 2.0 / 255.0), "mean |diff| {:?} > 2/255", d);
    assert!(left.iter().any(|&x| x > 10.0 / 255.0), "the two styles' frames are too alike for the test to mean something: {left:?}");
    // Over HTTPS requests a switch by colour is refused with its reason, nothing sent (the
    // page loads the whole style there).
    let geometry = r["asset"]["geometry"].as_str().expect("the welcome names the geometry").to_string();
    let (addr, hash) = (web.addr, web.cert_hash.clone().unwrap());
    let host = format!("127.0.0.1:{}", addr.port());
    let body = snerf_stream::proto::encode_frame(
        &serde_json::json!({"type": "hello", "version": 1, "token": h.token(), "asset": "scene.warm", "colour_of": geometry}),
    );
    let sent_before = stats.bytes_sent.load(Ordering::Relaxed);
    for part in ["part=data", "part=control"] {
        let (status, got) = runtime().block_on(post_http(addr, &hash, &host, Some(&format!("https://{host}")), part, &body));
        assert!(status.starts_with("HTTP/1.1 400"), "{part}: {status}");
        assert!(String::from_utf8_lossy(&got).contains("colour_of"), "{part}: {}", String::from_utf8_lossy(&got));
    }
    assert_eq!(stats.bytes_sent.load(Ordering::Relaxed), sent_before);
    h.shutdown();
}
