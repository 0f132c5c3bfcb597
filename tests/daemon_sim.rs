//! The daemon closed loop on the simulator: `opennav run` (no chair
//! devices on this machine, so the simulated living room) finds the
//! prompted object and drives there through the real R-Net writer without
//! touching anything; a stop word and SIGTERM bring the chair to rest.

use std::io::Write;
use std::process::{Command, Stdio};
use std::time::Duration;

use serde_json::Value;

fn opennav() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_opennav"));
    // the simulator, whatever devices this machine has
    c.args(["run", "--sim"]);
    c
}

fn report(stdout: &[u8]) -> Value {
    let text = String::from_utf8_lossy(stdout);
    let line = text
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'))
        .unwrap_or_else(|| panic!("no report in {text}"));
    serde_json::from_str(line).expect("report JSON")
}

fn drive_to(word: &str) -> Value {
    let out = opennav()
        .args([
            "--prompt",
            word,
            "--exit-on-arrival",
            "--max-duration",
            "120s",
            "--no-stdin",
        ])
        .output()
        .expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    report(&out.stdout)
}

fn check_arrival(r: &Value, word: &str) {
    assert_eq!(r["outcome"], "arrived", "{r}");
    let said: Vec<&str> = r["said"]
        .as_array()
        .expect("said")
        .iter()
        .filter_map(|s| s.as_str())
        .collect();
    assert!(
        said.contains(&format!("Arrived at the {word}.").as_str()),
        "{said:?}"
    );
    let w = &r["sim"]["world"];
    assert_eq!(w["collision_steps"], 0, "{w}");
    assert!(w["min_clearance_m"].as_f64().unwrap_or(0.0) > 0.1, "{w}");
    // the chair's front 0.6 m from the object (base_link 0.55 m behind
    // the front), within the goal tolerance and the odometry's error
    let d = r["sim"]["distance_to_goal_object_m"]
        .as_f64()
        .expect("distance");
    assert!((0.95..=1.45).contains(&d), "{d} m from the {word}");
    assert!(
        w["v_mps"].as_f64().unwrap_or(1.0).abs() < 0.05,
        "still moving: {w}"
    );
    assert!(r["sim"]["scan_matches"].as_u64().unwrap_or(0) > 10, "{r}");
    // the camera IMU's yaw rate went into the heading
    assert!(r["sim"]["gyro_fused"].as_u64().unwrap_or(0) > 100, "{r}");
    assert_eq!(r["actuator"]["state"], "released");
    assert_eq!(r["actuator"]["dropped"], 0);
}

#[test]
fn finds_the_chair_and_drives_there() {
    check_arrival(&drive_to("chair"), "chair");
}

#[test]
fn finds_the_cabinet_after_turning_to_look_for_it() {
    let r = drive_to("cabinet");
    check_arrival(&r, "cabinet");
    // it was out of view at the start: the chair turned to find it
    assert!(
        r["sim"]["world"]["distance_travelled_m"]
            .as_f64()
            .unwrap_or(0.0)
            > 0.8,
        "{r}"
    );
}

#[test]
fn a_word_nothing_answers_ends_in_not_found_after_one_turn() {
    let out = opennav()
        .args([
            "--prompt",
            "piano",
            "--exit-on-arrival",
            "--max-duration",
            "120s",
            "--no-stdin",
        ])
        .output()
        .expect("runs");
    let r = report(&out.stdout);
    assert_eq!(r["outcome"], "not found", "{r}");
    assert!(r["said"].to_string().contains("cannot find a piano"), "{r}");
    assert_eq!(r["sim"]["world"]["collision_steps"], 0);
}

#[test]
fn the_stop_word_brings_the_chair_to_rest() {
    let mut child = opennav()
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("runs");
    let mut stdin = child.stdin.take().expect("stdin");
    writeln!(stdin, "cabinet").expect("word");
    // moving (searching, then driving) for a while
    std::thread::sleep(Duration::from_secs(4));
    writeln!(stdin, "stop").expect("stop");
    std::thread::sleep(Duration::from_millis(1500));
    writeln!(stdin, "quit").expect("quit");
    let out = child.wait_with_output().expect("exits");
    assert!(out.status.success());
    let r = report(&out.stdout);
    assert_eq!(r["outcome"], "quit");
    assert_eq!(r["supervisor"]["Stopped"], "UserStop", "{r}");
    assert!(r["said"].to_string().contains("Stopped."), "{r}");
    let w = &r["sim"]["world"];
    assert!(w["v_mps"].as_f64().unwrap_or(1.0).abs() < 0.01, "{w}");
    assert!(w["omega_radps"].as_f64().unwrap_or(1.0).abs() < 0.01, "{w}");
}

