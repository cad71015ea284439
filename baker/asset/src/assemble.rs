//! Chunk semantics: turns checked chunks into an `Asset`, one chunk at a time, in any order
//! after `HEAD`. A streaming client feeds it what arrives and renders the partial asset;
//! `Asset::from_bytes` feeds it a whole file in strict mode (duplicates, END position and
//! the END count are errors there, and sizes are checked against the bytes actually left).

use anyhow::{anyhow, bail, ensure, Result};

use crate::asset::{Asset, EMPTY};
use crate::chunk::{
    check_preamble, le_u32, parse_chunk_at, tag_name, ChunkIter, CHUNK_HEADER_LEN, MAX_HEAD_LEN, PREAMBLE_LEN,
    TAG_BLKS, TAG_END, TAG_GRID, TAG_HEAD, TAG_SCOL, TAG_SGRD, TAG_SMLP, TAG_VMLP,
};
use crate::header::Header;
use crate::mlp::{ViewMlp, MLP_FLOATS};
use crate::quantize::load_voxels;

pub struct Assembler {
    asset: Asset,
    have_mlp: bool,
    have_grid: Vec<bool>,
    missing: usize,
    /// Chunks accepted so far, HEAD included (names chunks in error messages).
    seen: usize,
    end: Option<u32>,
    /// File mode: the chunk sequence is the file's, so order and duplicates are checked.
    strict: bool,
    /// The file's version (from its preamble): which chunks it may hold.
    version: u32,
    /// A multi-style file's style chunks (index, tag, payload), decoded by `layers` once
    /// the geometry they colour has been read.
    pub(crate) style_chunks: Vec<StyleChunk>,
}

/// A multi-style file's SMLP or SCOL chunk, undecoded: its index, tag and payload.
pub(crate) type StyleChunk = (usize, [u8; 4], Vec<u8>);

/// Parse and validate a `HEAD` payload.
pub fn parse_head(payload: &[u8]) -> Result<Header> {
    ensure!(payload.len() <= MAX_HEAD_LEN, "HEAD is {} bytes (max {})", payload.len(), MAX_HEAD_LEN);
    let text = std::str::from_utf8(payload).map_err(|e| anyhow!("HEAD is not UTF-8: {}", e))?;
    let h: Header = serde_json::from_str(text).map_err(|e| anyhow!("HEAD is not a valid header: {}", e))?;
    h.validate()?;
    Ok(h)
}

impl Assembler {
    /// Start from the first bytes of a stream: the 16-byte preamble and the HEAD chunk,
    /// optionally followed by further whole chunks (all of which are pushed).
    pub fn new(bytes: &[u8]) -> Result<Assembler> {
        let version = check_preamble(bytes)?;
        let head = parse_chunk_at(bytes, PREAMBLE_LEN, 0)?;
        ensure!(head.tag == TAG_HEAD, "chunk 0 is {}, expected HEAD", tag_name(&head.tag));
        let header = parse_head(&bytes[head.payload.clone()])?;
        ensure!(
            header.styles.is_none(),
            "a multi-style asset (version 3) cannot be streamed yet; bake one style to stream it"
        );
        let mut asm = Assembler::with_header(header, version, false)?;
        for c in ChunkIter::new(bytes, head.range.end, 1) {
            let c = c?;
            asm.push(c.tag, &bytes[c.payload])?;
        }
        Ok(asm)
    }

