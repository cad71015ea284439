//! Cross-view consistency as the SNeRF paper measures it (Sec. 5, Tables 1–2): render a novel
//! camera path; for frame pairs (i, i+1) (short range) and (i, i+7) (long range) warp
//! stylized frame i into frame j with the correspondence obtained by reprojecting the
//! *realistic* field's depth, drop occluded and uncovered pixels, and report the mean squared
//! RGB error (colours in [0,1]) over what is left. Frame i is read only where its pixels
//! show the same surface (`reproject`): a warp that interpolated across a silhouette would
//! charge the stylization with the background's colour. The same geometry scores every
//! method, so the numbers compare stylizations, not depth estimates.
//!
//! Only pixels at least a pixel from the silhouette take part, in both frames (`WARP_PIXELS`):
//! the pixel and its eight neighbours show the scene (realistic opacity above `COVERED`).
//! Those are the pixels the surface covers wholly on a trained field, and the rule asks no
//! opacity to reach 1 (a translucent or under-trained surface still has them). A silhouette
//! pixel is part background, in a share that changes from view to view with the sub-pixel
//! position of the edge, so its error measures how the edge is antialiased against the
//! background, the same for every stylization. On a dark object in front of the white
//! background those pixels carried most of the error: the unstylized field's own error on
//! them was above per-frame stylization's (microsoft-mixed-reality × spring: 0.0193 against
//! 0.0130; docs/stylize-notebook.md §5s), and they held 58–84% of the field's error, so they set a floor on
//! SNeRF ÷ per-frame that no stylization could go below.
//!
//! Consistency alone can be bought by washing the style out, so style distances come with
//! it (`StyleMeters`): the weight-free `style_metric` (the painting's palette covered by the
//! scene's pixels, and their texture statistics against the painting's; no stylizer aims at
//! it), and, when the model is
//! installed, `style_gram` (Gram matrices of ImageNet features, independent of every stylizer
//! but `gatys`) and the distance between Magenta style embeddings of the frames and of the
//! style image (the space `arbitrary` aims at).
//!
//! `PathGeometry::carried` shows the same path as a field that held its training targets
//! exactly would (each surface point the colour its owner view gives it in the targets, read
//! by copying a pixel or bilinearly): what the targets allow, so a gap can be put on the
//! targets or on the field's fit of them (docs/stylize-notebook.md §5t).

use anyhow::Result;
use serde::Serialize;
use snerf_data::{Dataset, Intrinsics};
use snerf_geometry::silhouette::min_max_3x3;
use snerf_geometry::camera::Orbit;
use snerf_geometry::camera_path::PathCamera;
use snerf_trainer::eval::{eval_background, render_camera};
use snerf_trainer::render::WorkspacePool;
use snerf_trainer::space::Vec3;
use snerf_trainer::train::{views_have_alpha, Model};

use crate::fusion::{self, Read, ViewGeometry};
use crate::reproject::{Seen, COVERED};
use crate::style_gram::{self, GramMetric, Grams};
use crate::style_metric::{self, StyleReference, StyleSamples, StyleScore};
use crate::stylizer::{Image, StyleEmbedder, Stylizer, StylizerOptions};

/// Cameras per full circle of the novel path: 5° apart on an orbit, so (i, i+1) is a small
/// motion and (i, i+7) a large one, as in the paper's test trajectories.
pub const PATH_STEPS_PER_TURN: usize = 72;

/// Frames of the style ring: the style distances pool frames evenly spaced around the whole
/// orbit (45° apart, half a step off the path's cameras), not frames of the path. A path of
/// 12–24 frames spans only 55–115° of the orbit, so its frames show one side of an object,
/// and on a thin one the style of that side moves with every round by more than the rounds
/// change the whole (hp-mixed-reality × Kandinsky: round 5 ÷ round 1 = 1.046 pooled over a
/// 16-frame path, 0.999 over a 48-frame one; docs/stylize-notebook.md §5l).
pub const STYLE_RING: usize = 8;

