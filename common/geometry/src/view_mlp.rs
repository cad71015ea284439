//! The view-dependent colour MLP (34 -> 16 -> 16 -> 3, ReLU): its input encoding and its
//! dense layers. The trainer (with a backward pass), the asset's CPU reference and the WGSL
//! shader evaluate the same network; this is the one CPU definition of its forward pass.

/// Composited diffuse rgb (3) + specular features (4).
pub const DIFFUSE_FEAT: usize = 7;
/// Sin/cos octaves of the view direction.
pub const OCTAVES: usize = 4;
/// Inputs: diffuse+features, the unit direction, sin and cos of each component per octave.
pub const INPUTS: usize = DIFFUSE_FEAT + 3 + 6 * OCTAVES;
pub const HIDDEN: usize = 16;
pub const OUTPUTS: usize = 3;

/// The MLP's input vector for composited values and a unit world direction.
pub fn encode(diffuse_feat: &[f32; DIFFUSE_FEAT], dir: [f32; 3]) -> [f32; INPUTS] {
    let mut x = [0.0f32; INPUTS];
    x[..DIFFUSE_FEAT].copy_from_slice(diffuse_feat);
    x[DIFFUSE_FEAT..DIFFUSE_FEAT + 3].copy_from_slice(&dir);
    let mut k = DIFFUSE_FEAT + 3;
    for o in 0..OCTAVES {
        let f = (1u32 << o) as f32 * std::f32::consts::PI;
        for d in dir {
            let (s, c) = (f * d).sin_cos();
            x[k] = s;
            x[k + 1] = c;
            k += 2;
        }
    }
    x
}

/// One dense layer, out[j] = b[j] + Σ_i w[j·n_in + i]·x[i] (row j of `w` holds output j's
/// weights), then ReLU if asked. Zipped iterators: a short weight slice gives a wrong
/// answer, never a panic or an out-of-bounds read.
pub fn dense(w: &[f32], b: &[f32], x: &[f32], out: &mut [f32], relu: bool) {
    let n_in = x.len();
    for ((o, bj), row) in out.iter_mut().zip(b).zip(w.chunks(n_in.max(1))) {
        let s = row.iter().zip(x).fold(*bj, |acc, (wi, xi)| acc + wi * xi);
        *o = if relu { s.max(0.0) } else { s };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encoding_and_layer() {
        let x = encode(&[0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7], [0.0, 0.0, 1.0]);
        assert_eq!(INPUTS, 34);
        assert_eq!(&x[7..10], &[0.0, 0.0, 1.0]);
        assert!((x[10] - 0.0).abs() < 1e-6 && (x[11] - 1.0).abs() < 1e-6); // sin(0), cos(0) for x
        let mut out = [0.0; 2];
        dense(&[1.0, 2.0, -1.0, -2.0], &[0.5, 0.0], &[1.0, 1.0], &mut out, true);
        assert_eq!(out, [3.5, 0.0]);
        dense(&[1.0, 2.0, -1.0, -2.0], &[0.5, 0.0], &[1.0, 1.0], &mut out, false);
        assert_eq!(out, [3.5, -3.0]);
    }
}
