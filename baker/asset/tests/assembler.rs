//! Streaming assembly: chunks in any order give the same asset; missing parts render empty.
mod common;
use common::*;
use snerf_asset::render::render_ray;
use snerf_asset::{chunks, encode_chunk, Assembler, Asset};

#[test]
fn shuffled_chunks_assemble_to_the_same_asset() {
    for dynamic in [false, true] {
        let a = sphere_asset(dynamic);
        let bytes = a.to_bytes();
        let cs = chunks(&bytes).unwrap();
        let head_end = cs[0].range.end;
        let mut asm = Assembler::new(&bytes[..head_end]).unwrap();
        assert!(!asm.is_complete());
        assert_eq!(asm.missing_blocks().len(), a.header.atlas_blocks as usize);
        let mut rest: Vec<_> = cs[1..].to_vec();
        let mut rng = Rng(0x1234_5678 + dynamic as u64);
        for i in (1..rest.len()).rev() {
            let j = rng.below(i as u64 + 1) as usize;
            rest.swap(i, j);
        }
        let n = rest.len();
        for (k, c) in rest.iter().enumerate() {
            assert!(!asm.is_complete(), "complete before chunk {} of {}", k, n);
            if k % 2 == 0 {
                asm.push_chunk(&bytes[c.range.clone()]).unwrap();
            } else {
                asm.push(c.tag, &bytes[c.payload.clone()]).unwrap();
            }
        }
        assert!(asm.is_complete());
        assert!(asm.missing_blocks().is_empty() && asm.missing_frames().is_empty());
        assert_eq!(asm.asset(), &a);
        assert_eq!(asm.into_asset(), a);
    }
}

#[test]
fn missing_blocks_render_as_empty() {
    let a = sphere_asset(false);
    let bytes = a.to_bytes();
    let cs = chunks(&bytes).unwrap();
    let mut asm = Assembler::new(&bytes[..cs[0].range.end]).unwrap();
    // A ray through the sphere's centre, straight down -z.
    let (o, d) = ([0.01, 0.02, 3.0], [0.0, 0.0, -1.0]);
    let empty = render_ray(asm.asset(), o, d, 0.0);
    assert_eq!(empty.opacity, 0.0);
    assert_eq!(empty.rgb, a.header.background);
    // grid + MLP but no blocks: still empty
    for c in cs.iter().filter(|c| &c.tag == b"GRID" || &c.tag == b"VMLP") {
        asm.push_chunk(&bytes[c.range.clone()]).unwrap();
    }
    assert_eq!(render_ray(asm.asset(), o, d, 0.0).opacity, 0.0);
    assert!(asm.asset().sample(0, [0.0, 0.0, 0.0]).is_none());
    // now every block
    for c in cs.iter().filter(|c| &c.tag == b"BLKS") {
        asm.push_chunk(&bytes[c.range.clone()]).unwrap();
    }
    assert!(asm.is_complete(), "END is optional when streaming");
    let full = render_ray(asm.asset(), o, d, 0.0);
    assert!(full.opacity > 0.9, "{:?}", full);
    assert_eq!(full, render_ray(&a, o, d, 0.0));
}

#[test]
fn streaming_rejects_bad_chunks_but_accepts_resent_blocks() {
    let a = sphere_asset(false);
    let bytes = a.to_bytes();
    let cs = chunks(&bytes).unwrap();
    let mut asm = Assembler::new(&bytes[..cs[0].range.end]).unwrap();
    let blk = cs.iter().find(|c| &c.tag == b"BLKS").unwrap();
    asm.push_chunk(&bytes[blk.range.clone()]).unwrap();
    asm.push_chunk(&bytes[blk.range.clone()]).unwrap(); // resent: harmless
    let mut corrupt = bytes[blk.range.clone()].to_vec();
    let last = corrupt.len() - 1;
    corrupt[last] ^= 1;
    let err = asm.push_chunk(&corrupt).unwrap_err().to_string();
    assert!(err.contains("BLKS") && err.contains("checksum"), "{}", err);
    let err = asm.push(*b"HEAD", b"{}").unwrap_err().to_string();
    assert!(err.contains("duplicate HEAD"), "{}", err);
    let err = asm.push(*b"XXXX", b"").unwrap_err().to_string();
    assert!(err.contains("unknown"), "{}", err);
    let err = asm.push_chunk(&encode_chunk(*b"GRID", &[0; 7])).unwrap_err().to_string();
    assert!(err.contains("GRID"), "{}", err);
    // a whole file can be given to new() too
    let whole = Assembler::new(&bytes).unwrap();
    assert!(whole.is_complete() && whole.saw_end());
    assert_eq!(whole.asset(), &Asset::from_bytes(&bytes).unwrap());
}
