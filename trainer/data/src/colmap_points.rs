//! Depth bounds of a COLMAP model from its sparse points (`points3D.bin`), as LLFF's
//! `poses_bounds.npy` holds them: a forward-facing scene's NDC near plane must sit in front of
//! the nearest content, and COLMAP's world scale is arbitrary, so the bound cannot be guessed
//! from the camera spread. Per image, the points in front of it and inside its view give depth
//! percentiles (1st and 99th, robust to stray points); near is the smallest, far the largest.

use anyhow::{bail, Result};

/// One sparse point: where it is and the images that observed it.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct SparsePoint {
    pub xyz: [f64; 3],
    /// Image ids of its track (an image may appear more than once).
    pub seen_by: Vec<u32>,
}

/// Every point in `points3D.bin` with a finite position: u64 count; per point u64 id, f64
/// xyz[3], u8 rgb[3], f64 error, u64 track length, then (i32 image id, i32 point2D index) per
/// track element.
pub(crate) fn read_points_bin(buf: &[u8]) -> Result<Vec<SparsePoint>> {
    let mut pos = 0usize;
    let mut take = |n: usize, what: &str| -> Result<&[u8]> {
        if buf.len() - pos < n {
            bail!(
                "truncated file: {what} at byte {pos} needs {n} bytes, {} left",
                buf.len() - pos
            );
        }
        let s = &buf[pos..pos + n];
        pos += n;
        Ok(s)
    };
    let n = u64::from_le_bytes(take(8, "number of points")?.try_into().unwrap());
    // id + xyz + rgb + error + track length: 51 bytes at least per point.
    if (n as u128) * 51 > buf.len() as u128 {
        bail!(
            "corrupt or truncated file: {n} points cannot fit in {} bytes",
            buf.len()
        );
    }
    let mut out = Vec::with_capacity(n as usize);
    for _ in 0..n {
        take(8, "point id")?;
        let mut p = [0.0; 3];
        for v in &mut p {
            *v = f64::from_le_bytes(take(8, "point position")?.try_into().unwrap());
        }
        take(3 + 8, "point colour and error")?;
        let len = u64::from_le_bytes(take(8, "track length")?.try_into().unwrap());
        let bytes = (len as u128) * 8;
        if bytes > (buf.len() as u128) {
            bail!("corrupt file: track length {len} exceeds the file");
        }
        let track = take(bytes as usize, "track")?;
        if p.iter().all(|v| v.is_finite()) {
            let seen_by = track.chunks_exact(8).map(|e| u32::from_le_bytes(e[..4].try_into().unwrap())).collect();
            out.push(SparsePoint { xyz: p, seen_by });
        }
    }
    Ok(out)
}

/// One camera for the bound: world-to-camera rotation and translation (OpenCV axes) and the
/// half-extent of its view as tangents (w / 2fx, h / 2fy).
pub(crate) struct BoundCamera {
    pub r: [[f64; 3]; 3],
    pub t: [f64; 3],
    pub tan_half: [f64; 2],
}

/// (near, far) over all cameras, or `None` when no camera sees at least 10 points.
pub(crate) fn near_far(points: &[[f64; 3]], cams: &[BoundCamera]) -> Option<(f32, f32)> {
    let (mut near, mut far) = (f64::INFINITY, 0.0f64);
    for c in cams {
        let mut z: Vec<f64> = points
            .iter()
            .filter_map(|p| {
                let q: Vec<f64> = (0..3)
                    .map(|i| c.r[i][0] * p[0] + c.r[i][1] * p[1] + c.r[i][2] * p[2] + c.t[i])
                    .collect();
                let inside = q[2] > 0.0
                    && (q[0] / q[2]).abs() <= c.tan_half[0] * 1.05
                    && (q[1] / q[2]).abs() <= c.tan_half[1] * 1.05;
                inside.then_some(q[2])
            })
            .collect();
        if z.len() < 10 {
            continue;
        }
        z.sort_by(|a, b| a.total_cmp(b));
        let pct = |f: f64| z[((z.len() - 1) as f64 * f).round() as usize];
        near = near.min(pct(0.01));
        far = far.max(pct(0.99));
    }
    (near.is_finite() && near > 0.0 && far > near).then_some((near as f32, far as f32))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_come_from_the_points_in_view() {
        let cam = BoundCamera {
            r: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            t: [0.0; 3],
            tan_half: [0.5, 0.5],
        };
        // 100 points at depths 2..=3 on the axis, one behind, one far outside the view.
        let mut pts: Vec<[f64; 3]> = (0..=100)
            .map(|i| [0.0, 0.0, 2.0 + i as f64 / 100.0])
            .collect();
        pts.push([0.0, 0.0, -5.0]);
        pts.push([50.0, 0.0, 1.0]);
        let (n, f) = near_far(&pts, &[cam]).unwrap();
        assert!(
            (n - 2.01).abs() < 0.011 && (f - 2.99).abs() < 0.011,
            "{n} {f}"
        );

        // A file with one point, its track of two elements.
        let mut b = 1u64.to_le_bytes().to_vec();
        b.extend(7u64.to_le_bytes());
        for v in [1.0f64, 2.0, 3.0] {
            b.extend(v.to_le_bytes());
        }
        b.extend([10u8, 20, 30]);
        b.extend(0.5f64.to_le_bytes());
        b.extend(2u64.to_le_bytes());
        for (image, point2d) in [(3i32, 0i32), (5, 1)] {
            b.extend(image.to_le_bytes());
            b.extend(point2d.to_le_bytes());
        }
        assert_eq!(read_points_bin(&b).unwrap(), vec![SparsePoint { xyz: [1.0, 2.0, 3.0], seen_by: vec![3, 5] }]);
        assert!(read_points_bin(&b[..b.len() - 1]).is_err());
        assert!(read_points_bin(&u64::MAX.to_le_bytes()).is_err());
    }
}
