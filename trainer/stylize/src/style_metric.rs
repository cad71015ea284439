//! A style distance that owes nothing to any stylizer: it compares the colours and the small
//! texture patches of a scene with those of a painting, so it can tell a stylized scene from
//! an unstylized one whatever network made it (the Magenta embedding cannot: it is the very
//! space the `arbitrary` stylizer aims at).
//!
//! A painting's style is its palette and its strokes; how much of each colour it holds belongs
//! to its subject (a seascape is mostly blue), and a painted chair need not be mostly blue.
//! So the two terms ask:
//!
//! - Colour (palette coverage): for each colour of the painting, how far (Oklab, a perceptual
//!   space where Euclidean distance follows perceived difference) is the nearest colour of the
//!   scene, averaged over the painting's pixels: a directed Chamfer distance, painting ->
//!   scene, taken in each view of the scene and averaged over the views (`coverage`: views
//!   painted independently must not cover the palette between them). The other direction is left out on purpose: a stylizer keeps some of the content's
//!   colours by design, and an unpainted scene's few colours mostly lie inside a rich
//!   painting's gamut, so "are the scene's colours in the painting" does not tell painted from
//!   unpainted. Comparing proportions (a Wasserstein distance between the colour
//!   distributions) did not either: on 24 model × painting pairs it ranked the unpainted scene
//!   nearer than the painted one on most pairs (docs/stylize-notebook.md §5m).
//! - Texture: at 3 scales (full, 1/2, 1/4 resolution), sliced Wasserstein-2 distance between
//!   5×5 Oklab patches with each patch's own mean taken out and its contrast normalized
//!   (divided by its RMS + `CONTRAST_EPS`), so texture is scored apart from colour and from
//!   overall contrast: the shapes of strokes and edges, their direction and how often flat
//!   areas occur (a flat patch stays near 0). Without the normalization a stylizer that
//!   paints with more contrast than the painting scores *farther* than the unstylized scene.
//!
//! Units: each term is divided by the same term measured between the painting's two halves
//! (`StyleReference`), so both are in "times the painting's own variation" and add without a
//! hand-picked weight; a scene as far from the painting as one half of it is from the other
//! scores 1 + 1 = 2.
//!
//! Sliced Wasserstein: project both sample sets on fixed random unit directions, sort, and
//! compare the two 1-D distributions quantile by quantile; the distance is the root mean
//! square difference over directions and quantiles. Everything random (directions, the
//! subsamples) comes from fixed seeds, so the distance is deterministic, and the sample counts
//! are capped at fixed sizes: the scenes compared against one painting (the realistic field,
//! per-frame stylization and SNeRF on one ring and one mask) are measured at the same count.
//!
//! Masks restrict the samples to the scene's pixels (e.g. the realistic field's opacity), so
//! a background does not count as style. Images are compared at the same pixel footprint:
//! callers resize the style picture to the views' size (`reference`).

use rayon::prelude::*;

use crate::stylizer::Image;

/// Patch side (pixels) of the texture statistics.
pub const PATCH: usize = 5;
/// Texture scales: full, 1/2 and 1/4 resolution.
pub const SCALES: usize = 3;
const PATCH_DIRS: usize = 64;
/// Quantiles compared per direction.
const QUANTILES: usize = 128;
/// Patches flatter than about this (Oklab RMS) count as flat.
pub const CONTRAST_EPS: f32 = 0.02;
/// At most this many colour samples per set (fixed-seed subsample beyond): a brute-force
/// nearest-neighbour search over 4096 × 4096 Oklab triples takes milliseconds.
const MAX_COLOR: usize = 4096;
const MAX_PATCHES: usize = 4096;

/// Both terms in units of the painting's own half-to-half distance; `total` = colour + texture
/// (the mean over the scales).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StyleScore {
    pub total: f64,
    pub color: f64,
    pub texture: f64,
    /// A readout beside the distance, not part of it: the share of the painting's colours
    /// that a view of the scene has nothing within a just-noticeable difference of
    /// ([`JND`]), per view, weighted by its scene pixels. The colour term averages how far
    /// each painting colour is from the view's nearest; this says how many of them a viewer
    /// could see missing. Absent (0) in records written before it.
    #[serde(default)]
    pub missed: f64,
}

