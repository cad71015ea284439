//! A baked asset as 3D Gaussian splats, derived from the volume-rendering equation the asset is
//! rendered with (`snerf_asset::render`), so that an engine's splat rasterizer draws what the
//! CPU reference marches.
//!
//! # From voxels to Gaussians
//!
//! The asset is a field of voxels: voxel *i* holds a density σᵢ (per model-space unit of
//! length; σ = exp(logit)), a display-referred diffuse colour cᵢ and, in view-dependent
//! assets, four features fᵢ. The reference renderer composites front to back,
//! `C = Σ Tᵢ αᵢ cᵢ + T·background` with `αᵢ = 1 − exp(−σᵢ δ)` and `T = exp(−Σ σ δ)`. A splat
//! rasterizer composites `C = Σ Tᵢ oᵢ G(x) cᵢ` over depth-sorted Gaussians with
//! `G(x) = exp(−½ xᵀΣ'⁻¹x)` on the image plane. The two agree when each Gaussian stands for a
//! region of the field with these three moments:
//!
//! * **Opacity at the footprint.** A ray that crosses a voxel of edge h (model units) along
//!   an axis accumulates optical depth σh, so the voxel seen face-on covers its h² footprint
//!   with opacity `α = 1 − exp(−σh)`. For a region of several voxels (see merging below) the
//!   optical depth through it along its thinnest principal axis is its optical *mass*
//!   `M = Σ σᵢ Vᵢ` divided by its face area `L₁L₂`: `α = 1 − exp(−M / (L₁ L₂))`, which is
//!   `1 − exp(−σh)` again for one voxel and for a full 2×2×2 block `1 − exp(−2σh)`.
//! * **Covariance from the footprint.** The splat must put the same total opacity on the
//!   image as the region it replaces: `∫ o·G = o·2π s₁s₂` must equal `α·L₁L₂` with `o = α`
//!   at the centre, so each principal standard deviation is `s = L/√(2π) ≈ 0.40·L`
//!   ([`FOOTPRINT_SIGMA`]). The principal extents L come from the region's second moment: a
//!   box of edge L has variance L²/12, so `L_k = √(12 λ_k)` with λ the eigenvalues of the
//!   region's covariance (each voxel counted as its box:
//!   `Σ Vᵢ (EᵢEᵢᵀ/12 + (xᵢ−μ)(xᵢ−μ)ᵀ) / Σ Vᵢ`, Eᵢ its model-space edge vectors); rotation =
//!   the eigenvectors. A voxel is measured through the grid's own map to model space
//!   (`Space::grid_to_world`), so unbounded scenes' contracted voxels become the large,
//!   elongated splats they are in the world. (A single opaque layer of such splats covers
//!   77% of its cells on average, so a one-voxel-thin opaque sheet shows a faint lattice;
//!   trained surfaces are several voxels thick and composite to full cover. Wider splats
//!   that close the lattice — s = 0.6·L with the peak chosen so the lattice covers α —
//!   measured 0.5–1.8 dB worse in the engine on real models: they blur every edge.)
//! * **Colour.** The opacity-weighted mean of the member voxels' colours. The asset's
//!   colours are display-referred sRGB values composited as they are, which is exactly
//!   KHR_gaussian_splatting's `srgb_rec709_display` colour space: degree-0 SH is
//!   `(c − 0.5)/Y₀₀` with `Y₀₀ = 0.2820947917738781`.
//!
//! # View dependence
//!
//! A diffuse asset (its MLP's output layer is zero) needs only degree 0. Otherwise the
//! renderer adds `opacity · mlp(composited diffuse + features, dir)`; per splat this is
//! approximated by `cᵢ + mlp(cᵢ, fᵢ, dir)`, and the real spherical harmonics of degree 1..=3
//! (Condon–Shortley signs, as in the extension's text) are fitted to it by least squares over
//! [`SH_FIT_DIRECTIONS`] directions on a Fibonacci sphere. `dir` is the unit world direction
//! from the eye to the point, as in 3DGS and the asset's MLP.
//!
//! # Merging flat regions and the budget
//!
//! One splat per voxel would turn every flat surface into a carpet of tiny splats. Voxels
//! are merged bottom-up over an octree (2³, 4³, 8³ voxels): a group whose members are all
//! nodes of the level below is replaced by the one Gaussian with the moments above when its
//! error is small. The error is the squared colour and opacity error the merge makes, each
//! member weighted by the opacity it puts on the image (`αᵢ·footprintᵢ`), plus the opacity
//! the Gaussian spreads over space its members do not fill:
//! `E = Σ aᵢ(‖cᵢ − c̄‖² + (αᵢ − o)²) + o·L₁L₂·(1 − fill)`. Merges with
//! `E ≤ tolerance · Σ aᵢ` are always made; with `--max-splats` the remaining candidates are
//! then merged in increasing order of E until the count fits, and if even the coarsest level
//! does not fit, the splats with the least opacity on the image go (an error bound: a splat
//! cannot change a pixel by more than its opacity).

