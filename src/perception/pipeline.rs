//! The paper's six steps for one RGB-D view: detect → segment → erode →
//! isolate depth + z-score → back-project + extrinsics → 3D boxes.

use std::time::Instant;

use nalgebra::Isometry3;
use rayon::prelude::*;
use serde::Serialize;
use thiserror::Error;

use super::boxes::Object3D;
use super::detector::{Detection, Detector, DetectorError, PromptReport};
use super::mask_points::{mask_object, MaskGeometry};
use super::masks::Mask;
use super::registration::register_depth_to_color;
use super::segmenter::{FloorInImage, Segmenter, SegmenterError};
use crate::msg::Frame;
use crate::msg::{DepthImage, ImageError, RgbImage};
use crate::msg::{Intrinsics, RgbdCalibration};

#[derive(Debug, Error)]
pub enum PipelineError {
    #[error(transparent)]
    Detector(#[from] DetectorError),
    #[error(transparent)]
    Segmenter(#[from] SegmenterError),
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error("{0}")]
    Input(String),
}

/// Geometry settings (config `[perception]`).
#[derive(Debug, Clone, PartialEq)]
pub struct GeometrySettings {
    /// 3×3 erosion passes (paper: 1).
    pub erosion_iterations: usize,
    /// Z-score threshold τ: depths with |z| ≥ τ are dropped (paper: 2).
    pub zscore_tau: f64,
    /// Objects with fewer valid 3D points are dropped, with a reason.
    pub min_points: usize,
    /// Depths outside [min_depth_m, max_depth_m] are ignored.
    pub min_depth_m: f32,
    pub max_depth_m: f32,
}

impl Default for GeometrySettings {
    fn default() -> Self {
        GeometrySettings {
            erosion_iterations: 1,
            zscore_tau: 2.0,
            min_points: 20,
            min_depth_m: 0.1,
            max_depth_m: 10.0,
        }
    }
}

/// A detection that produced no 3D object, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Dropped {
    pub label: String,
    pub score: f32,
    pub box_xyxy: [f32; 4],
    pub reason: String,
}

/// Steps 3–6 for one view: each (detection, mask) pair → an object in the
/// frame of `target_from_camera`, or a reason it was dropped. `depth` is
/// registered to the colour image and `intrinsics` are the colour camera's.
pub fn objects_from_masks(
    detections: &[Detection],
    masks: &[Mask],
    depth: &DepthImage,
    intrinsics: &Intrinsics,
    target_from_camera: &Isometry3<f64>,
    frame: Frame,
    settings: &GeometrySettings,
) -> (Vec<Object3D>, Vec<Dropped>) {
    let mut objects = Vec::new();
    let mut dropped = Vec::new();
    let g = MaskGeometry {
        erosion_iterations: settings.erosion_iterations,
        min_depth_m: settings.min_depth_m,
        max_depth_m: settings.max_depth_m,
        zscore_tau: settings.zscore_tau,
        intrinsics,
        target_from_camera,
        frame,
    };
    // each mask on its own (the pool's threads), the results in order
    let lift = |(det, mask): (&Detection, &Mask)| {
        mask_object(mask, depth, &g, &det.label, det.score, Some(det.box_xyxy))
    };
    let made: Vec<_> = if super::pool_is_parallel() && detections.len() > 1 {
        detections.par_iter().zip(masks).map(lift).collect()
    } else {
        detections.iter().zip(masks).map(lift).collect()
    };
    for ((det, mask), made) in detections.iter().zip(masks).zip(made) {
        match made.object {
            Some(o) if made.points >= settings.min_points.max(1) => objects.push(o),
            _ => dropped.push(Dropped {
                label: det.label.clone(),
                score: det.score,
                box_xyxy: det.box_xyxy,
                reason: format!(
                    "{} points after filtering (< {}): mask {} px, eroded {} px, valid depth {}",
                    made.points,
                    settings.min_points,
                    mask.count(),
                    made.eroded_px,
                    made.depth_samples,
                ),
            }),
        }
    }
    (objects, dropped)
}

/// Milliseconds spent per stage.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Timing {
    /// Depth registered into the colour camera, on a thread beside the
    /// detector (so not part of `total` beyond the detector's time); 0
    /// when the depth is already in the colour camera.
    pub registration: f64,
    pub detector: f64,
    pub segmenter: f64,
    pub geometry: f64,
    pub total: f64,
}

/// Everything one view produced.
#[derive(Debug, Clone, Default)]
pub struct ViewResult {
    pub prompts: PromptReport,
    pub detections: Vec<Detection>,
    pub masks: Vec<Mask>,
    pub objects: Vec<Object3D>,
    pub dropped: Vec<Dropped>,
    pub timing_ms: Timing,
}

