//! What cameras write gets in: JPEG with its EXIF orientation applied, WebP, a JPEG no one here
//! made, big images capped by `max_size` (antialiased, premultiplied when translucent) and
//! cached, and corrupt or unsupported files named in the error.

mod common;

use std::path::Path;

use common::*;
use serde_json::json;
use snerf_data::{load, Dataset, LoadOptions};

/// A nerfstudio dataset whose frames are `files` (already written under `dir`), all with one
/// camera of focal `f`; `size` adds `w`/`h` to the JSON (the size the loader must then find).
fn write_ns_json(dir: &Path, files: &[&str], f: f64, size: Option<(u32, u32)>) {
    let cams = ring_cameras(files.len());
    let frames: Vec<_> = files
        .iter()
        .zip(&cams)
        .map(|(name, c)| json!({ "file_path": name, "transform_matrix": mat4(c) }))
        .collect();
    let mut v = json!({ "fl_x": f, "fl_y": f, "frames": frames });
    if let Some((w, h)) = size {
        v["w"] = json!(w);
        v["h"] = json!(h);
    }
    write_json(&dir.join("transforms.json"), &v);
}

fn opts(cache: Option<&Path>, max_size: Option<u32>) -> LoadOptions {
    LoadOptions {
        holdout_every: Some(0),
        max_size,
        // A cache in the test's own folder, never the user's.
        cache_dir: Some(
            cache
                .map(Path::to_path_buf)
                .unwrap_or_else(|| "/nonexistent".into()),
        ),
        ..Default::default()
    }
}

fn px(ds: &Dataset, view: usize, x: u32, y: u32) -> [u8; 4] {
    let v = &ds.train[view];
    let i = ((y * v.intrinsics.width + x) * 4) as usize;
    v.rgba[i..i + 4].try_into().unwrap()
}

fn assert_near(got: [u8; 4], want: [u8; 3], tol: i32, ctx: &str) {
    for c in 0..3 {
        assert!(
            (got[c] as i32 - want[c] as i32).abs() <= tol,
            "{ctx}: got {got:?}, want about {want:?}"
        );
    }
    assert_eq!(got[3], 255, "{ctx}: JPEG has no alpha, so it loads opaque");
}

const RED: [u8; 3] = [220, 30, 30];
const BLUE: [u8; 3] = [30, 30, 220];
const GREEN: [u8; 3] = [30, 200, 30];
const WHITE: [u8; 3] = [240, 240, 240];

/// `w x h` with quadrants top-left red, top-right blue, bottom-left green, bottom-right white:
/// every rotation and flip of it is distinguishable.
fn quadrants(w: u32, h: u32) -> image::RgbImage {
    image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb(match (x < w / 2, y < h / 2) {
            (true, true) => RED,
            (false, true) => BLUE,
            (true, false) => GREEN,
            (false, false) => WHITE,
        })
    })
}

fn jpeg_bytes(img: &image::RgbImage, quality: u8) -> Vec<u8> {
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality)
        .encode_image(img)
        .unwrap();
    out
}

/// Inserts an EXIF APP1 segment holding only an Orientation tag right after the JPEG's SOI, as
/// a phone does: "Exif\0\0", a big-endian TIFF header, one IFD with tag 0x0112 (SHORT).
fn with_exif_orientation(jpeg: &[u8], orientation: u16) -> Vec<u8> {
    assert_eq!(&jpeg[..2], &[0xFF, 0xD8], "not a JPEG");
    let mut exif = b"Exif\0\0".to_vec();
    exif.extend_from_slice(b"MM\0\x2a\0\0\0\x08"); // TIFF header, IFD0 at offset 8
    exif.extend_from_slice(&1u16.to_be_bytes()); // one entry
    exif.extend_from_slice(&0x0112u16.to_be_bytes()); // Orientation
    exif.extend_from_slice(&3u16.to_be_bytes()); // SHORT
    exif.extend_from_slice(&1u32.to_be_bytes()); // count
    exif.extend_from_slice(&orientation.to_be_bytes());
    exif.extend_from_slice(&[0, 0]); // value padded to 4 bytes
    exif.extend_from_slice(&0u32.to_be_bytes()); // no next IFD
    let mut out = jpeg[..2].to_vec();
    out.extend_from_slice(&[0xFF, 0xE1]);
    out.extend_from_slice(&((exif.len() + 2) as u16).to_be_bytes());
    out.extend_from_slice(&exif);
    out.extend_from_slice(&jpeg[2..]);
    out
}