use anyhow::{bail, ensure, Result};
use serde::Serialize;
use snerf_asset::quantize::decode_density;
use snerf_asset::{Asset, EMPTY};
use snerf_geometry::sym3::sym3_eigen;
use std::collections::HashMap;

/// `Y₀₀`, the degree-0 real spherical harmonic.
pub const SH_C0: f32 = 0.282_094_8;
/// Directions the view-dependent colour is sampled in for the SH fit.
pub const SH_FIT_DIRECTIONS: usize = 128;
/// Octree levels merged above the voxels (2³, 4³, 8³ voxels).
pub const MAX_MERGE_LEVEL: u32 = 3;

/// One Gaussian, in world coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Splat {
    pub position: [f32; 3],
    /// Unit quaternion (x, y, z, w): the Gaussian's local axes in world space.
    pub rotation: [f32; 4],
    /// Linear standard deviations along the local axes (world units).
    pub scale: [f32; 3],
    /// Peak opacity in [0, 1].
    pub opacity: f32,
    /// Diffuse display colour (what degree-0 SH encodes).
    pub color: [f32; 3],
    /// Degree 1.. SH coefficients (RGB each), in the extension's order: (ℓ, m = −ℓ..ℓ).
    pub sh: Vec<[f32; 3]>,
}

#[derive(Clone, Debug)]
pub struct SplatOptions {
    /// Keep at most this many splats (None: as many as the tolerance leaves).
    pub max_splats: Option<usize>,
    /// Voxels whose face-on opacity is below this are left out (they cannot change an 8-bit
    /// pixel on their own).
    pub min_opacity: f32,
    /// Relative merge error always accepted (see the module doc).
    pub tolerance: f32,
    /// SH degree above 0; None: 0 for diffuse assets, 1 otherwise.
    pub sh_degree: Option<u32>,
}

impl Default for SplatOptions {
    fn default() -> Self {
        SplatOptions {
            max_splats: None,
            min_opacity: 1.0 / 512.0,
            tolerance: 2.0e-3,
            sh_degree: None,
        }
    }
}

/// What the conversion did.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct SplatStats {
    pub voxels: usize,
    pub splats: usize,
    pub merged_by_tolerance: usize,
    pub merged_for_budget: usize,
    pub dropped_for_budget: usize,
    pub sh_degree: u32,
    /// RMS error of the SH fit of the view-dependent colour (0 for diffuse assets).
    pub sh_fit_rms: f32,
}

/// A region of voxels and its moments (model space).
#[derive(Clone, Debug)]
struct Node {
    level: u32,
    key: [u32; 3],
    /// Σ V
    volume: f64,
    /// Σ V x
    first: [f64; 3],
    /// Σ V (EEᵀ/12 + x xᵀ)
    second: [[f64; 3]; 3],
    /// optical mass Σ σ V
    mass: f64,
    /// Σ a, Σ a c, Σ a f, Σ a (|c|² + α²) for the error; a = α·footprint
    a: f64,
    ac: [f64; 3],
    af: [f64; 4],
    a_c2: f64,
    a_alpha: f64,
    a_alpha2: f64,
}

/// Mean, principal axes (columns) and extents L (descending) of a node.
struct Shape {
    mean: [f64; 3],
    axes: [[f64; 3]; 3],
    extents: [f64; 3],
}

