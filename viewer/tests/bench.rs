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
    assert!(b.diffuse.is_none(), "only a diffuse asset is compared with the full variant");
}

#[test]
fn bench_view_compares_a_diffuse_asset_with_the_full_variant() {
    if !have_gpu("bench_view_compares_a_diffuse_asset_with_the_full_variant") {
        return;
    }
    let mut a = object_asset();
    a.make_diffuse();
    let b = snerf_viewer::bench_view(&a, 160, 120, 4).unwrap();
    println!("{}", b);
    let d = b.diffuse.expect("a diffuse asset is timed against the full variant");
    assert!(d.diffuse_median_ms > 0.0 && d.full_median_ms > 0.0 && d.ratio.is_finite());
    // the same pixels from half the texture memory
    assert_eq!(2 * d.diffuse_atlas_bytes, d.full_atlas_bytes);
    assert!(d.max_abs_diff <= 1e-5, "{}", d.max_abs_diff);
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
