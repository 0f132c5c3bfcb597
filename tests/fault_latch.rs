//! A latched fault survives a restart: a bus-off during a trip is written
//! to the state directory; the next start stays stopped and says why until
//! a person acknowledges it (`opennav ack-fault`); then the chair drives.

mod common;

use std::process::Command;
use std::time::Duration;

use opennav::actuation::can::BusError;
use opennav::config::Settings;
use opennav::daemon::latch;
use opennav::daemon::{RunOptions, RunReport};
use opennav::msg::{FaultReason, SupervisorState, UserInput};
use opennav::sim::devices::SimSummary;
use opennav::sim::world::SimWorld;

/// Looking for the cabinet (the chair turns after "yes") for 4 s of the
/// virtual clock; with `bus_off_at`, the bus goes off then.
async fn run(state: &std::path::Path, bus_off_at: Option<Duration>) -> (RunReport, SimSummary) {
    let settings = Settings::load(None).expect("defaults");
    let world = SimWorld::living_room(settings.drive_params());
    let words = vec![
        (Duration::ZERO, UserInput::Goto("cabinet".into())),
        // "yes" to the question about the rear (never seen at start-up)
        (Duration::from_millis(2500), UserInput::Yes),
    ];
    let opts = RunOptions {
        max_duration: Some(Duration::from_secs(4)),
        state_dir: Some(state.to_path_buf()),
        ..Default::default()
    };
    common::sim_run(&settings, world, words, opts, |_, sim| {
        if let Some(at) = bus_off_at {
            let bus = sim.bus.clone();
            tokio::spawn(async move {
                tokio::time::sleep(at).await;
                bus.inject_error(BusError::bus_off());
            });
        }
    })
    .await
}

#[tokio::test(start_paused = true)]
async fn a_bus_off_holds_across_a_restart_until_acknowledged() {
    let dir = tempfile::tempdir().expect("tmp");
    // the trip: the bus goes off after 2 s
    let (r, _) = run(dir.path(), Some(Duration::from_secs(2))).await;
    assert_eq!(
        r.supervisor,
        SupervisorState::Fault(FaultReason::CanBus),
        "{r:?}"
    );
    let held = latch::load(dir.path()).expect("written at once");
    assert_eq!(held.fault, FaultReason::CanBus);
    assert!(held.reason.contains("bus-off"), "{held:?}");
    // the restart: stopped from the start, and it says why
    let (r, s) = run(dir.path(), None).await;
    assert_eq!(
        r.supervisor,
        SupervisorState::Fault(FaultReason::CanBus),
        "{r:?}"
    );
    assert!(
        r.said
            .iter()
            .any(|l| l.starts_with("A fault from before the restart holds")),
        "{:?}",
        r.said
    );
    // the chair never moved: where it started, facing as it started
    let start = SimWorld::living_room(Settings::load(None).expect("defaults").drive_params()).start;
    assert!(s.world.distance_travelled_m < 1e-3, "{s:?}");
    assert!(
        (s.world.truth.theta_rad - start.theta_rad).abs() < 1e-3,
        "it turned: {s:?}"
    );
    // a person acknowledges it: the next start drives
    let cleared = latch::acknowledge(dir.path())
        .expect("ack")
        .expect("was latched");
    assert_eq!(cleared.fault, FaultReason::CanBus);
    let (r, s) = run(dir.path(), None).await;
    assert!(!matches!(r.supervisor, SupervisorState::Fault(_)), "{r:?}");
    // it turned to look (or drove)
    assert!(
        (s.world.truth.theta_rad - start.theta_rad).abs() > 0.1
            || s.world.distance_travelled_m > 0.0,
        "{s:?}"
    );
}

#[test]
fn ack_fault_clears_the_record_and_says_what_it_was() {
    let dir = tempfile::tempdir().expect("tmp");
    let ack = || {
        Command::new(env!("CARGO_BIN_EXE_opennav"))
            .arg("ack-fault")
            .env("OPENNAV_RUNTIME__STATE_DIR", dir.path())
            // no daemon listens there
            .env(
                "OPENNAV_INPUT__CONTROL_SOCKET",
                dir.path().join("control.sock"),
            )
            .output()
            .expect("runs")
    };
    latch::store(
        dir.path(),
        &latch::LatchedFault {
            fault: FaultReason::MotorLink,
            reason: "Rebus /dev/opennav_rebus: 5 packets in a row unanswered".into(),
            since_unix_s: 1_700_000_000,
        },
    )
    .expect("stored");
    let out = ack();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
    assert_eq!(v["acknowledged"]["fault"], "MotorLink", "{v}");
    assert_eq!(latch::load(dir.path()), None);
    let v: serde_json::Value = serde_json::from_slice(&ack().stdout).expect("json");
    assert_eq!(
        v["acknowledged"],
        serde_json::Value::Null,
        "nothing latched: {v}"
    );
}
