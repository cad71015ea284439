//! `snerf bench publish`: a published scene behind a real CDN edge on loopback (caddy origin,
//! varnish edge: `snerf_stream::edge`), BENCH.md §8d. Three parts, one run:
//! 1. object size: for each `--object-kb`, the object count, the manifest, bytes on the wire
//!    per viewer over the asset, time to the first block and to the whole asset (warm edge),
//!    and what re-publishing after one changed block writes;
//! 2. load: `--viewers` simulated viewers (`cdn_load`: each reads the manifest, orders the
//!    objects for its own pose with the server's planner, checks every hash and the file's),
//!    `--concurrent` at a time, through varnish: byte-identical count, p50/p99 times, origin
//!    requests per viewer and the edge's hit ratio (varnishstat);
//! 3. the same viewers against `snerf serve` (QUIC, `snerf fetch`), as a ratio.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_stream::cdn_load::load;
use snerf_stream::edge::{Edge, EdgeOptions};
use snerf_stream::publish::{publish, PublishOptions};

#[derive(Args, Debug)]
pub struct BenchPublishArgs {
    /// A baked asset (.snerf).
    pub asset: PathBuf,
    /// Simulated viewers through the edge (and against `snerf serve`).
    #[arg(long, default_value_t = 1000)]
    pub viewers: usize,
    /// Viewers at once.
    #[arg(long, default_value_t = 100)]
    pub concurrent: usize,
    /// Connections per viewer.
    #[arg(long, default_value_t = 2)]
    pub parallel: usize,
    /// Object sizes to compare, KiB (the last is used for the load).
    #[arg(long, value_delimiter = ',', default_value = "16,64,1024,256")]
    pub object_kb: Vec<u64>,
    /// Viewers per object size in part 1.
    #[arg(long, default_value_t = 20)]
    pub size_viewers: usize,
    /// Viewers against `snerf serve` (0: skip; default: --viewers).
    #[arg(long)]
    pub serve_viewers: Option<usize>,
    /// Work folder (default: a new folder under the system temp dir, removed at the end).
    #[arg(long)]
    pub work: Option<PathBuf>,
}

fn counters_delta(
    e: &Edge,
    before: &std::collections::BTreeMap<String, u64>,
) -> Result<(u64, u64, u64)> {
    let a = e.counters()?;
    let d = |k: &str| a.get(k).copied().unwrap_or(0) - before.get(k).copied().unwrap_or(0);
    Ok((
        d("MAIN.cache_hit"),
        d("MAIN.cache_miss"),
        d("MAIN.backend_req"),
    ))
}

/// Flip one voxel byte of a middle BLKS chunk and fix its CRC: a re-bake changing one block.
fn change_one_block(bytes: &[u8]) -> Result<Vec<u8>> {
    let mut b = bytes.to_vec();
    let list = snerf_asset::chunks(&b)?;
    let blks: Vec<_> = list
        .iter()
        .filter(|c| &b[c.range.start..c.range.start + 4] == b"BLKS")
        .cloned()
        .collect();
    let c = blks.get(blks.len() / 2).context("no BLKS chunk")?.clone();
    b[c.payload.start + 8] ^= 0x01;
    let crc = crc32(&b[c.payload.clone()]);
    b[c.range.start + 8..c.range.start + 12].copy_from_slice(&crc.to_le_bytes());
    Ok(b)
}

