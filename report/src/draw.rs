//! Plots drawn with plotters: PNG (through `image`) and SVG from the same drawing code.
//!
//! Lines are drawn 2 px wide without anti-aliasing and in a fixed palette, so a picture can
//! be checked by its pixels (which run colours are present) as well as looked at.

use anyhow::{anyhow, Result};
use plotters::coord::ranged1d::{Ranged, ValueFormatter};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::font::{self, FAMILY};
use crate::model::Plot;

/// Run colours (a run keeps its colour on every plot; more than ten runs reuse them).
pub const PALETTE: [(u8, u8, u8); 10] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (188, 189, 34),
    (23, 190, 207),
    (0, 0, 128),
];

/// Reference lines: a baseline to beat (0), a floor (1).
pub const REFERENCE: [(u8, u8, u8); 2] = [(90, 90, 90), (170, 170, 170)];

pub fn run_color(i: usize) -> RGBColor {
    let (r, g, b) = PALETTE[i % PALETTE.len()];
    RGBColor(r, g, b)
}

/// Picture size of a plot in the report.
pub const SIZE: (u32, u32) = (800, 480);

fn err<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow!("drawing a plot: {e:?}")
}

/// A number as an axis shows it: 3 significant digits, with k/M/G for large values.
pub fn short(v: f64) -> String {
    let a = v.abs();
    let (x, suffix) = if a >= 1e9 {
        (v / 1e9, "G")
    } else if a >= 1e6 {
        (v / 1e6, "M")
    } else if a >= 1e4 {
        (v / 1e3, "k")
    } else {
        (v, "")
    };
    let ax = x.abs();
    let digits = if ax == 0.0 || ax >= 100.0 { 0 } else if ax >= 10.0 { 1 } else if ax >= 1.0 { 2 } else { 3 };
    let mut s = format!("{x:.digits$}");
    if s.contains('.') {
        s = s.trim_end_matches('0').trim_end_matches('.').to_string();
    }
    format!("{s}{suffix}")
}

fn padded(lo: f64, hi: f64, log: bool) -> (f64, f64) {
    if log {
        let (lo, hi) = (lo.max(1e-9), hi.max(1e-9));
        if hi / lo < 1.01 {
            return (lo / 2.0, hi * 2.0);
        }
        return (lo / 1.15, hi * 1.15);
    }
    let span = hi - lo;
    if span <= f64::EPSILON * hi.abs().max(1.0) {
        let d = (hi.abs() * 0.1).max(1e-3);
        return (lo - d, hi + d);
    }
    (lo - 0.06 * span, hi + 0.06 * span)
}

/// Ticks of a log axis: 1-2-5 per decade, or every integer mantissa when that gives fewer
/// than three (plotters' own log ticks are whole decades, so a short run gets none).
pub fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let decades = (lo.log10().floor() as i32)..=(hi.log10().ceil() as i32);
    let pick = |mantissas: &[f64]| -> Vec<f64> {
        decades.clone().flat_map(|e| mantissas.iter().map(move |m| m * 10f64.powi(e))).filter(|&v| v >= lo && v <= hi).collect()
    };
    let t = pick(&[1.0, 2.0, 5.0]);
    if t.len() >= 3 {
        return t;
    }
    let t = pick(&[1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]);
    if t.len() >= 3 {
        return t;
    }
    // narrower than a mantissa step: evenly spaced
    (0..5).map(|i| lo + (hi - lo) * (i as f64 + 0.5) / 5.0).collect()
}

/// Draw `plot` on `root` (any backend, any size).
/// Reference lines named in a plot's legend at most (two runs' worth).
pub const MAX_LABELLED_REFERENCES: usize = 4;

pub fn draw<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, plot: &Plot) -> Result<()> {
    font::register();
    root.fill(&WHITE).map_err(err)?;
    let (w, h) = root.dim_in_pixel();
    let scale = (w.min(h * 5 / 3) as f64 / 800.0).clamp(0.75, 2.0);
    let Some((xb, yb)) = plot.bounds() else {
        root.draw(&Text::new(format!("{}: no data yet", plot.title), (10, 10), (FAMILY, 16.0 * scale).into_font())).map_err(err)?;
        return Ok(());
    };
    let (y0, y1) = padded(yb[0], yb[1], false);
    let (x0, x1) = padded(xb[0], xb[1], plot.log_x);
    let mut builder = ChartBuilder::on(root);
    builder
        .caption(&plot.title, (FAMILY, 20.0 * scale).into_font())
        .margin((12.0 * scale) as u32)
        .x_label_area_size((44.0 * scale) as u32)
        .y_label_area_size((64.0 * scale) as u32);
    if plot.log_x {
        let chart = builder.build_cartesian_2d((x0..x1).log_scale().with_key_points(log_ticks(x0, x1)), y0..y1).map_err(err)?;
        body(chart, plot, scale)
    } else {
        let chart = builder.build_cartesian_2d(x0..x1, y0..y1).map_err(err)?;
        body(chart, plot, scale)
    }
}