/// Detector + segmenter + calibration: RGB-D frame and prompts → objects in
/// `base_link`.
pub struct Pipeline {
    pub detector: Box<dyn Detector>,
    pub segmenter: Box<dyn Segmenter>,
    pub calibration: RgbdCalibration,
    pub geometry: GeometrySettings,
    prompts: PromptReport,
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

impl Pipeline {
    pub fn new(
        detector: Box<dyn Detector>,
        segmenter: Box<dyn Segmenter>,
        calibration: RgbdCalibration,
        geometry: GeometrySettings,
    ) -> Self {
        Pipeline {
            detector,
            segmenter,
            calibration,
            geometry,
            prompts: PromptReport::default(),
        }
    }

    /// Sets the active prompts (the vocabulary may change between frames).
    pub fn set_prompts(&mut self, prompts: &[String]) -> Result<PromptReport, PipelineError> {
        self.prompts = self.detector.set_prompts(prompts)?;
        Ok(self.prompts.clone())
    }

    /// The detector's model run once on a blank input before the first
    /// view (see [`Detector::warm_up`]); returns how long it took, ms.
    pub fn warm_up(&mut self) -> Result<f64, PipelineError> {
        let t = Instant::now();
        self.detector.warm_up()?;
        Ok(ms(t))
    }

    /// Depth in the colour camera: registered when the rig has a separate
    /// depth camera, checked for size otherwise.
    pub fn depth_in_color(
        &self,
        color: &RgbImage,
        depth: &DepthImage,
    ) -> Result<DepthImage, PipelineError> {
        depth_in_color(&self.calibration, color, depth)
    }

    /// Runs one view. Without depth only the 2D detections are returned.
    pub fn process(
        &mut self,
        color: &RgbImage,
        depth: Option<&DepthImage>,
    ) -> Result<ViewResult, PipelineError> {
        let t0 = Instant::now();
        // depth already in the colour camera is checked and borrowed; a
        // separate depth camera's image is registered on a thread beside
        // the detector (with the model on a GPU the CPU would wait idle)
        let (registered, registration_ms, detections, detector_ms) =
            match (depth, &self.calibration.depth) {
                (Some(d), Some(_)) => {
                    let calibration = &self.calibration;
                    let detector = &mut self.detector;
                    let (registered, detected) = std::thread::scope(|scope| {
                        let registration = scope.spawn(|| {
                            let t = Instant::now();
                            depth_in_color(calibration, color, d).map(|r| (r, ms(t)))
                        });
                        let t = Instant::now();
                        let detected = detector.detect(color).map(|v| (v, ms(t)));
                        (registration.join(), detected)
                    });
                    let (registered, registration_ms) = registered.map_err(|_| {
                        PipelineError::Input("the depth registration thread panicked".into())
                    })??;
                    let (detections, detector_ms) = detected?;
                    (
                        Some(std::borrow::Cow::Owned(registered)),
                        registration_ms,
                        detections,
                        detector_ms,
                    )
                }
                (depth, _) => {
                    if let Some(d) = depth {
                        check_sizes(&self.calibration, color, d)?;
                    }
                    let t = Instant::now();
                    let detections = self.detector.detect(color)?;
                    (
                        depth.map(std::borrow::Cow::Borrowed),
                        0.0,
                        detections,
                        ms(t),
                    )
                }
            };
        let mut result = match registered {
            Some(depth) => lift_detections(
                self.segmenter.as_mut(),
                color,
                &depth,
                detections,
                &self.calibration.color,
                &self.calibration.base_from_camera,
                Frame::BaseLink,
                &self.geometry,
                floor_in_image(&self.calibration),
            )?,
            None => ViewResult {
                detections,
                ..Default::default()
            },
        };
        result.prompts = self.prompts.clone();
        result.timing_ms.registration = registration_ms;
        result.timing_ms.detector = detector_ms;
        result.timing_ms.total = ms(t0);
        Ok(result)
    }
}

/// Depth in the colour camera: registered when the rig has a separate
/// depth camera, checked for size otherwise.
pub fn depth_in_color(
    calibration: &RgbdCalibration,
    color: &RgbImage,
    depth: &DepthImage,
) -> Result<DepthImage, PipelineError> {
    check_sizes(calibration, color, depth)?;
    Ok(match &calibration.depth {
        Some((dk, color_from_depth)) => {
            register_depth_to_color(depth, dk, color_from_depth, &calibration.color)?
        }
        None => depth.clone(),
    })
}

/// The frame's images have the calibration's sizes.
fn check_sizes(
    calibration: &RgbdCalibration,
    color: &RgbImage,
    depth: &DepthImage,
) -> Result<(), PipelineError> {
    let (dw, dh) = calibration.depth_size();
    if (depth.width(), depth.height()) != (dw, dh) {
        return Err(PipelineError::Input(format!(
            "depth image is {}x{}, calibration expects {dw}x{dh}",
            depth.width(),
            depth.height()
        )));
    }
    let c = &calibration.color;
    if (color.width(), color.height()) != (c.width, c.height) {
        return Err(PipelineError::Input(format!(
            "colour image is {}x{}, calibration expects {}x{}",
            color.width(),
            color.height(),
            c.width,
            c.height
        )));
    }
    Ok(())
}

/// Steps 2–6 for detections already made: a mask per box, then objects in
/// the frame of `target_from_camera`. `depth` is registered to `color`, and
/// `intrinsics` are the colour camera's; `floor`, where the floor is in the
/// image when known ([`floor_in_image`]). Timing covers segmenter and
/// geometry (`total` is their sum).
#[allow(clippy::too_many_arguments)]
pub fn lift_detections(
    segmenter: &mut dyn Segmenter,
    color: &RgbImage,
    depth: &DepthImage,
    detections: Vec<Detection>,
    intrinsics: &Intrinsics,
    target_from_camera: &Isometry3<f64>,
    frame: Frame,
    geometry: &GeometrySettings,
    floor: Option<FloorInImage>,
) -> Result<ViewResult, PipelineError> {
    let boxes: Vec<[f32; 4]> = detections.iter().map(|d| d.box_xyxy).collect();
    let t = Instant::now();
    segmenter.set_floor(floor);
    let masks = segmenter.segment(color, Some(depth), &boxes)?;
    let segmenter_ms = ms(t);
    if masks.len() != boxes.len() {
        return Err(PipelineError::Input(format!(
            "segmenter returned {} masks for {} boxes",
            masks.len(),
            boxes.len()
        )));
    }
    let t = Instant::now();
    let (objects, dropped) = objects_from_masks(
        &detections,
        &masks,
        depth,
        intrinsics,
        target_from_camera,
        frame,
        geometry,
    );
    let geometry_ms = ms(t);
    for d in &dropped {
        tracing::debug!(label = %d.label, score = d.score, reason = %d.reason, "detection dropped");
    }
    Ok(ViewResult {
        prompts: PromptReport::default(),
        detections,
        masks,
        objects,
        dropped,
        timing_ms: Timing {
            registration: 0.0,
            detector: 0.0,
            segmenter: segmenter_ms,
            geometry: geometry_ms,
            total: segmenter_ms + geometry_ms,
        },
    })
}

/// Where the floor is in the rig's colour image, when the rig says where
/// the floor is.
pub fn floor_in_image(calibration: &crate::msg::RgbdCalibration) -> Option<FloorInImage> {
    calibration
        .floor_z_m
        .map(|z| FloorInImage::new(&calibration.color, &calibration.base_from_camera, z))
}

#[path = "stream.rs"]
mod stream;
pub use stream::StreamFrame;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::segmenter::DepthBoxSegmenter;

