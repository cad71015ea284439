//! `snerf serve`'s web viewer, whole: a baked asset, the `snerf serve` binary on loopback, the
//! page in headless Chromium (viewer/stream/tests/web/page.mjs, playwright-core), and its
//! WebGPU frame against the PNG `snerf render` writes for the same camera.
//!
//! Needs /usr/bin/chromium (or SNERF_CHROMIUM) and playwright-core under
//! target/test-assets/playwright (`.ci/run` installs both); skips with a message without
//! them, unless SNERF_REQUIRE_BROWSER=1 (CI), where it fails.

use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use snerf_files::ScratchDir;

fn snerf() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_snerf"));
    c.env("RAYON_NUM_THREADS", "2");
    c
}

fn ok(out: Output) -> serde_json::Value {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "command failed: {stderr}");
    serde_json::from_slice(&out.stdout).unwrap_or_else(|e| panic!("stdout is not JSON ({e}): {}", String::from_utf8_lossy(&out.stdout)))
}

fn browser() -> Option<(PathBuf, PathBuf)> {
    let chromium = std::env::var_os("SNERF_CHROMIUM").map(PathBuf::from).unwrap_or_else(|| PathBuf::from("/usr/bin/chromium"));
    let pw = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/test-assets/playwright/node_modules/playwright-core");
    let why = if !chromium.exists() {
        format!("no Chromium at {}", chromium.display())
    } else if !pw.join("package.json").exists() {
        format!("no playwright-core at {}", pw.display())
    } else if Command::new("node").arg("--version").output().is_err() {
        "no node".to_string()
    } else {
        return Some((chromium, pw));
    };
    if std::env::var("SNERF_REQUIRE_BROWSER").as_deref() == Ok("1") {
        panic!("SNERF_REQUIRE_BROWSER=1 but {why} (.ci/run installs it)");
    }
    eprintln!("skipping the web viewer test: {why} (.ci/run installs chromium and playwright-core)");
    None
}

