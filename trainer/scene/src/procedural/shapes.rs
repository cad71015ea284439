//! Parametric meshes (sphere, box, cylinder, cone, torus, grid) with normals and UVs, built in
//! local coordinates; scenes place them with `Geometry::append(&shape, &transform)`.

use glam::{vec3, Vec3};
use crate::mesh::Geometry;
use std::f32::consts::{PI, TAU};

/// Generic parametric surface over (u, v) in [0,1]^2: `f` returns (position, normal).
fn param(
    nu: usize,
    nv: usize,
    mat: u32,
    uv_scale: [f32; 2],
    f: impl Fn(f32, f32) -> (Vec3, Vec3),
) -> Geometry {
    let mut g = Geometry::default();
    for j in 0..=nv {
        for i in 0..=nu {
            let (u, v) = (i as f32 / nu as f32, j as f32 / nv as f32);
            let (p, n) = f(u, v);
            g.vertex(p, n, [u * uv_scale[0], v * uv_scale[1]]);
        }
    }
    let idx = |i: usize, j: usize| (j * (nu + 1) + i) as u32;
    for j in 0..nv {
        for i in 0..nu {
            let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
            g.tri(a, c, b, mat);
            g.tri(a, d, c, mat);
        }
    }
    g
}

/// Unit sphere (radius 1); u = longitude, v = 0 at the top (+y) to 1 at the bottom.
pub fn sphere(segs: usize, rings: usize, mat: u32) -> Geometry {
    param(segs, rings, mat, [1.0, 1.0], |u, v| {
        let (th, ph) = (u * TAU, v * PI);
        let n = vec3(ph.sin() * th.sin(), ph.cos(), ph.sin() * th.cos());
        (n, n)
    })
}

/// Torus around the y axis with major radius `r0`, minor radius `r1`.
pub fn torus(
    r0: f32,
    r1: f32,
    segs: usize,
    sides: usize,
    mat: u32,
    uv_scale: [f32; 2],
) -> Geometry {
    param(segs, sides, mat, uv_scale, |u, v| {
        let (a, b) = (u * TAU, (1.0 - v) * TAU);
        let ring = vec3(a.sin(), 0.0, a.cos());
        let n = ring * b.cos() + vec3(0.0, b.sin(), 0.0);
        (ring * r0 + n * r1, n)
    })
}

/// Cylinder of radius `r` from y = 0 to y = `h`, with caps when `caps`.
pub fn cylinder(r: f32, h: f32, segs: usize, mat: u32, caps: bool, uv_scale: [f32; 2]) -> Geometry {
    let mut g = param(segs, 1, mat, uv_scale, |u, v| {
        let a = u * TAU;
        let n = vec3(a.sin(), 0.0, a.cos());
        (n * r + vec3(0.0, h * (1.0 - v), 0.0), n)
    });
    if caps {
        for (y, up) in [(h, 1.0f32), (0.0, -1.0)] {
            let c = g.vertex(vec3(0.0, y, 0.0), vec3(0.0, up, 0.0), [0.5, 0.5]);
            let first = g.positions.len() as u32;
            for i in 0..=segs {
                let a = i as f32 / segs as f32 * TAU;
                g.vertex(
                    vec3(a.sin() * r, y, a.cos() * r),
                    vec3(0.0, up, 0.0),
                    [0.5 + 0.5 * a.sin(), 0.5 + 0.5 * a.cos()],
                );
            }
            for i in 0..segs as u32 {
                if up > 0.0 {
                    g.tri(c, first + i, first + i + 1, mat);
                } else {
                    g.tri(c, first + i + 1, first + i, mat);
                }
            }
        }
    }
    g
}

/// Cone with base radius `r` at y = 0 and apex at y = `h`.
pub fn cone(r: f32, h: f32, segs: usize, mat: u32, uv_scale: [f32; 2]) -> Geometry {
    let slope = r / h;
    param(segs, 8, mat, uv_scale, |u, v| {
        let a = u * TAU;
        let k = v; // 0 at the apex, 1 at the base
        let dir = vec3(a.sin(), 0.0, a.cos());
        let p = dir * (r * k) + vec3(0.0, h * (1.0 - k), 0.0);
        (p, (dir + vec3(0.0, slope, 0.0)).normalize_or(Vec3::Y))
    })
}

