//! Triangle geometry and materials, the common form every scene (procedural or glTF) is
//! turned into before rasterization.

use crate::math::normal_matrix;
use glam::{vec3, Mat4, Vec3};
use crate::texture::Texture;

/// Indexed triangle mesh in world space. All per-vertex arrays have the same length.
#[derive(Clone, Default)]
pub struct Geometry {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub uvs: Vec<[f32; 2]>,
    /// Linear RGBA vertex colour (white when the source has none).
    pub colors: Vec<[f32; 4]>,
    pub tris: Vec<[u32; 3]>,
    /// Material index of each triangle.
    pub tri_material: Vec<u32>,
}

impl Geometry {
    pub fn vertex(&mut self, p: Vec3, n: Vec3, uv: [f32; 2]) -> u32 {
        self.positions.push(p);
        self.normals.push(n);
        self.uvs.push(uv);
        self.colors.push([1.0; 4]);
        (self.positions.len() - 1) as u32
    }

    pub fn tri(&mut self, a: u32, b: u32, c: u32, material: u32) {
        self.tris.push([a, b, c]);
        self.tri_material.push(material);
    }

    /// Append `other`, transformed by `xf` (normals by its normal matrix).
    pub fn append(&mut self, other: &Geometry, xf: &Mat4) {
        let base = self.positions.len() as u32;
        let nm = normal_matrix(xf);
        self.positions
            .extend(other.positions.iter().map(|p| xf.transform_point3(*p)));
        self.normals
            .extend(other.normals.iter().map(|n| (nm * *n).normalize_or(Vec3::Y)));
        self.uvs.extend_from_slice(&other.uvs);
        self.colors.extend_from_slice(&other.colors);
        self.tris.extend(
            other
                .tris
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
        self.tri_material.extend_from_slice(&other.tri_material);
    }

    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self
            .tris
            .iter()
            .flat_map(|t| t.iter())
            .map(|&i| self.positions[i as usize]);
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }
}

#[derive(Clone, Debug)]
pub struct Material {
    /// Linear RGBA base colour factor.
    pub base_color: [f32; 4],
    /// Index into the scene's textures.
    pub texture: Option<usize>,
    /// Not lit (sky, emissive screens): colour is used as is.
    pub unlit: bool,
}

impl Material {
    pub fn color(c: [f32; 3]) -> Material {
        Material {
            base_color: [c[0], c[1], c[2], 1.0],
            texture: None,
            unlit: false,
        }
    }
    pub fn textured(t: usize) -> Material {
        Material {
            base_color: [1.0; 4],
            texture: Some(t),
            unlit: false,
        }
    }
}

/// What a ray that hits nothing sees.
#[derive(Clone, Copy)]
pub enum Background {
    /// Alpha 0 (object datasets with transparent background).
    Transparent,
    /// Opaque colour as a function of the world-space view direction (sky at infinity).
    Sky(fn(Vec3) -> [f32; 3]),
}

/// Everything shared by all frames of a scene except the (possibly time-varying) geometry.
pub struct Look {
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub background: Background,
    /// Unit direction towards the light, world space.
    pub light_dir: Vec3,
    pub ambient: f32,
    pub diffuse: f32,
}

impl Look {
    pub fn new(background: Background) -> Look {
        Look {
            materials: Vec::new(),
            textures: Vec::new(),
            background,
            light_dir: vec3(0.45, 0.8, 0.4).normalize_or(Vec3::Y),
            ambient: 0.35,
            diffuse: 0.75,
        }
    }
    pub fn add_texture(&mut self, t: Texture) -> usize {
        self.textures.push(t);
        self.textures.len() - 1
    }
    pub fn add_material(&mut self, m: Material) -> u32 {
        self.materials.push(m);
        (self.materials.len() - 1) as u32
    }
}
