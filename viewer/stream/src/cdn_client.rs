//! The client of a published scene (`publish.rs`, PUBLISH.md): `snerf fetch
//! https://HOST/NAME/manifest.json` and the `snerf bench publish` load generator.
//!
//! It reads the manifest (refusing another format version), orders the objects with the
//! server's planner (`Manifest::object_order`, built on `plan::order_blocks`), fetches them
//! over a few keep-alive HTTP/1.1 connections (plain or TLS via rustls: the crates the server
//! already links; no HTTP library is added for four request kinds), and checks every
//! object's SHA-256 against its name. A wrong, truncated or stale object (a misconfigured
//! cache) is asked for once more under a cache-busting query, which an edge keys apart and
//! sends to the origin; a second bad answer stops the fetch with an error naming the object
//! and the URL. Verified objects are appended to `OUT.part`, so an interrupted fetch resumes
//! with the objects it lacks. The file appears atomically, hash-checked and re-validated.

use std::collections::VecDeque;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{anyhow, bail, ensure, Context, Result};
use rustls::pki_types::pem::PemObject;
use rustls::pki_types::{CertificateDer, ServerName};
use serde::Serialize;
use sha2::{Digest, Sha256};
use tokio::io::{AsyncBufReadExt, AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, BufReader};
use tokio::net::TcpStream;

use crate::proto::{to_hex, Pose};
use crate::publish::Manifest;

/// `http://` or `https://` HOST[:PORT] PATH.
#[derive(Clone, Debug, PartialEq)]
pub struct HttpUrl {
    pub tls: bool,
    pub host: String,
    pub port: u16,
    /// Path and query, starting with `/`.
    pub path: String,
}

impl HttpUrl {
    pub fn parse(s: &str) -> Result<HttpUrl> {
        let (tls, rest) = if let Some(r) = s.strip_prefix("https://") {
            (true, r)
        } else if let Some(r) = s.strip_prefix("http://") {
            (false, r)
        } else {
            bail!("{s}: not an http:// or https:// URL");
        };
        let (auth, path) = match rest.find('/') {
            Some(i) => (&rest[..i], &rest[i..]),
            None => (rest, "/"),
        };
        let (host, port) = if let Some(h) = auth.strip_prefix('[') {
            let (h, p) = h
                .split_once(']')
                .ok_or_else(|| anyhow!("{s}: bad IPv6 host"))?;
            (h.to_string(), p.strip_prefix(':'))
        } else {
            match auth.rsplit_once(':') {
                Some((h, p)) => (h.to_string(), Some(p)),
                None => (auth.to_string(), None),
            }
        };
        ensure!(!host.is_empty() && !host.contains('@'), "{s}: bad host");
        let port = match port {
            Some(p) => p.parse().map_err(|_| anyhow!("{s}: bad port {p:?}"))?,
            None if tls => 443,
            None => 80,
        };
        Ok(HttpUrl {
            tls,
            host,
            port,
            path: path.to_string(),
        })
    }

    /// A reference relative to this URL (`../chunks/X`, `X`, `/X`), as a browser resolves it.
    pub fn join(&self, rel: &str) -> HttpUrl {
        let path = if rel.starts_with('/') {
            rel.to_string()
        } else {
            let base = self.path.split(['?', '#']).next().unwrap_or("/");
            let mut segs: Vec<&str> = base.split('/').collect();
            segs.pop(); // the file name
            for s in rel.split('/') {
                match s {
                    ".." => {
                        if segs.len() > 1 {
                            segs.pop();
                        }
                    }
                    "." => {}
                    s => segs.push(s),
                }
            }
            segs.join("/")
        };
        HttpUrl {
            path,
            ..self.clone()
        }
    }

    fn authority(&self) -> String {
        let h = if self.host.contains(':') {
            format!("[{}]", self.host)
        } else {
            self.host.clone()
        };
        match (self.tls, self.port) {
            (true, 443) | (false, 80) => h,
            _ => format!("{h}:{}", self.port),
        }
    }
}

impl std::fmt::Display for HttpUrl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}://{}{}",
            if self.tls { "https" } else { "http" },
            self.authority(),
            self.path
        )
    }
}

