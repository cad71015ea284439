//! `snerf/1` over HTTPS requests: the carrier for browsers without WebTransport (Safari and
//! Firefox today, older headset browsers), on the page's own HTTPS port (PROTOCOL.md, "Over
//! HTTPS").
//!
//! Each request is a `POST /snerf/1/http?part=control|data` whose body is the client's
//! control frames exactly as on the control stream (`u32 length` + JSON: a `hello`, then
//! optionally a `list`); the token, the asset, the `have` ranges with their `resume_id` and
//! the pose all ride in that `hello`. The answer to `part=control` is the server's control
//! frames (`welcome`, then `listing` when asked); the answer to `part=data` is the next batch
//! of records (`u32 chunk index` + chunk, as on a data stream): the small parts first, then
//! blocks in the order `plan::order_blocks` gives for that pose (the order QUIC and
//! WebTransport send in), then `END` once the client holds everything else.
//!
//! Why requests rather than a WebSocket carrying the streams: the server keeps no state per
//! client (the `hello` says what the client holds and where it looks), so resuming after a
//! lost connection is just the next request, a pose change reorders from the next batch on,
//! back-pressure is the client asking only when it has read the last answer, and the only
//! new code on the server is this file; the page server's limits (per address, request-head
//! and write deadlines) bound it like the page. What it gives up against WebTransport: one
//! round trip per batch, and no datagrams (the pose waits for the next request).
//!
//! Refusals send nothing of the asset: a wrong token is 401, an unknown asset 404, a body
//! that does not decode 400, one over `Limits::max_message` 413, a request whose `Origin` is
//! not this server's page 403. The snerf/1 close code is the first word of an error's body.

use std::sync::atomic::Ordering;

use crate::proto::{code, decode_client_msg, encode_frame, split_frame, ClientMsg, ServerMsg, PROTOCOL_VERSION};
use crate::shared::{Close, Shared};

/// The path of the requests.
pub const HTTP_SESSION_PATH: &str = "/snerf/1/http";

/// An answer: HTTP status and body (records or control frames for 200, `CODE reason` text
/// otherwise). The page server (`page.rs`) writes it.
pub(crate) struct Answer {
    pub status: u16,
    pub body: Vec<u8>,
}

/// The answer to one request. `origin_ok`: its `Origin` is this server's page.
pub(crate) async fn answer(shared: &Shared, query: &str, body: &[u8], origin_ok: bool) -> Answer {
    if !origin_ok {
        shared.stats.unauthorized.fetch_add(1, Ordering::Relaxed);
        return error(Close(code::UNAUTHORIZED, "the request does not come from this server's page".into()), 403);
    }
    let r = match query {
        "part=control" => control(shared, body).await,
        "part=data" => data(shared, body).await,
        _ => Err(Close(code::MALFORMED, "part=control or part=data".into())),
    };
    match r {
        Ok(body) => Answer { status: 200, body },
        Err(c) => {
            match c.0 {
                code::UNAUTHORIZED => shared.stats.unauthorized.fetch_add(1, Ordering::Relaxed),
                code::NOT_FOUND => 0,
                _ => shared.stats.protocol_errors.fetch_add(1, Ordering::Relaxed),
            };
            let status = match c.0 {
                code::UNAUTHORIZED => 401,
                code::NOT_FOUND => 404,
                code::TOO_LARGE => 413,
                code::INTERNAL => 500,
                _ => 400,
            };
            error(c, status)
        }
    }
}

fn error(c: Close, status: u16) -> Answer {
    Answer { status, body: format!("{} {}", c.0, c.1).into_bytes() }
}

/// The client's frames: a `hello` first, then anything else it sent.
fn frames(shared: &Shared, body: &[u8]) -> Result<Vec<ClientMsg>, Close> {
    let mut out = Vec::new();
    let mut rest = body;
    while !rest.is_empty() {
        let (frame, after) = split_frame(rest, shared.limits.max_message)
            .map_err(|e| Close(code::TOO_LARGE, format!("{e:#}")))?
            .ok_or_else(|| Close(code::MALFORMED, "truncated frame".into()))?;
        out.push(decode_client_msg(frame).map_err(|e| Close(code::MALFORMED, format!("{e:#}")))?);
        rest = after;
    }
    match out.first() {
        Some(ClientMsg::Hello { version, token, .. }) => {
            if *version != PROTOCOL_VERSION {
                return Err(Close(code::VERSION, format!("protocol version {version} not supported")));
            }
            if !crate::tls::token_eq(token, &shared.token) {
                return Err(Close(code::UNAUTHORIZED, "invalid access token".into()));
            }
        }
        _ => return Err(Close(code::PROTOCOL, "the first frame must be hello".into())),
    }
    if out.iter().skip(1).any(|m| matches!(m, ClientMsg::Hello { .. })) {
        return Err(Close(code::PROTOCOL, "duplicate Hello".into()));
    }
    Ok(out)
}

