//! Stiff and extreme cases for volume rendering, the scene mapping, the field and the
//! optimizer. Each test's name says the case. "Finite" means no NaN and no ±Inf anywhere.

use snerf_trainer::adam::Adam;
use snerf_trainer::composite::{self, V};
use snerf_trainer::data::SceneKind;
use snerf_trainer::field::{Field, FieldConfig, Rng};
use snerf_trainer::occupancy::Occupancy;
use snerf_trainer::render::{render_chunk, train_chunk, RayResult, RayTask, Workspace};
use snerf_trainer::space::{contract, SceneSpace};

fn all_finite(xs: &[f32]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

/// Forward + backward of one ray with a fixed upstream gradient; returns
/// (value, T_final, weights, dσ, dv) and asserts finiteness and Σw ≤ 1.
fn run_ray(sigma: &[f32], delta: &[f32]) -> (composite::RayComposite, Vec<f32>, Vec<f32>, Vec<[f32; V]>) {
    let n = sigma.len();
    let v: Vec<[f32; V]> = (0..n).map(|k| [0.25 + 0.05 * (k % 5) as f32; V]).collect();
    let c = composite::forward(sigma, delta, &v);
    let (mut w, mut t) = (Vec::new(), Vec::new());
    let t_final = composite::weights(sigma, delta, &mut w, &mut t);
    let mut ds = vec![0.0; n];
    let mut dv = vec![[0.0; V]; n];
    composite::backward(sigma, delta, &v, &[1.0; V], 0.5, &[], &mut ds, &mut dv, &mut Vec::new());
    assert!(all_finite(&c.value) && c.t_final.is_finite(), "forward not finite: {c:?}");
    assert!(all_finite(&w) && all_finite(&t) && t_final.is_finite());
    assert!(all_finite(&ds), "dσ not finite: {ds:?}");
    assert!(dv.iter().all(|d| all_finite(d)));
    let sum: f32 = w.iter().sum();
    assert!(sum <= 1.0 + 1e-6, "weights sum to {sum} > 1");
    assert!((sum + t_final - 1.0).abs() < 1e-4, "Σw + T_N = {} (should be 1)", sum + t_final);
    assert!((0.0..=1.0).contains(&t_final));
    (c, w, ds, dv)
}

#[test]
fn sigma_zero_everywhere_is_fully_transparent() {
    let (c, w, ds, _) = run_ray(&[0.0; 16], &[0.01; 16]);
    assert_eq!(c.t_final, 1.0);
    assert!(w.iter().all(|&x| x == 0.0));
    // σ = 0 still gets a (negative, "add density here" or not) gradient
    assert!(ds.iter().any(|&d| d != 0.0));
}

#[test]
fn sigma_1e10_is_opaque_at_the_first_dense_sample() {
    let mut sigma = vec![0.1f32; 16];
    sigma[3] = 1e10;
    let (c, w, _, _) = run_ray(&sigma, &[0.01; 16]);
    assert!(c.t_final == 0.0);
    assert!(w[4..].iter().all(|&x| x == 0.0), "nothing behind an opaque sample is seen");
    assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6);
}

#[test]
fn sigma_sweep_from_zero_to_1e10_stays_finite_and_monotone() {
    let mut last_t = 1.0f32;
    for e in -8..=10 {
        let s = 10f32.powi(e);
        let (c, _, _, _) = run_ray(&[s; 8], &[0.01; 8]);
        assert!(c.t_final <= last_t, "transmittance must fall as σ grows");
        last_t = c.t_final;
    }
}

#[test]
fn sigma_infinite_and_nan_inputs_do_not_poison_the_ray() {
    let (c, _, _, _) = run_ray(&[0.5, f32::INFINITY, 0.5], &[0.1; 3]);
    assert_eq!(c.t_final, 0.0);
    let (c, w, _, _) = run_ray(&[0.5, f32::NAN, 0.5], &[0.1; 3]);
    assert_eq!(w[1], 0.0, "NaN density counts as empty");
    assert!(c.t_final > 0.0);
}

#[test]
fn step_size_zero_contributes_nothing() {
    let (c, w, _, _) = run_ray(&[5.0; 8], &[0.0; 8]);
    assert_eq!(c.t_final, 1.0);
    assert!(w.iter().all(|&x| x == 0.0));
}

#[test]
fn step_size_huge_with_huge_sigma_stays_finite() {
    run_ray(&[1e10; 8], &[1e30; 8]);
    run_ray(&[1e-20; 8], &[1e30; 8]);
    let (c, _, _, _) = run_ray(&[1.0; 4], &[f32::MAX; 4]);
    assert_eq!(c.t_final, 0.0);
}

