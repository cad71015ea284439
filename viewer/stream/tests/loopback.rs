//! Loopback streaming: byte-identical fetch with QUIC vs plain TCP throughput side by side,
//! time to first renderable view, pose re-prioritization and 4D keyframe order.

mod common;
use common::*;
use snerf_stream::plan::{ServedAsset, View};
use snerf_stream::{fetch, fetch_with, ClientOptions, LiveAsset, Pose};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[test]
fn fetch_is_byte_identical_and_keeps_up_with_tcp() {
    let _s = serial();
    let dir = TempDir::new("throughput");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let bytes = Arc::new(write_asset(&static_asset(128, 8, 1.0, 1), &assets, "big"));
    let size = bytes.len() as u64;
    let server = start_server(&assets, &dir.join("state"), Default::default());
    let rt = runtime();
    let url = server.url("big");
    let out = dir.join("big.snerf");
    let (mut best_q, mut best_t, mut best_total) = (Duration::MAX, Duration::MAX, Duration::MAX);
    for round in 0..4 {
        let _ = std::fs::remove_file(&out);
        let st = rt
            .block_on(fetch(&url, server.fingerprint(), server.token(), &out))
            .unwrap();
        assert_eq!(
            std::fs::read(&out).unwrap(),
            *bytes,
            "fetched file differs from the served file"
        );
        assert!(
            !snerf_stream::part_path(&out).exists(),
            ".part left behind after a complete fetch"
        );
        assert_eq!(st.chunks_received, st.chunks);
        let tcp_out = dir.join("tcp.bin");
        let t = tcp_copy(bytes.clone(), &tcp_out);
        assert_eq!(std::fs::metadata(&tcp_out).unwrap().len(), size);
        println!(
            "round {}: QUIC transfer {:.1} ms ({:.0} MB/s; total with write+verify {:.1} ms), TCP {:.1} ms ({:.0} MB/s)",
            round,
            st.transfer.as_secs_f64() * 1e3,
            mb(size) / st.transfer.as_secs_f64(),
            st.elapsed.as_secs_f64() * 1e3,
            t.as_secs_f64() * 1e3,
            mb(size) / t.as_secs_f64()
        );
        best_q = best_q.min(st.transfer);
        best_total = best_total.min(st.elapsed);
        best_t = best_t.min(t);
    }
    let ratio = best_t.as_secs_f64() / best_q.as_secs_f64();
    println!(
        "THROUGHPUT {:.1} MiB asset: QUIC {:.0} MB/s (best transfer {:.1} ms, end-to-end incl. write+verify {:.1} ms), TCP {:.0} MB/s ({:.1} ms); QUIC/TCP = {:.0}%",
        mb(size),
        mb(size) / best_q.as_secs_f64(),
        best_q.as_secs_f64() * 1e3,
        best_total.as_secs_f64() * 1e3,
        mb(size) / best_t.as_secs_f64(),
        best_t.as_secs_f64() * 1e3,
        ratio * 100.0
    );
    // The QUIC/TCP ratio is a benchmark figure (BENCH.md), never asserted: on a shared
    // machine it swings with whatever else runs. The byte-identity above is the test.
    server.shutdown();
}

/// Blocks whose centre lies in the view cone of `pose`, by the server's own rule.
fn blocks_in_view(path: &std::path::Path, pose: &Pose) -> (Vec<u32>, u64, u64) {
    let a = ServedAsset::load("x", path).unwrap();
    let v = View::new(&a, pose);
    let mut blocks = Vec::new();
    let mut bytes: u64 = a.meta.iter().map(|&i| a.record_len(i)).sum();
    let meta = bytes;
    for b in &a.blks {
        if a.in_view(b, &v) {
            let r = &a.ranges[b.chunk as usize];
            let p = &a.bytes[r.start + 12..];
            let first = u32::from_le_bytes([p[0], p[1], p[2], p[3]]);
            blocks.push(first);
            bytes += a.record_len(b.chunk);
        }
    }
    (blocks, bytes, meta)
}

