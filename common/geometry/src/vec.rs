//! 3-vectors and 3x3 rotations as plain arrays, the form every file format stores; glam does
//! the arithmetic so nothing here is hand-rolled beyond the conversion.

use glam::{Mat3, Vec3 as G};

pub type Vec3 = [f32; 3];
/// A rotation as three rows (row-major), the form the asset header and checkpoints store.
pub type Rows3 = [[f32; 3]; 3];

#[inline]
pub fn dot(a: Vec3, b: Vec3) -> f32 {
    G::from(a).dot(G::from(b))
}
#[inline]
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    (G::from(a) + G::from(b)).into()
}
#[inline]
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    (G::from(a) - G::from(b)).into()
}
#[inline]
pub fn scale(a: Vec3, s: f32) -> Vec3 {
    (G::from(a) * s).into()
}
#[inline]
pub fn norm(a: Vec3) -> f32 {
    G::from(a).length()
}
#[inline]
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    G::from(a).cross(G::from(b)).into()
}
/// Unit vector along `a`; a zero (or non-finite) vector gives -z, the camera's forward axis,
/// so a degenerate ray still has a direction and never produces NaN downstream.
#[inline]
pub fn normalize(a: Vec3) -> Vec3 {
    let n = norm(a);
    if n > 0.0 && n.is_finite() {
        scale(a, 1.0 / n)
    } else {
        [0.0, 0.0, -1.0]
    }
}
/// Largest absolute component (the L∞ norm the contraction uses).
#[inline]
pub fn max_abs(a: Vec3) -> f32 {
    a[0].abs().max(a[1].abs()).max(a[2].abs())
}
#[inline]
fn mat(rows: &Rows3) -> Mat3 {
    // glam is column-major: the rows of `rows` are the columns of its transpose.
    Mat3::from_cols(G::from(rows[0]), G::from(rows[1]), G::from(rows[2])).transpose()
}
/// rows · v.
#[inline]
pub fn mat_vec(rows: &Rows3, v: Vec3) -> Vec3 {
    (mat(rows) * G::from(v)).into()
}
/// rowsᵀ · v: the inverse rotation when `rows` is orthonormal.
#[inline]
pub fn mat_t_vec(rows: &Rows3, v: Vec3) -> Vec3 {
    (mat(rows).transpose() * G::from(v)).into()
}
pub const IDENTITY: Rows3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_mean_rows() {
        let r: Rows3 = [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]];
        assert_eq!(mat_vec(&r, [1.0, 2.0, 3.0]), [2.0, 3.0, 1.0]);
        assert_eq!(mat_t_vec(&r, mat_vec(&r, [1.0, 2.0, 3.0])), [1.0, 2.0, 3.0]);
        assert_eq!(cross([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
        assert_eq!(normalize([0.0; 3]), [0.0, 0.0, -1.0]);
        assert_eq!(normalize([f32::NAN, 0.0, 0.0]), [0.0, 0.0, -1.0]);
    }
}
