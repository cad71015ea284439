//! snerf-data: posed multi-view datasets in. Reads `transforms.json` (Blender / nerfstudio),
//! LLFF `poses_bounds.npy` and COLMAP sparse models (text and binary) into one [`Dataset`]:
//! cameras in the OpenGL convention (camera-to-world, x right, y up, looking down -z), images as
//! 8-bit RGBA, optional per-frame time. Data flow: `source` finds which format a path holds, the
//! format module (`transforms`, `llff`, `colmap`) parses poses and intrinsics into pending views,
//! `images` decodes the PNG/JPEG/WebP files in parallel and reduces them to training size, and `detect` decides the scene kind
//! (object / forward / unbounded) and whether the scene is dynamic, unless the caller overrides it.

pub mod backdrop;
pub mod capture;
mod colmap;
mod colmap_points;
pub mod detect;
mod images;
mod llff;
mod npy;
mod pose;
mod source;
mod sparse;
mod summary;
mod transforms;

pub use detect::{detect_kind, max_view_angle_deg, transparent_fraction};
pub use images::{default_cache_dir, CACHE_MIN_PIXELS, DEFAULT_MAX_SIZE};
pub use sparse::{sparse_tracks, SparseTracks, TrackedPoint};
pub use summary::summary;

use std::path::Path;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// Pinhole intrinsics in pixels plus OpenCV radial/tangential distortion (k1 k2 p1 p2).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    /// k1, k2, p1, p2; all zero means no distortion.
    pub distortion: [f32; 4],
}

/// One posed image.
#[derive(Clone)]
pub struct View {
    /// The image file this view was read from (for error messages and outputs).
    pub path: PathBuf,
    pub intrinsics: Intrinsics,
    /// Camera-to-world, rows of a 3x4 matrix, OpenGL convention.
    pub c2w: [[f32; 4]; 3],
    /// Time in [0,1] for dynamic scenes.
    pub time: Option<f32>,
    /// Row-major RGBA8, `width * height * 4` bytes; alpha 255 when the file has none.
    pub rgba: Vec<u8>,
}

/// What kind of space the scene occupies; decides the field's parametrization.
pub use snerf_geometry::SceneKind;

/// Overrides for what `load` would otherwise detect.
#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    pub kind: Option<SceneKind>,
    /// Some(false) forces a static field even if frames carry times.
    pub dynamic: Option<bool>,
    /// For formats without splits (LLFF, COLMAP, a single transforms.json): every n-th image
    /// (indices 0, n, 2n, ...) is a test view (default 8); `Some(0)` holds nothing out.
    pub holdout_every: Option<usize>,
    /// Integer image downscale factor, a box filter (LLFF/COLMAP `images_N` folders are used
    /// when present).
    pub downscale: Option<u32>,
    /// Cap on the longer image side in pixels after `downscale`; larger images are resized at
    /// load (see the `images` module). `None` is [`DEFAULT_MAX_SIZE`], `Some(0)` no cap.
    pub max_size: Option<u32>,
    /// Where reduced images are cached; `None` is [`default_cache_dir`].
    pub cache_dir: Option<PathBuf>,
}

#[derive(Clone, Debug)]
pub struct Dataset {
    pub root: PathBuf,
    /// "blender", "nerfstudio", "llff" or "colmap".
    pub format: String,
    pub train: Vec<View>,
    pub val: Vec<View>,
    pub test: Vec<View>,
    pub kind: SceneKind,
    pub dynamic: bool,
    /// Near/far depth bounds when the format has them (LLFF), in world units.
    pub near_far: Option<(f32, f32)>,
    /// Axis-aligned box of interest in world units when the data says so
    /// (`aabb` key in transforms.json, a snerf extension).
    pub aabb: Option<([f32; 3], [f32; 3])>,
    /// Why `kind` and `dynamic` have their values (override, file hint or detection measures),
    /// for the CLI to print.
    pub detection_note: String,
    /// The file the poses were read from (transforms.json, images.bin, poses_bounds.npy):
    /// a COLMAP model's sparse points are read beside it, from the same reconstruction.
    pub pose_file: PathBuf,
}

impl Intrinsics {
    /// The intrinsics after an integer box-filter downscale by `s` (image cropped to a multiple
    /// of `s` first).
    pub fn downscaled(&self, s: u32) -> Intrinsics {
        let sf = s.max(1) as f32;
        Intrinsics {
            width: self.width / s.max(1),
            height: self.height / s.max(1),
            fx: self.fx / sf,
            fy: self.fy / sf,
            cx: self.cx / sf,
            cy: self.cy / sf,
            distortion: self.distortion,
        }
    }
}