fn crc32(b: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &x in b {
        c ^= x as u32;
        for _ in 0..8 {
            c = if c & 1 == 1 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

pub fn run(a: &BenchPublishArgs) -> Result<Value> {
    let work = a.work.clone().unwrap_or_else(|| {
        std::env::temp_dir().join(format!("snerf-bench-publish-{}", std::process::id()))
    });
    std::fs::create_dir_all(&work)?;
    let r = run_in(a, &work);
    if a.work.is_none() {
        let _ = std::fs::remove_dir_all(&work);
    }
    r
}

fn run_in(a: &BenchPublishArgs, work: &Path) -> Result<Value> {
    let bytes =
        std::fs::read(&a.asset).with_context(|| format!("{}: cannot read", a.asset.display()))?;
    let name = a
        .asset
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get());
    let mut sizes = Vec::new();
    // 1. Object sizes.
    for &kb in &a.object_kb {
        let site = work.join(format!("site-{kb}"));
        let src = work.join(format!("src-{kb}"));
        std::fs::create_dir_all(&src)?;
        let file = src.join(format!("{name}.snerf"));
        std::fs::write(&file, &bytes)?;
        let o = PublishOptions {
            object_bytes: kb * 1024,
            web: true,
        };
        let p = publish(&file, &site, &o)?;
        std::fs::write(&file, change_one_block(&bytes)?)?;
        let re = publish(&file, &site, &o)?;
        std::fs::write(&file, &bytes)?;
        publish(&file, &site, &o)?;
        let edge = Edge::start(
            &site,
            &work.join(format!("edge-{kb}")),
            &EdgeOptions::default(),
        )?;
        let url = edge.edge_url(&format!("/{name}/manifest.json"));
        let cold = load(&url, None, 1, 1, a.parallel, threads)?;
        let warm = load(&url, None, a.size_viewers, 1, a.parallel, threads)?;
        let row = json!({
            "object_kb": kb, "objects": p.objects, "manifest_bytes": p.manifest_bytes,
            "cold_wire_over_asset": cold.wire_over_asset, "wire_over_asset": warm.wire_over_asset,
            "requests_per_viewer": warm.requests_per_viewer,
            "first_block_p50_s": warm.first_block_p50_s, "all_p50_s": warm.all_p50_s,
            "republish_one_block_bytes": re.bytes_written, "republish_objects": re.objects_written,
            "identical": warm.identical,
        });
        eprintln!("size {kb} KiB: {row}");
        sizes.push(row);
    }
    // 2. Load through the edge, on the last size's layout.
    let kb = *a.object_kb.last().context("--object-kb")?;
    let edge = Edge::start(
        &work.join(format!("site-{kb}")),
        &work.join("edge-load"),
        &EdgeOptions::default(),
    )?;
    let url = edge.edge_url(&format!("/{name}/manifest.json"));
    let c0 = edge.counters()?;
    let first = load(&url, None, 1, 1, a.parallel, threads)?;
    let (h1, m1, o1) = counters_delta(&edge, &c0)?;
    let c1 = edge.counters()?;
    let t = Instant::now();
    let r = load(&url, None, a.viewers, a.concurrent, a.parallel, threads)?;
    let wall = t.elapsed().as_secs_f64();
    let (hits, misses, origin) = counters_delta(&edge, &c1)?;
    let edge_row = json!({
        "viewers": a.viewers, "concurrent": a.concurrent, "parallel": a.parallel, "object_kb": kb,
        "ok": r.ok, "identical": r.identical, "errors": r.errors.iter().take(5).collect::<Vec<_>>(),
        "first_block_p50_s": r.first_block_p50_s, "first_block_p99_s": r.first_block_p99_s,
        "all_p50_s": r.all_p50_s, "all_p99_s": r.all_p99_s, "wall_s": wall,
        "viewers_per_s": a.viewers as f64 / wall,
        "requests_per_viewer": r.requests_per_viewer, "wire_over_asset": r.wire_over_asset,
        "first_viewer": { "hits": h1, "misses": m1, "origin_requests": o1, "identical": first.identical },
        "edge_hits": hits, "edge_misses": misses, "origin_requests": origin,
        "origin_requests_per_viewer": origin as f64 / a.viewers.max(1) as f64,
        "hit_ratio": hits as f64 / (hits + misses).max(1) as f64,
    });
    eprintln!("edge: {edge_row}");
    drop(edge);
    // 3. The same viewers against `snerf serve`.
    let sv = a.serve_viewers.unwrap_or(a.viewers);
    let serve_row = if sv > 0 {
        serde_json::to_value(snerf_stream::cdn_load::serve_load(
            &bytes,
            &name,
            work,
            sv,
            a.concurrent,
            threads,
        )?)?
    } else {
        Value::Null
    };
    eprintln!("serve: {serve_row}");
    let ratio = if serve_row.is_null() {
        Value::Null
    } else {
        json!(
            edge_row["viewers_per_s"].as_f64().unwrap_or(0.0)
                / serve_row["viewers_per_s"].as_f64().unwrap_or(f64::NAN)
        )
    };
    Ok(json!({
        "command": "bench publish", "asset": crate::args::pj(&a.asset), "asset_bytes": bytes.len(),
        "threads": threads, "sizes": sizes, "edge": edge_row, "serve": serve_row,
        "edge_over_serve_viewers_per_s": ratio,
    }))
}
