//! Timing the `arbitrary` stylizer with tract, and the same two networks with onnxruntime
//! (through `scripts/bench_onnxruntime.py`) for a side-by-side comparison in one run.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Arc;
use std::time::Instant;

use anyhow::Result;
use serde::Serialize;

use super::arbitrary::{ArbitraryStylizer, MagentaNets, EMBEDDING_LEN};
use super::tract_plans::ensure_executor;
use super::{Image, Stylizer, StylizerOptions};

/// What `bench_arbitrary` measured (seconds).
#[derive(Clone, Debug, Serialize)]
pub struct BenchResult {
    /// View side (the view is size x size).
    pub size: usize,
    pub reps: usize,
    /// tract matmul threads.
    pub threads: usize,
    /// Transform network input shape used for this view (height, width).
    pub transform_shape: (usize, usize),
    /// Optimizing the style network for 256x256 (once per process).
    pub predict_optimize_s: f64,
    /// Optimizing the transform network for `transform_shape` (once per shape).
    pub transform_optimize_s: f64,
    /// The first stylization of a fresh stylizer, optimization included.
    pub first_call_s: f64,
    /// Median of `reps` whole stylizations after a warm-up (resize, pad, network, crop).
    pub stylize_median_s: f64,
    /// Median of the transform network alone at `transform_shape`.
    pub transform_median_s: f64,
    /// Median of the style network alone at 256x256.
    pub predict_median_s: f64,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    if v.is_empty() {
        return f64::NAN;
    }
    v[v.len() / 2]
}

fn time_reps(reps: usize, mut f: impl FnMut() -> Result<()>) -> Result<f64> {
    f()?; // warm-up
    let mut times = Vec::with_capacity(reps);
    for _ in 0..reps.max(1) {
        let t0 = Instant::now();
        f()?;
        times.push(t0.elapsed().as_secs_f64());
    }
    Ok(median(times))
}

/// A deterministic colourful test image (smooth gradients plus stripes).
pub fn synthetic_image(width: usize, height: usize, seed: u32) -> Image {
    let mut data = Vec::with_capacity(width * height * 3);
    let s = seed as f32;
    for y in 0..height {
        for x in 0..width {
            let (u, v) = (x as f32 / width as f32, y as f32 / height as f32);
            let stripe = ((u * 12.0 + v * 5.0 + s).sin() * 0.5 + 0.5) * 0.4;
            data.push((0.2 + 0.6 * u + stripe * (s * 0.7).cos().abs()).clamp(0.0, 1.0));
            data.push((0.3 + 0.5 * v * (1.0 - u) + stripe * 0.5).clamp(0.0, 1.0));
            data.push((0.8 - 0.6 * v + 0.2 * ((u + v) * 9.0 + s).cos()).clamp(0.0, 1.0));
        }
    }
    Image { width, height, data }
}

/// Times `arbitrary` on one `size x size` view (see `BenchResult`).
pub fn bench_arbitrary(opts: &StylizerOptions, size: usize, reps: usize) -> Result<BenchResult> {
    let threads = ensure_executor();
    let nets = Arc::new(MagentaNets::open(opts)?);
    let predict_optimize_s = nets.prepare_predict()?.unwrap_or(0.0);
    let style = synthetic_image(320, 256, 7);
    let content = synthetic_image(size, size, 1);
    let stylizer = ArbitraryStylizer::with_nets(nets.clone(), &style, opts)?;
    let (th, tw) = stylizer.network_size(size, size);

    let t0 = Instant::now();
    let transform_optimize_s = nets.prepare_transform(th, tw)?.unwrap_or(0.0);
    stylizer.stylize(&content)?;
    let first_call_s = t0.elapsed().as_secs_f64();

    let stylize_median_s = time_reps(reps, || stylizer.stylize(&content).map(|_| ()))?;
    let input = vec![0.5f32; th * tw * 3];
    let emb = stylizer.style_embedding().to_vec();
    debug_assert_eq!(emb.len(), EMBEDDING_LEN);
    let transform_median_s = time_reps(reps, || nets.transform_raw(&input, th, tw, &emb).map(|_| ()))?;
    let side = opts.style_size;
    let style_in = vec![0.5f32; side * side * 3];
    let predict_median_s = time_reps(reps, || nets.predict_raw(&style_in, side).map(|_| ()))?;
    Ok(BenchResult {
        size,
        reps,
        threads,
        transform_shape: (th, tw),
        predict_optimize_s,
        transform_optimize_s,
        first_call_s,
        stylize_median_s,
        transform_median_s,
        predict_median_s,
    })
}

/// `scripts/bench_onnxruntime.py`: in `$SNERF_SCRIPTS_DIR` if set, else in this source
/// tree, else under the current directory.
pub fn onnxruntime_script() -> PathBuf {
    const NAME: &str = "bench_onnxruntime.py";
    if let Some(dir) = std::env::var_os("SNERF_SCRIPTS_DIR") {
        return PathBuf::from(dir).join(NAME);
    }
    let in_tree = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts").join(NAME);
    if in_tree.is_file() {
        return in_tree;
    }
    Path::new("scripts").join(NAME)
}

/// onnxruntime's medians for the same two networks (style 256x256, transform
/// `transform_side` squared) with `threads` intra-op threads, or None when python3 or
/// onnxruntime is not available.
pub fn bench_onnxruntime(models_dir: &Path, transform_side: usize, reps: usize, threads: usize) -> Option<serde_json::Value> {
    let out = Command::new("python3")
        .arg(onnxruntime_script())
        .arg(models_dir)
        .arg(transform_side.to_string())
        .arg(reps.to_string())
        .arg("--threads")
        .arg(threads.to_string())
        .output()
        .ok()?;
    if !out.status.success() {
        return None;
    }
    serde_json::from_slice(&out.stdout).ok()
}
