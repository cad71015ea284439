//! snerf-report: error against run time, as pictures.
//!
//! The numbers a user wants to see while choosing a budget live in JSON records written by
//! the other commands: `metrics.json` of a training run (held-out PSNR against training
//! seconds), `stylize.json` of a stylization run (style distance and consistency per
//! round), bake summaries (faithfulness and size per resolution; for 4D bakes, bytes per
//! second of animation against fidelity at held-out times) and `quality.json` of the
//! quality benchmark. This crate reads any of them ([`sources`]), turns them into plots with
//! the exact numbers behind them ([`plots`]), draws the plots as PNG and SVG with a font
//! compiled into the binary so a headless machine needs nothing installed ([`draw`]), and
//! writes `report.md`, a self-contained `report.html` and `report.json` ([`pages`]).
//! [`compare`] sets two runs of the same data side by side at equal times; [`live`] keeps a
//! running job's own report up to date.
//!
//! It depends on no trainer crate: the records are read as JSON, so the training library
//! stays free of drawing code and a report can be drawn from records alone.

pub mod base64;
pub mod compare;
pub mod draw;
pub mod font;
pub mod live;
pub mod model;
pub mod pages;
pub mod plots;
pub mod sources;

pub use model::{HLine, Plot, Series, Table};
pub use pages::{write_plots, write_report, Options, Written};
pub use sources::{load, load_all, Source, SourceKind};
