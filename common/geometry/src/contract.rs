//! MERF's L∞ contraction of unbounded space into [-2,2]³ and its inverse.

use crate::march::UNBOUNDED_FAR;
use crate::vec::{max_abs, Vec3};

/// Identity in the unit cube; a point with |p|∞ = m > 1 goes to (2 - 1/m) along its largest
/// axis and p/m along the others. NaN coordinates count as 0 (a degenerate camera must not
/// poison a sample); points at infinity land on the outer shell.
#[inline]
pub fn contract(p: Vec3) -> Vec3 {
    let p = p.map(|x| if x.is_nan() { 0.0 } else { x });
    let m = max_abs(p);
    if m <= 1.0 {
        return p;
    }
    if !m.is_finite() {
        return p.map(|x| if x.is_infinite() { 2.0 * x.signum() } else { 0.0 });
    }
    p.map(|x| if x.abs() == m { (2.0 - 1.0 / m) * x.signum() } else { x / m })
}

/// The largest |c|∞ that [`uncontract`] inverts exactly; beyond it points map to the same
/// far (finite) shell at |p|∞ = 1/(2 - MAX_CONTRACTED) = 1e3, where unbounded rays end.
pub const MAX_CONTRACTED: f32 = 2.0 - 1.0 / UNBOUNDED_FAR;

/// Inverse of [`contract`]: |c|∞ = mc > 1 came from |p|∞ = 1/(2 - mc).
pub fn uncontract(c: Vec3) -> Vec3 {
    let m = max_abs(c);
    if m <= 1.0 {
        return c;
    }
    let mc = m.min(MAX_CONTRACTED);
    let r = 1.0 / (2.0 - mc);
    c.map(|x| if x.abs() >= m { r * x.signum() } else { x * r })
}

/// Unbounded march step at `p` for a grid step `step`: constant in contracted space, so it
/// grows with |p|∞² outside the unit cube (capped at the far bound).
#[inline]
pub fn unbounded_dt(step: f32, p: Vec3) -> f32 {
    let m = max_abs(p).max(1.0);
    (2.0 * step * m * m).min(UNBOUNDED_FAR)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_the_documented_point() {
        // [3, 1.5, 0] contracts to [5/3, 0.5, 0] and comes back.
        let c = contract([3.0, 1.5, 0.0]);
        assert!((c[0] - 5.0 / 3.0).abs() < 1e-6 && (c[1] - 0.5).abs() < 1e-6);
        let p = uncontract(c);
        assert!((p[0] - 3.0).abs() < 1e-4 && (p[1] - 1.5).abs() < 1e-4, "{p:?}");
        let mut s = 1u32;
        for _ in 0..2000 {
            let mut r = || {
                s = s.wrapping_mul(1664525).wrapping_add(1013904223);
                (s >> 8) as f32 / (1u32 << 24) as f32
            };
            let p = [(r() - 0.5) * 40.0, (r() - 0.5) * 4.0, (r() - 0.5) * 0.5];
            let q = uncontract(contract(p));
            for i in 0..3 {
                assert!((p[i] - q[i]).abs() <= 1e-3 * p[i].abs().max(1.0), "{p:?} -> {q:?}");
            }
        }
        assert!(contract([f32::INFINITY, 0.0, f32::NAN]) == [2.0, 0.0, 0.0]);
        assert!(uncontract([2.0, 0.0, 0.0])[0] <= UNBOUNDED_FAR * 1.001);
    }
}
