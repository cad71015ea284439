//! Benchmarks (ignored by default; they print their numbers):
//!   cargo test --release -p snerf-stylize --test stylizer_bench -- --ignored --nocapture
//! - tract vs onnxruntime for `arbitrary` on one 384x384 view, side by side in one run
//!   (the bar: tract <= 1.5x onnxruntime);
//! - gatys optimisation step time at 128x128 with full-width (random) VGG-16 weights, and
//!   with the MobileNetV2 features at 128, 256 and 512.

mod stylizer_support;

use snerf_stylize::stylizer::gatys::{net_step_time, step_time, MobileNet, VggWeights, VGG16_WIDTHS};
use snerf_stylize::stylizer::{model_path, ARBITRARY_PREDICT};
use snerf_stylize::stylizer::{bench_arbitrary, bench_onnxruntime, models_dir};
use stylizer_support::models_or_skip;

#[test]
#[ignore]
fn bench_tract_vs_onnxruntime_384() {
    let Some(opts) = models_or_skip("bench_tract_vs_onnxruntime_384") else { return };
    let reps = 7;
    let tract = bench_arbitrary(&opts, 384, reps).unwrap();
    println!("tract: {}", serde_json::to_string(&tract).unwrap());
    let Some(ort) = bench_onnxruntime(&models_dir(&opts), tract.transform_shape.0, reps, tract.threads) else {
        println!("onnxruntime not importable: no side-by-side numbers (run scripts/setup-models.sh)");
        return;
    };
    println!("onnxruntime: {ort}");
    let ort_transform = ort["transform_median_s"].as_f64().unwrap();
    let ort_predict = ort["predict_median_s"].as_f64().unwrap();
    let ratio = tract.transform_median_s / ort_transform;
    println!(
        "transform 384x384: tract {:.3} s, onnxruntime {:.3} s, ratio {ratio:.2}; style 256x256: tract {:.3} s, onnxruntime {:.3} s; \
         whole stylization {:.3} s; first call {:.2} s (optimize {:.2} s)",
        tract.transform_median_s, ort_transform, tract.predict_median_s, ort_predict, tract.stylize_median_s, tract.first_call_s, tract.transform_optimize_s
    );
    assert!(ratio <= 1.5, "tract is {ratio:.2}x onnxruntime on the 384x384 transform (bar: 1.5x)");
}

#[test]
#[ignore]
fn bench_gatys_step_128() {
    let vgg = step_time(VggWeights::random(VGG16_WIDTHS, 1), 128, 3);
    println!("gatys: {vgg:.3} s per Adam step at 128x128 (full-width VGG-16, random weights, {} threads)", rayon::current_num_threads());
    let Some(opts) = models_or_skip("bench_gatys_step_128 (MobileNetV2)") else { return };
    let net = MobileNet::load(&model_path(ARBITRARY_PREDICT, &opts).unwrap()).unwrap();
    for size in [128, 256, 512] {
        let t = net_step_time(&net, size, 5);
        println!("gatys: {t:.4} s per Adam step at {size}x{size} (MobileNetV2 from arbitrary_predict.onnx){}", if size == 128 { format!(", {:.1}x faster than VGG-16", vgg / t) } else { String::new() });
    }
}

/// Correlation between the gradient magnitudes of two images (how much of the content's
/// edge structure survives at full resolution).
fn edge_correlation(a: &snerf_stylize::stylizer::Image, b: &snerf_stylize::stylizer::Image) -> f64 {
    let grad = |img: &snerf_stylize::stylizer::Image| -> Vec<f64> {
        let lum = |x: usize, y: usize| {
            let p = img.pixel(x, y);
            (0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2]) as f64
        };
        let mut g = Vec::new();
        for y in 0..img.height - 1 {
            for x in 0..img.width - 1 {
                let (dx, dy) = (lum(x + 1, y) - lum(x, y), lum(x, y + 1) - lum(x, y));
                g.push((dx * dx + dy * dy).sqrt());
            }
        }
        g
    };
    let (ga, gb) = (grad(a), grad(b));
    let n = ga.len() as f64;
    let (ma, mb) = (ga.iter().sum::<f64>() / n, gb.iter().sum::<f64>() / n);
    let cov: f64 = ga.iter().zip(&gb).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = ga.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = gb.iter().map(|y| (y - mb).powi(2)).sum();
    cov / (va * vb).sqrt()
}

/// How views larger than 384 should be handled: resize to 384 and back, or run the
/// transform network at the view's own size. Prints time, style distance and edge
/// correlation with the content for both.
#[test]
#[ignore]
fn bench_large_views_resize_vs_native() {
    use snerf_stylize::stylizer::{style_distance, ArbitraryStylizer, LargeViews, StyleEmbedder, Stylizer};
    let Some(opts) = models_or_skip("bench_large_views_resize_vs_native") else { return };
    let style = stylizer_support::style_image(256, 256);
    let embedder = StyleEmbedder::new(&opts).unwrap();
    let style_emb = embedder.embed(&style).unwrap();
    for (w, h) in [(768, 512), (1008, 548)] {
        // SNERF_BENCH_CONTENT=photo.jpg measures on a real picture instead of the synthetic one.
        let content = match std::env::var_os("SNERF_BENCH_CONTENT") {
            Some(p) => snerf_stylize::stylizer::resize(&snerf_stylize::stylizer::image_from_png(std::path::Path::new(&p)).unwrap(), w, h),
            None => stylizer_support::content_image(w, h),
        };
        for mode in [LargeViews::Resize, LargeViews::Native] {
            let s = ArbitraryStylizer::new(&style, &opts).unwrap().with_large_views(mode);
            let t0 = std::time::Instant::now();
            s.stylize(&content).unwrap();
            let first = t0.elapsed().as_secs_f64();
            let t0 = std::time::Instant::now();
            let out = s.stylize(&content).unwrap();
            let warm = t0.elapsed().as_secs_f64();
            let d = style_distance(&embedder, &out, &style_emb).unwrap();
            println!(
                "{w}x{h} {mode:?}: first {first:.2} s, warm {warm:.2} s, style distance {d:.3}, edge correlation with content {:.3}",
                edge_correlation(&content, &out)
            );
        }
    }
}
