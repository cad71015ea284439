//! The in-memory asset and its whole-file encode/decode. Decoding goes through the same
//! `Assembler` a streaming client uses, in strict file mode, so there is one validator.

use anyhow::{anyhow, ensure, Result};
use std::path::Path;

use crate::assemble::Assembler;
use crate::atomic::write_atomic;
use crate::chunk::{encode_chunk, preamble_of, TAG_BLKS, TAG_END, TAG_GRID, TAG_HEAD, TAG_SGRD, TAG_VMLP};
use crate::quantize::{store_voxels, CHANNELS};
use crate::header::Header;
use crate::mlp::ViewMlp;

/// Indirection-grid entry of an empty cell.
pub const EMPTY: u32 = 0xFFFF_FFFF;

/// A baked scene. Fields are public so the baker may also build one directly (see
/// `AssetBuilder` for the checked way); `validate` says whether it is writable.
///
/// Invariants of a complete asset: `grids.len() == num_frames()`, each grid has
/// `grid_dim()^3` entries, `atlas.len() == atlas_blocks * block_bytes()`,
/// `present.len() == atlas_blocks`. While streaming, a frame whose `GRID` has not arrived
/// has an empty grid and a block not yet arrived has `present == false`; both render empty.
#[derive(Clone, Debug, PartialEq)]
pub struct Asset {
    pub header: Header,
    pub mlp: ViewMlp,
    pub grids: Vec<Vec<u32>>,
    pub atlas: Vec<u8>,
    pub present: Vec<bool>,
}

impl Asset {
    pub fn block_bytes(&self) -> usize {
        self.header.block_bytes()
    }
    pub fn grid_dim(&self) -> usize {
        self.header.grid_dim()
    }
    pub fn num_frames(&self) -> usize {
        self.header.num_frames()
    }
    pub fn is_dynamic(&self) -> bool {
        self.header.is_dynamic()
    }

    /// One time sample of a dynamic asset as a static asset of exactly that occupancy: frame
    /// `f`'s grid and only the blocks it uses (renumbered in order of first use). What a 4D
    /// asset's playback cost is compared with (`snerf bench view --static-twin`). A motion
    /// entry becomes the block it shows (the reference moved, re-quantized), or nothing where
    /// that block is transparent.
    pub fn frame_as_static(&self, f: usize) -> Result<Asset> {
        ensure!(f < self.grids.len(), "frame {} of {}", f, self.grids.len());
        let bb = self.block_bytes();
        let mut remap = std::collections::HashMap::new();
        let mut atlas = Vec::new();
        let mut grid = self.grids[f].clone();
        let mut moved = 0u32;
        for (cell, e) in grid.iter_mut().enumerate() {
            if *e == EMPTY {
                continue;
            }
            if let Some(d) = crate::motion::motion_offset(*e) {
                let blk = self.moved_block(cell, d);
                if blk.chunks_exact(crate::quantize::CHANNELS).all(|v| v[0] == 0) {
                    *e = EMPTY;
                    continue;
                }
                // a unique key per moved block (motion entries never repeat a cell)
                let next = remap.len() as u32;
                remap.insert(crate::motion::MOTION_TAG | 0x4000_0000 | moved, next);
                moved += 1;
                atlas.extend_from_slice(&blk);
                *e = next;
                continue;
            }
            let next = remap.len() as u32;
            let n = *remap.entry(*e).or_insert_with(|| {
                let i = *e as usize;
                atlas.extend_from_slice(&self.atlas[i * bb..(i + 1) * bb]);
                next
            });
            *e = n;
        }
        let mut header = self.header.clone();
        header.frames = None;
        header.time_range = None;
        header.motion_ref = None;
        header.static_frame_blocks = None;
        header.colour_by_density = false;
        header.atlas_blocks = remap.len() as u32;
        let a = Asset { header, mlp: self.mlp.clone(), grids: vec![grid], atlas, present: vec![true; remap.len()] };
        a.validate()?;
        Ok(a)
    }

    /// The apron-inclusive block of `cell` that the reference moved by `d` voxels shows,
    /// quantized like a stored block.
    fn moved_block(&self, cell: usize, d: [f32; 3]) -> Vec<u8> {
        let e = self.header.block as usize + 2;
        let mut out = Vec::with_capacity(self.block_bytes());
        for z in 0..e {
            for y in 0..e {
                for x in 0..e {
                    let loc = crate::sample::Loc { cell, local: [x as f32, y as f32, z as f32] };
                    let v = self.sample_moved(&loc, d);
                    out.extend_from_slice(&crate::quantize::encode_voxel(
                        v[0],
                        [v[1], v[2], v[3]],
                        [v[4], v[5], v[6], v[7]],
                        &self.header.density,
                    ));
                }
            }
        }
        out
    }

