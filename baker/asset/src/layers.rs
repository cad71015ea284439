//! Multi-style assets (format version 3): styles as layers of one asset.
//!
//! A scene stylized after several paintings with its geometry frozen (`snerf stylize
//! --appearance-only`) differs between styles only in colour. Such an asset stores what the
//! styles share once and each style's colour apart:
//!
//! - **geometry** (shared): the header (its `styles` list names the layers), every frame's
//!   `GRID` and, in the `BLKS` chunks, every voxel's density code (1 byte a voxel);
//! - **colour** (one part per style): the style's view MLP (`SMLP`, none when every style is
//!   diffuse) and per block one `SCOL` chunk with the diffuse RGB (and the four specular
//!   features unless every style is diffuse) of the block's *live* voxels only.
//!
//! A voxel is live when some voxel of its 3×3×3 neighbourhood in the block (apron included)
//! has a density code above 0. A trilinear sample reads the 8 voxels around it: if one of
//! them has density, all 8 are live, so every sample with any density above the code-0 floor
//! reads exactly the colours the style was baked with. Samples whose 8 voxels are all at the
//! floor (σ·step = 1e-5 in the baker's range) read colour 0 instead of the baked colour; that
//! is the only difference to a single-style bake of the same style (tested: within 1/255 of
//! its CPU reference). A dynamic asset blends the voxels of two blocks: where it weights
//! colour by density (`Header::colour_by_density`, every dynamic bake since) a side whose 8
//! voxels sit at the floor adds at most exp(logit_min) of the other side's share of colour,
//! so the same rule holds there; in dynamic assets blended without it every voxel is live. What the file leaves out reads back as colour 0, so `LayeredAsset::new` clears it too
//! and a round trip is exact.
//!
//! A block's apron repeats voxels of its neighbours (the baker evaluates both at one point).
//! In a static asset whose blocks each serve one cell, a colour part stores an apron voxel
//! only where the neighbouring cell is empty; a reader copies the rest from the neighbour's
//! block (`LayeredAsset::new` does the same, so the round trip stays exact). That halves a
//! colour part at 8³ blocks. A dynamic asset's block may serve its cell at several times,
//! beside different neighbours, so there (blended by density) a colour part stores no apron
//! voxel: each takes the colour of the nearest interior voxel of its own block. A style's
//! colour then stops at its block's edge instead of reaching halfway into the neighbour's;
//! the density, and so the geometry, is untouched.
//!
//! Each `SCOL` carries the CRC-32 of the density codes of the block it colours: a colour part
//! spliced from an asset of another geometry is refused by name, not drawn on the wrong
//! surface. Readers that only want one style (`Asset::read`) get the first.

use anyhow::{anyhow, bail, ensure, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

use crate::asset::Asset;
use crate::atomic::write_atomic;
use crate::chunk::{check_preamble, le_u32, tag_name, CHUNK_HEADER_LEN, TAG_SCOL, TAG_SMLP};
use crate::header::{Header, StyleInfo};
use crate::mlp::{ViewMlp, MLP_FLOATS};
use crate::quantize::CHANNELS;

/// Every style of a multi-style asset as a complete single-style asset (in the header's
/// order). All share the header (but for `styles`), the grids and every voxel's density.
#[derive(Clone, Debug, PartialEq)]
pub struct LayeredAsset {
    pub styles: Vec<StyleInfo>,
    pub layers: Vec<Asset>,
}

/// Encoded bytes of one style's colour part (its `SMLP` and `SCOL` chunks, headers included).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StyleBytes {
    pub name: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    pub swatch: [f32; 3],
    pub bytes: u64,
}

/// Whether a file's bytes are a multi-style asset (version 3 preamble; version 4 is a
/// motion asset, which holds one style).
pub fn is_layered(bytes: &[u8]) -> bool {
    check_preamble(bytes).is_ok_and(|v| v == 3)
}

