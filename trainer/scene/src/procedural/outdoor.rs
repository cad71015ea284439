//! `outdoor`: an unbounded 360-degree scene: a textured statue on a pedestal in [-1, 1]^3,
//! a paved ground disk of radius 100, a ring of pillars, trees and mountains at radius
//! 20-60, and a sky at infinity (gradient + clouds + sun as a function of direction).

use super::{rgb, Built};
use crate::math::{fbm, smoothstep, Rng};
use glam::{vec3, Mat4, Vec3};
use crate::mesh::{Background, Geometry, Look, Material};
use crate::procedural::shapes;
use crate::texture::{Texture, Wrap};
use crate::SceneKind;

pub const GROUND_Y: f32 = -1.0;

/// Sky colour (linear) for a world direction.
pub fn sky(d: Vec3) -> [f32; 3] {
    if d.y < 0.0 {
        // Below the horizon beyond the ground disk: hazy ground.
        let k = smoothstep(0.0, -0.2, d.y);
        let haze = [0.55, 0.6, 0.62];
        let ground = [0.2, 0.25, 0.15];
        return [0, 1, 2].map(|i| haze[i] + (ground[i] - haze[i]) * k);
    }
    let h = d.y.clamp(0.0, 1.0);
    let horizon = [0.75, 0.82, 0.9];
    let zenith = [0.12, 0.3, 0.75];
    let t = h.powf(0.5);
    let mut c = [0, 1, 2].map(|i| horizon[i] + (zenith[i] - horizon[i]) * t);
    // Clouds on a plane above the world.
    let s = 1.0 / (d.y + 0.08);
    let (px, pz) = (d.x * s * 1.5, d.z * s * 1.5);
    let n = fbm(px, pz, 0.0, 77, 5, 0);
    let cloud = smoothstep(0.5, 0.75, n) * smoothstep(0.0, 0.15, d.y);
    c = c.map(|x| x + (0.95 - x) * cloud);
    // Sun.
    let sun = vec3(0.45, 0.8, 0.4).normalize_or(Vec3::Y);
    let a = d.dot(sun);
    let glow = smoothstep(0.995, 0.999, a) + 0.25 * smoothstep(0.9, 1.0, a);
    c.map(|x| x + glow)
}