/// TLS trust for https: the certificates of `ca` (PEM), else the system's CA bundle.
pub fn tls_config(ca: Option<&Path>) -> Result<Arc<rustls::ClientConfig>> {
    let mut roots = rustls::RootCertStore::empty();
    let path = match ca {
        Some(p) => p.to_path_buf(),
        None => PathBuf::from("/etc/ssl/certs/ca-certificates.crt"),
    };
    let bytes = std::fs::read(&path).with_context(|| {
        format!(
            "{}: cannot read CA certificates (--ca FILE)",
            path.display()
        )
    })?;
    for c in CertificateDer::pem_slice_iter(&bytes) {
        let c = c.map_err(|e| anyhow!("{}: {e}", path.display()))?;
        roots
            .add(c)
            .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    }
    ensure!(
        !roots.is_empty(),
        "{}: no PEM certificate in it",
        path.display()
    );
    let mut cfg = rustls::ClientConfig::builder_with_provider(crate::tls::provider())
        .with_safe_default_protocol_versions()?
        .with_root_certificates(roots)
        .with_no_client_auth();
    cfg.alpn_protocols = vec![b"http/1.1".to_vec()];
    Ok(Arc::new(cfg))
}

trait Io: AsyncRead + AsyncWrite + Unpin + Send {}
impl<T: AsyncRead + AsyncWrite + Unpin + Send> Io for T {}

/// One keep-alive HTTP/1.1 connection to one origin (reconnects when the server closes).
pub struct HttpConn {
    origin: HttpUrl,
    tls: Option<Arc<rustls::ClientConfig>>,
    /// Extra request headers (e.g. `Authorization: Bearer …`).
    headers: Vec<(String, String)>,
    io: Option<BufReader<Box<dyn Io>>>,
    /// Bytes sent and received (request and response heads and bodies).
    pub wire_bytes: u64,
    pub requests: u64,
}

/// A response: status and body.
pub struct Resp {
    pub status: u16,
    pub body: Vec<u8>,
    /// `Content-Encoding` (lower case; empty when none).
    pub encoding: String,
}

impl HttpConn {
    pub fn new(
        origin: &HttpUrl,
        tls: Option<Arc<rustls::ClientConfig>>,
        headers: Vec<(String, String)>,
    ) -> HttpConn {
        HttpConn {
            origin: origin.clone(),
            tls,
            headers,
            io: None,
            wire_bytes: 0,
            requests: 0,
        }
    }

    async fn connect(
        origin: HttpUrl,
        tls: Option<Arc<rustls::ClientConfig>>,
    ) -> Result<BufReader<Box<dyn Io>>> {
        let tcp = TcpStream::connect((origin.host.as_str(), origin.port))
            .await
            .with_context(|| format!("cannot connect to {}", origin.authority()))?;
        let _ = tcp.set_nodelay(true);
        let io: Box<dyn Io> = if origin.tls {
            let cfg = tls.ok_or_else(|| anyhow!("https needs a TLS configuration"))?;
            let name = ServerName::try_from(origin.host.clone())
                .map_err(|e| anyhow!("{}: {e}", origin.host))?;
            let s = tokio_rustls::TlsConnector::from(cfg)
                .connect(name, tcp)
                .await
                .with_context(|| {
                    format!(
                        "TLS to {} (trust its certificate with --ca FILE)",
                        origin.authority()
                    )
                })?;
            Box::new(s)
        } else {
            Box::new(tcp)
        };
        Ok(BufReader::with_capacity(64 << 10, io))
    }

    /// GET `url` (same origin as the connection); a body over `max` bytes is refused.
    pub async fn get(&mut self, url: &HttpUrl, max: u64) -> Result<Resp> {
        self.get_with(url, max, "identity").await
    }

