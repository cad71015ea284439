//! The `snerf serve` side: a quinn endpoint that authenticates clients by token and streams
//! assets chunk by chunk, small parts first, then blocks in priority order for each client's
//! pose. Each client is its own task; every asset file is held once in memory and shared
//! (zero-copy `Bytes` slices) by all clients; QUIC flow control plus a per-client send window
//! bound what a slow client can pin, and a stall timeout drops clients that stop reading.

use anyhow::{anyhow, bail, Context, Result};
use bytes::Bytes;
use quinn::{Endpoint, VarInt};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime};
use tokio::sync::{watch, OwnedSemaphorePermit, Semaphore};
use tokio::task::JoinSet;
use tokio::time::Instant;

use crate::cache::AssetCache;
use crate::conn::{Conn, Recv, Send};
use crate::pending::{Pending, PendingTable};
use crate::plan::{ServedAsset, View};
use crate::proto::{
    code, decode_client_msg, decode_pose, encode_frame, read_frame, valid_asset_name, ClientMsg,
    FrameError, ListEntry, Pose, ServerMsg, PROTOCOL_VERSION,
};
use crate::tls;
pub use crate::stats::{SentBatch, ServerStats};

/// Server limits (most have CLI flags in `snerf serve`).
#[derive(Clone, Debug)]
pub struct Limits {
    /// Simultaneous authenticated clients (a Hello with a valid token). While all are taken,
    /// new connections are refused at the QUIC level (CONNECTION_REFUSED); one that wins a
    /// race for the last slot is closed with BUSY after its Hello. Connections that have not
    /// authenticated never take a slot (see `max_pending`).
    pub max_clients: usize,
    /// Largest control message accepted (bytes).
    pub max_message: usize,
    /// QUIC idle timeout: a peer silent this long is dropped.
    pub idle_timeout: Duration,
    /// Time from a connection's first packet to a valid Hello (TLS handshake, control stream,
    /// Hello): kept short because unauthenticated connections cost the server resources.
    pub auth_timeout: Duration,
    /// Time from the end of the TLS handshake to Hello. `auth_timeout` applies as well, so
    /// this matters only when set shorter than that.
    pub hello_timeout: Duration,
    /// Unauthenticated connections at a time from one source address (IPv6: one /64). At the
    /// cap a new one closes the oldest of that address (BUSY), so an idle flood from an
    /// address cannot lock out a legitimate client at the same address. Large enough for a
    /// burst of legitimate clients starting at once behind one NAT (each is pending only for
    /// its handshake); an attacker then needs `max_pending / this` addresses to fill the table.
    pub max_pending_per_ip: usize,
    /// Unauthenticated connections at a time, all addresses; at the cap a new one closes the
    /// oldest. From half this, new addresses must first pass a QUIC Retry (prove they receive
    /// our packets), so spoofed source addresses cannot fill the table.
    pub max_pending: usize,
    /// Loaded assets kept in memory, by file size; least recently used dropped first. An
    /// asset larger than this is served without being kept.
    pub cache_bytes: u64,
    /// A client whose streams accept no data for this long is dropped (it stopped reading).
    pub stall_timeout: Duration,
    /// Per-client send budget: bytes buffered for one client, unacknowledged (QUIC send window).
    pub send_budget: u64,
    /// Unidirectional data streams in flight per client.
    pub max_streams: usize,
    /// Target bytes per data stream (several blocks per stream).
    pub batch_bytes: usize,
    /// Congestion controller for the data the server sends.
    pub congestion: Congestion,
    /// After everything is sent and acknowledged, close the connection if the client has not
    /// done so within this time.
    pub linger: Duration,
    /// Per-client pacing of block data, bytes per second (None: as fast as QUIC allows), so
    /// one client cannot take a whole uplink; also how tests stretch a stream in time.
    pub max_rate: Option<f64>,
    /// The web viewer's generated certificate is replaced this often (it is valid 13 days;
    /// browsers accept at most 14 for pinned hashes). Default 12 days.
    pub web_cert_rotate: Duration,
    /// Record each batch of blocks committed to a stream, with the pose it was ordered for,
    /// in `ServerStats::send_log` (what tests check the send order on).
    pub log_sends: bool,
    /// The web page's server (`page.rs`): time allowed for a request head, counted from the
    /// connection's accept (TLS handshake included) or from the end of the previous response
    /// on a kept-alive connection. What stops a client that trickles its header (slowloris)
    /// or opens a connection and says nothing.
    pub page_head_timeout: Duration,
    /// Time allowed to hand one response to the kernel: a client that stops reading is
    /// dropped.
    pub page_write_timeout: Duration,
    /// Page connections at a time from one address (IPv6: one /64); at the cap a new one
    /// closes that address's oldest. A browser opens at most 6 per host; this leaves room for
    /// a few headsets behind one NAT.
    pub page_conns_per_ip: usize,
    /// Page connections at a time, all addresses; at the cap a new one closes the oldest.
    pub page_conns: usize,
}

impl Default for Limits {
    fn default() -> Limits {
        Limits {
            max_clients: 64,
            max_message: 64 * 1024,
            idle_timeout: Duration::from_secs(30),
            auth_timeout: Duration::from_secs(3),
            hello_timeout: Duration::from_secs(10),
            max_pending_per_ip: 32,
            max_pending: 256,
            cache_bytes: 1 << 30,
            stall_timeout: Duration::from_secs(30),
            send_budget: 8 << 20,
            max_streams: 8,
            batch_bytes: 256 * 1024,
            linger: Duration::from_secs(10),
            congestion: Congestion::Cubic,
            log_sends: false,
            max_rate: None,
            web_cert_rotate: Duration::from_secs(12 * 86400),
            page_head_timeout: Duration::from_secs(5),
            page_write_timeout: Duration::from_secs(10),
            page_conns_per_ip: 16,
            page_conns: 256,
        }
    }
}

/// Congestion control. Cubic (default) is quinn's standard controller and the fastest on
/// clean paths (loopback: ~190 MB/s vs ~75 MB/s with BBR here). BBR keeps throughput under
/// random (e.g. Wi-Fi) loss, where loss-based Cubic collapses: through a 5%-loss, 50 ms RTT
/// relay a 1.6 MiB fetch took ~1.3 s with BBR and ~18 s with Cubic (tests/faults.rs). quinn
/// marks its BBR experimental.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Congestion {
    Bbr,
    Cubic,
}

