//! `snerf export-gltf --format splats` in a real engine: an asset -> the CLI's
//! KHR_gaussian_splatting .glb -> Babylon.js (npm babylonjs + babylonjs-loaders, its own glTF
//! loader and Gaussian-splat renderer) in headless Debian Chromium (WebGL2 on SwiftShader),
//! camera placed exactly at `snerf render`'s orbit poses in a right-handed scene -> PSNR
//! against the CPU reference render of the same asset at the same poses
//! (tests/splats/babylon_render.mjs). Also the command's errors on bad input.
//!
//! Needs Chromium, playwright-core (target/test-assets/playwright) and Babylon.js
//! (target/test-assets/babylon), which `.ci/run` installs; skips with a message without them,
//! unless SNERF_REQUIRE_SPLAT_ENGINE=1 (CI), where it fails.
mod common;
use common::{ok, snerf};

use std::path::{Path, PathBuf};
use std::process::Command;

use snerf_asset::render::{self as asset_render};
use snerf_asset::{encode_voxel, Asset, AssetBuilder, Header, Kind, ViewMlp};
use snerf_files::ScratchDir;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// (playwright dir, babylon dir) or None (skip) when a part is missing.
fn engine() -> Option<(PathBuf, PathBuf)> {
    let chromium = std::env::var_os("SNERF_CHROMIUM")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/usr/bin/chromium"));
    let pw = root().join("target/test-assets/playwright");
    let bab = root().join("target/test-assets/babylon");
    let why = if !chromium.exists() {
        format!("no Chromium at {}", chromium.display())
    } else if !pw.join("node_modules/playwright-core/package.json").exists() {
        format!("no playwright-core under {}", pw.display())
    } else if !bab.join("node_modules/babylonjs-loaders/package.json").exists() {
        format!("no babylonjs-loaders under {}", bab.display())
    } else if Command::new("node").arg("--version").output().is_err() {
        "no node".to_string()
    } else {
        return Some((pw, bab));
    };
    if std::env::var("SNERF_REQUIRE_SPLAT_ENGINE").as_deref() == Ok("1") {
        panic!("SNERF_REQUIRE_SPLAT_ENGINE=1 but {why} (.ci/run installs it)");
    }
    eprintln!("skipping the splat engine test: {why} (.ci/run installs chromium, playwright-core and babylonjs)");
    None
}

/// A stylized object: a sphere with painted bands (hard colour edges finer than the sphere),
/// a soft, semi-transparent halo box beside it and a thin slab, in a world frame that is
/// rotated, scaled and offset from the grid (so any axis or rotation slip shows).
pub fn painted_asset() -> Asset {
    let res = 64u32;
    let mut h = Header::new(Kind::Object, res, 8);
    h.density = snerf_asset::DensityRange {
        logit_min: -8.0,
        logit_max: 6.0,
    };
    let (c, s) = (0.5f32.cos(), 0.5f32.sin());
    h.space.rot = [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]];
    h.space.scale = 2.0;
    h.space.center = [0.3, 1.0, -0.2];
    h.background = [1.0, 1.0, 1.0];
    let d = h.density;
    let centre = move |i: usize| -1.0 + (i as f32 + 0.5) * 2.0 / res as f32;
    let voxel = move |v: [usize; 3]| {
        let g = v.map(centre);
        let r = ((g[0] + 0.2).powi(2) + g[1].powi(2) + g[2].powi(2)).sqrt();
        // sphere of radius 0.5, surface over ~1 voxel
        let sphere = (0.5 - r) / (2.0 / res as f32);
        let band = ((g[1] * 6.0).floor() as i32).rem_euclid(3);
        let paint = match band {
            0 => [0.85, 0.2, 0.15],
            1 => [0.95, 0.8, 0.2],
            _ => [0.15, 0.3, 0.8],
        };
        // semi-transparent box at x in [0.45, 0.85]
        let in_box = g[0] > 0.45 && g[0] < 0.85 && g[1].abs() < 0.2 && g[2].abs() < 0.2;
        // thin slab (2 voxels) above
        let in_slab = g[1] > 0.6 && g[1] < 0.6 + 4.0 / res as f32 && g[0].abs() < 0.5 && g[2].abs() < 0.4;
        if sphere > -1.5 {
            encode_voxel((3.0 * sphere).clamp(-8.0, 6.0), paint, [0.0; 4], &d)
        } else if in_box {
            encode_voxel(0.5, [0.2, 0.7, 0.3], [0.0; 4], &d)
        } else if in_slab {
            encode_voxel(4.0, [0.5, 0.2, 0.6], [0.0; 4], &d)
        } else {
            encode_voxel(-8.0, [0.0; 3], [0.0; 4], &d)
        }
    };
    let mut b = AssetBuilder::new(h, ViewMlp::zeros()).unwrap();
    b.fill_from_fn(0, voxel).unwrap();
    b.finish().unwrap()
}

