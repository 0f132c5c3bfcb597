//! Perception benchmarks.
//! - `geometry_10_masks`: paper steps 3–6 (erosion, depth isolation +
//!   z-score, back-projection + extrinsics, boxes) on a 640×480 frame with
//!   10 masks, one core. Target ≤ 0.5 ms. The paper's numpy/scipy stack on
//!   the same scene: `benches/paper_geometry.py`.
//! - `depth_segmenter_10_boxes`: step 2 without a model.
//! - `letterbox_640`: the detector's pre-processing of a 640×480 frame.
//! - `whole_view_yolo11n_depth`: one whole view on the real MRPT RGB-D frame
//!   with YOLO11n (CPU) + the depth segmenter. Target ≤ 130 ms (the paper's
//!   GPU figure). Needs ../shared/models/yolo11n_coco.onnx and the ONNX
//!   Runtime library (scripts/fetch-onnxruntime.sh).
//! - `yolo11n_model_only`: the same model's inference alone (its own
//!   session, same settings, a pre-made input): the whole view's ratio
//!   to it is what perception adds to the model. After both, each stage's
//!   median over 50 views is printed (`whole_view stages`), and one view
//!   at a time alternated with one bare model run, 300 pairs, with the
//!   median of the pairs' ratios (`whole_view alternated`).
//! - `yolo11n_detect_prepared`: the detector on an input letterboxed
//!   beforehand (the model and the decoding); `letterbox_mrpt`: that
//!   letterbox of the real frame.
//! - `whole_view_pipelined`: the same views as a stream of frames
//!   (`Pipeline::process_stream`: the next frame's depth registration and
//!   letterbox, and the last frame's masks and geometry, beside the
//!   model): the time per view is the stream's period.
//! - `registration_640`: the MRPT frame's depth registered into its
//!   colour camera.
//!
//! Environment: `OPENNAV_BENCH_PROVIDER` = cpu (default), cuda or
//! tensorrt (a provider the library lacks is not measured);
//! `OPENNAV_BENCH_THREADS`, `OPENNAV_BENCH_DETECTOR` (another YOLO11n file).
//!
//! Run: `cargo bench --bench perception`

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::Isometry3;
use opennav::msg::Frame;
use opennav::msg::{DepthImage, RgbImage};
use opennav::msg::{Intrinsics, RgbdCalibration};
use opennav::perception::detector::{open_detector, Detection, DetectorSettings, PreparedImage};
use opennav::perception::image::{letterbox_chw, letterbox_hwc_u8};
use opennav::perception::pipeline::{
    depth_in_color, floor_in_image, objects_from_masks, GeometrySettings, Pipeline, Timing,
};
use opennav::perception::registration::register_depth_to_color;
use opennav::perception::runtime::ExecutionProviderKind;
use opennav::perception::segmenter::{DepthBoxSegmenter, Segmenter};
use serde::de::IntoDeserializer;
use serde::Deserialize;

/// A 640×480 scene: a wall at 3.5 m and 10 box-shaped objects in front.
fn scene() -> (DepthImage, Vec<Detection>) {
    let (w, h) = (640usize, 480usize);
    let mut d = vec![3.5f32; w * h];
    let mut dets = Vec::new();
    for i in 0..10 {
        let x0 = 20 + (i % 5) * 120;
        let y0 = 40 + (i / 5) * 220;
        let (bw, bh) = (90, 160);
        let z = 1.0 + 0.2 * i as f32;
        for v in y0..y0 + bh {
            for u in x0..x0 + bw {
                // a little slope and noise-like ripple
                d[v * w + u] = z + 0.002 * ((u * 7 + v * 13) % 11) as f32;
            }
        }
        dets.push(Detection {
            label: format!("object{i}"),
            class: "object".into(),
            score: 0.9,
            box_xyxy: [
                x0 as f32 - 10.0,
                y0 as f32 - 10.0,
                (x0 + bw) as f32 + 10.0,
                (y0 + bh) as f32 + 10.0,
            ],
        });
    }
    (DepthImage::new(w, h, d).expect("depth"), dets)
}