impl Node {
    fn shape(&self) -> Shape {
        let v = self.volume.max(1e-300);
        let mean = self.first.map(|x| x / v);
        let mut cov = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                cov[i][j] = self.second[i][j] / v - mean[i] * mean[j];
            }
        }
        let (vals, vecs) = sym3_eigen(cov);
        let mut order = [0, 1, 2];
        order.sort_by(|&i, &j| vals[j].total_cmp(&vals[i]));
        let extents = order.map(|k| (12.0 * vals[k].max(0.0)).sqrt());
        let axes = [0, 1, 2].map(|r| order.map(|k| vecs[r][k]));
        Shape { mean, axes, extents }
    }

    fn opacity(&self, s: &Shape) -> f64 {
        let face = (s.extents[0] * s.extents[1]).max(1e-300);
        -(-(self.mass / face)).exp_m1()
    }

    fn merge(nodes: &[&Node], level: u32, key: [u32; 3]) -> Node {
        let mut m = Node {
            level,
            key,
            volume: 0.0,
            first: [0.0; 3],
            second: [[0.0; 3]; 3],
            mass: 0.0,
            a: 0.0,
            ac: [0.0; 3],
            af: [0.0; 4],
            a_c2: 0.0,
            a_alpha: 0.0,
            a_alpha2: 0.0,
        };
        for n in nodes {
            m.volume += n.volume;
            m.mass += n.mass;
            m.a += n.a;
            m.a_c2 += n.a_c2;
            m.a_alpha += n.a_alpha;
            m.a_alpha2 += n.a_alpha2;
            for i in 0..3 {
                m.first[i] += n.first[i];
                m.ac[i] += n.ac[i];
                for j in 0..3 {
                    m.second[i][j] += n.second[i][j];
                }
            }
            for i in 0..4 {
                m.af[i] += n.af[i];
            }
        }
        m
    }

    /// `E / Σa` of representing this node by one Gaussian (module doc).
    fn relative_error(&self) -> f64 {
        if self.a <= 0.0 {
            return 0.0;
        }
        let s = self.shape();
        let o = self.opacity(&s);
        let cbar = self.ac.map(|x| x / self.a);
        // Σ a‖c − c̄‖² = Σ a|c|² − Σa |c̄|², Σ a(α − o)² = Σ aα² − 2oΣaα + o²Σa
        let c_err = self.a_c2 - self.a * (cbar[0] * cbar[0] + cbar[1] * cbar[1] + cbar[2] * cbar[2]);
        let a_err = self.a_alpha2 - 2.0 * o * self.a_alpha + o * o * self.a;
        let box_volume = s.extents[0] * s.extents[1] * s.extents[2];
        let fill = if box_volume > 0.0 {
            (self.volume / box_volume).min(1.0)
        } else {
            1.0
        };
        let spread = o * s.extents[0] * s.extents[1] * (1.0 - fill);
        ((c_err + a_err).max(0.0) + spread) / self.a
    }
}

