//! Shared by the stylizer tests: model availability (skip or fail), test images.
#![allow(dead_code)]

use snerf_stylize::stylizer::gatys::Planes;
use snerf_stylize::stylizer::{models_dir, Image, StylizerOptions, MODEL_FILES, SETUP_COMMAND};

/// Options pointing at the model directory, or None (test skipped with a note) when the
/// models are missing, unless SNERF_REQUIRE_MODELS=1, in which case the test fails.
pub fn models_or_skip(test: &str) -> Option<StylizerOptions> {
    let opts = StylizerOptions::default();
    let dir = models_dir(&opts);
    let missing: Vec<&str> = MODEL_FILES.iter().filter(|m| !dir.join(m.name).is_file()).map(|m| m.name).collect();
    if missing.is_empty() {
        return Some(opts);
    }
    if std::env::var("SNERF_REQUIRE_MODELS").as_deref() == Ok("1") {
        panic!("{test}: models {missing:?} missing in {} and SNERF_REQUIRE_MODELS=1; run `{SETUP_COMMAND}`", dir.display());
    }
    eprintln!("SKIP {test}: models {missing:?} not in {} (run `{SETUP_COMMAND}`)", dir.display());
    None
}

/// A "photo": smooth sky-like gradient, a dark ground, a few hard-edged shapes.
pub fn content_image(width: usize, height: usize) -> Image {
    let mut data = Vec::with_capacity(width * height * 3);
    for y in 0..height {
        for x in 0..width {
            let (u, v) = (x as f32 / width as f32, y as f32 / height as f32);
            let mut rgb = if v < 0.6 { [0.45 + 0.3 * v, 0.6 + 0.2 * v, 0.9 - 0.2 * u] } else { [0.35, 0.3 - 0.1 * v, 0.2] };
            let (dx, dy) = (u - 0.35, v - 0.45);
            if dx * dx + dy * dy < 0.02 {
                rgb = [0.9, 0.85, 0.2];
            }
            if (0.6..0.8).contains(&u) && (0.3..0.7).contains(&v) {
                rgb = [0.7, 0.2, 0.2];
            }
            data.extend_from_slice(&rgb);
        }
    }
    Image { width, height, data }
}

/// A "painting": saturated, high-frequency swirls in a distinct palette.
pub fn style_image(width: usize, height: usize) -> Image {
    let mut data = Vec::with_capacity(width * height * 3);
    for y in 0..height {
        for x in 0..width {
            let (u, v) = (x as f32 / width as f32 * 6.3, y as f32 / height as f32 * 6.3);
            let a = (u * 3.0 + (v * 2.0).sin() * 2.0).sin();
            let b = (v * 4.0 + (u * 3.0).cos() * 1.5).cos();
            data.push((0.5 + 0.45 * a).clamp(0.0, 1.0));
            data.push((0.25 + 0.2 * b).clamp(0.0, 1.0));
            data.push((0.55 + 0.4 * a * b).clamp(0.0, 1.0));
        }
    }
    Image { width, height, data }
}

pub fn assert_finite_in_range(img: &Image) {
    assert_eq!(img.data.len(), img.width * img.height * 3);
    assert!(img.data.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)), "output has values outside [0,1] or non-finite");
}

/// Deterministic pseudo-random numbers in [-1, 1] (directions for gradient checks).
pub fn noise(n: usize, seed: u64) -> Vec<f32> {
    let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (0..n)
        .map(|_| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((s >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
        })
        .collect()
}

/// `x + h * dir`.
pub fn shifted(x: &Planes, dir: &[f32], h: f32) -> Planes {
    Planes { data: x.data.iter().zip(dir).map(|(a, d)| a + h * d).collect(), ..x.clone() }
}
