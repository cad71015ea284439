//! Headless rendering through the same shaders as the window: camera paths -> frames
//! (`snerf render --gpu`), with a fallback to the CPU reference renderer that says so.

use anyhow::Result;

use crate::gpu::{GpuOptions, GpuRenderer, NoAdapterError};
use snerf_asset::{Asset, Camera, Frame};

/// Render each (camera, time) on the GPU. Fails with `NoAdapterError` (downcast the
/// error) when there is no adapter; the caller may then use the CPU reference renderer.
pub fn render_frames(asset: &Asset, cams: &[(Camera, f32)]) -> Result<Vec<Frame>> {
    render_frames_with(asset, cams, GpuOptions::default())
}

pub fn render_frames_with(
    asset: &Asset,
    cams: &[(Camera, f32)],
    opts: GpuOptions,
) -> Result<Vec<Frame>> {
    let mut r = GpuRenderer::with_options(asset, opts)?;
    cams.iter().map(|(c, t)| r.render(c, *t)).collect()
}

/// Which renderer produced the frames of `render_frames_or_cpu`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum RenderedBy {
    /// The GPU path; the adapter's description.
    Gpu(String),
    /// The CPU reference renderer, and why (the GPU path's error).
    Cpu(String),
}

/// GPU if an adapter exists, else the CPU reference renderer (`snerf_asset::render`);
/// `RenderedBy::Cpu` carries the message to print. Errors other than "no adapter" (a lost
/// device, an asset beyond the GPU's limits) also fall back, with their message.
pub fn render_frames_or_cpu(
    asset: &Asset,
    cams: &[(Camera, f32)],
) -> Result<(Vec<Frame>, RenderedBy)> {
    match GpuRenderer::new(asset) {
        Ok(mut r) => {
            let info = r.adapter_info();
            let mut out = Vec::with_capacity(cams.len());
            for (c, t) in cams {
                match r.render(c, *t) {
                    Ok(f) => out.push(f),
                    Err(e) => {
                        let why = format!("GPU rendering failed after {} frames ({:#}); CPU reference renderer used", out.len(), e);
                        for (c, t) in &cams[out.len()..] {
                            out.push(snerf_asset::render(asset, c, *t));
                        }
                        return Ok((out, RenderedBy::Cpu(why)));
                    }
                }
            }
            Ok((out, RenderedBy::Gpu(info)))
        }
        Err(e) => {
            let why = if e.downcast_ref::<NoAdapterError>().is_some() {
                format!("{}; falling back to the CPU reference renderer", e)
            } else {
                format!(
                    "GPU renderer unavailable ({:#}); falling back to the CPU reference renderer",
                    e
                )
            };
            let frames = cams
                .iter()
                .map(|(c, t)| snerf_asset::render(asset, c, *t))
                .collect();
            Ok((frames, RenderedBy::Cpu(why)))
        }
    }
}
