//! The baker's checked way to make an asset: give it a header (res, block, kind, space,
//! density range, march, background, and for dynamic assets time_range + frames), then put
//! blocks into cells frame by frame. Identical blocks at the same cell in consecutive frames
//! are stored once (the "store only blocks that change" rule of dynamic assets). Building
//! `Asset` by hand is also allowed; `Asset::validate` then says whether it is consistent.

use anyhow::{ensure, Result};

use crate::asset::{Asset, EMPTY};
use crate::header::Header;
use crate::mlp::ViewMlp;
use crate::quantize::CHANNELS;

pub struct AssetBuilder {
    header: Header,
    mlp: ViewMlp,
    grids: Vec<Vec<u32>>,
    atlas: Vec<u8>,
    blocks: u32,
}

impl AssetBuilder {
    /// `header.atlas_blocks` is ignored (the builder counts blocks). Frames come from
    /// `header.frames` (dynamic) or are the single frame 0 (static).
    pub fn new(mut header: Header, mlp: ViewMlp) -> Result<AssetBuilder> {
        header.atlas_blocks = 0;
        header.validate()?;
        mlp.validate()?;
        let g = header.grid_dim();
        let grids = vec![vec![EMPTY; g * g * g]; header.num_frames()];
        Ok(AssetBuilder { header, mlp, grids, atlas: Vec::new(), blocks: 0 })
    }

    pub fn header(&self) -> &Header {
        &self.header
    }
    pub fn num_blocks(&self) -> u32 {
        self.blocks
    }

    fn cell_index(&self, frame: usize, cell: [usize; 3]) -> Result<usize> {
        let g = self.header.grid_dim();
        ensure!(frame < self.grids.len(), "frame {} out of range ({} frames)", frame, self.grids.len());
        ensure!(cell.iter().all(|&c| c < g), "cell {:?} out of range (grid {}^3)", cell, g);
        Ok((cell[2] * g + cell[1]) * g + cell[0])
    }

    /// Store `voxels` ((block+2)^3 x 8 bytes, apron included) as the block of `cell` in
    /// `frame`. If the previous frame holds a byte-identical block at this cell, that block
    /// is reused instead of stored again. Returns the atlas index used.
    pub fn set_block(&mut self, frame: usize, cell: [usize; 3], voxels: &[u8]) -> Result<u32> {
        let idx = self.cell_index(frame, cell)?;
        let bb = self.header.block_bytes();
        ensure!(voxels.len() == bb, "block has {} bytes, expected {}", voxels.len(), bb);
        if frame > 0 {
            let prev = self.grids[frame - 1][idx];
            if prev != EMPTY && self.atlas[prev as usize * bb..(prev as usize + 1) * bb] == *voxels {
                self.grids[frame][idx] = prev;
                return Ok(prev);
            }
        }
        let i = self.blocks;
        self.atlas.extend_from_slice(voxels);
        self.blocks += 1;
        self.grids[frame][idx] = i;
        Ok(i)
    }

    /// Point `cell` of `frame` at an already stored block (explicit sharing).
    pub fn share_block(&mut self, frame: usize, cell: [usize; 3], block: u32) -> Result<()> {
        let idx = self.cell_index(frame, cell)?;
        ensure!(block < self.blocks, "block {} not stored yet ({} blocks)", block, self.blocks);
        self.grids[frame][idx] = block;
        Ok(())
    }

    /// Lay out one block of `cell` from a per-voxel function of *global* voxel indices. The
    /// apron reads the neighbours' voxels; beyond the grid edge the index is clamped (edge
    /// voxels repeat), so `voxel` only ever sees indices in 0..res.
    pub fn block_from_fn(&self, cell: [usize; 3], mut voxel: impl FnMut([usize; 3]) -> [u8; CHANNELS]) -> Vec<u8> {
        let b = self.header.block as i64;
        let res = self.header.res as i64;
        let e = (b + 2) as usize;
        let mut out = vec![0u8; self.header.block_bytes()];
        for z in 0..e {
            for y in 0..e {
                for x in 0..e {
                    let gi = |c: usize, l: usize| (c as i64 * b - 1 + l as i64).clamp(0, res - 1) as usize;
                    let v = voxel([gi(cell[0], x), gi(cell[1], y), gi(cell[2], z)]);
                    let off = ((z * e + y) * e + x) * CHANNELS;
                    out[off..off + CHANNELS].copy_from_slice(&v);
                }
            }
        }
        out
    }

    /// Store a block at every cell of `frame` from a per-voxel function of global voxel
    /// indices (a dense asset; tests and synthetic scenes).
    pub fn fill_from_fn(&mut self, frame: usize, voxel: impl Fn([usize; 3]) -> [u8; CHANNELS]) -> Result<()> {
        let g = self.header.grid_dim();
        for z in 0..g {
            for y in 0..g {
                for x in 0..g {
                    let blk = self.block_from_fn([x, y, z], &voxel);
                    self.set_block(frame, [x, y, z], &blk)?;
                }
            }
        }
        Ok(())
    }

    pub fn finish(mut self) -> Result<Asset> {
        self.header.atlas_blocks = self.blocks;
        let asset = Asset {
            header: self.header,
            mlp: self.mlp,
            grids: self.grids,
            present: vec![true; self.blocks as usize],
            atlas: self.atlas,
        };
        asset.validate()?;
        Ok(asset)
    }
}
