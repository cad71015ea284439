//! Motion entries in the CPU reference (`snerf_asset::motion`, `Asset::sample_slot`): a
//! frame whose cells move the reference keyframe reads the reference at the moved position,
//! and between two such frames the offset is interpolated (one read), not the values blended.
mod common;
use common::*;
use snerf_asset::motion::motion_entry;
use snerf_asset::{Asset, Source};

/// `sphere_asset(true)` with frame 0 as the reference and every cell of frames 1.. moved by
/// `d(frame)` voxels.
fn moved(d: impl Fn(usize) -> [f32; 3]) -> Asset {
    let mut a = sphere_asset(true);
    a.header.motion_ref = Some(0);
    let n = a.grids[0].len();
    for f in 1..a.grids.len() {
        a.grids[f] = vec![motion_entry(d(f)); n];
    }
    a.validate().unwrap();
    a
}

/// Grid-space point moved by `d` voxels.
fn shift(a: &Asset, g: [f32; 3], d: [f32; 3]) -> [f32; 3] {
    let res = a.header.res as f32;
    std::array::from_fn(|i| g[i] + d[i] * 2.0 / res)
}

#[test]
fn a_motion_frame_reads_the_reference_at_the_moved_point() {
    let d = [2.0f32, -1.0, 0.0];
    let a = moved(|_| d);
    assert!(a.num_frames() >= 2);
    let t1 = a.header.frame_time(1);
    let mut rng = Rng(7);
    let mut checked = 0;
    for _ in 0..2000 {
        let g = [rng.range(-0.9, 0.9), rng.range(-0.9, 0.9), rng.range(-0.9, 0.9)];
        let want = a.sample(0, shift(&a, g, d)).unwrap_or_else(|| a.empty_values());
        let got = a.sample_at_time(t1, g).expect("a motion entry is never empty");
        for c in 0..8 {
            assert!((got[c] - want[c]).abs() < 1e-4, "{g:?} channel {c}: {} vs {}", got[c], want[c]);
        }
        checked += (want[0] > a.header.density.logit_min + 1.0) as usize;
    }
    assert!(checked > 100, "too few points inside the moved sphere ({checked})");
}

#[test]
fn between_two_motion_frames_the_offset_is_interpolated_not_the_values() {
    // frame f moves by f * 4 voxels in x: halfway between frames 1 and 2 is a move of 6
    let a = moved(|f| [4.0 * f as f32, 0.0, 0.0]);
    assert!(a.num_frames() >= 3);
    let (t1, t2) = (a.header.frame_time(1), a.header.frame_time(2));
    let tm = 0.5 * (t1 + t2);
    let slot = a.time_slot(tm);
    assert_eq!((slot.k0, slot.k1), (1, 2));
    let mut rng = Rng(11);
    let mut differs_from_blend = 0;
    for _ in 0..2000 {
        let g = [rng.range(-0.9, 0.9), rng.range(-0.9, 0.9), rng.range(-0.9, 0.9)];
        let want = a.sample(0, shift(&a, g, [6.0, 0.0, 0.0])).unwrap_or_else(|| a.empty_values());
        let got = a.sample_at_time(tm, g).unwrap();
        for c in 0..8 {
            assert!((got[c] - want[c]).abs() < 1e-3 * (1.0 + want[c].abs()), "{g:?} channel {c}: {} vs {}", got[c], want[c]);
        }
        let blend0 = 0.5 * (a.sample_at_time(t1, g).unwrap()[0] + a.sample_at_time(t2, g).unwrap()[0]);
        differs_from_blend += ((blend0 - got[0]).abs() > 0.5) as usize;
    }
    assert!(differs_from_blend > 50, "motion reads like a blend ({differs_from_blend})");
}

#[test]
fn motion_entries_are_sources_and_only_valid_in_motion_assets() {
    let a = moved(|_| [1.25, 0.0, -0.5]);
    assert_eq!(a.source(1, 0), Source::Motion([1.25, 0.0, -0.5]));
    // the reference frame cannot hold motion entries
    let mut b = a.clone();
    b.grids[0][0] = motion_entry([0.0; 3]);
    let e = b.validate().unwrap_err().to_string();
    assert!(e.contains("motion entry"), "{e}");
    // nor can an asset without a reference
    let mut c = a.clone();
    c.header.motion_ref = None;
    assert!(c.validate().is_err());
    // and the file round-trips (version 5: a motion asset's grids may be sparse)
    let bytes = a.to_bytes();
    assert_eq!(u32::from_le_bytes(bytes[8..12].try_into().unwrap()), 5);
    assert_eq!(Asset::from_bytes(&bytes).unwrap(), a);
}

