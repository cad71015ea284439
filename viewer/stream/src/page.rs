//! The web viewer's page over HTTPS: HTTP/1.1 with keep-alive, GET and HEAD of a few fixed
//! routes (PROTOCOL.md, "WebTransport"), on the TCP side of the web port.
//!
//! Why hand-written rather than hyper: the server answers seven fixed routes with bodies it
//! holds in memory, and what it must get right is what a hostile peer on the same Wi-Fi can
//! do to it, which is bounded here in a few lines with the same admission table the QUIC side
//! uses:
//! - every connection holds a place in a `PendingTable` (per address, IPv6 per /64, and in
//!   total); at a cap the oldest of that address (or of all) is closed, so idle connections
//!   from one address cannot lock out another address;
//! - the TLS handshake and each request head must arrive within
//!   `Limits::page_head_timeout` (slowloris: a header trickled one line every few seconds);
//! - a request head larger than 16 KiB is answered 431 and closed: memory per connection is
//!   that buffer and the response being written;
//! - a response not taken by the peer within `Limits::page_write_timeout` closes the
//!   connection (a client that never reads).
//!
//! Keep-alive saves a TLS handshake per file: the page loads seven files at start.

use std::net::IpAddr;
use std::sync::atomic::Ordering;
use std::sync::{Arc, RwLock};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::watch;
use tokio::task::JoinSet;
use tokio::time::{timeout_at, Duration, Instant};

use crate::http_stream::HTTP_SESSION_PATH;
use crate::pending::{Counted, PendingTable};
use crate::shared::Shared;
use snerf_geometry::march::{march_shader, ShaderVariant};

/// The page and its script, embedded at build time (no build step: plain ES modules).
pub const INDEX_HTML: &str = include_str!("../web/index.html");
pub const APP_JS: &str = include_str!("../web/app.js");
pub const XR_JS: &str = include_str!("../web/xr.js");
pub const APP_CSS: &str = include_str!("../web/app.css");

/// Path of the WebTransport session (`https://HOST:PORT/snerf/1`).
pub const SESSION_PATH: &str = "/snerf/1";

/// Largest request head accepted (bytes).
pub const MAX_HEAD: usize = 16 * 1024;

/// The page's TLS identity: the acceptor and the certificate it presents (whose names the
/// `Host` check accepts). Replaced whole when the generated certificate is rotated.
pub(crate) struct PageCert {
    pub acceptor: tokio_rustls::TlsAcceptor,
    pub der: rustls::pki_types::CertificateDer<'static>,
    /// SHA-256 of a generated certificate, which the page passes to WebTransport (rotated
    /// with it); None for the user's certificate, which browsers verify normally.
    pub hash: Option<String>,
}

pub(crate) type PageCerts = Arc<RwLock<Arc<PageCert>>>;

/// Serve the page on `l` until `stop`.
pub(crate) async fn run(
    l: TcpListener,
    certs: PageCerts,
    port: u16,
    shared: Arc<Shared>,
    mut stop: watch::Receiver<bool>,
) {
    let limits = &shared.limits;
    let table = Arc::new(PendingTable::new(
        limits.page_conns_per_ip,
        limits.page_conns,
        shared.stats.clone(),
        Counted::Pages,
    ));
    let mut conns = JoinSet::new();
    loop {
        let r = tokio::select! {
            r = l.accept() => r,
            _ = stop.wait_for(|s| *s) => break,
        };
        let Ok((s, peer)) = r else {
            // Out of file descriptors or similar: back off rather than spin.
            tokio::time::sleep(Duration::from_millis(50)).await;
            continue;
        };
        while conns.try_join_next().is_some() {}
        let mut place = table.admit(peer.ip());
        let cert = certs.read().map(|c| c.clone()).unwrap_or_else(|e| e.into_inner().clone());
        let shared = shared.clone();
        let certs = certs.clone();
        conns.spawn(async move {
            tokio::select! {
                _ = place.evicted() => {}
                _ = connection(s, cert, &certs, port, &shared) => {}
            }
        });
    }
    conns.abort_all();
}