/// The asset's keyframe `frame` as splats.
pub fn asset_splats(asset: &Asset, frame: usize, opts: &SplatOptions) -> Result<(Vec<Splat>, SplatStats)> {
    if opts.max_splats == Some(0) {
        bail!("--max-splats 0: a splat file needs at least one splat");
    }
    ensure!(
        frame < asset.num_frames(),
        "frame {frame} of an asset with {} frames",
        asset.num_frames()
    );
    let h = &asset.header;
    let sh_degree = opts
        .sh_degree
        .unwrap_or(if h.diffuse || asset.mlp.output_is_zero() { 0 } else { 1 });
    ensure!(
        sh_degree <= 3,
        "SH degree {sh_degree}: KHR_gaussian_splatting stores degrees 0 to 3"
    );
    let mut nodes = voxel_nodes(asset, frame, opts.min_opacity);
    let mut stats = SplatStats {
        voxels: nodes.len(),
        sh_degree,
        ..Default::default()
    };
    if nodes.is_empty() {
        bail!(
            "the asset has no occupied voxels with opacity above {} in frame {frame}: nothing to turn into splats",
            opts.min_opacity
        );
    }
    for pass_budget in [false, true] {
        for level in 1..=MAX_MERGE_LEVEL {
            if pass_budget && opts.max_splats.is_none_or(|m| nodes.len() <= m) {
                break;
            }
            let before = nodes.len();
            nodes = merge_level(
                nodes,
                level,
                opts.tolerance as f64,
                if pass_budget { opts.max_splats } else { None },
            );
            if pass_budget {
                stats.merged_for_budget += before - nodes.len();
            } else {
                stats.merged_by_tolerance += before - nodes.len();
            }
        }
    }
    if let Some(max) = opts.max_splats {
        if nodes.len() > max {
            nodes.sort_by(|a, b| b.a.total_cmp(&a.a));
            stats.dropped_for_budget = nodes.len() - max;
            nodes.truncate(max);
        }
    }
    let k = FOOTPRINT_SIGMA;
    let dirs = fibonacci_sphere(SH_FIT_DIRECTIONS);
    let fit = (sh_degree > 0).then(|| ShFit::new(&dirs, sh_degree));
    let mut sq_err = 0.0f64;
    let mut splats = Vec::with_capacity(nodes.len());
    for n in &nodes {
        let s = n.shape();
        let o = n.opacity(&s) as f32;
        let color = n.ac.map(|x| (x / n.a.max(1e-300)) as f32);
        let feat = n.af.map(|x| (x / n.a.max(1e-300)) as f32);
        let mut sh = vec![];
        let mut dc = color;
        if let Some(fit) = &fit {
            let (d0, rest, err) = fit.fit(asset, color, feat, &dirs);
            dc = d0;
            sh = rest;
            sq_err += err as f64;
        }
        let (position, rotation, scale) = to_world(asset, &s, k);
        splats.push(Splat {
            position,
            rotation,
            scale,
            opacity: o.clamp(0.0, 1.0),
            color: dc,
            sh,
        });
    }
    stats.splats = splats.len();
    if sh_degree > 0 {
        stats.sh_fit_rms = (sq_err / (splats.len() * SH_FIT_DIRECTIONS * 3) as f64).sqrt() as f32;
    }
    Ok((splats, stats))
}

/// One node per voxel whose face-on opacity reaches `min_opacity`.
fn voxel_nodes(asset: &Asset, frame: usize, min_opacity: f32) -> Vec<Node> {
    let h = &asset.header;
    let res = h.res as usize;
    let b = h.block as usize;
    let g = asset.grid_dim();
    let bb = b + 2;
    let vox = 2.0 / res as f32;
    let model = |p: [f32; 3]| -> [f64; 3] { h.space.to_model(h.space.grid_to_world(h.kind, p)).map(|x| x as f64) };
    let channels = snerf_asset::quantize::CHANNELS;
    let mut out = vec![];
    for (c, &blk) in asset.grids[frame].iter().enumerate() {
        if blk == EMPTY || !asset.present.get(blk as usize).copied().unwrap_or(false) {
            continue;
        }
        let cell = [c % g, (c / g) % g, c / (g * g)];
        let base = blk as usize * asset.block_bytes();
        for lz in 0..b {
            for ly in 0..b {
                for lx in 0..b {
                    let off = base + (((lz + 1) * bb + ly + 1) * bb + lx + 1) * channels;
                    let v = &asset.atlas[off..off + channels];
                    let sigma = decode_density(v[0], &h.density).exp() as f64;
                    let idx = [cell[0] * b + lx, cell[1] * b + ly, cell[2] * b + lz];
                    let gc = idx.map(|i| -1.0 + (i as f32 + 0.5) * vox);
                    let x = model(gc);
                    // model-space edge vectors of the voxel
                    let mut e = [[0.0f64; 3]; 3];
                    for a in 0..3 {
                        let (mut lo, mut hi) = (gc, gc);
                        lo[a] -= 0.5 * vox;
                        hi[a] += 0.5 * vox;
                        let (pl, ph) = (model(lo), model(hi));
                        e[a] = [0, 1, 2].map(|k| ph[k] - pl[k]);
                    }
                    let vol = det3([e[0], e[1], e[2]]).abs();
                    if !(vol > 0.0 && vol.is_finite() && x.iter().all(|v| v.is_finite())) {
                        continue;
                    }
                    let lens = e.map(|v| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt());
                    let mut sorted = lens;
                    sorted.sort_by(|a, b| b.total_cmp(a));
                    let face = sorted[0] * sorted[1];
                    let alpha = -(-(sigma * vol / face)).exp_m1();
                    if !(alpha >= min_opacity as f64) {
                        continue;
                    }
                    let col = [v[1], v[2], v[3]].map(|c| c as f64 / 255.0);
                    let feat = [v[4], v[5], v[6], v[7]].map(|c| c as f64 / 255.0);
                    let a = alpha * face;
                    let mut second = [[0.0; 3]; 3];
                    for i in 0..3 {
                        for j in 0..3 {
                            let ee: f64 = (0..3).map(|k| e[k][i] * e[k][j]).sum();
                            second[i][j] = vol * (ee / 12.0 + x[i] * x[j]);
                        }
                    }
                    out.push(Node {
                        level: 0,
                        key: idx.map(|i| i as u32),
                        volume: vol,
                        first: x.map(|c| vol * c),
                        second,
                        mass: sigma * vol,
                        a,
                        ac: col.map(|c| a * c),
                        af: feat.map(|f| a * f),
                        a_c2: a * (col[0] * col[0] + col[1] * col[1] + col[2] * col[2]),
                        a_alpha: a * alpha,
                        a_alpha2: a * alpha * alpha,
                    });
                }
            }
        }
    }
    out
}

