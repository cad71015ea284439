//! Writers for synthetic datasets: temp dirs, PNGs, .npy, COLMAP text/binary, camera helpers.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use serde_json::{json, Value};

/// A fresh directory under the system temp dir, removed on drop when the test passes and
/// kept (its path printed) when it fails.
pub struct TempDir(snerf_files::ScratchDir);

impl TempDir {
    pub fn new(tag: &str) -> TempDir {
        static N: AtomicUsize = AtomicUsize::new(0);
        let name = format!("{}-{tag}", N.fetch_add(1, Ordering::SeqCst));
        TempDir(snerf_files::ScratchDir::new("snerf-data", &name).unwrap())
    }
    pub fn path(&self) -> &Path {
        &self.0
    }
}

pub const W: u32 = 8;
pub const H: u32 = 6;
pub const F: f64 = 7.0;

pub type C2w = [[f64; 4]; 3];

fn norm(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|x| x / n)
}
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// OpenGL camera-to-world looking from `eye` at `target`.
pub fn look_at(eye: [f64; 3], target: [f64; 3], up: [f64; 3]) -> C2w {
    let z = norm([eye[0] - target[0], eye[1] - target[1], eye[2] - target[2]]);
    let x = norm(cross(up, z));
    let y = cross(z, x);
    std::array::from_fn(|r| [x[r], y[r], z[r], eye[r]])
}

/// Cameras all around the origin (a 360 capture), various heights.
pub fn ring_cameras(n: usize) -> Vec<C2w> {
    (0..n)
        .map(|i| {
            let a = i as f64 / n as f64 * std::f64::consts::TAU;
            let eye = [3.0 * a.cos(), 0.5 + 0.3 * (i as f64).sin(), 3.0 * a.sin()];
            look_at(eye, [0.0, 0.2, 0.0], [0.0, 1.0, 0.0])
        })
        .collect()
}

/// Forward-facing cameras on a small plane, all looking roughly down -z.
pub fn forward_cameras(n: usize) -> Vec<C2w> {
    (0..n)
        .map(|i| {
            let eye = [
                0.3 * (i as f64 * 1.3).sin(),
                0.2 * (i as f64 * 0.7).cos(),
                4.0,
            ];
            look_at(eye, [0.05 * i as f64, 0.0, 0.0], [0.0, 1.0, 0.0])
        })
        .collect()
}

pub fn mat4(c: &C2w) -> Value {
    json!([c[0], c[1], c[2], [0.0, 0.0, 0.0, 1.0]])
}

/// Writes an RGBA PNG; `transparent_bg` makes the border transparent.
pub fn write_png(path: &Path, w: u32, h: u32, seed: u8, transparent_bg: bool) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    let img = image::RgbaImage::from_fn(w, h, |x, y| {
        let inside = x > 0 && y > 0 && x + 1 < w && y + 1 < h;
        let a = if transparent_bg && !inside { 0 } else { 255 };
        image::Rgba([seed.wrapping_add(x as u8 * 10), y as u8 * 20, 128, a])
    });
    img.save(path).unwrap();
}

/// Writes an opaque RGB PNG (no alpha channel).
pub fn write_rgb_png(path: &Path, w: u32, h: u32, seed: u8) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    image::RgbImage::from_fn(w, h, |x, y| {
        image::Rgb([seed.wrapping_add(x as u8), y as u8, 7])
    })
    .save(path)
    .unwrap();
}

pub fn write_json(path: &Path, v: &Value) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap()).unwrap();
}

/// A nerfstudio transforms.json + images/frame_i.png in `dir`.
pub fn write_nerfstudio(dir: &Path, cams: &[C2w], transparent: bool, times: Option<&[f64]>) {
    let frames: Vec<Value> = cams
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let name = format!("images/frame_{i:03}.png");
            write_png(&dir.join(&name), W, H, i as u8, transparent);
            let mut f = json!({ "file_path": name, "transform_matrix": mat4(c) });
            if let Some(t) = times {
                f["time"] = json!(t[i]);
            }
            f
        })
        .collect();
    write_json(
        &dir.join("transforms.json"),
        &json!({
            "camera_model": "OPENCV", "fl_x": F, "fl_y": F, "cx": W as f64 / 2.0, "cy": H as f64 / 2.0,
            "w": W, "h": H, "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0, "frames": frames
        }),
    );
}

