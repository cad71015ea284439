//! A minimal reader for NumPy `.npy` files (format versions 1, 2 and 3) holding little-endian
//! float64 or float32 arrays in C order; enough for LLFF's `poses_bounds.npy`.

use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};

/// A float array read from a `.npy` file, converted to f64.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct NpyArray {
    pub shape: Vec<usize>,
    pub data: Vec<f64>,
}

pub(crate) fn read(path: &Path) -> Result<NpyArray> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    parse(&bytes).map_err(|e| anyhow!("{}: {e}", path.display()))
}

/// Parses the bytes of a `.npy` file; errors do not name the file (the caller adds it).
pub(crate) fn parse(bytes: &[u8]) -> Result<NpyArray> {
    const MAGIC: &[u8] = b"\x93NUMPY";
    if bytes.len() < 10 || &bytes[..6] != MAGIC {
        bail!("not a .npy file (bad magic)");
    }
    let major = bytes[6];
    let (header_len, header_start) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10usize),
        2 | 3 => {
            if bytes.len() < 12 {
                bail!("truncated .npy header");
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        v => bail!("unsupported .npy format version {v}"),
    };
    let data_start = header_start
        .checked_add(header_len)
        .filter(|&e| e <= bytes.len())
        .ok_or_else(|| anyhow!("truncated .npy header"))?;
    let header = std::str::from_utf8(&bytes[header_start..data_start])
        .map_err(|_| anyhow!("npy header is not text"))?;

    let descr = dict_value(header, "descr").ok_or_else(|| anyhow!("npy header has no 'descr'"))?;
    let descr = descr.trim_matches(|c| c == '\'' || c == '"');
    let itemsize = match descr {
        "<f8" => 8,
        "<f4" => 4,
        other => bail!(
            "unsupported dtype '{other}' (expected '<f8' or '<f4', float64/float32 little-endian)"
        ),
    };
    let fortran = dict_value(header, "fortran_order").unwrap_or("False");
    if fortran.trim() != "False" {
        bail!("fortran_order arrays are not supported (save with C order)");
    }
    let shape_txt =
        dict_value(header, "shape").ok_or_else(|| anyhow!("npy header has no 'shape'"))?;
    let shape = parse_shape(shape_txt)?;
    let count = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| anyhow!("npy shape {shape:?} overflows"))?;
    let need = count
        .checked_mul(itemsize)
        .ok_or_else(|| anyhow!("npy shape {shape:?} overflows"))?;
    let body = &bytes[data_start..];
    if body.len() < need {
        bail!(
            "truncated npy data: shape {shape:?} needs {need} bytes, file has {}",
            body.len()
        );
    }
    let data = if itemsize == 8 {
        body[..need]
            .chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect()
    } else {
        body[..need]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes(c.try_into().unwrap()) as f64)
            .collect()
    };
    Ok(NpyArray { shape, data })
}

/// The raw text of the value for `key` in a Python dict literal (up to the next top-level comma).
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let pos = header
        .find(&format!("'{key}'"))
        .or_else(|| header.find(&format!("\"{key}\"")))?;
    let rest = &header[pos + key.len() + 2..];
    let rest = rest.trim_start().strip_prefix(':')?.trim_start();
    let mut depth = 0i32;
    for (i, c) in rest.char_indices() {
        match c {
            '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            ',' | '}' if depth == 0 => return Some(rest[..i].trim()),
            _ => {}
        }
    }
    Some(rest.trim())
}

fn parse_shape(s: &str) -> Result<Vec<usize>> {
    let inner = s
        .trim()
        .strip_prefix('(')
        .and_then(|t| t.strip_suffix(')'))
        .ok_or_else(|| anyhow!("bad npy shape '{s}'"))?;
    inner
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .map(|t| {
            t.trim_end_matches('L')
                .parse::<usize>()
                .map_err(|_| anyhow!("bad npy shape '{s}'"))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn npy(descr: &str, shape: &str, body: &[u8], version: u8) -> Vec<u8> {
        let mut h = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
        let pre = if version == 1 { 10 } else { 12 };
        while (pre + h.len() + 1) % 64 != 0 {
            h.push(' ');
        }
        h.push('\n');
        let mut out = b"\x93NUMPY".to_vec();
        out.extend([version, 0]);
        if version == 1 {
            out.extend((h.len() as u16).to_le_bytes());
        } else {
            out.extend((h.len() as u32).to_le_bytes());
        }
        out.extend(h.as_bytes());
        out.extend(body);
        out
    }

    #[test]
    fn reads_f8_f4_and_versions() {
        let body: Vec<u8> = [1.0f64, 2.0, 3.0, 4.5, 5.0, 6.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        for v in [1, 2, 3] {
            let a = parse(&npy("<f8", "(2, 3)", &body, v)).unwrap();
            assert_eq!(a.shape, vec![2, 3]);
            assert_eq!(a.data[3], 4.5);
        }
        let body4: Vec<u8> = [1.5f32, 2.0].iter().flat_map(|v| v.to_le_bytes()).collect();
        let a = parse(&npy("<f4", "(2,)", &body4, 1)).unwrap();
        assert_eq!(
            a,
            NpyArray {
                shape: vec![2],
                data: vec![1.5, 2.0]
            }
        );
    }

    #[test]
    fn rejects_bad_dtype_truncation_magic() {
        let e = parse(&npy("<i4", "(2,)", &[0; 8], 1))
            .unwrap_err()
            .to_string();
        assert!(e.contains("dtype '<i4'"), "{e}");
        let e = parse(&npy("<f8", "(2, 17)", &[0; 16], 1))
            .unwrap_err()
            .to_string();
        assert!(e.contains("truncated"), "{e}");
        let e = parse(b"hello world, not npy").unwrap_err().to_string();
        assert!(e.contains("magic"), "{e}");
        let e = parse(&npy(">f8", "(1,)", &[0; 8], 1))
            .unwrap_err()
            .to_string();
        assert!(e.contains("dtype"), "{e}");
    }
}
