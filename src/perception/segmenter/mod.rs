//! Step 2: a mask per detection box. Two backends: SAM-family ONNX (image
//! encoder once per frame, prompt decoder per box) and a depth-guided box
//! segmenter that needs no model.

pub mod depth;
pub mod sam;

use thiserror::Error;

use super::masks::Mask;
use super::runtime::RuntimeError;
use crate::msg::{DepthImage, Intrinsics, RgbImage};
use nalgebra::Isometry3;

pub use depth::{DepthBoxSegmenter, DepthSegmenterSettings};
pub use sam::SamSegmenter;

#[derive(Debug, Error)]
pub enum SegmenterError {
    #[error(transparent)]
    Runtime(#[from] RuntimeError),
    #[error("{model}: output `{output}` has shape {shape:?}, expected {expected}")]
    Output {
        model: String,
        output: String,
        shape: Vec<i64>,
        expected: String,
    },
    #[error("segmenter input: {0}")]
    Input(String),
}

/// Produces one mask per box prompt (boxes in colour pixels).
/// The floor as the colour camera sees it: the height above it of the
/// point at pixel (u, v) and depth z is
/// z · (per_u · u + per_v · v + per_z) + camera_height, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FloorInImage {
    per_u: f32,
    per_v: f32,
    per_z: f32,
    camera_height_m: f32,
}

impl FloorInImage {
    /// From the colour camera's intrinsics, its pose in `base_link`
    /// (optical frame: z forward, x right, y down; base_link z up) and the
    /// floor's height there.
    pub fn new(k: &Intrinsics, base_from_camera: &Isometry3<f64>, floor_z_m: f64) -> FloorInImage {
        let r = base_from_camera.rotation.to_rotation_matrix();
        let m = r.matrix();
        let (r0, r1, r2) = (m[(2, 0)], m[(2, 1)], m[(2, 2)]);
        FloorInImage {
            per_u: (r0 / k.fx) as f32,
            per_v: (r1 / k.fy) as f32,
            per_z: (r2 - r0 * k.cx / k.fx - r1 * k.cy / k.fy) as f32,
            camera_height_m: (base_from_camera.translation.vector.z - floor_z_m) as f32,
        }
    }

    /// Height above the floor of pixel (u, v) at depth `z_m`, m.
    #[inline]
    pub fn height_m(&self, u: usize, v: usize, z_m: f32) -> f32 {
        z_m * (self.per_u * u as f32 + self.per_v * v as f32 + self.per_z) + self.camera_height_m
    }
}

pub trait Segmenter: Send {
    fn backend(&self) -> &'static str;
    /// Where the floor is in the image (None: not known, e.g. a dataset's
    /// sensor frame). A segmenter that
    /// grows over depth keeps off it; the others ignore it.
    fn set_floor(&mut self, floor: Option<FloorInImage>) {
        let _ = floor;
    }
    /// Masks for `boxes` in the colour image; `depth` is registered to the
    /// colour image when present. Returns one mask per box, in order.
    fn segment(
        &mut self,
        image: &RgbImage,
        depth: Option<&DepthImage>,
        boxes: &[[f32; 4]],
    ) -> Result<Vec<Mask>, SegmenterError>;
}
