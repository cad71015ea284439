//! `snerf bench capture-depth`: a capture's geometry against the depth sensor that filmed it
//! (`snerf_data::capture::known_depth`): one scale for every camera, and how far each point's
//! depth strays from the sensor's.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_trainer::data::capture::known_depth::{agreement, Rig};

use crate::args::pj;

#[derive(Args, Debug)]
pub struct BenchCaptureDepthArgs {
    /// A dataset `snerf capture` wrote from the sequence's photos (its `sparse/0` is read).
    pub data: PathBuf,
    /// The castel sequence of Debian's visp-images-data (…/ViSP-images/mbt-depth/castel): its
    /// rig files and `castel/depth_image_NNNN.bin`, matched to photos named `image_NNNN.*`.
    #[arg(long)]
    pub visp_castel: PathBuf,
}

pub fn run(a: &BenchCaptureDepthArgs) -> Result<Value> {
    let model = a.data.join("sparse").join("0");
    if !model.join("points3D.bin").is_file() {
        bail!("{}: no sparse model (sparse/0/points3D.bin); give a dataset `snerf capture` wrote", a.data.display());
    }
    let rig = Rig::visp_castel(&a.visp_castel)?;
    let depth_dir = a.visp_castel.join("castel");
    let r = agreement(&model, &rig, |name| {
        let stem = std::path::Path::new(name).file_stem()?.to_str()?;
        let n = stem.strip_prefix("image_")?;
        let p = depth_dir.join(format!("depth_image_{n}.bin"));
        p.is_file().then_some(p)
    })?;
    eprintln!(
        "{} observations over {} cameras: {:.4} m per COLMAP unit; median depth error {:.2}%, {:.1}% within 5%; camera scales within {:.2}% of the median",
        r.observations,
        r.cameras.len(),
        r.metres_per_unit,
        100.0 * r.median_relative_error,
        100.0 * r.within_5_percent,
        100.0 * r.worst_camera_scale
    );
    Ok(json!({ "command": "bench capture-depth", "data": pj(&a.data), "visp_castel": pj(&a.visp_castel), "agreement": r }))
}
