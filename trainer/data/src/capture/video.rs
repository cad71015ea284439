//! Frames from a video file with ffmpeg, when it is installed: `fps` frames per second of video,
//! scaled so the longer side is at most the capture's size cap, written as high-quality JPEG.
//! Without ffmpeg the capture stops with a message that says how to install it, or to extract
//! the frames with another tool and pass the folder instead.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{anyhow, bail, Result};

use super::{tool, Event};

/// Writes `frame_00001.jpg`, ... into `dir`; returns how many.
pub fn extract(
    video: &Path,
    dir: &Path,
    fps: f64,
    max_size: u32,
    progress: &mut dyn FnMut(Event),
) -> Result<usize> {
    if !video.is_file() {
        bail!("--video {}: no such file", video.display());
    }
    let ffmpeg = tool::on_path("ffmpeg").ok_or_else(|| {
        anyhow!(
            "--video {}: reading video frames needs ffmpeg, which is not installed \
             (`apt-get install ffmpeg`, or `bash scripts/setup-capture.sh`); or extract the frames \
             with any other tool and pass their folder instead of --video",
            video.display()
        )
    })?;
    std::fs::create_dir_all(dir).map_err(|e| anyhow!("{}: cannot create: {e}", dir.display()))?;
    // Longer side capped, aspect kept, even sizes (some codecs' frames are odd-sized).
    let cap = if max_size == 0 { 1 << 14 } else { max_size };
    let filter = format!(
        "fps={fps},scale='if(gt(iw,ih),min({cap},iw),-2)':'if(gt(iw,ih),-2,min({cap},ih))'"
    );
    let mut cmd = Command::new(ffmpeg);
    cmd.arg("-hide_banner")
        .arg("-nostdin")
        .arg("-i")
        .arg(video)
        .args(["-vf", &filter, "-q:v", "2", "-start_number", "1"])
        .arg(dir.join("frame_%05d.jpg"));
    progress(Event::Phase {
        name: "video frames".into(),
        total: 0,
    });
    tool::run(
        &format!("ffmpeg reading {}", video.display()),
        cmd,
        progress,
        &mut |l, p| {
            // "frame=   42 fps=..." as ffmpeg goes.
            if let Some(rest) = l.trim_start().strip_prefix("frame=") {
                if let Some(n) = rest.split_whitespace().next().and_then(|n| n.parse().ok()) {
                    p(Event::Done(n));
                }
            }
        },
    )?;
    let frames: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| anyhow!("{}: {e}", dir.display()))?
        .flatten()
        .map(|e| e.path())
        .collect();
    if frames.is_empty() {
        bail!(
            "--video {}: ffmpeg wrote no frames (is it a video file?)",
            video.display()
        );
    }
    Ok(frames.len())
}