/// Where the apron voxels of a static asset's blocks are stored: an apron voxel repeats a
/// voxel of the neighbouring cell's block (the baker evaluates both at one point), so a
/// style's colour part stores it only where that cell is empty; readers copy it from there.
struct Owners {
    g: usize,
    b: usize,
    /// Per block: its cell, when it is one static asset's block of exactly one cell.
    cell_of: Vec<Option<usize>>,
    grid: Vec<u32>,
    /// A dynamic asset blended by density: every apron voxel is held by the nearest
    /// interior voxel of its own block (module doc).
    clamp: bool,
}

impl Owners {
    fn new(h: &Header, grids: &[Vec<u32>]) -> Owners {
        let clamp = h.is_dynamic() && h.colour_by_density;
        let (g, b) = (h.grid_dim(), h.block as usize);
        let n = h.atlas_blocks as usize;
        let mut cell_of = vec![None; n];
        if !h.is_dynamic() && grids.len() == 1 {
            let mut uses = vec![0u32; n];
            for (c, &e) in grids[0].iter().enumerate() {
                if let Some(u) = uses.get_mut(e as usize) {
                    *u += 1;
                    cell_of[e as usize] = Some(c);
                }
            }
            for (c, u) in cell_of.iter_mut().zip(&uses) {
                if *u != 1 {
                    *c = None;
                }
            }
        }
        Owners { g, b, cell_of, grid: grids.first().cloned().unwrap_or_default(), clamp }
    }

    /// Whether some voxels of block `blk` are held by another voxel.
    fn holds(&self, blk: usize) -> bool {
        self.clamp || self.cell_of[blk].is_some()
    }

    /// The (block, voxel) that holds voxel `v` of block `blk`, when another voxel does.
    fn owner(&self, blk: usize, v: usize) -> Option<(usize, usize)> {
        let (g, b) = (self.g, self.b);
        let e = b + 2;
        let l = [v % e, (v / e) % e, v / (e * e)];
        if l.iter().all(|&x| (1..=b).contains(&x)) {
            return None;
        }
        if self.clamp {
            let i = l.map(|x| x.clamp(1, b));
            return Some((blk, (i[2] * e + i[1]) * e + i[0]));
        }
        let c = self.cell_of[blk]?;
        let cell = [c % g, (c / g) % g, c / (g * g)];
        let mut oc = [0usize; 3];
        let mut ol = [0usize; 3];
        for a in 0..3 {
            // global voxel index, the owning cell and the voxel's place in its block
            let gi = (cell[a] * b + l[a]) as isize - 1;
            if gi < 0 || gi >= (g * b) as isize {
                return None;
            }
            oc[a] = gi as usize / b;
            ol[a] = gi as usize - oc[a] * b + 1;
        }
        let o = self.grid[(oc[2] * g + oc[1]) * g + oc[0]];
        if o == crate::asset::EMPTY || self.cell_of.get(o as usize).copied().flatten().is_none() {
            return None;
        }
        Some((o as usize, (ol[2] * e + ol[1]) * e + ol[0]))
    }

    /// Copy every apron voxel's colour (channels 1..8) from the block that holds it.
    fn fill(&self, atlas: &mut [u8], bb: usize) {
        let voxels = bb / CHANNELS;
        for blk in 0..atlas.len() / bb {
            if !self.holds(blk) {
                continue;
            }
            for v in 0..voxels {
                if let Some((o, ov)) = self.owner(blk, v) {
                    let src = o * bb + ov * CHANNELS;
                    let dst = blk * bb + v * CHANNELS;
                    let colour: [u8; CHANNELS - 1] = atlas[src + 1..src + CHANNELS].try_into().unwrap_or([0; CHANNELS - 1]);
                    atlas[dst + 1..dst + CHANNELS].copy_from_slice(&colour);
                }
            }
        }
    }

    /// Voxels of block `blk` whose colour the file stores: live and not held by another block.
    fn stored(&self, blk: usize, live: &[bool]) -> Vec<bool> {
        live.iter().enumerate().map(|(v, &on)| on && self.owner(blk, v).is_none()).collect()
    }
}

