//! Temporal flicker of a stylized 4D scene: one camera held still, frames at neighbouring
//! times. A per-frame stylizer paints each instant on its own and its strokes crawl from one
//! to the next even where nothing moves; a consistent 4D stylization keeps what stays put the
//! same.
//!
//! The measure is the warped error between neighbouring times at a fixed camera, with the
//! warp taken where it is known exactly. Where the realistic field's frames do not change
//! between two times, at a pixel and its eight neighbours (by less than `STILL`), nothing moved
//! there as that camera sees it, the correct warp is the identity, and any change in the
//! stylized frames is flicker. Pixels the realistic frames show moving are left out: the time
//! planes give no correspondence for them. Only scene pixels count (realistic opacity above
//! `COVERED` in both frames), as in the cross-view errors. The same pixels score every method,
//! so the numbers compare stylizations.

use anyhow::Result;
use serde::Serialize;
use snerf_data::{Dataset, Intrinsics};
use snerf_geometry::silhouette::min_max_3x3;
use snerf_trainer::eval::{eval_background, render_camera};
use snerf_trainer::render::WorkspacePool;
use snerf_trainer::space::Vec3;
use snerf_trainer::train::{views_have_alpha, Model};

use crate::consistency::{evaluation_orbit, preview, PATH_STEPS_PER_TURN};
use crate::reproject::COVERED;
use crate::stylizer::{Image, Stylizer};

/// Largest change of a realistic pixel (any channel, colours in [0,1]) between two
/// neighbouring times for the pixel to count as still: about 5/255, above the time planes'
/// own drift on parts that do not move and well below a moving edge.
pub const STILL: f32 = 0.02;

/// One camera of the evaluation orbit and the realistic field's frames at `times`.
pub struct TimePath {
    pub c2w: [[f32; 4]; 3],
    pub intr: Intrinsics,
    pub times: Vec<f32>,
    pub bg: Vec3,
    pub realistic: Vec<Image>,
    /// Per neighbouring pair (k, k+1): the pixels that score.
    pub still: Vec<Vec<bool>>,
    pub description: String,
}

/// Flicker of one method: mean squared change (RGB in [0,1]) between neighbouring times over
/// the still pixels.
#[derive(Clone, Debug, Serialize)]
pub struct Flicker {
    pub method: String,
    pub flicker: f64,
}

/// What `snerf consistency` reports of an animated scene: the realistic floor, per-frame
/// stylization and SNeRF on the same still pixels.
#[derive(Clone, Debug, Serialize)]
pub struct TemporalScores {
    pub path: String,
    pub still_fraction: f64,
    pub methods: Vec<Flicker>,
    pub snerf_over_per_frame: f64,
}

impl TemporalScores {
    /// Score a stylized model against the per-frame baseline along `path`.
    pub fn measure(path: &TimePath, stylized: &Model, pool: &WorkspacePool, stylizer: &dyn Stylizer, by_box: bool, res: usize) -> Result<TemporalScores> {
        let per_frame = path.stylize_frames(stylizer, by_box, res)?;
        let snerf = path.render(stylized, pool);
        let methods: Vec<Flicker> = [("Realistic field (no stylization)", &path.realistic), ("Per-frame image stylization", &per_frame), ("SNeRF", &snerf)]
            .into_iter()
            .map(|(method, frames)| Flicker { method: method.into(), flicker: path.flicker(frames) })
            .collect();
        Ok(TemporalScores {
            path: path.description.clone(),
            still_fraction: path.still_fraction(),
            snerf_over_per_frame: methods[2].flicker / methods[1].flicker,
            methods,
        })
    }

    /// One Markdown line for `consistency.md`.
    pub fn markdown(&self) -> String {
        format!(
            "Temporal flicker ({}; mean squared change between neighbouring instants on the {:.0}% of scene pixels the realistic frames show still): \
             realistic {:.2e}, per-frame {:.2e}, SNeRF {:.2e}; SNeRF / per-frame {:.3}×.\n",
            self.path,
            100.0 * self.still_fraction,
            self.methods[0].flicker,
            self.methods[1].flicker,
            self.methods[2].flicker,
            self.snerf_over_per_frame,
        )
    }
}

impl TimePath {
    /// `frames` instants evenly spread over the animation, (k + ½) / frames, seen from the
    /// first camera of `snerf consistency`'s evaluation orbit.
    pub fn evaluation(realistic: &Model, pool: &WorkspacePool, data: &Dataset, frames: usize) -> Result<TimePath> {
        anyhow::ensure!(data.dynamic, "{}: a static scene has no time to flicker over", data.root.display());
        anyhow::ensure!(frames >= 2, "a temporal path needs at least 2 frames");
        let (orbit, _) = evaluation_orbit(&preview(&realistic.space, data));
        let c2w = orbit.path(PATH_STEPS_PER_TURN)[0];
        let mut intr = data.test.first().unwrap_or(&data.train[0]).intrinsics;
        intr.distortion = [0.0; 4];
        let bg = eval_background(views_have_alpha(&data.train));
        let times: Vec<f32> = (0..frames).map(|k| (k as f32 + 0.5) / frames as f32).collect();
        let rendered: Vec<_> = times.iter().map(|&t| render_camera(realistic, pool, &c2w, &intr, Some(t), bg)).collect();
        let (w, h) = (intr.width as usize, intr.height as usize);
        let still = rendered.windows(2).map(|p| still_pixels(&p[0].rgb, &p[1].rgb, &p[0].opacity, &p[1].opacity, w, h)).collect();
        let realistic = rendered.into_iter().map(|r| Image { width: r.width, height: r.height, data: r.rgb }).collect();
        let description = format!("{frames} instants (k + ½) / {frames} of the animation, one camera (the evaluation orbit's first)");
        Ok(TimePath { c2w, intr, times, bg, realistic, still, description })
    }

