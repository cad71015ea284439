//! Window controls end to end: real X input events (xdotool through XTEST) drive the
//! window: left drag orbits, the wheel zooms, F12 saves a screenshot, R resets the view,
//! a resize reconfigures the swapchain, Esc quits. Each screenshot must equal the headless render of the camera the controls
//! should have produced. One test per binary (one winit event loop per process).
mod common;
use common::*;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

fn xdo(args: &[&str]) -> String {
    let out = Command::new("xdotool")
        .args(args)
        .output()
        .expect("xdotool runs");
    String::from_utf8_lossy(&out.stdout).trim().to_string()
}

fn pngs(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|r| {
            r.filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "png"))
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

fn max_level_diff(shot: &std::path::Path, frame: &snerf_asset::Frame) -> i32 {
    let img = image::open(shot).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (frame.width, frame.height));
    img.as_raw()
        .iter()
        .zip(frame.rgb.iter().map(|&v| snerf_asset::quantize_unit(v)))
        .map(|(a, b)| (*a as i32 - b as i32).abs())
        .max()
        .unwrap_or(0)
}

#[test]
fn mouse_and_keys_drive_the_view() {
    if !have_gpu("mouse_and_keys_drive_the_view") {
        return;
    }
    if !which("xdotool") {
        if gpu_required() {
            panic!("xdotool missing, and SNERF_REQUIRE_GPU_TESTS=1 (apt-get install xdotool)");
        }
        eprintln!("SKIP window input test: xdotool not installed");
        return;
    }
    let Some(_x) = display() else {
        if gpu_required() {
            panic!("no DISPLAY and no Xvfb, and SNERF_REQUIRE_GPU_TESTS=1");
        }
        eprintln!("SKIP window input test: no DISPLAY and no Xvfb");
        return;
    };
    let dir = tmp("input");
    let asset = object_asset();
    let (w, h) = (160u32, 120u32);
    let title = format!("snerf input test {}", std::process::id());
    let opts = snerf_viewer::ViewOptions {
        width: w,
        height: h,
        screenshot_dir: dir.to_path_buf(),
        timeout: Some(Duration::from_secs(240)),
        title: title.clone(),
        print_stats: false,
        ..Default::default()
    };
    // The driver: waits for the window, then plays input and waits for each screenshot.
    let d2 = dir.to_path_buf();
    let driver = std::thread::spawn(move || {
        let t0 = Instant::now();
        let wid = loop {
            let id = xdo(&["search", "--name", &title]);
            if let Some(first) = id.lines().next().filter(|s| !s.is_empty()) {
                break first.to_string();
            }
            assert!(
                t0.elapsed() < Duration::from_secs(120),
                "window never appeared"
            );
            std::thread::sleep(Duration::from_millis(200));
        };
        std::thread::sleep(Duration::from_millis(1500));
        let wait_for = |n: usize| {
            let t = Instant::now();
            while pngs(&d2).len() < n {
                assert!(
                    t.elapsed() < Duration::from_secs(120),
                    "screenshot {} never written",
                    n
                );
                std::thread::sleep(Duration::from_millis(100));
            }
        };
        // No window manager: give the window the keyboard focus ourselves.
        xdo(&["windowfocus", &wid]);
        // Orbit: left drag 60 px to the right; zoom: two wheel clicks up.
        xdo(&["mousemove", "--window", &wid, "40", "60"]);
        std::thread::sleep(Duration::from_millis(500));
        xdo(&["mousedown", "1"]);
        std::thread::sleep(Duration::from_millis(300));
        xdo(&["mousemove", "--window", &wid, "100", "60"]);
        std::thread::sleep(Duration::from_millis(300));
        xdo(&["mouseup", "1"]);
        xdo(&["click", "4"]);
        xdo(&["click", "4"]);
        std::thread::sleep(Duration::from_millis(800));
        xdo(&["key", "F12"]);
        wait_for(1);
        xdo(&["key", "r"]);
        std::thread::sleep(Duration::from_millis(800));
        xdo(&["key", "F12"]);
        wait_for(2);
        // Resize: the swapchain and the rendered image follow the window.
        xdo(&["windowsize", &wid, "120", "90"]);
        std::thread::sleep(Duration::from_millis(1500));
        xdo(&["key", "F12"]);
        wait_for(3);
        xdo(&["key", "Escape"]);
    });
    let r = snerf_viewer::run_window(Box::new(snerf_viewer::FileSource::new(asset.clone())), opts);
    let drv = driver.join();
    r.unwrap();
    drv.expect("input driver failed");

    let shots = pngs(&dir);
    assert_eq!(shots.len(), 3, "{:?}", shots);
    // X11 reports a wheel click as one or two scroll events depending on the server's
    // input extensions, so accept 2 to 4 zoom steps for the two clicks.
    let mut cams = Vec::new();
    for steps in 2..=4 {
        let mut ctl = snerf_viewer::Controller::new(&asset.header);
        ctl.orbit(60.0, 0.0);
        ctl.zoom(steps as f32);
        cams.push((snerf_viewer::camera_from_c2w(ctl.c2w(), w, h, 50.0), 0.0));
    }
    let home = snerf_viewer::initial_camera(&asset.header, w, h, 50.0);
    cams.push((home, 0.0));
    let f = snerf_viewer::render_frames(&asset, &cams).unwrap();
    let d_moved = (0..3)
        .map(|k| max_level_diff(&shots[0], &f[k]))
        .min()
        .unwrap();
    let d_home = max_level_diff(&shots[1], &f[3]);
    let d_cross = max_level_diff(&shots[0], &f[3]);
    println!(
        "after drag+wheel vs expected: max {} levels; after R vs home: {}; drag vs home: {}",
        d_moved, d_home, d_cross
    );
    assert!(
        d_moved <= 1,
        "orbit/zoom did not produce the expected view ({} levels)",
        d_moved
    );
    assert!(d_home <= 1, "R did not reset the view ({} levels)", d_home);
    assert!(d_cross > 20, "the controls did not move the camera");
    let small = snerf_viewer::initial_camera(&asset.header, 120, 90, 50.0);
    let fs = snerf_viewer::render_frames(&asset, &[(small, 0.0)]).unwrap();
    let d_small = max_level_diff(&shots[2], &fs[0]);
    println!("after resize to 120x90 vs headless: max {} levels", d_small);
    assert!(d_small <= 1, "resized window shows {} levels off", d_small);
}
