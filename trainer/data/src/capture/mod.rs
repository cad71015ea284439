//! Photos (or a video) in, a posed dataset out, with COLMAP: feature extraction, matching,
//! mapping, then undistortion, into a folder snerf's COLMAP loader reads directly
//! (`images/` + `sparse/0/{cameras,images,points3D}.bin`, plus `capture.json`, the report).
//!
//! Steps: the photos are staged (`photos`: copied, or turned upright and reduced), COLMAP runs
//! its phases as child processes (`tool`), the largest model is kept (`model`) and checked
//! against the registration floor, the images are undistorted to a pinhole camera, and the
//! result is loaded once with this crate's loader (so a dataset that would not train is never
//! written) to detect and explain the scene kind. Photos before a plain backdrop get
//! `backdrop.json` (see [`crate::backdrop`]): the loader keys the backdrop out and the capture
//! trains as an object, in the box of its sparse points grown to hold its silhouettes.
//!
//! Matching: sequential (each frame against the next `overlap` frames in name order, default
//! 10, plus quadratic steps) for video frames and for more than [`EXHAUSTIVE_MAX`] photos; exhaustive (every pair)
//! for [`EXHAUSTIVE_MAX`] photos or fewer, which does not assume any order. Exhaustive costs
//! n²/2 pairs, and on a CPU each pair of 4096-feature images costs about 0.1–0.3 s.
//!
//! Undistortion: COLMAP's `image_undistorter` resamples every image to a pinhole camera, so
//! OPENCV, RADIAL and FISHEYE lenses all leave as PINHOLE, and everything downstream
//! (training, stylization's reprojection, baking) sees straight rays. `undistort: false`
//! keeps the distorted model and the original photos instead; the loader then bends the rays
//! (SIMPLE_RADIAL, RADIAL and OPENCV; fisheye models are refused there).
//!
//! Nothing half-written is left: all work happens in a temp folder beside the output
//! (`.NAME.PID.snerf-tmp`, removed on failure and Ctrl-C), renamed into place at the end.

pub mod known_depth;
mod model;
mod photos;
pub mod pycolmap;
mod tool;
mod video;

pub use model::parse_reprojection_error;
pub use photos::PHOTO_EXTS;
pub use tool::{find_colmap, COLMAP_ENV, SETUP_HINT};

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use serde::Serialize;
use snerf_files::atomic::TempPath;
use snerf_files::guard::{self, Ownership};

/// Exhaustive matching up to this many photos, sequential above (see the module docs).
pub const EXHAUSTIVE_MAX: usize = 50;

/// Default floor on the fraction of photos COLMAP must register.
pub const DEFAULT_MIN_REGISTERED: f64 = 0.8;

/// What the capture reports as it goes; the caller draws it (a bar per phase).
#[derive(Clone, Debug)]
pub enum Event {
    /// A phase starts; `total` steps (0 when unknown).
    Phase { name: String, total: u64 },
    /// Steps done so far in the current phase.
    Done(u64),
    /// A line worth showing the user.
    Note(String),
}

/// Which COLMAP runs the capture: Debian's `colmap` binary (3.8) or PyPI's pycolmap (4.x, in
/// the setup step's virtual environment). `Auto` takes pycolmap when it is installed (it mapped
/// 5.7× faster at the same registration, BENCH.md §2d), else `colmap`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    Auto,
    Colmap,
    Pycolmap,
}

impl std::str::FromStr for Backend {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Backend::Auto),
            "colmap" | "debian" => Ok(Backend::Colmap),
            "pycolmap" => Ok(Backend::Pycolmap),
            _ => Err(format!("'{s}': use auto, colmap or pycolmap")),
        }
    }
}

/// The COLMAP a capture runs.
enum Tool {
    Colmap(PathBuf),
    Py(pycolmap::Pycolmap),
}

