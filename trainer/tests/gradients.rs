//! Every hand-written backward pass against central finite differences (in f64 where the
//! forward allows, else f32 with step sizes chosen for its precision).

use snerf_trainer::composite::{self, V};
use snerf_trainer::data::SceneKind;
use snerf_trainer::deform::DeformConfig;
use snerf_trainer::field::{activate, activate_backward, Field, FieldConfig, Rng, OUT};
use snerf_trainer::occupancy::Occupancy;
use snerf_trainer::render::{train_chunk, train_chunk_with, Backward, RayTask, Workspace};
use snerf_trainer::space::{SceneSpace, Vec3};
use snerf_trainer::view_mlp::{ViewLayout, VIN, VOUT};

fn assert_close(name: &str, analytic: f64, numeric: f64, rel: f64, abs: f64) {
    let err = (analytic - numeric).abs();
    assert!(
        err <= abs + rel * numeric.abs().max(analytic.abs()),
        "{name}: analytic {analytic:.6e} vs finite difference {numeric:.6e} (err {err:.3e})"
    );
}

fn small_field(dynamic: bool) -> Field {
    let cfg = FieldConfig {
        resolutions: vec![4, 8],
        time_resolutions: if dynamic { vec![3, 5] } else { vec![] },
        hidden: 8,
        deform: None,
        colour_head: false,
    };
    let mut f = Field::new(cfg, 7).unwrap();
    // Perturb so nothing sits at a symmetric or zero point.
    let mut rng = Rng::new(3);
    for p in f.params.iter_mut() {
        *p += 0.05 * (rng.uniform() - 0.5);
    }
    f
}

/// A small dynamic field with a deformation whose coefficients are far from their start (0),
/// so offsets are a sizeable part of a plane cell.
fn small_deformed_field() -> Field {
    let mut cfg = small_field(true).cfg;
    cfg.deform = Some(DeformConfig { resolution: 3, modes: 2, time_resolution: 4 });
    let mut f = Field::new(cfg, 7).unwrap();
    let mut rng = Rng::new(3);
    for p in f.params.iter_mut() {
        *p += 0.05 * (rng.uniform() - 0.5);
    }
    let d = f.layout.deform.unwrap();
    for p in &mut f.params[d.basis..d.end] {
        *p = 2.0 * rng.uniform() - 1.0;
    }
    f
}

#[test]
fn compositing_backward_matches_finite_differences() {
    let mut rng = Rng::new(11);
    let n = 12;
    let sigma: Vec<f32> = (0..n).map(|i| if i == 5 { 40.0 } else { 3.0 * rng.uniform() }).collect();
    let delta: Vec<f32> = (0..n).map(|_| 0.05 + 0.05 * rng.uniform()).collect();
    let v: Vec<[f32; V]> = (0..n).map(|_| [0; V].map(|_| rng.uniform())).collect();
    let g: [f32; V] = [0; V].map(|_| rng.uniform() - 0.5);
    let g_t = 0.7f32;
    let loss = |sigma: &[f32], v: &[[f32; V]]| -> f64 {
        let c = composite::forward(sigma, &delta, v);
        (0..V).map(|k| (g[k] * c.value[k]) as f64).sum::<f64>() + (g_t * c.t_final) as f64
    };
    let mut ds = vec![0.0; n];
    let mut dv = vec![[0.0; V]; n];
    composite::backward(&sigma, &delta, &v, &g, g_t, &[], &mut ds, &mut dv, &mut Vec::new());
    for k in 0..n {
        let h = 1e-2 * sigma[k].max(0.1);
        let (mut a, mut b) = (sigma.clone(), sigma.clone());
        a[k] += h;
        b[k] -= h;
        let num = (loss(&a, &v) - loss(&b, &v)) / (2.0 * h as f64);
        assert_close(&format!("dσ[{k}]"), ds[k] as f64, num, 2e-2, 1e-5);
        for c in [0, 3, 7] {
            let (mut a, mut b) = (v.clone(), v.clone());
            a[k][c] += 1e-2;
            b[k][c] -= 1e-2;
            let num = (loss(&sigma, &a) - loss(&sigma, &b)) / 2e-2;
            assert_close(&format!("dv[{k}][{c}]"), dv[k][c] as f64, num, 1e-2, 1e-5);
        }
    }
}