#[test]
fn jpeg_exif_orientation_is_applied() {
    let d = TempDir::new("jpeg-exif");
    std::fs::create_dir_all(d.path().join("images")).unwrap();
    // Stored 32x16; tag 6 = "rotate 90° clockwise to display", tag 1 = upright, tag 3 = 180°.
    let stored = jpeg_bytes(&quadrants(32, 16), 95);
    for (name, tag) in [("a.jpg", 6), ("b.JPEG", 1), ("c.jpg", 3)] {
        std::fs::write(
            d.path().join("images").join(name),
            with_exif_orientation(&stored, tag),
        )
        .unwrap();
    }
    write_ns_json(
        d.path(),
        &["images/a.jpg", "images/b.JPEG", "images/c.jpg"],
        20.0,
        None,
    );
    let ds = load(d.path(), &opts(None, None)).unwrap();

    // Rotated clockwise: 16 wide, 32 tall; the stored left column is now the top row, so the
    // quadrants read green red / white blue.
    let k = ds.train[0].intrinsics;
    assert_eq!((k.width, k.height, k.cx, k.cy), (16, 32, 8.0, 16.0));
    assert_near(px(&ds, 0, 4, 8), GREEN, 24, "tag 6 top-left");
    assert_near(px(&ds, 0, 12, 8), RED, 24, "tag 6 top-right");
    assert_near(px(&ds, 0, 4, 24), WHITE, 24, "tag 6 bottom-left");
    assert_near(px(&ds, 0, 12, 24), BLUE, 24, "tag 6 bottom-right");
    // Upright: as stored.
    assert_eq!(ds.train[1].intrinsics.width, 32);
    assert_near(px(&ds, 1, 8, 4), RED, 24, "tag 1 top-left");
    assert_near(px(&ds, 1, 24, 12), WHITE, 24, "tag 1 bottom-right");
    // 180°: top-left is what was bottom-right.
    assert_near(px(&ds, 2, 8, 4), WHITE, 24, "tag 3 top-left");
    assert_near(px(&ds, 2, 24, 12), RED, 24, "tag 3 bottom-right");
}

#[test]
fn rotated_jpeg_that_disagrees_with_declared_size_says_why() {
    let d = TempDir::new("jpeg-exif-size");
    std::fs::create_dir_all(d.path().join("images")).unwrap();
    let bytes = with_exif_orientation(&jpeg_bytes(&quadrants(32, 16), 90), 6);
    std::fs::write(d.path().join("images/a.jpg"), bytes).unwrap();
    // The stored pixels are 32x16 and the JSON says so; the tag makes the picture 16x32.
    write_ns_json(d.path(), &["images/a.jpg"], 20.0, Some((32, 16)));
    let err = load(d.path(), &opts(None, None)).unwrap_err();
    assert_err_has(
        &err,
        &[
            "a.jpg",
            "image is 16x32",
            "EXIF Orientation",
            "declares 32x16",
        ],
    );
}

#[test]
fn webp_lossless_and_blender_extensionless_jpeg_load() {
    let d = TempDir::new("webp");
    std::fs::create_dir_all(d.path().join("train")).unwrap();
    let img = image::RgbaImage::from_fn(12, 10, |x, y| {
        image::Rgba([x as u8 * 20, y as u8 * 25, 77, if x == 0 { 0 } else { 255 }])
    });
    let mut webp = Vec::new();
    image::codecs::webp::WebPEncoder::new_lossless(&mut webp)
        .encode(img.as_raw(), 12, 10, image::ExtendedColorType::Rgba8)
        .unwrap();
    std::fs::write(d.path().join("train/r_0.webp"), webp).unwrap();
    std::fs::write(
        d.path().join("train/r_1.jpg"),
        jpeg_bytes(&quadrants(12, 10), 95),
    )
    .unwrap();
    // Blender style: no extension in file_path; the loader finds the .webp and the .jpg.
    let frames: Vec<_> = ring_cameras(2)
        .iter()
        .enumerate()
        .map(|(i, c)| json!({ "file_path": format!("./train/r_{i}"), "transform_matrix": mat4(c) }))
        .collect();
    write_json(
        &d.path().join("transforms.json"),
        &json!({ "camera_angle_x": 0.7, "frames": frames }),
    );
    let ds = load(d.path(), &opts(None, None)).unwrap();
    assert!(ds.train[0].path.ends_with("train/r_0.webp"));
    // Lossless: every pixel exact, alpha kept.
    assert_eq!(ds.train[0].rgba, img.into_raw());
    assert!(ds.train[1].path.ends_with("train/r_1.jpg"));
    assert_eq!(ds.train[1].intrinsics.width, 12);
}

