//! The CPU renderer: a supersampled z-buffer triangle rasterizer with near-plane clipping,
//! perspective-correct attribute interpolation, mip-mapped texturing and simple
//! view-independent Lambert lighting. Work is split into horizontal bands run with rayon.

use glam::{Mat3, Mat4, Vec3};
use snerf_geometry::camera::{position, C2w, Pinhole};
use crate::mesh::{Background, Geometry, Look};
use crate::texture::encode_srgb8;
use rayon::prelude::*;

/// The pinhole camera of a dataset view: square pixels, principal point at the centre and
/// the horizontal field of view `fov_x` (radians), which is what nerf_synthetic's
/// `camera_angle_x` stores.
pub fn camera(c2w: C2w, width: u32, height: u32, fov_x: f32) -> Pinhole {
    let f = focal(width, fov_x);
    Pinhole { c2w, fx: f, fy: f, cx: width as f32 * 0.5, cy: height as f32 * 0.5, width, height }
}

/// Focal length in pixels of an image `width` pixels wide with horizontal field of view
/// `fov_x` (radians).
pub fn focal(width: u32, fov_x: f32) -> f32 {
    0.5 * width as f32 / (0.5 * fov_x).tan()
}

/// The camera-to-world rows as a glam matrix (the fourth row is implied).
pub fn c2w_matrix(c2w: &C2w) -> Mat4 {
    Mat4::from_cols_array_2d(&[
        [c2w[0][0], c2w[1][0], c2w[2][0], 0.0],
        [c2w[0][1], c2w[1][1], c2w[2][1], 0.0],
        [c2w[0][2], c2w[1][2], c2w[2][2], 0.0],
        [c2w[0][3], c2w[1][3], c2w[2][3], 1.0],
    ])
}

/// World-to-camera of a camera pose: the rotation transposed, not a general inverse, because
/// poses are rigid and the transpose is exact where `inverse()` would round.
pub fn world_to_camera(c2w: &C2w) -> Mat4 {
    let m = c2w_matrix(c2w);
    let r = Mat3::from_mat4(m).transpose();
    Mat4::from_mat3_translation(r, -(r * m.w_axis.truncate()))
}

/// A rendered view: 8-bit RGBA (straight alpha) and per-pixel mean z-depth of the covered
/// samples along the camera's -z axis (infinity where nothing was hit).
#[cfg_attr(not(test), allow(dead_code))]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
    pub depth: Vec<f32>,
}

const NEAR: f64 = 1e-2;
const BAND_PIXELS: usize = 8;
const NONE: u32 = u32::MAX;

/// A screen-space (sample-space) triangle ready for scan conversion. Attribute planes are
/// `a0 + dx * (x - x0) + dy * (y - y0)` for 1/depth and for q1/depth, q2/depth, where q are
/// barycentric coordinates of the original (unclipped) triangle.
struct RTri {
    tri: u32,
    p: [[f64; 2]; 3],
    invd: [f64; 3],
    q1: [f64; 3],
    q2: [f64; 3],
    /// Sign applied to the interpolated vertex normal so it faces the visible side.
    nsign: f32,
    bbox: [i64; 4],
}

fn plane(p: &[[f64; 2]; 3], a: [f64; 3], area2: f64) -> [f64; 3] {
    let (x0, y0) = (p[0][0], p[0][1]);
    let (e1x, e1y) = (p[1][0] - x0, p[1][1] - y0);
    let (e2x, e2y) = (p[2][0] - x0, p[2][1] - y0);
    let (d1, d2) = (a[1] - a[0], a[2] - a[0]);
    let dx = (d1 * e2y - d2 * e1y) / area2;
    let dy = (d2 * e1x - d1 * e2x) / area2;
    [a[0], dx, dy]
}

#[inline]
fn eval(pl: &[f64; 3], p0: &[f64; 2], x: f64, y: f64) -> f64 {
    pl[0] + pl[1] * (x - p0[0]) + pl[2] * (y - p0[1])
}