#[test]
fn encoding_backward_matches_finite_differences_static_and_dynamic() {
    for dynamic in [false, true] {
        let f = small_field(dynamic);
        let g: Vec3 = [0.31, -0.47, 0.73];
        let t = 0.37;
        let inp = f.layout.input;
        let mut rng = Rng::new(5);
        let w: Vec<f32> = (0..inp).map(|_| rng.uniform() - 0.5).collect();
        let loss = |f: &Field| -> f64 {
            let mut feat = vec![0.0; inp];
            f.encode(&g, t, &mut feat);
            feat.iter().zip(&w).map(|(a, b)| (a * b) as f64).sum()
        };
        let mut grad = vec![0.0f32; f.params.len()];
        f.encode_backward(&g, t, &w, &mut grad, &mut vec![0u8; f.params.len() / 8]);
        let touched: Vec<usize> = (0..f.layout.plane_end).filter(|&i| grad[i] != 0.0).collect();
        // 2 levels x planes x 4 corners x C channels
        assert_eq!(touched.len(), 2 * f.cfg.planes() * 4 * 8, "dynamic={dynamic}");
        for &i in touched.iter().step_by(7) {
            let mut fa = f.clone();
            fa.params[i] += 1e-2;
            let mut fb = f.clone();
            fb.params[i] -= 1e-2;
            let num = (loss(&fa) - loss(&fb)) / 2e-2;
            assert_close(&format!("plane param {i} (dynamic={dynamic})"), grad[i] as f64, num, 1e-2, 1e-6);
        }
    }
}

#[test]
fn decoder_and_activation_backward_match_finite_differences() {
    check_decoder(&small_field(false));
}

/// A style layer's decoder: the colour outputs read a hidden layer of their own.
#[test]
fn colour_head_backward_matches_finite_differences_and_leaves_density_alone() {
    let plain = small_field(false);
    let mut f = plain.with_colour_head().unwrap();
    let c = f.layout.colour.unwrap();
    // as added, the head is a copy: the field's outputs are unchanged
    let (inp, hw) = (f.layout.input, f.layout.hid_width());
    let n = 4;
    let mut rng = Rng::new(21);
    let feat: Vec<f32> = (0..n * inp).map(|_| rng.uniform()).collect();
    let decode = |f: &Field| {
        let mut hid = vec![0.0; n * f.layout.hid_width()];
        let mut out = vec![0.0; n * OUT];
        f.decode_forward(n, &feat, &mut hid, &mut out);
        (hid, out)
    };
    assert_eq!(decode(&plain).1, decode(&f).1, "a new colour head changed the outputs");
    // a head that has learned changes the colours, never σ
    for x in &mut f.params[c.w1..f.layout.total] {
        *x += 0.3 * (rng.uniform() - 0.5);
    }
    let (hid, out) = decode(&f);
    let plain_out = decode(&plain).1;
    for r in 0..n {
        assert_eq!(out[r * OUT], plain_out[r * OUT], "σ moved with the colour head");
    }
    assert!((1..OUT).any(|k| out[k] != plain_out[k]), "the colour head changed nothing");
    check_decoder(&f);
    // the frozen-geometry pass computes the output layer's and the head's gradients as the
    // full pass does
    let wo: Vec<f32> = (0..n * OUT).map(|_| rng.uniform() - 0.5).collect();
    let mut full = vec![0.0f32; f.params.len()];
    let mut cut = vec![0.0f32; f.params.len()];
    let (mut d_hid, mut d_feat) = (vec![0.0; n * hw], vec![0.0; n * inp]);
    f.decode_backward(n, &feat, &hid, &wo, &mut d_hid, &mut d_feat, &mut full);
    f.decode_backward_output(n, &feat, &hid, &wo, &mut d_hid, &mut cut);
    let l = &f.layout;
    assert_eq!(&cut[l.w2..l.b2 + OUT], &full[l.w2..l.b2 + OUT]);
    assert_eq!(&cut[c.w1..l.total], &full[c.w1..l.total]);
    assert!(cut[c.w1..l.total].iter().any(|&g| g != 0.0));
    assert!(cut[l.w1..l.w2].iter().all(|&g| g == 0.0), "the frozen pass reached the shared layer");
}

