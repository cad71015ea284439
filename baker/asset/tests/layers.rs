//! Multi-style assets (version 3, `layers`): two styles of one geometry round-trip through
//! the file exactly, each renders within 1/255 of the CPU reference of a single-style asset
//! of that style, the colour parts are smaller than a whole asset, and a layer that is
//! missing or made for another geometry is refused with the file and the problem named.
use snerf_asset::chunk::{check_preamble, TAG_SCOL, TAG_SMLP};
use snerf_asset::{
    chunks, encode_chunk, encode_voxel, orbit, preamble, render, Asset, AssetBuilder, Assembler, Header, Kind, LayeredAsset,
    StyleInfo, ViewMlp,
};

const RES: u32 = 32;
const BLOCK: u32 = 8;

/// A ball of radius `r` (density code 0 outside: empty air, as the baker writes it) whose
/// colour is `paint` of the voxel's position; view MLP and features for a non-diffuse asset.
fn ball(r: f32, paint: impl Fn([f32; 3]) -> [f32; 3], diffuse: bool) -> Asset {
    let mut h = Header::new(Kind::Object, RES, BLOCK);
    h.background = [0.1, 0.2, 0.3];
    let mut mlp = ViewMlp::zeros();
    for (i, w) in mlp.w1.iter_mut().enumerate() {
        *w = ((i * 7 % 13) as f32 - 6.0) * 0.05;
    }
    mlp.b1.fill(0.1);
    for (i, w) in mlp.w2.iter_mut().enumerate() {
        *w = ((i * 5 % 11) as f32 - 5.0) * 0.05;
    }
    for (i, w) in mlp.w3.iter_mut().enumerate() {
        *w = ((i * 3 % 7) as f32 - 3.0) * 0.02;
    }
    let g = h.grid_dim();
    let at = |i: usize| -1.0 + (i as f32 + 0.5) * 2.0 / RES as f32;
    let mut b = AssetBuilder::new(h.clone(), mlp).unwrap();
    for z in 0..g {
        for y in 0..g {
            for x in 0..g {
                let blk = b.block_from_fn([x, y, z], |v| {
                    let p = v.map(at);
                    let d = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
                    let logit = if d < r { 2.0 + 4.0 * (r - d) } else { -10.0 };
                    encode_voxel(logit, paint(p), [0.2, 0.5, 0.7, 0.9], &h.density)
                });
                if blk.chunks_exact(8).any(|v| v[0] > 0) {
                    b.set_block(0, [x, y, z], &blk).unwrap();
                }
            }
        }
    }
    let mut a = b.finish().unwrap();
    if diffuse {
        a.make_diffuse();
    }
    a
}

fn warm(p: [f32; 3]) -> [f32; 3] {
    [0.8 + 0.2 * p[0], 0.4 + 0.3 * p[1], 0.1 + 0.1 * p[2]]
}
fn cold(p: [f32; 3]) -> [f32; 3] {
    [0.1 + 0.1 * p[2], 0.3 + 0.2 * p[0], 0.9 - 0.1 * p[1]]
}

fn info(name: &str) -> StyleInfo {
    StyleInfo { name: name.into(), source: Some(format!("painting:{name}")), swatch: [0.5, 0.5, 0.5] }
}

fn two_styles(diffuse: bool) -> (LayeredAsset, [Asset; 2]) {
    let singles = [ball(0.6, warm, diffuse), ball(0.6, cold, diffuse)];
    let l = LayeredAsset::new(vec![info("warm"), info("cold")], singles.to_vec()).unwrap();
    (l, singles)
}

/// The largest difference of any pixel channel between two renders.
fn max_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f32::max)
}

