//! Reading one view's colour at a world point: the single home of the reprojection rule that
//! both target fusion (`fusion`) and the consistency measurement (`consistency`) use.
//!
//! A view sees a world point when the point projects inside the image and the surface the
//! view shows at that pixel lies at the point's distance (within `OCCLUSION_TOL`). Its
//! colour there is the bilinear mean of the four nearest pixels, *over those of them that
//! show the same surface*: a tap that shows the background, or an occluding surface, is
//! left out and the others are renormalized. Plain bilinear reads background into every
//! point within a pixel of a silhouette: warping an object whose colour differs from the
//! background then reports an error that belongs to the interpolation, not to the
//! stylization, and fusion carries that background into the targets' rims, a little more
//! each consensus round (docs/stylize-notebook.md §5g).
//!
//! `Seen::nearest` is the other read, for fusion: the colour of the pixel the point falls in,
//! under the same visibility rule. A bilinear read is a small blur; fusion that reads
//! bilinearly blurs the targets once per round, and iterated over consensus rounds that
//! takes the painting's contrast away (docs/stylize-notebook.md §5i). The nearest pixel copies what was
//! painted.

use snerf_trainer::space::{norm, sub, Vec3};

use crate::stylizer::Image;

/// A pixel counts as showing the scene above this opacity.
pub const COVERED: f32 = 0.5;
/// Relative depth tolerance of the occlusion test.
pub const OCCLUSION_TOL: f32 = 0.03;

/// What a view shows: its camera centre and, per pixel, the surface point it sees (None: no
/// surface).
pub struct Seen<'a> {
    pub origin: Vec3,
    pub width: usize,
    pub height: usize,
    pub points: &'a [Option<Vec3>],
}

impl Seen<'_> {
    fn shows(&self, q: usize, dist: f32) -> bool {
        self.points[q].is_some_and(|s| (norm(sub(s, self.origin)) - dist).abs() <= OCCLUSION_TOL * dist)
    }

    /// The pixel that continuous pixel coordinates (u, v) fall in, when the view sees the
    /// point there from distance `dist` (inside the image's pixel centres, not background,
    /// not occluded).
    fn seen_pixel(&self, u: f32, v: f32, dist: f32) -> Option<usize> {
        let (w, h) = (self.width, self.height);
        if !(u >= 0.5 && v >= 0.5 && u <= w as f32 - 0.5 && v <= h as f32 - 0.5) {
            return None;
        }
        let q = (v as usize).min(h - 1) * w + (u as usize).min(w - 1);
        self.shows(q, dist).then_some(q)
    }

    /// The colour of `img`'s pixel that the point falls in, where `colour` would read one:
    /// no resampling, so a read changes no colour.
    pub fn nearest(&self, img: &Image, u: f32, v: f32, dist: f32) -> Option<[f32; 3]> {
        let q = self.seen_pixel(u, v, dist)?;
        Some([0, 1, 2].map(|c| img.data[q * 3 + c]))
    }

    /// The colour of `img` (this view's image) at the point that projects to continuous pixel
    /// coordinates (u, v) (pixel x spans [x, x+1)) from distance `dist`; None when the view
    /// does not see it (off the image, background, or occluded).
    pub fn colour(&self, img: &Image, u: f32, v: f32, dist: f32) -> Option<[f32; 3]> {
        let (w, h) = (self.width, self.height);
        let q = self.seen_pixel(u, v, dist)?;
        let (x, y) = (u - 0.5, v - 0.5);
        let x0 = (x.floor().max(0.0) as usize).min(w - 1);
        let y0 = (y.floor().max(0.0) as usize).min(h - 1);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = ((x - x0 as f32).clamp(0.0, 1.0), (y - y0 as f32).clamp(0.0, 1.0));
        let taps = [(x0, y0, (1.0 - fx) * (1.0 - fy)), (x1, y0, fx * (1.0 - fy)), (x0, y1, (1.0 - fx) * fy), (x1, y1, fx * fy)];
        let (mut sum, mut wsum) = ([0.0f32; 3], 0.0f32);
        for (tx, ty, wt) in taps {
            let t = ty * w + tx;
            if wt > 0.0 && self.shows(t, dist) {
                for c in 0..3 {
                    sum[c] += wt * img.data[t * 3 + c];
                }
                wsum += wt;
            }
        }
        if wsum <= 1e-6 {
            // the nearest pixel shows the point but carries no bilinear weight (an exact edge)
            return Some([0, 1, 2].map(|c| img.data[q * 3 + c]));
        }
        Some(sum.map(|s| s / wsum))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 4×1 strip: two scene pixels (red, green) at distance 5 from the camera, then two
    /// background pixels (white).
    fn strip() -> (Image, [Option<Vec3>; 4]) {
        let img = Image { width: 4, height: 1, data: vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0] };
        let p = Some([0.0, 0.0, 0.0]);
        (img, [p, p, None, None])
    }

    /// On the strip: between the scene pixels the read is the plain bilinear mean; between
    /// green and background it is green alone; on the background, nothing.
    #[test]
    fn background_taps_are_left_out() {
        let (img, points) = strip();
        let seen = Seen { origin: [0.0, 0.0, 5.0], width: 4, height: 1, points: &points };
        let mid = seen.colour(&img, 1.0, 0.5, 5.0).unwrap();
        assert!((mid[0] - 0.5).abs() < 1e-6 && (mid[1] - 0.5).abs() < 1e-6, "{mid:?}");
        let rim = seen.colour(&img, 1.9, 0.5, 5.0).unwrap();
        assert_eq!(rim, [0.0, 1.0, 0.0], "a rim read must not take the background's white");
        assert!(seen.colour(&img, 2.6, 0.5, 5.0).is_none());
        // a point farther than the surface the pixel shows is occluded
        assert!(seen.colour(&img, 1.0, 0.5, 6.0).is_none());
    }

    /// The nearest read returns the pixel the point falls in, unmixed, and sees what the
    /// bilinear read sees.
    #[test]
    fn the_nearest_read_copies_a_pixel_under_the_same_visibility() {
        let (img, points) = strip();
        let seen = Seen { origin: [0.0, 0.0, 5.0], width: 4, height: 1, points: &points };
        assert_eq!(seen.nearest(&img, 0.9, 0.5, 5.0), Some([1.0, 0.0, 0.0]));
        assert_eq!(seen.nearest(&img, 1.1, 0.5, 5.0), Some([0.0, 1.0, 0.0]));
        assert_eq!(seen.nearest(&img, 1.9, 0.5, 5.0), Some([0.0, 1.0, 0.0]));
        for (u, d) in [(2.6, 5.0), (1.0, 6.0), (0.2, 5.0)] {
            assert_eq!(seen.nearest(&img, u, 0.5, d), None, "u {u}, dist {d}");
            assert_eq!(seen.colour(&img, u, 0.5, d), None, "u {u}, dist {d}");
        }
    }
}
