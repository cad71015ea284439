//! Bad input gives an error that names the file and the problem, never a panic.

mod common;

use common::*;
use serde_json::json;
use snerf_data::{load, LoadOptions};

fn load_err(path: &std::path::Path) -> anyhow::Error {
    load(path, &LoadOptions::default()).expect_err("expected an error")
}

/// nerfstudio dataset with 3 ring cameras; returns (dir, transforms.json value).
fn ns(tag: &str) -> (TempDir, serde_json::Value) {
    let d = TempDir::new(tag);
    write_nerfstudio(d.path(), &ring_cameras(3), false, None);
    let v =
        serde_json::from_str(&std::fs::read_to_string(d.path().join("transforms.json")).unwrap())
            .unwrap();
    (d, v)
}

#[test]
fn missing_image_is_named() {
    let (d, _) = ns("missing-image");
    std::fs::remove_file(d.path().join("images/frame_001.png")).unwrap();
    assert_err_has(&load_err(d.path()), &["frame_001.png", "not found"]);
}

#[test]
fn blender_missing_extensionless_image_is_named_with_png() {
    let d = TempDir::new("missing-blender");
    write_blender_single(d.path(), &ring_cameras(2), true);
    std::fs::remove_file(d.path().join("train/r_1.png")).unwrap();
    assert_err_has(&load_err(d.path()), &["train/r_1.png", "not found"]);
}

#[test]
fn undecodable_png_is_named() {
    let (d, _) = ns("bad-png");
    std::fs::write(
        d.path().join("images/frame_002.png"),
        b"\x89PNG\r\n\x1a\nbroken",
    )
    .unwrap();
    assert_err_has(&load_err(d.path()), &["frame_002.png", "decode"]);
}

#[test]
fn image_size_must_match_json() {
    let (d, _) = ns("size-mismatch");
    write_png(&d.path().join("images/frame_001.png"), 5, 5, 0, false);
    assert_err_has(
        &load_err(d.path()),
        &[
            "frame_001.png",
            "image is 5x5",
            "declares 8x6",
            "transforms.json frame 1",
        ],
    );
}

#[test]
fn unreadable_format_is_a_clear_error() {
    let (d, mut v) = ns("tiff");
    v["frames"][0]["file_path"] = json!("images/frame_000.tif");
    write_json(&d.path().join("transforms.json"), &v);
    assert_err_has(
        &load_err(d.path()),
        &[
            "frame_000.tif",
            "unsupported image format '.tif'",
            "PNG, JPEG and WebP",
        ],
    );
}

#[test]
fn nan_in_pose_names_frame_and_file() {
    let (d, mut v) = ns("nan-pose");
    // Python's json.dump writes NaN / Infinity literally.
    for tok in ["NaN", "Infinity", "-Infinity"] {
        v["frames"][1]["transform_matrix"][0][3] = json!(12345.5);
        let text = serde_json::to_string_pretty(&v)
            .unwrap()
            .replace("12345.5", tok);
        std::fs::write(d.path().join("transforms.json"), text).unwrap();
        assert_err_has(
            &load_err(d.path()),
            &["transforms.json", "frame 1", "NaN or Inf"],
        );
    }
}

#[test]
fn non_rigid_pose_names_frame_and_file() {
    let (d, mut v) = ns("shear");
    v["frames"][2]["transform_matrix"][0][1] = json!(0.5); // shear
    write_json(&d.path().join("transforms.json"), &v);
    assert_err_has(
        &load_err(d.path()),
        &["transforms.json", "frame 2", "not rigid", "orthonormal"],
    );
}

#[test]
fn scaled_pose_is_accepted_but_reflection_is_not() {
    let (d, mut v) = ns("reflect");
    for r in 0..3 {
        for c in 0..3 {
            let x = v["frames"][0]["transform_matrix"][r][c].as_f64().unwrap();
            v["frames"][0]["transform_matrix"][r][c] = json!(x * 2.5);
        }
    }
    write_json(&d.path().join("transforms.json"), &v);
    let ds = load(
        d.path(),
        &LoadOptions {
            holdout_every: Some(0),
            ..Default::default()
        },
    )
    .unwrap();
    assert_c2w_close(
        &ds.train[0].c2w,
        &ring_cameras(3)[0],
        1e-5,
        "scale divided out",
    );
    for r in 0..3 {
        let x = v["frames"][1]["transform_matrix"][r][0].as_f64().unwrap();
        v["frames"][1]["transform_matrix"][r][0] = json!(-x);
    }
    write_json(&d.path().join("transforms.json"), &v);
    assert_err_has(
        &load_err(d.path()),
        &["transforms.json", "frame 1", "reflection", "+1"],
    );
}

