//! Benchmarks (ignored by default; they print their numbers):
//!   cargo test --release -p snerf-stylize --test stylizer_bench -- --ignored --nocapture
//! - tract vs onnxruntime for `arbitrary` on one 384x384 view, side by side in one run
//!   (the target: tract <= 1.5x onnxruntime);
//! - gatys optimisation step time at 128x128 with full-width (random) VGG-16 weights, and
//!   with the MobileNetV2 features at 128, 256 and 512;
//! - `arbitrary` on views larger than 384: resize, native, bands (`bench_large_views`).

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

/// `img` minus itself shrunk so its longer side is 384 and enlarged back: the band a 384 view
/// cannot hold.
fn fine_band(img: &snerf_stylize::stylizer::Image) -> Vec<f32> {
    use snerf_stylize::stylizer::resize;
    let (w, h) = (img.width, img.height);
    let (sw, sh) = if w >= h { (384, (h * 384).div_ceil(w)) } else { ((w * 384).div_ceil(h), 384) };
    let low = resize(&resize(img, sw, sh), w, h);
    img.data.iter().zip(&low.data).map(|(a, b)| a - b).collect()
}

fn correlation(a: &[f32], b: &[f32]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().map(|x| *x as f64).sum::<f64>() / n, b.iter().map(|x| *x as f64).sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (*x as f64 - ma) * (*y as f64 - mb)).sum();
    let va: f64 = a.iter().map(|x| (*x as f64 - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (*y as f64 - mb).powi(2)).sum();
    cov / (va * vb).sqrt().max(1e-30)
}

/// Largest mean jump across a vertical or horizontal line at a multiple of 384 (where 384²
/// tiles would meet), divided by the mean jump between neighbouring columns / rows elsewhere:
/// about 1 when nothing happens at tile borders.
fn seam_ratio(img: &snerf_stylize::stylizer::Image) -> f64 {
    let col_jump = |x: usize| (0..img.height).map(|y| (0..3).map(|c| (img.pixel(x + 1, y)[c] - img.pixel(x, y)[c]).abs() as f64).sum::<f64>()).sum::<f64>() / img.height as f64;
    let row_jump = |y: usize| (0..img.width).map(|x| (0..3).map(|c| (img.pixel(x, y + 1)[c] - img.pixel(x, y)[c]).abs() as f64).sum::<f64>()).sum::<f64>() / img.width as f64;
    let cols: Vec<f64> = (0..img.width - 1).map(col_jump).collect();
    let rows: Vec<f64> = (0..img.height - 1).map(row_jump).collect();
    let mean = (cols.iter().sum::<f64>() + rows.iter().sum::<f64>()) / (cols.len() + rows.len()) as f64;
    let at = |v: &[f64]| (1..v.len()).filter(|i| (i + 1) % 384 == 0).map(|i| v[i]).fold(0.0f64, f64::max);
    at(&cols).max(at(&rows)) / mean.max(1e-12)
}

/// How views larger than 384 should be handled (`LargeViews`): for each mode, time, the style
/// distances to the painting (Magenta embedding; Gram distance at the 384 footprint, where
/// the painting's strokes are), how much of the content's band finer than 384 the output
/// keeps (correlation of the two fine bands; and its energy against the content's), and the
/// seam ratio at 384-pixel lines. Content: the PNGs in `SNERF_BENCH_CONTENT` (separated by
/// `:`), else a synthetic picture at 1008x756; styles: the three paintings.
#[test]
#[ignore]
fn bench_large_views() {
    use snerf_stylize::paintings::{path, styles_dir, PAINTINGS};
    use snerf_stylize::style_gram::{distance, GramMetric};
    use snerf_stylize::stylizer::{image_from_png, load_style_image, resize, style_distance, ArbitraryStylizer, LargeViews, StyleEmbedder, Stylizer};
    let Some(opts) = models_or_skip("bench_large_views") else { return };
    let embedder = StyleEmbedder::new(&opts).unwrap();
    let gram = GramMetric::open(&opts).unwrap();
    let contents: Vec<(String, snerf_stylize::stylizer::Image)> = match std::env::var("SNERF_BENCH_CONTENT") {
        Ok(list) => list.split(':').map(|p| (p.to_string(), image_from_png(std::path::Path::new(p)).unwrap())).collect(),
        Err(_) => vec![("synthetic".into(), stylizer_support::content_image(1008, 756))],
    };
    for painting in PAINTINGS {
        let Ok(path) = path(&styles_dir(), &painting) else {
            println!("{}: not installed (bash scripts/setup-styles.sh)", painting.key);
            continue;
        };
        let style = load_style_image(&path).unwrap();
        let style_emb = embedder.embed(&style).unwrap();
        for (name, content) in &contents {
            let (w, h) = (content.width, content.height);
            let (sw, sh) = if w >= h { (384, (h * 384).div_ceil(w)) } else { ((w * 384).div_ceil(h), 384) };
            let style_grams = gram.reference(&style, sw, sh).unwrap();
            let content_band = fine_band(content);
            let content_energy = content_band.iter().map(|x| (x * x) as f64).sum::<f64>();
            for mode in [LargeViews::Resize, LargeViews::Native, LargeViews::Bands] {
                let s = ArbitraryStylizer::new(&style, &opts).unwrap().with_large_views(mode);
                s.stylize(content).unwrap();
                let t0 = std::time::Instant::now();
                let out = s.stylize(content).unwrap();
                let warm = t0.elapsed().as_secs_f64();
                let emb = style_distance(&embedder, &out, &style_emb).unwrap();
                let g = distance(&gram.grams(&[(&resize(&out, sw, sh), None)]).unwrap(), &style_grams);
                let band = fine_band(&out);
                let energy = band.iter().map(|x| (x * x) as f64).sum::<f64>() / content_energy.max(1e-30);
                println!(
                    "{} {name} {w}x{h} {mode:?}: {warm:.2} s, embedding distance {emb:.3}, Gram distance {g:.4}, fine band: correlation with content {:.3}, energy {energy:.2}x content's; seam ratio {:.2}",
                    painting.key,
                    correlation(&band, &content_band),
                    seam_ratio(&out)
                );
            }
        }
    }
}