    /// Strict whole-file decode (used by `Asset::from_bytes`).
    pub(crate) fn from_file_bytes(bytes: &[u8]) -> Result<Assembler> {
        let version = check_preamble(bytes)?;
        let mut iter = ChunkIter::new(bytes, PREAMBLE_LEN, 0);
        let head = match iter.next() {
            None => bail!("file has no chunks after the preamble (truncated?)"),
            Some(c) => c?,
        };
        ensure!(head.tag == TAG_HEAD, "chunk 0 is {}, expected HEAD", tag_name(&head.tag));
        let header = parse_head(&bytes[head.payload.clone()])?;
        // Before allocating from the header: could the rest of the file even hold what it
        // claims? Every block and grid entry needs its bytes on disk.
        let remaining = (bytes.len() - head.range.end) as u64;
        let g = header.grid_dim() as u64;
        let atlas = header.atlas_blocks as u64 * header.file_block_bytes() as u64;
        let dense_grids = header.num_frames() as u64 * 4 * g * g * g;
        // a sparse grid (version 5) needs its frame and count on disk, and is expanded in
        // memory, so the expanded grids are bounded as an atlas is
        let grids = if version >= 5 {
            ensure!(
                dense_grids <= crate::header::MAX_ATLAS_BYTES,
                "header claims {} frames of {}^3 cells ({} bytes of grids in memory, max {})",
                header.num_frames(),
                g,
                dense_grids,
                crate::header::MAX_ATLAS_BYTES
            );
            header.num_frames() as u64 * (CHUNK_HEADER_LEN as u64 + 8)
        } else {
            dense_grids
        };
        ensure!(
            atlas + grids <= remaining,
            "header claims {} atlas blocks and {} frames of {}^3 cells ({} bytes) but only {} bytes follow",
            header.atlas_blocks,
            header.num_frames(),
            g,
            atlas + grids,
            remaining
        );
        if let Some(styles) = &header.styles {
            // every style needs a colour chunk per block (a layer holds a copy of the atlas)
            let n = styles.len() as u64;
            let colours = n * header.atlas_blocks as u64 * (CHUNK_HEADER_LEN as u64 + 12);
            ensure!(
                atlas + grids + colours <= remaining,
                "header claims {} styles of {} blocks but only {} bytes follow",
                n,
                header.atlas_blocks,
                remaining
            );
            let layers = (n + 1) * header.atlas_blocks as u64 * header.block_bytes() as u64;
            ensure!(
                layers <= crate::header::MAX_ATLAS_BYTES,
                "header claims {} styles of {} blocks: {} bytes in memory (max {})",
                n,
                header.atlas_blocks,
                layers,
                crate::header::MAX_ATLAS_BYTES
            );
        }
        let mut asm = Assembler::with_header(header, version, true)?;
        for c in iter {
            let c = c?;
            ensure!(asm.end.is_none(), "chunk {} ({}) follows the END chunk", c.index, tag_name(&c.tag));
            asm.push(c.tag, &bytes[c.payload])?;
        }
        ensure!(asm.end.is_some(), "file ends without an END chunk (truncated?)");
        Ok(asm)
    }

    fn with_header(header: Header, version: u32, strict: bool) -> Result<Assembler> {
        header.validate()?;
        ensure!(
            version >= header.file_version(),
            "the header says {}, which a version {} file cannot be (needs version {})",
            match header.file_version() {
                4 => "motion",
                3 => "multi-style",
                _ => "diffuse",
            },
            version,
            header.file_version()
        );
        let n = header.atlas_blocks as usize;
        let frames = header.num_frames();
        let atlas = vec![0u8; n * header.block_bytes()];
        // a diffuse asset's view MLP is zero and has no chunk: it is there from the start (a
        // multi-style asset's are per style, in SMLP chunks)
        let have_mlp = header.diffuse || header.styles.is_some();
        let asset =
            Asset { mlp: ViewMlp::zeros(), grids: vec![Vec::new(); frames], atlas, present: vec![false; n], header };
        Ok(Assembler {
            asset,
            have_mlp,
            have_grid: vec![false; frames],
            missing: n,
            seen: 1,
            end: None,
            strict,
            version,
            style_chunks: Vec::new(),
        })
    }

    /// Accept one whole encoded chunk (checks its framing and CRC).
    pub fn push_chunk(&mut self, encoded: &[u8]) -> Result<()> {
        let c = parse_chunk_at(encoded, 0, self.seen)?;
        ensure!(
            c.range.end == encoded.len(),
            "chunk {} ({}) has {} trailing bytes",
            self.seen,
            tag_name(&c.tag),
            encoded.len() - c.range.end
        );
        self.push(c.tag, &encoded[c.payload])
    }

