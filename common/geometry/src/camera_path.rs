//! Camera paths on disk: nerfstudio's `camera_path.json`, the file users already make with
//! nerfstudio's viewer and Blender add-on, read and written by every snerf command that takes
//! or produces a path (`snerf render --path`, turntables, the viewer's `--poses`).
//!
//! ```json
//! {"camera_type": "perspective", "render_width": 640, "render_height": 480, "fps": 24,
//!  "seconds": 2.0, "camera_path": [{"camera_to_world": [16 numbers, row-major 4x4],
//!  "fov": 50.0, "aspect": 1.333, "time": 0.5}]}
//! ```
//! `camera_to_world` is OpenGL (x right, y up, looking down -z), `fov` the vertical field of
//! view in degrees. `time` (optional, snerf's addition) is the scene time of a 4D asset. A
//! plain list of `{"c2w": 3 or 4 rows of 4, "time"}` (snerf's older pose file, optionally with
//! "fx", "fy", "cx", "cy", "width", "height") reads too.

use serde::{Deserialize, Serialize};

use crate::camera::Pinhole;

/// One camera of a path: a pinhole camera and the scene time it shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathCamera {
    pub cam: Pinhole,
    pub time: Option<f32>,
}

impl PathCamera {
    /// Vertical field of view in degrees.
    pub fn fov_y(&self) -> f32 {
        2.0 * (0.5 * self.cam.height as f32 / self.cam.fy).atan().to_degrees()
    }
}

#[derive(Serialize, Deserialize)]
struct NsKeyframe {
    camera_to_world: Vec<f32>,
    fov: f32,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    aspect: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    time: Option<f32>,
}

#[derive(Serialize, Deserialize)]
struct NsPath {
    #[serde(default = "perspective")]
    camera_type: String,
    render_width: u32,
    render_height: u32,
    #[serde(default)]
    fps: Option<f32>,
    #[serde(default)]
    seconds: Option<f32>,
    camera_path: Vec<NsKeyframe>,
}

fn perspective() -> String {
    "perspective".into()
}

#[derive(Deserialize)]
struct PoseEntry {
    c2w: Vec<[f32; 4]>,
    #[serde(default)]
    time: Option<f32>,
    fx: Option<f32>,
    fy: Option<f32>,
    cx: Option<f32>,
    cy: Option<f32>,
    width: Option<u32>,
    height: Option<u32>,
}

/// Parse a camera path. `default_size` and `default_fov_y` fill what a pose list lacks.
pub fn parse(text: &str, default_size: (u32, u32), default_fov_y: f32) -> Result<Vec<PathCamera>, String> {
    let v: serde_json::Value = serde_json::from_str(text).map_err(|e| format!("not JSON: {e}"))?;
    let cams = if v.get("camera_path").is_some() {
        let p: NsPath = serde_json::from_value(v).map_err(|e| format!("not a nerfstudio camera_path.json: {e}"))?;
        if p.camera_type != "perspective" {
            return Err(format!("camera_type {:?}: only perspective cameras are supported", p.camera_type));
        }
        p.camera_path
            .iter()
            .enumerate()
            .map(|(i, k)| {
                if k.camera_to_world.len() != 16 {
                    return Err(format!("camera {i}: camera_to_world has {} numbers, expected 16", k.camera_to_world.len()));
                }
                let m = &k.camera_to_world;
                let c2w = [[m[0], m[1], m[2], m[3]], [m[4], m[5], m[6], m[7]], [m[8], m[9], m[10], m[11]]];
                if !(k.fov > 0.0 && k.fov < 180.0) {
                    return Err(format!("camera {i}: fov {} must be in (0, 180) degrees", k.fov));
                }
                Ok(PathCamera { cam: Pinhole::from_fov(c2w, p.render_width, p.render_height, k.fov), time: k.time })
            })
            .collect::<Result<Vec<_>, _>>()?
    } else {
        let list: Vec<PoseEntry> =
            serde_json::from_value(v).map_err(|e| format!("neither a nerfstudio camera_path.json nor a list of {{c2w, time}}: {e}"))?;
        list.iter()
            .enumerate()
            .map(|(i, p)| {
                if !(p.c2w.len() == 3 || p.c2w.len() == 4) {
                    return Err(format!("pose {i} has {} rows (need 3 or 4 rows of 4)", p.c2w.len()));
                }
                let c2w = [p.c2w[0], p.c2w[1], p.c2w[2]];
                let (w, h) = (p.width.unwrap_or(default_size.0), p.height.unwrap_or(default_size.1));
                let mut cam = Pinhole::from_fov(c2w, w, h, default_fov_y);
                cam.fx = p.fx.unwrap_or(cam.fx);
                cam.fy = p.fy.unwrap_or(cam.fy);
                cam.cx = p.cx.unwrap_or(cam.cx);
                cam.cy = p.cy.unwrap_or(cam.cy);
                Ok(PathCamera { cam, time: p.time })
            })
            .collect::<Result<Vec<_>, _>>()?
    };
    if cams.is_empty() {
        return Err("no cameras".into());
    }
    for (i, PathCamera { cam: c, time }) in cams.iter().enumerate() {
        let numbers = c.c2w.iter().flatten().chain([&c.fx, &c.fy, &c.cx, &c.cy]);
        if !numbers.into_iter().all(|x| x.is_finite()) || time.is_some_and(|t| !t.is_finite()) {
            return Err(format!("camera {i} has non-finite values"));
        }
        if !(c.fx > 0.0 && c.fy > 0.0) {
            return Err(format!("camera {i}: fx and fy must be positive (fx {}, fy {})", c.fx, c.fy));
        }
        if !(1..=16384).contains(&c.width) || !(1..=16384).contains(&c.height) {
            return Err(format!("camera {i}: size {}x{} out of range", c.width, c.height));
        }
    }
    Ok(cams)
}