#[test]
fn two_styles_round_trip_and_render_like_their_single_style_assets() {
    for diffuse in [false, true] {
        let (l, singles) = two_styles(diffuse);
        let bytes = l.to_bytes();
        assert_eq!(check_preamble(&bytes).unwrap(), 3, "a multi-style asset is version 3");
        let back = LayeredAsset::from_bytes(&bytes).unwrap();
        assert_eq!(back, l, "diffuse {diffuse}: exact round trip");
        assert_eq!(Asset::from_bytes(&bytes).unwrap(), l.layers[0], "a one-style reader gets the first style");
        // every style against the CPU reference of its own single-style file (version 1 or 2)
        for (name, single) in ["warm", "cold"].iter().zip(&singles) {
            let single = Asset::from_bytes(&single.to_bytes()).unwrap();
            assert!(check_preamble(&single.to_bytes()).unwrap() <= 2);
            let layer = back.style(name).unwrap();
            for i in 0..3 {
                let cam = orbit(&single.header, 3, i, 32, 24, 45.0);
                let (fs, fl) = (render(&single, &cam, 0.0), render(layer, &cam, 0.0));
                assert!(fs.opacity.iter().any(|&o| o > 0.5), "view {i} sees the ball");
                let d = max_diff(&fs.rgb, &fl.rgb);
                assert!(d <= 1.0 / 255.0, "diffuse {diffuse}, style {name}, view {i}: differs by {d}");
                assert!(max_diff(&fs.depth, &fl.depth) < 1e-3 && max_diff(&fs.opacity, &fl.opacity) < 1e-4);
            }
        }
        // the two styles really are different pictures
        let cam = orbit(&l.layers[0].header, 3, 0, 32, 24, 45.0);
        assert!(max_diff(&render(&l.layers[0], &cam, 0.0).rgb, &render(&l.layers[1], &cam, 0.0).rgb) > 0.2);
        // sizes: one layer is much smaller than a whole single-style file, and the parts add up
        let s = back.summary(bytes.len() as u64);
        assert_eq!(s.styles.len(), 2);
        assert_eq!(s.styles[1].name, "cold");
        let parts = s.bytes.header + s.bytes.mlp + s.bytes.grids + s.bytes.blocks + s.styles.iter().map(|x| x.bytes).sum::<u64>() + 16;
        assert_eq!(parts, bytes.len() as u64, "{:?}", s);
        let whole = singles[1].to_bytes().len() as f64;
        let ratio = s.styles[1].bytes as f64 / whole;
        eprintln!("diffuse {diffuse}: a layer is {ratio:.3} of a whole asset");
        assert!(ratio < 0.35, "diffuse {diffuse}: a layer is {ratio:.3} of a whole asset");
    }
}

#[test]
fn a_file_round_trip_names_the_styles() {
    let dir = snerf_files::ScratchDir::new("snerf-asset-layers", "file").unwrap();
    let path = dir.join("styles.snerf");
    let (l, _) = two_styles(true);
    l.write(&path).unwrap();
    let back = LayeredAsset::read(&path).unwrap();
    assert_eq!(back.names(), vec!["warm".to_string(), "cold".to_string()]);
    assert_eq!(back, l);
    let err = back.style("blue").unwrap_err().to_string();
    assert!(err.contains("\"blue\"") && err.contains("warm, cold"), "{err}");
}

/// The file's chunks with `keep` deciding which stay (END recounted).
fn rebuild(bytes: &[u8], keep: impl Fn(usize, [u8; 4], &[u8]) -> Option<Vec<u8>>) -> Vec<u8> {
    let mut out = preamble().to_vec();
    out[8..12].copy_from_slice(&bytes[8..12]);
    let mut n = 0u32;
    for c in chunks(bytes).unwrap() {
        if c.tag == *b"END " {
            continue;
        }
        if let Some(p) = keep(c.index, c.tag, &bytes[c.payload.clone()]) {
            out.extend_from_slice(&encode_chunk(c.tag, &p));
            n += 1;
        }
    }
    out.extend_from_slice(&encode_chunk(*b"END ", &n.to_le_bytes()));
    out
}

fn read_err(dir: &snerf_files::ScratchDir, name: &str, bytes: &[u8]) -> String {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    let e = format!("{:#}", LayeredAsset::read(&path).unwrap_err());
    let e1 = format!("{:#}", Asset::read(&path).unwrap_err());
    assert_eq!(e, e1, "both readers refuse it alike");
    assert!(e.contains(name), "the error names the file: {e}");
    e
}

