//! Small linear-algebra helpers: 3-vectors, row-major 4x4 matrices, quaternions, a seeded RNG
//! and value noise. Kept local so the crate needs no maths dependency.

use std::ops::{Add, Mul, Neg, Sub};

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct V3 {
    pub x: f32,
    pub y: f32,
    pub z: f32,
}

pub const fn v3(x: f32, y: f32, z: f32) -> V3 {
    V3 { x, y, z }
}

impl V3 {
    pub fn from_arr(a: [f32; 3]) -> V3 {
        v3(a[0], a[1], a[2])
    }
    pub fn arr(self) -> [f32; 3] {
        [self.x, self.y, self.z]
    }
    pub fn dot(self, o: V3) -> f32 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    pub fn cross(self, o: V3) -> V3 {
        v3(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    pub fn len(self) -> f32 {
        self.dot(self).sqrt()
    }
    pub fn norm(self) -> V3 {
        let l = self.len();
        if l > 1e-20 {
            self * (1.0 / l)
        } else {
            v3(0.0, 1.0, 0.0)
        }
    }
    pub fn mul_elem(self, o: V3) -> V3 {
        v3(self.x * o.x, self.y * o.y, self.z * o.z)
    }
    pub fn min(self, o: V3) -> V3 {
        v3(self.x.min(o.x), self.y.min(o.y), self.z.min(o.z))
    }
    pub fn max(self, o: V3) -> V3 {
        v3(self.x.max(o.x), self.y.max(o.y), self.z.max(o.z))
    }
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
}

impl Add for V3 {
    type Output = V3;
    fn add(self, o: V3) -> V3 {
        v3(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl Sub for V3 {
    type Output = V3;
    fn sub(self, o: V3) -> V3 {
        v3(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl Mul<f32> for V3 {
    type Output = V3;
    fn mul(self, s: f32) -> V3 {
        v3(self.x * s, self.y * s, self.z * s)
    }
}
impl Neg for V3 {
    type Output = V3;
    fn neg(self) -> V3 {
        v3(-self.x, -self.y, -self.z)
    }
}

pub fn lerp(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

pub fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Row-major 4x4 matrix: `m[row][col]`, column vectors (p' = M p).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mat4 {
    pub m: [[f32; 4]; 4],
}

impl Mat4 {
    pub const IDENTITY: Mat4 = Mat4 {
        m: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ],
    };

    /// From glTF's column-major 4x4 (`cols[c][r]`).
    pub fn from_cols(cols: [[f32; 4]; 4]) -> Mat4 {
        let mut m = [[0.0; 4]; 4];
        for (c, col) in cols.iter().enumerate() {
            for (r, v) in col.iter().enumerate() {
                m[r][c] = *v;
            }
        }
        Mat4 { m }
    }

    pub fn translate(t: V3) -> Mat4 {
        let mut r = Mat4::IDENTITY;
        r.m[0][3] = t.x;
        r.m[1][3] = t.y;
        r.m[2][3] = t.z;
        r
    }

    pub fn scale(s: V3) -> Mat4 {
        let mut r = Mat4::IDENTITY;
        r.m[0][0] = s.x;
        r.m[1][1] = s.y;
        r.m[2][2] = s.z;
        r
    }

    /// Rotation about a (unit) axis by `angle` radians.
    pub fn rotate(axis: V3, angle: f32) -> Mat4 {
        let a = axis.norm();
        let h = angle * 0.5;
        let s = h.sin();
        Mat4::from_quat([a.x * s, a.y * s, a.z * s, h.cos()])
    }

    /// Quaternion in glTF order (x, y, z, w).
    pub fn from_quat(q: [f32; 4]) -> Mat4 {
        let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        let [x, y, z, w] = if n > 0.0 {
            [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
        } else {
            [0.0, 0.0, 0.0, 1.0]
        };
        Mat4 {
            m: [
                [
                    1.0 - 2.0 * (y * y + z * z),
                    2.0 * (x * y - z * w),
                    2.0 * (x * z + y * w),
                    0.0,
                ],
                [
                    2.0 * (x * y + z * w),
                    1.0 - 2.0 * (x * x + z * z),
                    2.0 * (y * z - x * w),
                    0.0,
                ],
                [
                    2.0 * (x * z - y * w),
                    2.0 * (y * z + x * w),
                    1.0 - 2.0 * (x * x + y * y),
                    0.0,
                ],
                [0.0, 0.0, 0.0, 1.0],
            ],
        }
    }

    pub fn trs(t: [f32; 3], r: [f32; 4], s: [f32; 3]) -> Mat4 {
        Mat4::translate(V3::from_arr(t)) * Mat4::from_quat(r) * Mat4::scale(V3::from_arr(s))
    }

    pub fn point(&self, p: V3) -> V3 {
        let m = &self.m;
        v3(
            m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
            m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
            m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3],
        )
    }

    pub fn dir(&self, p: V3) -> V3 {
        let m = &self.m;
        v3(
            m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z,
            m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z,
            m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z,
        )
    }

    pub fn col(&self, c: usize) -> V3 {
        v3(self.m[0][c], self.m[1][c], self.m[2][c])
    }

    /// Matrix that transforms normals: inverse-transpose of the upper 3x3 (cofactor matrix,
    /// which differs only by the positive/negative determinant; normals are renormalized).
    pub fn normal_matrix(&self) -> Mat4 {
        let a = &self.m;
        let c = |r0: usize, r1: usize, c0: usize, c1: usize| {
            a[r0][c0] * a[r1][c1] - a[r0][c1] * a[r1][c0]
        };
        let mut n = Mat4::IDENTITY;
        n.m[0][0] = c(1, 2, 1, 2);
        n.m[0][1] = -c(1, 2, 0, 2);
        n.m[0][2] = c(1, 2, 0, 1);
        n.m[1][0] = -c(0, 2, 1, 2);
        n.m[1][1] = c(0, 2, 0, 2);
        n.m[1][2] = -c(0, 2, 0, 1);
        n.m[2][0] = c(0, 1, 1, 2);
        n.m[2][1] = -c(0, 1, 0, 2);
        n.m[2][2] = c(0, 1, 0, 1);
        let det = a[0][0] * n.m[0][0] + a[0][1] * n.m[0][1] + a[0][2] * n.m[0][2];
        if det < 0.0 {
            for r in 0..3 {
                for cc in 0..3 {
                    n.m[r][cc] = -n.m[r][cc];
                }
            }
        }
        n
    }

    /// Inverse of a rigid transform (rotation + translation).
    pub fn rigid_inverse(&self) -> Mat4 {
        let mut r = Mat4::IDENTITY;
        for i in 0..3 {
            for j in 0..3 {
                r.m[i][j] = self.m[j][i];
            }
        }
        let t = r.dir(self.col(3));
        r.m[0][3] = -t.x;
        r.m[1][3] = -t.y;
        r.m[2][3] = -t.z;
        r
    }

    pub fn rows(&self) -> Vec<Vec<f32>> {
        self.m.iter().map(|r| r.to_vec()).collect()
    }
}

impl Mul for Mat4 {
    type Output = Mat4;
    fn mul(self, o: Mat4) -> Mat4 {
        let mut r = [[0.0f32; 4]; 4];
        for (i, row) in r.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (0..4).map(|k| self.m[i][k] * o.m[k][j]).sum();
            }
        }
        Mat4 { m: r }
    }
}

/// Camera-to-world matrix (OpenGL convention: x right, y up, looking down -z) for a camera
/// at `eye` looking at `target`.
pub fn look_at(eye: V3, target: V3, up: V3) -> Mat4 {
    let f = (target - eye).norm();
    let mut right = f.cross(up);
    if right.len() < 1e-4 {
        right = f.cross(v3(0.0, 0.0, 1.0));
    }
    let right = right.norm();
    let u = right.cross(f).norm();
    let b = -f;
    Mat4 {
        m: [
            [right.x, u.x, b.x, eye.x],
            [right.y, u.y, b.y, eye.y],
            [right.z, u.z, b.z, eye.z],
            [0.0, 0.0, 0.0, 1.0],
        ],
    }
}

/// Spherical linear interpolation of unit quaternions (x, y, z, w).
pub fn slerp(a: [f32; 4], b: [f32; 4], t: f32) -> [f32; 4] {
    let mut b = b;
    let mut d: f32 = (0..4).map(|i| a[i] * b[i]).sum();
    if d < 0.0 {
        d = -d;
        b = [-b[0], -b[1], -b[2], -b[3]];
    }
    let (wa, wb) = if d > 0.9995 {
        (1.0 - t, t)
    } else {
        let th = d.clamp(-1.0, 1.0).acos();
        let s = th.sin();
        (((1.0 - t) * th).sin() / s, (t * th).sin() / s)
    };
    let q = [0, 1, 2, 3].map(|i| wa * a[i] + wb * b[i]);
    normalize_quat(q)
}

pub fn normalize_quat(q: [f32; 4]) -> [f32; 4] {
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if n > 0.0 && n.is_finite() {
        q.map(|v| v / n)
    } else {
        [0.0, 0.0, 0.0, 1.0]
    }
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
    let a = lerp(
        lerp(g(0, 0, 0), g(1, 0, 0), sx),
        lerp(g(0, 1, 0), g(1, 1, 0), sx),
        sy,
    );
    let b = lerp(
        lerp(g(0, 0, 1), g(1, 0, 1), sx),
        lerp(g(0, 1, 1), g(1, 1, 1), sx),
        sy,
    );
    lerp(a, b, sz)
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
