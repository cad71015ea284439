//! Loading glTF / GLB files into a `Rig` (meshes, materials with base-colour textures, node
//! hierarchy, skins, morph targets, first animation), with validation that turns bad input
//! into clear errors naming the file and the part at fault.

use crate::animation::{
    Channel, Instance, Interp, NodeRest, Path as AnimPath, PrimData, Rig, Skin,
};
use glam::{vec3, Mat4, Vec3};
use crate::mesh::{Background, Look, Material};
use crate::procedural::{Built, Content};
use crate::texture::{Texture, Wrap};
use crate::SceneKind;
use anyhow::{anyhow, bail, Result};
use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

/// Width, height and 8-bit sRGB RGBA texels of a decoded image.
type DecodedImage = (usize, usize, Vec<[u8; 4]>);

/// Load `path` and build a renderable scene, normalized to the unit sphere.
pub fn load(path: &Path) -> Result<Built> {
    let p = path.to_path_buf();
    match std::panic::catch_unwind(move || load_inner(&p)) {
        Ok(r) => r,
        Err(e) => {
            let msg = e
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "unknown".into());
            bail!(
                "{}: malformed glTF data (the reader failed: {msg})",
                path.display()
            )
        }
    }
}

fn wrap_mode(m: gltf::texture::WrappingMode) -> Wrap {
    match m {
        gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    }
}