fn setup(geom: &Geometry, cam: &Pinhole, w2c: &Mat4, ss: f64, sw: i64, sh: i64) -> Vec<RTri> {
    let cam_pos = Vec3::from(position(&cam.c2w));
    let mut out = Vec::new();
    for (ti, t) in geom.tris.iter().enumerate() {
        let wp = t.map(|i| geom.positions[i as usize]);
        if !(wp[0].is_finite() && wp[1].is_finite() && wp[2].is_finite()) {
            continue;
        }
        let fnorm = (wp[1] - wp[0]).cross(wp[2] - wp[0]);
        if fnorm.length() == 0.0 {
            continue;
        }
        let nsum = t
            .iter()
            .fold(Vec3::default(), |a, &i| a + geom.normals[i as usize]);
        let agree = if fnorm.dot(nsum) >= 0.0 { 1.0 } else { -1.0 };
        let visible_front = if fnorm.dot(cam_pos - wp[0]) >= 0.0 {
            1.0
        } else {
            -1.0
        };
        let nsign = agree * visible_front;

        // Camera space, depth d = -z; clip the polygon against d >= NEAR.
        let cv: [[f64; 4]; 3] = [0, 1, 2].map(|k| {
            let c = w2c.transform_point3(wp[k]);
            [c.x as f64, c.y as f64, -(c.z as f64), 0.0]
        });
        let qs = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let mut poly: Vec<([f64; 3], [f64; 3])> = Vec::with_capacity(4);
        if cv.iter().all(|v| v[2] >= NEAR) {
            for k in 0..3 {
                poly.push(([cv[k][0], cv[k][1], cv[k][2]], qs[k]));
            }
        } else {
            for k in 0..3 {
                let (a, b) = (cv[k], cv[(k + 1) % 3]);
                let (qa, qb) = (qs[k], qs[(k + 1) % 3]);
                let (ina, inb) = (a[2] >= NEAR, b[2] >= NEAR);
                if ina {
                    poly.push(([a[0], a[1], a[2]], qa));
                }
                if ina != inb {
                    let s = (NEAR - a[2]) / (b[2] - a[2]);
                    let l = |u: f64, v: f64| u + (v - u) * s;
                    poly.push((
                        [l(a[0], b[0]), l(a[1], b[1]), NEAR],
                        [l(qa[0], qb[0]), l(qa[1], qb[1]), l(qa[2], qb[2])],
                    ));
                }
            }
        }
        if poly.len() < 3 {
            continue;
        }
        let proj: Vec<([f64; 2], f64, [f64; 3])> = poly
            .iter()
            .map(|(c, q)| {
                let inv = 1.0 / c[2];
                let x = (cam.cx as f64 + cam.fx as f64 * c[0] * inv) * ss;
                let y = (cam.cy as f64 - cam.fy as f64 * c[1] * inv) * ss;
                ([x, y], inv, *q)
            })
            .collect();
        for k in 1..proj.len() - 1 {
            let mut v = [proj[0], proj[k], proj[k + 1]];
            let area = |v: &[([f64; 2], f64, [f64; 3]); 3]| {
                (v[1].0[0] - v[0].0[0]) * (v[2].0[1] - v[0].0[1])
                    - (v[2].0[0] - v[0].0[0]) * (v[1].0[1] - v[0].0[1])
            };
            let mut a2 = area(&v);
            if !a2.is_finite() || a2.abs() < 1e-12 {
                continue;
            }
            if a2 < 0.0 {
                v.swap(1, 2);
                a2 = -a2;
            }
            let p = [v[0].0, v[1].0, v[2].0];
            let xmin = p.iter().map(|q| q[0]).fold(f64::INFINITY, f64::min);
            let xmax = p.iter().map(|q| q[0]).fold(f64::NEG_INFINITY, f64::max);
            let ymin = p.iter().map(|q| q[1]).fold(f64::INFINITY, f64::min);
            let ymax = p.iter().map(|q| q[1]).fold(f64::NEG_INFINITY, f64::max);
            // Samples at integer + 0.5.
            let bx0 = ((xmin - 0.5).ceil() as i64).max(0);
            let bx1 = ((xmax - 0.5).floor() as i64).min(sw - 1);
            let by0 = ((ymin - 0.5).ceil() as i64).max(0);
            let by1 = ((ymax - 0.5).floor() as i64).min(sh - 1);
            if bx0 > bx1 || by0 > by1 {
                continue;
            }
            let invd = plane(&p, [v[0].1, v[1].1, v[2].1], a2);
            let q1 = plane(
                &p,
                [v[0].2[1] * v[0].1, v[1].2[1] * v[1].1, v[2].2[1] * v[2].1],
                a2,
            );
            let q2 = plane(
                &p,
                [v[0].2[2] * v[0].1, v[1].2[2] * v[1].1, v[2].2[2] * v[2].1],
                a2,
            );
            out.push(RTri {
                tri: ti as u32,
                p,
                invd,
                q1,
                q2,
                nsign,
                bbox: [bx0, bx1, by0, by1],
            });
        }
    }
    out
}