    /// Boxes at several depths in front of a wall, one box over no depth.
    fn scene() -> (DepthImage, Vec<Detection>) {
        let (w, h) = (160, 120);
        let mut d = vec![4.0f32; w * h];
        let boxes = [
            (10, 10, 40, 50, 1.2f32),
            (60, 20, 90, 70, 2.0),
            (100, 60, 150, 110, 2.8),
            (20, 70, 50, 100, 0.0),
        ];
        let mut detections = Vec::new();
        for (i, &(x0, y0, x1, y1, z)) in boxes.iter().enumerate() {
            for v in y0..y1 {
                for u in x0..x1 {
                    d[v * w + u] = z + 0.002 * ((u * 7 + v * 3) % 11) as f32;
                }
            }
            detections.push(Detection {
                label: format!("object {i}"),
                class: "object".into(),
                score: 0.9 - 0.1 * i as f32,
                box_xyxy: [
                    x0 as f32 - 3.0,
                    y0 as f32 - 3.0,
                    x1 as f32 + 3.0,
                    y1 as f32 + 3.0,
                ],
            });
        }
        (DepthImage::new(w, h, d).unwrap(), detections)
    }

    #[test]
    fn objects_are_the_same_on_one_thread_and_on_several() {
        let (depth, detections) = scene();
        let k = crate::msg::calibration::tests::intr_160x120();
        let color = RgbImage::filled(160, 120, [0, 0, 0]).unwrap();
        let lift = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                lift_detections(
                    &mut DepthBoxSegmenter::default(),
                    &color,
                    &depth,
                    detections.clone(),
                    &k,
                    &Isometry3::identity(),
                    Frame::BaseLink,
                    &GeometrySettings::default(),
                    None,
                )
                .unwrap()
            })
        };
        let (one, four) = (lift(1), lift(4));
        assert_eq!(one.objects.len(), 3);
        assert_eq!(one.dropped.len(), 1);
        assert_eq!(one.dropped[0].label, "object 3");
        assert_eq!(one.masks, four.masks);
        assert_eq!(one.objects, four.objects);
        assert_eq!(one.dropped, four.dropped);
        let labels: Vec<&str> = four.objects.iter().map(|o| o.label.as_str()).collect();
        assert_eq!(labels, ["object 0", "object 1", "object 2"]);
    }
}