/// Which pixels the warp errors score, as `snerf consistency` records it (`warp_pixels`):
/// records scored before the rule (silhouette pixels included) do not carry it.
pub const WARP_PIXELS: &str = "off the silhouette";

/// The novel path and the realistic field's geometry along it, followed by the style ring.
/// Every per-frame list (`realistic`, `render`'s output, the frames callers pass back in)
/// holds the path's frames first, then the ring's `STYLE_RING`: warp errors use the path,
/// style distances the ring.
pub struct PathGeometry {
    /// Frames of the path (the rest of `cams` is the style ring).
    pub path_frames: usize,
    pub cams: Vec<[[f32; 4]; 3]>,
    pub intr: Intrinsics,
    pub time: Option<f32>,
    pub bg: Vec3,
    /// Realistic renders of the path and the ring (the per-frame baseline stylizes these).
    pub realistic: Vec<Image>,
    /// World point seen at each pixel (None where the scene does not cover the pixel).
    points: Vec<Vec<Option<Vec3>>>,
    /// `points` at least a pixel from the silhouette (None elsewhere): the pixels the warp
    /// errors score and read.
    surface: Vec<Vec<Option<Vec3>>>,
    /// The realistic field's opacity per pixel.
    opacity: Vec<Vec<f32>>,
    /// Whether the training views have a silhouette (alpha): a bounded object.
    silhouette: bool,
    /// Which frames these are, as records and reports name them.
    pub description: String,
}

impl PathGeometry {
    /// The loop's own path (its per-round measurement): `frames` cameras 5° apart on the
    /// preview orbit, and the style ring around it.
    pub fn new(realistic: &Model, pool: &WorkspacePool, data: &Dataset, frames: usize) -> Result<PathGeometry> {
        Self::new_with_progress(realistic, pool, data, frames, &mut |_, _| {})
    }

    /// [`PathGeometry::new`], calling `frame_done(done, total)` after each camera it renders
    /// (a forward-facing capture at full size takes minutes: the command line draws a bar).
    pub fn new_with_progress(
        realistic: &Model,
        pool: &WorkspacePool,
        data: &Dataset,
        frames: usize,
        frame_done: &mut dyn FnMut(usize, usize),
    ) -> Result<PathGeometry> {
        anyhow::ensure!(frames >= 2, "a consistency path needs at least 2 frames");
        let orbit = preview(&realistic.space, data);
        let what = format!("the loop's path: {frames} frames 5° apart on the preview orbit, and {STYLE_RING} style frames 45° apart around it");
        Self::on_orbit(realistic, pool, data, &orbit, frames, what, frame_done)
    }

    /// The evaluation path `snerf consistency` scores by default: as `new`, on an orbit at
    /// another elevation and radius ([`evaluation_orbit`]), so it shares no frame with the
    /// loop's per-round measurement.
    pub fn evaluation(realistic: &Model, pool: &WorkspacePool, data: &Dataset, frames: usize) -> Result<PathGeometry> {
        anyhow::ensure!(frames >= 2, "a consistency path needs at least 2 frames");
        let (orbit, change) = evaluation_orbit(&preview(&realistic.space, data));
        let what = format!(
            "the evaluation path: {frames} frames 5° apart on an orbit {change} than the loop's (no frame shared with its per-round measurement), and {STYLE_RING} style frames 45° apart around it"
        );
        Self::on_orbit(realistic, pool, data, &orbit, frames, what, &mut |_, _| {})
    }

