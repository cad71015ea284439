//! Each format loads intrinsics, poses, splits and images right; the same camera written in all
//! formats loads to the same OpenGL c2w and focal.

mod common;

use common::*;
use serde_json::json;
use snerf_data::{load, summary, LoadOptions, SceneKind};

fn no_holdout() -> LoadOptions {
    LoadOptions {
        holdout_every: Some(0),
        ..Default::default()
    }
}

#[test]
fn same_cameras_agree_across_all_formats() {
    let cams = ring_cameras(5);
    let ns = TempDir::new("x-ns");
    write_nerfstudio(ns.path(), &cams, false, None);
    let bl = TempDir::new("x-bl");
    write_blender_single(bl.path(), &cams, false);
    let ll = TempDir::new("x-llff");
    write_llff(ll.path(), &cams);
    let cb = TempDir::new("x-colbin");
    write_colmap(cb.path(), &cams, true);
    let ct = TempDir::new("x-coltxt");
    write_colmap(ct.path(), &cams, false);

    let opts = no_holdout();
    let sets = [
        ("nerfstudio", load(ns.path(), &opts).unwrap()),
        ("blender", load(bl.path(), &opts).unwrap()),
        ("llff", load(ll.path(), &opts).unwrap()),
        ("colmap", load(cb.path(), &opts).unwrap()),
        ("colmap", load(ct.path(), &opts).unwrap()),
    ];
    for (fmt, ds) in &sets {
        assert_eq!(&ds.format, fmt);
        assert_eq!(ds.train.len(), cams.len(), "{fmt}");
        assert!(ds.test.is_empty() && ds.val.is_empty());
        for (i, (v, c)) in ds.train.iter().zip(&cams).enumerate() {
            assert_c2w_close(&v.c2w, c, 1e-5, &format!("{fmt} view {i}"));
            let k = v.intrinsics;
            assert_eq!((k.width, k.height), (W, H), "{fmt}");
            assert!(
                (k.fx - F as f32).abs() < 1e-4 && (k.fy - F as f32).abs() < 1e-4,
                "{fmt}: {k:?}"
            );
            assert!(
                (k.cx - 4.0).abs() < 1e-6 && (k.cy - 3.0).abs() < 1e-6,
                "{fmt}: {k:?}"
            );
            assert_eq!(k.distortion, [0.0; 4]);
            assert_eq!(v.rgba.len(), (W * H * 4) as usize);
            // Pixel (1, 0) of image i: R = i + 10, G = 0, B = 128.
            assert_eq!(
                &v.rgba[4..8],
                &[i as u8 + 10, 0, 128, 255],
                "{fmt} view {i}"
            );
        }
    }
    // The c2w is a proper rotation: -z looks at the target.
    let v = &sets[0].1.train[0];
    let f = v.forward();
    let o = v.origin();
    let to_target = [-o[0], 0.2 - o[1], -o[2]];
    let n = (to_target.iter().map(|x| x * x).sum::<f32>()).sqrt();
    let cos = (f[0] * to_target[0] + f[1] * to_target[1] + f[2] * to_target[2]) / n;
    assert!(
        cos > 0.9999,
        "camera does not look at the target: cos {cos}"
    );
}