/// A Blender transforms.json (camera_angle_x, extension-less file paths) + train/r_i.png.
pub fn write_blender_single(dir: &Path, cams: &[C2w], transparent: bool) {
    let frames: Vec<Value> = cams
        .iter()
        .enumerate()
        .map(|(i, c)| {
            write_png(&dir.join(format!("train/r_{i}.png")), W, H, i as u8, transparent);
            json!({ "file_path": format!("./train/r_{i}"), "rotation": 0.1, "transform_matrix": mat4(c) })
        })
        .collect();
    let angle_x = 2.0 * (W as f64 / (2.0 * F)).atan();
    write_json(
        &dir.join("transforms.json"),
        &json!({ "camera_angle_x": angle_x, "frames": frames }),
    );
}

/// LLFF row for an OpenGL c2w.
pub fn llff_row(c: &C2w, near: f64, far: f64) -> Vec<f64> {
    let hwf = [H as f64, W as f64, F];
    let mut row = Vec::new();
    for r in 0..3 {
        row.extend([-c[r][1], c[r][0], c[r][2], c[r][3], hwf[r]]);
    }
    row.extend([near, far]);
    row
}

pub fn npy_bytes(descr: &str, shape: &[usize], body: &[u8]) -> Vec<u8> {
    let shape_s = match shape.len() {
        1 => format!("({},)", shape[0]),
        _ => format!(
            "({})",
            shape
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mut h = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape_s}, }}");
    while (10 + h.len() + 1) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((h.len() as u16).to_le_bytes());
    out.extend(h.as_bytes());
    out.extend(body);
    out
}

pub fn write_npy_f64(path: &Path, rows: &[Vec<f64>]) {
    let cols = rows.first().map(|r| r.len()).unwrap_or(17);
    let body: Vec<u8> = rows
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    std::fs::write(path, npy_bytes("<f8", &[rows.len(), cols], &body)).unwrap();
}

/// LLFF dataset: poses_bounds.npy + images/IMG_i.png (W x H).
pub fn write_llff(dir: &Path, cams: &[C2w]) {
    let rows: Vec<Vec<f64>> = cams
        .iter()
        .enumerate()
        .map(|(i, c)| llff_row(c, 1.0 + i as f64 * 0.1, 10.0 + i as f64))
        .collect();
    std::fs::create_dir_all(dir).unwrap();
    write_npy_f64(&dir.join("poses_bounds.npy"), &rows);
    for i in 0..cams.len() {
        write_png(
            &dir.join(format!("images/IMG_{i:03}.png")),
            W,
            H,
            i as u8,
            false,
        );
    }
}

