//! End-to-end tests of the `snerf` command: scene -> train -> eval -> resume -> demo, and
//! what bad input gets (a clear error naming the file, a non-zero exit, nothing lost).

use std::path::{Path, PathBuf};
use std::process::Command;

use snerf_files::ScratchDir;

mod common;
use common::{fails, ok, snerf};

/// This test's directory: removed when it passes, kept (and named) when it fails.
fn tmp(name: &str) -> ScratchDir {
    ScratchDir::new("snerf-cli", name).unwrap()
}

fn scene(name: &str, dir: &Path, views: usize, size: &str) -> serde_json::Value {
    ok(snerf()
        .args(["--json", "scene", name, "--out"])
        .arg(dir)
        .args(["--views", &views.to_string(), "--test-views", "4", "--size", size, "--supersample", "2"])
        .output()
        .unwrap())
}

fn metrics(run: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(run.join("metrics.json")).unwrap()).unwrap()
}

#[test]
fn scene_train_eval_resume_on_the_object_scene() {
    let d = tmp("object");
    let data = d.join("data");
    let s = scene("object", &data, 30, "48x48");
    assert_eq!(s["kind"], "object");
    let info = ok(snerf().args(["--json", "data"]).arg(&data).output().unwrap());
    assert_eq!(info["kind"], "object");
    assert_eq!(info["counts"]["train"], 30);

    let run = d.join("run");
    let t = ok(snerf().args(["--json", "train"]).arg(&data).arg("--out").arg(&run).args(["--steps", "60"]).output().unwrap());
    assert_eq!(t["metrics"]["step"], 60);
    let m = metrics(&run);
    let curve = m["curve"].as_array().unwrap();
    let last = curve.last().unwrap()["test_psnr"].as_f64().unwrap();
    assert!(last > 16.0, "60 steps should reach a recognisable image, got {last:.2} dB");

    // an existing run is never silently overwritten
    fails(
        snerf().arg("train").arg(&data).arg("--out").arg(&run).args(["--steps", "5"]).output().unwrap(),
        &["already exists", "--resume"],
    );
    // resume continues the same run to a larger step budget and keeps improving
    let t2 =
        ok(snerf().args(["--json", "train"]).arg(&data).arg("--out").arg(&run).args(["--steps", "120", "--resume"]).output().unwrap());
    assert_eq!(t2["metrics"]["step"], 120);
    let later = metrics(&run)["curve"].as_array().unwrap().last().unwrap()["test_psnr"].as_f64().unwrap();
    assert!(later > last, "resumed training improves: {last:.2} -> {later:.2}");

    let e = ok(snerf().args(["--json", "eval"]).arg(&run).arg(&data).output().unwrap());
    let psnr = e["report"]["mean_psnr"].as_f64().unwrap();
    let ssim = e["report"]["mean_ssim"].as_f64().unwrap();
    assert!(psnr > 18.0 && ssim > 0.5 && ssim <= 1.0, "psnr {psnr} ssim {ssim}");
    assert_eq!(e["report"]["views"].as_array().unwrap().len(), 4);
    // The march's cost per view: some samples on every view (the object is in each), and no
    // more than a ray through the whole box at every one of a silhouette pixel's 4 rays.
    for v in e["report"]["views"].as_array().unwrap() {
        let spp = v["samples_per_pixel"].as_f64().unwrap();
        assert!(spp > 1.0 && spp < 512.0 * 4.0, "samples per pixel {spp}");
    }
    assert!(e["report"]["pixels_per_second"].as_f64().unwrap() > 0.0);
    let img = image::open(run.join("eval/r_000.png")).unwrap();
    assert_eq!((img.width(), img.height()), (48 * 3, 48), "prediction | truth | depth");
}

#[test]
fn killed_training_resumes_from_its_last_checkpoint() {
    let d = tmp("kill");
    let data = d.join("data");
    scene("object", &data, 20, "32x32");
    let run = d.join("run");
    let mut child = snerf()
        .arg("train")
        .arg(&data)
        .arg("--out")
        .arg(&run)
        .args(["--minutes", "10", "--checkpoint-every", "0.5"])
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let ck = run.join("checkpoint.snerfck");
    let t0 = std::time::Instant::now();
    while !ck.exists() && t0.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    std::thread::sleep(std::time::Duration::from_millis(300));
    child.kill().unwrap(); // SIGKILL: no chance to clean up
    child.wait().unwrap();
    assert!(ck.exists(), "a checkpoint was written before the kill");
    let step_at_kill = metrics(&run)["step"].as_u64().unwrap();
    assert!(step_at_kill > 0);
    // no temp files are left looking like results
    for e in std::fs::read_dir(&run).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().to_string();
        assert!(!name.ends_with(".snerfck") || name == "checkpoint.snerfck", "{name}");
    }
    let target = step_at_kill + 20;
    let t = ok(snerf()
        .args(["--json", "train"])
        .arg(&data)
        .arg("--out")
        .arg(&run)
        .args(["--resume", "--steps", &target.to_string()])
        .output()
        .unwrap());
    assert!(t["metrics"]["step"].as_u64().unwrap() >= target);
}

