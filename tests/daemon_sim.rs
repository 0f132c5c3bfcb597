//! The daemon on the simulator: the same `daemon::run` as on the chair,
//! with the simulator's devices behind the device traits, on the virtual
//! clock (tokio's paused clock: deterministic, as fast as the computation
//! allows). The chair finds the prompted object and drives there through
//! the real R-Net writer without touching anything; the stop word and a
//! failing task bring it to rest; two runs of one trip are identical; a
//! real-time run reaches the same outcome.

mod common;

use std::process::{Command, Stdio};
use std::time::Duration;

use opennav::config::Settings;
use opennav::daemon::{Devices, Outcome, RunOptions, RunReport};
use opennav::msg::UserInput;
use opennav::sim::devices::{SimHandle, SimSummary};
use opennav::sim::world::SimWorld;
use serde_json::Value;

fn opennav() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_opennav"));
    c.args(["run", "--sim"]);
    c
}

use common::report;

/// Runs `c` to its end, which must be success, and parses its report.
fn report_of(c: &mut Command) -> Value {
    let out = c.output().expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    report(&out.stdout)
}

/// One simulated trip in the living room (`common::sim_run`).
async fn trip(
    words: Vec<(Duration, UserInput)>,
    opts: RunOptions,
    adapt: impl FnOnce(&mut Devices, &SimHandle),
) -> (RunReport, SimSummary) {
    let settings = Settings::load(None).expect("defaults");
    let world = SimWorld::living_room(settings.drive_params());
    common::sim_run(&settings, world, words, opts, adapt).await
}

fn go(word: &str) -> Vec<(Duration, UserInput)> {
    vec![(Duration::ZERO, UserInput::Goto(word.into()))]
}

/// The word, then "yes" when the chair asks whether it is clear around it
/// (it has not seen its rear, nor the floor beside it, at start-up: a
/// turn on the spot needs them).
fn go_clear_behind(word: &str) -> Vec<(Duration, UserInput)> {
    vec![
        (Duration::ZERO, UserInput::Goto(word.into())),
        (Duration::from_millis(2500), UserInput::Yes),
    ]
}

/// The question before a turn on the spot (about behind the chair, or
/// all around it where the camera has not seen the floor beside it).
const TURN_QUESTION: &str = "Say yes to let me turn";

fn to_arrival() -> RunOptions {
    RunOptions {
        exit_on_arrival: true,
        max_duration: Some(Duration::from_secs(120)),
        ..Default::default()
    }
}

fn check_arrival(r: &RunReport, s: &SimSummary, word: &str) {
    assert_eq!(r.outcome, Outcome::Arrived, "{r:?}");
    assert!(
        r.said.contains(&format!("Arrived at the {word}.")),
        "{:?}",
        r.said
    );
    assert_eq!(s.world.collision_steps, 0, "{s:?}");
    assert!(s.world.min_clearance_m > 0.1, "{s:?}");
    // the chair's front 0.6 m from the object (base_link 0.55 m behind
    // the front), within the goal tolerance and the odometry's error
    let d = s.distance_to_goal_object_m.expect("distance");
    assert!((0.95..=1.45).contains(&d), "{d} m from the {word}");
    // the trip ends with the chair at rest (odometry ≤ 0.02 m/s), not as
    // the stop is decided
    assert!(s.world.v_mps.abs() <= 0.025, "still moving: {s:?}");
    assert!(r.estimation.scan_matches > 10, "{r:?}");
    // the IMU's yaw rate went into the heading
    assert!(r.estimation.gyro_fused > 100, "{r:?}");
    assert!(r.estimation.views_placed >= 3, "{r:?}");
    assert_eq!(r.actuator.state, "released");
    assert_eq!(r.actuator.dropped, 0);
}

#[tokio::test(start_paused = true)]
async fn finds_the_chair_and_drives_there() {
    let (r, s) = trip(go("chair"), to_arrival(), |_, _| {}).await;
    check_arrival(&r, &s, "chair");
}

#[tokio::test(start_paused = true)]
async fn finds_the_cabinet_after_turning_to_look_for_it() {
    let (r, s) = trip(go_clear_behind("cabinet"), to_arrival(), |_, _| {}).await;
    check_arrival(&r, &s, "cabinet");
    assert!(
        r.said.iter().any(|l| l.contains(TURN_QUESTION)),
        "{:?}",
        r.said
    );
    // it was out of view at the start: the chair turned to find it
    assert!(s.world.distance_travelled_m > 0.8, "{s:?}");
}