    /// A path of the user's (nerfstudio `camera_path.json`, read with
    /// `snerf_geometry::camera_path::parse`): every camera a path frame, and the style frames
    /// 8 of them evenly spaced. The cameras must share one image size.
    pub fn from_cameras(realistic: &Model, pool: &WorkspacePool, data: &Dataset, cams: &[PathCamera], name: &str) -> Result<PathGeometry> {
        anyhow::ensure!(cams.len() >= 2, "{name}: a consistency path needs at least 2 cameras, not {}", cams.len());
        let first = cams[0].cam;
        if let Some((i, c)) = cams.iter().enumerate().find(|(_, c)| (c.cam.width, c.cam.height) != (first.width, first.height)) {
            anyhow::bail!("{name}: camera {i} is {}x{}, camera 0 {}x{}; the warp errors need one image size", c.cam.width, c.cam.height, first.width, first.height);
        }
        let mut intr = data.test.first().unwrap_or(&data.train[0]).intrinsics;
        (intr.fx, intr.fy, intr.cx, intr.cy, intr.width, intr.height) = (first.fx, first.fy, first.cx, first.cy, first.width, first.height);
        intr.distortion = [0.0; 4];
        let n = cams.len();
        let ring: Vec<usize> = (0..STYLE_RING.min(n)).map(|k| k * n / STYLE_RING.min(n)).collect();
        let mut c2w: Vec<_> = cams.iter().map(|c| c.cam.c2w).collect();
        c2w.extend(ring.iter().map(|&k| cams[k].cam.c2w));
        let time = cams[0].time.or(data.dynamic.then_some(0.5));
        let what = format!("camera path {name}: {n} frames, style scored on {} of them evenly spaced", ring.len());
        Self::with_cameras(realistic, pool, data, c2w, n, intr, time, what, &mut |_, _| {})
    }

    fn on_orbit(
        realistic: &Model,
        pool: &WorkspacePool,
        data: &Dataset,
        orbit: &Orbit,
        frames: usize,
        what: String,
        frame_done: &mut dyn FnMut(usize, usize),
    ) -> Result<PathGeometry> {
        let turn = PATH_STEPS_PER_TURN.max(frames);
        let mut cams: Vec<_> = orbit.path(turn).into_iter().take(frames).collect();
        cams.extend(orbit.path(2 * STYLE_RING).into_iter().skip(1).step_by(2));
        let mut intr = data.test.first().unwrap_or(&data.train[0]).intrinsics;
        intr.distortion = [0.0; 4];
        // Dynamic scenes: the path holds time still (mid-sequence), so reprojection is exact.
        let time = data.dynamic.then_some(0.5);
        Self::with_cameras(realistic, pool, data, cams, frames, intr, time, what, frame_done)
    }

    /// The realistic field's renders and geometry at `cams` (the first `frames` the path,
    /// the rest the style frames).
    #[allow(clippy::too_many_arguments)]
    fn with_cameras(
        realistic: &Model,
        pool: &WorkspacePool,
        data: &Dataset,
        cams: Vec<[[f32; 4]; 3]>,
        frames: usize,
        intr: Intrinsics,
        time: Option<f32>,
        description: String,
        frame_done: &mut dyn FnMut(usize, usize),
    ) -> Result<PathGeometry> {
        let silhouette = views_have_alpha(&data.train);
        let bg = eval_background(silhouette);
        let mut images = Vec::with_capacity(cams.len());
        let mut points = Vec::with_capacity(cams.len());
        let mut opacity = Vec::with_capacity(cams.len());
        for c2w in &cams {
            let r = render_camera(realistic, pool, c2w, &intr, time, bg);
            points.push(surface_points(realistic, c2w, &intr, time, &r));
            images.push(Image { width: r.width, height: r.height, data: r.rgb });
            opacity.push(r.opacity);
            frame_done(images.len(), cams.len());
        }
        let surface = off_silhouette(&points, &opacity, intr.width as usize, intr.height as usize);
        Ok(PathGeometry { path_frames: frames, cams, intr, time, bg, realistic: images, points, surface, opacity, silhouette, description })
    }

    /// Whether the scene is a bounded object with a silhouette in its training views.
    pub fn has_silhouette(&self) -> bool {
        self.silhouette
    }