async fn connection(s: TcpStream, cert: Arc<PageCert>, certs: &PageCerts, port: u16, shared: &Shared) {
    let _ = s.set_nodelay(true);
    let deadline = Instant::now() + shared.limits.page_head_timeout;
    match timeout_at(deadline, cert.acceptor.accept(s)).await {
        Ok(Ok(tls)) => serve_requests(tls, deadline, &cert, certs, port, shared).await,
        Ok(Err(_)) => {}
        Err(_) => {
            shared.stats.page_timeouts.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Requests on one connection until the peer closes, asks to close, errs or times out.
/// `cert`: the connection's own certificate; `certs`: the one in force now.
async fn serve_requests<S: AsyncRead + AsyncWrite + Unpin>(
    mut s: S,
    first_deadline: Instant,
    cert: &PageCert,
    certs: &PageCerts,
    port: u16,
    shared: &Shared,
) {
    let limits = &shared.limits;
    let mut buf = Vec::with_capacity(2048);
    let mut deadline = first_deadline;
    loop {
        let head = match timeout_at(deadline, read_head(&mut s, &mut buf)).await {
            Ok(Ok(Head::Complete(h))) => h,
            Ok(Ok(Head::TooLarge)) => {
                let r = Response::text(431, "request header too large");
                let _ = tokio::time::timeout(limits.page_write_timeout, write(&mut s, &r, false, false)).await;
                return;
            }
            Ok(Ok(Head::Closed)) | Ok(Err(_)) => return,
            Err(_) => {
                shared.stats.page_timeouts.fetch_add(1, Ordering::Relaxed);
                return;
            }
        };
        let req = Request::parse(&head);
        let (resp, keep) = if req.path == HTTP_SESSION_PATH {
            // snerf/1 over HTTPS: the one route with a body, read whole (at most
            // `max_message`) within the same deadline as the head.
            let host = req.host.as_deref().filter(|h| host_ok(h, port, &cert.der));
            match (host, req.method.as_str(), req.content_length) {
                (None, ..) => (Response::text(421, "unknown host"), false),
                (Some(_), "POST", Some(n)) if n <= limits.max_message => {
                    let body = match timeout_at(deadline, read_body(&mut s, &mut buf, n)).await {
                        Ok(Ok(b)) => b,
                        Ok(Err(_)) => return,
                        Err(_) => {
                            shared.stats.page_timeouts.fetch_add(1, Ordering::Relaxed);
                            return;
                        }
                    };
                    let origin_ok = match (&req.origin, host) {
                        (Some(o), Some(h)) => *o == format!("https://{h}"),
                        _ => false,
                    };
                    let a = crate::http_stream::answer(shared, &req.query, &body, origin_ok).await;
                    let ctype = if a.status == 200 { "application/octet-stream" } else { "text/plain" };
                    let r = Response { status: a.status, ctype, body: a.body.into(), csp: None };
                    (r, req.keep_alive && req.has_body == (n > 0))
                }
                (Some(_), "POST", _) => (Response::text(413, "body missing or too large"), false),
                _ => (Response::text(405, "method not allowed"), false),
            }
        } else {
            // /config.json gives the hash in force now, not this connection's: a page opens
            // sessions long after it loaded (a resume, the listing after the first frame) on
            // the connection it loaded from, and must pin the certificate those meet.
            let now = certs.read().map(|c| c.hash.clone()).unwrap_or_else(|e| e.into_inner().hash.clone());
            (route(&req, port, cert, now.as_deref()), req.keep_alive && !req.has_body)
        };
        let written = tokio::time::timeout(
            limits.page_write_timeout,
            write(&mut s, &resp, req.method == "HEAD", keep),
        )
        .await;
        match written {
            Ok(Ok(())) if keep => {}
            Ok(_) => return,
            Err(_) => {
                shared.stats.page_timeouts.fetch_add(1, Ordering::Relaxed);
                return;
            }
        }
        deadline = Instant::now() + limits.page_head_timeout;
    }
}

enum Head {
    Complete(String),
    TooLarge,
    Closed,
}

/// Read until the end of a request head; bytes after it (a pipelined request) stay in `buf`.
async fn read_head<S: AsyncRead + Unpin>(s: &mut S, buf: &mut Vec<u8>) -> std::io::Result<Head> {
    let mut chunk = [0u8; 2048];
    loop {
        if let Some(p) = buf.windows(4).position(|w| w == b"\r\n\r\n") {
            let head = String::from_utf8_lossy(&buf[..p]).into_owned();
            buf.drain(..p + 4);
            return Ok(Head::Complete(head));
        }
        if buf.len() > MAX_HEAD {
            return Ok(Head::TooLarge);
        }
        let n = s.read(&mut chunk).await?;
        if n == 0 {
            return Ok(Head::Closed);
        }
        buf.extend_from_slice(&chunk[..n]);
    }
}

/// The `n` bytes of a body: what `read_head` left over in `buf`, then the rest from `s`;
/// bytes after the body (a pipelined request) stay in `buf`.
async fn read_body<S: AsyncRead + Unpin>(s: &mut S, buf: &mut Vec<u8>, n: usize) -> std::io::Result<Vec<u8>> {
    let mut chunk = [0u8; 4096];
    while buf.len() < n {
        let k = s.read(&mut chunk).await?;
        if k == 0 {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        buf.extend_from_slice(&chunk[..k]);
    }
    Ok(buf.drain(..n).collect())
}

/// What the server reads of a request head.
#[derive(Debug, Default)]
pub(crate) struct Request {
    pub method: String,
    pub path: String,
    pub query: String,
    pub host: Option<String>,
    pub keep_alive: bool,
    pub origin: Option<String>,
    /// `Content-Length`, when given and a number.
    pub content_length: Option<usize>,
    /// A body was announced (the routes take none: answered, then the connection closed,
    /// since the body's bytes would be read as the next request).
    pub has_body: bool,
}

impl Request {
    pub fn parse(head: &str) -> Request {
        let mut lines = head.split("\r\n");
        let mut first = lines.next().unwrap_or("").split(' ');
        let method = first.next().unwrap_or("").to_string();
        let target = first.next().unwrap_or("");
        let version = first.next().unwrap_or("");
        let (path, query) = target.split_once('?').unwrap_or((target, ""));
        let mut r = Request {
            method,
            path: path.to_string(),
            query: query.to_string(),
            keep_alive: version == "HTTP/1.1",
            ..Request::default()
        };
        for (k, v) in lines.filter_map(|l| l.split_once(':')) {
            let (k, v) = (k.trim(), v.trim());
            if k.eq_ignore_ascii_case("host") {
                r.host = Some(v.to_string());
            } else if k.eq_ignore_ascii_case("connection") && v.to_ascii_lowercase().contains("close") {
                r.keep_alive = false;
            } else if k.eq_ignore_ascii_case("origin") {
                r.origin = Some(v.to_string());
            } else if k.eq_ignore_ascii_case("content-length") {
                r.content_length = v.parse().ok();
                r.has_body |= v != "0";
            } else if k.eq_ignore_ascii_case("transfer-encoding") {
                r.has_body = true;
            }
        }
        r
    }
}

pub(crate) struct Response {
    pub status: u16,
    pub ctype: &'static str,
    pub body: std::borrow::Cow<'static, [u8]>,
    /// The Content-Security-Policy, for responses to a request that named this server.
    pub csp: Option<String>,
}

impl Response {
    fn text(status: u16, msg: &'static str) -> Response {
        Response { status, ctype: "text/plain", body: msg.as_bytes().into(), csp: None }
    }
}

/// The response to one request; `hash`: the certificate hash /config.json hands out.
pub(crate) fn route(req: &Request, port: u16, cert: &PageCert, hash: Option<&str>) -> Response {
    let Some(host) = req.host.as_deref().filter(|h| host_ok(h, port, &cert.der)) else {
        return Response::text(421, "unknown host");
    };
    if req.method != "GET" && req.method != "HEAD" {
        return Response::text(405, "method not allowed");
    }
    let csp = format!(
        "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self'; \
         connect-src 'self' https://{host}; base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
    );
    let stat = |ctype, body: &'static str| (200, ctype, std::borrow::Cow::Borrowed(body.as_bytes()));
    let (status, ctype, body): (u16, &'static str, std::borrow::Cow<'static, [u8]>) = match req.path.as_str() {
        "/" | "/index.html" => stat("text/html; charset=utf-8", INDEX_HTML),
        "/app.js" => stat("text/javascript; charset=utf-8", APP_JS),
        "/xr.js" => stat("text/javascript; charset=utf-8", XR_JS),
        "/app.css" => stat("text/css; charset=utf-8", APP_CSS),
        "/config.json" => {
            let cfg = serde_json::json!({
                "protocol": crate::proto::PROTOCOL_VERSION,
                "webtransport": format!("https://{}{}", host, SESSION_PATH),
                "cert_hash": hash,
                "workgroup": snerf_geometry::march::WORKGROUP,
            });
            (200, "application/json", cfg.to_string().into_bytes().into())
        }
        "/present.wgsl" => stat("text/plain; charset=utf-8", snerf_geometry::march::PRESENT_WGSL),
        "/march.wgsl" => match shader_query(&req.query) {
            Some(variant) => (200, "text/plain; charset=utf-8", march_shader(variant).into_bytes().into()),
            None => (400, "text/plain", b"bad shader variant".as_slice().into()),
        },
        // The same march as GLSL ES 3.00 for the WebGL2 renderer (`glsl.rs`).
        "/march.glsl" => match shader_query(&req.query).map(crate::glsl::march_glsl) {
            Some(Ok(p)) => (200, "application/json", p.to_json().into_bytes().into()),
            Some(Err(_)) => (500, "text/plain", b"shader translation failed".as_slice().into()),
            None => (400, "text/plain", b"bad shader variant".as_slice().into()),
        },
        _ => (404, "text/plain", b"not found".as_slice().into()),
    };
    Response { status, ctype, body, csp: Some(csp) }
}

/// `kind=K&dynamic=0|1&diffuse=0|1&block=B` with K in 0..=2 and B in 4..=64: the variant
/// the page's asset needs (the web page always reads the atlas by texel loads).
pub(crate) fn shader_query(q: &str) -> Option<ShaderVariant> {
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

/// `Host` must name this server with this port: an IP literal or `localhost` (no DNS name an
/// attacker controls can point here: DNS rebinding), or a DNS name the page's certificate is
/// valid for (`laptop.local`, the name of a real certificate given with `--cert`), checked by
/// the same code rustls verifies certificates with.
pub(crate) fn host_ok(h: &str, port: u16, cert: &rustls::pki_types::CertificateDer<'_>) -> bool {
    let Some((name, p)) = h.rsplit_once(':') else {
        return false;
    };
    if p.parse::<u16>().ok() != Some(port) {
        return false;
    }
    let name = name.trim_start_matches('[').trim_end_matches(']');
    if name.eq_ignore_ascii_case("localhost") || name.parse::<IpAddr>().is_ok() {
        return true;
    }
    let Ok(server) = rustls::pki_types::ServerName::try_from(name) else {
        return false;
    };
    webpki::EndEntityCert::try_from(cert)
        .map(|c| c.verify_is_valid_for_subject_name(&server).is_ok())
        .unwrap_or(false)
}

async fn write<S: AsyncWrite + Unpin>(s: &mut S, r: &Response, head_only: bool, keep: bool) -> std::io::Result<()> {
    let reason = match r.status {
        200 => "OK",
        400 => "Bad Request",
        404 => "Not Found",
        401 => "Unauthorized",
        403 => "Forbidden",
        405 => "Method Not Allowed",
        413 => "Content Too Large",
        421 => "Misdirected Request",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        _ => "Error",
    };
    let mut h = format!(
        "HTTP/1.1 {} {reason}\r\nContent-Type: {}\r\nContent-Length: {}\r\n\
         Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nReferrer-Policy: no-referrer\r\n\
         X-Frame-Options: DENY\r\nCross-Origin-Opener-Policy: same-origin\r\n\
         Cross-Origin-Resource-Policy: same-origin\r\n",
        r.status,
        r.ctype,
        r.body.len()
    );
    h += if keep { "Connection: keep-alive\r\n" } else { "Connection: close\r\n" };
    if let Some(c) = &r.csp {
        h += &format!("Content-Security-Policy: {c}\r\n");
    }
    h += "\r\n";
    // One write for head and body: no small TLS record followed by a delayed one.
    let mut out = h.into_bytes();
    if !head_only {
        out.extend_from_slice(&r.body);
    }
    s.write_all(&out).await?;
    if keep {
        s.flush().await
    } else {
        s.shutdown().await
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_are_read_for_keep_alive_and_bodies() {
        let r = Request::parse("GET /app.js?x=1 HTTP/1.1\r\nHost: 10.0.0.2:4434\r\nAccept: */*");
        assert_eq!((r.method.as_str(), r.path.as_str(), r.query.as_str()), ("GET", "/app.js", "x=1"));
        assert_eq!(r.host.as_deref(), Some("10.0.0.2:4434"));
        assert!(r.keep_alive && !r.has_body);
        assert!(!Request::parse("GET / HTTP/1.1\r\nConnection: Close").keep_alive);
        assert!(!Request::parse("GET / HTTP/1.0\r\nHost: a:1").keep_alive);
        assert!(Request::parse("POST / HTTP/1.1\r\nContent-Length: 5").has_body);
        assert!(Request::parse("POST / HTTP/1.1\r\nTransfer-Encoding: chunked").has_body);
    }

    #[test]
    fn shader_variants_parse_strictly() {
        let v = |kind, dynamic, diffuse, block| Some(ShaderVariant { kind, dynamic, diffuse, block, hardware_filter: false });
        assert_eq!(shader_query("kind=2&dynamic=1&diffuse=0&block=8"), v(2, true, false, 8));
        assert_eq!(shader_query("diffuse=1&kind=0&dynamic=0&block=16"), v(0, false, true, 16));
        assert_eq!(shader_query("kind=3&dynamic=1&diffuse=0&block=8"), None);
        assert_eq!(shader_query("kind=0&dynamic=0&diffuse=2&block=8"), None);
        assert_eq!(shader_query("kind=0&dynamic=0&block=8"), None);
        assert_eq!(shader_query("kind=0&dynamic=0"), None);
        assert_eq!(shader_query("kind=0&dynamic=0&diffuse=0&block=8&x=1"), None);
    }

    #[test]
    fn hosts_are_ip_literals_localhost_or_names_in_the_certificate() {
        let names = ["localhost", "127.0.0.1", "laptop", "laptop.local"].map(String::from).to_vec();
        let c = rcgen::generate_simple_self_signed(names).unwrap();
        let der = c.cert.der().clone();
        let ok = |h: &str| host_ok(h, 80, &der);
        assert!(ok("127.0.0.1:80") && ok("[::1]:80") && ok("LOCALHOST:80") && ok("192.168.1.5:80"));
        assert!(ok("laptop.local:80") && ok("laptop:80") && ok("Laptop.Local:80"));
        assert!(!ok("evil.example:80") && !ok("laptop.evil:80") && !ok("127.0.0.1:81") && !ok("127.0.0.1"));
        assert!(!ok("laptop.local:81") && !ok(":80") && !ok("a b:80"));
    }
}