#[tokio::test(start_paused = true)]
async fn a_word_nothing_answers_ends_in_not_found_after_searching() {
    let (r, s) = trip(go_clear_behind("piano"), to_arrival(), |_, _| {}).await;
    assert_eq!(r.outcome, Outcome::NotFound, "{r:?}");
    assert!(
        r.said.iter().any(|l| l.contains("cannot find a piano")),
        "{:?}",
        r.said
    );
    assert_eq!(s.world.collision_steps, 0);
    // a full turn on the spot (~21 s at 0.3 rad/s, after the question),
    // then on to any place it has not seen that it can turn in (the living
    // room has none), within the search's time limit
    let limit = opennav::config::Settings::defaults().goal.search_at_most_s;
    assert!(
        (18.0..limit + 2.0).contains(&r.duration_s),
        "{}",
        r.duration_s
    );
}

#[tokio::test(start_paused = true)]
async fn a_turn_on_the_spot_waits_until_someone_says_it_is_clear_behind() {
    // nobody answers: asked once, and the chair does not turn
    let opts = RunOptions {
        max_duration: Some(Duration::from_secs(10)),
        ..to_arrival()
    };
    let (r, s) = trip(go("cabinet"), opts.clone(), |_, _| {}).await;
    assert_eq!(r.outcome, Outcome::Timeout, "{r:?}");
    let asked = r.said.iter().filter(|l| l.contains(TURN_QUESTION)).count();
    assert_eq!(asked, 1, "{:?}", r.said);
    assert_eq!(
        serde_json::to_value(r.supervisor).expect("json"),
        serde_json::json!({"Stopped": "RearUnseen"}),
        "{r:?}"
    );
    let turned = (s.world.truth.theta_rad
        - SimWorld::living_room(Settings::defaults().drive_params())
            .start
            .theta_rad)
        .abs();
    assert!(turned < 0.05, "turned {turned} rad without a seen rear");
    assert!(s.world.distance_travelled_m < 0.02, "{s:?}");
    // "no": the chair says it will not turn here, does not ask again
    // here, and never turns on the spot where it was asked
    let words = vec![
        (Duration::ZERO, UserInput::Goto("cabinet".into())),
        (Duration::from_millis(2500), UserInput::No),
    ];
    let (r, s) = trip(words, opts, |_, _| {}).await;
    assert!(
        r.said
            .iter()
            .any(|l| l.starts_with("I will not turn here.")),
        "{:?}",
        r.said
    );
    let asked = r.said.iter().filter(|l| l.contains(TURN_QUESTION)).count();
    assert_eq!(asked, 1, "{:?}", r.said);
    assert_eq!(s.world.collision_steps, 0, "{s:?}");
    // (base_link stays put on the spot: any turn came with driving on)
    let start = SimWorld::living_room(Settings::defaults().drive_params()).start;
    let w = &s.world;
    let turned = (w.truth.theta_rad - start.theta_rad).abs();
    assert!(
        turned < 0.05 || w.distance_travelled_m > 0.05,
        "turned {turned} rad on the spot: {s:?}"
    );
}

#[tokio::test(start_paused = true)]
async fn the_stop_word_brings_the_chair_to_rest() {
    let words = vec![
        (Duration::ZERO, UserInput::Goto("cabinet".into())),
        (Duration::from_millis(2500), UserInput::Yes),
        // moving (searching, then driving) for a while
        (Duration::from_secs(4), UserInput::Stop),
        (Duration::from_millis(1500), UserInput::Quit),
    ];
    let (r, s) = trip(words, RunOptions::default(), |_, _| {}).await;
    assert_eq!(r.outcome, Outcome::Quit);
    assert_eq!(
        serde_json::to_value(r.supervisor).expect("json"),
        serde_json::json!({"Stopped": "UserStop"}),
        "{r:?}"
    );
    assert!(r.said.contains(&"Stopped.".to_string()), "{:?}", r.said);
    assert!(s.world.v_mps.abs() < 0.01, "{s:?}");
    assert!(s.world.omega_radps.abs() < 0.01, "{s:?}");
}

#[tokio::test(start_paused = true)]
async fn two_runs_of_one_trip_on_the_virtual_clock_are_identical() {
    let a = trip(go_clear_behind("cabinet"), to_arrival(), |_, _| {}).await;
    let b = trip(go_clear_behind("cabinet"), to_arrival(), |_, _| {}).await;
    // all but what the host measures: the steps' and the views' durations,
    // the memory
    let json = |(r, s): &(RunReport, SimSummary)| {
        let mut r = r.clone();
        r.control.step = Default::default();
        r.view_time = Default::default();
        r.memory = None;
        serde_json::to_string(&serde_json::json!({"report": r, "sim": s})).expect("json")
    };
    assert_eq!(a.0.outcome, Outcome::Arrived);
    assert_eq!(json(&a), json(&b));
}

