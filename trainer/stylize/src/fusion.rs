//! Multi-view fusion of stylized targets. A feed-forward stylizer paints every view on its
//! own, so the same surface point gets a different colour in each view; trained on that, a
//! field memorizes the disagreement (or averages it into mud). Fusion makes each target
//! agree with its neighbours before the field sees it: every scene pixel of view i is
//! carried, through the current field's depth, to the same surface point in each of the K
//! nearest training views (skipping views where that point is hidden or off-screen), and the
//! target becomes the per-channel median of the view's own colour and those reprojected
//! colours. A surface point then has (about) one target colour, whatever view shows it.
//!
//! `fuse_owner` is the other rule: each surface point takes the colour that the nearest view
//! seeing it painted there (the point's own view where that is the nearest). Every view then
//! reads the same painter at a point, so the targets agree as the median's do, but a point
//! keeps one painting's strokes where the median blends five views' different strokes into
//! a flatter, browner average (docs/stylize-notebook.md §5h). Nearest by camera centre: for views around an
//! object, the view that sees a surface from closest sees it largest and, mostly, most
//! frontally. Where the painter changes, a seam: consistent across views, since the choice
//! depends on the point alone.
//!
//! Both rules read the other views' colours by `Read`: `Nearest` (the default) copies the
//! pixel a point falls in, `Bilinear` mixes the four around it. A bilinear read is a small
//! blur, once per fusion, and the consensus rounds compound it: over five rounds the
//! targets' lightness contrast (standard deviation of Oklab L over their scene pixels) went
//! from the stylizations' 0.23 to 0.16 with bilinear reads and to 0.20 with nearest ones
//! (oculus-touch-v3 × Renoir; the painting's is 0.21), and with bilinear reads the style
//! distance of round 5 ended above round 1's on 3 of 9 pairs (docs/stylize-notebook.md §5i). The price of
//! copying: what the views disagree on is no longer smoothed away, and the warp error of the
//! stylized field is about twice the bilinear loop's.

use rayon::prelude::*;
use snerf_data::Intrinsics;
use snerf_trainer::space::{norm, sub, Vec3};

use crate::reproject::{Seen, COVERED};
use crate::stylizer::Image;

/// One training view's camera and the surface point the current field shows at each pixel.
pub struct ViewGeometry {
    pub c2w: [[f32; 4]; 3],
    pub intr: Intrinsics,
    /// World point per pixel, None where the pixel shows no surface.
    pub points: Vec<Option<Vec3>>,
}

impl ViewGeometry {
    /// From a render's depth and opacity (`render_camera`), through the model's space.
    pub fn from_render(
        space: &snerf_trainer::space::SceneSpace,
        c2w: &[[f32; 4]; 3],
        intr: &Intrinsics,
        time: Option<f32>,
        depth: &[f32],
        opacity: &[f32],
    ) -> ViewGeometry {
        let w = intr.width as usize;
        let points = (0..depth.len())
            .map(|p| {
                if opacity[p] <= COVERED {
                    return None;
                }
                let ray = space.ray(c2w, intr, (p % w) as f32 + 0.5, (p / w) as f32 + 0.5, time)?;
                let x = space.march_to_world(&ray, depth[p]);
                x.iter().all(|v| v.is_finite()).then_some(x)
            })
            .collect();
        ViewGeometry { c2w: *c2w, intr: *intr, points }
    }

    fn origin(&self) -> Vec3 {
        [self.c2w[0][3], self.c2w[1][3], self.c2w[2][3]]
    }

    /// Continuous pixel coordinates and distance of a world point; None behind the camera.
    fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        let k = &self.intr;
        snerf_geometry::camera::project(&self.c2w, k.fx, k.fy, k.cx, k.cy, p)
    }


    /// The colour of `img` (this view's image) at world point `x` when this view sees it
    /// (`reproject::Seen`: only pixels that show the same surface), read by `read`.
    fn sample_visible(&self, img: &Image, x: Vec3, read: Read) -> Option<[f32; 3]> {
        let (u, v, dist) = self.project(x)?;
        let seen = Seen { origin: self.origin(), width: self.intr.width as usize, height: self.intr.height as usize, points: &self.points };
        match read {
            Read::Nearest => seen.nearest(img, u, v, dist),
            Read::Bilinear => seen.colour(img, u, v, dist),
        }
    }
}

/// How fusion reads another view's colour at a surface point (see the module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Read {
    /// The bilinear mean of the four pixels around the point that show it (runs recorded
    /// before this option were fused so).
    #[default]
    Bilinear,
    /// The pixel the point falls in: no resampling.
    Nearest,
}

