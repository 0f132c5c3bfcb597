//! Views pipelined across frames: three stages on three threads, so that a
//! stream of frames goes at the pace of its slowest stage (the model)
//! rather than of the stages one after the other.
//!
//! - prepare: the frame's depth checked, or registered into the colour
//!   camera, beside the detector's letterboxed input (YOLO, YOLO-World);
//! - model: the detector on that input (the model run and the decoding);
//! - lift: segmenter and steps 3–6, on the calling thread.
//!
//! Frame n+1 is prepared and frame n−1 lifted while the model runs on
//! frame n. Each frame's view is the one [`Pipeline::process`] gives it.

use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::time::Instant;

use super::{
    check_sizes, depth_in_color, lift_detections, ms, Pipeline, PipelineError, ViewResult,
};
use crate::msg::{DepthImage, Frame, RgbImage};
use crate::perception::detector::{Detection, InputLayout, PreparedImage};

/// One frame of a stream: the colour image and, with a depth camera, its
/// depth image (in the depth camera, as it comes).
pub type StreamFrame = (RgbImage, Option<DepthImage>);

/// A frame between the stages, with what has been made of it so far.
struct Staged<T> {
    color: RgbImage,
    /// The depth in the colour camera, or why there is none usable.
    depth: Option<Result<DepthImage, PipelineError>>,
    work: T,
    registration_ms: f64,
    /// When its preparation began: the view's `total` counts from here.
    started: Instant,
}

type Prepared = Staged<Option<PreparedImage>>;
type Detected = Staged<Result<(Vec<Detection>, f64), PipelineError>>;

impl Pipeline {
    /// Views of a stream of frames, pipelined: while the model runs on one
    /// frame, another thread prepares the next (its depth registered, the
    /// detector's input made) and the calling thread lifts the one before
    /// (masks, steps 3–6). `view` gets each frame's view, or the error that
    /// frame met, in the frames' order — the results of
    /// [`process`](Self::process) frame by frame — and returns false to
    /// end the stream. A frame's error ends nothing; a stage's thread that
    /// dies ends the stream with an error naming it. Each view's
    /// `timing_ms.total` is its latency, from its preparation to its
    /// objects; its stages' times are its own.
    pub fn process_stream<I>(
        &mut self,
        frames: I,
        mut view: impl FnMut(Result<ViewResult, PipelineError>) -> bool,
    ) where
        I: Iterator<Item = StreamFrame> + Send,
    {
        let Pipeline {
            detector,
            segmenter,
            calibration,
            geometry,
            prompts,
        } = self;
        let side = detector
            .letterbox_side()
            .map(|s| (s, detector.input_layout()));
        let calibration = &*calibration;
        // handed over, never queued: a stage that runs ahead waits with
        // its frame, so no frame grows old in a queue
        let (to_model, at_model) = sync_channel::<Prepared>(0);
        let (to_lift, at_lift) = sync_channel::<Detected>(0);
        std::thread::scope(|scope| {
            let prepare = scope.spawn(move || {
                crate::perception::one_thread_here(|| {
                    prepare_stage(frames, calibration, side, to_model)
                })
            });
            let model = scope.spawn(move || {
                for f in at_model {
                    let t = Instant::now();
                    let work = match (&f.depth, f.work) {
                        // no view for a frame whose depth is unusable
                        (Some(Err(_)), _) => Ok(Vec::new()),
                        (_, Some(input)) => detector.detect_prepared(input),
                        (_, None) => detector.detect(&f.color),
                    }
                    .map(|d| (d, ms(t)))
                    .map_err(PipelineError::from);
                    let detected = Staged {
                        color: f.color,
                        depth: f.depth,
                        work,
                        registration_ms: f.registration_ms,
                        started: f.started,
                    };
                    if to_lift.send(detected).is_err() {
                        // the stream was ended
                        return;
                    }
                }
            });
            let ended_early = crate::perception::one_thread_here(|| {
                lift_stage(
                    at_lift,
                    segmenter.as_mut(),
                    calibration,
                    geometry,
                    prompts,
                    &mut view,
                )
            });
            for (stage, handle) in [("preparation", prepare), ("model", model)] {
                if handle.join().is_err() && !ended_early {
                    view(Err(PipelineError::Input(format!(
                        "the pipelined views' {stage} thread died; the stream ends"
                    ))));
                }
            }
        });
    }
}

/// The first stage: each frame's depth in the colour camera and the
/// detector's input, handed on until the model's stage is gone.
fn prepare_stage(
    frames: impl Iterator<Item = StreamFrame>,
    calibration: &crate::msg::RgbdCalibration,
    side: Option<(usize, InputLayout)>,
    to_model: SyncSender<Prepared>,
) {
    for (color, depth) in frames {
        let started = Instant::now();
        // the depth registered (a separate depth camera) beside the
        // letterbox: neither needs the other
        let (depth, registration_ms, input) = std::thread::scope(|scope| {
            let registration = depth.map(|d| {
                let color = &color;
                scope.spawn(move || {
                    let t = Instant::now();
                    // depth already in the colour camera is checked and
                    // kept as it came (the frame is ours: no copy)
                    let depth = match calibration.depth {
                        Some(_) => depth_in_color(calibration, color, &d),
                        None => check_sizes(calibration, color, &d).map(|()| d),
                    };
                    (depth, ms(t))
                })
            });
            let input = side.map(|(s, layout)| PreparedImage::letterboxed(&color, s, layout));
            let registered = registration.map(|h| {
                h.join().unwrap_or_else(|_| {
                    let e = "the depth registration thread panicked".to_string();
                    (Err(PipelineError::Input(e)), 0.0)
                })
            });
            match registered {
                Some((depth, t)) => (Some(depth), t, input),
                None => (None, 0.0, input),
            }
        });
        let registration_ms = if calibration.depth.is_some() {
            registration_ms
        } else {
            0.0
        };
        let prepared = Staged {
            color,
            depth,
            work: input,
            registration_ms,
            started,
        };
        if to_model.send(prepared).is_err() {
            return;
        }
    }
}

/// The last stage, on the calling thread: masks and objects for each
/// frame's detections, handed to `view`. True when `view` ended the stream.
fn lift_stage(
    at_lift: Receiver<Detected>,
    segmenter: &mut dyn crate::perception::segmenter::Segmenter,
    calibration: &crate::msg::RgbdCalibration,
    geometry: &super::GeometrySettings,
    prompts: &crate::perception::detector::PromptReport,
    view: &mut impl FnMut(Result<ViewResult, PipelineError>) -> bool,
) -> bool {
    for f in at_lift {
        let result = f.work.and_then(|(detections, detector_ms)| {
            let mut result = match f.depth {
                Some(depth) => lift_detections(
                    segmenter,
                    &f.color,
                    &depth?,
                    detections,
                    &calibration.color,
                    &calibration.base_from_camera,
                    Frame::BaseLink,
                    geometry,
                    super::floor_in_image(calibration),
                )?,
                None => ViewResult {
                    detections,
                    ..Default::default()
                },
            };
            result.prompts = prompts.clone();
            result.timing_ms.registration = f.registration_ms;
            result.timing_ms.detector = detector_ms;
            result.timing_ms.total = ms(f.started);
            Ok(result)
        });
        if !view(result) {
            return true;
        }
    }
    false
}
