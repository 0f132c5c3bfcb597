//! The closed loop over generated apartments: a small fixed set of
//! scenes (`sim::scene`, seed 1) through the whole daemon
//! (`sim::trial::run`), each on its own paused runtime.

mod common;

use opennav::config::Settings;
use opennav::sim::scene::{generate, scene_seed};
use opennav::sim::trial::{self, TrialResult};

fn trial(settings: &Settings, k: u64) -> TrialResult {
    trial_of(settings, 1, k)
}

/// Scene `k` of seed `seed`, as `opennav sim --seed S --scene K` runs it.
fn trial_of(settings: &Settings, seed: u64, k: u64) -> TrialResult {
    let scene = generate(scene_seed(seed, k));
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()
        .expect("runtime")
        .block_on(trial::run(settings, k, &scene, None, false))
        .expect("the trip runs")
}

#[test]
fn twelve_generated_scenes_are_driven_without_touching_anything() {
    let settings = Settings::load(None).expect("defaults");
    let results: Vec<TrialResult> = (0..12).map(|k| trial(&settings, k)).collect();
    for r in &results {
        eprintln!("{}", serde_json::to_string(r).expect("json"));
    }
    for r in &results {
        assert!(!r.collision, "{r:?}");
        assert!(!r.fell, "{r:?}");
    }
    // the benchmark's test of "reachable" (the chair's own footprint
    // driven on the true floor plan) never denies a place the chair got to
    for r in results.iter().filter(|r| r.reached) {
        assert!(
            r.reachable,
            "reached where the benchmark says no drive leads: {r:?}"
        );
    }
    // a trip that ends anywhere but at the object says why
    for r in results.iter().filter(|r| !r.reached) {
        assert!(r.last_said.is_some(), "{r:?}");
    }
    // the set's result when this assertion was written: 9 of 12 (scene 2
    // unreachable and said so; 1 not found; 4 and 10 held with no way
    // round); fewer is a regression of the planner, the detours or the
    // search
    let succeeded = results.iter().filter(|r| r.success).count();
    assert!(succeeded >= 9, "{succeeded} of 12 succeeded");
}

/// Seed 2's scene 57: the chair starts beside a bed's corner (0.5 m
/// high, under the lasers' plane) whose floor the camera never sees; a
/// doorway's line-up later bends right past it, and the rear-left corner
/// swung 4 cm into the bed before a bend was held for floor never seen
/// beside the chair.
#[test]
fn a_bend_does_not_swing_the_rear_into_a_bed_the_lasers_pass_over() {
    let settings = Settings::load(None).expect("defaults");
    let r = trial_of(&settings, 2, 57);
    eprintln!("{}", serde_json::to_string(&r).expect("json"));
    assert!(!r.collision, "{r:?}");
    assert!(r.min_clearance_m > 0.0, "{r:?}");
}

fn sim_lines(args: &[&str]) -> Vec<serde_json::Value> {
    let mut all = vec![std::ffi::OsStr::new("sim")];
    all.extend(args.iter().map(std::ffi::OsStr::new));
    common::opennav_json_lines(&all)
}

#[test]
fn the_command_prints_a_line_per_scene_and_a_summary_whatever_the_job_count() {
    let one = sim_lines(&["--scenes", "3", "--seed", "5", "--jobs", "1", "--json"]);
    let two = sim_lines(&["--scenes", "3", "--seed", "5", "--jobs", "2", "--json"]);
    assert_eq!(one.len(), 4);
    assert_eq!(one[..3], two[..3], "scenes differ with the job count");
    let summary = &one[3]["summary"];
    assert_eq!(summary["scenes"], 3);
    let reached = one[..3].iter().filter(|l| l["reached"] == true).count();
    assert_eq!(summary["reached"], reached);
    // each line says how the trip went: the stopping error, the doorways
    // and back-offs
    for l in &one[..3] {
        assert!(l["standoff_error_m"].is_number(), "{l}");
        for k in ["doorways", "doorways_given_up", "back_offs", "detours"] {
            assert!(l["navigation"][k].is_u64(), "{k}: {l}");
        }
        assert!(
            l["navigation"]["doorways_given_up"].as_u64() <= l["navigation"]["doorways"].as_u64()
        );
        // the last passage given up says in which phase and where
        let last = &l["navigation"]["last_doorway_given_up"];
        assert_eq!(
            last.is_null(),
            l["navigation"]["doorways_given_up"] == 0,
            "{l}"
        );
        if !last.is_null() {
            assert!(
                last["phase"].is_string() && last["along_m"].is_number(),
                "{l}"
            );
        }
        assert_eq!(l["collision"] == true, l["contact"].is_string(), "{l}");
        // the drive to the chair's own stopping place is never shorter
        // than to the edge of the `reached` test's wider band
        if let (Some(own), Some(band)) = (
            l["shortest_path_to_standoff_m"].as_f64(),
            l["shortest_path_m"].as_f64(),
        ) {
            assert!(own >= band, "{l}");
        }
    }
    for k in ["path_ratio_median", "path_ratio_median_reached_band"] {
        assert!(summary.get(k).is_some(), "no {k} in the summary: {summary}");
    }
    // how the failed trips ended, by their lines' outcomes
    for reachable in [true, false] {
        let by = &summary["failed_by_outcome"][if reachable {
            "reachable"
        } else {
            "unreachable"
        }];
        let by = by.as_object().expect("failed_by_outcome");
        let failed: Vec<&serde_json::Value> = one[..3]
            .iter()
            .filter(|l| l["reachable"] == reachable && l["success"] == false)
            .collect();
        assert_eq!(
            by.values().filter_map(|n| n.as_u64()).sum::<u64>(),
            failed.len() as u64,
            "{summary}"
        );
        for l in failed {
            let name = l["outcome"]
                .as_str()
                .map(str::to_string)
                .or_else(|| {
                    l["outcome"]
                        .as_object()
                        .and_then(|o| o.keys().next().cloned())
                })
                .expect("an outcome");
            assert!(by[&name].as_u64() >= Some(1), "{name}: {summary}");
        }
    }
    // a detector that sees nothing: the trip ends not found, and the
    // summary counts it so
    let blind = sim_lines(&["--scene", "1", "--seed", "5", "--misses", "1", "--json"]);
    assert_eq!(blind[0]["outcome"], "not_found", "{}", blind[0]);
    let by = &blind[1]["summary"]["failed_by_outcome"];
    assert_eq!(by["reachable"], serde_json::json!({"not_found": 1}), "{by}");
    assert_eq!(by["unreachable"], serde_json::json!({}), "{by}");
    // a scene re-runs alone
    let alone = sim_lines(&["--scene", "2", "--seed", "5", "--json"]);
    assert_eq!(alone[0], one[2]);
    // and is described without a trip: the same scene, seed and word
    let described = sim_lines(&["--scenes", "3", "--seed", "5", "--describe"]);
    assert_eq!(described.len(), 3, "{described:?}");
    for (d, trip) in described.iter().zip(&one) {
        for key in ["scene", "seed", "prompt"] {
            assert_eq!(d[key], trip[key], "{key}: {d} against {trip}");
        }
        assert!(
            d["objects"]
                .as_array()
                .is_some_and(|o| o.iter().any(|o| o["label"] == trip["prompt"])),
            "{d}"
        );
    }
    // no scene count: a clear error
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .arg("sim")
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--scenes"));
}

