//! The report a running job keeps of itself in `RUN/report/`: `snerf train` and `snerf
//! stylize` redraw it as their records grow, so a person looking at a running job sees its
//! curve without running `snerf report`.

use std::path::Path;
use std::time::Instant;

use serde_json::Value;

use crate::{pages, sources, Source};

/// Where a run keeps its own report.
pub const RUN_REPORT_DIR: &str = "report";

fn label_of(run: &Path) -> String {
    let p = std::fs::canonicalize(run).unwrap_or_else(|_| run.to_path_buf());
    p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "run".into())
}

/// The live report of a running job, written into `RUN/report/`. A failure to draw is said
/// once and never stops the job: the pictures are a view on the records, not the records.
pub struct LiveReport {
    pub seconds: f64,
    pub writes: usize,
    warned: bool,
}

impl Default for LiveReport {
    fn default() -> Self {
        Self::new()
    }
}

impl LiveReport {
    pub fn new() -> LiveReport {
        LiveReport { seconds: 0.0, writes: 0, warned: false }
    }

    fn write(&mut self, run: &Path, source: Source) {
        let t0 = Instant::now();
        let title = format!("{} — {}", source.label, if source.kind == crate::SourceKind::Train { "training" } else { "stylization" });
        let dir = run.join(RUN_REPORT_DIR);
        let opts = pages::Options { title, compare: None, svg: true };
        // a defect in drawing must not cost a training run
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| crate::write_report(&[source], &dir, &opts)))
            .unwrap_or_else(|_| Err(anyhow::anyhow!("drawing panicked")));
        self.seconds += t0.elapsed().as_secs_f64();
        self.writes += 1;
        if let Err(e) = r {
            if !self.warned {
                eprintln!("warning: the run's report could not be written ({e:#}); training goes on");
                self.warned = true;
            }
        }
    }

    /// A training run's curve as it stands (`metrics` as `run::metrics_json` gives it).
    pub fn train(&mut self, run: &Path, metrics: Value) {
        let eval_path = run.join(sources::EVAL);
        let eval = std::fs::read(&eval_path).ok().and_then(|b| serde_json::from_slice(&b).ok());
        self.write(run, Source::train(&label_of(run), run, metrics, eval));
    }

    /// A stylization run's rounds as they stand (`state` as `stylize.json` holds it).
    pub fn stylize(&mut self, run: &Path, state: Value) {
        let c = run.join(sources::CONSISTENCY);
        let consistency = std::fs::read(&c).ok().and_then(|b| serde_json::from_slice(&b).ok());
        self.write(run, Source::stylize(&label_of(run), run, state, consistency));
    }
}