/// A just-noticeable colour difference in Oklab (ΔE_OK = 0.02, the JND CSS Color 4 uses in
/// its gamut mapping).
pub const JND: f32 = 0.02;

/// The samples of one image (or a set of frames pooled together).
#[derive(Clone, Debug)]
pub struct StyleSamples {
    /// Per image: its scene pixels' colours (subsampled) and how many scene pixels it has.
    colors: Vec<(Vec<[f32; 3]>, usize)>,
    patches: Vec<Vec<Vec<f32>>>,
}

/// sRGB in [0,1] -> Oklab (Björn Ottosson's matrices).
// The matrices as published, digit for digit: a check against the source is a text match.
#[allow(clippy::excessive_precision)]
pub fn oklab(rgb: [f32; 3]) -> [f32; 3] {
    let lin = |c: f32| {
        let c = c.clamp(0.0, 1.0);
        if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        }
    };
    let (r, g, b) = (lin(rgb[0]), lin(rgb[1]), lin(rgb[2]));
    let l = (0.4122214708 * r + 0.5363325363 * g + 0.0514459929 * b).cbrt();
    let m = (0.2119034982 * r + 0.6806995451 * g + 0.1073969566 * b).cbrt();
    let s = (0.0883024619 * r + 0.2817188376 * g + 0.6299787005 * b).cbrt();
    [
        0.2104542553 * l + 0.7936177850 * m - 0.0040720468 * s,
        1.9779984951 * l - 2.4285922050 * m + 0.4505937099 * s,
        0.0259040371 * l + 0.7827717662 * m - 0.8086757660 * s,
    ]
}

/// Oklab -> sRGB in [0,1] (the inverse of `oklab`, same source; colours outside the sRGB
/// gamut are clamped to it).
#[allow(clippy::excessive_precision)]
pub fn srgb_from_oklab(c: [f32; 3]) -> [f32; 3] {
    let l = c[0] + 0.3963377774 * c[1] + 0.2158037573 * c[2];
    let m = c[0] - 0.1055613458 * c[1] - 0.0638541728 * c[2];
    let s = c[0] - 0.0894841775 * c[1] - 1.2914855480 * c[2];
    let (l, m, s) = (l * l * l, m * m * m, s * s * s);
    let lin = [
        4.0767416621 * l - 3.3077115913 * m + 0.2309699292 * s,
        -1.2684380046 * l + 2.6097574011 * m - 0.3413193965 * s,
        -0.0041960863 * l - 0.7034186147 * m + 1.7076147010 * s,
    ];
    lin.map(|v| {
        let v = v.clamp(0.0, 1.0);
        if v <= 0.0031308 {
            12.92 * v
        } else {
            1.055 * v.powf(1.0 / 2.4) - 0.055
        }
    })
}