fn resolve(backend: Backend) -> Result<(Tool, Backend)> {
    Ok(match backend {
        Backend::Colmap => (Tool::Colmap(find_colmap()?), Backend::Colmap),
        Backend::Pycolmap => (Tool::Py(pycolmap::find()?), Backend::Pycolmap),
        Backend::Auto => match pycolmap::find() {
            Ok(p) => (Tool::Py(p), Backend::Pycolmap),
            Err(py) => match find_colmap() {
                Ok(c) => (Tool::Colmap(c), Backend::Colmap),
                Err(e) => bail!("{e:#} (and pycolmap: {py:#})"),
            },
        },
    })
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Matcher {
    Auto,
    Sequential,
    Exhaustive,
}

impl std::str::FromStr for Matcher {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(Matcher::Auto),
            "sequential" => Ok(Matcher::Sequential),
            "exhaustive" => Ok(Matcher::Exhaustive),
            _ => Err(format!("'{s}': use auto, sequential or exhaustive")),
        }
    }
}

/// Where the photos come from.
#[derive(Clone, Debug)]
pub enum Input {
    Photos(PathBuf),
    /// A video file and the frames per second to take from it.
    Video {
        file: PathBuf,
        fps: f64,
    },
}

#[derive(Clone, Debug)]
pub struct CaptureOptions {
    pub input: Input,
    pub out: PathBuf,
    pub matcher: Matcher,
    /// Fail below this fraction of registered photos.
    pub min_registered: f64,
    /// Longer side cap for the photos COLMAP and the dataset get (0 = none).
    pub max_size: u32,
    /// Sequential matching: each photo against this many following ones (in name order).
    pub overlap: u32,
    /// SIFT features per image (COLMAP's default is 8192; matching cost grows with its square).
    pub max_features: u32,
    /// COLMAP camera model for the shared camera (SIMPLE_RADIAL, OPENCV, ...).
    pub camera_model: String,
    /// A known focal length in pixels of the photos as given (a calibrated camera): COLMAP then
    /// keeps it fixed instead of estimating it, which makes the geometry exact up to scale.
    pub focal_px: Option<f64>,
    /// One camera for all photos (one phone, one video) or one per photo.
    pub single_camera: bool,
    /// Resample to a pinhole camera (see the module docs).
    pub undistort: bool,
    pub threads: usize,
    /// Which COLMAP (see [`Backend`]).
    pub backend: Backend,
    /// pycolmap's mapper seed (the same seed and photos give the same capture when `threads`
    /// is 1; with more, the mapping differs from run to run); Debian's COLMAP 3.8 takes none.
    pub seed: Option<u64>,
    /// Look for a plain backdrop and, when there is one, have it keyed out at load time
    /// (`backdrop.json`, see [`crate::backdrop`]).
    pub backdrop: bool,
}

/// What `capture` did, also written to `DATA/capture.json`.
#[derive(Clone, Debug, Serialize)]
pub struct CaptureReport {
    pub out: String,
    pub backend: Backend,
    pub colmap: String,
    pub colmap_version: String,
    pub photos: usize,
    pub registered: usize,
    pub registered_fraction: f64,
    pub min_registered: f64,
    pub not_registered: Vec<String>,
    pub models_found: usize,
    pub matcher: Matcher,
    pub matcher_reason: String,
    pub camera_model: String,
    pub undistorted: bool,
    pub mean_reprojection_error_px: Option<f64>,
    pub converted_photos: usize,
    pub image_size: [u32; 2],
    pub seconds: Vec<(String, f64)>,
    pub total_seconds: f64,
    pub kind: String,
    pub detection_note: String,
    pub train_views: usize,
    pub test_views: usize,
    /// The plain backdrop that is keyed out, when one was found (also in `backdrop.json`).
    pub backdrop: Option<crate::backdrop::Backdrop>,
    /// Why the photos were or were not taken as standing before a plain backdrop.
    pub backdrop_note: String,
}