/// Live voxels of one block (module doc) from its density codes ((block+2)³, x fastest).
pub fn live_voxels(header: &Header, density: &[u8]) -> Vec<bool> {
    if header.is_dynamic() && !header.colour_by_density {
        return vec![true; density.len()];
    }
    let e = header.block as usize + 2;
    // separable 3-wide max along x, then y, then z
    let mut a: Vec<bool> = density.iter().map(|&d| d > 0).collect();
    for stride in [1, e, e * e] {
        let b = a.clone();
        for (i, v) in a.iter_mut().enumerate() {
            let k = (i / stride) % e;
            *v = b[i] || (k > 0 && b[i - stride]) || (k + 1 < e && b[i + stride]);
        }
    }
    a
}

/// Mean diffuse colour of an asset's voxels with density above the floor: a style's swatch.
pub fn swatch(asset: &Asset) -> [f32; 3] {
    let (mut sum, mut n) = ([0f64; 3], 0u64);
    for v in asset.atlas.chunks_exact(CHANNELS).filter(|v| v[0] > 0) {
        for c in 0..3 {
            sum[c] += v[1 + c] as f64;
        }
        n += 1;
    }
    sum.map(|s| (s / n.max(1) as f64 / 255.0) as f32)
}

/// The first difference between two assets' geometry (header but `diffuse`/`styles`, grids,
/// density codes), or None when they share it.
pub fn geometry_difference(a: &Asset, b: &Asset) -> Option<String> {
    let plain = |h: &Header| {
        let mut h = h.clone();
        h.diffuse = false;
        h.styles = None;
        serde_json::to_value(h).unwrap_or_default()
    };
    let (ha, hb) = (plain(&a.header), plain(&b.header));
    if ha != hb {
        let keys: Vec<String> = ha
            .as_object()
            .into_iter()
            .flatten()
            .filter(|(k, v)| hb.get(k.as_str()) != Some(v))
            .map(|(k, _)| k.clone())
            .collect();
        return Some(format!("its header differs ({})", keys.join(", ")));
    }
    if let Some(f) = (0..a.grids.len().max(b.grids.len())).find(|&f| a.grids.get(f) != b.grids.get(f)) {
        return Some(format!("frame {f}'s grid differs"));
    }
    let bb = a.block_bytes();
    let differs = |i: usize| {
        let (x, y) = (&a.atlas[i * bb..(i + 1) * bb], &b.atlas[i * bb..(i + 1) * bb]);
        x.chunks_exact(CHANNELS).zip(y.chunks_exact(CHANNELS)).filter(|(p, q)| p[0] != q[0]).count()
    };
    let blocks = a.header.atlas_blocks as usize;
    let counts: Vec<usize> = (0..blocks).map(differs).collect();
    let voxels: usize = counts.iter().sum();
    if voxels > 0 {
        let first = counts.iter().position(|&c| c > 0).unwrap_or(0);
        return Some(format!("{voxels} voxels' density differs (first in block {first})"));
    }
    None
}

/// Writes another style's colour part into a single-style asset of the same multi-style file,
/// chunk by chunk in any order, as a stream delivers it: what a client holding one style does
/// when it switches to another (the geometry stays; only `SMLP` and `SCOL` chunks travel).
/// Each `SCOL` is checked against the block's density (its checksum and its stored-voxel
/// count), so colour for another geometry is refused; apron voxels held by a neighbour are
/// copied from it as soon as both blocks hold the new style, so every block is exact once all
/// have arrived (before that, a block's apron may still show the old style next to a
/// neighbour that has not arrived).
pub struct Recolour {
    /// Per block: (stored mask, density checksum).
    blocks: Vec<(Vec<bool>, u32)>,
    /// Per block: (apron voxel, holder block, holder voxel), and the reverse (dependent
    /// block, its voxel, this block's voxel).
    from: Vec<Vec<(u32, u32, u32)>>,
    to: Vec<Vec<(u32, u32, u32)>>,
    mlp: bool,
    have: Vec<bool>,
    diffuse: bool,
}