    /// A model's frames along the path.
    pub fn render(&self, model: &Model, pool: &WorkspacePool) -> Vec<Image> {
        self.times
            .iter()
            .map(|&t| {
                let r = render_camera(model, pool, &self.c2w, &self.intr, Some(t), self.bg);
                Image { width: r.width, height: r.height, data: r.rgb }
            })
            .collect()
    }

    /// The per-frame baseline: each realistic frame stylized on its own (in the object's box
    /// when `by_box`), at `res` as the loop paints its views.
    pub fn stylize_frames(&self, stylizer: &dyn Stylizer, by_box: bool, res: usize) -> Result<Vec<Image>> {
        self.realistic
            .iter()
            .map(|f| {
                let mask: Vec<bool> = f.data.chunks_exact(3).map(|p| p.iter().zip(&self.bg).any(|(a, b)| (a - b).abs() > 1e-3)).collect();
                crate::stylize_view::stylize_region(stylizer, f, by_box.then_some(mask.as_slice()), res)
            })
            .collect()
    }

    /// Mean squared change between neighbouring frames over the still pixels; NaN when no
    /// pixel is still.
    pub fn flicker(&self, frames: &[Image]) -> f64 {
        flicker(frames, &self.still)
    }

    /// Share of the scene's pixels that score (still in a pair), over all pairs.
    pub fn still_fraction(&self) -> f64 {
        let n: usize = self.still.iter().map(|s| s.iter().filter(|&&b| b).count()).sum();
        n as f64 / self.still.iter().map(|s| s.len()).sum::<usize>().max(1) as f64
    }
}

/// Pixels where both frames show the scene and neither the pixel nor its eight neighbours
/// changed by `STILL` or more.
pub fn still_pixels(a: &[f32], b: &[f32], op_a: &[f32], op_b: &[f32], w: usize, h: usize) -> Vec<bool> {
    let change: Vec<f32> = (0..w * h).map(|p| (0..3).map(|c| (a[p * 3 + c] - b[p * 3 + c]).abs()).fold(0.0, f32::max)).collect();
    let covered: Vec<f32> = (0..w * h).map(|p| op_a[p].min(op_b[p])).collect();
    (0..w * h)
        .map(|p| {
            let (x, y) = (p % w, p / w);
            let (_, most) = min_max_3x3(w, h, x, y, |q| change[q]);
            let (least, _) = min_max_3x3(w, h, x, y, |q| covered[q]);
            most < STILL && least > COVERED
        })
        .collect()
}

/// Mean squared RGB change between frames k and k+1 over `still[k]`, pooled over the pairs.
pub fn flicker(frames: &[Image], still: &[Vec<bool>]) -> f64 {
    let (mut sum, mut count) = (0.0f64, 0u64);
    for (pair, mask) in frames.windows(2).zip(still) {
        for (p, _) in mask.iter().enumerate().filter(|(_, &s)| s) {
            sum += (0..3).map(|c| ((pair[1].data[p * 3 + c] - pair[0].data[p * 3 + c]) as f64).powi(2)).sum::<f64>() / 3.0;
            count += 1;
        }
    }
    if count == 0 {
        f64::NAN
    } else {
        sum / count as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3]) -> Image {
        Image { width: w, height: h, data: (0..w * h).flat_map(|p| f(p % w, p / w)).collect() }
    }

    #[test]
    fn a_moving_square_is_left_out_and_flicker_on_still_pixels_is_counted() {
        let (w, h) = (16, 16);
        // realistic: a bright 3×3 square moves one pixel right; the rest is still grey
        let sq = |x0: usize| move |x: usize, y: usize| if (x0..x0 + 3).contains(&x) && (6..9).contains(&y) { [1.0; 3] } else { [0.4; 3] };
        let (a, b) = (image(w, h, sq(4)), image(w, h, sq(5)));
        let op = vec![1.0f32; w * h];
        let still = still_pixels(&a.data, &b.data, &op, &op, w, h);
        // pixels within a pixel of the squares' union are not still; far ones are
        assert!(!still[7 * w + 4] && !still[7 * w + 8] && !still[7 * w + 3]);
        assert!(still[0] && still[15 * w + 15] && still[7 * w + 12]);
        // a background pixel (opacity 0) never scores
        let mut op_b = op.clone();
        op_b[0] = 0.0;
        assert!(!still_pixels(&a.data, &b.data, &op, &op_b, w, h)[0]);
        // frames that match the realistic ones have no flicker; a uniform 0.1 change has 0.01
        assert_eq!(flicker(&[a.clone(), b.clone()], &[still.clone()]), 0.0);
        let shifted = image(w, h, |x, y| sq(5)(x, y).map(|v| v + 0.1));
        let f = flicker(&[a, shifted], &[still]);
        assert!((f - 0.01).abs() < 1e-6, "{f}");
        // no still pixel: NaN, not 0
        assert!(flicker(&[image(2, 2, |_, _| [0.0; 3]), image(2, 2, |_, _| [1.0; 3])], &[vec![false; 4]]).is_nan());
    }
}
