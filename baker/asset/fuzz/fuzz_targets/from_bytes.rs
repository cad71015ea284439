//! Any bytes: decoding must return Ok or Err, never panic, hang or allocate wildly; an
//! accepted asset must re-encode to something that decodes again. Each input is tried as
//! is and with every chunk's CRC recomputed, so mutations also reach the semantic checks.
#![no_main]
use libfuzzer_sys::fuzz_target;
use snerf_asset::{encode_chunk, Asset};

fn reseal(bytes: &[u8]) -> Vec<u8> {
    let mut out = bytes[..bytes.len().min(16)].to_vec();
    let mut pos = 16;
    while pos + 12 <= bytes.len() {
        let len = u32::from_le_bytes(bytes[pos + 4..pos + 8].try_into().unwrap()) as usize;
        let end = (pos + 12).saturating_add(len).min(bytes.len());
        out.extend(encode_chunk(bytes[pos..pos + 4].try_into().unwrap(), &bytes[pos + 12..end]));
        pos = end;
    }
    out
}

fn check(data: &[u8]) {
    let _ = snerf_asset::chunks(data);
    if let Ok(a) = Asset::from_bytes(data) {
        let _ = a.sample_at_time(0.5, [0.1, 0.2, -0.3]);
        let _ = a.summary(data.len() as u64);
        assert!(Asset::from_bytes(&a.to_bytes()).is_ok());
    }
}

fuzz_target!(|data: &[u8]| {
    check(data);
    check(&reseal(data));
});
