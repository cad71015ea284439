//! Checking a capture's geometry against a depth sensor. COLMAP recovers the cameras and the
//! sparse points only up to one similarity (its units are arbitrary), so its geometry is right
//! when a single scale maps every point's depth, seen from every registered camera, onto the
//! depth a sensor measured there. A scale that drifts from camera to camera (a bent or folded
//! reconstruction), or points whose depth disagrees with the sensor (a misplaced camera), show
//! up here; the reprojection error COLMAP reports cannot see either, since it is measured
//! against COLMAP's own cameras.
//!
//! The sensor's depth images are carried into the colour camera (deprojected with the sensor's
//! intrinsics and lens model, moved by the rig's extrinsics, projected with the colour camera's
//! calibrated intrinsics, nearest surface kept), so COLMAP's self-calibration plays no part in
//! where a point is looked up. Each observation of a sparse point gives a ratio (sensor depth ÷
//! COLMAP depth); the scale is the median ratio, and the check reports how far the ratios stray
//! from it, overall and per camera.
//!
//! [`Rig::visp_castel`] is the rig of Debian's `visp-images-data` castel sequence (an SR300
//! depth camera: depth and greyscale colour at 640×480), with the constants ViSP's own
//! depth-tracker test reads the sequence with.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use serde::Serialize;

use crate::colmap::read_images_bin;
use crate::colmap_points::read_points_bin;
use crate::pose::quat_to_mat;

/// Pinhole intrinsics in pixels.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Pinhole {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

/// A depth sensor beside a colour camera.
#[derive(Clone, Debug, Serialize)]
pub struct Rig {
    pub depth: Pinhole,
    /// The depth stream's lens (librealsense's inverse Brown–Conrady: k1, k2, p1, p2, k3,
    /// applied when deprojecting).
    pub depth_lens: [f64; 5],
    /// Metres per depth unit.
    pub depth_scale: f64,
    pub colour: Pinhole,
    /// Colour-camera coordinates from depth-camera coordinates (rows of a 3×4, metres).
    pub colour_from_depth: [[f64; 4]; 3],
}

impl Rig {
    /// The castel sequence of `visp-images-data` (`root` = `.../mbt-depth/castel`): SR300
    /// depth intrinsics, lens and scale as ViSP's depth-tracker test reads them, the
    /// colour camera of `chateau.xml`, and the extrinsics of `depth_M_color.txt`.
    pub fn visp_castel(root: &Path) -> Result<Rig> {
        let m_path = root.join("depth_M_color.txt");
        let text = std::fs::read_to_string(&m_path).with_context(|| format!("{}: cannot read", m_path.display()))?;
        let v: Vec<f64> = text.split_whitespace().map(|t| t.parse::<f64>()).collect::<Result<_, _>>().map_err(|e| anyhow!("{}: not a 4×4 matrix of numbers: {e}", m_path.display()))?;
        if v.len() != 16 {
            bail!("{}: expected a 4×4 matrix (16 numbers), found {}", m_path.display(), v.len());
        }
        // depth_M_color maps colour coordinates into depth coordinates; invert the rigid motion
        let r = [[v[0], v[1], v[2]], [v[4], v[5], v[6]], [v[8], v[9], v[10]]];
        let t = [v[3], v[7], v[11]];
        let mut inv = [[0.0; 4]; 3];
        for i in 0..3 {
            for j in 0..3 {
                inv[i][j] = r[j][i];
            }
            inv[i][3] = -(0..3).map(|k| r[k][i] * t[k]).sum::<f64>();
        }
        Ok(Rig {
            depth: Pinhole { fx: 476.053619, fy: 476.053497, cx: 311.484558, cy: 246.283234 },
            depth_lens: [0.165056542, -0.0508309528, 0.00435937941, 0.00541406544, 0.250085592],
            depth_scale: 0.000124986647,
            colour: Pinhole { fx: 615.1674804688, fy: 615.1675415039, cx: 312.1889953613, cy: 243.4373779297 },
            colour_from_depth: inv,
        })
    }
}

/// A depth image as ViSP writes it: u32 height, u32 width (little-endian), then height × width
/// u16 depth units, row by row. Returns (width, height, units).
pub fn read_visp_depth(path: &Path) -> Result<(usize, usize, Vec<u16>)> {
    let b = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    if b.len() < 8 {
        bail!("{}: not a ViSP depth image ({} bytes, the header alone is 8)", path.display(), b.len());
    }
    let h = u32::from_le_bytes(b[0..4].try_into().unwrap()) as usize;
    let w = u32::from_le_bytes(b[4..8].try_into().unwrap()) as usize;
    if w.checked_mul(h).and_then(|n| n.checked_mul(2)).map(|n| n + 8) != Some(b.len()) {
        bail!("{}: header says {w}×{h} depth values, the file holds {} bytes", path.display(), b.len());
    }
    Ok((w, h, b[8..].chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect()))
}

