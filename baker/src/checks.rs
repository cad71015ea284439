//! Checks of an exported mesh: how close it lies to the field's own surface, and what the
//! Khronos glTF validator says of the file.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::Serialize;
use serde_json::{json, Value};
use snerf_asset::Asset;
use snerf_data::View;
use snerf_trainer::eval;
use snerf_trainer::render::WorkspacePool;
use snerf_trainer::train::Model;

use crate::marching_cubes::Mesh;

/// Distances (in voxels of the asset) from the field's expected-depth surface points to the
/// mesh: median, 90th percentile, and how many lie beyond 6 voxels.
#[derive(Clone, Debug, Serialize)]
pub struct SurfaceAgreement {
    pub points: usize,
    pub median_voxels: f32,
    pub p90_voxels: f32,
    pub beyond_6_voxels: usize,
}

/// Render up to 8 `views` from the field, take every pixel at least 90% opaque to its world
/// surface point, and measure its distance to `mesh`.
pub fn surface_agreement(asset: &Asset, mesh: &Mesh, model: &Model, pool: &WorkspacePool, views: &[View]) -> Result<SurfaceAgreement> {
    let bg = asset.header.background;
    let mut points = Vec::new();
    for v in views.iter().take(8) {
        let r = eval::render_camera(model, pool, &v.c2w, &v.intrinsics, v.time, bg);
        for p in 0..r.opacity.len() {
            if r.opacity[p] < 0.9 {
                continue;
            }
            let (x, y) = (p % r.width, p / r.width);
            if let Some(ray) = model.space.ray(&v.c2w, &v.intrinsics, x as f32 + 0.5, y as f32 + 0.5, v.time) {
                points.push(model.space.march_to_world(&ray, r.depth[p]));
            }
        }
    }
    if points.is_empty() {
        bail!("the field covers no pixel of the views; nothing to compare");
    }
    // one voxel in world units (exact for objects; at the centre for other kinds)
    let voxel = 2.0 / asset.header.res as f32 / asset.header.space.scale;
    let mut d: Vec<f32> = crate::mesh_export::distances_to_mesh(mesh, &points, voxel * 2.0).into_iter().map(|x| x / voxel).collect();
    d.sort_by(|a, b| a.total_cmp(b));
    let q = |f: f64| d[((d.len() - 1) as f64 * f) as usize];
    Ok(SurfaceAgreement {
        points: d.len(),
        median_voxels: q(0.5),
        p90_voxels: q(0.9),
        beyond_6_voxels: d.iter().filter(|x| !x.is_finite()).count(),
    })
}

/// The validator runner, carried inside the binary so an installed `snerf` needs no checkout.
const VALIDATE_SCRIPT: &str = include_str!("../../scripts/validate-gltf.mjs");

/// Where the npm `gltf-validator` package is: `$GLTF_VALIDATOR_DIR`, else
/// `target/test-assets/gltf-validator` under the current directory (where `.ci/run` puts it).
pub fn validator_dir() -> Option<PathBuf> {
    if let Some(d) = std::env::var_os("GLTF_VALIDATOR_DIR") {
        return Some(PathBuf::from(d));
    }
    let local = Path::new("target/test-assets/gltf-validator");
    local.join("node_modules/gltf-validator").exists().then(|| local.to_path_buf())
}

/// Run the Khronos glTF validator (Node.js + npm `gltf-validator`) on `path`; the report's
/// `issues` object.
pub fn validate_glb(path: &Path) -> Result<Value> {
    let dir = validator_dir().context(
        "glTF validator not found: `npm install --prefix DIR gltf-validator` and set GLTF_VALIDATOR_DIR=DIR (needs Node.js)",
    )?;
    // The script goes to node on stdin (as an ES module), so nothing is written anywhere.
    let mut child = std::process::Command::new("node")
        .args(["--input-type=module", "-"])
        .arg(path)
        .env("GLTF_VALIDATOR_DIR", std::path::absolute(&dir).unwrap_or(dir))
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .context("running node (needed for --validate; install Node.js and `npm install gltf-validator`)")?;
    {
        use std::io::Write;
        let mut stdin = child.stdin.take().context("node's stdin")?;
        stdin.write_all(VALIDATE_SCRIPT.as_bytes()).context("writing the validator script to node")?;
    }
    let out = child.wait_with_output().context("waiting for node")?;
    let report: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|_| json!({ "raw": String::from_utf8_lossy(&out.stdout) }));
    if out.status.code() == Some(2) {
        bail!("glTF validator unavailable: {}", String::from_utf8_lossy(&out.stderr).trim());
    }
    Ok(report)
}
