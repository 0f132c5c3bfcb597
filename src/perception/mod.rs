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
pub mod tokenizer;

pub use boxes::{merge_objects, Aabb, Object3D, OrientedBox};
pub use detector::{Detection, Detector};
pub use pipeline::{Pipeline, ViewResult};
