//! Style layers: one realistic run stylized after several paintings, each an appearance-only
//! stylization (geometry frozen, only colour learns), so that `snerf bake` stores the
//! geometry once and one colour part per style (`snerf_asset::layers`).
//!
//! A layered stylize run `SRUN` holds `SRUN/layers.json` (this module's `LayersRecord`) and
//! one ordinary stylized run directory per style, `SRUN/layers/<name>/`, which every reader
//! of a stylized run reads as usual. A style's name is its painting's key (`painting:vangogh`
//! → `vangogh`) or its file's stem, lowercased; names must differ.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};

/// The record of a layered run, in `SRUN/`.
pub const RECORD: &str = "layers.json";
/// The folder of the layers' run directories, in `SRUN/`.
pub const DIR: &str = "layers";
const FORMAT: &str = "snerf-style-layers";

/// One style of a layered run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LayerRecord {
    /// The style's name (`style_name`), also its folder under `layers/`.
    pub name: String,
    /// The style as `--style` gave it (a file or `painting:KEY`).
    pub source: String,
    /// Wall seconds its stylization took (absent until it has finished).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f64>,
}

/// `SRUN/layers.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LayersRecord {
    pub format: String,
    /// The realistic run every layer was stylized from.
    pub source_run: PathBuf,
    pub layers: Vec<LayerRecord>,
}

impl LayersRecord {
    /// A record for these styles (`--style` values, in order); fails when two give one name.
    pub fn new(source_run: &Path, styles: &[String]) -> Result<LayersRecord> {
        let mut layers: Vec<LayerRecord> = Vec::new();
        for s in styles {
            let name = style_name(s);
            if let Some(other) = layers.iter().find(|l| l.name == name) {
                bail!("--style {s} and --style {} would both be the layer {name:?}; give styles of different names", other.source);
            }
            layers.push(LayerRecord { name, source: s.clone(), seconds: None });
        }
        Ok(LayersRecord { format: FORMAT.into(), source_run: source_run.to_path_buf(), layers })
    }

    /// The run directory of layer `name` in `srun`.
    pub fn dir(srun: &Path, name: &str) -> PathBuf {
        srun.join(DIR).join(name)
    }

    /// The record of `srun`, or None when it is not a layered run.
    pub fn read(srun: &Path) -> Result<Option<LayersRecord>> {
        let path = srun.join(RECORD);
        if !path.exists() {
            return Ok(None);
        }
        let bytes = std::fs::read(&path).with_context(|| format!("{}: cannot read", path.display()))?;
        let r: LayersRecord = serde_json::from_slice(&bytes).with_context(|| format!("{}: not a style-layers record", path.display()))?;
        if r.format != FORMAT || r.layers.is_empty() {
            bail!("{}: not a style-layers record (format {:?}, {} layers)", path.display(), r.format, r.layers.len());
        }
        for l in &r.layers {
            if style_name(&l.name) != l.name {
                bail!("{}: layer name {:?} is not a folder name this record could have written", path.display(), l.name);
            }
        }
        Ok(Some(r))
    }

    pub fn write(&self, srun: &Path) -> Result<()> {
        snerf_files::write_json_atomic(&srun.join(RECORD), self)
    }
}

/// What a layer's stylization does where the command line does not say (several `--style`):
/// only the work an appearance-only layer needs. Its geometry is frozen, so a layer learns
/// only colour (the decoder's colour outputs and the colour head's hidden layer,
/// `snerf_trainer::field::ColourHead`) over a fixed set of surface points: fewer views cover
/// those points (a realistic run's 100 views see the
/// object from every side several times over), fewer steps fit them, and the per-round
/// measurement on the loop's own path (16 frames a round) is work for a comparison of
/// rounds, not for the layer; `snerf consistency` scores the layer afterwards.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct LayerPlan {
    /// Training views the rounds render, paint and train on (evenly spaced).
    pub views: usize,
    /// Training steps per round on average.
    pub steps_per_round: u64,
    /// Frames of the per-round measurement (0: none).
    pub consistency_frames: usize,
}

/// A layer's defaults (`LayerPlan`): BENCH.md "Style layers" measures them against the
/// single-style defaults.
pub const LAYER_DEFAULTS: LayerPlan = LayerPlan { views: 24, steps_per_round: 100, consistency_frames: 0 };

/// Where a stylization's time went, from its rounds' records: render, stylize and train
/// summed over the rounds, and the rest of the wall time (loading, the per-round
/// measurement, saving).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TimeSplit {
    pub render_seconds: f64,
    pub stylize_seconds: f64,
    pub train_seconds: f64,
    pub other_seconds: f64,
    pub wall_seconds: f64,
}

impl TimeSplit {
    /// The split of a run whose command took `wall` seconds.
    pub fn of(state: &crate::snerf_loop::StylizeState, wall: f64) -> TimeSplit {
        let sum = |f: fn(&crate::snerf_loop::RoundRecord) -> f64| state.records.iter().map(f).sum::<f64>();
        let (render, stylize, train) = (sum(|r| r.render_seconds), sum(|r| r.stylize_seconds), sum(|r| r.train_seconds));
        TimeSplit {
            render_seconds: render,
            stylize_seconds: stylize,
            train_seconds: train,
            other_seconds: (wall - render - stylize - train).max(0.0),
            wall_seconds: wall,
        }
    }

    /// `52 s: render 9 s, stylize 14 s, train 21 s, other 8 s`.
    pub fn line(&self) -> String {
        format!(
            "{:.1} s: render {:.1} s, stylize {:.1} s, train {:.1} s, other {:.1} s (loading, measurement, saving)",
            self.wall_seconds, self.render_seconds, self.stylize_seconds, self.train_seconds, self.other_seconds
        )
    }
}

/// A style's name: the key of `painting:KEY`, else the file's stem; lowercased, anything but
/// letters, digits, `-` and `_` made `-`, at most 64 characters ("style" if nothing is left).
pub fn style_name(spec: &str) -> String {
    let base = match spec.strip_prefix("painting:") {
        Some(key) => key.to_string(),
        None => Path::new(spec).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
    };
    let mut name: String = base
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c.to_ascii_lowercase() } else { '-' })
        .take(64)
        .collect();
    name = name.trim_matches('-').to_string();
    if name.is_empty() {
        "style".into()
    } else {
        name
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_come_from_the_painting_or_the_file_and_must_differ() {
        assert_eq!(style_name("painting:vangogh"), "vangogh");
        assert_eq!(style_name("/tmp/My Style.PNG"), "my-style");
        assert_eq!(style_name("..."), "style");
        assert_eq!(style_name(&style_name("a b/c d.png")), style_name("a b/c d.png"));
        let r = LayersRecord::new(Path::new("run"), &["painting:renoir".into(), "x/kandinsky.png".into()]).unwrap();
        assert_eq!(r.layers.iter().map(|l| l.name.as_str()).collect::<Vec<_>>(), ["renoir", "kandinsky"]);
        let e = LayersRecord::new(Path::new("run"), &["a/renoir.png".into(), "painting:renoir".into()]).unwrap_err().to_string();
        assert!(e.contains("\"renoir\""), "{e}");
    }
}