    /// Render the path and the ring from another (e.g. stylized) model.
    pub fn render(&self, model: &Model, pool: &WorkspacePool) -> Vec<Image> {
        self.cams
            .iter()
            .map(|c2w| {
                let r = render_camera(model, pool, c2w, &self.intr, self.time, self.bg);
                Image { width: r.width, height: r.height, data: r.rgb }
            })
            .collect()
    }

    /// The path and the ring as a field that held `targets` (images of the training views
    /// `geoms`) exactly would show them (`fusion::carry_to`); pixels whose point no view
    /// sees keep `base`'s colour.
    pub fn carried(&self, base: &[Image], targets: &[Image], geoms: &[ViewGeometry], read: Read) -> Vec<Image> {
        let mut frames = base.to_vec();
        fusion::carry_to(&mut frames, &self.points, targets, geoms, read);
        frames
    }

    /// Project a world point into camera `i`: continuous pixel coordinates (pixel x spans
    /// [x, x+1)) and the distance from the camera centre; None behind the camera.
    fn project(&self, i: usize, p: Vec3) -> Option<(f32, f32, f32)> {
        let k = &self.intr;
        snerf_geometry::camera::project(&self.cams[i], k.fx, k.fy, k.cx, k.cy, p)
    }


    /// Mean squared error between path frame j = i + gap and path frame i warped into it,
    /// over all pairs and all non-occluded pixels off the silhouette (read from frame i's pixels
    /// off the silhouette). NaN if no pixel qualifies.
    pub fn warp_error(&self, frames: &[Image], gap: usize) -> f64 {
        let (w, h) = (self.intr.width as usize, self.intr.height as usize);
        let (mut sum, mut count) = (0.0f64, 0u64);
        for i in 0..frames.len().min(self.path_frames).saturating_sub(gap) {
            let j = i + gap;
            let seen = Seen { origin: [self.cams[i][0][3], self.cams[i][1][3], self.cams[i][2][3]], width: w, height: h, points: &self.surface[i] };
            for (p, pt) in self.surface[j].iter().enumerate() {
                let Some(x) = pt else { continue };
                let Some((u, v, dist)) = self.project(i, *x) else { continue };
                // frame i's colour at the point, from its pixels that show that surface
                let Some(warped) = seen.colour(&frames[i], u, v, dist) else { continue };
                let target = &frames[j].data[p * 3..p * 3 + 3];
                sum += (0..3).map(|c| ((warped[c] - target[c]) as f64).powi(2)).sum::<f64>() / 3.0;
                count += 1;
            }
        }
        if count == 0 {
            f64::NAN
        } else {
            sum / count as f64
        }
    }

    /// Frames composited over the background with the realistic field's opacity: what the
    /// scene looks like, without whatever a per-frame stylizer painted into empty space, so
    /// style distances compare the scene's stylization alone.
    pub fn masked(&self, frames: &[Image]) -> Vec<Image> {
        self.composite(frames, &self.opacity)
    }

    /// `frames` composited over the background with `opacity` (one per frame).
    fn composite(&self, frames: &[Image], opacity: &[Vec<f32>]) -> Vec<Image> {
        frames
            .iter()
            .zip(opacity)
            .map(|(f, op)| {
                let mut data = f.data.clone();
                for (p, &a) in op.iter().enumerate() {
                    for c in 0..3 {
                        data[p * 3 + c] = f.data[p * 3 + c] * a + self.bg[c] * (1.0 - a);
                    }
                }
                Image { width: f.width, height: f.height, data }
            })
            .collect()
    }

    /// Scene pixels of each frame: the realistic field's opacity above `COVERED`.
    pub fn masks(&self) -> Vec<Vec<bool>> {
        scene_masks(&self.opacity)
    }

