//! snerf-files: every file snerf writes goes through here, so that no command can lose a
//! user's data.
//!
//! - `atomic`: replace a file by writing a temp file beside it, fsync, rename; temp files are
//!   removed on failure, on Ctrl-C, and (left by a killed process) on the next write into the
//!   same directory.
//! - `guard`: one output-path check for every command — an output may never be one of the
//!   command's inputs or lie inside an input tree — and ownership manifests, so a directory is
//!   replaced only when snerf can prove it wrote every file in it.
//! - `lock`: an exclusive lock on a run directory (released by the kernel if the process dies).
//! - `interrupt`: Ctrl-C / SIGTERM handling: long jobs stop at a safe point and save; anything
//!   else cleans its temp files and exits.
//! - `scratch`: tests' temporary directories, removed when a test passes, kept when it fails.
//!
//! Depends on nothing of snerf's, so every crate (the viewer's included) can use it.

pub mod atomic;
pub mod guard;
pub mod interrupt;
pub mod lock;
pub mod scratch;

pub use atomic::{write_atomic, write_json_atomic};
pub use guard::{check_output, Input};
pub use lock::DirLock;
pub use scratch::ScratchDir;
