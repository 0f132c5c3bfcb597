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
pub(crate) mod hull;
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

/// Work shared out over rayon's pool of threads only when the pool has
/// more than one (on one core, handing work to the pool's thread costs
/// and gains nothing), and not inside [`one_thread_here`].
pub(crate) fn pool_is_parallel() -> bool {
    !ONE_THREAD.with(std::cell::Cell::get) && rayon::current_num_threads() > 1
}

thread_local! {
    static ONE_THREAD: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs `f` with this thread's perception work on this thread alone: the
/// pipelined stream's stages run beside the model, whose run they would
/// only slow by taking the other cores (measured on an H100 machine: the
/// stream's period went from 0.87-1.02x the model to 1.01-1.13x with its
/// stages on the pool).
pub(crate) fn one_thread_here<R>(f: impl FnOnce() -> R) -> R {
    struct Restore(bool);
    impl Drop for Restore {
        fn drop(&mut self) {
            ONE_THREAD.with(|c| c.set(self.0));
        }
    }
    let _restore = Restore(ONE_THREAD.with(|c| c.replace(true)));
    f()
}

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