#[test]
fn malformed_layers_are_refused_with_the_file_and_the_problem_named() {
    let dir = snerf_files::ScratchDir::new("snerf-asset-layers", "bad").unwrap();
    let (l, _) = two_styles(false);
    let bytes = l.to_bytes();
    let style_of = |p: &[u8]| u32::from_le_bytes([p[0], p[1], p[2], p[3]]);

    // a style's colour part is missing (all of it, or one block of it)
    let no_cold = rebuild(&bytes, |_, t, p| ((t != TAG_SCOL && t != TAG_SMLP) || style_of(p) == 0).then(|| p.to_vec()));
    let e = read_err(&dir, "no-cold.snerf", &no_cold);
    assert!(e.contains("\"cold\"") && e.contains("colour part is missing"), "{e}");
    let first_scol = chunks(&bytes).unwrap().into_iter().find(|c| c.tag == TAG_SCOL).unwrap().index;
    let e = read_err(&dir, "one-block.snerf", &rebuild(&bytes, |i, _, p| (i != first_scol).then(|| p.to_vec())));
    assert!(e.contains("\"warm\"") && e.contains("no colour for 1 of") && e.contains("block 0"), "{e}");

    // a layer made for another geometry: the colour chunks of a ball of another radius
    let other = LayeredAsset::new(vec![info("warm"), info("cold")], vec![ball(0.5, warm, false), ball(0.5, cold, false)]).unwrap();
    let foreign: Vec<Vec<u8>> = chunks(&other.to_bytes())
        .unwrap()
        .into_iter()
        .filter(|c| c.tag == TAG_SCOL)
        .map(|c| other.to_bytes()[c.payload].to_vec())
        .filter(|p| style_of(p) == 1)
        .collect();
    let spliced = rebuild(&bytes, |_, t, p| {
        if t == TAG_SCOL && style_of(p) == 1 {
            let b = u32::from_le_bytes([p[4], p[5], p[6], p[7]]) as usize;
            return Some(foreign.iter().find(|f| u32::from_le_bytes([f[4], f[5], f[6], f[7]]) as usize == b).unwrap_or(&p.to_vec()).clone());
        }
        Some(p.to_vec())
    });
    let e = read_err(&dir, "spliced.snerf", &spliced);
    assert!(e.contains("(SCOL)") && e.contains("\"cold\"") && e.contains("another geometry"), "{e}");
    // ... or one whose checksum was forged to match: the live voxels do not add up
    let forged = rebuild(&bytes, |_, t, p| {
        let mut p = p.to_vec();
        if t == TAG_SCOL && style_of(&p) == 1 {
            p.truncate(p.len() - 3);
        }
        Some(p)
    });
    let e = read_err(&dir, "forged.snerf", &forged);
    assert!(e.contains("live voxels") && e.contains("another geometry"), "{e}");

    // a style chunk for a style the header does not list, and style chunks in a one-style file
    let e = read_err(&dir, "style-9.snerf", &rebuild(&bytes, |_, t, p| {
        let mut p = p.to_vec();
        if t == TAG_SMLP && style_of(&p) == 1 {
            p[..4].copy_from_slice(&9u32.to_le_bytes());
        }
        Some(p)
    }));
    assert!(e.contains("style 9") && e.contains("lists 2 styles"), "{e}");
    let single = l.layers[0].to_bytes();
    let mut with_scol = single[..single.len() - 16].to_vec();
    with_scol.extend_from_slice(&encode_chunk(TAG_SCOL, &[0; 12]));
    let n = chunks(&single).unwrap().len() as u32;
    with_scol.extend_from_slice(&encode_chunk(*b"END ", &n.to_le_bytes()));
    let e = format!("{:#}", Asset::from_bytes(&with_scol).unwrap_err());
    assert!(e.contains("lists no styles"), "{e}");

    // building one from layers of different geometry names the style
    let e = LayeredAsset::new(vec![info("warm"), info("small")], vec![ball(0.6, warm, true), ball(0.5, cold, true)]).unwrap_err().to_string();
    assert!(e.contains("\"small\"") && e.contains("another geometry") && e.contains("density differs"), "{e}");

    // streaming a multi-style asset is refused in words, not misread
    let e = Assembler::new(&bytes).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(e.contains("multi-style"), "{e}");
}

