//! `snerf capture`: photos or a video in, a posed dataset out, with COLMAP (the work is in
//! `snerf_data::capture`); this module parses the flags and draws a bar per phase.

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use indicatif::ProgressBar;
use serde_json::Value;
use snerf_files::guard::{check_output, Input as GuardInput};
use snerf_trainer::data::capture::{self, Backend, CaptureOptions, Event, Input, Matcher};

use crate::args::bar;

pub const CAPTURE_HELP: &str = "Photos (or a video) in, a dataset snerf trains on out, with COLMAP on the CPU.\n\n\
Phases, each with a bar: the photos are copied into a work folder (rotated phone JPEGs are turned upright, \
photos larger than --max-size reduced, WebP/PGM/PPM converted); COLMAP extracts SIFT features, matches them \
(--matcher auto: exhaustive for 50 photos or fewer, sequential in name order above that and for video), maps \
(incremental SfM), and undistorts the registered photos to a pinhole camera. The result is loaded once as \
training will load it, and the scene kind is detected and explained (also `snerf data DATA`).\n\n\
Photos before a plain backdrop (every photo's edges within a few levels of one colour, as a product on a \
turntable before a sweep) are trained as an object: the capture writes backdrop.json (the colour, the keying \
tolerance, the object's box from COLMAP's points, grown to hold the photos' silhouettes) and every load keys the backdrop out as transparent, the \
photos staying as taken; --no-backdrop turns this off.\n\n\
DATA gets images/, sparse/0/{cameras,images,points3D}.bin (COLMAP's own format, read by `snerf train DATA`) \
and capture.json (this command's report: registration, COLMAP's mean reprojection error, times). It is \
written into a temp folder beside DATA and renamed into place at the end: a failure or Ctrl-C leaves no \
half-written dataset, and an existing DATA is replaced only if snerf wrote it and nobody changed it.\n\n\
Photos COLMAP cannot place are listed; below --min-registered (default 0.8) of them the capture fails and \
writes nothing. Good photos: 30-200 of them, sharp, each part of the scene seen from 3 or more places, \
60-80% overlap between neighbours, fixed focus and exposure if the phone allows, walking around the object \
or through the room rather than turning on the spot.\n\n\
Needs COLMAP: PyPI's pycolmap in the setup step's virtual environment (the default when present: it \
mapped 5.7x faster than Debian's COLMAP 3.8 at the same registration, BENCH.md 2d; $SNERF_PYCOLMAP may name \
another Python with pycolmap), or Debian's `colmap` package (--colmap colmap; $SNERF_COLMAP may name the \
binary); `bash scripts/setup-capture.sh` installs both and ffmpeg (for --video).";

#[derive(Args, Debug)]
pub struct CaptureArgs {
    /// Folder of photos (JPEG, PNG, WebP, PGM/PPM), taken in name order for sequential matching.
    #[arg(required_unless_present = "video", conflicts_with = "video")]
    pub photos: Option<PathBuf>,
    /// A video file instead of photos: frames are taken with ffmpeg (which must be installed).
    #[arg(long)]
    pub video: Option<PathBuf>,
    /// Frames per second of video to take with --video.
    #[arg(long, default_value_t = 2.0, value_parser = crate::args::positive)]
    pub fps: f64,
    /// The dataset folder to write.
    #[arg(long)]
    pub out: PathBuf,
    /// auto | sequential | exhaustive (auto: exhaustive up to 50 photos, sequential above and
    /// for video).
    #[arg(long, default_value = "auto")]
    pub matcher: Matcher,
    /// Sequential matching: each photo is matched with the next N in name order (and at quadratic
    /// steps 2, 4, 8, ... beyond). Smaller is faster, and safer on symmetric scenes, where
    /// matching look-alike views from opposite sides folds the reconstruction.
    #[arg(long, default_value_t = 10, value_parser = crate::args::int_in::<u32>(1, 1000, ""))]
    pub overlap: u32,
    /// Fail (writing nothing) when COLMAP registers less than this fraction of the photos.
    #[arg(long, default_value_t = capture::DEFAULT_MIN_REGISTERED, value_parser = fraction)]
    pub min_registered: f64,
    /// Longest side of the photos COLMAP and the dataset get, in pixels (0 = as taken).
    #[arg(long, default_value_t = 1600, value_parser = crate::args::int_in::<u32>(0, 16384, ""))]
    pub max_size: u32,
    /// SIFT features per photo (COLMAP's default is 8192; CPU matching time grows with its square).
    #[arg(long, default_value_t = 4096, value_parser = crate::args::int_in::<u32>(256, 65536, ""))]
    pub max_features: u32,
    /// COLMAP camera model: SIMPLE_RADIAL (default, phones), OPENCV, RADIAL, OPENCV_FISHEYE, ...
    #[arg(long, default_value = "SIMPLE_RADIAL")]
    pub camera_model: String,
    /// Known focal length in pixels of the photos as given (a calibrated camera); COLMAP keeps
    /// it fixed instead of estimating it. Without it the focal comes from the EXIF data, or is
    /// estimated (on a synthetic 24-view ring it came out 11-13% long, see BENCH.md 2d).
    #[arg(long, value_parser = crate::args::positive)]
    pub focal: Option<f64>,
    /// One camera per photo instead of one shared by all (photos from different cameras/zooms).
    #[arg(long)]
    pub camera_per_photo: bool,
    /// Keep the distorted camera and the photos as taken instead of undistorting to a pinhole
    /// camera (the loader then bends the rays; SIMPLE_RADIAL, RADIAL and OPENCV only).
    #[arg(long)]
    pub keep_distortion: bool,
    /// Which COLMAP: auto (pycolmap when the setup step installed it, else `colmap`), colmap
    /// (Debian's 3.8 binary, or $SNERF_COLMAP) or pycolmap (PyPI's 4.x in the setup step's
    /// virtual environment, or the Python $SNERF_PYCOLMAP names).
    #[arg(long, default_value = "auto")]
    pub colmap: Backend,
    /// pycolmap's mapper seed: the same seed and photos give the same poses with `--threads 1`
    /// (with more threads COLMAP's mapping order, and so its poses, differ from run to run;
    /// Debian's COLMAP 3.8 takes no seed, and its runs differ).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Keep the photos opaque even when they stand before a plain backdrop. By default the
    /// photos' edges are checked, and a plain backdrop (a product on a turntable before a
    /// sweep) is keyed out as transparent when the dataset loads, so the object trains alone
    /// (on a turntable the backdrop stays with the camera while the object turns).
    #[arg(long)]
    pub no_backdrop: bool,
}