#[test]
fn the_benchmark_reads_the_configuration_it_is_given() {
    // a configuration the benchmark would ignore could not compare two
    // set-ups (a camera's pose, the planner's weights)
    let dir = tempfile::tempdir().expect("tempdir");
    let bad = dir.path().join("opennav.toml");
    std::fs::write(&bad, "[safety]\nv_forward_max_mps = 9.0\n").expect("write");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(["sim", "--scenes", "1", "--json", "--config"])
        .arg(&bad)
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("v_forward_max_mps"), "{err}");
    assert!(
        out.stdout.is_empty(),
        "a run with a bad configuration printed lines"
    );
}

#[test]
fn logs_to_a_pipe_carry_no_colour_codes() {
    // under systemd stderr is journald's pipe: escape codes would be kept
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(["sim", "--scenes", "1", "--json"])
        .env("RUST_LOG", "opennav=info")
        .output()
        .expect("runs");
    assert!(out.status.success(), "{out:?}");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("say="), "no log lines to check: {err}");
    assert!(!err.contains('\u{1b}'), "escape codes in the log: {err}");
}

/// Under systemd (`JOURNAL_STREAM` names stderr) the log goes to journald
/// with its fields, and each sentence is logged once, not also printed;
/// where journald cannot be reached (no systemd here) it says so and logs
/// as text — and still prints each sentence once.
#[test]
fn under_systemd_the_log_goes_to_journald_and_each_sentence_once() {
    use std::os::unix::fs::MetadataExt;
    let dir = tempfile::tempdir().expect("tmp");
    let log = dir.path().join("stderr");
    let file = std::fs::File::create(&log).expect("file");
    let meta = file.metadata().expect("meta");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args([
            "run",
            "--sim",
            "--no-stdin",
            "--prompt",
            "chair",
            "--exit-on-arrival",
        ])
        .env("JOURNAL_STREAM", format!("{}:{}", meta.dev(), meta.ino()))
        .env("RUST_LOG", "opennav=info")
        .stderr(file)
        .output()
        .expect("runs");
    assert!(out.status.success(), "{out:?}");
    let err = std::fs::read_to_string(&log).expect("log");
    if std::path::Path::new("/run/systemd/journal/socket").exists() {
        // journald took the log: nothing of it on stderr
        assert!(!err.contains("Arrived at the chair."), "{err}");
    } else {
        assert!(err.contains("journald cannot be reached"), "{err}");
        assert_eq!(
            err.matches("opennav says: Arrived at the chair.").count(),
            1,
            "{err}"
        );
    }
}

#[test]
fn the_version_names_the_git_revision() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_opennav"))
        .arg("--version")
        .output()
        .expect("runs");
    assert!(out.status.success(), "{out:?}");
    let line = String::from_utf8_lossy(&out.stdout).to_string();
    let head = std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string());
    match head {
        Some(rev) => assert!(line.contains(&format!("(git {rev})")), "{line} vs {rev}"),
        None => {
            eprintln!("NOT CHECKED AGAINST GIT: no git checkout here");
            assert!(line.contains("(git unknown)"), "{line}");
        }
    }
}