#[test]
fn mutated_multi_style_files_never_panic() {
    let (l, _) = two_styles(false);
    let bytes = l.to_bytes();
    let list = chunks(&bytes).unwrap();
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    for _ in 0..1500 {
        // flip a byte of one chunk's payload and fix its CRC, so the semantic checks see it
        let c = &list[next() as usize % list.len()];
        let mut m = bytes.clone();
        if c.payload.is_empty() {
            continue;
        }
        let at = c.payload.start + next() as usize % c.payload.len();
        m[at] ^= 1 << (next() % 8);
        let crc = crc32fast::hash(&m[c.payload.clone()]);
        m[c.range.start + 8..c.range.start + 12].copy_from_slice(&crc.to_le_bytes());
        let r = std::panic::catch_unwind(|| {
            let _ = LayeredAsset::from_bytes(&m);
            let _ = Asset::from_bytes(&m);
        });
        assert!(r.is_ok(), "a mutated byte at {at} in chunk {} panicked", c.index);
    }
}

/// A client holding one style writes another style's colour part into it, chunk by chunk in
/// any order (as a stream delivers it): the result is that style's single-style asset byte
/// for byte, diffuse or not; a colour part of another geometry is refused by block.
#[test]
fn recolouring_one_style_with_anothers_colour_part_gives_that_style_exactly() {
    for diffuse in [false, true] {
        let (l, _) = two_styles(diffuse);
        let bytes = l.to_bytes();
        let want = l.clone().into_style(1).unwrap();
        let mut held = l.clone().into_style(0).unwrap();
        assert_ne!(held.to_bytes(), want.to_bytes());
        let mut part: Vec<([u8; 4], Vec<u8>)> = chunks(&bytes)
            .unwrap()
            .into_iter()
            .filter(|c| (c.tag == TAG_SMLP || c.tag == TAG_SCOL) && bytes[c.payload.start] == 1)
            .map(|c| (c.tag, bytes[c.payload.clone()].to_vec()))
            .collect();
        // arrival order: reversed, then every other one (neighbours arrive both before and after)
        part.reverse();
        let (even, odd): (Vec<_>, Vec<_>) = part.into_iter().enumerate().partition(|(i, _)| i % 2 == 0);
        let mut r = snerf_asset::Recolour::new(&held);
        assert_eq!(r.blocks(), held.header.atlas_blocks as usize);
        let mut changed_neighbours = false;
        for (_, (tag, p)) in even.into_iter().chain(odd) {
            assert!(!r.is_complete());
            let changed = r.apply(&mut held, tag, &p).unwrap();
            changed_neighbours |= changed.len() > 1;
        }
        assert!(r.is_complete());
        assert!(changed_neighbours, "aprons were copied into neighbours");
        assert!(held.to_bytes() == want.to_bytes(), "diffuse {diffuse}: the recoloured asset is not style 1's");
    }
    // another geometry: a smaller ball's colour part
    let other = LayeredAsset::new(vec![info("warm"), info("cold")], vec![ball(0.5, warm, false), ball(0.5, cold, false)]).unwrap();
    let ob = other.to_bytes();
    let (l, _) = two_styles(false);
    let mut held = l.into_style(0).unwrap();
    let mut r = snerf_asset::Recolour::new(&held);
    let c = chunks(&ob).unwrap().into_iter().find(|c| c.tag == TAG_SCOL && ob[c.payload.start] == 1).unwrap();
    let e = r.apply(&mut held, TAG_SCOL, &ob[c.payload.clone()]).unwrap_err().to_string();
    assert!(e.contains("another geometry") || e.contains("stores"), "{e}");
    let e = r.apply(&mut held, *b"BLKS", &[0; 16]).unwrap_err().to_string();
    assert!(e.contains("BLKS"), "{e}");
}

