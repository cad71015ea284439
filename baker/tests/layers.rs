//! Style layers on a small trained field: a layer of the same field bakes exactly the
//! first bake, a layer trained further with its geometry frozen (the trainer's own
//! `freeze_geometry`, what `snerf stylize --appearance-only` sets) bakes onto the same
//! geometry and round-trips as a two-style asset, and a layer whose geometry moved is refused.

use snerf_asset::{LayeredAsset, StyleInfo};
use snerf_baker::bake::{bake, BakeOptions};
use snerf_baker::layers::bake_colour;
use snerf_data::{load, LoadOptions};
use snerf_trainer::eval::eval_background;
use snerf_trainer::train::{views_have_alpha, TrainConfig, Trainer};

fn style(name: &str) -> StyleInfo {
    StyleInfo { name: name.into(), source: None, swatch: [0.0; 3] }
}

/// A built-in scene at 48², 24 views, trained 120 steps (the directory lives as long as the
/// returned guard).
fn trained(scene: &str) -> (snerf_files::ScratchDir, snerf_data::Dataset, TrainConfig, Trainer) {
    let dir = snerf_files::ScratchDir::new("snerf-bake-layers", scene).unwrap();
    let source = snerf_scene::Source::parse(scene).unwrap();
    let mut spec = snerf_scene::SceneSpec::default_for(source);
    (spec.train_views, spec.test_views, spec.width, spec.height, spec.supersample) = (24, 2, 48, 48, 1);
    snerf_scene::write_dataset(&spec, &dir.join("data"), &|_, _| {}).unwrap();
    let data = load(&dir.join("data"), &LoadOptions::default()).unwrap();
    let cfg = TrainConfig::for_dataset(&data);
    let mut t = Trainer::new(&data, cfg.clone()).unwrap();
    for s in 0..120 {
        t.step(s as f64 / 120.0);
    }
    (dir, data, cfg, t)
}

/// `t`'s field trained 30 more steps, its geometry frozen (what `snerf stylize
/// --appearance-only` sets) or not.
fn trained_further(data: &snerf_data::Dataset, cfg: &TrainConfig, t: &Trainer, freeze_geometry: bool) -> Trainer {
    let c = TrainConfig { freeze_geometry, ..cfg.clone() };
    let adam = snerf_trainer::adam::Adam::new(t.model.field.params.len());
    let mut l = Trainer::from_parts(data, c, t.model.clone(), adam).unwrap();
    for s in 0..30 {
        l.step(s as f64 / 30.0);
    }
    l
}

#[test]
fn layers_bake_onto_one_geometry_and_a_moved_geometry_is_refused() {
    let (_dir, data, cfg, t) = trained("object");
    let bg = eval_background(views_have_alpha(&data.train));
    let opts = BakeOptions { res: 64, visibility_views: 8, ..Default::default() };
    let (first, _) = bake(&t.model, &t.pool, &data.train, bg, &opts, &|_, _, _| {}).unwrap();

    // the same field as a layer: exactly the bake
    let (same, report) = bake_colour(&t.model, &t.pool, &t.model, &first).unwrap();
    assert_eq!(same, first, "{report:?}");

    // further training with the geometry frozen: same density, other colours
    let train_on = |freeze: bool| trained_further(&data, &cfg, &t, freeze);
    let frozen = train_on(true);
    let (second, report) = bake_colour(&frozen.model, &frozen.pool, &t.model, &first).unwrap();
    assert_eq!(report.density_mismatches, 0);
    assert_eq!(second.grids, first.grids);
    assert!(second.atlas != first.atlas, "the frozen layer's colours moved");
    let two = LayeredAsset::new(vec![style("a"), style("b")], vec![first.clone(), second.clone()]).unwrap();
    let bytes = two.to_bytes();
    let back = LayeredAsset::from_bytes(&bytes).unwrap();
    assert_eq!(back, two);
    // each style draws what its own single-style bake draws (the file keeps only the live
    // voxels' colours, and the apron's where no neighbour holds them)
    for (single, layer) in [(&first, &back.layers[0]), (&second, &back.layers[1])] {
        for i in 0..2 {
            let cam = snerf_asset::orbit(&single.header, 2, i, 40, 40, 40.0);
            let (a, b) = (snerf_asset::render(single, &cam, 0.0), snerf_asset::render(layer, &cam, 0.0));
            let d = a.rgb.iter().zip(&b.rgb).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max);
            assert!(d <= 1.0 / 255.0, "view {i}: {d}");
        }
    }
    let layer_bytes = back.style_bytes()[1].bytes as f64;
    let whole = second.to_bytes().len() as f64;
    eprintln!("a layer is {:.3} of a single-style asset ({} of {} bytes)", layer_bytes / whole, layer_bytes, whole);
    assert!(layer_bytes / whole < 0.5);

    // training that moves the geometry gives a layer the bake refuses
    let moved = train_on(false);
    let e = bake_colour(&moved.model, &moved.pool, &t.model, &first).unwrap_err().to_string();
    assert!(e.contains("density differs from the geometry's"), "{e}");
}

