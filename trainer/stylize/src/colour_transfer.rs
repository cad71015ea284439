//! Joint colour-distribution transfer: a map of Oklab colours that takes one distribution
//! of colours onto another, all three channels together (`ColourFit::Distribution` measures
//! with it how far the colours a field shows are from the distribution of its targets).
//!
//! Iterated one-dimensional quantile maps along random orthonormal bases (Pitié, Kokaram and
//! Dahyot, "N-dimensional probability density function transfer and its application to
//! colour transfer", ICCV 2005): project both sets on three orthonormal directions, move each
//! colour along each direction to the value the other set has at the same quantile, draw a
//! new basis, repeat. Each 1-D map is monotone and a function of the colour alone, so the
//! whole map is one too. A per-channel quantile map (`palette`) matches each channel's
//! spread but not which colours go together; this matches the joint distribution. It is
//! iterated until an iteration moves the colours by less than a tenth of a just-noticeable
//! difference (RMS), a change no viewer could see; nothing in it is a tuned parameter.

use rayon::prelude::*;

use crate::fusion::ViewGeometry;
use crate::style_metric::{directions, oklab, JND};
use crate::stylizer::Image;

/// Colours kept of a distribution: enough that each of the `LEVELS` quantiles rests on 32.
pub const SAMPLES: usize = 16384;
/// Quantile levels of each 1-D map.
const LEVELS: usize = 512;
/// An iteration that moves the colours by less than this (RMS, Oklab) ends the transfer.
const SETTLED: f64 = JND as f64 / 10.0;
/// At most this many iterations (3-D colour transfers settle in about 20; Pitié et al.).
const MAX_ITERATIONS: usize = 60;

/// A colour distribution: Oklab samples of the scene pixels of a set of views.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Colours {
    pub samples: Vec<[f32; 3]>,
}

impl Colours {
    /// The scene pixels (those that show a surface in `geoms`) of `imgs`, at most `SAMPLES`
    /// of them, evenly strided (deterministic).
    pub fn of(imgs: &[Image], geoms: &[ViewGeometry]) -> Colours {
        let mut all = Vec::new();
        for (im, g) in imgs.iter().zip(geoms) {
            for (p, x) in g.points.iter().enumerate() {
                if x.is_some() {
                    all.push([im.data[p * 3], im.data[p * 3 + 1], im.data[p * 3 + 2]]);
                }
            }
        }
        let stride = all.len().div_ceil(SAMPLES).max(1);
        Colours { samples: all.into_iter().step_by(stride).map(oklab).collect() }
    }
}

/// One 1-D step: along `dir`, the value at each quantile level of the colours being moved
/// (`from`) and of the reference (`to`).
#[derive(Clone, Debug)]
struct Step {
    dir: [f32; 3],
    from: Vec<f32>,
    to: Vec<f32>,
}

/// A map of Oklab colours that takes one distribution onto another.
#[derive(Clone, Debug, Default)]
pub struct Transfer {
    steps: Vec<Step>,
}

/// The values of `v` at `LEVELS + 1` evenly spaced quantiles (`v` non-empty).
fn levels(mut v: Vec<f32>) -> Vec<f32> {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    (0..=LEVELS).map(|k| v[((k as f64 / LEVELS as f64) * (n - 1) as f64).round() as usize]).collect()
}

/// The quantile in [0, 1] of `t` in the level table `q`: linear between levels, the middle
/// of a run of equal levels (so a distribution mapped onto itself is unchanged).
fn quantile_of(q: &[f32], t: f32) -> f64 {
    let lo = q.partition_point(|x| *x < t);
    let hi = q.partition_point(|x| *x <= t);
    let top = (q.len() - 1) as f64;
    if hi > lo {
        return (lo + hi - 1) as f64 / 2.0 / top;
    }
    if lo == 0 {
        return 0.0;
    }
    if lo == q.len() {
        return 1.0;
    }
    let (a, b) = (q[lo - 1], q[lo]);
    ((lo - 1) as f64 + ((t - a) / (b - a)) as f64) / top
}