impl Recolour {
    /// For `asset` (a complete single-style asset: its density is what the colour goes on).
    pub fn new(asset: &Asset) -> Recolour {
        let h = &asset.header;
        let bb = h.block_bytes();
        let owners = Owners::new(h, &asset.grids);
        let n = h.atlas_blocks as usize;
        let (mut from, mut to) = (vec![Vec::new(); n], vec![Vec::new(); n]);
        let blocks = asset
            .atlas
            .chunks_exact(bb)
            .enumerate()
            .map(|(i, blk)| {
                let density: Vec<u8> = blk.chunks_exact(CHANNELS).map(|v| v[0]).collect();
                (owners.stored(i, &live_voxels(h, &density)), crc32fast::hash(&density))
            })
            .collect();
        let voxels = bb / CHANNELS;
        for (blk, links) in from.iter_mut().enumerate() {
            if !owners.holds(blk) {
                continue;
            }
            for v in 0..voxels {
                if let Some((o, ov)) = owners.owner(blk, v) {
                    links.push((v as u32, o as u32, ov as u32));
                    to[o].push((blk as u32, v as u32, ov as u32));
                }
            }
        }
        Recolour { blocks, from, to, mlp: h.diffuse, have: vec![false; n], diffuse: h.diffuse }
    }

    /// Ready for another style's colour part over the same geometry (the tables depend on the
    /// density alone, so one `Recolour` serves every switch of an asset).
    pub fn restart(&mut self) {
        self.have.fill(false);
        self.mlp = self.diffuse;
    }

    /// Blocks of the asset.
    pub fn blocks(&self) -> usize {
        self.have.len()
    }

    /// Whether every block's colour and the view MLP (unless diffuse) have been written.
    pub fn is_complete(&self) -> bool {
        self.mlp && self.have.iter().all(|&h| h)
    }

    /// Write one chunk of a style's colour part (`SMLP` payload or `SCOL` payload, without
    /// the chunk header) into `asset`. Returns the blocks whose bytes changed (a `SCOL`'s
    /// block and the neighbours whose aprons it holds); errors say what does not fit.
    pub fn apply(&mut self, asset: &mut Asset, tag: [u8; 4], p: &[u8]) -> Result<Vec<usize>> {
        ensure!(p.len() >= 4, "{} bytes, too short for a style index", p.len());
        if tag == TAG_SMLP {
            ensure!(!self.diffuse, "a view MLP for a diffuse asset");
            ensure!(p.len() == 4 + 4 * MLP_FLOATS, "a view MLP of {} bytes, expected {}", p.len() - 4, 4 * MLP_FLOATS);
            let floats: Vec<f32> = p[4..].chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
            asset.mlp = ViewMlp::from_flat(&floats)?;
            self.mlp = true;
            return Ok(Vec::new());
        }
        ensure!(tag == TAG_SCOL, "a {} chunk is no part of a style's colour", tag_name(&tag));
        ensure!(p.len() >= 12, "{} bytes, too short for style, block and checksum", p.len());
        let (b, crc) = (le_u32(&p[4..8]) as usize, le_u32(&p[8..12]));
        ensure!(b < self.have.len(), "colour for block {} but the atlas has {}", b, self.have.len());
        let (stored, geo_crc) = &self.blocks[b];
        ensure!(crc == *geo_crc, "the colour of block {} was made for another geometry (the block's density checksum differs)", b);
        let cc = asset.header.style_channels();
        let count = stored.iter().filter(|&&s| s).count();
        ensure!(p.len() - 12 == count * cc, "the colour of block {} has {} bytes, the block stores {} voxels ({} bytes)", b, p.len() - 12, count, count * cc);
        let bb = asset.block_bytes();
        let blk = &mut asset.atlas[b * bb..(b + 1) * bb];
        let mut src = p[12..].chunks_exact(cc);
        for (v, &on) in blk.chunks_exact_mut(CHANNELS).zip(stored) {
            if on {
                v[1..1 + cc].copy_from_slice(src.next().unwrap_or(&[]));
            } else {
                v[1..].fill(0);
            }
        }
        self.have[b] = true;
        let copy = |atlas: &mut [u8], dst: (usize, usize), src: (usize, usize)| {
            let s = src.0 * bb + src.1 * CHANNELS;
            let colour: [u8; CHANNELS - 1] = atlas[s + 1..s + CHANNELS].try_into().unwrap_or([0; CHANNELS - 1]);
            let d = dst.0 * bb + dst.1 * CHANNELS;
            atlas[d + 1..d + CHANNELS].copy_from_slice(&colour);
        };
        // its aprons from their holders (whatever style they hold now: exact once they arrive)
        for &(v, o, ov) in &self.from[b] {
            copy(&mut asset.atlas, (b, v as usize), (o as usize, ov as usize));
        }
        let mut changed = vec![b];
        for &(d, v, ov) in &self.to[b] {
            copy(&mut asset.atlas, (d as usize, v as usize), (b, ov as usize));
            if changed.last() != Some(&(d as usize)) {
                changed.push(d as usize);
            }
        }
        changed.sort_unstable();
        changed.dedup();
        Ok(changed)
    }
}