    /// Makes the asset diffuse (FORMAT.md, version 2): a zero view MLP, zero specular
    /// features, and the header key that lets the file leave both out. Changes no pixel
    /// exactly when the MLP's output layer was zero (`ViewMlp::output_is_zero`).
    pub fn make_diffuse(&mut self) {
        self.header.diffuse = true;
        self.mlp = ViewMlp::zeros();
        let fc = self.header.file_channels();
        for v in self.atlas.chunks_exact_mut(CHANNELS) {
            v[fc..].fill(0);
        }
    }

    /// Stored bytes of block `i` (None if out of range or not yet arrived).
    pub fn block(&self, i: u32) -> Option<&[u8]> {
        if !*self.present.get(i as usize)? {
            return None;
        }
        let n = self.block_bytes();
        self.atlas.get(i as usize * n..(i as usize + 1) * n)
    }

    /// Read and fully validate a file; errors name the file.
    pub fn read(path: impl AsRef<Path>) -> Result<Asset> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|e| anyhow!("{}: cannot read: {}", path.display(), e))?;
        Asset::from_bytes(&bytes).map_err(|e| anyhow!("{}: {:#}", path.display(), e))
    }

    /// Decode a whole file. Requires every frame's grid, every block and the END chunk. A
    /// multi-style file (`layers`) reads as its first style; `LayeredAsset` reads them all.
    pub fn from_bytes(bytes: &[u8]) -> Result<Asset> {
        if crate::chunk::check_preamble(bytes)? == 3 {
            return crate::layers::LayeredAsset::from_bytes(bytes)?.into_style(0);
        }
        Asset::geometry_from_bytes(bytes).map(|(a, _)| a)
    }

    /// Decode a whole file's header, grids, blocks (and MLP); with a multi-style file's style
    /// chunks, undecoded.
    pub(crate) fn geometry_from_bytes(bytes: &[u8]) -> Result<(Asset, Vec<crate::assemble::StyleChunk>)> {
        let mut asm = Assembler::from_file_bytes(bytes)?;
        let missing = asm.missing_blocks();
        let frames = asm.missing_frames();
        ensure!(asm.has_mlp(), "file has no VMLP chunk");
        ensure!(frames.is_empty(), "file has no GRID chunk for frame {}", frames[0]);
        ensure!(missing.is_empty(), "file lacks {} atlas blocks (first: block {})", missing.len(), missing[0]);
        let styles = std::mem::take(&mut asm.style_chunks);
        Ok((asm.take_asset(), styles))
    }

    /// Whether the file stores its grids as occupied cells only (`SGRD`, version 5) where
    /// that is smaller: the assets with motion (version 4 otherwise), whose readers are all
    /// of this release or later. Their many grids (one a keyframe) are mostly empty cells;
    /// static assets and the codebook alone (`--motion false`) keep dense grids, so readers
    /// from before sparse grids still read them.
    pub fn sparse_grids(&self) -> bool {
        self.header.motion_ref.is_some()
    }

    /// Payload bytes of `grid`'s chunk in this asset's file: sparse where that is smaller.
    pub fn grid_payload_bytes(&self, grid: &[u32]) -> usize {
        let dense = dense_grid_bytes(grid.len());
        if !self.sparse_grids() {
            return dense;
        }
        dense.min(sparse_grid_bytes(grid.iter().filter(|&&e| e != EMPTY).count()))
    }

    /// Encode: preamble, HEAD, VMLP, one GRID per frame, one BLKS per block, END. Blocks not
    /// present and grids not arrived are left out (such a file reads back as incomplete). A
    /// diffuse asset is version 2, without VMLP and with 4 bytes a voxel.
    pub fn to_bytes(&self) -> Vec<u8> {
        self.encode(&[])
    }

    /// `to_bytes` with `extra` chunks (a multi-style asset's styles) before END.
    pub(crate) fn encode(&self, extra: &[([u8; 4], Vec<u8>)]) -> Vec<u8> {
        let mut out =
            Vec::with_capacity(64 + self.atlas.len() + self.grids.iter().map(|g| 4 * g.len() + 16).sum::<usize>());
        let diffuse = self.header.diffuse;
        let sparse = self.sparse_grids();
        out.extend_from_slice(&preamble_of(if sparse { 5 } else { self.header.file_version() }));
        let mut n = 0u32;
        let mut put = |out: &mut Vec<u8>, tag, payload: &[u8]| {
            out.extend_from_slice(&encode_chunk(tag, payload));
            n += 1;
        };
        let head = serde_json::to_vec(&self.header).expect("header serializes");
        put(&mut out, TAG_HEAD, &head);
        if !diffuse && self.header.styles.is_none() {
            let mlp: Vec<u8> = self.mlp.to_flat().iter().flat_map(|x| x.to_le_bytes()).collect();
            put(&mut out, TAG_VMLP, &mlp);
        }
        for (f, grid) in self.grids.iter().enumerate() {
            if grid.is_empty() {
                continue;
            }
            let payload = self.grid_payload_bytes(grid);
            if payload < dense_grid_bytes(grid.len()) {
                let occupied = grid.iter().filter(|&&e| e != EMPTY).count();
                let mut p = Vec::with_capacity(payload);
                p.extend_from_slice(&(f as u32).to_le_bytes());
                p.extend_from_slice(&(occupied as u32).to_le_bytes());
                for (c, e) in grid.iter().enumerate().filter(|(_, &e)| e != EMPTY) {
                    p.extend_from_slice(&(c as u32).to_le_bytes());
                    p.extend_from_slice(&e.to_le_bytes());
                }
                put(&mut out, TAG_SGRD, &p);
                continue;
            }
            let mut p = Vec::with_capacity(dense_grid_bytes(grid.len()));
            p.extend_from_slice(&(f as u32).to_le_bytes());
            for e in grid {
                p.extend_from_slice(&e.to_le_bytes());
            }
            put(&mut out, TAG_GRID, &p);
        }
        let (bb, fc) = (self.block_bytes(), self.header.file_channels());
        for (i, block) in self.atlas.chunks_exact(bb).enumerate() {
            if !self.present.get(i).copied().unwrap_or(false) {
                continue;
            }
            let mut p = Vec::with_capacity(8 + self.header.file_block_bytes());
            p.extend_from_slice(&(i as u32).to_le_bytes());
            p.extend_from_slice(&1u32.to_le_bytes());
            store_voxels(block, fc, &mut p);
            put(&mut out, TAG_BLKS, &p);
        }
        for (tag, payload) in extra {
            put(&mut out, *tag, payload);
        }
        let count = n;
        out.extend_from_slice(&encode_chunk(TAG_END, &count.to_le_bytes()));
        out
    }

    /// Validate, then write atomically (temp file in the same directory, fsync, rename), so
    /// a crash never leaves a torn asset where a good one was.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        self.validate().map_err(|e| anyhow!("{}: refusing to write an invalid asset: {:#}", path.display(), e))?;
        write_atomic(path, &self.to_bytes())
    }

    /// Everything a reader would check, on an in-memory asset (e.g. one built by hand).
    pub fn validate(&self) -> Result<()> {
        let h = &self.header;
        h.validate()?;
        self.mlp.validate()?;
        if h.styles.is_some() {
            // the shared geometry of a multi-style asset: density only (`layers`)
            ensure!(self.mlp == ViewMlp::zeros(), "a multi-style asset's geometry has no view MLP (its styles have)");
            if let Some(v) = self.atlas.chunks_exact(CHANNELS).position(|v| v[1..].iter().any(|&b| b != 0)) {
                anyhow::bail!("a multi-style asset's geometry voxel {} has colour (its styles hold colour)", v);
            }
        } else if h.diffuse {
            // what the file leaves out must be what a reader puts back
            ensure!(self.mlp == ViewMlp::zeros(), "a diffuse asset's view MLP must be zero (its file has none)");
            let fc = h.file_channels();
            if let Some(v) = self.atlas.chunks_exact(CHANNELS).position(|v| v[fc..].iter().any(|&b| b != 0)) {
                anyhow::bail!("a diffuse asset's voxel {} has specular features (its file stores none)", v);
            }
        }
        let bb = self.block_bytes();
        ensure!(
            self.atlas.len() as u64 == h.atlas_blocks as u64 * bb as u64,
            "atlas has {} bytes, header claims {} blocks of {} bytes",
            self.atlas.len(),
            h.atlas_blocks,
            bb
        );
        ensure!(
            self.present.len() == h.atlas_blocks as usize,
            "present has {} flags for {} blocks",
            self.present.len(),
            h.atlas_blocks
        );
        if let Some(i) = self.present.iter().position(|p| !p) {
            anyhow::bail!("atlas block {} is missing", i);
        }
        ensure!(self.grids.len() == self.num_frames(), "{} grids for {} frames", self.grids.len(), self.num_frames());
        let g = self.grid_dim();
        for (f, grid) in self.grids.iter().enumerate() {
            ensure!(grid.len() == g * g * g, "frame {} grid has {} entries, expected {}", f, grid.len(), g * g * g);
            let motion_ok = h.motion_ref.is_some_and(|r| r as usize != f);
            let bad = |e: u32| e != EMPTY && e >= h.atlas_blocks && !(motion_ok && crate::motion::is_motion(e));
            if let Some((c, e)) = grid.iter().enumerate().find(|(_, &e)| bad(e)) {
                if crate::motion::is_motion(*e) {
                    anyhow::bail!("frame {} cell {} holds a motion entry {:#x}, which this frame cannot (motion_ref {:?})", f, c, e, h.motion_ref);
                }
                anyhow::bail!("frame {} cell {} points at block {} (atlas has {})", f, c, e, h.atlas_blocks);
            }
        }
        Ok(())
    }
}

/// Payload bytes of a dense `GRID` of `cells` cells: frame index, one entry a cell.
pub fn dense_grid_bytes(cells: usize) -> usize {
    4 + 4 * cells
}

/// Payload bytes of a sparse `SGRD` with `occupied` cells: frame, count, (cell, entry) pairs.
pub fn sparse_grid_bytes(occupied: usize) -> usize {
    8 + 8 * occupied
}
