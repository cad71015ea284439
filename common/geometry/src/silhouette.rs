//! Which pixels are drawn as the mean over their square, and where in the square their rays
//! go: the one rule the trainer (on target alpha and on rendered opacity), the asset's CPU
//! reference renderer and the march shader (`shaders/march.wgsl`, second pass) all apply.
//!
//! A pixel of a captured view is the mean of the scene over the pixel's square. Inside a
//! surface that mean and the value at the centre agree to first order; on a silhouette they
//! do not (the pixel holds the covered fraction of its square), so there a pixel takes
//! several rays on a fixed sub-pixel grid and shows their mean.

/// Opacity within this of 0 or 1 counts as empty or covered (one 8-bit level): the
/// silhouette test on rendered opacity (`mixed_coverage`).
pub const COVER_EPS: f32 = 1.0 / 255.0;

/// Most rays a pixel may take (a 4x4 grid).
pub const MAX_PIXEL_RAYS: usize = 16;

/// Side of the square sub-pixel grid of `k` rays (k = side²; anything else rounds).
pub fn subpixel_side(k: usize) -> usize {
    (k.max(1) as f32).sqrt().round() as usize
}

/// Fixed sub-pixel positions of `k` rays (a side x side grid of cell centres, row by row),
/// in pixel units from the pixel's corner: how a renderer takes the mean over a pixel's square.
pub fn subpixel_grid(k: usize) -> Vec<(f32, f32)> {
    let side = subpixel_side(k);
    (0..side * side).map(|j| (((j % side) as f32 + 0.5) / side as f32, ((j / side) as f32 + 0.5) / side as f32)).collect()
}

/// Whether `k` rays form a square grid the renderers accept (1, 4, 9 or 16).
pub fn valid_pixel_rays(k: usize) -> bool {
    (1..=MAX_PIXEL_RAYS).contains(&k) && subpixel_side(k).pow(2) == k
}

/// The smallest and largest of `at(pixel index)` over the 3x3 neighbourhood of (x, y) in a
/// `w` x `h` image (clipped at the borders): the one home of the silhouette rule's window.
pub fn min_max_3x3<T: Copy + PartialOrd>(w: usize, h: usize, x: usize, y: usize, at: impl Fn(usize) -> T) -> (T, T) {
    let (mut lo, mut hi) = (at(y * w + x), at(y * w + x));
    for yy in y.saturating_sub(1)..(y + 2).min(h) {
        for xx in x.saturating_sub(1)..(x + 2).min(w) {
            let a = at(yy * w + xx);
            if a < lo {
                lo = a;
            }
            if a > hi {
                hi = a;
            }
        }
    }
    (lo, hi)
}

/// Rendered opacity in the 3x3 neighbourhood of (x, y) is neither all covered nor all
/// empty: the pixel is on a silhouette (the trainer's rule on target alpha, on opacity).
pub fn mixed_coverage(opacity: &[f32], w: usize, h: usize, x: usize, y: usize) -> bool {
    let (lo, hi) = min_max_3x3(w, h, x, y, |i| opacity[i]);
    lo < 1.0 - COVER_EPS && hi > COVER_EPS
}

/// The mean of one pixel's rays, as every renderer forms it: colour and opacity averaged
/// over the rays (summed in ray order, then divided), depth weighted by opacity (0 where
/// the rays hold none).
pub fn mean_of_rays(rays: &[([f32; 3], f32, f32)]) -> ([f32; 3], f32, f32) {
    let n = rays.len() as f32;
    let mut rgb = [0.0f32; 3];
    let (mut opacity, mut depth) = (0.0f32, 0.0f32);
    for (c, o, d) in rays {
        for k in 0..3 {
            rgb[k] += c[k];
        }
        opacity += o;
        depth += d * o;
    }
    let depth = if opacity > 1e-6 { depth / opacity } else { 0.0 };
    (rgb.map(|c| c / n), opacity / n, depth)
}