fn intrinsics() -> Intrinsics {
    Intrinsics {
        width: 640,
        height: 480,
        fx: 385.0,
        fy: 385.0,
        cx: 320.0,
        cy: 240.0,
    }
}

fn bench_geometry(c: &mut Criterion) {
    // as the opennav binary does at start; OPENNAV_BENCH_TRIM_HEAP=1: the
    // allocator's own policy, for comparison
    if std::env::var_os("OPENNAV_BENCH_TRIM_HEAP").is_none() {
        opennav::memory::keep_freed_heap();
    }
    let (depth, dets) = scene();
    let seg = DepthBoxSegmenter::default();
    let masks: Vec<_> = dets
        .iter()
        .map(|d| seg.segment_box(&depth, d.box_xyxy))
        .collect();
    let k = intrinsics();
    let base_from_camera = Isometry3::translation(0.3, 0.0, 0.9);
    let settings = GeometrySettings::default();
    let (objs, _) = objects_from_masks(
        &dets,
        &masks,
        &depth,
        &k,
        &base_from_camera,
        Frame::BaseLink,
        &settings,
    );
    assert_eq!(objs.len(), 10);
    c.bench_function("geometry_10_masks", |b| {
        b.iter(|| {
            objects_from_masks(
                &dets,
                &masks,
                &depth,
                &k,
                &base_from_camera,
                Frame::BaseLink,
                &settings,
            )
        })
    });
    // the same masks seen by a camera mounted as on the chair (looking
    // along base x, 0.9 m up): each object's ground projection is a strip
    // a few centimetres deep, not a filled rectangle
    let level = nalgebra::Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    let base_from_camera_forward = Isometry3::from_parts(
        nalgebra::Translation3::new(0.3, 0.0, 0.9),
        nalgebra::UnitQuaternion::from_rotation_matrix(
            &nalgebra::Rotation3::from_matrix_unchecked(level),
        ),
    );
    c.bench_function("geometry_10_masks_forward", |b| {
        b.iter(|| {
            objects_from_masks(
                &dets,
                &masks,
                &depth,
                &k,
                &base_from_camera_forward,
                Frame::BaseLink,
                &settings,
            )
        })
    });
    c.bench_function("depth_segmenter_10_boxes", |b| {
        b.iter(|| {
            dets.iter()
                .map(|d| seg.segment_box(&depth, d.box_xyxy))
                .collect::<Vec<_>>()
        })
    });
    // depth registered into the colour camera: the real MRPT frame and rig
    // (a separate depth camera, 640×480 both)
    let fx = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/mrpt_openni2");
    let cal = RgbdCalibration::load(&fx.join("calibration.json")).expect("calibration");
    let mrpt_depth =
        DepthImage::load_png(&fx.join("depth_mm.png"), cal.depth_scale_m as f32).expect("depth");
    let (depth_k, color_from_depth) = cal.depth.expect("the MRPT rig has a depth camera");
    c.bench_function("registration_640", |b| {
        b.iter(|| {
            register_depth_to_color(&mrpt_depth, &depth_k, &color_from_depth, &cal.color)
                .expect("registration")
        })
    });
    let img = RgbImage::filled(640, 480, [100, 150, 200]).expect("image");
    c.bench_function("letterbox_640", |b| {
        b.iter(|| letterbox_chw(&img, 640, 114))
    });
    // the same as bytes, for a model that takes them (the fixture step's
    // yolo11n_coco_u8.onnx)
    c.bench_function("letterbox_640_bytes", |b| {
        b.iter(|| letterbox_hwc_u8(&img, 640, 114))
    });
}

fn shared() -> PathBuf {
    std::env::var_os("OPENNAV_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared"))
}

