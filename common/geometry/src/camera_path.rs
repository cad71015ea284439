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
//! plain list of `{"c2w": 3 or 4 rows of 4, "time"}` (snerf's older pose file) reads too.

use serde::{Deserialize, Serialize};

use crate::camera::{C2w, Pinhole};

/// One camera of a path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathCamera {
    pub c2w: C2w,
    /// Vertical field of view, degrees.
    pub fov_y: f32,
    pub width: u32,
    pub height: u32,
    pub time: Option<f32>,
}

impl PathCamera {
    pub fn pinhole(&self) -> Pinhole {
        Pinhole::from_fov(self.c2w, self.width, self.height, self.fov_y)
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
                Ok(PathCamera { c2w, fov_y: k.fov, width: p.render_width, height: p.render_height, time: k.time })
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
                Ok(PathCamera { c2w, fov_y: default_fov_y, width: default_size.0, height: default_size.1, time: p.time })
            })
            .collect::<Result<Vec<_>, _>>()?
    };
    if cams.is_empty() {
        return Err("no cameras".into());
    }
    for (i, c) in cams.iter().enumerate() {
        if !c.c2w.iter().flatten().all(|x| x.is_finite()) || c.time.is_some_and(|t| !t.is_finite()) {
            return Err(format!("camera {i} has non-finite values"));
        }
        if !(c.fov_y > 0.0 && c.fov_y < 180.0) {
            return Err(format!("camera {i}: fov {} must be in (0, 180) degrees", c.fov_y));
        }
        if !(1..=16384).contains(&c.width) || !(1..=16384).contains(&c.height) {
            return Err(format!("render size {}x{} out of range", c.width, c.height));
        }
    }
    Ok(cams)
}

/// A nerfstudio `camera_path.json` for `cams` (all of one size), played at `fps`.
pub fn to_json(cams: &[PathCamera], fps: f32) -> String {
    let (w, h) = cams.first().map(|c| (c.width, c.height)).unwrap_or((1, 1));
    let p = NsPath {
        camera_type: perspective(),
        render_width: w,
        render_height: h,
        fps: Some(fps),
        seconds: Some(cams.len() as f32 / fps),
        camera_path: cams
            .iter()
            .map(|c| {
                let m = c.c2w;
                let mut flat: Vec<f32> = m.iter().flatten().copied().collect();
                flat.extend([0.0, 0.0, 0.0, 1.0]);
                NsKeyframe { camera_to_world: flat, fov: c.fov_y, aspect: Some(c.width as f32 / c.height as f32), time: c.time }
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
            .map(|i| PathCamera {
                c2w: look_at([i as f32, 1.0, 3.0], [0.0; 3], [0.0, 1.0, 0.0]),
                fov_y: 40.0,
                width: 64,
                height: 48,
                time: (i == 1).then_some(0.5),
            })
            .collect();
        let text = to_json(&cams, 24.0);
        assert!(text.contains("\"camera_to_world\"") && text.contains("\"render_width\": 64"));
        assert_eq!(parse(&text, (1, 1), 1.0).unwrap(), cams);
        let list = r#"[{"c2w": [[1,0,0,0],[0,1,0,0],[0,0,1,2]], "time": 0.25}]"#;
        let p = parse(list, (32, 16), 50.0).unwrap();
        assert_eq!((p[0].width, p[0].height, p[0].fov_y, p[0].time), (32, 16, 50.0, Some(0.25)));
        for bad in ["[]", "{}", r#"{"render_width":1,"render_height":1,"camera_path":[{"camera_to_world":[1,2],"fov":40}]}"#, r#"[{"c2w": [[1,0,0,0]]}]"#] {
            assert!(parse(bad, (1, 1), 40.0).is_err(), "{bad}");
        }
    }
}
