//! The deferred view-dependence MLP (SNeRG): runs once per pixel on the composited diffuse
//! colour + 4 features + view direction and returns a specular RGB residual. Same layout and
//! arithmetic as the trainer's `view_mlp`, so baked weights mean the same thing here.

use anyhow::{ensure, Result};
use snerf_geometry::view_mlp;

pub const MLP_IN: usize = view_mlp::INPUTS;
pub const MLP_HIDDEN: usize = view_mlp::HIDDEN;
pub const MLP_OUT: usize = view_mlp::OUTPUTS;
pub const MLP_OCTAVES: usize = view_mlp::OCTAVES;
/// Total f32 count in the `VMLP` chunk.
pub const MLP_FLOATS: usize =
    MLP_HIDDEN * MLP_IN + MLP_HIDDEN + MLP_HIDDEN * MLP_HIDDEN + MLP_HIDDEN + MLP_OUT * MLP_HIDDEN + MLP_OUT;

/// Weights are output-major (row j of w1 = the 34 weights feeding hidden unit j).
#[derive(Clone, Debug, PartialEq)]
pub struct ViewMlp {
    pub w1: Vec<f32>,
    pub b1: Vec<f32>,
    pub w2: Vec<f32>,
    pub b2: Vec<f32>,
    pub w3: Vec<f32>,
    pub b3: Vec<f32>,
}

impl ViewMlp {
    /// All-zero weights: a purely diffuse asset.
    pub fn zeros() -> ViewMlp {
        ViewMlp {
            w1: vec![0.0; MLP_HIDDEN * MLP_IN],
            b1: vec![0.0; MLP_HIDDEN],
            w2: vec![0.0; MLP_HIDDEN * MLP_HIDDEN],
            b2: vec![0.0; MLP_HIDDEN],
            w3: vec![0.0; MLP_OUT * MLP_HIDDEN],
            b3: vec![0.0; MLP_OUT],
        }
    }

    /// From the flat order of the `VMLP` chunk (w1, b1, w2, b2, w3, b3).
    pub fn from_flat(v: &[f32]) -> Result<ViewMlp> {
        ensure!(v.len() == MLP_FLOATS, "view MLP has {} floats, expected {}", v.len(), MLP_FLOATS);
        ensure!(v.iter().all(|x| x.is_finite()), "view MLP has non-finite weights");
        let mut rest = v;
        let mut take = |n: usize| {
            let (a, b) = rest.split_at(n);
            rest = b;
            a.to_vec()
        };
        Ok(ViewMlp {
            w1: take(MLP_HIDDEN * MLP_IN),
            b1: take(MLP_HIDDEN),
            w2: take(MLP_HIDDEN * MLP_HIDDEN),
            b2: take(MLP_HIDDEN),
            w3: take(MLP_OUT * MLP_HIDDEN),
            b3: take(MLP_OUT),
        })
    }

    pub fn to_flat(&self) -> Vec<f32> {
        [&self.w1, &self.b1, &self.w2, &self.b2, &self.w3, &self.b3].iter().flat_map(|v| v.iter().copied()).collect()
    }

    /// Whether the output layer is zero, so the MLP adds 0 whatever its input (what a
    /// diffuse asset's MLP must be).
    pub fn output_is_zero(&self) -> bool {
        self.w3.iter().chain(&self.b3).all(|&w| w == 0.0)
    }

    /// Sizes and finiteness (public fields can be set to anything by a caller).
    pub fn validate(&self) -> Result<()> {
        ViewMlp::from_flat(&self.to_flat()).map(|_| ())
    }

    /// Input vector: composited diffuse rgb + 4 features, unit world direction, then
    /// sin/cos of each direction component at frequencies 2^o·π, o = 0..4.
    pub fn input(diffuse_feat: &[f32; 7], dir: [f32; 3]) -> [f32; MLP_IN] {
        view_mlp::encode(diffuse_feat, dir)
    }

    /// relu(W1 x + b1) -> relu(W2 h + b2) -> W3 h + b3. Written with zips so a malformed
    /// (wrong-length) weight vector gives a wrong answer, never a panic.
    pub fn forward(&self, x: &[f32; MLP_IN]) -> [f32; MLP_OUT] {
        let mut h1 = [0.0f32; MLP_HIDDEN];
        view_mlp::dense(&self.w1, &self.b1, x, &mut h1, true);
        let mut h2 = [0.0f32; MLP_HIDDEN];
        view_mlp::dense(&self.w2, &self.b2, &h1, &mut h2, true);
        let mut out = [0.0f32; MLP_OUT];
        view_mlp::dense(&self.w3, &self.b3, &h2, &mut out, false);
        out
    }
}
