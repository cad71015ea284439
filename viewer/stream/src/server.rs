//! The `snerf serve` side: a quinn endpoint that authenticates clients by token and streams
//! assets chunk by chunk, small parts first, then blocks in priority order for each client's
//! pose. Each client is its own task; every asset file is held once in memory and shared
//! (zero-copy `Bytes` slices) by all clients; QUIC flow control plus a per-client send window
//! bound what a slow client can pin, and a stall timeout drops clients that stop reading.

use anyhow::{anyhow, bail, Context, Result};
use quinn::{Endpoint, VarInt};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use tokio::sync::{watch, Semaphore};
use tokio::task::JoinSet;
use tokio::time::Instant;

use crate::cache::AssetCache;
use crate::conn::Conn;
use crate::pending::{Pending, PendingTable};
use crate::plan::ServedAsset;
use crate::proto::{code, valid_asset_name};
use crate::tls;
pub use crate::limits::{Congestion, Limits};
pub use crate::shared::asset_name;
use crate::limits::transport;
use crate::shared::{log, Shared, Source};
use crate::session::handle;
pub use crate::stats::{SentBatch, ServerStats};

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
    /// Paintings clients may ask to have trained as new styles (PROTOCOL.md, "New styles").
    pub offer: Option<Offer>,
}

// (lives with the sessions' shared state, which reads it; named here for servers' callers)
pub use crate::shared::Offer;

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
            offer: None,
        }
    }
}

/// Tells a running server's watching sessions (`List::watch`) that an asset's styles
/// changed: a new style was added to its file (PROTOCOL.md, "New styles"). Cheap to clone;
/// usable from any thread.
#[derive(Clone)]
pub struct Announcer {
    shared: Arc<Shared>,
}

impl Announcer {
    /// Send every watching session asset `asset`'s style list as its file's header has it
    /// now; returns how many sessions were told. Sessions opened later read the file anew
    /// (its mtime and size changed), so they see the new style without this.
    pub fn styles_changed(&self, asset: &str) -> Result<usize> {
        self.shared.announce_styles(asset)
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
    announcer: Announcer,
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
    /// What tells this server's watching sessions of new styles.
    pub fn announcer(&self) -> Announcer {
        self.announcer.clone()
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

/// Bind and start serving on the current tokio runtime; returns once the socket is bound.
pub async fn start(opts: ServeOptions) -> Result<ServerHandle> {
    let (shared, endpoint, id) = setup(&opts)?;
    let addr = endpoint.local_addr()?;
    let web = match opts.web {
        Some(w) => {
            let state = opts.state_dir.clone().unwrap_or_else(|| tls::default_state_dir(&opts.path));
            Some(crate::web::bind(w, &id, opts.cert.is_some(), &state, &opts.limits)?)
        }
        None => None,
    };
    let web_info = web.as_ref().map(|w| w.info.clone());
    let (stop, stop_rx) = watch::channel(false);
    let stats = shared.stats.clone();
    let announcer = Announcer { shared: shared.clone() };
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
        announcer,
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
                            h.announcer.clone(),
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
    let (addr, fingerprint, token, token_file, created, stats, web, announcer, stop) = rx
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
        announcer,
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
        if let Some(q) = token.and_then(|t| w.qr(t)) {
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
        let a = ServedAsset::load(&name, &opts.path)?;
        if let (Some(st), false) = (&a.styles, opts.quiet) {
            eprintln!("snerf serve: {}", st.message(&opts.path, &name));
        }
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
        // Watchers that fall this far behind miss messages (each names a whole style list,
        // so the next one for that asset makes up for it).
        updates: tokio::sync::broadcast::channel(64).0,
        offer: opts.offer.clone(),
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

