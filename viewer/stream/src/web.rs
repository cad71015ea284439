//! The web viewer of `snerf serve`: a page (embedded at build time from `viewer/stream/web/`)
//! served over HTTP, and `snerf/1` carried over WebTransport (HTTP/3) for it — see
//! PROTOCOL.md, "WebTransport". Both listen on the same port number (TCP for the page, UDP
//! for WebTransport), on their own socket beside the native QUIC endpoint.
//!
//! Why `wtransport` rather than h3 + h3-quinn + h3-webtransport: it is built on the quinn 0.11
//! and rustls 0.23 this crate already uses, hands out the underlying quinn streams (so the
//! session code in `server.rs` serves both transports unchanged, stream priorities included),
//! and its server API is one stable crate, where the h3 WebTransport extension is marked
//! experimental and spread over three. WebTransport gets its own UDP socket so the native
//! endpoint keeps its stream limits (one client bidi stream, no client uni streams) exactly.
//!
//! Trust: without `--cert/--key` each start makes a fresh self-signed ECDSA P-256 certificate
//! valid for 13 days (browsers accept at most 14 for `serverCertificateHashes`) whose
//! subject alternative names hold every name a headset may open the page by (`lan.rs`): the
//! page is served over HTTPS with it (a secure context on any address, once the person has
//! clicked through the browser's one-time warning) and the page hands its SHA-256 to
//! WebTransport in `/config.json`. With `--cert/--key` that certificate serves both and the
//! browser verifies it normally.
//!
//! Who may connect: the page needs the access token, which it takes from the URL fragment
//! (never sent in a request, never logged); the WebTransport CONNECT must come from a page of
//! this server (its `Origin` equals `https://` + the authority it connected to, on this
//! server's port), or it is refused with 403 before any `snerf/1` byte. HTTP requests must name
//! this server in `Host` by an IP literal, `localhost` or a name of its certificate (no DNS
//! rebinding; `page.rs`).

use anyhow::{anyhow, Context, Result};
use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::TcpListener;
use tokio::sync::watch;
use tokio::task::JoinSet;
use tokio::time::Instant;

use crate::conn::Conn;
use crate::pending::Pending;
use crate::proto::code;
use crate::lan::LocalNames;
use crate::page::{PageCert, PageCerts};
use crate::limits::transport;
use crate::session::handle;
use crate::shared::{log, Shared};

pub use crate::page::{APP_CSS, APP_JS, INDEX_HTML, SESSION_PATH, XR_JS};

use crate::web_cert::CERT_DAYS;

/// What a started web viewer listens on.
#[derive(Clone, Debug)]
pub struct WebInfo {
    /// TCP (page) and UDP (WebTransport) address; same port.
    pub addr: SocketAddr,
    /// Hex SHA-256 of the generated certificate (None with `--cert/--key`).
    pub cert_hash: Option<String>,
    /// The page is served over HTTPS (always: with the generated certificate or the user's).
    pub https: bool,
    /// `https://ADDR:PORT/` on each LAN address the socket reaches (`lan.rs`), private IPv4
    /// first; empty when bound to loopback or when the machine has no network.
    pub lan_urls: Vec<String>,
    /// The generated certificate's subject alternative names (empty with `--cert/--key`).
    pub cert_names: Vec<String>,
    /// The generated certificate's hash now (it is rotated before it expires).
    live_hash: Arc<std::sync::RwLock<Option<String>>>,
}

impl WebInfo {
    /// SHA-256 of the generated WebTransport certificate in use now: `cert_hash` until the
    /// first rotation (see `Limits::web_cert_rotate`). None with `--cert/--key`.
    pub fn current_cert_hash(&self) -> Option<String> {
        self.live_hash.read().map(|h| h.clone()).unwrap_or_else(|_| self.cert_hash.clone())
    }

    /// The page's URL (the token goes in the fragment: `#token=…`): the first LAN URL when
    /// there is one — what a headset opens — else the address it is bound to, loopback for an
    /// unspecified one.
    pub fn url(&self) -> String {
        if let Some(u) = self.lan_urls.first() {
            return u.clone();
        }
        let ip = if self.addr.ip().is_unspecified() {
            std::net::IpAddr::from([127, 0, 0, 1])
        } else {
            self.addr.ip()
        };
        crate::lan::page_url(SocketAddr::new(ip, self.addr.port()))
    }

