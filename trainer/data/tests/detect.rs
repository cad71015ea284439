//! Scene kind (forward / object / unbounded) and dynamics detection, overrides and hints.

mod common;

use common::*;
use snerf_data::{
    detect_kind, load, max_view_angle_deg, summary, Intrinsics, LoadOptions, SceneKind, View,
};

fn view_looking(dir_deg_about_y: f64, alpha: &[u8]) -> View {
    // Rotate the default camera (looking down -z) about y.
    let a = dir_deg_about_y.to_radians();
    let (c, s) = (a.cos() as f32, a.sin() as f32);
    View {
        path: "v.png".into(),
        intrinsics: Intrinsics {
            width: alpha.len() as u32,
            height: 1,
            fx: 1.0,
            fy: 1.0,
            cx: 0.5,
            cy: 0.5,
            distortion: [0.0; 4],
        },
        c2w: [[c, 0.0, s, 0.0], [0.0, 1.0, 0.0, 0.0], [-s, 0.0, c, 0.0]],
        time: None,
        rgba: alpha.iter().flat_map(|&a| [0, 0, 0, a]).collect(),
    }
}

#[test]
fn forward_threshold_is_forty_degrees() {
    let opaque = [255u8; 4];
    let a = view_looking(35.0, &opaque);
    let b = view_looking(-35.0, &opaque);
    let angle = max_view_angle_deg(&[&a, &b]);
    assert!((angle - 35.0).abs() < 1e-3, "{angle}");
    assert_eq!(detect_kind(&[&a, &b], &[&a, &b]).0, SceneKind::Forward);
    let a = view_looking(45.0, &opaque);
    let b = view_looking(-45.0, &opaque);
    let (kind, note) = detect_kind(&[&a, &b], &[&a, &b]);
    assert_eq!(kind, SceneKind::Unbounded, "{note}");
    // Opposite cameras: mean direction vanishes.
    let a = view_looking(0.0, &opaque);
    let b = view_looking(180.0, &opaque);
    assert_eq!(max_view_angle_deg(&[&a, &b]), 180.0);
}

#[test]
fn object_needs_more_than_one_percent_transparent() {
    let mut alpha = vec![255u8; 200];
    alpha[0] = 0; // 0.5%
    let a = view_looking(0.0, &alpha);
    let b = view_looking(90.0, &alpha);
    let c = view_looking(180.0, &alpha);
    let (k, note) = detect_kind(&[&a, &b, &c], &[&a, &b, &c]);
    assert_eq!(k, SceneKind::Unbounded, "{note}");
    alpha[1] = 254;
    alpha[2] = 10; // 1.5%
    let a = view_looking(0.0, &alpha);
    let (k, note) = detect_kind(&[&a, &b, &c], &[&a]);
    assert_eq!(k, SceneKind::Object, "{note}");
    assert!(
        note.contains("1.5% of training pixels are transparent"),
        "{note}"
    );
}

#[test]
fn forward_facing_dataset_is_forward() {
    let d = TempDir::new("det-forward");
    write_nerfstudio(d.path(), &forward_cameras(6), true, None);
    let ds = load(d.path(), &LoadOptions::default()).unwrap();
    // Forward wins over transparency.
    assert_eq!(ds.kind, SceneKind::Forward, "{}", ds.detection_note);
    assert!(
        ds.detection_note
            .starts_with("forward: all view directions within"),
        "{}",
        ds.detection_note
    );
    assert!(!ds.dynamic);
}

#[test]
fn transparent_360_is_object_and_opaque_360_is_unbounded() {
    let d = TempDir::new("det-object");
    write_blender_single(d.path(), &ring_cameras(8), true);
    let ds = load(d.path(), &LoadOptions::default()).unwrap();
    assert_eq!(ds.kind, SceneKind::Object, "{}", ds.detection_note);
    assert!(ds.detection_note.starts_with("object:"));

    let d = TempDir::new("det-unbounded");
    write_colmap(d.path(), &ring_cameras(8), true);
    let ds = load(d.path(), &LoadOptions::default()).unwrap();
    assert_eq!(ds.kind, SceneKind::Unbounded, "{}", ds.detection_note);
    assert!(ds.detection_note.starts_with("unbounded:"));
    assert_eq!(summary(&ds)["kind"], "unbounded");
}

#[test]
fn caller_override_beats_hint_beats_detection() {
    let d = TempDir::new("det-override");
    write_nerfstudio(d.path(), &ring_cameras(4), false, None);
    let opts = LoadOptions {
        kind: Some(SceneKind::Forward),
        ..Default::default()
    };
    let ds = load(d.path(), &opts).unwrap();
    assert_eq!(ds.kind, SceneKind::Forward);
    assert!(ds.detection_note.contains("set by the caller"));
    let p = d.path().join("transforms.json");
    let mut v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    v["scene_kind"] = serde_json::json!("object");
    write_json(&p, &v);
    assert_eq!(
        load(d.path(), &LoadOptions::default()).unwrap().kind,
        SceneKind::Object
    );
    assert_eq!(load(d.path(), &opts).unwrap().kind, SceneKind::Forward);
}

#[test]
fn dynamic_when_times_differ() {
    let d = TempDir::new("det-dynamic");
    let times = [0.0, 0.25, 0.5, 0.75, 1.0];
    write_nerfstudio(d.path(), &ring_cameras(5), true, Some(&times));
    let ds = load(d.path(), &LoadOptions::default()).unwrap();
    assert!(ds.dynamic, "{}", ds.detection_note);
    assert_eq!(ds.time_range(), Some((0.0, 1.0)));
    let s = summary(&ds);
    assert_eq!(s["dynamic"], true);
    assert_eq!(s["time_range"], serde_json::json!([0.0, 1.0]));
    assert_eq!(ds.test[0].time, Some(0.0));
    assert_eq!(ds.train[0].time, Some(0.25));

    let ds = load(
        d.path(),
        &LoadOptions {
            dynamic: Some(false),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(!ds.dynamic);
    assert!(ds
        .detection_note
        .contains("dynamic=false: set by the caller"));

    let d = TempDir::new("det-static-times");
    write_nerfstudio(d.path(), &ring_cameras(3), true, Some(&[0.5, 0.5, 0.5]));
    let ds = load(d.path(), &LoadOptions::default()).unwrap();
    assert!(!ds.dynamic);
    assert!(ds.detection_note.contains("all frame times are equal"));
    let ds = load(
        d.path(),
        &LoadOptions {
            dynamic: Some(true),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(ds.dynamic);
}
