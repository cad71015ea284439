//! The VGG-16 feature extractor up to relu4_1, with a recorded forward pass and its
//! backward pass (gradient w.r.t. the input image only; the weights stay fixed).
//!
//! torchvision's `features` up to index 18: conv1_1 relu conv1_2 relu pool conv2_1 relu
//! conv2_2 relu pool conv3_1 relu conv3_2 relu conv3_3 relu pool conv4_1 relu. Inputs are
//! RGB in [0, 1] normalised with the ImageNet mean and std, as the weights expect.

use super::layers::{maxpool_backward, maxpool_forward, Planes};
use super::net::{FeatureNet, Trace};
use super::weights::VggWeights;

pub const IMAGENET_MEAN: [f32; 3] = [0.485, 0.456, 0.406];
pub const IMAGENET_STD: [f32; 3] = [0.229, 0.224, 0.225];

/// Number of feature taps: relu1_1, relu2_1, relu3_1, relu4_1.
pub const TAPS: usize = 4;
/// Index of relu4_1 among the taps (the content layer).
pub const CONTENT_TAP: usize = 3;

#[derive(Clone, Copy, Debug)]
enum Op {
    /// Convolution `i` of `VggWeights::convs`, with ReLU.
    Conv(usize),
    Pool,
}

const OPS: [Op; 11] = [
    Op::Conv(0),
    Op::Conv(1),
    Op::Pool,
    Op::Conv(2),
    Op::Conv(3),
    Op::Pool,
    Op::Conv(4),
    Op::Conv(5),
    Op::Conv(6),
    Op::Pool,
    Op::Conv(7),
];

/// Which op's output is each tap (relu1_1, relu2_1, relu3_1, relu4_1).
const TAP_OPS: [usize; TAPS] = [0, 3, 6, 10];

pub struct Vgg {
    pub weights: VggWeights,
}

impl Vgg {
    pub fn new(weights: VggWeights) -> Vgg {
        Vgg { weights }
    }

}

impl FeatureNet for Vgg {
    fn name(&self) -> &str {
        "vgg16"
    }

    fn taps(&self) -> usize {
        TAPS
    }

    fn content_tap(&self) -> usize {
        CONTENT_TAP
    }

    /// Three pools before relu4_1.
    fn min_side(&self) -> usize {
        16
    }

    /// Normalises a planar RGB image in [0, 1] and runs the network, recording activations.
    fn forward(&self, rgb: &Planes) -> Trace {
        let mut x = rgb.clone();
        let n = x.h * x.w;
        for c in 0..3 {
            for v in &mut x.data[c * n..(c + 1) * n] {
                *v = (*v - IMAGENET_MEAN[c]) / IMAGENET_STD[c];
            }
        }
        let mut acts = vec![x];
        let mut pool_args = Vec::with_capacity(OPS.len());
        for op in OPS {
            let input = acts.last().unwrap();
            let (out, arg) = match op {
                Op::Conv(i) => (self.weights.convs[i].forward_relu(input), None),
                Op::Pool => {
                    let (o, a) = maxpool_forward(input);
                    (o, Some(a))
                }
            };
            acts.push(out);
            pool_args.push(arg);
        }
        Trace { acts, aux: pool_args, taps: TAP_OPS.iter().map(|o| o + 1).collect() }
    }

    /// Gradient w.r.t. the un-normalised input image, given gradients w.r.t. the taps
    /// (`None` = zero).
    fn backward(&self, trace: &Trace, tap_grads: &[Option<Planes>]) -> Planes {
        let last = trace.acts.last().unwrap();
        let mut g = Planes::zeros(last.c, last.h, last.w);
        for (i, op) in OPS.iter().enumerate().rev() {
            if let Some(t) = TAP_OPS.iter().position(|&o| o == i) {
                if let Some(tg) = &tap_grads[t] {
                    for (a, b) in g.data.iter_mut().zip(&tg.data) {
                        *a += b;
                    }
                }
            }
            g = match op {
                Op::Conv(c) => self.weights.convs[*c].backward_relu(&trace.acts[i + 1], &g),
                Op::Pool => maxpool_backward(&trace.acts[i], trace.aux[i].as_ref().unwrap(), &g),
            };
        }
        let n = g.h * g.w;
        for c in 0..3 {
            for v in &mut g.data[c * n..(c + 1) * n] {
                *v /= IMAGENET_STD[c];
            }
        }
        g
    }
}
