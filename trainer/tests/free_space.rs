//! Free-space carving from sparse points: it carves the lines of sight and never the surface
//! the points lie on, in object, forward-facing (NDC) and unbounded (contracted) space.

use snerf_data::{Dataset, Intrinsics, SceneKind, TrackedPoint, View};
use snerf_trainer::free_space::{carve, walk_segment, CarveRules};
use snerf_trainer::occupancy::Occupancy;
use snerf_trainer::space::{norm, sub, SceneSpace, Vec3};
use snerf_trainer::train::{TrainConfig, Trainer};
use snerf_geometry::{Ndc, Space};

/// A small deterministic generator (the tests must not depend on a seed's luck).
struct Lcg(u64);
impl Lcg {
    fn uniform(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
    fn normal(&mut self) -> f32 {
        let (u, v) = (self.uniform().max(1e-7), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
    }
}

/// Cell of a world point, through the same mappings the carving uses.
fn cell_of(occ: &Occupancy, space: &SceneSpace, p: Vec3) -> Option<usize> {
    space.world_to_march(p).and_then(|m| occ.cell(&space.to_grid(m)))
}

/// A forward-facing space like a capture's: reference camera at the origin looking down -z,
/// content from depth 2 on.
fn forward_space() -> SceneSpace {
    let mut s = SceneSpace::identity(SceneKind::Forward, false);
    s.frame = Space { center: [0.0; 3], rot: snerf_trainer::space::IDENTITY, scale: 1.0 / (2.0 * 0.75), ndc: Some(Ndc { fx: 50.0, fy: 50.0, width: 64.0, height: 48.0, near: 1.0, xy_extent: 1.25 }) };
    s
}

/// A wall of points at depth `z` (world), seen by every camera.
fn wall(z: f32, cams: usize) -> Vec<TrackedPoint> {
    let mut pts = Vec::new();
    for i in 0..15 {
        for j in 0..15 {
            let (x, y) = (-0.7 + 0.1 * i as f32, -0.5 + 0.075 * j as f32);
            pts.push(TrackedPoint { xyz: [x * -z / 2.0, y * -z / 2.0, z], seen_by: (0..cams as u32).collect() });
        }
    }
    pts
}

#[test]
fn carving_keeps_every_point_cell_and_carves_the_observed_segments() {
    let cams: Vec<Vec3> = vec![[0.0, 0.0, 0.0], [0.2, 0.0, 0.05], [-0.2, 0.1, 0.0], [0.0, -0.15, -0.1]];
    for (name, space, z) in [
        ("object", SceneSpace::identity(SceneKind::Object, false), -0.8f32),
        ("forward", forward_space(), -6.0),
        ("unbounded", SceneSpace::identity(SceneKind::Unbounded, false), -4.0),
    ] {
        let cams: Vec<Vec3> = if name == "object" { cams.iter().map(|c| [c[0], c[1], c[2] + 0.9]).collect() } else { cams.clone() };
        let pts = wall(z, cams.len());
        let mut occ = Occupancy::new(64, 512);
        let stats = carve(&mut occ, &space, &cams, &pts, CarveRules::default());
        assert!(stats.carved_cells > 0, "{name}: nothing carved: {stats:?}");
        for p in &pts {
            let c = cell_of(&occ, &space, p.xyz).unwrap_or_else(|| panic!("{name}: point {:?} is outside the grid", p.xyz));
            assert!(occ.allowed[c], "{name}: the cell holding point {:?} was carved", p.xyz);
        }
        // The middle of the line of sight from the first camera to the wall's central point
        // is free and crossed by every camera's segments nearby: carved.
        let centre = pts[7 * 15 + 7].xyz;
        let cam = cams[0];
        let at = |f: f32| [cam[0] + f * (centre[0] - cam[0]), cam[1] + f * (centre[1] - cam[1]), cam[2] + f * (centre[2] - cam[2])];
        let carved_mid = [0.5f32, 0.6, 0.7].iter().filter_map(|&f| cell_of(&occ, &space, at(f))).any(|c| !occ.allowed[c]);
        assert!(carved_mid, "{name}: the middle of an observed segment was left: {stats:?}");
        // Behind the wall no camera saw anything: untouched.
        let behind = [centre[0], centre[1], centre[2] * 1.6];
        if let Some(c) = cell_of(&occ, &space, behind) {
            assert!(occ.allowed[c], "{name}: a cell behind the wall was carved");
        }
    }
}

#[test]
fn a_segment_stops_short_of_its_point() {
    let space = SceneSpace::identity(SceneKind::Object, false);
    let occ = Occupancy::new(64, 512);
    let (cam, p) = ([0.0, 0.0, 0.95], [0.0, 0.0, -0.95]);
    let mut cells = Vec::new();
    walk_segment(&occ, &space, cam, p, 0.1, |c| cells.push(c));
    let far = cells.iter().map(|&c| occ.cell_center(c)[2]).fold(f32::INFINITY, f32::min);
    // 10% of 1.9 short of z = -0.95 is z = -0.76; the last cell reaches at most one cell past it
    assert!(far > -0.76 - 2.0 / 64.0 && far < -0.70, "last cell centre at z = {far}");
    // consecutive, distinct cells: each crossed cell is marked once
    let mut sorted = cells.clone();
    sorted.sort_unstable();
    sorted.dedup();
    assert_eq!(sorted.len(), cells.len());
}

/// A sphere of radius 0.5 seen by 30 cameras all around, with 2000 noisy points on it (3%
/// depth noise, each seen by the cameras in front of its tangent plane) and 20 false matches
/// inside it, each "seen" by two cameras.
fn sphere_case() -> (SceneSpace, Vec<Vec3>, Vec<TrackedPoint>) {
    let space = SceneSpace::identity(SceneKind::Object, false);
    let radius = SPHERE;
    let mut rng = Lcg(7);
    // cameras on a sphere of radius 2.4 (outside the box, as a capture's are)
    let cams: Vec<Vec3> = (0..30)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / 30.0;
            let r = (1.0 - z * z).sqrt();
            let a = i as f32 * 2.39996;
            [2.4 * r * a.cos(), 2.4 * r * a.sin(), 2.4 * z]
        })
        .collect();
    let mut pts = Vec::new();
    for i in 0..2000 {
        let z = 1.0 - 2.0 * (i as f32 + 0.5) / 2000.0;
        let r = (1.0 - z * z).sqrt();
        let a = i as f32 * 2.39996;
        let n = [r * a.cos(), r * a.sin(), z];
        let p = n.map(|v| v * radius);
        let seen: Vec<u32> = (0..cams.len() as u32)
            .filter(|&c| {
                let d = sub(cams[c as usize], p);
                (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) / norm(d) > 0.05
            })
            .collect();
        // depth noise along the line of sight of the first observer
        let c0 = cams[seen[0] as usize];
        let d = sub(p, c0);
        let k = 1.0 + 0.03 * rng.normal();
        pts.push(TrackedPoint { xyz: [c0[0] + d[0] * k, c0[1] + d[1] * k, c0[2] + d[2] * k], seen_by: seen });
    }
    for i in 0..20u32 {
        let p = [0.3 * rng.normal(), 0.3 * rng.normal(), 0.3 * rng.normal()].map(|v: f32| v.clamp(-0.3, 0.3));
        pts.push(TrackedPoint { xyz: p, seen_by: vec![i % 30, (i * 7 + 3) % 30] });
    }
    (space, cams, pts)
}

