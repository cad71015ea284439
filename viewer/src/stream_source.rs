//! A `snerf-stream` live client as a viewer source: the asset is drawn as soon as it can be
//! (header, grids and view MLP arrived; blocks not yet arrived draw empty), then follows the
//! stream: changed keyframe grids first, then the blocks as they arrive. The viewer's pose
//! goes back to the server so the blocks in view come first.

use snerf_stream::LiveAsset;

use crate::window::{AssetSource, AssetUpdate};

pub struct StreamSource {
    live: LiveAsset,
    sent: bool,
    grids: Vec<Vec<u32>>,
    generation: u64,
}

impl StreamSource {
    pub fn new(live: LiveAsset) -> StreamSource {
        StreamSource { live, sent: false, grids: Vec::new(), generation: 0 }
    }

    /// Connect to `quic://HOST:PORT/ASSET` (pinned certificate, access token).
    pub fn connect(url: &str, pin: &str, token: &str) -> anyhow::Result<StreamSource> {
        Ok(StreamSource::new(LiveAsset::connect(url, pin, token)?))
    }

    /// The client underneath (completion, errors, bytes received).
    pub fn live(&self) -> &LiveAsset {
        &self.live
    }
}

impl AssetSource for StreamSource {
    fn poll(&mut self) -> Option<AssetUpdate> {
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

    fn status(&self) -> Option<String> {
        if let Some(e) = self.live.error() {
            return Some(format!("stream error: {e}"));
        }
        (!self.live.is_complete()).then(|| format!("streaming: {:.1} MB", self.live.bytes_received() as f64 / 1e6))
    }
}