/// A 4D field's layers: the time codebook shares a block among frames, and a layer is
/// evaluated at the sample each block was taken from (not the first frame that shows it), so
/// the same field bakes exactly the first bake and a frozen-geometry layer bakes onto it at
/// every time.
#[test]
fn a_4d_field_bakes_layers_at_each_blocks_own_sample() {
    let (_dir, data, cfg, t) = trained("avatar");
    assert!(t.model.space.dynamic);
    let bg = eval_background(views_have_alpha(&data.train));
    // style layers hold blocks only (no motion entries), and a tight budget makes the
    // codebook share blocks across samples
    let opts = BakeOptions { res: 64, visibility_views: 8, keyframes: 8, motion: false, time_budget: 1.5, ..Default::default() };
    let (first, report) = bake(&t.model, &t.pool, &data.train, bg, &opts, &|_, _, _| {}).unwrap();
    assert!(first.is_dynamic() && report.shared_blocks > 0, "{report:?}");
    let (same, r) = bake_colour(&t.model, &t.pool, &t.model, &first).unwrap();
    assert_eq!(r.density_mismatches, 0);
    assert_eq!(same, first, "the same field as a layer is exactly the bake");

    let l = trained_further(&data, &cfg, &t, true);
    let (second, r) = bake_colour(&l.model, &l.pool, &t.model, &first).unwrap();
    assert_eq!(r.density_mismatches, 0);
    assert_eq!(second.grids, first.grids);
    let two = LayeredAsset::new(vec![style("a"), style("b")], vec![first.clone(), second.clone()]).unwrap();
    let back = LayeredAsset::from_bytes(&two.to_bytes()).unwrap();
    assert_eq!(back, two);
    // blended by density (every dynamic bake), a 4D layer stores only its live interior
    // voxels' colours; lerped, it would need every voxel's
    assert!(first.header.colour_by_density);
    let lerped: Vec<_> = [&first, &second].map(|a| {
        let mut a = a.clone();
        a.header.colour_by_density = false;
        a
    }).into();
    let all = LayeredAsset::new(vec![style("a"), style("b")], lerped).unwrap();
    let (live, every) = (two.style_bytes()[1].bytes as f64, all.style_bytes()[1].bytes as f64);
    eprintln!("a 4D layer: {live} bytes blended by density, {every} lerped ({:.3})", live / every);
    assert!(live < 0.6 * every, "{live} against {every}");
    let (lo, hi) = (first.header.frame_time(0), first.header.frame_time(first.num_frames() - 1));
    for time in [lo, 0.37 * lo + 0.63 * hi] {
        let cam = snerf_asset::orbit(&second.header, 2, 1, 40, 40, 40.0);
        let (a, b) = (snerf_asset::render(&second, &cam, time), snerf_asset::render(&back.layers[1], &cam, time));
        // a 4D layer's colour stops at its block's edge (no apron colours; FORMAT.md)
        let d = a.rgb.iter().zip(&b.rgb).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max);
        let mean = a.rgb.iter().zip(&b.rgb).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.rgb.len() as f32;
        eprintln!("t = {time}: layer against its single-style bake, mean {mean:.5}, max {d:.4}");
        assert!(mean <= 1.0 / 255.0 && d <= 0.1, "t = {time}: mean {mean}, max {d}");
    }
}
