//! Thumbnails for the listing: each asset's start view, rendered by the CPU reference
//! (`snerf_asset::render`) at a stamp size, cached by path, size and modification time so
//! each file is read and rendered once. Only clients that ask get them (`list` with
//! `thumbs: true`: the web page), so the native listing stays small.

use base64::Engine;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::SystemTime;

use crate::proto::Thumb;

/// Thumbnail size (the orbit's 40° start view).
pub const THUMB_W: u32 = 64;
pub const THUMB_H: u32 = 48;
/// Files larger than this get no thumbnail (reading one would hold up the listing).
const MAX_FILE: u64 = 512 << 20;

/// A file's size and modification time: a cached thumbnail is redrawn when either changes.
type Stamp = (u64, Option<SystemTime>);

#[derive(Default)]
pub struct Thumbs {
    cache: Mutex<HashMap<PathBuf, (Stamp, Option<Thumb>)>>,
}

impl Thumbs {
    /// The thumbnail of `path`, from the cache or rendered now (blocking: call it off the
    /// async workers). None for an unreadable or oversized file.
    pub fn get(&self, path: &Path) -> Option<Thumb> {
        let meta = std::fs::metadata(path).ok()?;
        let stamp: Stamp = (meta.len(), meta.modified().ok());
        if let Some((s, t)) = self.cache.lock().ok()?.get(path) {
            if *s == stamp {
                return t.clone();
            }
        }
        let t = if meta.len() <= MAX_FILE { render(path) } else { None };
        self.cache.lock().ok()?.insert(path.to_path_buf(), (stamp, t.clone()));
        t
    }
}

/// The start view as RGB8, base64.
pub fn render(path: &Path) -> Option<Thumb> {
    let bytes = std::fs::read(path).ok()?;
    let asset = snerf_asset::Asset::from_bytes(&bytes).ok()?;
    let cam = snerf_asset::orbit(&asset.header, 1, 0, THUMB_W, THUMB_H, 40.0);
    let t0 = asset.header.frames.as_ref().and_then(|f| f.first()).map_or(0.0, |k| k.time);
    let frame = snerf_asset::render(&asset, &cam, t0);
    let rgb: Vec<u8> = frame.rgb.iter().map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8).collect();
    Some(Thumb { width: THUMB_W, height: THUMB_H, rgb: base64::engine::general_purpose::STANDARD.encode(rgb) })
}
