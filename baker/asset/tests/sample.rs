//! Point sampling: trilinear interpolation against a hand computation from the dense voxel
//! function, and keyframe blending for dynamic assets.
mod common;
use common::*;
use snerf_asset::{decode_density, encode_voxel, AssetBuilder, Header, Keyframe, Kind, ViewMlp};

fn hash_voxel(h: &Header, v: [usize; 3]) -> [u8; 8] {
    let mut x = (v[0] * 73856093) ^ (v[1] * 19349663) ^ (v[2] * 83492791);
    let mut out = [0u8; 8];
    for o in out.iter_mut() {
        x = x.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        *o = (x >> 33) as u8;
    }
    let _ = h;
    out
}

/// Trilinear of decoded values straight from the global voxel function (edges clamped).
fn manual(h: &Header, f: &dyn Fn([usize; 3]) -> [u8; 8], g: [f32; 3]) -> [f32; 8] {
    let res = h.res as i64;
    let mut i0 = [0i64; 3];
    let mut w = [0f32; 3];
    for a in 0..3 {
        let u = (g[a] + 1.0) * 0.5 * res as f32 - 0.5;
        i0[a] = u.floor() as i64;
        w[a] = u - u.floor();
    }
    let mut out = [0f32; 8];
    for corner in 0..8usize {
        let d = [corner & 1, (corner >> 1) & 1, corner >> 2];
        let mut wt = 1.0;
        let mut v = [0usize; 3];
        for a in 0..3 {
            wt *= if d[a] == 1 { w[a] } else { 1.0 - w[a] };
            v[a] = (i0[a] + d[a] as i64).clamp(0, res - 1) as usize;
        }
        let vox = f(v);
        out[0] += wt * decode_density(vox[0], &h.density);
        for c in 1..8 {
            out[c] += wt * vox[c] as f32 / 255.0;
        }
    }
    out
}

fn close(a: [f32; 8], b: [f32; 8], tol: f32) -> bool {
    a.iter().zip(&b).all(|(x, y)| (x - y).abs() <= tol)
}

#[test]
fn trilinear_matches_hand_computation() {
    let h = Header::new(Kind::Object, 16, 4);
    let mut b = AssetBuilder::new(h.clone(), ViewMlp::zeros()).unwrap();
    for z in 0..4 {
        for y in 0..4 {
            for x in 0..4 {
                let blk = b.block_from_fn([x, y, z], |v| hash_voxel(&h, v));
                b.set_block(0, [x, y, z], &blk).unwrap();
            }
        }
    }
    let a = b.finish().unwrap();
    let mut rng = Rng(7);
    for i in 0..5000 {
        let g = if i < 8 {
            // corners and edges of the grid
            [[-1.0, -1.0, -1.0], [1.0, 1.0, 1.0], [1.0, -1.0, 0.0], [0.0, 0.0, 0.0]][i % 4]
        } else {
            [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)]
        };
        let s = a.sample(0, g).expect("all cells occupied");
        let m = manual(&h, &|v| hash_voxel(&h, v), g);
        assert!(close(s, m, 2e-4), "at {:?}: {:?} vs {:?}", g, s, m);
    }
    assert!(a.sample(0, [1.0001, 0.0, 0.0]).is_none());
    assert!(a.sample(0, [f32::NAN, 0.0, 0.0]).is_none());
    assert!(a.sample(5, [0.0; 3]).is_none());
}

#[test]
fn sparse_sampling_matches_and_empty_is_none() {
    let a = sphere_asset(false);
    let h = a.header.clone();
    let g = a.grid_dim();
    let mut rng = Rng(99);
    let (mut hits, mut misses) = (0, 0);
    for _ in 0..5000 {
        let p = [rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)];
        let cell = p.map(|x| (((x + 1.0) * 0.5 * g as f32) as usize).min(g - 1));
        match a.sample(0, p) {
            Some(s) => {
                assert!(sphere_cell_occupied(cell));
                let m = manual(&h, &|v| sphere_voxel(&h, v, 0), p);
                assert!(close(s, m, 2e-4), "at {:?}: {:?} vs {:?}", p, s, m);
                hits += 1;
            }
            None => {
                assert!(!sphere_cell_occupied(cell));
                misses += 1;
            }
        }
    }
    assert!(hits > 100 && misses > 100);
}