/// Rotation matrix -> quaternion (w, x, y, z).
pub fn mat_to_quat(m: [[f64; 3]; 3]) -> [f64; 4] {
    let tr = m[0][0] + m[1][1] + m[2][2];
    if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [
            0.25 * s,
            (m[2][1] - m[1][2]) / s,
            (m[0][2] - m[2][0]) / s,
            (m[1][0] - m[0][1]) / s,
        ]
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let s = (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt() * 2.0;
        [
            (m[2][1] - m[1][2]) / s,
            0.25 * s,
            (m[0][1] + m[1][0]) / s,
            (m[0][2] + m[2][0]) / s,
        ]
    } else if m[1][1] > m[2][2] {
        let s = (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt() * 2.0;
        [
            (m[0][2] - m[2][0]) / s,
            (m[0][1] + m[1][0]) / s,
            0.25 * s,
            (m[1][2] + m[2][1]) / s,
        ]
    } else {
        let s = (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt() * 2.0;
        [
            (m[1][0] - m[0][1]) / s,
            (m[0][2] + m[2][0]) / s,
            (m[1][2] + m[2][1]) / s,
            0.25 * s,
        ]
    }
}

/// COLMAP (qvec, tvec) world-to-camera in OpenCV axes for an OpenGL c2w.
pub fn colmap_pose(c: &C2w) -> ([f64; 4], [f64; 3]) {
    // c2w_cv columns = [x, -y, -z]; R_w2c = its transpose.
    let r: [[f64; 3]; 3] = std::array::from_fn(|i| {
        let sign = [1.0, -1.0, -1.0][i];
        [sign * c[0][i], sign * c[1][i], sign * c[2][i]]
    });
    let t = [c[0][3], c[1][3], c[2][3]];
    let tw: [f64; 3] = std::array::from_fn(|i| -(r[i][0] * t[0] + r[i][1] * t[1] + r[i][2] * t[2]));
    (mat_to_quat(r), tw)
}

pub struct ColmapCam {
    pub id: u32,
    pub model: &'static str,
    pub model_id: i32,
    pub w: u64,
    pub h: u64,
    pub params: Vec<f64>,
}

pub fn pinhole_cam() -> ColmapCam {
    ColmapCam {
        id: 1,
        model: "PINHOLE",
        model_id: 1,
        w: W as u64,
        h: H as u64,
        params: vec![F, F, W as f64 / 2.0, H as f64 / 2.0],
    }
}

pub struct ColmapImg {
    pub name: String,
    pub cam: u32,
    pub q: [f64; 4],
    pub t: [f64; 3],
    pub npoints: usize,
}

pub fn colmap_images(cams: &[C2w]) -> Vec<ColmapImg> {
    cams.iter()
        .enumerate()
        .map(|(i, c)| {
            let (q, t) = colmap_pose(c);
            ColmapImg {
                name: format!("img_{i:02}.png"),
                cam: 1,
                q,
                t,
                npoints: i % 3,
            }
        })
        .collect()
}

pub fn cameras_txt(cams: &[ColmapCam]) -> String {
    let mut s = String::from("# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n");
    for c in cams {
        let p: Vec<String> = c.params.iter().map(|v| format!("{v}")).collect();
        s += &format!("{} {} {} {} {}\n", c.id, c.model, c.w, c.h, p.join(" "));
    }
    s
}

pub fn images_txt(imgs: &[ColmapImg]) -> String {
    let mut s = String::from("# Image list with two lines of data per image:\n");
    for (i, im) in imgs.iter().enumerate() {
        s += &format!(
            "{} {} {} {} {} {} {} {} {} {}\n",
            i + 1,
            im.q[0],
            im.q[1],
            im.q[2],
            im.q[3],
            im.t[0],
            im.t[1],
            im.t[2],
            im.cam,
            im.name
        );
        let pts: Vec<String> = (0..im.npoints)
            .map(|k| format!("{}.5 {}.25 {}", k, k, k as i64 - 1))
            .collect();
        s += &pts.join(" ");
        s += "\n";
    }
    s
}

pub fn cameras_bin(cams: &[ColmapCam]) -> Vec<u8> {
    let mut b = (cams.len() as u64).to_le_bytes().to_vec();
    for c in cams {
        b.extend((c.id as i32).to_le_bytes());
        b.extend(c.model_id.to_le_bytes());
        b.extend(c.w.to_le_bytes());
        b.extend(c.h.to_le_bytes());
        for p in &c.params {
            b.extend(p.to_le_bytes());
        }
    }
    b
}

pub fn images_bin(imgs: &[ColmapImg]) -> Vec<u8> {
    let mut b = (imgs.len() as u64).to_le_bytes().to_vec();
    for (i, im) in imgs.iter().enumerate() {
        b.extend((i as u32 + 1).to_le_bytes());
        for v in im.q.iter().chain(&im.t) {
            b.extend(v.to_le_bytes());
        }
        b.extend(im.cam.to_le_bytes());
        b.extend(im.name.as_bytes());
        b.push(0);
        b.extend((im.npoints as u64).to_le_bytes());
        for k in 0..im.npoints {
            b.extend((k as f64 + 0.5).to_le_bytes());
            b.extend((k as f64).to_le_bytes());
            b.extend((k as i64 - 1).to_le_bytes());
        }
    }
    b
}

/// COLMAP dataset: root/sparse/0/{cameras,images}.{bin|txt} + root/images/img_i.png.
pub fn write_colmap(root: &Path, cams: &[C2w], binary: bool) -> PathBuf {
    let model = root.join("sparse/0");
    std::fs::create_dir_all(&model).unwrap();
    let imgs = colmap_images(cams);
    let cam = [pinhole_cam()];
    if binary {
        std::fs::write(model.join("cameras.bin"), cameras_bin(&cam)).unwrap();
        std::fs::write(model.join("images.bin"), images_bin(&imgs)).unwrap();
    } else {
        std::fs::write(model.join("cameras.txt"), cameras_txt(&cam)).unwrap();
        std::fs::write(model.join("images.txt"), images_txt(&imgs)).unwrap();
    }
    for (i, im) in imgs.iter().enumerate() {
        write_png(&root.join("images").join(&im.name), W, H, i as u8, false);
    }
    model
}

pub fn assert_c2w_close(got: &[[f32; 4]; 3], want: &C2w, tol: f32, ctx: &str) {
    for r in 0..3 {
        for c in 0..4 {
            assert!(
                (got[r][c] - want[r][c] as f32).abs() < tol,
                "{ctx}: c2w[{r}][{c}] = {} but expected {}\n got {got:?}\n want {want:?}",
                got[r][c],
                want[r][c]
            );
        }
    }
}

/// Asserts that `err` mentions every needle.
pub fn assert_err_has(err: &anyhow::Error, needles: &[&str]) {
    let s = format!("{err:#}");
    for n in needles {
        assert!(s.contains(n), "error message {s:?} does not mention {n:?}");
    }
}