impl std::str::FromStr for Congestion {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<Congestion> {
        match s.to_ascii_lowercase().as_str() {
            "bbr" => Ok(Congestion::Bbr),
            "cubic" => Ok(Congestion::Cubic),
            _ => bail!("congestion controller {:?}: use bbr or cubic", s),
        }
    }
}

#[derive(Clone, Debug)]
pub struct ServeOptions {
    /// A directory of `.snerf` files or one file.
    pub path: PathBuf,
    pub listen: SocketAddr,
    /// Where the generated certificate, key and token live (default: see `tls::default_state_dir`).
    pub state_dir: Option<PathBuf>,
    pub cert: Option<PathBuf>,
    pub key: Option<PathBuf>,
    pub token_file: Option<PathBuf>,
    pub limits: Limits,
    /// No per-connection log lines on stderr.
    pub quiet: bool,
    /// Also serve the web viewer: its page over HTTP (TCP) and WebTransport (UDP), both on
    /// this address's port (0: a free port). See `web.rs`.
    pub web: Option<SocketAddr>,
}

impl ServeOptions {
    pub fn new(path: impl Into<PathBuf>, listen: SocketAddr) -> ServeOptions {
        ServeOptions {
            path: path.into(),
            listen,
            state_dir: None,
            cert: None,
            key: None,
            token_file: None,
            limits: Limits::default(),
            quiet: false,
            web: None,
        }
    }
}

/// A running server. `shutdown` stops it; dropping the handle stops it too.
pub struct ServerHandle {
    addr: SocketAddr,
    fingerprint: String,
    token: String,
    token_file: Option<PathBuf>,
    created: bool,
    stats: Arc<ServerStats>,
    web: Option<crate::web::WebInfo>,
    stop: watch::Sender<bool>,
    thread: Option<std::thread::JoinHandle<()>>,
    task: Option<tokio::task::JoinHandle<()>>,
}

impl ServerHandle {
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }
    /// Hex SHA-256 of the certificate (what clients pin).
    pub fn fingerprint(&self) -> &str {
        &self.fingerprint
    }
    pub fn token(&self) -> &str {
        &self.token
    }
    /// The token came from the user's `--token-file` (`ServeOptions::token_file`), so the
    /// user has it: print "from FILE" rather than the token, which would leak into logs.
    pub fn token_from_file(&self) -> bool {
        self.token_file.is_some()
    }
    /// The user's token file, if the token came from one.
    pub fn token_file(&self) -> Option<&Path> {
        self.token_file.as_deref()
    }
    /// Whether this start created the certificate or token (first run).
    pub fn created_identity(&self) -> bool {
        self.created
    }
    pub fn stats(&self) -> &Arc<ServerStats> {
        &self.stats
    }
    /// The web viewer's address and certificate hash, when it is served.
    pub fn web(&self) -> Option<&crate::web::WebInfo> {
        self.web.as_ref()
    }
    /// `quic://ADDR/ASSET` for this server.
    pub fn url(&self, asset: &str) -> String {
        format!("quic://{}/{}", self.addr, asset)
    }
    /// Stop accepting, close every connection (code SHUTDOWN) and, for a `spawn`ed server,
    /// join its thread.
    pub fn shutdown(mut self) {
        let _ = self.stop.send(true);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
    /// Wait until the server stops (after `shutdown` from elsewhere or an accept failure).
    pub async fn join(mut self) {
        if let Some(t) = self.task.take() {
            let _ = t.await;
        }
    }
}

impl Drop for ServerHandle {
    fn drop(&mut self) {
        let _ = self.stop.send(true);
    }
}

enum Source {
    Dir(PathBuf),
    File { name: String, path: PathBuf },
}

pub(crate) struct Shared {
    pub(crate) limits: Limits,
    token: String,
    source: Source,
    cache: Mutex<AssetCache<ServedAsset>>,
    load_lock: tokio::sync::Mutex<()>,
    /// One permit per authenticated client (native and web).
    pub(crate) slots: Arc<Semaphore>,
    pub(crate) pending: Arc<PendingTable>,
    pub(crate) stats: Arc<ServerStats>,
    quiet: bool,
    thumbs: crate::thumbs::Thumbs,
}

/// A connection-ending error: QUIC application code + reason sent to the client.
#[derive(Debug)]
struct Close(u32, String);

impl Shared {
    pub(crate) fn quiet(&self) -> bool {
        self.quiet
    }
}

pub(crate) fn log(shared: &Shared, who: SocketAddr, msg: &str) {
    if !shared.quiet {
        eprintln!("snerf serve: {}: {}", who, msg);
    }
}

/// Name an asset is served under: the file name without `.snerf`.
pub fn asset_name(path: &Path) -> String {
    let f = path
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    f.strip_suffix(".snerf").map(str::to_string).unwrap_or(f)
}

/// The scene kind named in an asset file's header (HEAD chunk), read without loading the
/// file; None when the file does not start with a readable header.
fn header_kind(path: &Path) -> Option<String> {
    use std::io::Read;
    let mut f = std::fs::File::open(path).ok()?;
    let mut head = [0u8; 28];
    f.read_exact(&mut head).ok()?;
    snerf_asset::chunk::check_preamble(&head[..16]).ok()?;
    if &head[16..20] != b"HEAD" {
        return None;
    }
    let len = u32::from_le_bytes([head[20], head[21], head[22], head[23]]) as usize;
    if len > 1 << 20 {
        return None;
    }
    let mut json = vec![0u8; len];
    f.read_exact(&mut json).ok()?;
    let v: serde_json::Value = serde_json::from_slice(&json).ok()?;
    v.get("kind")?.as_str().map(str::to_string)
}

