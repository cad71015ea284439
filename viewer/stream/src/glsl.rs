//! The web page's WebGL2 march: the fragment target of the march shader
//! (`snerf_geometry::march::march_shader_for(variant, Target::Fragment)`, the same
//! `shaders/march.wgsl` body the compute shader runs) translated to GLSL ES 3.00 by naga, so
//! there is no second copy of the march to keep in step. `snerf serve` hands it to the page
//! as `GET /march.glsl` (JSON, see `GlProgram::to_json`).
//!
//! The vertex shader (a full-screen triangle) is translated from the same module (`vs` in
//! `shaders/march_fragment.wgsl`) rather than written out in GLSL: both stages then come from
//! one validated module, and naga's own conventions (entry points renamed `main`, its y flip
//! of `gl_Position`) hold for both.
//!
//! GLSL ES 3.00 has no `layout(binding = …)`: the page binds uniform blocks and samplers by
//! name. naga chooses those names; they come from its reflection, keyed by WGSL binding.

use anyhow::{anyhow, Result};
use naga::back::glsl;
use naga::valid::{Capabilities, ValidationFlags, Validator};
use snerf_geometry::march::{march_shader_for, ShaderVariant, Target};
use std::collections::BTreeMap;

/// The WebGL2 program of one march variant.
#[derive(Clone, Debug)]
pub struct GlProgram {
    /// GLSL ES 3.00 vertex shader (a full-screen triangle, 3 vertices, no attributes).
    pub vertex: String,
    /// GLSL ES 3.00 fragment shader: the march; location 0 RGBA (opacity in A), location 1
    /// depth.
    pub fragment: String,
    /// WGSL binding -> GLSL uniform block name (0: the params, 2: the view MLP).
    pub uniforms: BTreeMap<u32, String>,
    /// WGSL binding -> GLSL sampler uniform name (1: the grid, 3 and 4: the first pass's RGBA
    /// and depth, 5: the atlas).
    pub textures: BTreeMap<u32, String>,
}

impl GlProgram {
    /// `{"vertex": …, "fragment": …, "uniforms": {"0": NAME, …}, "textures": {"1": NAME, …}}`:
    /// what the page fetches.
    pub fn to_json(&self) -> String {
        serde_json::json!({
            "vertex": self.vertex,
            "fragment": self.fragment,
            "uniforms": self.uniforms,
            "textures": self.textures,
        })
        .to_string()
    }
}

/// Parse and validate one WGSL module; translate one of its entry points.
fn translate(
    module: &naga::Module,
    info: &naga::valid::ModuleInfo,
    stage: naga::ShaderStage,
    entry: &str,
) -> Result<(String, glsl::ReflectionInfo)> {
    let options = glsl::Options {
        version: glsl::Version::Embedded { version: 300, is_webgl: true },
        ..glsl::Options::default()
    };
    let pipeline = glsl::PipelineOptions { shader_stage: stage, entry_point: entry.to_string(), multiview: None };
    let mut out = String::new();
    // Unchecked: every index the march computes is in range by construction, as in the
    // compute shader (which WebGPU runs with robust buffer access besides).
    let mut w = glsl::Writer::new(&mut out, module, info, &options, &pipeline, naga::proc::BoundsCheckPolicies::default())
        .map_err(|e| anyhow!("GLSL translation of {entry}: {e}"))?;
    let reflection = w.write().map_err(|e| anyhow!("GLSL translation of {entry}: {e}"))?;
    Ok((out, reflection))
}

