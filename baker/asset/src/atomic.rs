//! Crash-safe file replacement (readers see the old file or the new one, never a torn one):
//! the one implementation in `snerf-files`, re-exported for the asset's users.

pub use snerf_files::write_atomic;
