//! A trained model as renderers see it: the scene mapping, the field and its occupancy grid.
//! Training produces and updates one (`train`), checkpoints store and restore one
//! (`checkpoint`), evaluation and camera paths render one (`eval`, `camera_path`); it sits
//! below all of them so that rendering a model never depends on the trainer.

use crate::field::Field;
use crate::occupancy::Occupancy;
use crate::space::SceneSpace;

/// What a renderer needs: the scene mapping, the field and its occupancy grid, and how many
/// rays a silhouette pixel takes (the training setting `pixel_rays`).
#[derive(Clone, Debug)]
pub struct Model {
    pub space: SceneSpace,
    pub field: Field,
    pub occ: Occupancy,
    pub pixel_rays: usize,
    /// `train::TrainConfig::pixel_footprint`.
    pub pixel_footprint: Option<f32>,
}
