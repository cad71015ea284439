//! Security: tokens, pins, hostile control messages, garbage datagrams, and a property test
//! over every decoder that sees network bytes.

mod common;
use common::*;
use snerf_stream::client::{connect_raw, open_session};
use snerf_stream::proto::{self, code, encode_frame, ClientMsg, PROTOCOL_VERSION};
use snerf_stream::{fetch, ClientOptions, LiveAsset, Pose, ServeOptions};
use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

fn setup(name: &str) -> (TempDir, snerf_stream::ServerHandle, Vec<u8>) {
    let dir = TempDir::new(name);
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let want = write_asset(&static_asset(64, 8, 0.95, 21), &assets, "scene");
    let server = start_server(&assets, &dir.join("state"), Default::default());
    (dir, server, want)
}

fn hello(token: &str, asset: Option<&str>) -> ClientMsg {
    ClientMsg::Hello {
        version: PROTOCOL_VERSION,
        token: token.into(),
        asset: asset.map(str::to_string),
        have: vec![],
        resume_id: None,
        pose: None,
        colour_of: None,
    }
}

#[test]
fn wrong_token_is_refused_before_any_asset_byte() {
    let (dir, server, _) = setup("token");
    let rt = runtime();
    rt.block_on(async {
        // Raw client: count every stream frame the server sends us.
        let opts = ClientOptions::default();
        let (_ep, conn, _) = connect_raw(server.addr(), server.fingerprint(), &opts)
            .await
            .unwrap();
        let (mut send, mut recv) = conn.open_bi().await.unwrap();
        send.write_all(&encode_frame(&hello(
            "0000wrong0000token0000",
            Some("scene"),
        )))
        .await
        .unwrap();
        let mut buf = [0u8; 64];
        let r = recv.read(&mut buf).await;
        assert!(
            r.is_err(),
            "server answered a wrong token with data: {:?}",
            r
        );
        let why = conn.closed().await;
        match &why {
            quinn::ConnectionError::ApplicationClosed(c) => {
                assert_eq!(c.error_code.into_inner(), code::UNAUTHORIZED as u64);
                assert!(String::from_utf8_lossy(&c.reason).contains("token"));
            }
            other => panic!("expected an application close, got {:?}", other),
        }
        assert!(conn.accept_uni().await.is_err());
        let st = conn.stats();
        assert_eq!(
            st.frame_rx.stream, 0,
            "server sent {} STREAM frames to an unauthenticated client",
            st.frame_rx.stream
        );
        println!(
            "SECURITY wrong token: closed with code {} ({}), STREAM frames received: {}",
            code::UNAUTHORIZED,
            why,
            st.frame_rx.stream
        );
        // The fetch client reports it clearly and writes nothing.
        let out = dir.join("x.snerf");
        let e = fetch(
            &server.url("scene"),
            server.fingerprint(),
            "not-the-token",
            &out,
        )
        .await
        .unwrap_err();
        let msg = format!("{:#}", e);
        assert!(
            msg.contains("unauthorized") && msg.contains("invalid access token"),
            "{}",
            msg
        );
        assert!(!out.exists() && !snerf_stream::part_path(&out).exists());
    });
    assert_eq!(server.stats().unauthorized.load(Ordering::Relaxed), 2);
    assert_eq!(server.stats().bytes_sent.load(Ordering::Relaxed), 0);
    assert_eq!(server.stats().streams_started.load(Ordering::Relaxed), 0);
    // LiveAsset too.
    let e = LiveAsset::connect(&server.url("scene"), server.fingerprint(), "nope")
        .err()
        .unwrap();
    assert!(format!("{:#}", e).contains("invalid access token"));
    server.shutdown();
}