#[test]
fn time_to_first_renderable_view() {
    let _s = serial();
    let dir = TempDir::new("ttfr");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let bytes = write_asset(&static_asset(96, 8, 0.95, 2), &assets, "room");
    let size = bytes.len() as u64;
    let server = start_server(&assets, &dir.join("state"), Default::default());
    // Eye at the centre of the scene looking along +x with a 60° field of view.
    let pose = Pose {
        eye: [0.0, 0.0, 0.0],
        forward: [1.0, 0.0, 0.0],
        time: 0.0,
        fov_deg: 60.0,
    };
    let (view, ideal_bytes, meta_bytes) = blocks_in_view(&assets.join("room.snerf"), &pose);
    let nblocks = ServedAsset::load("x", &assets.join("room.snerf"))
        .unwrap()
        .blks
        .len();
    assert!(
        view.len() * 3 < nblocks,
        "test view should see a minority of blocks ({} of {})",
        view.len(),
        nblocks
    );
    let url = server.url("room");
    let measure = |label: &str| {
        let opts = ClientOptions {
            pose: Some(pose),
            ..Default::default()
        };
        let t0 = Instant::now();
        let live =
            LiveAsset::connect_with(&url, server.fingerprint(), server.token(), opts).unwrap();
        let (mut t_render, mut t_view) = (None, None);
        let mut order: Vec<u32> = Vec::new();
        let mut missing: std::collections::HashSet<u32> = view.iter().copied().collect();
        let mut view_pos = None;
        while t0.elapsed() < Duration::from_secs(60) {
            if t_render.is_none() && live.with_asset(|a| a.header.atlas_blocks).is_some() {
                t_render = Some(t0.elapsed());
            }
            for b in live.take_new_blocks() {
                order.push(b);
                missing.remove(&b);
                if missing.is_empty() && view_pos.is_none() {
                    view_pos = Some(order.len());
                    t_view = Some(t0.elapsed());
                }
            }
            if live.is_complete() || live.error().is_some() {
                break;
            }
            std::thread::sleep(Duration::from_micros(200));
        }
        // Bytes the client had when the last block of the view arrived: meta + every block
        // that arrived up to it (all blocks have the same size), from the arrival order.
        let per_block = (size - meta_bytes) as f64 / nblocks as f64;
        let bytes_at_view =
            meta_bytes as f64 + view_pos.expect("view blocks never arrived") as f64 * per_block;
        live.wait(Duration::from_secs(60)).unwrap();
        let total = live.time_to_complete().unwrap();
        let t_view = t_view.expect("view blocks never arrived");
        let frac = bytes_at_view / size as f64;
        println!(
            "TTFR ({}) {:.1} MiB asset, {} blocks, {} in the first view: renderable (header+grids+MLP, {:.1} KiB) after {:.1} ms (client clock {:.1} ms); first view's blocks after {:.1} ms having received {:.1}% of the file (ideal {:.1}%); complete after {:.1} ms",
            label,
            mb(size),
            nblocks,
            view.len(),
            meta_bytes as f64 / 1024.0,
            t_render.unwrap().as_secs_f64() * 1e3,
            live.time_to_renderable().unwrap().as_secs_f64() * 1e3,
            t_view.as_secs_f64() * 1e3,
            frac * 100.0,
            ideal_bytes as f64 / size as f64 * 100.0,
            total.as_secs_f64() * 1e3
        );
        assert!(live.with_asset(|a| a.present.iter().all(|&p| p)).unwrap());
        frac
    };
    // Cold: the server reads and validates the file on the first request.
    measure("cold server");
    let frac = measure("warm server");
    // File order would need nearly the whole file; pose order needs the view plus what is in flight.
    assert!(
        frac < 0.6,
        "first view needed {:.0}% of the file",
        frac * 100.0
    );
    server.shutdown();
}

