//! Open-vocabulary 3D object detection, the paper's six steps: detectors
//! (`detector`: YOLO, YOLO-World with the CLIP text encoder and our
//! `tokenizer`), box-prompted masks (`segmenter`: SAM-family, depth-guided),
//! erosion (`masks`), depth isolation and back-projection (`cloud`,
//! `registration`; fused per mask in `mask_points`), 3D boxes and merging (`boxes`), all per view in
//! `pipeline`; ONNX Runtime sessions (`runtime`), the model manifest
//! (`models`), images (`image`).

pub mod boxes;
pub mod cloud;
pub mod depth_obstacles;
pub mod detector;
pub mod image;
pub mod mask_points;
pub mod masks;
pub mod models;
pub mod pipeline;
pub mod registration;
pub mod runtime;
pub mod segmenter;
pub(crate) mod sweep;
pub mod tokenizer;

pub use boxes::{merge_objects, Aabb, Object3D, OrientedBox};
pub use detector::{Detection, Detector};
pub use pipeline::{Pipeline, ViewResult};

/// A fixed sequence for the tests' random masks, depths and points (a
/// 64-bit LCG's high bits): the same cases on every run.
#[cfg(test)]
pub(crate) fn test_sequence(seed: u64) -> impl FnMut() -> usize {
    let mut state = seed;
    move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as usize
    }
}
