//! Many viewers of a published scene at once (`snerf bench publish`, `tests/publish.rs`):
//! each one does what `snerf fetch https://…` does — the manifest, then every object in the
//! planner's order for its own pose, each checked against its SHA-256, then the file
//! assembled and checked against the asset's SHA-256 — in memory, on its own connections.

use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Result;
use serde::Serialize;

use crate::cdn_client::{fetch_objects, get_manifest, CdnOptions, CdnStats, HttpConn, HttpUrl};
use crate::proto::Pose;

/// One viewer's result.
#[derive(Clone, Debug, Serialize)]
pub struct ViewerRun {
    pub first_block_s: f64,
    pub all_s: f64,
    pub requests: u64,
    pub wire_bytes: u64,
    pub asset_bytes: u64,
    pub refetched: usize,
    /// The assembled file's SHA-256 equals the manifest's.
    pub identical: bool,
}

/// A pose on a circle around the asset's centre: viewer `i` of `n` looks in from its own side.
pub fn orbit_pose(origin: [f32; 3], radius: f32, i: usize, n: usize) -> Pose {
    let a = i as f32 / n.max(1) as f32 * std::f32::consts::TAU;
    let eye = [
        origin[0] + radius * a.cos(),
        origin[1] + 0.4 * radius,
        origin[2] + radius * a.sin(),
    ];
    Pose {
        eye,
        forward: [origin[0] - eye[0], origin[1] - eye[1], origin[2] - eye[2]],
        time: 0.0,
        fov_deg: 60.0,
    }
}

/// One viewer: manifest, objects in its planner order, assemble, compare.
pub async fn viewer(
    url: &HttpUrl,
    tls: Option<Arc<rustls::ClientConfig>>,
    i: usize,
    n: usize,
    parallel: usize,
) -> Result<ViewerRun> {
    let t0 = Instant::now();
    let mut conn = HttpConn::new(url, tls.clone(), vec![]);
    let m = get_manifest(&mut conn, url).await?;
    let planner = m.planner()?;
    let radius = 3.0 / planner.header.space.scale.max(1e-6);
    let pose = orbit_pose(planner.origin, radius, i, n);
    let order = m.object_order(&planner, Some(pose), &[]);
    let mut has_block = vec![false; m.objects.len()];
    for b in &planner.blks {
        has_block[m.chunks[b.chunk as usize][0] as usize] = true;
    }
    let mut stats = CdnStats {
        requests: conn.requests,
        wire_bytes: conn.wire_bytes,
        ..Default::default()
    };
    drop(conn);
    let mut held: Vec<Vec<u8>> = vec![Vec::new(); m.objects.len()];
    let mut first = None;
    let opts = CdnOptions {
        parallel,
        ..Default::default()
    };
    fetch_objects(
        &m,
        &url.join(&m.objects_base),
        tls,
        &opts,
        order,
        |o, b| {
            if has_block[o] && first.is_none() {
                first = Some(t0.elapsed());
            }
            held[o] = b;
            Ok(())
        },
        &mut stats,
    )
    .await?;
    let identical = m.assemble(&held).is_ok();
    Ok(ViewerRun {
        first_block_s: first.unwrap_or(Duration::ZERO).as_secs_f64(),
        all_s: t0.elapsed().as_secs_f64(),
        requests: stats.requests,
        wire_bytes: stats.wire_bytes,
        asset_bytes: m.asset.size,
        refetched: stats.refetched,
        identical,
    })
}

/// `viewers` viewers, at most `concurrent` at a time, on a runtime of `threads` workers.
/// Failed viewers are counted, not fatal.
#[derive(Clone, Debug, Serialize)]
pub struct LoadReport {
    pub viewers: usize,
    pub concurrent: usize,
    pub ok: usize,
    pub identical: usize,
    pub errors: Vec<String>,
    pub wall_s: f64,
    pub first_block_p50_s: f64,
    pub first_block_p99_s: f64,
    pub all_p50_s: f64,
    pub all_p99_s: f64,
    pub requests_per_viewer: f64,
    /// Bytes on the wire per viewer over the asset's size.
    pub wire_over_asset: f64,
    pub runs: Vec<ViewerRun>,
}

