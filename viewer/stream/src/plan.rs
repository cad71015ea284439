//! What the server knows about one served file: its bytes (shared by every client), its
//! chunk table, and for every BLKS chunk where its blocks sit in the world and which
//! keyframes use them, so the blocks can be ordered for a client's pose.

use anyhow::{anyhow, ensure, Context, Result};
use bytes::Bytes;
use sha2::{Digest, Sha256};
use snerf_asset::chunk::{
    chunks, le_u32, tag_name, PREAMBLE_LEN, TAG_BLKS, TAG_END, TAG_GRID, TAG_HEAD, TAG_SGRD, TAG_VMLP,
};
use snerf_asset::layers::is_layered;
use snerf_asset::{Asset, Header, LayeredAsset, EMPTY};
use std::ops::Range;
use std::path::{Path, PathBuf};

use crate::proto::{to_hex, AssetInfo, Pose};

/// Default diagonal field of view when a pose does not say (degrees).
pub const DEFAULT_FOV_DEG: f32 = 90.0;

#[derive(Clone, Debug)]
pub struct BlkEntry {
    /// File chunk index.
    pub chunk: u32,
    /// World-space centre of the (first) cell using the block, and a bounding radius.
    pub centre: [f32; 3],
    pub radius: f32,
    /// Keyframes using these blocks, as merged [lo, hi] ranges (inclusive).
    pub frames: Vec<(u32, u32)>,
}

pub struct ServedAsset {
    pub name: String,
    pub path: PathBuf,
    /// The whole file; clients get zero-copy slices of it.
    pub bytes: Bytes,
    pub sha256: String,
    pub header: Header,
    /// Byte range (header + payload) of every chunk, by file chunk index.
    pub ranges: Vec<Range<usize>>,
    /// HEAD, VMLP and GRID chunk indices in file order.
    pub meta: Vec<u32>,
    pub blks: Vec<BlkEntry>,
    pub end: u32,
    /// World-space centre of the grid (priority origin without a pose).
    pub origin: [f32; 3],
    /// A multi-style file (version 3): its styles, and which one these bytes are.
    pub styles: Option<ServedStyle>,
    /// Of a multi-style file: the served style's colour part, for a switch to it.
    pub colour: Option<ColourPart>,
}

/// One style's colour part as its multi-style file holds it: what a client that holds
/// another style of the file is sent to switch to this one (`Hello::colour_of`). The density
/// stays, so only the view MLP and, per block, the colour of its stored voxels travel.
pub struct ColourPart {
    /// The geometry its styles share (`geometry_id`): what a client's `colour_of` must name.
    pub geometry: String,
    /// The style's `SMLP` and `SCOL` chunks, headers included, as the file has them.
    pub bytes: Bytes,
    /// The `SMLP` chunk's range in `bytes` and the `VMLP` chunk it rewrites (none when the
    /// styles are diffuse).
    pub mlp: Option<(Range<usize>, u32)>,
    /// Per entry of `ServedAsset::blks`: the range in `bytes` of its block's `SCOL` chunk.
    pub blocks: Vec<Range<usize>>,
}

impl ColourPart {
    /// Bytes the records of the whole colour part take on the wire (each a u32 index and
    /// the chunk).
    pub fn records_len(&self) -> u64 {
        let chunks = self.blocks.len() + self.mlp.is_some() as usize;
        (self.bytes.len() + 4 * chunks) as u64
    }

    /// Records the whole colour part takes.
    pub fn records(&self) -> u32 {
        (self.blocks.len() + self.mlp.is_some() as usize) as u32
    }

    pub fn block_bytes(&self, b: u32) -> Bytes {
        self.bytes.slice(self.blocks[b as usize].clone())
    }

    pub fn record_len(&self, b: u32) -> u64 {
        (self.blocks[b as usize].len() + 4) as u64
    }
}

