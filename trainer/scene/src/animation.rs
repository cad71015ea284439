//! glTF animation evaluation: keyframe sampling (LINEAR / STEP / CUBICSPLINE), node
//! hierarchies, skinning and morph targets, producing world-space geometry at a time t.

use crate::math::{normal_matrix, normalize_quat, slerp};
use glam::{FloatExt, Mat4, Vec3};
use crate::mesh::Geometry;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interp {
    Linear,
    Step,
    CubicSpline,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Path {
    Translation,
    Rotation,
    Scale,
    Weights,
}

#[derive(Clone, Debug)]
pub struct Channel {
    pub node: usize,
    pub path: Path,
    pub interp: Interp,
    pub inputs: Vec<f32>,
    /// Flattened outputs; for CUBICSPLINE each key holds in-tangent, value, out-tangent.
    pub outputs: Vec<f32>,
    /// Components per value (3, 4 or the number of morph targets).
    pub stride: usize,
}

impl Channel {
    fn value(&self, key: usize) -> &[f32] {
        let s = self.stride;
        match self.interp {
            Interp::CubicSpline => &self.outputs[(3 * key + 1) * s..(3 * key + 2) * s],
            _ => &self.outputs[key * s..(key + 1) * s],
        }
    }

    /// Value of the channel at `time` (seconds); clamps outside the keyframe range.
    pub fn sample(&self, time: f32) -> Vec<f32> {
        let n = self.inputs.len();
        if n == 0 {
            return vec![0.0; self.stride];
        }
        if time <= self.inputs[0] || n == 1 {
            return self.value(0).to_vec();
        }
        if time >= self.inputs[n - 1] {
            return self.value(n - 1).to_vec();
        }
        let k = self
            .inputs
            .partition_point(|&x| x <= time)
            .saturating_sub(1)
            .min(n - 2);
        let (t0, t1) = (self.inputs[k], self.inputs[k + 1]);
        let dt = t1 - t0;
        let u = if dt > 0.0 {
            ((time - t0) / dt).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (a, b) = (self.value(k), self.value(k + 1));
        match self.interp {
            Interp::Step => a.to_vec(),
            Interp::Linear => {
                if self.path == Path::Rotation && self.stride == 4 {
                    slerp([a[0], a[1], a[2], a[3]], [b[0], b[1], b[2], b[3]], u).to_array().to_vec()
                } else {
                    a.iter().zip(b).map(|(x, y)| x.lerp(*y, u)).collect()
                }
            }
            Interp::CubicSpline => {
                let s = self.stride;
                let out_a = &self.outputs[(3 * k + 2) * s..(3 * k + 3) * s];
                let in_b = &self.outputs[(3 * (k + 1)) * s..(3 * (k + 1) + 1) * s];
                let (u2, u3) = (u * u, u * u * u);
                let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
                let h10 = u3 - 2.0 * u2 + u;
                let h01 = -2.0 * u3 + 3.0 * u2;
                let h11 = u3 - u2;
                let v: Vec<f32> = (0..s)
                    .map(|i| h00 * a[i] + h10 * dt * out_a[i] + h01 * b[i] + h11 * dt * in_b[i])
                    .collect();
                if self.path == Path::Rotation && s == 4 {
                    normalize_quat([v[0], v[1], v[2], v[3]]).to_array().to_vec()
                } else {
                    v
                }
            }
        }
    }
}

#[derive(Clone, Debug)]
pub struct NodeRest {
    pub t: [f32; 3],
    pub r: [f32; 4],
    pub s: [f32; 3],
    /// A node given by a matrix is not animatable by TRS channels (per the glTF spec).
    pub matrix: Option<Mat4>,
    pub weights: Option<Vec<f32>>,
}

/// Mesh data of one glTF primitive, in the mesh's local space.
pub struct PrimData {
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub uvs: Vec<[f32; 2]>,
    pub colors: Option<Vec<[f32; 4]>>,
    pub tris: Vec<[u32; 3]>,
    pub joints: Option<Vec<[u16; 4]>>,
    pub weights: Option<Vec<[f32; 4]>>,
    /// Morph targets: position deltas and optional normal deltas.
    pub targets: Vec<(Vec<Vec3>, Option<Vec<Vec3>>)>,
    pub material: u32,
}

/// One instance of a primitive in the scene (mesh primitive placed by a node).
pub struct Instance {
    pub node: usize,
    pub skin: Option<usize>,
    pub mesh_weights: Vec<f32>,
    pub prim: std::sync::Arc<PrimData>,
}

pub struct Skin {
    pub joints: Vec<usize>,
    pub inverse_bind: Vec<Mat4>,
}

/// Everything needed to pose a glTF scene at any time.
pub struct Rig {
    pub rest: Vec<NodeRest>,
    pub parent: Vec<Option<usize>>,
    /// Nodes of the default scene in parent-before-child order.
    pub order: Vec<usize>,
    pub instances: Vec<Instance>,
    pub skins: Vec<Skin>,
    pub channels: Vec<Channel>,
    pub start: f32,
    pub end: f32,
    /// Applied last (centring and scaling to the unit sphere).
    pub normalize: Mat4,
}

impl Rig {
    pub fn animated(&self) -> bool {
        !self.channels.is_empty() && self.end > self.start
    }

    /// World matrices of all nodes and morph weights per node at normalized time t in [0,1].
    fn pose(&self, t: f32) -> (Vec<Mat4>, Vec<Option<Vec<f32>>>) {
        let time = self.start + t.clamp(0.0, 1.0) * (self.end - self.start);
        let mut trs: Vec<([f32; 3], [f32; 4], [f32; 3])> =
            self.rest.iter().map(|r| (r.t, r.r, r.s)).collect();
        let mut weights: Vec<Option<Vec<f32>>> =
            self.rest.iter().map(|r| r.weights.clone()).collect();
        for ch in &self.channels {
            let v = ch.sample(time);
            let e = &mut trs[ch.node];
            match ch.path {
                Path::Translation if v.len() >= 3 => e.0 = [v[0], v[1], v[2]],
                Path::Rotation if v.len() >= 4 => e.1 = [v[0], v[1], v[2], v[3]],
                Path::Scale if v.len() >= 3 => e.2 = [v[0], v[1], v[2]],
                Path::Weights => weights[ch.node] = Some(v),
                _ => {}
            }
        }
        let mut world = vec![Mat4::IDENTITY; self.rest.len()];
        for &n in &self.order {
            let local = match self.rest[n].matrix {
                Some(m) => m,
                None => Mat4::from_scale_rotation_translation(
                    trs[n].2.into(),
                    normalize_quat(trs[n].1),
                    trs[n].0.into(),
                ),
            };
            world[n] = match self.parent[n] {
                Some(p) => world[p] * local,
                None => local,
            };
        }
        (world, weights)
    }

    /// World-space geometry at normalized time t (before `normalize` when `raw`).
    pub fn geometry_raw(&self, t: f32) -> Geometry {
        let (world, node_weights) = self.pose(t);
        let mut g = Geometry::default();
        for inst in &self.instances {
            let p = &*inst.prim;
            let w: &[f32] = node_weights[inst.node]
                .as_deref()
                .unwrap_or(&inst.mesh_weights);
            // Morph.
            let mut pos = p.positions.clone();
            let mut nrm: Option<Vec<Vec3>> = p.normals.clone();
            for (k, (dp, dn)) in p.targets.iter().enumerate() {
                let wk = w.get(k).copied().unwrap_or(0.0);
                if wk == 0.0 {
                    continue;
                }
                for (a, d) in pos.iter_mut().zip(dp) {
                    *a += *d * wk;
                }
                if let (Some(n), Some(dn)) = (nrm.as_mut(), dn) {
                    for (a, d) in n.iter_mut().zip(dn) {
                        *a += *d * wk;
                    }
                }
            }
            // Skin or node transform.
            let base = g.positions.len() as u32;
            let skin = inst.skin.and_then(|s| self.skins.get(s));
            match (skin, &p.joints, &p.weights) {
                (Some(skin), Some(js), Some(ws)) => {
                    let jm: Vec<Mat4> = skin
                        .joints
                        .iter()
                        .enumerate()
                        .map(|(i, &j)| {
                            world[j] * skin.inverse_bind.get(i).copied().unwrap_or(Mat4::IDENTITY)
                        })
                        .collect();
                    for (vi, v) in pos.iter().enumerate() {
                        let (j, wt) = (js[vi], ws[vi]);
                        let sum: f32 = wt.iter().sum();
                        let mut m = Mat4::ZERO;
                        if sum > 0.0 {
                            for k in 0..4 {
                                let Some(jmk) = jm.get(j[k] as usize) else {
                                    continue;
                                };
                                m += *jmk * (wt[k] / sum);
                            }
                        }
                        let m = if sum > 0.0 {
                            m
                        } else {
                            world[inst.node]
                        };
                        let n = nrm
                            .as_ref()
                            .map(|n| (normal_matrix(&m) * n[vi]).normalize_or(Vec3::Y))
                            .unwrap_or_default();
                        g.vertex(m.transform_point3(*v), n, p.uvs[vi]);
                    }
                }
                _ => {
                    let m = world[inst.node];
                    let nm = normal_matrix(&m);
                    for (vi, v) in pos.iter().enumerate() {
                        let n = nrm
                            .as_ref()
                            .map(|n| (nm * n[vi]).normalize_or(Vec3::Y))
                            .unwrap_or_default();
                        g.vertex(m.transform_point3(*v), n, p.uvs[vi]);
                    }
                }
            }
            if let Some(c) = &p.colors {
                let k = base as usize;
                g.colors[k..k + c.len()].copy_from_slice(c);
            }
            let start_tri = g.tris.len();
            for t in &p.tris {
                g.tri(t[0] + base, t[1] + base, t[2] + base, p.material);
            }
            if p.normals.is_none() {
                // Flat-ish normals from the posed triangles of this primitive.
                let mut acc = vec![Vec3::default(); pos.len()];
                for t in &g.tris[start_tri..] {
                    let [a, b, c] = t.map(|i| g.positions[i as usize]);
                    let f = (b - a).cross(c - a);
                    for &i in t {
                        acc[(i - base) as usize] += f;
                    }
                }
                for (i, n) in acc.into_iter().enumerate() {
                    g.normals[base as usize + i] = n.normalize_or(Vec3::Y);
                }
            }
        }
        g
    }

    pub fn geometry(&self, t: f32) -> Geometry {
        let raw = self.geometry_raw(t);
        let mut g = Geometry::default();
        g.append(&raw, &self.normalize);
        g
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ch(
        interp: Interp,
        inputs: Vec<f32>,
        outputs: Vec<f32>,
        stride: usize,
        path: Path,
    ) -> Channel {
        Channel {
            node: 0,
            path,
            interp,
            inputs,
            outputs,
            stride,
        }
    }

    #[test]
    fn linear_step_cubic() {
        let c = ch(
            Interp::Linear,
            vec![0.0, 1.0],
            vec![0.0, 0.0, 0.0, 2.0, 4.0, 6.0],
            3,
            Path::Translation,
        );
        assert_eq!(c.sample(0.5), vec![1.0, 2.0, 3.0]);
        assert_eq!(c.sample(-1.0), vec![0.0, 0.0, 0.0]);
        assert_eq!(c.sample(9.0), vec![2.0, 4.0, 6.0]);
        let s = ch(
            Interp::Step,
            vec![0.0, 1.0],
            vec![0.0, 0.0, 0.0, 2.0, 4.0, 6.0],
            3,
            Path::Translation,
        );
        assert_eq!(s.sample(0.99), vec![0.0, 0.0, 0.0]);
        // Cubic with zero tangents: smoothstep between values.
        let cs = ch(
            Interp::CubicSpline,
            vec![0.0, 1.0],
            vec![0.0, 0.0, 0.0, 0.0, 1.0, 0.0],
            1,
            Path::Weights,
        );
        assert!((cs.sample(0.5)[0] - 0.5).abs() < 1e-6);
        assert!((cs.sample(0.25)[0] - 0.15625).abs() < 1e-6);
    }

    #[test]
    fn rotation_slerp_is_unit() {
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let c = ch(
            Interp::Linear,
            vec![0.0, 1.0],
            vec![0.0, 0.0, 0.0, 1.0, 0.0, h, 0.0, h],
            4,
            Path::Rotation,
        );
        let q = c.sample(0.5);
        let n: f32 = q.iter().map(|x| x * x).sum();
        assert!((n - 1.0).abs() < 1e-5);
        // Half of 90 degrees about y.
        assert!(
            (q[1] - (std::f32::consts::PI / 8.0).sin()).abs() < 1e-4,
            "{q:?}"
        );
    }
}
