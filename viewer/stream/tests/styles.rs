//! Multi-style assets (format version 3) over the loopback: the file's name streams its first
//! style and `NAME.STYLE` any style, each as that style's single-style asset byte for byte
//! (what every client reads); the listing names the styles; a style the file does not have is
//! refused by name.

mod common;
use common::*;
use snerf_asset::{Asset, LayeredAsset};
use snerf_stream::{fetch, list};
use snerf_stream::plan::ServedAsset;

#[test]
fn a_multi_style_file_streams_one_style_per_name() {
    let _s = serial();
    let dir = TempDir::new("styles");
    let assets = dir.join("assets");
    std::fs::create_dir_all(&assets).unwrap();
    let file = assets.join("scene.snerf");
    two_styles().write(&file).unwrap();
    let expect = |i: usize| LayeredAsset::read(&file).unwrap().into_style(i).unwrap().to_bytes();
    let (warm, cold) = (expect(0), expect(1));
    assert_ne!(warm, cold);

    // the planner's view: the first style unless a style is named; its styles listed
    let served = ServedAsset::load("scene", &file).unwrap();
    assert_eq!(&served.bytes[..], &warm[..]);
    let st = served.styles.clone().unwrap();
    assert_eq!((st.names.as_slice(), st.served), (&["warm".to_string(), "cold".to_string()][..], 0));
    assert!(st.message(&file, "scene").contains("scene.cold"), "{}", st.message(&file, "scene"));
    let e = ServedAsset::load_style("scene.x", &file, Some("x")).err().unwrap();
    assert!(format!("{e:#}").contains("warm, cold"), "{e:#}");

    let server = start_server(&assets, &dir.join("state"), Default::default());
    let rt = runtime();
    // the listing names the styles and their swatches, from the header
    let listed = rt.block_on(list(&server.url(""), server.fingerprint(), server.token())).unwrap();
    let styles = listed.iter().find(|e| e.name == "scene").and_then(|e| e.styles.clone()).unwrap();
    assert_eq!(styles, LayeredAsset::read(&file).unwrap().styles, "{listed:?}");
    for (name, want) in [("scene", &warm), ("scene.warm", &warm), ("scene.cold", &cold)] {
        let out = dir.join(&format!("{name}.fetched.snerf"));
        rt.block_on(fetch(&server.url(name), server.fingerprint(), server.token(), &out)).unwrap();
        let got = std::fs::read(&out).unwrap();
        assert!(got == *want, "{name}: the fetched file is not that style's single-style asset");
        let a = Asset::read(&out).unwrap();
        assert!(a.header.styles.is_none(), "{name}: a client gets a single-style asset");
    }
    let e = rt
        .block_on(fetch(&server.url("scene.sepia"), server.fingerprint(), server.token(), &dir.join("no.snerf")))
        .unwrap_err();
    assert!(format!("{e:#}").contains("no style \"sepia\""), "{e:#}");
    server.shutdown();
}
