//! `snerf capture` on real and known data, with Debian's COLMAP: real camera frames (ViSP's
//! cube sequence, Debian visp-images-data) register and load as a dataset; the camera centres
//! COLMAP recovers for a synthetic turntable match the rig that rendered it up to a similarity
//! (every pairwise distance scaled by one factor); the castel sequence's sparse depths agree with
//! the depth sensor that filmed it under one scale; a capture that cannot register enough photos,
//! or runs without COLMAP, fails with a clear message and writes nothing; real frames before a
//! textured scene are not taken for a plain backdrop, and the same frames on a white sweep are.
//!
//! Needs `colmap` and visp-images-data (`scripts/setup-capture.sh`, run by .ci/run, which sets
//! SNERF_REQUIRE_COLMAP=1: then a missing tool fails the tests instead of skipping them).
mod common;
use common::{ok, snerf};

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use snerf_files::ScratchDir;
use snerf_trainer::data::{self, LoadOptions};

const CUBE: &str = "/usr/share/visp-images-data/ViSP-images/cube";
const CASTEL: &str = "/usr/share/visp-images-data/ViSP-images/mbt-depth/castel/castel";

fn tmp(name: &str) -> ScratchDir {
    ScratchDir::new("snerf-capture", name).unwrap()
}

/// Whether COLMAP and the ViSP frames are here; panics when they must be (CI) and are not.
fn tools_ready() -> bool {
    let colmap = Command::new("colmap").arg("help").env("QT_QPA_PLATFORM", "offscreen").output().is_ok();
    let frames = Path::new(CUBE).is_dir() && Path::new(CASTEL).is_dir();
    if colmap && frames {
        return true;
    }
    if std::env::var_os("SNERF_REQUIRE_COLMAP").is_some() {
        panic!("SNERF_REQUIRE_COLMAP is set but colmap ({colmap}) or visp-images-data ({frames}) is missing");
    }
    eprintln!("skipped: colmap or visp-images-data missing (bash scripts/setup-capture.sh)");
    false
}

/// Whether the setup step's pycolmap is here; panics when it must be (CI) and is not.
fn pycolmap_ready() -> bool {
    let python = std::env::var_os("SNERF_PYCOLMAP")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target/capture-venv/bin/python"));
    let ready = Command::new(&python).args(["-c", "import pycolmap"]).output().is_ok_and(|o| o.status.success());
    if !ready && std::env::var_os("SNERF_REQUIRE_PYCOLMAP").is_some() {
        panic!("SNERF_REQUIRE_PYCOLMAP is set but {} cannot import pycolmap", python.display());
    }
    if !ready {
        eprintln!("pycolmap part skipped: {} cannot import pycolmap (bash scripts/setup-capture.sh)", python.display());
    }
    ready
}

/// Copies `names` from `from` into a new folder `to`.
fn pick(from: &str, names: &[String], to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for n in names {
        std::fs::copy(Path::new(from).join(n), to.join(n)).unwrap_or_else(|e| panic!("{from}/{n}: {e}"));
    }
}