/// A motion asset whose frames show only the sphere's cells: each grid is stored as its
/// occupied cells (`SGRD`), which read back as the dense grid; the same asset written with
/// dense grids as version 4 (the release before sparse grids) reads back equal; a sparse grid
/// in a version 4 file, or one whose cells are out of order, is refused by name.
#[test]
fn a_motion_asset_stores_its_grids_sparsely_and_older_files_still_read() {
    use snerf_asset::chunk::{chunks, encode_chunk, preamble_of, TAG_END, TAG_GRID, TAG_SGRD};
    let mut a = sphere_asset(true);
    a.header.motion_ref = Some(0);
    // one cell in five keeps its block (a sparse scene)
    for (c, e) in a.grids[0].iter_mut().enumerate() {
        if c % 5 != 0 {
            *e = snerf_asset::EMPTY;
        }
    }
    let occupied: Vec<bool> = a.grids[0].iter().map(|&e| e != snerf_asset::EMPTY).collect();
    assert!(occupied.iter().any(|&o| o) && occupied.iter().filter(|&&o| o).count() * 2 < occupied.len());
    for f in 1..a.grids.len() {
        a.grids[f] = occupied.iter().map(|&o| if o { motion_entry([f as f32 * 0.25, 0.0, 0.0]) } else { snerf_asset::EMPTY }).collect();
    }
    a.validate().unwrap();
    let bytes = a.to_bytes();
    let list = chunks(&bytes).unwrap();
    assert_eq!(list.iter().filter(|c| c.tag == TAG_SGRD).count(), a.num_frames());
    assert!(!list.iter().any(|c| c.tag == TAG_GRID));
    assert_eq!(Asset::from_bytes(&bytes).unwrap(), a);
    let s = a.summary(bytes.len() as u64);
    assert_eq!(s.bytes.total, bytes.len() as u64);
    let sum: u64 = s.bytes.header + s.bytes.mlp + s.bytes.grids + s.bytes.blocks;
    assert_eq!(sum + 16, bytes.len() as u64, "{s:?}"); // the header part counts the preamble; + END

    // rewrite: every SGRD as a dense GRID, in a version `v` file
    let rewrite = |v: u32, dense: bool, tamper: bool| {
        let mut out = preamble_of(v).to_vec();
        let mut n = 0u32;
        for c in &list {
            let p = &bytes[c.payload.clone()];
            let (tag, payload) = match c.tag {
                TAG_END => continue,
                TAG_SGRD if dense => {
                    let mut grid = vec![snerf_asset::EMPTY; occupied.len()];
                    for pair in p[8..].chunks_exact(8) {
                        grid[u32::from_le_bytes(pair[..4].try_into().unwrap()) as usize] = u32::from_le_bytes(pair[4..].try_into().unwrap());
                    }
                    let mut q = p[..4].to_vec();
                    q.extend(grid.iter().flat_map(|e| e.to_le_bytes()));
                    (TAG_GRID, q)
                }
                TAG_SGRD if tamper => {
                    // the first two pairs swapped: cells out of order
                    let mut q = p.to_vec();
                    let (x, y) = (q[8..16].to_vec(), q[16..24].to_vec());
                    q[8..16].copy_from_slice(&y);
                    q[16..24].copy_from_slice(&x);
                    (TAG_SGRD, q)
                }
                t => (t, p.to_vec()),
            };
            out.extend(encode_chunk(tag, &payload));
            n += 1;
        }
        out.extend(encode_chunk(TAG_END, &n.to_le_bytes()));
        out
    };
    let old = rewrite(4, true, false);
    assert!(old.len() > bytes.len());
    assert_eq!(Asset::from_bytes(&old).unwrap(), a);
    let e = format!("{:#}", Asset::from_bytes(&rewrite(4, false, false)).unwrap_err());
    assert!(e.contains("SGRD") && e.contains("version 5"), "{e}");
    let e = format!("{:#}", Asset::from_bytes(&rewrite(5, false, true)).unwrap_err());
    assert!(e.contains("SGRD") && e.contains("out of order"), "{e}");
}
