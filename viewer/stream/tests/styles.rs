//! Multi-style assets (format version 3) over the loopback: the file's name streams its first
//! style and `NAME.STYLE` any style, each as that style's single-style asset byte for byte
//! (what every client reads); the listing names the styles; a style the file does not have is
//! refused by name. A switch of style sends only the new style's colour part.

mod common;
use common::*;
use snerf_asset::{Asset, LayeredAsset};
use snerf_stream::{fetch, list};
use snerf_stream::plan::ServedAsset;
use snerf_stream::restyle::switch_style;
use std::sync::atomic::Ordering;

#[test]
fn a_multi_style_file_streams_one_style_per_name() {
    let _s = serial();
    let dir = TempDir::new("styles");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let file = assets.join("scene.snerf");
    two_styles().write(&file).unwrap();
    let expect = |i: usize| LayeredAsset::read(&file).unwrap().into_style(i).unwrap().to_bytes();
    let (warm, cold) = (expect(0), expect(1));
    assert_ne!(warm, cold);

    // the planner's view: the first style unless a style is named; its styles listed
    let served = ServedAsset::load("scene", &file).unwrap();
    assert_eq!(&served.bytes[..], &warm[..]);
    let st = served.styles.clone().unwrap();
    assert_eq!((st.names.as_slice(), st.served), (&["warm".to_string(), "cold".to_string()][..], 0));
    assert!(st.message(&file, "scene").contains("scene.cold"), "{}", st.message(&file, "scene"));
    let e = ServedAsset::load_style("scene.x", &file, Some("x")).err().unwrap();
    assert!(format!("{e:#}").contains("warm, cold"), "{e:#}");

    let server = start_server(&assets, &dir.join("state"), Default::default());
    let rt = runtime();
    // the listing names the styles and their swatches, from the header
    let listed = rt.block_on(list(&server.url(""), server.fingerprint(), server.token())).unwrap();
    let styles = listed.iter().find(|e| e.name == "scene").and_then(|e| e.styles.clone()).unwrap();
    assert_eq!(styles, LayeredAsset::read(&file).unwrap().styles, "{listed:?}");
    for (name, want) in [("scene", &warm), ("scene.warm", &warm), ("scene.cold", &cold)] {
        let out = dir.join(&format!("{name}.fetched.snerf"));
        rt.block_on(fetch(&server.url(name), server.fingerprint(), server.token(), &out)).unwrap();
        let got = std::fs::read(&out).unwrap();
        assert!(got == *want, "{name}: the fetched file is not that style's single-style asset");
        let a = Asset::read(&out).unwrap();
        assert!(a.header.styles.is_none(), "{name}: a client gets a single-style asset");
    }
    let e = rt
        .block_on(fetch(&server.url("scene.sepia"), server.fingerprint(), server.token(), &dir.join("no.snerf")))
        .unwrap_err();
    assert!(format!("{e:#}").contains("no style \"sepia\""), "{e:#}");
    server.shutdown();
}

