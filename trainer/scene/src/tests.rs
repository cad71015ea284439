//! Crate tests: renderer correctness on known scenes, anti-aliasing, dataset layout and JSON,
//! dynamic vs static scenes, glTF loading (an in-code model always; installed test models
//! when present) and error cases.

use glam::{vec3, Mat4, Vec3};
use crate::mesh::{Background, Geometry, Look, Material};
use crate::procedural::{shapes, Content};
use crate::raster::{c2w_matrix, camera, render, world_to_camera, Frame};
use snerf_geometry::camera::C2w;
use crate::texture::{Texture, Wrap};
use crate::*;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// This test's directory: removed when it passes, kept (and named) when it fails.
fn tmpdir(tag: &str) -> snerf_files::ScratchDir {
    snerf_files::ScratchDir::new("snerf-scene-test", tag).unwrap()
}

fn px(f: &Frame, x: u32, y: u32) -> [u8; 4] {
    let i = ((y * f.width + x) * 4) as usize;
    [f.rgba[i], f.rgba[i + 1], f.rgba[i + 2], f.rgba[i + 3]]
}

/// A quad in the plane z = `z` spanning [-s, s]^2, facing +z.
fn quad(z: f32, s: f32, mat: u32) -> Geometry {
    let mut g = Geometry::default();
    g.append(
        &shapes::grid(s, s, 1, 1, mat, 1.0),
        &(Mat4::from_translation(vec3(0.0, 0.0, z))
            * Mat4::from_axis_angle(vec3(1.0, 0.0, 0.0), std::f32::consts::FRAC_PI_2)),
    );
    g
}

/// A camera at `eye` looking at `target` with `up` as the image's up.
fn look_at(eye: Vec3, target: Vec3, up: Vec3) -> C2w {
    snerf_geometry::look_at(eye.into(), target.into(), up.into())
}

fn front_camera(w: u32, h: u32, fov_deg: f32) -> snerf_geometry::Pinhole {
    let identity = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
    camera(identity, w, h, fov_deg.to_radians())
}

#[test]
fn depth_and_colour_of_a_known_quad() {
    let mut look = Look::new(Background::Transparent);
    let m = look.add_material(Material::color([0.5, 0.25, 0.125]));
    let g = quad(-3.0, 1.0, m);
    let cam = front_camera(64, 64, 60.0);
    let f = render(&look, &g, &cam, 4);
    // Centre pixel: depth 3, colour = albedo * (ambient + diffuse * n.l), n = +z.
    let c = (32 * 64 + 32) as usize;
    assert!((f.depth[c] - 3.0).abs() < 1e-4, "depth {}", f.depth[c]);
    let l = look.ambient + look.diffuse * look.light_dir.z.max(0.0);
    let p = px(&f, 32, 32);
    for k in 0..3 {
        let want = crate::texture::encode_srgb8([0.5, 0.25, 0.125][k] * l);
        assert!(
            (p[k] as i32 - want as i32).abs() <= 1,
            "channel {k}: {} vs {want}",
            p[k]
        );
    }
    assert_eq!(p[3], 255);
    // The quad's half-width 1 at depth 3 projects to fx / 3 pixels from the centre.
    let half = cam.fx / 3.0;
    let edge = 32.0 + half;
    let inside = (edge - 1.5) as u32;
    let outside = (edge + 1.5) as u32;
    assert_eq!(px(&f, inside, 32)[3], 255);
    assert_eq!(
        px(&f, outside, 32),
        [0, 0, 0, 0],
        "transparent pixels have RGB 0"
    );
    assert!(f.depth[(32 * 64 + outside) as usize].is_infinite());
    // Seen from behind, a one-sided light would make it dark; the shading normal is flipped
    // towards the camera, so the back reads as lit by the ambient + |back-facing| rule.
    let back = camera(
        look_at(vec3(0.0, 0.0, -6.0), vec3(0.0, 0.0, -3.0), vec3(0.0, 1.0, 0.0)),
        64,
        64,
        60f32.to_radians(),
    );
    let fb = render(&look, &g, &back, 2);
    assert_eq!(px(&fb, 32, 32)[3], 255);
    assert!((fb.depth[c] - 3.0).abs() < 1e-4);
}

#[test]
fn perspective_correct_texturing() {
    // A floor from z = -1 to z = -21 at y = -1, texture split at v = 0.5 (red near, blue far).
    let mut look = Look::new(Background::Transparent);
    let t = look.add_texture(Texture::from_fn(64, 64, Wrap::Clamp, |_u, v| {
        if v < 0.5 {
            [1.0, 0.0, 0.0, 1.0]
        } else {
            [0.0, 0.0, 1.0, 1.0]
        }
    }));
    let m = look.add_material(Material::textured(t));
    let mut g = Geometry::default();
    let n = vec3(0.0, 1.0, 0.0);
    let a = g.vertex(vec3(-5.0, -1.0, -1.0), n, [0.0, 0.0]);
    let b = g.vertex(vec3(5.0, -1.0, -1.0), n, [1.0, 0.0]);
    let c = g.vertex(vec3(5.0, -1.0, -21.0), n, [1.0, 1.0]);
    let d = g.vertex(vec3(-5.0, -1.0, -21.0), n, [0.0, 1.0]);
    g.tri(a, c, b, m);
    g.tri(a, d, c, m);
    let cam = front_camera(64, 128, 90.0);
    let f = render(&look, &g, &cam, 4);
    // v = 0.5 is z = -11: image row cy + fy * 1 / 11.
    let row = cam.cy + cam.fy / 11.0;
    let x = 32;
    let red_row = (row + 1.5) as u32;
    let blue_row = (row - 1.5) as u32;
    let r = px(&f, x, red_row);
    let bl = px(&f, x, blue_row);
    assert!(
        r[0] > 150 && r[2] < 60,
        "below the split should be red: {r:?} (row {red_row})"
    );
    assert!(
        bl[2] > 150 && bl[0] < 60,
        "above the split should be blue: {bl:?} (row {blue_row})"
    );
}

