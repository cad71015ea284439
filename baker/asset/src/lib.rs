//! snerf-asset: the baked scene file (indirection grid + 3D atlas of 8-bit blocks + view MLP).
//!
//! Depends on nothing from the trainer so a headset client can read assets without it.
//! The format itself lands with issue 4; this crate is intentionally empty until then.