/// The depth (metres, along the colour camera's axis) the sensor saw at each pixel of a
/// `width` × `height` colour image; 0 where it saw nothing.
pub fn depth_in_colour(rig: &Rig, dw: usize, dh: usize, units: &[u16], width: usize, height: usize) -> Vec<f32> {
    let mut z = vec![f32::INFINITY; width * height];
    let [k1, k2, p1, p2, k3] = rig.depth_lens;
    let m = &rig.colour_from_depth;
    for v in 0..dh {
        for u in 0..dw {
            let d = units[v * dw + u] as f64 * rig.depth_scale;
            if d <= 0.0 {
                continue;
            }
            let x = (u as f64 - rig.depth.cx) / rig.depth.fx;
            let y = (v as f64 - rig.depth.cy) / rig.depth.fy;
            let r2 = x * x + y * y;
            let f = 1.0 + k1 * r2 + k2 * r2 * r2 + k3 * r2 * r2 * r2;
            let ux = x * f + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
            let uy = y * f + 2.0 * p2 * x * y + p1 * (r2 + 2.0 * y * y);
            let p = [d * ux, d * uy, d];
            let c: [f64; 3] = std::array::from_fn(|i| m[i][0] * p[0] + m[i][1] * p[1] + m[i][2] * p[2] + m[i][3]);
            if c[2] <= 0.0 {
                continue;
            }
            let pu = (rig.colour.fx * c[0] / c[2] + rig.colour.cx).round();
            let pv = (rig.colour.fy * c[1] / c[2] + rig.colour.cy).round();
            if pu >= 0.0 && pv >= 0.0 && (pu as usize) < width && (pv as usize) < height {
                let i = pv as usize * width + pu as usize;
                z[i] = z[i].min(c[2] as f32);
            }
        }
    }
    z.iter_mut().filter(|v| !v.is_finite()).for_each(|v| *v = 0.0);
    z
}

/// The nearest surface the sensor saw within a pixel of (u, v) (its depth maps leave holes
/// where the colour camera is sampled more finely than the sensor).
fn depth_near(z: &[f32], width: usize, height: usize, u: f64, v: f64) -> Option<f64> {
    let (cu, cv) = (u.round() as i64, v.round() as i64);
    let mut best = f32::INFINITY;
    for dv in -1..=1 {
        for du in -1..=1 {
            let (x, y) = (cu + du, cv + dv);
            if x >= 0 && y >= 0 && (x as usize) < width && (y as usize) < height {
                let d = z[y as usize * width + x as usize];
                if d > 0.0 {
                    best = best.min(d);
                }
            }
        }
    }
    best.is_finite().then_some(best as f64)
}

/// One camera's agreement.
#[derive(Clone, Debug, Serialize)]
pub struct CameraAgreement {
    pub image: String,
    pub observations: usize,
    /// Its median ratio ÷ the overall scale.
    pub scale_ratio: f64,
}

/// How well a COLMAP model's depths agree with the sensor's.
#[derive(Clone, Debug, Serialize)]
pub struct DepthAgreement {
    /// Observations (point × camera) the sensor saw a surface at.
    pub observations: usize,
    /// Metres per COLMAP unit: the median of sensor ÷ COLMAP depth.
    pub metres_per_unit: f64,
    /// Median of |ratio ÷ scale − 1| over the observations.
    pub median_relative_error: f64,
    /// Fraction of observations within 5% of the scale.
    pub within_5_percent: f64,
    /// Per camera (with at least 20 observations), its median ratio ÷ the scale.
    pub cameras: Vec<CameraAgreement>,
    /// The largest |camera's scale ratio − 1|.
    pub worst_camera_scale: f64,
}

