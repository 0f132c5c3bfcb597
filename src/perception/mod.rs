//! Open-vocabulary 3D object detection: the paper's six steps.

pub mod boxes;
pub mod calibration;
pub mod cloud;
pub mod detector;
pub mod image;
pub mod masks;
pub mod models;
pub mod pipeline;
pub mod runtime;
pub mod segmenter;
pub mod setup;
pub mod tokenizer;

pub use boxes::{merge_objects, Aabb, Object3D, OrientedBox};
pub use calibration::{Intrinsics, RgbdCalibration};
pub use detector::{Detection, Detector};
pub use pipeline::{Pipeline, ViewResult};
