//! What every command shares, and the only module of the command line that the command
//! modules import: validated value parsers (numbers are finite and in range when they are
//! parsed, so NaN or a 120 GB allocation never reaches the pipeline; each parser names the
//! accepted range in its error, which clap prints with the flag), the argument groups
//! several commands flatten in (`DataOpts`, `TokenArgs`), and the small output helpers every
//! command's summary and progress use.

use std::ops::RangeInclusive;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::Value;
use snerf_files::guard::{check_output, Input};
use snerf_trainer::data::{self, Dataset, LoadOptions, SceneKind};
use snerf_trainer::run_dir::RunDir;

fn number<T: std::str::FromStr>(s: &str) -> Result<T, String> {
    s.trim().parse::<T>().map_err(|_| format!("'{s}' is not a number"))
}

/// A finite f64 in `range`.
fn f64_in(s: &str, range: RangeInclusive<f64>, what: &str) -> Result<f64, String> {
    let v: f64 = number(s)?;
    if !v.is_finite() || !range.contains(&v) {
        return Err(format!("'{s}': must be {what}"));
    }
    Ok(v)
}

/// > 0 and finite (learning rates, timeouts, minutes).
pub fn positive(s: &str) -> Result<f64, String> {
    let v = f64_in(s, 0.0..=1e12, "a finite number greater than 0")?;
    if v == 0.0 {
        return Err(format!("'{s}': must be a finite number greater than 0"));
    }
    Ok(v)
}

pub fn positive_f32(s: &str) -> Result<f32, String> {
    let v = positive(s)?;
    if v > f32::MAX as f64 {
        return Err(format!("'{s}': too large"));
    }
    Ok(v as f32)
}

/// Any finite number (a time in the data's units).
pub fn finite_f32(s: &str) -> Result<f32, String> {
    f64_in(s, -1e30..=1e30, "a finite number").map(|v| v as f32)
}

/// >= 0 and finite (loss weights, tolerances).
pub fn non_negative(s: &str) -> Result<f64, String> {
    f64_in(s, 0.0..=1e12, "a finite number >= 0")
}

pub fn non_negative_f32(s: &str) -> Result<f32, String> {
    non_negative(s).map(|v| v as f32)
}

/// In [0, 1] (strengths, opacities).
pub fn unit_f32(s: &str) -> Result<f32, String> {
    f64_in(s, 0.0..=1.0, "a number in [0, 1]").map(|v| v as f32)
}

/// Field of view in degrees, (0, 180).
pub fn fov_degrees(s: &str) -> Result<f32, String> {
    let v = f64_in(s, 0.0..=179.0, "an angle in degrees between 0 and 179")?;
    if v < 1.0 {
        return Err(format!("'{s}': must be an angle in degrees between 1 and 179"));
    }
    Ok(v as f32)
}