/// A nerfstudio `camera_path.json` for `cams` (all of one size), played at `fps`.
pub fn to_json(cams: &[PathCamera], fps: f32) -> String {
    let (w, h) = cams.first().map(|c| (c.cam.width, c.cam.height)).unwrap_or((1, 1));
    let p = NsPath {
        camera_type: perspective(),
        render_width: w,
        render_height: h,
        fps: Some(fps),
        seconds: Some(cams.len() as f32 / fps),
        camera_path: cams
            .iter()
            .map(|c| {
                let mut flat: Vec<f32> = c.cam.c2w.iter().flatten().copied().collect();
                flat.extend([0.0, 0.0, 0.0, 1.0]);
                NsKeyframe { camera_to_world: flat, fov: c.fov_y(), aspect: Some(c.cam.width as f32 / c.cam.height as f32), time: c.time }
            })
            .collect(),
    };
    serde_json::to_string_pretty(&p).expect("a camera path serializes")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::look_at;

    #[test]
    fn round_trip_and_the_older_pose_list() {
        let cams: Vec<PathCamera> = (0..3)
            .map(|i| PathCamera { cam: Pinhole::from_fov(look_at([i as f32, 1.0, 3.0], [0.0; 3], [0.0, 1.0, 0.0]), 64, 48, 40.0), time: (i == 1).then_some(0.5) })
            .collect();
        let text = to_json(&cams, 24.0);
        assert!(text.contains("\"camera_to_world\"") && text.contains("\"render_width\": 64"));
        let back = parse(&text, (1, 1), 1.0).unwrap();
        for (a, b) in back.iter().zip(&cams) {
            assert_eq!((a.cam.c2w, a.cam.width, a.cam.height, a.time), (b.cam.c2w, b.cam.width, b.cam.height, b.time));
            assert!((a.cam.fy - b.cam.fy).abs() < 1e-3 && (a.cam.cx - b.cam.cx).abs() < 1e-6);
        }
        let list = r#"[{"c2w": [[1,0,0,0],[0,1,0,0],[0,0,1,2]], "time": 0.25}]"#;
        let p = parse(list, (32, 16), 50.0).unwrap();
        assert_eq!((p[0].cam.width, p[0].cam.height, p[0].time), (32, 16, Some(0.25)));
        assert!((p[0].fov_y() - 50.0).abs() < 1e-3);
        let with_k = r#"[{"c2w": [[1,0,0,0],[0,1,0,0],[0,0,1,2]], "fx": 20, "fy": 21, "cx": 8, "cy": 7, "width": 16, "height": 14}]"#;
        let k = parse(with_k, (1, 1), 50.0).unwrap()[0].cam;
        assert_eq!((k.fx, k.fy, k.cx, k.cy, k.width, k.height), (20.0, 21.0, 8.0, 7.0, 16, 14));
        let e = parse(&with_k.replace("\"fx\": 20", "\"fx\": 0"), (1, 1), 50.0).unwrap_err();
        assert!(e.contains("fx"), "{e}");
        for bad in ["[]", "{}", r#"{"render_width":1,"render_height":1,"camera_path":[{"camera_to_world":[1,2],"fov":40}]}"#, r#"[{"c2w": [[1,0,0,0]]}]"#] {
            assert!(parse(bad, (1, 1), 40.0).is_err(), "{bad}");
        }
    }
}
