//! How a dynamic (animated) dataset is trained by default: the time resolution follows the
//! data (views per time cell, never finer than the distinct times), the time planes carry
//! K-Planes' priors, and silhouette pixels are the mean of their square as for static objects.

use snerf_data::{Dataset, Intrinsics, SceneKind, View};
use snerf_trainer::train::{finest_time_resolution, TrainConfig, VIEWS_PER_TIME_CELL};

fn view(time: Option<f32>, azim: f32) -> View {
    let (s, c) = azim.sin_cos();
    // a camera 4 units out on a circle, looking at the origin (OpenGL: it looks down −z)
    let c2w = [[c, 0.0, s, 4.0 * s], [0.0, 1.0, 0.0, 0.0], [-s, 0.0, c, 4.0 * c]];
    let (w, h) = (16u32, 16u32);
    let mut rgba = vec![0u8; (w * h * 4) as usize];
    for y in 4..12 {
        for x in 4..12 {
            rgba[((y * w + x) * 4) as usize..][..4].copy_from_slice(&[200, 100, 50, 255]);
        }
    }
    View {
        path: "v.png".into(),
        intrinsics: Intrinsics { width: w, height: h, fx: 20.0, fy: 20.0, cx: 8.0, cy: 8.0, distortion: [0.0; 4] },
        c2w,
        time,
        rgba,
    }
}

fn dataset(times: &[f32]) -> Dataset {
    let train: Vec<View> = times.iter().enumerate().map(|(i, &t)| view(Some(t), i as f32 * 2.4)).collect();
    Dataset {
        root: "mem".into(),
        format: "blender".into(),
        test: vec![view(Some(0.5), 0.3)],
        val: Vec::new(),
        train,
        kind: SceneKind::Object,
        dynamic: true,
        near_far: None,
        aabb: None,
        detection_note: String::new(),
        pose_file: Default::default(),
    }
}

#[test]
fn time_resolution_follows_views_per_cell_and_distinct_times() {
    // monocular: one camera per instant, 120 distinct times
    let mono: Vec<f32> = (0..120).map(|i| i as f32 / 119.0).collect();
    assert_eq!(finest_time_resolution(&dataset(&mono)), (120 / VIEWS_PER_TIME_CELL) as u32);
    // twice the views: twice the time cells
    let mono2: Vec<f32> = (0..240).map(|i| i as f32 / 239.0).collect();
    assert_eq!(finest_time_resolution(&dataset(&mono2)), (240 / VIEWS_PER_TIME_CELL).min(64) as u32);
    // many cameras at 6 instants: no finer than the instants (the 4..=64 clamp aside)
    let multi: Vec<f32> = (0..120).map(|i| (i % 6) as f32 / 5.0).collect();
    assert_eq!(finest_time_resolution(&dataset(&multi)), 6);
    // very few views: the coarsest allowed
    assert_eq!(finest_time_resolution(&dataset(&[0.0, 0.5, 1.0])), 4);
}

#[test]
fn a_dynamic_object_gets_time_priors_and_silhouette_pixels() {
    let data = dataset(&(0..60).map(|i| i as f32 / 59.0).collect::<Vec<_>>());
    let cfg = TrainConfig::for_dataset(&data);
    cfg.validate().unwrap();
    assert!(cfg.field.dynamic());
    let t = finest_time_resolution(&data);
    assert_eq!(cfg.field.time_resolutions.last(), Some(&t));
    assert!(cfg.time_smooth > 0.0 && cfg.time_sparse > 0.0, "K-Planes' priors are on for dynamic scenes");
    assert_eq!(cfg.pixel_rays, 4, "an animated object on transparent film: silhouette pixels are the mean of their square");
    assert!(cfg.pixel_footprint.is_some());
    // a static scene has no time planes and no time priors to pay for
    let mut stat = dataset(&[0.0; 10]);
    stat.dynamic = false;
    stat.train.iter_mut().for_each(|v| v.time = None);
    let cfg = TrainConfig::for_dataset(&stat);
    assert!(!cfg.field.dynamic() && cfg.time_smooth == 0.0 && cfg.time_sparse == 0.0);
}