/// Runs the whole capture (see the module docs); `progress` receives phases and steps.
pub fn capture(opts: &CaptureOptions, progress: &mut dyn FnMut(Event)) -> Result<CaptureReport> {
    let t_all = Instant::now();
    let (tool, backend) = resolve(opts.backend)?;
    if !(0.0..=1.0).contains(&opts.min_registered) {
        bail!(
            "the registration floor must be in [0, 1], not {}",
            opts.min_registered
        );
    }
    check_replaceable(&opts.out)?;
    let _graceful = snerf_files::interrupt::Graceful::enter();
    let tmp = TempPath::for_target(&opts.out)?;
    let root = tmp.path().to_path_buf();
    let work = root.join("colmap");
    let input_dir = work.join("input");
    std::fs::create_dir_all(&input_dir)
        .with_context(|| format!("{}: cannot create", input_dir.display()))?;
    let mut seconds: Vec<(String, f64)> = Vec::new();
    let timed = |seconds: &mut Vec<(String, f64)>, name: &str, t: Instant| {
        seconds.push((name.to_string(), t.elapsed().as_secs_f64()))
    };

    // Photos in.
    let t = Instant::now();
    let (photo_dir, from_video) = match &opts.input {
        Input::Photos(d) => (d.clone(), false),
        Input::Video { file, fps } => {
            let frames = work.join("frames");
            let n = video::extract(file, &frames, *fps, opts.max_size, progress)?;
            progress(Event::Note(format!("{n} frames from {}", file.display())));
            (frames, true)
        }
    };
    let list = photos::list(&photo_dir, 3)?;
    progress(Event::Phase {
        name: "photos".into(),
        total: list.len() as u64,
    });
    let staged = photos::stage(&list, &input_dir, opts.max_size)?;
    progress(Event::Done(list.len() as u64));
    if from_video {
        let _ = std::fs::remove_dir_all(work.join("frames"));
    }
    timed(&mut seconds, "photos", t);
    let n = staged.len();

    // COLMAP: features, matches, mapping.
    let (matcher, matcher_reason) = choose_matcher(opts.matcher, n, from_video);
    progress(Event::Note(format!("matching: {matcher_reason}")));
    let threads = opts.threads.max(1).to_string();
    let db = work.join("database.db");
    let sparse = work.join("sparse");
    std::fs::create_dir_all(&sparse)
        .with_context(|| format!("{}: cannot create", sparse.display()))?;
    let camera_params = match opts.focal_px {
        Some(f) => Some(known_camera(
            f,
            &opts.camera_model,
            &list[0],
            &input_dir.join(&staged[0].name),
        )?),
        None => None,
    };
    let (colmap_name, version, mapped) = match &tool {
        Tool::Py(py) => {
            let args = serde_json::json!({
                "step": "map",
                "photos": n,
                "database": db,
                "images": input_dir,
                "sparse": sparse,
                "camera_model": opts.camera_model,
                "camera_params": camera_params,
                "single_camera": opts.single_camera,
                "threads": opts.threads.max(1),
                "max_features": opts.max_features,
                "max_size": opts.max_size,
                "matcher": if matcher == Matcher::Exhaustive { "exhaustive" } else { "sequential" },
                "overlap": opts.overlap,
                "seed": opts.seed,
            });
            let mapped = py.run(&work, &args, progress).map(|(log, secs)| {
                seconds.extend(secs);
                log
            });
            (py.python.display().to_string(), py.version.clone(), mapped)
        }
        Tool::Colmap(colmap) => {
            let version = colmap_version(colmap);
            let t = Instant::now();
            let mut cmd = Command::new(colmap);
            cmd.arg("feature_extractor")
                .arg("--database_path")
                .arg(&db)
                .arg("--image_path")
                .arg(&input_dir)
                .args(["--ImageReader.camera_model", &opts.camera_model])
                .args([
                    "--ImageReader.single_camera",
                    if opts.single_camera { "1" } else { "0" },
                ])
                .args(["--SiftExtraction.use_gpu", "0"])
                .args(["--SiftExtraction.num_threads", &threads])
                .args([
                    "--SiftExtraction.max_num_features",
                    &opts.max_features.to_string(),
                ]);
            if opts.max_size > 0 {
                cmd.args([
                    "--SiftExtraction.max_image_size",
                    &opts.max_size.to_string(),
                ]);
            }
            if let Some(params) = &camera_params {
                cmd.args(["--ImageReader.camera_params", params]);
            }
            phase(progress, "features", n as u64);
            tool::run("COLMAP feature extraction", cmd, progress, &mut |l, p| {
                if let Some((i, _)) = tool::bracket_count(l, "Processed file") {
                    p(Event::Done(i));
                }
            })?;
            timed(&mut seconds, "features", t);

            let t = Instant::now();
            let mut cmd = Command::new(colmap);
            match matcher {
                Matcher::Exhaustive => cmd.arg("exhaustive_matcher"),
                _ => cmd
                    .arg("sequential_matcher")
                    .args(["--SequentialMatching.overlap", &opts.overlap.to_string()]),
            };
            cmd.arg("--database_path")
                .arg(&db)
                .args(["--SiftMatching.use_gpu", "0"])
                .args(["--SiftMatching.num_threads", &threads]);
            if matcher == Matcher::Exhaustive {
                // Blocks of 10 images: the bar moves every block instead of once.
                cmd.args(["--ExhaustiveMatching.block_size", "10"]);
            }
            let blocks = n.div_ceil(10) as u64;
            phase(
                progress,
                "matching",
                if matcher == Matcher::Exhaustive {
                    blocks * blocks
                } else {
                    n as u64
                },
            );
            tool::run("COLMAP feature matching", cmd, progress, &mut |l, p| {
                if let Some((i, _)) = tool::bracket_count(l, "Matching image") {
                    p(Event::Done(i));
                } else if let Some((i, nb)) = tool::bracket_count(l, "Matching block") {
                    // "Matching block [i/nb, j/nb]": j is the inner loop.
                    let j = l
                        .split(',')
                        .nth(1)
                        .and_then(|s| s.trim().split('/').next())
                        .and_then(|s| s.trim().parse::<u64>().ok())
                        .unwrap_or(1);
                    p(Event::Done((i - 1) * nb + j));
                }
            })?;
            timed(&mut seconds, "matching", t);

            let t = Instant::now();
            let mut cmd = Command::new(colmap);
            cmd.arg("mapper")
                .arg("--database_path")
                .arg(&db)
                .arg("--image_path")
                .arg(&input_dir)
                .arg("--output_path")
                .arg(&sparse)
                .args(["--Mapper.num_threads", &threads]);
            if opts.focal_px.is_some() {
                cmd.args(["--Mapper.ba_refine_focal_length", "0"]);
            }
            phase(progress, "mapping", n as u64);
            let mut best = 0u64;
            let mapped = tool::run("COLMAP mapping", cmd, progress, &mut |l, p| {
                // "Registering image #12 (7)": the 7th image of the model is being registered.
                if let Some(rest) = l.trim_start().strip_prefix("Registering image #") {
                    if let Some(k) = rest
                        .split('(')
                        .nth(1)
                        .and_then(|s| s.trim_end_matches(')').trim().parse::<u64>().ok())
                    {
                        best = best.max(k);
                        p(Event::Done(best));
                    }
                }
            });
            timed(&mut seconds, "mapping", t);
            (colmap.display().to_string(), version, mapped)
        }
    };
    let map_reproj = mapped
        .as_ref()
        .ok()
        .and_then(|l| parse_reprojection_error(l));

    // The largest model, against the floor. COLMAP exits with an error when it built none,
    // which `model::largest` explains better than its log does.
    let model = match (mapped, model::largest(&sparse)) {
        (_, Ok(m)) => m,
        (Err(e), Err(_)) if snerf_files::interrupt::is_interrupted(&e) => return Err(e),
        (_, Err(e)) => return Err(e.context(format!("{n} photos, nothing was written"))),
    };
    let registered = model.registered.len();
    let fraction = registered as f64 / n as f64;
    let not_registered: Vec<String> = staged
        .iter()
        .filter(|s| model.registered.binary_search(&s.name).is_err())
        .map(|s| s.source.display().to_string())
        .collect();
    if !not_registered.is_empty() {
        progress(Event::Note(format!(
            "{} of {n} photos not registered: {}",
            not_registered.len(),
            not_registered.join(", ")
        )));
    }
    if fraction < opts.min_registered {
        bail!(
            "COLMAP registered {registered} of {n} photos ({:.0}%), below the floor of {:.0}% \
             (--min-registered): nothing was written. Not registered: {}. Photos need overlap \
             (each scene point seen from 3+ photos, ~60-80% overlap between neighbours), texture \
             and sharp focus; {}{} models were found{}",
            fraction * 100.0,
            opts.min_registered * 100.0,
            not_registered.join(", "),
            if matcher == Matcher::Sequential {
                "sequential matching assumes the names are in capture order (try --matcher exhaustive); "
            } else {
                ""
            },
            model.models_found,
            if model.models_found > 1 {
                " (the photos fell into groups COLMAP could not join; the largest was used)"
            } else {
                ""
            }
        );
    }
    let reproj = match &tool {
        Tool::Py(_) => map_reproj,
        Tool::Colmap(colmap) => {
            let mut cmd = Command::new(colmap);
            cmd.arg("model_analyzer").arg("--path").arg(&model.dir);
            tool::run("COLMAP model analysis", cmd, &mut |_| {}, &mut |_, _| {})
                .ok()
                .and_then(|log| parse_reprojection_error(&log))
        }
    };

    // Undistort (or keep the distorted model), then lay the dataset out.
    let t = Instant::now();
    let final_sparse = root.join("sparse").join("0");
    if opts.undistort {
        let und = work.join("undistorted");
        match &tool {
            Tool::Py(py) => {
                let args = serde_json::json!({
                    "step": "undistort",
                    "output": und,
                    "model": model.dir,
                    "images": input_dir,
                    "threads": opts.threads.max(1),
                });
                py.run(&work, &args, progress)?;
            }
            Tool::Colmap(colmap) => {
                let mut cmd = Command::new(colmap);
                cmd.arg("image_undistorter")
                    .arg("--image_path")
                    .arg(&input_dir)
                    .arg("--input_path")
                    .arg(&model.dir)
                    .arg("--output_path")
                    .arg(&und)
                    .args(["--output_type", "COLMAP"]);
                phase(progress, "undistortion", registered as u64);
                tool::run("COLMAP undistortion", cmd, progress, &mut |l, p| {
                    if let Some((i, _)) = tool::bracket_count(l, "Undistorting image") {
                        p(Event::Done(i));
                    }
                })?;
            }
        }
        move_path(&und.join("images"), &root.join("images"))?;
        std::fs::create_dir_all(root.join("sparse"))?;
        move_path(&und.join("sparse"), &final_sparse)?;
    } else {
        move_path(&input_dir, &root.join("images"))?;
        std::fs::create_dir_all(root.join("sparse"))?;
        move_path(&model.dir, &final_sparse)?;
    }
    // COLMAP 3.8 writes a project.ini beside the model; it names the temp folder.
    let _ = std::fs::remove_file(final_sparse.join("project.ini"));
    std::fs::remove_dir_all(&work).with_context(|| format!("{}: cannot remove", work.display()))?;
    timed(&mut seconds, "undistortion", t);

    // Load it as training will (all images decoded): detection, and proof that it reads.
    let mut ds = crate::load(&root, &crate::LoadOptions::default())
        .map_err(|e| anyhow!("the capture does not load as a dataset: {e:#}"))?;
    // A plain backdrop: described for the loader to key out, then loaded again as keyed.
    let (backdrop, backdrop_note) = if opts.backdrop {
        let views: Vec<crate::backdrop::Rgba> = ds
            .all_views()
            .map(|v| crate::backdrop::Rgba {
                pixels: &v.rgba,
                width: v.intrinsics.width as usize,
                height: v.intrinsics.height as usize,
            })
            .collect();
        match crate::backdrop::detect(&views) {
            Ok(mut b) => {
                b.aabb = sparse_box(&final_sparse)?;
                snerf_files::atomic::write_json_atomic(&root.join(crate::backdrop::FILE), &b)?;
                let note = b.describe();
                progress(Event::Note(note.clone()));
                ds = crate::load(&root, &crate::LoadOptions::default())
                    .map_err(|e| anyhow!("the capture does not load as a dataset: {e:#}"))?;
                // The points' box, grown where the keyed photos show object outside it.
                if let Some(aabb) = b.aabb {
                    let views: Vec<&crate::View> = ds.all_views().collect();
                    let (grown, f) = crate::backdrop::cover_silhouettes(aabb, &views);
                    if f > 1.0 {
                        b.aabb = Some(grown);
                        progress(Event::Note(format!(
                            "the object's box from the sparse points grown {f:.2}x to hold the photos' silhouettes"
                        )));
                        snerf_files::atomic::write_json_atomic(&root.join(crate::backdrop::FILE), &b)?;
                        ds = crate::load(&root, &crate::LoadOptions::default())
                            .map_err(|e| anyhow!("the capture does not load as a dataset: {e:#}"))?;
                    }
                }
                (Some(b), note)
            }
            Err(why) => (None, why),
        }
    } else {
        (None, "not looked for (--no-backdrop)".to_string())
    };
    let first = ds
        .all_views()
        .next()
        .map(|v| [v.intrinsics.width, v.intrinsics.height]);
    let mut report = CaptureReport {
        out: opts.out.display().to_string(),
        backend,
        colmap: colmap_name,
        colmap_version: version,
        photos: n,
        registered,
        registered_fraction: fraction,
        min_registered: opts.min_registered,
        not_registered,
        models_found: model.models_found,
        matcher,
        matcher_reason,
        camera_model: opts.camera_model.clone(),
        undistorted: opts.undistort,
        mean_reprojection_error_px: reproj,
        converted_photos: staged.iter().filter(|s| s.converted).count(),
        image_size: first.unwrap_or([0, 0]),
        seconds: Vec::new(),
        total_seconds: 0.0,
        kind: ds.kind.as_str().to_string(),
        // The loads above read the temp folder; the note names the dataset where it will be.
        detection_note: ds
            .detection_note
            .replace(&root.display().to_string(), &opts.out.display().to_string()),
        train_views: ds.train.len(),
        test_views: ds.test.len(),
        backdrop,
        backdrop_note,
    };
    drop(ds);
    report.seconds = seconds;
    report.total_seconds = t_all.elapsed().as_secs_f64();
    snerf_files::atomic::write_json_atomic(&root.join("capture.json"), &report)?;
    guard::write_manifest(&root, "snerf capture")?;

    // Into place: an old capture aside, the new one in, the old one removed.
    check_replaceable(&opts.out)?;
    let old = TempPath::for_target(&opts.out.with_file_name(format!(
        "{}.old",
        opts.out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
    )))?;
    let had_old = opts.out.exists();
    if had_old {
        std::fs::rename(&opts.out, old.path())
            .with_context(|| format!("cannot move the old {} aside", opts.out.display()))?;
    }
    if let Err(e) = std::fs::rename(&root, &opts.out) {
        if had_old {
            let _ = std::fs::rename(old.path(), &opts.out);
        }
        return Err(e)
            .with_context(|| format!("cannot move the capture to {}", opts.out.display()));
    }
    tmp.keep();
    drop(old);
    Ok(report)
}