    /// GET with an `Accept-Encoding` (the body is returned as sent: see `Resp::encoding`).
    pub async fn get_with(&mut self, url: &HttpUrl, max: u64, accept: &str) -> Result<Resp> {
        // A kept-alive connection the server has closed fails on first use: once more afresh.
        let fresh = self.io.is_none();
        match self.try_get(url, max, accept).await {
            Ok(r) => Ok(r),
            Err(_) if !fresh => {
                self.io = None;
                self.try_get(url, max, accept).await
            }
            Err(e) => Err(e),
        }
        .with_context(|| format!("GET {url}"))
    }

    async fn try_get(&mut self, url: &HttpUrl, max: u64, accept: &str) -> Result<Resp> {
        if self.io.is_none() {
            self.io = Some(Self::connect(self.origin.clone(), self.tls.clone()).await?);
        }
        let io = self.io.as_mut().unwrap();
        let mut req = format!(
            "GET {} HTTP/1.1\r\nHost: {}\r\nUser-Agent: snerf\r\nAccept-Encoding: {accept}\r\n",
            url.path,
            url.authority()
        );
        for (k, v) in &self.headers {
            req.push_str(&format!("{k}: {v}\r\n"));
        }
        req.push_str("\r\n");
        io.get_mut().write_all(req.as_bytes()).await?;
        io.get_mut().flush().await?;
        self.wire_bytes += req.len() as u64;
        self.requests += 1;
        let mut head = Vec::new();
        loop {
            let n = io.read_until(b'\n', &mut head).await?;
            ensure!(n > 0, "connection closed before a response");
            ensure!(head.len() <= 64 << 10, "response head too large");
            if head.ends_with(b"\r\n\r\n") || head == b"\r\n" {
                break;
            }
        }
        self.wire_bytes += head.len() as u64;
        let text = String::from_utf8_lossy(&head).to_string();
        let mut lines = text.split("\r\n");
        let status: u16 = lines
            .next()
            .and_then(|l| l.split(' ').nth(1))
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| anyhow!("not an HTTP response"))?;
        let (mut len, mut chunked, mut close, mut encoding) = (None, false, false, String::new());
        for l in lines {
            let Some((k, v)) = l.split_once(':') else {
                continue;
            };
            let (k, v) = (k.trim().to_ascii_lowercase(), v.trim().to_ascii_lowercase());
            match k.as_str() {
                "content-length" => {
                    len = Some(
                        v.parse::<u64>()
                            .map_err(|_| anyhow!("bad Content-Length"))?,
                    )
                }
                "transfer-encoding" => chunked = v.contains("chunked"),
                "connection" => close = v.contains("close"),
                "content-encoding" => encoding = v,
                _ => {}
            }
        }
        let mut body = Vec::new();
        if chunked {
            loop {
                let mut l = String::new();
                io.read_line(&mut l).await?;
                self.wire_bytes += l.len() as u64;
                let n = u64::from_str_radix(l.trim().split(';').next().unwrap_or(""), 16)
                    .map_err(|_| anyhow!("bad chunk size"))?;
                ensure!(
                    body.len() as u64 + n <= max,
                    "response larger than {max} bytes"
                );
                let at = body.len();
                body.resize(at + n as usize, 0);
                io.read_exact(&mut body[at..]).await?;
                let mut crlf = [0u8; 2];
                io.read_exact(&mut crlf).await?;
                self.wire_bytes += n + 2;
                if n == 0 {
                    // Trailers (none expected) end with an empty line: read_exact took it.
                    break;
                }
            }
        } else if let Some(n) = len {
            // A body larger than allowed is still read off (bounded) so the connection stays
            // in step; the caller sees its size and refuses it.
            ensure!(
                n <= max.saturating_mul(2).max(1 << 20),
                "response of {n} bytes, expected at most {max}"
            );
            body.resize(n as usize, 0);
            let got = read_full(io, &mut body).await?;
            self.wire_bytes += got as u64;
            if got < n as usize {
                body.truncate(got);
                self.io = None;
                return Ok(Resp {
                    status,
                    body,
                    encoding,
                });
            }
        } else if status != 204 && status != 304 {
            // Until the server closes.
            AsyncReadExt::take(&mut *io, max + 1)
                .read_to_end(&mut body)
                .await?;
            self.wire_bytes += body.len() as u64;
            close = true;
        }
        if close {
            self.io = None;
        }
        Ok(Resp {
            status,
            body,
            encoding,
        })
    }
}

