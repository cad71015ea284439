//! Keeping the painting's colours through the consensus rounds. Iterated, the per-pixel
//! median of the consensus (`fusion::fuse`) narrows the targets' colour distribution: an
//! extreme colour (the darkest dark of a stroke, its most saturated red) survives a median
//! only where most of the neighbours read it too, and reprojection misregisters thin strokes
//! by about a pixel, so the tails shrink a little every round (docs/stylize-notebook.md §5p, §5q). The
//! consensus is there to reconcile where the views disagree, not to change which colours the
//! scene has.
//!
//! So before each consensus round the previous round's targets are mapped, per Oklab channel,
//! onto the colour distribution of the first fused stylizations (the painter's own pixels):
//! each value goes to the reference's value at the same quantile (its mid-rank among the
//! targets' scene pixels). The map is monotone and a function of the colour alone, so colours
//! the views agree on stay in agreement, and the median that follows reconciles the rest.
//! Nothing in it is a tuned parameter.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::fusion::ViewGeometry;
use crate::style_metric::{oklab, srgb_from_oklab};
use crate::stylizer::Image;

/// Quantile levels kept of the reference distribution (its values at q = k / LEVELS).
const LEVELS: usize = 1024;

/// A colour distribution: per Oklab channel (L, a, b), its values at `LEVELS + 1` evenly
/// spaced quantiles, from the minimum to the maximum; no values at all when the first fusion
/// showed no surface (then there is no palette to keep and the map leaves colours alone).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quantiles {
    pub channels: [Vec<f32>; 3],
}

/// Per Oklab channel, the sorted values of every scene pixel (a pixel that shows a surface
/// in `geoms`) of `imgs`.
fn sorted_channels(imgs: &[Image], geoms: &[ViewGeometry]) -> [Vec<f32>; 3] {
    let mut ch: [Vec<f32>; 3] = Default::default();
    for (im, g) in imgs.iter().zip(geoms) {
        for (p, x) in g.points.iter().enumerate() {
            if x.is_some() {
                let c = oklab([im.data[p * 3], im.data[p * 3 + 1], im.data[p * 3 + 2]]);
                for k in 0..3 {
                    ch[k].push(c[k]);
                }
            }
        }
    }
    ch.par_iter_mut().for_each(|v| v.sort_by(|a, b| a.total_cmp(b)));
    ch
}

impl Quantiles {
    /// The distribution of the scene pixels of `imgs` (empty when no pixel shows a surface).
    pub fn of(imgs: &[Image], geoms: &[ViewGeometry]) -> Quantiles {
        let ch = sorted_channels(imgs, geoms);
        let n = ch[0].len();
        if n == 0 {
            return Quantiles { channels: Default::default() };
        }
        let channels = ch.map(|v| (0..=LEVELS).map(|k| v[((k as f64 / LEVELS as f64) * (n - 1) as f64).round() as usize]).collect());
        Quantiles { channels }
    }

    fn is_empty(&self) -> bool {
        self.channels[0].is_empty()
    }

    /// Channel `k`'s value at quantile `q` in [0, 1] (linear between levels).
    fn at(&self, k: usize, q: f64) -> f32 {
        let v = &self.channels[k];
        let pos = q.clamp(0.0, 1.0) * (v.len() - 1) as f64;
        let i = (pos.floor() as usize).min(v.len() - 1);
        let j = (i + 1).min(v.len() - 1);
        v[i] + (pos - i as f64) as f32 * (v[j] - v[i])
    }
}

/// The quantile of `v` among `sorted`: the mean rank of the values equal to it, over n - 1
/// (so equal colours get one quantile, and a distribution mapped onto itself is unchanged).
fn quantile(sorted: &[f32], v: f32) -> f64 {
    let n = sorted.len();
    if n < 2 {
        return 0.5;
    }
    let lo = sorted.partition_point(|x| *x < v);
    let hi = sorted.partition_point(|x| *x <= v).max(lo + 1);
    ((lo + hi - 1) as f64 / 2.0) / (n - 1) as f64
}

/// `imgs` with every scene pixel's colour mapped, per Oklab channel, to the value of
/// `reference` at the quantile the colour has among the scene pixels of `imgs` (see the
/// module doc). Pixels that show no surface are unchanged.
pub fn map_onto(imgs: &[Image], geoms: &[ViewGeometry], reference: &Quantiles) -> Vec<Image> {
    if reference.is_empty() {
        return imgs.to_vec();
    }
    let src = sorted_channels(imgs, geoms);
    if src[0].is_empty() {
        return imgs.to_vec();
    }
    imgs.par_iter()
        .zip(geoms)
        .map(|(im, g)| {
            let mut out = im.clone();
            for (p, x) in g.points.iter().enumerate() {
                if x.is_some() {
                    let c = oklab([im.data[p * 3], im.data[p * 3 + 1], im.data[p * 3 + 2]]);
                    let m = [0, 1, 2].map(|k| reference.at(k, quantile(&src[k], c[k])));
                    out.data[p * 3..p * 3 + 3].copy_from_slice(&srgb_from_oklab(m));
                }
            }
            out
        })
        .collect()
}

