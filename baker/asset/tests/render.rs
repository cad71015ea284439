//! The reference renderer against closed forms, and robustness for rays in any direction.
mod common;
use common::*;
use snerf_asset::render::{camera_ray, render_ray};
use snerf_asset::{
    contact_strip, decode_density, encode_voxel, orbit, render, render_pixel, write_png, Asset, AssetBuilder, Camera,
    Header, Kind, Ndc, ViewMlp,
};

const CODE: u8 = 130;
const COLOUR: [u8; 3] = [200, 60, 20];

/// res 32, block 8, identity object space; cells with z-index < 2 (model z < 0) hold a
/// uniform density/colour, everything else is empty. Zero MLP.
fn half_slab(t_terminate: f32) -> Asset {
    let mut h = Header::new(Kind::Object, 32, 8);
    h.march.step = 2.0 / 64.0;
    h.march.t_terminate = t_terminate;
    h.background = [0.2, 0.4, 0.6];
    let mut b = AssetBuilder::new(h.clone(), ViewMlp::zeros()).unwrap();
    for z in 0..2 {
        for y in 0..4 {
            for x in 0..4 {
                let blk = b.block_from_fn([x, y, z], |_| [CODE, COLOUR[0], COLOUR[1], COLOUR[2], 0, 0, 0, 0]);
                b.set_block(0, [x, y, z], &blk).unwrap();
            }
        }
    }
    b.finish().unwrap()
}

#[test]
fn constant_slab_matches_closed_form() {
    let a = half_slab(0.0);
    let sigma = (decode_density(CODE, &a.header.density) as f64).exp();
    let dt = 1.0f64 / 32.0;
    // Ray straight down -z from z = 3: box from t = 2 to 4, the slab (z < 0) from t = 3 to 4,
    // which holds exactly 32 lattice points t = 2 + (i + 0.5) dt, i = 32..63.
    let cam = Camera {
        c2w: [[1.0, 0.0, 0.0, 0.013], [0.0, 1.0, 0.0, -0.021], [0.0, 0.0, 1.0, 3.0]],
        fx: 1.0,
        fy: 1.0,
        cx: 0.5,
        cy: 0.5,
        width: 1,
        height: 1,
    };
    let p = render_pixel(&a, &cam, 0, 0, 0.0);
    assert_eq!(p.samples, 32);
    let t_final = (-sigma).exp();
    let opacity = 1.0 - t_final;
    assert!((p.opacity as f64 - opacity).abs() < 1e-3, "{} vs {}", p.opacity, opacity);
    for (c, &col) in COLOUR.iter().enumerate() {
        let want = col as f64 / 255.0 * opacity + t_final * a.header.background[c] as f64;
        assert!((p.rgb[c] as f64 - want).abs() < 1e-3, "channel {}: {} vs {}", c, p.rgb[c], want);
    }
    // depth: geometric weights over the 32 samples
    let a_k = 1.0 - (-sigma * dt).exp();
    let (mut num, mut den) = (0.0, 0.0);
    for k in 0..32 {
        let w = (-sigma * dt * k as f64).exp() * a_k;
        num += w * (3.0 + (k as f64 + 0.5) * dt);
        den += w;
    }
    assert!((p.depth as f64 - num / den).abs() < 1e-3, "{} vs {}", p.depth, num / den);

    // The same ray marched without empty-space skipping must agree: compare against a dense
    // asset whose "empty" half is stored explicitly with the lowest density code... the
    // lowest code still has a small σ, so instead check that skipping changes nothing by
    // rendering a ray that starts inside the slab (no empty cells before it).
    let inside = render_ray(&a, [0.013, -0.021, -0.5], [0.0, 0.0, -1.0], 0.0);
    // t from 0 to 0.5 (box exit at z = -1): 16 samples
    assert_eq!(inside.samples, 16);
    assert!((inside.opacity as f64 - (1.0 - (-sigma * 0.5).exp())).abs() < 1e-3);
}