impl Shared {
    fn list(&self) -> Vec<ListEntry> {
        match &self.source {
            Source::File { name, path } => {
                let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
                vec![ListEntry {
                    name: name.clone(),
                    size,
                    kind: header_kind(path),
                    thumb: None,
                }]
            }
            Source::Dir(d) => {
                let mut out = Vec::new();
                if let Ok(rd) = std::fs::read_dir(d) {
                    for e in rd.flatten() {
                        let p = e.path();
                        let name = asset_name(&p);
                        if p.extension().is_some_and(|x| x == "snerf") && valid_asset_name(&name) {
                            if let Ok(m) = e.metadata() {
                                if m.is_file() {
                                    out.push(ListEntry {
                                        name,
                                        size: m.len(),
                                        kind: header_kind(&p),
                                        thumb: None,
                                    });
                                }
                            }
                        }
                    }
                }
                out.sort_by(|a, b| a.name.cmp(&b.name));
                out
            }
        }
    }

    /// The file of a listed asset.
    fn asset_path(&self, name: &str) -> Option<PathBuf> {
        self.resolve(Some(name)).ok().map(|(_, p)| p)
    }

    fn resolve(&self, asked: Option<&str>) -> Result<(String, PathBuf), Close> {
        let asked = asked
            .map(|a| a.strip_suffix(".snerf").unwrap_or(a))
            .filter(|a| !a.is_empty());
        match (&self.source, asked) {
            (Source::File { name, path }, None) => Ok((name.clone(), path.clone())),
            (Source::File { name, path }, Some(a)) if a == name => Ok((name.clone(), path.clone())),
            (Source::File { name, .. }, Some(a)) => Err(Close(
                code::NOT_FOUND,
                format!("no asset {:?} (this server serves {:?})", a, name),
            )),
            (Source::Dir(_), None) => {
                let l = self.list();
                match l.len() {
                    1 => self.resolve(Some(&l[0].name.clone())),
                    0 => Err(Close(code::NOT_FOUND, "this server has no assets".into())),
                    _ => Err(Close(
                        code::NOT_FOUND,
                        format!(
                            "name an asset: {}",
                            l.iter()
                                .take(20)
                                .map(|e| e.name.as_str())
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    )),
                }
            }
            (Source::Dir(d), Some(a)) => {
                if !valid_asset_name(a) {
                    return Err(Close(
                        code::NOT_FOUND,
                        format!("invalid asset name {:?}", a),
                    ));
                }
                let p = d.join(format!("{}.snerf", a));
                if p.is_file() {
                    Ok((a.to_string(), p))
                } else {
                    Err(Close(code::NOT_FOUND, format!("no asset {:?}", a)))
                }
            }
        }
    }

    async fn load(&self, name: &str, path: &Path) -> Result<Arc<ServedAsset>, Close> {
        let _g = self.load_lock.lock().await;
        let meta = std::fs::metadata(path)
            .map_err(|e| Close(code::NOT_FOUND, format!("{}: {}", name, e)))?;
        let (mtime, len) = (
            meta.modified().unwrap_or(SystemTime::UNIX_EPOCH),
            meta.len(),
        );
        if let Some(a) = self.cached(|c| c.get(name, mtime, len)) {
            return Ok(a);
        }
        let (n, p) = (name.to_string(), path.to_path_buf());
        let a = tokio::task::spawn_blocking(move || ServedAsset::load(&n, &p))
            .await
            .map_err(|e| Close(code::INTERNAL, format!("loading {}: {}", name, e)))?
            .map_err(|e| {
                if !self.quiet {
                    eprintln!("snerf serve: cannot serve {}: {:#}", path.display(), e);
                }
                Close(
                    code::INTERNAL,
                    format!("asset {:?} cannot be served (invalid file)", name),
                )
            })?;
        let a = Arc::new(a);
        self.cached(|c| c.insert(name, mtime, len, &a));
        Ok(a)
    }

    /// Run `f` on the asset cache and publish its size in the stats.
    fn cached<R>(&self, f: impl FnOnce(&mut AssetCache<ServedAsset>) -> R) -> R {
        let mut c = self.cache.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let r = f(&mut c);
        self.stats.cache_bytes.store(c.bytes(), Ordering::Relaxed);
        self.stats
            .cache_evictions
            .store(c.evictions(), Ordering::Relaxed);
        r
    }
}

pub(crate) fn transport(limits: &Limits) -> Result<quinn::TransportConfig> {
    let mut t = quinn::TransportConfig::default();
    t.max_concurrent_bidi_streams(VarInt::from_u32(1))
        .max_concurrent_uni_streams(VarInt::from_u32(0))
        .stream_receive_window(VarInt::from_u32(
            (limits.max_message as u32).saturating_mul(2).max(64 * 1024),
        ))
        .receive_window(VarInt::from_u32(
            (limits.max_message as u32)
                .saturating_mul(4)
                .max(256 * 1024),
        ))
        .send_window(limits.send_budget.max(64 * 1024))
        .max_idle_timeout(Some(
            limits
                .idle_timeout
                .try_into()
                .map_err(|_| anyhow!("idle timeout too large"))?,
        ))
        .datagram_receive_buffer_size(Some(16 * 1024))
        .datagram_send_buffer_size(16 * 1024);
    match limits.congestion {
        Congestion::Bbr => {
            t.congestion_controller_factory(Arc::new(quinn::congestion::BbrConfig::default()))
        }
        Congestion::Cubic => {
            t.congestion_controller_factory(Arc::new(quinn::congestion::CubicConfig::default()))
        }
    };
    Ok(t)
}

/// Bind and start serving on the current tokio runtime; returns once the socket is bound.
pub async fn start(opts: ServeOptions) -> Result<ServerHandle> {
    let (shared, endpoint, id) = setup(&opts)?;
    let addr = endpoint.local_addr()?;
    let web = match opts.web {
        Some(w) => Some(crate::web::bind(w, &id, opts.cert.is_some(), &opts.limits)?),
        None => None,
    };
    let web_info = web.as_ref().map(|w| w.info.clone());
    let (stop, stop_rx) = watch::channel(false);
    let stats = shared.stats.clone();
    let web_task = web.map(|w| tokio::spawn(crate::web::run(shared.clone(), w, stop_rx.clone())));
    let native = tokio::spawn(accept_loop(shared, endpoint, stop_rx));
    let task = tokio::spawn(async move {
        let _ = native.await;
        if let Some(w) = web_task {
            let _ = w.await;
        }
    });
    Ok(ServerHandle {
        addr,
        fingerprint: id.fingerprint,
        token: id.token,
        token_file: opts.token_file.clone(),
        created: id.created,
        stats,
        web: web_info,
        stop,
        thread: None,
        task: Some(task),
    })
}

/// Start a server on its own background runtime thread (2 worker threads); for tests,
/// benches and embedding in synchronous programs.
pub fn spawn(opts: ServeOptions) -> Result<ServerHandle> {
    let (tx, rx) = std::sync::mpsc::channel();
    let thread = std::thread::Builder::new()
        .name("snerf-serve".into())
        .spawn(move || {
            let rt = match tokio::runtime::Builder::new_multi_thread()
                .worker_threads(2)
                .enable_all()
                .build()
            {
                Ok(rt) => rt,
                Err(e) => {
                    let _ = tx.send(Err(anyhow!("cannot start the server runtime: {}", e)));
                    return;
                }
            };
            rt.block_on(async move {
                match start(opts).await {
                    Err(e) => {
                        let _ = tx.send(Err(e));
                    }
                    Ok(mut h) => {
                        let task = h.task.take();
                        let mut stop = h.stop.subscribe();
                        // The real stop sender moves to the caller's handle; this one gets a
                        // dummy so dropping it stops nothing.
                        let real_stop = std::mem::replace(&mut h.stop, watch::channel(false).0);
                        let info = (
                            h.addr,
                            h.fingerprint.clone(),
                            h.token.clone(),
                            h.token_file.clone(),
                            h.created,
                            h.stats.clone(),
                            h.web.clone(),
                            real_stop,
                        );
                        drop(h);
                        let _ = tx.send(Ok(info));
                        let _ = stop.wait_for(|s| *s).await;
                        if let Some(t) = task {
                            let _ = t.await;
                        }
                    }
                }
            });
        })
        .context("cannot spawn the server thread")?;
    let (addr, fingerprint, token, token_file, created, stats, web, stop) = rx
        .recv()
        .map_err(|_| anyhow!("server thread ended during start"))??;
    Ok(ServerHandle {
        addr,
        fingerprint,
        token,
        token_file,
        created,
        stats,
        web,
        stop,
        thread: Some(thread),
        task: None,
    })
}

/// `snerf serve`: start, print the address, fingerprint and token (to stderr), serve until
/// Ctrl-C.
pub async fn serve(opts: ServeOptions) -> Result<()> {
    serve_with(opts, |_| {}).await
}

/// `serve`, calling `on_ready` once the server listens (after the banner): the way for a
/// caller to get the address, fingerprint and token as data, e.g. to print JSON on stdout,
/// which the server itself never writes to.
pub async fn serve_with(opts: ServeOptions, on_ready: impl FnOnce(&ServerHandle)) -> Result<()> {
    let path = opts.path.clone();
    let h = start(opts).await?;
    eprint!("{}", banner(&path, &h));
    on_ready(&h);
    tokio::signal::ctrl_c()
        .await
        .context("waiting for Ctrl-C")?;
    eprintln!("snerf serve: shutting down");
    let _ = h.stop.send(true);
    h.join().await;
    Ok(())
}

/// What `serve` prints for a person. A token the user supplied in a file is not repeated:
/// they have it, and a printed token ends up in logs.
fn banner(path: &Path, h: &ServerHandle) -> String {
    let token = match h.token_file() {
        Some(f) => format!("from {}", f.display()),
        None => h.token().to_string(),
    };
    let mut b = format!(
        "snerf serve: serving {} on quic://{}\n",
        path.display(),
        h.addr()
    );
    b += &format!("  fingerprint (--pin): {}\n", h.fingerprint());
    b += &format!("  token (--token):     {}\n", token);
    if let Some(w) = h.web() {
        b += &web_banner(w, h.token_file().is_none().then(|| h.token()));
    }
    if h.created_identity() && h.token_from_file() {
        // A token file is never created, so only the certificate can be new.
        b += "  (certificate created on this first run)\n";
    } else if h.created_identity() {
        b += "  (certificate/token created on this first run)\n";
    }
    b
}

/// The web viewer's part of the banner: one URL per LAN address (the token in the fragment,
/// which the browser never sends), the QR code of the first (a headset's camera reads it off
/// the terminal), the loopback URL for this machine, and the one thing a person must do once.
/// `token`: None when it came from the user's file (not printed).
fn web_banner(w: &crate::web::WebInfo, token: Option<&str>) -> String {
    let frag = |u: &str| format!("{u}#token={}", token.unwrap_or("TOKEN"));
    let mut b = String::new();
    let local = crate::lan::page_url(SocketAddr::new(
        if w.addr.ip().is_unspecified() { std::net::IpAddr::from([127, 0, 0, 1]) } else { w.addr.ip() },
        w.addr.port(),
    ));
    if w.lan_urls.is_empty() {
        b += &format!("  web viewer:          {}\n", frag(&local));
        b += "  (this machine only: listen on 0.0.0.0 (--listen 0.0.0.0:PORT) for a headset on the LAN)\n";
    } else {
        for (i, u) in w.lan_urls.iter().enumerate() {
            let label = if i == 0 { "web viewer (headset):" } else { "                     " };
            b += &format!("  {label} {}\n", frag(u));
        }
        if w.addr.ip().is_unspecified() {
            b += &format!("  on this machine:      {}\n", frag(&local));
        }
        if let Some(name) = w.cert_names.iter().find(|n| n.ends_with(".local")) {
            b += &format!("  by name (mDNS):       {}\n", frag(&crate::lan::page_url_named(name, w.addr.port())));
        }
    }
    if token.is_some() && std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        if let Some(q) = w.qr_url().and_then(|u| crate::web::qr_text(&frag(u))) {
            b += &q;
        }
    }
    if token.is_none() {
        b += "  (TOKEN: the token from the file)\n";
    }
    if w.cert_hash.is_some() {
        b += "  The page's certificate is made here, so the browser warns once: choose Advanced, then Proceed.\n";
    }
    b
}

