//! `snerf serve`, `snerf fetch`: baked assets over QUIC (TLS 1.3, pinned self-signed
//! certificate, access token), and `snerf bench stream`; `snerf publish` and `snerf fetch
//! https://…/manifest.json`: a published scene on any static host or CDN.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_stream::{Congestion, Limits, ServeOptions};

mod styles_dir;

#[derive(Args, Debug)]
pub struct ServeArgs {
    /// A directory of .snerf files, or one file.
    pub path: PathBuf,
    /// Address to listen on (UDP).
    #[arg(long, default_value = "127.0.0.1:4433")]
    pub listen: SocketAddr,
    /// Where the generated certificate, key and token are kept (default ~/.config/snerf/serve).
    #[arg(long)]
    pub state: Option<PathBuf>,
    /// PEM certificate to use instead of the generated one (with --key).
    #[arg(long, requires = "key")]
    pub cert: Option<PathBuf>,
    /// PEM private key for --cert.
    #[arg(long, requires = "cert")]
    pub key: Option<PathBuf>,
    /// File holding the access token (default: generated in the state directory).
    #[arg(long)]
    pub token_file: Option<PathBuf>,
    /// Simultaneous authenticated clients; more are refused (connections still in their
    /// handshake are capped separately, per address and in total).
    #[arg(long, default_value_t = 64, value_parser = crate::args::int_in::<usize>(1, 100000, ""))]
    pub max_clients: usize,
    /// Largest control message accepted, bytes.
    #[arg(long, default_value_t = 64 * 1024, value_parser = crate::args::int_in::<usize>(1024, 16777216, ""))]
    pub max_message: usize,
    /// Drop a silent peer after this many seconds.
    #[arg(long, default_value_t = 30.0, value_parser = crate::args::positive)]
    pub idle_timeout: f64,
    /// Drop a client that stops reading for this many seconds.
    #[arg(long, default_value_t = 30.0, value_parser = crate::args::positive)]
    pub stall_timeout: f64,
    /// Bytes in flight per client (back-pressure).
    #[arg(long, default_value_t = 8 << 20, value_parser = crate::args::int_in::<u64>(65536, 1073741824, ""))]
    pub send_budget: u64,
    /// Data streams in flight per client.
    #[arg(long, default_value_t = 8, value_parser = crate::args::int_in::<usize>(1, 1024, ""))]
    pub max_streams: usize,
    /// Seconds a new connection has to finish its handshake and authenticate (slow, lossy
    /// links may need more).
    #[arg(long, default_value_t = 3.0, value_parser = crate::args::positive)]
    pub auth_timeout: f64,
    /// Connections still authenticating, per source address (the oldest is dropped beyond it).
    #[arg(long, default_value_t = 32, value_parser = crate::args::int_in::<usize>(1, 100000, ""))]
    pub max_pending_per_ip: usize,
    /// Memory for cached assets, MB (least recently used ones are dropped beyond it).
    #[arg(long, default_value_t = 1024, value_parser = crate::args::int_in::<u64>(1, 1 << 20, ""))]
    pub cache_mb: u64,
    /// Congestion control: cubic (best on loopback/LAN) or bbr (10x faster under random loss, e.g. Wi-Fi).
    #[arg(long, default_value = "cubic")]
    pub congestion: String,
    /// Web viewer address: the page over HTTPS (TCP) and WebTransport (UDP) on this port
    /// (default: the --listen address, port + 1). Without --cert/--key the certificate is
    /// generated for every address and name of this machine (browsers show a one-time
    /// warning); listen on 0.0.0.0 for a headset on the LAN: one URL per LAN address is printed
    /// and the first is shown as a QR code.
    #[arg(long, conflicts_with = "no_web")]
    pub web: Option<SocketAddr>,
    /// Do not serve the web viewer.
    #[arg(long)]
    pub no_web: bool,
    /// Add styles while serving: a painting (PNG, JPEG) put in this folder is trained as a new
    /// layer of --styles-run (its first layer's options, as `snerf stylize` trains one), baked
    /// onto the served asset's geometry, written into the asset (atomically, the styles there
    /// kept) and offered to every client; sessions watching the listing are told. A painting
    /// whose style the asset has is not trained again. Clients may also ask for one of the
    /// installed paintings (`painting:KEY`, `bash scripts/setup-styles.sh`) the listing
    /// offers; they never send a file. Each added style prints a JSON line on stdout
    /// (`"event": "style_added"`, train and bake seconds). PATH must be the multi-style asset
    /// `snerf bake SRUN` wrote.
    #[arg(long, requires = "styles_run")]
    pub styles_dir: Option<PathBuf>,
    /// The layered stylize run (`snerf stylize --style A --style B --out SRUN`) the served
    /// asset was baked from: new layers go to SRUN/layers/NAME and SRUN/layers.json.
    #[arg(long, requires = "styles_dir")]
    pub styles_run: Option<PathBuf>,
    /// Seconds between looks at --styles-dir.
    #[arg(long, default_value_t = 2.0, value_parser = crate::args::positive)]
    pub styles_poll: f64,
    /// Model directory for the new layers' stylizer (default $SNERF_MODELS or
    /// ~/.cache/snerf/models), as `snerf stylize --models`.
    #[arg(long, requires = "styles_dir")]
    pub models: Option<PathBuf>,
}

