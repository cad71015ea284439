//! A fused "fake quantization" op for tract: `QuantizeLinear(i8)` immediately followed by
//! `DequantizeLinear(f32)` on activations, evaluated in one vectorised, multithreaded pass.
//!
//! Why: the Magenta ONNX files are int8-quantized in QDQ form (181 Q/DQ pairs in the
//! transform network). tract runs each QuantizeLinear as a scalar single-threaded loop;
//! profiled on these machines that was about a quarter of a 384x384 stylization. The
//! fused op computes exactly what the two ops compute (same formula, same rounding), so
//! outputs are bit-identical; it only runs faster.

use rayon::prelude::*;
use tract_onnx::prelude::*;
use tract_onnx::tract_core::internal::*;
use tract_onnx::tract_core::ops::element_wise::ElementWiseOp;
use tract_onnx::tract_core::ops::quant::{DequantizeLinearF32, QuantizeLinearI8};

/// `y = (clamp(round_ties_even(x * q_scale) + q_zero, -128, 127) - dq_zero) * dq_scale`.
/// (`q_scale` is tract's stored reciprocal of the ONNX scale, as in `QuantizeLinearI8`.)
#[derive(Clone, Debug)]
pub struct FakeQuantI8 {
    q_scale: f32,
    q_zero: i32,
    dq_scale: f32,
    dq_zero: i32,
}

impl PartialEq for FakeQuantI8 {
    fn eq(&self, o: &Self) -> bool {
        self.q_scale.to_bits() == o.q_scale.to_bits()
            && self.q_zero == o.q_zero
            && self.dq_scale.to_bits() == o.dq_scale.to_bits()
            && self.dq_zero == o.dq_zero
    }
}
impl Eq for FakeQuantI8 {}

/// Elements per parallel task: large enough to amortise scheduling.
const CHUNK: usize = 1 << 15;

impl FakeQuantI8 {
    #[inline]
    fn apply(&self, x: f32) -> f32 {
        // Same expression as tract's quantize_linear_f32_i8 then DequantizeLinearF32.
        let q = ((x * self.q_scale).round_ties_even() as i32 + self.q_zero).clamp(-128, 127);
        (q - self.dq_zero) as f32 * self.dq_scale
    }
}

impl Op for FakeQuantI8 {
    fn name(&self) -> StaticName {
        "FakeQuantI8".into()
    }

    op_as_typed_op!();
}

impl EvalOp for FakeQuantI8 {
    op_out_of_plan!();

    fn eval(&self, _ctx: &EvalContext, inputs: TVec<TValue>) -> TractResult<TVec<TValue>> {
        let input = args_1!(inputs);
        let xs = input.try_as_plain_ram()?;
        let xs = xs.as_slice::<f32>()?;
        // SAFETY: every element of `output` is written below (one per input element) before
        // the tensor is read or returned.
        let mut output = unsafe { Tensor::uninitialized::<f32>(input.shape())? };
        {
            let mut view = output.try_as_plain_ram_mut()?;
            let ys = view.as_slice_mut::<f32>()?;
            ys.par_chunks_mut(CHUNK).zip(xs.par_chunks(CHUNK)).for_each(|(ys, xs)| {
                for (y, x) in ys.iter_mut().zip(xs) {
                    *y = self.apply(*x);
                }
            });
        }
        Ok(tvec!(output.into_tvalue()))
    }
}

impl TypedOp for FakeQuantI8 {
    fn output_facts(&self, inputs: &[&TypedFact]) -> TractResult<TVec<TypedFact>> {
        Ok(tvec!(f32::datum_type().fact(inputs[0].shape.clone())))
    }

    as_op!();
}

/// The quantize parameters of `node` if it is an f32 -> i8 QuantizeLinear.
fn quantize_i8(node: &TypedNode) -> Option<(f32, i32)> {
    let op = node.op_as::<ElementWiseOp>()?;
    let q = op.0.downcast_ref::<QuantizeLinearI8>()?;
    Some((q.scale, q.zero_point as i32))
}

/// Replaces every f32 QuantizeLinear(i8) -> DequantizeLinear(f32) pair in an optimized
/// model by one `FakeQuantI8` node; returns the model and how many pairs were fused.
pub fn fuse_fake_quant(mut model: TypedModel) -> TractResult<(TypedModel, usize)> {
    let candidates: Vec<usize> = model.eval_order()?;
    let mut fused = 0;
    for id in candidates {
        let node = model.node(id);
        let Some((q_scale, q_zero)) = quantize_i8(node) else { continue };
        if model.outlet_fact(node.inputs[0])?.datum_type != f32::datum_type() {
            continue;
        }
        let Some(succ) = model.single_succ(id)? else { continue };
        let Some(dq) = succ.op_as::<DequantizeLinearF32>() else { continue };
        if model.outputs.contains(&OutletId::new(id, 0)) {
            continue;
        }
        let op = FakeQuantI8 { q_scale, q_zero, dq_scale: dq.scale, dq_zero: dq.zero_point };
        let patch = TypedModelPatch::fuse_with_next(&model, node, op)?;
        patch.apply(&mut model)?;
        fused += 1;
    }
    Ok((model.into_compact()?, fused))
}