#[test]
fn blender_splits_and_extensionless_paths() {
    let d = TempDir::new("blender-splits");
    let cams = ring_cameras(6);
    let angle_x = 2.0 * (W as f64 / (2.0 * F)).atan();
    for (split, range) in [("train", 0..3), ("val", 3..4), ("test", 4..6)] {
        let frames: Vec<_> = range
            .map(|i| {
                write_png(&d.path().join(format!("{split}/r_{i}.png")), W, H, i as u8, true);
                json!({ "file_path": format!("./{split}/r_{i}"), "transform_matrix": mat4(&cams[i]) })
            })
            .collect();
        write_json(
            &d.path().join(format!("transforms_{split}.json")),
            &json!({ "camera_angle_x": angle_x, "camera_angle_y": angle_x, "frames": frames }),
        );
    }
    let ds = load(d.path(), &LoadOptions::default()).unwrap();
    assert_eq!(ds.format, "blender");
    assert_eq!((ds.train.len(), ds.val.len(), ds.test.len()), (3, 1, 2));
    assert!(ds.test[1].path.ends_with("test/r_5.png"));
    assert_c2w_close(&ds.val[0].c2w, &cams[3], 1e-5, "val");
    // camera_angle_y with H != W gives fy from the height.
    let fy = 0.5 * H as f64 / (0.5 * angle_x).tan();
    assert!((ds.train[0].intrinsics.fy - fy as f32).abs() < 1e-4);
    // Passing one split file loads the whole set.
    let ds2 = load(
        &d.path().join("transforms_test.json"),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(ds2.train.len(), 3);
    assert_eq!(ds2.kind, SceneKind::Object);
}

#[test]
fn nerfstudio_per_frame_intrinsics_distortion_hints_and_holdout() {
    let d = TempDir::new("ns-perframe");
    let cams = ring_cameras(10);
    let frames: Vec<_> = cams
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let name = format!("rgb/{i}.png");
            write_rgb_png(&d.path().join(&name), W, H, i as u8);
            json!({ "file_path": name, "transform_matrix": mat4(c), "fl_x": 5.0 + i as f64, "cx": 3.5,
                    "k1": 0.01 * i as f64, "p2": -0.002 })
        })
        .collect();
    write_json(
        &d.path().join("transforms.json"),
        &json!({ "camera_model": "OPENCV", "fl_x": 99.0, "fl_y": 6.0, "cy": 2.5, "w": W, "h": H,
                 "scene_kind": "unbounded", "aabb": [[-1, -2, -3], [1, 2, 3]], "frames": frames }),
    );
    let ds = load(&d.path().join("transforms.json"), &LoadOptions::default()).unwrap();
    assert_eq!(ds.format, "nerfstudio");
    // Holdout every 8th: frames 0 and 8 are test.
    assert_eq!((ds.train.len(), ds.test.len()), (8, 2));
    assert!(ds.test[1].path.ends_with("rgb/8.png"));
    let k = ds.train[0].intrinsics; // frame 1
    assert_eq!((k.fx, k.fy, k.cx, k.cy), (6.0, 6.0, 3.5, 2.5));
    assert!((k.distortion[0] - 0.01).abs() < 1e-7 && k.distortion[3] == -0.002);
    // RGB file -> alpha 255.
    assert!(ds.train[0].rgba.chunks_exact(4).all(|p| p[3] == 255));
    assert_eq!(ds.kind, SceneKind::Unbounded);
    assert!(ds.detection_note.contains("hint"), "{}", ds.detection_note);
    assert_eq!(ds.aabb, Some(([-1.0, -2.0, -3.0], [1.0, 2.0, 3.0])));
    let s = summary(&ds);
    assert_eq!(s["counts"]["train"], 8);
    assert_eq!(s["kind"], "unbounded");
    assert_eq!(s["image_sizes"], json!([[W, H]]));
    assert_eq!(s["aabb"], json!([[-1.0, -2.0, -3.0], [1.0, 2.0, 3.0]]));
    assert!(s["time_range"].is_null());
}