/// What the `hello` asks of an asset: the asset, which chunks not to send, whether the
/// `have` ranges were honoured, and the pose.
struct Asked {
    asset: std::sync::Arc<crate::plan::ServedAsset>,
    skip: Vec<bool>,
    resumed: bool,
    pose: Option<crate::proto::Pose>,
}

async fn asked(shared: &Shared, hello: &ClientMsg) -> Result<Option<Asked>, Close> {
    let ClientMsg::Hello { asset: Some(name), have, resume_id, pose, colour_of, .. } = hello else {
        return Ok(None);
    };
    // A style switch keeps a session open while its colour part streams; these requests
    // keep none, and the page switches over HTTPS by asking for the whole style instead.
    if colour_of.is_some() {
        return Err(Close(
            code::PROTOCOL,
            "a switch of style by colour alone (colour_of) needs QUIC or WebTransport; over HTTPS ask for the whole asset".into(),
        ));
    }
    let (name, path) = shared.resolve(Some(name))?;
    let asset = shared.load(&name, &path).await?;
    let (skip, resumed) = crate::plan::skipped(&asset, have, resume_id.as_deref());
    Ok(Some(Asked { asset, skip, resumed, pose: pose.filter(|p| p.validate().is_ok()) }))
}

async fn control(shared: &Shared, body: &[u8]) -> Result<Vec<u8>, Close> {
    let msgs = frames(shared, body)?;
    let mut out = Vec::new();
    let welcome = match asked(shared, &msgs[0]).await? {
        Some(a) => {
            let sending: Vec<u32> = (0..a.skip.len() as u32).filter(|&i| !a.skip[i as usize]).collect();
            ServerMsg::Welcome {
                version: PROTOCOL_VERSION,
                asset: Some(a.asset.info()),
                resumed: a.resumed,
                sending_chunks: sending.len() as u32,
                sending_bytes: crate::plan::records_len(&a.asset, &sending),
                colour_only: false,
            }
        }
        None => ServerMsg::Welcome { version: PROTOCOL_VERSION, asset: None, resumed: false, sending_chunks: 0, sending_bytes: 0, colour_only: false },
    };
    out.extend(encode_frame(&welcome));
    for m in &msgs[1..] {
        // `watch` asks for later messages, which a request's one answer cannot carry: ignored.
        if let ClientMsg::List { thumbs, .. } = m {
            let mut assets = shared.list();
            if *thumbs {
                // Rendering a thumbnail blocks: off the async workers' queue.
                tokio::task::block_in_place(|| {
                    for a in &mut assets {
                        a.thumb = shared.asset_path(&a.name).and_then(|p| shared.thumbs.get(&p));
                    }
                });
            }
            out.extend(encode_frame(&ServerMsg::Listing { assets }));
        }
    }
    Ok(out)
}

/// The next batch: every small part the client lacks, else up to `2 × batch_bytes` of blocks
/// most urgent for its pose first, else `END`; empty when the client holds everything.
async fn data(shared: &Shared, body: &[u8]) -> Result<Vec<u8>, Close> {
    let msgs = frames(shared, body)?;
    let Some(a) = asked(shared, &msgs[0]).await? else {
        return Err(Close(code::PROTOCOL, "part=data needs an asset in the hello".into()));
    };
    let mut batch: Vec<u32> = a.asset.meta.iter().copied().filter(|&i| !a.skip[i as usize]).collect();
    if batch.is_empty() {
        let mut blocks: Vec<u32> =
            (0..a.asset.blks.len() as u32).filter(|&b| !a.skip[a.asset.blks[b as usize].chunk as usize]).collect();
        crate::plan::order_blocks(&a.asset, &mut blocks, a.pose);
        let target = 2 * shared.limits.batch_bytes as u64;
        let mut bytes = 0;
        while let Some(b) = blocks.pop() {
            let c = a.asset.blks[b as usize].chunk;
            batch.push(c);
            bytes += a.asset.record_len(c);
            if bytes >= target {
                break;
            }
        }
    }
    if batch.is_empty() && !a.skip[a.asset.end as usize] {
        batch.push(a.asset.end);
    }
    let mut out = Vec::with_capacity(crate::plan::records_len(&a.asset, &batch) as usize);
    for &i in &batch {
        out.extend_from_slice(&i.to_le_bytes());
        out.extend_from_slice(&a.asset.chunk_bytes(i));
    }
    shared.stats.streams_started.fetch_add(1, Ordering::Relaxed);
    shared.stats.streams_completed.fetch_add(1, Ordering::Relaxed);
    shared.stats.bytes_sent.fetch_add(out.len() as u64, Ordering::Relaxed);
    Ok(out)
}
