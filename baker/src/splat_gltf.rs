//! Gaussian splats (`splats`) as binary glTF 2.0 with `KHR_gaussian_splatting`: one node,
//! one mesh, one `POINTS` primitive whose attributes are, per the extension's text:
//!
//! | attribute | storage | bytes |
//! | --- | --- | --- |
//! | `POSITION` | float VEC3 (with min/max) | 12 |
//! | `KHR_gaussian_splatting:ROTATION` | normalized signed byte VEC4, unit quaternion (x, y, z, w) | 4 |
//! | `KHR_gaussian_splatting:SCALE` | float VEC3, **linear** standard deviations (world units) | 12 |
//! | `KHR_gaussian_splatting:OPACITY` | normalized unsigned byte, stride 4 (attribute alignment) | 4 |
//! | `KHR_gaussian_splatting:SH_DEGREE_0_COEF_0` | float VEC3 (the extension allows only float) | 12 |
//! | `KHR_gaussian_splatting:SH_DEGREE_ℓ_COEF_n`, ℓ ≥ 1 | float VEC3, only for view-dependent assets | 12 each |
//! | `COLOR_0` | normalized unsigned byte RGBA: diffuse colour, opacity (point-cloud fallback) | 4 |
//!
//! 48 bytes per splat for a diffuse asset. The extension object says `kernel: "ellipse"`,
//! `colorSpace: "srgb_rec709_display"` (the asset's colours are display-referred sRGB,
//! composited as they are), `projection: "perspective"`, `sortingMethod: "cameraDistance"`.
//! Quantized rotations lose nothing an engine keeps: Babylon.js packs them into bytes itself.
//! Positions and scales stay float because glTF's normalized integers have no range of their
//! own (KHR_mesh_quantization would move the dequantization into a node transform).

use anyhow::{ensure, Context, Result};
use serde::Serialize;
use serde_json::{json, Value};
use std::path::Path;

use crate::gltf_export::{accessor, f32_bytes, glb_container, unorm8, Bin, ARRAY_BUFFER, FLOAT, UNSIGNED_BYTE};
use crate::splats::{asset_splats, Splat, SplatOptions, SplatStats, SH_C0};
use snerf_asset::Asset;

const BYTE: u32 = 5120;
pub const EXTENSION: &str = "KHR_gaussian_splatting";
/// The colour space the asset's colours are in (module doc).
pub const COLOR_SPACE: &str = "srgb_rec709_display";

/// What was written.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct SplatExportReport {
    pub splats: usize,
    pub bytes: u64,
    pub bytes_per_splat: f64,
    pub sh_degree: u32,
    pub conversion: SplatStats,
}

/// Normalized signed byte of a value in [−1, 1] (glTF: value = max(c / 127, −1)).
pub fn snorm8(v: f32) -> i8 {
    if v.is_nan() {
        0
    } else {
        (v.clamp(-1.0, 1.0) * 127.0).round() as i8
    }
}

