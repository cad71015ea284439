//! VGG building blocks on planar `[channels, height, width]` tensors, forward and hand-written
//! backward: 3x3 convolution (stride 1, zero padding 1) fused with ReLU, and 2x2 max pooling
//! (stride 2, odd sizes floored as in PyTorch).
//!
//! The convolution is nine GEMMs, one per kernel tap, over shifted views of a zero-padded
//! copy of the input: with rows of `W + 2` elements, the tap (ky, kx) view of channel c
//! starts at `c * S + ky * (W + 2) + kx`, so output pixel (y, x) lands in column
//! `y * (W + 2) + x`. The two extra columns per row are junk and discarded. Each channel
//! block has 2 spare elements at its end (`S = (H + 2) (W + 2) + 2`) so the junk columns of
//! the last row never reach into the next channel.

use super::gemm::{gemm, View, ViewMut};

/// A 3x3 convolution's parameters in PyTorch layout: weight `[cout, cin, 3, 3]`, bias `[cout]`.
#[derive(Clone, Debug)]
pub struct Conv3x3 {
    pub cout: usize,
    pub cin: usize,
    pub weight: Vec<f32>,
    pub bias: Vec<f32>,
}

/// A planar tensor `[c, h, w]`.
#[derive(Clone, Debug)]
pub struct Planes {
    pub c: usize,
    pub h: usize,
    pub w: usize,
    pub data: Vec<f32>,
}

impl Planes {
    pub fn zeros(c: usize, h: usize, w: usize) -> Planes {
        Planes { c, h, w, data: vec![0.0; c * h * w] }
    }
}

fn padded_stride(h: usize, w: usize) -> usize {
    (h + 2) * (w + 2) + 2
}

/// Zero-padded copy of `x` with per-channel stride `padded_stride`.
fn pad(x: &Planes) -> Vec<f32> {
    let (h, w) = (x.h, x.w);
    let s = padded_stride(h, w);
    let mut p = vec![0.0f32; x.c * s];
    for c in 0..x.c {
        for y in 0..h {
            let src = &x.data[(c * h + y) * w..(c * h + y + 1) * w];
            let dst = c * s + (y + 1) * (w + 2) + 1;
            p[dst..dst + w].copy_from_slice(src);
        }
    }
    p
}

impl Conv3x3 {
    /// `relu(conv(x) + bias)`.
    pub fn forward_relu(&self, x: &Planes) -> Planes {
        assert_eq!(x.c, self.cin);
        let (h, w) = (x.h, x.w);
        let xp = pad(x);
        let s = padded_stride(h, w) as isize;
        let n = h * (w + 2);
        let mut acc = vec![0.0f32; self.cout * n];
        for tap in 0..9 {
            let (ky, kx) = (tap / 3, tap % 3);
            // SAFETY: A reads weight[co, ci, tap] (in bounds); B reads xp rows of n elements
            // starting at most 2(w+2)+2 into each channel block of length s, ending at most
            // at the block's last element; C rows are disjoint blocks of acc.
            unsafe {
                gemm(
                    self.cout,
                    self.cin,
                    n,
                    1.0,
                    View { ptr: self.weight.as_ptr().add(tap), rs: (self.cin * 9) as isize, cs: 9 },
                    View { ptr: xp.as_ptr().add(ky * (w + 2) + kx), rs: s, cs: 1 },
                    if tap == 0 { 0.0 } else { 1.0 },
                    ViewMut { ptr: acc.as_mut_ptr(), rs: n as isize, cs: 1 },
                );
            }
        }
        let mut out = Planes::zeros(self.cout, h, w);
        for co in 0..self.cout {
            let b = self.bias[co];
            for y in 0..h {
                let src = &acc[co * n + y * (w + 2)..co * n + y * (w + 2) + w];
                let dst = &mut out.data[(co * h + y) * w..(co * h + y + 1) * w];
                for (d, v) in dst.iter_mut().zip(src) {
                    *d = (v + b).max(0.0);
                }
            }
        }
        out
    }

    /// Gradient w.r.t. the input, given the forward output `y` (post-ReLU, for the mask)
    /// and the gradient `gy` w.r.t. it. Weights are fixed, so no weight gradient.
    pub fn backward_relu(&self, y: &Planes, gy: &Planes) -> Planes {
        let (h, w) = (y.h, y.w);
        let n = h * (w + 2);
        // Gradient through ReLU, laid out with the junk columns (which stay zero).
        let mut g = vec![0.0f32; self.cout * n];
        for co in 0..self.cout {
            for yy in 0..h {
                let base = (co * h + yy) * w;
                for x in 0..w {
                    if y.data[base + x] > 0.0 {
                        g[co * n + yy * (w + 2) + x] = gy.data[base + x];
                    }
                }
            }
        }
        let s = padded_stride(h, w);
        let mut gxp = vec![0.0f32; self.cin * s];
        for tap in 0..9 {
            let (ky, kx) = (tap / 3, tap % 3);
            // SAFETY: A is weight^T for this tap; C writes, per input channel, n elements
            // from offset ky(w+2)+kx inside that channel's block of s (ends <= s - 1), so
            // rows never overlap; column chunks of one call are disjoint.
            unsafe {
                gemm(
                    self.cin,
                    self.cout,
                    n,
                    1.0,
                    View { ptr: self.weight.as_ptr().add(tap), rs: 9, cs: (self.cin * 9) as isize },
                    View { ptr: g.as_ptr(), rs: n as isize, cs: 1 },
                    1.0,
                    ViewMut { ptr: gxp.as_mut_ptr().add(ky * (w + 2) + kx), rs: s as isize, cs: 1 },
                );
            }
        }
        let mut gx = Planes::zeros(self.cin, h, w);
        for c in 0..self.cin {
            for yy in 0..h {
                let src = c * s + (yy + 1) * (w + 2) + 1;
                gx.data[(c * h + yy) * w..(c * h + yy + 1) * w].copy_from_slice(&gxp[src..src + w]);
            }
        }
        gx
    }
}

/// 2x2 max pooling, stride 2; returns the output and, per output element, the input index
/// of its maximum (for the backward pass).
pub fn maxpool_forward(x: &Planes) -> (Planes, Vec<u32>) {
    let (oh, ow) = (x.h / 2, x.w / 2);
    let mut out = Planes::zeros(x.c, oh, ow);
    let mut arg = vec![0u32; x.c * oh * ow];
    for c in 0..x.c {
        for y in 0..oh {
            for xx in 0..ow {
                let mut best = f32::NEG_INFINITY;
                let mut best_i = 0usize;
                for (dy, dx) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                    let i = (c * x.h + 2 * y + dy) * x.w + 2 * xx + dx;
                    if x.data[i] > best {
                        best = x.data[i];
                        best_i = i;
                    }
                }
                let o = (c * oh + y) * ow + xx;
                out.data[o] = best;
                arg[o] = best_i as u32;
            }
        }
    }
    (out, arg)
}

/// Routes each output gradient to the input element that was the maximum.
pub fn maxpool_backward(input: &Planes, arg: &[u32], gy: &Planes) -> Planes {
    let mut gx = Planes::zeros(input.c, input.h, input.w);
    for (o, &i) in arg.iter().enumerate() {
        gx.data[i as usize] += gy.data[o];
    }
    gx
}
