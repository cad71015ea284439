//! `snerf scene`: a dataset from a built-in scene or a glTF file (the work is in snerf-scene).

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use serde_json::Value;
use snerf_files::guard::{check_output, Input};

use crate::args::{bar, parse_size};

#[derive(Args, Debug)]
pub struct SceneArgs {
    /// object | room | outdoor | avatar | gltf:<file.gltf|file.glb>
    pub name: String,
    /// Output dataset directory (replaced only if empty or a previous snerf dataset).
    #[arg(long)]
    pub out: PathBuf,
    /// Training views (default depends on the scene).
    #[arg(long, value_parser = crate::args::int_in::<usize>(1, 100000, ""))]
    pub views: Option<usize>,
    /// Held-out test views.
    #[arg(long, value_parser = crate::args::int_in::<usize>(1, 100000, ""))]
    pub test_views: Option<usize>,
    /// Image size WxH, e.g. 128x128.
    #[arg(long)]
    pub size: Option<String>,
    /// Supersampling per axis for anti-aliasing (4 = 16 samples per pixel).
    #[arg(long, value_parser = crate::args::int_in::<u32>(1, 16, ""))]
    pub supersample: Option<u32>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Cameras: sphere (train spread over a sphere, test on an orbit) or orbit.
    #[arg(long, default_value = "sphere")]
    pub path: String,
}

pub fn scene(a: &SceneArgs) -> Result<Value> {
    let source = snerf_scene::Source::parse(&a.name)?;
    if let snerf_scene::Source::Gltf(f) = &source {
        check_output("--out", &a.out, &[Input::Tree(f)])?;
    }
    let mut spec = snerf_scene::SceneSpec::default_for(source);
    if let Some(v) = a.views {
        spec.train_views = v;
    }
    if let Some(v) = a.test_views {
        spec.test_views = v;
    }
    if let Some(s) = &a.size {
        (spec.width, spec.height) = parse_size(s)?;
    }
    if let Some(s) = a.supersample {
        spec.supersample = s;
    }
    spec.seed = a.seed;
    spec.path = match a.path.as_str() {
        "sphere" => snerf_scene::CameraPath::Sphere,
        "orbit" => snerf_scene::CameraPath::Orbit,
        p => bail!("--path '{p}': use sphere or orbit"),
    };
    let pb = bar((spec.train_views + spec.test_views) as u64, "{spinner} rendering views {bar:30} {pos}/{len} [{elapsed}]");
    let out = snerf_scene::write_dataset(&spec, &a.out, &|done, total| {
        pb.set_length(total as u64);
        pb.set_position(done as u64);
    })?;
    pb.finish_and_clear();
    eprintln!("wrote {} ({} train + {} test views)", a.out.display(), spec.train_views, spec.test_views);
    Ok(out)
}
