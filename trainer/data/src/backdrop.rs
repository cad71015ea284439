//! Plain backdrops: an object photographed before one flat colour (a product on a turntable
//! before a white sweep) is keyed out of its photos and trained as an object on transparent
//! film, because on a turntable the backdrop and the lights stay with the camera while the
//! object turns: in the object's frame the backdrop is not part of a static scene, and fitting
//! it as one left the field a haze.
//!
//! `snerf capture` decides ([`detect`]) on the undistorted photos and, when the backdrop is
//! plain, writes [`FILE`] beside `images/` with the colour, the keying tolerance and the object's
//! box from the sparse points. The loader then keys every view as it loads it ([`key`]); the
//! photos on disk stay as taken, so turning the mode off is deleting that file (or capturing
//! with `--no-backdrop`).
//!
//! Detection: a ring along the four edges of every photo (1/64 of the shorter side, at least 2
//! pixels) is the backdrop's sample. Plain when at least [`PLAIN_MIN_ALL`] of all ring pixels
//! and [`PLAIN_MIN_EACH`] of each photo's lie within [`PLAIN_MAX_DIST`] (largest channel
//! difference, of 255) of the rings' median colour: the object may touch an edge in some
//! photos, but a room, a street or a table top fails it.
//!
//! The box: from the sparse points ([`object_box`]), then grown until the keyed photos'
//! object pixels all look through it ([`cover_silhouettes`]).
//!
//! Keying: the backdrop is what is within the tolerance of its colour *and* connected to the
//! photo's edge through such pixels, or an enclosed region of that colour of at least 1/1000 of
//! the photo (a hole: a handle, a ring); a smaller enclosed spot of the backdrop's colour (a
//! highlight, a white eyelet) stays object, and so does a light part whose colour is beyond the
//! tolerance even where it touches the outline (a white sole a little darker than the sweep).
//! Specks of the object smaller than 1/10000 of the photo are backdrop. Object pixels within 2 pixels of the backdrop get a soft
//! alpha from their distance to the backdrop colour (full at [`SOFT_SCALE`] times the
//! tolerance), their colour un-mixed from it, so composited back on the backdrop colour they
//! give the photo's pixel again.
//!
//! Training, evaluation and baking then treat the capture as any object on transparent film:
//! scored on white. For a white backdrop (the usual product sweep) that is the photos' own
//! pixels; a backdrop of another colour is scored against the keyed photos on white, not the
//! photos as taken.

use serde::{Deserialize, Serialize};

/// The file beside `images/` that turns the keying on.
pub const FILE: &str = "backdrop.json";
/// Largest channel difference (of 255) from the rings' median for a ring pixel to be plain.
pub const PLAIN_MAX_DIST: u8 = 12;
/// Fraction of all ring pixels that must be plain.
pub const PLAIN_MIN_ALL: f64 = 0.9;
/// Fraction of each photo's ring pixels that must be plain.
pub const PLAIN_MIN_EACH: f64 = 0.6;
/// Object pixels near the backdrop reach full alpha at this many tolerances from its colour.
pub const SOFT_SCALE: f32 = 4.0;

/// What the capture found, as written to [`FILE`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Backdrop {
    /// The backdrop colour (sRGB, 8 bit).
    pub colour: [u8; 3],
    /// Largest channel difference from `colour` that is still backdrop.
    pub tolerance: u8,
    /// Fraction of the photos' edge rings within [`PLAIN_MAX_DIST`] of `colour`.
    pub plain_fraction: f64,
    /// Mean fraction of each photo keyed out as backdrop.
    pub backdrop_fraction: f64,
    /// The object's box in world units (from the capture's sparse points), when known.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aabb: Option<([f32; 3], [f32; 3])>,
}

impl Backdrop {
    /// One line for the detection note.
    pub fn describe(&self) -> String {
        let [r, g, b] = self.colour;
        format!(
            "a plain backdrop (colour {r},{g},{b}; {:.0}% of the photos' edges within {PLAIN_MAX_DIST} of it) \
             is keyed out ({:.0}% of each photo on average, tolerance {})",
            self.plain_fraction * 100.0,
            self.backdrop_fraction * 100.0,
            self.tolerance
        )
    }
}

/// An 8-bit RGBA image, row-major.
#[derive(Clone, Copy)]
pub struct Rgba<'a> {
    pub pixels: &'a [u8],
    pub width: usize,
    pub height: usize,
}

