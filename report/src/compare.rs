//! Two runs of the same data side by side: each curve read at the other's measurement
//! times (linear interpolation in time, inside the span both runs cover), so a difference
//! is always between equal times and never an extrapolation.

use crate::model::{Plot, Table};

/// `points` (sorted by x) read at `x`, linearly between neighbours; None outside their span.
pub fn interpolate(points: &[[f64; 2]], x: f64) -> Option<f64> {
    let (first, last) = (points.first()?, points.last()?);
    if x < first[0] || x > last[0] {
        return None;
    }
    let i = points.partition_point(|p| p[0] < x);
    let b = points[i.min(points.len() - 1)];
    if b[0] == x || i == 0 {
        return Some(b[1]);
    }
    let a = points[i - 1];
    let t = (x - a[0]) / (b[0] - a[0]);
    Some(a[1] + t * (b[1] - a[1]))
}

/// One row of a comparison: at time `x`, run A's and run B's value and B − A.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    pub metric: String,
    pub x: f64,
    pub a: f64,
    pub b: f64,
    pub b_minus_a: f64,
}

/// For every metric both runs have on `plot`: the union of their measurement times inside
/// the common span, each curve read there.
pub fn rows(plot: &Plot, a: &str, b: &str) -> Vec<Row> {
    let mut out = Vec::new();
    for sa in plot.series.iter().filter(|s| s.run == a) {
        let Some(sb) = plot.series.iter().find(|s| s.run == b && s.metric == sa.metric) else { continue };
        let mut xs: Vec<f64> = sa.points.iter().chain(&sb.points).map(|p| p[0]).collect();
        xs.sort_by(f64::total_cmp);
        xs.dedup();
        for x in xs {
            if let (Some(va), Some(vb)) = (interpolate(&sa.points, x), interpolate(&sb.points, x)) {
                out.push(Row { metric: sa.metric.clone(), x, a: va, b: vb, b_minus_a: vb - va });
            }
        }
    }
    out
}

pub fn table(plot: &Plot, rows: &[Row], a: &str, b: &str) -> Table {
    let mut t = Table { header: vec!["metric".into(), plot.x_label.clone(), a.into(), b.into(), format!("{b} − {a}")], rows: Vec::new() };
    for r in rows {
        let d = if r.a.abs().max(r.b.abs()) >= 1e4 { 0 } else { 4 };
        t.rows.push(vec![r.metric.clone(), format!("{:.2}", r.x), format!("{:.d$}", r.a), format!("{:.d$}", r.b), format!("{:+.d$}", r.b_minus_a)]);
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_between_points_and_not_outside() {
        let p = [[1.0, 10.0], [3.0, 20.0], [4.0, 20.0]];
        assert_eq!(interpolate(&p, 2.0), Some(15.0));
        assert_eq!(interpolate(&p, 1.0), Some(10.0));
        assert_eq!(interpolate(&p, 4.0), Some(20.0));
        assert_eq!(interpolate(&p, 0.5), None);
        assert_eq!(interpolate(&p, 4.5), None);
        assert_eq!(interpolate(&[], 1.0), None);
    }
}
