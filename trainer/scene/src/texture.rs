//! Textures: 8-bit sRGB images with a box-filtered mip pyramid, sampled trilinearly
//! (bilinear within a level) with per-axis wrap modes as in glTF samplers.

use std::sync::OnceLock;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Wrap {
    Repeat,
    Mirror,
    Clamp,
}

struct Level {
    w: usize,
    h: usize,
    /// sRGB-encoded RGB, linear alpha.
    data: Vec<[u8; 4]>,
}

pub struct Texture {
    levels: Vec<Level>,
    pub wrap_s: Wrap,
    pub wrap_t: Wrap,
}

fn srgb_lut() -> &'static [f32; 256] {
    static LUT: OnceLock<[f32; 256]> = OnceLock::new();
    LUT.get_or_init(|| {
        let mut t = [0.0; 256];
        for (i, v) in t.iter_mut().enumerate() {
            *v = srgb_to_linear(i as f32 / 255.0);
        }
        t
    })
}

pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

pub fn linear_to_srgb(c: f32) -> f32 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// Linear [0,1] -> 8-bit sRGB.
pub fn encode_srgb8(c: f32) -> u8 {
    (linear_to_srgb(c) * 255.0 + 0.5) as u8
}

impl Texture {
    /// From 8-bit sRGB RGBA texels (row 0 = top = v 0, as in glTF).
    pub fn from_srgba8(
        w: usize,
        h: usize,
        data: Vec<[u8; 4]>,
        wrap_s: Wrap,
        wrap_t: Wrap,
    ) -> Texture {
        assert_eq!(data.len(), w * h);
        let lut = srgb_lut();
        let mut levels = vec![Level { w, h, data }];
        while levels.last().map(|l| l.w > 1 || l.h > 1).unwrap_or(false) {
            let prev = levels.last().unwrap();
            let (nw, nh) = ((prev.w / 2).max(1), (prev.h / 2).max(1));
            let mut data = Vec::with_capacity(nw * nh);
            for y in 0..nh {
                for x in 0..nw {
                    let mut acc = [0.0f32; 4];
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let sx = (2 * x + dx).min(prev.w - 1);
                        let sy = (2 * y + dy).min(prev.h - 1);
                        let t = prev.data[sy * prev.w + sx];
                        for c in 0..3 {
                            acc[c] += lut[t[c] as usize];
                        }
                        acc[3] += t[3] as f32 / 255.0;
                    }
                    data.push([
                        encode_srgb8(acc[0] / 4.0),
                        encode_srgb8(acc[1] / 4.0),
                        encode_srgb8(acc[2] / 4.0),
                        (acc[3] / 4.0 * 255.0 + 0.5) as u8,
                    ]);
                }
            }
            levels.push(Level { w: nw, h: nh, data });
        }
        Texture {
            levels,
            wrap_s,
            wrap_t,
        }
    }

    /// A procedural texture: `f(u, v)` returns linear RGBA; each texel averages 2x2 samples.
    pub fn from_fn(
        w: usize,
        h: usize,
        wrap: Wrap,
        f: impl Fn(f32, f32) -> [f32; 4] + Sync,
    ) -> Texture {
        use rayon::prelude::*;
        let data: Vec<[u8; 4]> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let mut acc = [0.0f32; 4];
                for (ox, oy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                    let c = f((x as f32 + ox) / w as f32, (y as f32 + oy) / h as f32);
                    for k in 0..4 {
                        acc[k] += c[k] * 0.25;
                    }
                }
                [
                    encode_srgb8(acc[0]),
                    encode_srgb8(acc[1]),
                    encode_srgb8(acc[2]),
                    (acc[3].clamp(0.0, 1.0) * 255.0 + 0.5) as u8,
                ]
            })
            .collect();
        Texture::from_srgba8(w, h, data, wrap, wrap)
    }

    pub fn size(&self) -> (usize, usize) {
        (self.levels[0].w, self.levels[0].h)
    }

    fn wrap(i: i64, n: usize, mode: Wrap) -> usize {
        let n = n as i64;
        (match mode {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::Clamp => i.clamp(0, n - 1),
            Wrap::Mirror => {
                let p = i.rem_euclid(2 * n);
                if p < n {
                    p
                } else {
                    2 * n - 1 - p
                }
            }
        }) as usize
    }

    fn bilinear(&self, level: usize, u: f32, v: f32) -> [f32; 4] {
        let l = &self.levels[level];
        let lut = srgb_lut();
        let x = u * l.w as f32 - 0.5;
        let y = v * l.h as f32 - 0.5;
        // Keep coordinates in a sane range so huge UVs cannot overflow.
        let (x, y) = (x.clamp(-1e7, 1e7), y.clamp(-1e7, 1e7));
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let (x0, y0) = (x0 as i64, y0 as i64);
        let xs = [
            Self::wrap(x0, l.w, self.wrap_s),
            Self::wrap(x0 + 1, l.w, self.wrap_s),
        ];
        let ys = [
            Self::wrap(y0, l.h, self.wrap_t),
            Self::wrap(y0 + 1, l.h, self.wrap_t),
        ];
        let mut out = [0.0f32; 4];
        for (j, wy) in [(0, 1.0 - fy), (1, fy)] {
            for (i, wx) in [(0, 1.0 - fx), (1, fx)] {
                let t = l.data[ys[j] * l.w + xs[i]];
                let w = wx * wy;
                out[0] += w * lut[t[0] as usize];
                out[1] += w * lut[t[1] as usize];
                out[2] += w * lut[t[2] as usize];
                out[3] += w * (t[3] as f32 * (1.0 / 255.0));
            }
        }
        out
    }

    /// Linear RGBA at `uv`; `footprint` is the size of the sample in texels of level 0
    /// (selects the mip level; trilinear between levels).
    pub fn sample(&self, u: f32, v: f32, footprint: f32) -> [f32; 4] {
        if !(u.is_finite() && v.is_finite()) {
            return self.bilinear(self.levels.len() - 1, 0.5, 0.5);
        }
        let lod = if footprint > 1.0 {
            footprint.log2()
        } else {
            0.0
        };
        let max = (self.levels.len() - 1) as f32;
        let lod = if lod.is_finite() { lod.min(max) } else { max };
        let l0 = lod.floor() as usize;
        let f = lod - l0 as f32;
        let a = self.bilinear(l0, u, v);
        if f < 1e-3 || l0 + 1 >= self.levels.len() {
            return a;
        }
        let b = self.bilinear(l0 + 1, u, v);
        [0, 1, 2, 3].map(|k| a[k] + (b[k] - a[k]) * f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_modes() {
        assert_eq!(Texture::wrap(-1, 4, Wrap::Repeat), 3);
        assert_eq!(Texture::wrap(-1, 4, Wrap::Clamp), 0);
        assert_eq!(Texture::wrap(4, 4, Wrap::Mirror), 3);
        assert_eq!(Texture::wrap(-1, 4, Wrap::Mirror), 0);
    }

    #[test]
    fn mip_of_checker_is_grey() {
        let t = Texture::from_fn(64, 64, Wrap::Repeat, |u, v| {
            let c = (((u * 8.0) as i32 + (v * 8.0) as i32) % 2) as f32;
            [c, c, c, 1.0]
        });
        let fine = t.sample(0.5 / 8.0 * 0.5, 0.5 / 8.0 * 0.5, 1.0);
        assert!(fine[0] > 0.95 || fine[0] < 0.05);
        let coarse = t.sample(0.3, 0.7, 64.0);
        assert!((coarse[0] - 0.5).abs() < 0.03, "{coarse:?}");
    }
}