#[inline]
fn dist(p: &[u8], c: [u8; 3]) -> u8 {
    (0..3).map(|i| p[i].abs_diff(c[i])).max().unwrap_or(0)
}

/// Indices of the edge ring of a `w x h` image.
fn ring(w: usize, h: usize) -> impl Iterator<Item = usize> {
    let r = (w.min(h) / 64).max(2).min(w.min(h) / 2).max(1);
    (0..h).flat_map(move |y| {
        let edge_row = y < r || y + r >= h;
        (0..w).filter(move |&x| edge_row || x < r || x + r >= w).map(move |x| y * w + x)
    })
}

fn median(hist: &[u64; 256]) -> u8 {
    let total: u64 = hist.iter().sum();
    let mut acc = 0;
    for (v, &n) in hist.iter().enumerate() {
        acc += n;
        if 2 * acc >= total {
            return v as u8;
        }
    }
    255
}

/// Whether the photos stand before a plain backdrop, and its colour and keying tolerance;
/// `Err` says why not (for the detection note).
pub fn detect(images: &[Rgba]) -> Result<Backdrop, String> {
    if images.is_empty() {
        return Err("no photos".into());
    }
    if images.iter().any(|im| im.pixels.chunks_exact(4).any(|p| p[3] < 255)) {
        return Err("the photos carry their own transparency".into());
    }
    let mut hist = [[0u64; 256]; 3];
    for im in images {
        for i in ring(im.width, im.height) {
            for c in 0..3 {
                hist[c][im.pixels[4 * i + c] as usize] += 1;
            }
        }
    }
    let colour = [median(&hist[0]), median(&hist[1]), median(&hist[2])];
    let mut dist_hist = [0u64; 256];
    let mut worst = (1.0f64, 0usize);
    for (k, im) in images.iter().enumerate() {
        let (mut n, mut plain) = (0u64, 0u64);
        for i in ring(im.width, im.height) {
            let d = dist(&im.pixels[4 * i..4 * i + 3], colour);
            dist_hist[d as usize] += 1;
            n += 1;
            plain += (d <= PLAIN_MAX_DIST) as u64;
        }
        let f = plain as f64 / n.max(1) as f64;
        if f < worst.0 {
            worst = (f, k);
        }
    }
    let total: u64 = dist_hist.iter().sum();
    let plain: u64 = dist_hist[..=PLAIN_MAX_DIST as usize].iter().sum();
    let plain_fraction = plain as f64 / total.max(1) as f64;
    let [r, g, b] = colour;
    if plain_fraction < PLAIN_MIN_ALL {
        return Err(format!(
            "no plain backdrop: {:.0}% of the photos' edges are within {PLAIN_MAX_DIST} of their median colour \
             {r},{g},{b} (< {:.0}%)",
            plain_fraction * 100.0,
            PLAIN_MIN_ALL * 100.0
        ));
    }
    if worst.0 < PLAIN_MIN_EACH {
        return Err(format!(
            "no plain backdrop: photo {} has {:.0}% of its edge within {PLAIN_MAX_DIST} of {r},{g},{b} (< {:.0}%)",
            worst.1 + 1,
            worst.0 * 100.0,
            PLAIN_MIN_EACH * 100.0
        ));
    }
    // The tolerance follows the backdrop's own noise: its 90th percentile plus a margin.
    let mut acc = 0;
    let mut p90 = 0u8;
    for (d, &n) in dist_hist.iter().enumerate() {
        acc += n;
        if acc as f64 >= 0.9 * total as f64 {
            p90 = d as u8;
            break;
        }
    }
    let tolerance = (p90 + 4).max(6);
    let mut keyed = 0.0;
    for (k, im) in images.iter().enumerate() {
        let mut px = im.pixels.to_vec();
        let f = key(&mut px, im.width, im.height, colour, tolerance);
        if f > 0.995 {
            return Err(format!(
                "a plain backdrop {r},{g},{b} fills photo {} ({:.1}%): no object to key out",
                k + 1,
                f * 100.0
            ));
        }
        keyed += f;
    }
    Ok(Backdrop {
        colour,
        tolerance,
        plain_fraction,
        backdrop_fraction: keyed / images.len() as f64,
        aabb: None,
    })
}