/// How coarse a display pixel must be, against a training pixel, for its silhouette pixels
/// to be drawn as the mean of several rays (`draws_pixel_means`): 1/√2, halfway (in scale)
/// between the training resolution, where the mean gains 1.3-4.3 dB, and twice it, where it
/// gains nothing on average (BENCH.md §2b, six models).
pub const MEAN_PIXEL_RATIO: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// A camera's pixel footprint at the scene's centre: the width in world units one pixel
/// spans at that distance (distance / focal length in pixels).
pub fn pixel_footprint(eye: [f32; 3], centre: [f32; 3], fx: f32) -> f32 {
    let d = ((eye[0] - centre[0]).powi(2) + (eye[1] - centre[1]).powi(2) + (eye[2] - centre[2]).powi(2)).sqrt();
    d / fx.abs()
}

/// The median [`pixel_footprint`] of cameras given as (eye, focal length in pixels) at the
/// scene's centre: how fine the pixels were that a field learnt its edges from.
pub fn median_footprint(cams: impl Iterator<Item = ([f32; 3], f32)>, centre: [f32; 3]) -> Option<f32> {
    let mut f: Vec<f32> = cams.map(|(eye, fx)| pixel_footprint(eye, centre, fx)).filter(|f| f.is_finite() && *f > 0.0).collect();
    f.sort_by(|a, b| a.total_cmp(b));
    f.get(f.len() / 2).copied()
}

/// Whether a camera draws silhouette pixels as the mean of several rays. The field learnt
/// its edges from pixels of the training views' size (`train_pixel`, their median
/// [`pixel_footprint`]), so a display pixel at least `MEAN_PIXEL_RATIO` of that size needs
/// the mean over its square to show them as the views did (+1.3 to +4.3 dB on held-out views at the
/// training resolution), while finer display pixels already resolve the edge the field
/// learnt and would only pay for more rays (no gain on average at 2x and 4x the resolution, a
/// frame 1.5-1.8x slower; BENCH.md §2b). Without a recorded `train_pixel` every camera does.
pub fn draws_pixel_means(train_pixel: Option<f32>, footprint: f32) -> bool {
    match train_pixel {
        Some(t) if t > 0.0 && t.is_finite() => !(footprint < MEAN_PIXEL_RATIO * t),
        _ => true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subpixel_grid_covers_the_square_evenly() {
        assert_eq!(subpixel_grid(1), vec![(0.5, 0.5)]);
        assert_eq!(subpixel_grid(4), vec![(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]);
        let g = subpixel_grid(16);
        let mean = g.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0 / 16.0, a.1 + p.1 / 16.0));
        assert!((mean.0 - 0.5f32).abs() < 1e-6 && (mean.1 - 0.5f32).abs() < 1e-6);
        assert!([1, 4, 9, 16].iter().all(|&k| valid_pixel_rays(k)));
        assert!([0, 2, 3, 5, 8, 17, 25].iter().all(|&k| !valid_pixel_rays(k)));
    }

    #[test]
    fn the_mean_of_rays_weights_depth_by_opacity() {
        let (rgb, o, d) = mean_of_rays(&[([1.0, 0.0, 0.5], 1.0, 2.0), ([0.0, 0.0, 0.5], 0.0, 0.0), ([1.0, 1.0, 0.5], 0.5, 4.0), ([0.0, 1.0, 0.5], 0.5, 4.0)]);
        assert_eq!(rgb, [0.5, 0.5, 0.5]);
        assert_eq!(o, 0.5);
        assert_eq!(d, 3.0);
        assert_eq!(mean_of_rays(&[([0.2; 3], 0.0, 5.0)]).2, 0.0);
    }

    #[test]
    fn only_pixels_about_as_coarse_as_the_training_ones_take_means() {
        let f = pixel_footprint([0.0, 3.0, 4.0], [0.0; 3], 100.0);
        assert_eq!(f, 0.05);
        assert!(draws_pixel_means(Some(0.05), f));
        assert!(draws_pixel_means(Some(0.07), f), "0.71 of a training pixel still does");
        assert!(!draws_pixel_means(Some(0.1), f), "half does not");
        assert!(!draws_pixel_means(Some(0.2), f), "a quarter does not");
        assert!(draws_pixel_means(None, f) && draws_pixel_means(Some(0.0), f) && draws_pixel_means(Some(f32::NAN), f));
    }
}