/// The decoder's and activation's backward against finite differences, every decoder
/// parameter (and the colour head's) and every input feature.
fn check_decoder(f: &Field) {
    let f = f.clone();
    let (inp, h) = (f.layout.input, f.layout.hid_width());
    let n = 5;
    let mut rng = Rng::new(9);
    let feat: Vec<f32> = (0..n * inp).map(|_| rng.uniform()).collect();
    let wo: Vec<f32> = (0..n * 8).map(|_| rng.uniform() - 0.5).collect();
    // loss = Σ wo · activate(decode(feat))
    let loss = |f: &Field, feat: &[f32]| -> f64 {
        let mut hid = vec![0.0; n * h];
        let mut out = vec![0.0; n * OUT];
        f.decode_forward(n, feat, &mut hid, &mut out);
        let mut s = 0.0f64;
        for r in 0..n {
            let (sg, v) = activate(&out[r * OUT..(r + 1) * OUT]);
            s += (wo[r * 8] * sg) as f64;
            for c in 0..7 {
                s += (wo[r * 8 + 1 + c] * v[c]) as f64;
            }
        }
        s
    };
    let mut hid = vec![0.0; n * h];
    let mut out = vec![0.0; n * OUT];
    f.decode_forward(n, &feat, &mut hid, &mut out);
    let mut d_out = vec![0.0; n * OUT];
    for r in 0..n {
        let o = &out[r * OUT..(r + 1) * OUT];
        let (sg, v) = activate(o);
        activate_backward(o, sg, &v, wo[r * 8], &wo[r * 8 + 1..r * 8 + 8], &mut d_out[r * OUT..(r + 1) * OUT]);
    }
    let mut grad = vec![0.0f32; f.params.len()];
    let mut d_hid = vec![0.0; n * h];
    let mut d_feat = vec![0.0; n * inp];
    f.decode_backward(n, &feat, &hid, &d_out, &mut d_hid, &mut d_feat, &mut grad);
    let l = &f.layout;
    let head = l.colour.map_or(0..0, |c| c.w1..l.total);
    for i in (l.w1..l.view.w1).step_by(5).chain(head.step_by(3)) {
        let mut fa = f.clone();
        fa.params[i] += 1e-3;
        let mut fb = f.clone();
        fb.params[i] -= 1e-3;
        let num = (loss(&fa, &feat) - loss(&fb, &feat)) / 2e-3;
        assert_close(&format!("decoder param {i}"), grad[i] as f64, num, 2e-2, 2e-4);
    }
    for i in (0..n * inp).step_by(3) {
        let (mut a, mut b) = (feat.clone(), feat.clone());
        a[i] += 1e-3;
        b[i] -= 1e-3;
        let num = (loss(&f, &a) - loss(&f, &b)) / 2e-3;
        assert_close(&format!("d feature {i}"), d_feat[i] as f64, num, 2e-2, 2e-4);
    }
}

#[test]
fn view_mlp_backward_matches_finite_differences() {
    let mut f = small_field(false);
    let view = f.layout.view;
    let mut rng = Rng::new(2);
    // non-zero last layer so every weight matters
    for p in &mut f.params[view.w3..view.end] {
        *p = 2.0 * rng.uniform() - 1.0;
    }
    let mut df = [0.0f32; 8];
    for x in df.iter_mut() {
        *x = rng.uniform();
    }
    let dir = [0.48, -0.6, 0.64];
    let wo = [0.3f32, -0.8, 0.5];
    let loss = |p: &[f32], df: &[f32; 8]| -> f64 {
        let (o, _) = view.forward(p, ViewLayout::input(df, &dir));
        (0..VOUT).map(|k| (wo[k] * o[k]) as f64).sum()
    };
    let (_, cache) = view.forward(&f.params, ViewLayout::input(&df, &dir));
    let mut grad = vec![0.0f32; f.params.len()];
    let d_in = view.backward(&f.params, &cache, &wo, &mut grad);
    assert_eq!(cache.x.len(), VIN);
    for i in (view.w1..view.end).step_by(3) {
        let mut a = f.params.clone();
        a[i] += 1e-3;
        let mut b = f.params.clone();
        b[i] -= 1e-3;
        let num = (loss(&a, &df) - loss(&b, &df)) / 2e-3;
        assert_close(&format!("view param {i}"), grad[i] as f64, num, 2e-2, 2e-4);
    }
    for c in 0..7 {
        let (mut a, mut b) = (df, df);
        a[c] += 1e-3;
        b[c] -= 1e-3;
        let num = (loss(&f.params, &a) - loss(&f.params, &b)) / 2e-3;
        assert_close(&format!("view input {c}"), d_in[c] as f64, num, 2e-2, 2e-4);
    }
}