/// Over a slow (delayed) path the server must follow a pose change: after turning around,
/// the new view's blocks arrive before the blocks nobody looks at.
#[test]
fn pose_change_reprioritizes_remaining_blocks() {
    let _s = serial();
    let dir = TempDir::new("repri");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    write_asset(&static_asset(96, 8, 0.95, 3), &assets, "room");
    let path = assets.join("room.snerf");
    let server = start_server(&assets, &dir.join("state"), Default::default());
    let a = Pose {
        eye: [0.0, 0.0, 0.0],
        forward: [1.0, 0.0, 0.0],
        time: 0.0,
        fov_deg: 60.0,
    };
    let b = Pose {
        eye: [0.0, 0.0, 0.0],
        forward: [-1.0, 0.0, 0.0],
        time: 0.0,
        fov_deg: 60.0,
    };
    let (va, _, _) = blocks_in_view(&path, &a);
    let (vb, _, _) = blocks_in_view(&path, &b);
    let n = ServedAsset::load("x", &path).unwrap().blks.len();
    let rt = runtime();
    let relay = rt.block_on(start_relay(
        server.addr(),
        RelayConfig {
            delay: Duration::from_millis(20),
            ..Default::default()
        },
    ));
    let url = format!("quic://{}/room", relay.addr);
    let opts = ClientOptions {
        pose: Some(a),
        ..Default::default()
    };
    let live = LiveAsset::connect_with(&url, server.fingerprint(), server.token(), opts).unwrap();
    // Turn around as soon as the first view is there.
    let t0 = Instant::now();
    loop {
        let p = live.present_blocks();
        if !p.is_empty() && va.iter().all(|&i| p[i as usize]) {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(60) && live.error().is_none(),
            "first view never arrived"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    live.set_pose_full(b);
    let p_turn = live.present_blocks();
    let had_at_turn = p_turn.iter().filter(|&&x| x).count();
    let others: Vec<u32> = (0..n as u32)
        .filter(|i| !va.contains(i) && !vb.contains(i))
        .collect();
    loop {
        let p = live.present_blocks();
        if vb.iter().all(|&i| p[i as usize]) {
            let others_new = others
                .iter()
                .filter(|&&i| p[i as usize] && !p_turn[i as usize])
                .count();
            let others_left_at_turn = others.iter().filter(|&&i| !p_turn[i as usize]).count();
            println!(
                "REPRIORITIZE {} blocks: view A {} / view B {} / others {}; at the turn {} present; when view B was complete {} of the {} others missing at the turn had arrived",
                n,
                va.len(),
                vb.len(),
                others.len(),
                had_at_turn,
                others_new,
                others_left_at_turn
            );
            // Without re-prioritization the original order (view A's surroundings, nearest
            // first) would deliver most of the others before view B's far side.
            assert!(
                (others_new as f64) < 0.5 * others_left_at_turn as f64,
                "{} of {} unviewed blocks arrived before the new view was complete",
                others_new,
                others_left_at_turn
            );
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(120) && live.error().is_none(),
            "view B never completed: {:?}",
            live.error()
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    live.wait(Duration::from_secs(120)).unwrap();
    drop(relay);
    server.shutdown();
}

/// 4D: blocks of the keyframes ahead of playback come first; a fetch is byte-identical.
#[test]
fn dynamic_keyframes_ahead_of_playback_first() {
    let _s = serial();
    let dir = TempDir::new("dyn");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let asset = dynamic_asset(64, 8, 0.95, 4, 4);
    let bytes = write_asset(&asset, &assets, "anim");
    let server = start_server(&assets, &dir.join("state"), Default::default());
    let rt = runtime();
    let out = dir.join("anim.snerf");
    rt.block_on(fetch(
        &server.url("anim"),
        server.fingerprint(),
        server.token(),
        &out,
    ))
    .unwrap();
    assert_eq!(std::fs::read(&out).unwrap(), bytes);
    // First frame using each block.
    let mut first_frame = vec![usize::MAX; asset.header.atlas_blocks as usize];
    for (f, g) in asset.grids.iter().enumerate() {
        for &e in g {
            if e != snerf_asset::EMPTY && first_frame[e as usize] == usize::MAX {
                first_frame[e as usize] = f;
            }
        }
    }
    // Through a delayed relay so arrival order reflects send order, playback at keyframe 2.
    let relay = rt.block_on(start_relay(
        server.addr(),
        RelayConfig {
            delay: Duration::from_millis(10),
            ..Default::default()
        },
    ));
    let url = format!("quic://{}/anim", relay.addr);
    let pose = Pose {
        eye: [0.0, 0.0, 3.0],
        forward: [0.0, 0.0, -1.0],
        time: 2.0,
        fov_deg: 60.0,
    };
    let live = LiveAsset::connect_with(
        &url,
        server.fingerprint(),
        server.token(),
        ClientOptions {
            pose: Some(pose),
            ..Default::default()
        },
    )
    .unwrap();
    let mut order = Vec::new();
    let t0 = Instant::now();
    while !live.is_complete() {
        order.extend(live.take_new_blocks());
        assert!(
            t0.elapsed() < Duration::from_secs(60) && live.error().is_none(),
            "{:?}",
            live.error()
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    order.extend(live.take_new_blocks());
    assert_eq!(order.len(), asset.header.atlas_blocks as usize);
    // Frames used by each block.
    let mut uses = vec![Vec::new(); asset.header.atlas_blocks as usize];
    for (f, g) in asset.grids.iter().enumerate() {
        for &e in g {
            if e != snerf_asset::EMPTY && !uses[e as usize].contains(&f) {
                uses[e as usize].push(f);
            }
        }
    }
    let mean_rank = |pred: &dyn Fn(&Vec<usize>) -> bool| {
        let r: Vec<usize> = order
            .iter()
            .enumerate()
            .filter(|(_, &b)| pred(&uses[b as usize]))
            .map(|(i, _)| i)
            .collect();
        (
            r.iter().sum::<usize>() as f64 / r.len().max(1) as f64,
            r.len(),
        )
    };
    let (now, n_now) = mean_rank(&|u| u.contains(&2));
    let (next, n_next) = mean_rank(&|u| u.contains(&3) && !u.contains(&2));
    let (past, n_past) = mean_rank(&|u| !u.contains(&2) && !u.contains(&3));
    println!(
        "4D order (playback at keyframe 2 of 4, {} blocks): mean arrival rank of frame-2 blocks {:.0} ({}), frame-3-only {:.0} ({}), earlier-only {:.0} ({})",
        order.len(),
        now,
        n_now,
        next,
        n_next,
        past,
        n_past
    );
    assert!(
        now < next && next < past,
        "keyframes not streamed ahead of playback"
    );
    let _ = first_frame;
    drop(relay);
    server.shutdown();
    let _ = fetch_with;
}

#[test]
fn bench_stream_runs() {
    let _s = serial();
    let dir = TempDir::new("bench");
    write_asset(&static_asset(64, 8, 0.95, 5), dir.path(), "b");
    let r = snerf_stream::bench::run(
        &dir.join("b.snerf"),
        &snerf_stream::bench::BenchOptions {
            rounds: 1,
            ..Default::default()
        },
    )
    .unwrap();
    println!("BENCH\n{}", r);
    assert!(r.first_view_blocks > 0 && r.first_view_blocks <= r.blocks);
    assert!(r.renderable <= r.first_view && r.first_view <= r.complete);
}