/// The web viewer's address: `--web`, else the QUIC address's port + 1 (0 stays 0).
fn web_addr(a: &ServeArgs) -> Option<SocketAddr> {
    if a.no_web {
        return None;
    }
    a.web.or_else(|| {
        let port = match a.listen.port() {
            0 => 0,
            p => p.checked_add(1)?,
        };
        Some(SocketAddr::new(a.listen.ip(), port))
    })
}

/// Serve until Ctrl-C. With `json`, one line of JSON on stdout once the server listens
/// (address, fingerprint, URL, token unless it came from the user's file); the human banner
/// goes to stderr. Returns Null: nothing more is printed when it stops.
pub fn serve_cmd(a: &ServeArgs, json: bool) -> Result<Value> {
    let mut o = ServeOptions::new(a.path.clone(), a.listen);
    o.state_dir = a.state.clone();
    o.cert = a.cert.clone();
    o.key = a.key.clone();
    o.token_file = a.token_file.clone();
    o.web = web_addr(a);
    o.limits = Limits {
        max_clients: a.max_clients,
        max_message: a.max_message,
        idle_timeout: Duration::from_secs_f64(a.idle_timeout.min(86400.0)),
        stall_timeout: Duration::from_secs_f64(a.stall_timeout.min(86400.0)),
        send_budget: a.send_budget,
        max_streams: a.max_streams,
        congestion: a.congestion.parse::<Congestion>()?,
        auth_timeout: Duration::from_secs_f64(a.auth_timeout),
        max_pending_per_ip: a.max_pending_per_ip,
        cache_bytes: a.cache_mb << 20,
        ..Limits::default()
    };
    let path = crate::args::pj(&a.path);
    // Checked before the server starts: a wrong run or asset is an error now, not later.
    let mut styles = match (&a.styles_dir, &a.styles_run) {
        (Some(d), Some(r)) => Some(styles_dir::StylesDir::open(d, r, &a.path, a.models.clone(), Duration::from_secs_f64(a.styles_poll.min(3600.0)))?),
        _ => None,
    };
    o.offer = styles.as_mut().map(|s| s.offer());
    snerf_stream::serve_blocking_with(o, |h| {
        if let Some(Err(e)) = styles.map(|s| s.spawn(h.announcer())) {
            eprintln!("snerf serve: --styles-dir: {e:#}");
        }
        if json {
            let v = json!({
                "command": "serve",
                "path": path,
                "address": h.addr().to_string(),
                "url": h.url(""),
                "fingerprint": h.fingerprint(),
                "token": if h.token_from_file() { Value::Null } else { Value::String(h.token().to_string()) },
                "token_file": h.token_file().map(crate::args::pj),
                "created_identity": h.created_identity(),
                // The page wants the token in the fragment: WEB_URL#token=TOKEN.
                "web_url": h.web().map(|w| w.url()),
                // One per LAN address (empty when bound to loopback); the QR code holds
                // `web_qr` + `#token=…`.
                "web_urls": h.web().map(|w| w.lan_urls.clone()),
                "web_qr": h.web().and_then(|w| w.qr_url().map(str::to_string)),
                "web_cert_names": h.web().map(|w| w.cert_names.clone()),
                "web_cert_sha256": h.web().and_then(|w| w.cert_hash.clone()),
            });
            println!("{v}");
            use std::io::Write;
            let _ = std::io::stdout().flush();
        }
    })?;
    Ok(Value::Null)
}

