//! Baking a small trained field: the asset holds what the scene needs and nothing more, and
//! the CPU reference renderer of the baked file reproduces the field's own renders.

use std::path::Path;

use snerf_baker::bake::{bake, BakeOptions};
use snerf_baker::faithfulness;
use snerf_data::{load, LoadOptions};
use snerf_trainer::eval::eval_background;
use snerf_trainer::train::{views_have_alpha, TrainConfig, Trainer};

fn tiny_run(scene: &str, dir: &Path, steps: usize) -> (snerf_data::Dataset, Trainer) {
    let source = snerf_scene::Source::parse(scene).unwrap();
    let mut spec = snerf_scene::SceneSpec::default_for(source);
    spec.train_views = 40;
    spec.test_views = 4;
    spec.width = 64;
    spec.height = 64;
    spec.supersample = 2;
    let data_dir = dir.join(scene);
    snerf_scene::write_dataset(&spec, &data_dir, &|_, _| {}).unwrap();
    let data = load(&data_dir, &LoadOptions::default()).unwrap();
    let cfg = TrainConfig::for_dataset(&data);
    let mut t = Trainer::new(&data, cfg).unwrap();
    for s in 0..steps {
        t.step(s as f64 / steps as f64);
    }
    (data, t)
}

fn tmp(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("snerf-bake-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn static_object_bakes_faithfully_and_without_time_data() {
    let dir = tmp("object");
    let (data, t) = tiny_run("object", &dir, 300);
    let bg = eval_background(views_have_alpha(&data.train));
    let opts = BakeOptions { res: 128, ..Default::default() };
    let (asset, report) = bake(&t.model, &t.pool, &data.train, bg, &opts, &|_, _, _| {}).unwrap();
    assert!(report.atlas_blocks > 0);
    // leave out what the scene does not need: no time data, no empty blocks
    assert!(!asset.is_dynamic());
    let file = dir.join("object.snerf");
    asset.write(&file).unwrap();
    let bytes = std::fs::read(&file).unwrap();
    let head = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]).to_string();
    assert!(!head.contains("time_range") && !head.contains("\"frames\""), "static header carries time data: {head}");
    let g = asset.grid_dim();
    let occupied = asset.grids[0].iter().filter(|&&c| c != snerf_asset::EMPTY).count();
    assert!(occupied < g * g * g / 2, "{occupied} of {} cells kept", g * g * g);
    assert!(report.dropped_transparent > 0, "{report:?}");
    let f = faithfulness::measure(&t.model, &t.pool, &asset, &data.test, 4).unwrap();
    eprintln!("{f:#?}\n{report:#?}");
    assert!(f.mean_baked_vs_field >= 30.0, "baked vs field {:.2} dB", f.mean_baked_vs_field);
    assert!(f.drop_db <= 1.0, "baking loses {:.2} dB on test views", f.drop_db);
    let back = snerf_asset::Asset::read(&file).unwrap();
    assert_eq!(back.atlas, asset.atlas);
}

#[test]
fn dynamic_avatar_bakes_keyframes_that_share_blocks() {
    let dir = tmp("avatar");
    let (data, t) = tiny_run("avatar", &dir, 300);
    let bg = eval_background(views_have_alpha(&data.train));
    let opts = BakeOptions { res: 64, keyframes: 4, ..Default::default() };
    let (asset, report) = bake(&t.model, &t.pool, &data.train, bg, &opts, &|_, _, _| {}).unwrap();
    assert!(asset.is_dynamic());
    assert_eq!(asset.num_frames(), 4);
    assert!(report.shared_blocks > 0, "no block was shared between keyframes: {report:?}");
    let f = faithfulness::measure(&t.model, &t.pool, &asset, &data.test, 4).unwrap();
    eprintln!("{f:#?}");
    assert!(f.mean_baked_vs_field >= 25.0, "baked vs field {:.2} dB", f.mean_baked_vs_field);
}

