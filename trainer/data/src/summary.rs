//! A JSON summary of a loaded dataset, for the CLI's `--json` output.

use serde_json::{json, Value};

use crate::Dataset;

/// Format, kind, dynamic, detection note, view counts per split, distinct image sizes, the first
/// view's intrinsics, near/far, aabb and time range.
pub fn summary(ds: &Dataset) -> Value {
    let mut sizes: Vec<[u32; 2]> = Vec::new();
    for v in ds.all_views() {
        let s = [v.intrinsics.width, v.intrinsics.height];
        if !sizes.contains(&s) {
            sizes.push(s);
        }
    }
    json!({
        "root": ds.root.display().to_string(),
        "format": ds.format,
        "kind": ds.kind.as_str(),
        "dynamic": ds.dynamic,
        "detection_note": ds.detection_note,
        "counts": { "train": ds.train.len(), "val": ds.val.len(), "test": ds.test.len() },
        "image_sizes": sizes,
        "intrinsics": ds.all_views().next().map(|v| serde_json::to_value(v.intrinsics).unwrap_or(Value::Null)),
        "near_far": ds.near_far.map(|(n, f)| [n, f]),
        "aabb": ds.aabb.map(|(a, b)| [a, b]),
        "time_range": ds.time_range().map(|(a, b)| [a, b]),
    })
}
