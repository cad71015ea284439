//! Built-in procedural scenes, each a set of triangle meshes with procedural textures.

pub mod avatar;
pub mod object;
pub mod outdoor;
pub mod room;
pub mod shapes;

use glam::Vec3;
use crate::mesh::{Geometry, Look};
use crate::SceneKind;

/// Geometry for one time t in [0, 1].
pub type Animate = Box<dyn Fn(f32) -> anyhow::Result<Geometry> + Send + Sync>;

pub enum Content {
    Static(Geometry),
    Dynamic(Animate),
}

/// A scene ready to render: shared look, geometry (fixed or per time), kind and bounds.
pub struct Built {
    pub look: Look,
    pub content: Content,
    pub kind: SceneKind,
    pub aabb: [Vec3; 2],
    pub fov_x: f32,
    /// Extra facts for the JSON summary (glTF scale, warnings...).
    pub info: serde_json::Map<String, serde_json::Value>,
    pub warnings: Vec<String>,
}

impl Built {
    pub fn still(look: Look, g: Geometry, kind: SceneKind, aabb: [Vec3; 2], fov_x: f32) -> Built {
        Built {
            look,
            content: Content::Static(g),
            kind,
            aabb,
            fov_x,
            info: Default::default(),
            warnings: Vec::new(),
        }
    }

    pub fn is_dynamic(&self) -> bool {
        matches!(self.content, Content::Dynamic(_))
    }
}

/// sRGB colour triple -> linear.
pub fn rgb(r: f32, g: f32, b: f32) -> [f32; 3] {
    use crate::texture::srgb_to_linear as l;
    [l(r), l(g), l(b)]
}