#[test]
#[ignore]
fn diagnose_static_object() {
    let dir = tmp("diag");
    let (data, t) = tiny_run("object", &dir, 300);
    let bg = eval_background(views_have_alpha(&data.train));
    let env = |k: &str, d: f32| std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d);
    let opts = BakeOptions {
        res: 128,
        min_alpha: env("MINA", 0.005),
        visibility_views: env("VIS", 32.0) as usize,
        ..Default::default()
    };
    let (asset, _report) = bake(&t.model, &t.pool, &data.train, bg, &opts, &|_, _, _| {}).unwrap();
    let g = asset.grid_dim();
    let b = asset.header.block as usize;
    let res = asset.header.res as f32;
    let mut rng = snerf_trainer::field::Rng::new(1);
    let mut pts = Vec::new();
    for (c, &blk) in asset.grids[0].iter().enumerate() {
        if blk == snerf_asset::EMPTY || pts.len() > 2000 {
            continue;
        }
        let (cx, cy, cz) = (c % g, (c / g) % g, c / (g * g));
        let u = [cx, cy, cz].map(|k| (k * b) as f32 + rng.uniform() * b as f32);
        pts.push(u.map(|v| -1.0 + v * 2.0 / res));
    }
    let mut vals = vec![[0.0f32; 8]; pts.len()];
    t.pool.with(|ws| snerf_trainer::render::values_batch(&t.model.field, &pts, &vec![0.0; pts.len()], ws, &mut vals));
    let mut d = [0.0f64; 8];
    let mut n = 0;
    for (p, v) in pts.iter().zip(&vals) {
        if let Some(s) = asset.sample(0, *p) {
            for c in 0..8 {
                d[c] += (s[c] - v[c]).abs() as f64;
            }
            n += 1;
        }
    }
    eprintln!("{} points, mean abs diff per channel: {:?}", n, d.map(|x| x / n as f64));
    let v = &data.test[0];
    let f = snerf_trainer::eval::render_camera(&t.model, &t.pool, &v.c2w, &v.intrinsics, v.time, bg);
    let a = snerf_asset::render(&asset, &faithfulness::camera_of(v), 0.0);
    let img = snerf_trainer::eval::side_by_side(&[&f.rgb, &a.rgb, &f.opacity.iter().flat_map(|&o| [o; 3]).collect::<Vec<_>>(), &a.opacity.iter().flat_map(|&o| [o; 3]).collect::<Vec<_>>()], f.width, f.height);
    img.save("/tmp/diag.png").unwrap();
    let dd: f32 = f.opacity.iter().zip(&a.opacity).map(|(x, y)| (x - y).abs()).sum::<f32>() / f.opacity.len() as f32;
    eprintln!("mean opacity diff {dd}");
    // where the baked render misses what the field shows: which cells are those?
    let (mut holes, mut empty_cell, mut occ_empty, mut outside) = (0, 0, 0, 0);
    for p in 0..f.opacity.len() {
        if f.opacity[p] > 0.5 && a.opacity[p] < 0.1 {
            holes += 1;
            let (x, y) = (p % f.width, p / f.width);
            let ray = t.model.space.ray(&v.c2w, &v.intrinsics, x as f32 + 0.5, y as f32 + 0.5, None).unwrap();
            let m = [0, 1, 2].map(|i| ray.o[i] + ray.d[i] * f.depth[p]);
            let gp = t.model.space.to_grid(m);
            if gp.iter().any(|v| v.abs() >= 1.0) { outside += 1; continue; }
            let cell = [0, 1, 2].map(|i| (((gp[i] + 1.0) * 0.5 * g as f32) as usize).min(g - 1));
            if asset.grids[0][(cell[2] * g + cell[1]) * g + cell[0]] == snerf_asset::EMPTY { empty_cell += 1; }
            if let Some(oc) = t.model.occ.cell(&gp) { if t.model.occ.occ[oc] == 0 { occ_empty += 1; } }
        }
    }
    eprintln!("holes {holes}: empty asset cell {empty_cell}, occupancy empty {occ_empty}, outside {outside}");
}