#[test]
fn every_scene_kind_is_detected_and_trains() {
    for (name, kind, dynamic) in [("room", "forward", false), ("outdoor", "unbounded", false), ("avatar", "object", true)] {
        let d = tmp(name);
        let data = d.join("data");
        scene(name, &data, 16, "40x32");
        let info = ok(snerf().args(["--json", "data"]).arg(&data).output().unwrap());
        assert_eq!(info["kind"], kind, "{name}");
        assert_eq!(info["dynamic"], dynamic, "{name}");
        let run = d.join("run");
        let t = ok(snerf().args(["--json", "train"]).arg(&data).arg("--out").arg(&run).args(["--steps", "30"]).output().unwrap());
        let curve = t["metrics"]["curve"].as_array().unwrap();
        let first = curve.first().unwrap()["test_psnr"].as_f64().unwrap();
        let last = curve.last().unwrap()["test_psnr"].as_f64().unwrap();
        assert!(last.is_finite() && last > first, "{name}: {first:.2} -> {last:.2} dB");
        let config: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).unwrap()).unwrap();
        let has_time_planes = !config["train"]["field"]["time_resolutions"].as_array().unwrap().is_empty();
        assert_eq!(has_time_planes, dynamic, "{name}: time inputs only for dynamic scenes");
    }
}

/// A built-in scene at 40x32 trained for `steps` in `d/run`, and a style picture of strong
/// colours in `d/style.png` (colour transfer then moves every frame's colours).
fn trained_run_and_style(d: &Path, name: &str, views: usize, steps: u32) -> (PathBuf, PathBuf) {
    let data = d.join("data");
    scene(name, &data, views, "40x32");
    let run = d.join("run");
    ok(snerf().args(["--json", "train"]).arg(&data).arg("--out").arg(&run).args(["--steps", &steps.to_string()]).output().unwrap());
    let style = d.join("style.png");
    image::RgbImage::from_fn(16, 16, |x, y| image::Rgb([(x * 16) as u8, (y * 16) as u8, 200])).save(&style).unwrap();
    (run, style)
}

/// `snerf stylize` with colour transfer, short rounds and no per-round measurement.
fn colour_stylize(run: &Path, style: &Path, out: &Path, rounds: usize, extra: &[&str]) -> serde_json::Value {
    ok(snerf()
        .args(["--json", "stylize"])
        .arg(run)
        .arg("--out")
        .arg(out)
        .arg("--style")
        .arg(style)
        .args(["--stylizer", "color", "--rounds", &rounds.to_string(), "--steps-per-round", "5", "--consistency-frames", "0"])
        .args(extra)
        .output()
        .unwrap())
}

#[test]
fn an_animated_scene_is_scored_for_temporal_flicker_and_a_static_one_is_not() {
    let d = tmp("flicker");
    let (run, style) = trained_run_and_style(&d, "avatar", 16, 40);
    let srun = d.join("styl");
    colour_stylize(&run, &style, &srun, 1, &[]);
    let c = ok(snerf().args(["--json", "consistency"]).arg(&srun).args(["--frames", "4", "--time-frames", "5"]).output().unwrap());
    let t = &c["temporal"];
    let flicker: Vec<f64> = t["methods"].as_array().unwrap().iter().map(|m| m["flicker"].as_f64().unwrap()).collect();
    assert_eq!(flicker.len(), 3, "{t}");
    let still = t["still_fraction"].as_f64().unwrap();
    assert!(still > 0.0 && still < 1.0, "{t}");
    // the realistic frames change by less than STILL on the pixels scored; colour transfer
    // of each instant on its own changes them by more
    assert!(flicker[0] < 0.02 * 0.02 && flicker[1] > flicker[0], "{t}");
    assert!(std::fs::read_to_string(srun.join("consistency.md")).unwrap().contains("Temporal flicker"));
    // one instant has no neighbour to compare with: refused, not silently skipped
    fails(snerf().args(["consistency"]).arg(&srun).args(["--time-frames", "1"]).output().unwrap(), &["--time-frames 1", "2 or more"]);
}

