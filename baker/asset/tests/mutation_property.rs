//! Property test without dependencies: mutate a valid file (bit flips, truncations,
//! insertions, random length fields, with or without fixing the CRCs) and feed fully random
//! chunk streams; decoding and streaming assembly must never panic and must stay fast.
mod common;
use common::*;
use snerf_asset::chunk::parse_chunk_at;
use snerf_asset::{
    chunks, encode_chunk, encode_voxel, preamble, Assembler, Asset, AssetBuilder, Header, Kind, ViewMlp,
};
use std::time::Instant;

fn small_valid() -> Vec<u8> {
    let mut h = Header::new(Kind::Unbounded, 8, 4);
    h.time_range = Some([0.0, 1.0]);
    h.frames = Some(vec![snerf_asset::Keyframe { time: 0.0 }, snerf_asset::Keyframe { time: 1.0 }]);
    let mut b = AssetBuilder::new(h.clone(), ViewMlp::zeros()).unwrap();
    for f in 0..2 {
        for cell in [[0, 0, 0], [1, 0, 1]] {
            let blk = b.block_from_fn(cell, |v| encode_voxel(v[0] as f32 * f as f32, [0.5; 3], [0.0; 4], &h.density));
            b.set_block(f, cell, &blk).unwrap();
        }
    }
    b.finish().unwrap().to_bytes()
}

/// Re-encode every chunk with a correct CRC (so mutations reach the semantic checks).
fn fix_crcs(bytes: &[u8]) -> Vec<u8> {
    let mut out = bytes[..bytes.len().min(16)].to_vec();
    let mut pos = 16;
    while pos + 12 <= bytes.len() {
        let len = u32::from_le_bytes(bytes[pos + 4..pos + 8].try_into().unwrap()) as usize;
        let end = (pos + 12).saturating_add(len).min(bytes.len());
        let tag: [u8; 4] = bytes[pos..pos + 4].try_into().unwrap();
        out.extend(encode_chunk(tag, &bytes[pos + 12..end]));
        pos = end;
    }
    out
}

fn exercise(bytes: &[u8]) {
    let r = std::panic::catch_unwind(|| {
        let _ = chunks(bytes);
        if let Ok(a) = Asset::from_bytes(bytes) {
            // accepted input must be usable: sample and re-encode
            let _ = a.sample_at_time(0.5, [0.1, -0.2, 0.3]);
            let _ = a.summary(bytes.len() as u64);
            assert!(Asset::from_bytes(&a.to_bytes()).is_ok());
        }
        let head_end = parse_chunk_at(bytes, 16, 0).map(|c| c.range.end).unwrap_or(bytes.len());
        if let Ok(mut asm) = Assembler::new(&bytes[..head_end]) {
            if let Ok(cs) = chunks(bytes) {
                for c in cs {
                    let _ = asm.push_chunk(&bytes[c.range]);
                }
            }
            let _ = asm.asset().sample(0, [0.0; 3]);
            let _ = asm.is_complete();
        }
    });
    assert!(r.is_ok(), "panic on input of {} bytes: {:?}", bytes.len(), &bytes[..bytes.len().min(64)]);
}

#[test]
fn mutated_files_never_panic() {
    let valid = small_valid();
    assert!(Asset::from_bytes(&valid).is_ok());
    // Seeds for the cargo-fuzz targets (baker/asset/fuzz): SNERF_ASSET_SEED_DIR=dir.
    if let Some(dir) = std::env::var_os("SNERF_ASSET_SEED_DIR") {
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(std::path::Path::new(&dir).join("dynamic.snerf"), &valid).unwrap();
    }
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let start = Instant::now();
    let mut accepted = 0;
    for it in 0..20_000 {
        let mut b = valid.clone();
        let edits = 1 + rng.below(4);
        for _ in 0..edits {
            match rng.below(6) {
                0 => {
                    let i = rng.below(b.len() as u64) as usize;
                    b[i] ^= 1 << rng.below(8);
                }
                1 => {
                    let n = rng.below(b.len() as u64 + 1) as usize;
                    b.truncate(n);
                }
                2 => {
                    let i = rng.below(b.len() as u64 + 1) as usize;
                    let n = 1 + rng.below(16) as usize;
                    let ins: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
                    b.splice(i..i, ins);
                }
                3 => {
                    // overwrite a plausible u32 field (length / index / count) with an extreme
                    if b.len() >= 4 {
                        let i = rng.below(b.len() as u64 - 3) as usize;
                        let v =
                            [0u32, 1, 2, 0xFFFF_FFFF, 0x7FFF_FFFF, 1 << 28, rng.next() as u32][rng.below(7) as usize];
                        b[i..i + 4].copy_from_slice(&v.to_le_bytes());
                    }
                }
                4 => {
                    let i = rng.below(b.len() as u64 + 1) as usize;
                    b.splice(
                        i..i,
                        encode_chunk(*[b"BLKS", b"GRID", b"VMLP", b"END ", b"HEAD"][rng.below(5) as usize], &[]),
                    );
                }
                _ => {
                    let i = rng.below(b.len() as u64) as usize;
                    b[i] = rng.next() as u8;
                }
            }
        }
        if it % 2 == 0 {
            b = fix_crcs(&b);
        }
        exercise(&b);
        accepted += Asset::from_bytes(&b).is_ok() as u32;
    }
    let el = start.elapsed();
    eprintln!("mutations: {} accepted of 20000 in {:?}", accepted, el);
}

#[test]
fn random_chunk_streams_never_panic() {
    let mut rng = Rng(42);
    let start = Instant::now();
    let tags = [*b"HEAD", *b"VMLP", *b"GRID", *b"BLKS", *b"END ", *b"\0\xff ?"];
    let head = {
        let v = small_valid();
        let c = &chunks(&v).unwrap()[0];
        v[c.payload.clone()].to_vec()
    };
    for it in 0..5_000 {
        let mut b = preamble().to_vec();
        if it % 2 == 0 {
            b.extend(encode_chunk(*b"HEAD", &head));
        }
        for _ in 0..rng.below(6) {
            let big = rng.below(4) == 0;
            let n = rng.below(if big { 4000 } else { 40 }) as usize;
            let mut payload: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
            if n >= 8 && rng.below(2) == 0 {
                payload[..4].copy_from_slice(&(rng.below(4) as u32).to_le_bytes());
            }
            b.extend(encode_chunk(tags[rng.below(tags.len() as u64) as usize], &payload));
        }
        if rng.below(3) == 0 {
            let n = rng.below(64) as usize;
            b.extend((0..n).map(|_| rng.next() as u8));
        }
        exercise(&b);
    }
    eprintln!("random chunk streams: {:?}", start.elapsed());
}
