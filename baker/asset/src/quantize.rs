//! 8-bit quantization of voxel channels. Density is stored as a code over a logit range
//! (from the header) because σ spans many orders of magnitude; colours and features are
//! plain value/255.

use crate::header::DensityRange;

/// Channels per voxel: density code, diffuse RGB, 4 specular features.
pub const CHANNELS: usize = 8;

/// Appends the first `channels` bytes of every voxel of `voxels` (CHANNELS bytes each) to
/// `out`: what a file stores of them (all 8, or density and RGB in a diffuse asset).
pub fn store_voxels(voxels: &[u8], channels: usize, out: &mut Vec<u8>) {
    if channels == CHANNELS {
        out.extend_from_slice(voxels);
    } else {
        for v in voxels.chunks_exact(CHANNELS) {
            out.extend_from_slice(&v[..channels]);
        }
    }
}

/// The inverse of `store_voxels`: fills `voxels` (CHANNELS bytes each) from `stored`
/// (`channels` bytes each), the channels a file leaves out zero.
pub fn load_voxels(voxels: &mut [u8], stored: &[u8], channels: usize) {
    if channels == CHANNELS {
        voxels.copy_from_slice(stored);
    } else {
        for (v, s) in voxels.chunks_exact_mut(CHANNELS).zip(stored.chunks_exact(channels)) {
            v[..channels].copy_from_slice(s);
            v[channels..].fill(0);
        }
    }
}

/// round(v*255) clamped to 0..=255; NaN maps to 0.
pub fn quantize_unit(v: f32) -> u8 {
    let q = (v * 255.0).round();
    if q.is_nan() {
        0
    } else {
        q.clamp(0.0, 255.0) as u8
    }
}

pub fn dequantize_unit(c: u8) -> f32 {
    c as f32 / 255.0
}

/// Logit -> code (clamped into the range).
pub fn encode_density(logit: f32, r: &DensityRange) -> u8 {
    let span = r.logit_max - r.logit_min;
    if !(span > 0.0) {
        return 0;
    }
    quantize_unit((logit - r.logit_min) / span)
}

/// Code -> logit; σ = exp(logit).
pub fn decode_density(code: u8, r: &DensityRange) -> f32 {
    r.logit_min + code as f32 / 255.0 * (r.logit_max - r.logit_min)
}

/// One voxel's 8 stored bytes from float values (rgb and features in [0,1]).
pub fn encode_voxel(logit: f32, rgb: [f32; 3], feat: [f32; 4], r: &DensityRange) -> [u8; CHANNELS] {
    [
        encode_density(logit, r),
        quantize_unit(rgb[0]),
        quantize_unit(rgb[1]),
        quantize_unit(rgb[2]),
        quantize_unit(feat[0]),
        quantize_unit(feat[1]),
        quantize_unit(feat[2]),
        quantize_unit(feat[3]),
    ]
}

/// One voxel's decoded values: (logit, r, g, b, f0..f3).
#[inline]
pub fn decode_voxel(v: &[u8; CHANNELS], r: &DensityRange) -> [f32; CHANNELS] {
    let mut out = [0.0f32; CHANNELS];
    out[0] = decode_density(v[0], r);
    for c in 1..CHANNELS {
        out[c] = dequantize_unit(v[c]);
    }
    out
}