/// Decoded glTF image -> 8-bit sRGB RGBA texels.
fn to_rgba8(img: &gltf::image::Data) -> Option<Vec<[u8; 4]>> {
    use gltf::image::Format::*;
    let px = &img.pixels;
    let n = (img.width * img.height) as usize;
    let u16at = |i: usize| (u16::from_le_bytes([px[2 * i], px[2 * i + 1]]) >> 8) as u8;
    let f32at = |i: usize| {
        let v = f32::from_le_bytes([px[4 * i], px[4 * i + 1], px[4 * i + 2], px[4 * i + 3]]);
        (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
    };
    let (ch, get): (usize, Box<dyn Fn(usize) -> u8>) = match img.format {
        R8 => (1, Box::new(|i| px[i])),
        R8G8 => (2, Box::new(|i| px[i])),
        R8G8B8 => (3, Box::new(|i| px[i])),
        R8G8B8A8 => (4, Box::new(|i| px[i])),
        R16 => (1, Box::new(u16at)),
        R16G16 => (2, Box::new(u16at)),
        R16G16B16 => (3, Box::new(u16at)),
        R16G16B16A16 => (4, Box::new(u16at)),
        R32G32B32FLOAT => (3, Box::new(f32at)),
        R32G32B32A32FLOAT => (4, Box::new(f32at)),
    };
    let bytes_per = match img.format {
        R8 | R8G8 | R8G8B8 | R8G8B8A8 => 1,
        R16 | R16G16 | R16G16B16 | R16G16B16A16 => 2,
        _ => 4,
    };
    if px.len() < n * ch * bytes_per {
        return None;
    }
    Some(
        (0..n)
            .map(|i| {
                let b = i * ch;
                match ch {
                    1 => [get(b), get(b), get(b), 255],
                    2 => [get(b), get(b), get(b), get(b + 1)],
                    3 => [get(b), get(b + 1), get(b + 2), 255],
                    _ => [get(b), get(b + 1), get(b + 2), get(b + 3)],
                }
            })
            .collect(),
    )
}

fn check_finite(v: &[Vec3], what: &str, file: &str, mesh: &str, prim: usize) -> Result<()> {
    if let Some((i, p)) = v.iter().enumerate().find(|(_, p)| !p.is_finite()) {
        bail!(
            "{file}: mesh {mesh}, primitive {prim}: {what} has a non-finite value at vertex {i} ({:?}, {:?}, {:?}); \
             the model cannot be rendered",
            p.x,
            p.y,
            p.z
        );
    }
    Ok(())
}

fn load_inner(path: &Path) -> Result<Built> {
    let mut validation_note: Option<String> = None;
    let r = load_checked(path, &mut validation_note);
    match (r, validation_note) {
        (Err(e), Some(v)) => Err(anyhow!("{e:#} (the file also fails glTF validation: {v})")),
        (r, _) => r,
    }
}

fn load_checked(path: &Path, validation_note: &mut Option<String>) -> Result<Built> {
    let file = path.display().to_string();
    if !path.exists() {
        bail!("{file}: no such file");
    }
    let bytes = std::fs::read(path).map_err(|e| anyhow!("{file}: cannot read: {e}"))?;
    let mut warnings = Vec::new();
    let gltf::Gltf {
        document: doc,
        blob,
    } = match gltf::Gltf::from_slice(&bytes) {
        Ok(g) => g,
        Err(gltf::Error::Validation(errs)) => {
            // Strict validation failed. Many real files fail it in harmless ways (e.g. missing
            // accessor bounds), so load without it; the checks below (and the panic guard in
            // `load`) still catch data that cannot be rendered, with a specific message.
            let msg: Vec<String> = errs
                .iter()
                .map(|(p, e)| format!("{}: {e}", p.as_str()))
                .collect();
            let g = gltf::Gltf::from_slice_without_validation(&bytes)
                .map_err(|e| anyhow!("{file}: not a valid glTF/GLB file: {e}"))?;
            warnings.push(format!(
                "{file} fails glTF validation ({}); rendered anyway",
                msg.join("; ")
            ));
            *validation_note = Some(msg.join("; "));
            g
        }
        Err(e) => bail!("{file}: not a valid glTF/GLB file: {e}"),
    };
    let base = path.parent().unwrap_or(Path::new("."));
    let buffers = gltf::import_buffers(&doc, Some(base), blob).map_err(|e| {
        let uris: Vec<String> = doc
            .buffers()
            .filter_map(|b| match b.source() {
                gltf::buffer::Source::Uri(u) if !u.starts_with("data:") => {
                    Some(base.join(u).display().to_string())
                }
                _ => None,
            })
            .collect();
        anyhow!("{file}: cannot load buffer data ({e}); external buffers: {uris:?}")
    })?;
    let get = |b: gltf::Buffer| buffers.get(b.index()).map(|d| &d.0[..]);

    let mut look = Look::new(Background::Transparent);

    // Textures, keyed by (image, sampler wrap modes).
    let mut image_cache: HashMap<usize, Option<DecodedImage>> = HashMap::new();
    let mut tex_cache: HashMap<(usize, Wrap, Wrap), usize> = HashMap::new();
    // Materials: glTF material i -> look material i; default material last.
    let mut mat_texcoord = Vec::new();
    for m in doc.materials() {
        let pbr = m.pbr_metallic_roughness();
        let f = pbr.base_color_factor();
        let mut mat = Material {
            base_color: f,
            texture: None,
            unlit: false,
        };
        let mut set = 0;
        if let Some(info) = pbr.base_color_texture() {
            let tex = info.texture();
            let img = tex.source();
            let entry = image_cache.entry(img.index()).or_insert_with(|| {
                match gltf::image::Data::from_source(img.source(), Some(base), &buffers) {
                    Ok(d) => match to_rgba8(&d) {
                        Some(px) if d.width > 0 && d.height > 0 => Some((d.width as usize, d.height as usize, px)),
                        _ => {
                            warnings.push(format!("image {}: unsupported pixel data; using base colour", img.index()));
                            None
                        }
                    },
                    Err(e) => {
                        warnings.push(format!(
                            "image {} ({}): cannot decode ({e}); material '{}' uses its base colour factor",
                            img.index(),
                            img.name().unwrap_or("unnamed"),
                            m.name().unwrap_or("unnamed")
                        ));
                        None
                    }
                }
            });
            if let Some((w, h, px)) = entry.clone() {
                let s = tex.sampler();
                let key = (img.index(), wrap_mode(s.wrap_s()), wrap_mode(s.wrap_t()));
                let ti = *tex_cache.entry(key).or_insert_with(|| {
                    look.add_texture(Texture::from_srgba8(w, h, px, key.1, key.2))
                });
                mat.texture = Some(ti);
                set = info.tex_coord();
            }
        }
        look.add_material(mat);
        mat_texcoord.push(set);
    }
    let default_mat = look.add_material(Material {
        base_color: [0.8, 0.8, 0.8, 1.0],
        texture: None,
        unlit: false,
    });

    // Nodes.
    let nodes: Vec<gltf::Node> = doc.nodes().collect();
    let mut parent = vec![None; nodes.len()];
    for n in &nodes {
        for c in n.children() {
            if parent[c.index()].is_some() || c.index() == n.index() {
                bail!(
                    "{file}: node {} has more than one parent (the node graph is not a tree)",
                    c.index()
                );
            }
            parent[c.index()] = Some(n.index());
        }
    }
    let rest: Vec<NodeRest> = nodes
        .iter()
        .map(|n| {
            let (matrix, (t, r, s)) = match n.transform() {
                gltf::scene::Transform::Matrix { matrix } => (
                    Some(Mat4::from_cols_array_2d(&matrix)),
                    ([0.0; 3], [0.0, 0.0, 0.0, 1.0], [1.0; 3]),
                ),
                gltf::scene::Transform::Decomposed {
                    translation,
                    rotation,
                    scale,
                } => (None, (translation, rotation, scale)),
            };
            NodeRest {
                t,
                r,
                s,
                matrix,
                weights: n.weights().map(|w| w.to_vec()),
            }
        })
        .collect();
    for (i, r) in rest.iter().enumerate() {
        let vals =
            r.t.iter()
                .chain(r.r.iter())
                .chain(r.s.iter())
                .chain(r.matrix.iter().flat_map(|m| m.as_ref().iter()));
        if vals.clone().any(|x| !x.is_finite()) {
            bail!(
                "{file}: node {i} ({}) has a non-finite transform",
                nodes[i].name().unwrap_or("unnamed")
            );
        }
    }

    // Scene roots -> order (parents first), with cycle protection.
    let nscenes = doc.scenes().count();
    let default_scene = match doc.as_json().scene {
        Some(i) if i.value() >= nscenes => {
            bail!(
                "{file}: the default scene is #{} but the file has {nscenes} scene(s)",
                i.value()
            )
        }
        Some(i) => doc.scenes().nth(i.value()),
        None => doc.scenes().next(),
    };
    let roots: Vec<usize> = match default_scene {
        Some(s) => s.nodes().map(|n| n.index()).collect(),
        None => (0..nodes.len()).filter(|&i| parent[i].is_none()).collect(),
    };
    let mut order = Vec::new();
    let mut seen = vec![false; nodes.len()];
    let mut stack: Vec<usize> = roots.iter().rev().copied().collect();
    while let Some(n) = stack.pop() {
        if seen[n] {
            bail!("{file}: node {n} is reached twice from the scene (a cycle or shared subtree in the hierarchy)");
        }
        seen[n] = true;
        order.push(n);
        for c in nodes[n].children() {
            stack.push(c.index());
        }
    }
    // Roots listed in the scene are roots even if some other node claims them.
    for &r in &roots {
        parent[r] = None;
    }

    // Primitives of meshes used by scene nodes.
    let mut mesh_cache: HashMap<usize, Vec<Arc<PrimData>>> = HashMap::new();
    let mut instances = Vec::new();
    let mut skipped_modes = 0usize;
    for &n in &order {
        let node = &nodes[n];
        let Some(mesh) = node.mesh() else { continue };
        let mesh_name = format!("'{}' (#{})", mesh.name().unwrap_or("unnamed"), mesh.index());
        #[allow(clippy::map_entry)]
        if !mesh_cache.contains_key(&mesh.index()) {
            let mut prims = Vec::new();
            for (pi, prim) in mesh.primitives().enumerate() {
                use gltf::mesh::Mode;
                let mode = prim.mode();
                if !matches!(
                    mode,
                    Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
                ) {
                    skipped_modes += 1;
                    continue;
                }
                let reader = prim.reader(get);
                let positions: Vec<Vec3> = reader
                    .read_positions()
                    .ok_or_else(|| {
                        anyhow!("{file}: mesh {mesh_name}, primitive {pi}: no POSITION attribute")
                    })?
                    .map(Vec3::from_array)
                    .collect();
                check_finite(&positions, "POSITION", &file, &mesh_name, pi)?;
                let nv = positions.len();
                let normals: Option<Vec<Vec3>> = reader
                    .read_normals()
                    .map(|it| it.map(Vec3::from_array).collect());
                let normals = normals.filter(|n| n.len() == nv && n.iter().all(|v| v.is_finite()));
                let mat_index = prim.material().index();
                let set = mat_index.map(|i| mat_texcoord[i]).unwrap_or(0);
                let uvs: Vec<[f32; 2]> = reader
                    .read_tex_coords(set)
                    .map(|it| it.into_f32().collect())
                    .filter(|u: &Vec<[f32; 2]>| u.len() == nv)
                    .unwrap_or_else(|| vec![[0.0, 0.0]; nv]);
                let colors: Option<Vec<[f32; 4]>> = reader
                    .read_colors(0)
                    .map(|c| c.into_rgba_f32().collect())
                    .filter(|c: &Vec<[f32; 4]>| c.len() == nv);
                let idx: Vec<u32> = match reader.read_indices() {
                    Some(i) => i.into_u32().collect(),
                    None => (0..nv as u32).collect(),
                };
                if let Some((k, bad)) = idx.iter().enumerate().find(|(_, &i)| i as usize >= nv) {
                    bail!(
                        "{file}: mesh {mesh_name}, primitive {pi}: index {bad} (at position {k}) is out of range \
                         for {nv} vertices"
                    );
                }
                let mut tris = Vec::new();
                match mode {
                    Mode::Triangles => tris.extend(idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]])),
                    Mode::TriangleStrip => {
                        for k in 0..idx.len().saturating_sub(2) {
                            if k % 2 == 0 {
                                tris.push([idx[k], idx[k + 1], idx[k + 2]]);
                            } else {
                                tris.push([idx[k + 1], idx[k], idx[k + 2]]);
                            }
                        }
                    }
                    _ => {
                        for k in 1..idx.len().saturating_sub(1) {
                            tris.push([idx[0], idx[k], idx[k + 1]]);
                        }
                    }
                }
                let joints: Option<Vec<[u16; 4]>> = reader
                    .read_joints(0)
                    .map(|j| j.into_u16().collect())
                    .filter(|j: &Vec<[u16; 4]>| j.len() == nv);
                let weights: Option<Vec<[f32; 4]>> = reader
                    .read_weights(0)
                    .map(|w| w.into_f32().collect())
                    .filter(|w: &Vec<[f32; 4]>| w.len() == nv);
                let mut targets = Vec::new();
                for (ti, (dp, dn, _)) in reader.read_morph_targets().enumerate() {
                    let dp: Vec<Vec3> = dp
                        .map(|it| it.map(Vec3::from_array).collect())
                        .unwrap_or_else(|| vec![Vec3::default(); nv]);
                    if dp.len() != nv {
                        bail!("{file}: mesh {mesh_name}, primitive {pi}: morph target {ti} has {} positions, expected {nv}", dp.len());
                    }
                    check_finite(
                        &dp,
                        &format!("morph target {ti} POSITION"),
                        &file,
                        &mesh_name,
                        pi,
                    )?;
                    let dn: Option<Vec<Vec3>> = dn
                        .map(|it| it.map(Vec3::from_array).collect())
                        .filter(|d: &Vec<Vec3>| d.len() == nv);
                    targets.push((dp, dn));
                }
                prims.push(Arc::new(PrimData {
                    positions,
                    normals,
                    uvs,
                    colors,
                    tris,
                    joints,
                    weights,
                    targets,
                    material: mat_index.map(|i| i as u32).unwrap_or(default_mat),
                }));
            }
            mesh_cache.insert(mesh.index(), prims);
        }
        let mesh_weights = mesh.weights().map(|w| w.to_vec()).unwrap_or_default();
        for prim in &mesh_cache[&mesh.index()] {
            instances.push(Instance {
                node: n,
                skin: node.skin().map(|s| s.index()),
                mesh_weights: mesh_weights.clone(),
                prim: prim.clone(),
            });
        }
    }
    if skipped_modes > 0 {
        warnings.push(format!(
            "{skipped_modes} point/line primitive(s) skipped (only triangles are rendered)"
        ));
    }
    let ntris: usize = instances.iter().map(|i| i.prim.tris.len()).sum();
    if ntris == 0 {
        bail!(
            "{file}: nothing to render: the scene has no triangles ({} nodes in the scene, {} meshes in the file{})",
            order.len(),
            doc.meshes().count(),
            if skipped_modes > 0 { "; point/line primitives are not rendered" } else { "" }
        );
    }

    // Skins.
    let mut skins = Vec::new();
    for s in doc.skins() {
        let joints: Vec<usize> = s.joints().map(|j| j.index()).collect();
        let ibm: Vec<Mat4> = match s.reader(get).read_inverse_bind_matrices() {
            Some(it) => it.map(|c| Mat4::from_cols_array_2d(&c)).collect(),
            None => vec![Mat4::IDENTITY; joints.len()],
        };
        for &j in &joints {
            if !seen[j] {
                // A joint outside the default scene: still needs a world matrix; add it.
                warnings.push(format!(
                    "skin {}: joint node {j} is not in the default scene",
                    s.index()
                ));
            }
        }
        skins.push(Skin {
            joints,
            inverse_bind: ibm,
        });
    }
    // Joints outside the scene tree are posed from their own ancestors.
    for j in 0..nodes.len() {
        if !seen[j] && skins.iter().any(|s| s.joints.contains(&j)) {
            let mut chain = vec![j];
            let mut p = parent[j];
            let mut guard = 0;
            while let Some(q) = p {
                if seen[q] || guard > nodes.len() {
                    break;
                }
                chain.push(q);
                p = parent[q];
                guard += 1;
            }
            for &c in chain.iter().rev() {
                if !seen[c] {
                    seen[c] = true;
                    order.push(c);
                }
            }
        }
    }

    // First animation.
    let mut channels = Vec::new();
    let mut anim_name = None;
    if let Some(anim) = doc.animations().next() {
        anim_name = Some(anim.name().unwrap_or("unnamed").to_string());
        for ch in anim.channels() {
            let r = ch.reader(get);
            let inputs: Vec<f32> = match r.read_inputs() {
                Some(i) => i.collect(),
                None => continue,
            };
            use gltf::animation::util::ReadOutputs;
            let (path, outputs): (AnimPath, Vec<f32>) = match r.read_outputs() {
                Some(ReadOutputs::Translations(it)) => {
                    (AnimPath::Translation, it.flatten().collect())
                }
                Some(ReadOutputs::Rotations(it)) => {
                    (AnimPath::Rotation, it.into_f32().flatten().collect())
                }
                Some(ReadOutputs::Scales(it)) => (AnimPath::Scale, it.flatten().collect()),
                Some(ReadOutputs::MorphTargetWeights(it)) => {
                    (AnimPath::Weights, it.into_f32().collect())
                }
                None => continue,
            };
            let interp = match ch.sampler().interpolation() {
                gltf::animation::Interpolation::Linear => Interp::Linear,
                gltf::animation::Interpolation::Step => Interp::Step,
                gltf::animation::Interpolation::CubicSpline => Interp::CubicSpline,
            };
            let per_key = if interp == Interp::CubicSpline { 3 } else { 1 };
            let stride = match path {
                AnimPath::Translation | AnimPath::Scale => 3,
                AnimPath::Rotation => 4,
                AnimPath::Weights => {
                    if inputs.is_empty() {
                        0
                    } else {
                        outputs.len() / (inputs.len() * per_key)
                    }
                }
            };
            if inputs.is_empty() || stride == 0 || outputs.len() < inputs.len() * per_key * stride {
                warnings.push(format!(
                    "animation channel for node {} has inconsistent keyframes; ignored",
                    ch.target().node().index()
                ));
                continue;
            }
            if inputs.iter().chain(outputs.iter()).any(|x| !x.is_finite()) {
                bail!(
                    "{file}: animation '{}' has non-finite keyframe data",
                    anim_name.as_deref().unwrap_or("")
                );
            }
            channels.push(Channel {
                node: ch.target().node().index(),
                path,
                interp,
                inputs,
                outputs,
                stride,
            });
        }
    }
    let start = channels
        .iter()
        .filter_map(|c| c.inputs.first().copied())
        .fold(f32::INFINITY, f32::min);
    let end = channels
        .iter()
        .filter_map(|c| c.inputs.last().copied())
        .fold(f32::NEG_INFINITY, f32::max);
    let (start, end) = if channels.is_empty() || end <= start {
        (0.0, 0.0)
    } else {
        (start, end)
    };

    let mut rig = Rig {
        rest,
        parent,
        order,
        instances,
        skins,
        channels,
        start,
        end,
        normalize: Mat4::IDENTITY,
    };

    // Normalize over the whole animation: centre the bounds and scale into the unit sphere.
    let samples: Vec<f32> = if rig.animated() {
        (0..=16).map(|i| i as f32 / 16.0).collect()
    } else {
        vec![0.0]
    };
    let geoms: Vec<_> = samples.iter().map(|&t| rig.geometry_raw(t)).collect();
    let mut lo = vec3(f32::INFINITY, f32::INFINITY, f32::INFINITY);
    let mut hi = -lo;
    for g in &geoms {
        if let Some((a, b)) = g.bounds() {
            lo = lo.min(a);
            hi = hi.max(b);
        }
    }
    if !(lo.is_finite() && hi.is_finite()) {
        bail!("{file}: the posed model has non-finite vertex positions (check node transforms, skins and animation)");
    }
    let centre = (lo + hi) * 0.5;
    let radius = geoms
        .iter()
        .flat_map(|g| {
            g.tris
                .iter()
                .flatten()
                .map(move |&i| (g.positions[i as usize] - centre).length())
        })
        .fold(0.0f32, f32::max);
    if radius.is_nan() || radius <= 1e-12 {
        bail!("{file}: the model has zero size");
    }
    let scale = 1.0 / radius;
    rig.normalize = Mat4::from_scale(vec3(scale, scale, scale)) * Mat4::from_translation(-centre);

    let dynamic = rig.animated();
    let mut info = serde_json::Map::new();
    info.insert("file".into(), file.clone().into());
    info.insert("normalize_scale".into(), (scale as f64).into());
    info.insert("normalize_centre".into(), serde_json::json!(centre.to_array()));
    info.insert("triangles".into(), ntris.into());
    info.insert("textures".into(), look.textures.len().into());
    if let Some(a) = &anim_name {
        info.insert("animation".into(), a.clone().into());
        info.insert("animation_seconds".into(), ((end - start) as f64).into());
    }
    let content = if dynamic {
        let rig = Arc::new(rig);
        Content::Dynamic(Box::new(move |t| Ok(rig.geometry(t))))
    } else {
        Content::Static(rig.geometry(0.0))
    };
    Ok(Built {
        look,
        content,
        kind: SceneKind::Object,
        aabb: [vec3(-1.05, -1.05, -1.05), vec3(1.05, 1.05, 1.05)],
        fov_x: 40f32.to_radians(),
        info,
        warnings,
    })
}