/// Keys the backdrop out of one RGBA image in place (see the module docs); returns the
/// fraction of pixels that became fully transparent.
pub fn key(rgba: &mut [u8], w: usize, h: usize, colour: [u8; 3], tolerance: u8) -> f64 {
    let n = w * h;
    assert_eq!(rgba.len(), n * 4, "key: {w}x{h} RGBA needs {} bytes", n * 4);
    if n == 0 {
        return 0.0;
    }
    let d: Vec<u8> = rgba.chunks_exact(4).map(|p| dist(p, colour)).collect();
    // Backdrop: near the colour and reachable from the edge (4-neighbours).
    let mut bg = vec![false; n];
    let mut stack: Vec<usize> = ring_1px(w, h).filter(|&i| d[i] <= tolerance).collect();
    for &i in &stack {
        bg[i] = true;
    }
    while let Some(i) = stack.pop() {
        for j in neighbours4(i, w, h) {
            if !bg[j] && d[j] <= tolerance {
                bg[j] = true;
                stack.push(j);
            }
        }
    }
    // Holes: regions of the backdrop's colour enclosed by the object (a handle, a ring) when
    // they are at least 1/1000 of the image; smaller ones are the object's own highlights.
    let hole = (n / 1000).max(16);
    let mut seen = bg.clone();
    for s in 0..n {
        if seen[s] || d[s] > tolerance {
            continue;
        }
        let mut comp = vec![s];
        seen[s] = true;
        let mut k = 0;
        while k < comp.len() {
            let i = comp[k];
            k += 1;
            for j in neighbours4(i, w, h) {
                if !seen[j] && d[j] <= tolerance {
                    seen[j] = true;
                    comp.push(j);
                }
            }
        }
        if comp.len() >= hole {
            for &i in &comp {
                bg[i] = true;
            }
        }
    }
    // Specks: object components (8-neighbours) smaller than 1/10000 of the image.
    let speck = (n / 10_000).max(4);
    let mut seen = bg.clone();
    let mut comp = Vec::new();
    for s in 0..n {
        if seen[s] {
            continue;
        }
        comp.clear();
        comp.push(s);
        seen[s] = true;
        let mut k = 0;
        while k < comp.len() {
            let i = comp[k];
            k += 1;
            for j in neighbours8(i, w, h) {
                if !seen[j] {
                    seen[j] = true;
                    comp.push(j);
                }
            }
            if comp.len() > speck {
                break;
            }
        }
        if comp.len() <= speck {
            for &i in &comp {
                bg[i] = true;
            }
        } else {
            // Mark the rest of this large component seen without collecting it.
            while k < comp.len() {
                let i = comp[k];
                k += 1;
                for j in neighbours8(i, w, h) {
                    if !seen[j] {
                        seen[j] = true;
                        comp.push(j);
                    }
                }
            }
        }
    }
    // Distance (Chebyshev, capped at 3) from the backdrop, for the soft edge.
    let mut near = vec![3u8; n];
    for i in 0..n {
        if bg[i] {
            near[i] = 0;
        }
    }
    for step in 1..=2u8 {
        let prev = near.clone();
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                if prev[i] <= step {
                    continue;
                }
                let touches = (y.saturating_sub(1)..=(y + 1).min(h - 1))
                    .any(|yy| (x.saturating_sub(1)..=(x + 1).min(w - 1)).any(|xx| prev[yy * w + xx] == step - 1));
                if touches {
                    near[i] = step;
                }
            }
        }
    }
    let soft = SOFT_SCALE * tolerance.max(1) as f32;
    let mut clear = 0usize;
    for i in 0..n {
        let p = &mut rgba[4 * i..4 * i + 4];
        if bg[i] {
            p[..3].copy_from_slice(&colour);
            p[3] = 0;
            clear += 1;
        } else if near[i] <= 2 {
            let a = (d[i] as f32 / soft).clamp(1.0 / 255.0, 1.0);
            for c in 0..3 {
                let v = colour[c] as f32 + (p[c] as f32 - colour[c] as f32) / a;
                p[c] = v.round().clamp(0.0, 255.0) as u8;
            }
            p[3] = ((p[3] as f32) * a).round() as u8;
        }
    }
    clear as f64 / n as f64
}

/// The outermost pixels of a `w x h` image.
fn ring_1px(w: usize, h: usize) -> impl Iterator<Item = usize> {
    (0..h).flat_map(move |y| {
        let edge_row = y == 0 || y + 1 == h;
        (0..w).filter(move |&x| edge_row || x == 0 || x + 1 == w).map(move |x| y * w + x)
    })
}

