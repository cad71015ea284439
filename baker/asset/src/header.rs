//! The JSON header (`HEAD` chunk): everything a reader needs to size and interpret the rest
//! of the file, and the limits every header must pass *before* anything is allocated from it.

use anyhow::{bail, ensure, Result};
use serde::{Deserialize, Serialize};

/// The `format` field's only valid value (guards against feeding some other JSON file).
pub const FORMAT_NAME: &str = "snerf-asset";
/// Largest voxel resolution per axis a reader accepts.
pub const MAX_RES: u32 = 2048;
/// Block edge length limits (voxels, without apron).
pub const MIN_BLOCK: u32 = 4;
pub const MAX_BLOCK: u32 = 64;
/// Largest indirection grid (cells) per frame: 2^24 cells = 64 MiB of u32 entries.
pub const MAX_GRID_CELLS: u64 = 1 << 24;
/// Largest number of keyframes.
pub const MAX_FRAMES: usize = 4096;
/// Largest atlas a reader (or streaming client) will allocate, whatever the header says.
pub const MAX_ATLAS_BYTES: u64 = 4 << 30;
/// Smallest march step (grid units): bounds the samples per ray (2√3/step ≈ 35k).
pub const MIN_STEP: f32 = 1.0e-4;
/// |logit| bound so that exp(logit) stays finite in f32 (exp(88.7) overflows).
pub const MAX_ABS_LOGIT: f32 = 80.0;
/// Channels of a voxel in a `diffuse` file: density code and diffuse RGB.
pub const DIFFUSE_CHANNELS: usize = 4;

/// How march-space points map onto the grid (`snerf_geometry::space` has the formulas).
pub use snerf_geometry::SceneKind as Kind;
/// NDC of the forward-facing reference camera, and the world -> model similarity.
pub use snerf_geometry::{Ndc, Orbit, Space};

/// Density quantization range: code c in 0..=255 means logit = min + c/255 * (max - min).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct DensityRange {
    pub logit_min: f32,
    pub logit_max: f32,
}

/// Ray-march parameters the renderer (CPU and GPU) must use to match the trainer.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct March {
    /// Step length in grid units.
    pub step: f32,
    /// Stop a ray once its transmittance falls below this.
    pub t_terminate: f32,
}

/// Shape of the view MLP. Version 1 supports exactly 34 -> 16 -> 16 -> 3 with 4 octaves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct MlpShape {
    pub inputs: u32,
    pub hidden: u32,
    pub outputs: u32,
    pub octaves: u32,
}

impl Default for MlpShape {
    fn default() -> Self {
        MlpShape { inputs: 34, hidden: 16, outputs: 3, octaves: 4 }
    }
}