/// Blocking `serve` on a fresh multi-threaded runtime.
pub fn serve_blocking(opts: ServeOptions) -> Result<()> {
    serve_blocking_with(opts, |_| {})
}

/// Blocking `serve_with` on a fresh multi-threaded runtime.
pub fn serve_blocking_with(opts: ServeOptions, on_ready: impl FnOnce(&ServerHandle)) -> Result<()> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("cannot start the tokio runtime")?
        .block_on(serve_with(opts, on_ready))
}

fn setup(opts: &ServeOptions) -> Result<(Arc<Shared>, Endpoint, tls::Identity)> {
    let meta = std::fs::metadata(&opts.path)
        .with_context(|| format!("{}: cannot serve", opts.path.display()))?;
    let source = if meta.is_dir() {
        Source::Dir(opts.path.clone())
    } else {
        let name = asset_name(&opts.path);
        if !valid_asset_name(&name) {
            bail!(
                "{}: file name is not a valid asset name (use letters, digits, . _ -)",
                opts.path.display()
            );
        }
        // Validate a single file up front: refusing to start beats failing every client.
        ServedAsset::load(&name, &opts.path)?;
        Source::File {
            name,
            path: opts.path.clone(),
        }
    };
    let state = opts
        .state_dir
        .clone()
        .unwrap_or_else(|| tls::default_state_dir(&opts.path));
    let id = tls::load_or_create_identity(
        &state,
        opts.cert.as_deref(),
        opts.key.as_deref(),
        opts.token_file.as_deref(),
    )?;
    let mut sc = quinn::ServerConfig::with_crypto(Arc::new(tls::server_crypto(&id)?));
    sc.transport_config(Arc::new(transport(&opts.limits)?));
    sc.migration(true);
    let socket = crate::proto::udp_socket(opts.listen)
        .with_context(|| format!("cannot listen on UDP {}", opts.listen))?;
    let runtime = quinn::default_runtime().ok_or_else(|| anyhow!("no async runtime"))?;
    let endpoint = Endpoint::new(quinn::EndpointConfig::default(), Some(sc), socket, runtime)
        .with_context(|| format!("cannot listen on UDP {}", opts.listen))?;
    let limits = &opts.limits;
    let stats = Arc::new(ServerStats::default());
    let shared = Arc::new(Shared {
        limits: limits.clone(),
        token: id.token.clone(),
        source,
        cache: Mutex::new(AssetCache::new(limits.cache_bytes)),
        load_lock: tokio::sync::Mutex::new(()),
        slots: Arc::new(Semaphore::new(limits.max_clients.max(1))),
        pending: Arc::new(PendingTable::new(
            limits.max_pending_per_ip,
            limits.max_pending,
            stats.clone(),
            crate::pending::Counted::Handshakes,
        )),
        stats,
        quiet: opts.quiet,
        thumbs: Default::default(),
    });
    Ok((shared, endpoint, id))
}