/// The whole fused training chunk: its gradient of the loss against finite differences of
/// the loss it reports, for parameters in every group; with one ray per pixel, and with
/// pixels of 3 rays whose mean is compared to the pixel's target.
#[test]
fn fused_training_chunk_gradient_matches_finite_differences() {
    for (dynamic, k, deformed) in [(false, 1, false), (true, 1, false), (false, 3, false), (true, 1, true)] {
        let mut field = if deformed { small_deformed_field() } else { small_field(dynamic) };
        // moderate densities so rays neither terminate early nor stay empty
        field.params[field.layout.b2] = 1.0;
        let space = SceneSpace::identity(SceneKind::Object, dynamic);
        let occ = Occupancy::new(8, 24);
        let mut rng = Rng::new(13);
        let tasks: Vec<RayTask> = (0..6)
            .map(|i| {
                let o = [3.0 * (i as f32 * 0.7).cos(), 0.4 * i as f32 - 1.0, 3.0 * (i as f32 * 0.7).sin()];
                let d = snerf_trainer::space::normalize([-o[0] + 0.1, -o[1] * 0.5, -o[2]]);
                RayTask {
                    ray: space.world_ray(o, d, Some(i as f32 / 6.0)),
                    bg: [rng.uniform(), rng.uniform(), rng.uniform()],
                    target: [rng.uniform(), rng.uniform(), rng.uniform()],
                    jitter: 0.3,
                }
            })
            .collect();
        // the rays of one pixel share its target and background
        let tasks: Vec<RayTask> = tasks
            .iter()
            .enumerate()
            .map(|(i, t)| RayTask { target: tasks[i / k * k].target, bg: tasks[i / k * k].bg, ..*t })
            .collect();
        assert!(tasks.iter().all(|t| t.ray.is_some()));
        let groups = vec![k as u16; tasks.len() / k];
        // with loss_scale 1 the gradient is of Σ_pixels (mean rgb - target)² + 3 λ / k Σ distortion
        let lambda = if dynamic { 0.0 } else { 0.05 };
        let loss_of = |f: &Field| -> f64 {
            let mut ws = Workspace::new(f.params.len());
            let s = train_chunk(f, &space, &occ, &tasks, &mut ws, 1.0, lambda, &groups);
            s.loss_sum + 3.0 * lambda as f64 / k as f64 * s.distortion_sum
        };
        let mut ws = Workspace::new(field.params.len());
        let stats = train_chunk(&field, &space, &occ, &tasks, &mut ws, 1.0, lambda, &groups);
        assert!(lambda == 0.0 || stats.distortion_sum > 0.0);
        assert!(stats.samples > 50, "rays must cross the field ({} samples)", stats.samples);
        let grad = ws.grad.clone();
        let l = &field.layout;
        let plane_touched: Vec<usize> = (0..l.plane_end).filter(|&i| grad[i].abs() > 1e-4).collect();
        assert!(!plane_touched.is_empty());
        let mut checks: Vec<usize> = plane_touched.iter().step_by((plane_touched.len() / 12).max(1)).cloned().collect();
        checks.extend((l.w1..l.b2 + 8).step_by(17));
        checks.extend((l.view.w1..l.view.end).step_by(37));
        if let Some(d) = l.deform {
            checks.extend((d.basis..d.coeffs).step_by(5));
            checks.extend(d.coeffs..d.end);
            assert!(grad[d.basis..d.end].iter().filter(|g| g.abs() > 1e-4).count() > 20, "the deformation gets gradient");
        }
        let mut checked = 0;
        for i in checks {
            let h = 2e-3f32;
            let mut fa = field.clone();
            fa.params[i] += h;
            let mut fb = field.clone();
            fb.params[i] -= h;
            let num = (loss_of(&fa) - loss_of(&fb)) / (2.0 * h as f64);
            assert_close(&format!("param {i} (dynamic={dynamic}, rays per pixel {k}, deformed={deformed})"), grad[i] as f64, num, 5e-2, 5e-4);
            checked += 1;
        }
        assert!(checked > 20);
    }
}

