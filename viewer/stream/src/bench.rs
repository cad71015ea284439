//! `snerf bench stream ASSET`: serve one file on 127.0.0.1, then measure side by side a QUIC
//! fetch against a plain TCP copy of the same bytes, and the time to the first renderable
//! view (header + grids + MLP, then every block in an orbit camera's view cone).

use anyhow::{anyhow, ensure, Context, Result};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::client::{fetch, ClientOptions};
use crate::live::LiveAsset;
use crate::plan::{ServedAsset, View};
use crate::proto::Pose;
use crate::server::{spawn, ServeOptions};

#[derive(Clone, Debug)]
pub struct BenchOptions {
    /// Rounds of each measurement; the best is reported.
    pub rounds: usize,
    /// Field of view (degrees) of the first-view camera.
    pub fov_deg: f32,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            rounds: 3,
            fov_deg: 60.0,
        }
    }
}

#[derive(Clone, Debug)]
pub struct BenchReport {
    pub size: u64,
    pub quic_transfer: Duration,
    pub quic_total: Duration,
    pub tcp: Duration,
    pub renderable: Duration,
    pub first_view: Duration,
    pub first_view_blocks: usize,
    pub blocks: usize,
    pub first_view_fraction: f64,
    pub first_view_ideal_fraction: f64,
    pub complete: Duration,
}

impl std::fmt::Display for BenchReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let mb = |d: Duration| self.size as f64 / (1 << 20) as f64 / d.as_secs_f64();
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        writeln!(
            f,
            "asset: {:.2} MiB, {} blocks",
            self.size as f64 / (1 << 20) as f64,
            self.blocks
        )?;
        writeln!(
            f,
            "loopback fetch: QUIC {:.1} ms ({:.0} MiB/s; {:.1} ms with file write + verify), TCP copy {:.1} ms ({:.0} MiB/s): QUIC/TCP = {:.0}%",
            ms(self.quic_transfer),
            mb(self.quic_transfer),
            ms(self.quic_total),
            ms(self.tcp),
            mb(self.tcp),
            100.0 * self.tcp.as_secs_f64() / self.quic_transfer.as_secs_f64()
        )?;
        write!(
            f,
            "first view: renderable after {:.1} ms; its {} blocks after {:.1} ms with {:.1}% of the file (ideal {:.1}%); complete after {:.1} ms",
            ms(self.renderable),
            self.first_view_blocks,
            ms(self.first_view),
            100.0 * self.first_view_fraction,
            100.0 * self.first_view_ideal_fraction,
            ms(self.complete)
        )
    }
}

struct Scratch(PathBuf);
impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn tcp_copy(bytes: Arc<Vec<u8>>, out: &Path) -> Result<Duration> {
    let l = std::net::TcpListener::bind("127.0.0.1:0")?;
    let addr = l.local_addr()?;
    let srv = std::thread::spawn(move || -> std::io::Result<()> {
        let (mut s, _) = l.accept()?;
        s.write_all(&bytes)
    });
    let t0 = Instant::now();
    let mut s = std::net::TcpStream::connect(addr)?;
    let mut f = std::io::BufWriter::with_capacity(1 << 20, std::fs::File::create(out)?);
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = s.read(&mut buf)?;
        if n == 0 {
            break;
        }
        f.write_all(&buf[..n])?;
    }
    f.flush()?;
    let t = t0.elapsed();
    srv.join().map_err(|_| anyhow!("TCP sender panicked"))??;
    Ok(t)
}