    /// Accept one chunk's payload whose integrity the caller has already checked.
    pub fn push(&mut self, tag: [u8; 4], payload: &[u8]) -> Result<()> {
        let index = self.seen;
        let name = tag_name(&tag);
        let r = match tag {
            TAG_HEAD => Err(anyhow!("duplicate HEAD")),
            TAG_VMLP => self.push_mlp(payload),
            TAG_GRID => self.push_grid(payload),
            TAG_SGRD if self.version >= 5 => self.push_sparse_grid(payload),
            TAG_SGRD => Err(anyhow!("a sparse grid in a version {} file (sparse grids need version 5)", self.version)),
            TAG_BLKS => self.push_blocks(payload),
            TAG_END => self.push_end(payload, index),
            TAG_SMLP | TAG_SCOL if self.asset.header.styles.is_some() => {
                self.style_chunks.push((index, tag, payload.to_vec()));
                Ok(())
            }
            TAG_SMLP | TAG_SCOL => Err(anyhow!("a style chunk in an asset that lists no styles")),
            _ => Err(anyhow!("unknown chunk tag")),
        };
        r.map_err(|e| anyhow!("chunk {} ({}): {:#}", index, name, e))?;
        self.seen += 1;
        Ok(())
    }

    fn push_mlp(&mut self, p: &[u8]) -> Result<()> {
        ensure!(self.asset.header.styles.is_none(), "a multi-style asset keeps its view MLPs per style (SMLP)");
        ensure!(!self.asset.header.diffuse, "a diffuse asset has no view MLP");
        ensure!(!self.have_mlp, "duplicate VMLP");
        ensure!(
            p.len() == MLP_FLOATS * 4,
            "VMLP has {} bytes, expected {} ({} f32)",
            p.len(),
            MLP_FLOATS * 4,
            MLP_FLOATS
        );
        let floats: Vec<f32> = p.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        self.asset.mlp = ViewMlp::from_flat(&floats)?;
        self.have_mlp = true;
        Ok(())
    }

    fn push_grid(&mut self, p: &[u8]) -> Result<()> {
        let g = self.asset.grid_dim();
        let cells = g * g * g;
        ensure!(
            p.len() == 4 + 4 * cells,
            "GRID has {} bytes, expected {} (frame index + {}^3 entries)",
            p.len(),
            4 + 4 * cells,
            g
        );
        let frame = self.grid_frame(p)?;
        let grid: Vec<u32> = p[4..].chunks_exact(4).map(le_u32).collect();
        self.set_grid(frame, grid)
    }

    /// `SGRD`: frame, count, then (cell, entry) pairs in increasing cell order.
    fn push_sparse_grid(&mut self, p: &[u8]) -> Result<()> {
        ensure!(p.len() >= 8, "SGRD has {} bytes, needs at least 8", p.len());
        let g = self.asset.grid_dim();
        let cells = g * g * g;
        let count = le_u32(&p[4..8]) as usize;
        ensure!(count <= cells, "SGRD lists {count} cells of a grid of {g}^3");
        ensure!(
            p.len() == crate::asset::sparse_grid_bytes(count),
            "SGRD has {} bytes, expected {} (frame, count + {count} cell/entry pairs)",
            p.len(),
            crate::asset::sparse_grid_bytes(count)
        );
        let frame = self.grid_frame(p)?;
        let mut grid = vec![EMPTY; cells];
        let mut next = 0usize;
        for pair in p[8..].chunks_exact(8) {
            let (c, e) = (le_u32(&pair[..4]) as usize, le_u32(&pair[4..]));
            ensure!(c >= next && c < cells, "SGRD for frame {frame} lists cell {c} out of order or outside the {g}^3 grid");
            ensure!(e != EMPTY, "SGRD for frame {frame} lists cell {c} as empty");
            grid[c] = e;
            next = c + 1;
        }
        self.set_grid(frame, grid)
    }

    /// The frame a grid chunk is for (its first 4 bytes), checked.
    fn grid_frame(&self, p: &[u8]) -> Result<usize> {
        let frame = le_u32(&p[..4]) as usize;
        let frames = self.asset.num_frames();
        ensure!(frame < frames, "grid for frame {} but the asset has {} frames", frame, frames);
        ensure!(!self.have_grid[frame], "duplicate grid for frame {}", frame);
        Ok(frame)
    }