    /// What the QR code holds: a LAN URL, never loopback (on the headset that names the
    /// headset). None when the server reaches no LAN interface.
    pub fn qr_url(&self) -> Option<&str> {
        self.lan_urls.first().map(String::as_str)
    }

    /// The QR code `snerf serve` prints: `qr_url()` with the token in its fragment.
    pub fn qr(&self, token: &str) -> Option<String> {
        qr_text(&format!("{}#token={token}", self.qr_url()?))
    }
}

/// `text` as a QR code drawn with Unicode half blocks (two modules per character cell, dark
/// on light, with the quiet zone), or None when it does not fit a QR code.
pub fn qr_text(text: &str) -> Option<String> {
    let code = qrcode::QrCode::with_error_correction_level(text.as_bytes(), qrcode::EcLevel::L).ok()?;
    Some(
        code.render::<qrcode::render::unicode::Dense1x2>()
            .dark_color(qrcode::render::unicode::Dense1x2::Light)
            .light_color(qrcode::render::unicode::Dense1x2::Dark)
            .build()
            + "\n",
    )
}

pub(crate) struct WebParts {
    pub info: WebInfo,
    http: TcpListener,
    /// TLS for the page: the same certificate as WebTransport, ALPN http/1.1.
    page: PageCerts,
    wt: wtransport::Endpoint<wtransport::endpoint::endpoint_side::Server>,
    /// When the certificate in use was made (rotation counts from it) and where it is kept.
    created: std::time::SystemTime,
    state: std::path::PathBuf,
}

/// The certificate chain and key for the web port: the user's, or a fresh short-lived one
/// for `names` (with its SHA-256).
type Chain = (Vec<rustls::pki_types::CertificateDer<'static>>, rustls::pki_types::PrivateKeyDer<'static>, Option<String>);

fn web_identity(id: &crate::tls::Identity, user_cert: bool, names: &[String], state: &std::path::Path, renew: Duration) -> Result<(Chain, std::time::SystemTime)> {
    if user_cert {
        Ok(((id.certs.clone(), id.key.clone_key(), None), std::time::SystemTime::now()))
    } else {
        let g = crate::web_cert::kept_or_new(state, names, renew)?;
        Ok(((vec![g.cert], g.key, Some(g.sha256)), g.created))
    }
}

/// The page's TLS: the web port's certificate with ALPN http/1.1.
fn page_cert(chain: &Chain) -> Result<PageCert> {
    let mut c = tls_config(chain.0.clone(), chain.1.clone_key())?;
    c.alpn_protocols = vec![b"http/1.1".to_vec()];
    Ok(PageCert { acceptor: tokio_rustls::TlsAcceptor::from(Arc::new(c)), der: chain.0[0].clone(), hash: chain.2.clone() })
}

/// TLS 1.3, ALPN h3, no 0-RTT.
fn tls_config(
    certs: Vec<rustls::pki_types::CertificateDer<'static>>,
    key: rustls::pki_types::PrivateKeyDer<'static>,
) -> Result<rustls::ServerConfig> {
    let mut cfg = rustls::ServerConfig::builder_with_provider(crate::tls::provider())
        .with_protocol_versions(&[&rustls::version::TLS13])
        .map_err(|e| anyhow!("TLS setup: {}", e))?
        .with_no_client_auth()
        .with_single_cert(certs, key)
        .map_err(|e| anyhow!("WebTransport TLS identity: {}", e))?;
    cfg.alpn_protocols = vec![b"h3".to_vec()];
    cfg.max_early_data_size = 0;
    Ok(cfg)
}

