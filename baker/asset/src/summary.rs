//! What `snerf inspect` prints: sizes and occupancy, including what each extra keyframe of
//! a dynamic asset costs (the point of sharing blocks between frames), its size against one
//! static frame of the same scene, and its bytes per second of animation, per part.

use serde::{Deserialize, Serialize};

use crate::asset::{Asset, EMPTY};
use crate::chunk::{CHUNK_HEADER_LEN, PREAMBLE_LEN};
use crate::header::Kind;
use crate::mlp::MLP_FLOATS;

/// Encoded bytes per part, as `Asset::to_bytes` lays them out (chunk headers included).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartBytes {
    /// Preamble + HEAD chunk.
    pub header: u64,
    pub mlp: u64,
    pub grids: u64,
    pub blocks: u64,
    /// The file's actual size as given by the caller.
    pub total: u64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    pub kind: Kind,
    pub res: u32,
    pub block: u32,
    pub frames: usize,
    pub atlas_blocks: u32,
    /// Colour independent of the view: no view MLP and 4 bytes a voxel in the file.
    pub diffuse: bool,
    /// Non-empty indirection cells per frame, and as a fraction of all g^3 cells.
    pub occupied_cells: Vec<u64>,
    pub occupied_fraction: Vec<f64>,
    pub bytes: PartBytes,
    /// Frame 0's grid plus the blocks it references.
    pub frame0_bytes: u64,
    /// Per additional keyframe: its grid plus the blocks it is first to reference.
    pub keyframe_bytes: Vec<u64>,
    /// Blocks no frame points at (wasted space; a good baker has none).
    pub unreferenced_blocks: u64,
    /// One static frame of this scene: preamble, HEAD, VMLP, one grid, and the blocks a
    /// static bake keeps at a keyframe's time, averaged over the keyframes (the header's
    /// `static_frame_blocks`, recorded by the bake; without it, one block per cell the asset
    /// draws in the average frame).
    pub static_frame_bytes: u64,
    /// `bytes.total / static_frame_bytes`.
    pub size_vs_static_frame: f64,
    /// Dynamic assets: cells whose frames point at more than one block (the moving part),
    /// of the cells occupied in any frame.
    pub cells_changing: u64,
    pub cells_occupied_any_frame: u64,
    /// Dynamic assets with a time range of positive length: its length (the asset's time
    /// unit, seconds for captures) and each part's bytes per unit of it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub animation_seconds: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bytes_per_second: Option<PartRates>,
    /// A multi-style asset's styles, each with the bytes of its colour part (`bytes` above
    /// is then the shared geometry's, and `total` the whole file's; `static_frame_bytes`
    /// counts the geometry alone).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub styles: Vec<crate::layers::StyleBytes>,
}

/// Bytes per second of animation of each part of a dynamic asset.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartRates {
    pub header: f64,
    pub mlp: f64,
    pub grids: f64,
    pub blocks: f64,
    pub total: f64,
}

impl Asset {
    pub fn summary(&self, file_bytes: u64) -> Summary {
        let h = &self.header;
        let g = self.grid_dim() as u64;
        let cells = g * g * g;
        let grid_chunk = (CHUNK_HEADER_LEN as u64) + 4 + 4 * cells;
        let block_chunk = (CHUNK_HEADER_LEN as u64) + 8 + h.file_block_bytes() as u64;
        let head_len = serde_json::to_vec(h).map(|v| v.len()).unwrap_or(0) as u64;
        let mut seen = vec![false; h.atlas_blocks as usize];
        let mut occupied = Vec::new();
        let mut per_frame = Vec::new();
        for grid in &self.grids {
            let mut occ = 0u64;
            let mut new_blocks = 0u64;
            for (c, &e) in grid.iter().enumerate() {
                if e == EMPTY {
                    continue;
                }
                // a motion entry stands for a block where it moves one into the cell
                if let Some(d) = crate::motion::motion_offset(e) {
                    occ += self.motion_reads_a_block(c, d) as u64;
                    continue;
                }
                occ += 1;
                if let Some(s) = seen.get_mut(e as usize) {
                    if !*s {
                        *s = true;
                        new_blocks += 1;
                    }
                }
            }
            occupied.push(occ);
            let grid_bytes = if grid.is_empty() { 0 } else { CHUNK_HEADER_LEN as u64 + self.grid_payload_bytes(grid) as u64 };
            per_frame.push(grid_bytes + new_blocks * block_chunk);
        }
        let present_blocks = self.present.iter().filter(|&&p| p).count() as u64;
        let head = PREAMBLE_LEN as u64 + CHUNK_HEADER_LEN as u64 + head_len;
        let mlp = if h.diffuse || h.styles.is_some() { 0 } else { CHUNK_HEADER_LEN as u64 + 4 * MLP_FLOATS as u64 };
        let grids_bytes: u64 =
            self.grids.iter().filter(|g| !g.is_empty()).map(|g| CHUNK_HEADER_LEN as u64 + self.grid_payload_bytes(g) as u64).sum();
        let blocks_bytes = present_blocks * block_chunk;
        let mean_occupied = occupied.iter().sum::<u64>() as f64 / occupied.len().max(1) as f64;
        // one static frame: what a static bake at a keyframe's time keeps (the bake records
        // it), else the cells this asset draws at one
        let static_blocks = h.static_frame_blocks.map_or(mean_occupied, |n| n as f64);
        // (a static asset's one grid is dense)
        let static_frame_bytes = head + mlp + grid_chunk + (static_blocks * block_chunk as f64).round() as u64;
        let (mut cells_changing, mut cells_occupied_any_frame) = (0u64, 0u64);
        for c in 0..cells as usize {
            let at = |g: &Vec<u32>| g.get(c).copied().unwrap_or(EMPTY);
            let first = self.grids.first().map_or(EMPTY, at);
            cells_changing += self.grids.iter().any(|g| at(g) != first) as u64;
            cells_occupied_any_frame += self.grids.iter().any(|g| at(g) != EMPTY) as u64;
        }
        let animation_seconds = h.time_range.map(|r| (r[1] - r[0]) as f64).filter(|&s| s > 0.0);
        let bytes_per_second = animation_seconds.map(|s| PartRates {
            header: head as f64 / s,
            mlp: mlp as f64 / s,
            grids: grids_bytes as f64 / s,
            blocks: blocks_bytes as f64 / s,
            total: file_bytes as f64 / s,
        });
        Summary {
            kind: h.kind,
            res: h.res,
            block: h.block,
            frames: self.num_frames(),
            atlas_blocks: h.atlas_blocks,
            diffuse: h.diffuse,
            occupied_fraction: occupied.iter().map(|&o| o as f64 / cells.max(1) as f64).collect(),
            occupied_cells: occupied,
            bytes: PartBytes { header: head, mlp, grids: grids_bytes, blocks: blocks_bytes, total: file_bytes },
            frame0_bytes: per_frame.first().copied().unwrap_or(0),
            keyframe_bytes: per_frame.iter().skip(1).copied().collect(),
            unreferenced_blocks: seen.iter().filter(|&&s| !s).count() as u64,
            static_frame_bytes,
            size_vs_static_frame: file_bytes as f64 / static_frame_bytes.max(1) as f64,
            cells_changing,
            cells_occupied_any_frame,
            animation_seconds,
            bytes_per_second,
            styles: Vec::new(),
        }
    }
}
