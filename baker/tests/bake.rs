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

/// This test's directory: removed when it passes, kept (and named) when it fails.
fn tmp(name: &str) -> snerf_files::ScratchDir {
    snerf_files::ScratchDir::new("snerf-bake", name).unwrap()
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
    // the capture's up and the floor travel with the asset
    let up = asset.header.view.expect("the asset carries its up and preview orbit").up();
    let cams_up = snerf_geometry::camera::mean_up(data.train.iter().map(|v| &v.c2w));
    assert!(snerf_geometry::vec::dot(up, cams_up) > 0.999, "asset up {up:?} vs cameras' {cams_up:?}");
    let floor = asset.header.floor.expect("the asset carries its floor");
    let centre = snerf_geometry::vec::dot(asset.header.space.center, up);
    let half = 1.0 / asset.header.space.scale;
    assert!(floor < centre && floor > centre - 1.75 * half, "floor {floor} vs centre height {centre} (box half {half})");
    let f = faithfulness::measure(&t.model, &t.pool, &asset, &data.test, 4).unwrap();
    eprintln!("{f:#?}\n{report:#?}");
    assert!(f.mean_baked_vs_field >= 30.0, "baked vs field {:.2} dB", f.mean_baked_vs_field);
    // the bake's own loss, like with like (both drawn as the asset draws each camera)
    assert!(f.bake_loss_db <= 1.0, "baking loses {:.2} dB on test views", f.bake_loss_db);
    // a static object's asset carries the trainer's silhouette rule and the footprint of the
    // pixels it was trained on (the run's own record), under which the held-out views use it
    assert_eq!(asset.header.pixel_rays, 4);
    let recorded = t.model.pixel_footprint.expect("the run records its views' pixel footprint");
    assert_eq!(asset.header.train_pixel, Some(recorded));
    assert!(data.test.iter().all(|v| asset.header.pixel_rays_for(&faithfulness::camera_of(v)) == 4));
    let back = snerf_asset::Asset::read(&file).unwrap();
    assert_eq!(back.atlas, asset.atlas);
}