#[test]
fn supersampling_antialiases_edges() {
    let mut look = Look::new(Background::Transparent);
    let m = look.add_material(Material::color([1.0, 1.0, 1.0]));
    let mut g = Geometry::default();
    // A quad whose right edge projects exactly to x = 20.5 pixels at depth 1 (fx known).
    let cam = front_camera(40, 40, 60.0);
    let xr = (20.5 - cam.cx) / cam.fx;
    let n = vec3(0.0, 0.0, 1.0);
    let a = g.vertex(vec3(-1.0, -1.0, -1.0), n, [0.0, 0.0]);
    let b = g.vertex(vec3(xr, -1.0, -1.0), n, [0.0, 0.0]);
    let c = g.vertex(vec3(xr, 1.0, -1.0), n, [0.0, 0.0]);
    let d = g.vertex(vec3(-1.0, 1.0, -1.0), n, [0.0, 0.0]);
    g.tri(a, b, c, m);
    g.tri(a, c, d, m);
    let f4 = render(&look, &g, &cam, 4);
    let alpha = px(&f4, 20, 20)[3];
    assert!(
        (alpha as i32 - 128).abs() <= 2,
        "half-covered pixel alpha {alpha}"
    );
    assert_eq!(px(&f4, 19, 20)[3], 255);
    assert_eq!(px(&f4, 21, 20)[3], 0);
    let f1 = render(&look, &g, &cam, 1);
    assert!(
        f1.rgba.chunks(4).all(|p| p[3] == 0 || p[3] == 255),
        "without supersampling coverage is binary"
    );
}

#[test]
fn views_agree_on_surface_colour() {
    // View-independent shading: a surface point seen from two cameras has the same colour.
    let built = build_scene(&Source::Object, 0).unwrap();
    let Content::Static(g) = &built.content else {
        panic!()
    };
    let cam_a = camera(
        look_at(vec3(0.0, 1.0, 4.0), Vec3::default(), vec3(0.0, 1.0, 0.0)),
        96,
        96,
        built.fov_x,
    );
    let cam_b = camera(
        look_at(vec3(1.2, 1.3, 3.7), Vec3::default(), vec3(0.0, 1.0, 0.0)),
        96,
        96,
        built.fov_x,
    );
    let fa = render(&built.look, g, &cam_a, 4);
    let fb = render(&built.look, g, &cam_b, 4);
    let w2c_b = world_to_camera(&cam_b.c2w);
    let c2w_a = c2w_matrix(&cam_a.c2w);
    let (mut checked, mut close) = (0, 0);
    for y in (10..86).step_by(3) {
        for x in (10..86).step_by(3) {
            let d = fa.depth[(y * 96 + x) as usize];
            if !d.is_finite() || px(&fa, x, y)[3] != 255 {
                continue;
            }
            // World point of pixel centre in A.
            let dir = c2w_a.transform_vector3(vec3(
                (x as f32 + 0.5 - cam_a.cx) / cam_a.fx,
                -(y as f32 + 0.5 - cam_a.cy) / cam_a.fy,
                -1.0,
            ));
            let p = c2w_a.w_axis.truncate() + dir * d;
            let q = w2c_b.transform_point3(p);
            let (u, v) = (
                cam_b.cx + cam_b.fx * q.x / -q.z,
                cam_b.cy - cam_b.fy * q.y / -q.z,
            );
            let (ui, vi) = (u as i32, v as i32);
            if ui < 1 || vi < 1 || ui > 94 || vi > 94 {
                continue;
            }
            let db = fb.depth[(vi as u32 * 96 + ui as u32) as usize];
            if !db.is_finite()
                || (db - (-q.z)).abs() > 0.01
                || px(&fb, ui as u32, vi as u32)[3] != 255
            {
                continue; // occluded in B
            }
            checked += 1;
            let (ca, cb) = (px(&fa, x, y), px(&fb, ui as u32, vi as u32));
            let diff: i32 = (0..3)
                .map(|k| (ca[k] as i32 - cb[k] as i32).abs())
                .max()
                .unwrap();
            if diff < 40 {
                close += 1;
            }
        }
    }
    assert!(checked > 100, "only {checked} co-visible points");
    // Textured surfaces differ a little between views from resampling; most must agree.
    assert!(
        close as f32 > 0.85 * checked as f32,
        "{close} of {checked} agree"
    );
}

