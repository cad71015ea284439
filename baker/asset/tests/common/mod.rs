//! Synthetic assets shared by the tests: a sphere of density with per-cell colours, static
//! or as 3 keyframes where only some blocks change (so blocks are shared between frames).
#![allow(dead_code)]

use snerf_asset::{encode_voxel, Asset, AssetBuilder, Header, Keyframe, Kind, ViewMlp};

pub const RES: u32 = 32;
pub const BLOCK: u32 = 8;

/// Voxel centre in grid space.
pub fn centre(i: usize) -> f32 {
    -1.0 + (i as f32 + 0.5) * 2.0 / RES as f32
}

/// The sphere's voxel at global index `v` in keyframe `frame`: dense inside radius 0.6;
/// colour depends on the cell and, for x-cells >= 2, on the frame (those blocks change).
pub fn sphere_voxel(h: &Header, v: [usize; 3], frame: usize) -> [u8; 8] {
    let p = [centre(v[0]), centre(v[1]), centre(v[2])];
    let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    let logit = if r < 0.6 { 3.0 } else { -8.0 };
    let cell = v.map(|i| i / BLOCK as usize);
    let changing = cell[0] >= 2 && frame > 0;
    let tint = if changing { 0.3 * frame as f32 } else { 0.0 };
    let rgb = [0.2 + 0.2 * cell[0] as f32, 0.1 + 0.25 * cell[1] as f32, (0.15 * cell[2] as f32 + tint).min(1.0)];
    encode_voxel(logit, rgb, [0.1, 0.2, 0.3, 0.4], &h.density)
}

/// Cells whose box comes within the sphere (plus a margin) are stored.
pub fn sphere_cell_occupied(c: [usize; 3]) -> bool {
    let g = (RES / BLOCK) as f32;
    let mut d2 = 0.0;
    for ca in c {
        let lo = -1.0 + ca as f32 * 2.0 / g;
        let hi = lo + 2.0 / g;
        let q = 0.0f32.clamp(lo, hi);
        d2 += q * q;
    }
    d2.sqrt() < 0.7
}

pub fn sphere_header(dynamic: bool) -> Header {
    let mut h = Header::new(Kind::Object, RES, BLOCK);
    h.background = [0.0, 0.0, 0.0];
    if dynamic {
        h.time_range = Some([0.0, 2.0]);
        h.frames = Some(vec![Keyframe { time: 0.0 }, Keyframe { time: 1.0 }, Keyframe { time: 2.0 }]);
    }
    h
}

pub fn small_mlp() -> ViewMlp {
    let mut m = ViewMlp::zeros();
    for (i, w) in m.w1.iter_mut().enumerate() {
        *w = ((i * 7919) % 13) as f32 * 0.01 - 0.06;
    }
    for (i, w) in m.w2.iter_mut().enumerate() {
        *w = ((i * 104729) % 11) as f32 * 0.01 - 0.05;
    }
    for (i, w) in m.w3.iter_mut().enumerate() {
        *w = ((i * 31) % 7) as f32 * 0.01 - 0.03;
    }
    m.b3 = vec![0.01, -0.02, 0.03];
    m
}

pub fn sphere_asset(dynamic: bool) -> Asset {
    let h = sphere_header(dynamic);
    let frames = h.num_frames();
    let g = h.grid_dim();
    let mut b = AssetBuilder::new(h.clone(), small_mlp()).unwrap();
    for f in 0..frames {
        for z in 0..g {
            for y in 0..g {
                for x in 0..g {
                    if sphere_cell_occupied([x, y, z]) {
                        let block = b.block_from_fn([x, y, z], |v| sphere_voxel(&h, v, f));
                        b.set_block(f, [x, y, z], &block).unwrap();
                    }
                }
            }
        }
    }
    b.finish().unwrap()
}

/// Tiny deterministic RNG for tests (xorshift64*).
pub struct Rng(pub u64);
impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    pub fn below(&mut self, n: u64) -> u64 {
        if n == 0 {
            0
        } else {
            self.next() % n
        }
    }
    pub fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.unit()
    }
}
