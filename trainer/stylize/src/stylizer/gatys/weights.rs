//! VGG-16 convolution weights up to conv4_1, read from a safetensors file in torchvision's
//! layout: `features.{k}.weight` `[cout, cin, 3, 3]` and `features.{k}.bias` `[cout]` for
//! k in 0, 2, 5, 7, 10, 12, 14, 17 (the keys may also lack the `features.` prefix, as in a
//! saved `vgg16().features.state_dict()`). Channel counts are read from the shapes, so a
//! narrower network (as the tests use) loads as well, as long as the layers chain.

use std::path::Path;

use anyhow::{bail, Context, Result};
use safetensors::{Dtype, SafeTensors};

use super::layers::Conv3x3;

/// torchvision `features` indices of the convolutions used (conv1_1 .. conv4_1).
pub const CONV_INDICES: [usize; 8] = [0, 2, 5, 7, 10, 12, 14, 17];
/// Layer names, for messages.
pub const CONV_NAMES: [&str; 8] =
    ["conv1_1", "conv1_2", "conv2_1", "conv2_2", "conv3_1", "conv3_2", "conv3_3", "conv4_1"];
/// Output channels of the real VGG-16 per block (conv1_x, conv2_x, conv3_x, conv4_1).
pub const VGG16_WIDTHS: [usize; 4] = [64, 128, 256, 512];

/// The eight convolutions conv1_1 .. conv4_1.
#[derive(Clone, Debug)]
pub struct VggWeights {
    pub convs: Vec<Conv3x3>,
}

/// Which block (0..4) each convolution belongs to.
const BLOCK_OF: [usize; 8] = [0, 0, 1, 1, 2, 2, 2, 3];

impl VggWeights {
    /// Reads and checks a safetensors file; errors name the file and the problem.
    pub fn load(path: &Path) -> Result<VggWeights> {
        let bytes = std::fs::read(path).with_context(|| format!("cannot read VGG weights {}", path.display()))?;
        Self::from_bytes(&bytes).with_context(|| format!("VGG weights {}", path.display()))
    }

    pub fn from_bytes(bytes: &[u8]) -> Result<VggWeights> {
        let st = SafeTensors::deserialize(bytes)
            .map_err(|e| anyhow::anyhow!("not a valid safetensors file (truncated or corrupt?): {e}"))?;
        let mut convs = Vec::with_capacity(8);
        let mut cin = 3usize;
        for (k, name) in CONV_INDICES.iter().zip(CONV_NAMES) {
            let (wkey, weight, wshape) = find_tensor(&st, &format!("{k}.weight"))?;
            let (bkey, bias, bshape) = find_tensor(&st, &format!("{k}.bias"))?;
            if wshape.len() != 4 || wshape[2] != 3 || wshape[3] != 3 {
                bail!("{wkey} ({name}) has shape {wshape:?}, expected [cout, cin, 3, 3]");
            }
            if wshape[1] != cin {
                bail!("{wkey} ({name}) has {} input channels, but the previous layer gives {cin}", wshape[1]);
            }
            let cout = wshape[0];
            if cout == 0 {
                bail!("{wkey} ({name}) has no output channels");
            }
            if bshape != [cout] {
                bail!("{bkey} ({name}) has shape {bshape:?}, expected [{cout}]");
            }
            if weight.iter().chain(&bias).any(|v| !v.is_finite()) {
                bail!("{wkey} or {bkey} ({name}) contains NaN or Inf");
            }
            convs.push(Conv3x3 { cout, cin, weight, bias });
            cin = cout;
        }
        Ok(VggWeights { convs })
    }