pub fn build(seed: u64) -> Built {
    let mut look = Look::new(Background::Sky(sky));
    let rgba = |c: [f32; 3]| [c[0], c[1], c[2], 1.0];

    let paving = look.add_texture(Texture::from_fn(256, 256, Wrap::Repeat, move |u, v| {
        // 4x4 stones per tile with grass in the joints.
        let (su, sv) = (u * 4.0, v * 4.0);
        let row = sv.floor();
        let off = if row as i32 % 2 == 0 { 0.0 } else { 0.5 };
        let (fu, fv) = ((su + off).fract(), sv.fract());
        let joint = fu < 0.08 || fv < 0.08;
        let stone = (su + off).floor() * 7.0 + row * 13.0;
        let n = fbm(u * 32.0, v * 32.0, 0.0, 81, 4, 32);
        if joint {
            rgba(rgb(0.25 + 0.2 * n, 0.45 + 0.2 * n, 0.15))
        } else {
            let tint = (stone * 0.37).sin() * 0.08;
            rgba(rgb(
                0.6 + tint + 0.2 * n,
                0.56 + tint + 0.2 * n,
                0.5 + 0.15 * n,
            ))
        }
    }));
    let rock = look.add_texture(Texture::from_fn(256, 256, Wrap::Repeat, move |u, v| {
        let n = fbm(u * 16.0, v * 16.0, 0.0, 91, 5, 16);
        let strata = ((v * 30.0 + n * 6.0).sin() * 0.5 + 0.5) * 0.15;
        let snow = smoothstep(0.25, 0.18, v + 0.1 * n);
        let c = rgb(
            0.4 + 0.3 * n + strata,
            0.36 + 0.25 * n + strata,
            0.33 + 0.2 * n,
        );
        rgba(c.map(|x| x + (0.95 - x) * snow))
    }));
    let marble = look.add_texture(Texture::from_fn(256, 256, Wrap::Repeat, move |u, v| {
        let n = fbm(u * 8.0, v * 8.0, 0.0, 101, 5, 8);
        let vein = (((u + v) * 20.0 + n * 12.0).sin()).abs().powf(0.3);
        rgba(rgb(0.5 + 0.45 * vein, 0.5 + 0.42 * vein, 0.52 + 0.4 * vein))
    }));
    let bark = look.add_texture(Texture::from_fn(64, 128, Wrap::Repeat, move |u, v| {
        let n = fbm(u * 16.0, v * 4.0, 0.0, 111, 3, 16);
        rgba(rgb(0.3 + 0.2 * n, 0.2 + 0.1 * n, 0.1))
    }));
    let foliage = look.add_texture(Texture::from_fn(128, 128, Wrap::Repeat, move |u, v| {
        let n = fbm(u * 16.0, v * 16.0, 0.0, 121, 4, 16);
        rgba(rgb(0.08 + 0.15 * n, 0.3 + 0.35 * n, 0.1 + 0.1 * n))
    }));
    let tiles = look.add_texture(Texture::from_fn(256, 256, Wrap::Repeat, move |u, v| {
        let (cu, cv) = ((u * 8.0).floor() as i32, (v * 8.0).floor() as i32);
        let c = match (cu + 2 * cv).rem_euclid(3) {
            0 => rgb(0.9, 0.75, 0.2),
            1 => rgb(0.15, 0.4, 0.8),
            _ => rgb(0.85, 0.3, 0.25),
        };
        let edge = (u * 8.0).fract() < 0.06 || (v * 8.0).fract() < 0.06;
        rgba(if edge { rgb(0.1, 0.1, 0.1) } else { c })
    }));

    let m_ground = look.add_material(Material::textured(paving));
    let m_rock = look.add_material(Material::textured(rock));
    let m_marble = look.add_material(Material::textured(marble));
    let m_bark = look.add_material(Material::textured(bark));
    let m_leaves = look.add_material(Material::textured(foliage));
    let m_tiles = look.add_material(Material::textured(tiles));
    let m_bronze = look.add_material(Material::color(rgb(0.7, 0.45, 0.2)));

    let mut g = Geometry::default();
    g.append(
        &shapes::disk(100.0, 24, 64, m_ground, 0.5),
        &Mat4::from_translation(vec3(0.0, GROUND_Y, 0.0)),
    );

    // Central statue: pedestal, tiled sphere, bronze ring, marble column.
    g.append(
        &shapes::cylinder(0.7, 0.35, 48, m_marble, true, [3.0, 0.5]),
        &Mat4::from_translation(vec3(0.0, GROUND_Y, 0.0)),
    );
    g.append(
        &shapes::cylinder(0.18, 0.7, 24, m_marble, false, [1.0, 1.0]),
        &Mat4::from_translation(vec3(0.0, GROUND_Y + 0.35, 0.0)),
    );
    g.append(
        &shapes::sphere(48, 24, m_tiles),
        &(Mat4::from_translation(vec3(0.0, 0.45, 0.0)) * Mat4::from_scale(vec3(0.42, 0.42, 0.42))),
    );
    g.append(
        &shapes::torus(0.62, 0.06, 64, 12, m_bronze, [1.0, 1.0]),
        &(Mat4::from_translation(vec3(0.0, 0.45, 0.0)) * Mat4::from_axis_angle(vec3(1.0, 0.0, 0.5).normalize(), 0.9)),
    );

    let mut rng = Rng::new(seed ^ 0x0u64.wrapping_add(4242));
    // Pillars at radius ~20.
    for k in 0..10 {
        let a = k as f32 / 10.0 * std::f32::consts::TAU + 0.2;
        let r = 20.0 + rng.range(-1.0, 1.0);
        g.append(
            &shapes::cylinder(0.8, 7.0, 24, m_marble, true, [2.0, 3.0]),
            &Mat4::from_translation(vec3(a.sin() * r, GROUND_Y, a.cos() * r)),
        );
    }
    // Trees at radius 24-34.
    for _ in 0..28 {
        let a = rng.range(0.0, std::f32::consts::TAU);
        let r = rng.range(24.0, 34.0);
        let s = rng.range(0.7, 1.4);
        let base = vec3(a.sin() * r, GROUND_Y, a.cos() * r);
        g.append(
            &shapes::cylinder(0.35 * s, 3.0 * s, 10, m_bark, false, [1.0, 1.0]),
            &Mat4::from_translation(base),
        );
        g.append(
            &shapes::cone(2.0 * s, 6.0 * s, 16, m_leaves, [2.0, 2.0]),
            &Mat4::from_translation(base + vec3(0.0, 2.0 * s, 0.0)),
        );
    }
    // Mountains at radius 45-60.
    for k in 0..14 {
        let a = k as f32 / 14.0 * std::f32::consts::TAU + rng.range(-0.2, 0.2);
        let r = rng.range(45.0, 60.0);
        let h = rng.range(10.0, 24.0);
        g.append(
            &shapes::cone(rng.range(12.0, 18.0), h, 24, m_rock, [3.0, 2.0]),
            &(Mat4::from_translation(vec3(a.sin() * r, GROUND_Y - 0.5, a.cos() * r))
                * Mat4::from_axis_angle(vec3(0.0, 1.0, 0.0), a)),
        );
    }

    Built::still(
        look,
        g,
        SceneKind::Unbounded,
        [vec3(-4.0, GROUND_Y - 0.1, -4.0), vec3(4.0, GROUND_Y + 3.9, 4.0)],
        60f32.to_radians(),
    )
}