/// The small moving scene (the avatar: mouth, eyes and brows move) baked at 24 time samples
/// is at most twice one static frame of it, shares blocks across time, and stays faithful
/// at the test views' own (held-out) times.
#[test]
fn dynamic_avatar_bakes_24_samples_within_twice_a_static_frame() {
    let dir = tmp("avatar");
    let (data, t) = tiny_run("avatar", &dir, 300);
    let bg = eval_background(views_have_alpha(&data.train));
    // the block codebook alone first (`--motion false`), under a budget below the default's
    // 2.4, so that it has to share blocks across time to fit twice a static frame
    let opts = BakeOptions { res: 64, keyframes: 24, motion: false, time_budget: 1.8, ..Default::default() };
    let (asset, report) = bake(&t.model, &t.pool, &data.train, bg, &opts, &|_, _, _| {}).unwrap();
    assert!(asset.is_dynamic() && asset.header.motion_ref.is_none());
    // playback blends colour by density (FORMAT.md, "Sampling a grid point")
    assert!(asset.header.colour_by_density);
    assert_eq!(asset.num_frames(), 24);
    assert!(report.shared_blocks > 0, "no block was shared between samples: {report:?}");
    let file = dir.join("avatar.snerf");
    asset.write(&file).unwrap();
    let bytes = std::fs::metadata(&file).unwrap().len();
    let s = asset.summary(bytes);
    eprintln!("{report:#?}\n{s:#?}");
    assert!(bytes as f64 <= 2.0 * s.static_frame_bytes as f64, "{bytes} bytes vs a static frame of {}", s.static_frame_bytes);
    // one static frame: the blocks the bake keeps per sample, recorded in the header, so the
    // bake's budget and the asset's summary measure against the same frame
    let mean_blocks = report.frame_blocks.iter().sum::<usize>() as f32 / report.frame_blocks.len() as f32;
    assert_eq!(asset.header.static_frame_blocks, Some(mean_blocks));
    assert!(report.static_frame_bytes.abs_diff(s.static_frame_bytes) * 50 < s.static_frame_bytes, "{} vs {}", report.static_frame_bytes, s.static_frame_bytes);
    assert!(s.animation_seconds.is_some() && s.bytes_per_second.as_ref().is_some_and(|r| r.total > 0.0));
    let f = faithfulness::measure(&t.model, &t.pool, &asset, &data.test, 4).unwrap();
    eprintln!("{f:#?}");
    assert!(f.views.iter().all(|v| v.time.is_some()));
    assert!(f.mean_baked_vs_field >= 25.0, "baked vs field {:.2} dB", f.mean_baked_vs_field);

    // The same run with motion (`snerf_baker::motion`, the default): a version 5 file (sparse grids) of the same size
    // bound, whose frames other than the reference show it moved, as faithful as above.
    let opts = BakeOptions { motion: true, ..opts };
    let (m, mr) = bake(&t.model, &t.pool, &data.train, bg, &opts, &|_, _, _| {}).unwrap();
    let r = mr.motion_reference.expect("a motion bake names its reference");
    assert_eq!(m.header.motion_ref, Some(r as u32));
    assert!(mr.motion_entries > 0, "{mr:?}");
    let file = dir.join("avatar-motion.snerf");
    m.write(&file).unwrap();
    let back = snerf_asset::Asset::read(&file).unwrap();
    assert_eq!(back, m);
    let mbytes = std::fs::metadata(&file).unwrap().len();
    let ms = m.summary(mbytes);
    assert!(mbytes as f64 <= 2.0 * mr.static_frame_bytes as f64, "{mbytes} bytes vs a static frame of {}", mr.static_frame_bytes);
    assert!(mr.static_frame_bytes.abs_diff(ms.static_frame_bytes) * 50 < ms.static_frame_bytes, "{} vs {}", mr.static_frame_bytes, ms.static_frame_bytes);
    let fm = faithfulness::measure(&t.model, &t.pool, &m, &data.test, 4).unwrap();
    eprintln!("motion: {mr:#?}\n{fm:#?}");
    assert!(fm.mean_baked_vs_field >= 25.0, "with motion: baked vs field {:.2} dB", fm.mean_baked_vs_field);
    // every frame's static twin resolves its motion entries into blocks
    let twin = m.frame_as_static((r + 1) % m.num_frames()).unwrap();
    assert!(twin.header.motion_ref.is_none() && twin.header.atlas_blocks > 0);
    // and the GLB flipbook meshes what every frame shows, as it does for the codebook alone
    let (_, meshes) = snerf_baker::mesh_export::export_glb(&m, 0.5, &dir.join("m.glb")).unwrap();
    let (_, plain) = snerf_baker::mesh_export::export_glb(&asset, 0.5, &dir.join("p.glb")).unwrap();
    for (f, (a, b)) in meshes.iter().zip(&plain).enumerate() {
        let (ta, tb) = (a.triangle_count() as f64, b.triangle_count() as f64);
        assert!(ta > 0.5 * tb && ta < 2.0 * tb, "frame {f}: {ta} triangles with motion, {tb} without");
    }

    // One static frame counted per sample: each sample counts exactly the blocks a static
    // bake at its time (`--at-time`) keeps, never more than the bake keeps there, and the
    // blocks each sample keeps are the same without the option.
    let few = BakeOptions { res: 64, keyframes: 3, motion: false, ..Default::default() };
    let (_, union) = bake(&t.model, &t.pool, &data.train, bg, &few, &|_, _, _| {}).unwrap();
    assert_eq!(union.static_blocks, union.frame_blocks);
    let per = BakeOptions { static_frame_per_sample: true, ..few.clone() };
    let (ps, pr) = bake(&t.model, &t.pool, &data.train, bg, &per, &|_, _, _| {}).unwrap();
    eprintln!("blocks per sample: kept {:?}, one static frame {:?}", pr.frame_blocks, pr.static_blocks);
    assert_eq!(pr.frame_blocks, union.frame_blocks);
    for f in 0..3 {
        let at = BakeOptions { at_time: Some(ps.header.frame_time(f)), ..few.clone() };
        let (_, one) = bake(&t.model, &t.pool, &data.train, bg, &at, &|_, _, _| {}).unwrap();
        assert_eq!(pr.static_blocks[f], one.frame_blocks[0], "sample {f}");
        assert!(pr.static_blocks[f] <= pr.frame_blocks[f], "sample {f}");
    }
}