async fn accept_loop(shared: Arc<Shared>, endpoint: Endpoint, mut stop: watch::Receiver<bool>) {
    let mut conns = JoinSet::new();
    loop {
        let incoming = tokio::select! {
            i = endpoint.accept() => match i { Some(i) => i, None => break },
            _ = stop.wait_for(|s| *s) => break,
        };
        while conns.try_join_next().is_some() {}
        let Some(incoming) = screen(&shared, incoming) else {
            continue;
        };
        // Entered here, in arrival order, so that "oldest" in the pending table is exact.
        let pending = shared.pending.admit(incoming.remote_address().ip());
        conns.spawn(connection(shared.clone(), incoming, pending));
    }
    endpoint.close(VarInt::from_u32(code::SHUTDOWN), b"server shutting down");
    conns.abort_all();
    while conns.join_next().await.is_some() {}
    endpoint.wait_idle().await;
}

/// Decide on a connection attempt before it costs a handshake. While every client slot is
/// taken it is refused (CONNECTION_REFUSED, as clients expect from a full server). While many
/// connections are pending, an address that has not proved it receives our packets gets a
/// QUIC Retry first: otherwise spoofed source addresses could fill the pending table (and
/// evict real clients) at no cost, and would make the per-address cap meaningless.
fn screen(shared: &Shared, incoming: quinn::Incoming) -> Option<quinn::Incoming> {
    if shared.slots.available_permits() == 0 {
        shared.stats.refused_busy.fetch_add(1, Ordering::Relaxed);
        log(
            shared,
            incoming.remote_address(),
            "refused: at the client limit",
        );
        incoming.refuse();
        return None;
    }
    if !incoming.remote_address_validated()
        && incoming.may_retry()
        && shared.pending.len() >= shared.pending.max_total() / 2
    {
        shared.stats.retries.fetch_add(1, Ordering::Relaxed);
        // Cannot fail after `may_retry`; a failure would drop (refuse) the attempt anyway.
        let _ = incoming.retry();
        return None;
    }
    Some(incoming)
}

/// One connection from its first packet: the TLS handshake, within `auth_timeout` and while
/// the pending table keeps it, then the session.
async fn connection(shared: Arc<Shared>, incoming: quinn::Incoming, mut pending: Pending) {
    let who = incoming.remote_address();
    let deadline = Instant::now() + shared.limits.auth_timeout;
    let connecting = match incoming.accept() {
        Ok(c) => c,
        Err(e) => return log(&shared, who, &format!("handshake failed: {}", e)),
    };
    // Dropping `connecting` (timeout, eviction) closes the half-open connection.
    let conn = tokio::select! {
        r = tokio::time::timeout_at(deadline, connecting) => match r {
            Ok(Ok(c)) => c,
            Ok(Err(e)) => return log(&shared, who, &format!("handshake failed: {}", e)),
            Err(_) => return log(&shared, who, "handshake timed out"),
        },
        why = pending.evicted() => {
            return log(&shared, who, &format!("dropped during the handshake: {}", why))
        }
    };
    shared.stats.connections.fetch_add(1, Ordering::Relaxed);
    handle(shared, Conn::Quic(conn), pending, deadline).await;
}