    /// Deterministic He-initialised weights with block widths `widths` (the real network is
    /// `VGG16_WIDTHS`); for tests and benchmarks, since no pretrained VGG is fetched here.
    pub fn random(widths: [usize; 4], seed: u64) -> VggWeights {
        let mut rng = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut uniform = move || {
            // xorshift64*: cheap, deterministic, good enough for weights.
            rng ^= rng >> 12;
            rng ^= rng << 25;
            rng ^= rng >> 27;
            (rng.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
        };
        let mut convs = Vec::new();
        let mut cin = 3;
        for block in BLOCK_OF {
            let cout = widths[block];
            // Uniform in [-a, a] has variance a^2/3; He init wants 2 / fan_in.
            let a = (6.0 / (cin * 9) as f32).sqrt();
            let weight = (0..cout * cin * 9).map(|_| uniform() * a).collect();
            let bias = (0..cout).map(|_| uniform() * 0.05).collect();
            convs.push(Conv3x3 { cout, cin, weight, bias });
            cin = cout;
        }
        VggWeights { convs }
    }

    /// The weights as a safetensors file in torchvision's layout (`features.{k}.*`).
    pub fn to_safetensors(&self) -> Result<Vec<u8>> {
        let mut owned: Vec<(String, Vec<usize>, Vec<u8>)> = Vec::new();
        for (conv, k) in self.convs.iter().zip(CONV_INDICES) {
            owned.push((format!("features.{k}.weight"), vec![conv.cout, conv.cin, 3, 3], f32_bytes(&conv.weight)));
            owned.push((format!("features.{k}.bias"), vec![conv.cout], f32_bytes(&conv.bias)));
        }
        let views: Vec<(String, safetensors::tensor::TensorView)> = owned
            .iter()
            .map(|(name, shape, data)| {
                Ok((name.clone(), safetensors::tensor::TensorView::new(Dtype::F32, shape.clone(), data)?))
            })
            .collect::<Result<_, safetensors::SafeTensorError>>()?;
        Ok(safetensors::serialize(views, &None)?)
    }
}

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Finds `features.{suffix}` or `{suffix}`; returns the key found, values as f32, shape.
fn find_tensor(st: &SafeTensors, suffix: &str) -> Result<(String, Vec<f32>, Vec<usize>)> {
    let key = [format!("features.{suffix}"), suffix.to_string()]
        .into_iter()
        .find(|k| st.names().contains(&k))
        .with_context(|| {
            let mut names: Vec<&String> = st.names();
            names.sort();
            let shown: Vec<&str> = names.iter().take(6).map(|s| s.as_str()).collect();
            format!(
                "missing tensor features.{suffix}; the file has {} tensors ({}{}). It must hold \
                 torchvision's vgg16 `features` state_dict",
                names.len(),
                shown.join(", "),
                if names.len() > 6 { ", ..." } else { "" }
            )
        })?;
    let view = st.tensor(&key)?;
    let data = view.data();
    let values: Vec<f32> = match view.dtype() {
        Dtype::F32 => data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect(),
        Dtype::F16 => data.chunks_exact(2).map(|b| f16_to_f32(u16::from_le_bytes([b[0], b[1]]))).collect(),
        Dtype::BF16 => data.chunks_exact(2).map(|b| f32::from_bits((u16::from_le_bytes([b[0], b[1]]) as u32) << 16)).collect(),
        other => bail!("{key} has dtype {other:?}; save the weights as float32 (or float16/bfloat16)"),
    };
    Ok((key, values, view.shape().to_vec()))
}

/// IEEE half -> single precision.
fn f16_to_f32(h: u16) -> f32 {
    let sign = ((h >> 15) as u32) << 31;
    let exp = ((h >> 10) & 0x1f) as u32;
    let mant = (h & 0x3ff) as u32;
    let bits = match (exp, mant) {
        (0, 0) => sign,
        (0, m) => {
            // Subnormal: renormalise.
            let shift = m.leading_zeros() - 21;
            let m = (m << shift) & 0x3ff;
            sign | ((127 - 15 + 1 - shift) << 23) | (m << 13)
        }
        (0x1f, 0) => sign | 0x7f80_0000,
        (0x1f, m) => sign | 0x7f80_0000 | (m << 13),
        (e, m) => sign | ((e + 127 - 15) << 23) | (m << 13),
    };
    f32::from_bits(bits)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_conversion() {
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0xc000), -2.0);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
        assert_eq!(f16_to_f32(0x7bff), 65504.0);
    }

    #[test]
    fn roundtrip() {
        let w = VggWeights::random([4, 5, 6, 7], 1);
        let back = VggWeights::from_bytes(&w.to_safetensors().unwrap()).unwrap();
        assert_eq!(back.convs[7].weight, w.convs[7].weight);
        assert_eq!(back.convs[7].cin, 6);
    }
}
