//! What a field trained on painted views falls short of, as a function of the colour it was
//! asked for (`ColourFit::Joint` in the loop).
//!
//! A field fitted to painted views shows less of each colour than its targets hold: a red
//! stroke a pixel or two wide on green leaves the field a mixture at the stroke's pixels,
//! and the area rays average it over each pixel's square. Matching the distribution of each
//! Oklab channel apart (`palette::compensated`) restores every channel's spread but not
//! which colours go together: on the pairs measured the field kept each channel's spread
//! and still lost the painting's joint colours (red on green) round after round (docs/stylize-notebook.md
//! §5v).
//!
//! So the shortfall is measured where it happens: at every scene pixel of the training
//! views, the target's colour minus the colour the field shows there, averaged over the
//! pixels whose target has (about) the same colour. That average is an offset per colour,
//! kept on a grid over Oklab whose cell is one just-noticeable difference ([`JND`]: a finer
//! grid would tell apart colours no viewer can; trilinear between the grid's nodes), and the
//! field is trained on `target + offset(target)`. It is the per-pixel iterative-learning step
//! (`u ← u + (want − shown)`) restricted to maps that depend on the colour alone: colours the
//! views agree on get one offset and stay in agreement, and the offsets cannot learn where
//! the views disagree, only what the field does to a colour.
//!
//! The k-th calibration of a run adds its measured shortfall times `1/k`: a Robbins–Monro
//! iteration for the offsets at which the field shows its targets, with the harmonic steps
//! the targets take. Where such offsets exist it approaches them in shrinking steps. Where
//! the field cannot reach a target at all (a colour beyond it, a disagreement no map of
//! colours can settle) the shortfall persists; a constant gain would add all of it again at
//! every calibration, harmonic gains a shrinking share of it.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::fusion::ViewGeometry;
use crate::palette;
use crate::style_metric::{oklab, srgb_from_oklab, JND};
use crate::stylizer::Image;

/// A grid node: the Oklab colour `index × JND`.
type Node = [i32; 3];

/// Offsets (Oklab) at the grid's nodes; a node without one has offset 0. Saved sorted by
/// node, so one run writes one file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ColourOffsets {
    /// The grid's cell, recorded so that a file read back is known to be on this grid.
    cell: f32,
    /// How many calibrations these offsets are the sum of.
    calibrations: u32,
    nodes: Vec<(Node, [f32; 3])>,
}

/// The 8 nodes around Oklab colour `c` with their trilinear weights.
fn corners(c: [f32; 3]) -> [(Node, f32); 8] {
    let g = c.map(|v| v / JND);
    let i = g.map(|v| v.floor() as i32);
    let f = [0, 1, 2].map(|a| g[a] - i[a] as f32);
    std::array::from_fn(|k| {
        let d = [k & 1, (k >> 1) & 1, (k >> 2) & 1];
        let w = (0..3).map(|a| if d[a] == 1 { f[a] } else { 1.0 - f[a] }).product();
        ([0, 1, 2].map(|a| i[a] + d[a] as i32), w)
    })
}

fn pixel(img: &Image, p: usize) -> [f32; 3] {
    [img.data[p * 3], img.data[p * 3 + 1], img.data[p * 3 + 2]]
}

impl ColourOffsets {
    fn table(&self) -> HashMap<Node, [f32; 3]> {
        self.nodes.iter().cloned().collect()
    }