/// Nothing but `keep` in `dir` (no temp folder left beside the output).
fn only(dir: &Path, keep: &[&str]) {
    let mut names: Vec<String> = std::fs::read_dir(dir).unwrap().flatten().map(|e| e.file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    let mut want: Vec<String> = keep.iter().map(|s| s.to_string()).collect();
    want.sort();
    assert_eq!(names, want, "{}: unexpected entries (a temp folder left behind?)", dir.display());
}

#[test]
fn real_visp_cube_frames_register_and_load() {
    if !tools_ready() {
        return;
    }
    let d = tmp("cube");
    // Every 5th of the 80 frames (16), 384x288 greyscale PGM from a robot-held camera.
    let names: Vec<String> = (0..80).step_by(5).map(|i| format!("image.{i:04}.pgm")).collect();
    let photos = d.join("photos");
    pick(CUBE, &names, &photos);
    let out = d.join("cube");
    let r = ok(snerf()
        .args(["--json", "capture"])
        .arg(&photos)
        .arg("--out")
        .arg(&out)
        .args(["--matcher", "sequential", "--colmap", "colmap"])
        .output()
        .unwrap());
    assert_eq!(r["backend"], "colmap");
    let frac = r["registered_fraction"].as_f64().unwrap();
    assert!(frac >= 0.95, "registered {frac} of the cube frames: {r}");
    assert_eq!(r["photos"], 16);
    assert_eq!(r["converted_photos"], 16, "PGM is converted to PNG");
    let reproj = r["mean_reprojection_error_px"].as_f64().unwrap();
    assert!(reproj > 0.0 && reproj < 1.0, "mean reprojection error {reproj} px");
    assert_eq!(r["kind"], "forward", "the cube is filmed from one side: {}", r["detection_note"]);
    assert!(r["backdrop"].is_null() && !out.join("backdrop.json").exists(), "the cube's table is no plain backdrop: {r}");
    assert!(r["backdrop_note"].as_str().unwrap().starts_with("no plain backdrop"), "{r}");
    only(&d, &["photos", "cube"]);
    assert!(out.join("capture.json").is_file() && out.join("sparse/0/cameras.bin").is_file());

    // The loader reads it: pinhole (undistorted), every registered frame, PNG images.
    let ds = data::load(&out, &LoadOptions::default()).unwrap();
    assert_eq!(ds.format, "colmap");
    assert_eq!(ds.train.len() + ds.test.len(), r["registered"].as_u64().unwrap() as usize);
    for v in ds.all_views() {
        assert_eq!(v.intrinsics.distortion, [0.0; 4], "{}: undistorted to a pinhole camera", v.path.display());
        assert!(v.path.extension().is_some_and(|e| e == "png"));
    }
    // `snerf data` says what it is.
    let s = ok(snerf().args(["--json", "data"]).arg(&out).output().unwrap());
    assert_eq!(s["format"], "colmap");
    assert!(s["detection_note"].as_str().unwrap().starts_with("forward"));

    // The same frames through pycolmap (the default backend when the setup step installed it).
    if pycolmap_ready() {
        let out2 = d.join("cube-py");
        let p = ok(snerf().args(["--json", "capture"]).arg(&photos).arg("--out").arg(&out2).args(["--matcher", "sequential"]).output().unwrap());
        assert_eq!(p["backend"], "pycolmap", "auto picks pycolmap when installed: {p}");
        assert!(p["colmap_version"].as_str().unwrap().starts_with("pycolmap 4."), "{p}");
        let frac = p["registered_fraction"].as_f64().unwrap();
        assert!(frac >= 0.95, "pycolmap registered {frac} of the cube frames: {p}");
        let reproj = p["mean_reprojection_error_px"].as_f64().unwrap();
        assert!(reproj > 0.0 && reproj < 1.0, "pycolmap: mean reprojection error {reproj} px");
        let ds = data::load(&out2, &LoadOptions::default()).unwrap();
        assert_eq!(ds.train.len() + ds.test.len(), p["registered"].as_u64().unwrap() as usize);
        assert!(ds.all_views().all(|v| v.intrinsics.distortion == [0.0; 4]), "undistorted to a pinhole camera");
        std::fs::remove_dir_all(&out2).unwrap();
    }

    // A second capture into the same folder replaces it (snerf wrote it); a folder with a user's
    // file in it is refused and left as it was.
    std::fs::write(out.join("notes.txt"), b"mine").unwrap();
    let o = snerf().arg("capture").arg(&photos).arg("--out").arg(&out).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("cannot replace"), "{err}");
    assert!(out.join("notes.txt").is_file() && out.join("capture.json").is_file());
}