#[test]
fn the_cli_runs_the_trip_and_a_real_time_run_reaches_the_same_outcome() {
    let run = |clock: &str| {
        report_of(opennav().args([
            "--clock",
            clock,
            "--prompt",
            "chair",
            "--exit-on-arrival",
            "--max-duration",
            "60s",
            "--no-stdin",
        ]))
    };
    let v = run("virtual");
    let rt = run("realtime");
    for r in [&v, &rt] {
        assert_eq!(r["outcome"], "arrived", "{r}");
        assert_eq!(r["sim"]["world"]["collision_steps"], 0, "{r}");
        let d = r["sim"]["distance_to_goal_object_m"].as_f64().expect("d");
        assert!((0.95..=1.45).contains(&d), "{d}");
    }
    // same trip within the real-time run's scheduling noise
    let dv = v["sim"]["distance_to_goal_object_m"]
        .as_f64()
        .unwrap_or(0.0);
    let dr = rt["sim"]["distance_to_goal_object_m"]
        .as_f64()
        .unwrap_or(9.0);
    assert!((dv - dr).abs() < 0.1, "{dv} vs {dr}");
}

#[test]
fn without_sim_and_without_devices_it_exits_1_naming_them() {
    let dir = tempfile::tempdir().expect("tmp");
    let cfg = dir.path().join("c.toml");
    std::fs::write(
        &cfg,
        format!(
            "[lasers.left]\nport = \"{0}/l\"\n[lasers.right]\nport = \"{0}/r\"\n[encoders]\nport = \"{0}/e\"\n[actuation]\nbackend = \"rebus\"\n[actuation.rebus]\nport = \"{0}/m\"\n",
            dir.path().display()
        ),
    )
    .expect("config");
    let notify = dir.path().join("notify");
    let sock = std::os::unix::net::UnixDatagram::bind(&notify).expect("bind");
    sock.set_nonblocking(true).expect("nonblocking");
    let out = Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(["--config"])
        .arg(&cfg)
        .args(["run", "--no-stdin", "--no-camera"])
        .env("NOTIFY_SOCKET", &notify)
        .env(
            "OPENNAV_RUNTIME__LOCK_FILE",
            dir.path().join("opennav.lock"),
        )
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    for what in [
        "left laser",
        "right laser",
        "encoder board",
        "Rebus motor interface",
    ] {
        assert!(err.contains(what), "{err}");
    }
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    let mut buf = [0u8; 256];
    assert!(sock.recv(&mut buf).is_err(), "no notify message (no READY)");
}

#[test]
fn speech_that_cannot_be_spoken_is_an_error_naming_the_synthesiser() {
    let out = opennav()
        .args(["--speak", "--no-stdin", "--max-duration", "1s"])
        .env("OPENNAV_SPEECH__COMMAND", "/nonexistent/espeak-ng")
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("/nonexistent/espeak-ng") && err.contains("speech.enabled"),
        "{err}"
    );
}

#[test]
fn a_second_opennav_driving_the_chair_refuses_to_start() {
    let dir = tempfile::tempdir().expect("tmp");
    let lock = dir.path().join("opennav.lock");
    let _held = opennav::daemon::lock::InstanceLock::acquire(&lock).expect("lock");
    for args in [
        &["run", "--no-stdin", "--no-camera"][..],
        &[
            "check",
            "rnet",
            "--iface",
            "nonexistent0",
            "--drive",
            "0,10",
            "--for",
            "1s",
        ][..],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_opennav"))
            .args(args)
            .env("OPENNAV_RUNTIME__LOCK_FILE", &lock)
            .output()
            .expect("runs");
        assert_eq!(out.status.code(), Some(1), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("another opennav drives the chair"),
            "{args:?}: {err}"
        );
        assert!(
            err.contains(&format!("pid {}", std::process::id())),
            "{err}"
        );
        assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    }
    // the simulator drives no chair: it does not need the lock
    let out = opennav()
        .args(["--no-stdin", "--max-duration", "1s"])
        .env("OPENNAV_RUNTIME__LOCK_FILE", &lock)
        .output()
        .expect("runs");
    assert!(out.status.success());
}