impl LayeredAsset {
    /// Styles and their layers (each a complete single-style asset). Fails, naming the
    /// style, when a layer's geometry is not the first's. Clears the colour of voxels that
    /// are not live (what the file leaves out), so what is written reads back equal.
    pub fn new(styles: Vec<StyleInfo>, mut layers: Vec<Asset>) -> Result<LayeredAsset> {
        ensure!(!layers.is_empty(), "a multi-style asset needs at least one style");
        ensure!(styles.len() == layers.len(), "{} style names for {} layers", styles.len(), layers.len());
        for (s, l) in styles.iter().zip(&layers).skip(1) {
            if let Some(d) = geometry_difference(&layers[0], l) {
                bail!("style {:?} was baked on another geometry than style {:?}: {d}", s.name, styles[0].name);
            }
        }
        let diffuse = layers.iter().all(|l| l.header.diffuse);
        let mut file_header = layers[0].header.clone();
        file_header.diffuse = diffuse;
        file_header.styles = Some(styles.clone());
        file_header.validate()?;
        let bb = file_header.block_bytes();
        let mut masks = Vec::with_capacity(file_header.atlas_blocks as usize);
        for blk in layers[0].atlas.chunks_exact(bb) {
            let density: Vec<u8> = blk.chunks_exact(CHANNELS).map(|v| v[0]).collect();
            masks.push(live_voxels(&file_header, &density));
        }
        let owners = Owners::new(&file_header, &layers[0].grids);
        for l in &mut layers {
            l.validate()?;
            l.header.diffuse = diffuse;
            l.header.styles = None;
            for (blk, live) in l.atlas.chunks_exact_mut(bb).zip(&masks) {
                for (v, &on) in blk.chunks_exact_mut(CHANNELS).zip(live) {
                    if !on {
                        v[1..].fill(0);
                    }
                }
            }
            owners.fill(&mut l.atlas, bb);
        }
        Ok(LayeredAsset { styles, layers })
    }

    /// The file's header (the first layer's, with the styles listed).
    pub fn header(&self) -> Header {
        let mut h = self.layers[0].header.clone();
        h.styles = Some(self.styles.clone());
        h
    }

    /// The style named `name` as a single-style asset; the error lists the names there are.
    pub fn style(&self, name: &str) -> Result<&Asset> {
        match self.styles.iter().position(|s| s.name == name) {
            Some(i) => Ok(&self.layers[i]),
            None => bail!("no style {:?} in this asset (it has {})", name, self.names().join(", ")),
        }
    }

    pub fn names(&self) -> Vec<String> {
        self.styles.iter().map(|s| s.name.clone()).collect()
    }

    /// Style `i` as a single-style asset.
    pub fn into_style(mut self, i: usize) -> Result<Asset> {
        ensure!(i < self.layers.len(), "style {} of {}", i, self.layers.len());
        Ok(self.layers.swap_remove(i))
    }

    /// The shared geometry as the file holds it: density only, no MLP.
    fn geometry(&self) -> Asset {
        let mut g = self.layers[0].clone();
        g.header = self.header();
        g.mlp = ViewMlp::zeros();
        for v in g.atlas.chunks_exact_mut(CHANNELS) {
            v[1..].fill(0);
        }
        g
    }

