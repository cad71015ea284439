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

/// A view of a sphere of radius `r` centred at `centre`, alpha 255 where a ray through the
/// pixel's centre meets it, 0 elsewhere (camera on a circle of radius 4 about the y axis,
/// looking at the origin).
fn sphere_view(time: f32, azim: f32, centre: [f32; 3], r: f32) -> View {
    let (s, c) = azim.sin_cos();
    let c2w = [[c, 0.0, s, 4.0 * s], [0.0, 1.0, 0.0, 0.0], [-s, 0.0, c, 4.0 * c]];
    let (w, h, f) = (64u32, 64u32, 80.0f32);
    let mut rgba = vec![0u8; (w * h * 4) as usize];
    let o = [c2w[0][3], c2w[1][3], c2w[2][3]];
    for y in 0..h {
        for x in 0..w {
            let dc = [(x as f32 + 0.5 - 32.0) / f, -(y as f32 + 0.5 - 32.0) / f, -1.0];
            let d: Vec<f32> = (0..3).map(|a| c2w[a][0] * dc[0] + c2w[a][1] * dc[1] + c2w[a][2] * dc[2]).collect();
            let oc: Vec<f32> = (0..3).map(|a| o[a] - centre[a]).collect();
            let (dd, od, cc) = (d.iter().map(|v| v * v).sum::<f32>(), (0..3).map(|a| oc[a] * d[a]).sum::<f32>(), oc.iter().map(|v| v * v).sum::<f32>() - r * r);
            if od * od - dd * cc >= 0.0 {
                rgba[((y * w + x) * 4) as usize..][..4].copy_from_slice(&[200, 100, 50, 255]);
            }
        }
    }
    View {
        path: "v.png".into(),
        intrinsics: Intrinsics { width: w, height: h, fx: f, fy: f, cx: 32.0, cy: 32.0, distortion: [0.0; 4] },
        c2w,
        time: Some(time),
        rgba,
    }
}

/// Whether the occupancy cell nearest world point `p` survived carving.
fn allowed_at(t: &snerf_trainer::train::Trainer, p: [f32; 3]) -> bool {
    let (occ, space) = (&t.model.occ, &t.model.space);
    let d2 = |i: usize| {
        let w = space.to_world(space.grid_to_march(occ.cell_center(i)));
        (0..3).map(|a| (w[a] - p[a]).powi(2)).sum::<f32>()
    };
    let best = (0..occ.allowed.len()).min_by(|&a, &b| d2(a).total_cmp(&d2(b))).unwrap();
    occ.allowed[best]
}

#[test]
fn silhouette_carving_keeps_where_a_moving_part_goes() {
    // a ball swinging along x between −0.6 and 0.6, one camera per instant (monocular)
    let n = 90;
    let centre = |t: f32| [0.6 * (std::f32::consts::TAU * t).cos(), 0.0, 0.0];
    let train: Vec<View> = (0..n)
        .map(|i| {
            let t = i as f32 / (n - 1) as f32;
            sphere_view(t, i as f32 * 2.4, centre(t), 0.25)
        })
        .collect();
    let mut data = dataset(&[0.0]);
    data.train = train;
    data.test = vec![sphere_view(0.5, 0.3, centre(0.5), 0.25)];
    let t = snerf_trainer::train::Trainer::new(&data, TrainConfig::for_dataset(&data)).unwrap();
    for p in [[0.6, 0.0, 0.0], [-0.6, 0.0, 0.0], [0.0, 0.0, 0.0], [0.4, 0.1, 0.1]] {
        assert!(allowed_at(&t, p), "the ball passes through {p:?}: it must not be carved");
    }
    for p in [[0.0, 0.9, 0.0], [0.0, -0.9, 0.3]] {
        assert!(!allowed_at(&t, p), "no view ever sees anything at {p:?}: it must be carved");
    }
    // The same views as one static scene: a view taken while the ball was at the other end
    // proves each end empty, so both are carved (what the dynamic rule must not do).
    let mut stat = data.clone();
    stat.dynamic = false;
    stat.train.iter_mut().chain(stat.test.iter_mut()).for_each(|v| v.time = None);
    let t = snerf_trainer::train::Trainer::new(&stat, TrainConfig::for_dataset(&stat)).unwrap();
    assert!(!allowed_at(&t, [0.6, 0.0, 0.0]) && !allowed_at(&t, [-0.6, 0.0, 0.0]));
}

#[test]
fn an_occupancy_grid_that_empties_early_reopens() {
    // A field whose density is ~0 everywhere, as early training of a mostly transparent
    // scene can make it: the warm-up measurement would mark every cell empty, and a march
    // that takes no samples can never learn the object back.
    let n = 30;
    let train: Vec<View> = (0..n).map(|i| sphere_view(i as f32 / (n - 1) as f32, i as f32 * 2.4, [0.0; 3], 0.3)).collect();
    let mut data = dataset(&[0.0]);
    data.train = train;
    let mut t = snerf_trainer::train::Trainer::new(&data, TrainConfig::for_dataset(&data)).unwrap();
    let b2 = t.model.field.layout.b2;
    t.model.field.params[b2] = -30.0; // σ = exp(o0) with o0 ≈ −30
    t.update_occupancy();
    assert!(t.model.occ.occupied_fraction() > 0.0, "the cells carving kept must stay open to samples");
    assert_eq!(t.model.occ.occ.iter().zip(&t.model.occ.allowed).filter(|(&o, &a)| o == 1 && !a).count(), 0, "carved cells stay carved");
}