pub(crate) async fn handle(shared: Arc<Shared>, conn: Conn, pending: Pending, deadline: Instant) {
    let who = conn.quic().remote_address();
    let mut tasks = JoinSet::new();
    let r = session(&shared, &conn, &mut tasks, pending, deadline).await;
    tasks.abort_all();
    match r {
        Ok(()) => {}
        Err(Close(c, reason)) => {
            match c {
                code::UNAUTHORIZED => shared.stats.unauthorized.fetch_add(1, Ordering::Relaxed),
                // BUSY is counted where it is decided (refused_busy, pending_evicted).
                code::DONE | code::NOT_FOUND | code::SHUTDOWN | code::BUSY => 0,
                _ => shared.stats.protocol_errors.fetch_add(1, Ordering::Relaxed),
            };
            log(
                &shared,
                who,
                &format!("closing ({}): {}", code::name(c as u64), reason),
            );
            conn.quic().close(VarInt::from_u32(c), reason.as_bytes());
        }
    }
    while tasks.join_next().await.is_some() {}
}

/// What a valid Hello asked for.
struct Hello {
    asset: Option<String>,
    have: Vec<[u32; 2]>,
    resume_id: Option<String>,
    pose: Option<Pose>,
}

/// An authenticated client's slot (`Limits::max_clients`), held while its session lasts.
struct Slot {
    _permit: OwnedSemaphorePermit,
    stats: Arc<ServerStats>,
}

impl Drop for Slot {
    fn drop(&mut self) {
        self.stats.clients.fetch_sub(1, Ordering::Relaxed);
    }
}

/// Take a client slot. `screen` refuses new connections while none is free, so this fails
/// only for a client that lost a race for the last one.
fn client_slot(shared: &Shared) -> Result<Slot, Close> {
    let permit = shared.slots.clone().try_acquire_owned().map_err(|_| {
        shared.stats.refused_busy.fetch_add(1, Ordering::Relaxed);
        Close(
            code::BUSY,
            format!(
                "server busy: all {} client slots are taken",
                shared.limits.max_clients.max(1)
            ),
        )
    })?;
    shared.stats.clients.fetch_add(1, Ordering::Relaxed);
    Ok(Slot {
        _permit: permit,
        stats: shared.stats.clone(),
    })
}

fn frame_close(conn: &Conn, e: FrameError) -> Close {
    if conn.quic().close_reason().is_some() {
        return Close(code::DONE, "connection closed".into());
    }
    match e {
        FrameError::TooLarge(..) => Close(code::TOO_LARGE, e.to_string()),
        FrameError::Truncated => Close(code::MALFORMED, e.to_string()),
        FrameError::Io(_) => Close(code::PROTOCOL, e.to_string()),
    }
}

async fn send_msg(send: &mut Send, m: &ServerMsg) -> Result<(), Close> {
    send.quic()
        .write_all(&encode_frame(m))
        .await
        .map_err(|e| Close(code::PROTOCOL, format!("control stream: {}", e)))
}

/// Accept the control stream and a Hello with a valid token by `deadline` (the connection's
/// `auth_timeout`) and within `hello_timeout` of the handshake, unless the pending table
/// closes the connection first to make room. Returning drops `pending`: the connection
/// leaves the table, authenticated or not.
async fn authenticate(
    shared: &Shared,
    conn: &Conn,
    mut pending: Pending,
    deadline: Instant,
) -> Result<(Send, Recv, Hello), Close> {
    let deadline = deadline.min(Instant::now() + shared.limits.hello_timeout);
    tokio::select! {
        r = read_hello(shared, conn, deadline) => r,
        why = pending.evicted() => Err(Close(code::BUSY, why.to_string())),
    }
}

async fn read_hello(
    shared: &Shared,
    conn: &Conn,
    deadline: Instant,
) -> Result<(Send, Recv, Hello), Close> {
    let limits = &shared.limits;
    let (mut send, mut recv) = match tokio::time::timeout_at(deadline, conn.accept_bi()).await {
        Err(_) => {
            return Err(Close(
                code::TIMEOUT,
                "no control stream opened in time".into(),
            ))
        }
        Ok(Err(_)) => return Err(Close(code::DONE, "connection closed".into())),
        Ok(Ok(s)) => s,
    };
    // Control messages go before any data stream.
    let _ = send.quic().set_priority(i32::MAX);
    let first =
        match tokio::time::timeout_at(deadline, read_frame(recv.quic(), limits.max_message)).await {
            Err(_) => return Err(Close(code::TIMEOUT, "no Hello received in time".into())),
            Ok(Err(e)) => return Err(frame_close(conn, e)),
            Ok(Ok(None)) => {
                return Err(Close(
                    code::PROTOCOL,
                    "control stream closed before Hello".into(),
                ))
            }
            Ok(Ok(Some(b))) => b,
        };
    let msg = decode_client_msg(&first).map_err(|e| Close(code::MALFORMED, format!("{:#}", e)))?;
    match msg {
        ClientMsg::List { .. } => Err(Close(code::PROTOCOL, "List before Hello".into())),
        ClientMsg::Hello {
            version,
            token,
            asset,
            have,
            resume_id,
            pose,
        } => {
            if version != PROTOCOL_VERSION {
                return Err(Close(
                    code::VERSION,
                    format!(
                        "protocol version {} not supported (server speaks {})",
                        version, PROTOCOL_VERSION
                    ),
                ));
            }
            if !tls::token_eq(&token, &shared.token) {
                return Err(Close(code::UNAUTHORIZED, "invalid access token".into()));
            }
            let hello = Hello {
                asset,
                have,
                resume_id,
                pose,
            };
            Ok((send, recv, hello))
        }
    }
}

