//! Back-projection against MRPT's own cloud of the real RGB-D frame, and the
//! whole pipeline on that frame with the real YOLO11n model.

mod common;

use nalgebra::Isometry3;
use opennav::msg::Frame;
use opennav::msg::RgbdCalibration;
use opennav::msg::{DepthImage, RgbImage};
use opennav::perception::cloud::{back_project, DepthSample};
use opennav::perception::detector::{open_detector, DetectorSettings};
use opennav::perception::pipeline::{GeometrySettings, Pipeline};
use opennav::perception::segmenter::DepthBoxSegmenter;

struct RefCloud {
    u: Vec<u16>,
    v: Vec<u16>,
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
}

fn reference_cloud() -> RefCloud {
    let bytes = std::fs::read(common::generated("mrpt_reference_cloud.bin")).expect("read");
    let n = u32::from_le_bytes(bytes[0..4].try_into().expect("4")) as usize;
    let mut off = 4;
    let u16s = |off: &mut usize| -> Vec<u16> {
        let v = bytes[*off..*off + 2 * n]
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        *off += 2 * n;
        v
    };
    let u = u16s(&mut off);
    let v = u16s(&mut off);
    let f32s = |off: &mut usize| -> Vec<f32> {
        let v = bytes[*off..*off + 4 * n]
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        *off += 4 * n;
        v
    };
    let x = f32s(&mut off);
    let y = f32s(&mut off);
    let z = f32s(&mut off);
    RefCloud { u, v, x, y, z }
}

#[test]
fn back_projection_reproduces_mrpt_cloud() {
    let cal = RgbdCalibration::load(&common::mrpt("calibration.json")).expect("calibration");
    let (depth_k, _) = cal.depth.expect("separate depth camera");
    let depth = DepthImage::load_png(&common::mrpt("depth_mm.png"), cal.depth_scale_m as f32)
        .expect("depth");
    let r = reference_cloud();
    assert!(r.u.len() > 200_000, "{} points", r.u.len());
    let samples: Vec<DepthSample> =
        r.u.iter()
            .zip(&r.v)
            .map(|(&u, &v)| DepthSample {
                u: u as u32,
                v: v as u32,
                z_m: depth
                    .at(u as usize, v as usize)
                    .expect("reference point has depth"),
            })
            .collect();
    // in the depth optical frame, then MRPT's axes: x = Z, y = −X, z = −Y
    let pts = back_project(&samples, &depth_k, &Isometry3::identity());
    let mut worst = 0.0f32;
    for (i, p) in pts.iter().enumerate() {
        let d = [
            (p.z - r.x[i]).abs(),
            (-p.x - r.y[i]).abs(),
            (-p.y - r.z[i]).abs(),
        ];
        worst = worst.max(d[0].max(d[1]).max(d[2]));
    }
    assert!(worst < 1e-5, "max deviation {worst} m");
    // and every valid depth pixel is in the reference: same count
    let valid = depth.data().iter().filter(|&&z| z > 0.0).count();
    assert_eq!(valid, r.u.len());
}

/// The whole pipeline (YOLO11n, the depth segmenter) on the MRPT rig, and
/// its frame.
fn mrpt_pipeline(score_threshold: f32) -> (Pipeline, RgbImage, DepthImage) {
    mrpt_pipeline_with(&common::yolo11n(), score_threshold)
}

fn mrpt_pipeline_with(
    model: &std::path::Path,
    score_threshold: f32,
) -> (Pipeline, RgbImage, DepthImage) {
    common::init_ort();
    let cal = RgbdCalibration::load(&common::mrpt("calibration.json")).expect("calibration");
    let color = RgbImage::load(&common::mrpt("rgb.png")).expect("rgb");
    let depth = DepthImage::load_png(&common::mrpt("depth_mm.png"), cal.depth_scale_m as f32)
        .expect("depth");
    let settings = DetectorSettings {
        score_threshold,
        ..Default::default()
    };
    let det = open_detector(model, &settings, None).expect("model");
    let p = Pipeline::new(
        det,
        Box::new(DepthBoxSegmenter::default()),
        cal,
        GeometrySettings::default(),
    );
    (p, color, depth)
}

