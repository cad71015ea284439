//! Faults between client and server: a lossy, delaying, reordering relay; a connection cut
//! half-way and a resume that fetches only the rest.

mod common;
use common::*;
use snerf_stream::{fetch, fetch_with, part_path, ClientOptions};
use std::time::{Duration, Instant};

#[test]
fn fetch_through_lossy_relay_is_byte_identical() {
    let _s = serial();
    let dir = TempDir::new("lossy");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let want = write_asset(&static_asset(64, 8, 0.95, 11), &assets, "scene");
    for cc in [
        snerf_stream::Congestion::Bbr,
        snerf_stream::Congestion::Cubic,
    ] {
        let limits = snerf_stream::Limits {
            congestion: cc,
            ..Default::default()
        };
        let server = start_server(&assets, &dir.join("state"), limits);
        let rt = runtime();
        rt.block_on(async {
        let cfg = RelayConfig {
            drop: 0.05,
            delay: Duration::from_millis(25),
            reorder: 0.1,
            reorder_extra: Duration::from_millis(15),
            ..Default::default()
        };
        let relay = start_relay(server.addr(), cfg).await;
        let out = dir.join("scene.snerf");
        let url = format!("quic://{}/scene", relay.addr);
        let t0 = Instant::now();
        let st = tokio::time::timeout(Duration::from_secs(240), fetch(&url, server.fingerprint(), server.token(), &out))
            .await
            .expect("lossy fetch did not finish in 240 s")
            .unwrap();
        let dt = t0.elapsed();
        assert!(std::fs::read(&out).unwrap() == want, "lossy fetch differs from the served file");
        let (fwd, drop) = (relay.forwarded.load(std::sync::atomic::Ordering::Relaxed), relay.dropped.load(std::sync::atomic::Ordering::Relaxed));
        println!(
            "LOSSY ({:?}) {:.2} MiB through 5% drop each way, 25 ms delay each way, 10% reordered (+0..15 ms): complete and byte-identical in {:.2} s ({:.2} MB/s; renderable after {:.0} ms); relay forwarded {} datagrams, dropped {} ({:.1}%)",
            cc,
            mb(want.len() as u64),
            dt.as_secs_f64(),
            mb(want.len() as u64) / st.transfer.as_secs_f64(),
            st.time_to_renderable.unwrap().as_secs_f64() * 1e3,
            fwd,
            drop,
            100.0 * drop as f64 / (fwd + drop).max(1) as f64
        );
        assert!(drop > 0, "the relay dropped nothing");
    });
        server.shutdown();
    }
}

#[test]
fn cut_at_half_then_resume_fetches_only_the_rest() {
    let _s = serial();
    let dir = TempDir::new("resume");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let want = write_asset(&static_asset(80, 8, 0.95, 12), &assets, "scene");
    let size = want.len() as u64;
    let server = start_server(&assets, &dir.join("state"), Default::default());
    let rt = runtime();
    rt.block_on(async {
        // The relay stops forwarding anything after half the file went server -> client.
        let cfg = RelayConfig { delay: Duration::from_millis(2), cut_after_s2c: Some(size / 2), ..Default::default() };
        let relay = start_relay(server.addr(), cfg).await;
        let out = dir.join("scene.snerf");
        let url = format!("quic://{}/scene", relay.addr);
        let opts = ClientOptions { idle_timeout: Duration::from_secs(2), keep_alive: Duration::from_millis(500), ..Default::default() };
        let e = fetch_with(&url, server.fingerprint(), server.token(), &out, &opts).await.unwrap_err();
        let msg = format!("{:#}", e);
        assert!(msg.contains("interrupted") && msg.contains(".part"), "{}", msg);
        assert!(!out.exists(), "a partial download must not appear as the output file");
        assert!(part_path(&out).exists());
        drop(relay);
        // Resume directly.
        let st = fetch(&server.url("scene"), server.fingerprint(), server.token(), &out).await.unwrap();
        assert!(std::fs::read(&out).unwrap() == want, "resumed file differs");
        assert!(!part_path(&out).exists());
        assert!(st.resumed);
        let remaining = size - st.bytes_already_had - 16;
        let ratio = st.bytes_received as f64 / remaining as f64;
        println!(
            "RESUME {:.2} MiB cut after {:.0}% ({} of {} chunks kept in .part); second connection received {} record bytes for {} remaining chunk bytes = {:.4}x (UDP incl. QUIC overhead: {} bytes = {:.3}x)",
            mb(size),
            100.0 * st.bytes_already_had as f64 / size as f64,
            st.chunks_already_had,
            st.chunks,
            st.bytes_received,
            remaining,
            ratio,
            st.udp_bytes_received,
            st.udp_bytes_received as f64 / remaining as f64
        );
        assert!(st.bytes_already_had as f64 > 0.25 * size as f64, "the cut kept too little ({} bytes)", st.bytes_already_had);
        assert!(ratio <= 1.05, "resume transferred {:.3}x the remaining bytes", ratio);
        assert!(st.udp_bytes_received as f64 <= 1.10 * remaining as f64 + 64.0 * 1024.0);
    });
    server.shutdown();
}

#[test]
fn client_abort_then_resume_and_torn_part_file() {
    let dir = TempDir::new("abort");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let want = write_asset(&static_asset(64, 8, 0.95, 13), &assets, "scene");
    let size = want.len() as u64;
    let server = start_server(&assets, &dir.join("state"), Default::default());
    let rt = runtime();
    rt.block_on(async {
        let out = dir.join("scene.snerf");
        let opts = ClientOptions {
            abort_after_bytes: Some(size / 2),
            ..Default::default()
        };
        fetch_with(
            &server.url("scene"),
            server.fingerprint(),
            server.token(),
            &out,
            &opts,
        )
        .await
        .unwrap_err();
        // Tear the tail of the .part log: the torn record is dropped and fetched again.
        let p = part_path(&out);
        let len = std::fs::metadata(&p).unwrap().len();
        let f = std::fs::OpenOptions::new().write(true).open(&p).unwrap();
        f.set_len(len - 100).unwrap();
        drop(f);
        let st = fetch(
            &server.url("scene"),
            server.fingerprint(),
            server.token(),
            &out,
        )
        .await
        .unwrap();
        assert!(st.resumed && st.chunks_already_had > 0);
        assert!(std::fs::read(&out).unwrap() == want);
        // A .part of another file (different sha) is discarded, not mixed in.
        let other = dir.join("other.snerf");
        fetch_with(
            &server.url("scene"),
            server.fingerprint(),
            server.token(),
            &other,
            &opts,
        )
        .await
        .unwrap_err();
        let asset2 = static_asset(64, 8, 0.95, 14);
        asset2.write(assets.join("scene.snerf")).unwrap();
        let want2 = std::fs::read(assets.join("scene.snerf")).unwrap();
        let st = fetch(
            &server.url("scene"),
            server.fingerprint(),
            server.token(),
            &other,
        )
        .await
        .unwrap();
        assert!(!st.resumed);
        assert!(std::fs::read(&other).unwrap() == want2);
    });
    server.shutdown();
}
