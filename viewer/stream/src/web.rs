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
//! valid for 13 days (browsers accept at most 14 for `serverCertificateHashes`) and hands its
//! SHA-256 to the page in `/config.json`; with `--cert/--key` that certificate is used and the
//! page relies on the browser's normal verification. The page is served over plain HTTP,
//! which browsers treat as a secure context only on loopback, or over HTTPS with that same
//! certificate when `--cert/--key` are given.
//!
//! Who may connect: the page needs the access token, which it takes from the URL fragment
//! (never sent in a request, never logged); the WebTransport CONNECT must come from a page of
//! this server (its `Origin` equals `http://` + the authority it connected to, on this
//! server's port), or it is refused with 403 before any `snerf/1` byte. HTTP requests must name
//! this server by an IP literal or `localhost` in `Host` (no DNS rebinding).

use anyhow::{anyhow, Context, Result};
use std::net::SocketAddr;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::TcpListener;
use tokio::sync::watch;
use tokio::task::JoinSet;
use tokio::time::Instant;

use crate::conn::Conn;
use crate::pending::Pending;
use crate::proto::code;
use crate::server::{handle, log, transport, Shared};
use snerf_geometry::march::{march_shader, ShaderVariant};

/// The page and its script, embedded at build time (no build step: plain ES modules).
pub const INDEX_HTML: &str = include_str!("../web/index.html");
pub const APP_JS: &str = include_str!("../web/app.js");
pub const XR_JS: &str = include_str!("../web/xr.js");
pub const APP_CSS: &str = include_str!("../web/app.css");

/// Path of the WebTransport session (`https://HOST:PORT/snerf/1`).
pub const SESSION_PATH: &str = "/snerf/1";

/// Validity of the generated WebTransport certificate (browsers require ≤ 14 days).
const CERT_DAYS: u32 = 13;

/// What a started web viewer listens on.
#[derive(Clone, Debug)]
pub struct WebInfo {
    /// TCP (page) and UDP (WebTransport) address; same port.
    pub addr: SocketAddr,
    /// Hex SHA-256 of the generated certificate (None with `--cert/--key`).
    pub cert_hash: Option<String>,
    /// The page is served over HTTPS (with `--cert/--key`), else plain HTTP.
    pub https: bool,
    /// The generated certificate's hash now (it is rotated before it expires).
    live_hash: Arc<std::sync::RwLock<Option<String>>>,
}

impl WebInfo {
    /// SHA-256 of the generated WebTransport certificate in use now: `cert_hash` until the
    /// first rotation (see `Limits::web_cert_rotate`). None with `--cert/--key`.
    pub fn current_cert_hash(&self) -> Option<String> {
        self.live_hash.read().map(|h| h.clone()).unwrap_or_else(|_| self.cert_hash.clone())
    }