fn body<'a, DB: DrawingBackend + 'a, X>(mut chart: ChartContext<'a, DB, Cartesian2d<X, RangedCoordf64>>, plot: &Plot, scale: f64) -> Result<()>
where
    X: Ranged<ValueType = f64> + ValueFormatter<f64> + 'a,
{
    let label_font = (FAMILY, 14.0 * scale).into_font();
    let fx = |v: &f64| short(*v);
    let fy = |v: &f64| short(*v);
    chart
        .configure_mesh()
        .x_desc(plot.x_label.as_str())
        .y_desc(plot.y_label.as_str())
        .x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .label_style(label_font.clone())
        .axis_desc_style(label_font)
        .max_light_lines(2)
        .light_line_style(RGBColor(240, 240, 240))
        .bold_line_style(RGBColor(215, 215, 215))
        .axis_style(BLACK.stroke_width(1))
        .draw()
        .map_err(err)?;
    let lw = ((2.0 * scale).round() as u32).max(2);
    for s in &plot.series {
        if s.points.is_empty() {
            continue;
        }
        let color = run_color(s.color);
        let style = color.stroke_width(lw);
        let pts: Vec<(f64, f64)> = s.points.iter().map(|p| (p[0], p[1])).filter(|p| p.0.is_finite() && p.1.is_finite()).collect();
        let label = s.label.clone();
        let dashed = s.dashed;
        let legend = move |(x, y): (i32, i32)| {
            if dashed {
                PathElement::new(vec![(x, y), (x + 7, y)], style).into_dyn()
            } else {
                PathElement::new(vec![(x, y), (x + 18, y)], style).into_dyn()
            }
        };
        // A dashed line beside a solid one of the same run is its secondary metric (the
        // title says which): one legend entry per run keeps the legend off the curves.
        let secondary = s.dashed && plot.series.iter().any(|o| o.run == s.run && !o.dashed && !o.points.is_empty());
        if s.dashed {
            let d = (7.0 * scale) as i32;
            let drawn = chart.draw_series(DashedLineSeries::new(pts.clone(), d, d * 2 / 3, style)).map_err(err)?;
            if !secondary {
                drawn.label(label).legend(legend);
            }
        } else {
            chart.draw_series(LineSeries::new(pts.clone(), style)).map_err(err)?.label(label).legend(legend);
        }
        if s.markers {
            let r = (3.5 * scale).round() as i32;
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, r.max(2), color.filled()))).map_err(err)?;
        }
    }
    let xr = chart.x_range();
    // Each stylized run brings two reference lines; past two runs their legend entries would
    // outnumber the curves' and cover them, so they are drawn unlabelled (the table lists them).
    let label_references = plot.hlines.len() <= MAX_LABELLED_REFERENCES;
    for hl in &plot.hlines {
        let (r, g, b) = REFERENCE[hl.role.min(1)];
        let style = RGBColor(r, g, b).stroke_width(lw);
        let d = (5.0 * scale) as i32;
        let drawn = chart.draw_series(DashedLineSeries::new(vec![(xr.start, hl.y), (xr.end, hl.y)], d, d, style)).map_err(err)?;
        if label_references {
            drawn.label(hl.label.clone()).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 6, y)], style));
        }
    }
    let pos = match plot.id.as_str() {
        "psnr" | "bake_faithfulness" | "stylize_fit" | "ssim" => SeriesLabelPosition::LowerRight,
        _ => SeriesLabelPosition::UpperRight,
    };
    chart
        .configure_series_labels()
        .position(pos)
        .label_font((FAMILY, 12.0 * scale).into_font())
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(200, 200, 200))
        .draw()
        .map_err(err)?;
    Ok(())
}

/// The plot as an RGB picture of `w` x `h` pixels.
pub fn rgb(plot: &Plot, w: u32, h: u32) -> Result<image::RgbImage> {
    let mut buf = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        draw(&root, plot)?;
        root.present().map_err(err)?;
    }
    image::RgbImage::from_raw(w, h, buf).ok_or_else(|| anyhow!("plot buffer size"))
}

/// PNG file bytes of the plot.
pub fn png(plot: &Plot, w: u32, h: u32) -> Result<Vec<u8>> {
    let img = rgb(plot, w, h)?;
    let mut out = Vec::new();
    image::ImageEncoder::write_image(
        // fast deflate: a running job redraws its report at each curve point, and flat-colour
        // plots compress well at any level
        image::codecs::png::PngEncoder::new_with_quality(&mut out, image::codecs::png::CompressionType::Fast, image::codecs::png::FilterType::Adaptive),
        img.as_raw(),
        w,
        h,
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(out)
}

/// SVG text of the plot (text stays text: it scales and can be searched).
pub fn svg(plot: &Plot, w: u32, h: u32) -> Result<String> {
    let mut s = String::new();
    {
        let root = SVGBackend::with_string(&mut s, (w, h)).into_drawing_area();
        draw(&root, plot)?;
        root.present().map_err(err)?;
    }
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_numbers_read_short() {
        assert_eq!(short(1_250_000.0), "1.25M");
        assert_eq!(short(30.0), "30");
        assert_eq!(short(25.125), "25.1");
        assert_eq!(short(0.0123), "0.012");
        assert_eq!(short(18_000.0), "18k");
    }

    #[test]
    fn a_short_log_axis_still_has_ticks() {
        assert_eq!(log_ticks(1.0, 300.0), vec![1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0]);
        let t = log_ticks(2.0, 4.2);
        assert!(t.len() >= 3 && t.iter().all(|&v| (2.0..=4.2).contains(&v)), "{t:?}");
        assert_eq!(log_ticks(3.1, 3.2).len(), 5);
    }

    #[test]
    fn the_embedded_font_parses() {
        assert!(plotters::style::register_font("test-family", plotters::style::FontStyle::Normal, font::TTF).is_ok());
    }
}