#[test]
fn wrong_pin_is_refused_by_the_client() {
    let (dir, server, _) = setup("pin");
    let rt = runtime();
    let wrong = "ab".repeat(32);
    rt.block_on(async {
        let out = dir.join("x.snerf");
        let e = fetch(&server.url("scene"), &wrong, server.token(), &out)
            .await
            .unwrap_err();
        let msg = format!("{:#}", e);
        println!("SECURITY wrong pin: {}", msg);
        assert!(
            msg.contains("does not match the pinned fingerprint"),
            "{}",
            msg
        );
        assert!(
            msg.contains(server.fingerprint()) && msg.contains(&wrong),
            "error should name both fingerprints: {}",
            msg
        );
        assert!(!out.exists());
        // Malformed pins are rejected before connecting.
        for bad in ["", "xyz", &"ab".repeat(31)] {
            let e = fetch(&server.url("scene"), bad, server.token(), &out)
                .await
                .unwrap_err();
            assert!(format!("{:#}", e).contains("fingerprint"), "{:#}", e);
        }
        // Pin formats with colons / prefix / upper case are accepted.
        let colon: String = server
            .fingerprint()
            .to_uppercase()
            .as_bytes()
            .chunks(2)
            .map(|c| std::str::from_utf8(c).unwrap())
            .collect::<Vec<_>>()
            .join(":");
        fetch(
            &server.url("scene"),
            &format!("sha256:{}", colon),
            server.token(),
            &out,
        )
        .await
        .unwrap();
    });
    // The token never reached a server the client did not trust: nothing was authenticated.
    server.shutdown();
}

/// Send raw bytes on a fresh control stream and return the close code the server used.
async fn close_code_for(
    server: &snerf_stream::ServerHandle,
    bytes: Vec<u8>,
    finish: bool,
) -> (u64, String) {
    let (_ep, conn, _) = connect_raw(
        server.addr(),
        server.fingerprint(),
        &ClientOptions::default(),
    )
    .await
    .unwrap();
    let (mut send, _recv) = conn.open_bi().await.unwrap();
    let _ = send.write_all(&bytes).await;
    if finish {
        let _ = send.finish();
    }
    match tokio::time::timeout(Duration::from_secs(20), conn.closed())
        .await
        .expect("server did not close the connection")
    {
        quinn::ConnectionError::ApplicationClosed(c) => (
            c.error_code.into_inner(),
            String::from_utf8_lossy(&c.reason).into_owned(),
        ),
        other => panic!("expected an application close, got {:?}", other),
    }
}

