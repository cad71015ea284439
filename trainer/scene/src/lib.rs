//! snerf-scene: the dataset generator behind `snerf scene`. It builds a scene (one of the
//! built-in procedural scenes — `object`, `room`, `outdoor`, `avatar` — or any glTF/GLB file,
//! animated ones as 4D sequences), picks train/test cameras (and times for dynamic scenes),
//! renders every view with one CPU rasterizer (supersampled, textured, Lambert-lit) and writes
//! a nerf_synthetic-style dataset: `transforms_{train,val,test}.json` + `train/`, `test/` PNGs.
//!
//! Data flow: `Source` -> `build_scene` (procedural/*, gltf_load + animation) -> `Built`
//! (geometry + look) -> `camera` poses -> `raster::render` per view -> `writer` (atomic).

mod animation;
mod camera;
mod gltf_load;
mod math;
mod mesh;
mod procedural;
mod raster;
mod texture;
mod writer;

#[cfg(test)]
mod tests;

use anyhow::{bail, Result};
use std::path::{Path, PathBuf};

/// Where the scene comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Source {
    Object,
    Room,
    Outdoor,
    Avatar,
    Gltf(PathBuf),
}

pub const SOURCE_NAMES: &str = "object, room, outdoor, avatar, gltf:<file.gltf|file.glb>";

impl Source {
    /// Parse a scene name: `object`, `room`, `outdoor`, `avatar` or `gltf:<file>`.
    pub fn parse(s: &str) -> Result<Source> {
        let t = s.trim();
        Ok(match t {
            "object" => Source::Object,
            "room" => Source::Room,
            "outdoor" => Source::Outdoor,
            "avatar" => Source::Avatar,
            _ => {
                if let Some(f) = t.strip_prefix("gltf:") {
                    if f.is_empty() {
                        bail!("scene 'gltf:' needs a file name, e.g. gltf:model.glb (valid scenes: {SOURCE_NAMES})");
                    }
                    Source::Gltf(PathBuf::from(f))
                } else if t.ends_with(".gltf") || t.ends_with(".glb") {
                    bail!("unknown scene '{t}'; to render a glTF file write gltf:{t} (valid scenes: {SOURCE_NAMES})")
                } else {
                    bail!("unknown scene '{t}' (valid scenes: {SOURCE_NAMES})")
                }
            }
        })
    }

    pub fn name(&self) -> String {
        match self {
            Source::Object => "object".into(),
            Source::Room => "room".into(),
            Source::Outdoor => "outdoor".into(),
            Source::Avatar => "avatar".into(),
            Source::Gltf(p) => format!("gltf:{}", p.display()),
        }
    }
}

/// How cameras are placed around object-like scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CameraPath {
    /// Train views spread over the sphere (mostly the upper hemisphere); test views on a
    /// smooth orbit (a novel path, good for consistency metrics).
    Sphere,
    /// Train and test views interleaved on one orbit at a fixed elevation.
    Orbit,
}

/// The scene kind written to `scene_kind` in the transforms files.
pub use snerf_geometry::SceneKind;

#[derive(Clone, Debug)]
pub struct SceneSpec {
    pub source: Source,
    pub train_views: usize,
    pub test_views: usize,
    pub width: u32,
    pub height: u32,
    pub seed: u64,
    /// Samples per pixel along each axis (4 -> 4x4).
    pub supersample: u32,
    pub path: CameraPath,
}

impl SceneSpec {
    /// Sensible defaults for each source.
    pub fn default_for(source: Source) -> SceneSpec {
        let (train_views, test_views, width, height) = match source {
            Source::Object => (100, 20, 200, 200),
            Source::Room => (40, 8, 252, 189),
            Source::Outdoor => (100, 20, 256, 192),
            Source::Avatar => (100, 20, 200, 200),
            Source::Gltf(_) => (100, 20, 200, 200),
        };
        SceneSpec {
            source,
            train_views,
            test_views,
            width,
            height,
            seed: 0,
            supersample: 4,
            path: CameraPath::Sphere,
        }
    }
}

/// Build the scene for `source` (geometry, materials, kind, bounds).
pub(crate) fn build_scene(source: &Source, seed: u64) -> Result<procedural::Built> {
    Ok(match source {
        Source::Object => procedural::object::build(),
        Source::Room => procedural::room::build(),
        Source::Outdoor => procedural::outdoor::build(seed),
        Source::Avatar => procedural::avatar::build(),
        Source::Gltf(p) => gltf_load::load(p)?,
    })
}

/// Render the dataset described by `spec` into `out_dir` (nerf_synthetic layout) and return a
/// JSON summary (scene, kind, counts, size, seconds, out dir, warnings...). `progress(done,
/// total)` is called on the calling thread as views finish. The dataset is written to a
/// temporary sibling directory and moved into place only on success; an existing `out_dir`
/// is replaced only if it is empty or a previous snerf dataset.
pub fn write_dataset(
    spec: &SceneSpec,
    out_dir: &Path,
    progress: &dyn Fn(usize, usize),
) -> Result<serde_json::Value> {
    writer::write(spec, out_dir, progress)
}