#[test]
fn books_on_the_shelf_in_3d() {
    let (mut p, color, depth) = mrpt_pipeline(0.15);
    p.set_prompts(&["book".into()]).expect("prompt");
    let view = p.process(&color, Some(&depth)).expect("view");
    assert!(view.detections.len() >= 3, "{:#?}", view.detections);
    assert!(!view.objects.is_empty());
    assert_eq!(
        view.objects.len() + view.dropped.len(),
        view.detections.len()
    );
    for o in &view.objects {
        assert_eq!(o.frame, Frame::BaseLink);
        assert_eq!(o.label, "book");
        assert!(o.points.len() >= 20);
        // base frame is MRPT's: x forward = depth; the frame's depths are 1.62–2.56 m
        assert!(
            o.aabb.min_m[0] >= 1.6 && o.aabb.max_m[0] <= 2.6,
            "{:?}",
            o.aabb
        );
        // books are small: no box larger than the shelf
        assert!(o.aabb.size_m().iter().all(|s| *s < 1.0), "{:?}", o.aabb);
        for q in &o.points {
            assert!(q.x.is_finite() && q.y.is_finite() && q.z.is_finite());
        }
    }
}

#[test]
fn registration_changes_little_for_this_rig() {
    // the MRPT rig's colour and depth cameras are ~1.6 mm apart; registered
    // depth keeps nearly every return
    let cal = RgbdCalibration::load(&common::mrpt("calibration.json")).expect("calibration");
    let (dk, color_from_depth) = cal.depth.expect("depth");
    let depth = DepthImage::load_png(&common::mrpt("depth_mm.png"), cal.depth_scale_m as f32)
        .expect("depth");
    let reg = opennav::perception::registration::register_depth_to_color(
        &depth,
        &dk,
        &color_from_depth,
        &cal.color,
    )
    .expect("register");
    let before = depth.data().iter().filter(|&&z| z > 0.0).count();
    let after = reg.data().iter().filter(|&&z| z > 0.0).count();
    // the colour camera's focal length is shorter (521 vs 573 px): the depth
    // image lands on a smaller area of the colour image, so some pixels
    // collide; far more than half remain
    assert!(after > before / 2 && after <= before, "{before} → {after}");
    let zs: Vec<f32> = reg.data().iter().copied().filter(|&z| z > 0.0).collect();
    let (lo, hi) = zs
        .iter()
        .fold((f32::MAX, f32::MIN), |(a, b), &z| (a.min(z), b.max(z)));
    assert!(lo > 1.6 && hi < 2.6, "{lo}..{hi}");
}

/// The MRPT frame mirrored left to right (colour and depth): another view
/// of the same kind for a stream.
fn mirrored(color: &RgbImage, depth: &DepthImage) -> (RgbImage, DepthImage) {
    let (w, h) = (color.width(), color.height());
    let mut rgb = Vec::with_capacity(w * h * 3);
    for v in 0..h {
        for u in (0..w).rev() {
            rgb.extend_from_slice(&color.data()[(v * w + u) * 3..(v * w + u) * 3 + 3]);
        }
    }
    let (dw, dh) = (depth.width(), depth.height());
    let mut d = Vec::with_capacity(dw * dh);
    for v in 0..dh {
        for u in (0..dw).rev() {
            d.push(depth.data()[v * dw + u]);
        }
    }
    (
        RgbImage::new(w, h, rgb).expect("rgb"),
        DepthImage::new(dw, dh, d).expect("depth"),
    )
}