#[test]
fn distortion_loss_gradient_matches_finite_differences() {
    let mut rng = Rng::new(21);
    let n = 9;
    let w: Vec<f32> = (0..n).map(|_| 0.1 * rng.uniform()).collect();
    let mut mid = Vec::new();
    let mut s = 0.0;
    for _ in 0..n {
        s += 0.01 + 0.05 * rng.uniform();
        mid.push(s);
    }
    let len: Vec<f32> = (0..n).map(|_| 0.02).collect();
    let mut g = vec![0.0; n];
    let l0 = composite::distortion(&w, &mid, &len, &mut g);
    // brute-force definition
    let brute = |w: &[f32]| -> f64 {
        let mut l = 0.0f64;
        for i in 0..n {
            for j in 0..n {
                l += (w[i] * w[j] * (mid[i] - mid[j]).abs()) as f64;
            }
            l += (w[i] * w[i] * len[i]) as f64 / 3.0;
        }
        l
    };
    assert_close("distortion value", l0 as f64, brute(&w), 1e-4, 1e-7);
    let mut scratch = vec![0.0; n];
    for k in 0..n {
        let (mut a, mut b) = (w.clone(), w.clone());
        a[k] += 1e-3;
        b[k] -= 1e-3;
        let num = (brute(&a) - brute(&b)) / 2e-3;
        assert_close(&format!("d distortion / dw[{k}]"), g[k] as f64, num, 1e-2, 1e-6);
        scratch[k] = g[k];
    }
}

#[test]
fn total_variation_gradient_matches_finite_differences() {
    let f = small_field(true);
    let mut grad = vec![0.0f32; f.params.len()];
    let mut touched = vec![0u8; f.params.len() / 8];
    let l0 = f.tv_backward(0.5, &mut grad, &mut touched);
    assert!(l0 > 0.0);
    let plane0 = &f.layout.planes[0][0];
    assert!(touched[..plane0.ru * plane0.rv].iter().all(|&t| t == 1), "spatial cells are marked for the optimizer");
    let loss = |f: &Field| -> f64 {
        let mut g = vec![0.0f32; f.params.len()];
        let mut t = vec![0u8; f.params.len() / 8];
        f.tv_backward(0.5, &mut g, &mut t) as f64
    };
    // time planes are not regularized here
    let time_plane = &f.layout.planes[0][3];
    assert!(grad[time_plane.offset..time_plane.offset + 8].iter().all(|&g| g == 0.0));
    for i in (0..f.layout.plane_end).step_by(13) {
        let mut a = f.clone();
        a.params[i] += 1e-2;
        let mut b = f.clone();
        b.params[i] -= 1e-2;
        let num = (loss(&a) - loss(&b)) / 2e-2;
        assert_close(&format!("tv param {i}"), grad[i] as f64, num, 2e-2, 1e-6);
    }
}

