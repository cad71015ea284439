//! `avatar`: a dynamic head. A skin-textured ellipsoid with hair, nose, ears, eyes with pupils,
//! eyebrows and a mouth; over t in [0, 1] the mouth opens and closes twice (revealing a dark
//! interior and teeth), the eyes blink three times and the brows rise twice.

use super::{rgb, Built, Content};
use crate::math::{fbm, smoothstep};
use glam::{vec3, Mat4, Vec3};
use crate::mesh::{Background, Geometry, Look, Material};
use crate::procedural::shapes;
use crate::texture::{Texture, Wrap};
use crate::SceneKind;
use std::f32::consts::{FRAC_PI_2, TAU};

/// Expression at time t: (mouth open, eye closure, brow raise), each in [0, 1].
pub fn expression(t: f32) -> (f32, f32, f32) {
    let open = 0.5 - 0.5 * (TAU * 2.0 * t).cos();
    let blink = (TAU * 3.0 * t).cos().max(0.0).powi(24);
    let brow = 0.5 - 0.5 * (TAU * 2.0 * t + 1.3).cos();
    (open, blink, brow)
}

struct Mats {
    skin: u32,
    eye: u32,
    brow: u32,
    lip: u32,
    mouth: u32,
    teeth: u32,
}

pub fn build() -> Built {
    let mut look = Look::new(Background::Transparent);
    let skin_tex = look.add_texture(Texture::from_fn(512, 256, Wrap::Repeat, |u, v| {
        // u: longitude (0 = front), v: 0 top .. 1 bottom.
        let n = fbm(u * 64.0, v * 32.0, 0.0, 201, 4, 64);
        let freck = fbm(u * 128.0, v * 64.0, 9.0, 203, 2, 128);
        let mut c = rgb(0.86 + 0.08 * n, 0.66 + 0.08 * n, 0.55 + 0.06 * n);
        if freck > 0.8 {
            c = rgb(0.7, 0.45, 0.33);
        }
        // Cheeks.
        for cu in [0.1f32, 0.9] {
            let d = ((u - cu).powi(2) * 4.0 + (v - 0.58).powi(2) * 9.0).sqrt();
            let k = smoothstep(0.35, 0.0, d) * 0.3;
            c = [c[0], c[1] * (1.0 - k), c[2] * (1.0 - k)];
        }
        // Hair: top of the head and the back.
        let front = (u - 0.5).abs() * 2.0; // 1 at the front, 0 at the back
        let hairline = 0.3 + 0.35 * (1.0 - front).powi(2);
        let strands = fbm(u * 256.0, v * 8.0, 1.0, 207, 3, 256);
        let hair = smoothstep(hairline + 0.02, hairline - 0.02, v);
        let hc = rgb(0.22 + 0.15 * strands, 0.13 + 0.08 * strands, 0.06);
        let c = [0, 1, 2].map(|i| c[i] + (hc[i] - c[i]) * hair);
        [c[0], c[1], c[2], 1.0]
    }));
    let eye_tex = look.add_texture(Texture::from_fn(256, 128, Wrap::Repeat, |u, v| {
        // Sphere pole (v = 0) looks forward.
        let c = if v < 0.07 {
            rgb(0.03, 0.03, 0.03)
        } else if v < 0.17 {
            let streak = 0.5 + 0.5 * (u * TAU * 24.0).sin();
            rgb(0.2 + 0.1 * streak, 0.45 + 0.15 * streak, 0.3 + 0.1 * streak)
        } else if v < 0.19 {
            rgb(0.1, 0.15, 0.1)
        } else {
            let vein = fbm(u * 64.0, v * 32.0, 0.0, 211, 3, 64);
            rgb(0.95, 0.93 - 0.1 * vein.powi(4), 0.9 - 0.1 * vein.powi(4))
        };
        [c[0], c[1], c[2], 1.0]
    }));
    let m = Mats {
        skin: look.add_material(Material::textured(skin_tex)),
        eye: look.add_material(Material::textured(eye_tex)),
        brow: look.add_material(Material::color(rgb(0.2, 0.12, 0.06))),
        lip: look.add_material(Material::color(rgb(0.75, 0.3, 0.3))),
        mouth: look.add_material(Material::color(rgb(0.18, 0.03, 0.04))),
        teeth: look.add_material(Material::color(rgb(0.95, 0.95, 0.9))),
    };
    let content = Content::Dynamic(Box::new(move |t| Ok(head(&m, t))));
    Built {
        look,
        content,
        kind: SceneKind::Object,
        aabb: [vec3(-1.0, -1.1, -1.0), vec3(1.0, 1.1, 1.1)],
        fov_x: 40f32.to_radians(),
        info: Default::default(),
        warnings: Vec::new(),
    }
}