#[test]
fn jpeg_made_elsewhere_decodes() {
    // A JPEG texture shipped by Debian's assimp-testmodels (installed by .ci/run), encoded by
    // software no one here wrote.
    let src = Path::new("/usr/share/assimp/models/LWO/LWO2/MappingModes/earthSpherical.jpg");
    if !src.is_file() {
        eprintln!(
            "skipped: {} not installed (apt-get install assimp-testmodels)",
            src.display()
        );
        return;
    }
    let d = TempDir::new("jpeg-foreign");
    std::fs::create_dir_all(d.path().join("images")).unwrap();
    std::fs::copy(src, d.path().join("images/earth.jpg")).unwrap();
    write_ns_json(d.path(), &["images/earth.jpg"], 100.0, None);
    let ds = load(d.path(), &opts(None, Some(0))).unwrap();
    let (w, h) = image::image_dimensions(src).unwrap();
    let v = &ds.train[0];
    assert_eq!((v.intrinsics.width, v.intrinsics.height), (w, h));
    assert_eq!(v.rgba.len(), (w * h * 4) as usize);
    // A real picture: many distinct colours, not a flat fill from a half-failed decode.
    let distinct: std::collections::HashSet<_> = v.rgba.chunks_exact(4).step_by(7).collect();
    assert!(distinct.len() > 100, "{} distinct colours", distinct.len());
}

#[test]
fn big_images_are_capped_with_scaled_intrinsics_and_cached() {
    let d = TempDir::new("max-size");
    let cache = d.path().join("cache");
    std::fs::create_dir_all(d.path().join("images")).unwrap();
    // 2000x1000 (2 MP, above the cache threshold), as a phone-sized JPEG would be.
    let img = quadrants(2000, 1000);
    let file = d.path().join("images/big.jpg");
    std::fs::write(&file, jpeg_bytes(&img, 95)).unwrap();
    write_ns_json(d.path(), &["images/big.jpg"], 1500.0, Some((2000, 1000)));

    let ds = load(d.path(), &opts(Some(&cache), Some(500))).unwrap();
    let k = ds.train[0].intrinsics;
    assert_eq!((k.width, k.height), (500, 250));
    assert_eq!((k.fx, k.fy, k.cx, k.cy), (375.0, 375.0, 250.0, 125.0));
    assert_eq!(ds.train[0].rgba.len(), 500 * 250 * 4);
    assert_near(px(&ds, 0, 125, 62), RED, 24, "capped top-left");
    assert_near(px(&ds, 0, 375, 187), WHITE, 24, "capped bottom-right");

    let entries: Vec<_> = std::fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(entries.len(), 1, "{entries:?}");
    let entry = &entries[0];

    // The second load reads the entry, not the JPEG: replace the entry's pixels with a flat
    // colour (keeping its header) and that colour comes back.
    let mut bytes = std::fs::read(entry).unwrap();
    bytes.truncate(16);
    let flat = image::RgbaImage::from_pixel(500, 250, image::Rgba([1, 2, 3, 255]));
    let mut png = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgba8(flat)
        .write_to(&mut png, image::ImageFormat::Png)
        .unwrap();
    bytes.extend(png.into_inner());
    std::fs::write(entry, bytes).unwrap();
    let ds = load(d.path(), &opts(Some(&cache), Some(500))).unwrap();
    assert_eq!(px(&ds, 0, 10, 10), [1, 2, 3, 255]);
    assert_eq!(ds.train[0].intrinsics, k);

    // Another cap is another entry (and the right size).
    let ds = load(d.path(), &opts(Some(&cache), Some(400))).unwrap();
    assert_eq!(ds.train[0].intrinsics.width, 400);
    assert_near(px(&ds, 0, 100, 50), RED, 24, "cap 400");

    // Replacing the photo (new content, new mtime) misses the old entry.
    std::fs::write(&file, jpeg_bytes(&quadrants(2000, 1000), 80)).unwrap();
    let f = std::fs::File::options().write(true).open(&file).unwrap();
    f.set_modified(std::time::SystemTime::now() + std::time::Duration::from_secs(5))
        .unwrap();
    drop(f);
    let ds = load(d.path(), &opts(Some(&cache), Some(500))).unwrap();
    assert_near(px(&ds, 0, 10, 10), RED, 24, "after the photo changed");
}