/// A box around the object from its sparse points: per axis the 2nd to 98th percentile
/// (stray matches on the backdrop or the rig do not stretch it), grown by a quarter of the
/// largest extent on every side, because untextured parts (a plain sole) give COLMAP no
/// points. `None` below 20 points.
pub fn object_box(points: &[[f64; 3]]) -> Option<([f32; 3], [f32; 3])> {
    if points.len() < 20 {
        return None;
    }
    let mut lo = [0.0f64; 3];
    let mut hi = [0.0f64; 3];
    for a in 0..3 {
        let mut v: Vec<f64> = points.iter().map(|p| p[a]).collect();
        v.sort_by(|x, y| x.total_cmp(y));
        let at = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
        lo[a] = at(0.02);
        hi[a] = at(0.98);
    }
    let ext = (0..3).map(|a| hi[a] - lo[a]).fold(0.0f64, f64::max);
    if !(ext.is_finite() && ext > 0.0) {
        return None;
    }
    let pad = 0.25 * ext;
    Some((lo.map(|v| (v - pad) as f32), hi.map(|v| (v + pad) as f32)))
}

/// Grows `aabb` about its centre (by 10% steps, at most 3x) until the rays through 99.5% of
/// the keyed views' object pixels (every 3rd pixel of every 3rd row) cross it, because a box
/// from the sparse points misses parts COLMAP found no texture on. Returns the box and the
/// factor it grew by (1 when it already held the silhouettes).
pub fn cover_silhouettes(aabb: ([f32; 3], [f32; 3]), views: &[&crate::View]) -> (([f32; 3], [f32; 3]), f32) {
    let mut rays: Vec<([f32; 3], [f32; 3])> = Vec::new();
    for v in views {
        let k = &v.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let m = &v.c2w;
        for y in (0..h).step_by(3) {
            for x in (0..w).step_by(3) {
                if v.rgba[4 * (y * w + x) + 3] < 128 {
                    continue;
                }
                // OpenGL camera: x right, y up, looking down -z.
                let c = [(x as f32 + 0.5 - k.cx) / k.fx, -(y as f32 + 0.5 - k.cy) / k.fy, -1.0];
                let d = [0, 1, 2].map(|r| m[r][0] * c[0] + m[r][1] * c[1] + m[r][2] * c[2]);
                rays.push((v.origin(), d));
            }
        }
    }
    if rays.is_empty() {
        return (aabb, 1.0);
    }
    let centre = [0, 1, 2].map(|a| 0.5 * (aabb.0[a] + aabb.1[a]));
    let half = [0, 1, 2].map(|a| 0.5 * (aabb.1[a] - aabb.0[a]));
    let mut f = 1.0f32;
    loop {
        let lo = [0, 1, 2].map(|a| centre[a] - f * half[a]);
        let hi = [0, 1, 2].map(|a| centre[a] + f * half[a]);
        let miss = rays.iter().filter(|(o, d)| !ray_hits_box(*o, *d, lo, hi)).count();
        if miss as f64 <= 0.005 * rays.len() as f64 || f >= 3.0 {
            return ((lo, hi), f);
        }
        f = (f * 1.1).min(3.0);
    }
}

/// Whether the ray `o + t d`, t > 0, crosses the box (slab test).
fn ray_hits_box(o: [f32; 3], d: [f32; 3], lo: [f32; 3], hi: [f32; 3]) -> bool {
    let (mut t0, mut t1) = (0.0f32, f32::INFINITY);
    for a in 0..3 {
        if d[a].abs() < 1e-12 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return false;
            }
            continue;
        }
        let (mut ta, mut tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
        if ta > tb {
            std::mem::swap(&mut ta, &mut tb);
        }
        t0 = t0.max(ta);
        t1 = t1.min(tb);
    }
    t0 <= t1
}

/// Pixel `i`'s 4-neighbours inside a `w`×`h` image (left, right, up, down).
fn neighbours4(i: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = (i % w, i / w);
    [(x > 0).then(|| i - 1), (x + 1 < w).then(|| i + 1), (y > 0).then(|| i - w), (y + 1 < h).then(|| i + w)].into_iter().flatten()
}

