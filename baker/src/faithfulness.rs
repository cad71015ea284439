//! How much baking loses: the baked asset rendered by the CPU reference renderer against the
//! field's own renders of the same cameras (the bake's error alone), and both against the
//! held-out photographs (what a user sees change).

use anyhow::Result;
use serde::Serialize;
use snerf_asset::render::{render, Camera};
use snerf_asset::Asset;
use snerf_data::View;
use snerf_trainer::eval::{ground_truth, render_camera, render_camera_with};
use snerf_trainer::metrics::psnr;
use snerf_trainer::render::WorkspacePool;
use snerf_trainer::train::Model;

#[derive(Clone, Debug, Serialize)]
pub struct ViewFaithfulness {
    pub name: String,
    pub time: Option<f32>,
    /// Baked render vs the field's render, both drawn the asset's way (its `pixel_rays` on
    /// silhouette pixels) (dB).
    pub baked_vs_field: f64,
    /// Field vs ground truth (drawn as trained: silhouette pixels as the mean of several
    /// rays), the same drawn the asset's way for this camera (one ray per pixel where its
    /// pixels are much finer than the training views'), baked vs ground truth (dB).
    pub field_vs_truth: f64,
    pub field_as_asset_vs_truth: f64,
    pub baked_vs_truth: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct Faithfulness {
    pub views: Vec<ViewFaithfulness>,
    pub mean_baked_vs_field: f64,
    pub mean_field_vs_truth: f64,
    pub mean_field_as_asset_vs_truth: f64,
    pub mean_baked_vs_truth: f64,
    /// field_vs_truth - baked_vs_truth: the test-view PSNR a user sees change from the field's
    /// evaluation to the baked asset.
    pub drop_db: f64,
    /// field_as_asset_vs_truth - baked_vs_truth: what baking itself costs, like with like.
    /// drop_db - bake_loss_db is what the asset's renderers give up by drawing silhouettes
    /// another way than the field's evaluation (0 where both take the field's rule).
    pub bake_loss_db: f64,
    pub seconds_field: f64,
    pub seconds_baked: f64,
}

/// The camera of a view in the asset renderer's terms (lens distortion is not baked).
pub fn camera_of(v: &View) -> Camera {
    let k = &v.intrinsics;
    Camera { c2w: v.c2w, fx: k.fx, fy: k.fy, cx: k.cx, cy: k.cy, width: k.width, height: k.height }
}

/// Score up to `max_views` evenly spaced views; `bg` must be the asset's background.
pub fn measure(model: &Model, pool: &WorkspacePool, asset: &Asset, views: &[View], max_views: usize) -> Result<Faithfulness> {
    let bg = asset.header.background;
    let n = views.len().min(max_views.max(1));
    let picked: Vec<&View> = (0..n).map(|i| &views[i * views.len() / n]).collect();
    let (mut t_field, mut t_baked) = (0.0, 0.0);
    let mut out = Vec::new();
    for (i, v) in picked.iter().enumerate() {
        let t0 = std::time::Instant::now();
        let field = render_camera(model, pool, &v.c2w, &v.intrinsics, v.time, bg);
        t_field += t0.elapsed().as_secs_f64();
        // The bake's own error compares like with like: the field drawn the way the asset's
        // renderers draw this camera (Header::pixel_rays_for).
        let k = asset.header.pixel_rays_for(&camera_of(v)) as usize;
        let centre = if model.pixel_rays != k {
            render_camera_with(model, pool, &v.c2w, &v.intrinsics, v.time, bg, k).rgb
        } else {
            field.rgb.clone()
        };
        let t0 = std::time::Instant::now();
        let baked = render(asset, &camera_of(v), v.time.unwrap_or(0.0));
        t_baked += t0.elapsed().as_secs_f64();
        let truth = ground_truth(v, bg);
        let clamp = |x: &[f32]| x.iter().map(|v| v.clamp(0.0, 1.0)).collect::<Vec<f32>>();
        let f = clamp(&field.rgb);
        out.push(ViewFaithfulness {
            name: v.path.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| format!("view_{i}")),
            time: v.time,
            baked_vs_field: psnr(&baked.rgb, &clamp(&centre)),
            field_vs_truth: psnr(&f, &truth),
            field_as_asset_vs_truth: psnr(&clamp(&centre), &truth),
            baked_vs_truth: psnr(&baked.rgb, &truth),
        });
    }
    let mean = |f: &dyn Fn(&ViewFaithfulness) -> f64| out.iter().map(f).sum::<f64>() / out.len().max(1) as f64;
    let (bf, ft, bt) = (mean(&|v| v.baked_vs_field), mean(&|v| v.field_vs_truth), mean(&|v| v.baked_vs_truth));
    let f1 = mean(&|v| v.field_as_asset_vs_truth);
    Ok(Faithfulness {
        views: out,
        mean_baked_vs_field: bf,
        mean_field_vs_truth: ft,
        mean_field_as_asset_vs_truth: f1,
        mean_baked_vs_truth: bt,
        drop_db: ft - bt,
        bake_loss_db: f1 - bt,
        seconds_field: t_field,
        seconds_baked: t_baked,
    })
}