/// Bind the page (TCP) and WebTransport (UDP) on one port. Port 0 picks a free port for both.
pub(crate) fn bind(
    addr: SocketAddr,
    id: &crate::tls::Identity,
    user_cert: bool,
    state: &std::path::Path,
    limits: &crate::limits::Limits,
) -> Result<WebParts> {
    let names = LocalNames::of_this_machine(addr.ip());
    let cert_names = if user_cert { vec![] } else { names.cert_names() };
    let (chain, created) = web_identity(id, user_cert, &cert_names, state, limits.web_cert_rotate)?;
    let tls = tls_config(chain.0.clone(), chain.1.clone_key())?;
    let page = Arc::new(std::sync::RwLock::new(Arc::new(page_cert(&chain)?)));
    let cert_hash = chain.2.clone();
    let t = wt_transport(limits)?;
    let mut last_err = None;
    for _ in 0..20 {
        let udp = crate::proto::udp_socket(addr)
            .with_context(|| format!("cannot listen on UDP {} (web viewer)", addr))?;
        let port = udp.local_addr()?.port();
        let tcp_addr = SocketAddr::new(addr.ip(), port);
        let tcp = match std::net::TcpListener::bind(tcp_addr) {
            Ok(l) => l,
            Err(e) if addr.port() == 0 => {
                last_err = Some(e);
                continue;
            }
            Err(e) => {
                return Err(e).with_context(|| format!("cannot listen on TCP {} (web page)", tcp_addr))
            }
        };
        tcp.set_nonblocking(true)?;
        let config = wtransport::ServerConfig::builder()
            .with_bind_socket(udp)
            .with_custom_tls_and_transport(tls.clone(), t)
            .build();
        let wt = wtransport::Endpoint::server(config)
            .with_context(|| format!("cannot start WebTransport on UDP {}", tcp_addr))?;
        return Ok(WebParts {
            info: WebInfo {
                addr: tcp_addr,
                live_hash: Arc::new(std::sync::RwLock::new(cert_hash.clone())),
                cert_hash,
                https: true,
                lan_urls: names.urls(port),
                cert_names,
            },
            http: TcpListener::from_std(tcp)?,
            page,
            wt,
            created,
            state: state.to_path_buf(),
        });
    }
    Err(anyhow!(
        "no port free for both TCP and UDP on {}: {:?}",
        addr.ip(),
        last_err
    ))
}

/// The QUIC transport for WebTransport sessions: HTTP/3 needs the client's control and QPACK
/// streams and its CONNECT request; snerf/1 adds one bidirectional control stream.
fn wt_transport(limits: &crate::limits::Limits) -> Result<quinn::TransportConfig> {
    let mut t = transport(limits)?;
    t.max_concurrent_bidi_streams(quinn::VarInt::from_u32(2))
        .max_concurrent_uni_streams(quinn::VarInt::from_u32(3));
    Ok(t)
}

/// Serve the page and WebTransport sessions until `stop`.
pub(crate) async fn run(shared: Arc<Shared>, parts: WebParts, stop: watch::Receiver<bool>) {
    let info = Arc::new(parts.info);
    let wt = Arc::new(parts.wt);
    let http = tokio::spawn(crate::page::run(parts.http, parts.page.clone(), info.addr.port(), shared.clone(), stop.clone()));
    let rotate = info
        .cert_hash
        .is_some()
        .then(|| tokio::spawn(rotate_loop(shared.clone(), wt.clone(), parts.page.clone(), info.clone(), parts.created, parts.state.clone())));
    wt_loop(shared, wt, info.addr.port(), stop).await;
    http.abort();
    let _ = http.await;
    if let Some(r) = rotate {
        r.abort();
        let _ = r.await;
    }
}