/// The object's box from the model's sparse points (`None` without enough of them).
fn sparse_box(model: &Path) -> Result<Option<([f32; 3], [f32; 3])>> {
    let p = model.join("points3D.bin");
    if !p.is_file() {
        return Ok(None);
    }
    let bytes = std::fs::read(&p).with_context(|| format!("{}: cannot read", p.display()))?;
    let pts = crate::colmap_points::read_points_bin(&bytes).map_err(|e| anyhow!("{}: {e}", p.display()))?;
    Ok(crate::backdrop::object_box(&pts.iter().map(|q| q.xyz).collect::<Vec<_>>()))
}

/// COLMAP's `camera_params` for a known focal length `f` (pixels of the photo as given),
/// scaled to the staged photo, principal point at its centre, no distortion to start from.
fn known_camera(f: f64, model: &str, original: &Path, staged: &Path) -> Result<String> {
    if !(f.is_finite() && f > 0.0) {
        bail!("the focal length must be a positive number of pixels, not {f}");
    }
    let (ow, oh) = image::image_dimensions(original)
        .with_context(|| format!("{}: cannot read its size", original.display()))?;
    let (w, h) = image::image_dimensions(staged)
        .with_context(|| format!("{}: cannot read its size", staged.display()))?;
    let f = f * w.max(h) as f64 / ow.max(oh) as f64;
    let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
    Ok(match model {
        "SIMPLE_PINHOLE" => format!("{f},{cx},{cy}"),
        "PINHOLE" => format!("{f},{f},{cx},{cy}"),
        "SIMPLE_RADIAL" => format!("{f},{cx},{cy},0"),
        "RADIAL" => format!("{f},{cx},{cy},0,0"),
        "OPENCV" => format!("{f},{f},{cx},{cy},0,0,0,0"),
        m => bail!("a known focal length works with SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL or OPENCV, not {m}"),
    })
}