    /// These offsets plus the field's shortfall times `1/k` (this is the k-th calibration):
    /// per node, the mean of
    /// `target − shown` (Oklab) over the scene pixels of the training views (those that show
    /// a surface in `geoms`), each weighted by how near its target's colour is to the node.
    /// A node that few pixels reach is shrunk toward no change (the weights' sum plus one
    /// pixel divides), so a stray colour does not set an offset alone.
    pub fn step(&self, targets: &[Image], shown: &[Image], geoms: &[ViewGeometry]) -> ColourOffsets {
        let gain = 1.0 / (self.calibrations + 1) as f32;
        let mut sums: HashMap<Node, ([f64; 3], f64)> = HashMap::new();
        for ((t, s), g) in targets.iter().zip(shown).zip(geoms) {
            for (p, x) in g.points.iter().enumerate() {
                if x.is_none() {
                    continue;
                }
                let (want, got) = (oklab(pixel(t, p)), oklab(pixel(s, p)));
                for (n, w) in corners(want) {
                    let e = sums.entry(n).or_default();
                    for k in 0..3 {
                        e.0[k] += (w * (want[k] - got[k])) as f64;
                    }
                    e.1 += w as f64;
                }
            }
        }
        let mut table = self.table();
        for (n, (r, w)) in sums {
            let o = table.entry(n).or_default();
            for k in 0..3 {
                o[k] += gain * (r[k] / (w + 1.0)) as f32;
            }
        }
        let mut nodes: Vec<_> = table.into_iter().collect();
        nodes.sort_by_key(|(n, _)| *n);
        ColourOffsets { cell: JND, calibrations: self.calibrations + 1, nodes }
    }

    /// `targets` with every scene pixel's colour moved by its offset (trilinear between the
    /// nodes; clamped to the sRGB gamut). Pixels that show no surface are unchanged.
    pub fn apply(&self, targets: &[Image], geoms: &[ViewGeometry]) -> Vec<Image> {
        let table = self.table();
        targets
            .par_iter()
            .zip(geoms)
            .map(|(t, g)| {
                let mut out = t.clone();
                for (p, x) in g.points.iter().enumerate() {
                    if x.is_some() {
                        let c = oklab(pixel(t, p));
                        let mut moved = c;
                        for (n, w) in corners(c) {
                            if let Some(o) = table.get(&n) {
                                for k in 0..3 {
                                    moved[k] += w * o[k];
                                }
                            }
                        }
                        out.data[p * 3..p * 3 + 3].copy_from_slice(&srgb_from_oklab(moved));
                    }
                }
                out
            })
            .collect()
    }

    /// The offsets a run last trained with (beside its consensus), if it has any.
    pub fn load(out: &Path) -> Result<Option<ColourOffsets>> {
        let p = path(out);
        if !p.exists() {
            return Ok(None);
        }
        let bytes = std::fs::read(&p).with_context(|| format!("{}: cannot read the run's colour offsets", p.display()))?;
        let o: ColourOffsets = serde_json::from_slice(&bytes).with_context(|| format!("{}: not a colour-offsets file", p.display()))?;
        anyhow::ensure!(o.cell == JND, "{}: colour offsets on a grid of {} (this version's is {JND})", p.display(), o.cell);
        anyhow::ensure!(o.nodes.iter().all(|(_, v)| v.iter().all(|x| x.is_finite())), "{}: a colour offset is not a number", p.display());
        Ok(Some(o))
    }

    pub fn save(&self, out: &Path) -> Result<()> {
        palette::save_file(&path(out), self)
    }
}