fn psnr(a: &[f32], b: &[f32]) -> f64 {
    let mse: f64 = a.iter().zip(b).map(|(x, y)| ((x - y) as f64).powi(2)).sum::<f64>() / a.len() as f64;
    10.0 * (1.0 / mse.max(1e-12)).log10()
}

/// Renders `glb` in Babylon.js at `n` of the asset's orbit poses and returns the PSNR of each
/// frame against the CPU reference, and the engine's load time (ms).
pub fn engine_psnr(asset: &Asset, glb: &Path, dir: &Path, n: usize, size: u32) -> Option<(Vec<f64>, f64)> {
    let (pw, bab) = engine()?;
    let cams: Vec<_> = (0..n).map(|i| asset_render::orbit(&asset.header, n, i, size, size, 40.0)).collect();
    let poses = serde_json::json!({
        "width": size, "height": size, "fov_y": 40.0,
        "background": asset.header.background,
        "poses": cams.iter().map(|c| c.c2w).collect::<Vec<_>>(),
    });
    let poses_file = dir.join("poses.json");
    std::fs::write(&poses_file, poses.to_string()).unwrap();
    let prefix = dir.join("engine_");
    let out = Command::new("node")
        .arg(root().join("tests/splats/babylon_render.mjs"))
        .args([&pw, &bab, &glb.to_path_buf(), &poses_file])
        .arg(format!("{}", prefix.display()))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "babylon_render.mjs failed: {}{}",
        String::from_utf8_lossy(&out.stderr),
        String::from_utf8_lossy(&out.stdout)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("babylon_render.mjs prints JSON");
    let mut scores = vec![];
    for (i, cam) in cams.iter().enumerate() {
        let reference = asset_render::render(asset, cam, 0.0);
        asset_render::write_png(&reference, dir.join(format!("reference_{i}.png"))).unwrap();
        let img = image::open(dir.join(format!("engine_{i}.png"))).unwrap().to_rgb8();
        assert_eq!((img.width(), img.height()), (size, size), "the engine's frame has the wrong size");
        let rgb: Vec<f32> = img.as_raw().iter().map(|&v| v as f32 / 255.0).collect();
        scores.push(psnr(&rgb, &reference.rgb));
    }
    Some((scores, report["load_ms"].as_f64().unwrap_or(f64::NAN)))
}

/// The engine's PSNR the test holds on the painted asset at three orbit poses (measured
/// 27.1 / 28.8 / 28.4 dB: its one-voxel slab and hard paint edges are harder than trained
/// surfaces, which reach 29.8 to 36.4 dB, BENCH.md §6b).
const BAR_DB: f64 = 26.0;

#[test]
fn babylon_renders_the_exported_splats_like_the_cpu_reference() {
    if engine().is_none() {
        return;
    }
    let d = ScratchDir::new("snerf-splats", "engine").unwrap();
    let asset = painted_asset();
    let file = (&*d).join("painted.snerf");
    asset.write(&file).unwrap();
    let glb = (&*d).join("painted.glb");
    let r = ok(snerf()
        .args(["--json", "export-gltf"])
        .arg(&file)
        .args(["--format", "splats", "--out"])
        .arg(&glb)
        .output()
        .unwrap());
    assert!(r["splats"].as_u64().unwrap() > 1000, "{r}");
    let (scores, load_ms) = engine_psnr(&asset, &glb, &d, 3, 160).unwrap();
    println!("engine vs CPU reference PSNR at 3 orbit poses: {scores:?} dB; load {load_ms:.0} ms; {r}");
    for (i, s) in scores.iter().enumerate() {
        assert!(
            *s >= BAR_DB,
            "pose {i}: Babylon.js frame vs CPU reference {s:.2} dB < {BAR_DB} (frames in {})",
            (&*d).display()
        );
    }
}

