//! snerf-viewer: renders baked assets in real time (wgpu/winit) and streams them over QUIC.
//!
//! Uses only `snerf-asset`, `snerf-geometry` and `snerf-stream`, never the trainer, so a
//! headset client stays small.
//!
//! Data flow: an `AssetSource` (a `FileSource`, or a `StreamSource` over a `snerf-stream`
//! live client) yields an `Asset` and later block updates (`AssetUpdate::apply` is what
//! they do to the CPU copy) -> `GpuRenderer` uploads the atlas into a 3D texture of (block+2)^3-voxel
//! blocks (one rg32uint texel per voxel), the indirection grids into a storage buffer and
//! the view MLP into a uniform buffer ->
//! per frame, `shaders/march.wgsl` (built for the scene's kind and static/dynamic only)
//! ray-marches each pixel exactly like `snerf_asset::render` (the CPU reference) into a
//! float buffer -> the window presents it (`shaders/present.wgsl`), headless callers read
//! it back as a `snerf_asset::Frame`. `bench_view` times the GPU path against the CPU
//! reference renderer in the same run.

pub mod bench;
pub mod camera;
pub mod gpu;
pub mod headless;
pub mod stream_source;
pub mod window;

pub use bench::{bench_view, bench_view_with, BenchOptions, BenchView, DiffuseBench, StereoBench};
pub use camera::{
    camera_from_c2w, initial_camera, load_poses, stereo_pair, Controller, PoseSample,
};
pub use gpu::{
    gpu_available, shader_source, shader_variant, AtlasLayout, DeviceLostError, GpuContext, GpuOptions,
    GpuRenderer, LimitError, NoAdapterError, View,
};
pub use headless::{render_frames, render_frames_or_cpu, render_frames_with, RenderedBy};
pub use wgpu;
pub use stream_source::StreamSource;
pub use window::{keys_help, run_window, Applied, AssetSource, AssetUpdate, FileSource, ViewOptions};