#[test]
fn mixed_stiff_ray_gradient_matches_finite_differences() {
    // small depths in front of a saturated sample: the prefix sums must stay exact
    let sigma = [0.3f32, 0.7, 2e4, 0.2];
    let delta = [0.01f32, 0.02, 1.0, 0.01];
    let (_, _, ds, _) = run_ray(&sigma, &delta);
    let v: Vec<[f32; V]> = (0..4).map(|k| [0.25 + 0.05 * (k % 5) as f32; V]).collect();
    let loss = |s: &[f32]| {
        let c = composite::forward(s, &delta, &v);
        c.value.iter().map(|&x| x as f64).sum::<f64>() + 0.5 * c.t_final as f64
    };
    for k in [0, 1, 3] {
        let h = 1e-2;
        let mut a = sigma;
        a[k] += h;
        let mut b = sigma;
        b[k] -= h;
        let num = (loss(&a) - loss(&b)) / (2.0 * h as f64);
        assert!((ds[k] as f64 - num).abs() < 1e-3 + 1e-2 * num.abs(), "dσ[{k}] {} vs {num}", ds[k]);
    }
    assert_eq!(ds[2], 0.0, "clamped optical depth has zero gradient");
}

#[test]
fn weights_sum_to_at_most_one_on_random_rays() {
    let mut rng = Rng::new(1);
    for _ in 0..500 {
        let n = 1 + rng.below(64);
        let sigma: Vec<f32> = (0..n).map(|_| 10f32.powf(rng.uniform() * 14.0 - 4.0)).collect();
        let delta: Vec<f32> = (0..n).map(|_| 10f32.powf(rng.uniform() * 8.0 - 6.0)).collect();
        run_ray(&sigma, &delta);
    }
}

fn object_space(dynamic: bool) -> SceneSpace {
    SceneSpace::identity(SceneKind::Object, dynamic)
}

fn dense_field(dynamic: bool, sigma_bias: f32) -> Field {
    let cfg = FieldConfig { resolutions: vec![8, 16], time_resolutions: if dynamic { vec![4, 4] } else { vec![] }, hidden: 8, deform: None, colour_head: false };
    let mut f = Field::new(cfg, 1).unwrap();
    f.params[f.layout.b2] = sigma_bias;
    f
}

fn render_one(field: &Field, space: &SceneSpace, task: RayTask) -> RayResult {
    let occ = Occupancy::new(16, 64);
    let mut ws = Workspace::new(field.params.len());
    let mut out = [RayResult::default()];
    render_chunk(field, space, &occ, &[task], &mut ws, &mut out);
    let loss = train_chunk(field, space, &occ, &[task], &mut ws, 1.0, 0.01, &[]);
    assert!(loss.loss_sum.is_finite());
    assert!(all_finite(&ws.grad), "gradient not finite");
    out[0]
}

#[test]
fn ray_starting_inside_dense_matter_sees_the_matter_at_once() {
    let space = object_space(false);
    let field = dense_field(false, 14.0); // σ ≈ e^14 ≈ 1.2e6 everywhere
    let ray = space.world_ray([0.1, 0.2, 0.0], [0.0, 0.0, -1.0], None);
    assert!(ray.is_some(), "a camera inside the box still gets a ray");
    let r = render_one(&field, &space, RayTask { ray, bg: [1.0, 0.0, 0.0], target: [0.5; 3], jitter: 0.5 });
    assert!(r.opacity > 0.999 && r.samples <= 24, "terminates early: {r:?}");
    assert!(all_finite(&r.rgb));
}

#[test]
fn ray_that_misses_the_scene_shows_the_background() {
    let space = object_space(false);
    let field = dense_field(false, 0.0);
    let ray = space.world_ray([5.0, 5.0, 5.0], [1.0, 0.0, 0.0], None);
    assert!(ray.is_none());
    let r = render_one(&field, &space, RayTask { ray, bg: [0.2, 0.4, 0.6], target: [0.0; 3], jitter: 0.5 });
    assert_eq!(r.rgb, [0.2, 0.4, 0.6]);
    assert_eq!(r.opacity, 0.0);
}

#[test]
fn ray_through_empty_field_is_background_and_finite() {
    let space = object_space(false);
    let field = dense_field(false, -40.0);
    let ray = space.world_ray([0.0, 0.0, 3.0], [0.0, 0.0, -1.0], None);
    let r = render_one(&field, &space, RayTask { ray, bg: [0.3; 3], target: [0.0; 3], jitter: 0.5 });
    assert!((r.rgb[0] - 0.3).abs() < 1e-4);
}

fn unbounded_space() -> SceneSpace {
    SceneSpace::identity(SceneKind::Unbounded, false)
}

