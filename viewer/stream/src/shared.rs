//! What every connection of a server shares: its limits, token, assets (loaded once, cached),
//! client slots, admission table and counters. Both carriers' sessions (`session.rs`) and the
//! web page (`page.rs`) read it; none of them owns it.

use anyhow::Result;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::SystemTime;
use tokio::sync::Semaphore;

use crate::cache::AssetCache;
use crate::limits::Limits;
use crate::pending::PendingTable;
use crate::plan::ServedAsset;
use crate::proto::{code, valid_asset_name, ListEntry};
use crate::stats::ServerStats;

pub(crate) enum Source {
    Dir(PathBuf),
    File { name: String, path: PathBuf },
}

pub(crate) struct Shared {
    pub(crate) limits: Limits,
    pub(crate) token: String,
    pub(crate) source: Source,
    pub(crate) cache: Mutex<AssetCache<ServedAsset>>,
    pub(crate) load_lock: tokio::sync::Mutex<()>,
    /// One permit per authenticated client (native and web).
    pub(crate) slots: Arc<Semaphore>,
    pub(crate) pending: Arc<PendingTable>,
    pub(crate) stats: Arc<ServerStats>,
    pub(crate) quiet: bool,
    pub(crate) thumbs: crate::thumbs::Thumbs,
    /// `Styles` messages for the sessions that watch (`List::watch`; `server::Announcer`).
    pub(crate) updates: tokio::sync::broadcast::Sender<crate::proto::ServerMsg>,
    /// Paintings clients may ask to have trained as new styles (`ClientMsg::AddStyle`).
    pub(crate) offer: Option<Offer>,
}

/// A connection-ending error: QUIC application code + reason sent to the client.
#[derive(Debug)]
pub(crate) struct Close(pub(crate) u32, pub(crate) String);

impl Shared {
    pub(crate) fn quiet(&self) -> bool {
        self.quiet
    }
}

pub(crate) fn log(shared: &Shared, who: SocketAddr, msg: &str) {
    if !shared.quiet {
        eprintln!("snerf serve: {}: {}", who, msg);
    }
}

/// Name an asset is served under: the file name without `.snerf`.
/// The style an asset name asks of the file at `path`: `scene.renoir` of the multi-style
/// file `scene.snerf` (`plan::ServedStyle`).
pub fn style_in_name<'a>(name: &'a str, path: &Path) -> Option<&'a str> {
    let stem = asset_name(path);
    name.strip_prefix(stem.as_str())?.strip_prefix('.').filter(|s| !s.is_empty())
}

pub fn asset_name(path: &Path) -> String {
    let f = path
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_default();
    f.strip_suffix(".snerf").map(str::to_string).unwrap_or(f)
}

/// The scene kind and the styles named in an asset file's header (HEAD chunk), read without
/// loading the file; None when the file does not start with a readable header.
fn header_kind(path: &Path) -> Option<(String, Option<Vec<snerf_asset::StyleInfo>>)> {
    use std::io::Read;
    let mut f = std::fs::File::open(path).ok()?;
    let mut head = [0u8; 28];
    f.read_exact(&mut head).ok()?;
    snerf_asset::chunk::check_preamble(&head[..16]).ok()?;
    if &head[16..20] != b"HEAD" {
        return None;
    }
    let len = u32::from_le_bytes([head[20], head[21], head[22], head[23]]) as usize;
    if len > 1 << 20 {
        return None;
    }
    let mut json = vec![0u8; len];
    f.read_exact(&mut json).ok()?;
    let v: serde_json::Value = serde_json::from_slice(&json).ok()?;
    let styles = v.get("styles").and_then(|s| serde_json::from_value(s.clone()).ok());
    Some((v.get("kind")?.as_str()?.to_string(), styles))
}