fn read_json(p: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn parse_names() {
    assert_eq!(Source::parse("object").unwrap(), Source::Object);
    assert_eq!(Source::parse("avatar").unwrap(), Source::Avatar);
    assert_eq!(
        Source::parse("gltf:a/b.glb").unwrap(),
        Source::Gltf("a/b.glb".into())
    );
    let e = Source::parse("teapot").unwrap_err().to_string();
    for n in ["object", "room", "outdoor", "avatar", "gltf:"] {
        assert!(e.contains(n), "{e}");
    }
    assert!(Source::parse("model.glb")
        .unwrap_err()
        .to_string()
        .contains("gltf:model.glb"));
}

#[test]
fn dataset_layout_and_json() {
    let root = tmpdir("layout");
    let out = root.join("ds");
    let mut spec = SceneSpec::default_for(Source::Object);
    spec.train_views = 5;
    spec.test_views = 3;
    spec.width = 40;
    spec.height = 30;
    spec.supersample = 2;
    let calls = std::cell::RefCell::new(Vec::new());
    let s = write_dataset(&spec, &out, &|d, t| calls.borrow_mut().push((d, t))).unwrap();
    assert_eq!(s["kind"], "object");
    assert_eq!(s["train_views"], 5);
    assert_eq!(calls.borrow().last(), Some(&(8, 8)));
    for (file, n, split) in [
        ("transforms_train.json", 5, "train"),
        ("transforms_val.json", 3, "test"),
        ("transforms_test.json", 3, "test"),
    ] {
        let j = read_json(&out.join(file));
        for k in [
            "camera_angle_x",
            "fl_x",
            "fl_y",
            "cx",
            "cy",
            "w",
            "h",
            "scene_kind",
            "aabb",
            "frames",
        ] {
            assert!(j.get(k).is_some(), "{file} lacks {k}");
        }
        assert_eq!(j["w"], 40);
        assert_eq!(j["cx"].as_f64().unwrap(), 20.0);
        assert_eq!(j["cy"].as_f64().unwrap(), 15.0);
        let fl = j["fl_x"].as_f64().unwrap();
        let ax = j["camera_angle_x"].as_f64().unwrap();
        assert!((fl - 20.0 / (ax / 2.0).tan()).abs() < 1e-3);
        assert_eq!(j["scene_kind"], "object");
        assert_eq!(j["aabb"].as_array().unwrap().len(), 2);
        let frames = j["frames"].as_array().unwrap();
        assert_eq!(frames.len(), n);
        for (i, f) in frames.iter().enumerate() {
            let fp = format!("{split}/r_{i:03}.png");
            assert_eq!(f["file_path"], fp.as_str());
            assert!(f.get("time").is_none());
            let m = f["transform_matrix"].as_array().unwrap();
            assert_eq!(m.len(), 4);
            assert_eq!(m[3], serde_json::json!([0.0, 0.0, 0.0, 1.0]));
            // Camera looks at the origin: -z axis (third column, negated) towards the centre.
            let col = |c: usize| {
                vec3(
                    m[0][c].as_f64().unwrap() as f32,
                    m[1][c].as_f64().unwrap() as f32,
                    m[2][c].as_f64().unwrap() as f32,
                )
            };
            assert!((-col(2)).dot((-col(3)).normalize_or(Vec3::Y)) > 0.99);
            let img = image::open(out.join(&fp)).unwrap();
            assert_eq!((img.width(), img.height()), (40, 30));
            assert_eq!(img.color(), image::ColorType::Rgba8);
        }
    }
    assert_eq!(
        read_json(&out.join("transforms_val.json"))["frames"],
        read_json(&out.join("transforms_test.json"))["frames"]
    );
    // Nothing else is left next to the dataset.
    let names: Vec<_> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "{names:?}");
    // Rewriting over a previous dataset works; over other data it is refused.
    spec.train_views = 2;
    write_dataset(&spec, &out, &|_, _| {}).unwrap();
    assert_eq!(
        read_json(&out.join("transforms_train.json"))["frames"]
            .as_array()
            .unwrap()
            .len(),
        2
    );
    assert!(!out.join("train/r_004.png").exists(), "old frames are gone");
    let other = root.join("precious");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "keep me").unwrap();
    let e = write_dataset(&spec, &other, &|_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("cannot replace"), "{e}");
    assert_eq!(
        std::fs::read_to_string(other.join("notes.txt")).unwrap(),
        "keep me"
    );
    // A user's capture that merely looks like a dataset (it has a transforms_train.json) is
    // not snerf's to replace, and neither is a snerf dataset the user added a photo to.
    let cap = root.join("cap");
    std::fs::create_dir_all(cap.join("train")).unwrap();
    std::fs::write(cap.join("train/IMG_precious.png"), "a photo").unwrap();
    std::fs::write(cap.join("transforms_train.json"), r#"{"camera_angle_x":0.69,"frames":[]}"#).unwrap();
    let e = write_dataset(&spec, &cap, &|_, _| {}).unwrap_err().to_string();
    assert!(e.contains("cannot replace") && e.contains("cap"), "{e}");
    assert_eq!(std::fs::read_to_string(cap.join("train/IMG_precious.png")).unwrap(), "a photo");
    std::fs::write(out.join("train/IMG_precious.png"), "a photo").unwrap();
    let e = write_dataset(&spec, &out, &|_, _| {}).unwrap_err().to_string();
    assert!(e.contains("IMG_precious.png"), "{e}");
    assert!(out.join("train/IMG_precious.png").exists());
    std::fs::remove_file(out.join("train/IMG_precious.png")).unwrap();
    // No test views: refused before anything is written (training needs held-out views).
    let e = write_dataset(&SceneSpec { test_views: 0, ..spec.clone() }, &root.join("novalid"), &|_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("test view"), "{e}");
    assert!(!root.join("novalid").exists());
    // A failing run leaves the previous dataset intact and no temporary directories.
    let bad = SceneSpec {
        source: Source::Gltf(root.join("missing.glb")),
        ..spec.clone()
    };
    let e = write_dataset(&bad, &out, &|_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.glb"), "{e}");
    assert!(out.join("transforms_train.json").exists());
    let names: Vec<_> = std::fs::read_dir(&root)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .collect();
    assert!(names.iter().all(|n| !n.starts_with('.')), "{names:?}");
}

#[test]
fn opaque_scenes_and_kinds() {
    for (src, kind) in [(Source::Room, "forward"), (Source::Outdoor, "unbounded")] {
        let root = tmpdir(kind);
        let out = root.join("ds");
        let mut spec = SceneSpec::default_for(src);
        spec.train_views = 4;
        spec.test_views = 2;
        spec.width = 48;
        spec.height = 36;
        write_dataset(&spec, &out, &|_, _| {}).unwrap();
        let j = read_json(&out.join("transforms_train.json"));
        assert_eq!(j["scene_kind"], kind);
        for i in 0..4 {
            let img = image::open(out.join(format!("train/r_{i:03}.png")))
                .unwrap()
                .to_rgba8();
            assert!(img.pixels().all(|p| p[3] == 255), "{kind} must be opaque");
            // Real content: many distinct colours.
            let mut cols: Vec<[u8; 3]> = img
                .pixels()
                .map(|p| [p[0] >> 3, p[1] >> 3, p[2] >> 3])
                .collect();
            cols.sort();
            cols.dedup();
            assert!(cols.len() > 40, "{kind}: only {} colours", cols.len());
        }
    }
}

#[test]
fn room_content_depths() {
    let built = build_scene(&Source::Room, 0).unwrap();
    let Content::Static(g) = &built.content else {
        panic!()
    };
    let mut rng = crate::math::Rng::new(0);
    let (train, _) = crate::camera::poses(
        crate::camera::layout_for(SceneKind::Forward, false),
        CameraPath::Sphere,
        9,
        1,
        &mut rng,
    );
    for c2w in train {
        let cam = camera(c2w, 64, 48, built.fov_x);
        let f = render(&built.look, g, &cam, 1);
        let min = f.depth.iter().cloned().fold(f32::INFINITY, f32::min);
        let max = f.depth.iter().cloned().fold(0.0f32, f32::max);
        assert!(min >= 1.5, "nearest content at depth {min}");
        assert!((6.0..=10.0).contains(&max), "back wall at depth {max}");
    }
}

fn diff_fraction(a: &Frame, b: &Frame) -> f32 {
    let n = a
        .rgba
        .chunks(4)
        .zip(b.rgba.chunks(4))
        .filter(|(p, q)| (0..4).any(|k| (p[k] as i32 - q[k] as i32).abs() > 20))
        .count();
    n as f32 / (a.width * a.height) as f32
}

#[test]
fn avatar_changes_with_time_static_scenes_do_not() {
    let cam = camera(
        look_at(vec3(0.0, 0.0, 4.0), Vec3::default(), vec3(0.0, 1.0, 0.0)),
        96,
        96,
        40f32.to_radians(),
    );
    let av = build_scene(&Source::Avatar, 0).unwrap();
    let Content::Dynamic(f) = &av.content else {
        panic!("avatar must be dynamic")
    };
    let r = |t: f32| render(&av.look, &f(t).unwrap(), &cam, 2);
    let (f0, f25, f50) = (r(0.0), r(0.25), r(0.5));
    assert!(
        diff_fraction(&f0, &f25) > 0.005,
        "mouth open at t = 0.25 must change the image"
    );
    // t = 0 and t = 0.5: mouth closed both times (two cycles), brows differ slightly.
    assert!(diff_fraction(&f0, &f50) < diff_fraction(&f0, &f25));
    // Mouth interior (dark) visible when open: darkest pixel in the lower face is darker.
    let dark = |f: &Frame| {
        (55..75)
            .flat_map(|y| (38..58).map(move |x| (x, y)))
            .map(|(x, y)| px(f, x, y)[0] as u32)
            .min()
            .unwrap()
    };
    assert!(
        dark(&f25) + 30 < dark(&f0),
        "open {} closed {}",
        dark(&f25),
        dark(&f0)
    );

    let obj = build_scene(&Source::Object, 0).unwrap();
    let Content::Static(g) = &obj.content else {
        panic!()
    };
    let a = render(&obj.look, g, &cam, 2);
    let b = render(&obj.look, g, &cam, 2);
    assert_eq!(a.rgba, b.rgba, "static scenes render deterministically");
}

#[test]
fn avatar_dataset_has_times() {
    let root = tmpdir("avatar");
    let out = root.join("ds");
    let mut spec = SceneSpec::default_for(Source::Avatar);
    spec.train_views = 9;
    spec.test_views = 3;
    spec.width = 32;
    spec.height = 32;
    spec.supersample = 2;
    let s = write_dataset(&spec, &out, &|_, _| {}).unwrap();
    assert_eq!(s["dynamic"], true);
    let times = |f: &str| -> Vec<f64> {
        read_json(&out.join(f))["frames"]
            .as_array()
            .unwrap()
            .iter()
            .map(|fr| fr["time"].as_f64().unwrap())
            .collect()
    };
    let tr = times("transforms_train.json");
    let te = times("transforms_test.json");
    assert_eq!(tr.first(), Some(&0.0));
    assert_eq!(tr.last(), Some(&1.0));
    assert!(te
        .iter()
        .all(|t| (0.0..=1.0).contains(t) && tr.iter().all(|x| (x - t).abs() > 1e-4)));
    let img = image::open(out.join("train/r_000.png")).unwrap().to_rgba8();
    assert!(img.pixels().any(|p| p[3] == 0) && img.pixels().any(|p| p[3] == 255));
}

#[test]
fn bad_specs_are_errors() {
    let root = tmpdir("bad");
    let mut spec = SceneSpec::default_for(Source::Object);
    spec.width = 0;
    assert!(write_dataset(&spec, &root.join("x"), &|_, _| {}).is_err());
    let mut spec = SceneSpec::default_for(Source::Object);
    spec.train_views = 0;
    assert!(write_dataset(&spec, &root.join("x"), &|_, _| {}).is_err());
    assert!(!root.join("x").exists());
}

/// 100 views at 128x128 with 4x4 supersampling: prints the time (the brief asks for a few seconds).
#[test]
fn speed_100_views_128() {
    let root = tmpdir("speed");
    let mut spec = SceneSpec::default_for(Source::Object);
    spec.train_views = 100;
    spec.test_views = 1;
    spec.width = 128;
    spec.height = 128;
    let t = std::time::Instant::now();
    write_dataset(&spec, &root.join("ds"), &|_, _| {}).unwrap();
    let secs = t.elapsed().as_secs_f64();
    println!(
        "object: 100 views 128x128 ss4 in {secs:.2} s ({} threads)",
        rayon::current_num_threads()
    );
    for src in [Source::Room, Source::Outdoor, Source::Avatar] {
        let name = src.name();
        let spec = SceneSpec {
            source: src,
            train_views: 100,
            test_views: 1,
            width: 128,
            height: 128,
            ..spec.clone()
        };
        let t = std::time::Instant::now();
        write_dataset(&spec, &root.join(&name), &|_, _| {}).unwrap();
        println!(
            "{name}: 100 views 128x128 ss4 in {:.2} s",
            t.elapsed().as_secs_f64()
        );
    }
}

// ---------------------------------------------------------------------------------------
// glTF

fn b64(data: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in data.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                s.push(T[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// A textured quad (left half red, right half green) with a morph target and an animation
/// that moves it right and back while the morph weight goes 0 -> 1 -> 0, all embedded.
fn tiny_gltf(dir: &Path, positions_override: Option<[f32; 3]>, mode: u32) -> PathBuf {
    let mut png = Vec::new();
    let mut img = image::RgbaImage::new(8, 8);
    for (x, _, p) in img.enumerate_pixels_mut() {
        *p = if x < 4 {
            image::Rgba([255, 0, 0, 255])
        } else {
            image::Rgba([0, 255, 0, 255])
        };
    }
    image::DynamicImage::ImageRgba8(img)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let mut buf: Vec<u8> = Vec::new();
    let f32s = |buf: &mut Vec<u8>, v: &[f32]| {
        v.iter()
            .for_each(|x| buf.extend_from_slice(&x.to_le_bytes()))
    };
    let mut pos = vec![
        -1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0f32,
    ];
    if let Some(p) = positions_override {
        pos[0..3].copy_from_slice(&p);
    }
    f32s(&mut buf, &pos); // 0..48
    f32s(&mut buf, &[0.0, 0.0, 1.0].repeat(4)); // 48..96
    f32s(&mut buf, &[0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]); // 96..128
    for i in [0u16, 1, 2, 0, 2, 3] {
        buf.extend_from_slice(&i.to_le_bytes()); // 128..140
    }
    f32s(
        &mut buf,
        &[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.5, 0.0],
    ); // 140..188
    f32s(&mut buf, &[0.0, 1.0, 2.0]); // 188..200
    f32s(&mut buf, &[0.0, 0.0, 0.0, 0.6, 0.0, 0.0, 0.0, 0.0, 0.0]); // 200..236
    f32s(&mut buf, &[0.0, 1.0, 0.0]); // 236..248
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "root", "children": [1]}, {"name": "quad", "mesh": 0}],
        "meshes": [{"name": "quad", "weights": [0.0], "primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
            "indices": 3, "material": 0, "mode": mode,
            "targets": [{"POSITION": 4}]
        }]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
        "textures": [{"source": 0, "sampler": 0}],
        "samplers": [{"wrapS": 33071, "wrapT": 33071}],
        "images": [{"uri": format!("data:image/png;base64,{}", b64(&png))}],
        "buffers": [{"byteLength": buf.len(), "uri": format!("data:application/octet-stream;base64,{}", b64(&buf))}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 32},
            {"buffer": 0, "byteOffset": 128, "byteLength": 12},
            {"buffer": 0, "byteOffset": 140, "byteLength": 48},
            {"buffer": 0, "byteOffset": 188, "byteLength": 12},
            {"buffer": 0, "byteOffset": 200, "byteLength": 36},
            {"buffer": 0, "byteOffset": 236, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1.0, -1.0, 0.0], "max": [1.0, 1.0, 0.0]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"},
            {"bufferView": 4, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0.0, 0.0, 0.0], "max": [0.0, 0.5, 0.0]},
            {"bufferView": 5, "componentType": 5126, "count": 3, "type": "SCALAR", "min": [0.0], "max": [2.0]},
            {"bufferView": 6, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 7, "componentType": 5126, "count": 3, "type": "SCALAR"}
        ],
        "animations": [{"name": "wiggle", "channels": [
            {"sampler": 0, "target": {"node": 1, "path": "translation"}},
            {"sampler": 1, "target": {"node": 1, "path": "weights"}}
        ], "samplers": [
            {"input": 5, "output": 6, "interpolation": "LINEAR"},
            {"input": 5, "output": 7, "interpolation": "LINEAR"}
        ]}]
    });
    let p = dir.join("tiny.gltf");
    std::fs::write(&p, serde_json::to_string(&doc).unwrap()).unwrap();
    p
}

