//! Binary glTF 2.0 (GLB) export of extracted meshes, for game engines.
//!
//! * [`write_glb`]: one node, one mesh, one triangle primitive with `POSITION` (with min/max),
//!   `NORMAL` (unit length), `COLOR_0` and indices (`u16` when they fit, else `u32`), and one
//!   material (metallic 0, roughness 1; `KHR_materials_unlit` by default, because baked
//!   radiance already contains its lighting).
//! * [`write_glb_frames`]: a dynamic asset as a visibility flipbook. Marching cubes gives every
//!   keyframe its own topology, so morph targets are out; instead each keyframe mesh gets its
//!   own node under one root node, and one animation drives every frame node's `scale` with a
//!   `STEP` sampler: `(1, 1, 1)` while that frame is current, `(0, 0, 0)` otherwise.
//!
//! [`GltfOptions::to_world`] is baked into the vertices (positions by the affine matrix,
//! normals by its inverse transpose, winding flipped when it mirrors), so the nodes carry no
//! transform and the file is in metres, Y-up, as glTF requires. Triangles with a repeated
//! vertex or zero area are dropped and unreferenced vertices removed. Files are written
//! atomically: a temporary file in the destination directory, then a rename.

use crate::marching_cubes::Mesh;
use anyhow::{bail, ensure, Context, Result};
use serde_json::{json, Value};
use std::path::Path;

/// How `COLOR_0` is stored. Colours are taken as linear RGB and clamped to [0, 1].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ColorFormat {
    /// Normalized unsigned byte RGBA (alpha 255): 4 bytes per vertex.
    #[default]
    Unorm8,
    /// Float RGB: 12 bytes per vertex, exact.
    Float32,
}

/// Options of the flipbook animation written by [`write_glb_frames`].
#[derive(Clone, Debug, PartialEq)]
pub struct FlipbookOptions {
    /// Name of the glTF animation.
    pub name: String,
    /// How long the last keyframe stays visible (seconds); `None`: as long as the interval
    /// before it (1/30 s for a single frame).
    pub last_frame_duration: Option<f32>,
}