/// COLMAP's camera centres against the rig: a ring of 24 views rendered by `snerf scene outdoor
/// --path orbit` (centres on a circle of radius 3.6 at equal 15-degree steps, looking in), with
/// the rig's focal length given as a calibrated camera's would be. COLMAP's frame and scale are
/// arbitrary, so the checks are similarity-invariant: seen from the normal of the ring through
/// the centroid of the centres, every step turns the same way by 3-45 degrees (the rig: 15) and
/// the whole ring by 345 +- 30 degrees: no view folded across, none out of order. Tighter bounds
/// (equal steps within 10%) failed: COLMAP misplaces a view or two along the chain on this
/// synthetic scene (BENCH.md 2d). Sequential matching with a small overlap: the scene looks
/// alike from opposite sides, and exhaustive matching folds the ring (measured).
#[test]
fn turntable_poses_match_the_rig_up_to_similarity() {
    if !tools_ready() {
        return;
    }
    let d = tmp("turntable");
    let scene = d.join("scene");
    ok(snerf()
        .args(["--json", "scene", "outdoor", "--path", "orbit", "--views", "24", "--test-views", "1", "--size", "400x300", "--out"])
        .arg(&scene)
        .output()
        .unwrap());
    let truth: Value = serde_json::from_slice(&std::fs::read(scene.join("transforms_train.json")).unwrap()).unwrap();
    let focal = truth["fl_x"].as_f64().unwrap();
    let out = d.join("cap");
    let r = ok(snerf()
        // One thread: pycolmap's seeded mapping then repeats exactly, so the test checks one
        // capture, not whichever a thread race gives (on two threads one CI run registered 21
        // of the 24 views).
        .args(["--json", "--threads", "1", "capture"])
        .arg(scene.join("train"))
        .arg("--out")
        .arg(&out)
        .args(["--matcher", "sequential", "--overlap", "3", "--focal", &focal.to_string()])
        .output()
        .unwrap());
    assert!(r["registered_fraction"].as_f64().unwrap() >= 0.95, "{r}");

    let mut rig: Vec<(String, [f64; 3])> = truth["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            let name = Path::new(f["file_path"].as_str().unwrap()).file_name().unwrap().to_string_lossy().into_owned();
            let m = &f["transform_matrix"];
            (name, [0, 1, 2].map(|i| m[i][3].as_f64().unwrap()))
        })
        .collect();
    rig.sort_by(|a, b| a.0.cmp(&b.0));
    let ds = data::load(&out, &LoadOptions { holdout_every: Some(0), ..Default::default() }).unwrap();
    let found: Vec<(String, [f64; 3])> = ds.all_views().map(|v| (file_name(&v.path), v.origin().map(|x| x as f64))).collect();
    let pairs: Vec<([f64; 3], [f64; 3])> = rig
        .iter()
        .filter_map(|(n, c)| found.iter().find(|(m, _)| m == n).map(|(_, f)| (*c, *f)))
        .collect();
    assert!(pairs.len() >= 23, "{} of 24 rig views found in the capture", pairs.len());
    // Around the centroid, in the plane of the ring: each step turns the same way by a positive
    // angle (truth: 15 degrees), and the whole ring turns 345 degrees (no fold, no collapse).
    // COLMAP's multi-threaded mapping differs from run to run: runs have ended at 313-350
    // degrees (a misplaced view, drift that leaves the ring open), so the total is held to
    // 45 degrees, three steps; a fold or a collapse misses it by far more.
    let n = pairs.len() as f64;
    let mut c = [0.0; 3];
    for (_, f) in &pairs {
        for i in 0..3 {
            c[i] += f[i] / n;
        }
    }
    let sub = |a: [f64; 3], b: [f64; 3]| [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    let cross = |a: [f64; 3], b: [f64; 3]| [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut normal = [0.0; 3];
    for w in pairs.windows(2) {
        let k = cross(sub(w[0].1, c), sub(w[1].1, c));
        for i in 0..3 {
            normal[i] += k[i];
        }
    }
    let nn = dot(normal, normal).sqrt();
    let normal = normal.map(|x| x / nn);
    let turns: Vec<f64> = pairs
        .windows(2)
        .map(|w| {
            let (a, b) = (sub(w[0].1, c), sub(w[1].1, c));
            dot(cross(a, b), normal).atan2(dot(a, b)).to_degrees()
        })
        .collect();
    let total: f64 = turns.iter().sum();
    eprintln!("turntable: {} centres, turns {turns:.1?}, total {total:.1} degrees", pairs.len());
    assert!(turns.iter().all(|t| *t > 3.0 && *t < 45.0), "the ring is folded or out of order: turns {turns:.1?}");
    let want = 15.0 * (pairs.len() - 1) as f64;
    assert!((total - want).abs() < 45.0, "the ring turns {total:.1} degrees, the rig {want}");
}

/// COLMAP's geometry against the depth sensor that filmed the castel sequence (every 3rd of its
/// 30 frames): one scale must map every camera's sparse depths onto the sensor's, and does to
/// within 1.12% on the worst camera (`--threads 1`: pycolmap's seeded mapping repeats exactly
/// there). The bound 1.5% is what this sequence allows: its camera turns by 10 degrees, so even
/// depth images paired with frames 9 or 15 later read 1.74-1.90% (BENCH.md 2d).
#[test]
fn castel_depths_agree_with_the_sensor_under_one_scale() {
    if !tools_ready() || !pycolmap_ready() {
        return;
    }
    let d = tmp("castel-depth");
    let names: Vec<String> = (0..30).step_by(3).map(|i| format!("image_{i:04}.pgm")).collect();
    let photos = d.join("photos");
    pick(CASTEL, &names, &photos);
    let out = d.join("castel");
    let r = ok(snerf().args(["--json", "--threads", "1", "capture"]).arg(&photos).arg("--out").arg(&out).args(["--colmap", "pycolmap"]).output().unwrap());
    assert_eq!(r["registered"], 10, "{r}");
    let root = Path::new(CASTEL).parent().unwrap();
    let c = ok(snerf().args(["--json", "bench", "capture-depth"]).arg(&out).arg("--visp-castel").arg(root).output().unwrap());
    let a = &c["agreement"];
    assert_eq!(a["cameras"].as_array().unwrap().len(), 10, "every camera sees the sensor's surface: {c}");
    assert!(a["observations"].as_u64().unwrap() > 2000, "{c}");
    let worst = a["worst_camera_scale"].as_f64().unwrap();
    let med = a["median_relative_error"].as_f64().unwrap();
    assert!(worst < 0.015, "a camera's scale strays {worst} from the others': {c}");
    assert!(med < 0.05, "median depth error {med}: {c}");
    // a folder without the rig's files is named
    let o = snerf().args(["bench", "capture-depth"]).arg(&out).arg("--visp-castel").arg(&d).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("depth_M_color.txt"), "{err}");
}

