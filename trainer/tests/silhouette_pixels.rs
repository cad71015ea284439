//! Which pixels are trained and rendered as the mean over their square: the silhouette band
//! of a view's alpha (training) and of a render's opacity (rendering), by one rule.

use snerf_data::{Intrinsics, View};
use snerf_trainer::eval::mixed_coverage;
use snerf_trainer::render::subpixel_grid;
use snerf_trainer::train::silhouette_mask;

fn view(w: u32, h: u32, alpha: impl Fn(u32, u32) -> u8) -> View {
    let rgba = [10u8, 20, 30, 0].repeat((w * h) as usize);
    let mut v = View {
        path: "v.png".into(),
        intrinsics: Intrinsics { width: w, height: h, fx: 10.0, fy: 10.0, cx: w as f32 / 2.0, cy: h as f32 / 2.0, distortion: [0.0; 4] },
        c2w: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 3.0]],
        time: None,
        rgba,
    };
    for y in 0..h {
        for x in 0..w {
            v.rgba[((y * w + x) * 4 + 3) as usize] = alpha(x, y);
        }
    }
    v
}

fn bit(mask: &[u64], p: usize) -> bool {
    mask[p / 64] >> (p % 64) & 1 == 1
}

#[test]
fn the_silhouette_band_is_the_pixels_next_to_both_coverages() {
    // a covered square x, y in 4..8 on an empty 12x10 view, with one partly covered pixel
    let inside = |x: u32, y: u32| (4..8).contains(&x) && (4..8).contains(&y);
    let a = view(12, 10, |x, y| if (x, y) == (8, 5) { 128 } else if inside(x, y) { 255 } else { 0 });
    let b = view(3, 3, |_, _| 255); // opaque: no silhouette at all
    let mask = silhouette_mask(&[a, b]);
    for y in 0..10 {
        for x in 0..12 {
            // Chebyshev distance to the square's border cells, and the partial pixel's window
            let near_edge = (3..=8).contains(&x) && (3..=8).contains(&y) && !((5..=6).contains(&x) && (5..=6).contains(&y));
            let near_partial = (7..=9).contains(&x) && (4..=6).contains(&y);
            assert_eq!(bit(&mask, (y * 12 + x) as usize), near_edge || near_partial, "pixel ({x}, {y})");
        }
    }
    assert!((120..129).all(|p| !bit(&mask, p)), "an opaque view has no silhouette pixels");
}

#[test]
fn rendered_opacity_marks_the_same_band() {
    let (w, h) = (6, 5);
    let o: Vec<f32> = (0..w * h).map(|p| if p % w >= 3 { 1.0 } else { 0.0 }).collect();
    let marked: Vec<usize> = (0..w * h).filter(|&p| mixed_coverage(&o, w, h, p % w, p / w)).map(|p| p % w).collect();
    assert!(marked.iter().all(|&x| x == 2 || x == 3) && marked.len() == 2 * h, "{marked:?}");
    // nearly covered and nearly empty (within one 8-bit level) count as covered and empty
    let o: Vec<f32> = (0..w * h).map(|p| if p % w >= 3 { 0.999 } else { 0.001 }).collect();
    assert_eq!((0..w * h).filter(|&p| mixed_coverage(&o, w, h, p % w, p / w)).count(), 2 * h);
    let o = vec![0.999f32; w * h];
    assert_eq!((0..w * h).filter(|&p| mixed_coverage(&o, w, h, p % w, p / w)).count(), 0);
}

#[test]
fn subpixel_grid_covers_the_square_evenly() {
    assert_eq!(subpixel_grid(1), vec![(0.5, 0.5)]);
    let g = subpixel_grid(4);
    assert_eq!(g, vec![(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]);
    let g = subpixel_grid(16);
    let mean = g.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0 / 16.0, a.1 + p.1 / 16.0));
    assert!((mean.0 - 0.5f32).abs() < 1e-6 && (mean.1 - 0.5f32).abs() < 1e-6);
}