/// One octree level: groups of nodes sharing a parent cell at `level` whose members all sit
/// at `level − 1` merge when their error is within `tol`, or (with `budget`) in increasing
/// error while the count is over it. Groups that do not merge keep their members as they are.
fn merge_level(nodes: Vec<Node>, level: u32, tol: f64, budget: Option<usize>) -> Vec<Node> {
    let mut groups: HashMap<[u32; 3], Vec<Node>> = HashMap::new();
    let mut keep = Vec::new();
    for n in nodes {
        if n.level >= level {
            keep.push(n);
            continue;
        }
        // a node at level l has its key in units of 2^l voxels
        let shift = level - n.level;
        let parent = n.key.map(|k| k >> shift);
        groups.entry(parent).or_default().push(n);
    }
    let mut candidates: Vec<(f64, Node, Vec<Node>)> = Vec::new();
    for (key, members) in groups {
        if members.iter().any(|n| n.level + 1 != level) {
            keep.extend(members);
            continue;
        }
        let refs: Vec<&Node> = members.iter().collect();
        let merged = Node::merge(&refs, level, key);
        let err = if members.len() == 1 { 0.0 } else { merged.relative_error() };
        candidates.push((err, merged, members));
    }
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut count = keep.len() + candidates.iter().map(|c| c.2.len()).sum::<usize>();
    for (err, merged, members) in candidates {
        if members.len() == 1 || err <= tol || budget.is_some_and(|b| count > b) {
            count -= members.len() - 1;
            keep.push(merged);
        } else {
            keep.extend(members);
        }
    }
    keep
}

/// World position, quaternion (x, y, z, w) and linear scales of a node's Gaussian.
fn to_world(asset: &Asset, s: &Shape, k: f64) -> ([f32; 3], [f32; 4], [f32; 3]) {
    let space = &asset.header.space;
    let pos = space.to_world(s.mean.map(|x| x as f32));
    // model = scale · rot · (world − centre): a model axis a is the world axis rotᵀ a, and
    // model lengths are world lengths · scale.
    let mut r = [[0.0f64; 3]; 3]; // columns = world axes
    for k in 0..3 {
        let axis = [s.axes[0][k], s.axes[1][k], s.axes[2][k]].map(|x| x as f32);
        let w = space.dir_to_world(axis);
        for i in 0..3 {
            r[i][k] = w[i] as f64;
        }
    }
    if det3(r) < 0.0 {
        for row in r.iter_mut() {
            row[2] = -row[2];
        }
    }
    let sd = s.extents.map(|l| (k * l / space.scale as f64) as f32);
    // a degenerate axis (a single plane of voxels in a nonlinear map) keeps a sliver of size
    let floor = sd[0].max(sd[1]).max(sd[2]) * 1e-3;
    (pos, quat_from_matrix(r), sd.map(|x| x.max(floor)))
}

