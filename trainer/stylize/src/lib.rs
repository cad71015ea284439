//! snerf-stylize: image stylizers behind one trait, and the SNeRF loop that uses them.
//!
//! - `stylizer`: `Stylizer::stylize(content) -> stylized` for `arbitrary`, `preset:N`,
//!   `onnx:FILE`, `gatys`, `color`; model files, style images, style embeddings.
//! - `snerf_loop`: Algorithm 1 of SNeRF — render the training views from the field, stylize
//!   each, train the field on random rays across them, repeat; every round checkpointed.
//! - `consistency`: the paper's cross-view consistency (warped-frame error, short and long
//!   range) and style distances, for SNeRF and the per-frame baseline.
//! - `style_metric`: a weight-free style distance (how much of the painting's palette the scene
//!   covers, in Oklab, and sliced Wasserstein over texture patches, each in units of the
//!   painting's own variation) that no stylizer aims at.
//! - `temporal`: a 4D scene's flicker at a fixed camera between neighbouring times, on the
//!   pixels the realistic frames show still, for SNeRF and the per-frame baseline.
//! - `style_gram`: a style distance on Gram matrices of ImageNet features (independent of
//!   every stylizer but `gatys`, which minimizes it).
//! - `fusion`: multi-view fusion of the stylized targets through the field's depth (a median
//!   over neighbouring views, or one painter per surface point).
//! - `reproject`: one view's colour at a world point (occlusion test; bilinear over the
//!   pixels that show that surface, or the nearest of them); fusion and the consistency
//!   measurement share it.
//! - `palette`: keeps the consensus rounds from narrowing the painting's colours (a
//!   per-channel Oklab quantile map onto the first fused stylizations).
//! - `colour_offsets`: what a field trained on painted views falls short of, per colour, so
//!   that the targets make it up.
//! - `paintings`: the real paintings used as styles by tests and benchmarks.
//! - `layers`: a run stylized after several paintings, one appearance-only stylized run per
//!   style under one directory, which `snerf bake` turns into one multi-style asset.
//!
//! The stylizer and the field never hold the machine at once: a round renders, then
//! stylizes, then trains, each phase with every core.

// Index loops over parallel image/channel arrays read as the formulas they implement, and
// the GEMM keeps BLAS's argument list.
#![allow(clippy::needless_range_loop, clippy::too_many_arguments)]

pub mod colour_offsets;
pub mod consistency;
pub mod fusion;
pub mod layers;
pub mod paintings;
pub mod palette;
pub mod reproject;
pub mod snerf_loop;
pub mod style_gram;
pub mod style_metric;
pub mod temporal;
pub mod stylize_view;
pub mod stylizer;
