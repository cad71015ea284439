//! `bench_view` runs both renderers and reports their frame times (the GPU-vs-CPU speed-up
//! is a benchmark figure, printed, never asserted: timings on shared machines are noise).
//! The 1280x720 numbers of the report: `cargo test --release -p snerf-viewer --test bench
//! -- --ignored --nocapture`.
mod common;
use common::*;

#[test]
fn bench_view_runs_both_renderers_small() {
    if !have_gpu("bench_view_runs_both_renderers_small") {
        return;
    }
    let a = object_asset();
    let b = snerf_viewer::bench_view(&a, 320, 240, 8).unwrap();
    println!("{}", b);
    assert!(b.gpu_median_ms > 0.0 && b.cpu_median_ms > 0.0 && b.speedup.is_finite());
}

#[test]
#[ignore]
fn bench_view_720p() {
    if !have_gpu("bench_view_720p") {
        return;
    }
    for (name, a) in [
        ("object", object_asset()),
        ("unbounded", unbounded_asset()),
        ("dynamic", dynamic_asset()),
    ] {
        let opts = snerf_viewer::BenchOptions {
            frames: 10,
            cpu_frames: 3,
            stereo: name == "object",
            ..Default::default()
        };
        let b = snerf_viewer::bench_view_with(&a, &opts).unwrap();
        println!(
            "== {} ({} blocks, res {})\n{}",
            name, a.header.atlas_blocks, a.header.res, b
        );
    }
}