/// The march of one variant as a WebGL2 program (GLSL ES 3.00), translated from WGSL.
pub fn march_glsl(v: ShaderVariant) -> Result<GlProgram> {
    let src = march_shader_for(v, Target::Fragment);
    let module = naga::front::wgsl::parse_str(&src).map_err(|e| anyhow!("march.wgsl (fragment): {}", e.emit_to_string(&src)))?;
    let info = Validator::new(ValidationFlags::all(), Capabilities::empty())
        .validate(&module)
        .map_err(|e| anyhow!("march.wgsl (fragment) does not validate: {}", e.emit_to_string(&src)))?;
    let (vertex, _) = translate(&module, &info, naga::ShaderStage::Vertex, "vs")?;
    let (fragment, r) = translate(&module, &info, naga::ShaderStage::Fragment, "fs")?;
    let binding = |h: naga::Handle<naga::GlobalVariable>| {
        module.global_variables[h].binding.as_ref().map(|b| b.binding).ok_or_else(|| anyhow!("a resource without a binding"))
    };
    let mut uniforms = BTreeMap::new();
    for (h, name) in &r.uniforms {
        uniforms.insert(binding(*h)?, name.clone());
    }
    let mut textures = BTreeMap::new();
    for (name, t) in &r.texture_mapping {
        textures.insert(binding(t.texture)?, name.clone());
    }
    Ok(GlProgram { vertex, fragment, uniforms, textures })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn variants() -> Vec<ShaderVariant> {
        let mut out = Vec::new();
        for kind in 0..=2 {
            for dynamic in [false, true] {
                for diffuse in [false, true] {
                    for block in [8, 16] {
                        out.push(ShaderVariant { kind, dynamic, diffuse, block, hardware_filter: false });
                    }
                }
            }
        }
        out
    }

    #[test]
    fn every_variant_translates_to_glsl_es_300_with_its_silhouette_pass() {
        for v in variants() {
            let p = march_glsl(v).unwrap_or_else(|e| panic!("{v:?}: {e:#}"));
            for s in [&p.vertex, &p.fragment] {
                assert!(s.starts_with("#version 300 es\n"), "{v:?}: {}", &s[..40.min(s.len())]);
            }
            // Every resource the page binds is there, by name: the params and MLP blocks, the
            // grid, the atlas, and the first pass's output, which the silhouette pass (a
            // runtime branch on P.frames.w in every variant) reads.
            assert_eq!(p.uniforms.keys().copied().collect::<Vec<_>>(), [0, 2], "{v:?}");
            assert_eq!(p.textures.keys().copied().collect::<Vec<_>>(), [1, 3, 4, 5], "{v:?}");
            for name in p.uniforms.values().chain(p.textures.values()) {
                assert!(p.fragment.contains(name.as_str()), "{v:?}: {name} is not in the fragment shader");
            }
            assert!(p.fragment.contains("usampler3D") && p.fragment.contains("usampler2D"), "{v:?}");
            // Two outputs (RGBA, depth) at locations 0 and 1; the vertex shader needs nothing.
            assert!(p.fragment.contains("layout(location = 0) out vec4") && p.fragment.contains("layout(location = 1) out float"), "{}", p.fragment);
            assert!(!p.vertex.contains("uniform"), "{}", p.vertex);
            // The compute variant of the same march still validates (what the native viewer and
            // WebGPU build).
            let src = snerf_geometry::march::march_shader(v);
            let m = naga::front::wgsl::parse_str(&src).unwrap_or_else(|e| panic!("{v:?}: {}", e.emit_to_string(&src)));
            Validator::new(ValidationFlags::all(), Capabilities::empty()).validate(&m).unwrap_or_else(|e| panic!("{v:?}: {}", e.emit_to_string(&src)));
        }
    }

    #[test]
    fn the_json_names_what_the_page_binds() {
        let v = ShaderVariant { kind: 0, dynamic: false, diffuse: false, block: 8, hardware_filter: false };
        let p = march_glsl(v).unwrap();
        let j: serde_json::Value = serde_json::from_str(&p.to_json()).unwrap();
        assert_eq!(j["fragment"], p.fragment.as_str());
        assert_eq!(j["vertex"], p.vertex.as_str());
        assert_eq!(j["uniforms"]["0"], p.uniforms[&0].as_str());
        assert_eq!(j["textures"]["5"], p.textures[&5].as_str());
    }
}
