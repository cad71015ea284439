//! Framing: the 16-byte preamble and the tag/length/CRC chunks that follow it. Knows nothing
//! about what chunks mean; it only guarantees that every chunk it hands out lies inside the
//! buffer and passed its checksum, so the layers above never see torn or corrupted bytes.

use anyhow::{bail, ensure, Result};
use std::ops::Range;

pub const MAGIC: [u8; 8] = *b"SNERFAST";
/// The newest version this reader knows. Version 2 is version 1 plus `diffuse` assets,
/// version 3 adds multi-style assets, version 4 motion entries in dynamic assets (FORMAT.md;
/// `motion`), version 5 sparse grids (`SGRD`); a writer uses the lowest version that
/// holds its asset, so older readers still read every asset of their versions.
pub const VERSION: u32 = 5;
pub const PREAMBLE_LEN: usize = 16;
/// tag (4) + length (4) + CRC-32 (4).
pub const CHUNK_HEADER_LEN: usize = 12;
/// Largest chunk payload any reader accepts.
pub const MAX_CHUNK_LEN: usize = 256 << 20;
/// Largest `HEAD` payload.
pub const MAX_HEAD_LEN: usize = 1 << 20;

pub const TAG_HEAD: [u8; 4] = *b"HEAD";
pub const TAG_VMLP: [u8; 4] = *b"VMLP";
pub const TAG_GRID: [u8; 4] = *b"GRID";
/// A frame's grid as its occupied cells only (version 5): frame, count, then `count`
/// (cell, entry) pairs in increasing cell order; every other cell is empty.
pub const TAG_SGRD: [u8; 4] = *b"SGRD";
pub const TAG_BLKS: [u8; 4] = *b"BLKS";
pub const TAG_END: [u8; 4] = *b"END ";
/// A style's view MLP in a multi-style asset (version 3).
pub const TAG_SMLP: [u8; 4] = *b"SMLP";
/// A style's colours of one block in a multi-style asset (version 3).
pub const TAG_SCOL: [u8; 4] = *b"SCOL";

/// The preamble of a version 1 file (every asset that is not diffuse).
pub fn preamble() -> [u8; PREAMBLE_LEN] {
    preamble_of(1)
}

/// The preamble of a file of `version`.
pub fn preamble_of(version: u32) -> [u8; PREAMBLE_LEN] {
    let mut p = [0u8; PREAMBLE_LEN];
    p[..8].copy_from_slice(&MAGIC);
    p[8..12].copy_from_slice(&version.to_le_bytes());
    // bytes 12..16: flags, 0 in versions 1 to 5
    p
}

/// Check the preamble at the start of `bytes`; the file's version.
pub fn check_preamble(bytes: &[u8]) -> Result<u32> {
    ensure!(
        bytes.len() >= PREAMBLE_LEN,
        "file too short for the preamble ({} bytes, need {})",
        bytes.len(),
        PREAMBLE_LEN
    );
    ensure!(bytes[..8] == MAGIC, "not a snerf asset (bad magic {})", tag_name(&bytes[..8]));
    let version = le_u32(&bytes[8..12]);
    ensure!(
        (1..=VERSION).contains(&version),
        "unsupported asset version {} (this reader knows versions 1 to {})",
        version,
        VERSION
    );
    let flags = le_u32(&bytes[12..16]);
    ensure!(flags == 0, "unsupported asset flags {:#x} (version {} defines none)", flags, version);
    Ok(version)
}

/// One chunk inside a buffer; its CRC has been checked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChunkRef {
    /// Position in the file's chunk sequence (HEAD = 0), as used in error messages.
    pub index: usize,
    pub tag: [u8; 4],
    /// The whole encoded chunk (header + payload), e.g. for forwarding it unchanged.
    pub range: Range<usize>,
    /// The payload alone.
    pub payload: Range<usize>,
}

/// tag + length + CRC + payload.
pub fn encode_chunk(tag: [u8; 4], payload: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(CHUNK_HEADER_LEN + payload.len());
    out.extend_from_slice(&tag);
    out.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(payload).to_le_bytes());
    out.extend_from_slice(payload);
    out
}

/// Split a whole file into checked chunks (preamble first). Fails on the first framing or
/// checksum problem; does not interpret chunk contents (see `Asset::from_bytes`).
pub fn chunks(bytes: &[u8]) -> Result<Vec<ChunkRef>> {
    check_preamble(bytes)?;
    ChunkIter::new(bytes, PREAMBLE_LEN, 0).collect()
}

/// Lazily walks the chunks from `pos`, so a reader can reject a bad header before it
/// spends time checksumming gigabytes of blocks behind it.
pub struct ChunkIter<'a> {
    bytes: &'a [u8],
    pos: usize,
    index: usize,
    failed: bool,
}

impl<'a> ChunkIter<'a> {
    /// Walk from byte `pos`, numbering the first chunk found there `index`.
    pub fn new(bytes: &'a [u8], pos: usize, index: usize) -> ChunkIter<'a> {
        ChunkIter { bytes, pos, index, failed: false }
    }
}

impl Iterator for ChunkIter<'_> {
    type Item = Result<ChunkRef>;
    fn next(&mut self) -> Option<Result<ChunkRef>> {
        if self.failed || self.pos >= self.bytes.len() {
            return None;
        }
        let r = parse_chunk_at(self.bytes, self.pos, self.index);
        match &r {
            Ok(c) => {
                self.pos = c.range.end;
                self.index += 1;
            }
            Err(_) => self.failed = true,
        }
        Some(r)
    }
}

/// Parse and CRC-check the chunk starting at `pos`; `index` only names it in errors.
pub fn parse_chunk_at(bytes: &[u8], pos: usize, index: usize) -> Result<ChunkRef> {
    let rest = bytes.get(pos..).unwrap_or(&[]);
    if rest.len() < CHUNK_HEADER_LEN {
        bail!(
            "chunk {}: only {} bytes left, a chunk header needs {} (file truncated?)",
            index,
            rest.len(),
            CHUNK_HEADER_LEN
        );
    }
    let tag: [u8; 4] = [rest[0], rest[1], rest[2], rest[3]];
    let name = tag_name(&tag);
    let len = le_u32(&rest[4..8]) as usize;
    let crc = le_u32(&rest[8..12]);
    let avail = rest.len() - CHUNK_HEADER_LEN;
    ensure!(len <= MAX_CHUNK_LEN, "chunk {} ({}) claims {} bytes (max {})", index, name, len, MAX_CHUNK_LEN);
    ensure!(
        len <= avail,
        "chunk {} ({}) claims {} bytes but only {} remain (file truncated?)",
        index,
        name,
        len,
        avail
    );
    let start = pos + CHUNK_HEADER_LEN;
    let payload = start..start + len;
    ensure!(crc32fast::hash(&bytes[payload.clone()]) == crc, "chunk {} ({}) checksum mismatch", index, name);
    Ok(ChunkRef { index, tag, range: pos..payload.end, payload })
}

/// Printable form of a tag for messages (non-ASCII bytes escaped, so garbage stays readable).
pub fn tag_name(tag: &[u8]) -> String {
    tag.iter()
        .map(|&b| if b.is_ascii_graphic() || b == b' ' { (b as char).to_string() } else { format!("\\x{:02x}", b) })
        .collect()
}

#[inline]
pub fn le_u32(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}