fn phase(progress: &mut dyn FnMut(Event), name: &str, total: u64) {
    progress(Event::Phase {
        name: name.into(),
        total,
    });
}

/// The matcher and why (see the module docs for the rule).
pub fn choose_matcher(asked: Matcher, n: usize, from_video: bool) -> (Matcher, String) {
    match asked {
        Matcher::Sequential => (Matcher::Sequential, "sequential (asked for)".into()),
        Matcher::Exhaustive => (Matcher::Exhaustive, "exhaustive (asked for)".into()),
        Matcher::Auto if from_video => (
            Matcher::Sequential,
            "sequential: video frames are in capture order".into(),
        ),
        Matcher::Auto if n > EXHAUSTIVE_MAX => (
            Matcher::Sequential,
            format!(
                "sequential: {n} photos > {EXHAUSTIVE_MAX}, every pair would cost too long on a CPU; \
                 assumes file names are in capture order (--matcher exhaustive otherwise)"
            ),
        ),
        Matcher::Auto => (
            Matcher::Exhaustive,
            format!("exhaustive: {n} photos <= {EXHAUSTIVE_MAX}, every pair, no order assumed"),
        ),
    }
}

/// Refuse to replace a folder unless it is missing, empty, or a capture nobody changed since.
fn check_replaceable(dir: &Path) -> Result<()> {
    match guard::ownership(dir)? {
        Ownership::Missing | Ownership::Empty | Ownership::Owned => Ok(()),
        Ownership::Foreign(why) => bail!(
            "{} exists and snerf cannot replace it: {why}. `snerf capture` replaces only a \
             dataset snerf wrote and nobody changed since; move it away or choose another --out",
            dir.display()
        ),
    }
}

fn move_path(from: &Path, to: &Path) -> Result<()> {
    std::fs::rename(from, to)
        .with_context(|| format!("cannot move {} to {}", from.display(), to.display()))
}

/// COLMAP's version line ("COLMAP 3.8 (Commit ...)"), or "unknown".
fn colmap_version(colmap: &Path) -> String {
    Command::new(colmap)
        .arg("help")
        .env("QT_QPA_PLATFORM", "offscreen")
        .output()
        .ok()
        .and_then(|o| {
            let s = String::from_utf8_lossy(&o.stdout).into_owned();
            s.lines()
                .find(|l| l.contains("COLMAP"))
                .map(|l| l.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matcher_rule() {
        assert_eq!(
            choose_matcher(Matcher::Auto, 30, false).0,
            Matcher::Exhaustive
        );
        assert_eq!(
            choose_matcher(Matcher::Auto, 51, false).0,
            Matcher::Sequential
        );
        assert_eq!(
            choose_matcher(Matcher::Auto, 10, true).0,
            Matcher::Sequential
        );
        assert_eq!(
            choose_matcher(Matcher::Exhaustive, 500, true).0,
            Matcher::Exhaustive
        );
    }
}
