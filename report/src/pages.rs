//! The report on disk: one PNG and one SVG per plot, `report.md` (pictures and tables),
//! `report.html` (the same, self-contained: pictures inlined as data URIs, so it can be
//! mailed or attached to a ticket as one file) and `report.json` (every plotted number).
//! Every file is replaced atomically, so a reader never sees half a report, even while a
//! training run rewrites it at each checkpoint.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde_json::{json, Value};

use crate::compare;
use crate::draw;
use crate::model::{Plot, Table};
use crate::plots;
use crate::sources::Source;

pub const JSON: &str = "report.json";
pub const MD: &str = "report.md";
pub const HTML: &str = "report.html";

#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Heading of the pages.
    pub title: String,
    /// Compare these two source labels (A, B): B − A at equal times under each plot.
    pub compare: Option<(String, String)>,
    /// Write the SVG pictures too (the per-checkpoint report of a running job skips nothing,
    /// but a caller may).
    pub svg: bool,
}

/// What was written.
#[derive(Clone, Debug)]
pub struct Written {
    pub files: Vec<PathBuf>,
    /// The content of `report.json`.
    pub json: Value,
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn html_table(t: &Table) -> String {
    if t.header.is_empty() || t.rows.is_empty() {
        return String::new();
    }
    let mut s = String::from("<table><thead><tr>");
    for h in &t.header {
        s.push_str(&format!("<th>{}</th>", esc(h)));
    }
    s.push_str("</tr></thead><tbody>");
    for r in &t.rows {
        s.push_str("<tr>");
        for c in r {
            s.push_str(&format!("<td>{}</td>", esc(c)));
        }
        s.push_str("</tr>");
    }
    s.push_str("</tbody></table>");
    s
}

const STYLE: &str = "body{font-family:sans-serif;margin:2em;color:#222}section{margin-bottom:2.5em}\
.row{display:flex;flex-wrap:wrap;gap:1.5em;align-items:flex-start}img{max-width:100%;border:1px solid #ddd}\
table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}\
td:first-child,th:first-child{text-align:left}th{background:#f3f3f3}.src{font-size:13px;color:#555}";

/// The sources as JSON; JSON holds UTF-8 only, so a path that is not is written lossily
/// rather than failing after the drawing is done.
fn sources_json(sources: &[Source]) -> Value {
    let lossy = |p: &Path| Value::String(p.to_string_lossy().into_owned());
    Value::Array(
        sources
            .iter()
            .map(|s| json!({ "kind": s.kind, "label": s.label, "path": lossy(&s.path), "files": s.files.iter().map(|f| lossy(f)).collect::<Vec<_>>() }))
            .collect(),
    )
}

/// Build the plots of `sources` and write the report into `dir` (created if missing).
pub fn write_report(sources: &[Source], dir: &Path, opts: &Options) -> Result<Written> {
    let plots = plots::build(sources);
    write_plots(sources, &plots, dir, opts)
}

pub fn write_plots(sources: &[Source], plots: &[Plot], dir: &Path, opts: &Options) -> Result<Written> {
    std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create", dir.display()))?;
    let (w, h) = draw::SIZE;
    let mut files = Vec::new();
    let mut md = format!("# {}\n\n", opts.title);
    let mut html = format!(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{0}</title><style>{STYLE}</style></head><body>\n<h1>{0}</h1>\n",
        esc(&opts.title)
    );
    let mut src_md = String::from("Sources:\n\n");
    let mut src_html = String::from("<ul class=\"src\">");
    for s in sources {
        let files: Vec<String> = s.files.iter().map(|f| f.display().to_string()).collect();
        src_md.push_str(&format!("- **{}** ({:?}): {}\n", s.label, s.kind, if files.is_empty() { s.path.display().to_string() } else { files.join(", ") }));
        src_html.push_str(&format!("<li><b>{}</b> ({:?}): {}</li>", esc(&s.label), s.kind, esc(&if files.is_empty() { s.path.display().to_string() } else { files.join(", ") })));
    }
    md.push_str(&src_md);
    md.push('\n');
    html.push_str(&src_html);
    html.push_str("</ul>\n");
    let mut plots_json = Vec::new();
    let mut compare_json = Vec::new();
    for p in plots {
        let png = draw::png(p, w, h)?;
        let png_path = dir.join(format!("{}.png", p.id));
        snerf_files::write_atomic(&png_path, &png)?;
        files.push(png_path);
        if opts.svg {
            let svg_path = dir.join(format!("{}.svg", p.id));
            snerf_files::write_atomic(&svg_path, draw::svg(p, w, h)?.as_bytes())?;
            files.push(svg_path);
        }
        let cmp = opts.compare.as_ref().map(|(a, b)| {
            let rows = compare::rows(p, a, b);
            let t = compare::table(p, &rows, a, b);
            compare_json.push(json!({ "plot": p.id, "a": a, "b": b, "rows": rows }));
            t
        });
        md.push_str(&format!("## {}\n\n![{}]({}.png)", p.title, p.title, p.id));
        if opts.svg {
            md.push_str(&format!(" ([SVG]({}.svg))", p.id));
        }
        md.push_str("\n\n");
        md.push_str(&p.table.markdown());
        html.push_str(&format!(
            "<section><h2>{}</h2><div class=\"row\"><img alt=\"{}\" src=\"data:image/png;base64,{}\" width=\"{w}\" height=\"{h}\"><div>{}",
            esc(&p.title),
            esc(&p.title),
            crate::base64::encode(&png),
            html_table(&p.table)
        ));
        if let Some(t) = &cmp {
            md.push_str(&format!("\nAt equal times ({}):\n\n{}", p.x_label, t.markdown()));
            if !t.rows.is_empty() {
                html.push_str(&format!("<p>At equal times ({}):</p>{}", esc(&p.x_label), html_table(t)));
            }
        }
        md.push('\n');
        html.push_str("</div></div></section>\n");
        let mut v = serde_json::to_value(p)?;
        v["png"] = json!(format!("{}.png", p.id));
        v["svg"] = if opts.svg { json!(format!("{}.svg", p.id)) } else { Value::Null };
        plots_json.push(v);
    }
    if plots.is_empty() {
        md.push_str("Nothing to plot yet: the records hold no measurement.\n");
        html.push_str("<p>Nothing to plot yet: the records hold no measurement.</p>\n");
    }
    html.push_str("</body></html>\n");
    let doc = json!({
        "command": "report",
        "title": opts.title,
        "sources": sources_json(sources),
        "plots": plots_json,
        "compare": if opts.compare.is_some() { Value::Array(compare_json) } else { Value::Null },
    });
    for (name, bytes) in [(MD, md.into_bytes()), (HTML, html.into_bytes()), (JSON, serde_json::to_vec_pretty(&doc)?)] {
        let p = dir.join(name);
        snerf_files::write_atomic(&p, &bytes)?;
        files.push(p);
    }
    Ok(Written { files, json: doc })
}