/// SplitMix64: small, fixed-seed, good enough for directions and subsampling.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^ (z >> 31)
    }
    fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
    fn gauss(&mut self) -> f64 {
        let (u, v) = (self.unit().max(1e-12), self.unit());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

fn directions(dim: usize, n: usize, seed: u64) -> Vec<Vec<f32>> {
    let mut rng = Rng(seed);
    (0..n)
        .map(|_| {
            let v: Vec<f64> = (0..dim).map(|_| rng.gauss()).collect();
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt().max(1e-12);
            v.iter().map(|x| (x / norm) as f32).collect()
        })
        .collect()
}

/// Keep at most `max` items, chosen by a fixed-seed shuffle (the same input keeps the same).
fn subsample<T>(mut v: Vec<T>, max: usize, seed: u64) -> Vec<T> {
    if v.len() <= max {
        return v;
    }
    let mut rng = Rng(seed);
    for i in 0..max {
        let j = i + (rng.next() % (v.len() - i) as u64) as usize;
        v.swap(i, j);
    }
    v.truncate(max);
    v
}

/// Oklab image with a per-pixel mask, halved `k` times (2×2 means over fully masked blocks).
struct Lab {
    w: usize,
    h: usize,
    px: Vec<[f32; 3]>,
    mask: Vec<bool>,
}

impl Lab {
    fn new(img: &Image, mask: Option<&[bool]>) -> Lab {
        let px = img.data.chunks_exact(3).map(|c| oklab([c[0], c[1], c[2]])).collect();
        let mask = mask.map(|m| m.to_vec()).unwrap_or_else(|| vec![true; img.width * img.height]);
        Lab { w: img.width, h: img.height, px, mask }
    }
    fn half(&self) -> Lab {
        let (w, h) = (self.w / 2, self.h / 2);
        let mut px = Vec::with_capacity(w * h);
        let mut mask = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let idx = [(2 * y) * self.w + 2 * x, (2 * y) * self.w + 2 * x + 1, (2 * y + 1) * self.w + 2 * x, (2 * y + 1) * self.w + 2 * x + 1];
                let mut s = [0.0f32; 3];
                for &i in &idx {
                    for c in 0..3 {
                        s[c] += self.px[i][c] * 0.25;
                    }
                }
                px.push(s);
                mask.push(idx.iter().all(|&i| self.mask[i]));
            }
        }
        Lab { w, h, px, mask }
    }
    /// Mean-free PATCH×PATCH patches lying wholly inside the mask.
    fn patches(&self, out: &mut Vec<Vec<f32>>) {
        if self.w < PATCH || self.h < PATCH {
            return;
        }
        for y in 0..=self.h - PATCH {
            for x in 0..=self.w - PATCH {
                if !(0..PATCH).all(|dy| (0..PATCH).all(|dx| self.mask[(y + dy) * self.w + x + dx])) {
                    continue;
                }
                let mut v = Vec::with_capacity(PATCH * PATCH * 3);
                let mut mean = [0.0f32; 3];
                for dy in 0..PATCH {
                    for dx in 0..PATCH {
                        let p = self.px[(y + dy) * self.w + x + dx];
                        v.extend_from_slice(&p);
                        for c in 0..3 {
                            mean[c] += p[c] / (PATCH * PATCH) as f32;
                        }
                    }
                }
                for (k, val) in v.iter_mut().enumerate() {
                    *val -= mean[k % 3];
                }
                let rms = (v.iter().map(|x| x * x).sum::<f32>() / v.len() as f32).sqrt();
                let s = 1.0 / (rms + CONTRAST_EPS);
                v.iter_mut().for_each(|x| *x *= s);
                out.push(v);
            }
        }
    }
}

impl StyleSamples {
    /// Samples pooled over `images`, each with an optional mask (true = scene pixel).
    pub fn of(images: &[(&Image, Option<&[bool]>)]) -> StyleSamples {
        let mut colors = Vec::new();
        let mut patches = vec![Vec::new(); SCALES];
        for (img, mask) in images {
            let mut lab = Lab::new(img, *mask);
            let c: Vec<[f32; 3]> = lab.px.iter().zip(&lab.mask).filter(|(_, m)| **m).map(|(p, _)| *p).collect();
            let n = c.len();
            colors.push((subsample(c, MAX_COLOR, 1), n));
            for (s, set) in patches.iter_mut().enumerate() {
                if s > 0 {
                    lab = lab.half();
                }
                lab.patches(set);
            }
        }
        StyleSamples {
            colors,
            patches: patches.into_iter().enumerate().map(|(s, p)| subsample(p, MAX_PATCHES, 2 + s as u64)).collect(),
        }
    }

    /// One image, unmasked.
    pub fn of_image(img: &Image) -> StyleSamples {
        StyleSamples::of(&[(img, None)])
    }

    /// Number of colour samples and of patches per scale (for reports and checks).
    pub fn counts(&self) -> (usize, Vec<usize>) {
        (self.colors.iter().map(|c| c.0.len()).sum(), self.patches.iter().map(|p| p.len()).collect())
    }

    /// All colour samples, pooled.
    fn pooled(&self) -> Vec<[f32; 3]> {
        self.colors.iter().flat_map(|c| c.0.iter().copied()).collect()
    }
}

