//! What `snerf inspect` prints: sizes and occupancy, including what each extra keyframe of
//! a dynamic asset costs (the point of sharing unchanged blocks between frames).

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
}

impl Asset {
    pub fn summary(&self, file_bytes: u64) -> Summary {
        let h = &self.header;
        let g = self.grid_dim() as u64;
        let cells = g * g * g;
        let grid_chunk = (CHUNK_HEADER_LEN as u64) + 4 + 4 * cells;
        let block_chunk = (CHUNK_HEADER_LEN as u64) + 8 + self.block_bytes() as u64;
        let head_len = serde_json::to_vec(h).map(|v| v.len()).unwrap_or(0) as u64;
        let mut seen = vec![false; h.atlas_blocks as usize];
        let mut occupied = Vec::new();
        let mut per_frame = Vec::new();
        for grid in &self.grids {
            let mut occ = 0u64;
            let mut new_blocks = 0u64;
            for &e in grid {
                if e == EMPTY {
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
            per_frame.push(if grid.is_empty() { 0 } else { grid_chunk } + new_blocks * block_chunk);
        }
        let present_blocks = self.present.iter().filter(|&&p| p).count() as u64;
        Summary {
            kind: h.kind,
            res: h.res,
            block: h.block,
            frames: self.num_frames(),
            atlas_blocks: h.atlas_blocks,
            occupied_fraction: occupied.iter().map(|&o| o as f64 / cells.max(1) as f64).collect(),
            occupied_cells: occupied,
            bytes: PartBytes {
                header: PREAMBLE_LEN as u64 + CHUNK_HEADER_LEN as u64 + head_len,
                mlp: CHUNK_HEADER_LEN as u64 + 4 * MLP_FLOATS as u64,
                grids: self.grids.iter().filter(|g| !g.is_empty()).count() as u64 * grid_chunk,
                blocks: present_blocks * block_chunk,
                total: file_bytes,
            },
            frame0_bytes: per_frame.first().copied().unwrap_or(0),
            keyframe_bytes: per_frame.iter().skip(1).copied().collect(),
            unreferenced_blocks: seen.iter().filter(|&&s| !s).count() as u64,
        }
    }
}