/// A style switch (`colour_of`): a client holding `scene.warm` asks for `scene.cold` by its
/// colour part alone. What the server sends, counted by its own counters and send log, is
/// exactly that style's colour part (its SMLP and SCOL chunks as the file has them) plus the
/// 4-byte index of each record, well below the whole style; the client ends with
/// `scene.cold` byte for byte. Blocks go in the order the pose gives (in view first).
/// Switches the server cannot answer by colour are refused with a reason.
#[test]
fn a_switch_of_style_sends_only_the_new_styles_colour_part() {
    let _s = serial();
    let dir = TempDir::new("styles-switch");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let file = assets.join("scene.snerf");
    let layered = two_styles();
    layered.write(&file).unwrap();
    write_asset(&static_asset(32, 8, 0.8, 5), &assets, "plain");
    let cold = layered.clone().into_style(1).unwrap().to_bytes();
    let colour_part = layered.style_bytes()[1].bytes;
    let blocks = layered.header().atlas_blocks as u64;
    let limits = snerf_stream::Limits { log_sends: true, ..Default::default() };
    let server = start_server(&assets, &dir.join("state"), limits);
    let rt = runtime();
    let out = dir.join("warm.snerf");
    rt.block_on(fetch(&server.url("scene.warm"), server.fingerprint(), server.token(), &out)).unwrap();
    let mut held = Asset::read(&out).unwrap();
    let held_info = ServedAsset::load_style("scene.warm", &file, Some("warm")).unwrap().info();
    assert!(held_info.geometry.is_some());
    let stats = server.stats().clone();
    let before = stats.bytes_sent.load(Ordering::Relaxed);
    let log_before = stats.send_log.lock().unwrap().len();
    let pose = snerf_stream::Pose::new([0.0, 0.0, 3.0], [0.0, 0.0, -1.0]);
    let sw = rt
        .block_on(switch_style(&server.url("scene.cold"), server.fingerprint(), server.token(), &mut held, &held_info, Some(pose)))
        .unwrap();
    assert!(held.to_bytes() == cold, "the switched asset is scene.cold byte for byte");
    let records = blocks + 1; // every block's colour and the view MLP
    let want = colour_part + 4 * records;
    assert_eq!(sw.records as u64, records);
    assert_eq!(sw.bytes, want, "received: the colour part and a 4-byte index per record");
    // The server's own count of what it sent for the switch (a writer counts its batch once
    // QUIC has taken it: wait a moment for the last one's count).
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
    while stats.bytes_sent.load(Ordering::Relaxed) - before < want && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let sent = stats.bytes_sent.load(Ordering::Relaxed) - before;
    assert_eq!(sent, want, "sent: the colour part and a 4-byte index per record");
    assert_eq!(stats.colour_bytes_sent.load(Ordering::Relaxed), want);
    assert_eq!(stats.colour_records_sent.load(Ordering::Relaxed), records);
    let log: Vec<_> = stats.send_log.lock().unwrap()[log_before..].to_vec();
    assert!(log.iter().all(|b| b.colour && b.pose == Some(pose)), "only colour batches, chosen for the pose");
    assert_eq!(log.iter().map(|b| b.chunks.len() as u64).sum::<u64>(), blocks, "each block's colour once");
    assert_eq!(log.iter().map(|b| b.bytes).sum::<u64>() + 4 + 4 * 883 + 16, want, "the blocks' records and the MLP's");
    let whole = cold.len() as u64;
    eprintln!(
        "switch: {} bytes ({} records) against {} for the whole style ({:.2}x); welcome {:?}, first record {:?}, complete {:?}",
        sent, records, whole, sent as f64 / whole as f64, sw.welcome, sw.first_record, sw.complete
    );
    assert!(sent * 4 < whole * 3, "a switch sends {sent} bytes, not well below the whole style's {whole}");
    // the order: the blocks in the order the planner gives for that pose (in view first)
    let served = ServedAsset::load_style("scene.cold", &file, Some("cold")).unwrap();
    let mut order: Vec<u32> = (0..served.blks.len() as u32).collect();
    snerf_stream::plan::order_blocks(&served, &mut order, Some(pose));
    let want_order: Vec<u32> = order.iter().rev().map(|&b| served.blks[b as usize].chunk).collect();
    let got_order: Vec<u32> = log.iter().flat_map(|b| b.chunks.clone()).collect();
    assert_eq!(got_order, want_order);

    // Refusals, each with its reason: a style the file lacks, a single-style asset, a
    // geometry that is not the file's.
    let try_switch = |name: &str, info: &snerf_stream::proto::AssetInfo| {
        let mut a = Asset::read(&out).unwrap();
        let e = rt
            .block_on(switch_style(&server.url(name), server.fingerprint(), server.token(), &mut a, info, None))
            .unwrap_err();
        format!("{e:#}")
    };
    let e = try_switch("scene.sepia", &held_info);
    assert!(e.contains("no style \"sepia\"") && e.contains("not found"), "{e}");
    let e = try_switch("plain", &held_info);
    assert!(e.contains("single style") && e.contains("colour_of"), "{e}");
    let mut other = held_info.clone();
    other.geometry = Some("0".repeat(64));
    let e = try_switch("scene.cold", &other);
    assert!(e.contains("not the geometry") && e.contains("whole asset"), "{e}");
    let mut plain = held_info.clone();
    plain.geometry = None;
    let e = try_switch("scene.cold", &plain);
    assert!(e.contains("not a style of a multi-style asset"), "{e}");
    server.shutdown();
}