/// One keyframe of a dynamic asset.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Keyframe {
    pub time: f32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Header {
    pub format: String,
    pub kind: Kind,
    pub space: Space,
    pub res: u32,
    pub block: u32,
    pub atlas_blocks: u32,
    pub density: DensityRange,
    pub march: March,
    pub background: [f32; 3],
    pub view_mlp: MlpShape,
    /// Dynamic assets only; a static asset's JSON has no such key at all.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time_range: Option<[f32; 2]>,
    /// Dynamic assets only: keyframe times, sorted. Static assets have one implicit frame 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frames: Option<Vec<Keyframe>>,
    /// The scene's world up direction and its preview orbit, from the capture's cameras
    /// (`snerf_geometry::camera`): every client's start view, turntable and "upright" come
    /// from here. Assets written before it existed get [`Header::orbit`]'s fallback.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view: Option<Orbit>,
    /// Height of the scene's floor along the view's up direction (world units from the world
    /// origin), for clients that stand a person on it (headsets). Baked from the lowest
    /// occupied cells.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor: Option<f32>,
    /// Rays a silhouette pixel takes (`snerf_geometry::silhouette`: a pixel whose 3x3
    /// neighbourhood of rendered opacity is partly covered is drawn as the mean of this many
    /// rays on a sub-pixel grid), as the field was trained: 4 for static objects, 1 (one ray
    /// through every pixel's centre; the key is then left out) for other scenes and for
    /// assets written before the rule.
    #[serde(default = "one_ray", skip_serializing_if = "is_one_ray")]
    pub pixel_rays: u32,
    /// The training views' median pixel footprint at the scene's centre (world units,
    /// `silhouette::pixel_footprint`): cameras with pixels much finer than this skip the
    /// silhouette rule (`silhouette::draws_pixel_means`). Absent: every camera applies it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub train_pixel: Option<f32>,
    /// The scene's colour does not depend on the viewing direction (a diffuse stylized
    /// field: its view MLP's output layer is zero). The file then leaves out what could not
    /// change a pixel: the VMLP chunk (readers use a zero MLP) and the four specular
    /// features of every voxel (stored as 4 bytes, read back as 8 with zero features).
    /// Needs file version 2; absent (false) in every other asset.
    #[serde(default, skip_serializing_if = "is_false")]
    pub diffuse: bool,
    /// A multi-style asset (version 3, `layers`): one shared geometry (grids and every
    /// voxel's density) and one colour part per style, named here in file order. Absent in
    /// every single-style asset. `diffuse` then says whether every style is diffuse.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub styles: Option<Vec<StyleInfo>>,
    /// A dynamic asset whose grids may hold motion entries (version 4, `motion`): the
    /// keyframe they point into. Its grid holds blocks only. Absent in every other asset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion_ref: Option<u32>,
    /// A dynamic asset: the blocks a static bake of the field keeps at each keyframe's time,
    /// averaged over the keyframes (`snerf bake --at-time` writes such a bake; the 4D bake
    /// counts them exactly with `--static-frame-per-sample`, else with its own visibility
    /// test, which can overstate them where one instant hides what another exposes). The size of
    /// "one static frame" the asset is measured against (`Summary::static_frame_bytes`);
    /// absent in static assets and in dynamic ones baked before it, where the summary
    /// estimates it from the cells the asset draws.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub static_frame_blocks: Option<f32>,
    /// A dynamic asset whose playback between two keyframes weights each side's colour (and
    /// features) by that side's density (`Asset::sample_slot`), so a side with no density
    /// there adds no colour: a surface that moves keeps its colour between keyframes instead
    /// of fading through the empty side's zero, and a voxel whose neighbourhood has no
    /// density is never read for colour (style layers leave it out, `layers`). Every dynamic
    /// asset the baker writes sets it; absent (false: both sides weighted 1 − w and w) in
    /// static assets and in dynamic ones baked before it.
    #[serde(default, skip_serializing_if = "is_false")]
    pub colour_by_density: bool,
}

/// Largest number of styles in one asset.
pub const MAX_STYLES: usize = 64;

/// One style of a multi-style asset: its name (the painting's key, what a client lists and
/// a renderer is asked for) and what a menu can show before any of its colour arrives.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StyleInfo {
    /// Unique in the asset; 1..=64 printable characters.
    pub name: String,
    /// The style image it was painted after, as the stylization was given it (a file name or
    /// `painting:KEY`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<String>,
    /// Mean colour of the style's occupied voxels (RGB in [0,1]): a swatch for a menu.
    pub swatch: [f32; 3],
}

fn is_false(b: &bool) -> bool {
    !*b
}

fn one_ray() -> u32 {
    1
}

fn is_one_ray(k: &u32) -> bool {
    *k == 1
}

impl Header {
    /// Rays a silhouette pixel of this camera takes: `pixel_rays`, or 1 where the camera's
    /// pixels are much finer than the training views' (`silhouette::draws_pixel_means`).
    /// The CPU reference, the native viewer and the web viewer (app.js `pixelSide`) ask this.
    pub fn pixel_rays_for(&self, cam: &snerf_geometry::Pinhole) -> u32 {
        let eye = snerf_geometry::camera::position(&cam.c2w);
        let footprint = snerf_geometry::silhouette::pixel_footprint(eye, self.space.center, cam.fx);
        if self.pixel_rays > 1 && snerf_geometry::silhouette::draws_pixel_means(self.train_pixel, footprint) {
            self.pixel_rays
        } else {
            1
        }
    }

