//! Test assets and helpers shared by the viewer tests: a static object with coloured,
//! partly transparent structure and a non-zero view MLP; an unbounded scene with far
//! content; a forward-facing (NDC) scene; a 3-keyframe dynamic asset.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use snerf_asset::{
    encode_voxel, Asset, AssetBuilder, Camera, Frame, Header, Keyframe, Kind, Ndc, ViewMlp,
};

/// This test's directory: removed when it passes, kept (and named) when it fails.
pub fn tmp(name: &str) -> snerf_files::ScratchDir {
    snerf_files::ScratchDir::new("snerf-viewer", name).unwrap()
}

/// Private XDG_RUNTIME_DIR (silences Mesa) and the "GPU tests are required" switch. The
/// directory is one under the target directory, shared by every run, so none is left behind.
pub fn setup() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
            let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join("xdg-runtime");
            let _ = std::fs::create_dir_all(&d);
            #[cfg(unix)]
            {
                use std::os::unix::fs::PermissionsExt;
                let _ = std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o700));
            }
            std::env::set_var("XDG_RUNTIME_DIR", &d);
        }
    });
}

pub fn gpu_required() -> bool {
    std::env::var("SNERF_REQUIRE_GPU_TESTS").is_ok_and(|v| v == "1")
}

/// True if a GPU adapter exists; otherwise prints a skip note (or panics when required).
pub fn have_gpu(test: &str) -> bool {
    setup();
    match snerf_viewer::gpu_available() {
        Some(_) => true,
        None => {
            if gpu_required() {
                panic!("{}: no GPU adapter, and SNERF_REQUIRE_GPU_TESTS=1", test);
            }
            eprintln!(
                "SKIP {}: no GPU adapter (install mesa-vulkan-drivers for lavapipe)",
                test
            );
            false
        }
    }
}

pub struct Rng(pub u64);
impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    pub fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

pub fn mlp(scale: f32) -> ViewMlp {
    let mut m = ViewMlp::zeros();
    let mut r = Rng(0x5eed);
    for w in m.w1.iter_mut() {
        *w = (r.unit() - 0.5) * 0.6 * scale;
    }
    for w in m.b1.iter_mut() {
        *w = (r.unit() - 0.3) * 0.2;
    }
    for w in m.w2.iter_mut() {
        *w = (r.unit() - 0.5) * 0.5 * scale;
    }
    for w in m.b2.iter_mut() {
        *w = (r.unit() - 0.3) * 0.2;
    }
    for w in m.w3.iter_mut() {
        *w = (r.unit() - 0.5) * 0.4 * scale;
    }
    m.b3 = vec![0.02, -0.03, 0.04];
    m
}