/// A ball moving along x over two keyframes, blended by density, painted by `paint`.
fn moving_ball(paint: impl Fn([f32; 3]) -> [f32; 3]) -> Asset {
    let mut h = Header::new(Kind::Object, RES, BLOCK);
    h.background = [0.1, 0.2, 0.3];
    h.time_range = Some([0.0, 1.0]);
    h.frames = Some(vec![snerf_asset::Keyframe { time: 0.0 }, snerf_asset::Keyframe { time: 1.0 }]);
    h.colour_by_density = true;
    let g = h.grid_dim();
    let at = |i: usize| -1.0 + (i as f32 + 0.5) * 2.0 / RES as f32;
    let mut b = AssetBuilder::new(h.clone(), ViewMlp::zeros()).unwrap();
    for f in 0..2 {
        for z in 0..g {
            for y in 0..g {
                for x in 0..g {
                    let blk = b.block_from_fn([x, y, z], |v| {
                        let p = v.map(at);
                        let q = [p[0] - 0.15 * f as f32, p[1], p[2]];
                        let d = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
                        let logit = if d < 0.55 { 2.0 + 4.0 * (0.55 - d) } else { -10.0 };
                        encode_voxel(logit, paint(p), [0.0; 4], &h.density)
                    });
                    if blk.chunks_exact(8).any(|v| v[0] > 0) {
                        b.set_block(f, [x, y, z], &blk).unwrap();
                    }
                }
            }
        }
    }
    let mut a = b.finish().unwrap();
    a.make_diffuse();
    a
}

/// A 4D two-style asset blended by density stores no apron colour: each apron voxel takes
/// its block's nearest interior voxel's colour, the file round-trips exactly, a switch by
/// colour part gives the other style byte for byte, and each style draws close to its own
/// single-style asset between the keyframes.
#[test]
fn a_4d_layer_stores_interior_colours_only_and_switches_exactly() {
    let singles = [moving_ball(warm), moving_ball(cold)];
    let l = LayeredAsset::new(vec![info("warm"), info("cold")], singles.to_vec()).unwrap();
    let bytes = l.to_bytes();
    assert_eq!(LayeredAsset::from_bytes(&bytes).unwrap(), l);
    let e = (BLOCK + 2) as usize;
    let bb = l.layers[0].block_bytes();
    for (i, blk) in l.layers[0].atlas.chunks_exact(bb).enumerate() {
        for v in 0..e * e * e {
            let c = [v % e, (v / e) % e, v / (e * e)];
            let k = c.map(|x| x.clamp(1, BLOCK as usize));
            let iv = (k[2] * e + k[1]) * e + k[0];
            assert_eq!(blk[v * 8 + 1..v * 8 + 4], blk[iv * 8 + 1..iv * 8 + 4], "block {i} voxel {c:?}");
        }
    }
    // the colour part against the same styles lerped (every voxel stored)
    let lerped: Vec<Asset> = singles.iter().map(|a| {
        let mut a = a.clone();
        a.header.colour_by_density = false;
        a
    }).collect();
    let all = LayeredAsset::new(vec![info("warm"), info("cold")], lerped).unwrap();
    let (part, every) = (l.style_bytes()[1].bytes as f64, all.style_bytes()[1].bytes as f64);
    eprintln!("4D colour part: {part} bytes, every voxel {every} ({:.3})", part / every);
    assert!(part < 0.55 * every, "{part} against {every}");
    // a switch by colour part
    let want = l.clone().into_style(1).unwrap();
    let mut held = l.clone().into_style(0).unwrap();
    let mut r = snerf_asset::Recolour::new(&held);
    for c in chunks(&bytes).unwrap().into_iter().filter(|c| (c.tag == TAG_SMLP || c.tag == TAG_SCOL) && bytes[c.payload.start] == 1) {
        r.apply(&mut held, c.tag, &bytes[c.payload.clone()]).unwrap();
    }
    assert!(r.is_complete());
    assert!(held.to_bytes() == want.to_bytes(), "the recoloured 4D asset is not style 1's");
    // near its single-style asset: only colour across block edges differs
    for (single, layer) in singles.iter().zip(&l.layers) {
        for t in [0.0f32, 0.4] {
            let cam = orbit(&single.header, 2, 1, 40, 40, 40.0);
            let (a, b) = (render(single, &cam, t), render(layer, &cam, t));
            let mean = a.rgb.iter().zip(&b.rgb).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.rgb.len() as f32;
            eprintln!("t {t}: mean {mean:.5}, max {:.4}", max_diff(&a.rgb, &b.rgb));
            assert!(mean < 2.0 / 255.0 && max_diff(&a.rgb, &b.rgb) < 0.1, "t {t}: mean {mean}");
        }
    }
}
