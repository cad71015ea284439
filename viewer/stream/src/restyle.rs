//! A style switch on the client side (`Hello::colour_of`, PROTOCOL.md "Style switches"): a
//! client holding one style of a multi-style file asks for another style by its colour part
//! alone and writes it into the asset it holds (`snerf_asset::Recolour`); the density stays.
//! The result is checked end to end: its file bytes hash to the new style's SHA-256.

use anyhow::{anyhow, bail, ensure, Result};
use sha2::{Digest, Sha256};
use snerf_asset::chunk::CHUNK_HEADER_LEN;
use snerf_asset::{Asset, Recolour};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

use crate::client::{open_session, receive, ClientOptions, Record};
use crate::proto::{to_hex, AssetInfo, ClientMsg, Pose, PROTOCOL_VERSION};
use crate::url::{parse_url, resolve};

/// What a switch did.
#[derive(Clone, Debug)]
pub struct Switched {
    /// The new style's asset information (the welcome's).
    pub info: AssetInfo,
    /// Record bytes received (chunk index + chunk).
    pub bytes: u64,
    pub records: u32,
    /// From the call to the welcome, to the first colour record written, to the last.
    pub welcome: Duration,
    pub first_record: Duration,
    pub complete: Duration,
}

/// Switch `held` (a complete style of a multi-style file, as `held_info` describes it) to the
/// style `url` names (`quic://HOST:PORT/NAME.STYLE`): only that style's colour part is sent,
/// blocks in view of `pose` first. On success `held` is the new style's asset, byte for byte.
pub async fn switch_style(
    url: &str,
    pin: &str,
    token: &str,
    held: &mut Asset,
    held_info: &AssetInfo,
    pose: Option<Pose>,
) -> Result<Switched> {
    let mut recolour = Recolour::new(held);
    switch_style_with(url, pin, token, held, held_info, pose, &mut recolour).await
}

/// `switch_style` with the asset's `Recolour` made beforehand (`Recolour::new(held)`, which
/// depends on the geometry alone: one serves every switch of that asset).
pub async fn switch_style_with(
    url: &str,
    pin: &str,
    token: &str,
    held: &mut Asset,
    held_info: &AssetInfo,
    pose: Option<Pose>,
    recolour: &mut Recolour,
) -> Result<Switched> {
    let t0 = Instant::now();
    recolour.restart();
    ensure!(recolour.blocks() == held.header.atlas_blocks as usize, "a Recolour made for another asset");
    let geometry = held_info
        .geometry
        .clone()
        .ok_or_else(|| anyhow!("{} is not a style of a multi-style asset: there is nothing to switch by colour", held_info.name))?;
    let (hp, name) = parse_url(url)?;
    let addr = resolve(&hp)?;
    let hello = ClientMsg::Hello {
        version: PROTOCOL_VERSION,
        token: token.to_string(),
        asset: Some(name.clone()),
        have: vec![],
        resume_id: None,
        pose,
        colour_of: Some(geometry.clone()),
    };
    let session = open_session(addr, pin, hello, &ClientOptions::default()).await?;
    let welcome = t0.elapsed();
    let info = session.asset.clone().ok_or_else(|| anyhow!("server sent no asset information"))?;
    ensure!(session.colour_only, "the server answered the switch to {} with the whole asset", name);
    ensure!(
        info.geometry.as_deref() == Some(geometry.as_str()) && info.atlas_blocks == held.header.atlas_blocks,
        "the server's {} is not of the geometry held",
        name
    );
    let bytes = Arc::new(AtomicU64::new(0));
    let (tx, mut rx) = mpsc::channel::<Record>(256);
    let conn = session.conn.clone();
    let recv_task = tokio::spawn(receive(conn.clone(), info.clone(), tx, bytes.clone(), None));
    let (mut records, mut first_record) = (0u32, None);
    let r = async {
        while records < session.sending_chunks {
            let Some(rec) = rx.recv().await else {
                bail!(
                    "the switch ended after {} of {} colour records: {}",
                    records,
                    session.sending_chunks,
                    session.close_error().map(|e| format!("{e:#}")).unwrap_or_else(|| "connection closed".into())
                );
            };
            let c = &rec.chunk;
            let tag = [c[0], c[1], c[2], c[3]];
            let crc = u32::from_le_bytes([c[8], c[9], c[10], c[11]]);
            let p = &c[CHUNK_HEADER_LEN..];
            ensure!(crc32fast::hash(p) == crc, "colour record for chunk {}: checksum mismatch", rec.index);
            recolour
                .apply(held, tag, p)
                .map_err(|e| anyhow!("server sent bad colour for chunk {}: {:#}", rec.index, e))?;
            records += 1;
            first_record.get_or_insert(t0.elapsed());
        }
        Ok(())
    }
    .await;
    session.close();
    recv_task.abort();
    r?;
    ensure!(recolour.is_complete(), "the server's colour part of {} misses blocks", name);
    let sha = to_hex(&Sha256::digest(held.to_bytes()));
    ensure!(sha == info.sha256, "after the switch the asset's SHA-256 is {}, the server's {} is {}", sha, name, info.sha256);
    Ok(Switched {
        info,
        bytes: bytes.load(Ordering::Relaxed),
        records,
        welcome,
        first_record: first_record.unwrap_or_default(),
        complete: t0.elapsed(),
    })
}

/// `switch_style_with` on a runtime of its own, for synchronous callers.
pub fn switch_style_blocking(
    url: &str,
    pin: &str,
    token: &str,
    held: &mut Asset,
    held_info: &AssetInfo,
    pose: Option<Pose>,
    recolour: &mut Recolour,
) -> Result<Switched> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| anyhow!("cannot start the tokio runtime: {e}"))?
        .block_on(switch_style_with(url, pin, token, held, held_info, pose, recolour))
}