    /// The per-frame baseline: the realistic frames from `first` on, each stylized on its own
    /// (in the object's box, the realistic silhouette's, when `by_box`), at `res` as the loop
    /// paints its views; the frames before `first` stay realistic.
    pub fn stylize_frames(&self, stylizer: &dyn Stylizer, by_box: bool, res: usize, first: usize) -> Result<Vec<Image>> {
        let masks = self.masks();
        let mut out = self.realistic.clone();
        for (k, frame) in out.iter_mut().enumerate().skip(first) {
            let mask = by_box.then_some(masks[k].as_slice());
            *frame = crate::stylize_view::stylize_region(stylizer, &self.realistic[k], mask, res)?;
        }
        Ok(out)
    }

    /// The ring's frames of a per-frame list (those after the path's).
    pub fn ring_part<'a>(&self, frames: &'a [Image]) -> &'a [Image] {
        &frames[self.path_frames.min(frames.len())..]
    }

    /// The ring's realistic opacity, one per ring frame.
    fn ring_opacity(&self) -> &[Vec<f32>] {
        &self.opacity[self.path_frames..]
    }

    /// The ring's scene masks: which of its pixels every style distance pools.
    fn ring_masks(&self) -> Vec<Vec<bool>> {
        scene_masks(self.ring_opacity())
    }

    /// The ring's frames of `frames` composited on their own opacity (as `masked`).
    fn ring_masked(&self, frames: &[Image]) -> Vec<Image> {
        self.composite(self.ring_part(frames), self.ring_opacity())
    }

    /// The weight-free style distance of `frames` (the ring's scene pixels, pooled) to the
    /// style picture's samples (`style_metric::reference`).
    pub fn style_score(&self, frames: &[Image], style: &StyleReference) -> StyleScore {
        let masks = self.ring_masks();
        style_metric::distance(&StyleSamples::of(&with_masks(self.ring_part(frames), &masks)), style)
    }

    /// The Gram style distance of the same frames and masks (`style_gram`), the frames
    /// composited on the scene's own opacity first: a feature's receptive field reaches past
    /// the mask, and paint a per-frame stylizer puts into empty space must not count.
    pub fn style_gram(&self, frames: &[Image], metric: &GramMetric, style: &Grams) -> Result<f64> {
        let (ring, masks) = (self.ring_masked(frames), self.ring_masks());
        Ok(style_gram::distance(&metric.grams(&with_masks(&ring, &masks))?, style))
    }

    /// The style picture's samples and units at this path's pixel footprint.
    pub fn style_reference(&self, style: &Image) -> StyleReference {
        style_metric::reference(style, self.intr.width as usize, self.intr.height as usize)
    }

    /// Fraction of the path's pixels that show the scene (for the report).
    pub fn coverage(&self) -> f64 {
        let path = &self.points[..self.path_frames];
        let covered: usize = path.iter().map(|f| f.iter().filter(|p| p.is_some()).count()).sum();
        covered as f64 / path.iter().map(|f| f.len()).sum::<usize>().max(1) as f64
    }
}

/// The capture's preview orbit (the one turntables and the viewer start on).
pub(crate) fn preview(space: &snerf_trainer::space::SceneSpace, data: &Dataset) -> Orbit {
    space.orbit.unwrap_or_else(|| {
        let refs: Vec<&snerf_data::View> = data.train.iter().collect();
        snerf_trainer::orbit::preview_orbit(space.kind, &space.frame, &refs, None)
    })
}

