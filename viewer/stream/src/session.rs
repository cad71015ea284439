//! One client's `snerf/1` session, the same code for both carriers (`conn.rs`): Hello and
//! token, the asset's small parts, then its blocks in priority order for the client's pose,
//! within the send window, until the client has every chunk.

use bytes::Bytes;
use quinn::VarInt;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{watch, OwnedSemaphorePermit};
use tokio::task::JoinSet;
use tokio::time::Instant;

use crate::conn::{Conn, Recv, Send};
use crate::pending::Pending;
use crate::plan::ServedAsset;
use crate::proto::{
    code, decode_client_msg, decode_pose, encode_frame, read_frame, ClientMsg, FrameError, Pose, ServerMsg,
    PROTOCOL_VERSION,
};
use crate::shared::{log, Close, Shared};
use crate::stats::{SentBatch, ServerStats};
use crate::tls;

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
    colour_of: Option<String>,
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
        ClientMsg::AddStyle { .. } => Err(Close(code::PROTOCOL, "AddStyle before Hello".into())),
        ClientMsg::Hello {
            version,
            token,
            asset,
            have,
            resume_id,
            pose,
            colour_of,
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
                colour_of,
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
        colour_of,
    } = hello;
    let mut asset_task = false;
    if colour_of.is_some() && asset.is_none() {
        return Err(Close(code::MALFORMED, "colour_of without an asset: name the style to switch to".into()));
    }
    if let (Some(name), Some(geometry)) = (&asset, &colour_of) {
        let (name, path) = shared.resolve(Some(name))?;
        let a = shared.load(&name, &path).await?;
        let part = colour_part(&name, &a, geometry)?;
        let (records, bytes) = (part.records(), part.records_len());
        send_msg(
            &mut send,
            &ServerMsg::Welcome {
                version: PROTOCOL_VERSION,
                asset: Some(a.info()),
                resumed: false,
                sending_chunks: records,
                sending_bytes: bytes,
                colour_only: true,
            },
        )
        .await?;
        log(shared, who, &format!("switching to {} by colour ({} records, {} bytes)", name, records, bytes));
        let (view_tx, view_rx) = watch::channel(pose.filter(|p| p.validate().is_ok()));
        tasks.spawn(read_poses(conn.clone(), view_tx, shared.stats.clone()));
        tasks.spawn(stream_asset(conn.clone(), a, Sending::Colour, view_rx, shared.clone()));
        asset_task = true;
    } else if let Some(name) = asset {
        let (name, path) = shared.resolve(Some(&name))?;
        let a = shared.load(&name, &path).await?;
        let n = a.chunk_count() as usize;
        let (skip, resumed) = crate::plan::skipped(&a, &have, resume_id.as_deref());
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
                colour_only: false,
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
        tasks.spawn(stream_asset(conn.clone(), a, Sending::Whole(skip), view_rx, shared.clone()));
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
                colour_only: false,
            },
        )
        .await?;
    }
    // Control loop: List may follow; anything else is out of order.
    let mut control_open = true;
    let mut linger: Option<tokio::time::Instant> = None;
    // Set by a `list` with `watch`: the `styles` messages this session forwards.
    let mut watching: Option<tokio::sync::broadcast::Receiver<ServerMsg>> = None;
    loop {
        tokio::select! {
            m = next_update(&mut watching), if watching.is_some() => {
                if let Some(m) = m {
                    send_msg(&mut send, &m).await?;
                }
            }
            f = read_frame(recv.quic(), limits.max_message), if control_open => {
                match f {
                    Err(e) => return Err(frame_close(conn, e)),
                    Ok(None) => control_open = false,
                    Ok(Some(b)) => match decode_client_msg(&b).map_err(|e| Close(code::MALFORMED, format!("{:#}", e)))? {
                        ClientMsg::List { thumbs, watch } => {
                            // Subscribed before the listing is read, so no change falls between.
                            if watch && watching.is_none() {
                                watching = Some(shared.updates.subscribe());
                            }
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
                        ClientMsg::AddStyle { asset, painting } => {
                            let style = shared.add_style(&asset, &painting)?;
                            log(shared, who, &format!("asked to train {painting:?} as a style of {asset}"));
                            send_msg(&mut send, &ServerMsg::Training { asset, style }).await?
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

/// The next message for a watching session; None when it fell behind (what it missed is
/// dropped: each message names an asset's whole style list, so the next one makes up for it)
/// or when the server is stopping (the watch then ends).
async fn next_update(rx: &mut Option<tokio::sync::broadcast::Receiver<ServerMsg>>) -> Option<ServerMsg> {
    use tokio::sync::broadcast::error::RecvError;
    match rx.as_mut()?.recv().await {
        Ok(m) => Some(m),
        Err(RecvError::Lagged(_)) => None,
        Err(RecvError::Closed) => {
            *rx = None;
            None
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

/// The colour part a `colour_of` hello may have: the asked style's, when the client's
/// geometry is that style's file's.
fn colour_part<'a>(name: &str, a: &'a ServedAsset, geometry: &str) -> Result<&'a crate::plan::ColourPart, Close> {
    let Some(part) = a.colour.as_ref() else {
        return Err(Close(
            code::NOT_FOUND,
            format!("asset {:?} has a single style: there is no other style's colour to switch to (ask for it without colour_of)", name),
        ));
    };
    if part.geometry != geometry {
        return Err(Close(
            code::NOT_FOUND,
            format!(
                "colour_of {:?} is not the geometry of {:?} (the file's geometry changed, or it is another asset's): ask for the whole asset",
                geometry, name
            ),
        ));
    }
    Ok(part)
}

/// What a session streams: the asset's chunks but those the client holds, or (a style
/// switch) the style's colour part, each record under the index of the chunk it rewrites.
enum Sending {
    Whole(Vec<bool>),
    Colour,
}

impl Sending {
    /// The record of block `b` (an index into `blks`): (chunk index, chunk bytes).
    fn block(&self, a: &ServedAsset, b: u32) -> (u32, Bytes, u64) {
        let c = a.blks[b as usize].chunk;
        match (self, &a.colour) {
            (Sending::Colour, Some(p)) => (c, p.block_bytes(b), p.record_len(b)),
            _ => (c, a.chunk_bytes(c), a.record_len(c)),
        }
    }
}

async fn write_batch(
    mut s: Send,
    records: Vec<(u32, Bytes)>,
    shared: Arc<Shared>,
) -> Result<u64, Close> {
    let mut bufs = Vec::with_capacity(records.len() * 2);
    let mut bytes = 0u64;
    for (i, chunk) in records {
        bytes += 4 + chunk.len() as u64;
        bufs.push(Bytes::copy_from_slice(&i.to_le_bytes()));
        bufs.push(chunk);
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
    sending: Sending,
    mut view_rx: watch::Receiver<Option<Pose>>,
    shared: Arc<Shared>,
) -> Result<(), Close> {
    let whole = |i: u32| (i, asset.chunk_bytes(i));
    let colour = matches!(sending, Sending::Colour);
    let skip = match &sending {
        Sending::Whole(skip) => skip.clone(),
        Sending::Colour => vec![true; asset.chunk_count() as usize],
    };
    let limits = shared.limits.clone();
    let max_streams = limits.max_streams.max(1);
    let mut writers: JoinSet<Result<u64, Close>> = JoinSet::new();
    let mut outstanding = 0u64;
    let mut prio = i32::MAX - 1;
    let joined = |r: Result<Result<u64, Close>, tokio::task::JoinError>| -> Result<u64, Close> {
        r.map_err(|_| Close(code::INTERNAL, "writer task failed".into()))?
    };
    // the small parts first: HEAD, VMLP, GRIDs; of a colour part, its view MLP
    let meta: Vec<(u32, Bytes)> = match (&sending, &asset.colour) {
        (Sending::Colour, Some(p)) => p.mlp.iter().map(|(r, v)| (*v, p.bytes.slice(r.clone()))).collect(),
        _ => asset.meta.iter().copied().filter(|&i| !skip[i as usize]).map(whole).collect(),
    };
    if !meta.is_empty() {
        let mut s = open_stream(&conn, limits.stall_timeout).await?;
        let _ = s.quic().set_priority(prio);
        prio -= 1;
        let bytes: u64 = meta.iter().map(|(_, b)| 4 + b.len() as u64).sum();
        outstanding += bytes;
        if colour {
            shared.stats.colour_bytes_sent.fetch_add(bytes, Ordering::Relaxed);
            shared.stats.colour_records_sent.fetch_add(meta.len() as u64, Ordering::Relaxed);
        }
        writers.spawn(write_batch(s, meta, shared.clone()));
    }
    let mut remaining: Vec<u32> = (0..asset.blks.len() as u32)
        .filter(|&b| colour || !skip[asset.blks[b as usize].chunk as usize])
        .collect();
    let sort = |remaining: &mut Vec<u32>, pose: Option<Pose>| crate::plan::order_blocks(&asset, remaining, pose);
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
            let (c, chunk, len) = sending.block(&asset, b);
            bytes += len;
            batch.push((c, chunk));
            remaining.pop();
        }
        if colour {
            shared.stats.colour_bytes_sent.fetch_add(bytes, Ordering::Relaxed);
            shared.stats.colour_records_sent.fetch_add(batch.len() as u64, Ordering::Relaxed);
        }
        if limits.log_sends {
            if let Ok(mut log) = shared.stats.send_log.lock() {
                let chunks = batch.iter().map(|r| r.0).collect();
                log.push(SentBatch { pose: pose_now, chunks, bytes, colour });
            }
        }
        let mut s = open_stream(&conn, limits.stall_timeout).await?;
        let _ = s.quic().set_priority(prio);
        prio = prio.saturating_sub(1).max(i32::MIN + 1);
        outstanding += bytes;
        paced_bytes += bytes;
        writers.spawn(write_batch(s, batch, shared.clone()));
    }
    while let Some(r) = writers.join_next().await {
        joined(r)?;
    }
    if !skip[asset.end as usize] {
        let mut s = open_stream(&conn, limits.stall_timeout).await?;
        let _ = s.quic().set_priority(i32::MIN);
        write_batch(s, vec![whole(asset.end)], shared.clone()).await?;
    } else {
        // Nothing more to send; wait for the client to close.
        std::future::pending::<()>().await;
    }
    Ok(())
}
