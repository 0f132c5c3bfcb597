//! Fault injection: a task or thread of the daemon that dies stops the
//! chair (the control step outputs zero with a latched fault, the writer
//! centres and releases, or — when the writer itself dies — its frames
//! stop and the power module stops the motors), and the run ends in a
//! fault naming the task; the command line exits 1 with one line.

use std::process::Command;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

use opennav::actuation::can::{BusEvent, CanBus, CanBusError, MemoryEndpoint};
use opennav::actuation::rnet::{CanFrame, TakeoverMode};
use opennav::actuation::writer::RnetActuator;
use opennav::actuation::{spawn_actuator_thread, thread_result};
use opennav::config::Settings;
use opennav::daemon::{Outcome, RunOptions};
use opennav::msg::{Clock, TokioClock, UserInput};
use opennav::sim::world::SimWorld;
use serde_json::Value;
use tokio_util::sync::CancellationToken;

/// `opennav run --sim` looking for the cabinet (the chair turns, then
/// drives), with `task` made to panic after 3 s of the virtual clock.
fn run_with_panic_in(task: &str) -> (Option<i32>, Value, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(["run", "--sim", "--prompt", "cabinet", "--no-stdin"])
        .args(["--max-duration", "60s", "--inject-panic"])
        .arg(format!("{task}@3s"))
        .output()
        .expect("runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .rev()
        .find(|l| l.starts_with('{'))
        .unwrap_or_else(|| panic!("no report: {stdout}"));
    (
        out.status.code(),
        serde_json::from_str(line).expect("json"),
        String::from_utf8_lossy(&out.stderr).to_string(),
    )
}

fn check_stopped_naming(task: &str) {
    let (code, r, err) = run_with_panic_in(task);
    assert_eq!(code, Some(1), "{err}");
    assert_eq!(r["outcome"]["fault"]["task"], task, "{r}");
    assert!(
        r["outcome"]["fault"]["reason"]
            .as_str()
            .unwrap_or("")
            .contains("injected panic"),
        "{r}"
    );
    assert!(
        err.lines()
            .last()
            .unwrap_or("")
            .contains(&format!("the {task} task failed")),
        "{err}"
    );
    assert!(
        r["said"]
            .to_string()
            .contains(&format!("Internal fault in {task}. Stopped.")),
        "{r}"
    );
    // the fault is latched in the supervisor's state
    assert_eq!(r["supervisor"], serde_json::json!({"Fault": "Task"}), "{r}");
    // stopped at 3 s, not at the end of the trip
    let t = r["duration_s"].as_f64().unwrap_or(0.0);
    assert!((3.0..3.5).contains(&t), "{t}");
    // the writer centred the joystick, then released the bus
    assert_eq!(r["actuator"]["state"], "released", "{r}");
    assert_eq!(
        r["actuator"]["last_output"],
        serde_json::json!([0, 0]),
        "{r}"
    );
    // and the chair was coming to rest (motors lag ~0.15 s)
    let w = &r["sim"]["world"];
    assert!(w["v_mps"].as_f64().unwrap_or(1.0).abs() < 0.05, "{w}");
    assert!(w["omega_radps"].as_f64().unwrap_or(1.0).abs() < 0.1, "{w}");
}

#[test]
fn a_panic_in_perception_stops_the_chair_and_names_it() {
    check_stopped_naming("perception");
}

#[test]
fn a_panic_in_estimation_stops_the_chair_and_names_it() {
    check_stopped_naming("estimation");
}

#[test]
fn a_panic_in_a_laser_reader_stops_the_chair_and_names_it() {
    check_stopped_naming("laser-left");
}

#[test]
fn a_panic_in_the_control_task_stops_the_chair_and_names_it() {
    let (code, r, err) = run_with_panic_in("control");
    assert_eq!(code, Some(1), "{err}");
    assert_eq!(r["outcome"]["fault"]["task"], "control", "{r}");
    // no control step is left to say zero: the writer's freshness rule
    // centres the joystick, then it releases the bus
    assert_eq!(r["actuator"]["state"], "released", "{r}");
    assert_eq!(
        r["actuator"]["last_output"],
        serde_json::json!([0, 0]),
        "{r}"
    );
}

/// A CAN bus whose writer panics on its `n`th frame.
struct PanickingBus {
    inner: MemoryEndpoint,
    sent: AtomicUsize,
    panic_at: usize,
}

impl CanBus for PanickingBus {
    fn try_send(&self, frame: &CanFrame) -> Result<(), CanBusError> {
        if self.sent.fetch_add(1, Ordering::SeqCst) == self.panic_at {
            panic!("injected panic in the writer thread");
        }
        self.inner.try_send(frame)
    }

    fn recv(&self) -> impl std::future::Future<Output = Result<BusEvent, CanBusError>> + Send {
        self.inner.recv()
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_panic_in_the_writer_thread_stops_the_chair_and_names_it() {
    let settings = Settings::load(None).expect("defaults");
    let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
    let world = SimWorld::living_room(settings.drive_params());
    let (mut devices, sim) =
        opennav::sim::devices::devices(&settings, world, clock.clone()).expect("devices");
    // the chair's writer on its own OS thread, as on the chair; it dies
    // after 1.5 s of frames, while the chair turns to search
    let endpoint = sim.bus.endpoint();
    let mut rnet = settings.rnet_settings();
    rnet.mode = TakeoverMode::JsmError;
    rnet.precise_timer = false;
    devices.actuator = Box::new(move |io| {
        let h = spawn_actuator_thread(
            "rnet-writer",
            0,
            move || {
                Ok(RnetActuator {
                    bus: PanickingBus {
                        inner: endpoint,
                        sent: AtomicUsize::new(0),
                        panic_at: 150,
                    },
                    settings: rnet,
                })
            },
            io,
        )
        .map_err(|e| opennav::daemon::DeviceError::new("rnet-writer", e.to_string()))?;
        Ok(Box::pin(thread_result(h)))
    });
    let (tx, rx) = tokio::sync::mpsc::channel(4);
    tx.send(UserInput::Goto("cabinet".into()))
        .await
        .expect("word");
    let r = opennav::daemon::run(
        devices,
        &settings,
        RunOptions {
            max_duration: Some(Duration::from_secs(30)),
            ..Default::default()
        },
        rx,
        clock.clone(),
        CancellationToken::new(),
    )
    .await
    .expect("runs");
    drop(tx);
    match &r.outcome {
        Outcome::Fault { task, reason } => {
            assert_eq!(task, "actuator");
            assert!(
                reason.contains("injected panic in the writer thread"),
                "{reason}"
            );
        }
        other => panic!("{other:?}"),
    }
    assert!(
        r.said
            .iter()
            .any(|s| s == "Internal fault in actuator. Stopped."),
        "{:?}",
        r.said
    );
    // no frames since: the power module's motor timeout stopped the chair
    let now = clock.now();
    let motor = sim.chair.lock().expect("chair").motor_output(now);
    assert_eq!(motor, None, "the motors still get a joystick value");
    // with nothing driving them the motors run down within a second
    let mapping = settings.joystick_mapping();
    let mut w = sim.world.lock().expect("world");
    for _ in 0..100 {
        w.step(0.01, motor, &mapping);
    }
    assert!(w.omega_radps.abs() < 0.01, "{}", w.omega_radps);
    assert!(w.v_mps.abs() < 0.01, "{}", w.v_mps);
}