#[test]
fn stops_at_t_terminate() {
    let a = half_slab(0.5);
    let sigma = (decode_density(CODE, &a.header.density) as f64).exp();
    let sd = sigma / 32.0;
    let n = (std::f64::consts::LN_2 / sd).ceil() as u32; // first n with exp(-n sd) < 0.5
    let p = render_ray(&a, [0.013, -0.021, 3.0], [0.0, 0.0, -1.0], 0.0);
    assert_eq!(p.samples, n);
    assert!(n < 32);
    assert!((p.opacity as f64 - (1.0 - (-sd * n as f64).exp())).abs() < 1e-4);
    let full = render_ray(&half_slab(0.0), [0.013, -0.021, 3.0], [0.0, 0.0, -1.0], 0.0);
    assert!(full.opacity > p.opacity + 0.05);
}

#[test]
fn view_mlp_adds_specular() {
    let mut a = half_slab(0.0);
    let base = render_ray(&a, [0.0, 0.0, 3.0], [0.0, 0.0, -1.0], 0.0);
    a.mlp.b3 = vec![0.1, 0.0, -0.1];
    let spec = render_ray(&a, [0.0, 0.0, 3.0], [0.0, 0.0, -1.0], 0.0);
    assert!((spec.rgb[0] - (base.rgb[0] + 0.1 * base.opacity)).abs() < 1e-5);
    assert!((spec.rgb[2] - (base.rgb[2] - 0.1 * base.opacity)).abs() < 1e-5);
    // ViewMlp input layout
    let x = ViewMlp::input(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0], [0.0, 0.6, 0.8]);
    assert_eq!(&x[..10], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 0.0, 0.6, 0.8]);
    assert_eq!((x[10], x[11]), (0.0, 1.0));
    let f = 8.0 * std::f32::consts::PI;
    assert!((x[32] - (f * 0.8).sin()).abs() < 1e-6 && (x[33] - (f * 0.8).cos()).abs() < 1e-6);
}

fn check_finite(p: &snerf_asset::PixelResult, what: &str) {
    assert!(p.rgb.iter().all(|c| c.is_finite() && (0.0..=1.0).contains(c)), "{}: {:?}", what, p);
    assert!(p.depth.is_finite() && p.opacity.is_finite() && (0.0..=1.0001).contains(&p.opacity), "{}: {:?}", what, p);
}

fn dense_asset(kind: Kind) -> Asset {
    let mut h = Header::new(kind, 16, 4);
    h.march.step = 2.0 / 48.0;
    h.density.logit_max = 80.0; // huge σ at the top codes: the clamp must hold
    if kind == Kind::Forward {
        h.space.ndc = Some(Ndc { fx: 50.0, fy: 50.0, width: 100.0, height: 80.0, near: 1.0, xy_extent: 1.25 });
    }
    let mut b = AssetBuilder::new(h.clone(), small_mlp()).unwrap();
    for z in 0..4 {
        for y in 0..4 {
            for x in 0..4 {
                if (x + y + z) % 3 == 0 {
                    continue;
                }
                let blk = b.block_from_fn([x, y, z], |v| {
                    let s = ((v[0] * 7 + v[1] * 13 + v[2] * 5) % 11) as f32 / 10.0;
                    encode_voxel(-10.0 + 90.0 * s * s, [s, 1.0 - s, 0.5], [s; 4], &h.density)
                });
                b.set_block(0, [x, y, z], &blk).unwrap();
            }
        }
    }
    b.finish().unwrap()
}