/// Render `geom` with `look` from `cam` with `ss` x `ss` samples per pixel.
pub fn render(look: &Look, geom: &Geometry, cam: &Pinhole, ss: u32) -> Frame {
    let ss = ss.max(1) as usize;
    let (w, h) = (cam.width as usize, cam.height as usize);
    let (sw, sh) = (w * ss, h * ss);
    let w2c = world_to_camera(&cam.c2w);
    let rtris = setup(geom, cam, &w2c, ss as f64, sw as i64, sh as i64);

    let band_rows = BAND_PIXELS * ss;
    let nbands = sh.div_ceil(band_rows);
    let mut bands: Vec<Vec<u32>> = vec![Vec::new(); nbands];
    for (i, rt) in rtris.iter().enumerate() {
        for band in &mut bands[rt.bbox[2] as usize / band_rows..=rt.bbox[3] as usize / band_rows] {
            band.push(i as u32);
        }
    }

    let results: Vec<(Vec<u8>, Vec<f32>)> = bands
        .par_iter()
        .enumerate()
        .map(|(bi, list)| {
            render_band(
                look,
                geom,
                cam,
                &rtris,
                list,
                bi * band_rows,
                band_rows.min(sh - bi * band_rows),
                ss,
                sw,
            )
        })
        .collect();
    let mut rgba = Vec::with_capacity(w * h * 4);
    let mut depth = Vec::with_capacity(w * h);
    for (c, d) in results {
        rgba.extend_from_slice(&c);
        depth.extend_from_slice(&d);
    }
    Frame {
        width: cam.width,
        height: cam.height,
        rgba,
        depth,
    }
}

#[allow(clippy::too_many_arguments)]
fn render_band(
    look: &Look,
    geom: &Geometry,
    cam: &Pinhole,
    rtris: &[RTri],
    list: &[u32],
    y0: usize,
    rows: usize,
    ss: usize,
    sw: usize,
) -> (Vec<u8>, Vec<f32>) {
    let mut zbuf = vec![0.0f64; sw * rows];
    let mut ids = vec![NONE; sw * rows];
    for &ri in list {
        let rt = &rtris[ri as usize];
        let ya = (rt.bbox[2] as usize).max(y0);
        let yb = (rt.bbox[3] as usize).min(y0 + rows - 1);
        if ya > yb {
            continue;
        }
        let p = &rt.p;
        // Edge functions E_k(x, y) = A x + B y + C; inside where all >= 0.
        let edges: [[f64; 3]; 3] = [0, 1, 2].map(|k| {
            let (a, b) = (p[(k + 1) % 3], p[(k + 2) % 3]);
            let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
            [-dy, dx, dy * a[0] - dx * a[1]]
        });
        let (xa, xb) = (rt.bbox[0] as usize, rt.bbox[1] as usize);
        for y in ya..=yb {
            let py = y as f64 + 0.5;
            let row = (y - y0) * sw;
            let px0 = xa as f64 + 0.5;
            let mut e = edges.map(|ed| ed[0] * px0 + ed[1] * py + ed[2]);
            let mut z = eval(&rt.invd, &p[0], px0, py);
            for x in xa..=xb {
                if e[0] >= 0.0 && e[1] >= 0.0 && e[2] >= 0.0 && z > zbuf[row + x] {
                    zbuf[row + x] = z;
                    ids[row + x] = ri;
                }
                e[0] += edges[0][0];
                e[1] += edges[1][0];
                e[2] += edges[2][0];
                z += rt.invd[1];
            }
        }
    }

    // Shade and resolve to pixels.
    let w = sw / ss;
    let prow = rows / ss;
    let mut rgba = vec![0u8; w * prow * 4];
    let mut depth = vec![f32::INFINITY; w * prow];
    let n = (ss * ss) as f32;
    for py in 0..prow {
        for px in 0..w {
            let mut acc = [0.0f32; 3];
            let mut covered = 0usize;
            let mut dsum = 0.0f64;
            for sy in 0..ss {
                let y = py * ss + sy;
                for sx in 0..ss {
                    let x = px * ss + sx;
                    let id = ids[y * sw + x];
                    if id == NONE {
                        continue;
                    }
                    let rt = &rtris[id as usize];
                    let (fx, fy) = (x as f64 + 0.5, (y + y0) as f64 + 0.5);
                    let c = shade(look, geom, rt, fx, fy);
                    acc[0] += c[0];
                    acc[1] += c[1];
                    acc[2] += c[2];
                    covered += 1;
                    dsum += 1.0 / zbuf[y * sw + x];
                }
            }
            let o = (py * w + px) * 4;
            if covered > 0 {
                depth[py * w + px] = (dsum / covered as f64) as f32;
            }
            match look.background {
                Background::Transparent => {
                    if covered > 0 {
                        let k = 1.0 / covered as f32;
                        rgba[o] = encode_srgb8(acc[0] * k);
                        rgba[o + 1] = encode_srgb8(acc[1] * k);
                        rgba[o + 2] = encode_srgb8(acc[2] * k);
                        rgba[o + 3] = ((covered as f32 / n) * 255.0 + 0.5) as u8;
                    }
                }
                Background::Sky(sky) => {
                    let miss = (ss * ss - covered) as f32;
                    if miss > 0.0 {
                        let d = Vec3::from(cam.ray(px as u32, (py + y0 / ss) as u32).1);
                        let s = sky(d);
                        for k in 0..3 {
                            acc[k] += s[k] * miss;
                        }
                    }
                    for k in 0..3 {
                        rgba[o + k] = encode_srgb8(acc[k] / n);
                    }
                    rgba[o + 3] = 255;
                }
            }
        }
    }
    (rgba, depth)
}