/// The listing of the asset file at `path`.
fn entry(name: String, size: u64, path: &Path) -> ListEntry {
    let (kind, styles) = match header_kind(path) {
        Some((k, s)) => (Some(k), s),
        None => (None, None),
    };
    ListEntry { name, size, kind, thumb: None, styles, paintings: None }
}

impl Shared {
    /// Tell every watching session the styles `asset` has now (as its file's header lists
    /// them). Returns how many sessions were told; an error when `asset` is not served or has
    /// no styles.
    pub(crate) fn announce_styles(&self, asset: &str) -> Result<usize> {
        let entry = self.list().into_iter().find(|e| e.name == asset);
        let Some(styles) = entry.as_ref().and_then(|e| e.styles.clone()) else {
            anyhow::bail!("{asset:?} is not a multi-style asset this server serves");
        };
        let told = self.updates.send(crate::proto::ServerMsg::Styles { asset: asset.to_string(), styles }).unwrap_or(0);
        if !self.quiet {
            eprintln!("snerf serve: {asset}: told {told} watching session(s) of its new style list");
        }
        Ok(told)
    }

    pub(crate) fn list(&self) -> Vec<ListEntry> {
        let mut entries = match &self.source {
            Source::File { name, path } => {
                let size = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
                vec![entry(name.clone(), size, path)]
            }
            Source::Dir(d) => {
                let mut out = Vec::new();
                if let Ok(rd) = std::fs::read_dir(d) {
                    for e in rd.flatten() {
                        let p = e.path();
                        let name = asset_name(&p);
                        if p.extension().is_some_and(|x| x == "snerf") && valid_asset_name(&name) {
                            if let Ok(m) = e.metadata() {
                                if m.is_file() {
                                    out.push(entry(name, m.len(), &p));
                                }
                            }
                        }
                    }
                }
                out.sort_by(|a, b| a.name.cmp(&b.name));
                out
            }
        };
        // the offer, less the styles the asset has by now
        if let Some(o) = &self.offer {
            for e in entries.iter_mut().filter(|e| e.name == o.asset) {
                let has = |k: &String| e.styles.iter().flatten().any(|s| &s.name == k);
                e.paintings = Some(o.paintings.iter().filter(|k| !has(k)).cloned().collect());
            }
        }
        entries
    }

    /// A client's `AddStyle`: queued when this server offers that painting for that asset.
    pub(crate) fn add_style(&self, asset: &str, painting: &str) -> Result<String, Close> {
        let Some(o) = self.offer.as_ref().filter(|o| o.asset == asset) else {
            return Err(Close(code::NOT_FOUND, format!("this server trains no new styles of {asset:?}")));
        };
        // what the listing offers now: not a painting whose style the asset has by now
        let offered = self.list().into_iter().find(|e| e.name == asset).and_then(|e| e.paintings).unwrap_or_default();
        if !offered.iter().any(|k| k == painting) {
            return Err(Close(code::NOT_FOUND, format!("painting {painting:?} is not offered for {asset:?} (offered: {})", offered.join(", "))));
        }
        o.requests
            .send(painting.to_string())
            .map_err(|_| Close(code::INTERNAL, "the server no longer trains new styles".into()))?;
        Ok(painting.to_string())
    }

    /// The file of a listed asset.
    pub(crate) fn asset_path(&self, name: &str) -> Option<PathBuf> {
        self.resolve(Some(name)).ok().map(|(_, p)| p)
    }

