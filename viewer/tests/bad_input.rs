//! Bad input gets a clear error, never a panic: an atlas beyond the device's 3D texture
//! limit, an inconsistent hand-built asset, empty images, bad pose files, no adapter.
mod common;
use common::*;
use snerf_viewer::{AtlasLayout, GpuOptions, GpuRenderer, LimitError, NoAdapterError};

#[test]
fn atlas_beyond_max_3d_texture_is_a_clear_error() {
    if !have_gpu("atlas_beyond_max_3d_texture_is_a_clear_error") {
        return;
    }
    // 412 blocks of 10^3 voxels; a device limited to 3D textures of 64 texels per axis
    // holds at most 6^3 = 216 blocks.
    let a = object_asset();
    assert!(
        a.header.atlas_blocks > 216,
        "{} blocks",
        a.header.atlas_blocks
    );
    let opts = GpuOptions {
        max_texture_dimension_3d: Some(64),
        ..Default::default()
    };
    let err = match GpuRenderer::with_options(&a, opts) {
        Ok(_) => panic!("an atlas beyond the texture limit was accepted"),
        Err(e) => e,
    };
    let msg = format!("{:#}", err);
    println!("error: {}", msg);
    assert!(msg.contains("max_texture_dimension_3d = 64"), "{}", msg);
    let le = err.downcast_ref::<LimitError>().expect("a LimitError");
    assert_eq!(le.limit, "max_texture_dimension_3d");
    // The same asset fits the real device.
    let r = GpuRenderer::new(&a).unwrap();
    let l = r.atlas_layout();
    assert!(l.nx * l.ny * l.nz >= a.header.atlas_blocks);
    println!(
        "real layout {:?}, device max 3D {}",
        l,
        r.context().limits().max_texture_dimension_3d
    );
}

#[test]
fn atlas_layout_plans() {
    let l = AtlasLayout::plan(1000, 10, 2048).unwrap();
    assert!(
        l.nx * l.ny * l.nz >= 1000 && l.texels().iter().all(|&t| t <= 2048),
        "{:?}",
        l
    );
    let l = AtlasLayout::plan(8_000_000, 10, 2048).unwrap(); // 204^3 = 8.49M fit
    assert!(
        l.nx as u64 * l.ny as u64 * l.nz as u64 >= 8_000_000
            && l.texels().iter().all(|&t| t <= 2048),
        "{:?}",
        l
    );
    let e = AtlasLayout::plan(9_000_000, 10, 2048).unwrap_err();
    assert!(
        e.to_string().contains("max_texture_dimension_3d = 2048"),
        "{}",
        e
    );
    assert!(
        AtlasLayout::plan(1, 66, 64).is_err(),
        "a block larger than the limit"
    );
    for n in [0u32, 1, 2, 7, 8, 9, 63, 64, 65, 1000, 4097] {
        let l = AtlasLayout::plan(n, 6, 256).unwrap();
        assert!(l.nx * l.ny * l.nz >= n.max(1));
        // all origins distinct and inside
        let t = l.texels();
        let mut seen = std::collections::HashSet::new();
        for i in 0..n {
            let o = l.origin(i);
            assert!(o[0] + 6 <= t[0] && o[1] + 6 <= t[1] && o[2] + 6 <= t[2]);
            assert!(seen.insert(o));
        }
    }
}

#[test]
fn inconsistent_asset_and_bad_cameras_are_errors() {
    if !have_gpu("inconsistent_asset_and_bad_cameras_are_errors") {
        return;
    }
    let mut a = dynamic_asset();
    a.atlas.truncate(a.atlas.len() - 1);
    let msg = format!(
        "{:#}",
        GpuRenderer::new(&a)
            .err()
            .expect("truncated atlas accepted")
    );
    assert!(msg.contains("atlas"), "{}", msg);

    let a = dynamic_asset();
    let mut r = GpuRenderer::new(&a).unwrap();
    let mut c = cams(&a.header, 1, 32, 32)[0];
    c.width = 0;
    assert!(r.render(&c, 0.0).is_err());
    let mut c = cams(&a.header, 1, 32, 32)[0];
    c.fx = 0.0;
    assert!(r.render(&c, 0.0).is_err());
    // An image larger than a storage buffer may hold.
    let mut c = cams(&a.header, 1, 32, 32)[0];
    c.width = 60_000;
    c.height = 60_000;
    let msg = format!("{:#}", r.render(&c, 0.0).expect_err("huge image accepted"));
    println!("huge image: {}", msg);
    assert!(msg.contains("limit"), "{}", msg);
    // Still usable afterwards.
    let c = cams(&a.header, 1, 32, 32)[0];
    r.render(&c, 0.5).unwrap();
}

#[test]
fn no_adapter_is_a_typed_error_and_cpu_fallback_says_so() {
    setup();
    // No backend at all: the same path as a machine without any GPU driver.
    let a = dynamic_asset();
    let opts = GpuOptions {
        backends: Some(wgpu::Backends::empty()),
        ..Default::default()
    };
    let err = GpuRenderer::with_options(&a, opts)
        .err()
        .expect("no backends gave an adapter");
    let msg = format!("{:#}", err);
    println!("{}", msg);
    assert!(err.downcast_ref::<NoAdapterError>().is_some(), "{}", msg);
    assert!(msg.contains("no GPU adapter"), "{}", msg);
}

#[test]
fn bad_pose_files_are_errors() {
    let dir = tmp("poses");
    let p = dir.join("poses.json");
    std::fs::write(&p, "[{\"c2w\": [[1,0,0,0],[0,1,0,0]], \"time\": 0.5}]").unwrap();
    let e = snerf_viewer::load_poses(&p).unwrap_err().to_string();
    assert!(e.contains("poses.json") && e.contains("rows"), "{}", e);
    std::fs::write(&p, "not json").unwrap();
    assert!(snerf_viewer::load_poses(&p)
        .unwrap_err()
        .to_string()
        .contains("poses.json"));
    std::fs::write(&p, "[{\"c2w\": [[1,0,0,0],[0,1,0,0],[0,0,1,3]], \"time\": 0.5}, {\"c2w\": [[1,0,0,0],[0,1,0,0],[0,0,1,3],[0,0,0,1]]}]").unwrap();
    let poses = snerf_viewer::load_poses(&p).unwrap();
    assert_eq!(poses.len(), 2);
    assert_eq!(poses[1].time, None);
}

#[test]
fn lost_device_is_an_error_not_a_panic() {
    if !have_gpu("lost_device_is_an_error_not_a_panic") {
        return;
    }
    let a = dynamic_asset();
    let mut r = GpuRenderer::new(&a).unwrap();
    let c = cams(&a.header, 1, 32, 24)[0];
    r.render(&c, 0.0).unwrap();
    r.context().destroy_device_for_test();
    for _ in 0..2 {
        let e = r
            .render(&c, 0.3)
            .expect_err("rendering on a destroyed device succeeded");
        let msg = format!("{:#}", e);
        println!("after device loss: {}", msg);
        assert!(
            e.downcast_ref::<snerf_viewer::DeviceLostError>().is_some(),
            "{}",
            msg
        );
    }
    // A fresh renderer works again (what the window does on loss).
    let mut r2 = GpuRenderer::new(&a).unwrap();
    r2.render(&c, 0.3).unwrap();
}
