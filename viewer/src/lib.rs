//! snerf-viewer: renders baked assets in real time (wgpu/winit) and streams them over QUIC.
//!
//! Uses only `snerf-asset`, never the trainer, so a headset client stays small.
//! The renderer lands with issue 5 and streaming with issue 6; nothing here yet.