    /// Each style's chunks: its SMLP (unless diffuse), then one SCOL per block.
    fn style_chunks(&self) -> Vec<Vec<([u8; 4], Vec<u8>)>> {
        let h = self.header();
        let (bb, cc) = (h.block_bytes(), h.style_channels());
        let base = &self.layers[0];
        let owners = Owners::new(&h, &base.grids);
        let geometry: Vec<(Vec<u8>, Vec<bool>, u32)> = base
            .atlas
            .chunks_exact(bb)
            .enumerate()
            .map(|(i, blk)| {
                let density: Vec<u8> = blk.chunks_exact(CHANNELS).map(|v| v[0]).collect();
                let stored = owners.stored(i, &live_voxels(&h, &density));
                let crc = crc32fast::hash(&density);
                (density, stored, crc)
            })
            .collect();
        self.layers
            .iter()
            .enumerate()
            .map(|(s, l)| {
                let mut out = Vec::new();
                if !h.diffuse {
                    let mut p = (s as u32).to_le_bytes().to_vec();
                    p.extend(l.mlp.to_flat().iter().flat_map(|x| x.to_le_bytes()));
                    out.push((TAG_SMLP, p));
                }
                for (b, (blk, (_, live, crc))) in l.atlas.chunks_exact(bb).zip(&geometry).enumerate() {
                    let mut p = Vec::with_capacity(12 + live.len() * cc);
                    for x in [s as u32, b as u32, *crc] {
                        p.extend_from_slice(&x.to_le_bytes());
                    }
                    for (v, _) in blk.chunks_exact(CHANNELS).zip(live).filter(|(_, &on)| on) {
                        p.extend_from_slice(&v[1..1 + cc]);
                    }
                    out.push((TAG_SCOL, p));
                }
                out
            })
            .collect()
    }

    /// The file: preamble (version 3), HEAD, GRIDs, the geometry's BLKS (density), then each
    /// style's colour part in turn (SMLP, one SCOL per block), END.
    pub fn to_bytes(&self) -> Vec<u8> {
        let extra: Vec<([u8; 4], Vec<u8>)> = self.style_chunks().into_iter().flatten().collect();
        self.geometry().encode(&extra)
    }

    /// Encoded bytes of each style's colour part, with its name and swatch.
    pub fn style_bytes(&self) -> Vec<StyleBytes> {
        self.style_chunks()
            .iter()
            .zip(&self.styles)
            .map(|(chunks, s)| StyleBytes {
                name: s.name.clone(),
                source: s.source.clone(),
                swatch: s.swatch,
                bytes: chunks.iter().map(|(_, p)| (CHUNK_HEADER_LEN + p.len()) as u64).sum(),
            })
            .collect()
    }

    /// What `snerf inspect` prints: the geometry's parts (as `Asset::summary`) and every
    /// style's bytes.
    pub fn summary(&self, file_bytes: u64) -> crate::summary::Summary {
        let mut s = self.geometry().summary(file_bytes);
        s.styles = self.style_bytes();
        s
    }

    /// Write atomically (see `Asset::write`).
    pub fn write(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        self.geometry()
            .validate()
            .map_err(|e| anyhow!("{}: refusing to write an invalid asset: {:#}", path.display(), e))?;
        write_atomic(path, &self.to_bytes())
    }