/// The distribution a field must be trained on to show `want`'s colours (`ColourFit::
/// Compensate` in the loop). A field fitted to painted views shows a narrower distribution
/// than its targets: a stroke's darkest dark or most saturated colour is a few pixels, and
/// the field, shared between many views and rays, reaches it only in part. Having trained
/// on `trained` and shown `shown`, the field falls short of its targets by
/// `trained − shown` at each quantile; targets at `trained + want − shown` make up that
/// shortfall (an iterative-learning step: if the shortfall stays as it was, the field then
/// shows `want`). Per Oklab channel and quantile, made non-decreasing so that the map it
/// defines keeps the order of the colours. Empty (no change) when any of them is.
pub fn compensated(want: &Quantiles, shown: &Quantiles, trained: &Quantiles) -> Quantiles {
    if want.is_empty() || shown.is_empty() || trained.is_empty() {
        return Quantiles { channels: Default::default() };
    }
    let channels = [0, 1, 2].map(|k| {
        let mut top = f32::NEG_INFINITY;
        (0..=LEVELS)
            .map(|l| {
                top = top.max(trained.channels[k][l] + want.channels[k][l] - shown.channels[k][l]);
                top
            })
            .collect()
    });
    Quantiles { channels }
}

/// Where a run keeps its reference distribution (beside the consensus it is used with, so a
/// run whose consensus was removed starts both again).
fn path(out: &Path) -> PathBuf {
    file(out, "palette.json")
}

/// A file the run keeps beside its consensus (`consensus/NAME`).
pub(crate) fn file(out: &Path, name: &str) -> PathBuf {
    out.join("consensus").join(name)
}

/// The distribution of the targets the field was last trained on (`compensated`), kept
/// beside the palette.
const TRAINED: &str = "trained.json";

pub fn save(out: &Path, q: &Quantiles) -> Result<()> {
    save_file(&path(out), q)
}

/// Writes `q` as JSON at `p` (atomically), creating its folder.
pub(crate) fn save_file<T: Serialize>(p: &Path, q: &T) -> Result<()> {
    std::fs::create_dir_all(p.parent().expect("in consensus/")).with_context(|| format!("{}: cannot create", p.display()))?;
    snerf_files::write_json_atomic(p, q)
}

/// Records the distribution of the targets the field is now trained on.
pub fn save_trained(out: &Path, q: &Quantiles) -> Result<()> {
    save_file(&file(out, TRAINED), q)
}

/// The distribution `save_trained` recorded, if the run has one.
pub fn load_trained(out: &Path) -> Result<Option<Quantiles>> {
    let p = file(out, TRAINED);
    if !p.exists() {
        return Ok(None);
    }
    load_file(&p).map(Some)
}

pub fn load(out: &Path) -> Result<Quantiles> {
    load_file(&path(out))
}

