//! Diffuse assets (version 2): a scene whose view MLP has a zero output layer is stored
//! without the VMLP chunk and with 4 bytes a voxel, reads back exactly, renders the same
//! pixels as the full file, streams in any order, and is refused where a reader could
//! otherwise get it wrong.
use snerf_asset::chunk::{check_preamble, TAG_VMLP};
use snerf_asset::{chunks, encode_chunk, encode_voxel, orbit, preamble, render, Asset, AssetBuilder, Assembler, Header, Kind, ViewMlp};

/// res 16, block 4: a few blocks of varied density and colour, with specular features, and a
/// view MLP whose hidden layers are not zero but whose output layer is (what a diffuse
/// stylized field bakes from).
fn full() -> Asset {
    let mut h = Header::new(Kind::Object, 16, 4);
    h.background = [0.2, 0.3, 0.4];
    let mut mlp = ViewMlp::zeros();
    for (i, w) in mlp.w1.iter_mut().enumerate() {
        *w = ((i * 7 % 13) as f32 - 6.0) * 0.05;
    }
    mlp.b1.fill(0.1);
    for (i, w) in mlp.w2.iter_mut().enumerate() {
        *w = ((i * 5 % 11) as f32 - 5.0) * 0.05;
    }
    let mut b = AssetBuilder::new(h.clone(), mlp).unwrap();
    for (k, cell) in [[1, 1, 1], [2, 1, 1], [1, 2, 1], [2, 2, 2], [1, 1, 2]].into_iter().enumerate() {
        let blk = b.block_from_fn(cell, |v| {
            let t = (v[0] + 2 * v[1] + 3 * v[2]) as f32 / 64.0;
            encode_voxel(0.5 + 3.0 * t, [t, 0.2 + 0.1 * k as f32, 1.0 - t], [0.3, 0.6, 0.9, t], &h.density)
        });
        b.set_block(0, cell, &blk).unwrap();
    }
    b.finish().unwrap()
}

/// The same scene as a diffuse asset: zero MLP, zero features.
fn diffuse_of(a: &Asset) -> Asset {
    let mut d = a.clone();
    d.make_diffuse();
    d
}

#[test]
fn a_diffuse_file_is_version_2_without_mlp_or_features_and_reads_back_exactly() {
    let a = full();
    let d = diffuse_of(&a);
    let (fa, fd) = (a.to_bytes(), d.to_bytes());
    assert_eq!(check_preamble(&fa).unwrap(), 1, "an asset that is not diffuse stays version 1");
    assert_eq!(check_preamble(&fd).unwrap(), 2);
    assert!(chunks(&fd).unwrap().iter().all(|c| c.tag != TAG_VMLP), "a diffuse file has no VMLP chunk");
    let blocks = (a.atlas.len() / 2) as i64;
    let mlp = 12 + 883 * 4;
    let head = |b: &[u8]| chunks(b).unwrap()[0].payload.len() as i64;
    let key = head(&fd) - head(&fa);
    assert_eq!(key, r#","diffuse":true"#.len() as i64);
    assert_eq!(fa.len() as i64 - fd.len() as i64, blocks + mlp - key, "the file saves 4 bytes a voxel and the MLP chunk");
    let back = Asset::from_bytes(&fd).unwrap();
    assert_eq!(back, d);
    // the summary counts what the file holds
    let s = back.summary(fd.len() as u64);
    assert!(s.diffuse && !a.summary(fa.len() as u64).diffuse);
    assert_eq!(s.bytes.mlp, 0);
    assert_eq!(s.bytes.header + s.bytes.grids + s.bytes.blocks + 12 + 4, fd.len() as u64, "{:?}", s.bytes);
}

#[test]
fn leaving_out_what_a_zero_output_layer_ignores_changes_no_pixel() {
    let a = full();
    let d = Asset::from_bytes(&diffuse_of(&a).to_bytes()).unwrap();
    for i in 0..3 {
        let cam = orbit(&a.header, 3, i, 24, 20, 45.0);
        let (fa, fd) = (render(&a, &cam, 0.0), render(&d, &cam, 0.0));
        assert!(fa.opacity.iter().any(|&o| o > 0.5), "view {i} sees the scene");
        assert_eq!(fa.rgb, fd.rgb, "view {i}");
        assert_eq!(fa.depth, fd.depth, "view {i}");
    }
}

#[test]
fn a_diffuse_file_streams_in_any_order() {
    let d = diffuse_of(&full());
    let bytes = d.to_bytes();
    let cs = chunks(&bytes).unwrap();
    let mut asm = Assembler::new(&bytes[..cs[0].range.end]).unwrap();
    assert!(asm.has_mlp(), "a diffuse asset's (zero) MLP is there with the header");
    let mut rest: Vec<_> = cs[1..].to_vec();
    rest.reverse();
    for c in rest {
        asm.push_chunk(&bytes[c.range.clone()]).unwrap();
    }
    assert!(asm.is_complete());
    assert_eq!(asm.into_asset(), d);
}

#[test]
fn what_a_reader_could_get_wrong_is_refused() {
    let a = full();
    // an asset that claims diffuse but would drop information
    let mut bad = a.clone();
    bad.header.diffuse = true;
    let e = format!("{:#}", bad.validate().unwrap_err());
    assert!(e.contains("view MLP must be zero"), "{e}");
    bad.mlp = ViewMlp::zeros();
    let e = format!("{:#}", bad.validate().unwrap_err());
    assert!(e.contains("specular features"), "{e}");

    let d = diffuse_of(&a).to_bytes();
    // a diffuse header in a version 1 file
    let mut v1 = d.clone();
    v1[..16].copy_from_slice(&preamble());
    let e = format!("{:#}", Asset::from_bytes(&v1).unwrap_err());
    assert!(e.contains("needs version 2"), "{e}");
    // a VMLP chunk in a diffuse file
    let cs = chunks(&d).unwrap();
    let mut with_mlp = d[..cs[1].range.start].to_vec();
    with_mlp.extend(encode_chunk(TAG_VMLP, &vec![0u8; 883 * 4]));
    let mut n = 2u32;
    for c in &cs[1..cs.len() - 1] {
        with_mlp.extend_from_slice(&d[c.range.clone()]);
        n += 1;
    }
    with_mlp.extend(encode_chunk(*b"END ", &n.to_le_bytes()));
    let e = format!("{:#}", Asset::from_bytes(&with_mlp).unwrap_err());
    assert!(e.contains("chunk 1 (VMLP)") && e.contains("no view MLP"), "{e}");
    // blocks of the full size in a diffuse file
    let full_blocks = a.to_bytes();
    let mut mixed = d[..cs[1].range.start].to_vec();
    let fc = chunks(&full_blocks).unwrap();
    let mut n = 1u32;
    for c in fc.iter().filter(|c| c.tag != TAG_VMLP && c.tag != *b"HEAD" && c.tag != *b"END ") {
        mixed.extend_from_slice(&full_blocks[c.range.clone()]);
        n += 1;
    }
    mixed.extend(encode_chunk(*b"END ", &n.to_le_bytes()));
    let e = format!("{:#}", Asset::from_bytes(&mixed).unwrap_err());
    assert!(e.contains("BLKS") && e.contains("data bytes"), "{e}");
}
