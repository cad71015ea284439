//! Test support: synthetic assets, temp dirs, a server on 127.0.0.1:0, a plain TCP copy to
//! compare throughput with, and a lossy user-space UDP relay (drop, delay, reorder, cut).
#![allow(dead_code)]

use snerf_asset::{Asset, AssetBuilder, Header, Keyframe, Kind, ViewMlp};
use snerf_stream::{Limits, ServeOptions, ServerHandle};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

/// Timing-sensitive tests take this so they do not run alongside each other.
pub fn serial() -> MutexGuard<'static, ()> {
    static M: Mutex<()> = Mutex::new(());
    M.lock().unwrap_or_else(|e| e.into_inner())
}

pub struct Rng(pub u64);
impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    pub fn below(&mut self, n: u64) -> u64 {
        if n == 0 {
            0
        } else {
            self.next() % n
        }
    }
    pub fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn fill(&mut self, b: &mut [u8]) {
        for c in b.chunks_mut(8) {
            let v = self.next().to_le_bytes();
            c.copy_from_slice(&v[..c.len()]);
        }
    }
}

/// A fresh directory under the system temp dir, removed on drop when the test passes and
/// kept (its path printed) when it fails.
pub struct TempDir(snerf_files::ScratchDir);
impl TempDir {
    pub fn new(name: &str) -> TempDir {
        static N: AtomicU64 = AtomicU64::new(0);
        let name = format!("{}-{name}", N.fetch_add(1, Ordering::Relaxed));
        TempDir(snerf_files::ScratchDir::new("snerf-stream", &name).unwrap())
    }
    pub fn path(&self) -> &Path {
        &self.0
    }
    pub fn join(&self, s: &str) -> PathBuf {
        self.0.join(s)
    }
}

pub fn mlp() -> ViewMlp {
    let mut m = ViewMlp::zeros();
    for (i, w) in m.w1.iter_mut().enumerate() {
        *w = ((i * 7919) % 13) as f32 * 0.01 - 0.06;
    }
    m.b3 = vec![0.01, -0.02, 0.03];
    m
}

fn cell_centre(c: usize, g: usize) -> f32 {
    -1.0 + (c as f32 + 0.5) * 2.0 / g as f32
}