#[test]
fn unbounded_and_forward_are_finite_for_any_ray() {
    let mut dirs: Vec<[f32; 3]> = vec![
        [0.0, 1.0, 0.0],
        [0.0, -1.0, 0.0],
        [0.0, 0.0, 1.0],
        [0.0, 0.0, -1.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, 0.0],
        [1e-30, 0.0, -1e-30],
        [f32::NAN, 0.0, 1.0],
        [0.0, 0.0, -1e-7],
    ];
    let mut rng = Rng(11);
    for _ in 0..300 {
        dirs.push([rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), rng.range(-1.0, 1.0)]);
    }
    let origins =
        [[0.0, 0.0, 0.0], [0.3, -0.2, 0.1], [5.0, 5.0, 5.0], [0.0, 0.0, 1e6], [-40.0, 3.0, 0.5], [0.0, 0.0, 0.99]];
    for kind in [Kind::Unbounded, Kind::Forward, Kind::Object] {
        let a = dense_asset(kind);
        let mut hit = 0;
        for o in origins {
            for d in &dirs {
                let p = render_ray(&a, o, *d, 0.0);
                check_finite(&p, &format!("{:?} o {:?} d {:?}", kind, o, d));
                hit += (p.opacity > 0.1) as u32;
            }
        }
        assert!(hit > 50, "{:?}: only {} rays hit anything", kind, hit);
        // forward: rays pointing up/away never reach the NDC volume
        if kind == Kind::Forward {
            let p = render_ray(&a, [0.0; 3], [0.0, 0.0, 1.0], 0.0);
            assert_eq!((p.opacity, p.rgb), (0.0, a.header.background));
            let p = render_ray(&a, [0.0; 3], [0.0, 0.0, -1.0], 0.0);
            assert!(p.opacity > 0.0, "{:?}", p);
        }
        if kind == Kind::Unbounded {
            // straight up from the middle still crosses the (occupied) contracted shell
            let p = render_ray(&a, [0.05, 0.0, 0.05], [0.0, 1.0, 0.0], 0.0);
            assert!(p.samples > 0, "{:?}", p);
        }
    }
}

#[test]
fn orbit_cameras_see_the_object_and_images_save() {
    let mut a = sphere_asset(false);
    // a non-trivial world placement: the orbit must map through it
    let (c, s) = (0.6f32.cos(), 0.6f32.sin());
    a.header.space.rot = [[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]];
    a.header.space.center = [1.0, -2.0, 0.5];
    a.header.space.scale = 0.5;
    let n = 6;
    let mut frames = Vec::new();
    for i in 0..n {
        let cam = orbit(&a.header, n, i, 24, 16, 40.0);
        let centre = render_pixel(&a, &cam, 12, 8, 0.0);
        assert!(centre.opacity > 0.9, "view {}: {:?}", i, centre);
        let corner = render_pixel(&a, &cam, 0, 0, 0.0);
        assert!(corner.opacity < 0.01, "view {}: {:?}", i, corner);
        let f = render(&a, &cam, 0.0);
        assert_eq!(f.rgb.len(), 24 * 16 * 3);
        let k = (8 * 24 + 12) as usize;
        assert_eq!(&f.rgb[3 * k..3 * k + 3], &centre.rgb);
        assert_eq!(f.opacity[k], centre.opacity);
        frames.push(f);
    }
    let dir = snerf_files::ScratchDir::new("snerf-asset-png", "strip").unwrap();
    write_png(&frames[0], dir.join("one.png")).unwrap();
    contact_strip(&frames, dir.join("strip.png")).unwrap();
    let img = image::open(dir.join("strip.png")).unwrap();
    assert_eq!((img.width(), img.height()), (24 * 6, 16));
    let one = image::open(dir.join("one.png")).unwrap().to_rgb8();
    let px = one.get_pixel(12, 8);
    assert_eq!(px.0[0], snerf_asset::quantize_unit(frames[0].rgb[3 * (8 * 24 + 12)]));
    drop(dir);

    // forward orbit: parallel cameras around the reference one, looking down model -z
    let f = dense_asset(Kind::Forward);
    let cam = orbit(&f.header, 8, 3, 10, 10, 50.0);
    let (o, d) = camera_ray(&cam, 4, 4);
    assert!((o[0].hypot(o[1]) - 0.1).abs() < 1e-5 && o[2].abs() < 1e-6, "{:?}", o);
    assert!(d[2] < -0.99, "{:?}", d);
}