#[test]
fn gltf_built_in_code_textured_and_animated() {
    let root = tmpdir("gltf");
    let file = tiny_gltf(&root, None, 4);
    let built = crate::gltf_load::load(&file).unwrap();
    assert!(built.is_dynamic(), "animated glTF gives a 4D sequence");
    assert_eq!(built.look.textures.len(), 1);
    assert_eq!(built.info["animation"], "wiggle");
    let Content::Dynamic(f) = &built.content else {
        panic!()
    };
    // Normalized into the unit sphere over the whole animation.
    for t in [0.0, 0.25, 0.5, 1.0] {
        let g = f(t).unwrap();
        assert!(g.positions.iter().all(|p| p.length() <= 1.0 + 1e-4));
    }
    // At t = 0.5 (1 s): translated by +0.6 and the top raised by 0.5 through the morph target.
    let (g0, g5) = (f(0.0).unwrap(), f(0.5).unwrap());
    let s = built.info["normalize_scale"].as_f64().unwrap() as f32;
    let d = g5.positions[0] - g0.positions[0];
    assert!((d.x - 0.6 * s).abs() < 1e-4 && d.y.abs() < 1e-5, "{d:?}");
    let d2 = g5.positions[2] - g0.positions[2];
    assert!((d2.y - 0.5 * s).abs() < 1e-4, "{d2:?}");
    // Texture: the left of the quad is red, the right green.
    let cam = camera(
        look_at(vec3(0.0, 0.0, 4.0), Vec3::default(), vec3(0.0, 1.0, 0.0)),
        64,
        64,
        built.fov_x,
    );
    let fr = render(&built.look, &g0, &cam, 2);
    let pts: Vec<[u8; 4]> = fr
        .rgba
        .chunks(4)
        .filter(|p| p[3] == 255)
        .map(|p| [p[0], p[1], p[2], p[3]])
        .collect();
    assert!(
        pts.iter().any(|p| p[0] > 150 && p[1] < 40),
        "red half visible"
    );
    assert!(
        pts.iter().any(|p| p[1] > 150 && p[0] < 40),
        "green half visible"
    );
    assert!(diff_fraction(&fr, &render(&built.look, &g5, &cam, 2)) > 0.05);
    // As a dataset: frames carry times.
    let spec = SceneSpec {
        train_views: 4,
        test_views: 2,
        width: 32,
        height: 32,
        supersample: 2,
        ..SceneSpec::default_for(Source::Gltf(file.clone()))
    };
    let s = write_dataset(&spec, &root.join("ds"), &|_, _| {}).unwrap();
    assert_eq!(s["dynamic"], true);
    assert!(s["normalize_scale"].as_f64().unwrap() > 0.0);
    let j = read_json(&root.join("ds/transforms_train.json"));
    assert!(j["frames"][1]["time"].is_number());
    // Triangle strip mode converts too (quad as a 2-triangle strip of indices 0 1 2 0 2 3 -> 4 triangles).
    let strip = tiny_gltf(&root, None, 5);
    assert!(crate::gltf_load::load(&strip).is_ok());
}