#[test]
fn unsupported_camera_model_in_transforms() {
    for model in ["OPENCV_FISHEYE", "EQUIRECTANGULAR"] {
        let (d, mut v) = ns("ns-model");
        v["camera_model"] = json!(model);
        write_json(&d.path().join("transforms.json"), &v);
        assert_err_has(
            &load_err(d.path()),
            &[
                "transforms.json",
                &format!("unsupported camera model '{model}'"),
            ],
        );
    }
}

#[test]
fn empty_frames_and_empty_split() {
    let (d, mut v) = ns("empty-frames");
    v["frames"] = json!([]);
    write_json(&d.path().join("transforms.json"), &v);
    assert_err_has(&load_err(d.path()), &["transforms.json", "no frames"]);

    let d = TempDir::new("empty-split");
    write_blender_single(d.path(), &ring_cameras(2), true);
    std::fs::rename(
        d.path().join("transforms.json"),
        d.path().join("transforms_train.json"),
    )
    .unwrap();
    write_json(
        &d.path().join("transforms_test.json"),
        &json!({ "camera_angle_x": 0.7, "frames": [] }),
    );
    assert_err_has(&load_err(d.path()), &["transforms_test.json", "no frames"]);
}

#[test]
fn malformed_json_names_file_and_position() {
    let (d, _) = ns("bad-json");
    std::fs::write(
        d.path().join("transforms.json"),
        "{\"fl_x\": 3, \"frames\": [ {,] }",
    )
    .unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["transforms.json", "malformed", "line 1"],
    );
    std::fs::write(d.path().join("transforms.json"), "{\"fl_x\": 3}").unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["transforms.json", "missing field `frames`"],
    );
}

#[test]
fn missing_focal_mixed_times_bad_time_bad_hint() {
    let (d, mut v) = ns("no-focal");
    v.as_object_mut().unwrap().remove("fl_x");
    v.as_object_mut().unwrap().remove("fl_y");
    write_json(&d.path().join("transforms.json"), &v);
    assert_err_has(&load_err(d.path()), &["transforms.json", "no focal length"]);

    let (d, mut v) = ns("mixed-time");
    v["frames"][0]["time"] = json!(0.5);
    write_json(&d.path().join("transforms.json"), &v);
    assert_err_has(
        &load_err(d.path()),
        &["transforms.json", "1 of 3 frames have a \"time\""],
    );

    for f in v["frames"].as_array_mut().unwrap() {
        f["time"] = json!(1.5);
    }
    write_json(&d.path().join("transforms.json"), &v);
    assert_err_has(
        &load_err(d.path()),
        &["transforms.json", "frame 0", "outside [0, 1]"],
    );

    let (d, mut v) = ns("bad-hint");
    v["scene_kind"] = json!("indoor");
    write_json(&d.path().join("transforms.json"), &v);
    assert_err_has(
        &load_err(d.path()),
        &["transforms.json", "scene_kind 'indoor'"],
    );
    v["scene_kind"] = json!("object");
    v["aabb"] = json!([[1, 1, 1], [0, 0, 0]]);
    write_json(&d.path().join("transforms.json"), &v);
    assert_err_has(&load_err(d.path()), &["transforms.json", "aabb"]);
}

