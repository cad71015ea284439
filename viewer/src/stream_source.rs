//! A `snerf-stream` live client as a viewer source: the asset is drawn as soon as it can be
//! (header, grids and view MLP arrived; blocks not yet arrived draw empty), then follows the
//! stream: changed keyframe grids first, then the blocks as they arrive. The viewer's pose
//! goes back to the server so the blocks in view come first. A style of a multi-style asset
//! switches to the file's other styles by keys 1..9 once it is complete: each switch streams
//! the new style's colour part only (`snerf_stream::restyle`), written over the asset held on a
//! thread of its own; the window then gets the new style whole (same geometry: the view stays).

use snerf_asset::{Asset, Recolour};
use snerf_stream::proto::AssetInfo;
use snerf_stream::LiveAsset;
use std::sync::mpsc;
use std::sync::{Arc, Mutex};

use crate::window::{AssetSource, AssetUpdate};

pub struct StreamSource {
    live: LiveAsset,
    sent: bool,
    grids: Vec<Vec<u32>>,
    generation: u64,
    styles: Option<Styles>,
}

/// A style shown after a switch: its asset, information and `Recolour`.
type Held = (Asset, AssetInfo, Recolour);
/// A multi-style file's served name and its style names.
type Names = (String, Vec<String>);

/// What switching styles over the stream needs: the server, the file's style names (from its
/// listing, read in the background), the style held after a switch, and a switch under way.
struct Styles {
    /// `quic://HOST:PORT/` of the server, its pin and token.
    base: String,
    pin: String,
    token: String,
    /// (the file's served name, its style names), once the listing has come.
    names: Arc<Mutex<Option<Names>>>,
    /// After a switch: the style shown (its asset and information) and its `Recolour`.
    held: Option<Held>,
    /// The style on screen after the last switch that worked (a failed switch leaves no
    /// `held`: the window still shows this one, and the next switch starts from the live
    /// asset, which a switch recolours whole).
    shown: Option<String>,
    running: Option<(String, mpsc::Receiver<anyhow::Result<Held>>)>,
}

impl StreamSource {
    pub fn new(live: LiveAsset) -> StreamSource {
        StreamSource { live, sent: false, grids: Vec::new(), generation: 0, styles: None }
    }

    /// Connect to `quic://HOST:PORT/ASSET` (pinned certificate, access token).
    pub fn connect(url: &str, pin: &str, token: &str) -> anyhow::Result<StreamSource> {
        let mut s = StreamSource::new(LiveAsset::connect(url, pin, token)?);
        let (hp, asset) = snerf_stream::parse_url(url)?;
        let names = Arc::new(Mutex::new(None));
        let (n2, base) = (names.clone(), format!("quic://{hp}/"));
        let (b2, p2, t2) = (base.clone(), pin.to_string(), token.to_string());
        // The listing says whether the asset is a style of a multi-style file and names its
        // styles; without it (an older server, an error) there are simply no style keys. The
        // session stays open for such a file: a style the server adds later (`snerf serve
        // --styles-dir`) gets the next key.
        std::thread::spawn(move || {
            let Ok(mut watch) = snerf_stream::watch::StyleWatch::open(&b2, &p2, &t2) else { return };
            let mut file = None;
            for e in std::mem::take(&mut watch.listing) {
                let Some(st) = e.styles else { continue };
                let ours = asset == e.name || st.iter().any(|s| asset == format!("{}.{}", e.name, s.name));
                if ours {
                    let names: Vec<String> = st.into_iter().map(|s| s.name).collect();
                    eprintln!("snerf view: styles {} (keys 1..{} switch, by colour alone)", names.join(", "), names.len().min(9));
                    file = Some(e.name.clone());
                    *n2.lock().unwrap_or_else(|p| p.into_inner()) = Some((e.name, names));
                }
            }
            let Some(file) = file else { return };
            // until the session ends (the server stopping, the window closed)
            while let Ok(next) = watch.next(std::time::Duration::from_secs(3600)) {
                let Some(n) = next.filter(|n| n.asset == file) else { continue };
                let names: Vec<String> = n.styles.into_iter().map(|s| s.name).collect();
                eprintln!("snerf view: a new style, {} (key {}): styles {}", names.last().map(String::as_str).unwrap_or(""), names.len(), names.join(", "));
                *n2.lock().unwrap_or_else(|p| p.into_inner()) = Some((n.asset, names));
            }
        });
        s.styles = Some(Styles { base, pin: pin.to_string(), token: token.to_string(), names, held: None, shown: None, running: None });
        Ok(s)
    }