    /// `http://ADDR/`, or `https://…` with `--cert/--key` (the token goes in the fragment:
    /// `#token=…`).
    pub fn url(&self) -> String {
        let host = if self.addr.ip().is_unspecified() {
            "127.0.0.1".to_string()
        } else {
            host_literal(self.addr.ip())
        };
        let scheme = if self.https { "https" } else { "http" };
        format!("{}://{}:{}/", scheme, host, self.addr.port())
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

fn host_literal(ip: std::net::IpAddr) -> String {
    match ip {
        std::net::IpAddr::V4(v) => v.to_string(),
        std::net::IpAddr::V6(v) => format!("[{}]", v),
    }
}

pub(crate) struct WebParts {
    pub info: WebInfo,
    http: TcpListener,
    /// TLS for the page (`--cert/--key`): the same certificate, ALPN http/1.1.
    page_tls: Option<tokio_rustls::TlsAcceptor>,
    wt: wtransport::Endpoint<wtransport::endpoint::endpoint_side::Server>,
}

/// The certificate and key for WebTransport: the user's, or a fresh short-lived one.
fn web_tls(
    id: &crate::tls::Identity,
    user_cert: bool,
    addr: SocketAddr,
) -> Result<(rustls::ServerConfig, Option<String>)> {
    use rustls::pki_types::{CertificateDer, PrivateKeyDer};
    let (certs, key, hash): (Vec<CertificateDer<'static>>, PrivateKeyDer<'static>, _) =
        if user_cert {
            (id.certs.clone(), id.key.clone_key(), None)
        } else {
            let (cert, key, hash) = generated_cert(addr)?;
            (vec![cert], key, Some(hash))
        };
    tls_config(certs, key).map(|c| (c, hash))
}

/// A fresh self-signed ECDSA P-256 certificate valid for `CERT_DAYS`, for the names a page
/// on this machine or at `addr` uses; and its SHA-256.
fn generated_cert(
    addr: SocketAddr,
) -> Result<(rustls::pki_types::CertificateDer<'static>, rustls::pki_types::PrivateKeyDer<'static>, String)> {
    use rustls::pki_types::{CertificateDer, PrivateKeyDer, PrivatePkcs8KeyDer};
    let mut names = vec!["localhost".to_string(), "127.0.0.1".into(), "::1".into()];
    if !addr.ip().is_unspecified() {
        names.push(addr.ip().to_string());
    }
    let g = wtransport::Identity::self_signed_builder()
        .subject_alt_names(names)
        .from_now_utc()
        .validity_days(CERT_DAYS)
        .build()
        .map_err(|e| anyhow!("cannot generate the WebTransport certificate: {}", e))?;
    let der = g.certificate_chain().as_slice()[0].der().to_vec();
    let hash = crate::tls::fingerprint(&der);
    let key = PrivateKeyDer::Pkcs8(PrivatePkcs8KeyDer::from(g.private_key().secret_der().to_vec()));
    Ok((CertificateDer::from(der), key, hash))
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
    limits: &crate::server::Limits,
) -> Result<WebParts> {
    let (tls, cert_hash) = web_tls(id, user_cert, addr)?;
    let page_tls = user_cert.then(|| {
        let mut c = tls.clone();
        c.alpn_protocols = vec![b"http/1.1".to_vec()];
        tokio_rustls::TlsAcceptor::from(Arc::new(c))
    });
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
                https: page_tls.is_some(),
            },
            http: TcpListener::from_std(tcp)?,
            page_tls,
            wt,
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
fn wt_transport(limits: &crate::server::Limits) -> Result<quinn::TransportConfig> {
    let mut t = transport(limits)?;
    t.max_concurrent_bidi_streams(quinn::VarInt::from_u32(2))
        .max_concurrent_uni_streams(quinn::VarInt::from_u32(3));
    Ok(t)
}

/// Serve the page and WebTransport sessions until `stop`.
pub(crate) async fn run(shared: Arc<Shared>, parts: WebParts, stop: watch::Receiver<bool>) {
    let info = Arc::new(parts.info);
    let wt = Arc::new(parts.wt);
    let http = tokio::spawn(http_loop(parts.http, parts.page_tls, info.clone(), stop.clone()));
    let rotate = info
        .cert_hash
        .is_some()
        .then(|| tokio::spawn(rotate_loop(shared.clone(), wt.clone(), info.clone())));
    wt_loop(shared, wt, info.addr.port(), stop).await;
    http.abort();
    let _ = http.await;
    if let Some(r) = rotate {
        r.abort();
        let _ = r.await;
    }
}

/// A generated certificate lives `CERT_DAYS`; every `Limits::web_cert_rotate` a new one
/// replaces it for new sessions (running ones keep theirs), `/config.json` hands out its
/// hash, and the server says so.
async fn rotate_loop(
    shared: Arc<Shared>,
    wt: Arc<wtransport::Endpoint<wtransport::endpoint::endpoint_side::Server>>,
    info: Arc<WebInfo>,
) {
    let every = shared.limits.web_cert_rotate.max(Duration::from_millis(100));
    loop {
        tokio::time::sleep(every).await;
        let next = generated_cert(info.addr).and_then(|(c, k, hash)| {
            let cfg = wtransport::ServerConfig::builder()
                .with_bind_default(0)
                .with_custom_tls_and_transport(tls_config(vec![c], k)?, wt_transport(&shared.limits)?)
                .build();
            wt.reload_config(cfg, false).context("reloading the WebTransport certificate")?;
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
/// `http(s)://` + the authority it connected to, and that authority must name this port.
pub fn origin_allowed(origin: Option<&str>, authority: &str, port: u16) -> bool {
    let Some(origin) = origin else { return false };
    let Some(auth_port) = authority.rsplit_once(':').and_then(|(_, p)| p.parse::<u16>().ok())
    else {
        return false;
    };
    auth_port == port
        && (origin == format!("http://{}", authority) || origin == format!("https://{}", authority))
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

// ---- the page over HTTP/1.1 ----

async fn http_loop(
    l: TcpListener,
    tls: Option<tokio_rustls::TlsAcceptor>,
    info: Arc<WebInfo>,
    mut stop: watch::Receiver<bool>,
) {
    let mut conns = JoinSet::new();
    loop {
        let r = tokio::select! {
            r = l.accept() => r,
            _ = stop.wait_for(|s| *s) => break,
        };
        let Ok((s, _)) = r else {
            // Out of file descriptors or similar: back off rather than spin.
            tokio::time::sleep(Duration::from_millis(50)).await;
            continue;
        };
        while conns.try_join_next().is_some() {}
        if conns.len() >= 64 {
            continue; // dropped: too many page requests at once
        }
        let (info, tls) = (info.clone(), tls.clone());
        conns.spawn(async move {
            let _ = tokio::time::timeout(Duration::from_secs(10), async {
                match tls {
                    Some(t) => match t.accept(s).await {
                        Ok(s) => http_conn(s, &info).await,
                        Err(_) => Ok(()),
                    },
                    None => http_conn(s, &info).await,
                }
            })
            .await;
        });
    }
    conns.abort_all();
}

/// One request per connection (`Connection: close`): GET or HEAD of a few fixed paths.
async fn http_conn<S: AsyncRead + AsyncWrite + Unpin>(mut s: S, info: &WebInfo) -> std::io::Result<()> {
    let mut buf = Vec::with_capacity(2048);
    let mut chunk = [0u8; 2048];
    let head_end = loop {
        let n = s.read(&mut chunk).await?;
        if n == 0 {
            return Ok(());
        }
        buf.extend_from_slice(&chunk[..n]);
        if let Some(p) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
            break p;
        }
        if buf.len() > 16 * 1024 {
            return respond(&mut s, 431, "text/plain", b"request header too large", None).await;
        }
    };
    let head = String::from_utf8_lossy(&buf[..head_end]).into_owned();
    let mut lines = head.split("\r\n");
    let mut req = lines.next().unwrap_or("").split(' ');
    let (method, target) = (req.next().unwrap_or(""), req.next().unwrap_or(""));
    let host = lines
        .filter_map(|l| l.split_once(':'))
        .find(|(k, _)| k.trim().eq_ignore_ascii_case("host"))
        .map(|(_, v)| v.trim().to_string());
    let Some(host) = host.filter(|h| host_ok(h, info.addr.port())) else {
        return respond(&mut s, 421, "text/plain", b"unknown host", None).await;
    };
    if method != "GET" && method != "HEAD" {
        return respond(&mut s, 405, "text/plain", b"method not allowed", None).await;
    }
    let head_only = method == "HEAD";
    let (path, query) = target.split_once('?').unwrap_or((target, ""));
    let csp = format!(
        "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; \
         connect-src 'self' https://{host}; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
    );
    let (status, ctype, body): (u16, &str, Vec<u8>) = match path {
        "/" | "/index.html" => (200, "text/html; charset=utf-8", INDEX_HTML.as_bytes().to_vec()),
        "/app.js" => (200, "text/javascript; charset=utf-8", APP_JS.as_bytes().to_vec()),
        "/xr.js" => (200, "text/javascript; charset=utf-8", XR_JS.as_bytes().to_vec()),
        "/app.css" => (200, "text/css; charset=utf-8", APP_CSS.as_bytes().to_vec()),
        "/config.json" => {
            let cfg = serde_json::json!({
                "protocol": crate::proto::PROTOCOL_VERSION,
                "webtransport": format!("https://{}{}", host, SESSION_PATH),
                "cert_hash": info.current_cert_hash(),
                "workgroup": snerf_geometry::march::WORKGROUP,
            });
            (200, "application/json", cfg.to_string().into_bytes())
        }
        "/present.wgsl" => (200, "text/plain; charset=utf-8", snerf_geometry::march::PRESENT_WGSL.as_bytes().to_vec()),
        "/march.wgsl" => match shader_query(query) {
            Some(variant) => (200, "text/plain; charset=utf-8", march_shader(variant).into_bytes()),
            None => (400, "text/plain", b"bad shader variant".to_vec()),
        },
        _ => (404, "text/plain", b"not found".to_vec()),
    };
    let body = if head_only { &body[..0] } else { &body[..] };
    respond(&mut s, status, ctype, body, Some(&csp)).await
}

/// `kind=K&dynamic=0|1&diffuse=0|1&block=B` with K in 0..=2 and B in 4..=64: the variant
/// the page's asset needs (the web page always reads the atlas by texel loads).
fn shader_query(q: &str) -> Option<ShaderVariant> {
    let (mut kind, mut dynamic, mut diffuse, mut block) = (None, None, None, None);
    let flag = |v: &str| match v {
        "0" => Some(false),
        "1" => Some(true),
        _ => None,
    };
    for kv in q.split('&') {
        match kv.split_once('=')? {
            ("kind", v) => kind = v.parse::<u32>().ok().filter(|k| *k <= 2),
            ("dynamic", v) => dynamic = Some(flag(v)?),
            ("diffuse", v) => diffuse = Some(flag(v)?),
            ("block", v) => block = v.parse::<u32>().ok().filter(|b| (4..=64).contains(b)),
            _ => return None,
        }
    }
    Some(ShaderVariant { kind: kind?, dynamic: dynamic?, diffuse: diffuse?, block: block?, hardware_filter: false })
}

/// `Host` must be an IP literal or `localhost`, with this port.
fn host_ok(h: &str, port: u16) -> bool {
    let Some((name, p)) = h.rsplit_once(':') else {
        return false;
    };
    if p.parse::<u16>().ok() != Some(port) {
        return false;
    }
    let name = name.trim_start_matches('[').trim_end_matches(']');
    name.eq_ignore_ascii_case("localhost") || name.parse::<std::net::IpAddr>().is_ok()
}

async fn respond<S: AsyncWrite + Unpin>(
    s: &mut S,
    status: u16,
    ctype: &str,
    body: &[u8],
    csp: Option<&str>,
) -> std::io::Result<()> {
    let reason = match status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        421 => "Misdirected Request",
        _ => "Request Header Fields Too Large",
    };
    let mut h = format!(
        "HTTP/1.1 {status} {reason}\r\nContent-Type: {ctype}\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nReferrer-Policy: no-referrer\r\n\
         X-Frame-Options: DENY\r\nCross-Origin-Opener-Policy: same-origin\r\n\
         Cross-Origin-Resource-Policy: same-origin\r\nConnection: close\r\n",
        body.len()
    );
    if let Some(c) = csp {
        h += &format!("Content-Security-Policy: {c}\r\n");
    }
    h += "\r\n";
    s.write_all(h.as_bytes()).await?;
    s.write_all(body).await?;
    s.shutdown().await
}

#[cfg(test)]
mod tests {
    use super::*;

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
        assert!(origin_allowed(Some("http://127.0.0.1:8443"), "127.0.0.1:8443", 8443));
        assert!(origin_allowed(Some("http://localhost:8443"), "localhost:8443", 8443));
        assert!(!origin_allowed(Some("http://evil.example"), "127.0.0.1:8443", 8443));
        assert!(!origin_allowed(Some("http://127.0.0.1:9000"), "127.0.0.1:8443", 8443));
        assert!(!origin_allowed(Some("http://127.0.0.1:9000"), "127.0.0.1:9000", 8443));
        assert!(!origin_allowed(None, "127.0.0.1:8443", 8443));
        assert!(host_ok("127.0.0.1:80", 80) && host_ok("[::1]:80", 80) && host_ok("LOCALHOST:80", 80));
        assert!(!host_ok("evil.example:80", 80) && !host_ok("127.0.0.1:81", 80) && !host_ok("127.0.0.1", 80));
        let v = |kind, dynamic, diffuse, block| Some(ShaderVariant { kind, dynamic, diffuse, block, hardware_filter: false });
        assert_eq!(shader_query("kind=2&dynamic=1&diffuse=0&block=8"), v(2, true, false, 8));
        assert_eq!(shader_query("diffuse=1&kind=0&dynamic=0&block=16"), v(0, false, true, 16));
        assert_eq!(shader_query("kind=3&dynamic=1&diffuse=0&block=8"), None);
        assert_eq!(shader_query("kind=0&dynamic=0&diffuse=2&block=8"), None);
        assert_eq!(shader_query("kind=0&dynamic=0&block=8"), None);
        assert_eq!(shader_query("kind=0&dynamic=0"), None);
        assert_eq!(shader_query("kind=0&dynamic=0&diffuse=0&block=8&x=1"), None);
    }
}