/// The value of the level table `q` at quantile `l` (linear between levels).
fn value_at(q: &[f32], l: f64) -> f32 {
    let pos = l.clamp(0.0, 1.0) * (q.len() - 1) as f64;
    let i = pos.floor() as usize;
    let j = (i + 1).min(q.len() - 1);
    q[i] + (pos - i as f64) as f32 * (q[j] - q[i])
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Three orthonormal directions (Gram–Schmidt on fixed-seed random ones).
fn basis(seed: u64) -> [[f32; 3]; 3] {
    let mut out: Vec<[f32; 3]> = Vec::new();
    let mut k = 0;
    while out.len() < 3 {
        k += 1;
        let d = directions(3, 1, seed.wrapping_mul(31).wrapping_add(k))[0].clone();
        let mut v = [d[0], d[1], d[2]];
        for b in &out {
            let p = dot(v, *b);
            v = [0, 1, 2].map(|i| v[i] - p * b[i]);
        }
        let n = dot(v, v).sqrt();
        if n > 1e-3 {
            out.push(v.map(|x| x / n));
        }
    }
    [out[0], out[1], out[2]]
}

impl Step {
    fn shift(&self, c: [f32; 3]) -> f32 {
        let t = dot(c, self.dir);
        value_at(&self.to, quantile_of(&self.from, t)) - t
    }
}

impl Transfer {
    /// The map that takes `from` (Oklab samples) onto `to`'s joint distribution; the
    /// identity when either is empty.
    pub fn between(from: &[[f32; 3]], to: &[[f32; 3]]) -> Transfer {
        let mut steps = Vec::new();
        if from.is_empty() || to.is_empty() {
            return Transfer { steps };
        }
        let mut x = from.to_vec();
        for it in 0..MAX_ITERATIONS {
            let mut moved = 0.0f64;
            for dir in basis(it as u64) {
                let step = Step { dir, from: levels(x.iter().map(|c| dot(*c, dir)).collect()), to: levels(to.iter().map(|c| dot(*c, dir)).collect()) };
                moved += x
                    .par_iter_mut()
                    .map(|c| {
                        let m = step.shift(*c);
                        *c = [0, 1, 2].map(|i| c[i] + m * dir[i]);
                        (m as f64).powi(2)
                    })
                    .sum::<f64>();
                steps.push(step);
            }
            if (moved / x.len() as f64).sqrt() < SETTLED {
                break;
            }
        }
        Transfer { steps }
    }

    /// Where the map takes Oklab colour `c`.
    pub fn apply(&self, c: [f32; 3]) -> [f32; 3] {
        self.steps.iter().fold(c, |c, s| {
            let m = s.shift(c);
            [0, 1, 2].map(|i| c[i] + m * s.dir[i])
        })
    }

    /// How many 1-D steps the map takes.
    pub fn len(&self) -> usize {
        self.steps.len()
    }

    pub fn is_empty(&self) -> bool {
        self.steps.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::palette;
    use crate::palette::tests::view;

    /// Sliced Wasserstein-2 distance between two Oklab sample sets (64 directions).
    fn swd(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
        let dirs = directions(3, 64, 7);
        let mut sum = 0.0;
        for d in &dirs {
            let d = [d[0], d[1], d[2]];
            let (qa, qb) = (levels(a.iter().map(|c| dot(*c, d)).collect()), levels(b.iter().map(|c| dot(*c, d)).collect()));
            sum += qa.iter().zip(&qb).map(|(x, y)| ((x - y) as f64).powi(2)).sum::<f64>() / qa.len() as f64;
        }
        (sum / dirs.len() as f64).sqrt()
    }

    /// Red strokes on green and blue strokes on yellow, in a few shades: which colours go
    /// together is the joint distribution, not the channels'.
    fn painted(n: usize) -> Vec<[f32; 3]> {
        (0..n)
            .map(|i| {
                let t = (i % 5) as f32 * 0.03;
                match i % 4 {
                    0 => [0.8 - t, 0.15, 0.1 + t],
                    1 => [0.2, 0.65 - t, 0.2 + t],
                    2 => [0.15 + t, 0.2, 0.8 - t],
                    _ => [0.85, 0.8 - t, 0.2 + t],
                }
            })
            .collect()
    }

    #[test]
    fn joint_colours_come_back_where_per_channel_maps_leave_them() {
        let colours = painted(4000);
        // every sRGB channel's distribution as painted, but the channels drawn from
        // different pixels: no red stroke is red any more
        let shuffled: Vec<f32> = (0..colours.len()).flat_map(|i| [colours[i][0], colours[(i * 7 + 3) % colours.len()][1], colours[(i * 13 + 1) % colours.len()][2]]).collect();
        let (src, g) = view(shuffled);
        let flat: Vec<f32> = colours.iter().flatten().copied().collect();
        let (reference_img, rg) = view(flat);
        let one = |i: &Image, g: &ViewGeometry| Colours::of(std::slice::from_ref(i), std::slice::from_ref(g)).samples;
        let (from, to) = (one(&src, &g), one(&reference_img, &rg));
        let per_channel = palette::map_onto(std::slice::from_ref(&src), std::slice::from_ref(&g), &palette::Quantiles::of(std::slice::from_ref(&reference_img), std::slice::from_ref(&rg)));
        let transfer = Transfer::between(&from, &to);
        let joint: Vec<[f32; 3]> = from.iter().map(|c| transfer.apply(*c)).collect();
        let (before, channel, joint_d) = (swd(&from, &to), swd(&one(&per_channel[0], &g), &to), swd(&joint, &to));
        // (measured: 0.0208 -> per channel 0.0129, joint 0.0035)
        assert!(joint_d < 0.5 * channel, "joint transfer should restore the joint colours: {before:.4} -> per channel {channel:.4}, joint {joint_d:.4}");
        assert!(joint_d < JND as f64 / 4.0, "{joint_d}");
        // the scene pixels only: the view's last pixel shows no surface
        assert_eq!(from.len(), src.width - 1);
    }

    #[test]
    fn a_distribution_mapped_onto_itself_is_left_alone() {
        let colours: Vec<[f32; 3]> = painted(2000).into_iter().map(oklab).collect();
        let transfer = Transfer::between(&colours, &colours);
        let worst = colours.iter().map(|c| {
            let m = transfer.apply(*c);
            dot([m[0] - c[0], m[1] - c[1], m[2] - c[2]], [m[0] - c[0], m[1] - c[1], m[2] - c[2]]).sqrt()
        });
        let worst = worst.fold(0.0f32, f32::max);
        assert!(worst < JND / 2.0, "a colour moved by {worst}");
        assert!(transfer.len() <= 3 * 2, "an identity settles at once: {} steps", transfer.len());
    }

    #[test]
    fn nothing_to_match_is_no_change() {
        let c = [[0.5, 0.1, -0.1]];
        assert!(Transfer::between(&[], &c).is_empty());
        assert_eq!(Transfer::between(&c, &[]).apply(c[0]), c[0]);
    }
}