/// `snerf bake --at-time T` freezes one instant of a 4D run into a static asset (the "one
/// static frame" a 4D asset's size is reported against), and the 4D bake records that frame's
/// blocks; `--static` on a 4D run, a time outside the run's range, or `--at-time` on a static
/// run are refused by name.
#[test]
fn a_4d_run_bakes_one_instant_as_a_static_asset() {
    let d = tmp("at-time");
    let (run, _) = trained_run_and_style(&d, "avatar", 16, 40);
    let small = ["--resolution", "32", "--visibility-views", "4", "--eval-views", "1"];
    let anim = ok(snerf().args(["--json", "bake"]).arg(&run).arg("--out").arg(d.join("anim.snerf")).args(small).args(["--keyframes", "4"]).output().unwrap());
    let frame_blocks: Vec<f64> = anim["report"]["frame_blocks"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert_eq!(frame_blocks.len(), 4, "{anim}");
    let config: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).unwrap()).unwrap();
    let range = &config["space"]["time_range"];
    let (lo, hi) = (range[0].as_f64().unwrap(), range[1].as_f64().unwrap());
    // keyframe 2 of 4 is at 2/3 of the time range
    let t = lo + (hi - lo) * 2.0 / 3.0;
    let one = ok(snerf().args(["--json", "bake"]).arg(&run).arg("--out").arg(d.join("one.snerf")).args(small).args(["--at-time", &t.to_string()]).output().unwrap());
    assert_eq!(one["asset"]["frames"].as_u64(), Some(1), "{one}");
    assert!((one["at_time"].as_f64().unwrap() - t).abs() < 1e-6 && anim["at_time"].is_null(), "{one}");
    assert!(one["asset"]["animation_seconds"].is_null(), "a frozen instant has no time: {one}");
    let info = ok(snerf().args(["--json", "inspect"]).arg(d.join("one.snerf")).output().unwrap());
    assert!(info["summary"]["animation_seconds"].is_null(), "{info}");
    // scored against the field at that instant (a coarse 32³ bake of a 40-step field)
    let f = &one["faithfulness"];
    assert!((f["views"][0]["time"].as_f64().unwrap() - t).abs() < 1e-4, "{one}");
    assert!(f["mean_baked_vs_field"].as_f64().unwrap() > 15.0, "{one}");
    // the 4D asset is measured against the blocks such bakes keep, averaged over its keyframes
    let blocks = one["report"]["atlas_blocks"].as_f64().unwrap();
    assert!((blocks - frame_blocks[2]).abs() <= 0.1 * frame_blocks[2], "{blocks} blocks frozen, {} at keyframe 2", frame_blocks[2]);
    let mean = frame_blocks.iter().sum::<f64>() / 4.0;
    let header = std::fs::read(d.join("anim.snerf")).unwrap();
    let head = String::from_utf8_lossy(&header[..header.len().min(4096)]).to_string();
    assert!(head.contains("static_frame_blocks"), "{head}");
    let est = anim["report"]["static_frame_bytes"].as_f64().unwrap();
    let summary = anim["asset"]["static_frame_bytes"].as_f64().unwrap();
    assert!((est - summary).abs() < 0.02 * summary, "bake {est} vs asset summary {summary} (mean {mean} blocks)");
    fails(snerf().args(["bake"]).arg(&run).arg("--out").arg(d.join("x.snerf")).arg("--static").output().unwrap(), &["4D run", "--at-time"]);
    fails(snerf().args(["bake"]).arg(&run).arg("--out").arg(d.join("x.snerf")).args(["--at-time", "7"]).output().unwrap(), &["--at-time 7", "outside"]);
    let (still, _) = trained_run_and_style(&d.join("still"), "object", 8, 10);
    fails(snerf().args(["bake"]).arg(&still).arg("--out").arg(d.join("x.snerf")).args(["--at-time", "0.5"]).output().unwrap(), &["--at-time 0.5", "static run"]);
    assert!(!d.join("x.snerf").exists());
}