/// Sorted projections of `set` on `dir`, read at QUANTILES evenly spaced quantiles.
fn quantiles<V: AsRef<[f32]>>(set: &[V], dir: &[f32]) -> Vec<f32> {
    let mut proj: Vec<f32> = set.iter().map(|v| v.as_ref().iter().zip(dir).map(|(a, b)| a * b).sum()).collect();
    proj.sort_by(|a, b| a.total_cmp(b));
    let n = proj.len();
    (0..QUANTILES)
        .map(|q| {
            let t = (q as f32 + 0.5) / QUANTILES as f32 * n as f32 - 0.5;
            let i0 = (t.floor().max(0.0) as usize).min(n - 1);
            let i1 = (i0 + 1).min(n - 1);
            let f = (t - i0 as f32).clamp(0.0, 1.0);
            proj[i0] * (1.0 - f) + proj[i1] * f
        })
        .collect()
}

/// Sliced Wasserstein-2 distance; NaN when either set is empty.
fn sliced_w2<V: AsRef<[f32]>>(a: &[V], b: &[V], dirs: &[Vec<f32>]) -> f64 {
    if a.is_empty() || b.is_empty() {
        return f64::NAN;
    }
    let mut sum = 0.0f64;
    for d in dirs {
        let (qa, qb) = (quantiles(a, d), quantiles(b, d));
        sum += qa.iter().zip(&qb).map(|(x, y)| ((x - y) as f64).powi(2)).sum::<f64>() / QUANTILES as f64;
    }
    (sum / dirs.len() as f64).sqrt()
}

/// Mean over `from` of the Euclidean distance to the nearest point of `to` (a directed
/// Chamfer distance); NaN when either set is empty.
fn chamfer(from: &[[f32; 3]], to: &[[f32; 3]]) -> f64 {
    let nearest = nearest(from, to);
    if nearest.is_empty() {
        return f64::NAN;
    }
    mean(&nearest)
}

/// The mean of distances, summed in order (the same figure whatever the thread count).
fn mean(d: &[f32]) -> f64 {
    d.iter().map(|&x| x as f64).sum::<f64>() / d.len() as f64
}

/// For each colour of `from`, the distance to the nearest colour of `to` (empty when either
/// set is).
fn nearest(from: &[[f32; 3]], to: &[[f32; 3]]) -> Vec<f32> {
    if from.is_empty() || to.is_empty() {
        return Vec::new();
    }
    let d2 = |a: &[f32; 3], b: &[f32; 3]| (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2);
    // collected in order, so `mean` sums in order
    from.par_iter().map(|a| to.iter().map(|b| d2(a, b)).fold(f32::INFINITY, f32::min).sqrt()).collect()
}

/// Palette coverage of a scene seen in several frames: each frame's own, weighted by its
/// scene pixels. A viewer sees one view at a time, so each view has to carry the palette:
/// pooled over the frames, eight views painted independently would cover more of it between
/// them than any one of them does, and a stylization whose views disagree would score better
/// than a consistent one for that alone. NaN when no frame has a scene pixel.
fn coverage(palette: &[[f32; 3]], scene: &StyleSamples) -> (f64, f64) {
    let (mut sum, mut missed, mut weight) = (0.0, 0.0, 0.0);
    for (c, n) in scene.colors.iter().filter(|c| !c.0.is_empty()) {
        let d = nearest(palette, c);
        if d.is_empty() {
            continue;
        }
        sum += mean(&d) * *n as f64;
        missed += d.iter().filter(|&&x| x > JND).count() as f64 / d.len() as f64 * *n as f64;
        weight += *n as f64;
    }
    if weight > 0.0 {
        (sum / weight, missed / weight)
    } else {
        (f64::NAN, f64::NAN)
    }
}

/// The texture distance between two sample sets: the mean over the scales at which both
/// sides have at least `QUANTILES` patches. Below that, the quantiles compared are
/// interpolated between fewer samples than there are quantiles, and a scale resting on a
/// handful of patches (a thin object at 1/4 resolution) would weigh as much as one resting
/// on thousands. (On a thin controller's 48-frame path, the one patch found at 1/4
/// resolution tripled the texture distance of every method; docs/stylize-notebook.md §5k.) When no scale has
/// that many, the scales with any patch at all are taken, so a tiny scene still gets a
/// (rough) figure.
fn texture(a: &StyleSamples, b: &StyleSamples) -> f64 {
    let pdirs = directions(PATCH * PATCH * 3, PATCH_DIRS, 12);
    let enough = |s: &usize| a.patches[*s].len().min(b.patches[*s].len()) >= QUANTILES;
    let scales: Vec<usize> = if (0..SCALES).any(|s| enough(&s)) { (0..SCALES).filter(enough).collect() } else { (0..SCALES).collect() };
    let tex: Vec<f64> = scales.into_iter().map(|s| sliced_w2(&a.patches[s], &b.patches[s], &pdirs)).filter(|d| d.is_finite()).collect();
    if tex.is_empty() {
        f64::NAN
    } else {
        tex.iter().sum::<f64>() / tex.len() as f64
    }
}

