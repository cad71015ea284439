//! The stream -> viewer adapter against a real `snerf-stream` server on loopback: what the
//! window draws while an asset streams in is renderable before the stream completes, and is
//! the served asset exactly once it has.

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

use snerf_asset::Asset;
use snerf_stream::{ClientOptions, LiveAsset, ServeOptions, ServerHandle};
use snerf_viewer::{AssetSource, StreamSource};

fn serve(dir: &Path) -> ServerHandle {
    let mut o = ServeOptions::new(dir.join("assets"), "127.0.0.1:0".parse().unwrap());
    o.state_dir = Some(dir.join("state"));
    o.quiet = true;
    snerf_stream::spawn(o).unwrap()
}

/// Poll `src` like the window does, applying every update to `held`, until the client has
/// finished (complete, or cut) and nothing is left to poll.
fn follow(src: &mut StreamSource, held: &mut Option<Asset>) {
    // A guard against a hang, not a speed requirement.
    let give_up = Instant::now() + Duration::from_secs(120);
    loop {
        let finished = src.live().is_finished();
        while let Some(u) = src.poll() {
            u.apply(held);
        }
        if finished {
            return;
        }
        assert!(Instant::now() < give_up, "the stream neither completed nor ended");
        std::thread::sleep(Duration::from_millis(2));
    }
}

#[test]
fn a_streamed_asset_is_drawable_early_and_exact_at_the_end() {
    let dir = common::tmp("stream-adapter");
    std::fs::create_dir_all(dir.join("assets")).unwrap();
    let file = dir.join("assets").join("scene.snerf");
    common::object_asset().write(&file).unwrap();
    let served = Asset::read(&file).unwrap();
    let size = std::fs::metadata(&file).unwrap().len();
    let server = serve(&dir);
    let url = server.url("scene");

    // Cut after half the file: what arrived must draw, be the served asset wherever it is
    // present, and say that the stream broke.
    let opts = ClientOptions { abort_after_bytes: Some(size / 2), ..Default::default() };
    let mut src = StreamSource::new(LiveAsset::connect_with(&url, server.fingerprint(), server.token(), opts).unwrap());
    let mut held = None;
    follow(&mut src, &mut held);
    assert!(!src.live().is_complete());
    assert!(src.status().is_some_and(|s| s.starts_with("stream error")), "{:?}", src.status());
    let partial = held.expect("nothing drawable arrived in half the file");
    assert!(partial.present.iter().any(|&p| !p), "half the file held every block");
    assert_eq!((&partial.header, &partial.mlp, &partial.grids), (&served.header, &served.mlp, &served.grids));
    let bb = served.block_bytes();
    for (i, _) in partial.present.iter().enumerate().filter(|(_, &p)| p) {
        assert_eq!(partial.atlas[i * bb..(i + 1) * bb], served.atlas[i * bb..(i + 1) * bb], "block {i}");
    }
    let cam = snerf_asset::orbit(&served.header, 4, 0, 48, 48, 50.0);
    let frame = snerf_asset::render(&partial, &cam, 0.0);
    assert!(frame.rgb.iter().all(|v| v.is_finite()));
    assert!(common::coverage(&frame) > 0.0, "the partial asset draws nothing");

    // Uncut: the adapter ends with the served asset, block for block.
    let mut src = StreamSource::connect(&url, server.fingerprint(), server.token()).unwrap();
    let mut held = None;
    follow(&mut src, &mut held);
    assert!(src.live().is_complete(), "{:?}", src.live().error());
    assert_eq!(src.status(), None);
    assert!(held.as_ref() == Some(&served), "the streamed asset differs from the served one");

    server.shutdown();
}