const SPHERE: f32 = 0.5;

/// (surface cells carved, surface cells, empty shell cells carved, empty shell cells).
fn surface_and_shell(occ: &Occupancy) -> (usize, usize, usize, usize) {
    let half_diag = 3f32.sqrt() / occ.res as f32;
    let (mut surface, mut lost, mut outside, mut outside_carved) = (0, 0, 0, 0);
    for i in 0..occ.allowed.len() {
        let r = norm(occ.cell_center(i));
        if (r - SPHERE).abs() <= half_diag {
            surface += 1;
            lost += !occ.allowed[i] as usize;
        } else if r > SPHERE + 0.1 && r < 0.9 {
            outside += 1;
            outside_carved += !occ.allowed[i] as usize;
        }
    }
    (lost, surface, outside_carved, outside)
}

/// Carving must leave every cell the known surface passes through, and still carve much of
/// the empty space around it.
#[test]
fn carving_never_removes_a_known_surface() {
    let (space, cams, pts) = sphere_case();
    let mut occ = Occupancy::new(64, 512);
    let stats = carve(&mut occ, &space, &cams, &pts, CarveRules::default());
    let (lost, surface, outside_carved, outside) = surface_and_shell(&occ);
    assert_eq!(lost, 0, "{lost} of {surface} cells on the surface were carved: {stats:?}");
    assert!(outside_carved * 3 > outside, "only {outside_carved} of {outside} empty cells around the sphere carved: {stats:?}");
}

/// The check above can fail: carving 5% past each point (as depth noise can put a point
/// behind the surface), on single lines of sight, cuts into the same surface.
#[test]
fn carving_without_margins_cuts_into_the_surface() {
    let (space, cams, pts) = sphere_case();
    let mut occ = Occupancy::new(64, 512);
    let stats = carve(&mut occ, &space, &cams, &pts, CarveRules { margin: -0.05, min_segments: 1, min_cameras: 1 });
    let (lost, surface, _, _) = surface_and_shell(&occ);
    assert!(lost > 0, "no surface cell lost out of {surface}: {stats:?}");
}

/// A forward-facing dataset held in memory, in `format`, rooted at `root`.
fn opaque_dataset(format: &str, root: &std::path::Path) -> Dataset {
    let view = |x: f32| View {
        path: root.join("images").join(format!("{x}.png")),
        intrinsics: Intrinsics { width: 16, height: 12, fx: 14.0, fy: 14.0, cx: 8.0, cy: 6.0, distortion: [0.0; 4] },
        c2w: [[1.0, 0.0, 0.0, x], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
        time: None,
        rgba: [120u8, 80, 40, 255].repeat(16 * 12),
    };
    Dataset {
        root: root.to_path_buf(),
        format: format.into(),
        train: vec![view(0.0), view(0.2), view(0.4)],
        val: Vec::new(),
        test: vec![view(0.1)],
        kind: SceneKind::Forward,
        dynamic: false,
        near_far: Some((2.0, 8.0)),
        aabb: None,
        detection_note: String::new(),
        pose_file: root.join("sparse").join("0").join("images.bin"),
    }
}

/// Only COLMAP models with sparse points are carved: a transforms.json dataset (the built-in
/// scenes), or a COLMAP one without points3D.bin, trains with every cell allowed even with the
/// option on.
#[test]
fn datasets_without_sparse_points_are_not_carved() {
    let dir = std::env::temp_dir().join(format!("snerf-free-space-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("sparse").join("0")).unwrap();
    for format in ["blender", "colmap"] {
        let data = opaque_dataset(format, &dir);
        let mut cfg = TrainConfig::for_dataset(&data);
        // on by default for COLMAP models only
        assert_eq!(cfg.sparse_carving, format == "colmap", "{format}");
        cfg.field.resolutions = vec![8, 16];
        cfg.sparse_carving = true;
        let t = Trainer::new(&data, cfg).unwrap();
        assert!(t.sparse_carve.is_none(), "{format}: carved without points");
        assert!(t.model.occ.allowed.iter().all(|&a| a), "{format}: a cell was carved");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