/// Linear RGB of the surface of `rt` at sample position (x, y).
fn shade(look: &Look, geom: &Geometry, rt: &RTri, x: f64, y: f64) -> [f32; 3] {
    let p0 = &rt.p[0];
    let invd = eval(&rt.invd, p0, x, y);
    let q1 = eval(&rt.q1, p0, x, y) / invd;
    let q2 = eval(&rt.q2, p0, x, y) / invd;
    let q0 = 1.0 - q1 - q2;
    let (q0f, q1f, q2f) = (q0 as f32, q1 as f32, q2 as f32);
    let t = geom.tris[rt.tri as usize];
    let [i0, i1, i2] = t.map(|i| i as usize);
    let mat = &look.materials[geom.tri_material[rt.tri as usize] as usize];
    let (c0, c1, c2) = (geom.colors[i0], geom.colors[i1], geom.colors[i2]);
    let mut albedo = [0.0f32; 4];
    for k in 0..4 {
        albedo[k] = mat.base_color[k] * (c0[k] * q0f + c1[k] * q1f + c2[k] * q2f);
    }
    if let Some(ti) = mat.texture {
        let tex = &look.textures[ti];
        let (uv0, uv1, uv2) = (geom.uvs[i0], geom.uvs[i1], geom.uvs[i2]);
        let u = uv0[0] * q0f + uv1[0] * q1f + uv2[0] * q2f;
        let v = uv0[1] * q0f + uv1[1] * q1f + uv2[1] * q2f;
        // Screen-space derivatives of q1, q2 (per sample), then of uv.
        let d1x = ((rt.q1[1] - q1 * rt.invd[1]) / invd) as f32;
        let d1y = ((rt.q1[2] - q1 * rt.invd[2]) / invd) as f32;
        let d2x = ((rt.q2[1] - q2 * rt.invd[1]) / invd) as f32;
        let d2y = ((rt.q2[2] - q2 * rt.invd[2]) / invd) as f32;
        let (tw, th) = tex.size();
        let (tw, th) = (tw as f32, th as f32);
        let dudx = (uv1[0] - uv0[0]) * d1x + (uv2[0] - uv0[0]) * d2x;
        let dvdx = (uv1[1] - uv0[1]) * d1x + (uv2[1] - uv0[1]) * d2x;
        let dudy = (uv1[0] - uv0[0]) * d1y + (uv2[0] - uv0[0]) * d2y;
        let dvdy = (uv1[1] - uv0[1]) * d1y + (uv2[1] - uv0[1]) * d2y;
        let fx = ((dudx * tw).powi(2) + (dvdx * th).powi(2)).sqrt();
        let fy = ((dudy * tw).powi(2) + (dvdy * th).powi(2)).sqrt();
        let tc = tex.sample(u, v, fx.max(fy));
        for k in 0..4 {
            albedo[k] *= tc[k];
        }
    }
    if mat.unlit {
        return [albedo[0], albedo[1], albedo[2]];
    }
    let (n0, n1, n2) = (geom.normals[i0], geom.normals[i1], geom.normals[i2]);
    let n = (n0 * q0f + n1 * q1f + n2 * q2f) * rt.nsign;
    let n = n.normalize_or(Vec3::Y);
    let l = look.ambient + look.diffuse * n.dot(look.light_dir).max(0.0);
    [albedo[0] * l, albedo[1] * l, albedo[2] * l]
}
