//! Step 2: a mask per detection box. Two backends: SAM-family ONNX (image
//! encoder once per frame, prompt decoder per box) and a depth-guided box
//! segmenter that needs no model.

pub mod depth;
pub mod sam;

use thiserror::Error;

use super::masks::Mask;
use super::runtime::RuntimeError;
use crate::msg::{DepthImage, RgbImage};

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
pub trait Segmenter: Send {
    fn backend(&self) -> &'static str;
    /// Masks for `boxes` in the colour image; `depth` is registered to the
    /// colour image when present. Returns one mask per box, in order.
    fn segment(
        &mut self,
        image: &RgbImage,
        depth: Option<&DepthImage>,
        boxes: &[[f32; 4]],
    ) -> Result<Vec<Mask>, SegmenterError>;
}
