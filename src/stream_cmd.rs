//! `snerf serve`, `snerf fetch`: baked assets over QUIC (TLS 1.3, pinned self-signed
//! certificate, access token), and `snerf bench stream`.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_stream::{Congestion, Limits, ServeOptions};

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
    /// Simultaneous clients; more are refused.
    #[arg(long, default_value_t = 64)]
    pub max_clients: usize,
    /// Largest control message accepted, bytes.
    #[arg(long, default_value_t = 64 * 1024)]
    pub max_message: usize,
    /// Drop a silent peer after this many seconds.
    #[arg(long, default_value_t = 30.0)]
    pub idle_timeout: f64,
    /// Drop a client that stops reading for this many seconds.
    #[arg(long, default_value_t = 30.0)]
    pub stall_timeout: f64,
    /// Bytes in flight per client (back-pressure).
    #[arg(long, default_value_t = 8 << 20)]
    pub send_budget: u64,
    /// Data streams in flight per client.
    #[arg(long, default_value_t = 8)]
    pub max_streams: usize,
    /// Congestion control: cubic (best on loopback/LAN) or bbr (10x faster under random loss, e.g. Wi-Fi).
    #[arg(long, default_value = "cubic")]
    pub congestion: String,
}

pub fn serve_cmd(a: &ServeArgs) -> Result<Value> {
    let mut o = ServeOptions::new(a.path.clone(), a.listen);
    o.state_dir = a.state.clone();
    o.cert = a.cert.clone();
    o.key = a.key.clone();
    o.token_file = a.token_file.clone();
    o.limits = Limits {
        max_clients: a.max_clients.max(1),
        max_message: a.max_message.max(1024),
        idle_timeout: Duration::from_secs_f64(a.idle_timeout.max(0.1)),
        stall_timeout: Duration::from_secs_f64(a.stall_timeout.max(0.1)),
        send_budget: a.send_budget.max(64 << 10),
        max_streams: a.max_streams.max(1),
        congestion: a.congestion.parse::<Congestion>()?,
        ..Limits::default()
    };
    snerf_stream::serve_blocking(o)?;
    Ok(json!({ "command": "serve", "path": a.path }))
}

#[derive(Args, Debug)]
pub struct FetchArgs {
    /// quic://HOST:PORT/ASSET
    pub url: String,
    /// SHA-256 fingerprint of the server's certificate (printed by `snerf serve`).
    #[arg(long)]
    pub pin: String,
    /// Access token (printed by `snerf serve`).
    #[arg(long)]
    pub token: String,
    /// The asset file to write; an interrupted fetch resumes from OUT.part.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn fetch_cmd(a: &FetchArgs) -> Result<Value> {
    let stats = snerf_stream::fetch_blocking(&a.url, &a.pin, &a.token, &a.out).with_context(|| format!("fetching {}", a.url))?;
    eprintln!("fetched {} -> {} ({:?})", a.url, a.out.display(), stats);
    Ok(json!({ "command": "fetch", "url": a.url, "out": a.out, "stats": format!("{stats:?}") }))
}

pub fn bench_stream(asset: &std::path::Path, rounds: usize) -> Result<Value> {
    let r = snerf_stream::bench::run(asset, &snerf_stream::bench::BenchOptions { rounds: rounds.max(1), ..Default::default() })?;
    eprintln!("{r}");
    Ok(json!({ "command": "bench stream", "asset": asset, "report": r.to_string() }))
}