/// A generated certificate lives `CERT_DAYS`; every `Limits::web_cert_rotate` a new one
/// for the same names replaces it for new sessions and page connections (running ones keep
/// theirs), `/config.json` hands out its hash, and the server says so. (A headset then shows
/// the certificate warning once more when it reloads the page.)
async fn rotate_loop(
    shared: Arc<Shared>,
    wt: Arc<wtransport::Endpoint<wtransport::endpoint::endpoint_side::Server>>,
    page: PageCerts,
    info: Arc<WebInfo>,
    mut created: std::time::SystemTime,
    state: std::path::PathBuf,
) {
    let every = shared.limits.web_cert_rotate.max(Duration::from_millis(100));
    loop {
        // Counted from when the certificate was made: a kept one may be days old already.
        let age = std::time::SystemTime::now().duration_since(created).unwrap_or_default();
        tokio::time::sleep(every.saturating_sub(age)).await;
        let next = crate::web_cert::generate(&info.cert_names).and_then(|g| {
            created = g.created;
            if let Err(e) = crate::web_cert::store(&state, &info.cert_names, &g) {
                eprintln!("snerf serve: cannot keep the web viewer's certificate: {e:#}");
            }
            let hash = g.sha256.clone();
            let chain: Chain = (vec![g.cert], g.key, Some(hash.clone()));
            let cfg = wtransport::ServerConfig::builder()
                .with_bind_default(0)
                .with_custom_tls_and_transport(tls_config(chain.0.clone(), chain.1.clone_key())?, wt_transport(&shared.limits)?)
                .build();
            wt.reload_config(cfg, false).context("reloading the WebTransport certificate")?;
            let pc = Arc::new(page_cert(&chain)?);
            *page.write().unwrap_or_else(|e| e.into_inner()) = pc;
            Ok(hash)
        });
        match next {
            Ok(hash) => {
                if let Ok(mut h) = info.live_hash.write() {
                    *h = Some(hash.clone());
                }
                shared.stats.cert_rotations.fetch_add(1, Ordering::Relaxed);
                if !shared.quiet() {
                    eprintln!(
                        "snerf serve: web viewer certificate rotated (browsers accept at most 14 days): SHA-256 {hash}, valid {CERT_DAYS} days"
                    );
                }
            }
            Err(e) => eprintln!("snerf serve: cannot rotate the web viewer certificate: {e:#}"),
        }
    }
}

async fn wt_loop(
    shared: Arc<Shared>,
    endpoint: Arc<wtransport::Endpoint<wtransport::endpoint::endpoint_side::Server>>,
    port: u16,
    mut stop: watch::Receiver<bool>,
) {
    let mut conns = JoinSet::new();
    loop {
        let incoming = tokio::select! {
            i = endpoint.accept() => i,
            _ = stop.wait_for(|s| *s) => break,
        };
        while conns.try_join_next().is_some() {}
        // The same screening as native connections (client slots, Retry under load).
        if shared.slots.available_permits() == 0 {
            shared.stats.refused_busy.fetch_add(1, Ordering::Relaxed);
            incoming.refuse();
            continue;
        }
        if !incoming.remote_address_validated()
            && shared.pending.len() >= shared.pending.max_total() / 2
        {
            shared.stats.retries.fetch_add(1, Ordering::Relaxed);
            incoming.retry();
            continue;
        }
        let pending = shared.pending.admit(incoming.remote_address().ip());
        conns.spawn(session(shared.clone(), incoming, pending, port));
    }
    endpoint.close(wtransport::VarInt::from_u32(code::SHUTDOWN), b"server shutting down");
    conns.abort_all();
    while conns.join_next().await.is_some() {}
    endpoint.wait_idle().await;
}

/// Whether a WebTransport CONNECT comes from a page of this server: its Origin must be
/// `https://` + the authority it connected to (the page is only ever served over HTTPS), and
/// that authority must name this port.
pub fn origin_allowed(origin: Option<&str>, authority: &str, port: u16) -> bool {
    let Some(origin) = origin else { return false };
    let Some(auth_port) = authority.rsplit_once(':').and_then(|(_, p)| p.parse::<u16>().ok())
    else {
        return false;
    };
    auth_port == port && origin == format!("https://{}", authority)
}