async fn session(
    shared: &Arc<Shared>,
    conn: &Conn,
    tasks: &mut JoinSet<Result<(), Close>>,
    pending: Pending,
    deadline: Instant,
) -> Result<(), Close> {
    let limits = &shared.limits;
    let who = conn.quic().remote_address();
    let (mut send, mut recv, hello) = authenticate(shared, conn, pending, deadline).await?;
    // Authenticated from here on: only now does the connection take a client slot.
    let _slot = client_slot(shared)?;
    let Hello {
        asset,
        have,
        resume_id,
        pose,
    } = hello;
    let mut asset_task = false;
    if let Some(name) = asset {
        let (name, path) = shared.resolve(Some(&name))?;
        let a = shared.load(&name, &path).await?;
        let n = a.chunk_count() as usize;
        let mut skip = vec![false; n];
        let resumed = resume_id.as_deref() == Some(a.sha256.as_str());
        if resumed {
            for r in &have {
                let (lo, hi) = (r[0] as usize, (r[1] as usize).min(n));
                for s in skip.iter_mut().take(hi).skip(lo) {
                    *s = true;
                }
            }
        }
        let sending: Vec<u32> = (0..n as u32).filter(|&i| !skip[i as usize]).collect();
        let sending_bytes = crate::plan::records_len(&a, &sending);
        send_msg(
            &mut send,
            &ServerMsg::Welcome {
                version: PROTOCOL_VERSION,
                asset: Some(a.info()),
                resumed,
                sending_chunks: sending.len() as u32,
                sending_bytes,
            },
        )
        .await?;
        log(
            shared,
            who,
            &format!(
                "streaming {} ({} of {} chunks, {} bytes{})",
                name,
                sending.len(),
                n,
                sending_bytes,
                if resumed { ", resumed" } else { "" }
            ),
        );
        let (view_tx, view_rx) = watch::channel(pose.filter(|p| p.validate().is_ok()));
        tasks.spawn(read_poses(conn.clone(), view_tx, shared.stats.clone()));
        tasks.spawn(stream_asset(conn.clone(), a, skip, view_rx, shared.clone()));
        asset_task = true;
    } else {
        send_msg(
            &mut send,
            &ServerMsg::Welcome {
                version: PROTOCOL_VERSION,
                asset: None,
                resumed: false,
                sending_chunks: 0,
                sending_bytes: 0,
            },
        )
        .await?;
    }
    // Control loop: List may follow; anything else is out of order.
    let mut control_open = true;
    let mut linger: Option<tokio::time::Instant> = None;
    loop {
        tokio::select! {
            f = read_frame(recv.quic(), limits.max_message), if control_open => {
                match f {
                    Err(e) => return Err(frame_close(conn, e)),
                    Ok(None) => control_open = false,
                    Ok(Some(b)) => match decode_client_msg(&b).map_err(|e| Close(code::MALFORMED, format!("{:#}", e)))? {
                        ClientMsg::List { thumbs } => {
                            let mut assets = shared.list();
                            if thumbs {
                                // Rendered (or read from the cache) off the async workers.
                                let sh = shared.clone();
                                assets = tokio::task::spawn_blocking(move || {
                                    for a in &mut assets {
                                        a.thumb = sh.asset_path(&a.name).and_then(|p| sh.thumbs.get(&p));
                                    }
                                    assets
                                })
                                .await
                                .map_err(|_| Close(code::INTERNAL, "thumbnail task failed".into()))?;
                            }
                            send_msg(&mut send, &ServerMsg::Listing { assets }).await?
                        }
                        ClientMsg::Hello { .. } => return Err(Close(code::PROTOCOL, "duplicate Hello".into())),
                    },
                }
            }
            r = tasks.join_next(), if asset_task => {
                match r {
                    None => asset_task = false,
                    Some(Ok(Ok(()))) => {
                        // Everything sent and acknowledged; give the client a moment to close,
                        // still answering List meanwhile (the loop keeps reading control).
                        linger = Some(tokio::time::Instant::now() + limits.linger);
                    }
                    Some(Ok(Err(c))) => return Err(c),
                    Some(Err(_)) => return Ok(()),
                }
            }
            _ = tokio::time::sleep_until(linger.unwrap_or_else(tokio::time::Instant::now)), if linger.is_some() => {
                return Err(Close(code::DONE, "transfer complete".into()));
            }
            _ = conn.quic().closed() => return Ok(()),
        }
    }
}

async fn read_poses(
    conn: Conn,
    tx: watch::Sender<Option<Pose>>,
    stats: Arc<ServerStats>,
) -> Result<(), Close> {
    let mut last: Option<u32> = None;
    // Ends when the connection does; a pose stream never closes it (datagrams are best effort).
    while let Some(d) = conn.read_datagram().await {
        match decode_pose(&d) {
            Ok((seq, p)) => {
                if last.is_none_or(|l| seq > l) {
                    last = Some(seq);
                    stats.pose_updates.fetch_add(1, Ordering::Relaxed);
                    let _ = tx.send(Some(p));
                }
            }
            Err(_) => {
                stats.bad_datagrams.fetch_add(1, Ordering::Relaxed);
            }
        }
    }
    // Keep the join set from reporting completion as "asset task done".
    std::future::pending::<()>().await;
    Ok(())
}

async fn open_stream(conn: &Conn, stall: Duration) -> Result<Send, Close> {
    match tokio::time::timeout(stall, conn.open_uni()).await {
        Err(_) => Err(Close(
            code::TIMEOUT,
            "client granted no stream credit (stopped reading)".into(),
        )),
        Ok(Err(e)) => Err(Close(code::DONE, format!("connection lost: {}", e))),
        Ok(Ok(s)) => Ok(s),
    }
}

async fn write_batch(
    mut s: Send,
    asset: Arc<ServedAsset>,
    idx: Vec<u32>,
    shared: Arc<Shared>,
) -> Result<u64, Close> {
    let mut bufs = Vec::with_capacity(idx.len() * 2);
    let mut bytes = 0u64;
    for &i in &idx {
        bufs.push(Bytes::copy_from_slice(&i.to_le_bytes()));
        bufs.push(asset.chunk_bytes(i));
        bytes += asset.record_len(i);
    }
    let stall = shared.limits.stall_timeout;
    shared.stats.streams_started.fetch_add(1, Ordering::Relaxed);
    match tokio::time::timeout(stall, s.quic().write_all_chunks(&mut bufs)).await {
        Err(_) => {
            return Err(Close(
                code::TIMEOUT,
                "client stopped reading (send stalled)".into(),
            ))
        }
        Ok(Err(e)) => return Err(Close(code::DONE, format!("connection lost: {}", e))),
        Ok(Ok(())) => {}
    }
    let _ = s.quic().finish();
    shared.stats.bytes_sent.fetch_add(bytes, Ordering::Relaxed);
    // Done when the client has acknowledged the whole stream: only then does the scheduler
    // commit more blocks, so what is queued stays ~2 congestion windows and a pose change
    // takes effect within about one round trip.
    match tokio::time::timeout(stall, s.quic().stopped()).await {
        Err(_) => {
            return Err(Close(
                code::TIMEOUT,
                "client stopped acknowledging data".into(),
            ))
        }
        Ok(Err(e)) => return Err(Close(code::DONE, format!("connection lost: {}", e))),
        Ok(Ok(Some(c))) => {
            return Err(Close(
                code::PROTOCOL,
                format!("client stopped a data stream (code {})", c),
            ))
        }
        Ok(Ok(None)) => {}
    }
    shared
        .stats
        .streams_completed
        .fetch_add(1, Ordering::Relaxed);
    Ok(bytes)
}

