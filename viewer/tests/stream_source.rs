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

/// A style of a multi-style asset over the stream: once complete, a style key
/// (`select_style`) switches by the new style's colour part alone (the server's count: that
/// part and a 4-byte index a record), and the window gets the new style whole, exactly; then
/// back. Keys for the style shown or a style the file lacks do nothing.
#[test]
fn a_streamed_style_switches_by_its_colour_part() {
    use snerf_asset::{LayeredAsset, StyleInfo};
    use snerf_viewer::window::AssetUpdate;
    let dir = common::tmp("stream-styles");
    std::fs::create_dir_all(dir.join("assets")).unwrap();
    let warm = common::object_asset();
    let mut cold = warm.clone();
    for v in cold.atlas.chunks_exact_mut(8) {
        for c in &mut v[1..] {
            *c = 255 - *c;
        }
    }
    let info = |n: &str| StyleInfo { name: n.into(), source: None, swatch: [0.5; 3] };
    let layered = LayeredAsset::new(vec![info("warm"), info("cold")], vec![warm, cold]).unwrap();
    layered.write(dir.join("assets").join("scene.snerf")).unwrap();
    let server = serve(&dir);
    let mut src = StreamSource::connect(&server.url("scene.warm"), server.fingerprint(), server.token()).unwrap();
    let mut held = None;
    follow(&mut src, &mut held);
    assert!(held.as_ref() == Some(&layered.layers[0]));
    let give_up = Instant::now() + Duration::from_secs(60);
    let switch = |src: &mut StreamSource, i: usize, name: &str| {
        // the listing (which names the styles) comes in the background
        let got = loop {
            if let Some(n) = src.select_style(i) {
                break n;
            }
            assert!(Instant::now() < give_up, "no style keys");
            std::thread::sleep(Duration::from_millis(5));
        };
        assert_eq!(got, name);
        assert_eq!(src.select_style(i), None, "a switch under way");
        loop {
            match src.poll() {
                Some(AssetUpdate::Whole(a)) => break *a,
                Some(_) => panic!("a switch yields the style whole"),
                None => {}
            }
            assert!(Instant::now() < give_up, "the switch did not complete: {:?}", src.status());
            std::thread::sleep(Duration::from_millis(2));
        }
    };
    let stats = server.stats().clone();
    let before = stats.colour_bytes_sent.load(std::sync::atomic::Ordering::Relaxed);
    let a = switch(&mut src, 1, "cold");
    assert!(a == layered.layers[1], "the switched asset is the cold style exactly");
    let records = layered.header().atlas_blocks as u64 + 1;
    let sent = stats.colour_bytes_sent.load(std::sync::atomic::Ordering::Relaxed) - before;
    assert_eq!(sent, layered.style_bytes()[1].bytes + 4 * records);
    assert_eq!(src.select_style(1), None, "already shown");
    assert_eq!(src.select_style(5), None, "no sixth style");
    let a = switch(&mut src, 0, "warm");
    assert!(a == layered.layers[0], "and back");

    // A style the server adds while the viewer shows the file (what `snerf serve --styles-dir`
    // does once a layer is trained: the file written again with it, the watching sessions
    // told): the next key reaches it, by colour.
    assert_eq!(src.select_style(2), None, "no third style yet");
    let mut green = layered.layers[0].clone();
    for v in green.atlas.chunks_exact_mut(8) {
        for c in &mut v[1..] {
            *c /= 2;
        }
    }
    let (mut styles, mut layers) = (layered.styles.clone(), layered.layers.clone());
    styles.push(info("green"));
    layers.push(green);
    let three = LayeredAsset::new(styles, layers).unwrap();
    three.write(dir.join("assets").join("scene.snerf")).unwrap();
    assert_eq!(server.announcer().styles_changed("scene").unwrap(), 1, "the viewer watches");
    let a = switch(&mut src, 2, "green");
    assert!(a == three.layers[2], "the new style exactly");
    server.shutdown();
}