fn file_name(p: &Path) -> String {
    p.file_name().unwrap().to_string_lossy().into_owned()
}

#[test]
fn too_few_registered_photos_or_no_colmap_write_nothing() {
    if !tools_ready() {
        return;
    }
    let d = tmp("fail");
    // Two neighbouring cube frames and two castle frames: two unrelated pairs, so at most half
    // register in one model, below a 0.9 floor.
    let photos = d.join("photos");
    pick(CUBE, &["image.0000.pgm".into(), "image.0002.pgm".into()], &photos);
    pick(CASTEL, &["image_0000.pgm".into(), "image_0001.pgm".into()], &photos);
    let out = d.join("data");
    let o = snerf().arg("capture").arg(&photos).arg("--out").arg(&out).args(["--min-registered", "0.9"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(err.contains("nothing was written") && !err.contains("panicked"), "{err}");
    only(&d, &["photos"]);

    // No COLMAP: the message names the setup step.
    let o = snerf()
        .arg("capture")
        .arg(&photos)
        .arg("--out")
        .arg(&out)
        .args(["--colmap", "colmap"])
        .env("SNERF_COLMAP", d.join("no-colmap"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("setup-capture.sh"), "{err}");
    // No pycolmap: the same, and `auto` with neither names both.
    let o = snerf()
        .arg("capture")
        .arg(&photos)
        .arg("--out")
        .arg(&out)
        .args(["--colmap", "pycolmap"])
        .env("SNERF_PYCOLMAP", d.join("no-python"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("setup-capture.sh") && err.contains("no-python"), "{err}");
    let o = snerf()
        .arg("capture")
        .arg(&photos)
        .arg("--out")
        .arg(&out)
        .env("SNERF_PYCOLMAP", d.join("no-python"))
        .env("SNERF_COLMAP", d.join("no-colmap"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("no-python") && err.contains("no-colmap"), "{err}");
    // A video without ffmpeg on PATH says so.
    let video = d.join("clip.mp4");
    std::fs::write(&video, b"not a video").unwrap();
    let o = snerf()
        .args(["capture", "--video"])
        .arg(&video)
        .arg("--out")
        .arg(&out)
        .env("PATH", PathBuf::from("/usr/bin").join("no-such-dir"))
        .env("SNERF_COLMAP", "/usr/bin/colmap")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("needs ffmpeg"), "{err}");
    only(&d, &["photos", "clip.mp4"]);
}

/// RGBA pixels of a greyscale ViSP frame, optionally on a white margin of `pad` pixels.
fn frame_rgba(path: &Path, pad: usize) -> (Vec<u8>, usize, usize) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgba8();
    let (w, h) = (img.width() as usize + 2 * pad, img.height() as usize + 2 * pad);
    let mut px = vec![255u8; w * h * 4];
    for (x, y, p) in img.enumerate_pixels() {
        let i = 4 * ((y as usize + pad) * w + x as usize + pad);
        px[i..i + 4].copy_from_slice(&p.0);
    }
    (px, w, h)
}

/// The plain-backdrop check on real frames: every 3rd frame of ViSP's cube sequence (a cube on a
/// textured table, filmed by a robot-held camera) and of the castel sequence (a model castle in
/// a room) stay opaque, so their captures are unchanged; the same cube frames on a white margin
/// of a fifth of their size (a sweep) are found to stand before one, every margin pixel is keyed
/// out and the frame's middle is not.
#[test]
fn real_frames_before_a_scene_are_not_taken_for_a_plain_backdrop() {
    if !tools_ready() {
        return;
    }
    use snerf_trainer::data::backdrop::{self, Rgba};
    for (dir, prefix) in [(CUBE, "image."), (CASTEL, "image_")] {
        let mut names: Vec<PathBuf> = std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.file_name().unwrap().to_string_lossy().starts_with(prefix) && p.extension().is_some_and(|e| e == "pgm"))
            .collect();
        names.sort();
        let frames: Vec<_> = names.iter().step_by(3).map(|p| frame_rgba(p, 0)).collect();
        assert!(frames.len() >= 10, "{dir}: {} frames", frames.len());
        let views: Vec<Rgba> = frames.iter().map(|(p, w, h)| Rgba { pixels: p, width: *w, height: *h }).collect();
        let why = backdrop::detect(&views).expect_err(dir);
        assert!(why.starts_with("no plain backdrop"), "{dir}: {why}");
        eprintln!("{dir}: {why}");

        if dir == CUBE {
            let pad = frames[0].1 / 10;
            let padded: Vec<_> = names.iter().step_by(3).map(|p| frame_rgba(p, pad)).collect();
            let views: Vec<Rgba> = padded.iter().map(|(p, w, h)| Rgba { pixels: p, width: *w, height: *h }).collect();
            let b = backdrop::detect(&views).expect("the frames on a white margin stand before a plain backdrop");
            assert_eq!(b.colour, [255, 255, 255]);
            let (mut px, w, h) = padded[0].clone();
            backdrop::key(&mut px, w, h, b.colour, b.tolerance);
            let alpha = |x: usize, y: usize| px[4 * (y * w + x) + 3];
            for y in 0..h {
                for x in 0..w {
                    if x < pad || y < pad || x >= w - pad || y >= h - pad {
                        assert_eq!(alpha(x, y), 0, "margin pixel {x},{y} is backdrop");
                    }
                }
            }
            assert_eq!(alpha(w / 2, h / 2), 255, "the frame's middle is not backdrop");
        }
    }
}

/// A turntable before a white sweep, end to end: `snerf scene object --path orbit` renders 36
/// views 10 degrees apart (as product spins are shot; 24 views at 256x256 registered 2) (a textured object with cream and white parts), flattened onto white
/// as a product photo is; the capture finds the plain backdrop, the dataset loads as an object,
/// and the keyed alpha matches the renderer's own silhouette on all but a sliver of pixels. With
/// --no-backdrop the same photos stay opaque and are not an object.
#[test]
fn a_turntable_before_a_white_sweep_is_keyed_to_its_silhouette() {
    if !pycolmap_ready() {
        return;
    }
    let d = tmp("sweep");
    let scene = d.join("scene");
    ok(snerf()
        .args(["--json", "scene", "object", "--path", "orbit", "--views", "36", "--test-views", "1", "--size", "384x384", "--out"])
        .arg(&scene)
        .output()
        .unwrap());
    let truth: Value = serde_json::from_slice(&std::fs::read(scene.join("transforms_train.json")).unwrap()).unwrap();
    let focal = truth["fl_x"].as_f64().unwrap();
    let photos = d.join("photos");
    std::fs::create_dir_all(&photos).unwrap();
    let mut silhouettes = std::collections::HashMap::new();
    for e in std::fs::read_dir(scene.join("train")).unwrap().flatten() {
        let img = image::open(e.path()).unwrap().to_rgba8();
        let (w, h) = img.dimensions();
        let mut flat = image::RgbImage::new(w, h);
        for (x, y, p) in img.enumerate_pixels() {
            let a = p[3] as f32 / 255.0;
            flat.put_pixel(x, y, image::Rgb([0, 1, 2].map(|c| (p[c] as f32 * a + 255.0 * (1.0 - a)).round() as u8)));
        }
        flat.save(photos.join(e.file_name())).unwrap();
        silhouettes.insert(e.file_name().to_string_lossy().into_owned(), (w, h, img.pixels().map(|p| p[3] >= 128).collect::<Vec<bool>>()));
    }
    let capture = |out: &Path, extra: &[&str]| {
        ok(snerf()
            .args(["--json", "--threads", "1", "capture"])
            .arg(&photos)
            .arg("--out")
            .arg(out)
            .args(["--colmap", "pycolmap", "--matcher", "sequential", "--overlap", "3", "--camera-model", "PINHOLE"])
            .args(["--focal", &focal.to_string()])
            .args(extra)
            .output()
            .unwrap())
    };
    let out = d.join("cap");
    let r = capture(&out, &[]);
    assert!(r["registered_fraction"].as_f64().unwrap() >= 0.95, "{r}");
    assert_eq!(r["backdrop"]["colour"], serde_json::json!([255, 255, 255]), "{r}");
    assert_eq!(r["kind"], "object", "{}", r["detection_note"]);
    assert!(r["detection_note"].as_str().unwrap().contains("plain backdrop"), "{r}");
    assert!(out.join("backdrop.json").is_file());

    let ds = data::load(&out, &LoadOptions { holdout_every: Some(0), ..Default::default() }).unwrap();
    // Pixels keyed unlike the silhouette, on its edge (within 2 pixels of a pixel on its other
    // side: the renderer's anti-aliasing and the soft matte differ there) and away from it (a
    // leak into the object's light parts or backdrop left in).
    let (mut edge, mut inner, mut total, mut views) = (0usize, 0usize, 0usize, 0usize);
    for v in ds.all_views() {
        let (w, h, truth) = &silhouettes[&file_name(&v.path)];
        let (w, h) = (*w as usize, *h as usize);
        assert_eq!((v.intrinsics.width as usize, v.intrinsics.height as usize), (w, h), "a pinhole capture keeps the photo's size");
        for (i, p) in v.rgba.chunks_exact(4).enumerate() {
            if (p[3] >= 128) == truth[i] {
                continue;
            }
            let (x, y) = (i % w, i / w);
            let near_edge = (y.saturating_sub(2)..(y + 3).min(h))
                .any(|yy| (x.saturating_sub(2)..(x + 3).min(w)).any(|xx| truth[yy * w + xx] != truth[i]));
            if near_edge {
                edge += 1;
            } else {
                inner += 1;
            }
        }
        total += w * h;
        views += 1;
    }
    let (edge, inner) = (edge as f64 / total as f64, inner as f64 / total as f64);
    eprintln!("sweep: {views} views; keyed unlike the silhouette: {:.3}% of pixels on its edge, {:.4}% away from it", edge * 100.0, inner * 100.0);
    assert!(views >= 35, "{views} views");
    assert!(inner < 0.001, "{:.3}% of pixels away from the silhouette's edge keyed wrongly", inner * 100.0);
    assert!(edge < 0.01, "{:.2}% of pixels on the silhouette's edge keyed wrongly", edge * 100.0);

    let plain = d.join("plain");
    let r = capture(&plain, &["--no-backdrop"]);
    assert!(r["backdrop"].is_null() && !plain.join("backdrop.json").exists(), "{r}");
    assert_ne!(r["kind"], "object", "{}", r["detection_note"]);
    let ds = data::load(&plain, &LoadOptions::default()).unwrap();
    assert!(ds.all_views().all(|v| v.rgba.chunks_exact(4).all(|p| p[3] == 255)), "--no-backdrop keeps the photos opaque");
}