/// The evaluation orbit: around an object, 15° higher (lower when the preview orbit is above
/// 45°), 1.15× the radius, and turned by half a path step; a forward-facing capture's ellipse
/// at 0.6× its radii, 1.15× as far from the target. Returns it with how it differs, in words.
pub fn evaluation_orbit(o: &Orbit) -> (Orbit, String) {
    match *o {
        Orbit::Around { center, up, start, radius, elevation } => {
            let turn = std::f32::consts::PI / PATH_STEPS_PER_TURN as f32;
            let side = snerf_geometry::vec::cross(up, start);
            let start = [0, 1, 2].map(|c| start[c] * turn.cos() + side[c] * turn.sin());
            let de = if elevation > 45f32.to_radians() { -15f32 } else { 15.0 };
            let around = Orbit::Around { center, up, start, radius: radius * 1.15, elevation: elevation + de.to_radians() };
            (around, format!("{} by 15° and 1.15× as far", if de > 0.0 { "higher" } else { "lower" }))
        }
        Orbit::Ellipse { center, right, up, target, rx, ry } => {
            let center = [0, 1, 2].map(|c| target[c] + (center[c] - target[c]) * 1.15);
            (Orbit::Ellipse { center, right, up, target, rx: rx * 0.6, ry: ry * 0.6 }, "with 0.6× the radii and 1.15× as far".into())
        }
    }
}

/// The world point seen at each pixel of a render (None where the scene does not cover it).
fn surface_points(model: &Model, c2w: &[[f32; 4]; 3], intr: &Intrinsics, time: Option<f32>, r: &snerf_trainer::eval::Rendered) -> Vec<Option<Vec3>> {
    let w = r.width;
    let mut pts = vec![None; w * r.height];
    for (p, slot) in pts.iter_mut().enumerate() {
        if r.opacity[p] <= COVERED {
            continue;
        }
        let (x, y) = (p % w, p / w);
        if let Some(ray) = model.space.ray(c2w, intr, x as f32 + 0.5, y as f32 + 0.5, time) {
            let wp = model.space.march_to_world(&ray, r.depth[p]);
            if wp.iter().all(|v| v.is_finite()) {
                *slot = Some(wp);
            }
        }
    }
    pts
}

/// The points of pixels at least a pixel from the silhouette: the pixel and its eight
/// neighbours show the scene (opacity above `COVERED`); the rest None.
fn off_silhouette(points: &[Vec<Option<Vec3>>], opacity: &[Vec<f32>], w: usize, h: usize) -> Vec<Vec<Option<Vec3>>> {
    points
        .iter()
        .zip(opacity)
        .map(|(pts, op)| {
            (0..pts.len())
                .map(|p| {
                    let (lo, _) = min_max_3x3(w, h, p % w, p / w, |i| op[i]);
                    pts[p].filter(|_| lo > COVERED)
                })
                .collect()
        })
        .collect()
}

/// Scene pixels per frame: opacity above `COVERED`.
fn scene_masks(opacity: &[Vec<f32>]) -> Vec<Vec<bool>> {
    opacity.iter().map(|op| op.iter().map(|&a| a > COVERED).collect()).collect()
}

/// Frames paired with their masks, as the style distances take them.
fn with_masks<'a>(frames: &'a [Image], masks: &'a [Vec<bool>]) -> Vec<(&'a Image, Option<&'a [bool]>)> {
    frames.iter().zip(masks).map(|(f, m)| (f, Some(m.as_slice()))).collect()
}

pub fn embedding_distance(a: &[f32], b: &[f32]) -> f64 {
    a.iter().zip(b).map(|(x, y)| ((x - y) as f64).powi(2)).sum::<f64>().sqrt()
}

/// Mean style distance of up to 4 evenly spaced frames.
pub fn style_distance_frames(embedder: &StyleEmbedder, frames: &[Image], style_embedding: &[f32]) -> Result<f64> {
    let n = frames.len().min(4);
    let mut sum = 0.0;
    for k in 0..n {
        let f = &frames[k * frames.len() / n];
        sum += embedding_distance(&embedder.embed(f)?, style_embedding);
    }
    Ok(sum / n.max(1) as f64)
}

/// The networks the style distances need, each present when its model is installed (the
/// weight-free distance needs none).
#[derive(Clone, Default)]
pub struct StyleMeters {
    pub embedder: Option<StyleEmbedder>,
    pub gram: Option<GramMetric>,
}

