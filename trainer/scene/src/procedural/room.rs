//! `room`: a forward-facing indoor scene in the spirit of LLFF Fern: a textured box room
//! (back wall with a framed picture, floor, side walls, ceiling), a table with things on it
//! and a plant in the foreground. Opaque.

use super::{rgb, Built};
use crate::math::fbm;
use glam::{vec3, Mat4, Vec3};
use crate::mesh::{Background, Geometry, Look, Material};
use crate::procedural::shapes;
use crate::texture::{Texture, Wrap};
use crate::SceneKind;
use std::f32::consts::FRAC_PI_2;

fn black_sky(_: Vec3) -> [f32; 3] {
    [0.0, 0.0, 0.0]
}

pub const ROOM_MIN: [f32; 3] = [-3.0, -1.5, -8.0];
pub const ROOM_MAX: [f32; 3] = [3.0, 2.0, 1.0];

pub fn build() -> Built {
    let mut look = Look::new(Background::Sky(black_sky));
    look.light_dir = vec3(0.3, 0.8, 0.5).normalize_or(Vec3::Y);
    let rgba = |c: [f32; 3]| [c[0], c[1], c[2], 1.0];

    let wallpaper = look.add_texture(Texture::from_fn(256, 256, Wrap::Repeat, move |u, v| {
        let stripe = (u * 8.0).fract() < 0.5;
        let n = fbm(u * 16.0, v * 16.0, 0.0, 21, 4, 16);
        let base = if stripe {
            rgb(0.78, 0.72, 0.6)
        } else {
            rgb(0.7, 0.62, 0.5)
        };
        let (du, dv) = ((u * 8.0).fract() - 0.25, (v * 8.0).fract() - 0.5);
        let flower = (du * du + dv * dv).sqrt() < 0.12 && stripe;
        let c = if flower {
            rgb(0.55, 0.2, 0.25)
        } else {
            base.map(|x| x * (0.85 + 0.3 * n))
        };
        rgba(c)
    }));
    let plaster = look.add_texture(Texture::from_fn(256, 256, Wrap::Repeat, move |u, v| {
        let n = fbm(u * 8.0, v * 8.0, 1.0, 31, 5, 8);
        rgba(rgb(0.55 + 0.25 * n, 0.62 + 0.2 * n, 0.66 + 0.15 * n))
    }));
    let planks = look.add_texture(Texture::from_fn(256, 256, Wrap::Repeat, move |u, v| {
        let plank = (u * 4.0).floor();
        let seam = (u * 4.0).fract() < 0.04 || ((v + plank * 0.37) * 1.0).fract() < 0.015;
        let grain = fbm(u * 4.0 * 8.0, v * 2.0, plank, 41, 4, 0);
        let ring = ((grain * 12.0 + u * 20.0).sin() * 0.5 + 0.5) * 0.25;
        let c = rgb(0.5 + ring, 0.3 + ring * 0.6, 0.15);
        rgba(if seam { rgb(0.15, 0.08, 0.04) } else { c })
    }));
    let painting = look.add_texture(Texture::from_fn(256, 192, Wrap::Clamp, move |u, v| {
        // A little landscape: sky, sun, hills, lake.
        let hill = 0.55 + 0.12 * (u * 9.0).sin() + 0.08 * fbm(u * 6.0, 0.0, 0.0, 51, 3, 0);
        let sun = ((u - 0.75).powi(2) + (v - 0.25).powi(2)).sqrt() < 0.08;
        let c = if v < hill {
            if sun {
                rgb(1.0, 0.85, 0.2)
            } else {
                rgb(0.35 + 0.4 * v, 0.55 + 0.3 * v, 0.95)
            }
        } else if v < 0.8 {
            let n = fbm(u * 20.0, v * 20.0, 0.0, 52, 3, 0);
            rgb(0.15 + 0.2 * n, 0.5 + 0.3 * n, 0.15)
        } else {
            rgb(0.1, 0.3 + 0.2 * (u * 60.0).sin().abs(), 0.6)
        };
        rgba(c)
    }));
    let leaf = look.add_texture(Texture::from_fn(128, 128, Wrap::Repeat, move |u, v| {
        let vein = ((u * 8.0).fract() < 0.06) as i32 as f32;
        let n = fbm(u * 16.0, v * 16.0, 2.0, 61, 3, 16);
        let c = rgb(0.1 + 0.15 * n, 0.45 + 0.3 * n, 0.1);
        rgba(c.map(|x| x + vein * 0.25))
    }));
    let pot = look.add_texture(Texture::from_fn(128, 64, Wrap::Repeat, move |u, v| {
        let band = ((v * 6.0).floor() as i32 % 2 == 0) as i32 as f32;
        let zig = ((u * 24.0).fract() - 0.5).abs() * 2.0;
        let mark = ((v * 6.0).fract() - zig).abs() < 0.15;
        let c = if mark && band > 0.0 {
            rgb(0.95, 0.9, 0.8)
        } else {
            rgb(0.72, 0.35, 0.2)
        };
        rgba(c)
    }));

    let m_wall = look.add_material(Material::textured(wallpaper));
    let m_side = look.add_material(Material::textured(plaster));
    let m_floor = look.add_material(Material::textured(planks));
    let m_ceiling = look.add_material(Material::color(rgb(0.92, 0.92, 0.88)));
    let m_paint = look.add_material(Material::textured(painting));
    let m_frame = look.add_material(Material::color(rgb(0.35, 0.2, 0.08)));
    let m_wood = look.add_material(Material::textured(planks));
    let m_leaf = look.add_material(Material::textured(leaf));
    let m_pot = look.add_material(Material::textured(pot));
    let m_stem = look.add_material(Material::color(rgb(0.25, 0.35, 0.1)));
    let m_vase = look.add_material(Material::color(rgb(0.2, 0.4, 0.85)));
    let m_book = look.add_material(Material::color(rgb(0.8, 0.15, 0.15)));

    let [x0, y0, z0] = ROOM_MIN;
    let [x1, y1, z1] = ROOM_MAX;
    let (cx, cy, cz) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0, (z0 + z1) / 2.0);
    let (hx, hy, hz) = ((x1 - x0) / 2.0, (y1 - y0) / 2.0, (z1 - z0) / 2.0);
    let mut g = Geometry::default();
    // `grid` lies in xz facing +y; rotate it into each wall, facing into the room.
    g.append(
        &shapes::grid(hx, hz, 6, 9, m_floor, 0.5),
        &Mat4::from_translation(vec3(cx, y0, cz)),
    );
    g.append(
        &shapes::grid(hx, hz, 6, 9, m_ceiling, 0.5),
        &(Mat4::from_translation(vec3(cx, y1, cz)) * Mat4::from_axis_angle(vec3(1.0, 0.0, 0.0), std::f32::consts::PI)),
    );
    g.append(
        &shapes::grid(hx, hy, 6, 4, m_wall, 0.5),
        &(Mat4::from_translation(vec3(cx, cy, z0)) * Mat4::from_axis_angle(vec3(1.0, 0.0, 0.0), FRAC_PI_2)),
    );
    g.append(
        &shapes::grid(hy, hz, 4, 9, m_side, 0.4),
        &(Mat4::from_translation(vec3(x0, cy, cz)) * Mat4::from_axis_angle(vec3(0.0, 0.0, 1.0), -FRAC_PI_2)),
    );
    g.append(
        &shapes::grid(hy, hz, 4, 9, m_side, 0.4),
        &(Mat4::from_translation(vec3(x1, cy, cz)) * Mat4::from_axis_angle(vec3(0.0, 0.0, 1.0), FRAC_PI_2)),
    );

    // Picture on the back wall.
    g.append(
        &shapes::cuboid(vec3(1.05, 0.8, 0.03), m_frame, 1.0),
        &Mat4::from_translation(vec3(0.3, 0.6, z0 + 0.03)),
    );
    g.append(
        &shapes::cuboid(vec3(0.9, 0.65, 0.03), m_paint, 1.0),
        &Mat4::from_translation(vec3(0.3, 0.6, z0 + 0.05)),
    );

    // Table at depth ~4 with a vase and books.
    let (tx, tz, ty) = (0.9, -4.2, -0.65);
    g.append(
        &shapes::cuboid(vec3(0.9, 0.05, 0.5), m_wood, 1.0),
        &Mat4::from_translation(vec3(tx, ty, tz)),
    );
    for (lx, lz) in [(-0.8, -0.42), (0.8, -0.42), (-0.8, 0.42), (0.8, 0.42)] {
        g.append(
            &shapes::cylinder(0.05, ty - y0, 12, m_wood, false, [1.0, 1.0]),
            &Mat4::from_translation(vec3(tx + lx, y0, tz + lz)),
        );
    }
    g.append(
        &shapes::sphere(24, 12, m_vase),
        &(Mat4::from_translation(vec3(tx + 0.4, ty + 0.3, tz)) * Mat4::from_scale(vec3(0.18, 0.26, 0.18))),
    );
    g.append(
        &shapes::cuboid(vec3(0.2, 0.05, 0.14), m_book, 1.0),
        &(Mat4::from_translation(vec3(tx - 0.35, ty + 0.1, tz + 0.1))
            * Mat4::from_axis_angle(vec3(0.0, 1.0, 0.0), 0.4)),
    );

    // Plant in the foreground (depth ~2.3): pot, stem, leaves.
    let (px, pz) = (-1.2, -2.4);
    g.append(
        &shapes::cylinder(0.22, 0.45, 24, m_pot, true, [2.0, 1.0]),
        &Mat4::from_translation(vec3(px, y0, pz)),
    );
    g.append(
        &shapes::cylinder(0.03, 0.9, 8, m_stem, false, [1.0, 1.0]),
        &Mat4::from_translation(vec3(px, y0 + 0.45, pz)),
    );
    for k in 0..9 {
        let a = k as f32 * 2.4;
        let h = y0 + 0.6 + 0.09 * k as f32;
        let dir = vec3(a.sin(), 0.0, a.cos());
        let c = vec3(px, h, pz) + dir * 0.22;
        let xf = Mat4::from_translation(c)
            * Mat4::from_axis_angle(vec3(0.0, 1.0, 0.0), a)
            * Mat4::from_axis_angle(vec3(1.0, 0.0, 0.0), 1.1)
            * Mat4::from_scale(vec3(0.08, 0.25, 0.025));
        g.append(&shapes::sphere(12, 8, m_leaf), &xf);
    }

    Built::still(
        look,
        g,
        SceneKind::Forward,
        [vec3(x0, y0, z0), vec3(x1, y1, -1.0)],
        55f32.to_radians(),
    )
}
