//! Malformed files: every problem is an error that names the chunk/field, never a panic or
//! a large allocation.
use snerf_asset::{chunks, encode_chunk, encode_voxel, preamble, Asset, AssetBuilder, Header, Kind, ViewMlp};

/// A tiny asset: res 8, block 4, 3 blocks.
fn tiny() -> Asset {
    let h = Header::new(Kind::Object, 8, 4);
    let mut b = AssetBuilder::new(h.clone(), ViewMlp::zeros()).unwrap();
    for cell in [[0, 0, 0], [1, 0, 0], [1, 1, 1]] {
        let blk = b.block_from_fn(cell, |v| encode_voxel(v[0] as f32 * 0.1, [0.5; 3], [0.0; 4], &h.density));
        b.set_block(0, cell, &blk).unwrap();
    }
    b.finish().unwrap()
}

/// The file's chunks as (tag, payload), without END.
fn parts(bytes: &[u8]) -> Vec<([u8; 4], Vec<u8>)> {
    chunks(bytes)
        .unwrap()
        .into_iter()
        .filter(|c| &c.tag != b"END ")
        .map(|c| (c.tag, bytes[c.payload].to_vec()))
        .collect()
}

/// Re-encode chunks with a correct END.
fn build(parts: &[([u8; 4], Vec<u8>)]) -> Vec<u8> {
    let mut out = preamble().to_vec();
    for (t, p) in parts {
        out.extend(encode_chunk(*t, p));
    }
    out.extend(encode_chunk(*b"END ", &(parts.len() as u32).to_le_bytes()));
    out
}

fn with_header(edit: impl FnOnce(&mut serde_json::Value)) -> Vec<u8> {
    let mut p = parts(&tiny().to_bytes());
    let mut v: serde_json::Value = serde_json::from_slice(&p[0].1).unwrap();
    edit(&mut v);
    p[0].1 = serde_json::to_vec(&v).unwrap();
    build(&p)
}

fn err_of(bytes: &[u8]) -> String {
    format!("{:#}", Asset::from_bytes(bytes).expect_err("must be rejected"))
}

#[test]
fn every_truncation_is_an_error() {
    let bytes = tiny().to_bytes();
    assert!(Asset::from_bytes(&bytes).is_ok());
    for n in 0..bytes.len() {
        let r = std::panic::catch_unwind(|| Asset::from_bytes(&bytes[..n]));
        let r = r.unwrap_or_else(|_| panic!("panic at prefix {}", n));
        assert!(r.is_err(), "prefix {} of {} accepted", n, bytes.len());
    }
    // cut at a chunk boundary: END missing
    let cs = chunks(&bytes).unwrap();
    let e = err_of(&bytes[..cs[cs.len() - 1].range.start]);
    assert!(e.contains("END"), "{}", e);
    let last_blks = cs.len() - 2;
    let e = err_of(&bytes[..cs[last_blks].range.end - 5]);
    assert!(e.contains(&format!("chunk {} (BLKS)", last_blks)) && e.contains("truncated"), "{}", e);
    // cut early: the header's claims no longer fit in what follows
    let e = err_of(&bytes[..cs[2].range.end + 5]);
    assert!(e.contains("bytes follow"), "{}", e);
}

#[test]
fn flipped_bit_in_each_chunk_names_the_chunk() {
    let bytes = tiny().to_bytes();
    let cs = chunks(&bytes).unwrap();
    for c in &cs {
        let mut b = bytes.clone();
        let mid = (c.payload.start + c.payload.end) / 2;
        b[mid] ^= 0x10;
        let name = String::from_utf8_lossy(&c.tag).to_string();
        let e = err_of(&b);
        assert!(e.contains(&format!("chunk {} ({})", c.index, name)) && e.contains("checksum mismatch"), "{}", e);
        // and in the stored CRC itself
        let mut b = bytes.clone();
        b[c.range.start + 9] ^= 0x01;
        let e = err_of(&b);
        assert!(e.contains(&format!("chunk {}", c.index)), "{}", e);
    }
}

#[test]
fn absurd_header_sizes_are_rejected_before_allocating() {
    let e = err_of(&with_header(|v| v["res"] = 1_000_000.into()));
    assert!(e.contains("res 1000000 (max 2048)"), "{}", e);
    let e = err_of(&with_header(|v| v["res"] = 10_000.into())); // 10^12 voxels
    assert!(e.contains("res 10000"), "{}", e);
    let e = err_of(&with_header(|v| {
        v["res"] = 2048.into();
        v["block"] = 4.into();
    }));
    assert!(e.contains("512^3 cells"), "{}", e);
    let e = err_of(&with_header(|v| v["atlas_blocks"] = 4_000_000_000u32.into()));
    assert!(e.contains("atlas blocks") && e.contains("max"), "{}", e);
    let e = err_of(&with_header(|v| v["atlas_blocks"] = 1_000_000.into()));
    assert!(e.contains("only") && e.contains("bytes follow"), "{}", e);
    let e = err_of(&with_header(|v| v["atlas_blocks"] = 1e15.into()));
    assert!(e.contains("HEAD"), "{}", e);
    let e = err_of(&with_header(|v| v["block"] = 3.into()));
    assert!(e.contains("block 3"), "{}", e);
    let e = err_of(&with_header(|v| v["res"] = 10.into()));
    assert!(e.contains("multiple"), "{}", e);
    let e = err_of(&with_header(|v| {
        v["time_range"] = serde_json::json!([0.0, 1.0]);
        v["frames"] = serde_json::Value::Array(vec![serde_json::json!({"time": 0.0}); 5000]);
    }));
    assert!(e.contains("5000 frames"), "{}", e);
    let e = err_of(&with_header(|v| v["march"]["step"] = 0.0.into()));
    assert!(e.contains("step"), "{}", e);
    let e = err_of(&with_header(|v| v["format"] = "other".into()));
    assert!(e.contains("format"), "{}", e);
    let e = err_of(&with_header(|v| v["kind"] = "forward".into()));
    assert!(e.contains("ndc"), "{}", e);
    // HEAD too large
    let mut p = parts(&tiny().to_bytes());
    p[0].1.extend(vec![b' '; 2 << 20]);
    let e = err_of(&build(&p));
    assert!(e.contains("HEAD is") && e.contains("max"), "{}", e);
}