impl Intrinsics {
    /// The intrinsics after resizing the whole image to `w x h` (each axis scales by its own
    /// exact ratio, so rounding the size to whole pixels does not shift the principal point).
    pub fn resized(&self, w: u32, h: u32) -> Intrinsics {
        let sx = w as f32 / self.width.max(1) as f32;
        let sy = h as f32 / self.height.max(1) as f32;
        Intrinsics {
            width: w,
            height: h,
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: self.cx * sx,
            cy: self.cy * sy,
            distortion: self.distortion,
        }
    }
}

impl std::fmt::Debug for View {
    /// Like a derived Debug, but the pixels are summarised by their byte count.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("View")
            .field("path", &self.path)
            .field("intrinsics", &self.intrinsics)
            .field("c2w", &self.c2w)
            .field("time", &self.time)
            .field("rgba", &format_args!("[{} bytes]", self.rgba.len()))
            .finish()
    }
}

impl View {
    /// Camera centre in world space.
    pub fn origin(&self) -> [f32; 3] {
        [self.c2w[0][3], self.c2w[1][3], self.c2w[2][3]]
    }

    /// Unit viewing direction in world space (the camera's -z axis).
    pub fn forward(&self) -> [f32; 3] {
        [-self.c2w[0][2], -self.c2w[1][2], -self.c2w[2][2]]
    }
}

impl Dataset {
    /// All views: train, then val, then test.
    pub fn all_views(&self) -> impl Iterator<Item = &View> {
        self.train
            .iter()
            .chain(self.val.iter())
            .chain(self.test.iter())
    }

    /// (min, max) of the per-frame times, if any frame has one.
    pub fn time_range(&self) -> Option<(f32, f32)> {
        let mut r: Option<(f32, f32)> = None;
        for t in self.all_views().filter_map(|v| v.time) {
            r = Some(match r {
                None => (t, t),
                Some((a, b)) => (a.min(t), b.max(t)),
            });
        }
        r
    }
}

/// Loads a dataset from a directory or a file (`transforms*.json`, `poses_bounds.npy`, or a
/// COLMAP `cameras`/`images` file), detecting the format; see the crate docs.
pub fn load(path: &Path, opts: &LoadOptions) -> anyhow::Result<Dataset> {
    let src = source::locate(path)?;
    let raw = match &src {
        source::Source::Transforms { files } => transforms::load(files, opts)?,
        source::Source::Llff { dir } => llff::load(dir, opts)?,
        source::Source::Colmap { model_dir } => colmap::load(model_dir, opts)?,
    };
    let mut raw = raw;
    let keyed = key_backdrop(&mut raw, opts)?;
    detect::finish(raw, opts, keyed)
}

/// Keys a plain backdrop out of every view when the dataset's folder holds
/// [`backdrop::FILE`] (written by `snerf capture`) and the caller did not ask for a kind other
/// than object; returns the note for the detection.
fn key_backdrop(raw: &mut RawDataset, opts: &LoadOptions) -> anyhow::Result<Option<String>> {
    use anyhow::Context;
    use rayon::prelude::*;
    let file = raw.root.join(backdrop::FILE);
    if !file.is_file() || opts.kind.is_some_and(|k| k != SceneKind::Object) {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&file).with_context(|| format!("{}: cannot read", file.display()))?;
    let b: backdrop::Backdrop = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a backdrop description (colour, tolerance, ...)", file.display()))?;
    raw.train
        .par_iter_mut()
        .chain(raw.val.par_iter_mut())
        .chain(raw.test.par_iter_mut())
        .for_each(|v| {
            let (w, h) = (v.intrinsics.width as usize, v.intrinsics.height as usize);
            backdrop::key(&mut v.rgba, w, h, b.colour, b.tolerance);
        });
    if raw.aabb.is_none() {
        raw.aabb = b.aabb;
    }
    Ok(Some(format!(
        "{} ({}; `snerf capture --no-backdrop` or deleting the file keeps the photos opaque)",
        b.describe(),
        file.display()
    )))
}

/// What a format loader hands to `detect::finish`.
pub(crate) struct RawDataset {
    pub root: std::path::PathBuf,
    pub format: String,
    pub train: Vec<View>,
    pub val: Vec<View>,
    pub test: Vec<View>,
    /// The file that holds the poses (for messages).
    pub pose_file: std::path::PathBuf,
    pub kind_hint: Option<SceneKind>,
    pub near_far: Option<(f32, f32)>,
    pub aabb: Option<([f32; 3], [f32; 3])>,
}

/// Indices `0, n, 2n, ...` are test (the LLFF protocol); `n == 0` holds nothing out; fewer than
/// two frames are all train.
pub(crate) fn holdout_split<T>(items: Vec<T>, opts: &LoadOptions) -> (Vec<T>, Vec<T>) {
    let n = opts.holdout_every.unwrap_or(8);
    if n == 0 || items.len() < 2 {
        return (items, Vec::new());
    }
    let mut train = Vec::new();
    let mut test = Vec::new();
    for (i, it) in items.into_iter().enumerate() {
        if i % n == 0 {
            test.push(it);
        } else {
            train.push(it);
        }
    }
    (train, test)
}
