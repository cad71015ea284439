//! The Gatys et al. objective as SNeRF uses it: content loss at relu4_1, style loss on Gram
//! matrices at relu1_1, relu2_1, relu3_1 and relu4_1, with hand-written gradients.
//!
//! Both losses are *relative* squared errors (divided by the target's squared norm), so
//! their scale does not depend on the layer widths or the weights' magnitudes; this keeps
//! one default balance valid for the real VGG-16 and for the narrow random networks of the
//! tests:
//!   content = |F4 - P4|^2 / |P4|^2
//!   style   = mean over taps of |G_l - A_l|^2 / |A_l|^2,   G = F F^T / (H W)

use super::gemm::{gemm, View, ViewMut};
use super::layers::Planes;
use super::vgg::{Vgg, CONTENT_TAP, TAPS};

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
    vgg: &'a Vgg,
    content_target: Planes,
    style_grams: &'a [Vec<f32>; TAPS],
    pub content_weight: f64,
    pub style_weight: f64,
}

/// Grams of the style image at each tap.
pub fn style_grams(vgg: &Vgg, style_rgb: &Planes) -> [Vec<f32>; TAPS] {
    let trace = vgg.forward(style_rgb);
    std::array::from_fn(|t| gram(trace.tap(t)))
}

impl<'a> Objective<'a> {
    pub fn new(vgg: &'a Vgg, content_rgb: &Planes, style_grams: &'a [Vec<f32>; TAPS], content_weight: f64, style_weight: f64) -> Objective<'a> {
        let trace = vgg.forward(content_rgb);
        Objective { vgg, content_target: trace.tap(CONTENT_TAP).clone(), style_grams, content_weight, style_weight }
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
        let trace = self.vgg.forward(rgb);
        let mut total = 0.0f64;
        let mut tap_grads: [Option<Planes>; TAPS] = Default::default();

        // Content: w_c |F - P|^2 / |P|^2  ->  dF = 2 w_c (F - P) / |P|^2.
        let f = trace.tap(CONTENT_TAP);
        let p = &self.content_target;
        let p_norm = sq_norm(&p.data) + 1e-12;
        let diff: Vec<f32> = f.data.iter().zip(&p.data).map(|(a, b)| a - b).collect();
        total += self.content_weight * sq_norm(&diff) / p_norm;
        if want_grad && self.content_weight != 0.0 {
            let k = (2.0 * self.content_weight / p_norm) as f32;
            tap_grads[CONTENT_TAP] = Some(Planes { c: f.c, h: f.h, w: f.w, data: diff.iter().map(|d| d * k).collect() });
        }

        // Style: (w_s / TAPS) |G - A|^2 / |A|^2 with G = F F^T / n
        //   dG = 2 (w_s / TAPS) (G - A) / |A|^2,  dF = (dG + dG^T) F / n = 2 dG F / n.
        if self.style_weight != 0.0 {
            for t in 0..TAPS {
                let f = trace.tap(t);
                let (c, n) = (f.c, f.h * f.w);
                let a = &self.style_grams[t];
                let a_norm = sq_norm(a) + 1e-12;
                let g = gram(f);
                let gd: Vec<f32> = g.iter().zip(a).map(|(x, y)| x - y).collect();
                let w = self.style_weight / TAPS as f64;
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
        let grad = want_grad.then(|| self.vgg.backward(&trace, &tap_grads));
        (total, grad)
    }
}