#[test]
fn sigterm_stops_the_chair_and_releases_the_bus() {
    let child = opennav()
        .args(["--prompt", "cabinet", "--no-stdin"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("runs");
    std::thread::sleep(Duration::from_secs(4));
    // SAFETY: kill(2) on our own child
    let rc = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGTERM) };
    assert_eq!(rc, 0);
    let out = child.wait_with_output().expect("exits");
    assert!(out.status.success());
    let r = report(&out.stdout);
    assert_eq!(r["outcome"], "signal", "{r}");
    assert_eq!(r["actuator"]["state"], "released", "{r}");
    assert_eq!(
        r["actuator"]["last_output"],
        serde_json::json!([0, 0]),
        "{r}"
    );
}

#[test]
fn notifies_systemd_ready_and_feeds_the_watchdog() {
    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("notify");
    let sock = std::os::unix::net::UnixDatagram::bind(&path).expect("bind");
    sock.set_read_timeout(Some(Duration::from_secs(10)))
        .expect("timeout");
    let child = opennav()
        .args(["--no-stdin", "--max-duration", "2s"])
        .env("NOTIFY_SOCKET", &path)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("runs");
    let mut msgs = Vec::new();
    let mut buf = [0u8; 256];
    while let Ok(n) = sock.recv(&mut buf) {
        let m = String::from_utf8_lossy(&buf[..n]).to_string();
        let done = m == "STOPPING=1";
        msgs.push(m);
        if done {
            break;
        }
    }
    let out = child.wait_with_output().expect("exits");
    assert!(out.status.success());
    assert_eq!(
        msgs.first().map(|s| s.as_str()),
        Some("READY=1"),
        "{msgs:?}"
    );
    let feeds = msgs.iter().filter(|m| *m == "WATCHDOG=1").count();
    // 20 Hz for about 2 s
    assert!(feeds > 20, "{feeds} watchdog messages");
    assert_eq!(msgs.last().map(|s| s.as_str()), Some("STOPPING=1"));
}

#[test]
fn records_a_run_that_replays_through_the_pipeline_to_the_same_objects() {
    use opennav::perception::pipeline::lift_detections;
    use opennav::record::{object_record, read_all, Recorded};
    let dir = tempfile::tempdir().expect("tmp");
    let file = dir.path().join("run.mcap");
    let out = opennav()
        .args([
            "--prompt",
            "chair",
            "--exit-on-arrival",
            "--max-duration",
            "120s",
            "--no-stdin",
        ])
        .arg("--record")
        .arg(&file)
        .output()
        .expect("runs");
    assert!(out.status.success());
    let r = report(&out.stdout);
    assert_eq!(r["outcome"], "arrived", "{r}");
    assert_eq!(r["record"]["dropped"], 0, "{r}");
    assert_eq!(r["record"]["error"], Value::Null, "{r}");
    let all = read_all(&file).expect("reads");
    let ticks = all
        .iter()
        .filter(|m| matches!(m, Recorded::Ticks(_)))
        .count();
    let scans = all
        .iter()
        .filter(|m| matches!(m, Recorded::Scan { .. }))
        .count();
    assert!(ticks > 200 && scans > 40, "{ticks} ticks, {scans} scans");
    // the recorded views through the geometry again: the same objects
    let settings = opennav::config::Settings::load(None).expect("defaults");
    let base_from_camera = settings
        .camera
        .base_from_camera
        .to_isometry("camera.base_from_camera")
        .expect("valid");
    let k = opennav::sim::replica::camera(2).intrinsics();
    let mut seg =
        opennav::perception::segmenter::DepthBoxSegmenter::new(settings.depth_segmenter_settings());
    let mut frames = Vec::new();
    let mut dets = Vec::new();
    let mut objects = Vec::new();
    for m in all {
        match m {
            Recorded::Rgbd(f) => frames.push(f),
            Recorded::Detections(_, d) => dets.push(d),
            Recorded::Objects(_, o) => objects.push(o),
            _ => {}
        }
    }
    assert!(frames.len() >= 3, "{} views", frames.len());
    assert_eq!(frames.len(), objects.len());
    for ((f, d), o) in frames.iter().zip(dets).zip(&objects) {
        let again = lift_detections(
            &mut seg,
            &f.value.color,
            &f.value.depth,
            d,
            &k,
            &base_from_camera,
            opennav::msg::Frame::BaseLink,
            &settings.geometry_settings(),
        )
        .expect("replayed");
        let again: Vec<_> = again.objects.iter().map(object_record).collect();
        assert_eq!(&again, o);
    }
}