/// The GLB bytes of one splat set (`sh_degree` ≥ 1 needs every splat's `sh` to hold the
/// (ℓ+1)² − 1 coefficients of degrees 1..=ℓ).
pub fn encode_splats_glb(splats: &[Splat], sh_degree: u32, name: &str) -> Result<Vec<u8>> {
    ensure!(!splats.is_empty(), "no splats to write");
    ensure!(sh_degree <= 3, "SH degree {sh_degree}: the extension stores 0 to 3");
    let n_sh = ((sh_degree + 1) * (sh_degree + 1) - 1) as usize;
    for (i, s) in splats.iter().enumerate() {
        ensure!(
            s.sh.len() == n_sh,
            "splat {i} has {} SH coefficients, degree {sh_degree} needs {n_sh}",
            s.sh.len()
        );
        let finite = s
            .position
            .iter()
            .chain(&s.scale)
            .chain(&s.rotation)
            .chain(&s.color)
            .all(|x| x.is_finite())
            && s.opacity.is_finite()
            && s.sh.iter().flatten().all(|x| x.is_finite());
        ensure!(finite, "splat {i} has non-finite values: {s:?}");
        ensure!(s.scale.iter().all(|&x| x >= 0.0), "splat {i} has a negative scale {:?}", s.scale);
    }
    let count = splats.len();
    let mut bin = Bin::default();
    let mut accessors: Vec<Value> = vec![];
    let mut attributes = serde_json::Map::new();

    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for s in splats {
        for a in 0..3 {
            lo[a] = lo[a].min(s.position[a]);
            hi[a] = hi[a].max(s.position[a]);
        }
    }
    let v = bin.view(f32_bytes(splats.iter().flat_map(|s| &s.position)), Some(ARRAY_BUFFER));
    attributes.insert(
        "POSITION".into(),
        accessor(&mut accessors, v, FLOAT, count, "VEC3", false, Some((&lo, &hi))).into(),
    );

    let rot: Vec<u8> = splats.iter().flat_map(|s| s.rotation.map(|q| snorm8(q) as u8)).collect();
    let v = bin.view(rot, Some(ARRAY_BUFFER));
    attributes.insert(
        format!("{EXTENSION}:ROTATION"),
        accessor(&mut accessors, v, BYTE, count, "VEC4", true, None).into(),
    );

    let v = bin.view(f32_bytes(splats.iter().flat_map(|s| &s.scale)), Some(ARRAY_BUFFER));
    attributes.insert(
        format!("{EXTENSION}:SCALE"),
        accessor(&mut accessors, v, FLOAT, count, "VEC3", false, None).into(),
    );

    // Vertex attributes are 4-byte aligned per element: one byte used of every four.
    let op: Vec<u8> = splats.iter().flat_map(|s| [unorm8(s.opacity), 0, 0, 0]).collect();
    let v = bin.view(op, Some(ARRAY_BUFFER));
    bin.views[v]["byteStride"] = json!(4);
    attributes.insert(
        format!("{EXTENSION}:OPACITY"),
        accessor(&mut accessors, v, UNSIGNED_BYTE, count, "SCALAR", true, None).into(),
    );

    let dc: Vec<f32> = splats.iter().flat_map(|s| s.color.map(|c| (c - 0.5) / SH_C0)).collect();
    let v = bin.view(f32_bytes(dc.iter()), Some(ARRAY_BUFFER));
    attributes.insert(
        format!("{EXTENSION}:SH_DEGREE_0_COEF_0"),
        accessor(&mut accessors, v, FLOAT, count, "VEC3", false, None).into(),
    );
    let mut k = 0;
    for l in 1..=sh_degree {
        for c in 0..(2 * l + 1) {
            let v = bin.view(f32_bytes(splats.iter().flat_map(|s| &s.sh[k])), Some(ARRAY_BUFFER));
            attributes.insert(
                format!("{EXTENSION}:SH_DEGREE_{l}_COEF_{c}"),
                accessor(&mut accessors, v, FLOAT, count, "VEC3", false, None).into(),
            );
            k += 1;
        }
    }

    let col: Vec<u8> = splats
        .iter()
        .flat_map(|s| [unorm8(s.color[0]), unorm8(s.color[1]), unorm8(s.color[2]), unorm8(s.opacity)])
        .collect();
    let v = bin.view(col, Some(ARRAY_BUFFER));
    attributes.insert(
        "COLOR_0".into(),
        accessor(&mut accessors, v, UNSIGNED_BYTE, count, "VEC4", true, None).into(),
    );

    let root = json!({
        "asset": { "version": "2.0", "generator": "snerf" },
        "extensionsUsed": [EXTENSION],
        "scene": 0,
        "scenes": [{ "name": name, "nodes": [0] }],
        "nodes": [{ "name": name, "mesh": 0 }],
        "meshes": [{
            "name": name,
            "primitives": [{
                "attributes": attributes,
                "mode": 0,
                "extensions": { EXTENSION: {
                    "kernel": "ellipse",
                    "colorSpace": COLOR_SPACE,
                    "projection": "perspective",
                    "sortingMethod": "cameraDistance",
                } },
            }],
        }],
        "accessors": accessors,
        "bufferViews": bin.views,
        "buffers": [{ "byteLength": bin.data.len() }],
    });
    glb_container(&root, &bin.data)
}

/// Converts a static asset to splats and writes them atomically at `path`.
pub fn export_splats(asset: &Asset, opts: &SplatOptions, path: &Path) -> Result<SplatExportReport> {
    ensure!(
        !asset.is_dynamic(),
        "a dynamic asset ({} keyframes) cannot be exported as splats yet; export it with --format mesh (a flipbook)",
        asset.num_frames()
    );
    let (splats, stats) = asset_splats(asset, 0, opts)?;
    let bytes = encode_splats_glb(&splats, stats.sh_degree, "snerf")?;
    snerf_files::write_atomic(path, &bytes).with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(SplatExportReport {
        splats: splats.len(),
        bytes: bytes.len() as u64,
        bytes_per_splat: bytes.len() as f64 / splats.len() as f64,
        sh_degree: stats.sh_degree,
        conversion: stats,
    })
}