/// Axis-aligned box with half extents `he`, each face with its own [0,1]^2 UVs times `uv_scale`.
pub fn cuboid(he: Vec3, mat: u32, uv_scale: f32) -> Geometry {
    let mut g = Geometry::default();
    let faces = [
        (vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, -1.0), vec3(0.0, 1.0, 0.0)),
        (vec3(-1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0), vec3(0.0, 1.0, 0.0)),
        (vec3(0.0, 1.0, 0.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, -1.0)),
        (vec3(0.0, -1.0, 0.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 0.0, 1.0)),
        (vec3(0.0, 0.0, 1.0), vec3(1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0)),
        (vec3(0.0, 0.0, -1.0), vec3(-1.0, 0.0, 0.0), vec3(0.0, 1.0, 0.0)),
    ];
    for (n, t, b) in faces {
        let base = g.positions.len() as u32;
        for (su, sv) in [(-1.0f32, -1.0f32), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            let p = (n + t * su + b * sv) * he;
            g.vertex(
                p,
                n,
                [(su + 1.0) * 0.5 * uv_scale, (1.0 - sv) * 0.5 * uv_scale],
            );
        }
        g.tri(base, base + 1, base + 2, mat);
        g.tri(base, base + 2, base + 3, mat);
    }
    g
}

/// A flat grid in the xz plane (y = 0, normal +y) covering [-sx, sx] x [-sz, sz], UV = xz * uv_per_unit.
pub fn grid(sx: f32, sz: f32, nx: usize, nz: usize, mat: u32, uv_per_unit: f32) -> Geometry {
    let mut g = param(nx, nz, mat, [1.0, 1.0], |u, v| {
        (
            vec3((u * 2.0 - 1.0) * sx, 0.0, (v * 2.0 - 1.0) * sz),
            vec3(0.0, 1.0, 0.0),
        )
    });
    for (p, uv) in g.positions.iter().zip(g.uvs.iter_mut()) {
        *uv = [p.x * uv_per_unit, p.z * uv_per_unit];
    }
    g
}

/// Flat disk of radius `r` in the xz plane in rings (so large disks stay well tessellated).
pub fn disk(r: f32, rings: usize, segs: usize, mat: u32, uv_per_unit: f32) -> Geometry {
    let mut g = Geometry::default();
    let up = vec3(0.0, 1.0, 0.0);
    let c = g.vertex(Vec3::default(), up, [0.0, 0.0]);
    // Geometric ring radii so near rings are small and far rings large.
    let radius = |k: usize| r * ((k as f32 / rings as f32) * 7.0).exp2() / 128.0f32;
    for k in 1..=rings {
        let rr = radius(k);
        for i in 0..segs {
            let a = i as f32 / segs as f32 * TAU;
            let p = vec3(a.sin() * rr, 0.0, a.cos() * rr);
            g.vertex(p, up, [p.x * uv_per_unit, p.z * uv_per_unit]);
        }
    }
    let ring = |k: usize, i: usize| (1 + (k - 1) * segs + i % segs) as u32;
    for i in 0..segs {
        g.tri(c, ring(1, i), ring(1, i + 1), mat);
    }
    for k in 1..rings {
        for i in 0..segs {
            let (a, b, cc, d) = (
                ring(k, i),
                ring(k, i + 1),
                ring(k + 1, i + 1),
                ring(k + 1, i),
            );
            g.tri(a, d, cc, mat);
            g.tri(a, cc, b, mat);
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every triangle of the closed shapes winds counter-clockwise seen from outside
    /// (its face normal agrees with the vertex normals).
    #[test]
    fn windings_agree_with_normals() {
        for (name, g) in [
            ("sphere", sphere(16, 8, 0)),
            ("torus", torus(1.0, 0.3, 16, 8, 0, [1.0, 1.0])),
            ("cylinder", cylinder(1.0, 1.0, 16, 0, true, [1.0, 1.0])),
            ("cone", cone(1.0, 1.0, 16, 0, [1.0, 1.0])),
            ("box", cuboid(vec3(1.0, 2.0, 3.0), 0, 1.0)),
            ("grid", grid(1.0, 1.0, 4, 4, 0, 1.0)),
            ("disk", disk(10.0, 6, 12, 0, 1.0)),
        ] {
            let mut bad = 0;
            for t in &g.tris {
                let [a, b, c] = t.map(|i| g.positions[i as usize]);
                let f = (b - a).cross(c - a);
                let n =
                    g.normals[t[0] as usize] + g.normals[t[1] as usize] + g.normals[t[2] as usize];
                if f.length() > 1e-6 && f.dot(n) < 0.0 {
                    bad += 1;
                }
            }
            assert_eq!(
                bad,
                0,
                "{name}: {bad} of {} triangles wound inwards",
                g.tris.len()
            );
        }
    }
}
