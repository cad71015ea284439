//! A capture's up direction travels from its cameras to every client: the same scene
//! captured z-up (Blender, nerf_synthetic) and y-up (glTF, nerfstudio) gets the same upright
//! preview orbit and start view, rendered identically from the baked asset.

use snerf_asset::render::{orbit, render};
use snerf_asset::{encode_voxel, Asset, AssetBuilder, Camera, Header, Kind, ViewMlp};
use snerf_data::{Intrinsics, SceneKind, View};
use snerf_geometry::camera::look_at;
use snerf_geometry::vec::{norm, sub};
use snerf_geometry::{Orbit, Space};
use snerf_trainer::camera_path::preview_orbit;

/// +90° about x: y-up → z-up.
fn rot(p: [f32; 3]) -> [f32; 3] {
    [p[0], -p[2], p[1]]
}
fn unrot(p: [f32; 3]) -> [f32; 3] {
    [p[0], p[2], -p[1]]
}

/// A ring of cameras 25° above the horizon of a y-up world, looking at the origin.
fn y_up_views() -> Vec<View> {
    (0..24)
        .map(|i| {
            let a = i as f32 / 24.0 * std::f32::consts::TAU + 0.4;
            let (el, r) = (25f32.to_radians(), 3.0);
            let eye = [r * el.cos() * a.sin(), r * el.sin(), r * el.cos() * a.cos()];
            view(look_at(eye, [0.0; 3], [0.0, 1.0, 0.0]))
        })
        .collect()
}

fn view(c2w: [[f32; 4]; 3]) -> View {
    let intrinsics = Intrinsics { width: 8, height: 8, fx: 8.0, fy: 8.0, cx: 4.0, cy: 4.0, distortion: [0.0; 4] };
    View { path: "v.png".into(), intrinsics, c2w, time: None, rgba: vec![255; 8 * 8 * 4] }
}

/// The same cameras in the z-up world.
fn rotated(v: &View) -> View {
    let m = v.c2w;
    let col = |j: usize| rot([m[0][j], m[1][j], m[2][j]]);
    let (x, y, z, t) = (col(0), col(1), col(2), col(3));
    view([[x[0], y[0], z[0], t[0]], [x[1], y[1], z[1], t[1]], [x[2], y[2], z[2], t[2]]])
}

/// A figure standing along +y in the y-up world: a body, a head, and colour from position
/// (so any turn or flip of the view shows).
fn figure(w: [f32; 3]) -> (f32, [f32; 3]) {
    let body = 0.35 - norm(sub(w, [0.0, -0.2, 0.0]));
    let head = 0.2 - norm(sub(w, [0.1, 0.35, 0.0]));
    let logit = (40.0 * body.max(head)).clamp(-10.0, 10.0);
    (logit, w.map(|x| (0.5 + 0.7 * x).clamp(0.0, 1.0)))
}

fn asset(view_orbit: Orbit, world_to_figure: fn([f32; 3]) -> [f32; 3]) -> Asset {
    const RES: u32 = 32;
    let mut h = Header::new(Kind::Object, RES, 8);
    h.view = Some(view_orbit);
    h.background = [1.0; 3];
    let centre = |i: usize| -1.0 + (i as f32 + 0.5) * 2.0 / RES as f32;
    let hc = h.clone();
    let voxel = move |v: [usize; 3]| {
        let (logit, rgb) = figure(world_to_figure(v.map(centre)));
        encode_voxel(logit, rgb, [0.0; 4], &hc.density)
    };
    let mut b = AssetBuilder::new(h, ViewMlp::zeros()).unwrap();
    b.fill_from_fn(0, voxel).unwrap();
    b.finish().unwrap()
}

fn mean_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.len() as f32
}

#[test]
fn z_up_and_y_up_captures_render_the_same_upright_orbit_and_start_view() {
    let vy = y_up_views();
    let vz: Vec<View> = vy.iter().map(rotated).collect();
    let frame = Space::identity();
    let oy = preview_orbit(SceneKind::Object, &frame, &vy.iter().collect::<Vec<_>>(), None);
    let oz = preview_orbit(SceneKind::Object, &frame, &vz.iter().collect::<Vec<_>>(), None);
    let (Orbit::Around { up: uy, start: sy, radius: ry, elevation: ey, .. }, Orbit::Around { up: uz, start: sz, radius: rz, elevation: ez, .. }) = (oy, oz) else {
        panic!("objects orbit around their centre")
    };
    assert!(norm(sub(rot(uy), uz)) < 1e-4 && norm(sub(rot(sy), sz)) < 1e-4, "orbits differ: {oy:?} vs {oz:?}");
    assert!((ry - rz).abs() < 1e-4 && (ey - ez).abs() < 1e-4);
    assert!(uz[2] > 0.99, "the z-up capture's up is +z: {uz:?}");

    let ay = asset(oy, |w| w);
    let az = asset(oz, unrot);
    let cams = |a: &Asset| -> Vec<Camera> {
        let mut c: Vec<Camera> = [0, 2, 5].iter().map(|&i| orbit(&a.header, 8, i, 40, 40, 45.0)).collect();
        c.push(Camera::from_fov(a.header.orbit().start_c2w(), 40, 40, 45.0));
        c
    };
    for (i, (cy, cz)) in cams(&ay).iter().zip(cams(&az)).enumerate() {
        let (fy, fz) = (render(&ay, cy, 0.0), render(&az, &cz, 0.0));
        let covered = fy.opacity.iter().filter(|&&o| o > 0.5).count();
        assert!(covered > 100, "view {i}: the figure covers only {covered} pixels");
        let d = mean_abs_diff(&fy.rgb, &fz.rgb);
        assert!(d < 1.0 / 255.0, "view {i}: z-up and y-up renders differ by {:.2}/255", d * 255.0);
    }

    // Without the stored up (an asset from before it existed) the z-up figure lies on its
    // side in the preview: the check above is what tells them apart.
    let mut old = az.clone();
    old.header.view = None;
    let d = mean_abs_diff(&render(&ay, &orbit(&ay.header, 8, 0, 40, 40, 45.0), 0.0).rgb, &render(&old, &orbit(&old.header, 8, 0, 40, 40, 45.0), 0.0).rgb);
    assert!(d > 4.0 / 255.0, "a model-+y orbit of the z-up capture should not look upright ({:.2}/255)", d * 255.0);
}