#[test]
fn time_priors_gradient_matches_finite_differences() {
    // time resolutions 3 and 5: the second difference exists at every level
    let f = small_field(true);
    let (smooth, sparse) = (0.7f32, 0.3f32);
    let mut grad = vec![0.0f32; f.params.len()];
    let mut touched = vec![0u8; f.params.len() / 8];
    let l0 = f.time_priors_backward(smooth, sparse, &mut grad, &mut touched);
    assert!(l0 > 0.0);
    let loss = |f: &Field| -> f64 {
        let mut g = vec![0.0f32; f.params.len()];
        let mut t = vec![0u8; f.params.len() / 8];
        f.time_priors_backward(smooth, sparse, &mut g, &mut t) as f64
    };
    // spatial planes are not touched; every time-plane cell is
    for level in &f.layout.planes {
        for p in level {
            let cells = &touched[p.offset / 8..p.offset / 8 + p.ru * p.rv];
            let g = &grad[p.offset..p.offset + p.ru * p.rv * 8];
            if p.axes.1 == 3 {
                assert!(cells.iter().all(|&t| t == 1), "time-plane cells are marked for the optimizer");
                assert!(g.iter().any(|&x| x != 0.0));
            } else {
                assert!(cells.iter().all(|&t| t == 0) && g.iter().all(|&x| x == 0.0), "spatial planes carry no time prior");
            }
        }
    }
    let mut checked = 0;
    for level in &f.layout.planes {
        for p in level.iter().filter(|p| p.axes.1 == 3) {
            for i in (p.offset..p.offset + p.ru * p.rv * 8).step_by(5) {
                // |1 - x| has a kink at 1: step only where the difference stays on one side
                let h = 1e-3f32;
                if (f.params[i] - 1.0).abs() < 2.0 * h {
                    continue;
                }
                let mut a = f.clone();
                a.params[i] += h;
                let mut b = f.clone();
                b.params[i] -= h;
                let num = (loss(&a) - loss(&b)) / (2.0 * h as f64);
                assert_close(&format!("time prior param {i}"), grad[i] as f64, num, 2e-2, 2e-5);
                checked += 1;
            }
        }
    }
    assert!(checked > 50, "only {checked} parameters checked");
    // a field whose time planes sit at 1 (its start) pays nothing and gets no gradient
    let start = Field::new(f.cfg.clone(), 7).unwrap();
    let mut g = vec![0.0f32; start.params.len()];
    let mut t = vec![0u8; start.params.len() / 8];
    assert_eq!(start.time_priors_backward(smooth, sparse, &mut g, &mut t), 0.0);
    assert!(g.iter().all(|&x| x == 0.0));
}

/// The deformation's backward: dL/d(point) through the canonical field's planes
/// (`encode_backward_recorded_dg`), and from there into the motion basis and its time
/// coefficients (`Deform::warp_backward`), against finite differences of
/// L = w · encode(warp(g, τ), τ); points inside the box and outside it (clamped: no gradient
/// along that axis).
#[test]
fn deformation_backward_matches_finite_differences() {
    let f = small_deformed_field();
    let d = f.layout.deform.unwrap();
    let inp = f.layout.input;
    let mut rng = Rng::new(5);
    let w: Vec<f32> = (0..inp).map(|_| rng.uniform() - 0.5).collect();
    let nh = f.hits_per_point();
    let loss_at = |f: &Field, p: &Vec3, t: f32| -> f64 {
        let mut feat = vec![0.0; inp];
        f.encode(p, t, &mut feat);
        feat.iter().zip(&w).map(|(a, b)| (a * b) as f64).sum()
    };
    let mut checked = 0;
    for (g, t) in [([0.31f32, -0.47, 0.63], 0.37f32), ([-0.12, 0.58, -0.33], 0.81), ([1.4, 0.2, -0.1], 0.1)] {
        let gw = f.warp(&g, t);
        assert!((0..3).map(|a| (gw[a] - g[a]).abs()).sum::<f32>() > 0.05, "the offset is not negligible: {g:?} -> {gw:?}");
        let mut feat = vec![0.0; inp];
        let mut hits = vec![Default::default(); nh];
        f.encode_recorded(&gw, t, &mut feat, &mut hits);
        let mut grad = vec![0.0f32; f.params.len()];
        let d_g = f.encode_backward_recorded_dg(&hits, &w, &mut grad, &mut vec![0u8; f.params.len() / 8], &gw);
        // dL/d(point) of the canonical field
        for a in 0..3 {
            let h = 1e-3f32;
            let (mut pa, mut pb) = (gw, gw);
            pa[a] += h;
            pb[a] -= h;
            let num = (loss_at(&f, &pa, t) - loss_at(&f, &pb, t)) / (2.0 * h as f64);
            let num = if gw[a].abs() + h >= 1.0 { 0.0 } else { num }; // clamped: the border holds
            assert_close(&format!("dL/dg'[{a}] at {g:?} -> {gw:?}"), d_g[a] as f64, num, 2e-2, 1e-5);
        }
        // the rest of the plane gradient is unchanged by asking for d_g
        let mut plain = vec![0.0f32; f.params.len()];
        f.encode_backward_recorded(&hits, &w, &mut plain, &mut vec![0u8; f.params.len() / 8]);
        assert_eq!(plain, grad);
        // into the basis and the coefficients
        let mut grad = vec![0.0f32; f.params.len()];
        d.warp_backward(&f.params, &g, t, &d_g, &mut grad);
        assert!(grad[..d.basis].iter().all(|&x| x == 0.0));
        let loss = |f: &Field| loss_at(f, &f.warp(&g, t), t);
        for i in (d.basis..d.end).filter(|&i| grad[i] != 0.0) {
            let h = 1e-3f32;
            let mut fa = f.clone();
            fa.params[i] += h;
            let mut fb = f.clone();
            fb.params[i] -= h;
            let num = (loss(&fa) - loss(&fb)) / (2.0 * h as f64);
            assert_close(&format!("deformation param {i} at {g:?}"), grad[i] as f64, num, 3e-2, 2e-5);
            checked += 1;
        }
    }
    assert!(checked > 60, "only {checked} parameters checked");
}