impl Default for FlipbookOptions {
    fn default() -> Self {
        Self {
            name: "flipbook".into(),
            last_frame_duration: None,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct GltfOptions {
    /// Column-major 4x4 matrix (`to_world[column][row]`, the glTF / OpenGL layout; the
    /// translation is `to_world[3]`) from the mesh's coordinates to metres, Y-up. It must be
    /// affine (last row `0 0 0 1`) and invertible. Applied to positions; normals get its
    /// inverse transpose and are renormalized.
    pub to_world: [[f32; 4]; 4],
    /// Name of the root node and mesh(es).
    pub name: String,
    /// Used by [`write_glb_frames`] (defaults apply when `None`); ignored by [`write_glb`].
    pub animation: Option<FlipbookOptions>,
    pub color_format: ColorFormat,
    /// Add `KHR_materials_unlit` to the material (the PBR values stay as the fallback).
    pub unlit: bool,
    pub double_sided: bool,
    /// The iso level the mesh was extracted at, quoted by the empty-mesh error.
    pub iso: Option<f32>,
}

pub const IDENTITY: [[f32; 4]; 4] = [
    [1.0, 0.0, 0.0, 0.0],
    [0.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 1.0, 0.0],
    [0.0, 0.0, 0.0, 1.0],
];

impl Default for GltfOptions {
    fn default() -> Self {
        Self {
            to_world: IDENTITY,
            name: "snerf".into(),
            animation: None,
            color_format: ColorFormat::default(),
            unlit: true,
            double_sided: false,
            iso: None,
        }
    }
}

/// What was written.
#[derive(Clone, Debug, PartialEq, Eq, Default)]
pub struct GlbStats {
    /// Size of the GLB file.
    pub bytes: u64,
    /// Vertices and triangles written, over all frames.
    pub vertices: usize,
    pub triangles: usize,
    /// Triangles dropped for a repeated vertex or zero area.
    pub degenerate_removed: usize,
    /// Number of meshes (keyframes) written; 1 for [`write_glb`].
    pub frames: usize,
    /// Largest index component size used, in bytes (2 or 4).
    pub index_bytes: u8,
}

/// Writes `mesh` as a static GLB at `path` (atomically).
pub fn write_glb(mesh: &Mesh, opts: &GltfOptions, path: &Path) -> Result<GlbStats> {
    let (bytes, stats) = encode_glb(std::slice::from_ref(mesh), None, opts)?;
    write_atomic(path, &bytes)?;
    Ok(stats)
}

/// Writes keyframe meshes as a visibility flipbook: frame `i` is shown from `times[i]` until
/// `times[i + 1]` (the last one for [`FlipbookOptions::last_frame_duration`]). Times are in
/// seconds, finite, non-negative and strictly increasing. Empty frames become nodes without a
/// mesh; all frames empty is an error.
pub fn write_glb_frames(
    meshes: &[Mesh],
    times: &[f32],
    opts: &GltfOptions,
    path: &Path,
) -> Result<GlbStats> {
    let (bytes, stats) = encode_glb(meshes, Some(times), opts)?;
    write_atomic(path, &bytes)?;
    Ok(stats)
}

/// The GLB bytes [`write_glb`] (`times == None`, exactly one mesh) or [`write_glb_frames`]
/// would write.
pub fn encode_glb(
    meshes: &[Mesh],
    times: Option<&[f32]>,
    opts: &GltfOptions,
) -> Result<(Vec<u8>, GlbStats)> {
    let xf = Affine::new(&opts.to_world)?;
    match times {
        None => ensure!(
            meshes.len() == 1,
            "a static GLB holds exactly one mesh, got {}",
            meshes.len()
        ),
        Some(t) => {
            ensure!(!meshes.is_empty(), "no keyframe meshes to export");
            ensure!(
                t.len() == meshes.len(),
                "{} keyframe times for {} meshes",
                t.len(),
                meshes.len()
            );
            ensure!(
                t.iter().all(|x| x.is_finite() && *x >= 0.0),
                "keyframe times must be finite and non-negative"
            );
            ensure!(
                t.windows(2).all(|w| w[1] > w[0]),
                "keyframe times must be strictly increasing"
            );
        }
    }
    let prepared: Vec<Prepared> = meshes
        .iter()
        .enumerate()
        .map(|(i, m)| prepare(m, &xf).with_context(|| format!("mesh {i}")))
        .collect::<Result<_>>()?;
    if prepared.iter().all(|p| p.indices.is_empty()) {
        let level = opts.iso.map_or_else(
            || "the chosen iso level".to_string(),
            |x| format!("iso level {x}"),
        );
        let what = if meshes.len() > 1 {
            "in any keyframe "
        } else {
            ""
        };
        bail!("the baked density has no surface {what}at {level}; lower --iso");
    }

    let mut bin = Bin::default();
    let mut accessors: Vec<Value> = vec![];
    let mut gl_meshes: Vec<Value> = vec![];
    let mut mesh_of_frame: Vec<Option<usize>> = vec![];
    let mut stats = GlbStats {
        frames: meshes.len(),
        index_bytes: 2,
        ..Default::default()
    };
    for (f, p) in prepared.iter().enumerate() {
        stats.degenerate_removed += p.degenerate;
        if p.indices.is_empty() {
            mesh_of_frame.push(None);
            continue;
        }
        stats.vertices += p.positions.len();
        stats.triangles += p.indices.len() / 3;
        let count = p.positions.len();
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for q in &p.positions {
            for a in 0..3 {
                lo[a] = lo[a].min(q[a]);
                hi[a] = hi[a].max(q[a]);
            }
        }
        let pos = bin.view(f32_bytes(p.positions.iter().flatten()), Some(ARRAY_BUFFER));
        let nrm = bin.view(f32_bytes(p.normals.iter().flatten()), Some(ARRAY_BUFFER));
        let mut attributes = serde_json::Map::new();
        attributes.insert(
            "POSITION".into(),
            accessor(
                &mut accessors,
                pos,
                FLOAT,
                count,
                "VEC3",
                false,
                Some((&lo, &hi)),
            )
            .into(),
        );
        attributes.insert(
            "NORMAL".into(),
            accessor(&mut accessors, nrm, FLOAT, count, "VEC3", false, None).into(),
        );
        let col = match opts.color_format {
            ColorFormat::Float32 => {
                let v = bin.view(f32_bytes(p.colors.iter().flatten()), Some(ARRAY_BUFFER));
                accessor(&mut accessors, v, FLOAT, count, "VEC3", false, None)
            }
            ColorFormat::Unorm8 => {
                let bytes: Vec<u8> = p
                    .colors
                    .iter()
                    .flat_map(|c| [unorm8(c[0]), unorm8(c[1]), unorm8(c[2]), 255])
                    .collect();
                let v = bin.view(bytes, Some(ARRAY_BUFFER));
                accessor(&mut accessors, v, UNSIGNED_BYTE, count, "VEC4", true, None)
            }
        };
        attributes.insert("COLOR_0".into(), col.into());
        // 65535 is the primitive restart value for u16 indices, which glTF forbids.
        let idx = if count <= 0xFFFF {
            let v = bin.view(
                p.indices
                    .iter()
                    .flat_map(|&i| (i as u16).to_le_bytes())
                    .collect(),
                Some(ELEMENT_ARRAY_BUFFER),
            );
            accessor(
                &mut accessors,
                v,
                UNSIGNED_SHORT,
                p.indices.len(),
                "SCALAR",
                false,
                None,
            )
        } else {
            stats.index_bytes = 4;
            let v = bin.view(
                p.indices.iter().flat_map(|&i| i.to_le_bytes()).collect(),
                Some(ELEMENT_ARRAY_BUFFER),
            );
            accessor(
                &mut accessors,
                v,
                UNSIGNED_INT,
                p.indices.len(),
                "SCALAR",
                false,
                None,
            )
        };
        let name = if times.is_some() {
            format!("{}_frame{f}", opts.name)
        } else {
            opts.name.clone()
        };
        mesh_of_frame.push(Some(gl_meshes.len()));
        gl_meshes.push(json!({
            "name": name,
            "primitives": [{ "attributes": attributes, "indices": idx, "material": 0, "mode": 4 }],
        }));
    }

    let mut material = json!({
        "name": format!("{}_material", opts.name),
        "pbrMetallicRoughness": { "baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0 },
        "doubleSided": opts.double_sided,
    });
    let mut root = serde_json::Map::new();
    root.insert(
        "asset".into(),
        json!({ "version": "2.0", "generator": "snerf" }),
    );
    if opts.unlit {
        material["extensions"] = json!({ "KHR_materials_unlit": {} });
        root.insert("extensionsUsed".into(), json!(["KHR_materials_unlit"]));
    }
    let mut nodes: Vec<Value> = vec![];
    match times {
        None => nodes.push(json!({ "name": opts.name, "mesh": mesh_of_frame[0].unwrap() })),
        Some(t) => {
            let n = t.len();
            nodes.push(json!({ "name": opts.name, "children": (1..=n).collect::<Vec<_>>() }));
            for (f, m) in mesh_of_frame.iter().enumerate() {
                let s = if f == 0 { 1.0 } else { 0.0 };
                let mut node =
                    json!({ "name": format!("{}_frame{f}", opts.name), "scale": [s, s, s] });
                if let Some(m) = m {
                    node["mesh"] = json!(m);
                }
                nodes.push(node);
            }
            let anim = opts.animation.clone().unwrap_or_default();
            let last = anim.last_frame_duration.unwrap_or(if n > 1 {
                t[n - 1] - t[n - 2]
            } else {
                1.0 / 30.0
            });
            ensure!(
                last.is_finite() && last > 0.0,
                "the last frame's duration must be positive"
            );
            // Keys at every frame time plus one at the end, so the last frame is shown for `last`.
            let mut keys = t.to_vec();
            keys.push(t[n - 1] + last);
            ensure!(
                keys[n] > keys[n - 1],
                "the last frame's duration vanishes at time {}",
                t[n - 1]
            );
            let v = bin.view(f32_bytes(keys.iter()), None);
            let input = accessor(
                &mut accessors,
                v,
                FLOAT,
                keys.len(),
                "SCALAR",
                false,
                Some((&[keys[0]], &[keys[n]])),
            );
            let (mut samplers, mut channels) = (vec![], vec![]);
            for f in 0..n {
                let vals: Vec<f32> = (0..=n)
                    .flat_map(|k| {
                        let on = if (k.min(n - 1)) == f { 1.0 } else { 0.0 };
                        [on, on, on]
                    })
                    .collect();
                let v = bin.view(f32_bytes(vals.iter()), None);
                let output = accessor(&mut accessors, v, FLOAT, n + 1, "VEC3", false, None);
                channels.push(json!({ "sampler": samplers.len(), "target": { "node": f + 1, "path": "scale" } }));
                samplers.push(json!({ "input": input, "output": output, "interpolation": "STEP" }));
            }
            root.insert(
                "animations".into(),
                json!([{ "name": anim.name, "samplers": samplers, "channels": channels }]),
            );
        }
    }
    root.insert("scene".into(), json!(0));
    root.insert(
        "scenes".into(),
        json!([{ "name": opts.name, "nodes": [0] }]),
    );
    root.insert("nodes".into(), nodes.into());
    root.insert("meshes".into(), gl_meshes.into());
    root.insert("materials".into(), json!([material]));
    root.insert("accessors".into(), accessors.into());
    root.insert("bufferViews".into(), std::mem::take(&mut bin.views).into());
    root.insert("buffers".into(), json!([{ "byteLength": bin.data.len() }]));

    let out = glb_container(&Value::Object(root), &bin.data)?;
    stats.bytes = out.len() as u64;
    Ok((out, stats))
}

/// The GLB container: header, JSON chunk (space padded), BIN chunk (4-byte aligned).
pub(crate) fn glb_container(root: &Value, bin_data: &[u8]) -> Result<Vec<u8>> {
    let mut json_bytes = serde_json::to_vec(root)?;
    while json_bytes.len() % 4 != 0 {
        json_bytes.push(b' ');
    }
    debug_assert_eq!(bin_data.len() % 4, 0);
    let total = 12 + 8 + json_bytes.len() + 8 + bin_data.len();
    ensure!(
        total <= u32::MAX as usize,
        "GLB would be {total} bytes, over the format's 4 GiB limit"
    );
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(&(bin_data.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(bin_data);
    Ok(out)
}

pub(crate) const FLOAT: u32 = 5126;
pub(crate) const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
pub(crate) const ARRAY_BUFFER: u32 = 34962;

#[derive(Default)]
pub(crate) struct Bin {
    pub(crate) data: Vec<u8>,
    pub(crate) views: Vec<Value>,
}

impl Bin {
    /// Appends a 4-byte aligned buffer view; returns its index.
    pub(crate) fn view(&mut self, bytes: Vec<u8>, target: Option<u32>) -> usize {
        let mut v =
            json!({ "buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len() });
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.data.extend_from_slice(&bytes);
        while !self.data.len().is_multiple_of(4) {
            self.data.push(0);
        }
        self.views.push(v);
        self.views.len() - 1
    }
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn accessor(
    list: &mut Vec<Value>,
    view: usize,
    component: u32,
    count: usize,
    kind: &str,
    normalized: bool,
    bounds: Option<(&[f32], &[f32])>,
) -> usize {
    let mut a =
        json!({ "bufferView": view, "componentType": component, "count": count, "type": kind });
    if normalized {
        a["normalized"] = json!(true);
    }
    if let Some((lo, hi)) = bounds {
        a["min"] = json!(lo);
        a["max"] = json!(hi);
    }
    list.push(a);
    list.len() - 1
}

pub(crate) fn f32_bytes<'a>(v: impl Iterator<Item = &'a f32>) -> Vec<u8> {
    v.flat_map(|x| x.to_le_bytes()).collect()
}

pub(crate) fn unorm8(c: f32) -> u8 {
    if c.is_nan() {
        0
    } else {
        (c.clamp(0.0, 1.0) * 255.0).round() as u8
    }
}

/// An affine map with its normal matrix (inverse transpose, up to a positive factor).
struct Affine {
    m: [[f32; 4]; 4],
    normal: [[f32; 3]; 3],
    mirror: bool,
}

impl Affine {
    fn new(m: &[[f32; 4]; 4]) -> Result<Self> {
        ensure!(
            m.iter().flatten().all(|x| x.is_finite()),
            "to_world has non-finite entries"
        );
        ensure!(
            m[0][3].abs() < 1e-6
                && m[1][3].abs() < 1e-6
                && m[2][3].abs() < 1e-6
                && (m[3][3] - 1.0).abs() < 1e-6,
            "to_world must be affine (column-major, last row 0 0 0 1): {m:?}"
        );
        // Rows of the 3x3 part: r[row][col] = m[col][row].
        let r = |i: usize, j: usize| m[j][i] as f64;
        let cof = |i: usize, j: usize| {
            let (i1, i2, j1, j2) = ((i + 1) % 3, (i + 2) % 3, (j + 1) % 3, (j + 2) % 3);
            r(i1, j1) * r(i2, j2) - r(i1, j2) * r(i2, j1)
        };
        let det = r(0, 0) * cof(0, 0) + r(0, 1) * cof(0, 1) + r(0, 2) * cof(0, 2);
        let scale = (0..3)
            .map(|i| (0..3).map(|j| r(i, j).abs()).fold(0.0, f64::max))
            .fold(0.0, f64::max);
        ensure!(
            det.abs() > 1e-12 * scale.powi(3).max(1e-30),
            "to_world is singular (determinant {det})"
        );
        // The cofactor matrix is det * inverse transpose; multiply by sign(det) to keep normals outward.
        let s = det.signum();
        let mut normal = [[0.0f32; 3]; 3];
        for (i, row) in normal.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                *x = (s * cof(i, j)) as f32;
            }
        }
        Ok(Self {
            m: *m,
            normal,
            mirror: det < 0.0,
        })
    }
    fn point(&self, p: [f32; 3]) -> [f32; 3] {
        let m = &self.m;
        [0, 1, 2].map(|r| m[0][r] * p[0] + m[1][r] * p[1] + m[2][r] * p[2] + m[3][r])
    }
    fn normal(&self, n: [f32; 3]) -> [f32; 3] {
        let t = self
            .normal
            .map(|row| row[0] * n[0] + row[1] * n[1] + row[2] * n[2]);
        let l = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
        if l.is_finite() && l > 1e-30 {
            t.map(|x| x / l)
        } else {
            [0.0, 1.0, 0.0]
        }
    }
}

/// A mesh in world space, without degenerate triangles or unused vertices.
struct Prepared {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    colors: Vec<[f32; 3]>,
    indices: Vec<u32>,
    degenerate: usize,
}

fn prepare(mesh: &Mesh, xf: &Affine) -> Result<Prepared> {
    let n = mesh.positions.len();
    ensure!(
        mesh.normals.len() == n && mesh.colors.len() == n,
        "mesh attribute counts differ: {n} positions, {} normals, {} colors",
        mesh.normals.len(),
        mesh.colors.len()
    );
    ensure!(
        mesh.indices.len().is_multiple_of(3),
        "index count {} is not a multiple of 3",
        mesh.indices.len()
    );
    if let Some(&bad) = mesh.indices.iter().find(|&&i| i as usize >= n) {
        bail!("index {bad} out of range for {n} vertices");
    }
    let world: Vec<[f32; 3]> = mesh.positions.iter().map(|&p| xf.point(p)).collect();
    let mut remap = vec![u32::MAX; n];
    let mut out = Prepared {
        positions: vec![],
        normals: vec![],
        colors: vec![],
        indices: vec![],
        degenerate: 0,
    };
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = if xf.mirror {
            [t[0], t[2], t[1]]
        } else {
            [t[0], t[1], t[2]]
        };
        let (pa, pb, pc) = (world[a as usize], world[b as usize], world[c as usize]);
        let (u, v) = (
            [pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]],
            [pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]],
        );
        let cr = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        let area2 = cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2];
        if a == b || b == c || a == c || area2 == 0.0 {
            out.degenerate += 1;
            continue;
        }
        for i in [a, b, c] {
            let slot = &mut remap[i as usize];
            if *slot == u32::MAX {
                let p = world[i as usize];
                ensure!(
                    p.iter().all(|x| x.is_finite()),
                    "vertex {i} has a non-finite position {p:?}"
                );
                *slot = out.positions.len() as u32;
                out.positions.push(p);
                out.normals.push(xf.normal(mesh.normals[i as usize]));
                out.colors.push(mesh.colors[i as usize]);
            }
            out.indices.push(*slot);
        }
    }
    Ok(out)
}

use snerf_files::write_atomic;