#[derive(Args, Debug)]
pub struct FetchArgs {
    /// quic://HOST:PORT/ASSET (from `snerf serve`), or http(s)://HOST/NAME/manifest.json (a
    /// scene written by `snerf publish`, served by any static host or CDN).
    pub url: String,
    /// SHA-256 fingerprint of the server's certificate (printed by `snerf serve`; quic:// only).
    #[arg(long)]
    pub pin: Option<String>,
    #[command(flatten)]
    pub token: crate::args::TokenArgs,
    /// The asset file to write; an interrupted fetch resumes from OUT.part.
    #[arg(long)]
    pub out: PathBuf,
    /// https:// only: PEM certificate(s) to trust (default: the system's CA bundle), e.g. a
    /// test origin's self-signed or private CA certificate.
    #[arg(long)]
    pub ca: Option<PathBuf>,
    /// http(s):// only: parallel connections.
    #[arg(long, default_value_t = 4, value_parser = crate::args::int_in::<usize>(1, 64, ""))]
    pub parallel: usize,
    /// http(s):// only: a file holding a bearer token the host requires (private scenes:
    /// sent as `Authorization: Bearer TOKEN`).
    #[arg(long)]
    pub bearer_file: Option<PathBuf>,
}

pub fn fetch_cmd(a: &FetchArgs) -> Result<Value> {
    if a.url.starts_with("http://") || a.url.starts_with("https://") {
        let mut o = snerf_stream::cdn_client::CdnOptions { ca: a.ca.clone(), parallel: a.parallel, ..Default::default() };
        if let Some(f) = &a.bearer_file {
            let t = std::fs::read_to_string(f).with_context(|| format!("--bearer-file {}: cannot read", f.display()))?;
            o.headers.push(("Authorization".into(), format!("Bearer {}", t.trim())));
        }
        let stats = snerf_stream::cdn_client::fetch_published_blocking(&a.url, &a.out, &o)?;
        eprintln!(
            "fetched {} -> {} ({} bytes, {} objects, {} requests, {} bytes on the wire, {:.2} s)",
            a.url,
            a.out.display(),
            stats.asset_bytes,
            stats.objects,
            stats.requests,
            stats.wire_bytes,
            stats.all_s
        );
        return Ok(json!({ "command": "fetch", "url": a.url, "out": crate::args::pj(&a.out), "published": stats }));
    }
    let pin = a.pin.as_deref().context("quic:// needs --pin (the fingerprint `snerf serve` prints)")?;
    let token = a.token.resolve()?;
    let stats = snerf_stream::fetch_blocking(&a.url, pin, &token, &a.out).with_context(|| format!("fetching {}", a.url))?;
    eprintln!("fetched {} -> {} ({:?})", a.url, a.out.display(), stats);
    Ok(json!({ "command": "fetch", "url": a.url, "out": crate::args::pj(&a.out), "stats": format!("{stats:?}") }))
}

#[derive(Args, Debug)]
pub struct PublishArgs {
    /// Baked asset files (.snerf): each becomes OUT/NAME/manifest.json.
    #[arg(required = true)]
    pub assets: Vec<PathBuf>,
    /// The folder to write (created; objects already there are kept and not written again).
    #[arg(long)]
    pub out: PathBuf,
    /// Target object size, KiB (objects pack neighbouring blocks; see BENCH.md §8d).
    #[arg(long, default_value_t = snerf_stream::publish::DEFAULT_OBJECT_BYTES / 1024, value_parser = crate::args::int_in::<u64>(4, 1 << 20, ""))]
    pub object_kb: u64,
    /// Leave out the web viewer (index.html, app.js, … and the asset's shaders).
    #[arg(long)]
    pub no_web: bool,
}

/// `snerf publish`: a content-addressed layout any static host or CDN serves (PUBLISH.md).
pub fn publish_cmd(a: &PublishArgs) -> Result<Value> {
    let o = snerf_stream::publish::PublishOptions { object_bytes: a.object_kb * 1024, web: !a.no_web };
    let mut out = Vec::new();
    for asset in &a.assets {
        let p = snerf_stream::publish::publish(asset, &a.out, &o).with_context(|| format!("publishing {}", asset.display()))?;
        eprintln!(
            "published {} -> {} ({} objects: {} written, {} bytes; {} already there)",
            asset.display(),
            p.manifest.display(),
            p.objects,
            p.objects_written,
            p.bytes_written,
            p.objects_reused
        );
        out.push(p);
    }
    Ok(json!({ "command": "publish", "out": crate::args::pj(&a.out), "assets": out }))
}