#[test]
fn dynamic_render_follows_time() {
    let a = sphere_asset(true);
    // a ray through the changing half (x-cells >= 2, model x > 0)
    let o = [0.3, 0.05, 3.0];
    let d = [0.0, 0.0, -1.0];
    let r0 = render_ray(&a, o, d, 0.0);
    let r1 = render_ray(&a, o, d, 1.0);
    let rh = render_ray(&a, o, d, 0.5);
    assert!(r0.rgb != r1.rgb);
    assert!((rh.rgb[2] - 0.5 * (r0.rgb[2] + r1.rgb[2])).abs() < 0.02, "{:?} {:?} {:?}", r0, rh, r1);
    // through the unchanged half, time does not matter
    let o = [-0.3, 0.05, 3.0];
    assert_eq!(render_ray(&a, o, d, 0.0), render_ray(&a, o, d, 1.7));
}

#[test]
fn a_frame_as_a_static_asset_renders_as_that_frame() {
    let a = sphere_asset(true);
    let times: Vec<f32> = a.header.frames.as_ref().unwrap().iter().map(|k| k.time).collect();
    for (f, &t) in times.iter().enumerate() {
        let s = a.frame_as_static(f).unwrap();
        assert!(!s.is_dynamic() && s.header.frames.is_none() && s.grids.len() == 1);
        // Only the blocks that frame uses.
        let used: std::collections::HashSet<u32> = a.grids[f].iter().copied().filter(|&e| e != snerf_asset::EMPTY).collect();
        assert_eq!(s.header.atlas_blocks as usize, used.len());
        let cam = snerf_asset::orbit(&a.header, 3, 1, 32, 24, 40.0);
        assert_eq!(snerf_asset::render(&s, &cam, 0.0).rgb, snerf_asset::render(&a, &cam, t).rgb, "frame {f}");
        // And it survives the file format.
        assert_eq!(snerf_asset::Asset::from_bytes(&s.to_bytes()).unwrap().atlas, s.atlas);
    }
    assert!(a.frame_as_static(times.len()).is_err());
}

/// The march spelled out literally from the format description, with no empty-space
/// skipping and no box clipping: every lattice point is visited.
fn reference_ray(a: &Asset, ow: [f32; 3], dw: [f32; 3]) -> (f32, [f32; 7], f32, u32) {
    let h = &a.header;
    let n = (dw[0] * dw[0] + dw[1] * dw[1] + dw[2] * dw[2]).sqrt();
    let dw = dw.map(|x| x / n);
    let r = h.space.rot;
    let mv = |v: [f32; 3]| [0, 1, 2].map(|i| r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2]);
    let o = mv([0, 1, 2].map(|i| ow[i] - h.space.center[i])).map(|x| x * h.space.scale);
    let d = mv(dw);
    let dn = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let d = d.map(|x| x / dn);
    // (t, grid point, delta) per sample
    let mut samples: Vec<(f32, [f32; 3], f32)> = Vec::new();
    match h.kind {
        Kind::Object => {
            let mut t0 = f32::NEG_INFINITY;
            let mut t1 = f32::INFINITY;
            for i in 0..3 {
                let (p, q) = ((-1.0 - o[i]) / d[i], (1.0 - o[i]) / d[i]);
                t0 = t0.max(p.min(q));
                t1 = t1.min(p.max(q));
            }
            if t1 > t0.max(0.0) {
                let t0 = t0.max(0.0);
                let dt = h.march.step;
                let mut i = 0;
                loop {
                    let t = t0 + (i as f32 + 0.5) * dt;
                    if t >= t1 {
                        break;
                    }
                    samples.push((t, [0, 1, 2].map(|k| o[k] + t * d[k]), dt));
                    i += 1;
                }
            }
        }
        Kind::Forward => {
            let nd = h.space.ndc.unwrap();
            if d[2] < -1e-6 {
                let t = -(nd.near + o[2]) / d[2];
                let o = [0, 1, 2].map(|k| o[k] + t * d[k]);
                let ax = -nd.fx / (nd.width / 2.0);
                let ay = -nd.fy / (nd.height / 2.0);
                let on = [ax * o[0] / o[2], ay * o[1] / o[2], 1.0 + 2.0 * nd.near / o[2]];
                let dnd = [ax * (d[0] / d[2] - o[0] / o[2]), ay * (d[1] / d[2] - o[1] / o[2]), -2.0 * nd.near / o[2]];
                let e = nd.xy_extent;
                let s = ((dnd[0] / e).powi(2) + (dnd[1] / e).powi(2) + dnd[2].powi(2)).sqrt();
                let dt = h.march.step / s;
                let delta = dt * (dnd[0].powi(2) + dnd[1].powi(2) + dnd[2].powi(2)).sqrt();
                let mut i = 0;
                loop {
                    let t = (i as f32 + 0.5) * dt;
                    if t >= 1.0 {
                        break;
                    }
                    let p = [0, 1, 2].map(|k| on[k] + t * dnd[k]);
                    samples.push((t, [p[0] / e, p[1] / e, p[2]], delta));
                    i += 1;
                }
            }
        }
        Kind::Unbounded => {
            let udt = |t: f32| {
                let p = [0, 1, 2].map(|k| o[k] + t * d[k]);
                let m = p[0].abs().max(p[1].abs()).max(p[2].abs());
                (2.0 * h.march.step * m.max(1.0).powi(2)).min(1000.0)
            };
            let mut t = 0.02 + 0.5 * udt(0.02);
            while t < 1000.0 {
                let p = [0, 1, 2].map(|k| o[k] + t * d[k]);
                let m = p[0].abs().max(p[1].abs()).max(p[2].abs());
                let c = if m <= 1.0 {
                    p
                } else {
                    p.map(|x| if x.abs() == m { (2.0 - 1.0 / m) * x.signum() } else { x / m })
                };
                let dt = udt(t);
                samples.push((t, c.map(|x| x / 2.0), dt));
                t += dt;
            }
        }
    }
    let (mut vals, mut acc, mut optical, mut depth, mut count) = ([0f32; 7], 0f32, 0f32, 0f32, 0u32);
    for (t, g, delta) in samples {
        let Some(v) = a.sample(0, g) else { continue };
        let sd = (v[0].exp() * delta).clamp(0.0, 80.0);
        let w = (-optical).exp() * -(-sd).exp_m1();
        for c in 0..7 {
            vals[c] += w * v[c + 1];
        }
        acc += w;
        depth += w * t;
        optical += sd;
        count += 1;
        if (-optical).exp() < h.march.t_terminate {
            break;
        }
    }
    (acc, vals, depth, count)
}