/// Style `served`'s chunks of a multi-style file: its SMLP (if any) and its SCOLs by block.
struct RawColour {
    geometry: String,
    bytes: Vec<u8>,
    mlp: Option<Range<usize>>,
    /// (block index, range in `bytes`)
    scol: Vec<(u32, Range<usize>)>,
}

/// The id of a multi-style file's geometry: the hex SHA-256 of its preamble, its header
/// without the style list, its GRID chunks and its BLKS chunks (the density), in file order.
/// Adding a style to the file (`snerf serve --styles-dir`) leaves it as it was, so a client
/// that holds a style from before can still switch by colour to every style, the new one
/// included; anything that changes what a held style's bytes are (the grids, the density,
/// the header's other fields) changes it, and such a switch is refused.
pub fn geometry_id(raw: &[u8]) -> Result<String> {
    let mut h = Sha256::new();
    h.update(&raw[..PREAMBLE_LEN.min(raw.len())]);
    for c in chunks(raw)? {
        match c.tag {
            TAG_HEAD => {
                let mut v: serde_json::Value = serde_json::from_slice(&raw[c.payload.clone()]).context("header is not JSON")?;
                if let Some(o) = v.as_object_mut() {
                    o.remove("styles");
                }
                let json = serde_json::to_vec(&v)?;
                h.update((json.len() as u64).to_le_bytes());
                h.update(&json);
            }
            TAG_GRID | TAG_SGRD | TAG_BLKS => h.update(&raw[c.range.clone()]),
            _ => {}
        }
    }
    Ok(to_hex(&h.finalize()))
}

fn raw_colour(raw: &[u8], served: usize) -> Result<RawColour> {
    use snerf_asset::chunk::{TAG_SCOL, TAG_SMLP};
    let mut out = RawColour { geometry: geometry_id(raw)?, bytes: Vec::new(), mlp: None, scol: Vec::new() };
    for c in chunks(raw)? {
        if c.tag != TAG_SMLP && c.tag != TAG_SCOL {
            continue;
        }
        let p = &raw[c.payload.clone()];
        if le_u32(&p[..4]) as usize != served {
            continue;
        }
        let at = out.bytes.len()..out.bytes.len() + c.range.len();
        out.bytes.extend_from_slice(&raw[c.range.clone()]);
        if c.tag == TAG_SMLP {
            out.mlp = Some(at);
        } else {
            out.scol.push((le_u32(&p[4..8]), at));
        }
    }
    Ok(out)
}

/// The style served from a multi-style file. Streaming sends one style per asset name: the
/// file's first style as the file's name (`scene`), every style as `scene.STYLE`; each is
/// that style's single-style asset (`LayeredAsset::into_style`), which every client reads.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ServedStyle {
    /// The file's styles, in its header's order.
    pub names: Vec<String>,
    /// The served one (an index into `names`).
    pub served: usize,
}

impl ServedStyle {
    /// What the server says when it loads such a file.
    pub fn message(&self, file: &Path, stem: &str) -> String {
        format!(
            "{}: a multi-style asset ({}); streaming sends one style per asset name: {} is {}, {}",
            file.display(),
            self.names.join(", "),
            stem,
            self.names[0],
            self.names.iter().map(|n| format!("{stem}.{n}")).collect::<Vec<_>>().join(", ")
        )
    }
}

/// The error of a name asking for a style its multi-style file does not have.
#[derive(Debug)]
pub struct NoSuchStyle(pub String);

impl std::fmt::Display for NoSuchStyle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for NoSuchStyle {}

/// A multi-style file's bytes as the single-style asset of `style` (None: the first).
fn single_style(raw: &[u8], style: Option<&str>) -> Result<(Vec<u8>, ServedStyle, RawColour)> {
    let layered = LayeredAsset::from_bytes(raw)?;
    let names = layered.names();
    let served = match style {
        None => 0,
        Some(s) => names.iter().position(|n| n == s).ok_or_else(|| {
            NoSuchStyle(format!("no style {:?} in this multi-style asset (it has {})", s, names.join(", ")))
        })?,
    };
    let bytes = layered.into_style(served)?.to_bytes();
    let colour = raw_colour(raw, served)?;
    Ok((bytes, ServedStyle { names, served }, colour))
}