#[test]
fn gltf_jpeg_texture() {
    let root = tmpdir("gltf-jpeg");
    let file = tiny_gltf(&root, None, 4);
    let mut img = image::RgbImage::new(16, 16);
    for (x, _, p) in img.enumerate_pixels_mut() {
        *p = if x < 8 {
            image::Rgb([250, 10, 10])
        } else {
            image::Rgb([10, 250, 10])
        };
    }
    let mut jpg = Vec::new();
    image::DynamicImage::ImageRgb8(img)
        .write_to(
            &mut std::io::Cursor::new(&mut jpg),
            image::ImageFormat::Jpeg,
        )
        .unwrap();
    let mut doc = read_json(&file);
    doc["images"][0]["uri"] = format!("data:image/jpeg;base64,{}", b64(&jpg)).into();
    std::fs::write(&file, doc.to_string()).unwrap();
    let b = crate::gltf_load::load(&file).unwrap();
    assert_eq!(
        b.look.textures.len(),
        1,
        "JPEG texture decoded: {:?}",
        b.warnings
    );
    let Content::Dynamic(f) = &b.content else {
        panic!()
    };
    let cam = camera(
        look_at(vec3(0.0, 0.0, 4.0), Vec3::default(), vec3(0.0, 1.0, 0.0)),
        64,
        64,
        b.fov_x,
    );
    let fr = render(&b.look, &f(0.0).unwrap(), &cam, 2);
    assert!(fr
        .rgba
        .chunks(4)
        .any(|p| p[3] == 255 && p[0] > 150 && p[1] < 60));
}

