//! `object`: a 360-degree inward-facing object scene (textured sphere, striped box, patterned
//! torus, brick cylinder and a cone) inside [-1, 1]^3 with a transparent background.

use super::{rgb, Built};
use crate::math::fbm;
use glam::{vec3, Mat4};
use crate::mesh::{Background, Geometry, Look, Material};
use crate::procedural::shapes;
use crate::texture::{Texture, Wrap};
use crate::SceneKind;

pub fn build() -> Built {
    let mut look = Look::new(Background::Transparent);

    // Checker with noise and thin grid lines (sphere).
    let checker = look.add_texture(Texture::from_fn(512, 256, Wrap::Repeat, |u, v| {
        let (cu, cv) = ((u * 16.0).floor() as i32, (v * 8.0).floor() as i32);
        let n = fbm(u * 32.0, v * 16.0, 0.0, 1, 4, 32);
        let base = if (cu + cv) % 2 == 0 {
            rgb(0.85, 0.25, 0.1)
        } else {
            rgb(0.95, 0.85, 0.6)
        };
        let line = ((u * 16.0).fract() < 0.04 || (v * 8.0).fract() < 0.04) as i32 as f32;
        let k = 0.75 + 0.5 * n;
        let c = base.map(|x| x * k * (1.0 - 0.8 * line));
        [c[0], c[1], c[2], 1.0]
    }));
    // Diagonal stripes with dots (box faces).
    let stripes = look.add_texture(Texture::from_fn(256, 256, Wrap::Repeat, |u, v| {
        let s = ((u + v) * 6.0).fract();
        let c = if s < 0.5 {
            rgb(0.1, 0.35, 0.8)
        } else {
            rgb(0.95, 0.95, 0.9)
        };
        let (du, dv) = ((u * 4.0).fract() - 0.5, (v * 4.0).fract() - 0.5);
        let dot = (du * du + dv * dv).sqrt() < 0.12;
        let c = if dot { rgb(0.95, 0.8, 0.1) } else { c };
        [c[0], c[1], c[2], 1.0]
    }));
    // Bands and noise (torus).
    let bands = look.add_texture(Texture::from_fn(512, 128, Wrap::Repeat, |u, v| {
        let b = (u * 24.0).floor() as i32 % 3;
        let n = fbm(u * 64.0, v * 16.0, 3.0, 7, 3, 64);
        let c = match b {
            0 => rgb(0.2, 0.7, 0.3),
            1 => rgb(0.9, 0.9, 0.2),
            _ => rgb(0.5, 0.15, 0.6),
        };
        let ring = ((v * 4.0).fract() < 0.08) as i32 as f32;
        let k = 0.7 + 0.6 * n;
        let c = c.map(|x| (x * k * (1.0 - 0.7 * ring)).min(1.0));
        [c[0], c[1], c[2], 1.0]
    }));
    // Bricks (cylinder).
    let bricks = look.add_texture(Texture::from_fn(256, 256, Wrap::Repeat, |u, v| {
        let (rows, cols) = (8.0, 8.0);
        let row = (v * rows).floor();
        let off = if row as i32 % 2 == 0 { 0.0 } else { 0.5 };
        let (fu, fv) = ((u * cols + off).fract(), (v * rows).fract());
        let mortar = fu < 0.06 || fv < 0.1;
        let n = fbm(u * 40.0, v * 40.0, 5.0, 11, 3, 40);
        let c = if mortar {
            rgb(0.8, 0.8, 0.75)
        } else {
            rgb(0.6 + 0.3 * n, 0.2 + 0.1 * n, 0.12)
        };
        [c[0], c[1], c[2], 1.0]
    }));

    let m_sphere = look.add_material(Material::textured(checker));
    let m_box = look.add_material(Material::textured(stripes));
    let m_torus = look.add_material(Material::textured(bands));
    let m_cyl = look.add_material(Material::textured(bricks));
    let m_cone = look.add_material(Material::color(rgb(0.1, 0.6, 0.65)));

    let mut g = Geometry::default();
    g.append(
        &shapes::sphere(48, 24, m_sphere),
        &(Mat4::from_translation(vec3(-0.4, 0.35, 0.25)) * Mat4::from_scale(vec3(0.55, 0.55, 0.55))),
    );
    g.append(
        &shapes::cuboid(vec3(0.35, 0.35, 0.35), m_box, 1.0),
        &(Mat4::from_translation(vec3(0.45, -0.55, 0.3)) * Mat4::from_axis_angle(vec3(0.0, 1.0, 0.0), 0.5)),
    );
    g.append(
        &shapes::torus(0.5, 0.14, 64, 16, m_torus, [1.0, 1.0]),
        &(Mat4::from_translation(vec3(0.3, 0.35, -0.3)) * Mat4::from_axis_angle(vec3(1.0, 0.0, 0.3).normalize(), 0.7)),
    );
    g.append(
        &shapes::cylinder(0.3, 0.8, 40, m_cyl, true, [2.0, 1.0]),
        &Mat4::from_translation(vec3(-0.45, -0.95, -0.4)),
    );
    g.append(
        &shapes::cone(0.25, 0.6, 32, m_cone, [1.0, 1.0]),
        &Mat4::from_translation(vec3(0.55, -0.2, 0.3)),
    );

    Built::still(
        look,
        g,
        SceneKind::Object,
        [vec3(-1.2, -1.2, -1.2), vec3(1.2, 1.2, 1.2)],
        40f32.to_radians(),
    )
}