#[test]
fn holdout_leaving_no_train_and_forced_dynamic_without_time() {
    let (d, _) = ns("holdout-1");
    let e = load(
        d.path(),
        &LoadOptions {
            holdout_every: Some(1),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert_err_has(&e, &["transforms.json", "no training views"]);
    let e = load(
        d.path(),
        &LoadOptions {
            dynamic: Some(true),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert_err_has(&e, &["transforms.json", "no \"time\""]);
}

#[test]
fn no_dataset_and_missing_path() {
    let d = TempDir::new("nothing");
    assert_err_has(
        &load_err(d.path()),
        &["no dataset found", "poses_bounds.npy"],
    );
    assert_err_has(&load_err(&d.path().join("nope")), &["nope", "no such file"]);
}

#[test]
fn llff_zero_images_count_mismatch_and_missing_folder() {
    let d = TempDir::new("llff-empty");
    write_llff(d.path(), &forward_cameras(3));
    for i in 0..3 {
        std::fs::remove_file(d.path().join(format!("images/IMG_{i:03}.png"))).unwrap();
    }
    assert_err_has(&load_err(d.path()), &["images", "no images found"]);
    write_png(&d.path().join("images/IMG_000.png"), W, H, 0, false);
    assert_err_has(
        &load_err(d.path()),
        &["1 images but", "poses_bounds.npy", "3 poses"],
    );
    std::fs::remove_dir_all(d.path().join("images")).unwrap();
    assert_err_has(&load_err(d.path()), &["images", "image folder not found"]);
}

#[test]
fn llff_unreadable_images_are_a_clear_error() {
    let d = TempDir::new("llff-tif");
    write_llff(d.path(), &forward_cameras(2));
    std::fs::rename(
        d.path().join("images/IMG_001.png"),
        d.path().join("images/IMG_001.TIF"),
    )
    .unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["IMG_001.TIF", "unsupported image format '.tif'"],
    );
}

#[test]
fn npy_wrong_shape_dtype_and_truncation() {
    let d = TempDir::new("npy-bad");
    write_llff(d.path(), &forward_cameras(2));
    let npy = d.path().join("poses_bounds.npy");
    write_npy_f64(&npy, &[vec![0.0; 15], vec![0.0; 15]]);
    assert_err_has(
        &load_err(d.path()),
        &["poses_bounds.npy", "expected shape (N, 17)", "[2, 15]"],
    );
    std::fs::write(&npy, npy_bytes("<i8", &[2, 17], &[0u8; 2 * 17 * 8])).unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["poses_bounds.npy", "unsupported dtype '<i8'"],
    );
    std::fs::write(&npy, npy_bytes("<f8", &[2, 17], &[0u8; 100])).unwrap();
    assert_err_has(&load_err(d.path()), &["poses_bounds.npy", "truncated"]);
    std::fs::write(&npy, b"not numpy at all").unwrap();
    assert_err_has(&load_err(d.path()), &["poses_bounds.npy", "magic"]);
}

#[test]
fn llff_bad_pose_and_bounds() {
    let d = TempDir::new("llff-badpose");
    let cams = forward_cameras(2);
    write_llff(d.path(), &cams);
    let mut rows: Vec<Vec<f64>> = cams.iter().map(|c| llff_row(c, 1.0, 5.0)).collect();
    rows[1][3] = f64::INFINITY;
    write_npy_f64(&d.path().join("poses_bounds.npy"), &rows);
    assert_err_has(
        &load_err(d.path()),
        &["poses_bounds.npy", "row 1", "NaN or Inf"],
    );
    rows[1][3] = 0.0;
    rows[1][15] = 6.0; // near > far
    write_npy_f64(&d.path().join("poses_bounds.npy"), &rows);
    assert_err_has(
        &load_err(d.path()),
        &["poses_bounds.npy", "row 1", "bad bounds"],
    );
    rows[1][15] = 1.0;
    rows[0][1] *= 3.0; // non-uniform scale of the right axis
    write_npy_f64(&d.path().join("poses_bounds.npy"), &rows);
    assert_err_has(
        &load_err(d.path()),
        &["poses_bounds.npy", "row 0", "not rigid"],
    );
}

#[test]
fn colmap_unknown_models_name_model_and_file() {
    let d = TempDir::new("colmap-model-txt");
    let model = write_colmap(d.path(), &ring_cameras(2), false);
    std::fs::write(
        model.join("cameras.txt"),
        "1 OPENCV_FISHEYE 8 6 7 7 4 3 0 0 0 0\n",
    )
    .unwrap();
    assert_err_has(
        &load_err(d.path()),
        &[
            "cameras.txt",
            "OPENCV_FISHEYE",
            "unsupported camera model",
            "line 1",
        ],
    );
    std::fs::write(model.join("cameras.txt"), "1 PINHOLE 8 6 7 7 4\n").unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["cameras.txt", "PINHOLE needs 4 parameters, found 3"],
    );

    let d = TempDir::new("colmap-model-bin");
    let model = write_colmap(d.path(), &ring_cameras(2), true);
    let cam = ColmapCam {
        id: 1,
        model: "OPENCV_FISHEYE",
        model_id: 5,
        w: 8,
        h: 6,
        params: vec![7.0; 8],
    };
    std::fs::write(model.join("cameras.bin"), cameras_bin(&[cam])).unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["cameras.bin", "OPENCV_FISHEYE", "unsupported camera model"],
    );
    let cam = ColmapCam {
        id: 1,
        model: "?",
        model_id: 99,
        w: 8,
        h: 6,
        params: vec![],
    };
    std::fs::write(model.join("cameras.bin"), cameras_bin(&[cam])).unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["cameras.bin", "unknown camera model id 99"],
    );
}

