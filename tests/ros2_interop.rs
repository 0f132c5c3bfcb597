//! The ROS 2 bridge against an independent DDS implementation: Eclipse
//! Cyclone DDS's Python binding (`tests/ros2_peer.py`, with the ROS 2 type
//! names and the `rt/` topic prefix) says "chair" on /opennav/prompt; the
//! simulated chair (real-time clock) goes there, and the peer hears the
//! sentences on /opennav/said and the status on /opennav/state.
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
            "--exit-on-arrival",
            "--max-duration",
            "90s",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs");
    let peer = Command::new(python)
        .arg(common::repo().join("tests/ros2_peer.py"))
        .arg("80")
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
    assert_eq!(report["outcome"], "arrived", "{report}");
}