/// The frozen-geometry backward (`Backward::OutputLayer`): the gradients it computes (the
/// decoder's output layer, the view MLP) are the full pass's bit for bit, and it leaves the
/// planes, the shared hidden layer and the deformation without any.
#[test]
fn output_layer_backward_is_the_full_pass_cut_short() {
    for (dynamic, k, deformed) in [(false, 1, false), (false, 4, false), (true, 1, true)] {
        let mut field = if deformed { small_deformed_field() } else { small_field(dynamic) };
        field.params[field.layout.b2] = 1.0;
        let space = SceneSpace::identity(SceneKind::Object, dynamic);
        let occ = Occupancy::new(8, 24);
        let mut rng = Rng::new(29);
        let tasks: Vec<RayTask> = (0..8 * k)
            .map(|i| {
                let o = [3.0 * (i as f32 * 0.7).cos(), 0.3 * i as f32 - 1.0, 3.0 * (i as f32 * 0.7).sin()];
                let d = snerf_trainer::space::normalize([-o[0] + 0.1, -o[1] * 0.5, -o[2]]);
                RayTask {
                    ray: space.world_ray(o, d, Some(i as f32 / 9.0)),
                    bg: [rng.uniform(), rng.uniform(), rng.uniform()],
                    target: [rng.uniform(), rng.uniform(), rng.uniform()],
                    jitter: 0.3,
                }
            })
            .collect();
        let groups = vec![k as u16; tasks.len() / k];
        let run = |backward| {
            let mut ws = Workspace::new(field.params.len());
            let s = train_chunk_with(&field, &space, &occ, &tasks, &mut ws, 0.5, 0.0, &groups, backward);
            (s, ws.grad.clone())
        };
        let (full_stats, full) = run(Backward::Full);
        let (cut_stats, cut) = run(Backward::OutputLayer);
        assert!(full_stats.samples > 50, "rays must cross the field ({} samples)", full_stats.samples);
        assert_eq!((full_stats.loss_sum, full_stats.samples), (cut_stats.loss_sum, cut_stats.samples), "the same forward pass");
        let l = &field.layout;
        let kept: Vec<std::ops::Range<usize>> = vec![l.w2..l.b2 + OUT, l.view.w1..l.view.end];
        let mut compared = 0;
        for (i, (&a, &b)) in full.iter().zip(&cut).enumerate() {
            if kept.iter().any(|r| r.contains(&i)) {
                assert_eq!(a.to_bits(), b.to_bits(), "parameter {i}: full {a}, cut {b}");
                compared += (a != 0.0) as usize;
            } else {
                assert_eq!(b, 0.0, "parameter {i} (outside the output layer and view MLP) got a gradient");
            }
        }
        // the colour rows and biases do carry gradient, and the full pass reaches the planes
        assert!(compared > 8, "only {compared} non-zero output-layer gradients");
        assert!(full[..l.plane_end].iter().any(|&g| g != 0.0));
    }
}