#[test]
fn hostile_control_messages_close_only_that_connection() {
    let (dir, server, want) = setup("hostile");
    let rt = runtime();
    let token = server.token().to_string();
    rt.block_on(async {
        // A good client streams the whole time through a slow relay.
        let relay = start_relay(
            server.addr(),
            RelayConfig {
                delay: Duration::from_millis(15),
                ..Default::default()
            },
        )
        .await;
        let good_url = format!("quic://{}/scene", relay.addr);
        let out = dir.join("good.snerf");
        let (pin, tok) = (server.fingerprint().to_string(), token.clone());
        let good =
            tokio::spawn(async move { fetch(&good_url, &pin, &tok, &out).await.map(|_| out) });

        let frame = |json: &str| {
            let mut b = (json.len() as u32).to_le_bytes().to_vec();
            b.extend_from_slice(json.as_bytes());
            b
        };
        let cases: Vec<(&str, Vec<u8>, bool, u32)> = vec![
            (
                "not JSON",
                frame("this is not json"),
                false,
                code::MALFORMED,
            ),
            (
                "unknown type",
                frame(r#"{"type":"gimme"}"#),
                false,
                code::MALFORMED,
            ),
            (
                "oversized length prefix",
                (100u32 << 20).to_le_bytes().to_vec(),
                false,
                code::TOO_LARGE,
            ),
            (
                "List before Hello",
                encode_frame(&ClientMsg::List { thumbs: false, watch: false }),
                false,
                code::PROTOCOL,
            ),
            (
                "truncated frame",
                {
                    let mut b = frame(r#"{"type":"list"}"#);
                    b.truncate(8);
                    b
                },
                true,
                code::MALFORMED,
            ),
            ("stream closed before Hello", vec![], true, code::PROTOCOL),
            (
                "wrong version",
                frame(&format!(
                    r#"{{"type":"hello","version":99,"token":"{}"}}"#,
                    token
                )),
                false,
                code::VERSION,
            ),
            (
                "duplicate Hello",
                {
                    let mut b = encode_frame(&hello(&token, None));
                    b.extend(encode_frame(&hello(&token, None)));
                    b
                },
                false,
                code::PROTOCOL,
            ),
            (
                "bad asset name",
                encode_frame(&hello(&token, Some("../etc/passwd"))),
                false,
                code::NOT_FOUND,
            ),
            (
                "no such asset",
                encode_frame(&hello(&token, Some("nope"))),
                false,
                code::NOT_FOUND,
            ),
            (
                "inverted have range",
                frame(&format!(
                    r#"{{"type":"hello","version":1,"token":"{}","have":[[5,1]]}}"#,
                    token
                )),
                false,
                code::MALFORMED,
            ),
            (
                "random bytes",
                {
                    let mut r = Rng(99);
                    let mut b = vec![0u8; 300];
                    r.fill(&mut b);
                    b[..4].copy_from_slice(&296u32.to_le_bytes());
                    b
                },
                false,
                code::MALFORMED,
            ),
        ];
        for (name, bytes, finish, want_code) in cases {
            let (c, reason) = close_code_for(&server, bytes, finish).await;
            println!(
                "SECURITY {:<28} -> closed with code {} ({}): {}",
                name,
                c,
                code::name(c),
                reason
            );
            assert_eq!(c, want_code as u64, "{}: {}", name, reason);
        }
        // Garbage UDP at the server port and garbage datagrams from an authenticated client.
        let sock = tokio::net::UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let mut r = Rng(7);
        for i in 0..2000 {
            let mut b = vec![0u8; 1 + (r.below(1400) as usize)];
            r.fill(&mut b);
            if i % 3 == 0 {
                b[0] |= 0xc0; // long-header-looking
            }
            let _ = sock.send_to(&b, server.addr()).await;
        }
        let mut s = open_session(
            server.addr(),
            server.fingerprint(),
            hello(&token, Some("scene")),
            &ClientOptions::default(),
        )
        .await
        .unwrap();
        for _ in 0..500 {
            let mut b = vec![0u8; r.below(60) as usize];
            r.fill(&mut b);
            let _ = s.conn.send_datagram(b.into());
        }
        // Datagrams are best effort and read by their own task: give it time to see some
        // (under load the session could otherwise close first), then check the session lives.
        let t0 = std::time::Instant::now();
        while server.stats().bad_datagrams.load(Ordering::Relaxed) == 0 && t0.elapsed().as_secs() < 20 {
            if t0.elapsed().as_millis() % 500 < 20 {
                for _ in 0..20 {
                    let mut b = vec![0u8; r.below(60) as usize];
                    r.fill(&mut b);
                    let _ = s.conn.send_datagram(b.into());
                }
            }
            tokio::time::sleep(std::time::Duration::from_millis(20)).await;
        }
        // Authenticated List works.
        let l = s.list().await.unwrap();
        assert_eq!(l.len(), 1);
        assert_eq!(l[0].name, "scene");
        s.close();

        let out = good
            .await
            .unwrap()
            .expect("the good client failed while others misbehaved");
        assert!(std::fs::read(&out).unwrap() == want);
        // And the server still serves new clients.
        let out2 = dir.join("after.snerf");
        fetch(&server.url("scene"), server.fingerprint(), &token, &out2)
            .await
            .unwrap();
        assert!(std::fs::read(&out2).unwrap() == want);
    });
    println!(
        "SECURITY server counters: protocol_errors {}, bad datagrams {}",
        server.stats().protocol_errors.load(Ordering::Relaxed),
        server.stats().bad_datagrams.load(Ordering::Relaxed)
    );
    assert!(server.stats().bad_datagrams.load(Ordering::Relaxed) > 0);
    server.shutdown();
}

#[test]
fn no_panic_on_arbitrary_network_bytes() {
    let mut rng = Rng(0x1234_5678);
    let valid: Vec<Vec<u8>> = vec![
        serde_json::to_vec(&ClientMsg::Hello {
            version: 1,
            token: "t".repeat(64),
            asset: Some("scene".into()),
            have: vec![[0, 5], [9, 12]],
            resume_id: Some("ab".repeat(32)),
            pose: Some(Pose::new([1.0, 2.0, 3.0], [0.0, 0.0, -1.0])),
            colour_of: None,
        })
        .unwrap(),
        serde_json::to_vec(&ClientMsg::List { thumbs: false, watch: false }).unwrap(),
        br#"{"type":"welcome","version":1,"asset":{"name":"a","size":100,"chunks":4,"sha256":"0000000000000000000000000000000000000000000000000000000000000000","preamble":"534e4552464153540100000000000000","atlas_blocks":1,"frames":1},"resumed":false}"#.to_vec(),
        br#"{"type":"listing","assets":[{"name":"a","size":1}]}"#.to_vec(),
        proto::encode_pose(7, &Pose::new([0.0; 3], [1.0, 0.0, 0.0])).to_vec(),
    ];
    let rt = tokio::runtime::Builder::new_current_thread()
        .build()
        .unwrap();
    let n = 200_000;
    let t0 = std::time::Instant::now();
    let mut accepted = 0usize;
    for i in 0..n {
        let mut b = if i % 2 == 0 {
            let mut b = vec![0u8; rng.below(200) as usize];
            rng.fill(&mut b);
            b
        } else {
            let mut b = valid[rng.below(valid.len() as u64) as usize].clone();
            for _ in 0..1 + rng.below(4) {
                if b.is_empty() {
                    break;
                }
                let j = rng.below(b.len() as u64) as usize;
                match rng.below(3) {
                    0 => b[j] = rng.next() as u8,
                    1 => {
                        b.remove(j);
                    }
                    _ => b.insert(j, rng.next() as u8),
                }
            }
            b
        };
        if i % 7 == 0 && b.len() >= 4 {
            let len = (b.len() - 4) as u32;
            b[..4].copy_from_slice(&len.to_le_bytes());
        }
        let r = std::panic::catch_unwind(|| {
            let mut ok = 0;
            ok += proto::decode_client_msg(&b).is_ok() as usize;
            ok += proto::decode_server_msg(&b).is_ok() as usize;
            ok += proto::decode_pose(&b).is_ok() as usize;
            if let Ok(Some((m, _))) = proto::split_frame(&b, 1 << 16) {
                ok += proto::decode_client_msg(m).is_ok() as usize;
            }
            if b.len() >= 16 {
                ok += proto::parse_record_header(&b[..16], 1000, 1 << 20).is_ok() as usize;
            }
            let s = String::from_utf8_lossy(&b);
            ok += snerf_stream::parse_url(&format!("quic://{}", s)).is_ok() as usize;
            ok += snerf_stream::tls::parse_pin(&s).is_ok() as usize;
            if i % 16 == 0 {
                let mut rd: &[u8] = &b;
                let _ = rt.block_on(proto::read_frame(&mut rd, 1 << 16));
            }
            ok
        });
        match r {
            Ok(k) => accepted += k,
            Err(_) => panic!(
                "decoder panicked on input {} ({} bytes): {:?}",
                i,
                b.len(),
                &b[..b.len().min(64)]
            ),
        }
    }
    println!(
        "PROPERTY {} inputs through 7 decoders in {:.1} s without a panic ({} accepted)",
        n,
        t0.elapsed().as_secs_f64(),
        accepted
    );
    assert!(accepted > 0);
}

/// A connection that completes the TLS handshake and then never says Hello. None if the
/// server closed it before the handshake completed.
async fn idle_connection(
    server: &snerf_stream::ServerHandle,
) -> Option<(quinn::Endpoint, quinn::Connection)> {
    connect_raw(
        server.addr(),
        server.fingerprint(),
        &ClientOptions::default(),
    )
    .await
    .ok()
    .map(|(ep, conn, _)| (ep, conn))
}

/// Open `n` idle connections one after another; returns them and the most connections the
/// server reported pending after any one of them.
async fn idle_connections(
    server: &snerf_stream::ServerHandle,
    n: usize,
) -> (Vec<(quinn::Endpoint, quinn::Connection)>, u64) {
    let (mut idle, mut peak) = (Vec::new(), 0);
    for _ in 0..n {
        idle.extend(idle_connection(server).await);
        peak = peak.max(server.stats().pending.load(Ordering::Relaxed));
    }
    (idle, peak)
}

fn close_code(e: &quinn::ConnectionError) -> Option<u64> {
    match e {
        quinn::ConnectionError::ApplicationClosed(c) => Some(c.error_code.into_inner()),
        _ => None,
    }
}

#[test]
fn idle_unauthenticated_connections_cannot_lock_out_a_client() {
    let _g = serial();
    let (dir, server, want) = setup("idle-flood");
    let limits = snerf_stream::Limits::default();
    let rt = runtime();
    rt.block_on(async {
        // 70 idle connections from 127.0.0.1, more than `max_clients` (64) and than the
        // per-address pending cap (32).
        let (idle, peak) = idle_connections(&server, 70).await;
        assert!(
            peak <= limits.max_pending_per_ip as u64,
            "{} pending from one address",
            peak
        );
        // And the attacker keeps opening more while the real client (same address) fetches.
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let attacker = {
            let (addr, pin, stop) = (
                server.addr(),
                server.fingerprint().to_string(),
                stop.clone(),
            );
            tokio::spawn(async move {
                let mut held = Vec::new();
                while !stop.load(Ordering::Relaxed) {
                    if let Ok(c) = connect_raw(addr, &pin, &ClientOptions::default()).await {
                        held.push(c);
                    }
                    tokio::time::sleep(Duration::from_millis(25)).await;
                }
                held.len()
            })
        };
        let out = dir.join("real.snerf");
        let t0 = Instant::now();
        let r = fetch(
            &server.url("scene"),
            server.fingerprint(),
            server.token(),
            &out,
        )
        .await;
        let took = t0.elapsed();
        stop.store(true, Ordering::Relaxed);
        let more = attacker.await.unwrap();
        r.expect("an authenticated fetch failed under an idle-connection flood");
        assert!(std::fs::read(&out).unwrap() == want);
        println!(
            "SECURITY idle flood: {} idle connections + {} more during the fetch; fetch took {:?}",
            idle.len(),
            more,
            took
        );
        // Every idle connection is closed: the oldest to make room (BUSY), the rest once
        // `auth_timeout` passes (TIMEOUT). Generous bound: auth_timeout is 3 s. (How many
        // of each depends on how fast the machine opened them, so only both are required.)
        let mut by_code = std::collections::BTreeMap::new();
        for (_ep, conn) in &idle {
            let e = tokio::time::timeout(Duration::from_secs(30), conn.closed())
                .await
                .expect("an idle unauthenticated connection was kept open");
            *by_code.entry(close_code(&e)).or_insert(0) += 1;
        }
        println!("SECURITY idle connections closed, by code: {:?}", by_code);
        assert!(by_code.contains_key(&Some(code::BUSY as u64)));
        assert!(by_code
            .keys()
            .all(|c| *c == Some(code::BUSY as u64) || *c == Some(code::TIMEOUT as u64)));
    });
    let st = server.stats();
    assert!(st.pending_evicted.load(Ordering::Relaxed) > 0);
    assert_eq!(st.refused_busy.load(Ordering::Relaxed), 0);
    server.shutdown();
}

#[test]
fn a_full_pending_table_drops_its_oldest_and_validates_addresses() {
    let _g = serial();
    let dir = TempDir::new("pending-total");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let want = write_asset(&static_asset(32, 8, 0.9, 22), &assets, "scene");
    let limits = snerf_stream::Limits {
        max_pending: 6,
        max_pending_per_ip: 100,
        ..Default::default()
    };
    let server = start_server(&assets, &dir.join("state"), limits);
    let rt = runtime();
    rt.block_on(async {
        let (idle, peak) = idle_connections(&server, 20).await;
        assert!(peak <= 6, "{} pending", peak);
        let out = dir.join("real.snerf");
        fetch(
            &server.url("scene"),
            server.fingerprint(),
            server.token(),
            &out,
        )
        .await
        .unwrap();
        assert!(std::fs::read(&out).unwrap() == want);
        // The oldest made room (or, on a very slow machine, timed out first).
        let first = tokio::time::timeout(Duration::from_secs(30), idle[0].1.closed())
            .await
            .unwrap();
        let c = close_code(&first);
        assert!(
            c == Some(code::BUSY as u64) || c == Some(code::TIMEOUT as u64),
            "{}",
            first
        );
    });
    let st = server.stats();
    println!(
        "SECURITY pending table of 6: {} evicted, {} Retry packets",
        st.pending_evicted.load(Ordering::Relaxed),
        st.retries.load(Ordering::Relaxed)
    );
    assert!(st.pending_evicted.load(Ordering::Relaxed) > 0);
    // From half full on, new connections had to prove their address first.
    assert!(st.retries.load(Ordering::Relaxed) > 0);
    server.shutdown();
}

const SERVE_CHILD: &str = "SNERF_TEST_SERVE_CHILD";

/// Child half of `serve_prints_data_on_stdout_and_the_banner_on_stderr` (does nothing unless
/// that test runs it): `serve_blocking_with` as `snerf serve --json` uses it, printing one
/// JSON line from `on_ready`.
#[test]
fn serve_child_process() {
    let Some(assets) = std::env::var_os(SERVE_CHILD) else {
        return;
    };
    let mut o = ServeOptions::new(assets, "127.0.0.1:0".parse().unwrap());
    o.state_dir = std::env::var_os("SNERF_TEST_SERVE_STATE").map(PathBuf::from);
    o.token_file = std::env::var_os("SNERF_TEST_SERVE_TOKEN_FILE").map(PathBuf::from);
    snerf_stream::serve_blocking_with(o, |h| {
        let token = (!h.token_from_file()).then(|| h.token().to_string());
        println!(
            "{}",
            serde_json::json!({
                "command": "serve",
                "address": h.addr().to_string(),
                "fingerprint": h.fingerprint(),
                "url": h.url(""),
                "token": token,
            })
        );
    })
    .unwrap();
}

/// Run `serve_child_process` in a child process; once its JSON line is out, fetch `scene`
/// through it, kill it and return (JSON, all of stdout, all of stderr).
fn run_serve_child(
    assets: &Path,
    state: &Path,
    token_file: Option<&Path>,
    out: &Path,
) -> (serde_json::Value, String, String) {
    let mut cmd = std::process::Command::new(std::env::current_exe().unwrap());
    cmd.args([
        "serve_child_process",
        "--exact",
        "--nocapture",
        "--test-threads=1",
    ])
    .env(SERVE_CHILD, assets)
    .env("SNERF_TEST_SERVE_STATE", state)
    .stdout(std::process::Stdio::piped())
    .stderr(std::process::Stdio::piped());
    if let Some(t) = token_file {
        cmd.env("SNERF_TEST_SERVE_TOKEN_FILE", t);
    }
    let mut child = cmd.spawn().unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let err = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    let (tx, rx) = std::sync::mpsc::channel();
    let stdout = std::io::BufReader::new(child.stdout.take().unwrap());
    let lines = std::thread::spawn(move || {
        let mut all = String::new();
        for l in stdout.lines().map_while(Result::ok) {
            // libtest's "test serve_child_process ... " precedes it on the same line.
            if let Some(i) = l.find("{\"") {
                let _ = tx.send(l[i..].to_string());
            }
            all.push_str(&l);
            all.push('\n');
        }
        all
    });
    let line = rx.recv_timeout(Duration::from_secs(120));
    let fetched = line.as_ref().ok().map(|l| {
        let v: serde_json::Value = serde_json::from_str(l).unwrap();
        let token = match token_file {
            Some(t) => std::fs::read_to_string(t).unwrap().trim().to_string(),
            None => v["token"].as_str().unwrap().to_string(),
        };
        let url = format!("{}scene", v["url"].as_str().unwrap());
        (
            v.clone(),
            snerf_stream::fetch_blocking(&url, v["fingerprint"].as_str().unwrap(), &token, out),
        )
    });
    let _ = child.kill();
    let _ = child.wait();
    let (stdout, stderr) = (lines.join().unwrap(), err.join().unwrap());
    let Some((v, r)) = fetched else {
        panic!(
            "the server printed no JSON line\nstdout:\n{}\nstderr:\n{}",
            stdout, stderr
        );
    };
    r.unwrap();
    (v, stdout, stderr)
}

#[test]
fn serve_prints_data_on_stdout_and_the_banner_on_stderr() {
    let dir = TempDir::new("serve-output");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let want = write_asset(&static_asset(32, 8, 0.9, 23), &assets, "scene");

    // Generated token: the banner shows it, on stderr; stdout carries only the JSON.
    let out = dir.join("a.snerf");
    let (v, stdout, stderr) = run_serve_child(&assets, &dir.join("state1"), None, &out);
    assert!(std::fs::read(&out).unwrap() == want);
    let token = std::fs::read_to_string(dir.join("state1").join("token")).unwrap();
    let token = token.trim();
    assert_eq!(v["token"], token);
    assert_eq!(v["command"], "serve");
    assert!(stderr.contains("snerf serve: serving"), "{}", stderr);
    assert!(
        stderr.contains(v["fingerprint"].as_str().unwrap()),
        "{}",
        stderr
    );
    assert!(
        stderr.contains(&format!("token (--token):     {}", token)),
        "{}",
        stderr
    );
    assert!(
        !stdout.contains("snerf serve") && !stdout.contains("fingerprint (--pin)"),
        "{}",
        stdout
    );
    assert_eq!(stdout.matches("{\"").count(), 1, "{}", stdout);

    // Token from the user's file: never printed, anywhere.
    let tf = dir.join("my-token");
    let secret = "user-supplied-secret-token-0123456789";
    std::fs::write(&tf, format!("{}\n", secret)).unwrap();
    let out = dir.join("b.snerf");
    let (v, stdout, stderr) = run_serve_child(&assets, &dir.join("state2"), Some(&tf), &out);
    assert!(std::fs::read(&out).unwrap() == want);
    println!("SERVE banner with --token-file (stderr):\n{}", stderr);
    assert!(v["token"].is_null());
    assert!(!stdout.contains(secret) && !stderr.contains(secret));
    assert!(
        stderr.contains(&format!("token (--token):     from {}", tf.display())),
        "{}",
        stderr
    );
    assert!(!stdout.contains("snerf serve"), "{}", stdout);
}

/// After the whole asset is sent the server lingers for the client to close; a List in that
/// window is still answered (it used to go unread until the linger closed the connection).
#[test]
fn list_is_answered_after_the_transfer_completes() {
    let (_dir, server, _) = setup("linger");
    let rt = runtime();
    rt.block_on(async {
        let mut s = open_session(
            server.addr(),
            server.fingerprint(),
            hello(server.token(), Some("scene")),
            &ClientOptions::default(),
        )
        .await
        .unwrap();
        // QUIC acknowledges stream data the application has not read yet, so the small
        // asset completes without this client reading it.
        let st = server.stats();
        let t0 = Instant::now();
        while !(st.streams_started.load(Ordering::Relaxed) > 0
            && st.streams_completed.load(Ordering::Relaxed) == st.streams_started.load(Ordering::Relaxed))
        {
            assert!(t0.elapsed() < Duration::from_secs(30), "the transfer never completed");
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        tokio::time::sleep(Duration::from_millis(300)).await;
        let l = tokio::time::timeout(Duration::from_secs(5), s.list())
            .await
            .expect("List went unanswered after the transfer completed")
            .unwrap();
        assert_eq!(l[0].name, "scene");
        s.close();
    });
    server.shutdown();
}