/// Smallest amount the scheduler keeps in flight, whatever the congestion window says.
const MIN_IN_FLIGHT: u64 = 128 * 1024;
const MIN_BATCH: u64 = 16 * 1024;

/// Stream everything not in `skip`: the meta chunks (HEAD, VMLP, GRIDs) on the first,
/// highest-priority stream, then BLKS chunks in batches ordered for the latest pose, then END
/// once every block stream has been acknowledged. Blocks are committed to streams only while
/// less than ~2 congestion windows are unacknowledged, so the order can follow the pose.
async fn stream_asset(
    conn: Conn,
    asset: Arc<ServedAsset>,
    skip: Vec<bool>,
    mut view_rx: watch::Receiver<Option<Pose>>,
    shared: Arc<Shared>,
) -> Result<(), Close> {
    let limits = shared.limits.clone();
    let max_streams = limits.max_streams.max(1);
    let mut writers: JoinSet<Result<u64, Close>> = JoinSet::new();
    let mut outstanding = 0u64;
    let mut prio = i32::MAX - 1;
    let joined = |r: Result<Result<u64, Close>, tokio::task::JoinError>| -> Result<u64, Close> {
        r.map_err(|_| Close(code::INTERNAL, "writer task failed".into()))?
    };
    let meta: Vec<u32> = asset
        .meta
        .iter()
        .copied()
        .filter(|&i| !skip[i as usize])
        .collect();
    if !meta.is_empty() {
        let mut s = open_stream(&conn, limits.stall_timeout).await?;
        let _ = s.quic().set_priority(prio);
        prio -= 1;
        outstanding += crate::plan::records_len(&asset, &meta);
        writers.spawn(write_batch(s, asset.clone(), meta, shared.clone()));
    }
    let mut remaining: Vec<u32> = (0..asset.blks.len() as u32)
        .filter(|&b| !skip[asset.blks[b as usize].chunk as usize])
        .collect();
    let sort = |remaining: &mut Vec<u32>, pose: Option<Pose>| {
        let view = pose.map(|p| View::new(&asset, &p));
        let mut keyed: Vec<((u32, u8, f32), u32)> = remaining
            .iter()
            .map(|&b| (asset.priority(&asset.blks[b as usize], view.as_ref()), b))
            .collect();
        // Descending, so the most urgent block is popped from the end.
        keyed.sort_by(|a, b| {
            b.0 .0
                .cmp(&a.0 .0)
                .then(b.0 .1.cmp(&a.0 .1))
                .then(b.0 .2.total_cmp(&a.0 .2))
        });
        remaining.clear();
        remaining.extend(keyed.into_iter().map(|k| k.1));
    };
    let p0 = *view_rx.borrow_and_update();
    sort(&mut remaining, p0);
    let mut pose_now = p0;
    let paced_from = tokio::time::Instant::now();
    let mut paced_bytes = 0u64;
    let mut last_sort = std::time::Instant::now() - Duration::from_secs(1);
    while !remaining.is_empty() {
        while let Some(r) = writers.try_join_next() {
            outstanding -= joined(r)?;
        }
        let cwnd = conn.quic().congestion_state().window();
        let target = cwnd
            .saturating_mul(2)
            .clamp(MIN_IN_FLIGHT, limits.send_budget.max(MIN_IN_FLIGHT));
        if outstanding >= target || writers.len() >= max_streams {
            tokio::select! {
                Some(r) = writers.join_next() => outstanding -= joined(r)?,
                _ = conn.quic().closed() => return Ok(()),
            }
            continue;
        }
        // Pacing: the next batch waits until the bytes so far fit the rate (and is chosen
        // after the wait, for the pose then).
        if let Some(rate) = limits.max_rate.filter(|r| *r > 0.0) {
            let due = paced_from + Duration::from_secs_f64(paced_bytes as f64 / rate);
            tokio::select! {
                _ = tokio::time::sleep_until(due) => {}
                _ = conn.quic().closed() => return Ok(()),
            }
        }
        // Re-sort for a new pose, at most every 10 ms (a client streaming poses at a high
        // rate must not make the server sort its blocks continuously).
        if last_sort.elapsed() >= Duration::from_millis(10)
            && view_rx.has_changed().unwrap_or(false)
        {
            let p = *view_rx.borrow_and_update();
            sort(&mut remaining, p);
            pose_now = p;
            last_sort = std::time::Instant::now();
        }
        let batch_target =
            (target / 4).clamp(MIN_BATCH, (limits.batch_bytes as u64).max(MIN_BATCH));
        let mut batch = Vec::new();
        let mut bytes = 0u64;
        while let Some(&b) = remaining.last() {
            if !batch.is_empty() && bytes >= batch_target {
                break;
            }
            let c = asset.blks[b as usize].chunk;
            bytes += asset.record_len(c);
            batch.push(c);
            remaining.pop();
        }
        if limits.log_sends {
            if let Ok(mut log) = shared.stats.send_log.lock() {
                log.push(SentBatch { pose: pose_now, chunks: batch.clone() });
            }
        }
        let mut s = open_stream(&conn, limits.stall_timeout).await?;
        let _ = s.quic().set_priority(prio);
        prio = prio.saturating_sub(1).max(i32::MIN + 1);
        outstanding += bytes;
        paced_bytes += bytes;
        writers.spawn(write_batch(s, asset.clone(), batch, shared.clone()));
    }
    while let Some(r) = writers.join_next().await {
        joined(r)?;
    }
    if !skip[asset.end as usize] {
        let mut s = open_stream(&conn, limits.stall_timeout).await?;
        let _ = s.quic().set_priority(i32::MIN);
        write_batch(s, asset.clone(), vec![asset.end], shared.clone()).await?;
    } else {
        // Nothing more to send; wait for the client to close.
        std::future::pending::<()>().await;
    }
    Ok(())
}