#[test]
fn translucent_images_are_capped_premultiplied() {
    // Left half opaque red, right half fully transparent *green*: the green must not bleed
    // into the edge pixels, whose colour is the red they partly cover.
    let d = TempDir::new("max-size-alpha");
    let img = image::RgbaImage::from_fn(16, 16, |x, _| {
        image::Rgba(if x < 7 {
            [200, 0, 0, 255]
        } else {
            [0, 255, 0, 0]
        })
    });
    std::fs::create_dir_all(d.path().join("images")).unwrap();
    img.save(d.path().join("images/a.png")).unwrap();
    write_ns_json(d.path(), &["images/a.png"], 10.0, None);
    let ds = load(d.path(), &opts(None, Some(4))).unwrap();
    assert_eq!(ds.train[0].intrinsics.width, 4);
    let edge = px(&ds, 0, 1, 2);
    assert!(
        edge[3] > 20 && edge[3] < 255,
        "edge is partly covered: {edge:?}"
    );
    assert!(
        edge[1] < 8 && edge[0] > 150,
        "edge keeps the object's colour: {edge:?}"
    );
    assert_eq!(px(&ds, 0, 3, 2)[3], 0, "far right stays transparent");
}

#[test]
fn downscale_then_cap_and_small_images_untouched_by_default() {
    let d = TempDir::new("down-cap");
    std::fs::create_dir_all(d.path().join("images")).unwrap();
    // 16-bit RGB PNG, 64x32: --downscale 2 gives 32x16, then the cap of 8 gives 8x4.
    let img16 = image::ImageBuffer::<image::Rgb<u16>, _>::from_fn(64, 32, |_, _| {
        image::Rgb([65535u16, 32896, 0])
    });
    img16.save(d.path().join("images/a.png")).unwrap();
    write_ns_json(d.path(), &["images/a.png"], 40.0, Some((64, 32)));
    let mut o = opts(None, Some(8));
    o.downscale = Some(2);
    let ds = load(d.path(), &o).unwrap();
    let k = ds.train[0].intrinsics;
    assert_eq!((k.width, k.height, k.fx, k.cx), (8, 4, 5.0, 4.0));
    assert_eq!(px(&ds, 0, 3, 1), [255, 128, 0, 255]);
    // The default cap (1600) leaves a 64x32 image alone.
    let ds = load(d.path(), &opts(None, None)).unwrap();
    assert_eq!(ds.train[0].intrinsics.width, 64);
}

#[test]
fn corrupt_and_unsupported_images_are_named() {
    let d = TempDir::new("corrupt");
    std::fs::create_dir_all(d.path().join("images")).unwrap();
    let good = jpeg_bytes(&quadrants(64, 64), 90);
    // Truncated mid-scan, as an interrupted copy leaves it.
    std::fs::write(d.path().join("images/cut.jpg"), &good[..good.len() / 3]).unwrap();
    write_ns_json(d.path(), &["images/cut.jpg"], 40.0, None);
    assert_err_has(
        &load(d.path(), &opts(None, None)).unwrap_err(),
        &["images/cut.jpg", "cannot decode image"],
    );
    // Not an image at all (decoded as what its extension says, and failing).
    std::fs::write(d.path().join("images/text.webp"), b"hello, not a picture").unwrap();
    write_ns_json(d.path(), &["images/text.webp"], 40.0, None);
    assert_err_has(
        &load(d.path(), &opts(None, None)).unwrap_err(),
        &["images/text.webp", "cannot decode image", "WebP"],
    );
    // A GIF named .jpg: recognised, and refused by name.
    std::fs::write(
        d.path().join("images/anim.jpg"),
        b"GIF89a\x01\0\x01\0\0\0\0;",
    )
    .unwrap();
    write_ns_json(d.path(), &["images/anim.jpg"], 40.0, None);
    assert_err_has(
        &load(d.path(), &opts(None, None)).unwrap_err(),
        &[
            "images/anim.jpg",
            "unsupported image format (gif)",
            "PNG, JPEG and WebP",
        ],
    );
    // An extension this build does not read.
    write_ns_json(d.path(), &["images/a.exr"], 40.0, None);
    assert_err_has(
        &load(d.path(), &opts(None, None)).unwrap_err(),
        &["images/a.exr", "unsupported image format '.exr'"],
    );
}