#[test]
fn sigterm_stops_the_chair_and_releases_the_bus() {
    let child = opennav()
        .args(["--clock", "realtime", "--prompt", "cabinet", "--no-stdin"])
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
fn notifies_systemd_ready_after_first_readings_and_feeds_the_watchdog() {
    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("notify");
    let sock = std::os::unix::net::UnixDatagram::bind(&path).expect("bind");
    sock.set_read_timeout(Some(Duration::from_secs(20)))
        .expect("timeout");
    let child = opennav()
        .args(["--no-stdin", "--max-duration", "2s"])
        .env("NOTIFY_SOCKET", &path)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("runs");
    let mut msgs = Vec::new();
    let mut buf = [0u8; 512];
    while let Ok(n) = sock.recv(&mut buf) {
        let m = String::from_utf8_lossy(&buf[..n]).trim_end().to_string();
        let done = m == "STOPPING=1";
        msgs.push(m);
        if done {
            break;
        }
    }
    let out = child.wait_with_output().expect("exits");
    assert!(out.status.success());
    let ready = msgs
        .iter()
        .position(|m| m == "READY=1")
        .unwrap_or_else(|| panic!("no READY: {msgs:?}"));
    // before READY: what it waits for (the motors answer last: the writer
    // learns the joystick id from the chair's JSM)
    assert!(
        msgs[..ready].iter().any(
            |m| m.starts_with("STATUS=waiting for a first reading from:") && m.contains("motors")
        ),
        "{msgs:?}"
    );
    assert_eq!(msgs.iter().filter(|m| *m == "READY=1").count(), 1);
    // then what it does, for `systemctl status` (no word given: idle)
    assert!(
        msgs[ready..]
            .iter()
            .any(|m| m.starts_with("STATUS=idle, waiting for a word")),
        "{msgs:?}"
    );
    let feeds = msgs[ready..].iter().filter(|m| *m == "WATCHDOG=1").count();
    // 20 Hz for about 2 s
    assert!(feeds > 20, "{feeds} watchdog messages");
    assert_eq!(msgs.last().map(|s| s.as_str()), Some("STOPPING=1"));
}

/// A recording as Foxglove reads it (the `mcap` crate, not our reader):
/// every channel has a schema and every message decodes by it; the live
/// view's topics are there; the metadata names the version and the clock
/// offset; log times are wall-clock.
fn foxglove_recording_checks(file: &std::path::Path) {
    use foxglove::messages as fg;
    use foxglove::Decode;
    let bytes = std::fs::read(file).expect("read");
    let mut topics = std::collections::BTreeMap::<String, usize>::new();
    let mut first_log_time = None;
    for m in mcap::MessageStream::new(&bytes).expect("mcap") {
        let m = m.expect("message");
        let c = &m.channel;
        let schema = c
            .schema
            .as_ref()
            .unwrap_or_else(|| panic!("{}: no schema", c.topic));
        first_log_time.get_or_insert(m.log_time);
        let d = &m.data[..];
        let ok = match (c.message_encoding.as_str(), schema.name.as_str()) {
            ("json", _) => {
                assert_eq!(schema.encoding, "jsonschema", "{}", c.topic);
                serde_json::from_slice::<Value>(&schema.data).expect("schema JSON");
                serde_json::from_slice::<Value>(d).is_ok()
            }
            ("protobuf", "foxglove.LaserScan") => fg::LaserScan::decode(d).is_ok(),
            ("protobuf", "foxglove.RawImage") => fg::RawImage::decode(d).is_ok(),
            ("protobuf", "foxglove.ImageAnnotations") => fg::ImageAnnotations::decode(d).is_ok(),
            ("protobuf", "foxglove.SceneUpdate") => fg::SceneUpdate::decode(d).is_ok(),
            ("protobuf", "foxglove.FrameTransforms") => fg::FrameTransforms::decode(d).is_ok(),
            ("protobuf", "foxglove.PosesInFrame") => fg::PosesInFrame::decode(d).is_ok(),
            ("protobuf", "foxglove.PointCloud") => fg::PointCloud::decode(d).is_ok(),
            ("protobuf", "foxglove.Log") => fg::Log::decode(d).is_ok(),
            (e, n) => panic!("{}: {e} / {n}", c.topic),
        };
        assert!(
            ok,
            "{}: a message does not decode as {}",
            c.topic, schema.name
        );
        *topics.entry(c.topic.clone()).or_default() += 1;
    }
    for t in opennav::live::TOPICS.iter().chain(&[
        "/camera/calibration",
        "/odometry/ticks",
        "/laser/left/codes",
    ]) {
        assert!(topics.contains_key(*t), "no {t} in {:?}", topics.keys());
    }
    let t = first_log_time.expect("messages");
    assert!(
        t > 1_704_067_200_000_000_000,
        "log time {t}: not wall-clock"
    );
    let mut meta = None;
    for r in mcap::read::LinearReader::new(&bytes).expect("records") {
        if let mcap::records::Record::Metadata(m) = r.expect("record") {
            meta = Some(m);
        }
    }
    let meta = meta.expect("a metadata record");
    assert_eq!(meta.name, "opennav");
    assert!(meta.metadata["version"].contains("git"), "{meta:?}");
    let offset: u64 = meta.metadata["wall_minus_monotonic_ns"]
        .parse()
        .expect("offset");
    assert!(offset > 1_704_067_200_000_000_000 / 2, "{offset}");
    assert!(
        meta.metadata["config"].contains("built-in defaults"),
        "{meta:?}"
    );
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
    assert!(
        all.iter().any(|m| matches!(m, Recorded::Calibration(_))),
        "no calibration recorded"
    );
    foxglove_recording_checks(&file);
    // played back: every view gives the recorded objects again, and the
    // tracker (placed with the recorded pose) holds the chair
    let out = Command::new(env!("CARGO_BIN_EXE_opennav"))
        .arg("replay")
        .arg(&file)
        .output()
        .expect("replays");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<Value> = String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect();
    let (summary, views) = lines.split_last().expect("lines");
    assert!(views.len() >= 3, "{lines:?}");
    assert!(
        views.iter().all(|v| v["same_as_recorded"] == true),
        "{views:?}"
    );
    let tracks = summary["summary"]["tracks"].as_array().expect("tracks");
    assert!(tracks.iter().any(|t| t["label"] == "chair"), "{summary}");
    // the recorded views through the geometry again: the same objects
    let settings = Settings::load(None).expect("defaults");
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
            // the chair's base_link stands on the floor
            Some(opennav::perception::segmenter::FloorInImage::new(
                &k,
                &base_from_camera,
                0.0,
            )),
        )
        .expect("replayed");
        let again: Vec<_> = again.objects.iter().map(object_record).collect();
        assert_eq!(&again, o);
    }
}

