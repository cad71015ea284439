//! snerf-geometry: every piece of scene math that more than one stage needs, defined once.
//!
//! The trainer marches rays through its field, the baker samples the field on a grid, the
//! asset's CPU reference renderer and the viewer's GPU shader march the baked grid, and the
//! stream server plans which blocks a pose needs. They must agree to the last bit on how a
//! world point becomes a grid point, where a ray starts and stops, and where the camera of
//! a turntable stands. This crate is that agreement; it depends on nothing heavier than glam
//! and serde so a headset client can use it without any trainer code.
//!
//! - `vec`: 3-vectors as `[f32; 3]` (the serialized form) with glam doing the arithmetic.
//! - `kind`: the three scene kinds and what each switches on.
//! - `space`: world -> model (a similarity) and model -> grid (identity, NDC or contraction).
//! - `contract`, `ndc`: MERF's contraction and LLFF's NDC with their inverses.
//! - `march`: constants every marcher shares (and the WGSL prelude generated from them).
//! - `camera`: pinhole rays, look-at, the one orbit and the scene's up direction.
//! - `camera_path`: nerfstudio's `camera_path.json`, read and written.
//! - `silhouette`: which pixels are drawn as the mean over their square, and their rays.
//! - `time`: which keyframes bracket a time.
//! - `view_mlp`: the view-dependent colour MLP's input encoding and layers.
//! - `sym3`: eigenvalues and eigenvectors of a symmetric 3×3 matrix (covariances).

// `!(x < y)` is deliberate: it sends NaN down the safe branch (a degenerate ray misses,
// a NaN time is the first frame), which `x >= y` would not.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod camera;
pub mod camera_path;
pub mod contract;
pub mod kind;
pub mod march;
pub mod ndc;
pub mod silhouette;
pub mod space;
pub mod sym3;
pub mod time;
pub mod vec;
pub mod view_mlp;

pub use camera::{look_at, Orbit, Pinhole};
pub use contract::{contract, uncontract, unbounded_dt};
pub use kind::SceneKind;
pub use march::box_hit;
pub use ndc::Ndc;
pub use space::{MarchRay, Space};
pub use time::{time_slot, TimeSlot};
pub use vec::Vec3;