/// Pixel `i`'s 8-neighbours (and itself) inside a `w`×`h` image, row by row.
fn neighbours8(i: usize, w: usize, h: usize) -> impl Iterator<Item = usize> {
    let (x, y) = ((i % w) as isize, (i / w) as isize);
    (-1..=1isize).flat_map(move |dy| (-1..=1isize).map(move |dx| (x + dx, y + dy))).filter(move |&(nx, ny)| nx >= 0 && ny >= 0 && nx < w as isize && ny < h as isize).map(move |(nx, ny)| ny as usize * w + nx as usize)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `w x h` image of `bg` (with noise of +-`noise`) holding a rectangle of `fg` from a
    /// quarter to three quarters of each side; inside it, a light part of colour `light` along
    /// the rectangle's left edge (it touches the outline), a hole showing the backdrop and a 2x2
    /// highlight of the backdrop's colour.
    fn scene(w: usize, h: usize, bg: [u8; 3], fg: [u8; 3], light: [u8; 3], noise: u8) -> Vec<u8> {
        let mut s = 12345u32;
        let mut px = Vec::with_capacity(w * h * 4);
        for y in 0..h {
            for x in 0..w {
                let inside = (w / 4..3 * w / 4).contains(&x) && (h / 4..3 * h / 4).contains(&y);
                let c = if !inside {
                    bg
                } else if x < w / 4 + 4 {
                    light
                } else {
                    let hole = (w / 2..w / 2 + 8).contains(&x) && (h / 2 - 4..h / 2 + 4).contains(&y);
                    let highlight = (w / 2 - 6..w / 2 - 4).contains(&x) && (h / 2..h / 2 + 2).contains(&y);
                    if hole || highlight {
                        bg
                    } else {
                        fg
                    }
                };
                for v in c {
                    s = s.wrapping_mul(1664525).wrapping_add(1013904223);
                    let e = (s >> 24) as i32 % (noise as i32 + 1);
                    px.push((v as i32 + if s & 1 == 0 { e } else { -e }).clamp(0, 255) as u8);
                }
                px.push(255);
            }
        }
        px
    }

    #[test]
    fn keys_a_plain_backdrop_and_keeps_the_objects_light_parts() {
        let (w, h) = (80, 60);
        // A white sweep with sensor noise; a grey object with a light part 14 levels from the
        // sweep along its outline (a white sole), a hole and a highlight.
        let bg = [250, 250, 250];
        let imgs: Vec<Vec<u8>> = (0..4).map(|_| scene(w, h, bg, [120, 90, 60], [236, 236, 236], 2)).collect();
        let views: Vec<Rgba> = imgs.iter().map(|p| Rgba { pixels: p, width: w, height: h }).collect();
        let b = detect(&views).expect("plain backdrop");
        assert!(b.colour.iter().all(|&c| c.abs_diff(250) <= 1), "{:?}", b.colour);
        assert!(b.tolerance >= 6 && b.tolerance < 12, "{}", b.tolerance);
        let mut px = imgs[0].clone();
        let f = key(&mut px, w, h, b.colour, b.tolerance);
        let hole = 8.0 * 8.0 / (w * h) as f64;
        assert!((f - 0.75 - hole).abs() < 0.005, "keyed {f}");
        let a = |x: usize, y: usize| px[4 * (y * w + x) + 3];
        assert_eq!(a(2, 2), 0, "backdrop corner");
        assert_eq!(a(w / 2 + 3, h / 2), 0, "the hole through the object");
        assert_eq!(a(w / 2 - 5, h / 2), 255, "the highlight stays object");
        assert_eq!(a(w / 4 + 10, h / 2), 255, "the object's inside");
        assert_eq!(a(w / 4 + 2, h / 2), 255, "the light part inside the outline");
        // On the outline the light part is soft (14 from the colour, full alpha at 4
        // tolerances) and composites back on the backdrop to the photo's pixel.
        let e = 4 * ((h / 2) * w + w / 4);
        let al = px[e + 3] as f32 / 255.0;
        assert!(al > 0.2 && al < 1.0, "edge alpha {al}");
        for c in 0..3 {
            let back = px[e + c] as f32 * al + b.colour[c] as f32 * (1.0 - al);
            assert!((back - imgs[0][e + c] as f32).abs() <= 3.0, "channel {c}: {back} vs {}", imgs[0][e + c]);
        }
        // Everything composited on the backdrop colour is within the tolerance of the photo.
        let worst = (0..w * h)
            .map(|i| {
                let al = px[4 * i + 3] as f32 / 255.0;
                (0..3)
                    .map(|c| (px[4 * i + c] as f32 * al + b.colour[c] as f32 * (1.0 - al) - imgs[0][4 * i + c] as f32).abs())
                    .fold(0.0f32, f32::max)
            })
            .fold(0.0f32, f32::max);
        assert!(worst <= b.tolerance as f32 + 1.0, "worst composite error {worst}");
    }

    #[test]
    fn a_speck_on_the_backdrop_is_backdrop() {
        let (w, h) = (100, 100);
        let mut px = scene(w, h, [255, 255, 255], [20, 30, 200], [20, 30, 200], 0);
        let i = 4 * (5 * w + 5);
        px[i..i + 3].copy_from_slice(&[0, 0, 0]);
        key(&mut px, w, h, [255, 255, 255], 6);
        assert_eq!(px[i + 3], 0, "a single dark pixel on the backdrop is keyed out");
        assert_eq!(px[4 * (50 * w + 30) + 3], 255);
    }

    #[test]
    fn textured_edges_are_not_a_backdrop() {
        let (w, h) = (64, 48);
        // A gradient floor and wall: every edge pixel differs.
        let imgs: Vec<Vec<u8>> = (0..3)
            .map(|k| {
                (0..w * h)
                    .flat_map(|i| {
                        let (x, y) = (i % w, i / w);
                        [(x * 4 + k) as u8, (y * 5) as u8, ((x + y) * 2) as u8, 255]
                    })
                    .collect()
            })
            .collect();
        let views: Vec<Rgba> = imgs.iter().map(|p| Rgba { pixels: p, width: w, height: h }).collect();
        let e = detect(&views).unwrap_err();
        assert!(e.starts_with("no plain backdrop"), "{e}");
        // A backdrop that fills the whole photo has nothing to key out.
        let blank = vec![200u8; w * h * 4].chunks(4).flat_map(|_| [200, 200, 200, 255]).collect::<Vec<u8>>();
        let e = detect(&[Rgba { pixels: &blank, width: w, height: h }]).unwrap_err();
        assert!(e.contains("no object"), "{e}");
    }

    #[test]
    fn the_box_grows_until_the_silhouettes_rays_cross_it() {
        // A camera at z = 5 looking down -z at a square silhouette 2 units across at z = 0
        // (focal 50, 100x100 pixels: the silhouette spans pixels 30..70).
        let (w, h) = (100usize, 100usize);
        let rgba: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                let (x, y) = (i % w, i / w);
                let inside = (30..70).contains(&x) && (30..70).contains(&y);
                [0, 0, 0, if inside { 255 } else { 0 }]
            })
            .collect();
        let view = crate::View {
            path: "v.png".into(),
            intrinsics: crate::Intrinsics { width: 100, height: 100, fx: 50.0, fy: 50.0, cx: 50.0, cy: 50.0, distortion: [0.0; 4] },
            c2w: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 5.0]],
            time: None,
            rgba,
        };
        // A box of half-size 0.5 about the origin: the ray through the silhouette's corner
        // pixel (at 1.95 from the axis at z = 0) crosses a box of half-size s at its front face
        // z = s when 1.95 (5 - s) / 5 <= s, s >= 1.40: a growth of 2.8 or more (2.85 in 10% steps).
        let ((lo, hi), f) = cover_silhouettes(([-0.5; 3], [0.5; 3]), &[&view]);
        assert!((2.8..2.9).contains(&f), "grown {f}: {lo:?} {hi:?}");
        // A box that already holds it is left as it was.
        let (b, f) = cover_silhouettes(([-1.5; 3], [1.5; 3]), &[&view]);
        assert_eq!((b, f), (([-1.5; 3], [1.5; 3]), 1.0));
    }

    #[test]
    fn object_box_ignores_strays_and_pads() {
        let mut pts: Vec<[f64; 3]> = (0..1000).map(|i| {
            let t = i as f64 / 999.0;
            [t * 2.0 - 1.0, (t * 7.0).sin() * 0.5, (t * 3.0).cos() * 0.25]
        }).collect();
        pts.push([100.0, 0.0, 0.0]);
        let (lo, hi) = object_box(&pts).unwrap();
        assert!(hi[0] < 2.0 && hi[0] > 1.3 && lo[0] > -2.0 && lo[0] < -1.3, "{lo:?} {hi:?}");
        assert!(object_box(&pts[..10]).is_none());
    }
}