/// Smallest units: a painting that is one flat colour, or one repeated texture, has no
/// half-to-half distance to divide by. (Oklab lightness runs 0..1; a contrast-normalized
/// patch has RMS about 1.)
const MIN_COLOR_UNIT: f64 = 0.002;
const MIN_TEXTURE_UNIT: f64 = 0.01;

/// A painting prepared for `distance`: its samples at the views' footprint and the units its
/// own variation sets.
#[derive(Clone, Debug)]
pub struct StyleReference {
    pub samples: StyleSamples,
    /// Palette coverage between the painting's two halves (mean of both directions).
    pub color_unit: f64,
    /// Texture distance between the painting's two halves.
    pub texture_unit: f64,
}

impl StyleReference {
    /// `img` (already at the views' footprint) and its units, from its two halves split
    /// across the longer side.
    pub fn new(img: &Image) -> StyleReference {
        let (a, b) = halves(img);
        let (a, b) = (StyleSamples::of_image(&a), StyleSamples::of_image(&b));
        let (ca, cb) = (a.pooled(), b.pooled());
        let color = 0.5 * (chamfer(&ca, &cb) + chamfer(&cb, &ca));
        StyleReference {
            samples: StyleSamples::of_image(img),
            color_unit: if color.is_finite() { color.max(MIN_COLOR_UNIT) } else { MIN_COLOR_UNIT },
            texture_unit: texture(&a, &b).max(MIN_TEXTURE_UNIT),
        }
    }
}

/// The two halves of `img`, split across its longer side.
fn halves(img: &Image) -> (Image, Image) {
    let crop = |x0: usize, y0: usize, w: usize, h: usize| {
        let mut data = Vec::with_capacity(w * h * 3);
        for y in y0..y0 + h {
            data.extend_from_slice(&img.data[(y * img.width + x0) * 3..(y * img.width + x0 + w) * 3]);
        }
        Image { width: w, height: h, data }
    };
    if img.width >= img.height {
        let w = img.width / 2;
        (crop(0, 0, w, img.height), crop(w, 0, w, img.height))
    } else {
        let h = img.height / 2;
        (crop(0, 0, img.width, h), crop(0, h, img.width, h))
    }
}

/// The distance of a scene's samples to a painting: palette coverage (painting -> scene) and
/// texture, each in the painting's own units. Not symmetric: the painting sets the palette to
/// cover and the units.
pub fn distance(scene: &StyleSamples, painting: &StyleReference) -> StyleScore {
    let (coverage, missed) = coverage(&painting.samples.pooled(), scene);
    let color = coverage / painting.color_unit;
    let texture = texture(scene, &painting.samples) / painting.texture_unit;
    StyleScore { total: color + texture, color, texture, missed }
}

