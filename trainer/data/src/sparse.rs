//! A COLMAP dataset's sparse points with the training views that observed them, for the
//! trainer's free-space carving: each observation is a line of sight, so the segment from
//! that camera's centre to (a little before) the point is empty.
//!
//! Only observations by *training* views are kept, so held-out photos add nothing to what the
//! trainer learns from; a point seen by no training view is dropped.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, Result};

use crate::colmap::{read_images_bin, read_images_txt};
use crate::colmap_points::read_points_bin;
use crate::Dataset;

/// One sparse point and the training views (indices into `Dataset::train`) that saw it.
#[derive(Clone, Debug, PartialEq)]
pub struct TrackedPoint {
    pub xyz: [f32; 3],
    /// Distinct training-view indices, ascending.
    pub seen_by: Vec<u32>,
}

/// The points of one model and where they were read from.
#[derive(Clone, Debug)]
pub struct SparseTracks {
    pub file: PathBuf,
    pub points: Vec<TrackedPoint>,
    /// Observations by training views (segments), summed over the points.
    pub observations: usize,
}

/// The dataset's sparse points, when it is a COLMAP model with a `points3D.bin`; `None` for
/// every other format (transforms.json, LLFF) and for a model without points.
pub fn sparse_tracks(data: &Dataset) -> Result<Option<SparseTracks>> {
    if data.format != "colmap" {
        return Ok(None);
    }
    // the points of the reconstruction the poses came from (a folder may hold several)
    let Some(model_dir) = data.pose_file.parent() else {
        return Ok(None);
    };
    let points_path = model_dir.join("points3D.bin");
    if !points_path.is_file() {
        return Ok(None);
    }
    let read = |p: &Path| std::fs::read(p).map_err(|e| anyhow!("{}: cannot read: {e}", p.display()));
    let points = read_points_bin(&read(&points_path)?).map_err(|e| anyhow!("{}: {e}", points_path.display()))?;
    let p = &data.pose_file;
    let images = if p.extension().is_some_and(|e| e == "bin") {
        read_images_bin(&read(p)?).map_err(|e| anyhow!("{}: {e}", p.display()))?
    } else {
        let text = std::fs::read_to_string(p).map_err(|e| anyhow!("{}: cannot read: {e}", p.display()))?;
        read_images_txt(&text).map_err(|e| anyhow!("{}: {e}", p.display()))?
    };
    // COLMAP image id -> training view index, by the image's name: the loader reads
    // `images/NAME` (or `images_N/NAME`), so a view is the image whose whole name ends its
    // path right below that folder (`000.jpg` is not `cam1/000.jpg`).
    let is_view_of = |v: &crate::View, name: &Path| {
        let below = v.path.ancestors().nth(name.components().count());
        v.path.ends_with(name) && below.and_then(Path::file_name).is_some_and(|f| f.to_string_lossy().starts_with("images"))
    };
    let mut train_of: HashMap<u32, u32> = HashMap::new();
    for img in &images {
        if let Some(i) = data.train.iter().position(|v| is_view_of(v, Path::new(&img.name))) {
            train_of.insert(img.id, i as u32);
        }
    }
    let mut out = Vec::with_capacity(points.len());
    let mut observations = 0;
    for p in points {
        let mut seen: Vec<u32> = p.seen_by.iter().filter_map(|id| train_of.get(id).copied()).collect();
        seen.sort_unstable();
        seen.dedup();
        if seen.is_empty() {
            continue;
        }
        observations += seen.len();
        out.push(TrackedPoint { xyz: p.xyz.map(|v| v as f32), seen_by: seen });
    }
    Ok(Some(SparseTracks { file: points_path, points: out, observations }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::LoadOptions;

    fn points_bin(points: &[([f64; 3], Vec<i32>)]) -> Vec<u8> {
        let mut b = Vec::new();
        b.extend((points.len() as u64).to_le_bytes());
        for (i, (xyz, track)) in points.iter().enumerate() {
            b.extend((i as u64 + 1).to_le_bytes());
            xyz.iter().for_each(|v| b.extend(v.to_le_bytes()));
            b.extend([1u8, 2, 3]);
            b.extend(0.5f64.to_le_bytes());
            b.extend((track.len() as u64).to_le_bytes());
            for (k, &img) in track.iter().enumerate() {
                b.extend(img.to_le_bytes());
                b.extend((k as i32).to_le_bytes());
            }
        }
        b
    }

    #[test]
    fn observations_map_to_training_views_and_held_out_ones_are_dropped() {
        let dir = std::env::temp_dir().join(format!("snerf-sparse-{}-{:?}", std::process::id(), std::thread::current().id()));
        let _ = std::fs::remove_dir_all(&dir);
        let model = dir.join("sparse").join("0");
        std::fs::create_dir_all(&model).unwrap();
        std::fs::create_dir_all(dir.join("images")).unwrap();
        let mut images = String::new();
        for (id, name) in [(1, "a.png"), (2, "b.png"), (3, "c.png"), (4, "d.png")] {
            image::RgbaImage::from_pixel(8, 8, image::Rgba([9, 9, 9, 255])).save(dir.join("images").join(name)).unwrap();
            images += &format!("{id} 1 0 0 0 0 0 {} 1 {name}\n\n", id as f64 * 0.1);
        }
        std::fs::write(model.join("cameras.txt"), "1 PINHOLE 8 8 10 10 4 4\n").unwrap();
        std::fs::write(model.join("images.txt"), images).unwrap();
        // point 1: a (held out), b, d; point 2: a and c only (held out); point 3: b twice
        let pts = [([0.0, 0.0, 5.0], vec![1, 2, 4]), ([1.0, 0.0, 5.0], vec![1, 3]), ([0.0, 1.0, 5.0], vec![2, 2])];
        std::fs::write(model.join("points3D.bin"), points_bin(&pts)).unwrap();
        let data = crate::load(&dir, &LoadOptions { holdout_every: Some(2), ..Default::default() }).unwrap();
        let names: Vec<_> = data.train.iter().map(|v| v.path.file_name().unwrap().to_string_lossy().into_owned()).collect();
        assert_eq!(names, ["b.png", "d.png"]);
        let t = sparse_tracks(&data).unwrap().expect("a COLMAP model with points");
        assert_eq!(t.points, vec![TrackedPoint { xyz: [0.0, 0.0, 5.0], seen_by: vec![0, 1] }, TrackedPoint { xyz: [0.0, 1.0, 5.0], seen_by: vec![0] }]);
        assert_eq!(t.observations, 3);
        // without points3D.bin there is nothing to carve with
        std::fs::remove_file(model.join("points3D.bin")).unwrap();
        let data = crate::load(&dir, &LoadOptions { holdout_every: Some(2), ..Default::default() }).unwrap();
        assert!(sparse_tracks(&data).unwrap().is_none());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