fn load_file(p: &Path) -> Result<Quantiles> {
    let bytes = std::fs::read(p).with_context(|| format!("{}: cannot read the run's colour distribution", p.display()))?;
    let q: Quantiles = serde_json::from_slice(&bytes).with_context(|| format!("{}: not a palette file", p.display()))?;
    let levels_ok = q.channels.iter().all(|c| c.len() == LEVELS + 1 && c.iter().all(|v| v.is_finite())) || q.channels.iter().all(Vec::is_empty);
    anyhow::ensure!(levels_ok, "{}: not a palette file ({} levels expected)", p.display(), LEVELS + 1);
    Ok(q)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use snerf_data::Intrinsics;

    /// One view of `w` pixels in a row, every pixel a scene pixel but the last (shared with
    /// `colour_offsets`' tests).
    pub(crate) fn view(data: Vec<f32>) -> (Image, ViewGeometry) {
        let w = data.len() / 3;
        let intr = Intrinsics { width: w as u32, height: 1, fx: 1.0, fy: 1.0, cx: 0.5, cy: 0.5, distortion: [0.0; 4] };
        let points = (0..w).map(|i| (i + 1 < w).then_some([i as f32, 0.0, 0.0])).collect();
        (Image { width: w, height: 1, data }, ViewGeometry { c2w: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]], intr, points })
    }

    fn ramp(n: usize, squeeze: f32) -> Vec<f32> {
        (0..n).flat_map(|i| {
            let t = i as f32 / (n - 1) as f32;
            let t = 0.5 + squeeze * (t - 0.5);
            [0.1 + 0.8 * t, 0.2 + 0.5 * t * t, 0.7 - 0.6 * t]
        })
        .collect()
    }

    /// A distribution squeezed toward its middle (what the iterated median does to the
    /// tails) is mapped back onto the reference's extremes; the pixel that shows no surface
    /// is left alone; a distribution mapped onto itself barely moves.
    #[test]
    fn a_narrowed_palette_is_stretched_back_and_equal_colours_stay_equal() {
        let (ref_img, ref_geom) = view(ramp(201, 1.0));
        let reference = Quantiles::of(std::slice::from_ref(&ref_img), std::slice::from_ref(&ref_geom));
        let mut squeezed = ramp(201, 0.6);
        // two pixels of the same colour
        let same: Vec<f32> = squeezed[30..33].to_vec();
        squeezed[60..63].copy_from_slice(&same);
        let (img, geom) = view(squeezed.clone());
        let mapped = map_onto(std::slice::from_ref(&img), std::slice::from_ref(&geom), &reference).remove(0);
        let lightness = |d: &[f32], i: usize| oklab([d[i * 3], d[i * 3 + 1], d[i * 3 + 2]])[0];
        let range = |d: &[f32]| {
            let l: Vec<f32> = (0..200).map(|i| lightness(d, i)).collect();
            l.iter().cloned().fold(f32::MIN, f32::max) - l.iter().cloned().fold(f32::MAX, f32::min)
        };
        let (want, before, after) = (range(&ref_img.data), range(&squeezed), range(&mapped.data));
        assert!(before < 0.7 * want, "the test's squeeze: {before} vs {want}");
        assert!((after - want).abs() < 0.02 * want, "lightness range after the map {after}, reference {want}");
        assert_eq!(mapped.data[30..33], mapped.data[60..63], "one colour, one mapped colour");
        assert_eq!(mapped.data[600..603], squeezed[600..603], "the pixel without a surface is not mapped");
        let (ri, rg) = (ref_img.clone(), ref_geom);
        let itself = map_onto(std::slice::from_ref(&ri), std::slice::from_ref(&rg), &reference).remove(0);
        let worst = itself.data.iter().zip(&ri.data).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(worst < 0.01, "a distribution mapped onto itself moved by {worst}");
    }

    /// A stand-in for a field that falls short of its targets: every colour pulled a fixed
    /// share of the way toward mid-grey. Trained on the compensated targets, it shows the
    /// targets' own spread after a step or two (against 0.8 of it uncompensated), and two
    /// pixels of one colour are still one colour.
    #[test]
    fn compensated_targets_make_up_a_fields_shortfall() {
        let field = |img: &Image| Image { data: img.data.iter().map(|v| 0.5 + 0.8 * (v - 0.5)).collect(), ..img.clone() };
        let mut data = ramp(201, 0.7);
        let same: Vec<f32> = data[30..33].to_vec();
        data[90..93].copy_from_slice(&same);
        let (want_img, geom) = view(data);
        let (imgs, geoms) = (std::slice::from_ref(&want_img), std::slice::from_ref(&geom));
        let want = Quantiles::of(imgs, geoms);
        let spread = |q: &Quantiles| q.channels[0][LEVELS - 10] - q.channels[0][10];
        let plain = spread(&Quantiles::of(&[field(&want_img)], geoms)) / spread(&want);
        assert!(plain < 0.85, "the stand-in field keeps {plain} of the spread");
        let (mut trained, mut targets) = (want.clone(), want_img.clone());
        for _ in 0..3 {
            let shown = Quantiles::of(&[field(&targets)], geoms);
            let asked = compensated(&want, &shown, &trained);
            targets = map_onto(imgs, geoms, &asked).remove(0);
            trained = asked;
        }
        let kept = spread(&Quantiles::of(&[field(&targets)], geoms)) / spread(&want);
        assert!((kept - 1.0).abs() < 0.03, "compensated, the field shows {kept} of the targets' spread (plain: {plain})");
        assert_eq!(targets.data[30..33], targets.data[90..93], "one colour, one compensated colour");
        assert!(compensated(&want, &Quantiles { channels: Default::default() }, &want).is_empty());
    }

    #[test]
    fn quantile_is_the_mean_rank_of_equal_values() {
        let s = [0.0, 1.0, 1.0, 1.0, 2.0];
        assert_eq!(quantile(&s, 0.0), 0.0);
        assert_eq!(quantile(&s, 1.0), 0.5);
        assert_eq!(quantile(&s, 2.0), 1.0);
    }

    #[test]
    fn a_saved_palette_reads_back_and_a_bad_one_is_named() {
        let dir = snerf_files::ScratchDir::new("snerf-palette", "saved").unwrap();
        let (img, geom) = view(ramp(50, 1.0));
        let q = Quantiles::of(std::slice::from_ref(&img), std::slice::from_ref(&geom));
        save(&dir, &q).unwrap();
        assert_eq!(load(&dir).unwrap(), q);
        // a first fusion that showed no surface: an empty palette, saved, read back, and a map
        // that leaves every colour alone (a later round may see surface the first did not)
        let nothing = ViewGeometry { c2w: geom.c2w, intr: geom.intr, points: vec![None; geom.points.len()] };
        let empty = Quantiles::of(std::slice::from_ref(&img), &[nothing]);
        save(&dir, &empty).unwrap();
        let back = load(&dir).unwrap();
        assert_eq!(back, empty);
        assert_eq!(map_onto(std::slice::from_ref(&img), std::slice::from_ref(&geom), &back)[0].data, img.data);
        std::fs::write(path(&dir), b"{\"channels\": [[1.0], [2.0], [3.0]]}").unwrap();
        let e = format!("{:#}", load(&dir).unwrap_err());
        assert!(e.contains("palette.json: not a palette file"), "{e}");
    }
}
