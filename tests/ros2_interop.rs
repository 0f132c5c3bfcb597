//! The ROS 2 bridge against an independent DDS implementation: Eclipse
//! Cyclone DDS's Python binding (`tests/ros2_peer.py`, with the ROS 2 type
//! names, the `rt/` topic prefix and the messages' layouts written from the
//! `.msg` files) waits until it has discovered every endpoint of the
//! chair, says "chair" on /opennav/prompt; the simulated chair (real-time
//! clock) goes there; a stop on /opennav/stop stops it; "go on" and
//! "chair" again, and it arrives; and the peer decodes what the chair publishes: the
//! sentences, the status, both scans, the odometry, /tf and the latched
//! /tf_static, the view's objects and the tracks.
#![cfg(feature = "ros2")]

mod common;

use std::process::{Command, Stdio};

#[test]
fn a_cyclone_dds_peer_sends_the_chair_and_hears_it_arrive() {
    let python = common::asset(common::repo().join(".venv/bin/python"));
    let chair = Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args([
            "run",
            "--sim",
            "--clock",
            "realtime",
            "--ros2",
            "--no-stdin",
            "--max-duration",
            "100s",
        ])
        // the supervisor's states and the planner's holds in the failure
        // message: this real-time trip is the one that has ended short
        .env(
            "RUST_LOG",
            "warn,opennav::safety=info,opennav::daemon::backoff=info,opennav::daemon::control_task=info",
        )
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs");
    let peer = Command::new(python)
        .arg(common::repo().join("tests/ros2_peer.py"))
        .arg("90")
        .output()
        .expect("the Cyclone DDS peer runs (cyclonedds from tests/fixtures/requirements.txt)");
    let out = chair.wait_with_output().expect("exits");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        peer.status.success(),
        "peer: {}",
        String::from_utf8_lossy(&peer.stderr)
    );
    let heard: serde_json::Value = serde_json::from_slice(&peer.stdout).expect("the peer's JSON");
    let said: Vec<&str> = heard["heard"]
        .as_array()
        .expect("heard")
        .iter()
        .filter_map(|s| s.as_str())
        .collect();
    assert!(said.contains(&"Going to the chair."), "{heard}\n{err}");
    assert!(said.contains(&"Arrived at the chair."), "{heard}\n{err}");
    assert!(heard["n_states"].as_u64().is_some_and(|n| n > 0), "{heard}");
    // a stop on /opennav/stop stopped the moving chair; then it went again
    assert_eq!(heard["stop_sent"], true, "{heard}");
    let stopped = &heard["stopped_state"];
    assert!(
        stopped["state"].to_string().contains("Stopped"),
        "{stopped}"
    );
    assert_eq!(heard["go_sent"], true, "{heard}");
    // every endpoint discovered
    assert_eq!(heard["unseen"], serde_json::json!([]), "{heard}");
    // the scans: laser frames, the URG-04LX's 682 steps and range
    for side in ["left", "right"] {
        assert!(
            heard["scans"][side].as_u64().is_some_and(|n| n >= 10),
            "{side}: {heard}"
        );
    }
    let scan = &heard["scan"];
    assert!(
        scan["frame_id"] == "laser_left" || scan["frame_id"] == "laser_right",
        "{scan}"
    );
    assert_eq!(scan["n"], 682, "{scan}");
    assert!(scan["range_max"]
        .as_f64()
        .is_some_and(|r| (r - 5.6).abs() < 1e-3));
    assert!(scan["min_finite"]
        .as_f64()
        .is_some_and(|r| r > 0.02 && r < 5.6));
    // stamps are wall-clock (ROS time), not the run's clock
    for lag in heard["stamp_lag_s"].as_array().expect("lags") {
        assert!(lag.as_f64().is_some_and(|l| l.abs() < 5.0), "{heard}");
    }
    // the odometry: odom → base_link, moved, with the pose's covariance and
    // z marked unknown
    let odom = &heard["odom_last"];
    assert_eq!(odom["frame_id"], "odom", "{odom}");
    assert_eq!(odom["child_frame_id"], "base_link", "{odom}");
    assert!(odom["x"].as_f64().is_some_and(|x| x.abs() > 0.2), "{odom}");
    assert!(odom["cov_xx"].as_f64().is_some_and(|c| c > 0.0), "{odom}");
    assert_eq!(odom["cov_zz"], 1e6, "{odom}");
    assert!(
        odom["lag_s"].as_f64().is_some_and(|l| l.abs() < 5.0),
        "{odom}"
    );
    // /tf and the latched /tf_static
    assert_eq!(
        heard["tf"],
        serde_json::json!([["odom", "base_link"]]),
        "{heard}"
    );
    let statics: Vec<(String, String)> = heard["tf_static"]
        .as_array()
        .expect("tf_static")
        .iter()
        .map(|t| (t["parent"].to_string(), t["child"].to_string()))
        .collect();
    for child in ["laser_left", "laser_right", "camera_optical"] {
        assert!(
            statics.contains(&("\"base_link\"".into(), format!("\"{child}\""))),
            "{child}: {heard}"
        );
    }
    // the view's objects and the tracks (vision_msgs/Detection3DArray)
    assert!(heard["objects"].as_u64().is_some_and(|n| n > 0), "{heard}");
    assert!(
        heard["object_labels"]
            .as_array()
            .is_some_and(|l| l.iter().any(|l| l == "chair")),
        "{heard}"
    );
    assert!(
        heard["track_labels"]
            .as_array()
            .is_some_and(|t| t.iter().any(|t| t[0] == "chair"
                && t[2] == "odom"
                && t[1].as_str().is_some_and(|id| id.parse::<u64>().is_ok()))),
        "{heard}"
    );
    assert!(
        heard["states"]
            .as_array()
            .is_some_and(|s| s.iter().any(|s| s["goal"] == "chair")),
        "{heard}"
    );
    assert!(out.status.success(), "{err}");
    let report: serde_json::Value = serde_json::from_str(
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .last()
            .expect("report"),
    )
    .expect("JSON report");
    // a stop ends a run that ends on arrival: this one ends on "quit"
    assert_eq!(report["outcome"], "quit", "{report}");
    // the bridge's own account: what its queue dropped, what DDS refused
    assert!(report["ros2"]["dropped"].is_u64(), "{report}");
    assert!(report["ros2"]["not_sent"].is_u64(), "{report}");
}