#[test]
fn gltf_errors_are_clear() {
    let root = tmpdir("gltf-err");
    // Non-finite position.
    let f = tiny_gltf(&root, Some([f32::INFINITY, 0.0, 0.0]), 4);
    let e = format!(
        "{:#}",
        crate::gltf_load::load(&f).err().expect("inf must fail")
    );
    assert!(
        e.contains("tiny.gltf") && e.contains("quad") && e.contains("non-finite"),
        "{e}"
    );
    // Points only: nothing to render.
    let f = tiny_gltf(&root, None, 0);
    let e = format!(
        "{:#}",
        crate::gltf_load::load(&f).err().expect("points must fail")
    );
    assert!(e.contains("no triangles"), "{e}");
    // Not a glTF file.
    let junk = root.join("junk.glb");
    std::fs::write(&junk, b"not a model").unwrap();
    let e = format!("{:#}", crate::gltf_load::load(&junk).err().unwrap());
    assert!(e.contains("junk.glb"), "{e}");
    let e = format!(
        "{:#}",
        crate::gltf_load::load(&root.join("nope.gltf"))
            .err()
            .unwrap()
    );
    assert!(e.contains("nope.gltf") && e.contains("no such file"), "{e}");
}

// Installed test models (skipped with a note when absent).

const ASSIMP: &str = "/usr/share/assimp/models/glTF2";