fn bench_whole_view(c: &mut Criterion) {
    // a filter that names none of this group's benches (`--bench
    // depth_segmenter_10_boxes`) skips the group and its printed figures,
    // minutes of model runs on a CPU
    const NAMES: &str = "whole_view_yolo11n_depth whole_view_pipelined yolo11n_model_only \
                         yolo11n_detect_prepared letterbox_mrpt segmenter_mrpt_boxes";
    // (criterion's options that take a value, whose value is no filter)
    const VALUED: [&str; 15] = [
        "--save-baseline",
        "--baseline",
        "--load-baseline",
        "--sample-size",
        "--warm-up-time",
        "--measurement-time",
        "--nresamples",
        "--noise-threshold",
        "--confidence-level",
        "--significance-level",
        "--plotting-backend",
        "--output-format",
        "--color",
        "--profile-time",
        "--format",
    ];
    let mut filter = None;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if VALUED.contains(&a.as_str()) {
            args.next();
        } else if !a.starts_with('-') {
            filter = Some(a);
        }
    }
    if filter.as_deref().is_some_and(|f| !NAMES.contains(f)) {
        return;
    }
    // the printed figures after the group: with no filter, or one naming
    // the whole view
    let prints = filter
        .as_deref()
        .is_none_or(|f| "whole_view_yolo11n_depth whole_view_pipelined".contains(f));
    // a provider that fails to register is logged (and the view runs on
    // the CPU): show it
    let _ = tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .try_init();
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    // OPENNAV_BENCH_DETECTOR: another YOLO11n file, e.g. the INT8 one the
    // fixture step makes (tests/fixtures/generated/yolo11n_int8.onnx)
    let model = std::env::var_os("OPENNAV_BENCH_DETECTOR")
        .map(PathBuf::from)
        .unwrap_or_else(|| shared().join("models/yolo11n_coco.onnx"));
    if !model.is_file() {
        eprintln!(
            "\n*** whole_view_yolo11n_depth NOT RUN: {} is missing ***\n",
            model.display()
        );
        return;
    }
    let lib = opennav::perception::runtime::resolve_library_path(None);
    let lib = if lib.is_relative() {
        root.join(lib)
    } else {
        lib
    };
    if let Err(e) = opennav::perception::runtime::init_runtime(&lib) {
        eprintln!("\n*** whole_view_yolo11n_depth NOT RUN: {e} ***\n");
        return;
    }
    let fx = root.join("tests/fixtures/mrpt_openni2");
    let cal = RgbdCalibration::load(&fx.join("calibration.json")).expect("calibration");
    let color = RgbImage::load(&fx.join("rgb.png")).expect("rgb");
    let depth =
        DepthImage::load_png(&fx.join("depth_mm.png"), cal.depth_scale_m as f32).expect("depth");
    let threads: usize = std::env::var("OPENNAV_BENCH_THREADS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let mut settings = DetectorSettings {
        score_threshold: 0.15,
        ..Default::default()
    };
    settings.session.intra_threads = threads;
    // OPENNAV_BENCH_PROVIDER: cpu (default), cuda or tensorrt; a GPU
    // provider the library lacks is not measured (never a CPU figure under
    // a GPU name)
    let provider = std::env::var("OPENNAV_BENCH_PROVIDER").unwrap_or_else(|_| "cpu".into());
    // the names the config takes (`runtime.execution_provider`)
    settings.session.provider =
        match ExecutionProviderKind::deserialize(provider.as_str().into_deserializer()) {
            Ok(kind) => kind,
            Err(e) => {
                let e: serde::de::value::Error = e;
                eprintln!(
                    "\n*** whole_view_yolo11n_depth NOT RUN: OPENNAV_BENCH_PROVIDER: {e} ***\n"
                );
                return;
            }
        };
    if !opennav::perception::runtime::provider_available(settings.session.provider) {
        eprintln!(
            "\n*** whole_view_yolo11n_depth NOT RUN: {} has no {provider} provider ***\n",
            lib.display()
        );
        return;
    }
    eprintln!("whole_view: provider {provider}, library {}", lib.display());
    let det = open_detector(&model, &settings, None).expect("model");
    let layout = det.input_layout();
    let mut p = Pipeline::new(
        det,
        Box::new(DepthBoxSegmenter::default()),
        cal.clone(),
        GeometrySettings::default(),
    );
    p.set_prompts(&["book".into(), "chair".into(), "person".into()])
        .expect("prompts");
    // the bare model: the same ONNX file in its own session with the same
    // settings, one pre-made 640×640 input in its layout, nothing before
    // or after
    let mut bare = Bare::load(&model, &settings, &color);
    // a model other than the shared FP32 one (OPENNAV_BENCH_DETECTOR): the
    // FP32 model bare too, alternated with the others
    let fp32_path = shared().join("models/yolo11n_coco.onnx");
    let mut fp32 = (model != fp32_path && fp32_path.is_file())
        .then(|| Bare::load(&fp32_path, &settings, &color));
    let mut group = c.benchmark_group("whole_view");
    group.sample_size(30);
    group.bench_function("whole_view_yolo11n_depth", |b| {
        b.iter(|| p.process(&color, Some(&depth)).expect("view"))
    });
    // a stream of frames, pipelined: the next frame prepared and the last
    // lifted while the model runs; the time per view is the stream's
    // period (each frame arrives owned, as from the camera)
    group.bench_function("whole_view_pipelined", |b| {
        b.iter_custom(|views| {
            let frames = (0..views).map(|_| (color.clone(), Some(depth.clone())));
            let t = std::time::Instant::now();
            p.process_stream(frames, |v| {
                v.expect("view");
                true
            });
            t.elapsed()
        })
    });
    group.bench_function("yolo11n_model_only", |b| b.iter(|| bare.run(true)));
    // the detector's own share: the model and the decoding of its output
    // into boxes, on an input letterboxed beforehand (copied each time, as
    // the bare model's)
    let mut detector = open_detector(&model, &settings, None).expect("model");
    detector
        .set_prompts(&["book".into(), "chair".into(), "person".into()])
        .expect("prompts");
    let prepared = PreparedImage::letterboxed(&color, 640, layout);
    group.bench_function("yolo11n_detect_prepared", |b| {
        b.iter(|| {
            detector
                .detect_prepared(prepared.clone())
                .expect("detections")
        })
    });
    group.bench_function("letterbox_mrpt", |b| {
        b.iter(|| PreparedImage::letterboxed(&color, 640, layout))
    });
    // the segmenter's stage alone on this frame: YOLO11n's boxes (made
    // once), the depth registered into the colour camera, one box after
    // another on this thread (`taskset -c 1 … -- segmenter_mrpt_boxes`)
    let boxes: Vec<[f32; 4]> = detector
        .detect_prepared(prepared.clone())
        .expect("detections")
        .iter()
        .map(|d| d.box_xyxy)
        .collect();
    let registered = depth_in_color(&cal, &color, &depth).expect("registration");
    let mut seg = DepthBoxSegmenter::default();
    seg.set_floor(floor_in_image(&cal));
    group.bench_function("segmenter_mrpt_boxes", |b| {
        b.iter(|| {
            boxes
                .iter()
                .map(|b| seg.segment_box(&registered, *b))
                .collect::<Vec<_>>()
        })
    });
    group.finish();
    if !prints {
        return;
    }
    // where the view's time goes: each stage's median over 50 views, one
    // view at a time
    let views: Vec<Timing> = (0..50)
        .map(|_| p.process(&color, Some(&depth)).expect("view").timing_ms)
        .collect();
    print_stages(&format!("whole_view stages ({provider}"), &views);
    // and as a pipelined stream: its detector stage is the model and the
    // decoding (the letterbox made beside the registration), `total` a
    // view's latency from its frame to its objects
    let mut views = Vec::new();
    p.process_stream((0..50).map(|_| (color.clone(), Some(depth.clone()))), |v| {
        views.push(v.expect("view").timing_ms);
        true
    });
    print_stages(&format!("whole_view_pipelined stages ({provider}"), &views);
    // one view at a time and the bare model, alternated run by run (on a
    // shared host whose speed drifts, each pair sees the same moment):
    // the medians and the median of the pairs' ratios
    let mut pairs: Vec<(f64, f64, f64)> = Vec::new();
    for _ in 0..300 {
        let t = std::time::Instant::now();
        p.process(&color, Some(&depth)).expect("view");
        let view_ms = t.elapsed().as_secs_f64() * 1e3;
        let model_ms = bare.run(false);
        let fp32_ms = fp32.as_mut().map_or(f64::NAN, |f| f.run(false));
        pairs.push((view_ms, model_ms, fp32_ms));
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    eprintln!(
        "whole_view alternated ({provider}, 300 pairs): a view {:.3} ms, the model alone {:.3} ms (its input made outside the timing), median ratio {:.2}x",
        median(pairs.iter().map(|p| p.0).collect()),
        median(pairs.iter().map(|p| p.1).collect()),
        median(pairs.iter().map(|p| p.0 / p.1).collect()),
    );
    if fp32.is_some() {
        eprintln!(
            "whole_view alternated ({provider}): the FP32 model alone {:.3} ms in the same rounds, the view's median ratio to it {:.2}x",
            median(pairs.iter().map(|p| p.2).collect()),
            median(pairs.iter().map(|p| p.0 / p.2).collect()),
        );
    }
    // the period over one long stream against the bare model over as many
    // runs, alternated: each view's time where the model is the limit
    const LONG: u32 = 300;
    for round in 1..=2 {
        let t = std::time::Instant::now();
        p.process_stream(
            (0..LONG).map(|_| (color.clone(), Some(depth.clone()))),
            |v| {
                v.expect("view");
                true
            },
        );
        let stream_ms = t.elapsed().as_secs_f64() * 1e3 / f64::from(LONG);
        let t = std::time::Instant::now();
        for _ in 0..LONG {
            bare.run(false);
        }
        let model_ms = t.elapsed().as_secs_f64() * 1e3 / f64::from(LONG);
        eprintln!(
            "whole_view_pipelined period ({provider}, {LONG} frames, round {round}): {stream_ms:.3} ms a view against the model alone's {model_ms:.3} ms: {:.2}x",
            stream_ms / model_ms
        );
    }
}