/// Rotation about the axis (1, 2, 3)/|.| by `angle` (row-major, orthonormal).
pub fn rot(angle: f32) -> [[f32; 3]; 3] {
    let n = (14f32).sqrt();
    let (x, y, z) = (1.0 / n, 2.0 / n, 3.0 / n);
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

fn centre(i: usize, res: u32) -> f32 {
    -1.0 + (i as f32 + 0.5) * 2.0 / res as f32
}

/// Fill every cell for which `occupied(cell)` holds, per frame, from `voxel(frame, grid point)`.
fn build(
    h: Header,
    m: ViewMlp,
    occupied: impl Fn(usize, [usize; 3]) -> bool,
    voxel: impl Fn(usize, [f32; 3]) -> [u8; 8],
) -> Asset {
    let g = h.grid_dim();
    let res = h.res;
    let frames = h.num_frames();
    let mut b = AssetBuilder::new(h, m).unwrap();
    for f in 0..frames {
        for z in 0..g {
            for y in 0..g {
                for x in 0..g {
                    if occupied(f, [x, y, z]) {
                        let blk = b.block_from_fn([x, y, z], |v| {
                            voxel(f, [centre(v[0], res), centre(v[1], res), centre(v[2], res)])
                        });
                        b.set_block(f, [x, y, z], &blk).unwrap();
                    }
                }
            }
        }
    }
    b.finish().unwrap()
}

/// Static object: a soft sphere shell, a thin translucent slab and a dense cube, smooth
/// colours and features, some noise; cells far from everything are left empty.
pub fn object_asset() -> Asset {
    let mut h = Header::new(Kind::Object, 64, 8);
    h.space.center = [0.3, -0.2, 0.5];
    h.space.rot = rot(0.7);
    h.space.scale = 0.8;
    h.background = [0.9, 0.85, 0.8];
    h.density = snerf_asset::DensityRange {
        logit_min: -8.0,
        logit_max: 6.0,
    };
    h.march.step = 1.0 / 64.0;
    let d = h.density;
    let noise = |p: [f32; 3]| {
        ((p[0] * 91.7 + p[1] * 47.3 + p[2] * 13.1).sin() * 43758.5)
            .fract()
            .abs()
    };
    build(
        h,
        mlp(1.0),
        |_, c| {
            // leave the +x,+y,+z corner region and a few others empty
            (c[0] < 6 || c[1] < 6) && (c[2] != 0 || c[0] >= 2)
        },
        move |_, p| {
            let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            let shell = (-((r - 0.55) / 0.06).powi(2)).exp() * 7.0;
            let slab = if (p[1] + 0.35).abs() < 0.04 && p[0].abs() < 0.8 {
                2.5
            } else {
                0.0
            };
            let cube =
                if (p[0] - 0.25).abs() < 0.15 && (p[1] - 0.1).abs() < 0.15 && p[2].abs() < 0.15 {
                    30.0
                } else {
                    0.0
                };
            let sigma = shell + slab + cube + 0.002;
            let rgb = [
                0.5 + 0.5 * p[0],
                0.5 + 0.4 * (3.0 * p[1]).sin(),
                0.3 + 0.6 * noise(p),
            ];
            let feat = [
                0.5 + 0.5 * p[2],
                noise(p),
                0.5 - 0.4 * p[0],
                0.25 + 0.5 * (p[1] * p[1]),
            ];
            encode_voxel(
                sigma.ln(),
                rgb.map(|v| v.clamp(0.0, 1.0)),
                feat.map(|v| v.clamp(0.0, 1.0)),
                &d,
            )
        },
    )
}

/// Unbounded: a small object in the unit cube plus a far coloured "environment" shell at
/// |p| ≈ 6-20 model units (grid radius 0.8-0.97 after contraction).
pub fn unbounded_asset() -> Asset {
    let mut h = Header::new(Kind::Unbounded, 64, 8);
    h.space.center = [0.0, 0.1, 0.0];
    h.space.scale = 1.3;
    h.background = [0.1, 0.2, 0.3];
    h.march.step = 1.0 / 64.0;
    let d = h.density;
    build(
        h,
        mlp(0.7),
        |_, _| true,
        move |_, g| {
            let m = g[0].abs().max(g[1].abs()).max(g[2].abs());
            let inner = {
                let q = [g[0] * 2.0, g[1] * 2.0, g[2] * 2.0];
                let r = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
                if r < 0.5 {
                    12.0
                } else {
                    0.0
                }
            };
            let far = if m > 0.8 && m < 0.97 { 0.8 } else { 0.0 };
            let sigma: f32 = inner + far + 1e-3;
            let rgb = [0.5 + 0.5 * g[0], 0.5 + 0.5 * g[2], 0.5 - 0.4 * g[1]];
            let feat = [m, 1.0 - m, 0.5 + 0.5 * g[1], 0.3];
            encode_voxel(
                sigma.ln(),
                rgb.map(|v| v.clamp(0.0, 1.0)),
                feat.map(|v| v.clamp(0.0, 1.0)),
                &d,
            )
        },
    )
}

/// Forward-facing (NDC): three translucent layers at different NDC depths with patterns.
pub fn forward_asset() -> Asset {
    let mut h = Header::new(Kind::Forward, 64, 8);
    h.space.ndc = Some(Ndc {
        fx: 60.0,
        fy: 60.0,
        width: 100.0,
        height: 80.0,
        near: 1.0,
        xy_extent: 1.3,
    });
    h.space.scale = 1.0;
    h.background = [0.0, 0.0, 0.0];
    h.march.step = 1.0 / 64.0;
    let d = h.density;
    build(
        h,
        mlp(0.8),
        |_, c| !(c[2] == 3 || c[2] == 6),
        move |_, g| {
            let layer = |z0: f32| (-((g[2] - z0) / 0.05).powi(2)).exp();
            let stripes = 0.5 + 0.5 * (g[0] * 9.0).sin() * (g[1] * 7.0).cos();
            let sigma = 40.0 * layer(-0.5) * stripes + 15.0 * layer(0.2) + 60.0 * layer(0.8) + 1e-3;
            let rgb = [0.5 + 0.5 * g[0], 0.5 + 0.5 * g[1], 0.5 + 0.5 * g[2]];
            encode_voxel(
                sigma.ln(),
                rgb.map(|v| v.clamp(0.0, 1.0)),
                [0.2, 0.4, stripes, 0.6],
                &d,
            )
        },
    )
}

/// 3 keyframes (t = 0, 0.5, 1): the sphere moves and changes colour; some cells exist in
/// only one keyframe (blending against "empty"); unchanged blocks are shared.
pub fn dynamic_asset() -> Asset {
    let mut h = Header::new(Kind::Object, 32, 8);
    h.background = [0.05, 0.05, 0.1];
    h.time_range = Some([0.0, 1.0]);
    h.frames = Some(vec![
        Keyframe { time: 0.0 },
        Keyframe { time: 0.5 },
        Keyframe { time: 1.0 },
    ]);
    h.march.step = 1.0 / 48.0;
    let d = h.density;
    build(
        h,
        mlp(1.0),
        |f, c| {
            // x-cell 3 only exists in the last frame; x-cell 0 only in the first two
            (c[0] != 3 || f == 2) && (c[0] != 0 || f < 2)
        },
        move |f, g| {
            let cx = -0.2 + 0.2 * f as f32;
            let r = ((g[0] - cx).powi(2) + g[1] * g[1] + g[2] * g[2]).sqrt();
            let sigma: f32 = if r < 0.5 { 8.0 } else { 0.05 };
            let rgb = [0.3 + 0.3 * f as f32, 0.5 + 0.4 * g[1], 0.8 - 0.3 * f as f32];
            encode_voxel(
                sigma.ln(),
                rgb.map(|v| v.clamp(0.0, 1.0)),
                [0.1 * f as f32, 0.5, 0.5 + 0.4 * g[0], 0.2],
                &d,
            )
        },
    )
}

/// A 4D asset with motion (`snerf_asset::motion`): `dynamic_asset`'s first frame is the
/// reference; frames 1 and 2 show it moved (every cell a motion entry, quarter-voxel
/// offsets), so playback between them moves the reference by the interpolated offset.
#[allow(dead_code)]
pub fn motion_asset() -> Asset {
    let mut a = dynamic_asset();
    a.header.motion_ref = Some(0);
    let n = a.grids[0].len();
    a.grids[1] = vec![snerf_asset::motion::motion_entry([-3.25, 0.75, 0.0]); n];
    a.grids[2] = vec![snerf_asset::motion::motion_entry([-6.5, 1.5, -0.75]); n];
    a.validate().unwrap();
    a
}

/// Per-channel differences between two frames' rgb (and opacity).
#[derive(Debug)]
pub struct Diff {
    pub mean: f64,
    pub p999: f64,
    pub max: f64,
    pub opacity_mean: f64,
    pub opacity_max: f64,
}

pub fn diff(a: &Frame, b: &Frame) -> Diff {
    assert_eq!((a.width, a.height), (b.width, b.height));
    let mut d: Vec<f64> = a
        .rgb
        .iter()
        .zip(&b.rgb)
        .map(|(x, y)| (x - y).abs() as f64)
        .collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    d.sort_by(|x, y| x.total_cmp(y));
    let p999 = d[((d.len() as f64 * 0.999) as usize).min(d.len() - 1)];
    let max = *d.last().unwrap();
    let od: Vec<f64> = a
        .opacity
        .iter()
        .zip(&b.opacity)
        .map(|(x, y)| (x - y).abs() as f64)
        .collect();
    Diff {
        mean,
        p999,
        max,
        opacity_mean: od.iter().sum::<f64>() / od.len() as f64,
        opacity_max: od.iter().cloned().fold(0.0, f64::max),
    }
}

/// Fraction of pixels that are not background-only (to check a test image has content).
pub fn coverage(f: &Frame) -> f64 {
    f.opacity.iter().filter(|&&o| o > 0.05).count() as f64 / f.opacity.len() as f64
}

pub fn cams(h: &Header, n: usize, w: u32, hh: u32) -> Vec<Camera> {
    (0..n)
        .map(|i| snerf_asset::orbit(h, n, i, w, hh, 50.0))
        .collect()
}

/// A private X display for window tests (Xvfb), stopped on drop.
pub struct Xvfb(Option<Child>);
impl Drop for Xvfb {
    fn drop(&mut self) {
        if let Some(c) = self.0.as_mut() {
            // SIGTERM first: Xvfb then removes its lock file and socket. Killed outright it
            // leaves both behind, and every later run has one display number fewer to use.
            let _ = Command::new("kill").args(["-TERM", &c.id().to_string()]).status();
            let t0 = Instant::now();
            while t0.elapsed() < Duration::from_secs(3) {
                if let Ok(Some(_)) = c.try_wait() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

pub fn which(bin: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(bin).is_file()))
}

/// A display: $DISPLAY, or a private Xvfb we start (and stop on drop).
pub fn display() -> Option<Xvfb> {
    if std::env::var_os("DISPLAY").is_some() {
        return Some(Xvfb(None));
    }
    if !which("Xvfb") {
        return None;
    }
    for n in 90 + (std::process::id() % 50)..200 {
        let sock = format!("/tmp/.X11-unix/X{}", n);
        if Path::new(&sock).exists() || Path::new(&format!("/tmp/.X{}-lock", n)).exists() {
            continue;
        }
        let child = Command::new("Xvfb")
            .args([
                &format!(":{}", n),
                "-screen",
                "0",
                "640x480x24",
                "-nolisten",
                "tcp",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .ok()?;
        let mut x = Xvfb(Some(child));
        let t0 = Instant::now();
        // Ready when its socket takes a connection (the file alone can be a stale one, and
        // on a loaded machine the server may still be starting); an Xvfb that exits (the
        // display taken after all) means the next number.
        let mut exited = false;
        while t0.elapsed() < Duration::from_secs(30) {
            if x.0.as_mut().is_some_and(|c| matches!(c.try_wait(), Ok(Some(_)))) {
                exited = true;
                break;
            }
            if std::os::unix::net::UnixStream::connect(&sock).is_ok() {
                std::env::set_var("DISPLAY", format!(":{}", n));
                return Some(x);
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        if !exited {
            return None;
        }
    }
    None
}