impl ServedAsset {
    /// Read and fully validate a file (framing, CRCs, semantics), then index it.
    pub fn load(name: &str, path: &Path) -> Result<ServedAsset> {
        Self::load_style(name, path, None)
    }

    /// `load` of one style of a multi-style file (`from_bytes_style`).
    pub fn load_style(name: &str, path: &Path, style: Option<&str>) -> Result<ServedAsset> {
        let raw =
            std::fs::read(path).map_err(|e| anyhow!("{}: cannot read: {}", path.display(), e))?;
        // context, not a new error: a missing style stays a `NoSuchStyle` underneath
        Self::from_bytes_style(name, path, raw, style)
            .with_context(|| path.display().to_string())
    }

    pub fn from_bytes(name: &str, path: &Path, raw: Vec<u8>) -> Result<ServedAsset> {
        Self::from_bytes_style(name, path, raw, None)
    }

    /// `from_bytes` of one style: a multi-style file (version 3) is served as the
    /// single-style asset of `style` (None: its first; `ServedStyle`); a single-style file
    /// has no styles to pick from.
    pub fn from_bytes_style(
        name: &str,
        path: &Path,
        raw: Vec<u8>,
        style: Option<&str>,
    ) -> Result<ServedAsset> {
        let (raw, styles, colour) = if is_layered(&raw) {
            let (bytes, s, c) = single_style(&raw, style)?;
            (bytes, Some(s), Some(c))
        } else {
            ensure!(style.is_none(), "a single-style asset has no style {:?}", style.unwrap_or(""));
            (raw, None, None)
        };
        // Full validation once, so no client is ever streamed a broken asset.
        let asset = Asset::from_bytes(&raw)?;
        let header = asset.header.clone();
        let list = chunks(&raw)?;
        ensure!(list.len() <= u32::MAX as usize, "too many chunks");
        let sha256 = to_hex(&Sha256::digest(&raw));
        let g = header.grid_dim();
        // block -> (first frame, first cell), frames using it
        let n = header.atlas_blocks as usize;
        let mut first_cell: Vec<Option<usize>> = vec![None; n];
        let mut frames: Vec<Vec<(u32, u32)>> = vec![Vec::new(); n];
        for (f, grid) in asset.grids.iter().enumerate() {
            for (c, &e) in grid.iter().enumerate() {
                // a motion entry reads the reference frame's blocks (below)
                if e == EMPTY || snerf_asset::motion::is_motion(e) {
                    continue;
                }
                let b = e as usize;
                if first_cell[b].is_none() {
                    first_cell[b] = Some(c);
                }
                let fr = &mut frames[b];
                let f = f as u32;
                match fr.last_mut() {
                    Some(last) if last.1 == f || last.1 + 1 == f => last.1 = f,
                    _ => fr.push((f, f)),
                }
            }
        }
        // Motion: every frame may read the reference frame's blocks.
        if let Some(r) = header.motion_ref {
            let last = header.num_frames().saturating_sub(1) as u32;
            for &e in asset.grids.get(r as usize).map_or(&[][..], |g| &g[..]) {
                if let Some(fr) = frames.get_mut(e as usize) {
                    *fr = vec![(0, last)];
                }
            }
        }
        drop(asset);
        let origin = grid_to_world(&header, [0.0, 0.0, 0.0]);
        let mut meta = Vec::new();
        let mut blks = Vec::new();
        let mut ranges = Vec::with_capacity(list.len());
        let mut end = None;
        // block index -> entry of `blks` (the writer puts one block in each BLKS chunk)
        let mut blk_of_block = vec![u32::MAX; n];
        let last_frame = header.num_frames().saturating_sub(1) as u32;
        for c in &list {
            let idx = c.index as u32;
            ranges.push(c.range.clone());
            match c.tag {
                TAG_HEAD | TAG_VMLP | TAG_GRID | TAG_SGRD => meta.push(idx),
                TAG_BLKS => {
                    let first = le_u32(&raw[c.payload.start..c.payload.start + 4]) as usize;
                    let count = le_u32(&raw[c.payload.start + 4..c.payload.start + 8]) as usize;
                    if count == 1 && first < n {
                        blk_of_block[first] = blks.len() as u32;
                    }
                    let (centre, radius) = match first_cell.get(first).copied().flatten() {
                        Some(cell) => cell_centre_radius(&header, g, cell),
                        None => (origin, 0.0),
                    };
                    let fr = frames
                        .get(first)
                        .cloned()
                        .filter(|f| !f.is_empty())
                        .unwrap_or(vec![(last_frame, last_frame)]);
                    blks.push(BlkEntry {
                        chunk: idx,
                        centre,
                        radius,
                        frames: fr,
                    });
                }
                TAG_END => end = Some(idx),
                t => anyhow::bail!("unexpected chunk {}", tag_name(&t)),
            }
        }
        let end = end.ok_or_else(|| anyhow!("no END chunk"))?;
        let colour = match colour {
            None => None,
            Some(c) => {
                let vmlp = list.iter().find(|c| c.tag == TAG_VMLP).map(|c| c.index as u32);
                let mut blocks = vec![0..0; blks.len()];
                let mut seen = vec![false; blks.len()];
                for (b, r) in c.scol {
                    let e = blk_of_block.get(b as usize).copied().unwrap_or(u32::MAX);
                    ensure!(e != u32::MAX, "style colour for block {} that no chunk of its own holds", b);
                    blocks[e as usize] = r;
                    seen[e as usize] = true;
                }
                ensure!(seen.iter().all(|&s| s), "a style without colour for every block");
                let mlp = match (c.mlp, vmlp) {
                    (Some(r), Some(v)) => Some((r, v)),
                    (None, None) => None,
                    _ => anyhow::bail!("a style's view MLP and the served asset's disagree"),
                };
                Some(ColourPart { geometry: c.geometry, bytes: Bytes::from(c.bytes), mlp, blocks })
            }
        };
        Ok(ServedAsset {
            name: name.to_string(),
            path: path.to_path_buf(),
            bytes: Bytes::from(raw),
            sha256,
            header,
            ranges,
            meta,
            blks,
            end,
            origin,
            styles,
            colour,
        })
    }