/// A model in its own session with a pre-made input in its layout.
struct Bare {
    model: opennav::perception::runtime::Model,
    input_name: String,
    input: PreparedImage,
}

impl Bare {
    fn load(path: &std::path::Path, settings: &DetectorSettings, color: &RgbImage) -> Bare {
        let layout = open_detector(path, settings, None)
            .expect("model")
            .input_layout();
        let model =
            opennav::perception::runtime::Model::load(path, &settings.session).expect("model");
        Bare {
            input_name: model.signature.inputs[0].name.clone(),
            model,
            input: PreparedImage::letterboxed(color, 640, layout),
        }
    }

    /// One run, its milliseconds; the input's copy into a tensor timed
    /// too when `with_input` (criterion's `yolo11n_model_only`), else not.
    fn run(&mut self, with_input: bool) -> f64 {
        let t0 = std::time::Instant::now();
        let input = self.input.clone().into_tensor().expect("tensor");
        let t = if with_input {
            t0
        } else {
            std::time::Instant::now()
        };
        self.model
            .session
            .run(ort::inputs![self.input_name.as_str() => input])
            .expect("inference");
        t.elapsed().as_secs_f64() * 1e3
    }
}

/// Each stage's median over the views, on one line.
fn print_stages(what: &str, views: &[Timing]) {
    type Stage = fn(&Timing) -> f64;
    let median = |stage: Stage| {
        let mut ms: Vec<f64> = views.iter().map(stage).collect();
        ms.sort_by(f64::total_cmp);
        ms[ms.len() / 2]
    };
    let stages: [(&str, Stage); 5] = [
        ("registration", |t| t.registration),
        ("detector", |t| t.detector),
        ("segmenter", |t| t.segmenter),
        ("geometry", |t| t.geometry),
        ("total", |t| t.total),
    ];
    let line: Vec<String> = stages
        .iter()
        .map(|(name, stage)| format!("{name} {:.3} ms", median(*stage)))
        .collect();
    eprintln!(
        "{what}, median of {} views): {}",
        views.len(),
        line.join(", ")
    );
}

criterion_group!(benches, bench_geometry, bench_whole_view);
criterion_main!(benches);