/// `snerf stylize` paints at its own size cap (`--max-size`, recorded in stylize.json), and
/// `snerf consistency` loads the data at the size the run painted at: the last targets are
/// scored carried onto the path only when their size matches the views'.
#[test]
fn a_stylization_paints_at_its_size_cap_and_is_scored_at_it() {
    let d = tmp("stylize-size");
    let (run, style) = trained_run_and_style(&d, "object", 12, 20);
    let stylize = |out: &Path, extra: &[&str]| colour_stylize(&run, &style, out, 1, extra);
    let small = d.join("small");
    let s = stylize(&small, &["--max-size", "20"]);
    assert_eq!(s["state"]["options"]["max_size"], 20, "{s}");
    let target = image::open(small.join("targets/round_1/view_000.png")).unwrap();
    assert_eq!((target.width(), target.height()), (20, 16), "the loop paints and trains at the cap");
    let c = ok(snerf().args(["--json", "consistency"]).arg(&small).args(["--frames", "3"]).output().unwrap());
    assert!(c.to_string().contains("Last targets carried"), "consistency loads the data at the run's size: {c}");
    // without --max-size: stylize's own default, which leaves 40x32 as it is
    let full = d.join("full");
    let s = stylize(&full, &[]);
    assert_eq!(s["state"]["options"]["max_size"], snerf_stylize::snerf_loop::DEFAULT_MAX_SIZE, "{s}");
    let target = image::open(full.join("targets/round_1/view_000.png")).unwrap();
    assert_eq!((target.width(), target.height()), (40, 32));
    // a run recorded before the cap existed (no max_size) resumes as it was, without --max-size
    let state = full.join("stylize.json");
    let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&state).unwrap()).unwrap();
    v["options"].as_object_mut().unwrap().remove("max_size");
    std::fs::write(&state, v.to_string()).unwrap();
    let s = colour_stylize(&run, &style, &full, 2, &[]);
    assert_eq!(s["state"]["rounds_done"], 2, "{s}");
    assert!(s["state"]["options"]["max_size"].is_null(), "{s}");
}

#[test]
fn demo_writes_pictures_and_a_summary() {
    let d = tmp("demo");
    let out = d.join("demo");
    let run = snerf()
        .args(["--json", "demo", "--out"])
        .arg(&out)
        .args(["--minutes", "0.15", "--views", "20", "--size", "32x32", "--frames", "4"])
        .args(["--rounds", "2", "--steps-per-round", "10"])
        .output()
        .unwrap();
    let banner = String::from_utf8_lossy(&run.stderr).to_string();
    let s = ok(run);
    assert!(s["eval"]["mean_psnr"].as_f64().unwrap() > 12.0);
    // the banner says what ran: the paper's loop, the stylizer painting every view each round
    assert!(banner.contains("SNeRF: 2 rounds of render -> stylize ("), "{banner}");
    let record: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("stylized/stylize.json")).unwrap()).unwrap();
    let painted: Vec<u64> = record["records"].as_array().unwrap().iter().map(|r| r["stylized_views"].as_u64().unwrap()).collect();
    assert!(painted.len() == 2 && painted.iter().all(|&n| n > 0 && n == painted[0]), "views the stylizer painted in each round: {painted:?}");
    // stylized, measured, baked, rendered and exported
    assert!(out.join("stylized/consistency.md").exists());
    assert!(out.join("baked_turntable/preview.png").exists());
    assert!(out.join("stylized.glb").exists());
    let asset = out.join("stylized.snerf");
    let info = ok(snerf().args(["--json", "inspect"]).arg(&asset).output().unwrap());
    assert_eq!(info["summary"]["frames"].as_u64(), Some(1), "{info}");
    // the stylized field is diffuse, so its asset leaves out the view MLP and the features
    assert!(snerf_asset::Asset::read(&asset).unwrap().header.diffuse, "the stylized asset is not diffuse");
    assert_eq!((info["summary"]["diffuse"].as_bool(), info["summary"]["bytes"]["mlp"].as_u64()), (Some(true), Some(0)), "{info}");
    // a file that is not an asset: a clear error naming it
    fails(snerf().args(["inspect"]).arg(out.join("summary.json")).output().unwrap(), &["summary.json"]);
    // the sheet has the training curve beside the held-out views (no empty band), and the
    // report of the whole path is beside it
    let sheet = image::open(out.join("contact_sheet.png")).unwrap().to_rgb8();
    let blue = (sheet.width() / 2..sheet.width()).flat_map(|x| (0..96).map(move |y| (x, y))).filter(|&(x, y)| sheet.get_pixel(x, y).0 == [31, 119, 180]).count();
    assert!(blue > 100, "the training curve is drawn right of the held-out views ({blue} pixels of its colour)");
    let report: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let ids: Vec<&str> = report["plots"].as_array().unwrap().iter().map(|p| p["id"].as_str().unwrap()).collect();
    for id in ["psnr", "ssim", "stylize_fit", "bake_faithfulness"] {
        assert!(ids.contains(&id), "{id} in {ids:?}");
    }
    assert!(std::fs::read_to_string(out.join("report.html")).unwrap().contains("data:image/png;base64,"));
    assert!(out.join("turntable/frame_003.png").exists());
    assert!(out.join("summary.json").exists());
    // running it again over its own output works; over someone else's directory it refuses
    let other = d.join("not-a-demo");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("precious.txt"), "keep me").unwrap();
    fails(snerf().args(["demo", "--out"]).arg(&other).args(["--minutes", "0.05"]).output().unwrap(), &["not-a-demo"]);
    assert!(other.join("precious.txt").exists());
}