/// Read until `buf` is full or the stream ends; bytes read.
async fn read_full<R: AsyncRead + Unpin>(r: &mut R, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut o = 0;
    while o < buf.len() {
        let n = r.read(&mut buf[o..]).await?;
        if n == 0 {
            break;
        }
        o += n;
    }
    Ok(o)
}

/// Options of a published fetch.
#[derive(Clone, Debug, Default)]
pub struct CdnOptions {
    /// PEM CA certificates to trust for https (default: the system bundle).
    pub ca: Option<PathBuf>,
    /// Parallel connections (default 4).
    pub parallel: usize,
    /// The pose to order blocks for (none: centre-out, as the server without a pose).
    pub pose: Option<Pose>,
    /// Extra request headers (a private scene's bearer token).
    pub headers: Vec<(String, String)>,
}

/// What a fetch did.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CdnStats {
    pub asset_bytes: u64,
    pub objects: usize,
    pub objects_resumed: usize,
    pub requests: u64,
    /// Objects asked for a second time (their first answer was wrong).
    pub refetched: usize,
    pub wire_bytes: u64,
    /// Seconds from the start to the manifest, to the first object holding a block, and
    /// to the whole asset.
    pub manifest_s: f64,
    pub first_block_s: f64,
    pub all_s: f64,
}

/// The manifest at `url`.
/// (Asked for gzip: JSON shrinks ~11x, and PUBLISH.md has hosts compress it.)
pub async fn get_manifest(conn: &mut HttpConn, url: &HttpUrl) -> Result<Manifest> {
    let r = conn.get_with(url, 64 << 20, "gzip").await?;
    ensure!(r.status == 200, "{url}: HTTP {}", r.status);
    let body = match r.encoding.as_str() {
        "" | "identity" => r.body,
        "gzip" | "x-gzip" => {
            let mut out = Vec::new();
            std::io::Read::read_to_end(
                &mut std::io::Read::take(flate2::read::GzDecoder::new(&r.body[..]), 64 << 20),
                &mut out,
            )
            .with_context(|| format!("{url}: bad gzip body"))?;
            out
        }
        e => bail!("{url}: Content-Encoding {e:?} (gzip or none expected)"),
    };
    Manifest::parse(&body, &url.to_string())
}