#[test]
fn colmap_truncated_and_corrupt_binaries() {
    let d = TempDir::new("colmap-trunc");
    let cams = ring_cameras(3);
    let model = write_colmap(d.path(), &cams, true);
    let full = images_bin(&colmap_images(&cams));
    // Cut at every length: always an error naming images.bin, never a panic.
    for cut in [0, 5, 8, 20, 70, full.len() - 30, full.len() - 1] {
        std::fs::write(model.join("images.bin"), &full[..cut]).unwrap();
        let e = load_err(d.path());
        assert_err_has(&e, &["images.bin"]);
        let s = format!("{e:#}");
        assert!(s.contains("truncated") || s.contains("corrupt"), "{s}");
    }
    // A huge image count: rejected before allocating.
    let mut bad = full.clone();
    bad[..8].copy_from_slice(&u64::MAX.to_le_bytes());
    std::fs::write(model.join("images.bin"), &bad).unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["images.bin", "corrupt or truncated", "number of images"],
    );
    // A huge 2D point count in the first image (after id, 7 doubles, camera id, name + NUL).
    let mut bad = full.clone();
    let at = 8 + 4 + 56 + 4 + "img_00.png".len() + 1;
    bad[at..at + 8].copy_from_slice(&(1u64 << 60).to_le_bytes());
    std::fs::write(model.join("images.bin"), &bad).unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["images.bin", "number of 2D points of image 'img_00.png'"],
    );
    // Truncated / corrupt cameras.bin.
    std::fs::write(model.join("images.bin"), &full).unwrap();
    let cb = cameras_bin(&[pinhole_cam()]);
    std::fs::write(model.join("cameras.bin"), &cb[..cb.len() - 3]).unwrap();
    assert_err_has(&load_err(d.path()), &["cameras.bin", "truncated"]);
    let mut bad = cb.clone();
    bad[..8].copy_from_slice(&(1u64 << 40).to_le_bytes());
    std::fs::write(model.join("cameras.bin"), &bad).unwrap();
    assert_err_has(&load_err(d.path()), &["cameras.bin", "number of cameras"]);
}

#[test]
fn colmap_bad_pose_missing_camera_and_image() {
    let d = TempDir::new("colmap-badpose");
    let cams = ring_cameras(3);
    let model = write_colmap(d.path(), &cams, false);
    let mut imgs = colmap_images(&cams);
    imgs[1].q = [0.0; 4];
    std::fs::write(model.join("images.txt"), images_txt(&imgs)).unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["images.txt", "img_01.png", "quaternion"],
    );
    imgs[1].q = [1.0, 0.0, 0.0, 0.0];
    imgs[2].t[0] = f64::NAN;
    std::fs::write(model.join("images.txt"), images_txt(&imgs)).unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["images.txt", "img_02.png", "NaN or Inf"],
    );
    imgs[2].t[0] = 0.0;
    imgs[0].cam = 5;
    std::fs::write(model.join("images.txt"), images_txt(&imgs)).unwrap();
    assert_err_has(
        &load_err(d.path()),
        &["images.txt", "camera 5", "cameras.txt"],
    );
    imgs[0].cam = 1;
    std::fs::write(model.join("images.txt"), images_txt(&imgs)).unwrap();
    std::fs::remove_file(d.path().join("images/img_02.png")).unwrap();
    assert_err_has(&load_err(d.path()), &["img_02.png", "not found"]);
    std::fs::write(model.join("images.txt"), "# nothing\n").unwrap();
    assert_err_has(&load_err(d.path()), &["images.txt", "no registered images"]);
}