    /// A static header with sensible defaults (the builder and tests start from this).
    pub fn new(kind: Kind, res: u32, block: u32) -> Header {
        Header {
            format: FORMAT_NAME.to_string(),
            kind,
            space: Space::identity(),
            res,
            block,
            atlas_blocks: 0,
            density: DensityRange { logit_min: -10.0, logit_max: 10.0 },
            march: March { step: 2.0 / res.max(1) as f32, t_terminate: 1.0e-4 },
            background: [1.0, 1.0, 1.0],
            view_mlp: MlpShape::default(),
            time_range: None,
            frames: None,
            view: None,
            floor: None,
            pixel_rays: 1,
            train_pixel: None,
            diffuse: false,
            styles: None,
            motion_ref: None,
            static_frame_blocks: None,
            colour_by_density: false,
        }
    }

    /// The scene's preview orbit and up direction: the stored one, or for assets without it
    /// the one implied by the model frame (model +y up; objects and unbounded scenes: 3
    /// model units out at 30°; forward: a small circle around the reference camera).
    pub fn orbit(&self) -> Orbit {
        if let Some(o) = self.view {
            return o;
        }
        let s = &self.space;
        let up = s.dir_to_world([0.0, 1.0, 0.0]);
        match self.kind {
            Kind::Forward => Orbit::Ellipse {
                center: s.to_world([0.0; 3]),
                right: s.dir_to_world([1.0, 0.0, 0.0]),
                up,
                target: s.to_world([0.0, 0.0, -2.0 / 0.75]),
                rx: 0.1 / s.scale,
                ry: 0.1 / s.scale,
            },
            Kind::Object | Kind::Unbounded => Orbit::Around {
                center: s.to_world([0.0; 3]),
                up,
                start: s.dir_to_world([0.0, 0.0, 1.0]),
                radius: 3.0 / s.scale,
                elevation: 30f32.to_radians(),
            },
        }
    }

    pub fn is_dynamic(&self) -> bool {
        self.frames.is_some()
    }

    pub fn num_frames(&self) -> usize {
        self.frames.as_ref().map_or(1, |f| f.len())
    }

    /// Indirection grid cells per axis.
    pub fn grid_dim(&self) -> usize {
        (self.res / self.block.max(1)) as usize
    }

    /// Bytes of one block in memory: (block+2)^3 voxels x 8 channels.
    pub fn block_bytes(&self) -> usize {
        self.voxels_per_block().saturating_mul(crate::quantize::CHANNELS)
    }

    /// Bytes of one block in the file: 8 per voxel, or 4 (density and diffuse RGB) in a
    /// `diffuse` asset.
    pub fn file_block_bytes(&self) -> usize {
        self.voxels_per_block().saturating_mul(self.file_channels())
    }

    /// The lowest file version that holds this asset: 3 for a multi-style one, 2 for a
    /// `diffuse` one, else 1 (so older readers read every asset they can).
    pub fn file_version(&self) -> u32 {
        if self.motion_ref.is_some() {
            4
        } else if self.styles.is_some() {
            3
        } else if self.diffuse {
            2
        } else {
            1
        }
    }

    /// Channels a voxel has in the file's `BLKS` chunks: 8, 4 in a `diffuse` asset, 1 (the
    /// density; colours are in the styles' `SCOL` chunks) in a multi-style asset.
    pub fn file_channels(&self) -> usize {
        if self.styles.is_some() {
            1
        } else if self.diffuse {
            DIFFUSE_CHANNELS
        } else {
            crate::quantize::CHANNELS
        }
    }

    /// Colour channels a voxel of a style holds in a multi-style file: diffuse RGB, and the
    /// four specular features unless every style is diffuse.
    pub fn style_channels(&self) -> usize {
        if self.diffuse {
            DIFFUSE_CHANNELS - 1
        } else {
            crate::quantize::CHANNELS - 1
        }
    }

