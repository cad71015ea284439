//! Constants every marcher shares (trainer, CPU reference, GPU shader, block planner), and
//! the WGSL prelude generated from them so the shader never holds a copy.

use crate::ndc::NDC_MIN_DZ;
use crate::vec::Vec3;

/// Optical depth per sample is clamped here: exp(-1e4) is exactly 0 in f32 (an opaque sample
/// hides everything behind it, to the last bit, in every marcher), and the clamp keeps σ·δ
/// finite when both are huge (1e10 · 1e30 overflows f32). Its gradient is 0 above the clamp,
/// where opacity's own derivative exp(-σδ) is already 0.
pub const MAX_OPTICAL_DEPTH: f32 = 1.0e4;
/// Unbounded rays start this far from the camera (model units)…
pub const UNBOUNDED_NEAR: f32 = 0.02;
/// …and end here: the contraction is within 1e-3 of its limit.
pub const UNBOUNDED_FAR: f32 = 1.0e3;
/// Loop guard for a marcher: a valid asset bounds samples per ray far below this.
pub const MAX_ITERS: u32 = 1 << 20;

/// Slab test against the cube [-h,h]³: (t_enter, t_exit) with t_exit > max(t_enter, 0).
pub fn box_hit(o: Vec3, d: Vec3, h: f32) -> Option<(f32, f32)> {
    let mut t0 = f32::NEG_INFINITY;
    let mut t1 = f32::INFINITY;
    for i in 0..3 {
        let inv = 1.0 / d[i];
        let (a, b) = ((-h - o[i]) * inv, (h - o[i]) * inv);
        let (a, b) = if a < b { (a, b) } else { (b, a) };
        if a.is_nan() || b.is_nan() {
            // d[i] == 0: inside the slab for all t, or never
            if !(o[i].abs() <= h) {
                return None;
            }
            continue;
        }
        t0 = t0.max(a);
        t1 = t1.min(b);
    }
    if t1 > t0.max(0.0) {
        Some((t0, t1))
    } else {
        None
    }
}

/// The march (`shaders/march.wgsl`), its two atlas access snippets and its two targets.
pub const MARCH_WGSL: &str = include_str!("../../../shaders/march.wgsl");
pub const MARCH_COMPUTE_WGSL: &str = include_str!("../../../shaders/march_compute.wgsl");
pub const MARCH_FRAGMENT_WGSL: &str = include_str!("../../../shaders/march_fragment.wgsl");
pub const ATLAS_LOAD_WGSL: &str = include_str!("../../../shaders/atlas_load.wgsl");
pub const ATLAS_FILTER_WGSL: &str = include_str!("../../../shaders/atlas_filter.wgsl");
/// The presentation pass (march output buffer -> screen), shared by the native window and
/// the web page.
pub const PRESENT_WGSL: &str = include_str!("../../../shaders/present.wgsl");
/// Workgroup edge of the march shader (WORKGROUP x WORKGROUP pixels per workgroup).
pub const WORKGROUP: u32 = 8;

/// Which march shader a scene needs. Only that variant is compiled, so a scene pays for
/// nothing it does not have (no keyframe blend in a static scene, no view MLP in a diffuse
/// one).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ShaderVariant {
    /// The scene kind's shader index: 0 object, 1 forward (NDC), 2 unbounded.
    pub kind: u32,
    /// Two keyframes blended (4D assets).
    pub dynamic: bool,
    /// A diffuse asset (FORMAT.md, version 2): its view MLP and features are zero, so the
    /// shader neither composites features nor runs the MLP, and the atlas holds 4 bytes a
    /// voxel (density code and RGB) instead of 8.
    pub diffuse: bool,
    /// Voxels per block edge (without the apron).
    pub block: u32,
    /// `atlas_filter.wgsl` (hardware trilinear) instead of `atlas_load.wgsl`.
    pub hardware_filter: bool,
}

/// What runs the march: the same march body with the resources and entry points of one
/// target (`shaders/march_compute.wgsl` or `shaders/march_fragment.wgsl`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    /// A compute shader, entry point `main` (storage buffers): the native viewer and the web
    /// page on WebGPU.
    Compute,
    /// A full-screen triangle (`vs`) and a fragment shader (`fs`) writing RGBA and depth to
    /// two render targets, the grid in a texture: the web page on WebGL2, translated to GLSL
    /// ES 3.00 by `snerf-stream` (`glsl.rs`).
    Fragment,
}

/// The march compute shader of one variant, composed exactly once for every client: the
/// native viewer builds its pipeline from it and `snerf serve` hands the same text to the web
/// page.
pub fn march_shader(v: ShaderVariant) -> String {
    march_shader_for(v, Target::Compute)
}

/// The march shader of one variant for one target. Every variant of every target is composed
/// here, from the same march body: only the resource access and the entry points differ.
pub fn march_shader_for(v: ShaderVariant, target: Target) -> String {
    format!(
        "const KIND: u32 = {}u;\nconst DYNAMIC: bool = {};\nconst DIFFUSE: bool = {};\nconst BLOCK: u32 = {}u;\nconst WG: u32 = {}u;\n{}{}\n{}\n{}",
        v.kind,
        v.dynamic,
        v.diffuse,
        v.block,
        WORKGROUP,
        wgsl_prelude(),
        MARCH_WGSL,
        if v.hardware_filter { ATLAS_FILTER_WGSL } else { ATLAS_LOAD_WGSL },
        match target {
            Target::Compute => MARCH_COMPUTE_WGSL,
            Target::Fragment => MARCH_FRAGMENT_WGSL,
        }
    )
}

/// WGSL declarations of the shared constants, prepended to `shaders/march.wgsl`.
pub fn wgsl_prelude() -> String {
    format!(
        "const MAX_OPTICAL_DEPTH: f32 = {:?};\nconst UNBOUNDED_NEAR: f32 = {:?};\nconst UNBOUNDED_FAR: f32 = {:?};\nconst NDC_MIN_DZ: f32 = {:e};\nconst MAX_ITERS: u32 = {}u;\nconst COVER_EMPTY: f32 = {:?};\nconst COVER_FULL: f32 = {:?};\n",
        MAX_OPTICAL_DEPTH,
        UNBOUNDED_NEAR,
        UNBOUNDED_FAR,
        NDC_MIN_DZ,
        MAX_ITERS,
        // the silhouette test's bounds, computed here so the shader compares against the very
        // f32 values `silhouette::mixed_coverage` does
        crate::silhouette::COVER_EPS,
        1.0 - crate::silhouette::COVER_EPS
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prelude_is_valid_wgsl_literals() {
        let p = wgsl_prelude();
        assert!(p.contains("const MAX_OPTICAL_DEPTH: f32 = 10000.0;"), "{p}");
        assert!(p.contains("const NDC_MIN_DZ: f32 = 1e-6;"), "{p}");
        assert!(p.contains("const MAX_ITERS: u32 = 1048576u;"), "{p}");
        assert!(p.contains("const COVER_EMPTY: f32 = 0.003921569;") && p.contains("const COVER_FULL: f32 = 0.99607843;"), "{p}");
    }

    #[test]
    fn box_hit_cases() {
        assert_eq!(box_hit([0.0, 0.0, 3.0], [0.0, 0.0, -1.0], 1.0), Some((2.0, 4.0)));
        assert_eq!(box_hit([0.0, 2.0, 3.0], [0.0, 0.0, -1.0], 1.0), None);
        assert_eq!(box_hit([0.0, 0.0, 3.0], [0.0, 0.0, 1.0], 1.0), None);
    }
}
