//! `arbitrary` (Magenta via tract) on real models: sizes, style pull, strength.

mod stylizer_support;

use snerf_stylize::stylizer::{from_spec, resize, save_png, style_distance, ArbitraryStylizer, Image, LargeViews, StyleEmbedder, Stylizer, StylizerOptions};
use stylizer_support::{assert_finite_in_range, content_image, models_or_skip, style_image};

fn style_file(dir: &std::path::Path) -> std::path::PathBuf {
    let path = dir.join("style.png");
    save_png(&path, &style_image(300, 240)).unwrap();
    path
}

#[test]
fn stylizes_square_and_non_square_views_toward_the_style() {
    let Some(opts) = models_or_skip("stylizes_square_and_non_square_views_toward_the_style") else { return };
    let dir = tempfile::tempdir().unwrap();
    let style_path = style_file(dir.path());
    let s = from_spec("arbitrary", Some(&style_path), &opts).unwrap();
    assert_eq!(s.name(), "arbitrary");
    let embedder = StyleEmbedder::new(&opts).unwrap();
    let style_emb = embedder.embed(&snerf_stylize::stylizer::load_style_image(&style_path).unwrap()).unwrap();
    assert_eq!(style_emb.len(), 100);
    // 384^2 (the network's own size), non-square smaller, and larger than 384 (resized).
    for (w, h) in [(384, 384), (200, 120), (96, 160), (520, 400)] {
        let content = content_image(w, h);
        let out = s.stylize(&content).unwrap();
        assert_eq!((out.width, out.height), (w, h));
        assert_finite_in_range(&out);
        let changed = out.mean_abs_diff(&content);
        assert!(changed > 0.05, "{w}x{h}: output barely differs from content ({changed})");
        let d_content = style_distance(&embedder, &content, &style_emb).unwrap();
        let d_out = style_distance(&embedder, &out, &style_emb).unwrap();
        println!("{w}x{h}: style distance content {d_content:.3} -> stylized {d_out:.3}, mean change {changed:.3}");
        assert!(d_out < 0.8 * d_content, "{w}x{h}: stylized view is not closer to the style ({d_out} vs {d_content})");
    }
}

#[test]
fn strength_moves_monotonically_toward_the_style() {
    let Some(opts) = models_or_skip("strength_moves_monotonically_toward_the_style") else { return };
    let style = style_image(256, 256);
    let content = content_image(240, 180);
    let embedder = StyleEmbedder::new(&opts).unwrap();
    let style_emb = embedder.embed(&style).unwrap();
    let mut outs = Vec::new();
    let mut dists = Vec::new();
    for strength in [0.0, 0.5, 1.0] {
        let s = ArbitraryStylizer::new(&style, &StylizerOptions { strength, ..opts.clone() }).unwrap();
        let out = s.stylize(&content).unwrap();
        dists.push(style_distance(&embedder, &out, &style_emb).unwrap());
        outs.push(out);
    }
    let change: Vec<f32> = outs.iter().map(|o| o.mean_abs_diff(&content)).collect();
    println!("strength 0/0.5/1: style distance {dists:?}, change from content {change:?}");
    assert!(dists[0] > dists[1] && dists[1] > dists[2], "style distance not decreasing with strength: {dists:?}");
    assert!(change[0] < change[1] && change[1] < change[2], "change from content not increasing: {change:?}");
    assert!(outs[0].mean_abs_diff(&outs[2]) > 0.03);
}

/// Energy of the band finer than a 384 view (the image minus itself shrunk to 384 and back).
fn detail_energy(img: &Image) -> f32 {
    let (sw, sh) = if img.width >= img.height { (384, img.height * 384 / img.width) } else { (img.width * 384 / img.height, 384) };
    let low = resize(&resize(img, sw, sh), img.width, img.height);
    img.data.iter().zip(&low.data).map(|(a, b)| (a - b) * (a - b)).sum::<f32>() / img.data.len() as f32
}

#[test]
fn large_view_modes_split_the_bands_as_documented() {
    let Some(opts) = models_or_skip("large_view_modes_split_the_bands_as_documented") else { return };
    let style = style_image(256, 256);
    let content = content_image(600, 400);
    let s = ArbitraryStylizer::new(&style, &opts).unwrap();
    assert_eq!(s.network_size(600, 400), (400, 600), "default for large views is Bands (runs at the view's size)");
    let bands = s.stylize(&content).unwrap();
    let s = s.with_large_views(LargeViews::Resize);
    assert_eq!(s.network_size(600, 400), (384, 384));
    let resized = s.stylize(&content).unwrap();
    let s = s.with_large_views(LargeViews::Native);
    assert_eq!(s.network_size(600, 400), (400, 600));
    let native = s.stylize(&content).unwrap();
    for img in [&bands, &resized, &native] {
        assert_eq!((img.width, img.height), (600, 400));
        assert_finite_in_range(img);
    }
    assert!(native.mean_abs_diff(&resized) > 0.01, "the large-view modes gave the same image");
    // Bands = Resize's coarse bands + Native's fine band: shrunk to 384, Bands is Resize
    // (up to the clamp to [0, 1]); above 384 it carries Native's detail.
    let shrink = |i: &Image| resize(i, 384, 256);
    let coarse_gap = shrink(&bands).mean_abs_diff(&shrink(&resized));
    let native_gap = shrink(&native).mean_abs_diff(&shrink(&resized));
    let (eb, er, en) = (detail_energy(&bands), detail_energy(&resized), detail_energy(&native));
    println!("coarse |bands - resize| {coarse_gap:.4} (native {native_gap:.4}); detail energy bands {eb:.5} resize {er:.5} native {en:.5}");
    assert!(coarse_gap < 0.25 * native_gap, "Bands' coarse bands are not Resize's: {coarse_gap} vs native {native_gap}");
    assert!(eb > 3.0 * er && eb > 0.5 * en, "Bands lost the fine band: {eb} (resize {er}, native {en})");
}

