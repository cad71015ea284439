//! Window smoke test: a real winit window (under Xvfb when there is no display) presents
//! frames of a file asset, then screenshots the swapchain; the screenshot must equal the
//! headless render of the same camera. One test per binary: winit allows one event loop
//! per process.
mod common;
use common::*;
use std::time::{Duration, Instant};

#[test]
fn window_presents_and_screenshot_matches_headless() {
    if !have_gpu("window_presents_and_screenshot_matches_headless") {
        return;
    }
    let Some(_x) = display() else {
        if gpu_required() {
            panic!("no DISPLAY and no Xvfb, and SNERF_REQUIRE_GPU_TESTS=1");
        }
        eprintln!("SKIP window test: no DISPLAY and no Xvfb (apt-get install xvfb)");
        return;
    };
    let dir = tmp("window");
    let asset_path = dir.join("object.snerf");
    let asset = object_asset();
    asset.write(&asset_path).unwrap();
    let shot = dir.join("shot.png");
    let (w, h) = (200u32, 150u32);
    let opts = snerf_viewer::ViewOptions {
        width: w,
        height: h,
        frames: Some(6),
        screenshot: Some(shot.clone()),
        timeout: Some(Duration::from_secs(240)),
        ..Default::default()
    };
    let src = snerf_viewer::FileSource::open(&asset_path).unwrap();
    let t0 = Instant::now();
    snerf_viewer::run_window(Box::new(src), opts).unwrap();
    println!(
        "window: 6 frames presented in {:.2} s",
        t0.elapsed().as_secs_f64()
    );

    let img = image::open(&shot).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (w, h), "screenshot size");
    let cam = snerf_viewer::initial_camera(&asset.header, w, h, 50.0);
    let frame = snerf_viewer::render_frames(&asset, &[(cam, 0.0)])
        .unwrap()
        .remove(0);
    let want: Vec<u8> = frame
        .rgb
        .iter()
        .map(|&v| snerf_asset::quantize_unit(v))
        .collect();
    let got = img.as_raw();
    let mut max = 0i32;
    let mut differing = 0usize;
    for (a, b) in got.iter().zip(&want) {
        let d = (*a as i32 - *b as i32).abs();
        max = max.max(d);
        differing += (d > 0) as usize;
    }
    println!(
        "screenshot vs headless: {} of {} values differ, max {} levels",
        differing,
        want.len(),
        max
    );
    assert!(
        max <= 1,
        "screenshot differs from the headless render by {} levels",
        max
    );
    assert!(
        differing * 1000 <= want.len(),
        "{} values differ",
        differing
    );
    // Not a blank image: the object covers part of the view.
    assert!(coverage(&frame) > 0.05);
}
