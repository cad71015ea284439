//! `snerf bench view`: median GPU frame time (march + submit + wait, no readback; with
//! readback reported too) against the CPU reference renderer on the same cameras, same run.

use anyhow::{ensure, Result};
use serde::Serialize;
use std::fmt;
use std::time::Instant;

use crate::camera::stereo_pair;
use crate::gpu::{GpuOptions, GpuRenderer, View};
use snerf_asset::{orbit, Asset, Camera};

#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub width: u32,
    pub height: u32,
    /// GPU frames timed (after 2 warm-up frames), cameras spread over an orbit.
    pub frames: usize,
    /// CPU reference frames timed (the first cameras of the same spread; median).
    pub cpu_frames: usize,
    /// Also time stereo: two eyes of `stereo_size` side by side.
    pub stereo: bool,
    pub stereo_size: (u32, u32),
    pub ipd: f32,
    pub fov_y: f32,
    pub gpu: GpuOptions,
}

impl Default for BenchOptions {
    fn default() -> Self {
        BenchOptions {
            width: 1280,
            height: 720,
            frames: 30,
            cpu_frames: 3,
            stereo: false,
            stereo_size: (1920, 1080),
            ipd: 0.064,
            fov_y: 50.0,
            gpu: GpuOptions::default(),
        }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct StereoBench {
    pub eye_width: u32,
    pub eye_height: u32,
    pub gpu_median_ms: f64,
    pub cpu_median_ms: f64,
    pub speedup: f64,
}

/// A diffuse asset drawn by its own shader variant (no features, no view MLP, a 4-byte
/// atlas texel) against the full variant drawing the same asset as if it were not diffuse
/// (8-byte texels, the zero MLP run): the same pixels, interleaved frame by frame.
#[derive(Clone, Debug, Serialize)]
pub struct DiffuseBench {
    pub diffuse_median_ms: f64,
    pub full_median_ms: f64,
    /// diffuse_median_ms / full_median_ms (< 1: the diffuse variant is faster).
    pub ratio: f64,
    /// Process CPU seconds per frame of each (lavapipe: the shader's work).
    pub diffuse_process_cpu_s: Option<f64>,
    pub full_process_cpu_s: Option<f64>,
    pub diffuse_atlas_bytes: u64,
    pub full_atlas_bytes: u64,
    /// Largest difference between the two variants' pixels.
    pub max_abs_diff: f32,
}

#[derive(Clone, Debug, Serialize)]
pub struct BenchView {
    pub adapter: String,
    pub width: u32,
    pub height: u32,
    pub gpu_frames: usize,
    /// March + submit + wait for the GPU, no readback.
    pub gpu_median_ms: f64,
    pub gpu_min_ms: f64,
    /// The same including reading the image back to the CPU.
    pub gpu_readback_median_ms: f64,
    pub cpu_frames: usize,
    pub cpu_median_ms: f64,
    /// GPU median over the same cameras the CPU rendered.
    pub gpu_same_cams_median_ms: f64,
    /// cpu_median_ms / gpu_same_cams_median_ms (> 1: GPU faster), measured interleaved.
    pub speedup: f64,
    /// Process CPU seconds per frame (Linux): the GPU path's (lavapipe runs on the CPU;
    /// near 0 on a real GPU) and the CPU reference's, on the same cameras.
    pub gpu_process_cpu_s: Option<f64>,
    pub cpu_process_cpu_s: Option<f64>,
    pub stereo: Option<StereoBench>,
    /// Only for a diffuse asset.
    pub diffuse: Option<DiffuseBench>,
}

impl fmt::Display for BenchView {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "adapter: {}", self.adapter)?;
        writeln!(
            f,
            "view {}x{}: GPU median {:.2} ms/frame (min {:.2}, with readback {:.2}) over {} frames",
            self.width,
            self.height,
            self.gpu_median_ms,
            self.gpu_min_ms,
            self.gpu_readback_median_ms,
            self.gpu_frames
        )?;
        writeln!(
            f,
            "view {}x{}: CPU reference median {:.2} ms/frame over {} frames (GPU on those cameras {:.2} ms)",
            self.width, self.height, self.cpu_median_ms, self.cpu_frames, self.gpu_same_cams_median_ms
        )?;
        write!(
            f,
            "view {}x{}: GPU/CPU speedup {:.2}x",
            self.width, self.height, self.speedup
        )?;
        if let (Some(g), Some(c)) = (self.gpu_process_cpu_s, self.cpu_process_cpu_s) {
            write!(
                f,
                " (process CPU time per frame: GPU path {:.2} s, CPU reference {:.2} s)",
                g, c
            )?;
        }
        if let Some(s) = &self.stereo {
            write!(
                f,
                "\nstereo 2x({}x{}): GPU median {:.2} ms/frame, CPU reference {:.2} ms/frame, speedup {:.2}x",
                s.eye_width, s.eye_height, s.gpu_median_ms, s.cpu_median_ms, s.speedup
            )?;
        }
        if let Some(d) = &self.diffuse {
            write!(
                f,
                "\ndiffuse variant: GPU median {:.2} ms/frame against {:.2} ms for the full variant on the same asset ({:.3}x); atlas texture {:.1} MB against {:.1} MB; max pixel difference {:.1e}",
                d.diffuse_median_ms,
                d.full_median_ms,
                d.ratio,
                d.diffuse_atlas_bytes as f64 / 1e6,
                d.full_atlas_bytes as f64 / 1e6,
                d.max_abs_diff
            )?;
            if let (Some(a), Some(b)) = (d.diffuse_process_cpu_s, d.full_process_cpu_s) {
                write!(f, " (process CPU time per frame {:.3} s against {:.3} s)", a, b)?;
            }
        }
        Ok(())
    }
}