#[test]
fn contraction_is_finite_for_huge_infinite_and_nan_points() {
    for p in [[1e30f32, 0.0, 0.0], [f32::INFINITY, 1.0, -2.0], [f32::NAN, 0.5, 0.5], [-1e38, -1e38, 3.0]] {
        let c = contract(p);
        assert!(c.iter().all(|x| x.is_finite() && x.abs() <= 2.0), "{p:?} -> {c:?}");
    }
    assert_eq!(contract([0.5, -0.25, 0.0]), [0.5, -0.25, 0.0], "identity inside the unit cube");
}

#[test]
fn camera_far_outside_the_contraction_renders_finitely() {
    let space = unbounded_space();
    let field = dense_field(false, 0.0);
    let ray = space.world_ray([1e6, 2e5, -3e6], snerf_trainer::space::normalize([-1.0, -0.2, 3.0]), None);
    let r = render_one(&field, &space, RayTask { ray, bg: [0.0; 3], target: [0.5; 3], jitter: 0.5 });
    assert!(all_finite(&r.rgb) && r.depth.is_finite());
}

#[test]
fn camera_at_the_centre_of_the_contraction_renders_finitely() {
    let space = unbounded_space();
    let field = dense_field(false, -2.0);
    for d in [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.577, 0.577, 0.577]] {
        let ray = space.world_ray([0.0; 3], d, None);
        let r = render_one(&field, &space, RayTask { ray, bg: [0.0; 3], target: [0.5; 3], jitter: 0.5 });
        assert!(all_finite(&r.rgb) && r.samples > 0, "{r:?}");
    }
}

#[test]
fn time_outside_zero_one_is_clamped_to_the_ends() {
    let space = object_space(true);
    assert_eq!(space.field_time(Some(-3.0)), 0.0);
    assert_eq!(space.field_time(Some(7.5)), 1.0);
    assert_eq!(space.field_time(Some(f32::NAN)), 0.0);
    let field = dense_field(true, 0.0);
    let (mut a, mut b) = (vec![0.0; field.layout.input], vec![0.0; field.layout.input]);
    field.encode(&[0.1, 0.2, 0.3], -5.0, &mut a);
    field.encode(&[0.1, 0.2, 0.3], 0.0, &mut b);
    assert_eq!(a, b);
    field.encode(&[0.1, 0.2, 0.3], 9.0, &mut a);
    field.encode(&[0.1, 0.2, 0.3], 1.0, &mut b);
    assert_eq!(a, b);
    let ray = space.world_ray([0.0, 0.0, 3.0], [0.0, 0.0, -1.0], Some(42.0));
    let r = render_one(&field, &space, RayTask { ray, bg: [0.0; 3], target: [0.5; 3], jitter: 0.5 });
    assert!(all_finite(&r.rgb));
}

#[test]
fn grid_points_far_outside_the_planes_clamp_to_the_border() {
    let field = dense_field(false, 0.0);
    let mut a = vec![0.0; field.layout.input];
    for g in [[1e9f32, -1e9, 0.0], [f32::NAN, 0.0, 0.0], [f32::INFINITY, f32::NEG_INFINITY, 2.0]] {
        field.encode(&g, 0.0, &mut a);
        assert!(all_finite(&a), "{g:?}");
    }
}

#[test]
fn adam_survives_huge_infinite_nan_and_zero_gradients() {
    let n = 8;
    let mut params = vec![0.5f32; n];
    let mut adam = Adam::new(n);
    let cases = [1e30f32, f32::INFINITY, f32::NAN, 0.0, -1e38, 1e-30];
    for g in cases {
        let mut grad = vec![g; n];
        adam.begin_step();
        adam.update_dense(&mut params, &mut [&mut grad], 0..n, 0.01);
        assert!(all_finite(&params), "params after g={g}: {params:?}");
        assert!(all_finite(&adam.m) && all_finite(&adam.v), "state after g={g}");
        assert!(grad.iter().all(|&x| x == 0.0), "gradient buffer is reset");
    }
    // and it still learns afterwards: a plain positive gradient lowers the parameter
    let before = params[0];
    for _ in 0..50 {
        let mut grad = vec![1.0f32; n];
        adam.begin_step();
        adam.update_dense(&mut params, &mut [&mut grad], 0..n, 0.01);
    }
    assert!(params[0] < before);
}

#[test]
fn adam_zero_gradient_from_the_start_leaves_parameters_unchanged() {
    let mut params = vec![0.25f32; 4];
    let mut adam = Adam::new(4);
    for _ in 0..10 {
        adam.begin_step();
        adam.update_dense(&mut params, &mut [&mut vec![0.0; 4]], 0..4, 0.1);
    }
    assert_eq!(params, vec![0.25; 4]);
}
