//! A multi-style asset in the native viewer's file source: the first style first, keys 1..9
//! (`AssetSource::select_style`) each another style's whole asset on the same geometry, a
//! style shown or missing nothing; a single-style file has no styles.

mod common;
use common::*;
use snerf_asset::{LayeredAsset, StyleInfo};
use snerf_viewer::window::{AssetSource, AssetUpdate, FileSource};

fn whole(u: Option<AssetUpdate>) -> snerf_asset::Asset {
    match u {
        Some(AssetUpdate::Whole(a)) => *a,
        _ => panic!("expected a whole asset"),
    }
}

#[test]
fn keys_switch_the_styles_of_a_multi_style_file() {
    let dir = tmp("styles");
    let warm = object_asset();
    let mut cold = warm.clone();
    for v in cold.atlas.chunks_exact_mut(8) {
        for c in &mut v[1..] {
            *c = 255 - *c;
        }
    }
    let info = |n: &str| StyleInfo { name: n.into(), source: None, swatch: [0.5; 3] };
    let file = dir.join("styles.snerf");
    LayeredAsset::new(vec![info("warm"), info("cold")], vec![warm.clone(), cold]).unwrap().write(&file).unwrap();
    let want = LayeredAsset::read(&file).unwrap();
    let mut src = FileSource::open(&file).unwrap();
    assert_eq!(src.style_names(), ["warm", "cold"]);
    assert_eq!(whole(src.poll()), want.layers[0]);
    assert!(src.poll().is_none());
    assert_eq!(src.select_style(0), None, "already shown");
    assert_eq!(src.select_style(7), None, "no eighth style");
    assert_eq!(src.select_style(1).as_deref(), Some("cold"));
    let b = whole(src.poll());
    assert_eq!(b, want.layers[1]);
    assert_ne!(b.atlas, want.layers[0].atlas);
    assert!(src.poll().is_none());
    assert_eq!(src.select_style(0).as_deref(), Some("warm"));
    assert_eq!(whole(src.poll()), want.layers[0]);
    // a single-style file
    let single = dir.join("warm.snerf");
    warm.write(&single).unwrap();
    let mut s = FileSource::open(&single).unwrap();
    assert!(s.style_names().is_empty());
    assert_eq!(whole(s.poll()), warm);
    assert_eq!(s.select_style(1), None);
}