    fn set_grid(&mut self, frame: usize, grid: Vec<u32>) -> Result<()> {
        let n = self.asset.header.atlas_blocks;
        // motion entries: in a motion asset, in any frame but the one they point into
        let motion_ok = self.asset.header.motion_ref.is_some_and(|r| r as usize != frame);
        for (c, &e) in grid.iter().enumerate() {
            ensure!(
                e == EMPTY || e < n || (motion_ok && crate::motion::is_motion(e)),
                "frame {} cell {} points at block {} (atlas has {})",
                frame,
                c,
                e,
                n
            );
        }
        self.asset.grids[frame] = grid;
        self.have_grid[frame] = true;
        Ok(())
    }

    fn push_blocks(&mut self, p: &[u8]) -> Result<()> {
        ensure!(p.len() >= 8, "BLKS has {} bytes, needs at least 8", p.len());
        let first = le_u32(&p[..4]) as u64;
        let count = le_u32(&p[4..8]) as u64;
        let n = self.asset.header.atlas_blocks as u64;
        ensure!(count >= 1, "BLKS with count 0");
        ensure!(first + count <= n, "BLKS blocks {}..{} out of range (atlas has {})", first, first + count, n);
        let fb = self.asset.header.file_block_bytes() as u64;
        ensure!(
            (p.len() - 8) as u64 == count * fb,
            "BLKS has {} data bytes, expected {} ({} blocks of {})",
            p.len() - 8,
            count * fb,
            count,
            fb
        );
        let (first, count, bb) = (first as usize, count as usize, self.asset.block_bytes());
        if self.strict {
            if let Some(i) = (first..first + count).find(|&i| self.asset.present[i]) {
                bail!("duplicate block {}", i);
            }
        }
        let fc = self.asset.header.file_channels();
        load_voxels(&mut self.asset.atlas[first * bb..(first + count) * bb], &p[8..], fc);
        for i in first..first + count {
            if !self.asset.present[i] {
                self.asset.present[i] = true;
                self.missing -= 1;
            }
        }
        Ok(())
    }

    fn push_end(&mut self, p: &[u8], index: usize) -> Result<()> {
        ensure!(p.len() == 4, "END has {} bytes, expected 4", p.len());
        let count = le_u32(p);
        ensure!(self.end.is_none(), "duplicate END");
        if self.strict {
            ensure!(
                count as usize == index,
                "END says {} chunks precede it but there are {} (chunks lost?)",
                count,
                index
            );
        }
        self.end = Some(count);
        Ok(())
    }

    /// The asset as far as it has arrived (missing blocks/grids render as empty).
    pub fn asset(&self) -> &Asset {
        &self.asset
    }
    pub fn header(&self) -> &Header {
        &self.asset.header
    }
    pub fn take_asset(&mut self) -> Asset {
        let h = self.asset.header.clone();
        std::mem::replace(
            &mut self.asset,
            Asset { header: h, mlp: ViewMlp::zeros(), grids: Vec::new(), atlas: Vec::new(), present: Vec::new() },
        )
    }
    pub fn into_asset(self) -> Asset {
        self.asset
    }
    pub fn has_mlp(&self) -> bool {
        self.have_mlp
    }
    /// Everything has arrived: the MLP, every frame's grid and every block.
    pub fn is_complete(&self) -> bool {
        self.have_mlp && self.missing == 0 && self.have_grid.iter().all(|&g| g)
    }
    pub fn missing_blocks(&self) -> Vec<u32> {
        self.asset.present.iter().enumerate().filter(|(_, &p)| !p).map(|(i, _)| i as u32).collect()
    }
    pub fn missing_frames(&self) -> Vec<usize> {
        self.have_grid.iter().enumerate().filter(|(_, &g)| !g).map(|(i, _)| i).collect()
    }
    /// Whether the END chunk has arrived (the stream's sender says it is done).
    pub fn saw_end(&self) -> bool {
        self.end.is_some()
    }
}