    /// The index of the style named `name`.
    pub fn style_index(&self, name: &str) -> Option<usize> {
        self.styles.as_ref()?.iter().position(|s| s.name == name)
    }

    /// (block+2)^3, the apron included.
    fn voxels_per_block(&self) -> usize {
        // Saturating: callers may ask before `validate` has bounded `block`.
        let e = (self.block as usize).saturating_add(2);
        e.saturating_mul(e).saturating_mul(e)
    }

    /// Keyframe time of frame `i` (0 for static assets).
    pub fn frame_time(&self, i: usize) -> f32 {
        self.frames.as_ref().and_then(|f| f.get(i)).map_or(0.0, |k| k.time)
    }

    /// Check every field; sizes first, so later code may allocate from them.
    pub fn validate(&self) -> Result<()> {
        ensure!(self.format == FORMAT_NAME, "header format is {:?}, expected {:?}", self.format, FORMAT_NAME);
        ensure!(self.res >= 1 && self.res <= MAX_RES, "header claims res {} (max {})", self.res, MAX_RES);
        ensure!(
            (MIN_BLOCK..=MAX_BLOCK).contains(&self.block),
            "header claims block {} (must be {}..={})",
            self.block,
            MIN_BLOCK,
            MAX_BLOCK
        );
        ensure!(self.res % self.block == 0, "header res {} is not a multiple of block {}", self.res, self.block);
        ensure!(
            snerf_geometry::silhouette::valid_pixel_rays(self.pixel_rays as usize),
            "header pixel_rays is {} (must be 1, 4, 9 or 16)",
            self.pixel_rays
        );
        if let Some(t) = self.train_pixel {
            ensure!(t.is_finite() && t > 0.0, "header train_pixel is {t} (must be finite and > 0)");
        }
        let g = self.grid_dim() as u64;
        ensure!(g * g * g <= MAX_GRID_CELLS, "header grid has {}^3 cells (max {})", g, MAX_GRID_CELLS);
        let atlas_bytes = self.atlas_blocks as u64 * self.block_bytes() as u64;
        ensure!(
            atlas_bytes <= MAX_ATLAS_BYTES,
            "header claims {} atlas blocks = {} bytes (max {} bytes)",
            self.atlas_blocks,
            atlas_bytes,
            MAX_ATLAS_BYTES
        );
        ensure!(
            self.view_mlp == MlpShape::default(),
            "header view_mlp {:?} is not supported (version 1 needs inputs 34, hidden 16, outputs 3, octaves 4)",
            self.view_mlp
        );
        let d = self.density;
        ensure!(
            d.logit_min.is_finite()
                && d.logit_max.is_finite()
                && d.logit_min < d.logit_max
                && d.logit_min.abs() <= MAX_ABS_LOGIT
                && d.logit_max.abs() <= MAX_ABS_LOGIT,
            "header density range [{}, {}] must be finite, increasing and within ±{}",
            d.logit_min,
            d.logit_max,
            MAX_ABS_LOGIT
        );
        let m = self.march;
        ensure!(
            m.step.is_finite() && m.step >= MIN_STEP && m.step <= 2.0,
            "header march step {} must be in [{}, 2]",
            m.step,
            MIN_STEP
        );
        ensure!(
            m.t_terminate.is_finite() && (0.0..1.0).contains(&m.t_terminate),
            "header t_terminate {} must be in [0, 1)",
            m.t_terminate
        );
        ensure!(self.background.iter().all(|x| x.is_finite()), "header background is not finite");
        self.validate_space()?;
        if let Some(o) = &self.view {
            let unit = |v: [f32; 3]| v.iter().all(|x| x.is_finite()) && (v.iter().map(|x| x * x).sum::<f32>() - 1.0).abs() < 1e-3;
            let ok = match *o {
                Orbit::Around { center, up, start, radius, elevation } => {
                    center.iter().all(|x| x.is_finite()) && unit(up) && unit(start) && radius.is_finite() && radius > 0.0 && elevation.is_finite()
                }
                Orbit::Ellipse { center, right, up, target, rx, ry } => {
                    center.iter().chain(&target).all(|x| x.is_finite()) && unit(right) && unit(up) && rx.is_finite() && ry.is_finite()
                }
            };
            ensure!(ok, "header view {:?} needs finite values, unit directions and a positive radius", o);
        }
        ensure!(self.floor.is_none_or(f32::is_finite), "header floor {:?} is not finite", self.floor);
        if let Some(styles) = &self.styles {
            ensure!(
                !styles.is_empty() && styles.len() <= MAX_STYLES,
                "header lists {} styles (must be 1..={})",
                styles.len(),
                MAX_STYLES
            );
            for (i, s) in styles.iter().enumerate() {
                ensure!(
                    !s.name.is_empty() && s.name.chars().count() <= 64 && !s.name.chars().any(char::is_control),
                    "header style {} has the name {:?} (1..=64 printable characters)",
                    i,
                    s.name
                );
                ensure!(styles[..i].iter().all(|o| o.name != s.name), "header names style {:?} twice", s.name);
                ensure!(s.swatch.iter().all(|x| x.is_finite()), "header style {:?} has a non-finite swatch", s.name);
            }
        }
        if let Some(r) = self.motion_ref {
            ensure!(
                (r as usize) < self.num_frames() && self.frames.is_some(),
                "header motion_ref {} names no keyframe of this asset ({} frames)",
                r,
                self.num_frames()
            );
            ensure!(self.styles.is_none(), "header has both motion_ref and styles (one asset holds one or the other)");
        }
        if let Some(n) = self.static_frame_blocks {
            ensure!(
                self.frames.is_some() && n.is_finite() && n >= 0.0 && n as f64 <= self.atlas_blocks as f64 * self.num_frames() as f64,
                "header static_frame_blocks {n} is not a block count of this dynamic asset"
            );
        }
        ensure!(!self.colour_by_density || self.frames.is_some(), "header colour_by_density is set on a static asset (it is how keyframes blend)");
        match (&self.time_range, &self.frames) {
            (None, None) => {}
            (Some(r), Some(frames)) => {
                ensure!(
                    r[0].is_finite() && r[1].is_finite() && r[0] <= r[1],
                    "header time_range [{}, {}] is not a finite interval",
                    r[0],
                    r[1]
                );
                ensure!(
                    !frames.is_empty() && frames.len() <= MAX_FRAMES,
                    "header has {} frames (must be 1..={})",
                    frames.len(),
                    MAX_FRAMES
                );
                for (i, w) in frames.windows(2).enumerate() {
                    ensure!(w[0].time <= w[1].time, "header frame times not sorted at frame {}", i + 1);
                }
                ensure!(frames.iter().all(|f| f.time.is_finite()), "header has a non-finite frame time");
            }
            _ => bail!("header must have both time_range and frames (dynamic) or neither (static)"),
        }
        Ok(())
    }

    fn validate_space(&self) -> Result<()> {
        let s = &self.space;
        ensure!(
            s.center.iter().all(|x| x.is_finite()) && s.scale.is_finite() && s.scale > 0.0,
            "header space center/scale must be finite with scale > 0"
        );
        // Orthonormal rows: the renderer inverts `rot` by transposing it.
        for i in 0..3 {
            for j in 0..3 {
                let dot: f32 = (0..3).map(|k| s.rot[i][k] * s.rot[j][k]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                ensure!((dot - want).abs() < 1e-3, "header space rot is not orthonormal (rows {} and {})", i, j);
            }
        }
        match (self.kind, &s.ndc) {
            (Kind::Forward, None) => bail!("header kind forward needs space.ndc"),
            (Kind::Forward, Some(n)) => {
                let v = [n.fx, n.fy, n.width, n.height, n.near, n.xy_extent];
                ensure!(
                    v.iter().all(|x| x.is_finite() && *x > 0.0),
                    "header space.ndc fields must be finite and positive: {:?}",
                    n
                );
            }
            (_, Some(_)) => bail!("header space.ndc is only allowed for kind forward"),
            (_, None) => {}
        }
        Ok(())
    }
}