#[test]
fn skipping_march_equals_the_literal_march() {
    let mut rng = Rng(2024);
    let mut sphere = sphere_asset(false);
    sphere.header.march.t_terminate = 0.0; // compare whole rays, sample for sample
    for (name, a) in
        [("object", sphere), ("forward", dense_asset(Kind::Forward)), ("unbounded", dense_asset(Kind::Unbounded))]
    {
        let mut nonempty = 0;
        for _ in 0..400 {
            let o = match a.header.kind {
                Kind::Forward => [rng.range(-0.3, 0.3), rng.range(-0.3, 0.3), rng.range(-0.2, 0.2)],
                _ => [rng.range(-3.0, 3.0), rng.range(-3.0, 3.0), rng.range(-3.0, 3.0)],
            };
            let target = [rng.range(-0.8, 0.8), rng.range(-0.8, 0.8), rng.range(-0.8, 0.8)];
            let d = match a.header.kind {
                Kind::Forward => [rng.range(-0.5, 0.5), rng.range(-0.5, 0.5), -1.0],
                _ => [0, 1, 2].map(|k| target[k] - o[k]),
            };
            let got = render_ray(&a, o, d, 0.0);
            let (acc, vals, depth, count) = reference_ray(&a, o, d);
            assert_eq!(got.samples, count, "{}: o {:?} d {:?}", name, o, d);
            assert!((got.opacity - acc).abs() < 1e-5, "{}: {} vs {}", name, got.opacity, acc);
            if acc > 1e-6 {
                assert!((got.depth - depth / acc).abs() < 1e-3 * (1.0 + got.depth.abs()));
            }
            let _ = vals;
            nonempty += (count > 0) as u32;
        }
        assert!(nonempty > 100, "{}: {} rays sampled anything", name, nonempty);
    }
}