/// Views pipelined across frames (the next frame prepared while the model
/// runs, the last one lifted) are each frame's own view, in order: the
/// same detections, objects and drops as one view at a time; a frame with
/// a depth image of the wrong size gets its error and the stream goes on;
/// the caller can end it early.
#[test]
fn a_pipelined_stream_gives_each_frame_its_own_view() {
    let (mut p, color, depth) = mrpt_pipeline(0.1);
    let (color_m, depth_m) = mirrored(&color, &depth);
    p.set_prompts(&["book".into(), "chair".into()])
        .expect("prompt");
    let small = DepthImage::new(4, 4, vec![1.0; 16]).expect("small depth");
    let frames: Vec<(RgbImage, Option<DepthImage>)> = vec![
        (color.clone(), Some(depth.clone())),
        (color_m.clone(), Some(depth_m.clone())),
        (color.clone(), Some(small)),
        (color_m.clone(), None),
        (color.clone(), Some(depth.clone())),
    ];
    let want: Vec<_> = frames
        .iter()
        .map(|(c, d)| p.process(c, d.as_ref()).map_err(|e| e.to_string()))
        .collect();
    assert!(want[2].is_err(), "the small depth image is refused");
    let want_err = want[2].as_ref().err().cloned().unwrap_or_default();
    assert!(want_err.contains("depth image is 4x4"), "{want_err}");
    let (first, second) = (
        want[0].as_ref().expect("view"),
        want[1].as_ref().expect("view"),
    );
    assert!(!first.objects.is_empty() && !second.objects.is_empty());
    assert_ne!(
        first.detections, second.detections,
        "the mirrored frame differs"
    );

    let mut got = Vec::new();
    p.process_stream(frames.clone().into_iter(), |v| {
        got.push(v.map_err(|e| e.to_string()));
        true
    });
    assert_eq!(got.len(), frames.len());
    for (k, (g, w)) in got.iter().zip(&want).enumerate() {
        match (g, w) {
            (Ok(g), Ok(w)) => {
                assert_eq!(g.detections, w.detections, "frame {k}");
                assert_eq!(g.objects, w.objects, "frame {k}");
                assert_eq!(g.dropped, w.dropped, "frame {k}");
                assert_eq!(g.prompts, w.prompts, "frame {k}");
                assert!(g.timing_ms.total >= g.timing_ms.detector, "frame {k}");
            }
            (Err(g), Err(w)) => assert_eq!(g, w, "frame {k}"),
            _ => panic!("frame {k}: stream {g:?} against one view {w:?}"),
        }
    }
    // frame 3 had no depth: 2D detections only, as one view gives
    assert!(got[3]
        .as_ref()
        .is_ok_and(|v| v.objects.is_empty() && !v.detections.is_empty()));

    // depth already in the colour camera (a rig without a separate depth
    // camera): the same views, and a wrong size refused as by one view
    let registered = p.depth_in_color(&color, &depth).expect("registered");
    p.calibration.depth = None;
    let frames_registered = vec![
        (color.clone(), Some(registered.clone())),
        (
            color.clone(),
            Some(DepthImage::new(4, 4, vec![1.0; 16]).expect("small")),
        ),
    ];
    let want: Vec<_> = frames_registered
        .iter()
        .map(|(c, d)| {
            p.process(c, d.as_ref())
                .map(|v| v.objects)
                .map_err(|e| e.to_string())
        })
        .collect();
    let mut got = Vec::new();
    p.process_stream(frames_registered.into_iter(), |v| {
        got.push(v.map(|v| v.objects).map_err(|e| e.to_string()));
        true
    });
    assert!(want[0].as_ref().is_ok_and(|o| !o.is_empty()), "{want:?}");
    assert!(want[1].is_err());
    assert_eq!(got, want);
    p.calibration = RgbdCalibration::load(&common::mrpt("calibration.json")).expect("calibration");

    // ended by the caller after two views: no third
    let mut seen = 0;
    p.process_stream(frames.into_iter().cycle().take(50), |_| {
        seen += 1;
        seen < 2
    });
    assert_eq!(seen, 2);
}

/// The uint8-input model the fixture step makes (the conversion to float
/// planes inside its graph): its views, one at a time and pipelined (the
/// bytes letterboxed on the preparing thread), are the FP32 model's.
#[test]
fn the_byte_input_model_gives_the_fp32_models_views() {
    let (mut fp32, color, depth) = mrpt_pipeline(0.1);
    let (mut bytes, _, _) = mrpt_pipeline_with(&common::generated("yolo11n_coco_u8.onnx"), 0.1);
    let (color_m, depth_m) = mirrored(&color, &depth);
    let prompts = [
        "book".to_string(),
        "chair".to_string(),
        "person".to_string(),
    ];
    fp32.set_prompts(&prompts).expect("prompts");
    bytes.set_prompts(&prompts).expect("prompts");
    let frames = vec![
        (color.clone(), Some(depth.clone())),
        (color_m, Some(depth_m)),
        (color, Some(depth)),
    ];
    let want: Vec<_> = frames
        .iter()
        .map(|(c, d)| fp32.process(c, d.as_ref()).expect("view"))
        .collect();
    assert!(want.iter().all(|v| v.objects.len() >= 3), "{want:#?}");
    for (k, ((c, d), w)) in frames.iter().zip(&want).enumerate() {
        let one = bytes.process(c, d.as_ref()).expect("view");
        assert_eq!(one.detections, w.detections, "frame {k}, one at a time");
        assert_eq!(one.objects, w.objects, "frame {k}, one at a time");
    }
    let mut got = Vec::new();
    bytes.process_stream(frames.into_iter(), |v| {
        got.push(v.expect("view"));
        true
    });
    assert_eq!(got.len(), want.len());
    for (k, (g, w)) in got.iter().zip(&want).enumerate() {
        assert_eq!(g.detections, w.detections, "frame {k}, pipelined");
        assert_eq!(g.objects, w.objects, "frame {k}, pipelined");
        assert_eq!(g.dropped, w.dropped, "frame {k}, pipelined");
    }
}
