//! Running ONNX models with tract: one parsed model per file, and one optimized plan per
//! concrete input shape.
//!
//! Why per shape: tract optimizes much better when every dimension is known (measured on
//! these machines: symbolic shapes ran 6-8x slower), and optimizing takes a while, so each
//! plan is built once and kept. Why a process-wide executor: tract's matmul kernels run
//! single-threaded unless `multithread-mm`'s default executor is set (~1.6x faster on 2
//! cores, bit-identical). Quantize/dequantize pairs are fused after optimization (see
//! `fake_quant`).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use tract_linalg::multithread::{set_default_executor, Executor};
use tract_onnx::prelude::*;

use super::fake_quant::fuse_fake_quant;

pub type Plan = Arc<TypedRunnableModel>;

/// Sets tract's matmul executor to one thread per core, once per process.
pub fn ensure_executor() -> usize {
    static THREADS: OnceLock<usize> = OnceLock::new();
    *THREADS.get_or_init(|| {
        let n = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
        if n > 1 {
            set_default_executor(Executor::multithread(n));
        }
        n
    })
}

/// Parses an ONNX file; the error names the file and says what is wrong with it.
pub fn load_onnx(path: &Path) -> Result<InferenceModel> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read ONNX model {}", path.display()))?;
    if bytes.is_empty() {
        bail!("ONNX model {} is empty", path.display());
    }
    tract_onnx::onnx()
        .model_for_read(&mut std::io::Cursor::new(bytes))
        .map_err(|e| anyhow!("{} is not a valid ONNX model (corrupt, truncated or another format): {e}", path.display()))
}

/// One ONNX model and the optimized plans built for the shapes it has been run at.
pub struct ShapePlans {
    base: InferenceModel,
    path: PathBuf,
    plans: Mutex<HashMap<Vec<Vec<usize>>, Plan>>,
}

impl ShapePlans {
    pub fn open(path: &Path) -> Result<ShapePlans> {
        ensure_executor();
        Ok(ShapePlans { base: load_onnx(path)?, path: path.to_path_buf(), plans: Mutex::new(HashMap::new()) })
    }

    pub fn from_model(base: InferenceModel, path: &Path) -> ShapePlans {
        ensure_executor();
        ShapePlans { base, path: path.to_path_buf(), plans: Mutex::new(HashMap::new()) }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The plan for f32 inputs of exactly `shapes` (one per model input), and the seconds
    /// spent building it if this call built it. The lock is held while building so views
    /// stylized in parallel do not optimize the same shape several times over.
    pub fn plan(&self, shapes: &[Vec<usize>]) -> Result<(Plan, Option<f64>)> {
        let mut plans = self.plans.lock().unwrap();
        if let Some(p) = plans.get(shapes) {
            return Ok((p.clone(), None));
        }
        let t0 = Instant::now();
        let mut model = self.base.clone();
        for (i, shape) in shapes.iter().enumerate() {
            model = model
                .with_input_fact(i, f32::fact(shape.as_slice()).into())
                .map_err(|e| anyhow!("{}: cannot set input {i} to shape {shape:?}: {e}", self.path.display()))?;
        }
        let plan = model
            .into_optimized()
            .and_then(|m| Ok(fuse_fake_quant(m)?.0))
            .and_then(|m| m.into_runnable())
            .map_err(|e| anyhow!("{}: cannot prepare the model for inputs {shapes:?}: {e:#}", self.path.display()))?;
        plans.insert(shapes.to_vec(), plan.clone());
        Ok((plan, Some(t0.elapsed().as_secs_f64())))
    }

    /// Runs the model on f32 inputs, returning every output as (shape, values).
    pub fn run(&self, inputs: &[(Vec<usize>, &[f32])]) -> Result<Vec<(Vec<usize>, Vec<f32>)>> {
        let shapes: Vec<Vec<usize>> = inputs.iter().map(|(s, _)| s.clone()).collect();
        let (plan, _) = self.plan(&shapes)?;
        run_plan(&plan, inputs).with_context(|| format!("running {}", self.path.display()))
    }
}

pub fn run_plan(plan: &Plan, inputs: &[(Vec<usize>, &[f32])]) -> Result<Vec<(Vec<usize>, Vec<f32>)>> {
    let mut values: TVec<TValue> = tvec![];
    for (shape, data) in inputs {
        values.push(Tensor::from_shape::<f32>(shape, data)?.into_tvalue());
    }
    let outputs = plan.run(values).map_err(|e| anyhow!("{e:#}"))?;
    outputs
        .iter()
        .map(|t| {
            let view = t.to_plain_array_view::<f32>().map_err(|e| anyhow!("output is not f32: {e}"))?;
            Ok((t.shape().to_vec(), view.iter().copied().collect()))
        })
        .collect()
}