    pub fn chunk_count(&self) -> u32 {
        self.ranges.len() as u32
    }

    /// Bytes a record of chunk `i` takes on the wire.
    pub fn record_len(&self, i: u32) -> u64 {
        let r = &self.ranges[i as usize];
        (r.end - r.start + 4) as u64
    }

    pub fn chunk_bytes(&self, i: u32) -> Bytes {
        self.bytes.slice(self.ranges[i as usize].clone())
    }

    pub fn info(&self) -> AssetInfo {
        AssetInfo {
            name: self.name.clone(),
            size: self.bytes.len() as u64,
            chunks: self.chunk_count(),
            sha256: self.sha256.clone(),
            preamble: to_hex(&self.bytes[..PREAMBLE_LEN]),
            atlas_blocks: self.header.atlas_blocks,
            frames: self.header.num_frames() as u32,
            geometry: self.colour.as_ref().map(|c| c.geometry.clone()),
        }
    }

    /// Keyframe index a playback time falls in (last keyframe with time <= t).
    pub fn frame_at(&self, t: f32) -> u32 {
        match &self.header.frames {
            None => 0,
            Some(f) => f.iter().rposition(|k| k.time <= t).unwrap_or(0) as u32,
        }
    }

    /// Sort key of a BLKS entry for a pose (smaller = sooner): keyframes ahead of playback
    /// first (wrapping), then in-frustum, in front, behind; then nearest first.
    pub fn priority(&self, b: &BlkEntry, view: Option<&View>) -> (u32, u8, f32) {
        let nf = self.header.num_frames() as u32;
        let k = view.map_or(0, |v| v.frame);
        let rank = b
            .frames
            .iter()
            .map(|&(lo, hi)| {
                if (lo..=hi).contains(&k) {
                    0
                } else if lo > k {
                    lo - k
                } else {
                    lo + nf - k
                }
            })
            .min()
            .unwrap_or(nf);
        match view {
            None => (rank, 0, dist(b.centre, self.origin)),
            Some(v) => {
                let d = sub(b.centre, v.eye);
                let len = norm(d);
                let near = (len - b.radius).max(0.0);
                if len <= b.radius || len < 1e-9 {
                    return (rank, 0, 0.0);
                }
                let cos = dot(d, v.forward) / len;
                // Widen the cone by the block's angular radius.
                let ang = cos.clamp(-1.0, 1.0).acos() - (b.radius / len).min(1.0).asin();
                let tier = if ang <= v.half_fov {
                    0
                } else if cos > 0.0 {
                    1
                } else {
                    2
                };
                (rank, tier, near)
            }
        }
    }