/// Run the benchmark on one `.snerf` file.
pub fn run(asset: &Path, opts: &BenchOptions) -> Result<BenchReport> {
    let bytes = Arc::new(
        std::fs::read(asset).with_context(|| format!("{}: cannot read", asset.display()))?,
    );
    let served = ServedAsset::from_bytes("bench", asset, bytes.to_vec())
        .map_err(|e| anyhow!("{}: {:#}", asset.display(), e))?;
    let scratch =
        Scratch(std::env::temp_dir().join(format!("snerf-bench-stream-{}", std::process::id())));
    std::fs::create_dir_all(&scratch.0)?;
    let mut so = ServeOptions::new(asset, "127.0.0.1:0".parse()?);
    so.state_dir = Some(scratch.0.join("state"));
    so.quiet = true;
    let server = spawn(so)?;
    let name = crate::server::asset_name(asset);
    let url = server.url(&name);
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?;
    let out = scratch.0.join("fetched.snerf");
    let (mut best_q, mut best_total, mut best_t) = (Duration::MAX, Duration::MAX, Duration::MAX);
    for _ in 0..opts.rounds.max(1) {
        let _ = std::fs::remove_file(&out);
        let st = rt.block_on(fetch(&url, server.fingerprint(), server.token(), &out))?;
        ensure!(
            std::fs::read(&out)? == *bytes,
            "fetched file differs from {}",
            asset.display()
        );
        best_q = best_q.min(st.transfer);
        best_total = best_total.min(st.elapsed);
        best_t = best_t.min(tcp_copy(bytes.clone(), &scratch.0.join("tcp.bin"))?);
    }
    // First view: camera 0 of the preview orbit.
    let cam = snerf_asset::orbit(&served.header, 8, 0, 640, 480, opts.fov_deg);
    let eye = [cam.c2w[0][3], cam.c2w[1][3], cam.c2w[2][3]];
    let forward = [-cam.c2w[0][2], -cam.c2w[1][2], -cam.c2w[2][2]];
    let pose = Pose {
        eye,
        forward,
        time: served.header.frame_time(0),
        fov_deg: opts.fov_deg * 1.25,
    };
    let view = View::new(&served, &pose);
    let meta: u64 = served.meta.iter().map(|&i| served.record_len(i)).sum();
    let mut in_view = std::collections::HashSet::new();
    let mut ideal = meta;
    for b in &served.blks {
        if served.in_view(b, &view) {
            let p = &served.bytes[served.ranges[b.chunk as usize].start + 12..];
            let first = u32::from_le_bytes([p[0], p[1], p[2], p[3]]);
            let count = u32::from_le_bytes([p[4], p[5], p[6], p[7]]);
            in_view.extend(first..first + count);
            ideal += served.record_len(b.chunk);
        }
    }
    let n_view = in_view.len();
    let live = LiveAsset::connect_with(
        &url,
        server.fingerprint(),
        server.token(),
        ClientOptions {
            pose: Some(pose),
            ..Default::default()
        },
    )?;
    let (mut renderable, mut first_view, mut frac) = (None, None, 1.0);
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(300) {
        if renderable.is_none() && live.with_asset(|_| ()).is_some() {
            renderable = live.time_to_renderable();
        }
        for b in live.take_new_blocks() {
            in_view.remove(&b);
            if in_view.is_empty() && first_view.is_none() {
                first_view = Some(live.elapsed());
                frac = live.bytes_received() as f64 / bytes.len() as f64;
            }
        }
        if live.is_complete() {
            break;
        }
        if let Some(e) = live.error() {
            return Err(anyhow!(e));
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    live.wait(Duration::from_secs(1))?;
    let renderable = renderable.or(live.time_to_renderable()).unwrap_or_default();
    let complete = live.time_to_complete().unwrap_or_default();
    // The poll loop may notice the last view block after the stream completed.
    let first_view = first_view.map(|t| t.min(complete));
    server.shutdown();
    Ok(BenchReport {
        size: bytes.len() as u64,
        quic_transfer: best_q,
        quic_total: best_total,
        tcp: best_t,
        renderable,
        first_view: first_view.unwrap_or(renderable),
        first_view_blocks: n_view,
        blocks: served.blks.len(),
        first_view_fraction: if n_view == 0 {
            meta as f64 / bytes.len() as f64
        } else {
            frac
        },
        first_view_ideal_fraction: ideal as f64 / bytes.len() as f64,
        complete,
    })
}