pub fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// This process's CPU time (user + system) in seconds, where the OS tells (Linux). On
/// lavapipe the "GPU" is this process's threads, so CPU seconds per frame compare the work
/// of both renderers even on a busy machine.
pub fn process_cpu_seconds() -> Option<f64> {
    let s = std::fs::read_to_string("/proc/self/stat").ok()?;
    let f: Vec<&str> = s.rsplit(')').next()?.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

/// Adds the CPU seconds between readings `a` and `b` to `acc` (None once any reading is).
fn add_cpu(acc: &mut Option<f64>, a: Option<f64>, b: Option<f64>) {
    *acc = match (*acc, a, b) {
        (Some(x), Some(a), Some(b)) => Some(x + (b - a)),
        _ => None,
    }
}

fn ms(d: std::time::Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

/// Bench at `width` x `height` with `frames` GPU frames (defaults otherwise).
pub fn bench_view(asset: &Asset, width: u32, height: u32, frames: usize) -> Result<BenchView> {
    bench_view_with(
        asset,
        &BenchOptions {
            width,
            height,
            frames,
            ..Default::default()
        },
    )
}

/// Time a dynamic asset mid-way through its time range (keyframe blending included).
fn bench_time(asset: &Asset) -> f32 {
    asset
        .header
        .time_range
        .map_or(0.0, |r| 0.5 * (r[0] + r[1]) + 0.013 * (r[1] - r[0]))
}

pub fn bench_view_with(asset: &Asset, o: &BenchOptions) -> Result<BenchView> {
    ensure!(
        o.width > 0 && o.height > 0 && o.frames > 0,
        "bench needs a non-empty size and at least one frame"
    );
    let mut r = GpuRenderer::with_options(asset, o.gpu.clone())?;
    let time = bench_time(asset);
    let n = o.frames.max(1);
    let cams: Vec<Camera> = (0..n)
        .map(|i| orbit(&asset.header, n, i, o.width, o.height, o.fov_y))
        .collect();
    let view = |c: &Camera| {
        [View {
            cam: *c,
            time,
            x0: 0,
        }]
    };
    for c in cams.iter().take(2) {
        r.render_wait(o.width, o.height, &view(c))?;
    }
    let mut gpu: Vec<f64> = Vec::with_capacity(n);
    for c in &cams {
        gpu.push(ms(r.render_wait(o.width, o.height, &view(c))?));
    }
    // CPU reference on the first cameras, each right after the GPU renders the same camera
    // again, so a busy machine slows both alike.
    let cpu_n = o.cpu_frames.clamp(1, n);
    let mut gpu_same = Vec::with_capacity(cpu_n);
    let mut cpu = Vec::with_capacity(cpu_n);
    let (mut gpu_cs, mut cpu_cs) = (Some(0.0), Some(0.0));
    for c in cams.iter().take(cpu_n) {
        let c0 = process_cpu_seconds();
        gpu_same.push(ms(r.render_wait(o.width, o.height, &view(c))?));
        let c1 = process_cpu_seconds();
        let t0 = Instant::now();
        std::hint::black_box(snerf_asset::render(asset, c, time));
        cpu.push(ms(t0.elapsed()));
        let c2 = process_cpu_seconds();
        add_cpu(&mut gpu_cs, c0, c1);
        add_cpu(&mut cpu_cs, c1, c2);
    }
    let mut readback = Vec::new();
    for c in cams.iter().take(3) {
        let t0 = Instant::now();
        r.render(c, time)?;
        readback.push(ms(t0.elapsed()));
    }
    let gpu_min = gpu.iter().cloned().fold(f64::INFINITY, f64::min);
    let gpu_median = median(&mut gpu);
    let cpu_median = median(&mut cpu);
    let gpu_same_median = median(&mut gpu_same);
    let stereo = if o.stereo {
        let (ew, eh) = o.stereo_size;
        let m = o.frames.clamp(1, 5);
        let pairs: Vec<(Camera, Camera)> = (0..m)
            .map(|i| {
                let c = orbit(&asset.header, m, i, ew, eh, o.fov_y);
                stereo_pair(c.c2w, o.ipd, ew, eh, o.fov_y)
            })
            .collect();
        let sv = |(l, rr): &(Camera, Camera)| {
            [
                View {
                    cam: *l,
                    time,
                    x0: 0,
                },
                View {
                    cam: *rr,
                    time,
                    x0: ew,
                },
            ]
        };
        r.render_wait(2 * ew, eh, &sv(&pairs[0]))?;
        let mut g = Vec::new();
        for p in &pairs {
            g.push(ms(r.render_wait(2 * ew, eh, &sv(p))?));
        }
        let mut c = Vec::new();
        for (l, rr) in pairs.iter().take(o.cpu_frames.clamp(1, m)) {
            g.push(ms(r.render_wait(2 * ew, eh, &sv(&(*l, *rr)))?));
            let t0 = Instant::now();
            std::hint::black_box((
                snerf_asset::render(asset, l, time),
                snerf_asset::render(asset, rr, time),
            ));
            c.push(ms(t0.elapsed()));
        }
        let (gm, cm) = (median(&mut g), median(&mut c));
        Some(StereoBench {
            eye_width: ew,
            eye_height: eh,
            gpu_median_ms: gm,
            cpu_median_ms: cm,
            speedup: cm / gm,
        })
    } else {
        None
    };
    let diffuse = if asset.header.diffuse {
        Some(bench_diffuse(asset, &cams, time, o)?)
    } else {
        None
    };
    Ok(BenchView {
        adapter: r.adapter_info(),
        width: o.width,
        height: o.height,
        gpu_frames: n,
        gpu_median_ms: gpu_median,
        gpu_min_ms: gpu_min,
        gpu_readback_median_ms: median(&mut readback),
        cpu_frames: cpu_n,
        cpu_median_ms: cpu_median,
        gpu_same_cams_median_ms: gpu_same_median,
        speedup: cpu_median / gpu_same_median,
        gpu_process_cpu_s: gpu_cs.map(|x| x / cpu_n as f64),
        cpu_process_cpu_s: cpu_cs.map(|x| x / cpu_n as f64),
        stereo,
        diffuse,
    })
}

/// `DiffuseBench` over `cams`: each camera drawn by the diffuse variant and then by the full
/// one, after a warm-up frame of each.
fn bench_diffuse(asset: &Asset, cams: &[Camera], time: f32, o: &BenchOptions) -> Result<DiffuseBench> {
    let mut twin = asset.clone();
    twin.header.diffuse = false;
    let mut rd = GpuRenderer::with_options(asset, o.gpu.clone())?;
    let mut rf = GpuRenderer::with_options(&twin, o.gpu.clone())?;
    let view = |c: &Camera| [View { cam: *c, time, x0: 0 }];
    let mut max_abs_diff = 0.0f32;
    if let Some(c) = cams.first() {
        let (a, b) = (rd.render(c, time)?, rf.render(c, time)?);
        for (x, y) in a.rgb.iter().zip(&b.rgb) {
            max_abs_diff = max_abs_diff.max((x - y).abs());
        }
    }
    let (mut td, mut tf) = (Vec::new(), Vec::new());
    let (mut cd, mut cf) = (Some(0.0), Some(0.0));
    for c in cams {
        let c0 = process_cpu_seconds();
        td.push(ms(rd.render_wait(o.width, o.height, &view(c))?));
        let c1 = process_cpu_seconds();
        tf.push(ms(rf.render_wait(o.width, o.height, &view(c))?));
        let c2 = process_cpu_seconds();
        add_cpu(&mut cd, c0, c1);
        add_cpu(&mut cf, c1, c2);
    }
    let n = cams.len().max(1) as f64;
    let (dm, fm) = (median(&mut td), median(&mut tf));
    Ok(DiffuseBench {
        diffuse_median_ms: dm,
        full_median_ms: fm,
        ratio: dm / fm,
        diffuse_process_cpu_s: cd.map(|x| x / n),
        full_process_cpu_s: cf.map(|x| x / n),
        diffuse_atlas_bytes: rd.atlas_texture_bytes(),
        full_atlas_bytes: rf.atlas_texture_bytes(),
        max_abs_diff,
    })
}