#[test]
fn structural_errors() {
    let good = parts(&tiny().to_bytes());
    let idx = |tag: &[u8; 4]| good.iter().position(|(t, _)| t == tag).unwrap();

    // grid entry outside the atlas
    let mut p = good.clone();
    let g = idx(b"GRID");
    p[g].1[4..8].copy_from_slice(&3u32.to_le_bytes());
    let e = err_of(&build(&p));
    assert!(e.contains("GRID") && e.contains("points at block 3 (atlas has 3)"), "{}", e);

    // BLKS index + count out of range
    let mut p = good.clone();
    let b = idx(b"BLKS");
    p[b].1[0..4].copy_from_slice(&2u32.to_le_bytes());
    p[b].1[4..8].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = err_of(&build(&p));
    assert!(e.contains("BLKS") && e.contains("out of range"), "{}", e);
    let mut p = good.clone();
    p[b].1[4..8].copy_from_slice(&0u32.to_le_bytes());
    assert!(err_of(&build(&p)).contains("count 0"));
    let mut p = good.clone();
    p[b].1.pop();
    assert!(err_of(&build(&p)).contains("data bytes"));

    // wrong VMLP length, non-finite weights
    let mut p = good.clone();
    let m = idx(b"VMLP");
    p[m].1.truncate(4 * 880);
    let e = err_of(&build(&p));
    assert!(e.contains("VMLP") && e.contains("883"), "{}", e);
    let mut p = good.clone();
    p[m].1[0..4].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(err_of(&build(&p)).contains("non-finite"));

    // duplicates, missing parts
    for tag in [b"HEAD", b"VMLP", b"GRID"] {
        let mut p = good.clone();
        p.push(good[idx(tag)].clone());
        let e = err_of(&build(&p));
        assert!(e.contains("duplicate"), "{}", e);
    }
    let mut p = good.clone();
    p.push(good[idx(b"BLKS")].clone());
    assert!(err_of(&build(&p)).contains("duplicate block"));
    let mut p = good.clone();
    p.remove(idx(b"BLKS"));
    assert!(err_of(&build(&p)).contains("lacks 1 atlas blocks"));
    let mut p = good.clone();
    p.remove(idx(b"GRID"));
    assert!(err_of(&build(&p)).contains("frame 0"));
    let mut p = good.clone();
    p.remove(idx(b"VMLP"));
    assert!(err_of(&build(&p)).contains("VMLP"));
    let mut p = good.clone();
    p.swap(0, 1);
    assert!(err_of(&build(&p)).contains("expected HEAD"));
    let mut p = good.clone();
    p.push((*b"ZZZZ", vec![1, 2, 3]));
    assert!(err_of(&build(&p)).contains("unknown chunk tag"));
    // GRID for a frame the asset doesn't have
    let mut p = good.clone();
    p[g].1[0..4].copy_from_slice(&1u32.to_le_bytes());
    assert!(err_of(&build(&p)).contains("frame 1"));

    // END count wrong, chunk after END
    let mut bytes = build(&good);
    let n = bytes.len();
    bytes.truncate(n - 16);
    bytes.extend(encode_chunk(*b"END ", &7u32.to_le_bytes()));
    let e = err_of(&bytes);
    assert!(e.contains("END says 7"), "{}", e);
    let mut bytes = build(&good);
    bytes.extend(encode_chunk(*b"VMLP", &[]));
    assert!(err_of(&bytes).contains("follows the END"));
}

#[test]
fn bad_preamble() {
    let mut bytes = tiny().to_bytes();
    bytes[8] = 3;
    let e = err_of(&bytes);
    assert!(e.contains("version 3"), "{}", e);
    let mut bytes = tiny().to_bytes();
    bytes[0] = b'X';
    assert!(err_of(&bytes).contains("magic"));
    let mut bytes = tiny().to_bytes();
    bytes[12] = 1;
    assert!(err_of(&bytes).contains("flags"));
    assert!(err_of(b"").contains("preamble"));
}

#[test]
fn huge_chunk_length_is_rejected() {
    let mut bytes = tiny().to_bytes();
    let cs = chunks(&bytes).unwrap();
    let at = cs[1].range.start + 4;
    bytes[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
    let e = err_of(&bytes);
    assert!(e.contains("chunk 1 (VMLP) claims 4294967295 bytes (max"), "{}", e);
    bytes[at..at + 4].copy_from_slice(&(100u32 << 20).to_le_bytes());
    let e = err_of(&bytes);
    assert!(e.contains("remain"), "{}", e);
}