/// A 4D asset as the baker writes it: each sample's cell points at whichever stored block
/// stands for it, not necessarily its own or its neighbour's (here frame 2 reuses frame 0's
/// blocks, A-B-A). Rendering is continuous in t between samples — no popping at a sample or
/// anywhere else — and lands exactly on each sample's blocks at its time.
#[test]
fn codebook_4d_asset_renders_continuously_between_samples() {
    let mut a = sphere_asset(true);
    a.grids[2] = a.grids[0].clone();
    a.validate().unwrap();
    let cam = orbit(&a.header, 8, 1, 24, 24, 40.0);
    let img = |t: f32| render(&a, &cam, t).rgb;
    let f0 = img(0.0);
    let f1 = img(1.0);
    // frame 2 shows frame 0's blocks; frame 1 differs
    assert_eq!(img(2.0), f0);
    let d01 = f0.iter().zip(&f1).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
    assert!(d01 > 0.05, "the samples look the same ({d01})");
    // Lipschitz in t: a step of h changes no channel by more than a few times h·d01/1 (the
    // samples are 1 apart), on a fine grid of times spanning both intervals and beyond.
    let h = 1.0 / 64.0;
    let mut prev = img(-0.5);
    let mut worst = 0.0f32;
    for i in 1..=(3.0 / h) as usize {
        let t = -0.5 + i as f32 * h;
        let cur = img(t);
        let d = prev.iter().zip(&cur).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
        worst = worst.max(d);
        prev = cur;
    }
    assert!(worst <= 3.0 * h * d01, "a step of {h} in time changed a pixel by {worst} (samples differ by {d01})");
    // approaching a sample from either side converges to it
    for (t, f) in [(1.0f32, &f1), (2.0, &f0)] {
        for e in [1e-3f32, -1e-3] {
            let d = img(t + e).iter().zip(f.iter()).map(|(x, y)| (x - y).abs()).fold(0.0f32, f32::max);
            assert!(d <= 0.01, "t={t}{e:+}: {d} away from the sample");
        }
    }
}

/// With the silhouette rule (`pixel_rays` 4), a pixel whose neighbourhood of first-pass
/// opacity is partly covered is the mean of its 4 sub-pixel rays; every other pixel is its
/// centre ray, bit for bit.
#[test]
fn silhouette_pixels_are_the_mean_of_their_rays() {
    let mut a = sphere_asset(false);
    let cam = orbit(&a.header, 6, 1, 40, 30, 40.0);
    let one = render(&a, &cam, 0.0);
    a.header.pixel_rays = 4;
    let four = render(&a, &cam, 0.0);
    let (w, h) = (40usize, 30usize);
    let mut edges = 0;
    for p in 0..w * h {
        let (x, y) = ((p % w) as u32, (p / w) as u32);
        let expect = if snerf_geometry::silhouette::mixed_coverage(&one.opacity, w, h, p % w, p / w) {
            edges += 1;
            snerf_asset::render::render_pixel_mean(&a, &cam, x, y, 0.0, 4)
        } else {
            render_pixel(&a, &cam, x, y, 0.0)
        };
        assert_eq!((&four.rgb[p * 3..p * 3 + 3], four.opacity[p], four.depth[p]), (&expect.rgb[..], expect.opacity, expect.depth), "pixel ({x}, {y})");
    }
    assert!(edges > 20 && edges < w * h / 2, "{edges} silhouette pixels");
    // the mean covers the square: an edge pixel's 4 rays are not all alike
    let differs = (0..w * h).filter(|&p| (four.opacity[p] - one.opacity[p]).abs() > 0.05).count();
    assert!(differs > 5, "only {differs} pixels changed opacity");
    // Trained on pixels this camera's are as coarse as: the rule applies. Trained on pixels
    // 4x as wide: this camera's finer pixels take one ray each.
    let footprint = snerf_geometry::silhouette::pixel_footprint(snerf_geometry::camera::position(&cam.c2w), a.header.space.center, cam.fx);
    a.header.train_pixel = Some(footprint);
    assert_eq!(render(&a, &cam, 0.0), four);
    a.header.train_pixel = Some(4.0 * footprint);
    assert_eq!(a.header.pixel_rays_for(&cam), 1);
    assert_eq!(render(&a, &cam, 0.0), one);
}