/// Compares the model in `model_dir` (`images.bin`, `points3D.bin`) with the sensor's depth
/// images: `depth_of(image name)` names the depth file of a registered image (None: skipped).
pub fn agreement(model_dir: &Path, rig: &Rig, depth_of: impl Fn(&str) -> Option<PathBuf>) -> Result<DepthAgreement> {
    let ip = model_dir.join("images.bin");
    let images = read_images_bin(&std::fs::read(&ip).with_context(|| format!("{}: cannot read", ip.display()))?).map_err(|e| anyhow!("{}: {e}", ip.display()))?;
    let pp = model_dir.join("points3D.bin");
    let points = read_points_bin(&std::fs::read(&pp).with_context(|| format!("{}: cannot read", pp.display()))?).map_err(|e| anyhow!("{}: {e}", pp.display()))?;
    let by_id: HashMap<u32, usize> = images.iter().enumerate().map(|(i, im)| (im.id, i)).collect();
    // the points each image observed (a track may name an image twice)
    let mut seen: Vec<Vec<usize>> = vec![Vec::new(); images.len()];
    for (k, p) in points.iter().enumerate() {
        for i in p.seen_by.iter().filter_map(|id| by_id.get(id)) {
            if seen[*i].last() != Some(&k) {
                seen[*i].push(k);
            }
        }
    }
    let mut ratios: Vec<Vec<f64>> = vec![Vec::new(); images.len()];
    for (i, im) in images.iter().enumerate() {
        let Some(path) = depth_of(&im.name) else { continue };
        let (dw, dh, units) = read_visp_depth(&path)?;
        // the colour images of these rigs are the depth images' size
        let (w, h) = (dw, dh);
        let z = depth_in_colour(rig, dw, dh, &units, w, h);
        let r = quat_to_mat(im.qvec).ok_or_else(|| anyhow!("{}: image '{}' has a zero rotation", ip.display(), im.name))?;
        for p in seen[i].iter().map(|&k| &points[k]) {
            let c: [f64; 3] = std::array::from_fn(|k| r[k][0] * p.xyz[0] + r[k][1] * p.xyz[1] + r[k][2] * p.xyz[2] + im.tvec[k]);
            if c[2] <= 0.0 {
                continue;
            }
            let u = rig.colour.fx * c[0] / c[2] + rig.colour.cx;
            let v = rig.colour.fy * c[1] / c[2] + rig.colour.cy;
            if let Some(d) = depth_near(&z, w, h, u, v) {
                ratios[i].push(d / c[2]);
            }
        }
    }
    let mut all: Vec<f64> = ratios.iter().flatten().copied().collect();
    if all.len() < 20 {
        bail!("{}: only {} observations fall where the sensor saw a surface (20 needed to compare)", model_dir.display(), all.len());
    }
    let scale = median(&mut all);
    let mut dev: Vec<f64> = all.iter().map(|r| (r / scale - 1.0).abs()).collect();
    let within = dev.iter().filter(|&&d| d <= 0.05).count() as f64 / dev.len() as f64;
    let median_relative_error = median(&mut dev);
    let mut cameras = Vec::new();
    for (im, mut r) in images.iter().zip(ratios) {
        if r.len() >= 20 {
            let n = r.len();
            cameras.push(CameraAgreement { image: im.name.clone(), observations: n, scale_ratio: median(&mut r) / scale });
        }
    }
    cameras.sort_by(|a, b| a.image.cmp(&b.image));
    let worst_camera_scale = cameras.iter().map(|c| (c.scale_ratio - 1.0).abs()).fold(0.0, f64::max);
    Ok(DepthAgreement { observations: all.len(), metres_per_unit: scale, median_relative_error, within_5_percent: within, cameras, worst_camera_scale })
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat wall 0.4 m in front of a rig whose cameras coincide: every pixel of the colour
    /// image reads 0.4 m, whatever the depth lens.
    #[test]
    fn a_wall_reads_its_distance_in_the_colour_camera() {
        let rig = Rig {
            depth: Pinhole { fx: 100.0, fy: 100.0, cx: 32.0, cy: 24.0 },
            depth_lens: [0.0; 5],
            depth_scale: 0.001,
            colour: Pinhole { fx: 100.0, fy: 100.0, cx: 32.0, cy: 24.0 },
            colour_from_depth: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
        };
        let units = vec![400u16; 64 * 48];
        let z = depth_in_colour(&rig, 64, 48, &units, 64, 48);
        assert!(z.iter().all(|&d| (d - 0.4).abs() < 1e-6));
        // moved 0.1 m toward the wall, the colour camera reads 0.3 m where it sees it
        let mut moved = rig.clone();
        moved.colour_from_depth[2][3] = -0.1;
        let z = depth_in_colour(&moved, 64, 48, &units, 64, 48);
        assert!((z[24 * 64 + 32] - 0.3).abs() < 1e-6, "{}", z[24 * 64 + 32]);
        assert_eq!(depth_near(&z, 64, 48, 32.4, 23.6), Some(z[24 * 64 + 32] as f64));
    }

    #[test]
    fn a_depth_file_of_the_wrong_size_is_named() {
        let dir = std::env::temp_dir().join(format!("snerf-known-depth-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("depth_image_0000.bin");
        let mut b = 2u32.to_le_bytes().to_vec();
        b.extend(3u32.to_le_bytes());
        b.extend([0u8; 12]);
        std::fs::write(&p, &b).unwrap();
        assert_eq!(read_visp_depth(&p).unwrap(), (3, 2, vec![0; 6]));
        std::fs::write(&p, &b[..b.len() - 2]).unwrap();
        let e = read_visp_depth(&p).unwrap_err().to_string();
        assert!(e.contains("depth_image_0000.bin") && e.contains("3×2"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