    /// Read and validate a multi-style file; errors name the file.
    pub fn read(path: impl AsRef<Path>) -> Result<LayeredAsset> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|e| anyhow!("{}: cannot read: {}", path.display(), e))?;
        LayeredAsset::from_bytes(&bytes).map_err(|e| anyhow!("{}: {:#}", path.display(), e))
    }

    /// Decode a whole multi-style file: the geometry as `Asset::from_bytes` checks it, then
    /// every style's colour part, which must be complete and made for this geometry.
    pub fn from_bytes(bytes: &[u8]) -> Result<LayeredAsset> {
        let version = check_preamble(bytes)?;
        ensure!(version >= 3, "a version {version} asset holds one style (multi-style assets are version 3)");
        let (geometry, chunks) = Asset::geometry_from_bytes(bytes)?;
        let h = geometry.header.clone();
        let styles = h.styles.clone().ok_or_else(|| anyhow!("a version 3 asset whose header lists no styles"))?;
        let (n, nb, bb, cc) = (styles.len(), h.atlas_blocks as usize, h.block_bytes(), h.style_channels());
        let owners = Owners::new(&h, &geometry.grids);
        let blocks: Vec<(Vec<bool>, u32)> = geometry
            .atlas
            .chunks_exact(bb)
            .enumerate()
            .map(|(i, blk)| {
                let density: Vec<u8> = blk.chunks_exact(CHANNELS).map(|v| v[0]).collect();
                (owners.stored(i, &live_voxels(&h, &density)), crc32fast::hash(&density))
            })
            .collect();
        let mut plain = geometry;
        plain.header.styles = None;
        let mut layers = vec![plain; n];
        let mut have_mlp = vec![h.diffuse; n];
        let mut have = vec![vec![false; nb]; n];
        for (index, tag, p) in chunks {
            let name = |s: usize| styles[s].name.clone();
            let r = (|| -> Result<()> {
                ensure!(p.len() >= 4, "{} bytes, too short for a style index", p.len());
                let s = le_u32(&p[..4]) as usize;
                ensure!(s < n, "for style {} but the asset lists {} styles", s, n);
                if tag == TAG_SMLP {
                    ensure!(!h.diffuse, "style {:?}: an asset whose styles are all diffuse has no view MLPs", name(s));
                    ensure!(!have_mlp[s], "duplicate view MLP of style {:?}", name(s));
                    ensure!(p.len() == 4 + 4 * MLP_FLOATS, "style {:?}'s view MLP has {} bytes, expected {}", name(s), p.len() - 4, 4 * MLP_FLOATS);
                    let floats: Vec<f32> = p[4..].chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
                    layers[s].mlp = ViewMlp::from_flat(&floats)?;
                    have_mlp[s] = true;
                    return Ok(());
                }
                ensure!(p.len() >= 12, "{} bytes, too short for style, block and checksum", p.len());
                let (b, crc) = (le_u32(&p[4..8]) as usize, le_u32(&p[8..12]));
                ensure!(b < nb, "style {:?} colours block {} but the atlas has {}", name(s), b, nb);
                ensure!(!have[s][b], "duplicate colour of style {:?} for block {}", name(s), b);
                let (live, geo_crc) = &blocks[b];
                ensure!(
                    crc == *geo_crc,
                    "style {:?}'s colour of block {} was made for another geometry (the block's density checksum differs): a layer for another geometry",
                    name(s),
                    b
                );
                let count = live.iter().filter(|&&l| l).count();
                ensure!(
                    p.len() - 12 == count * cc,
                    "style {:?}'s colour of block {} has {} bytes, the block stores {} live voxels ({} bytes): a layer for another geometry",
                    name(s),
                    b,
                    p.len() - 12,
                    count,
                    count * cc
                );
                let atlas = &mut layers[s].atlas[b * bb..(b + 1) * bb];
                let mut src = p[12..].chunks_exact(cc);
                for (v, _) in atlas.chunks_exact_mut(CHANNELS).zip(live).filter(|(_, &on)| on) {
                    v[1..1 + cc].copy_from_slice(src.next().unwrap_or(&[]));
                }
                have[s][b] = true;
                Ok(())
            })();
            r.map_err(|e| anyhow!("chunk {} ({}): {:#}", index, tag_name(&tag), e))?;
        }
        for l in &mut layers {
            owners.fill(&mut l.atlas, bb);
        }
        for s in 0..n {
            ensure!(have_mlp[s], "style {:?} has no view MLP (SMLP chunk): its colour part is missing", styles[s].name);
            let missing: Vec<usize> = (0..nb).filter(|&b| !have[s][b]).collect();
            if let Some(&b) = missing.first() {
                bail!(
                    "style {:?} has no colour for {} of {} blocks (first: block {}): its colour part is missing",
                    styles[s].name,
                    missing.len(),
                    nb,
                    b
                );
            }
        }
        Ok(LayeredAsset { styles, layers })
    }
}
