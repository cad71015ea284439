//! Styles as layers of one asset, end to end: `snerf stylize --style A --style B` writes one
//! appearance-only stylization per style, `snerf bake` turns them into one multi-style
//! asset, `snerf inspect` lists the styles with their bytes, `snerf render --style` draws
//! one; a layer trained on another geometry, or one that has not finished, is refused with
//! the layer and the problem named.

use std::path::Path;
use std::process::Output;

use snerf_files::ScratchDir;

mod common;
use common::{fails, ok, snerf};

fn stylize(run: &Path, out: &Path, styles: &[&Path], extra: &[&str]) -> Output {
    let mut c = snerf();
    c.args(["--json", "stylize"]).arg(run).arg("--out").arg(out);
    for s in styles {
        c.arg("--style").arg(s);
    }
    // colour transfer and no style meters (no model directory): seconds a stylization
    c.args(["--stylizer", "color", "--rounds", "1", "--steps-per-round", "5", "--consistency-frames", "0"]);
    c.arg("--models").arg(out.with_extension("no-models")).args(extra);
    c.output().unwrap()
}

#[test]
fn two_styles_stylize_bake_inspect_and_render_as_layers_of_one_asset() {
    let d = ScratchDir::new("snerf-style-layers", "cli").unwrap();
    let data = d.join("data");
    ok(snerf().args(["--json", "scene", "object", "--out"]).arg(&data).args(["--views", "16", "--test-views", "2", "--size", "32x32"]).output().unwrap());
    let run = d.join("run");
    ok(snerf().args(["--json", "train"]).arg(&data).arg("--out").arg(&run).args(["--steps", "40"]).output().unwrap());
    let (warm, cold) = (d.join("warm.png"), d.join("cold.png"));
    image::RgbImage::from_fn(16, 16, |x, y| image::Rgb([200 + (x * 3) as u8, 90 + (y * 4) as u8, 20])).save(&warm).unwrap();
    image::RgbImage::from_fn(16, 16, |x, y| image::Rgb([20, 60 + (x * 4) as u8, 180 + (y * 3) as u8])).save(&cold).unwrap();

    // several styles are refused inside the run, before anything is written there
    fails(stylize(&run, &run.join("styles"), &[&warm, &cold], &[]), &["--out"]);
    assert!(!run.join("styles").exists());
    let srun = d.join("srun");
    let s = ok(stylize(&run, &srun, &[&warm, &cold], &[]));
    let layers = s["layers"].as_array().unwrap();
    assert_eq!(layers.iter().map(|l| l["name"].as_str().unwrap()).collect::<Vec<_>>(), ["warm", "cold"], "{s}");
    assert!(layers.iter().all(|l| l["seconds"].as_f64().unwrap() > 0.0));
    // where each layer's time went: render, stylize and train, within its wall time
    for l in layers {
        let t = &l["time"];
        let parts: Vec<f64> = ["render_seconds", "stylize_seconds", "train_seconds", "other_seconds"].iter().map(|k| t[k].as_f64().unwrap()).collect();
        assert!(parts[..3].iter().all(|&x| x > 0.0), "{t}");
        assert!((parts.iter().sum::<f64>() - t["wall_seconds"].as_f64().unwrap()).abs() < 1e-6, "{t}");
    }
    // a layer's defaults where the command line gives none (--views), what it gives elsewhere
    let plan = serde_json::json!({ "views": snerf_stylize::layers::LAYER_DEFAULTS.views, "steps_per_round": 5, "consistency_frames": 0 });
    assert_eq!(s["plan"], plan, "{s}");
    for name in ["warm", "cold"] {
        let rec: serde_json::Value = serde_json::from_slice(&std::fs::read(srun.join("layers").join(name).join("stylize.json")).unwrap()).unwrap();
        assert_eq!(rec["options"]["appearance_only"], true, "several styles are always appearance-only: {rec}");
        assert_eq!((&rec["options"]["views"], &rec["options"]["steps_per_round"]), (&plan["views"], &plan["steps_per_round"]), "{rec}");
    }

    let asset = d.join("styles.snerf");
    let b = ok(snerf().args(["--json", "bake"]).arg(&srun).arg("--out").arg(&asset).args(["--resolution", "32", "--eval-views", "0", "--visibility-views", "4"]).output().unwrap());
    assert_eq!(b["asset"]["styles"].as_array().unwrap().len(), 2, "{b}");
    let i = ok(snerf().args(["--json", "inspect"]).arg(&asset).output().unwrap());
    let styles = i["summary"]["styles"].as_array().unwrap();
    assert_eq!(styles.iter().map(|s| s["name"].as_str().unwrap()).collect::<Vec<_>>(), ["warm", "cold"]);
    let total = i["summary"]["bytes"]["total"].as_u64().unwrap();
    assert!(styles.iter().all(|s| s["bytes"].as_u64().unwrap() > 0 && s["bytes"].as_u64().unwrap() < total / 2), "{i}");
    // each style as the CPU reference draws it; the two differ
    let frame = |style: &str| {
        let out = d.join(format!("render-{style}"));
        ok(snerf().args(["--json", "render"]).arg(&asset).args(["--style", style, "--frames", "1", "--size", "24x24"]).arg("--out").arg(&out).output().unwrap());
        image::open(out.join("frame_000.png")).unwrap().to_rgb8().into_raw()
    };
    let (fw, fc) = (frame("warm"), frame("cold"));
    let red = |f: &[u8]| f.chunks_exact(3).map(|p| p[0] as i64 - p[2] as i64).sum::<i64>();
    assert!(red(&fw) > red(&fc), "the warm style draws redder than the cold one");
    fails(snerf().args(["render"]).arg(&asset).args(["--style", "blue", "--out"]).arg(d.join("r")).output().unwrap(), &["styles.snerf", "\"blue\"", "warm, cold"]);

    // a layer whose geometry moved (stylized without --appearance-only) is refused by name
    let moved = d.join("moved");
    std::fs::create_dir_all(moved.join("layers")).unwrap();
    std::fs::copy(srun.join("layers.json"), moved.join("layers.json")).unwrap();
    ok(stylize(&run, &moved.join("layers/warm"), &[&warm], &["--appearance-only"]));
    ok(stylize(&run, &moved.join("layers/cold"), &[&cold], &[]));
    fails(
        snerf().args(["bake"]).arg(&moved).arg("--out").arg(d.join("moved.snerf")).args(["--resolution", "32", "--eval-views", "0"]).output().unwrap(),
        &["layer \"cold\" was trained on another geometry than layer \"warm\"", "--appearance-only"],
    );
    // ... and so is one that has not finished
    std::fs::remove_dir_all(moved.join("layers/cold")).unwrap();
    fails(
        snerf().args(["bake"]).arg(&moved).arg("--out").arg(d.join("moved.snerf")).args(["--resolution", "32"]).output().unwrap(),
        &["layer \"cold\" has no checkpoint"],
    );
}