/// `[sim] detector = "model"`: the configured detector (YOLO11n, from the
/// shared folder) and segmenter on the rendered frames, as on the chair;
/// the run report has the control steps' timing and the daemon's memory,
/// which holds the model (more than the ground-truth run, which loads no
/// model at all).
#[test]
fn the_simulator_runs_the_configured_model_and_reports_timing_and_memory() {
    let dir = tempfile::tempdir().expect("tempdir");
    let config = dir.path().join("model.toml");
    std::fs::write(
        &config,
        format!(
            "[sim]\ndetector = \"model\"\n[perception]\ndetector = {:?}\nsegmenter = \"depth\"\n",
            common::yolo11n().display().to_string()
        ),
    )
    .expect("config");
    let run = |extra: &[&std::ffi::OsStr]| {
        report_of(
            opennav()
                .args(["--prompt", "chair", "--no-stdin", "--max-duration", "3s"])
                .args(extra),
        )
    };
    let model = run(&["--config".as_ref(), config.as_os_str()]);
    let truth = run(&[]);
    let views = model["estimation"]["views_placed"].as_u64().expect("views");
    assert!(views >= 10, "{views} views in 3 s at 30 Hz: {model}");
    // the 20 Hz steps on the virtual clock: 50 ms apart, to the histogram's bin
    let period = &model["control"]["period"];
    assert!(period["count"].as_u64().expect("count") >= 50, "{period}");
    let p50 = period["p50_us"].as_f64().expect("p50");
    assert!((49_990.0..=50_010.0).contains(&p50), "{period}");
    assert!(model["control"]["step"]["max_us"].as_f64().expect("step") > 0.0);
    // frame-to-command through the whole daemon: the simulator's 100 ms
    // stand-in for the compute time, then at most one world step (the
    // frame's stamp) and one R-Net period (the JSM's next frame)
    let f2c = &truth["actuator"]["frame_to_command"];
    let views = truth["estimation"]["views_placed"].as_u64().expect("views");
    assert!(views >= 3, "{truth}");
    assert!(f2c["count"].as_u64().expect("count") + 1 >= views, "{f2c}");
    for q in ["p01_us", "p50_us", "max_us"] {
        let us = f2c[q].as_f64().expect("latency");
        assert!((100_000.0..=120_100.0).contains(&us), "{q}: {f2c}");
    }
    assert!(model["view_time"]["count"].as_u64().expect("views") >= 10);
    assert!(model["view_time"]["p50_us"].as_f64().expect("view time") > 0.0);
    let peak = |r: &Value| r["memory"]["peak_rss_mb"].as_f64().expect("peak memory");
    assert!(
        peak(&model) > peak(&truth) + 20.0,
        "model {} MB, ground truth {} MB",
        peak(&model),
        peak(&truth)
    );
}
