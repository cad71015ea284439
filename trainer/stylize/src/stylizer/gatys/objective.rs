//! The Gatys et al. objective as SNeRF uses it: content loss at one tap of a feature network
//! (VGG's relu4_1), style loss on Gram matrices at every tap (relu1_1 .. relu4_1), with
//! hand-written gradients.
//!
//! Both losses are *relative* squared errors (divided by the target's squared norm), so
//! their scale does not depend on the layer widths or the weights' magnitudes; this keeps
//! one default balance valid for the real VGG-16 and for the narrow random networks of the
//! tests:
//!   content = |F4 - P4|^2 / |P4|^2
//!   style   = mean over taps of |G_l - A_l|^2 / |A_l|^2,   G = F F^T / (H W)

use super::gemm::{gemm, View, ViewMut};
use super::layers::Planes;
use super::net::FeatureNet;

/// `F F^T / n` for `F` = `[c, n]`.
pub fn gram(f: &Planes) -> Vec<f32> {
    let (c, n) = (f.c, f.h * f.w);
    let mut g = vec![0.0f32; c * c];
    // SAFETY: A is F (c x n), B is F^T (n x c) via swapped strides, C is g (c x c).
    unsafe {
        gemm(
            c,
            n,
            c,
            1.0 / n.max(1) as f32,
            View { ptr: f.data.as_ptr(), rs: n as isize, cs: 1 },
            View { ptr: f.data.as_ptr(), rs: 1, cs: n as isize },
            0.0,
            ViewMut { ptr: g.as_mut_ptr(), rs: c as isize, cs: 1 },
        );
    }
    g
}

fn sq_norm(v: &[f32]) -> f64 {
    v.iter().map(|x| (*x as f64) * (*x as f64)).sum()
}

/// Style and content targets plus weights; evaluates the loss and its image gradient.
pub struct Objective<'a> {
    net: &'a dyn FeatureNet,
    content_target: Planes,
    style_grams: &'a [Vec<f32>],
    pub content_weight: f64,
    pub style_weight: f64,
}

/// Grams of the style image at each tap.
pub fn style_grams(net: &dyn FeatureNet, style_rgb: &Planes) -> Vec<Vec<f32>> {
    let trace = net.forward(style_rgb);
    (0..net.taps()).map(|t| gram(trace.tap(t))).collect()
}

impl<'a> Objective<'a> {
    pub fn new(net: &'a dyn FeatureNet, content_rgb: &Planes, style_grams: &'a [Vec<f32>], content_weight: f64, style_weight: f64) -> Objective<'a> {
        assert_eq!(style_grams.len(), net.taps(), "one style Gram per tap");
        let trace = net.forward(content_rgb);
        Objective { net, content_target: trace.tap(net.content_tap()).clone(), style_grams, content_weight, style_weight }
    }

    /// Loss only.
    pub fn loss(&self, rgb: &Planes) -> f64 {
        self.evaluate(rgb, false).0
    }

    /// Loss and its gradient w.r.t. the planar RGB image.
    pub fn loss_and_grad(&self, rgb: &Planes) -> (f64, Planes) {
        let (l, g) = self.evaluate(rgb, true);
        (l, g.unwrap())
    }

    fn evaluate(&self, rgb: &Planes, want_grad: bool) -> (f64, Option<Planes>) {
        let trace = self.net.forward(rgb);
        let taps = self.net.taps();
        let content_tap = self.net.content_tap();
        let mut total = 0.0f64;
        let mut tap_grads: Vec<Option<Planes>> = vec![None; taps];

        // Content: w_c |F - P|^2 / |P|^2  ->  dF = 2 w_c (F - P) / |P|^2.
        let f = trace.tap(content_tap);
        let p = &self.content_target;
        let p_norm = sq_norm(&p.data) + 1e-12;
        let diff: Vec<f32> = f.data.iter().zip(&p.data).map(|(a, b)| a - b).collect();
        total += self.content_weight * sq_norm(&diff) / p_norm;
        if want_grad && self.content_weight != 0.0 {
            let k = (2.0 * self.content_weight / p_norm) as f32;
            tap_grads[content_tap] = Some(Planes { c: f.c, h: f.h, w: f.w, data: diff.iter().map(|d| d * k).collect() });
        }

        // Style: (w_s / taps) |G - A|^2 / |A|^2 with G = F F^T / n
        //   dG = 2 (w_s / taps) (G - A) / |A|^2,  dF = (dG + dG^T) F / n = 2 dG F / n.
        if self.style_weight != 0.0 {
            for t in 0..taps {
                let f = trace.tap(t);
                let (c, n) = (f.c, f.h * f.w);
                let a = &self.style_grams[t];
                let a_norm = sq_norm(a) + 1e-12;
                let g = gram(f);
                let gd: Vec<f32> = g.iter().zip(a).map(|(x, y)| x - y).collect();
                let w = self.style_weight / taps as f64;
                total += w * sq_norm(&gd) / a_norm;
                if !want_grad {
                    continue;
                }
                let alpha = (4.0 * w / (a_norm * n.max(1) as f64)) as f32;
                let mut df = Planes::zeros(c, f.h, f.w);
                // SAFETY: gd is c x c, F is c x n, df is c x n; no aliasing.
                unsafe {
                    gemm(
                        c,
                        c,
                        n,
                        alpha,
                        View { ptr: gd.as_ptr(), rs: c as isize, cs: 1 },
                        View { ptr: f.data.as_ptr(), rs: n as isize, cs: 1 },
                        0.0,
                        ViewMut { ptr: df.data.as_mut_ptr(), rs: n as isize, cs: 1 },
                    );
                }
                match &mut tap_grads[t] {
                    Some(existing) => existing.data.iter_mut().zip(&df.data).for_each(|(e, d)| *e += d),
                    slot => *slot = Some(df),
                }
            }
        }
        let grad = want_grad.then(|| self.net.backward(&trace, &tap_grads));
        (total, grad)
    }
}