    /// Whether a block chunk is in the first tier (in the view cone) for a pose.
    pub fn in_view(&self, b: &BlkEntry, view: &View) -> bool {
        self.priority(b, Some(view)).1 == 0
    }
}

/// A pose prepared for prioritizing.
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub eye: [f32; 3],
    pub forward: [f32; 3],
    pub half_fov: f32,
    pub frame: u32,
}

impl View {
    pub fn new(asset: &ServedAsset, p: &Pose) -> View {
        let n = norm(p.forward).max(1e-12);
        let fov = if p.fov_deg > 0.0 {
            p.fov_deg
        } else {
            DEFAULT_FOV_DEG
        };
        View {
            eye: p.eye,
            forward: p.forward.map(|x| x / n),
            half_fov: (fov * 0.5).to_radians(),
            frame: asset.frame_at(p.time),
        }
    }
}

fn cell_centre_radius(h: &Header, g: usize, cell: usize) -> ([f32; 3], f32) {
    let (x, y, z) = (cell % g, (cell / g) % g, cell / (g * g));
    let s = 2.0 / g as f32;
    let lo = [x, y, z].map(|i| -1.0 + i as f32 * s);
    let c = lo.map(|l| l + 0.5 * s);
    let wc = grid_to_world(h, c);
    let mut r: f32 = 0.0;
    for corner in 0..8 {
        let p = [0, 1, 2].map(|a| lo[a] + if corner >> a & 1 == 1 { s } else { 0.0 });
        let d = dist(grid_to_world(h, p), wc);
        if d.is_finite() {
            r = r.max(d);
        }
    }
    (wc, r)
}

pub use snerf_asset::render::grid_to_world;

/// Record bytes of a set of chunks.
/// Order block indices (into `asset.blks`) for `pose`, **most urgent last** (the sender pops
/// from the end): the one order both carriers send in (`session.rs` over QUIC and
/// WebTransport, `http_stream.rs` over HTTPS).
pub fn order_blocks(asset: &ServedAsset, blocks: &mut Vec<u32>, pose: Option<Pose>) {
    let view = pose.map(|p| View::new(asset, &p));
    let mut keyed: Vec<((u32, u8, f32), u32)> = blocks
        .iter()
        .map(|&b| (asset.priority(&asset.blks[b as usize], view.as_ref()), b))
        .collect();
    keyed.sort_by(|a, b| b.0 .0.cmp(&a.0 .0).then(b.0 .1.cmp(&a.0 .1)).then(b.0 .2.total_cmp(&a.0 .2)));
    blocks.clear();
    blocks.extend(keyed.into_iter().map(|k| k.1));
}

