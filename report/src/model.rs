//! What a report is made of: plots (series of exact numbers, reference lines) and the table
//! that goes beside each plot. Everything drawn is in these structures, and these structures
//! are what `report.json` holds, so the pictures never show a number the JSON lacks.

use serde::Serialize;

/// One line on a plot: the points of one metric of one run, in the source's units.
#[derive(Clone, Debug, Serialize)]
pub struct Series {
    /// The run (source) label; a run keeps its colour on every plot.
    pub run: String,
    /// Which record field the points come from (e.g. `test_psnr`).
    pub metric: String,
    /// The legend text.
    pub label: String,
    /// Palette index of the run.
    pub color: usize,
    /// Dashed lines mark a secondary metric (train PSNR beside held-out PSNR, long range
    /// beside short range).
    pub dashed: bool,
    /// Draw a marker at each point (records with a few points: rounds, resolutions).
    pub markers: bool,
    /// (x, y) in the axis units.
    pub points: Vec<[f64; 2]>,
}

/// A horizontal reference line (a baseline or a floor a curve is read against).
#[derive(Clone, Debug, Serialize)]
pub struct HLine {
    pub run: String,
    pub label: String,
    pub y: f64,
    /// 0: a baseline to beat, 1: a floor nothing reaches.
    pub role: usize,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct Table {
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

impl Table {
    pub fn markdown(&self) -> String {
        if self.header.is_empty() {
            return String::new();
        }
        let mut s = format!("| {} |\n|{}\n", self.header.join(" | "), "---|".repeat(self.header.len()));
        for r in &self.rows {
            s.push_str(&format!("| {} |\n", r.join(" | ")));
        }
        s
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct Plot {
    /// File stem of the pictures (`ID.png`, `ID.svg`).
    pub id: String,
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub series: Vec<Series>,
    pub hlines: Vec<HLine>,
    pub table: Table,
}

impl Plot {
    pub fn new(id: &str, title: &str, x_label: &str, y_label: &str, log_x: bool) -> Plot {
        Plot {
            id: id.into(),
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            log_x,
            series: Vec::new(),
            hlines: Vec::new(),
            table: Table::default(),
        }
    }

    /// Nothing to draw: no series with a point.
    pub fn is_empty(&self) -> bool {
        self.series.iter().all(|s| s.points.is_empty())
    }

    /// The x and y ranges covering every point and reference line (x > 0 on a log axis).
    pub fn bounds(&self) -> Option<([f64; 2], [f64; 2])> {
        let (mut x, mut y) = ([f64::MAX, f64::MIN], [f64::MAX, f64::MIN]);
        for p in self.series.iter().flat_map(|s| &s.points) {
            if !(p[0].is_finite() && p[1].is_finite()) || (self.log_x && p[0] <= 0.0) {
                continue;
            }
            x = [x[0].min(p[0]), x[1].max(p[0])];
            y = [y[0].min(p[1]), y[1].max(p[1])];
        }
        if x[0] > x[1] {
            return None;
        }
        for h in self.hlines.iter().filter(|h| h.y.is_finite()) {
            y = [y[0].min(h.y), y[1].max(h.y)];
        }
        Some((x, y))
    }
}