fn model(rel: &str) -> Option<PathBuf> {
    let p = if rel.starts_with('/') {
        PathBuf::from(rel)
    } else {
        Path::new(ASSIMP).join(rel)
    };
    if p.exists() {
        Some(p)
    } else {
        println!(
            "note: {} not installed; skipping (apt-get install -y assimp-testmodels)",
            p.display()
        );
        None
    }
}

fn render_model(p: &Path) -> (crate::procedural::Built, Frame) {
    let b = crate::gltf_load::load(p).unwrap_or_else(|e| panic!("{}: {e:#}", p.display()));
    let g = match &b.content {
        Content::Static(g) => g.clone(),
        Content::Dynamic(f) => f(0.3).unwrap(),
    };
    let cam = camera(
        look_at(vec3(2.0, 2.0, 3.0), Vec3::default(), vec3(0.0, 1.0, 0.0)),
        64,
        64,
        b.fov_x,
    );
    let f = render(&b.look, &g, &cam, 2);
    (b, f)
}

fn coverage(f: &Frame) -> f32 {
    f.rgba.chunks(4).filter(|p| p[3] > 0).count() as f32 / (f.width * f.height) as f32
}

#[test]
fn assimp_box_textured_and_engine() {
    for rel in [
        "BoxTextured-glTF/BoxTextured.gltf",
        "BoxTextured-glTF-Binary/BoxTextured.glb",
        "BoxTextured-glTF-Embedded/BoxTextured.gltf",
    ] {
        let Some(p) = model(rel) else { return };
        let (b, f) = render_model(&p);
        assert_eq!(b.look.textures.len(), 1, "{rel}: texture loaded");
        assert!(coverage(&f) > 0.1, "{rel}");
        // The CesiumLogo texture is not grey: some saturated pixels.
        assert!(
            f.rgba
                .chunks(4)
                .any(|p| p[3] == 255 && (p[0] as i32 - p[2] as i32).abs() > 40),
            "{rel}"
        );
    }
    let Some(p) = model("2CylinderEngine-glTF-Binary/2CylinderEngine.glb") else {
        return;
    };
    let (b, f) = render_model(&p);
    assert!(b.info["triangles"].as_u64().unwrap() > 10000);
    assert!(coverage(&f) > 0.05);
}

#[test]
fn assimp_animated_models() {
    for rel in [
        "glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf",
        "simple_skin/simple_skin.gltf",
    ] {
        let Some(p) = model(rel) else { return };
        let b = crate::gltf_load::load(&p).unwrap_or_else(|e| panic!("{rel}: {e:#}"));
        assert!(b.is_dynamic(), "{rel} is animated");
        let Content::Dynamic(f) = &b.content else {
            panic!()
        };
        let cam = camera(
            look_at(vec3(0.5, 1.0, 4.0), Vec3::default(), vec3(0.0, 1.0, 0.0)),
            64,
            64,
            b.fov_x,
        );
        let frames: Vec<Frame> = [0.0, 0.25, 0.5, 0.75]
            .iter()
            .map(|&t| render(&b.look, &f(t).unwrap(), &cam, 2))
            .collect();
        let max_diff = frames
            .windows(2)
            .map(|w| diff_fraction(&w[0], &w[1]))
            .fold(0.0, f32::max);
        assert!(
            max_diff > 0.01,
            "{rel}: frames over time must differ ({max_diff})"
        );
        for fr in &frames {
            assert!(coverage(fr) > 0.02, "{rel}");
        }
    }
}

