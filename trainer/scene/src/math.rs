//! What the scene generator needs beyond glam and snerf-geometry: vectors, matrices and
//! quaternions are glam's, cameras and look-at are snerf-geometry's. What stays here has no
//! counterpart there: a normal matrix that survives flattening transforms, quaternion clean-up
//! for untrusted glTF keyframes, and the seeded RNG and noise the procedural scenes are built
//! from (their exact sequences are part of every generated dataset, so they are not swapped
//! for a library's).

use glam::{FloatExt, Mat3, Mat4, Quat, Vec4};

pub fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Matrix that transforms normals: the inverse-transpose of the upper 3x3 up to a positive
/// factor (normals are renormalized afterwards). Built from the cofactors (the cross products
/// of the columns) times the sign of the determinant rather than from `inverse()`, because
/// glTF nodes and procedural parts may be scaled to zero along one axis (a flat decal, a
/// collapsed eyelid), where there is no inverse but the cofactors still give the right normal.
pub fn normal_matrix(m: &Mat4) -> Mat3 {
    let (a, b, c) = (m.x_axis.truncate(), m.y_axis.truncate(), m.z_axis.truncate());
    let cof = Mat3::from_cols(b.cross(c), c.cross(a), a.cross(b));
    if a.dot(cof.x_axis) < 0.0 {
        -cof
    } else {
        cof
    }
}

/// A glTF quaternion (x, y, z, w) made unit; a zero or non-finite one (possible in keyframe
/// data) becomes the identity instead of NaN.
pub fn normalize_quat(q: [f32; 4]) -> Quat {
    Vec4::from_array(q).try_normalize().map_or(Quat::IDENTITY, Quat::from_vec4)
}

/// Spherical interpolation of two glTF keyframe rotations, unit even when the keys are not.
pub fn slerp(a: [f32; 4], b: [f32; 4], t: f32) -> Quat {
    let q = normalize_quat(a).slerp(normalize_quat(b), t);
    normalize_quat(q.to_array())
}

/// Small deterministic RNG (SplitMix64), so datasets are reproducible from a seed.
#[derive(Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed ^ 0x9E37_79B9_7F4A_7C15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    pub fn range(&mut self, a: f32, b: f32) -> f32 {
        a + (b - a) * self.f32()
    }
}

fn hash3(x: i32, y: i32, z: i32, seed: u32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343)
        ^ (y as u32).wrapping_mul(0xd816_3841)
        ^ (z as u32).wrapping_mul(0xcb1a_b31f)
        ^ seed.wrapping_mul(0x1656_67b1);
    h ^= h >> 13;
    h = h.wrapping_mul(0x5bd1_e995);
    h ^= h >> 15;
    (h & 0xff_ffff) as f32 / 0xff_ffff as f32
}

/// Smooth value noise in [0, 1], periodic with period `per` on x and y when `per` > 0
/// (so it tiles on textures that wrap).
pub fn value_noise(x: f32, y: f32, z: f32, seed: u32, per: i32) -> f32 {
    let (xi, yi, zi) = (x.floor() as i32, y.floor() as i32, z.floor() as i32);
    let (fx, fy, fz) = (x - x.floor(), y - y.floor(), z - z.floor());
    let s = |t: f32| t * t * (3.0 - 2.0 * t);
    let (sx, sy, sz) = (s(fx), s(fy), s(fz));
    let w = |i: i32| if per > 0 { i.rem_euclid(per) } else { i };
    let g = |dx: i32, dy: i32, dz: i32| hash3(w(xi + dx), w(yi + dy), zi + dz, seed);
    let a = f32::lerp(
        f32::lerp(g(0, 0, 0), g(1, 0, 0), sx),
        f32::lerp(g(0, 1, 0), g(1, 1, 0), sx),
        sy,
    );
    let b = f32::lerp(
        f32::lerp(g(0, 0, 1), g(1, 0, 1), sx),
        f32::lerp(g(0, 1, 1), g(1, 1, 1), sx),
        sy,
    );
    f32::lerp(a, b, sz)
}

/// Fractal sum of value noise, in [0, 1].
pub fn fbm(x: f32, y: f32, z: f32, seed: u32, octaves: u32, per: i32) -> f32 {
    let (mut sum, mut amp, mut f, mut norm) = (0.0, 0.5, 1.0, 0.0);
    for o in 0..octaves {
        let p = if per > 0 { per * f as i32 } else { 0 };
        sum += amp * value_noise(x * f, y * f, z * f, seed + o, p);
        norm += amp;
        amp *= 0.5;
        f *= 2.0;
    }
    sum / norm
}