/// Fetch objects `order` (indices into `m.objects`) from `base` over `parallel` connections;
/// each verified object goes to `got` in arrival order. A bad object is asked for once more
/// (cache-busting query); a second bad one is an error.
pub async fn fetch_objects(
    m: &Manifest,
    base: &HttpUrl,
    tls: Option<Arc<rustls::ClientConfig>>,
    opts: &CdnOptions,
    order: Vec<usize>,
    mut got: impl FnMut(usize, Vec<u8>) -> Result<()>,
    stats: &mut CdnStats,
) -> Result<()> {
    let queue = Arc::new(Mutex::new(order.into_iter().collect::<VecDeque<usize>>()));
    let (tx, mut rx) = tokio::sync::mpsc::channel::<Result<(usize, Vec<u8>, bool)>>(16);
    let mut tasks = Vec::new();
    let objects = Arc::new(m.objects.clone());
    for _ in 0..opts.parallel.max(1) {
        let (queue, tx, objects, base) = (queue.clone(), tx.clone(), objects.clone(), base.clone());
        let mut conn = HttpConn::new(&base, tls.clone(), opts.headers.clone());
        tasks.push(tokio::spawn(async move {
            loop {
                let Some(i) = queue.lock().unwrap().pop_front() else {
                    break;
                };
                let r = one_object(&mut conn, &base, &objects[i])
                    .await
                    .map(|(b, again)| (i, b, again));
                let failed = r.is_err();
                if tx.send(r).await.is_err() || failed {
                    break;
                }
            }
            (conn.requests, conn.wire_bytes)
        }));
    }
    drop(tx);
    let mut err = None;
    while let Some(r) = rx.recv().await {
        match r.and_then(|(i, b, again)| {
            stats.refetched += again as usize;
            got(i, b)
        }) {
            Ok(()) => {}
            Err(e) => {
                queue.lock().unwrap().clear();
                err.get_or_insert(e);
            }
        }
    }
    for t in tasks {
        let (req, wire) = t.await.map_err(|e| anyhow!("{e}"))?;
        stats.requests += req;
        stats.wire_bytes += wire;
    }
    match err {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

/// One object, checked against its name; once more under `?refetch=NONCE` if wrong.
async fn one_object(
    conn: &mut HttpConn,
    base: &HttpUrl,
    o: &crate::publish::ObjectRef,
) -> Result<(Vec<u8>, bool)> {
    let url = base.join(&o.sha256);
    let first = match conn.get(&url, o.size).await {
        Ok(r) => match check(&r, o) {
            Ok(()) => return Ok((r.body, false)),
            Err(e) => e,
        },
        Err(e) => e,
    };
    // A query of its own: a cache keyed on path and query (every CDN by default) has no copy
    // of it, so the answer comes from the origin.
    let nonce = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let again = HttpUrl {
        path: format!("{}?refetch={nonce:x}", url.path),
        ..url.clone()
    };
    let r = conn
        .get(&again, o.size)
        .await
        .with_context(|| format!("object {} from {url}: {first:#}; asked again", o.sha256))?;
    check(&r, o).map_err(|e| {
        anyhow!(
            "object {} from {url}: {first:#}; asked again (bypassing caches): {e:#}",
            o.sha256
        )
    })?;
    Ok((r.body, true))
}

fn check(r: &Resp, o: &crate::publish::ObjectRef) -> Result<()> {
    ensure!(r.status == 200, "HTTP {}", r.status);
    ensure!(
        r.body.len() as u64 == o.size,
        "{} bytes, the manifest says {} (truncated or stale)",
        r.body.len(),
        o.size
    );
    let got = to_hex(&Sha256::digest(&r.body));
    ensure!(got == o.sha256, "SHA-256 mismatch (got {got})");
    Ok(())
}

/// `OUT.part` of a published fetch: a line `snerf-publish-part SHA256\n`, then records
/// `u32 object index, u32 length, bytes`.
fn part_path(out: &Path) -> PathBuf {
    let mut p = out.as_os_str().to_owned();
    p.push(".part");
    PathBuf::from(p)
}

/// The objects a previous fetch of the same asset verified (a torn or wrong tail is cut).
fn load_part(path: &Path, m: &Manifest) -> Vec<Option<Vec<u8>>> {
    let mut held = vec![None; m.objects.len()];
    let Ok(b) = std::fs::read(path) else {
        return held;
    };
    let magic = format!("snerf-publish-part {}\n", m.asset.sha256);
    if !b.starts_with(magic.as_bytes()) {
        return held;
    }
    let mut o = magic.len();
    while o + 8 <= b.len() {
        let i = u32::from_le_bytes(b[o..o + 4].try_into().unwrap()) as usize;
        let n = u32::from_le_bytes(b[o + 4..o + 8].try_into().unwrap()) as usize;
        let Some(body) = b.get(o + 8..o + 8 + n) else {
            break;
        };
        match m.objects.get(i) {
            Some(r) if r.size as usize == n && to_hex(&Sha256::digest(body)) == r.sha256 => {
                held[i] = Some(body.to_vec())
            }
            _ => break,
        }
        o += 8 + n;
    }
    held
}

/// `snerf fetch https://HOST/NAME/manifest.json --out FILE`.
pub async fn fetch_published(url: &str, out: &Path, opts: &CdnOptions) -> Result<CdnStats> {
    let t0 = Instant::now();
    let url = HttpUrl::parse(url)?;
    let tls = if url.tls {
        Some(tls_config(opts.ca.as_deref())?)
    } else {
        None
    };
    let mut conn = HttpConn::new(&url, tls.clone(), opts.headers.clone());
    let m = get_manifest(&mut conn, &url).await?;
    let mut stats = CdnStats {
        asset_bytes: m.asset.size,
        objects: m.objects.len(),
        manifest_s: t0.elapsed().as_secs_f64(),
        ..Default::default()
    };
    stats.requests += conn.requests;
    stats.wire_bytes += conn.wire_bytes;
    drop(conn);
    let planner = m.planner()?;
    let part = part_path(out);
    let mut held = load_part(&part, &m);
    stats.objects_resumed = held.iter().filter(|h| h.is_some()).count();
    let is_held: Vec<bool> = held.iter().map(|h| h.is_some()).collect();
    let order = m.object_order(&planner, opts.pose, &is_held);
    // Objects holding a block: the first of them is "the first block".
    let mut has_block = vec![false; m.objects.len()];
    for b in &planner.blks {
        has_block[m.chunks[b.chunk as usize][0] as usize] = true;
    }
    if let Some(d) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(d).with_context(|| format!("{}: cannot create", d.display()))?;
    }
    let mut log = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&part)
        .with_context(|| format!("{}: cannot write", part.display()))?;
    if stats.objects_resumed == 0 {
        log.set_len(0)?;
        log.write_all(format!("snerf-publish-part {}\n", m.asset.sha256).as_bytes())?;
    }
    let base = url.join(&m.objects_base);
    let mut first_block = held
        .iter()
        .zip(&has_block)
        .any(|(h, b)| h.is_some() && *b)
        .then_some(Duration::ZERO);
    fetch_objects(
        &m,
        &base,
        tls,
        opts,
        order,
        |i, b| {
            log.write_all(&(i as u32).to_le_bytes())?;
            log.write_all(&(b.len() as u32).to_le_bytes())?;
            log.write_all(&b)?;
            if has_block[i] && first_block.is_none() {
                first_block = Some(t0.elapsed());
            }
            held[i] = Some(b);
            Ok(())
        },
        &mut stats,
    )
    .await
    .with_context(|| {
        format!(
            "fetching {url} ({} of its objects are kept in {} for the next try)",
            held_count(&part),
            part.display()
        )
    })?;
    log.sync_all()?;
    drop(log);
    let objects: Vec<Vec<u8>> = held.into_iter().map(|h| h.unwrap_or_default()).collect();
    let file = m.assemble(&objects).with_context(|| url.to_string())?;
    snerf_asset::Asset::from_bytes(&file).with_context(|| format!("{url}: the assembled asset"))?;
    snerf_asset::atomic::write_atomic(out, &file)
        .with_context(|| format!("{}: cannot write", out.display()))?;
    let _ = std::fs::remove_file(&part);
    stats.first_block_s = first_block.unwrap_or_default().as_secs_f64();
    stats.all_s = t0.elapsed().as_secs_f64();
    Ok(stats)
}