    pub(crate) fn resolve(&self, asked: Option<&str>) -> Result<(String, PathBuf), Close> {
        let asked = asked
            .map(|a| a.strip_suffix(".snerf").unwrap_or(a))
            .filter(|a| !a.is_empty());
        match (&self.source, asked) {
            (Source::File { name, path }, None) => Ok((name.clone(), path.clone())),
            (Source::File { name, path }, Some(a)) if a == name => Ok((name.clone(), path.clone())),
            // a style of a multi-style file (`plan::style_in_name`)
            (Source::File { path, .. }, Some(a)) if style_in_name(a, path).is_some() => {
                Ok((a.to_string(), path.clone()))
            }
            (Source::File { name, .. }, Some(a)) => Err(Close(
                code::NOT_FOUND,
                format!("no asset {:?} (this server serves {:?})", a, name),
            )),
            (Source::Dir(_), None) => {
                let l = self.list();
                match l.len() {
                    1 => self.resolve(Some(&l[0].name.clone())),
                    0 => Err(Close(code::NOT_FOUND, "this server has no assets".into())),
                    _ => Err(Close(
                        code::NOT_FOUND,
                        format!(
                            "name an asset: {}",
                            l.iter()
                                .take(20)
                                .map(|e| e.name.as_str())
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    )),
                }
            }
            (Source::Dir(d), Some(a)) => {
                if !valid_asset_name(a) {
                    return Err(Close(
                        code::NOT_FOUND,
                        format!("invalid asset name {:?}", a),
                    ));
                }
                let p = d.join(format!("{}.snerf", a));
                // `STEM.STYLE`: a style of the multi-style file STEM.snerf
                let styled = a
                    .rsplit_once('.')
                    .map(|(stem, _)| d.join(format!("{}.snerf", stem)))
                    .filter(|p| p.is_file());
                if p.is_file() {
                    Ok((a.to_string(), p))
                } else if let Some(p) = styled {
                    Ok((a.to_string(), p))
                } else {
                    Err(Close(code::NOT_FOUND, format!("no asset {:?}", a)))
                }
            }
        }
    }

    pub(crate) async fn load(&self, name: &str, path: &Path) -> Result<Arc<ServedAsset>, Close> {
        let _g = self.load_lock.lock().await;
        let meta = std::fs::metadata(path)
            .map_err(|e| Close(code::NOT_FOUND, format!("{}: {}", name, e)))?;
        let (mtime, len) = (
            meta.modified().unwrap_or(SystemTime::UNIX_EPOCH),
            meta.len(),
        );
        if let Some(a) = self.cached(|c| c.get(name, mtime, len)) {
            return Ok(a);
        }
        let (n, p) = (name.to_string(), path.to_path_buf());
        let style = style_in_name(name, path).map(str::to_string);
        let a = tokio::task::spawn_blocking(move || ServedAsset::load_style(&n, &p, style.as_deref()))
            .await
            .map_err(|e| Close(code::INTERNAL, format!("loading {}: {}", name, e)))?
            .map_err(|e| {
                if let Some(n) = e.downcast_ref::<crate::plan::NoSuchStyle>() {
                    return Close(code::NOT_FOUND, format!("asset {:?}: {}", name, n));
                }
                if !self.quiet {
                    eprintln!("snerf serve: cannot serve {}: {:#}", path.display(), e);
                }
                Close(
                    code::INTERNAL,
                    format!("asset {:?} cannot be served (invalid file)", name),
                )
            })?;
        if let (Some(st), false) = (&a.styles, self.quiet) {
            eprintln!("snerf serve: {}", st.message(path, &asset_name(path)));
        }
        let a = Arc::new(a);
        self.cached(|c| c.insert(name, mtime, len, &a));
        Ok(a)
    }

    /// Run `f` on the asset cache and publish its size in the stats.
    pub(crate) fn cached<R>(&self, f: impl FnOnce(&mut AssetCache<ServedAsset>) -> R) -> R {
        let mut c = self.cache.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        let r = f(&mut c);
        self.stats.cache_bytes.store(c.bytes(), Ordering::Relaxed);
        self.stats
            .cache_evictions
            .store(c.evictions(), Ordering::Relaxed);
        r
    }
}

/// What a server offers to train as new styles of one multi-style asset: painting keys; a
/// client's accepted `add_style` sends its key to `requests` (whoever trains them listens).
#[derive(Clone, Debug)]
pub struct Offer {
    pub asset: String,
    pub paintings: Vec<String>,
    pub requests: std::sync::mpsc::Sender<String>,
}
