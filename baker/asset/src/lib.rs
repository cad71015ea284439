//! snerf-asset: the baked scene file of snerf and a CPU reference renderer for it.
//!
//! A baked scene is a sparse voxel grid over grid space [-1,1]^3: a coarse indirection grid
//! (one u32 per cell and keyframe) points into an atlas of 8-bit blocks (density code,
//! diffuse RGB, 4 specular features, each block with a 1-voxel apron), plus the tiny view
//! MLP that turns composited diffuse + features + direction into specular colour. A diffuse
//! asset (the MLP's output layer zero) leaves the MLP and the features out of its file.
//!
//! Data flow:
//! - baker: `AssetBuilder` (header + blocks per cell/frame) -> `Asset` -> `Asset::write`
//!   (atomic) -> file = preamble + chunks (`chunk`), layout in FORMAT.md.
//! - viewer / `snerf inspect`: `Asset::read` -> `chunk` framing + CRC -> `Assembler`
//!   (validates every size before allocating) -> `Asset` -> `sample` / `render` / `summary`.
//! - streaming: the server splits a file with `chunks()` and sends HEAD first; the client
//!   feeds an `Assembler` whatever arrives and renders the partial asset meanwhile.
//! - styles as layers (`layers`, format version 3): one shared geometry (grids, density)
//!   and one colour part per style (view MLP, colours of the live voxels);
//!   `LayeredAsset` holds every style as a single-style `Asset`, and `Asset::read` of such a
//!   file gives its first style.
//!
//! Depends on nothing from the trainer so a headset client can read assets without it; the
//! renderer reproduces the trainer's march so a GPU shader can be checked against it.

// `!(x < y)` and `.max(0.0).min(1.0)` are deliberate: both send NaN down the safe branch
// (clamp() would pass NaN through). `%` instead of is_multiple_of keeps the 1.80 MSRV.
#![allow(clippy::neg_cmp_op_on_partial_ord, clippy::manual_clamp, clippy::manual_is_multiple_of)]

pub mod assemble;
pub mod asset;
pub mod atomic;
pub mod builder;
pub mod chunk;
pub mod header;
pub mod layers;
pub mod mlp;
pub mod motion;
pub mod quantize;
pub mod render;
pub mod sample;
pub mod summary;

pub use assemble::{parse_head, Assembler};
pub use asset::{Asset, EMPTY};
pub use builder::AssetBuilder;
pub use chunk::{chunks, encode_chunk, preamble, ChunkRef};
pub use header::{DensityRange, Header, Keyframe, Kind, March, MlpShape, Ndc, Space, StyleInfo};
pub use layers::{LayeredAsset, Recolour, StyleBytes};
pub use mlp::ViewMlp;
pub use quantize::{decode_density, encode_density, encode_voxel, quantize_unit};
pub use render::{contact_strip, orbit, render, render_pixel, render_ray, write_png, Camera, Frame, PixelResult};
pub use sample::{Loc, Source, TimeSlot};
pub use summary::{PartBytes, PartRates, Summary};