/// A splat's standard deviation as a fraction of its region's extent L: 1/√(2π) (module doc).
pub const FOOTPRINT_SIGMA: f64 = 0.398_942_280_401_432_7;

/// Unit quaternion (x, y, z, w) of a rotation matrix (rows), w ≥ 0.
pub fn quat_from_matrix(m: [[f64; 3]; 3]) -> [f32; 4] {
    let tr = m[0][0] + m[1][1] + m[2][2];
    let q = if tr > 0.0 {
        let s = (tr + 1.0).sqrt() * 2.0;
        [(m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s, 0.25 * s]
    } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
        let s = (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt() * 2.0;
        [0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s, (m[2][1] - m[1][2]) / s]
    } else if m[1][1] > m[2][2] {
        let s = (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt() * 2.0;
        [(m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s, (m[0][2] - m[2][0]) / s]
    } else {
        let s = (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt() * 2.0;
        [(m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s, (m[1][0] - m[0][1]) / s]
    };
    let n = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    let sign = if q[3] < 0.0 { -1.0 } else { 1.0 };
    q.map(|x| (sign * x / n) as f32)
}

/// Rotation matrix (rows) of a unit quaternion (x, y, z, w): the extension's formula.
pub fn matrix_from_quat(q: [f32; 4]) -> [[f32; 3]; 3] {
    let [x, y, z, w] = q;
    [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ]
}

fn det3(m: [[f64; 3]; 3]) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// `n` near-uniform unit directions.
pub fn fibonacci_sphere(n: usize) -> Vec<[f32; 3]> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let phi = golden * i as f32;
            [r * phi.cos(), y, r * phi.sin()]
        })
        .collect()
}

/// The real SH basis of degrees 0..=`degree` at unit direction d, with the signs and
/// constants of KHR_gaussian_splatting (and 3DGS).
pub fn sh_basis(d: [f32; 3], degree: u32) -> Vec<f32> {
    let [x, y, z] = d;
    let mut b = vec![SH_C0];
    if degree >= 1 {
        let c1 = 0.488_602_5;
        b.extend([-c1 * y, c1 * z, -c1 * x]);
    }
    if degree >= 2 {
        b.extend([
            1.092_548_4 * x * y,
            -1.092_548_4 * y * z,
            0.315_391_57 * (2.0 * z * z - x * x - y * y),
            -1.092_548_4 * x * z,
            0.546_274_2 * (x * x - y * y),
        ]);
    }
    if degree >= 3 {
        b.extend([
            -0.590_043_6 * y * (3.0 * x * x - y * y),
            2.890_611_4 * x * y * z,
            -0.457_045_8 * y * (4.0 * z * z - x * x - y * y),
            0.373_176_33 * z * (2.0 * z * z - 3.0 * x * x - 3.0 * y * y),
            -0.457_045_8 * x * (4.0 * z * z - x * x - y * y),
            1.445_305_7 * z * (x * x - y * y),
            -0.590_043_6 * x * (x * x - 3.0 * y * y),
        ]);
    }
    b
}

/// Least squares of SH coefficients: coefficients = P · samples with P = (BᵀB)⁻¹Bᵀ, the same
/// for every splat because the directions are.
struct ShFit {
    degree: u32,
    /// (k × n) pseudo-inverse, k basis functions, n directions.
    pinv: Vec<Vec<f32>>,
    basis: Vec<Vec<f32>>,
}

impl ShFit {
    fn new(dirs: &[[f32; 3]], degree: u32) -> ShFit {
        let basis: Vec<Vec<f32>> = dirs.iter().map(|&d| sh_basis(d, degree)).collect();
        let k = basis[0].len();
        let mut btb = vec![vec![0.0f64; k]; k];
        for row in &basis {
            for i in 0..k {
                for j in 0..k {
                    btb[i][j] += row[i] as f64 * row[j] as f64;
                }
            }
        }
        let inv = invert(btb);
        let pinv = (0..k)
            .map(|i| {
                basis
                    .iter()
                    .map(|row| (0..k).map(|j| inv[i][j] * row[j] as f64).sum::<f64>() as f32)
                    .collect()
            })
            .collect();
        ShFit { degree, pinv, basis }
    }

    /// Fits colour(d) = c + mlp(c, f, d) (clamped to [0, 1] as the renderer does): returns the
    /// diffuse colour degree 0 encodes, the higher coefficients and the squared error sum.
    fn fit(&self, asset: &Asset, c: [f32; 3], f: [f32; 4], dirs: &[[f32; 3]]) -> ([f32; 3], Vec<[f32; 3]>, f32) {
        let df = [c[0], c[1], c[2], f[0], f[1], f[2], f[3]];
        let samples: Vec<[f32; 3]> = dirs
            .iter()
            .map(|&d| {
                let s = asset.mlp.forward(&snerf_asset::ViewMlp::input(&df, d));
                [0, 1, 2].map(|i| (c[i] + s[i]).clamp(0.0, 1.0))
            })
            .collect();
        let k = self.pinv.len();
        let mut coef = vec![[0.0f32; 3]; k];
        for (i, row) in self.pinv.iter().enumerate() {
            for (p, s) in row.iter().zip(&samples) {
                for ch in 0..3 {
                    coef[i][ch] += p * (s[ch] - 0.5);
                }
            }
        }
        let mut err = 0.0;
        for (b, s) in self.basis.iter().zip(&samples) {
            for ch in 0..3 {
                let v: f32 = b.iter().zip(&coef).map(|(bi, ci)| bi * ci[ch]).sum::<f32>() + 0.5;
                err += (v - s[ch]) * (v - s[ch]);
            }
        }
        let _ = self.degree;
        let dc = coef[0].map(|x| x * SH_C0 + 0.5);
        (dc, coef[1..].to_vec(), err)
    }
}

fn invert(mut a: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
    let n = a.len();
    let mut inv: Vec<Vec<f64>> = (0..n).map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect()).collect();
    for col in 0..n {
        let piv = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs())).unwrap();
        a.swap(col, piv);
        inv.swap(col, piv);
        let d = a[col][col];
        for j in 0..n {
            a[col][j] /= d;
            inv[col][j] /= d;
        }
        for r in 0..n {
            if r != col {
                let f = a[r][col];
                if f != 0.0 {
                    for j in 0..n {
                        a[r][j] -= f * a[col][j];
                        inv[r][j] -= f * inv[col][j];
                    }
                }
            }
        }
    }
    inv
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternion_round_trips_through_the_extension_formula() {
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        let m = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]];
        let q = quat_from_matrix(m);
        // rotation of 0.3 rad about z: (0, 0, sin 0.15, cos 0.15)
        assert!((q[2] - 0.15f32.sin()).abs() < 1e-6 && (q[3] - 0.15f32.cos()).abs() < 1e-6, "{q:?}");
        let back = matrix_from_quat(q);
        for i in 0..3 {
            for j in 0..3 {
                assert!((back[i][j] as f64 - m[i][j]).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn jacobi_finds_the_eigenvectors() {
        let a = [[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 1.0]];
        let (vals, v) = sym3_eigen(a);
        for k in 0..3 {
            let col = [v[0][k], v[1][k], v[2][k]];
            for i in 0..3 {
                let av: f64 = (0..3).map(|j| a[i][j] * col[j]).sum();
                assert!((av - vals[k] * col[i]).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn sh_fit_recovers_a_degree_one_colour() {
        let dirs = fibonacci_sphere(SH_FIT_DIRECTIONS);
        let fit = ShFit::new(&dirs, 1);
        // samples of 0.5 + 0.3·x in every channel: coefficient of −C1·x is −0.3/C1
        let k = fit.pinv.len();
        let mut coef = vec![0.0f32; k];
        for (i, row) in fit.pinv.iter().enumerate() {
            coef[i] = row.iter().zip(&dirs).map(|(p, d)| p * 0.3 * d[0]).sum();
        }
        assert!(coef[0].abs() < 1e-4 && (coef[3] + 0.3 / 0.488_602_5).abs() < 1e-3, "{coef:?}");
    }
}