/// Kills the server when the test ends, however it ends.
struct Server(std::process::Child);
impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn snerf_serve_web_page_renders_what_snerf_render_draws() {
    let Some((chromium, pw)) = browser() else { return };
    let d = ScratchDir::new("snerf-web", "page").unwrap();
    // A small real asset: scene -> train -> bake.
    let ds = d.join("ds");
    ok(snerf()
        .args(["--json", "scene", "object", "--out"])
        .arg(&ds)
        .args(["--views", "6", "--test-views", "2", "--size", "16x16", "--supersample", "1"])
        .output()
        .unwrap());
    let run = d.join("run");
    ok(snerf().args(["--json", "train"]).arg(&ds).arg("--out").arg(&run).args(["--steps", "2"]).output().unwrap());
    let assets = d.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let file = assets.join("a.snerf");
    ok(snerf()
        .args(["--json", "bake"])
        .arg(&run)
        .arg("--out")
        .arg(&file)
        .args(["--resolution", "32", "--eval-views", "0", "--visibility-views", "4"])
        .output()
        .unwrap());
    // The CPU reference image of the orbit's first camera.
    let frames = d.join("frames");
    ok(snerf().args(["--json", "render"]).arg(&file).args(["--path", "orbit", "--frames", "1", "--size", "24x16", "--out"]).arg(&frames).output().unwrap());
    let png = image::open(frames.join("frame_000.png")).unwrap().to_rgb8();
    let asset = snerf_asset::Asset::read(&file).unwrap();
    let cam = snerf_asset::orbit(&asset.header, 1, 0, 24, 16, 40.0);
    // Its diffuse twin (what a diffuse stylized field bakes to: version 2, no view MLP, 4
    // bytes a voxel), which the page must expand as the reader does.
    let mut diffuse = asset.clone();
    diffuse.make_diffuse();
    diffuse.write(assets.join("b.snerf")).unwrap();
    // The server, its web viewer on a free port.
    let mut child = snerf()
        .args(["--json", "serve"])
        .arg(&assets)
        .args(["--listen", "127.0.0.1:0", "--web", "127.0.0.1:0", "--state"])
        .arg(d.join("state"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let server = Server(child);
    let ready: serde_json::Value = serde_json::from_str(&line).unwrap_or_else(|e| panic!("serve --json: {e}: {line}"));
    let web = ready["web_url"].as_str().expect("web_url").to_string();
    assert!(ready["web_cert_sha256"].as_str().is_some_and(|h| h.len() == 64), "{ready}");
    let token = ready["token"].as_str().unwrap();
    let camj = serde_json::json!({"c2w": cam.c2w, "fx": cam.fx, "fy": cam.fy, "cx": cam.cx, "cy": cam.cy, "width": cam.width, "height": cam.height}).to_string();
    let enc: String = camj.bytes().map(|b| if b.is_ascii_alphanumeric() || b"-_.".contains(&b) { (b as char).to_string() } else { format!("%{b:02X}") }).collect();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("viewer/stream/tests/web/page.mjs");
    let page = |name: &str| -> serde_json::Value {
        let url = format!("{web}#token={token}&asset={name}&cam={enc}");
        let out = Command::new("node").arg(&script).arg(&pw).arg(&url).arg("done").env("SNERF_CHROMIUM", &chromium).output().unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "page.mjs ({name}): {stderr}");
        serde_json::from_slice(&out.stdout).unwrap()
    };
    let r = page("a");
    assert_eq!(r["error"], serde_json::Value::Null, "page error: {}", r["error"]);
    assert_eq!(r["sha256"].as_str().unwrap().len(), 64);
    assert_eq!(r["sha256"], r["asset"]["sha256"]);
    let rgba = r["lastRender"]["rgba"].as_array().unwrap();
    assert_eq!(rgba.len(), 24 * 16 * 4);
    // Per channel, in 8-bit steps as both images are shown.
    let mut diff = [0f64; 3];
    for (i, p) in png.pixels().enumerate() {
        for c in 0..3 {
            let web = (rgba[4 * i + c].as_f64().unwrap().clamp(0.0, 1.0) * 255.0).round();
            diff[c] += (web - p[c] as f64).abs();
        }
    }
    let diff = diff.map(|x| x / (24.0 * 16.0));
    eprintln!("snerf serve web page vs snerf render: mean |diff| per channel {diff:?} (of 255)");
    assert!(diff.iter().all(|&x| x <= 2.0), "mean |diff| {diff:?} > 2/255");
    // The object was trained with silhouette pixels as the mean of 4 rays, and the page draws
    // them so (march.wgsl's second pass): where that rule changes the CPU reference, the page
    // is the 4-ray image, not the one-ray one.
    assert_eq!(asset.header.pixel_rays, 4, "a static object's asset carries the trainer's rule");
    assert_eq!(asset.header.pixel_rays_for(&cam), 4, "this camera's pixels are about as coarse as the training views' ({:?})", asset.header.train_pixel);
    assert_eq!(r["lastFrame"]["pixelSides"], serde_json::json!([2]), "the page's own choice of rays (app.js pixelSide)");
    let four = snerf_asset::render(&asset, &cam, 0.0);
    let mut centre_only = asset.clone();
    centre_only.header.pixel_rays = 1;
    let one = snerf_asset::render(&centre_only, &cam, 0.0);
    let (mut to_four, mut to_one, mut changed) = (0.0f64, 0.0f64, 0);
    for p in 0..24 * 16 {
        if (0..3).all(|c| (four.rgb[p * 3 + c] - one.rgb[p * 3 + c]).abs() < 2.0 / 255.0) {
            continue;
        }
        changed += 1;
        for c in 0..3 {
            let web = rgba[4 * p + c].as_f64().unwrap();
            to_four += (web - four.rgb[p * 3 + c] as f64).abs();
            to_one += (web - one.rgb[p * 3 + c] as f64).abs();
        }
    }
    eprintln!("silhouette pixels the rule changes: {changed}; page vs 4 rays {to_four:.4}, vs one ray {to_one:.4}");
    assert!(changed > 0 && to_four < 0.1 * to_one, "the page does not draw silhouette pixels as the mean of 4 rays ({to_four} vs {to_one} over {changed} pixels)");

    // The diffuse twin draws what the CPU reference draws of it.
    let r = page("b");
    assert_eq!(r["error"], serde_json::Value::Null, "page error (diffuse asset): {}", r["error"]);
    let rgba = r["lastRender"]["rgba"].as_array().unwrap();
    let reference = snerf_asset::render(&snerf_asset::Asset::read(assets.join("b.snerf")).unwrap(), &cam, 0.0);
    assert!(reference.opacity.iter().any(|&o| o > 0.5), "the camera sees the object");
    let mut diff = 0.0f64;
    for p in 0..24 * 16 {
        for c in 0..3 {
            diff += (rgba[4 * p + c].as_f64().unwrap() - reference.rgb[p * 3 + c] as f64).abs() * 255.0;
        }
    }
    let diff = diff / (24.0 * 16.0 * 3.0);
    let apart = four.rgb.iter().zip(&reference.rgb).map(|(a, b)| (a - b).abs() as f64 * 255.0).sum::<f64>() / (24.0 * 16.0 * 3.0);
    eprintln!("diffuse asset: page vs CPU reference mean |diff| {diff:.3} (of 255); the full asset's image is {apart:.3} away");
    assert!(diff <= 2.0, "diffuse asset: mean |diff| {diff} > 2/255");
    // closer to the diffuse reference than the full asset's own image is (the page drew the
    // diffuse file, and drew it without the view MLP)
    assert!(diff < 0.5 * apart, "diffuse asset: the page is {diff} from the diffuse reference, the full image {apart}");
    drop(server);
}
