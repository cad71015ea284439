//! snerf-baker: turns a trained field into a baked asset (sparse grid + view MLP) and glTF.
//!
//! Data flow: trainer checkpoint -> `bake`: candidate blocks from the occupancy grid ->
//! dense evaluation of each block (+ apron) -> drop transparent and never-seen blocks ->
//! 8-bit quantization -> (dynamic scenes: `temporal` picks each cell's codebook of sampled
//! blocks within a size budget) -> `snerf_asset::Asset` (written by the asset crate). `faithfulness`
//! scores the baked asset against the field it came from. `layers` bakes further
//! appearance-only stylizations of the same geometry as colour onto a baked asset (one
//! multi-style asset). `marching_cubes` + `gltf_export`
//! turn the baked density and colour into a mesh for engines; `splats` + `splat_gltf` turn the
//! baked voxels into Gaussian splats (glTF `KHR_gaussian_splatting`) for engines that draw them.

// Index loops over parallel per-voxel arrays read as the formulas they implement.
#![allow(clippy::needless_range_loop)]

pub mod bake;
pub mod checks;
pub mod faithfulness;
pub mod gltf_export;
pub mod layers;
pub mod marching_cubes;
pub mod mesh_export;
pub mod motion;
pub mod splat_gltf;
pub mod splats;
pub mod temporal;
