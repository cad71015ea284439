//! snerf-stream: QUIC streaming of baked snerf assets (protocol `snerf/1`, see PROTOCOL.md).
//!
//! - `server`: `serve` / `serve_blocking` (`_with`: a callback gets the ready server's
//!   address, fingerprint and token as data) / `start` / `spawn` — a quinn endpoint serving a
//!   directory of `.snerf` files or one file, token-authenticated, self-signed certificate.
//! - `client`: `fetch` — headless download to a complete, checksum-verified file, resumable.
//! - `live`: `LiveAsset` — progressive client for the viewer (renders while blocks arrive).
//! - `restyle`: `switch_style` — a style switch by colour alone (a multi-style asset's other
//!   style, written over the one held); `watch`: hearing of styles a server adds while it
//!   serves (`server::Announcer` on the server's side).
//! - `bench`: `snerf bench stream` (QUIC vs TCP side by side, time to first view).
//! - `web`: the web viewer — its certificate (every name in `lan`), `snerf/1` over
//!   WebTransport beside the native endpoint (`ServeOptions::web`), and `page`: the page
//!   (`web/`, embedded) over HTTPS, bounded against hostile peers.
//! - `session`: one client's `snerf/1` session, the same code for both carriers (`conn`);
//!   `shared`: what all connections of a server share; `limits`: what they may use;
//!   `pending`: admission (per address, in total); `stats`: counters.
//! - `glsl`: the march shader translated to GLSL ES 3.00 for the page's WebGL2 renderer.
//! - `publish`: `snerf publish` — a content-addressed layout (manifest + immutable objects)
//!   any static host or CDN serves; `cdn_client`: its client (`snerf fetch https://…`), which
//!   orders its own fetches with `plan::order_blocks` and checks every object's SHA-256;
//!   `cdn_load`: many such viewers at once (`snerf bench publish`); `edge`: caddy (origin, TLS front) + varnish (caching edge) on loopback, for the tests
//!   and `snerf bench publish`.
//! - `proto`: the wire format; `tls`: certificates, fingerprints, pinning; `plan`: block
//!   priorities for a pose; `url`: `quic://HOST:PORT/ASSET`.
//!
//! Depends on `snerf-asset` only (never on the trainer).

// `%` instead of is_multiple_of keeps older toolchains building.
#![allow(clippy::manual_is_multiple_of)]

pub mod bench;
mod cache;
pub mod cdn_client;
pub mod cdn_load;
mod conn;
pub mod client;
pub mod edge;
pub mod glsl;
pub mod http_stream;
pub mod lan;
mod limits;
pub mod live;
mod pending;
mod page;
pub mod plan;
pub mod thumbs;
pub mod proto;
pub mod publish;
pub mod restyle;
pub mod server;
mod session;
mod shared;
mod stats;
pub mod tls;
pub mod url;
pub mod watch;
pub mod web;
mod web_cert;

pub use client::{fetch, fetch_blocking, fetch_with, list, list_blocking, part_path, ClientOptions, FetchStats};
pub use live::LiveAsset;
pub use proto::{Pose, ALPN, DEFAULT_PORT, PROTOCOL_VERSION};
pub use server::{
    serve, serve_blocking, serve_blocking_with, serve_with, spawn, start, Congestion, Limits,
    SentBatch, ServeOptions, ServerHandle, ServerStats,
};
pub use url::{parse_url, resolve};