async fn session(
    shared: Arc<Shared>,
    incoming: wtransport::endpoint::IncomingSession,
    mut pending: Pending,
    port: u16,
) {
    let who = incoming.remote_address();
    let deadline = Instant::now() + shared.limits.auth_timeout;
    let request = tokio::select! {
        r = tokio::time::timeout_at(deadline, incoming) => match r {
            Ok(Ok(r)) => r,
            Ok(Err(e)) => return log(&shared, who, &format!("WebTransport handshake failed: {}", e)),
            Err(_) => return log(&shared, who, "WebTransport handshake timed out"),
        },
        why = pending.evicted() => {
            return log(&shared, who, &format!("dropped during the handshake: {}", why))
        }
    };
    if request.path() != SESSION_PATH {
        log(&shared, who, "WebTransport request for an unknown path: 404");
        request.not_found().await;
        return;
    }
    if !origin_allowed(request.origin(), request.authority(), port) {
        shared.stats.unauthorized.fetch_add(1, Ordering::Relaxed);
        log(
            &shared,
            who,
            &format!(
                "WebTransport refused (403): origin {:?} is not this server's page",
                request.origin().unwrap_or("(none)")
            ),
        );
        request.forbidden().await;
        return;
    }
    let conn = match tokio::time::timeout_at(deadline, request.accept()).await {
        Ok(Ok(c)) => c,
        Ok(Err(e)) => return log(&shared, who, &format!("WebTransport session failed: {}", e)),
        Err(_) => return log(&shared, who, "WebTransport session timed out"),
    };
    shared.stats.connections.fetch_add(1, Ordering::Relaxed);
    handle(shared, Conn::Web(conn), pending, deadline).await;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The printed QR code (Unicode half blocks) as a greyscale picture, 4 pixels a module.
    fn qr_picture(q: &str) -> (usize, usize, Vec<u8>) {
        let rows: Vec<Vec<char>> = q.lines().map(|l| l.chars().collect()).collect();
        let (w, h) = (rows[0].len() * 4, rows.len() * 8);
        let mut px = vec![255u8; w * h];
        for (r, row) in rows.iter().enumerate() {
            for (c, ch) in row.iter().enumerate() {
                // Dense1x2 with dark on light inverted for a dark terminal: the *light*
                // modules are drawn; ' ' is two dark modules, '█' two light ones.
                let (top_light, bottom_light) = match ch {
                    ' ' => (false, false),
                    '▀' => (true, false),
                    '▄' => (false, true),
                    _ => (true, true),
                };
                for (half, light) in [(0, top_light), (1, bottom_light)] {
                    for y in 0..4 {
                        for x in 0..4 {
                            px[(r * 8 + half * 4 + y) * w + c * 4 + x] = if light { 255 } else { 0 };
                        }
                    }
                }
            }
        }
        (w, h, px)
    }

    #[test]
    fn the_printed_qr_code_reads_back_as_the_lan_url_with_the_token() {
        let info = WebInfo {
            addr: "0.0.0.0:4434".parse().unwrap(),
            cert_hash: None,
            https: true,
            lan_urls: vec!["https://192.168.1.20:4434/".into(), "https://10.0.0.2:4434/".into()],
            cert_names: vec![],
            live_hash: Default::default(),
        };
        let token = "ab".repeat(32);
        let (w, h, px) = qr_picture(&info.qr(&token).unwrap());
        let mut img = rqrr::PreparedImage::prepare_from_greyscale(w, h, |x, y| px[y * w + x]);
        let grids = img.detect_grids();
        assert_eq!(grids.len(), 1);
        let (_, content) = grids[0].decode().unwrap();
        assert_eq!(content, format!("https://192.168.1.20:4434/#token={token}"));
        // No LAN address: no QR code (a loopback URL would open the headset's own loopback).
        let lonely = WebInfo { lan_urls: vec![], ..info };
        assert!(lonely.qr(&token).is_none());
        assert!(lonely.url().starts_with("https://127.0.0.1:4434/"));
    }

    #[test]
    fn the_address_fits_a_qr_code() {
        let url = format!("https://192.168.100.200:4434/#token={}", "ab".repeat(32));
        let q = qr_text(&url).unwrap();
        // Version 6 or so: a few dozen lines, each as wide as the code plus quiet zone.
        let lines: Vec<&str> = q.lines().collect();
        assert!(lines.len() > 15 && lines.len() < 40, "{} lines", lines.len());
        assert!(lines.iter().all(|l| l.chars().count() == lines[0].chars().count()));
    }

    #[test]
    fn origins_and_hosts() {
        assert!(origin_allowed(Some("https://127.0.0.1:8443"), "127.0.0.1:8443", 8443));
        assert!(origin_allowed(Some("https://laptop.local:8443"), "laptop.local:8443", 8443));
        assert!(!origin_allowed(Some("http://127.0.0.1:8443"), "127.0.0.1:8443", 8443));
        assert!(!origin_allowed(Some("http://evil.example"), "127.0.0.1:8443", 8443));
        assert!(!origin_allowed(Some("http://127.0.0.1:9000"), "127.0.0.1:8443", 8443));
        assert!(!origin_allowed(Some("http://127.0.0.1:9000"), "127.0.0.1:9000", 8443));
        assert!(!origin_allowed(None, "127.0.0.1:8443", 8443));
    }
}