/// The style picture, prepared once for every style distance at a path's footprint.
pub struct StyleTargets {
    embedding: Option<Vec<f32>>,
    samples: StyleReference,
    grams: Option<Grams>,
}

/// One set of frames scored by every style distance.
#[derive(Clone, Copy, Debug)]
pub struct StyleScores {
    pub embedding: Option<f64>,
    pub swd: StyleScore,
    pub gram: Option<f64>,
}

impl StyleMeters {
    /// Opens whichever networks are installed (none is required).
    pub fn open(opts: &StylizerOptions) -> StyleMeters {
        StyleMeters { embedder: StyleEmbedder::new(opts).ok(), gram: GramMetric::open(opts).ok() }
    }

    pub fn targets(&self, path: &PathGeometry, style: &Image) -> Result<StyleTargets> {
        let (w, h) = (path.intr.width as usize, path.intr.height as usize);
        Ok(StyleTargets {
            embedding: self.embedder.as_ref().map(|e| e.embed(style)).transpose()?,
            samples: path.style_reference(style),
            grams: self.gram.as_ref().map(|g| g.reference(style, w, h)).transpose()?,
        })
    }

    /// Every style distance of `frames` (renders along `path`) to the style picture.
    pub fn score(&self, path: &PathGeometry, frames: &[Image], targets: &StyleTargets) -> Result<StyleScores> {
        Ok(StyleScores {
            embedding: self
                .embedder
                .as_ref()
                .zip(targets.embedding.as_deref())
                .map(|(e, s)| style_distance_frames(e, &path.ring_masked(frames), s))
                .transpose()?,
            swd: path.style_score(frames, &targets.samples),
            gram: self.gram.as_ref().zip(targets.grams.as_ref()).map(|(g, s)| path.style_gram(frames, g, s)).transpose()?,
        })
    }
}

/// The scores of one method.
#[derive(Clone, Debug, Serialize)]
pub struct MethodScores {
    pub method: String,
    pub short_range: f64,
    pub long_range: f64,
    /// Magenta style-embedding distance (None without the model).
    pub style_distance: Option<f64>,
    /// The weight-free style distance (`style_metric`): colour + texture.
    pub style_swd: StyleScore,
    /// The Gram style distance (`style_gram`; None without the model).
    pub style_gram: Option<f64>,
}

impl MethodScores {
    pub fn of(method: &str, path: &PathGeometry, frames: &[Image], meters: &StyleMeters, targets: &StyleTargets) -> Result<MethodScores> {
        let style = meters.score(path, frames, targets)?;
        Ok(MethodScores {
            method: method.to_string(),
            short_range: path.warp_error(frames, 1),
            long_range: path.warp_error(frames, 7),
            style_distance: style.embedding,
            style_swd: style.swd,
            style_gram: style.gram,
        })
    }
}

/// Markdown table in the layout of the paper's Tables 1 and 2.
pub fn markdown_table(methods: &[MethodScores]) -> String {
    let mut s = String::from(
        "| Method | Short-range error ↓ | Long-range error ↓ | Style distance (colour + texture) ↓ | Painting colours missed ↓ | Gram style distance ↓ | Embedding style distance ↓ |\n|---|---:|---:|---:|---:|---:|---:|\n",
    );
    for m in methods {
        s += &format!(
            "| {} | {:.5} | {:.5} | {:.4} ({:.4} + {:.4}) | {:.1}% | {} | {} |\n",
            m.method,
            m.short_range,
            m.long_range,
            m.style_swd.total,
            m.style_swd.color,
            m.style_swd.texture,
            100.0 * m.style_swd.missed,
            m.style_gram.map(|d| format!("{d:.4}")).unwrap_or_else(|| "n/a".into()),
            m.style_distance.map(|d| format!("{d:.3}")).unwrap_or_else(|| "n/a".into())
        );
    }
    s
}