/// An integer in `lo..=hi`, with the reason for the bound in the error.
pub fn int_in<T>(lo: u64, hi: u64, why: &'static str) -> impl Fn(&str) -> Result<T, String> + Clone + Send + Sync + 'static
where
    T: TryFrom<u64>,
{
    move |s: &str| {
        let v: u64 = number(s)?;
        if v < lo || v > hi {
            return Err(format!("'{s}': must be in {lo}..={hi}{}", if why.is_empty() { String::new() } else { format!(" ({why})") }));
        }
        T::try_from(v).map_err(|_| format!("'{s}': out of range"))
    }
}

/// Worker threads: 1 ..= 4 × this machine's cores (more only adds overhead; 100 000 threads
/// would take the machine down before any work starts).
/// A direction "x,y,z" (finite, not zero), returned unit length; also the axis names
/// "+x", "-y", "+z", ….
pub fn direction(s: &str) -> Result<[f32; 3], String> {
    let t = s.trim();
    let axis = |i: usize, sign: f32| {
        let mut v = [0.0f32; 3];
        v[i] = sign;
        v
    };
    let named = match t.to_ascii_lowercase().as_str() {
        "x" | "+x" => Some(axis(0, 1.0)),
        "-x" => Some(axis(0, -1.0)),
        "y" | "+y" => Some(axis(1, 1.0)),
        "-y" => Some(axis(1, -1.0)),
        "z" | "+z" => Some(axis(2, 1.0)),
        "-z" => Some(axis(2, -1.0)),
        _ => None,
    };
    if let Some(v) = named {
        return Ok(v);
    }
    let parts: Vec<&str> = t.split(',').collect();
    let bad = || format!("'{s}': must be an axis (+x, -y, z, ...) or three finite numbers x,y,z, not all 0");
    if parts.len() != 3 {
        return Err(bad());
    }
    let mut v = [0.0f32; 3];
    for (o, p) in v.iter_mut().zip(&parts) {
        *o = p.trim().parse::<f32>().map_err(|_| bad())?;
    }
    let n = v.iter().map(|x| x * x).sum::<f32>().sqrt();
    if !n.is_finite() || n == 0.0 {
        return Err(bad());
    }
    Ok(v.map(|x| x / n))
}

pub fn threads(s: &str) -> Result<usize, String> {
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let max = 4 * cores;
    let v: usize = number(s)?;
    if v == 0 || v > max {
        return Err(format!("'{s}': must be in 1..={max} (4 x the {cores} cores of this machine)"));
    }
    Ok(v)
}

/// Image sizes `WxH`.
pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s.split_once(['x', 'X']).with_context(|| format!("--size '{s}': expected WxH, e.g. 128x128"))?;
    let w: u32 = w.trim().parse().with_context(|| format!("--size '{s}': bad width"))?;
    let h: u32 = h.trim().parse().with_context(|| format!("--size '{s}': bad height"))?;
    if !(8..=8192).contains(&w) || !(8..=8192).contains(&h) {
        bail!("--size '{s}': width and height must be in 8..=8192");
    }
    Ok((w, h))
}

#[derive(Args, Debug, Clone, Default)]
pub struct DataOpts {
    /// Override the detected scene kind: object | forward | unbounded.
    #[arg(long)]
    pub kind: Option<String>,
    /// Treat the scene as static even if frames carry times.
    #[arg(long = "static")]
    pub force_static: bool,
    /// Integer image downscale factor N: each N×N pixel block is averaged (box filter) and the
    /// intrinsics divided by N; an `images_N/` folder beside `images/` (LLFF, COLMAP) is used
    /// instead when present.
    #[arg(long, value_parser = crate::args::int_in::<u32>(1, 64, ""))]
    pub downscale: Option<u32>,
    /// Longest image side in pixels, after --downscale [default: 1600, and 512 for `snerf
    /// stylize`, whose rounds render every view many times; 0 = no cap]. Larger images (a
    /// 4000×3000 phone photo) are resized once at load with an antialiased bicubic filter and
    /// cached in ~/.cache/snerf/images, so the next load is fast.
    #[arg(long, value_parser = crate::args::int_in::<u32>(0, 16384, ""))]
    pub max_size: Option<u32>,
    /// For LLFF/COLMAP/single-file data: every n-th image is held out for testing.
    #[arg(long, value_parser = crate::args::int_in::<usize>(2, 100000, ""))]
    pub holdout_every: Option<usize>,
}

impl DataOpts {
    pub fn load(&self, path: &Path) -> Result<Dataset> {
        let kind = match self.kind.as_deref() {
            None => None,
            Some(k) => Some(parse_kind(k)?),
        };
        let opts = LoadOptions {
            kind,
            dynamic: if self.force_static { Some(false) } else { None },
            holdout_every: self.holdout_every,
            downscale: self.downscale,
            max_size: self.max_size,
            ..Default::default()
        };
        data::load(path, &opts)
    }
}