#[test]
fn assimp_bad_files_give_errors() {
    let Some(p) = model("BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb") else {
        return;
    };
    let e = format!(
        "{:#}",
        crate::gltf_load::load(&p)
            .err()
            .expect("BoxWithInfinites must fail")
    );
    println!("BoxWithInfinites: {e}");
    assert!(
        e.contains("BoxWithInfinites.glb") && e.contains("mesh") && e.contains("non-finite"),
        "{e}"
    );
    for rel in [
        "MissingBin/BoxTextured.gltf",
        "IndexOutOfRange/IndexOutOfRange.gltf",
        "IndexOutOfRange/AllIndicesOutOfRange.gltf",
        "RecursiveNodes/RecursiveNodes.gltf",
        "SchemaFailures/sceneWrongType.gltf",
        "TestNoRootNode/NoScene.gltf",
        "TestNoRootNode/SceneWithoutNodes.gltf",
        "wrongTypes/badArray.gltf",
        "IncorrectVertexArrays/Cube.gltf",
        "BoxBadNormals-glTF-Binary/BoxBadNormals.glb",
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_00.gltf",
        "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_13.gltf",
        "textureTransform/TextureTransformTest.gltf",
        "issue_3269/texcoord_crash.gltf",
    ] {
        let Some(p) = model(rel) else { continue };
        // Must never panic; errors must name the file.
        match crate::gltf_load::load(&p) {
            Ok(b) => println!(
                "{rel}: ok ({} triangles, warnings {:?})",
                b.info["triangles"], b.warnings
            ),
            Err(e) => {
                let e = format!("{e:#}");
                println!("{rel}: error: {e}");
                assert!(
                    e.contains(p.file_name().unwrap().to_str().unwrap()),
                    "{rel}: {e}"
                );
            }
        }
    }
}

/// Where `.ci/run` installs the npm package `@webxr-input-profiles/assets`
/// (override with SNERF_WEBXR_DIR).
fn webxr_profiles() -> PathBuf {
    let root = std::env::var("SNERF_WEBXR_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|_| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../target/test-assets/webxr")));
    root.join("node_modules/@webxr-input-profiles/assets/dist/profiles")
}

#[test]
fn webxr_controller_glb() {
    let p = webxr_profiles().join("generic-trigger-squeeze/left.glb");
    let p = if p.exists() {
        p
    } else {
        println!("note: {} not installed; skipping (bash .ci/run installs it)", p.display());
        return;
    };
    let (b, f) = render_model(&p);
    println!(
        "webxr: {} triangles, {} textures, warnings {:?}",
        b.info["triangles"],
        b.look.textures.len(),
        b.warnings
    );
    assert!(!b.look.textures.is_empty(), "controller texture loaded");
    assert!(coverage(&f) > 0.03);
}

/// Writes a contact sheet per scene to $SNERF_PREVIEW_DIR (default /tmp/snerf-previews) for
/// looking at by eye: `cargo test --release -p snerf-scene -- --ignored previews`.
#[test]
#[ignore]
fn previews() {
    let dir = PathBuf::from(
        std::env::var("SNERF_PREVIEW_DIR").unwrap_or_else(|_| "/tmp/snerf-previews".into()),
    );
    std::fs::create_dir_all(&dir).unwrap();
    let mut sources = vec![
        Source::Object,
        Source::Room,
        Source::Outdoor,
        Source::Avatar,
    ];
    for rel in [
        "BoxTextured-glTF/BoxTextured.gltf",
        "2CylinderEngine-glTF-Binary/2CylinderEngine.glb",
        "simple_skin/simple_skin.gltf",
        "glTF-Sample-Models/AnimatedMorphCube-glTF/AnimatedMorphCube.gltf",
    ] {
        if let Some(p) = model(rel) {
            sources.push(Source::Gltf(p));
        }
    }
    let xr = webxr_profiles().join("generic-trigger-squeeze/left.glb");
    if xr.exists() {
        sources.push(Source::Gltf(xr));
    }
    for (k, src) in sources.into_iter().enumerate() {
        let out = dir.join(format!("ds{k}"));
        let mut spec = SceneSpec::default_for(src.clone());
        spec.train_views = 8;
        spec.test_views = 0;
        spec.width = 160;
        spec.height = 120;
        write_dataset(&spec, &out, &|_, _| {}).unwrap();
        let mut sheet =
            image::RgbaImage::from_pixel(160 * 4, 120 * 2, image::Rgba([60, 60, 60, 255]));
        for i in 0..8 {
            let img = image::open(out.join(format!("train/r_{i:03}.png")))
                .unwrap()
                .to_rgba8();
            for (x, y, p) in img.enumerate_pixels() {
                let a = p[3] as f32 / 255.0;
                let bg = 60.0 * (1.0 - a);
                let q = image::Rgba([
                    (p[0] as f32 * a + bg) as u8,
                    (p[1] as f32 * a + bg) as u8,
                    (p[2] as f32 * a + bg) as u8,
                    255,
                ]);
                sheet.put_pixel((i % 4) * 160 + x, (i / 4) * 120 + y, q);
            }
        }
        sheet.save(dir.join(format!("sheet{k}.png"))).unwrap();
        println!("sheet{k}: {}", src.name());
    }
}