fn ellipsoid(g: &mut Geometry, c: Vec3, r: Vec3, rot: Mat4, mat: u32, segs: usize) {
    g.append(
        &shapes::sphere(segs, segs / 2, mat),
        &(Mat4::from_translation(c) * rot * Mat4::from_scale(r)),
    );
}

fn head(m: &Mats, t: f32) -> Geometry {
    let (open, blink, brow) = expression(t);
    let id = Mat4::IDENTITY;
    let mut g = Geometry::default();
    ellipsoid(
        &mut g,
        vec3(0.0, 0.05, 0.0),
        vec3(0.72, 0.92, 0.8),
        id,
        m.skin,
        64,
    );
    // Ears.
    for s in [-1.0f32, 1.0] {
        ellipsoid(
            &mut g,
            vec3(0.7 * s, 0.05, -0.02),
            vec3(0.07, 0.18, 0.12),
            Mat4::from_axis_angle(vec3(0.0, 1.0, 0.0), 0.3 * s),
            m.skin,
            16,
        );
    }
    // Nose.
    ellipsoid(
        &mut g,
        vec3(0.0, -0.02, 0.76),
        vec3(0.08, 0.15, 0.11),
        Mat4::from_axis_angle(vec3(1.0, 0.0, 0.0), -0.3),
        m.skin,
        16,
    );
    // Eyes: pole of the sphere turned to face +z; blinking squashes them into the head.
    let open_eye = 1.0 - 0.92 * blink;
    for s in [-1.0f32, 1.0] {
        let c = vec3(0.26 * s, 0.2, 0.62);
        let xf = Mat4::from_translation(c)
            * Mat4::from_scale(vec3(0.13, 0.13 * open_eye, 0.13))
            * Mat4::from_axis_angle(vec3(1.0, 0.0, 0.0), FRAC_PI_2);
        g.append(&shapes::sphere(24, 12, m.eye), &xf);
        // Brows.
        let b = Mat4::from_translation(vec3(0.27 * s, 0.4 + 0.09 * brow, 0.66))
            * Mat4::from_axis_angle(vec3(0.0, 0.0, 1.0), -s * (0.12 + 0.15 * brow))
            * Mat4::from_axis_angle(vec3(0.0, 1.0, 0.0), 0.35 * s);
        g.append(&shapes::cuboid(vec3(0.13, 0.028, 0.05), m.brow, 1.0), &b);
    }
    // Mouth: dark interior and teeth appear as the lips part.
    let my = -0.4;
    ellipsoid(
        &mut g,
        vec3(0.0, my - 0.05 * open, 0.63),
        vec3(0.2, 0.02 + 0.11 * open, 0.1),
        id,
        m.mouth,
        24,
    );
    ellipsoid(
        &mut g,
        vec3(0.0, my + 0.03 * open, 0.64),
        vec3(0.14, 0.025 + 0.015 * open, 0.08),
        id,
        m.teeth,
        16,
    );
    ellipsoid(
        &mut g,
        vec3(0.0, my + 0.035 + 0.03 * open, 0.67),
        vec3(0.21, 0.04, 0.07),
        id,
        m.lip,
        24,
    );
    ellipsoid(
        &mut g,
        vec3(0.0, my - 0.04 - 0.16 * open, 0.66),
        vec3(0.19, 0.045, 0.07),
        id,
        m.lip,
        24,
    );
    g
}
