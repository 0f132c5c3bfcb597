//! `opennav detect` as a user runs it: the JSON schema, the outputs, and
//! exit code 2 with a one-line error naming the input for bad input.

mod common;

use std::path::Path;
use std::process::{Command, Output};

fn opennav(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(args)
        .current_dir(common::repo())
        .env_remove("RUST_LOG")
        .output()
        .expect("runs")
}

fn p(path: &Path) -> String {
    path.display().to_string()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).to_string()
}

fn models_dir() -> String {
    p(common::yolo11n().parent().expect("dir"))
}

#[test]
fn detect_2d_json_schema() {
    let bus = common::asset(common::shared().join("data/images/bus.jpg"));
    let o = opennav(&[
        "detect",
        "--rgb",
        &p(&bus),
        "--prompt",
        "bus, person",
        "--models",
        &models_dir(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json on stdout");
    let dets = v["detections"].as_array().expect("detections");
    assert_eq!(dets.len(), 5);
    assert_eq!(dets[0]["label"], "bus");
    assert!(dets[0]["score"].as_f64().expect("score") > 0.9);
    assert_eq!(dets[0]["box_xyxy"].as_array().expect("box").len(), 4);
    assert!(v["objects"].as_array().expect("objects").is_empty());
    for k in ["registration", "detector", "segmenter", "geometry", "total"] {
        assert!(v["timing_ms"][k].is_number(), "timing_ms.{k}");
    }
}

#[test]
fn detect_3d_writes_overlay_and_ply() {
    let out = tempfile::tempdir().expect("tmp");
    let o = opennav(&[
        "detect",
        "--rgb",
        &p(&common::mrpt("rgb.png")),
        "--depth",
        &p(&common::mrpt("depth_mm.png")),
        "--calibration",
        &p(&common::mrpt("calibration.json")),
        "--prompt",
        "book",
        "--score-threshold",
        "0.15",
        "--segmenter",
        "depth",
        "--models",
        &models_dir(),
        "--out",
        &p(out.path()),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    let objs = v["objects"].as_array().expect("objects");
    assert!(!objs.is_empty());
    for ob in objs {
        assert_eq!(ob["frame"], "base_link");
        for k in ["center_m", "size_m", "min_m", "max_m"] {
            assert_eq!(ob[k].as_array().expect(k).len(), 3);
        }
        let x = ob["center_m"][0].as_f64().expect("x");
        assert!((1.6..=2.6).contains(&x), "{x}");
        assert!(ob["yaw_rad"].is_number());
        assert!(ob["points"].as_u64().expect("points") >= 20);
    }
    assert!(out.path().join("overlay.png").is_file());
    let plys = std::fs::read_dir(out.path())
        .expect("dir")
        .filter(|e| {
            e.as_ref()
                .is_ok_and(|e| e.path().extension().is_some_and(|x| x == "ply"))
        })
        .count();
    assert_eq!(plys, objs.len());
}

fn assert_bad_input(o: &Output, needle: &str) {
    assert_eq!(o.status.code(), Some(2), "stderr: {}", stderr(o));
    let e = stderr(o);
    assert!(e.contains(needle), "expected {needle:?} in {e:?}");
    assert!(!e.contains("panicked"), "{e}");
}

#[test]
fn missing_image_is_named() {
    let o = opennav(&[
        "detect",
        "--rgb",
        "/no/such/frame.png",
        "--prompt",
        "chair",
        "--models",
        &models_dir(),
    ]);
    assert_bad_input(&o, "/no/such/frame.png");
}

#[test]
fn unreadable_image_is_named() {
    let dir = tempfile::tempdir().expect("tmp");
    let f = dir.path().join("notes.png");
    std::fs::write(&f, "this is not an image").expect("write");
    let o = opennav(&[
        "detect",
        "--rgb",
        &p(&f),
        "--prompt",
        "chair",
        "--models",
        &models_dir(),
    ]);
    assert_bad_input(&o, "notes.png");
}

#[test]
fn empty_prompt_is_refused() {
    let o = opennav(&[
        "detect",
        "--rgb",
        &p(&common::mrpt("rgb.png")),
        "--prompt",
        " , ",
        "--models",
        &models_dir(),
    ]);
    assert_bad_input(&o, "--prompt");
}

#[test]
fn depth_of_another_size_is_refused() {
    let bus = common::asset(common::shared().join("data/images/bus.jpg"));
    let o = opennav(&[
        "detect",
        "--rgb",
        &p(&bus),
        "--depth",
        &p(&common::mrpt("depth_mm.png")),
        "--calibration",
        &p(&common::mrpt("calibration.json")),
        "--prompt",
        "person",
        "--segmenter",
        "depth",
        "--models",
        &models_dir(),
    ]);
    assert_bad_input(&o, "colour image is 810x1080, calibration expects 640x480");
}

#[test]
fn depth_without_calibration_is_refused() {
    let o = opennav(&[
        "detect",
        "--rgb",
        &p(&common::mrpt("rgb.png")),
        "--depth",
        &p(&common::mrpt("depth_mm.png")),
        "--prompt",
        "book",
    ]);
    assert_bad_input(&o, "--calibration");
}

#[test]
fn colour_image_as_depth_is_refused() {
    let o = opennav(&[
        "detect",
        "--rgb",
        &p(&common::mrpt("rgb.png")),
        "--depth",
        &p(&common::mrpt("rgb.png")),
        "--calibration",
        &p(&common::mrpt("calibration.json")),
        "--prompt",
        "book",
        "--models",
        &models_dir(),
    ]);
    assert_bad_input(&o, "16-bit");
}

#[test]
fn model_with_wrong_signature_is_refused() {
    let o = opennav(&[
        "detect",
        "--rgb",
        &p(&common::mrpt("rgb.png")),
        "--prompt",
        "book",
        "--detector",
        &p(&common::generated("mobile_sam_encoder.onnx")),
    ]);
    assert_bad_input(&o, "mobile_sam_encoder.onnx");
}

#[test]
fn missing_model_names_the_file_and_how_to_get_it() {
    let empty = tempfile::tempdir().expect("tmp");
    let o = opennav(&[
        "detect",
        "--rgb",
        &p(&common::mrpt("rgb.png")),
        "--prompt",
        "book",
        "--models",
        &p(empty.path()),
    ]);
    assert_bad_input(&o, "yolo11n_coco.onnx");
    assert!(stderr(&o).contains("models/README.md"));
}

#[test]
fn broken_calibration_is_named() {
    let dir = tempfile::tempdir().expect("tmp");
    let f = dir.path().join("cal.json");
    std::fs::write(&f, "{\"format\": \"opennav-calibration/1\"}").expect("write");
    let o = opennav(&[
        "detect",
        "--rgb",
        &p(&common::mrpt("rgb.png")),
        "--depth",
        &p(&common::mrpt("depth_mm.png")),
        "--calibration",
        &p(&f),
        "--prompt",
        "book",
    ]);
    assert_bad_input(&o, "cal.json");
}

#[test]
fn bad_config_value_is_named() {
    let dir = tempfile::tempdir().expect("tmp");
    let f = dir.path().join("opennav.toml");
    std::fs::write(&f, "[perception]\nnms_iou = 3.0\n").expect("write");
    let o = opennav(&[
        "--config",
        &p(&f),
        "detect",
        "--rgb",
        &p(&common::mrpt("rgb.png")),
        "--prompt",
        "book",
    ]);
    assert_bad_input(&o, "perception.nms_iou");
}