#[test]
fn bad_input_gets_a_clear_error_and_nothing_is_written() {
    let d = ScratchDir::new("snerf-splats", "bad-input").unwrap();
    // an asset with no occupied voxel
    let h = Header::new(Kind::Object, 32, 8);
    let dens = h.density;
    let mut b = AssetBuilder::new(h, ViewMlp::zeros()).unwrap();
    b.fill_from_fn(0, |_| encode_voxel(-10.0, [0.0; 3], [0.0; 4], &dens)).unwrap();
    let empty = b.finish().unwrap();
    let empty_file = (&*d).join("empty.snerf");
    empty.write(&empty_file).unwrap();
    let out = (&*d).join("out.glb");
    let r = snerf()
        .arg("export-gltf")
        .arg(&empty_file)
        .args(["--format", "splats", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        !r.status.success() && err.contains("empty.snerf") && err.contains("no occupied voxels"),
        "{err}"
    );
    assert!(!out.exists(), "an empty asset wrote {}", out.display());

    let file = (&*d).join("painted.snerf");
    painted_asset().write(&file).unwrap();
    let r = snerf()
        .arg("export-gltf")
        .arg(&file)
        .args(["--format", "splats", "--max-splats", "0", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("--max-splats 0"), "{err}");
    assert!(!out.exists());

    let before = std::fs::read(&file).unwrap();
    let r = snerf()
        .arg("export-gltf")
        .arg(&file)
        .args(["--format", "splats", "--out"])
        .arg(&file)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("--out"), "{err}");
    assert_eq!(std::fs::read(&file).unwrap(), before, "the input was overwritten");

    // a budget is met, and the JSON summary says so
    let r = ok(snerf()
        .args(["--json", "export-gltf"])
        .arg(&file)
        .args(["--format", "splats", "--max-splats", "2000", "--out"])
        .arg(&out)
        .output()
        .unwrap());
    assert!(r["splats"].as_u64().unwrap() <= 2000 && r["splats"].as_u64().unwrap() > 1000, "{r}");
    assert_eq!(r["bytes"].as_u64().unwrap(), std::fs::metadata(&out).unwrap().len());
    assert!(r["bytes_per_splat"].as_f64().unwrap() > 40.0);
}

/// BENCH.md §6b: `SNERF_SPLAT_BENCH=a.snerf,b.snerf cargo test --release --test splats_engine
/// -- --ignored bench --nocapture` exports each asset with the CLI and prints one table row:
/// splats, bytes, bytes per splat, size against the .snerf, export seconds, the engine's load
/// time and its PSNR against the CPU reference at 3 orbit poses (192×192).
/// `SNERF_SPLAT_BENCH_MAX=N` exports with `--max-splats N`.
#[test]
#[ignore]
fn bench_splats_on_assets() {
    let list = std::env::var("SNERF_SPLAT_BENCH").expect("SNERF_SPLAT_BENCH=a.snerf,b.snerf");
    let d = ScratchDir::new("snerf-splats", "bench").unwrap();
    println!("| asset | voxels | splats | MB | B/splat | ÷ .snerf | export s | load ms | PSNR at 3 poses (dB) | mean | worst |");
    println!("|---|---|---|---|---|---|---|---|---|---|---|");
    for (k, file) in list.split(',').enumerate() {
        let file = PathBuf::from(file);
        let asset = Asset::read(&file).unwrap();
        let glb = d.join(format!("a{k}.glb"));
        let t0 = std::time::Instant::now();
        let mut cmd = snerf();
        cmd.args(["--json", "export-gltf"]).arg(&file).args(["--format", "splats", "--out"]).arg(&glb);
        if let Ok(max) = std::env::var("SNERF_SPLAT_BENCH_MAX") {
            cmd.args(["--max-splats", &max]);
        }
        let r = ok(cmd.output().unwrap());
        let secs = t0.elapsed().as_secs_f64();
        let sub = d.join(format!("a{k}"));
        std::fs::create_dir_all(&sub).unwrap();
        let (scores, load_ms) = engine_psnr(&asset, &glb, &sub, 3, 192).unwrap();
        let mean = scores.iter().sum::<f64>() / scores.len() as f64;
        let worst = scores.iter().cloned().fold(f64::INFINITY, f64::min);
        println!(
            "| {} | {} | {} | {:.2} | {:.1} | {:.2} | {:.2} | {:.0} | {} | {:.2} | {:.2} |",
            file.display(),
            r["report"]["conversion"]["voxels"],
            r["splats"],
            r["bytes"].as_f64().unwrap() / 1e6,
            r["bytes_per_splat"].as_f64().unwrap(),
            r["size_ratio"].as_f64().unwrap(),
            secs,
            load_ms,
            scores.iter().map(|s| format!("{s:.2}")).collect::<Vec<_>>().join(" / "),
            mean,
            worst
        );
    }
}