pub fn pct(xs: &[f64], p: f64) -> f64 {
    if xs.is_empty() {
        return f64::NAN;
    }
    let mut v = xs.to_vec();
    v.sort_by(f64::total_cmp);
    v[((p / 100.0 * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)]
}

pub fn load(
    url: &str,
    ca: Option<&std::path::Path>,
    viewers: usize,
    concurrent: usize,
    parallel: usize,
    threads: usize,
) -> Result<LoadReport> {
    let u = HttpUrl::parse(url)?;
    let tls = if u.tls {
        Some(crate::cdn_client::tls_config(ca)?)
    } else {
        None
    };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(threads.max(1))
        .enable_all()
        .build()?;
    let t0 = Instant::now();
    let results: Vec<Result<ViewerRun>> = rt.block_on(async {
        let sem = Arc::new(tokio::sync::Semaphore::new(concurrent.max(1)));
        let mut tasks = Vec::new();
        for i in 0..viewers {
            let (u, tls, sem) = (u.clone(), tls.clone(), sem.clone());
            tasks.push(tokio::spawn(async move {
                let _permit = sem.acquire_owned().await.expect("semaphore");
                viewer(&u, tls, i, viewers, parallel).await
            }));
        }
        let mut out = Vec::new();
        for t in tasks {
            out.push(t.await.unwrap_or_else(|e| Err(anyhow::anyhow!("{e}"))));
        }
        out
    });
    let wall_s = t0.elapsed().as_secs_f64();
    let mut runs = Vec::new();
    let mut errors = Vec::new();
    for r in results {
        match r {
            Ok(v) => runs.push(v),
            Err(e) => errors.push(format!("{e:#}")),
        }
    }
    let fb: Vec<f64> = runs.iter().map(|r| r.first_block_s).collect();
    let all: Vec<f64> = runs.iter().map(|r| r.all_s).collect();
    let n = runs.len().max(1) as f64;
    Ok(LoadReport {
        viewers,
        concurrent,
        ok: runs.len(),
        identical: runs.iter().filter(|r| r.identical).count(),
        errors,
        wall_s,
        first_block_p50_s: pct(&fb, 50.0),
        first_block_p99_s: pct(&fb, 99.0),
        all_p50_s: pct(&all, 50.0),
        all_p99_s: pct(&all, 99.0),
        requests_per_viewer: runs.iter().map(|r| r.requests as f64).sum::<f64>() / n,
        wire_over_asset: runs
            .iter()
            .map(|r| r.wire_bytes as f64 / r.asset_bytes.max(1) as f64)
            .sum::<f64>()
            / n,
        runs,
    })
}

/// The same viewers against `snerf serve` (QUIC; each a `snerf fetch` to a file, checked and
/// removed), `concurrent` at a time: `snerf bench publish`'s comparison.
#[derive(Clone, Debug, Serialize)]
pub struct ServeLoad {
    pub viewers: usize,
    pub concurrent: usize,
    pub ok: usize,
    pub identical: usize,
    pub errors: Vec<String>,
    /// Connect to header + grids + MLP in (the server sends those first).
    pub renderable_p50_s: f64,
    pub renderable_p99_s: f64,
    pub all_p50_s: f64,
    pub all_p99_s: f64,
    pub wall_s: f64,
    pub viewers_per_s: f64,
}

pub fn serve_load(
    bytes: &[u8],
    name: &str,
    work: &std::path::Path,
    viewers: usize,
    concurrent: usize,
    threads: usize,
) -> Result<ServeLoad> {
    use sha2::{Digest, Sha256};
    let dir = work.join("serve-assets");
    std::fs::create_dir_all(&dir)?;
    std::fs::write(dir.join(format!("{name}.snerf")), bytes)?;
    let mut o = crate::ServeOptions::new(dir.clone(), "127.0.0.1:0".parse()?);
    o.state_dir = Some(work.join("serve-state"));
    o.quiet = true;
    o.web = None;
    o.limits.max_clients = concurrent.max(1) + 8;
    o.limits.max_pending_per_ip = concurrent.max(32) + 8;
    o.limits.max_pending = (concurrent + 8).max(256);
    let h = crate::spawn(o)?;
    let (url, pin, token) = (
        h.url(name),
        h.fingerprint().to_string(),
        h.token().to_string(),
    );
    let want = crate::proto::to_hex(&Sha256::digest(bytes));
    let outs = work.join("serve-out");
    std::fs::create_dir_all(&outs)?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(threads.max(1))
        .enable_all()
        .build()?;
    let t0 = Instant::now();
    let res: Vec<Result<(f64, f64, bool)>> = rt.block_on(async {
        let sem = Arc::new(tokio::sync::Semaphore::new(concurrent.max(1)));
        let mut tasks = Vec::new();
        for i in 0..viewers {
            let (url, pin, token, sem, want) = (
                url.clone(),
                pin.clone(),
                token.clone(),
                sem.clone(),
                want.clone(),
            );
            let out = outs.join(format!("{i}.snerf"));
            tasks.push(tokio::spawn(async move {
                let _p = sem.acquire_owned().await.expect("semaphore");
                let s = crate::fetch(&url, &pin, &token, &out).await?;
                let ok = std::fs::read(&out)
                    .map(|b| crate::proto::to_hex(&Sha256::digest(&b)) == want)
                    .unwrap_or(false);
                let _ = std::fs::remove_file(&out);
                Ok((
                    s.time_to_renderable.unwrap_or_default().as_secs_f64(),
                    s.elapsed.as_secs_f64(),
                    ok,
                ))
            }));
        }
        let mut v = Vec::new();
        for t in tasks {
            v.push(t.await.unwrap_or_else(|e| Err(anyhow::anyhow!("{e}"))));
        }
        v
    });
    let wall_s = t0.elapsed().as_secs_f64();
    h.shutdown();
    let ok: Vec<(f64, f64, bool)> = res
        .iter()
        .filter_map(|r| r.as_ref().ok().copied())
        .collect();
    let fr: Vec<f64> = ok.iter().map(|x| x.0).collect();
    let all: Vec<f64> = ok.iter().map(|x| x.1).collect();
    Ok(ServeLoad {
        viewers,
        concurrent,
        ok: ok.len(),
        identical: ok.iter().filter(|x| x.2).count(),
        errors: res
            .iter()
            .filter_map(|r| r.as_ref().err().map(|e| format!("{e:#}")))
            .take(5)
            .collect(),
        renderable_p50_s: pct(&fr, 50.0),
        renderable_p99_s: pct(&fr, 99.0),
        all_p50_s: pct(&all, 50.0),
        all_p99_s: pct(&all, 99.0),
        wall_s,
        viewers_per_s: viewers as f64 / wall_s,
    })
}