/// The style picture at the views' pixel footprint: resized so its longer side equals the
/// views' longer side.
pub fn reference(style: &Image, view_width: usize, view_height: usize) -> StyleReference {
    let long = view_width.max(view_height);
    let s = long as f32 / style.width.max(style.height) as f32;
    let (w, h) = (((style.width as f32 * s).round() as usize).max(PATCH * 4), ((style.height as f32 * s).round() as usize).max(PATCH * 4));
    StyleReference::new(&crate::stylize_view::resize(style, w, h))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: usize, h: usize, tint: [f32; 3]) -> Image {
        let mut data = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
                data.extend_from_slice(&[tint[0] * (0.3 + 0.7 * u), tint[1] * (0.4 + 0.5 * v), tint[2] * (0.5 + 0.4 * u * v)]);
            }
        }
        Image { width: w, height: h, data }
    }

    fn strokes(w: usize, h: usize) -> Image {
        let mut data = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let (u, v) = (x as f32 * 0.7, y as f32 * 0.7);
                let a = (u + (v * 0.5).sin() * 3.0).sin();
                data.extend_from_slice(&[0.2 + 0.2 * a, 0.3 + 0.25 * (v * 0.9 + a).cos(), 0.6 + 0.3 * a]);
            }
        }
        Image { width: w, height: h, data }
    }

    #[test]
    fn oklab_round_trips() {
        for rgb in [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.9, 0.1, 0.2], [0.05, 0.6, 0.3], [0.3, 0.3, 0.95], [0.02, 0.01, 0.0]] {
            let back = srgb_from_oklab(oklab(rgb));
            for c in 0..3 {
                assert!((back[c] - rgb[c]).abs() < 1e-4, "{rgb:?} -> {back:?}");
            }
        }
    }

    #[test]
    fn oklab_white_and_black() {
        let w = oklab([1.0, 1.0, 1.0]);
        assert!((w[0] - 1.0).abs() < 1e-3 && w[1].abs() < 1e-3 && w[2].abs() < 1e-3, "{w:?}");
        let k = oklab([0.0, 0.0, 0.0]);
        assert!(k.iter().all(|v| v.abs() < 1e-6), "{k:?}");
    }

    #[test]
    fn zero_for_the_painting_itself_and_deterministic() {
        let painting = gradient(64, 48, [1.0, 0.9, 0.8]);
        let r = StyleReference::new(&painting);
        assert!(r.color_unit > MIN_COLOR_UNIT && r.texture_unit > MIN_TEXTURE_UNIT, "{r:?}");
        assert_eq!(distance(&StyleSamples::of_image(&painting), &r), StyleScore { total: 0.0, color: 0.0, texture: 0.0, missed: 0.0 });
        let d = distance(&StyleSamples::of_image(&strokes(64, 48)), &r);
        assert!(d.color > 0.5 && d.texture > 0.5, "{d:?}");
        assert_eq!(d, distance(&StyleSamples::of_image(&strokes(64, 48)), &StyleReference::new(&gradient(64, 48, [1.0, 0.9, 0.8]))));
    }

    /// Palette coverage is directed: a scene holding every colour of the painting and more
    /// covers it (colour 0); a scene holding half of its colours does not.
    #[test]
    fn colour_asks_whether_the_scene_covers_the_palette() {
        let (w, h) = (48, 40); // fewer pixels than MAX_COLOR: no subsample, exact
        let painting = strokes(w, h);
        let r = StyleReference::new(&painting);
        let mut more = Image::filled(w, 2 * h, [1.0, 0.0, 0.0]);
        more.data[..w * h * 3].copy_from_slice(&painting.data);
        assert_eq!(distance(&StyleSamples::of_image(&more), &r).color, 0.0);
        // the painting's darker half only
        let mut dark = painting.clone();
        for v in dark.data.chunks_exact_mut(3) {
            let l = oklab([v[0], v[1], v[2]])[0];
            if l > 0.55 {
                v.copy_from_slice(&[0.1, 0.1, 0.1]);
            }
        }
        let d = distance(&StyleSamples::of_image(&dark), &r);
        assert!(d.color > 0.5, "{d:?}");
        // the colours it misses are about the light ones it lost (those within a JND of a
        // kept dark one excepted)
        let light_share = painting.data.chunks_exact(3).filter(|v| oklab([v[0], v[1], v[2]])[0] > 0.55).count() as f64 / (w * h) as f64;
        assert!(light_share > 0.2 && d.missed > 0.5 * light_share && d.missed <= light_share + 1e-9, "{d:?}, light {light_share}");
        // one 8-bit level lighter is no colour missed; a fifth of the range lighter, most of them
        let shifted = |by: f32| Image { data: painting.data.iter().map(|v| (v + by).min(1.0)).collect(), ..painting.clone() };
        assert_eq!(distance(&StyleSamples::of_image(&shifted(1.0 / 255.0)), &r).missed, 0.0);
        let far = distance(&StyleSamples::of_image(&shifted(0.2)), &r);
        assert!(far.missed > 0.8, "{far:?}");
        // two views, each with one half of the palette, do not cover it between them
        let mut light = painting.clone();
        for (v, o) in light.data.chunks_exact_mut(3).zip(painting.data.chunks_exact(3)) {
            if oklab([o[0], o[1], o[2]])[0] <= 0.55 {
                v.copy_from_slice(&[1.0, 1.0, 1.0]);
            }
        }
        let two = distance(&StyleSamples::of(&[(&dark, None), (&light, None)]), &r);
        assert!(two.color > 0.5, "{two:?}");
        // a flat painting has no own variation: the units fall back to their floors
        let flat = StyleReference::new(&Image::filled(32, 32, [0.4, 0.5, 0.6]));
        assert_eq!((flat.color_unit, flat.texture_unit), (MIN_COLOR_UNIT, MIN_TEXTURE_UNIT));
        assert!(distance(&StyleSamples::of_image(&painting), &flat).total.is_finite());
    }

    #[test]
    fn masks_drop_the_background() {
        // The same picture on two different backgrounds, masked to the picture: one distance.
        let (w, h) = (48, 40);
        let fg = strokes(w, h);
        let mut on_white = Image::filled(w, h, [1.0, 1.0, 1.0]);
        let mut on_black = Image::filled(w, h, [0.0, 0.0, 0.0]);
        let mut mask = vec![false; w * h];
        for y in 8..32 {
            for x in 10..40 {
                let p = y * w + x;
                mask[p] = true;
                for c in 0..3 {
                    on_white.data[p * 3 + c] = fg.data[p * 3 + c];
                    on_black.data[p * 3 + c] = fg.data[p * 3 + c];
                }
            }
        }
        // a painting with white in its palette: the white background would cover it
        let r = StyleReference::new(&on_white);
        let a = StyleSamples::of(&[(&on_white, Some(&mask))]);
        let b = StyleSamples::of(&[(&on_black, Some(&mask))]);
        assert_eq!(distance(&a, &r), distance(&b, &r));
        let (uw, ub) = (distance(&StyleSamples::of_image(&on_white), &r), distance(&StyleSamples::of_image(&on_black), &r));
        assert!(uw.color == 0.0 && ub.color > 0.1, "{uw:?} vs {ub:?}");
    }

    #[test]
    fn texture_ignores_a_colour_shift_and_colour_sees_it() {
        let a = strokes(64, 64);
        let mut b = a.clone();
        for v in b.data.chunks_exact_mut(3) {
            v[0] = (v[0] + 0.2).min(1.0);
        }
        let r = StyleReference::new(&a);
        let d = distance(&StyleSamples::of_image(&b), &r);
        assert!(d.color > 1.0, "{d:?}");
        // another texture (a smooth gradient) is far; the same strokes shifted in colour are not
        let other = distance(&StyleSamples::of_image(&gradient(64, 64, [1.0, 0.9, 0.8])), &r);
        assert!(d.texture < 0.3 * other.texture, "shifted {d:?}, other texture {other:?}");
    }

    /// A scale resting on fewer patches than quantiles does not enter the texture mean: two
    /// sets with the same texture at full and half resolution, and one disagreeing patch each
    /// at quarter resolution, are at texture distance 0. Where no scale has enough patches,
    /// the scales with any are taken, so a tiny scene is still measured.
    #[test]
    fn a_scale_with_a_handful_of_patches_does_not_weigh_like_a_full_one() {
        let a = StyleSamples::of_image(&strokes(64, 64));
        let (_, counts) = a.counts();
        assert!(counts[0] >= QUANTILES && counts[1] >= QUANTILES, "{counts:?}");
        let patch = |v: f32| vec![vec![v; PATCH * PATCH * 3]];
        let (mut x, mut y) = (a.clone(), a.clone());
        x.patches[2] = patch(1.0);
        y.patches[2] = patch(-1.0);
        assert!(texture(&x, &y).abs() < 1e-9);
        // nothing but the handful: measured from it
        for s in 0..2 {
            x.patches[s] = patch(0.5);
            y.patches[s] = patch(0.5);
        }
        assert!(texture(&x, &y) > 0.3);
    }
}
