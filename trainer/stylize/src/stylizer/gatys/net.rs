//! What the Gatys objective needs from a feature network: a recorded forward pass, the
//! activations at its taps (style Grams at every tap, content at one), and the gradient
//! w.r.t. the input image given gradients at the taps. Two networks implement it: the
//! MobileNetV2 trunk of Magenta's style network (`mobilenet`, the default: its weights come
//! with the stylizer models) and VGG-16 (`vgg`, the paper's, from a user-supplied file).

use super::layers::Planes;

/// A forward pass: `acts[0]` is the (network-normalised) input, `acts[i + 1]` the output of
/// op `i`; `aux[i]` holds whatever op `i`'s backward pass needs besides activations
/// (max-pool argmax indices).
pub struct Trace {
    pub acts: Vec<Planes>,
    pub aux: Vec<Option<Vec<u32>>>,
    /// Index into `acts` of each tap.
    pub taps: Vec<usize>,
}

impl Trace {
    /// The activation at tap `t`.
    pub fn tap(&self, t: usize) -> &Planes {
        &self.acts[self.taps[t]]
    }
}

/// A fixed-weight feature network with hand-written input gradients.
pub trait FeatureNet: Send + Sync {
    /// Short name for messages and reports.
    fn name(&self) -> &str;
    /// Number of taps (style layers).
    fn taps(&self) -> usize;
    /// The tap whose activation the content loss compares.
    fn content_tap(&self) -> usize;
    /// Smallest image side the taps still have pixels at.
    fn min_side(&self) -> usize;
    /// Runs the network on planar RGB in [0, 1] as far as the last tap, recording it.
    fn forward(&self, rgb: &Planes) -> Trace;
    /// Gradient w.r.t. the RGB input given gradients w.r.t. the taps (`None` = zero).
    fn backward(&self, trace: &Trace, tap_grads: &[Option<Planes>]) -> Planes;
}
