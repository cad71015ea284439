//! Style images in every pixel format a user may hand us, and the bad ones.

use std::path::Path;

use image::{ImageBuffer, Luma, Rgb, Rgba};
use snerf_stylize::stylizer::{image_from_png, load_style_image, save_png, Image, MAX_STYLE_SIDE};

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() < 1.0 / 255.0 + 1e-6
}

#[test]
fn grayscale_png_becomes_rgb() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("gray.png");
    ImageBuffer::from_fn(40, 30, |x, _| Luma([(x * 6) as u8])).save(&path).unwrap();
    let img = load_style_image(&path).unwrap();
    assert_eq!((img.width, img.height), (40, 30));
    let p = img.pixel(10, 5);
    assert!(close(p[0], 60.0 / 255.0) && p[0] == p[1] && p[1] == p[2], "{p:?}");
}

#[test]
fn sixteen_bit_png_keeps_precision() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("deep.png");
    ImageBuffer::from_fn(20, 20, |x, y| Rgb([(x * 3000) as u16, 65535, (y * 1000) as u16])).save(&path).unwrap();
    let img = load_style_image(&path).unwrap();
    let p = img.pixel(7, 9);
    assert!((p[0] - 21000.0 / 65535.0).abs() < 1e-5 && (p[1] - 1.0).abs() < 1e-6 && (p[2] - 9000.0 / 65535.0).abs() < 1e-5, "{p:?}");
}

#[test]
fn rgba_png_is_composited_on_white() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("alpha.png");
    // Left half transparent black, right half opaque red, middle column half-transparent.
    ImageBuffer::from_fn(32, 16, |x, _| match x {
        0..=15 => Rgba([0u8, 0, 0, 0]),
        16 => Rgba([0, 0, 255, 128]),
        _ => Rgba([255, 0, 0, 255]),
    })
    .save(&path)
    .unwrap();
    let img = load_style_image(&path).unwrap();
    assert_eq!(img.pixel(3, 3), [1.0, 1.0, 1.0], "transparent pixels read as white");
    assert_eq!(img.pixel(20, 3), [1.0, 0.0, 0.0]);
    let half = img.pixel(16, 3);
    assert!(close(half[0], 127.0 / 255.0) && close(half[2], 1.0), "{half:?}");
}

#[test]
fn paletted_png_is_expanded() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("palette.png");
    let file = std::fs::File::create(&path).unwrap();
    let mut enc = png::Encoder::new(std::io::BufWriter::new(file), 16, 16);
    enc.set_color(png::ColorType::Indexed);
    enc.set_depth(png::BitDepth::Eight);
    enc.set_palette(vec![255u8, 0, 0, 0, 0, 255]);
    let mut w = enc.write_header().unwrap();
    let data: Vec<u8> = (0..256).map(|i| ((i % 16) >= 8) as u8).collect();
    w.write_image_data(&data).unwrap();
    w.finish().unwrap();
    let img = load_style_image(&path).unwrap();
    assert_eq!(img.pixel(2, 2), [1.0, 0.0, 0.0]);
    assert_eq!(img.pixel(12, 2), [0.0, 0.0, 1.0]);
}

fn expect_error(path: &Path, needle: &str) {
    let err = format!("{:#}", load_style_image(path).unwrap_err());
    assert!(err.contains(&path.display().to_string()), "error does not name the file: {err}");
    assert!(err.contains(needle), "error lacks {needle:?}: {err}");
}

#[test]
fn tiny_png_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tiny.png");
    ImageBuffer::from_fn(8, 8, |_, _| Rgb([10u8, 20, 30])).save(&path).unwrap();
    expect_error(&path, "8x8");
}

#[test]
fn corrupt_truncated_text_and_missing_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.png");
    ImageBuffer::from_fn(64, 64, |x, y| Rgb([x as u8 * 3, y as u8 * 3, 77u8])).save(&good).unwrap();
    let bytes = std::fs::read(&good).unwrap();

    let truncated = dir.path().join("truncated.png");
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    expect_error(&truncated, "corrupt");

    let corrupt = dir.path().join("corrupt.png");
    let mut bad = bytes.clone();
    for b in bad.iter_mut().skip(40) {
        *b ^= 0x5a;
    }
    std::fs::write(&corrupt, &bad).unwrap();
    expect_error(&corrupt, "corrupt");

    let text = dir.path().join("style.png");
    std::fs::write(&text, "not an image").unwrap();
    expect_error(&text, "not a PNG, JPEG or WebP");

    expect_error(&dir.path().join("missing.png"), "cannot read");
}

#[test]
fn huge_header_is_refused_before_decoding() {
    // A valid header claiming 9000x20: refused by size without decoding pixel data.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("wide.png");
    ImageBuffer::from_fn(9000, 20, |_, _| Luma([0u8])).save(&path).unwrap();
    expect_error(&path, "8192");
}

#[test]
fn large_style_images_are_downscaled() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.png");
    ImageBuffer::from_fn(2000, 1000, |x, _| Rgb([(x % 256) as u8, 0u8, 0u8])).save(&path).unwrap();
    let img = load_style_image(&path).unwrap();
    assert_eq!((img.width, img.height), (MAX_STYLE_SIDE, MAX_STYLE_SIDE / 2));
}

#[test]
fn save_png_roundtrips_and_replaces_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.png");
    let img = Image { width: 3, height: 2, data: vec![0.0, 0.5, 1.0, 0.25, 0.75, 0.1, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.2, 0.4, 0.6, 0.8, 0.9, 0.3] };
    save_png(&path, &img).unwrap();
    save_png(&path, &img).unwrap(); // overwrite in place
    let back = image_from_png(&path).unwrap();
    assert!(img.data.iter().zip(&back.data).all(|(a, b)| close(*a, *b)));
    let leftovers: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(leftovers.len(), 1, "temporary files left behind: {leftovers:?}");
    // Writing into a missing directory fails and names the path.
    let err = save_png(&dir.path().join("no/such/dir/out.png"), &img).unwrap_err().to_string();
    assert!(err.contains("out.png"), "{err}");
}