#[test]
fn bad_input_gets_a_clear_error_naming_the_file() {
    let d = tmp("bad");
    // a dataset directory that does not exist
    fails(snerf().arg("train").arg(d.join("nope")).arg("--out").arg(d.join("r")).output().unwrap(), &["nope"]);
    // an image missing from a dataset
    let data = d.join("data");
    scene("object", &data, 8, "24x24");
    std::fs::remove_file(data.join("train/r_003.png")).unwrap();
    fails(snerf().arg("train").arg(&data).arg("--out").arg(d.join("r")).output().unwrap(), &["r_003.png"]);
    assert!(!d.join("r/checkpoint.snerfck").exists(), "no partial run left looking complete");
    // a NaN in a pose
    scene("object", &data, 8, "24x24");
    let tf = data.join("transforms_train.json");
    let text = std::fs::read_to_string(&tf).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["frames"][2]["transform_matrix"][0][3] = serde_json::Value::String("NaN".into());
    std::fs::write(&tf, serde_json::to_string(&json).unwrap()).unwrap();
    fails(snerf().arg("data").arg(&data).output().unwrap(), &["transforms_train.json"]);
    std::fs::write(&tf, text).unwrap();
    // a corrupt checkpoint, and one from another version
    let run = d.join("run");
    ok(snerf().args(["--json", "train"]).arg(&data).arg("--out").arg(&run).args(["--steps", "3"]).output().unwrap());
    let ck = run.join("checkpoint.snerfck");
    let mut bytes = std::fs::read(&ck).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x40;
    std::fs::write(&ck, &bytes).unwrap();
    fails(snerf().arg("eval").arg(&run).arg(&data).output().unwrap(), &["checkpoint.snerfck", "corrupt"]);
    bytes[mid] ^= 0x40;
    bytes[8] = 99; // version field
    std::fs::write(&ck, &bytes).unwrap();
    fails(snerf().arg("eval").arg(&run).arg(&data).output().unwrap(), &["checkpoint.snerfck", "version 99"]);
    // a truncated checkpoint
    std::fs::write(&ck, &bytes[..100]).unwrap();
    fails(snerf().arg("eval").arg(&run).arg(&data).output().unwrap(), &["checkpoint.snerfck"]);
    // unknown scene, bad size, unknown kind
    fails(snerf().args(["scene", "castle", "--out"]).arg(d.join("c")).output().unwrap(), &["castle", "object"]);
    fails(snerf().args(["scene", "object", "--size", "12by12", "--out"]).arg(d.join("c")).output().unwrap(), &["12by12"]);
    fails(snerf().arg("data").arg(&data).args(["--kind", "planet"]).output().unwrap(), &["planet"]);
}

/// The inputs of the `bench snerf` tests: a real model's folder (None, with a note, when
/// assimp-testmodels is not installed), a fresh directory, and a style file in it, so the
/// tests do not depend on the paintings being installed.
fn bench_snerf_inputs(name: &str) -> Option<(&'static Path, ScratchDir, PathBuf)> {
    let models = Path::new("/usr/share/assimp/models/glTF2/BoxTextured-glTF");
    if !models.is_dir() {
        eprintln!("SKIP: {} not installed (apt-get install assimp-testmodels)", models.display());
        return None;
    }
    let d = tmp(name);
    let style = d.join("stripes.png");
    image::RgbImage::from_fn(64, 48, |x, y| if (x + y / 2) % 8 < 4 { image::Rgb([200, 40, 30]) } else { image::Rgb([240, 220, 120]) }).save(&style).unwrap();
    Some((models, d, style))
}