fn path(out: &Path) -> PathBuf {
    palette::file(out, "offsets.json")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::palette::tests::view;

    /// Red strokes one pixel wide on green, in a few shades.
    fn strokes() -> Vec<f32> {
        (0..2400)
            .flat_map(|i| {
                let t = (i % 7) as f32 / 30.0;
                if i % 6 == 0 { [0.75 - t, 0.25 + t, 0.2] } else { [0.25, 0.6 - t, 0.3 + t] }
            })
            .collect()
    }

    /// A stand-in for a field that falls short jointly: every pixel shows 0.7 of its colour
    /// and 0.3 of its neighbours' mean, so each red stroke is shown a little green and each
    /// green a little red (per channel, the spread narrows too).
    fn field(img: &Image) -> Image {
        let n = img.width;
        let mut out = img.clone();
        for i in 0..n {
            let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
            for k in 0..3 {
                out.data[i * 3 + k] = 0.7 * img.data[i * 3 + k] + 0.15 * (img.data[a * 3 + k] + img.data[b * 3 + k]);
            }
        }
        out
    }

    /// The mean Oklab distance between `a` and `b` over the red strokes.
    fn stroke_error(a: &Image, b: &Image) -> f32 {
        let strokes: Vec<usize> = (0..a.width - 1).filter(|p| p % 6 == 0).collect();
        strokes
            .iter()
            .map(|&p| {
                let (x, y) = (oklab(pixel(a, p)), oklab(pixel(b, p)));
                ((x[0] - y[0]).powi(2) + (x[1] - y[1]).powi(2) + (x[2] - y[2]).powi(2)).sqrt()
            })
            .sum::<f32>()
            / strokes.len() as f32
    }

    /// Trained on offset targets (three calibrations), the stand-in field shows the red
    /// strokes far more nearly in their own colour than trained on the targets as they are
    /// (the green beside a stroke cannot be helped by a map of colours: the same green lies
    /// away from the strokes too); one colour gets
    /// one offset wherever it is; the pixel without a surface is left alone.
    #[test]
    fn offsets_make_up_a_fields_joint_shortfall() {
        let (want, geom) = view(strokes());
        let (imgs, geoms) = (std::slice::from_ref(&want), std::slice::from_ref(&geom));
        let plain = stroke_error(&field(&want), &want);
        let mut offsets = ColourOffsets::default();
        let mut targets = want.clone();
        for _ in 0..3 {
            offsets = offsets.step(imgs, &[field(&targets)], geoms);
            targets = offsets.apply(imgs, geoms).remove(0);
        }
        assert_eq!(offsets.calibrations, 3);
        let compensated = stroke_error(&field(&targets), &want);
        assert!(compensated < 0.4 * plain, "the strokes' mean Oklab error to the targets: {compensated} compensated, {plain} plain");
        // pixels 0 and 42: the same colour (stroke phase and shade repeat every 42 pixels)
        assert_eq!(want.data[0..3], want.data[126..129]);
        assert_eq!(targets.data[0..3], targets.data[126..129], "one colour, one offset");
        let last = want.data.len() - 3;
        assert_eq!(targets.data[last..], want.data[last..], "the pixel without a surface keeps its colour");
    }

    /// With nothing to make up, the offsets are zero and the targets come back unchanged
    /// (up to the Oklab round trip).
    #[test]
    fn a_field_that_shows_its_targets_gets_no_offsets() {
        let (want, geom) = view(strokes());
        let o = ColourOffsets::default().step(std::slice::from_ref(&want), std::slice::from_ref(&want), std::slice::from_ref(&geom));
        assert!(o.nodes.iter().all(|(_, v)| v.iter().all(|x| x.abs() < 1e-6)));
        let back = o.apply(std::slice::from_ref(&want), std::slice::from_ref(&geom)).remove(0);
        let worst = back.data.iter().zip(&want.data).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(worst < 1e-3, "moved by {worst}");
    }

    #[test]
    fn saved_offsets_read_back_and_a_bad_file_is_named() {
        let dir = snerf_files::ScratchDir::new("snerf-offsets", "saved").unwrap();
        assert_eq!(ColourOffsets::load(&dir).unwrap(), None);
        let (want, geom) = view(strokes());
        let o = ColourOffsets::default().step(std::slice::from_ref(&want), &[field(&want)], std::slice::from_ref(&geom));
        o.save(&dir).unwrap();
        assert_eq!(ColourOffsets::load(&dir).unwrap(), Some(o));
        std::fs::write(path(&dir), b"{\"cell\": 0.05, \"calibrations\": 1, \"nodes\": []}").unwrap();
        let e = format!("{:#}", ColourOffsets::load(&dir).unwrap_err());
        assert!(e.contains("offsets.json: colour offsets on a grid of 0.05"), "{e}");
        std::fs::write(path(&dir), b"[1, 2").unwrap();
        let e = format!("{:#}", ColourOffsets::load(&dir).unwrap_err());
        assert!(e.contains("offsets.json: not a colour-offsets file"), "{e}");
    }
}
