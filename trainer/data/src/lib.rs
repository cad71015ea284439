//! Posed images in: `transforms.json` (Blender / nerfstudio), LLFF `poses_bounds.npy`, COLMAP
//! sparse models. Every loader produces the same [`Dataset`]: cameras in the OpenGL convention
//! (camera-to-world, x right, y up, looking down -z), images as 8-bit RGBA, optional time.
//! The scene kind is detected from the poses (see `detect`) unless the caller overrides it.

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
#[derive(Clone, Debug)]
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
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SceneKind {
    /// A bounded object seen from around it: a box, no contraction.
    Object,
    /// Forward-facing capture (LLFF): normalized device coordinates.
    Forward,
    /// Unbounded 360 degree capture: contraction of far space into a bounded box.
    Unbounded,
}

/// Overrides for what `load` would otherwise detect.
#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    pub kind: Option<SceneKind>,
    /// Some(false) forces a static field even if frames carry times.
    pub dynamic: Option<bool>,
    /// For formats without splits (LLFF, COLMAP): every n-th image is a test view (default 8).
    pub holdout_every: Option<usize>,
    /// Integer image downscale factor (LLFF `images_N` folders are used when present).
    pub downscale: Option<u32>,
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
}
