//! Ctrl-C and SIGTERM. A long job (training, stylization) marks itself with `Graceful`: the
//! first signal then only sets a flag, which the job polls at safe points (between steps) to
//! save its state and stop with `Interrupted`. Outside such a job, or on a second signal, the
//! process removes its live temp files and exits at once (130 for SIGINT, 143 for SIGTERM).
//!
//! A second signal counts only when it comes `SECOND_PRESS` or more after the first: a person
//! pressing Ctrl-C again. Signals within that time are the same request delivered twice, as
//! `timeout -s INT` or a terminal sends one to the process and another to its group; quitting
//! on those would lose the run the first one asked to save.
//!
//! Signals arrive on an ordinary thread (signal-hook's iterator), not in a signal handler,
//! so the cleanup may allocate and take locks.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Once, OnceLock};
use std::time::{Duration, Instant};

static REQUESTED: AtomicBool = AtomicBool::new(false);
static GRACEFUL: AtomicUsize = AtomicUsize::new(0);
static INSTALL: Once = Once::new();
static FIRST: OnceLock<Instant> = OnceLock::new();

/// Signals closer than this to the first are the same request (see the module doc).
pub const SECOND_PRESS: Duration = Duration::from_secs(1);

/// Exit status of a process stopped by SIGINT (the shell's convention, 128 + 2).
pub const EXIT_INTERRUPTED: u8 = 130;

/// Take over SIGINT and SIGTERM for this process (idempotent). Servers that shut down on
/// their own signal handling should not call this.
pub fn install() {
    INSTALL.call_once(|| {
        use signal_hook::consts::{SIGINT, SIGTERM};
        let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
            return; // keep the default behaviour: the process dies, the next run sweeps
        };
        std::thread::Builder::new()
            .name("snerf-signals".into())
            .spawn(move || {
                for sig in signals.forever() {
                    let graceful = GRACEFUL.load(Ordering::SeqCst) > 0;
                    if graceful && !REQUESTED.swap(true, Ordering::SeqCst) {
                        let _ = FIRST.set(Instant::now());
                        eprintln!(
                            "\nsnerf: interrupted; saving at the next safe point (press Ctrl-C again to quit at once)"
                        );
                        continue;
                    }
                    if graceful && FIRST.get().is_some_and(|t| t.elapsed() < SECOND_PRESS) {
                        continue; // the first request again, not a second press
                    }
                    crate::atomic::remove_live_temps();
                    std::process::exit(128 + sig);
                }
            })
            .ok();
    });
}

/// True once a signal asked a graceful job to stop.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::SeqCst)
}

/// While one lives, the first Ctrl-C asks the job to stop instead of killing the process.
pub struct Graceful(());

impl Graceful {
    pub fn enter() -> Graceful {
        GRACEFUL.fetch_add(1, Ordering::SeqCst);
        Graceful(())
    }
}

impl Drop for Graceful {
    fn drop(&mut self) {
        GRACEFUL.fetch_sub(1, Ordering::SeqCst);
    }
}

/// The error a job returns after it stopped on request and saved what it had.
#[derive(Debug)]
pub struct Interrupted(pub String);

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "interrupted: {}", self.0)
    }
}

impl std::error::Error for Interrupted {}

/// Whether an error chain ends in `Interrupted` (the command line exits 130 for it).
pub fn is_interrupted(e: &anyhow::Error) -> bool {
    e.chain().any(|c| c.is::<Interrupted>())
}