fn held_count(part: &Path) -> String {
    match std::fs::metadata(part) {
        Ok(m) => format!("{} bytes", m.len()),
        Err(_) => "none".into(),
    }
}

/// Blocking `fetch_published` (its own runtime).
pub fn fetch_published_blocking(url: &str, out: &Path, opts: &CdnOptions) -> Result<CdnStats> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()?
        .block_on(fetch_published(url, out, opts))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_parse_and_join_as_a_browser_does() {
        let u = HttpUrl::parse("https://cdn.example:8443/scenes/a/manifest.json").unwrap();
        assert_eq!(
            (u.tls, u.host.as_str(), u.port, u.path.as_str()),
            (true, "cdn.example", 8443, "/scenes/a/manifest.json")
        );
        assert_eq!(
            u.join("../chunks/ab").to_string(),
            "https://cdn.example:8443/scenes/chunks/ab"
        );
        assert_eq!(u.join("x").path, "/scenes/a/x");
        assert_eq!(u.join("/y").path, "/y");
        let p = HttpUrl::parse("http://127.0.0.1/manifest.json").unwrap();
        assert_eq!((p.port, p.join("../../c/d").path.as_str()), (80, "/c/d"));
        assert_eq!(HttpUrl::parse("http://[::1]:81/").unwrap().host, "::1");
        assert!(HttpUrl::parse("quic://h:1/a").is_err());
        assert!(HttpUrl::parse("http://h:xx/").is_err());
    }
}