/// A fraction in [0, 1].
fn fraction(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("'{s}': must be a number in [0, 1]")),
    }
}

pub fn capture_cmd(a: &CaptureArgs, threads: Option<usize>) -> Result<Value> {
    let input = match (&a.photos, &a.video) {
        (_, Some(v)) => Input::Video { file: v.clone(), fps: a.fps },
        (Some(p), None) => {
            if !p.is_dir() {
                bail!("{}: not a folder of photos (for a video file use --video)", p.display());
            }
            check_output("--out", &a.out, &[GuardInput::Tree(p)])?;
            Input::Photos(p.clone())
        }
        (None, None) => bail!("give a folder of photos or --video FILE"),
    };
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let opts = CaptureOptions {
        input,
        out: a.out.clone(),
        matcher: a.matcher,
        min_registered: a.min_registered,
        overlap: a.overlap,
        max_size: a.max_size,
        max_features: a.max_features,
        camera_model: a.camera_model.clone(),
        focal_px: a.focal,
        single_camera: !a.camera_per_photo,
        undistort: !a.keep_distortion,
        threads: threads.unwrap_or(cores),
        backend: a.colmap,
        seed: Some(a.seed),
        backdrop: !a.no_backdrop,
    };
    let mut pb: Option<ProgressBar> = None;
    let report = capture::capture(&opts, &mut |ev| match ev {
        Event::Phase { name, total } => {
            if let Some(p) = pb.take() {
                p.finish();
            }
            let p = if total > 0 {
                bar(total, &format!("{{spinner}} {name:<12} {{bar:30}} {{pos}}/{{len}} [{{elapsed}}]"))
            } else {
                bar(0, &format!("{{spinner}} {name:<12} {{pos}} [{{elapsed}}]"))
            };
            p.enable_steady_tick(std::time::Duration::from_millis(200));
            pb = Some(p);
        }
        Event::Done(i) => {
            if let Some(p) = &pb {
                p.set_position(i);
            }
        }
        Event::Note(s) => match &pb {
            Some(p) => p.println(s),
            None => eprintln!("{s}"),
        },
    });
    if let Some(p) = pb.take() {
        p.finish();
    }
    let report = report?;
    eprintln!(
        "wrote {}: {} of {} photos registered ({:.0}%), mean reprojection error {}, {:.0} s",
        a.out.display(),
        report.registered,
        report.photos,
        report.registered_fraction * 100.0,
        report.mean_reprojection_error_px.map(|e| format!("{e:.3} px")).unwrap_or_else(|| "unknown".into()),
        report.total_seconds
    );
    if report.backdrop.is_none() {
        eprintln!("backdrop: {}", report.backdrop_note);
    }
    eprintln!("scene kind {}", report.detection_note);
    eprintln!("next: snerf train {} --out RUN", a.out.display());
    Ok(serde_json::to_value(&report)?)
}