/// Tile images into rows (each resized to the first image's size).
pub fn grid_image(rows: &[Vec<&Image>]) -> image::RgbImage {
    // tiles take the size of the largest image (a style picture may be tiny or huge)
    let (tw, th) = rows.iter().flatten().map(|i| (i.width, i.height)).max_by_key(|&(w, h)| w * h).unwrap_or((1, 1));
    let (tw, th) = if tw * th > 512 * 512 { (tw * 256 / tw.max(th), th * 256 / tw.max(th)) } else { (tw, th) };
    let cols = rows.iter().map(|r| r.len()).max().unwrap_or(1).max(1);
    let mut out = image::RgbImage::from_pixel((tw * cols) as u32, (th * rows.len().max(1)) as u32, image::Rgb([255, 255, 255]));
    for (ri, row) in rows.iter().enumerate() {
        for (ci, img) in row.iter().enumerate() {
            let tile = if img.width == tw && img.height == th {
                (*img).clone()
            } else {
                crate::stylize_view::resize(img, tw, th)
            };
            for y in 0..th {
                for x in 0..tw {
                    let p = &tile.data[(y * tw + x) * 3..(y * tw + x) * 3 + 3];
                    let px = image::Rgb(
                        [0, 1, 2].map(|c| (p[c].clamp(0.0, 1.0) * 255.0).round() as u8),
                    );
                    out.put_pixel((ci * tw + x) as u32, (ri * th + y) as u32, px);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two frames from one camera of a red surface over white: pixels 0 and 1 wholly covered,
    /// pixel 2 on the silhouette (covered 60% in frame 0, 90% in frame 1: the edge moved by a
    /// fraction of a pixel), pixel 3 background.
    fn edge_path() -> PathGeometry {
        let intr = Intrinsics { width: 4, height: 1, fx: 4.0, fy: 4.0, cx: 2.0, cy: 0.5, distortion: [0.0; 4] };
        let cam = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];
        let point = |x: usize| Some([(x as f32 + 0.5 - 2.0) / 4.0 * 5.0, 0.0, -5.0]);
        let points: Vec<Vec<Option<Vec3>>> = (0..2).map(|_| vec![point(0), point(1), point(2), None]).collect();
        let opacity = vec![vec![1.0, 1.0, 0.6, 0.0], vec![1.0, 1.0, 0.9, 0.0]];
        let realistic = opacity.iter().map(|op| edge_frame(op, [1.0, 0.0, 0.0])).collect();
        let surface = off_silhouette(&points, &opacity, intr.width as usize, intr.height as usize);
        PathGeometry { path_frames: 2, cams: vec![cam; 2], intr, time: None, bg: [1.0; 3], realistic, points, surface, opacity, silhouette: true, description: String::new() }
    }

    /// `colour` over white with each pixel's coverage.
    fn edge_frame(opacity: &[f32], colour: [f32; 3]) -> Image {
        Image { width: 4, height: 1, data: opacity.iter().flat_map(|&a| colour.map(|c| c * a + (1.0 - a))).collect() }
    }

    /// A surface of one colour is consistent whatever its silhouette pixels show; a colour
    /// that changes between the frames is not.
    #[test]
    fn warp_errors_score_only_pixels_off_the_silhouette() {
        let path = edge_path();
        assert_eq!(path.warp_error(&path.realistic, 1), 0.0, "the edge's sub-pixel motion is not an inconsistency");
        // what the rule removes: the silhouette pixel read across the two frames differs by
        // the change in coverage (0.3 of the white background in G and B)
        let (i, j) = (&path.realistic[0].data, &path.realistic[1].data);
        assert!((i[2 * 3 + 1] - j[2 * 3 + 1]).abs() > 0.29);
        let mut repainted = path.realistic.clone();
        repainted[1] = edge_frame(&path.opacity[1], [0.8, 0.0, 0.0]);
        let e = path.warp_error(&repainted, 1);
        assert!((e - 0.04 / 3.0).abs() < 1e-6, "{e}");
    }
}
