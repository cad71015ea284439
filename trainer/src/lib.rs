//! snerf-trainer: learns a radiance field from posed views, fast on a CPU.
//!
//! Data flow: `snerf_data::load` gives posed RGBA views -> `space` maps the world into the
//! field's grid (box, NDC or contraction, by scene kind) -> `train` samples random rays
//! across views and runs the fused `render` pipeline (occupancy-skipping march, K-Planes
//! `field` encode + decoder, stable `composite`, per-ray `view_mlp`) forward and backward on
//! rayon workers -> `adam` updates the one flat parameter vector -> `checkpoint` writes it
//! atomically. `eval` renders held-out views and scores them with `metrics`. `run` trains into a
//! run directory whose layout (and reading back: dataset, model) `run_dir` owns.
//!
//! Modules are layered, each naming only modules of its own layer or below (no cycles;
//! `tests/architecture.rs` checks it):
//! 1. core: `rng`, `orbit`, `space`, `metrics`, `png`, `adam`, `composite`, `occupancy`,
//!    `appearance` (per-photo colour transforms the training loss sees), `free_space`
//!    (carving the occupancy grid along the lines of sight of a capture's sparse points);
//! 2. the field and its rendering: `view_mlp`, `deform` (a dynamic field's motion), `field`,
//!    `render`;
//! 3. `model` (what a renderer needs of a trained field);
//! 4. `train`, `eval`;
//! 5. `checkpoint` (a trainer's state on disk), `camera_path` (rendering a path), `run`,
//!    `run_dir`.

// Index loops over parallel fixed-size arrays (channels, axes, samples) read as the
// formulas they implement; iterator zips of three or four arrays would not.
#![allow(clippy::needless_range_loop)]

pub use snerf_data as data;

pub mod adam;
pub mod appearance;
pub mod camera_path;
pub mod checkpoint;
pub mod composite;
pub mod deform;
pub mod eval;
pub mod field;
pub mod free_space;
pub mod metrics;
pub mod model;
pub mod occupancy;
pub mod orbit;
pub mod png;
pub mod render;
pub mod rng;
pub mod run;
pub mod run_dir;
pub mod space;
pub mod train;
pub mod view_mlp;