/// The chunks a hello's `have` ranges spare (true: not sent), honoured only when its
/// `resume_id` is this asset's SHA-256; and whether it was. Both carriers start from this
/// (`session.rs`, `http_stream.rs`).
pub fn skipped(asset: &ServedAsset, have: &[[u32; 2]], resume_id: Option<&str>) -> (Vec<bool>, bool) {
    let n = asset.chunk_count() as usize;
    let mut skip = vec![false; n];
    let resumed = resume_id == Some(asset.sha256.as_str());
    if resumed {
        for r in have {
            let (lo, hi) = (r[0] as usize, (r[1] as usize).min(n));
            for s in skip.iter_mut().take(hi).skip(lo) {
                *s = true;
            }
        }
    }
    (skip, resumed)
}

pub fn records_len(a: &ServedAsset, idx: &[u32]) -> u64 {
    idx.iter().map(|&i| a.record_len(i)).sum::<u64>()
}

use snerf_geometry::vec::{dot, norm, sub};

pub(crate) fn dist(a: [f32; 3], b: [f32; 3]) -> f32 {
    norm(sub(a, b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use snerf_asset::{AssetBuilder, Keyframe, Kind, ViewMlp};

    fn asset(kind: Kind, dynamic: bool) -> ServedAsset {
        let mut h = Header::new(kind, 32, 8);
        if kind == Kind::Forward {
            h.space.ndc = Some(snerf_asset::Ndc {
                fx: 50.0,
                fy: 50.0,
                width: 64.0,
                height: 48.0,
                near: 1.0,
                xy_extent: 1.0,
            });
        }
        if dynamic {
            h.time_range = Some([0.0, 2.0]);
            h.frames = Some(vec![
                Keyframe { time: 0.0 },
                Keyframe { time: 1.0 },
                Keyframe { time: 2.0 },
            ]);
        }
        let g = h.grid_dim();
        let frames = h.num_frames();
        let mut b = AssetBuilder::new(h, ViewMlp::zeros()).unwrap();
        let bb = b.header().block_bytes();
        for f in 0..frames {
            for z in 0..g {
                for y in 0..g {
                    for x in 0..g {
                        // Frame f changes the cells with x == f (others shared).
                        let v =
                            vec![(x + 4 * y + 16 * z + if x == f { 64 * f } else { 0 }) as u8; bb];
                        b.set_block(f, [x, y, z], &v).unwrap();
                    }
                }
            }
        }
        let a = b.finish().unwrap();
        ServedAsset::from_bytes("t", Path::new("t.snerf"), a.to_bytes()).unwrap()
    }

    fn order(a: &ServedAsset, pose: Option<Pose>) -> Vec<&BlkEntry> {
        let v = pose.map(|p| View::new(a, &p));
        let mut b: Vec<&BlkEntry> = a.blks.iter().collect();
        b.sort_by(|x, y| {
            let (p, q) = (a.priority(x, v.as_ref()), a.priority(y, v.as_ref()));
            p.0.cmp(&q.0).then(p.1.cmp(&q.1)).then(p.2.total_cmp(&q.2))
        });
        b
    }

    #[test]
    fn frustum_then_distance() {
        let a = asset(Kind::Object, false);
        assert_eq!(a.blks.len(), 64);
        let pose = Pose {
            eye: [3.0, 0.0, 0.0],
            forward: [-1.0, 0.0, 0.0],
            time: 0.0,
            fov_deg: 20.0,
        };
        let o = order(&a, Some(pose));
        // Nearest block first: on the +x face, near the axis.
        assert!(
            o[0].centre[0] > 0.7 && o[0].centre[1].abs() < 0.3,
            "{:?}",
            o[0].centre
        );
        // Everything in the cone precedes everything outside it.
        let v = View::new(&a, &pose);
        let tiers: Vec<u8> = o.iter().map(|b| a.priority(b, Some(&v)).1).collect();
        assert!(tiers.windows(2).all(|w| w[0] <= w[1]));
        assert!(tiers.contains(&0) && tiers.iter().any(|&t| t > 0));
        // Looking the other way: blocks behind the eye are last.
        let back = Pose {
            eye: [0.0, 0.0, -0.6],
            forward: [0.0, 0.0, 1.0],
            time: 0.0,
            fov_deg: 60.0,
        };
        let o = order(&a, Some(back));
        assert!(o.last().unwrap().centre[2] < -0.6);
        assert!(o[0].centre[2] > -0.6 - o[0].radius);
        let v = View::new(&a, &back);
        assert_eq!(a.priority(o.last().unwrap(), Some(&v)).1, 2);
        // No pose: centre-out.
        let o = order(&a, None);
        assert!(
            crate::plan::dist(o[0].centre, [0.0; 3]) <= crate::plan::dist(o[63].centre, [0.0; 3])
        );
    }

    #[test]
    fn keyframes_ahead_of_playback() {
        let a = asset(Kind::Object, true);
        for (t, k) in [
            (0.0, 0u32),
            (1.0, 1),
            (1.5, 1),
            (2.0, 2),
            (-5.0, 0),
            (9.0, 2),
        ] {
            assert_eq!(a.frame_at(t), k);
            let pose = Pose {
                eye: [0.0, 0.0, 3.0],
                forward: [0.0, 0.0, -1.0],
                time: t,
                fov_deg: 60.0,
            };
            let o = order(&a, Some(pose));
            let rank = |b: &BlkEntry| a.priority(b, Some(&View::new(&a, &pose))).0;
            assert!(o.windows(2).all(|w| rank(w[0]) <= rank(w[1])));
            // Blocks used by the playback keyframe first.
            assert!(o[0].frames.iter().any(|&(lo, hi)| (lo..=hi).contains(&k)));
            let first_other = o
                .iter()
                .position(|b| !b.frames.iter().any(|&(lo, hi)| (lo..=hi).contains(&k)))
                .unwrap();
            assert!(o[first_other..]
                .iter()
                .all(|b| !b.frames.iter().any(|&(lo, hi)| (lo..=hi).contains(&k))));
        }
    }

    #[test]
    fn grid_to_world_inverts_the_mappings() {
        // Forward: the NDC inverse maps back through the forward mapping.
        let a = asset(Kind::Forward, false);
        let n = a.header.space.ndc.unwrap();
        for g in [[0.0, 0.0, 0.0], [0.5, -0.5, 0.5], [-0.9, 0.2, -0.9]] {
            let m = grid_to_world(&a.header, g);
            let ax = -n.fx / (n.width * 0.5);
            let ay = -n.fy / (n.height * 0.5);
            let back = [
                ax * m[0] / m[2] / n.xy_extent,
                ay * m[1] / m[2] / n.xy_extent,
                1.0 + 2.0 * n.near / m[2],
            ];
            for i in 0..3 {
                assert!(
                    (back[i] - g[i]).abs() < 1e-4,
                    "{:?} -> {:?} -> {:?}",
                    g,
                    m,
                    back
                );
            }
        }
        // Unbounded: contraction of the inverse gives the grid point back.
        let mut h = a.header.clone();
        h.kind = Kind::Unbounded;
        h.space.ndc = None;
        for g in [[0.1, 0.2, -0.3], [0.75, 0.1, -0.2], [-0.2, -0.9, 0.4]] {
            let w = grid_to_world(&h, g);
            let c = snerf_geometry::contract(w);
            for i in 0..3 {
                assert!(
                    (c[i] / 2.0 - g[i]).abs() < 1e-4,
                    "{:?} -> {:?} -> {:?}",
                    g,
                    w,
                    c
                );
            }
        }
    }
}
