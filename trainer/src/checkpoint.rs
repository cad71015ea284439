//! Checkpoints: everything needed to resume training or render, in one file written
//! atomically (temp file + rename), versioned and checksummed.
//!
//! Layout: magic `SNERFCKP`, u32 version, u64 header length, JSON header (configs, scene
//! space, progress, curve), then little-endian arrays: params, Adam m, Adam v (f32 each),
//! occupancy depth (f32 x res³), occupancy mask (u8 x res³), and a u64 checksum of all
//! bytes before it.

use std::fs;
use std::path::Path;

use anyhow::{bail, ensure, Context, Result};
use serde::{Deserialize, Serialize};

use crate::adam::Adam;
use crate::field::Field;
use crate::occupancy::Occupancy;
use crate::space::SceneSpace;
use crate::model::Model;
use crate::train::{CurvePoint, TrainConfig, Trainer};

pub const MAGIC: &[u8; 8] = b"SNERFCKP";
pub const VERSION: u32 = 1;
pub const FILE_NAME: &str = "checkpoint.snerfck";

#[derive(Serialize, Deserialize)]
struct Header {
    cfg: TrainConfig,
    space: SceneSpace,
    step: u64,
    train_seconds: f64,
    samples_seen: u64,
    curve: Vec<CurvePoint>,
    occupancy_res: usize,
    occupancy_step: f32,
    params: usize,
    adam_step: u64,
    adam_betas: (f32, f32, f32),
}

/// Everything a checkpoint holds.
#[derive(Clone)]
pub struct Checkpoint {
    pub cfg: TrainConfig,
    pub model: Model,
    pub adam: Adam,
    pub step: u64,
    pub train_seconds: f64,
    pub samples_seen: u64,
    pub curve: Vec<CurvePoint>,
}

/// FNV-1a over 8-byte words (fast enough for hundreds of MB, catches flips and truncation).
/// The checkpoint's integrity checksum (FNV-style over 8-byte words).
pub fn checksum(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut chunks = bytes.chunks_exact(8);
    for c in &mut chunks {
        h ^= u64::from_le_bytes(c.try_into().unwrap());
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    for &b in chunks.remainder() {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

fn push_f32s(buf: &mut Vec<u8>, xs: &[f32]) {
    buf.reserve(xs.len() * 4);
    for x in xs {
        buf.extend_from_slice(&x.to_le_bytes());
    }
}

pub fn save(trainer: &Trainer, path: &Path) -> Result<()> {
    let m = &trainer.model;
    // A checkpoint that could not be loaded again, or a diverged field, must not replace the
    // last good one.
    trainer.cfg.validate()?;
    ensure!(
        m.field.params.iter().all(|p| p.is_finite()),
        "the field diverged (non-finite parameters at step {}); {} keeps its last good state",
        trainer.step,
        path.display()
    );
    let header = Header {
        cfg: trainer.cfg.clone(),
        space: m.space.clone(),
        step: trainer.step,
        train_seconds: trainer.train_seconds,
        samples_seen: trainer.samples_seen,
        curve: trainer.curve.clone(),
        occupancy_res: m.occ.res,
        occupancy_step: m.occ.step,
        params: m.field.params.len(),
        adam_step: trainer.adam.step,
        adam_betas: (trainer.adam.beta1, trainer.adam.beta2, trainer.adam.eps),
    };
    let json = serde_json::to_vec(&header)?;
    let mut buf = Vec::new();
    buf.extend_from_slice(MAGIC);
    buf.extend_from_slice(&VERSION.to_le_bytes());
    buf.extend_from_slice(&(json.len() as u64).to_le_bytes());
    buf.extend_from_slice(&json);
    push_f32s(&mut buf, &m.field.params);
    push_f32s(&mut buf, &trainer.adam.m);
    push_f32s(&mut buf, &trainer.adam.v);
    push_f32s(&mut buf, &m.occ.depth);
    buf.extend(m.occ.allowed.iter().map(|&a| a as u8));
    let sum = checksum(&buf);
    buf.extend_from_slice(&sum.to_le_bytes());
    write_atomic(path, &buf)
}

pub fn load(path: &Path) -> Result<Checkpoint> {
    let bytes = fs::read(path).with_context(|| format!("{}: cannot read checkpoint", path.display()))?;
    let name = path.display();
    ensure!(bytes.len() >= 28, "{name}: not a snerf checkpoint (file is {} bytes)", bytes.len());
    ensure!(&bytes[..8] == MAGIC, "{name}: not a snerf checkpoint (bad magic bytes)");
    let version = u32::from_le_bytes(bytes[8..12].try_into().unwrap());
    if version != VERSION {
        bail!("{name}: checkpoint version {version}, this snerf reads version {VERSION}; retrain or use a matching snerf");
    }
    let body = &bytes[..bytes.len() - 8];
    let stored = u64::from_le_bytes(bytes[bytes.len() - 8..].try_into().unwrap());
    ensure!(checksum(body) == stored, "{name}: checkpoint is corrupt or truncated (checksum mismatch)");
    let hlen = u64::from_le_bytes(bytes[12..20].try_into().unwrap()) as usize;
    ensure!(hlen <= body.len() - 20, "{name}: header length {hlen} exceeds the file");
    let header: Header =
        serde_json::from_slice(&bytes[20..20 + hlen]).with_context(|| format!("{name}: bad checkpoint header"))?;
    header.cfg.validate().with_context(|| format!("{name}: bad checkpoint header"))?;
    let field = Field::new(header.cfg.field.clone(), 0).with_context(|| format!("{name}: bad field config"))?;
    ensure!(
        field.params.len() == header.params,
        "{name}: header says {} parameters, its field config needs {}",
        header.params,
        field.params.len()
    );
    let cells = header.occupancy_res.checked_pow(3).filter(|&c| c <= 1 << 30).context("bad occupancy size")?;
    let need = 20 + hlen + 3 * 4 * header.params + 5 * cells;
    ensure!(body.len() == need, "{name}: expected {need} bytes of data, found {}", body.len());
    let mut off = 20 + hlen;
    let mut take = |n: usize| -> Vec<f32> {
        let v = bytes[off..off + 4 * n].chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect();
        off += 4 * n;
        v
    };
    let params = take(header.params);
    let m = take(header.params);
    let v = take(header.params);
    let depth = take(cells);
    let allowed = bytes[off..off + cells].iter().map(|&b| b != 0).collect();
    let mut occ = Occupancy { res: header.occupancy_res, step: header.occupancy_step, depth, allowed, occ: Vec::new() };
    occ.refresh_bits();
    let (beta1, beta2, eps) = header.adam_betas;
    Ok(Checkpoint {
        model: Model { space: header.space, field: Field { params, ..field }, occ, pixel_rays: header.cfg.pixel_rays, pixel_footprint: header.cfg.pixel_footprint },
        adam: Adam { beta1, beta2, eps, step: header.adam_step, m, v },
        cfg: header.cfg,
        step: header.step,
        train_seconds: header.train_seconds,
        samples_seen: header.samples_seen,
        curve: header.curve,
    })
}

pub use snerf_files::{write_atomic, write_json_atomic};

// Commands have always found the image writer beside the other atomic writers here.
pub use crate::png::write_png_atomic;