/// The `k` views nearest to each view (by camera centre).
pub fn neighbours(geoms: &[ViewGeometry], k: usize) -> Vec<Vec<usize>> {
    (0..geoms.len())
        .map(|i| {
            let mut d: Vec<(f32, usize)> =
                (0..geoms.len()).filter(|&j| j != i).map(|j| (norm(sub(geoms[i].origin(), geoms[j].origin())), j)).collect();
            d.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            d.into_iter().take(k).map(|(_, j)| j).collect()
        })
        .collect()
}

fn median(v: &mut [f32]) -> f32 {
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Every view's target with each scene pixel replaced by `pixel(scratch, i, p, x)` (view i,
/// pixel p showing world point x) where that returns a colour; pixels that show no surface,
/// and those it returns None for, keep their own. `S` is per-view scratch space. Returns the
/// targets and the fraction of scene pixels replaced.
fn per_scene_pixel<S: Default>(
    targets: &[Image],
    geoms: &[ViewGeometry],
    pixel: impl Fn(&mut S, usize, usize, Vec3) -> Option<[f32; 3]> + Sync,
) -> (Vec<Image>, f64) {
    assert_eq!(targets.len(), geoms.len());
    let results: Vec<(Image, usize, usize)> = (0..targets.len())
        .into_par_iter()
        .map(|i| {
            let mut out = targets[i].clone();
            let (mut scene, mut replaced) = (0usize, 0usize);
            let mut scratch = S::default();
            for (p, pt) in geoms[i].points.iter().enumerate() {
                let Some(x) = pt else { continue };
                scene += 1;
                if let Some(rgb) = pixel(&mut scratch, i, p, *x) {
                    out.data[p * 3..p * 3 + 3].copy_from_slice(&rgb);
                    replaced += 1;
                }
            }
            (out, scene, replaced)
        })
        .collect();
    let scene: usize = results.iter().map(|r| r.1).sum();
    let replaced: usize = results.iter().map(|r| r.2).sum();
    (results.into_iter().map(|r| r.0).collect(), replaced as f64 / scene.max(1) as f64)
}

/// Fuse each view's target with its `k` nearest views' targets (see the module doc).
/// Pixels that show no surface keep their own colour. Returns the fused targets and the
/// fraction of scene pixels that had at least one neighbour's colour.
pub fn fuse(targets: &[Image], geoms: &[ViewGeometry], k: usize, read: Read) -> (Vec<Image>, f64) {
    assert_eq!(targets.len(), geoms.len());
    if k == 0 || targets.len() < 2 {
        return (targets.to_vec(), 0.0);
    }
    let nb = neighbours(geoms, k);
    per_scene_pixel(targets, geoms, |vals: &mut [Vec<f32>; 3], i, p, x| {
        for (c, v) in vals.iter_mut().enumerate() {
            v.clear();
            v.push(targets[i].data[p * 3 + c]);
        }
        for &j in &nb[i] {
            if let Some(rgb) = geoms[j].sample_visible(&targets[j], x, read) {
                for c in 0..3 {
                    vals[c].push(rgb[c]);
                }
            }
        }
        (vals[0].len() > 1).then(|| [0, 1, 2].map(|c| median(&mut vals[c])))
    })
}

/// One painter per surface point (see the module doc): every scene pixel of view i takes the
/// colour that the view nearest to its surface point (by camera centre) and seeing it
/// painted there; view i's own colour when it is that view. Every view is a candidate, so
/// the choice depends on the point alone, not on which view asks. Returns the targets and
/// the fraction of scene pixels painted by another view.
pub fn fuse_owner(targets: &[Image], geoms: &[ViewGeometry], read: Read) -> (Vec<Image>, f64) {
    per_scene_pixel(targets, geoms, |order: &mut Vec<(f32, usize)>, i, _, x| owner_colour(targets, geoms, x, read, Some(i), order))
}

/// The colour `targets` give world point `x` under `fuse_owner`'s rule: what the nearest
/// view (by camera centre) that sees `x` painted there. With `own`, None where that view
/// would be `own` or come after it (the asking view keeps its own colour). `order` is
/// scratch space.
fn owner_colour(
    targets: &[Image],
    geoms: &[ViewGeometry],
    x: Vec3,
    read: Read,
    own: Option<usize>,
    order: &mut Vec<(f32, usize)>,
) -> Option<[f32; 3]> {
    order.clear();
    order.extend(geoms.iter().enumerate().map(|(j, g)| (norm(sub(g.origin(), x)), j)));
    order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    order.iter().take_while(|&&(_, j)| Some(j) != own).find_map(|&(_, j)| geoms[j].sample_visible(&targets[j], x, read))
}

/// Images seen from other cameras (`frames`, each with its world point per pixel in
/// `points`) as a field that held `targets` exactly would show them: every pixel with a
/// surface point takes the colour `fuse_owner`'s rule gives that point; pixels without
/// one, or whose point no view sees, keep the colour they have.
pub fn carry_to(frames: &mut [Image], points: &[Vec<Option<Vec3>>], targets: &[Image], geoms: &[ViewGeometry], read: Read) {
    frames.par_iter_mut().zip(points).for_each(|(img, pts)| {
        let mut order = Vec::new();
        for (p, x) in pts.iter().enumerate() {
            if let Some(rgb) = x.and_then(|x| owner_colour(targets, geoms, x, read, None, &mut order)) {
                img.data[p * 3..p * 3 + 3].copy_from_slice(&rgb);
            }
        }
    });
}

/// `render + step * (target - render)`, per pixel: a damped step from the current render
/// toward the stylized target (step 1: the target itself).
pub fn step_toward(render: &Image, target: &Image, step: f32) -> Image {
    let data = render.data.iter().zip(&target.data).map(|(r, t)| r + step * (t - r)).collect();
    Image { width: target.width, height: target.height, data }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_odd_and_even() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), 2.5);
    }

    fn cam_at(x: f32) -> [[f32; 4]; 3] {
        // looking down -z from (x, 0, 5)
        [[1.0, 0.0, 0.0, x], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 5.0]]
    }

    /// Three cameras over a plane z = 0 (2.4 pixels apart at the plane, so reads fall
    /// between pixels); each sees the plane, and view `vi` paints surface point `p` with
    /// `colour(vi, p, pixel x)`.
    fn views_of_a_plane(colour: impl Fn(usize, Vec3, usize) -> [f32; 3]) -> (Vec<ViewGeometry>, Vec<Image>) {
        let (w, h) = (32usize, 32usize);
        let intr = Intrinsics { width: w as u32, height: h as u32, fx: 40.0, fy: 40.0, cx: 16.0, cy: 16.0, distortion: [0.0; 4] };
        let mut geoms = Vec::new();
        let mut targets = Vec::new();
        for (vi, cx) in [-0.3f32, 0.0, 0.3].into_iter().enumerate() {
            let c2w = cam_at(cx);
            let mut points = Vec::new();
            let mut data = Vec::new();
            for y in 0..h {
                for x in 0..w {
                    let xc = (x as f32 + 0.5 - 16.0) / 40.0;
                    let yc = -(y as f32 + 0.5 - 16.0) / 40.0;
                    // ray (xc, yc, -1) from (cx, 0, 5) hits z = 0 at t = 5
                    let p = [cx + 5.0 * xc, 5.0 * yc, 0.0];
                    points.push(Some(p));
                    data.extend_from_slice(&colour(vi, p, x));
                }
            }
            geoms.push(ViewGeometry { c2w, intr, points });
            targets.push(Image { width: w, height: h, data });
        }
        (geoms, targets)
    }

    /// A colour that is a smooth function of the surface point, except an outlier stripe in
    /// the middle view.
    fn three_views_of_a_plane() -> (Vec<ViewGeometry>, Vec<Image>) {
        views_of_a_plane(|vi, p, x| if vi == 1 && (12..20).contains(&x) { [1.0, 0.0, 0.0] } else { [0.5 + 0.2 * p[0], 0.5 + 0.2 * p[1], 0.5] })
    }

    #[test]
    fn fusion_takes_the_median_of_views_of_the_same_point() {
        let (geoms, targets) = three_views_of_a_plane();
        let w = 32usize;
        // a nearest read is off by up to half a pixel: 0.2 × 0.125 / 2 in this colour ramp
        for (read, tol) in [(Read::Bilinear, 0.01), (Read::Nearest, 0.0126)] {
            let (fused, helped) = fuse(&targets, &geoms, 2, read);
            assert!(helped > 0.8, "{helped}");
            let p = 16 * w + 16;
            let got = &fused[1].data[p * 3..p * 3 + 3];
            let x = geoms[1].points[p].unwrap();
            let want = [0.5 + 0.2 * x[0], 0.5 + 0.2 * x[1], 0.5];
            for c in 0..3 {
                assert!((got[c] - want[c]).abs() < tol, "{read:?}: fused {got:?}, surface colour {want:?}");
            }
            // nothing to fuse with: unchanged
            let (same, _) = fuse(&targets, &geoms, 0, read);
            assert_eq!(same[1].data, targets[1].data);
        }
    }

    /// Fusion iterated as consensus rounds are: with views that agree on a fine painted
    /// texture (stripes 2 pixels wide) and reads that fall between pixels, the nearest read
    /// keeps the texture's contrast and the bilinear read blurs it away round by round.
    #[test]
    fn consensus_with_nearest_reads_keeps_the_painted_contrast() {
        let stripes = |_: usize, p: Vec3, _: usize| if (p[0] / 0.25).rem_euclid(2.0) < 1.0 { [0.9, 0.8, 0.2] } else { [0.1, 0.2, 0.6] };
        let (geoms, painted) = views_of_a_plane(stripes);
        let spread = |img: &Image| {
            let g: Vec<f32> = img.data.chunks_exact(3).map(|c| c[0]).collect();
            let m = g.iter().sum::<f32>() / g.len() as f32;
            (g.iter().map(|v| (v - m).powi(2)).sum::<f32>() / g.len() as f32).sqrt()
        };
        let before = spread(&painted[1]);
        let mut kept = Vec::new();
        for read in [Read::Nearest, Read::Bilinear] {
            let mut t = painted.clone();
            for _ in 0..5 {
                t = fuse(&t, &geoms, 2, read).0;
            }
            kept.push(spread(&t[1]) / before);
        }
        eprintln!("contrast kept after 5 fusions: nearest {:.3}, bilinear {:.3}", kept[0], kept[1]);
        assert!(kept[0] > 0.95, "nearest reads kept {:.3} of the contrast", kept[0]);
        assert!(kept[1] < 0.85, "bilinear reads kept {:.3} of the contrast", kept[1]);
    }

    /// Every view's target at a surface point is what the nearest camera that sees the point
    /// painted there: the views agree, and each keeps what it painted itself where it is the
    /// nearest (the middle view's stripe lies under the middle camera).
    #[test]
    fn owner_fusion_gives_every_point_its_nearest_painter() {
        let (geoms, targets) = three_views_of_a_plane();
        for read in [Read::Nearest, Read::Bilinear] {
            let (fused, other) = fuse_owner(&targets, &geoms, read);
            assert!(other > 0.2 && other < 0.9, "{other}");
            let w = 32usize;
            for (i, g) in geoms.iter().enumerate() {
                for (p, x) in g.points.iter().enumerate() {
                    let x = x.unwrap();
                    // the owner: the camera whose centre (cx, 0, 5) is nearest, all see the plane
                    let owner = [-0.3f32, 0.0, 0.3].iter().enumerate().min_by(|a, b| (a.1 - x[0]).abs().total_cmp(&(b.1 - x[0]).abs())).unwrap().0;
                    let got = &fused[i].data[p * 3..p * 3 + 3];
                    if owner == i {
                        assert_eq!(got, &targets[i].data[p * 3..p * 3 + 3], "view {i} pixel {p} is its own");
                    } else if let Some(want) = geoms[owner].sample_visible(&targets[owner], x, read) {
                        for c in 0..3 {
                            assert!((got[c] - want[c]).abs() < 1e-6, "view {i} pixel {p}: {got:?} vs owner {owner}'s {want:?}");
                        }
                    }
                }
            }
            // the stripe the middle view painted under its own camera stays in its target
            let p = 16 * w + 16;
            assert_eq!(&fused[1].data[p * 3..p * 3 + 3], &[1.0, 0.0, 0.0]);
        }
    }

    /// A camera between the views sees every surface point in the colour its owner painted
    /// there, the middle view's stripe included; a pixel with no surface, or with a point no
    /// view sees, keeps the colour it had.
    #[test]
    fn carried_frames_show_each_point_in_its_owners_colour() {
        let (geoms, targets) = three_views_of_a_plane();
        let (w, h) = (32usize, 32usize);
        let cx = -0.12f32;
        let mut points: Vec<Option<Vec3>> = (0..w * h)
            .map(|p| {
                let (x, y) = ((p % w) as f32 + 0.5 - 16.0, (p / w) as f32 + 0.5 - 16.0);
                Some([cx + 5.0 * x / 40.0, -5.0 * y / 40.0, 0.0])
            })
            .collect();
        points[0] = None;
        points[1] = Some([100.0, 0.0, 0.0]);
        let base = Image { width: w, height: h, data: vec![0.25; w * h * 3] };
        for read in [Read::Nearest, Read::Bilinear] {
            let mut frames = vec![base.clone()];
            carry_to(&mut frames, &[points.clone()], &targets, &geoms, read);
            let got = |p: usize| &frames[0].data[p * 3..p * 3 + 3];
            assert_eq!(got(0), &[0.25; 3], "no surface: unchanged");
            assert_eq!(got(1), &[0.25; 3], "a point no view sees: unchanged");
            let mut stripe = 0;
            for (p, x) in points.iter().enumerate().skip(2) {
                let x = x.unwrap();
                let owner = [-0.3f32, 0.0, 0.3].iter().enumerate().min_by(|a, b| (a.1 - x[0]).abs().total_cmp(&(b.1 - x[0]).abs())).unwrap().0;
                let want = geoms[owner].sample_visible(&targets[owner], x, read).expect("every view sees the plane");
                assert_eq!(got(p), &want, "{read:?}: pixel {p}, owner {owner}");
                stripe += (got(p) == [1.0, 0.0, 0.0]) as usize;
            }
            assert!(stripe > 10, "{read:?}: the middle view's stripe shows on {stripe} pixels");
        }
    }
}
