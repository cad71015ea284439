//! The scene kind: the one switch that decides how space is parametrized (and nothing else
//! is switched on: a bounded object gets no background model, a static scene no time).

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SceneKind {
    /// A bounded object seen from around it: grid = model box [-1,1]³, no contraction.
    Object,
    /// Forward-facing capture (LLFF): grid = NDC of the reference camera.
    Forward,
    /// Unbounded 360° capture: grid = MERF's L∞ contraction / 2.
    Unbounded,
}

impl SceneKind {
    /// The index the WGSL shader's `KIND` constant uses.
    pub fn shader_index(self) -> u32 {
        match self {
            SceneKind::Object => 0,
            SceneKind::Forward => 1,
            SceneKind::Unbounded => 2,
        }
    }
    pub fn as_str(self) -> &'static str {
        match self {
            SceneKind::Object => "object",
            SceneKind::Forward => "forward",
            SceneKind::Unbounded => "unbounded",
        }
    }

    /// Parses "object", "forward" or "unbounded" (case-insensitive).
    pub fn parse(s: &str) -> Option<SceneKind> {
        match s.to_ascii_lowercase().as_str() {
            "object" => Some(SceneKind::Object),
            "forward" => Some(SceneKind::Forward),
            "unbounded" => Some(SceneKind::Unbounded),
            _ => None,
        }
    }
}

impl std::fmt::Display for SceneKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}