fn parse_kind(k: &str) -> Result<SceneKind> {
    Ok(match k {
        "object" => SceneKind::Object,
        "forward" => SceneKind::Forward,
        "unbounded" => SceneKind::Unbounded,
        _ => bail!("unknown scene kind '{k}' (use object, forward or unbounded)"),
    })
}

/// How a client gets the server's access token. A token on the command line shows in `ps`
/// and shell history, so a file or the environment is preferred.
#[derive(Args, Debug, Clone, Default)]
pub struct TokenArgs {
    /// Access token (printed by `snerf serve`). Visible to other users in `ps`; prefer
    /// --token-file or $SNERF_TOKEN.
    #[arg(long)]
    pub token: Option<String>,
    /// File holding the access token (e.g. the server's state directory `token` file).
    #[arg(long, conflicts_with = "token")]
    pub token_file: Option<PathBuf>,
}

pub const TOKEN_ENV: &str = "SNERF_TOKEN";

impl TokenArgs {
    /// --token, else --token-file, else $SNERF_TOKEN.
    pub fn resolve(&self) -> Result<String> {
        let token = if let Some(t) = &self.token {
            t.clone()
        } else if let Some(f) = &self.token_file {
            std::fs::read_to_string(f).with_context(|| format!("--token-file {}: cannot read", f.display()))?.trim().to_string()
        } else if let Ok(t) = std::env::var(TOKEN_ENV) {
            t.trim().to_string()
        } else {
            anyhow::bail!("no access token: pass --token-file FILE, set ${TOKEN_ENV}, or --token T (all printed by `snerf serve`)");
        };
        anyhow::ensure!(!token.is_empty(), "the access token is empty");
        Ok(token)
    }
}

/// A path as a JSON string. JSON holds UTF-8 only; a path that is not is written lossily
/// rather than failing after the work is done.
pub fn pj(p: impl AsRef<Path>) -> Value {
    Value::String(p.as_ref().to_string_lossy().into_owned())
}

/// A progress bar drawn on stderr.
pub fn bar(len: u64, template: &str) -> ProgressBar {
    let pb = ProgressBar::new(len);
    pb.set_style(ProgressStyle::with_template(template).unwrap().progress_chars("=> "));
    pb
}

/// `check_output` with a run's files and a dataset tree as the inputs.
pub fn guard_run_output(flag: &str, out: &Path, run: &Path, data_root: Option<&Path>) -> Result<()> {
    let files = RunDir::new(run).files();
    let mut inputs: Vec<Input> = files.iter().map(|f| Input::File(f)).collect();
    if let Some(d) = data_root {
        inputs.push(Input::Tree(d));
    }
    check_output(flag, out, &inputs)
}

/// Peak resident memory of this process so far (Linux), in MB.
pub fn peak_rss_mb() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_and_out_of_range_numbers_are_refused() {
        assert_eq!(direction("+z"), Ok([0.0, 0.0, 1.0]));
        assert_eq!(direction("0, -2, 0"), Ok([0.0, -1.0, 0.0]));
        for bad in ["0,0,0", "1,2", "NaN,0,1", "inf,0,0", "up"] {
            assert!(direction(bad).is_err(), "{bad}");
        }
        for bad in ["NaN", "nan", "inf", "-inf", "1e400", "-1", "0", "abc", ""] {
            assert!(positive(bad).is_err(), "{bad}");
        }
        assert_eq!(positive("0.04"), Ok(0.04));
        assert!(positive_f32("1e39").is_err());
        assert!(non_negative("NaN").is_err());
        assert_eq!(non_negative("0"), Ok(0.0));
        assert!(unit_f32("1.5").is_err());
        assert!(fov_degrees("180").is_err() && fov_degrees("0").is_err());
        let f = int_in::<usize>(1, 10, "why");
        assert!(f("0").unwrap_err().contains("why"));
        assert_eq!(f("10"), Ok(10));
        assert!(f("-3").is_err());
        assert!(threads("100000").is_err());
        assert_eq!(threads("1"), Ok(1));
    }
}
