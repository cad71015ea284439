//! Pose checks and conversions shared by the loaders: rigid-transform validation (finite,
//! orthonormal after removing a uniform scale, det +1), quaternions, small 3x3 algebra.

use std::path::Path;

use anyhow::{bail, Result};

/// Tolerance on `|RᵀR / s² - I|` (max entry) for a pose to count as rigid.
pub(crate) const ORTHO_TOL: f64 = 1e-3;

pub(crate) type Mat3 = [[f64; 3]; 3];

/// Checks a camera-to-world matrix (rows of a 3x4) and returns it as f32 with any uniform scale
/// divided out of the rotation part. `what` names the frame ("frame 3", "image 'a.png'").
pub(crate) fn rigid_c2w(m: [[f64; 4]; 3], file: &Path, what: &str) -> Result<[[f32; 4]; 3]> {
    if m.iter().flatten().any(|v| !v.is_finite()) {
        bail!("{}: {what}: pose contains NaN or Inf", file.display());
    }
    let r: Mat3 = [
        [m[0][0], m[0][1], m[0][2]],
        [m[1][0], m[1][1], m[1][2]],
        [m[2][0], m[2][1], m[2][2]],
    ];
    // Mean squared column norm = s² for a scaled rotation.
    let s2 = (0..3)
        .map(|c| (0..3).map(|k| r[k][c] * r[k][c]).sum::<f64>())
        .sum::<f64>()
        / 3.0;
    if s2 <= 1e-20 {
        bail!(
            "{}: {what}: pose rotation part is zero (degenerate)",
            file.display()
        );
    }
    let s = s2.sqrt();
    let rn: Mat3 = std::array::from_fn(|i| std::array::from_fn(|j| r[i][j] / s));
    let mut err = 0.0f64;
    for i in 0..3 {
        for j in 0..3 {
            let dot: f64 = (0..3).map(|k| rn[k][i] * rn[k][j]).sum();
            let target = if i == j { 1.0 } else { 0.0 };
            err = err.max((dot - target).abs());
        }
    }
    if err > ORTHO_TOL {
        bail!(
            "{}: {what}: pose is not rigid: rotation part is not orthonormal \
             (max |RᵀR/s² - I| = {err:.3e} > {ORTHO_TOL:.0e})",
            file.display()
        );
    }
    let d = det3(&rn);
    if d < 0.0 {
        bail!(
            "{}: {what}: pose is a reflection (rotation determinant {d:.4}, must be +1)",
            file.display()
        );
    }
    Ok(std::array::from_fn(|i| {
        [
            rn[i][0] as f32,
            rn[i][1] as f32,
            rn[i][2] as f32,
            m[i][3] as f32,
        ]
    }))
}

pub(crate) fn det3(m: &Mat3) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// Rotation matrix of a unit quaternion (w, x, y, z); the quaternion is normalized first.
/// Returns None for a zero or non-finite quaternion.
pub(crate) fn quat_to_mat(q: [f64; 4]) -> Option<Mat3> {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if !n.is_finite() || n < 1e-12 {
        return None;
    }
    let [w, x, y, z] = q.map(|v| v / n);
    Some([
        [
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
        ],
        [
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
        ],
        [
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        ],
    ])
}

/// COLMAP world-to-camera (OpenCV axes) -> camera-to-world (OpenGL axes), rows of a 3x4.
pub(crate) fn w2c_opencv_to_c2w_opengl(r: &Mat3, t: [f64; 3]) -> [[f64; 4]; 3] {
    // c2w rotation = Rᵀ, centre = -Rᵀ t; then flip the camera's y and z axes (columns 1, 2).
    let mut out = [[0.0; 4]; 3];
    for i in 0..3 {
        out[i][0] = r[0][i];
        out[i][1] = -r[1][i];
        out[i][2] = -r[2][i];
        out[i][3] = -(r[0][i] * t[0] + r[1][i] * t[1] + r[2][i] * t[2]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quat_identity_and_rigid_checks() {
        let r = quat_to_mat([2.0, 0.0, 0.0, 0.0]).unwrap();
        assert_eq!(r, [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        assert!(quat_to_mat([0.0; 4]).is_none());
        let p = Path::new("x.json");
        // A uniform scale of 2 is divided out.
        let m = [
            [2.0, 0.0, 0.0, 1.0],
            [0.0, 2.0, 0.0, 2.0],
            [0.0, 0.0, 2.0, 3.0],
        ];
        let c = rigid_c2w(m, p, "frame 0").unwrap();
        assert_eq!(c[0], [1.0, 0.0, 0.0, 1.0]);
        let refl = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, -1.0, 0.0],
        ];
        let e = rigid_c2w(refl, p, "frame 4").unwrap_err().to_string();
        assert!(
            e.contains("reflection") && e.contains("frame 4") && e.contains("x.json"),
            "{e}"
        );
    }
}
