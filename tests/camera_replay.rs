//! The replay camera on a TUM-layout recording made of the real MRPT frame:
//! pairing by timestamp, stamps, scale, and `opennav check camera`.

mod common;

use std::path::Path;

use opennav::sensors::camera::{CameraSource, ReplaySource};

/// Three colour frames, four depth frames (one without a partner, one
/// colour frame without a partner), all the MRPT frame.
fn recording(dir: &Path) {
    std::fs::create_dir_all(dir.join("rgb")).unwrap();
    std::fs::create_dir_all(dir.join("depth")).unwrap();
    let mut rgb = String::from("# color images\n# timestamp filename\n");
    for t in ["100.000000", "100.033333", "100.066667", "100.500000"] {
        std::fs::copy(common::mrpt("rgb.png"), dir.join(format!("rgb/{t}.png"))).unwrap();
        rgb.push_str(&format!("{t} rgb/{t}.png\n"));
    }
    let mut depth = String::from("# depth maps\n");
    for t in ["100.004000", "100.030000", "100.070000", "100.300000"] {
        std::fs::copy(
            common::mrpt("depth_mm.png"),
            dir.join(format!("depth/{t}.png")),
        )
        .unwrap();
        depth.push_str(&format!("{t} depth/{t}.png\n"));
    }
    std::fs::write(dir.join("rgb.txt"), rgb).unwrap();
    std::fs::write(dir.join("depth.txt"), depth).unwrap();
    std::fs::copy(
        common::mrpt("calibration.json"),
        dir.join("calibration.json"),
    )
    .unwrap();
}

#[test]
fn replay_pairs_by_timestamp_and_ends() {
    let dir = tempfile::tempdir().unwrap();
    recording(dir.path());
    let mut src = ReplaySource::open(dir.path()).expect("opens");
    assert_eq!(src.len(), 3);
    assert_eq!((src.unpaired_color, src.unpaired_depth), (1, 1));
    let mut stamps = Vec::new();
    while let Some(f) = src.next_frame().expect("frame") {
        let dt = (f.value.color_stamp.as_secs_f64() - f.value.depth_stamp.as_secs_f64()).abs();
        assert!(dt < 0.02, "{dt}");
        // millimetre depth scaled once, at the driver: 1.62–2.56 m
        let max = f.value.depth.data().iter().copied().fold(0.0f32, f32::max);
        assert!((2.5..2.6).contains(&max), "{max}");
        stamps.push(f.stamp.as_secs_f64());
    }
    assert_eq!(stamps.len(), 3);
    assert!(
        (stamps[0]).abs() < 1e-9
            && (stamps[1] - 0.033333).abs() < 1e-6
            && (stamps[2] - 0.066667).abs() < 1e-6
    );
}

#[test]
fn broken_recordings_are_named() {
    let dir = tempfile::tempdir().unwrap();
    recording(dir.path());
    std::fs::write(
        dir.path().join("depth.txt"),
        "100.0 depth/a.png\nnot-a-time depth/b.png\n",
    )
    .unwrap();
    let e = ReplaySource::open(dir.path())
        .err()
        .expect("bad list")
        .to_string();
    assert!(e.contains("depth.txt") && e.contains("line 2"), "{e}");
    std::fs::write(dir.path().join("depth.txt"), "200.0 depth/x.png\n").unwrap();
    let e = ReplaySource::open(dir.path())
        .err()
        .expect("no pairs")
        .to_string();
    assert!(e.contains("no colour frame"), "{e}");
}

#[test]
fn check_camera_prints_frames() {
    let dir = tempfile::tempdir().unwrap();
    recording(dir.path());
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args([
            "check",
            "camera",
            "--replay",
            &dir.path().display().to_string(),
            "--count",
            "5",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 3);
    assert_eq!(lines[0]["width"], 640);
    assert!(lines[0]["valid_depth_fraction"].as_f64().unwrap() > 0.5);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(["check", "camera"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains("RealSense"));
}