#[test]
fn nerfstudio_filename_split_lists() {
    let d = TempDir::new("ns-lists");
    write_nerfstudio(d.path(), &ring_cameras(4), false, None);
    let p = d.path().join("transforms.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    v["train_filenames"] = json!(["images/frame_000.png", "images/frame_002.png"]);
    v["val_filenames"] = json!(["./images/frame_001.png"]);
    v["test_filenames"] = json!(["images/frame_003.png"]);
    write_json(&p, &v);
    let ds = load(d.path(), &LoadOptions::default()).unwrap();
    assert_eq!((ds.train.len(), ds.val.len(), ds.test.len()), (2, 1, 1));
    assert!(ds.val[0].path.ends_with("frame_001.png"));
}

#[test]
fn downscale_box_filters_and_scales_intrinsics() {
    let d = TempDir::new("ns-down");
    write_nerfstudio(d.path(), &ring_cameras(3), false, None);
    let opts = LoadOptions {
        downscale: Some(2),
        holdout_every: Some(0),
        ..Default::default()
    };
    let ds = load(d.path(), &opts).unwrap();
    let v = &ds.train[1];
    let k = v.intrinsics;
    assert_eq!((k.width, k.height), (4, 3));
    assert_eq!((k.fx, k.fy, k.cx, k.cy), (3.5, 3.5, 2.0, 1.5));
    assert_eq!(v.rgba.len(), 4 * 3 * 4);
    // Pixel (0,0) averages x in {0,1}, y in {0,1}: R = 1 + (0 + 10)/2 = 6, G = (0+20)/2 = 10.
    assert_eq!(&v.rgba[..4], &[6, 10, 128, 255]);
}

#[test]
fn sixteen_bit_and_gray_pngs_become_rgba8() {
    let d = TempDir::new("ns-16bit");
    let cams = ring_cameras(2);
    write_nerfstudio(d.path(), &cams, false, None);
    let img16 = image::ImageBuffer::<image::Rgba<u16>, _>::from_fn(W, H, |x, _| {
        image::Rgba([65535, 0, 32896, if x == 0 { 0 } else { 65535 }])
    });
    img16.save(d.path().join("images/frame_000.png")).unwrap();
    let gray = image::GrayImage::from_fn(W, H, |x, _| image::Luma([x as u8 * 30]));
    gray.save(d.path().join("images/frame_001.png")).unwrap();
    let ds = load(d.path(), &no_holdout()).unwrap();
    assert_eq!(&ds.train[0].rgba[..8], &[255, 0, 128, 0, 255, 0, 128, 255]);
    assert_eq!(&ds.train[1].rgba[4..8], &[30, 30, 30, 255]);
}

#[test]
fn llff_bounds_holdout_images_n_and_downscale() {
    let d = TempDir::new("llff");
    let cams = forward_cameras(9);
    write_llff(d.path(), &cams);
    let ds = load(d.path(), &LoadOptions::default()).unwrap();
    assert_eq!(ds.format, "llff");
    assert_eq!((ds.train.len(), ds.test.len()), (7, 2));
    assert!(ds.test[0].path.ends_with("IMG_000.png") && ds.test[1].path.ends_with("IMG_008.png"));
    assert_c2w_close(&ds.train[0].c2w, &cams[1], 1e-5, "llff view 1");
    let (n, f) = ds.near_far.unwrap();
    assert!((n - 1.0).abs() < 1e-6 && (f - 18.0).abs() < 1e-6, "{n} {f}");
    assert_eq!(ds.kind, SceneKind::Forward);

    // Software downscale (no images_2 folder): focal halves.
    let opts = LoadOptions {
        downscale: Some(2),
        ..Default::default()
    };
    let ds2 = load(d.path(), &opts).unwrap();
    assert_eq!(ds2.train[0].intrinsics.fx, 3.5);
    assert_eq!(ds2.train[0].intrinsics.width, 4);

    // images_2 folder with 4x3 images is used as is; focal scales by 4 / 8.
    for i in 0..cams.len() {
        write_png(
            &d.path().join(format!("images_2/IMG_{i:03}.png")),
            4,
            3,
            200,
            false,
        );
    }
    let ds3 = load(&d.path().join("poses_bounds.npy"), &opts).unwrap();
    let k = ds3.train[0].intrinsics;
    assert_eq!((k.width, k.height, k.fx, k.cx, k.cy), (4, 3, 3.5, 2.0, 1.5));
    assert!(ds3.train[0].path.to_string_lossy().contains("images_2"));
    assert_eq!(ds3.train[0].rgba[0], 200);
}

#[test]
fn llff_f4_npy_is_read() {
    let d = TempDir::new("llff-f4");
    let cams = forward_cameras(3);
    write_llff(d.path(), &cams);
    let body: Vec<u8> = cams
        .iter()
        .flat_map(|c| llff_row(c, 1.0, 5.0))
        .flat_map(|v| (v as f32).to_le_bytes())
        .collect();
    std::fs::write(
        d.path().join("poses_bounds.npy"),
        npy_bytes("<f4", &[3, 17], &body),
    )
    .unwrap();
    let ds = load(d.path(), &no_holdout()).unwrap();
    assert_c2w_close(&ds.train[2].c2w, &cams[2], 1e-5, "f4");
}

#[test]
fn colmap_models_layouts_and_text_binary_agree() {
    let cams = ring_cameras(4);
    let models: Vec<ColmapCam> = vec![
        ColmapCam {
            id: 1,
            model: "SIMPLE_PINHOLE",
            model_id: 0,
            w: 8,
            h: 6,
            params: vec![7.0, 4.0, 3.0],
        },
        ColmapCam {
            id: 2,
            model: "SIMPLE_RADIAL",
            model_id: 2,
            w: 8,
            h: 6,
            params: vec![6.0, 4.5, 3.5, 0.1],
        },
        ColmapCam {
            id: 3,
            model: "RADIAL",
            model_id: 3,
            w: 8,
            h: 6,
            params: vec![6.0, 4.5, 3.5, 0.1, -0.2],
        },
        ColmapCam {
            id: 7,
            model: "OPENCV",
            model_id: 4,
            w: 8,
            h: 6,
            params: vec![6.0, 6.5, 4.5, 3.5, 0.1, -0.2, 0.01, 0.02],
        },
    ];
    let mut imgs = colmap_images(&cams);
    // Names out of order: loader sorts by name.
    imgs.reverse();
    for (im, c) in imgs.iter_mut().zip([1, 2, 3, 7]) {
        im.cam = c;
    }
    let mut loaded = Vec::new();
    for binary in [false, true] {
        // Model straight in the root (no sparse/), images/ next to it.
        let d = TempDir::new("colmap-models");
        if binary {
            std::fs::write(d.path().join("cameras.bin"), cameras_bin(&models)).unwrap();
            std::fs::write(d.path().join("images.bin"), images_bin(&imgs)).unwrap();
        } else {
            std::fs::write(d.path().join("cameras.txt"), cameras_txt(&models)).unwrap();
            std::fs::write(d.path().join("images.txt"), images_txt(&imgs)).unwrap();
        }
        for im in &imgs {
            write_png(&d.path().join("images").join(&im.name), 8, 6, 1, false);
        }
        let file = d
            .path()
            .join(if binary { "images.bin" } else { "images.txt" });
        let ds = load(&file, &no_holdout()).unwrap();
        assert_eq!(ds.format, "colmap");
        let names: Vec<_> = ds
            .train
            .iter()
            .map(|v| v.path.file_name().unwrap().to_string_lossy().to_string())
            .collect();
        assert_eq!(
            names,
            ["img_00.png", "img_01.png", "img_02.png", "img_03.png"]
        );
        for (i, v) in ds.train.iter().enumerate() {
            assert_c2w_close(&v.c2w, &cams[i], 1e-5, "colmap");
        }
        // img_03 uses camera 1 (SIMPLE_PINHOLE), img_00 camera 7 (OPENCV).
        let k = ds.train[3].intrinsics;
        assert_eq!(
            (k.fx, k.fy, k.cx, k.cy, k.distortion),
            (7.0, 7.0, 4.0, 3.0, [0.0; 4])
        );
        let k = ds.train[2].intrinsics;
        assert_eq!((k.fx, k.fy, k.distortion), (6.0, 6.0, [0.1, 0.0, 0.0, 0.0]));
        let k = ds.train[1].intrinsics;
        assert_eq!(k.distortion, [0.1, -0.2, 0.0, 0.0]);
        let k = ds.train[0].intrinsics;
        assert_eq!(
            (k.fx, k.fy, k.cx, k.cy, k.distortion),
            (6.0, 6.5, 4.5, 3.5, [0.1, -0.2, 0.01, 0.02])
        );
        loaded.push(ds);
    }
    for (a, b) in loaded[0].train.iter().zip(&loaded[1].train) {
        assert_eq!(a.c2w, b.c2w);
        assert_eq!(a.intrinsics, b.intrinsics);
    }
}

#[test]
fn colmap_sparse_dir_holdout_and_images_n() {
    let d = TempDir::new("colmap-sparse");
    let cams = ring_cameras(10);
    write_colmap(d.path(), &cams, true);
    let ds = load(
        d.path(),
        &LoadOptions {
            holdout_every: Some(4),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!((ds.train.len(), ds.test.len()), (7, 3));
    assert!(ds.test[2].path.ends_with("images/img_08.png"));
    assert_eq!(ds.root, d.path());
    let opts = LoadOptions {
        downscale: Some(2),
        holdout_every: Some(0),
        ..Default::default()
    };
    for i in 0..cams.len() {
        write_png(
            &d.path().join(format!("images_2/img_{i:02}.png")),
            4,
            3,
            9,
            false,
        );
    }
    let ds = load(&d.path().join("sparse/0/cameras.bin"), &opts).unwrap();
    let k = ds.train[0].intrinsics;
    assert_eq!((k.width, k.height, k.fx, k.cx), (4, 3, 3.5, 2.0));
}
