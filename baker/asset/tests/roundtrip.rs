//! Encode -> decode gives back the same asset, through memory and through a file.
mod common;
use common::*;
use snerf_asset::{chunks, Asset, EMPTY};

fn head_json(bytes: &[u8]) -> String {
    let c = &chunks(bytes).unwrap()[0];
    assert_eq!(&c.tag, b"HEAD");
    String::from_utf8(bytes[c.payload.clone()].to_vec()).unwrap()
}

#[test]
fn static_roundtrip_in_memory() {
    let a = sphere_asset(false);
    assert_eq!(a.num_frames(), 1);
    assert!(!a.is_dynamic());
    let occupied = a.grids[0].iter().filter(|&&e| e != EMPTY).count();
    assert!(occupied > 8 && occupied < 64, "sphere occupies {} of 64 cells", occupied);
    let bytes = a.to_bytes();
    let b = Asset::from_bytes(&bytes).unwrap();
    assert_eq!(a, b);
    assert_eq!(b.to_bytes(), bytes, "encoding is deterministic");
}

#[test]
fn static_header_has_no_time_fields() {
    let bytes = sphere_asset(false).to_bytes();
    let json = head_json(&bytes);
    assert!(!json.contains("time"), "{}", json);
    assert!(!json.contains("frames"), "{}", json);
    assert!(json.contains("\"kind\":\"object\""), "{}", json);
    // exactly one GRID chunk, for frame 0
    let grids: Vec<_> = chunks(&bytes).unwrap().into_iter().filter(|c| &c.tag == b"GRID").collect();
    assert_eq!(grids.len(), 1);
    assert_eq!(&bytes[grids[0].payload.start..grids[0].payload.start + 4], &0u32.to_le_bytes());
}

#[test]
fn dynamic_roundtrip_shares_blocks() {
    let a = sphere_asset(true);
    assert_eq!(a.num_frames(), 3);
    let json = head_json(&a.to_bytes());
    assert!(json.contains("time_range") && json.contains("frames"), "{}", json);
    // Voxels with x-cell >= 2 change colour per frame; so do blocks of x-cell 1 (their apron
    // reaches into x-cell 2). Only x-cell 0 blocks are identical: frames 1, 2 share them.
    let g = a.grid_dim();
    let mut shared = 0;
    let mut changed = 0;
    for idx in 0..g * g * g {
        let x = idx % g;
        let (e0, e1, e2) = (a.grids[0][idx], a.grids[1][idx], a.grids[2][idx]);
        if e0 == EMPTY {
            continue;
        }
        if x == 0 {
            assert_eq!((e0, e0), (e1, e2));
            shared += 1;
        } else {
            assert!(e0 != e1 && e1 != e2);
            changed += 1;
        }
    }
    assert!(shared > 0 && changed > 0);
    let per_frame = a.grids[0].iter().filter(|&&e| e != EMPTY).count() as u32;
    assert_eq!(a.header.atlas_blocks, per_frame + 2 * changed as u32);
    let b = Asset::from_bytes(&a.to_bytes()).unwrap();
    assert_eq!(a, b);

    let s = a.summary(a.to_bytes().len() as u64);
    assert_eq!(s.frames, 3);
    assert_eq!(s.keyframe_bytes.len(), 2);
    assert!(s.keyframe_bytes[0] < s.frame0_bytes, "{:?}", s);
    assert_eq!(s.unreferenced_blocks, 0);
    let parts = s.bytes.header + s.bytes.mlp + s.bytes.grids + s.bytes.blocks + 16; // + END chunk
    assert_eq!(parts, s.bytes.total, "{:?}", s);
    assert!(serde_json::to_string(&s).unwrap().contains("keyframe_bytes"));
}

#[test]
fn file_roundtrip_is_atomic() {
    let dir = snerf_files::ScratchDir::new("snerf-asset-rt", "file").unwrap();
    let path = dir.join("scene.snerf");
    for dynamic in [false, true] {
        let a = sphere_asset(dynamic);
        a.write(&path).unwrap();
        assert_eq!(Asset::read(&path).unwrap(), a);
    }
    // no temp files left behind
    let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names.len(), 1, "{:?}", names);
    // an invalid asset is refused and the good file stays
    let mut bad = sphere_asset(false);
    bad.present[0] = false;
    let err = bad.write(&path).unwrap_err().to_string();
    assert!(err.contains("scene.snerf") && err.contains("missing"), "{}", err);
    assert_eq!(Asset::read(&path).unwrap(), sphere_asset(true));
    // errors name the file
    let missing = dir.join("nope.snerf");
    let err = format!("{:#}", Asset::read(&missing).unwrap_err());
    assert!(err.contains("nope.snerf"), "{}", err);
    std::fs::write(&missing, b"SNERFAST\x01\0\0\0\0\0\0\0").unwrap();
    let err = format!("{:#}", Asset::read(&missing).unwrap_err());
    assert!(err.starts_with(&missing.display().to_string()), "{}", err);
}

#[test]
fn the_silhouette_rule_is_written_only_when_it_applies_and_checked_on_reading() {
    let mut a = sphere_asset(false);
    assert!(!head_json(&a.to_bytes()).contains("pixel_rays"), "one ray per pixel is the default, not written");
    a.header.pixel_rays = 4;
    let bytes = a.to_bytes();
    assert!(head_json(&bytes).contains("\"pixel_rays\":4"));
    assert_eq!(Asset::from_bytes(&bytes).unwrap().header.pixel_rays, 4);
    a.header.pixel_rays = 3;
    let err = format!("{:#}", Asset::from_bytes(&a.to_bytes()).unwrap_err());
    assert!(err.contains("pixel_rays is 3"), "{err}");
}