/// Static object asset: random blocks in every cell whose centre is within `radius` of the
/// grid centre. res 96 / block 8 / radius 0.95 -> ~780 blocks, ~6 MB.
pub fn static_asset(res: u32, block: u32, radius: f32, seed: u64) -> Asset {
    let mut h = Header::new(Kind::Object, res, block);
    h.background = [0.0; 3];
    let g = h.grid_dim();
    let bb = h.block_bytes();
    let mut b = AssetBuilder::new(h, mlp()).unwrap();
    let mut rng = Rng(seed | 1);
    let mut buf = vec![0u8; bb];
    for z in 0..g {
        for y in 0..g {
            for x in 0..g {
                let p = [cell_centre(x, g), cell_centre(y, g), cell_centre(z, g)];
                if (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() < radius {
                    rng.fill(&mut buf);
                    b.set_block(0, [x, y, z], &buf).unwrap();
                }
            }
        }
    }
    b.finish().unwrap()
}

/// A 4-keyframe asset with motion (FORMAT.md "Motion"): keyframe 1 is the reference, and
/// every cell of keyframes 0, 2 and 3 shows it moved by its own quarter-voxel offset.
#[allow(dead_code)]
pub fn motion_asset() -> Asset {
    let mut a = dynamic_asset(16, 8, 0.9, 4, 41);
    a.header.motion_ref = Some(1);
    let n = a.grids[1].len();
    for (f, d) in [(0, [1.5f32, -0.75, 0.25]), (2, [-2.0, 1.0, 0.5]), (3, [0.75, 0.5, -1.25])] {
        // frame 3 moves three cells of eight, the rest empty: a grid the file stores sparsely
        a.grids[f] = (0..n).map(|c| if f != 3 || c % 3 == 0 { snerf_asset::motion::motion_entry(d) } else { snerf_asset::EMPTY }).collect();
    }
    a.validate().unwrap();
    let bytes = a.to_bytes();
    let tags: Vec<[u8; 4]> = snerf_asset::chunk::chunks(&bytes).unwrap().iter().map(|c| c.tag).collect();
    assert!(tags.contains(&snerf_asset::chunk::TAG_SGRD) && tags.contains(&snerf_asset::chunk::TAG_GRID), "a sparse and a dense grid");
    a
}

/// Dynamic asset with `frames` keyframes (times 0,1,2,..): frame 0 as `static_asset`; in each
/// later frame a third of the cells change (new blocks), the rest are shared.
pub fn dynamic_asset(res: u32, block: u32, radius: f32, frames: usize, seed: u64) -> Asset {
    let mut h = Header::new(Kind::Object, res, block);
    h.background = [0.0; 3];
    h.time_range = Some([0.0, (frames - 1) as f32]);
    h.frames = Some((0..frames).map(|f| Keyframe { time: f as f32 }).collect());
    let g = h.grid_dim();
    let bb = h.block_bytes();
    let mut b = AssetBuilder::new(h, mlp()).unwrap();
    let mut rng = Rng(seed | 1);
    let mut prev: std::collections::HashMap<[usize; 3], Vec<u8>> = Default::default();
    for f in 0..frames {
        for z in 0..g {
            for y in 0..g {
                for x in 0..g {
                    let p = [cell_centre(x, g), cell_centre(y, g), cell_centre(z, g)];
                    if (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() >= radius {
                        continue;
                    }
                    let changes = f == 0 || (x + y + z) % 3 == f % 3;
                    let e = prev.entry([x, y, z]).or_insert_with(|| vec![0u8; bb]);
                    if changes {
                        rng.fill(e);
                    }
                    b.set_block(f, [x, y, z], e).unwrap();
                }
            }
        }
    }
    b.finish().unwrap()
}

/// Write `asset` as `dir/name.snerf`; returns the file bytes.
pub fn write_asset(asset: &Asset, dir: &Path, name: &str) -> Vec<u8> {
    let p = dir.join(format!("{}.snerf", name));
    asset.write(&p).unwrap();
    std::fs::read(&p).unwrap()
}

pub fn start_server(assets: &Path, state: &Path, limits: Limits) -> ServerHandle {
    let mut o = ServeOptions::new(assets, "127.0.0.1:0".parse().unwrap());
    o.state_dir = Some(state.to_path_buf());
    o.limits = limits;
    o.quiet = std::env::var_os("SNERF_STREAM_LOG").is_none();
    snerf_stream::spawn(o).unwrap()
}

pub fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap()
}

/// Plain TCP copy of `bytes` over loopback into `out` (buffered file writes, like the QUIC
/// client's .part log). Returns connect-to-EOF time.
pub fn tcp_copy(bytes: Arc<Vec<u8>>, out: &Path) -> Duration {
    use std::io::{Read, Write};
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = l.local_addr().unwrap();
    let srv = std::thread::spawn(move || {
        let (mut s, _) = l.accept().unwrap();
        s.write_all(&bytes).unwrap();
    });
    let t0 = Instant::now();
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    let mut f = std::io::BufWriter::with_capacity(1 << 20, std::fs::File::create(out).unwrap());
    let mut buf = vec![0u8; 1 << 16];
    loop {
        let n = s.read(&mut buf).unwrap();
        if n == 0 {
            break;
        }
        f.write_all(&buf[..n]).unwrap();
    }
    f.flush().unwrap();
    let t = t0.elapsed();
    srv.join().unwrap();
    t
}

#[derive(Clone, Debug)]
pub struct RelayConfig {
    /// Probability of dropping each datagram (each direction).
    pub drop: f64,
    /// One-way delay added to every datagram.
    pub delay: Duration,
    /// Probability that a datagram gets an extra 0..reorder_extra delay (so later ones overtake it).
    pub reorder: f64,
    pub reorder_extra: Duration,
    /// Stop forwarding anything once this many server->client bytes have passed.
    pub cut_after_s2c: Option<u64>,
    /// Largest datagram forwarded (a path MTU); larger ones are dropped like on a real path.
    pub max_datagram: usize,
    pub seed: u64,
}

impl Default for RelayConfig {
    fn default() -> Self {
        RelayConfig {
            drop: 0.0,
            delay: Duration::ZERO,
            reorder: 0.0,
            reorder_extra: Duration::ZERO,
            cut_after_s2c: None,
            max_datagram: 1472,
            seed: 0x5eed,
        }
    }
}

/// A UDP relay on 127.0.0.1 between one client and the server.
pub struct Relay {
    pub addr: SocketAddr,
    pub s2c_bytes: Arc<AtomicU64>,
    pub dropped: Arc<AtomicU64>,
    pub forwarded: Arc<AtomicU64>,
    pub cut: Arc<AtomicBool>,
    tasks: Vec<tokio::task::JoinHandle<()>>,
}

impl Drop for Relay {
    fn drop(&mut self) {
        for t in &self.tasks {
            t.abort();
        }
    }
}

/// Start a relay on the current tokio runtime.
pub async fn start_relay(server: SocketAddr, cfg: RelayConfig) -> Relay {
    use tokio::net::UdpSocket;
    let front = Arc::new(UdpSocket::bind("127.0.0.1:0").await.unwrap());
    let back = Arc::new(UdpSocket::bind("127.0.0.1:0").await.unwrap());
    back.connect(server).await.unwrap();
    let addr = front.local_addr().unwrap();
    let client: Arc<Mutex<Option<SocketAddr>>> = Arc::new(Mutex::new(None));
    let s2c_bytes = Arc::new(AtomicU64::new(0));
    let dropped = Arc::new(AtomicU64::new(0));
    let forwarded = Arc::new(AtomicU64::new(0));
    let cut = Arc::new(AtomicBool::new(false));
    let rng = Arc::new(Mutex::new(Rng(cfg.seed | 1)));
    // Decide the fate of one datagram: None = drop, Some(delay).
    let fate = {
        let (cfg, rng, dropped, cut) = (cfg.clone(), rng.clone(), dropped.clone(), cut.clone());
        move |len: usize| -> Option<Duration> {
            let mut r = rng.lock().unwrap();
            if cut.load(Ordering::Relaxed) || len > cfg.max_datagram || r.unit() < cfg.drop {
                dropped.fetch_add(1, Ordering::Relaxed);
                return None;
            }
            let mut d = cfg.delay;
            if r.unit() < cfg.reorder {
                d += cfg.reorder_extra.mul_f64(r.unit());
            }
            Some(d)
        }
    };
    let c2s = {
        let (front, back, client, fate, fwd) = (
            front.clone(),
            back.clone(),
            client.clone(),
            fate.clone(),
            forwarded.clone(),
        );
        tokio::spawn(async move {
            let mut buf = vec![0u8; 65536];
            loop {
                let Ok((n, from)) = front.recv_from(&mut buf).await else {
                    break;
                };
                *client.lock().unwrap() = Some(from);
                if let Some(d) = fate(n) {
                    let (pkt, back, fwd) = (buf[..n].to_vec(), back.clone(), fwd.clone());
                    tokio::spawn(async move {
                        if !d.is_zero() {
                            tokio::time::sleep(d).await;
                        }
                        let _ = back.send(&pkt).await;
                        fwd.fetch_add(1, Ordering::Relaxed);
                    });
                }
            }
        })
    };
    let s2c = {
        let (front, back, client, fate, fwd, bytes, cut) = (
            front.clone(),
            back.clone(),
            client.clone(),
            fate.clone(),
            forwarded.clone(),
            s2c_bytes.clone(),
            cut.clone(),
        );
        let cut_after = cfg.cut_after_s2c;
        tokio::spawn(async move {
            let mut buf = vec![0u8; 65536];
            loop {
                let Ok(n) = back.recv(&mut buf).await else {
                    break;
                };
                let total = bytes.fetch_add(n as u64, Ordering::Relaxed) + n as u64;
                if cut_after.is_some_and(|c| total > c) {
                    cut.store(true, Ordering::Relaxed);
                }
                let Some(to) = *client.lock().unwrap() else {
                    continue;
                };
                if let Some(d) = fate(n) {
                    let (pkt, front, fwd) = (buf[..n].to_vec(), front.clone(), fwd.clone());
                    tokio::spawn(async move {
                        if !d.is_zero() {
                            tokio::time::sleep(d).await;
                        }
                        let _ = front.send_to(&pkt, to).await;
                        fwd.fetch_add(1, Ordering::Relaxed);
                    });
                }
            }
        })
    };
    Relay {
        addr,
        s2c_bytes,
        dropped,
        forwarded,
        cut,
        tasks: vec![c2s, s2c],
    }
}

pub fn mb(bytes: u64) -> f64 {
    bytes as f64 / (1 << 20) as f64
}

/// A multi-style asset of two styles, `warm` and `cold`, on one geometry (`static_asset`):
/// the second's colour and features are the first's inverted.
#[allow(dead_code)]
pub fn two_styles() -> snerf_asset::LayeredAsset {
    let a = static_asset(48, 8, 0.9, 7);
    let mut b = a.clone();
    for v in b.atlas.chunks_exact_mut(8) {
        for c in &mut v[1..] {
            *c = 255 - *c;
        }
    }
    let style = |name: &str| snerf_asset::StyleInfo { name: name.into(), source: Some(format!("painting:{name}")), swatch: [0.5, 0.5, 0.5] };
    snerf_asset::LayeredAsset::new(vec![style("warm"), style("cold")], vec![a, b]).unwrap()
}