/// `stylize_crop` paints a crop at its whole view's scale: a view given as its own crop is
/// the plain stylization (the same network input), and a crop is painted at the view's
/// scale, not brought to 384 on its own.
#[test]
fn a_crop_is_painted_at_its_views_scale() {
    let Some(opts) = models_or_skip("a_crop_is_painted_at_its_views_scale") else { return };
    let s = ArbitraryStylizer::new(&style_image(256, 256), &opts).unwrap();
    let view = content_image(128, 128);
    let whole = s.stylize(&view).unwrap();
    let as_crop = s.stylize_crop(&view, 128).unwrap();
    assert!(whole.mean_abs_diff(&as_crop) < 1e-6, "the view as its own crop differs: {}", whole.mean_abs_diff(&as_crop));
    // a 64x48 crop of that view, painted at the view's scale (x3) and, as a picture of its
    // own, at 384 (x6): different stroke scales give different images of the right size
    let part = resize(&view, 64, 48);
    let at_view = s.stylize_crop(&part, 128).unwrap();
    let alone = s.stylize(&part).unwrap();
    assert_eq!((at_view.width, at_view.height), (64, 48));
    assert_finite_in_range(&at_view);
    assert!(at_view.mean_abs_diff(&alone) > 0.01, "the crop ignored its view's scale");
}

/// `stylize_region` with an object mask paints the object's box only (grown by 1/16 of the
/// view) and leaves the rest of the view as it was; a mask whose box fills the view is the
/// whole view's stylization.
#[test]
fn region_stylization_paints_the_object_box() {
    use snerf_stylize::snerf_loop::{stylize_at, stylize_region};
    let dir = tempfile::tempdir().unwrap();
    let st = from_spec("color", Some(&style_file(dir.path())), &StylizerOptions::default()).unwrap();
    let (w, h) = (96, 80);
    let view = content_image(w, h);
    // object: a 30x20 block at (40, 30); box with the 6-pixel margin: x 34..76, y 24..56
    let mask: Vec<bool> = (0..w * h).map(|p| (40..70).contains(&(p % w)) && (30..50).contains(&(p / w))).collect();
    let out = stylize_region(st.as_ref(), &view, Some(&mask), 0).unwrap();
    let inside = |x: usize, y: usize| (34..76).contains(&x) && (24..56).contains(&y);
    let mut changed_inside = 0;
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) * 3;
            if inside(x, y) {
                changed_inside += (out.data[i..i + 3] != view.data[i..i + 3]) as usize;
            } else {
                assert_eq!(out.data[i..i + 3], view.data[i..i + 3], "pixel ({x}, {y}) outside the box changed");
            }
        }
    }
    assert!(changed_inside > 42 * 32 / 2, "the box was not painted ({changed_inside} pixels changed)");
    let full = vec![true; w * h];
    let whole = stylize_region(st.as_ref(), &view, Some(&full), 0).unwrap();
    assert_eq!(whole.data, stylize_at(st.as_ref(), &view, 0).unwrap().data);
}

#[test]
fn missing_models_give_the_setup_command() {
    let dir = tempfile::tempdir().unwrap();
    let opts = StylizerOptions { models_dir: Some(dir.path().to_path_buf()), ..Default::default() };
    let err = format!("{:#}", ArbitraryStylizer::new(&style_image(64, 64), &opts).err().unwrap());
    assert!(err.contains("arbitrary_predict.onnx") && err.contains("setup-models.sh"), "{err}");
    // A file with the right name but wrong contents fails the hash check.
    std::fs::write(dir.path().join("arbitrary_predict.onnx"), b"not the model").unwrap();
    let err = format!("{:#}", ArbitraryStylizer::new(&style_image(64, 64), &opts).err().unwrap());
    assert!(err.contains("SHA-256") && err.contains("arbitrary_predict.onnx"), "{err}");
}

#[test]
fn spec_errors() {
    let opts = StylizerOptions::default();
    let e = from_spec("arbitrary", None, &opts).err().unwrap().to_string();
    assert!(e.contains("style image"), "{e}");
    let e = from_spec("vangogh", None, &opts).err().unwrap().to_string();
    assert!(e.contains("unknown stylizer") && e.contains("preset:N"), "{e}");
    let e = from_spec("preset:x", None, &opts).err().unwrap().to_string();
    assert!(e.contains("preset"), "{e}");
    let bad = StylizerOptions { strength: 1.5, ..Default::default() };
    let e = from_spec("color", None, &bad).err().unwrap().to_string();
    assert!(e.contains("strength"), "{e}");
    // gatys needs no weight file (it uses the installed style network) but a style image
    let e = from_spec("gatys", None, &opts).err().unwrap().to_string();
    assert!(e.contains("style image"), "{e}");
}