/// `snerf bench snerf` on one real model and one painting at tiny settings: every pair gets
/// its scores and the bars, and a second invocation reuses the finished steps instead of
/// training or stylizing again.
#[test]
fn bench_snerf_scores_pairs_and_reuses_finished_steps() {
    let Some((models, d, style)) = bench_snerf_inputs("bench-snerf") else { return };
    let out = d.join("grid");
    let args = |cmd: &mut Command| {
        cmd.args(["--json", "bench", "snerf"]).arg(models).arg("--out").arg(&out).arg("--styles").arg(&style);
        cmd.args(["--size", "32", "--views", "8", "--seconds", "3", "--frames", "8"]);
        cmd.args(["--stylize-flags", "--views 4 --rounds 2 --steps-per-round 5 --consistency-frames 8 --stylizer color"]);
    };
    let mut c = snerf();
    args(&mut c);
    let s = ok(c.output().unwrap());
    let pairs = s["pairs"].as_array().unwrap();
    assert_eq!(pairs.len(), 1, "{s}");
    assert_eq!(pairs[0]["model"], "BoxTextured");
    assert_eq!(pairs[0]["style"], "stripes");
    let sc = &pairs[0]["scores"];
    for k in ["short_range", "long_range", "style"] {
        assert!(sc["snerf_over_per_frame"][k].as_f64().is_some_and(|x| x.is_finite() && x > 0.0), "{k}: {s}");
        assert!(sc["last_over_first_round"][k].as_f64().is_some_and(|x| x.is_finite() && x > 0.0), "{k}: {s}");
    }
    // the bound the last targets put on the field: copied and bilinear reads
    let carried = sc["targets_carried_over_per_frame"].as_array().unwrap_or_else(|| panic!("no targets carried: {s}"));
    assert_eq!(carried.len(), 2, "{s}");
    for c in carried {
        assert!(c["short_range"].as_f64().is_some_and(|x| x.is_finite() && x > 0.0), "{s}");
    }
    assert_eq!(s["bars"]["pairs"], 1);
    assert!(out.join("snerf.md").exists() && out.join("snerf.json").exists());
    // again: nothing is trained or stylized twice, and the same numbers come back
    let ck = out.join("runs/BoxTextured/checkpoint.snerfck");
    let st = out.join("stylized/BoxTextured--stripes/stylize.json");
    let stamp = |p: &Path| std::fs::metadata(p).unwrap().modified().unwrap();
    let (ck0, st0) = (stamp(&ck), stamp(&st));
    let mut c = snerf();
    args(&mut c);
    let again = ok(c.output().unwrap());
    assert_eq!((stamp(&ck), stamp(&st)), (ck0, st0), "a finished step ran again");
    assert_eq!(again["pairs"][0]["scores"], pairs[0]["scores"]);
}

/// With a step budget (`--steps`) the grid repeats: two grids in two directories, each
/// rendering, training, stylizing and scoring from scratch, give the same scores to the
/// last digit (training adds its gradients in a fixed order; docs/stylize-notebook.md §5k).
#[test]
fn bench_snerf_with_a_step_budget_repeats_exactly() {
    let Some((models, d, style)) = bench_snerf_inputs("bench-snerf-steps") else { return };
    let grid = |name: &str| {
        let mut c = snerf();
        c.args(["--json", "bench", "snerf"]).arg(models).arg("--out").arg(d.join(name)).arg("--styles").arg(&style);
        c.args(["--size", "32", "--views", "8", "--steps", "60", "--frames", "8"]);
        c.args(["--stylize-flags", "--views 4 --rounds 2 --steps-per-round 5 --consistency-frames 8 --stylizer color"]);
        ok(c.output().unwrap())
    };
    let (a, b) = (grid("a"), grid("b"));
    let steps = |name: &str| -> serde_json::Value { serde_json::from_slice(&std::fs::read(d.join(name).join("runs/BoxTextured/metrics.json")).unwrap()).unwrap() };
    assert_eq!(steps("a")["step"], 60, "the realistic field trains the steps asked");
    let doc: serde_json::Value = serde_json::from_slice(&std::fs::read(d.join("a/snerf.json")).unwrap()).unwrap();
    assert_eq!(doc["realistic_training"]["steps"], 60, "{doc}");
    assert!(a["pairs"][0]["scores"].is_object(), "{a}");
    assert_eq!(a["pairs"][0]["scores"], b["pairs"][0]["scores"]);
}
