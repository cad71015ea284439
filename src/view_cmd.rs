//! `snerf view FILE | quic://HOST:PORT/ASSET` (the wgpu window).

use std::path::PathBuf;

use anyhow::{bail, Result};
use clap::Args;
use serde_json::{json, Value};
use snerf_viewer::{AssetSource, FileSource, StreamSource, ViewOptions};

#[derive(Args, Debug)]
#[command(after_help = snerf_viewer::keys_help())]
pub struct ViewArgs {
    /// A baked asset file (.snerf), or quic://HOST:PORT/ASSET served by `snerf serve`.
    pub asset: String,
    /// Server certificate fingerprint (SHA-256, printed by `snerf serve`) for quic:// URLs.
    #[arg(long)]
    pub pin: Option<String>,
    #[command(flatten)]
    pub token: crate::args::TokenArgs,
    /// Window size WxH.
    #[arg(long, default_value = "1280x720")]
    pub size: String,
    /// Vertical field of view in degrees.
    #[arg(long, default_value_t = 50.0, value_parser = crate::args::fov_degrees)]
    pub fov: f32,
    /// Render left and right eyes side by side, for displays that show each half to one eye
    /// (3D monitors, phone viewers). Not a headset mode: on a headset, open the web viewer of
    /// `snerf serve` and press Enter VR.
    #[arg(long)]
    pub stereo: bool,
    /// Eye separation in world units for --stereo.
    #[arg(long, default_value_t = 0.064, value_parser = crate::args::non_negative_f32)]
    pub ipd: f32,
    /// Head poses from a file (a nerfstudio camera_path.json, or a JSON list of {"c2w": rows,
    /// "time": optional}), one per frame.
    #[arg(long)]
    pub poses: Option<PathBuf>,
    /// Turn vsync off (frames as fast as they render).
    #[arg(long)]
    pub no_vsync: bool,
    /// Present this many frames, then exit (with --screenshot: save the last one).
    #[arg(long, value_parser = crate::args::int_in::<u64>(1, 1000000000, ""))]
    pub frames: Option<u64>,
    /// Save the last frame here (PNG) when exiting after --frames.
    #[arg(long)]
    pub screenshot: Option<PathBuf>,
    /// Seconds for one pass through a dynamic asset's time.
    #[arg(long, default_value_t = 4.0, value_parser = crate::args::positive_f32)]
    pub loop_seconds: f32,
}

pub fn view_cmd(a: &ViewArgs) -> Result<Value> {
    let (w, h) = crate::args::parse_size(&a.size)?;
    if let Some(shot) = &a.screenshot {
        if !a.asset.starts_with("quic://") {
            snerf_files::check_output("--screenshot", shot, &[snerf_files::Input::File(std::path::Path::new(&a.asset))])?;
        }
    }
    let source: Box<dyn AssetSource> = if a.asset.starts_with("quic://") {
        let Some(pin) = &a.pin else {
            bail!("{}: a quic:// asset needs --pin FINGERPRINT and an access token (both printed by `snerf serve`)", a.asset);
        };
        let token = a.token.resolve()?;
        Box::new(StreamSource::connect(&a.asset, pin, &token)?)
    } else {
        Box::new(FileSource::open(&a.asset)?)
    };
    let opts = ViewOptions {
        width: w,
        height: h,
        fov_y: a.fov,
        vsync: !a.no_vsync,
        stereo: a.stereo,
        ipd: a.ipd,
        pose_file: a.poses.clone(),
        frames: a.frames,
        screenshot: a.screenshot.clone(),
        loop_seconds: a.loop_seconds,
        title: format!("snerf — {}", a.asset),
        ..ViewOptions::default()
    };
    snerf_viewer::run_window(source, opts)?;
    Ok(json!({ "command": "view", "asset": a.asset }))
}