    /// The client underneath (completion, errors, bytes received).
    pub fn live(&self) -> &LiveAsset {
        &self.live
    }
}

impl AssetSource for StreamSource {
    fn poll(&mut self) -> Option<AssetUpdate> {
        if let Some(st) = &mut self.styles {
            if let Some((name, rx)) = &st.running {
                match rx.try_recv() {
                    Err(mpsc::TryRecvError::Empty) => {}
                    Err(mpsc::TryRecvError::Disconnected) => st.running = None,
                    Ok(Err(e)) => {
                        eprintln!("snerf view: switching to {name}: {e:#}");
                        st.running = None;
                    }
                    Ok(Ok((asset, info, recolour))) => {
                        st.running = None;
                        let whole = asset.clone();
                        st.shown = Some(info.name.clone());
                        st.held = Some((asset, info, recolour));
                        return Some(AssetUpdate::Whole(Box::new(whole)));
                    }
                }
            }
        }
        let g = self.live.generation();
        if self.sent && g == self.generation {
            return None;
        }
        if !self.sent {
            // Take the arrival list before copying the asset: a block that lands between the
            // two is then both in the copy and sent again (harmless), never in neither.
            self.live.take_new_blocks();
            let whole = self.live.with_asset(|a| a.clone())?;
            self.grids = whole.grids.clone();
            self.sent = true;
            self.generation = g;
            return Some(AssetUpdate::Whole(Box::new(whole)));
        }
        // a changed keyframe grid first, then the new blocks
        let changed = self.live.with_asset(|a| {
            a.grids.iter().enumerate().find(|(f, grid)| self.grids.get(*f) != Some(*grid)).map(|(f, grid)| (f, grid.clone()))
        })?;
        if let Some((f, entries)) = changed {
            if self.grids.len() <= f {
                self.grids.resize(f + 1, Vec::new());
            }
            self.grids[f] = entries.clone();
            return Some(AssetUpdate::Grid { frame: f as u32, entries });
        }
        self.generation = g;
        let new = self.live.take_new_blocks();
        if new.is_empty() {
            return None;
        }
        let blocks = self.live.with_asset(|a| new.iter().filter_map(|&i| a.block(i).map(|b| (i, b.to_vec()))).collect())?;
        Some(AssetUpdate::Blocks(blocks))
    }

    fn set_pose(&mut self, eye: [f32; 3], forward: [f32; 3]) {
        self.live.set_pose(eye, forward);
    }

    fn select_style(&mut self, i: usize) -> Option<String> {
        let st = self.styles.as_mut()?;
        let (stem, names) = st.names.lock().unwrap_or_else(|p| p.into_inner()).clone()?;
        let style = names.get(i)?.clone();
        let target = format!("{stem}.{style}");
        let shown = match (&st.running, &st.shown) {
            (Some((n, _)), _) => n.clone(),
            (None, Some(n)) => n.clone(),
            (None, None) => self.live.info().name.clone(),
        };
        let first = shown == stem && i == 0;
        if st.running.is_some() || target == shown || first || !self.live.is_complete() {
            return None;
        }
        let (mut asset, info, recolour) = match st.held.take() {
            Some(h) => h,
            None => {
                let a = self.live.with_asset(|a| a.clone())?;
                let r = Recolour::new(&a);
                (a, self.live.info().clone(), r)
            }
        };
        let (tx, rx) = mpsc::channel();
        let (url, pin, token) = (format!("{}{}", st.base, target), st.pin.clone(), st.token.clone());
        std::thread::spawn(move || {
            let mut recolour = recolour;
            let r = snerf_stream::restyle::switch_style_blocking(&url, &pin, &token, &mut asset, &info, None, &mut recolour);
            let _ = tx.send(r.map(|sw| (asset, sw.info, recolour)));
        });
        st.running = Some((target, rx));
        Some(style)
    }

    fn status(&self) -> Option<String> {
        if let Some((name, _)) = self.styles.as_ref().and_then(|s| s.running.as_ref()) {
            return Some(format!("switching to {name}"));
        }
        if let Some(e) = self.live.error() {
            return Some(format!("stream error: {e}"));
        }
        (!self.live.is_complete()).then(|| format!("streaming: {:.1} MB", self.live.bytes_received() as f64 / 1e6))
    }
}