#[test]
fn dynamic_interpolation() {
    let a = sphere_asset(true);
    let mut rng = Rng(5);
    let mut changed = 0;
    for _ in 0..2000 {
        let p = [rng.range(-0.7, 0.7), rng.range(-0.7, 0.7), rng.range(-0.7, 0.7)];
        for k in 0..3 {
            assert_eq!(a.sample_at_time(k as f32, p), a.sample(k, p));
        }
        assert_eq!(a.sample_at_time(-3.0, p), a.sample(0, p));
        assert_eq!(a.sample_at_time(9.0, p), a.sample(2, p));
        assert_eq!(a.sample_at_time(f32::NAN, p), a.sample(0, p));
        if let (Some(s0), Some(s1)) = (a.sample(0, p), a.sample(1, p)) {
            let mid = a.sample_at_time(0.5, p).unwrap();
            let want: Vec<f32> = (0..8).map(|c| 0.5 * (s0[c] + s1[c])).collect();
            assert!(close(mid, want.try_into().unwrap(), 1e-5));
            let q = a.sample_at_time(1.25, p).unwrap();
            let s2 = a.sample(2, p).unwrap();
            assert!((q[3] - (0.75 * s1[3] + 0.25 * s2[3])).abs() < 1e-5);
            changed += (s0 != s1) as u32;
        }
    }
    assert!(changed > 50, "{}", changed);
}

/// Two keyframes, one block at the first and nothing at the second (a surface that goes).
fn one_block_then_empty(colour_by_density: bool) -> (Header, snerf_asset::Asset) {
    let mut h = Header::new(Kind::Object, 8, 4);
    h.time_range = Some([0.0, 1.0]);
    h.frames = Some(vec![Keyframe { time: 0.0 }, Keyframe { time: 1.0 }]);
    h.colour_by_density = colour_by_density;
    let mut b = AssetBuilder::new(h.clone(), ViewMlp::zeros()).unwrap();
    let blk = b.block_from_fn([0, 0, 0], |_| encode_voxel(5.0, [1.0, 0.5, 0.0], [1.0; 4], &h.density));
    b.set_block(0, [0, 0, 0], &blk).unwrap();
    (h, b.finish().unwrap())
}

#[test]
fn empty_side_counts_as_lowest_density_and_zero() {
    let (h, a) = one_block_then_empty(false);
    let p = [-0.5, -0.5, -0.5];
    let v0 = a.sample(0, p).unwrap();
    assert!(a.sample(1, p).is_none());
    let mid = a.sample_at_time(0.5, p).unwrap();
    let lo = h.density.logit_min;
    assert!((mid[0] - 0.5 * (v0[0] + lo)).abs() < 1e-5);
    for c in 1..8 {
        assert!((mid[c] - 0.5 * v0[c]).abs() < 1e-6);
    }
    assert!(a.sample_at_time(1.0, p).is_none());
}

/// With `colour_by_density` the empty side adds no colour: a surface that is present at one
/// keyframe and gone at the next keeps its colour while its density fades (the logit still
/// blends linearly), instead of fading through black.
#[test]
fn colour_by_density_keeps_the_dense_sides_colour() {
    let (h, a) = one_block_then_empty(true);
    let p = [-0.5, -0.5, -0.5];
    let v0 = a.sample(0, p).unwrap();
    let lo = h.density.logit_min;
    for t in [0.1f32, 0.5, 0.9] {
        let mid = a.sample_at_time(t, p).unwrap();
        assert!((mid[0] - ((1.0 - t) * v0[0] + t * lo)).abs() < 1e-4, "logit at {t}");
        // the empty side weighs t·exp(lo) against (1 − t)·exp(v0): exp(−15) of the colour here
        for c in 1..8 {
            assert!((mid[c] - v0[c]).abs() < 1e-4, "channel {c} at {t}: {} against {}", mid[c], v0[c]);
        }
    }
}

/// The colour weight: w where both sides are equally dense, each side's density share
/// otherwise, 0 and 1 at the ends, finite (never NaN) at any logits.
#[test]
fn blend_weight_is_the_density_share() {
    use snerf_asset::sample::blend_weight;
    for w in [0.1f32, 0.5, 0.75] {
        assert!((blend_weight(2.0, 2.0, w) - w).abs() < 1e-6);
        let (sa, sb) = (1.5f32.exp(), (-0.5f32).exp());
        let want = w * sb / ((1.0 - w) * sa + w * sb);
        assert!((blend_weight(1.5, -0.5, w) - want).abs() < 1e-6, "{w}");
    }
    assert!(blend_weight(3.0, -3.0, 0.0) < 1e-20);
    assert_eq!(blend_weight(3.0, -3.0, 1.0), 1.0);
    assert_eq!(blend_weight(-3.0, 3.0, 1.0), 1.0);
    for (la, lb) in [(-1e30f32, 1e30f32), (1e30, -1e30), (0.0, 0.0)] {
        for w in [0.0f32, 1e-7, 0.5, 1.0 - 1e-7, 1.0] {
            let x = blend_weight(la, lb, w);
            assert!((0.0..=1.0).contains(&x), "{la} {lb} {w}: {x}");
        }
    }
}

/// The key only means something between keyframes: a static header with it is refused.
#[test]
fn colour_by_density_on_a_static_header_is_refused() {
    let mut h = Header::new(Kind::Object, 8, 4);
    h.colour_by_density = true;
    let e = h.validate().unwrap_err().to_string();
    assert!(e.contains("colour_by_density") && e.contains("static"), "{e}");
}
