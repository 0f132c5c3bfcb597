//! The R-Net writer against the simulated chair (JSM + power module) on the
//! in-memory CAN bus, on tokio's paused clock: takeover in both modes,
//! exact frame values and period, the 100 ms command freshness rule, the
//! user taking over, shutdown, bus faults and a full TX queue. The same
//! scenarios run on real SocketCAN in the VM (`tests/vcan_hil.rs`).

use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use opennav::actuation::can::{BusError, CanBus, MemoryBus};
use opennav::actuation::rnet::{JoystickMapping, TakeoverMode};
use opennav::actuation::writer::{RnetActuator, RnetSettings};
use opennav::actuation::{Actuator, ActuatorEvent, ActuatorIo, ActuatorStatus};
use opennav::msg::{Clock, Stamp, TokioClock};
use opennav::msg::{FaultReason, StopReason, SupervisorState, VelocityCmd};
use opennav::safety::{SafetyLimits, Supervisor};
use opennav::sim::rnet::{
    run_control_stand_in, run_sim_chair, ControlStandIn, DriveFrame, SimChair, SimChairSettings,
};
use tokio::sync::{mpsc, watch};
use tokio::task::JoinHandle;
use tokio_util::sync::CancellationToken;

const JSM_ID: u32 = 0x0200_0200;
const MAPPING: JoystickMapping = JoystickMapping {
    forward_full_mps: 0.5,
    reverse_full_mps: 0.25,
    turn_full_radps: 1.0,
    deadband: 3,
};
/// v 0.2 m/s, ω 0.3 rad/s (left) → Y 40, X −30.
const CMD: VelocityCmd = VelocityCmd {
    v_mps: 0.2,
    omega_radps: 0.3,
};
const CMD_XY: (i8, i8) = (-30, 40);

struct Rig {
    bus: MemoryBus,
    chair: Arc<Mutex<SimChair>>,
    planner: watch::Sender<Option<VelocityCmd>>,
    seen: Arc<Mutex<Vec<(Stamp, ActuatorEvent)>>>,
    status: watch::Receiver<ActuatorStatus>,
    clock: Arc<dyn Clock>,
    writer_cancel: CancellationToken,
    writer: JoinHandle<Result<ActuatorStatus, opennav::actuation::ActuatorError>>,
    control: JoinHandle<Supervisor>,
    control_cancel: CancellationToken,
    queue_full: Arc<std::sync::atomic::AtomicBool>,
}

fn limits() -> SafetyLimits {
    // acceleration limits high enough that the output equals the planner's
    // command at once (the values are what these tests check)
    SafetyLimits {
        a_linear_max_mps2: 100.0,
        a_angular_max_radps2: 100.0,
        // no camera in this harness
        camera_max_age: None,
        ..opennav::config::Settings::defaults().safety_limits()
    }
}

/// The speed setting the rig's writer pins.
const MAX_SPEED_PERCENT: u8 = 40;

fn rig(mode: TakeoverMode) -> Rig {
    let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
    let bus = MemoryBus::new();
    let chair = Arc::new(Mutex::new(SimChair::new(
        SimChairSettings {
            joystick_id: JSM_ID,
            ..Default::default()
        },
        clock.now(),
    )));
    let chair_cancel = CancellationToken::new();
    tokio::spawn(run_sim_chair(
        bus.endpoint(),
        chair.clone(),
        clock.clone(),
        chair_cancel,
    ));
    let (planner, planner_rx) = watch::channel(Some(CMD));
    let (cmd_tx, cmd_rx) = watch::channel(None);
    let (ev_tx, ev_rx) = mpsc::channel(64);
    let (status_tx, status) = watch::channel(ActuatorStatus::default());
    let seen = Arc::new(Mutex::new(Vec::new()));
    let control_cancel = CancellationToken::new();
    let control = tokio::spawn(run_control_stand_in(ControlStandIn {
        supervisor: Supervisor::new(limits()),
        planner: planner_rx,
        commands: cmd_tx,
        events: ev_rx,
        seen: seen.clone(),
        clock: clock.clone(),
        period: Duration::from_millis(50),
        cancel: control_cancel.clone(),
    }));
    let endpoint = bus.endpoint();
    let queue_full = endpoint.queue_full_switch();
    let writer_cancel = CancellationToken::new();
    let writer = tokio::spawn(
        RnetActuator {
            bus: endpoint,
            settings: RnetSettings {
                // tokio's timer: these tests run on its paused clock
                precise_timer: false,
                max_speed_percent: Some(MAX_SPEED_PERCENT),
                ..RnetSettings::new(mode, MAPPING)
            },
        }
        .run(ActuatorIo {
            commands: cmd_rx,
            events: ev_tx,
            status: status_tx,
            cancel: writer_cancel.clone(),
            clock: clock.clone(),
        }),
    );
    Rig {
        bus,
        chair,
        planner,
        seen,
        status,
        clock,
        writer_cancel,
        writer,
        control,
        control_cancel,
        queue_full,
    }
}

impl Rig {
    /// Frames from the writer (not the JSM) as the power module saw them.
    fn ours(&self) -> Vec<DriveFrame> {
        self.chair
            .lock()
            .expect("chair")
            .drive_log
            .iter()
            .filter(|d| !d.from_jsm)
            .copied()
            .collect()
    }

    fn events(&self) -> Vec<ActuatorEvent> {
        self.seen
            .lock()
            .expect("events")
            .iter()
            .map(|(_, e)| e.clone())
            .collect()
    }

    fn now(&self) -> Stamp {
        self.clock.now()
    }
}

/// Stops the control loop and the writer; their supervisor's final state.
async fn finish(r: Rig) -> SupervisorState {
    r.control_cancel.cancel();
    let sup = r.control.await.expect("control loop");
    r.writer_cancel.cancel();
    let _ = r.writer.await;
    sup.state()
}

async fn sleep_ms(ms: u64) {
    tokio::time::sleep(Duration::from_millis(ms)).await;
}

fn after(frames: &[DriveFrame], t: Stamp) -> Vec<DriveFrame> {
    frames.iter().filter(|d| d.at > t).copied().collect()
}

#[tokio::test(start_paused = true)]
async fn jsmerror_takes_over_with_exact_values_every_10_ms() {
    let r = rig(TakeoverMode::JsmError);
    sleep_ms(1000).await;
    let ev = r.events();
    assert_eq!(
        ev.first(),
        Some(&ActuatorEvent::Ready {
            joystick_id: Some(JSM_ID)
        }),
        "learned the JSM's id by listening: {ev:?}"
    );
    assert!(ev.contains(&ActuatorEvent::Active));
    {
        let c = r.chair.lock().expect("chair");
        assert_eq!(c.silence_frames, 3);
        assert!(c.jsm_silenced);
        assert_eq!(c.motor_output(r.now()), Some(CMD_XY));
    }
    let ours = r.ours();
    assert!(ours.len() > 90, "{} frames in 1 s", ours.len());
    assert_eq!((ours[0].x, ours[0].y), (0, 0), "starts from centred");
    // centred until the supervisor's first non-zero output (its second
    // step, 50 ms in), then exactly the command
    let k = ours
        .iter()
        .position(|d| (d.x, d.y) != (0, 0))
        .expect("commanded frames");
    assert!(
        ours[k].at <= Stamp(Duration::from_millis(60)),
        "{:?}",
        ours[k]
    );
    assert!(ours[k..].iter().all(|d| (d.x, d.y) == CMD_XY), "{ours:?}");
    for w in ours.windows(2) {
        assert_eq!(w[1].at.0 - w[0].at.0, Duration::from_millis(10));
    }
    // no JSM joystick frame once silenced
    let jsm_after = r
        .chair
        .lock()
        .expect("chair")
        .drive_log
        .iter()
        .filter(|d| d.from_jsm && d.at > ours[0].at)
        .count();
    assert_eq!(jsm_after, 0);
    let st = r.status.borrow().clone();
    assert_eq!(st.joystick_id, Some(JSM_ID));
    assert_eq!(st.state, "active");
    assert_eq!(st.period.p50_us, 10_000.0);
    assert_eq!(st.dropped, 0);
}

#[tokio::test(start_paused = true)]
async fn a_stale_command_is_sent_as_centred() {
    let r = rig(TakeoverMode::JsmError);
    sleep_ms(500).await;
    // the control loop dies: its last command ages
    r.control.abort();
    let dead_at = r.now();
    sleep_ms(400).await;
    let late = after(&r.ours(), dead_at);
    // the last command was stamped at most one control period (50 ms) before
    let fresh_until = Stamp(dead_at.0 + Duration::from_millis(100));
    for d in &late {
        if d.at > fresh_until {
            assert_eq!((d.x, d.y), (0, 0), "stale command sent at {:?}", d.at);
        }
    }
    let centred = late.iter().filter(|d| (d.x, d.y) == (0, 0)).count();
    assert!(
        centred >= 25,
        "{centred} centred frames after the command went stale"
    );
    assert_eq!(
        r.chair.lock().expect("chair").motor_output(r.now()),
        Some((0, 0))
    );
}

#[tokio::test(start_paused = true)]
async fn planner_going_quiet_stops_the_chair_through_the_supervisor() {
    let r = rig(TakeoverMode::JsmError);
    sleep_ms(500).await;
    r.planner.send_replace(None);
    let quiet_at = r.now();
    sleep_ms(500).await;
    // the supervisor's 200 ms command limit, plus one control period
    let limit = Stamp(quiet_at.0 + Duration::from_millis(260));
    assert!(after(&r.ours(), limit).iter().all(|d| (d.x, d.y) == (0, 0)));
    assert!(!after(&r.ours(), limit).is_empty());
}

#[tokio::test(start_paused = true)]
async fn followjsm_answers_each_jsm_frame_and_yields_to_the_user() {
    let r = rig(TakeoverMode::FollowJsm);
    sleep_ms(500).await;
    let log = r.chair.lock().expect("chair").drive_log.clone();
    // after each JSM frame, ours at the same instant with the command
    let mut answered = 0;
    for (i, d) in log.iter().enumerate() {
        if d.from_jsm && d.at > Stamp(Duration::from_millis(100)) {
            let next = log.get(i + 1).expect("an answer follows");
            assert!(!next.from_jsm);
            assert_eq!(next.at, d.at);
            assert_eq!((next.x, next.y), CMD_XY);
            answered += 1;
        }
    }
    assert!(answered > 30);
    // the user pushes the real joystick
    r.chair.lock().expect("chair").user = (0, 50);
    let pushed = r.now();
    sleep_ms(300).await;
    let log = r.chair.lock().expect("chair").drive_log.clone();
    let first_deflected = log
        .iter()
        .find(|d| d.from_jsm && d.at >= pushed)
        .expect("JSM frame")
        .at;
    assert!(
        log.iter()
            .filter(|d| d.at >= first_deflected)
            .all(|d| d.from_jsm),
        "we sent after the user's first deflected frame"
    );
    assert!(r
        .events()
        .contains(&ActuatorEvent::UserDeflection { x: 0, y: 50 }));
    assert_eq!(r.status.borrow().state, "yielded");
    assert_eq!(
        finish(r).await,
        SupervisorState::Stopped(StopReason::UserTakeover)
    );
}

#[tokio::test(start_paused = true)]
async fn shutdown_sends_centred_for_200_ms_then_nothing() {
    let mut r = rig(TakeoverMode::JsmError);
    sleep_ms(500).await;
    r.writer_cancel.cancel();
    let cancel_at = r.now();
    let status = (&mut r.writer)
        .await
        .expect("joined")
        .expect("clean release");
    assert_eq!(status.state, "released");
    sleep_ms(500).await;
    let late = after(&r.ours(), cancel_at);
    assert!(late.iter().all(|d| (d.x, d.y) == (0, 0)), "{late:?}");
    let last = late.last().expect("centred frames").at;
    let held = last.0 - cancel_at.0;
    assert!(
        held >= Duration::from_millis(190) && held <= Duration::from_millis(210),
        "centred for {held:?}"
    );
    assert!(r.events().contains(&ActuatorEvent::Released));
    // the JSM stays silenced, our frames stopped: the power module stops
    assert_eq!(r.chair.lock().expect("chair").motor_output(r.now()), None);
}

#[tokio::test(start_paused = true)]
async fn bus_off_latches_a_fault_and_centres_at_once() {
    let r = rig(TakeoverMode::JsmError);
    sleep_ms(500).await;
    r.bus.inject_error(BusError::decode(0x040, &[]));
    let fault_at = r.now();
    sleep_ms(500).await;
    let late = after(&r.ours(), fault_at);
    assert!(late.len() > 40);
    assert!(late.iter().all(|d| (d.x, d.y) == (0, 0)), "{late:?}");
    assert!(r
        .events()
        .iter()
        .any(|e| matches!(e, ActuatorEvent::Fault { reason, .. } if reason == "bus-off")));
    assert_eq!(finish(r).await, SupervisorState::Fault(FaultReason::CanBus));
}

/// A second program on the chair's bus sends joystick frames `xy` on the
/// JSM's id every 10 ms (a forgotten can2RNET script, a second daemon).
async fn other_writer(bus: MemoryBus, xy: (i8, i8), until: Stamp, clock: Arc<dyn Clock>) {
    let other = bus.endpoint();
    let mut tick = tokio::time::interval(Duration::from_millis(10));
    while clock.now() < until {
        tick.tick().await;
        other
            .try_send(&opennav::actuation::rnet::joystick_frame(
                JSM_ID, xy.0, xy.1,
            ))
            .expect("send");
    }
}

#[tokio::test(start_paused = true)]
async fn another_writer_on_the_joystick_id_is_a_latched_fault_in_both_modes() {
    // FollowJSM: frames on top of the JSM's, deflected (they also look
    // like the user: the count outranks that). JSMerror: with the JSM
    // silenced any steady stream is another writer; a deflected one is
    // taken for the JSM woken up, i.e. the user (we yield and stop
    // driving: `followjsm_answers_each_jsm_frame_and_yields_to_the_user`),
    // so this one holds the chair centred.
    for (mode, xy) in [
        (TakeoverMode::FollowJsm, (0, 60)),
        (TakeoverMode::JsmError, (0, 0)),
    ] {
        let r = rig(mode);
        sleep_ms(500).await;
        assert_eq!(r.status.borrow().last_output, CMD_XY, "{mode:?} drives");
        let from = r.now();
        let until = Stamp(from.0 + Duration::from_millis(300));
        tokio::spawn(other_writer(r.bus.clone(), xy, until, r.clock.clone()));
        sleep_ms(500).await;
        let fault = r
            .events()
            .into_iter()
            .find_map(|e| match e {
                ActuatorEvent::Fault { kind, reason } => Some((kind, reason)),
                _ => None,
            })
            .unwrap_or_else(|| panic!("{mode:?}: no fault: {:?}", r.events()));
        assert_eq!(fault.0, FaultReason::OtherWriter, "{mode:?}");
        assert!(fault.1.contains("another program"), "{}", fault.1);
        // found within two windows (a reader's stall fills one, another
        // writer fills every one), and ours centred from then on
        let at = r
            .seen
            .lock()
            .expect("events")
            .iter()
            .find(|(_, e)| matches!(e, ActuatorEvent::Fault { .. }))
            .map(|(t, _)| *t)
            .expect("fault stamp");
        assert!(
            from.age_at(at) <= Duration::from_millis(210),
            "{mode:?}: found after {:?}",
            from.age_at(at)
        );
        // (the power module logs the other program's frames too; ours
        // after the fault are centred, theirs stop at `until`)
        let late: Vec<DriveFrame> = after(&r.ours(), until);
        assert!(late.len() > 10, "{mode:?}: {late:?}");
        assert!(
            late.iter().all(|d| (d.x, d.y) == (0, 0)),
            "{mode:?}: {late:?}"
        );
        assert_eq!(
            finish(r).await,
            SupervisorState::Fault(FaultReason::OtherWriter),
            "{mode:?}"
        );
    }
}

#[tokio::test(start_paused = true)]
async fn error_passive_is_a_fault_and_a_warning_is_not() {
    let r = rig(TakeoverMode::JsmError);
    sleep_ms(300).await;
    // a warning: counted, the chair keeps going
    r.bus.inject_error(BusError::decode(0x004, &[0, 0x08]));
    sleep_ms(200).await;
    assert_eq!(r.status.borrow().bus_errors, 1);
    assert_eq!(r.status.borrow().last_output, CMD_XY);
    r.bus.inject_error(BusError::error_passive());
    sleep_ms(200).await;
    let st = r.status.borrow().clone();
    assert_eq!(st.bus_errors, 2);
    assert_eq!(st.last_output, (0, 0));
    assert_eq!(finish(r).await, SupervisorState::Fault(FaultReason::CanBus));
}

#[tokio::test(start_paused = true)]
async fn a_full_tx_queue_drops_frames_and_never_sends_them_late() {
    let r = rig(TakeoverMode::JsmError);
    sleep_ms(500).await;
    r.queue_full.store(true, Ordering::SeqCst);
    let full_at = r.now();
    sleep_ms(50).await;
    r.queue_full.store(false, Ordering::SeqCst);
    let free_at = r.now();
    sleep_ms(200).await;
    let ours = r.ours();
    assert!(ours
        .iter()
        .all(|d| d.at <= full_at || d.at > Stamp(free_at.0 - Duration::from_millis(1))));
    // one frame per slot after the gap, none bunched up
    let resumed = after(&ours, full_at);
    for w in resumed.windows(2) {
        assert_eq!(w[1].at.0 - w[0].at.0, Duration::from_millis(10));
    }
    sleep_ms(100).await;
    let st = r.status.borrow().clone();
    assert_eq!(st.dropped, 5, "{st:?}");
}

#[tokio::test(start_paused = true)]
async fn check_listen_reports_ids_heartbeats_and_battery() {
    let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
    let bus = MemoryBus::new();
    let chair = Arc::new(Mutex::new(SimChair::new(
        SimChairSettings {
            joystick_id: JSM_ID,
            battery_percent: 64,
            ..Default::default()
        },
        clock.now(),
    )));
    chair.lock().expect("chair").user = (-3, 17);
    tokio::spawn(run_sim_chair(
        bus.endpoint(),
        chair,
        clock,
        CancellationToken::new(),
    ));
    let listener = bus.endpoint();
    let bus2 = bus.clone();
    tokio::spawn(async move {
        sleep_ms(500).await;
        bus2.inject_error(BusError::bus_off());
    });
    let r = opennav::actuation::check::listen(&listener, Duration::from_secs(2))
        .await
        .expect("listen");
    let j = r.joystick.get("02000200").expect("joystick id reported");
    assert!((j.rate_hz - 100.0).abs() <= 1.0, "{}", j.rate_hz);
    assert_eq!(j.last, (-3, 17));
    assert!(
        (r.jsm_heartbeat_hz - 10.0).abs() <= 0.5,
        "{}",
        r.jsm_heartbeat_hz
    );
    assert!((r.power_module_heartbeat_hz - 1.0).abs() <= 0.5);
    assert_eq!(r.battery_percent, Some(64));
    assert_eq!(r.error_frames, 1);
    assert_eq!(r.errors, vec!["bus-off".to_string()]);
}

/// `check rnet --drive` on the simulated chair (the writer on its own
/// thread, real time): a JSM that keeps talking after the silence request
/// makes a JSMerror takeover fail, and that is an error naming why; a JSM
/// that honours it is taken over.
#[tokio::test(start_paused = true)]
async fn check_drive_fails_when_the_takeover_does_not_happen() {
    for ignores_silence in [true, false] {
        let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
        let bus = MemoryBus::new();
        let chair = Arc::new(Mutex::new(SimChair::new(
            SimChairSettings {
                joystick_id: JSM_ID,
                ignores_silence,
                ..Default::default()
            },
            clock.now(),
        )));
        let stop_chair = CancellationToken::new();
        tokio::spawn(run_sim_chair(
            bus.endpoint(),
            chair.clone(),
            clock.clone(),
            stop_chair.clone(),
        ));
        let endpoint = bus.endpoint();
        // the writer as a task on the paused clock (on the chair: its own
        // real-time thread, `check::drive`)
        let start_writer = move |io| {
            let task = tokio::spawn(
                RnetActuator {
                    bus: endpoint,
                    settings: RnetSettings {
                        precise_timer: false,
                        ..RnetSettings::new(TakeoverMode::JsmError, MAPPING)
                    },
                }
                .run(io),
            );
            async move { task.await.expect("writer task") }
        };
        let r = opennav::actuation::check::drive_with(
            start_writer,
            TakeoverMode::JsmError,
            MAPPING,
            (0, 20),
            Duration::from_millis(600),
            clock,
            CancellationToken::new(),
        )
        .await;
        stop_chair.cancel();
        if ignores_silence {
            let e = r.expect_err("no takeover").to_string();
            assert!(e.contains("the takeover did not happen"), "{e}");
            assert!(e.contains("kept talking"), "{e}");
            // the JSM's own frames went on; ours never drove
            let c = chair.lock().expect("chair");
            assert!(c.silence_frames > 0);
            assert!(c.drive_log.iter().all(|d| d.from_jsm), "we drove");
        } else {
            let r = r.expect("taken over");
            assert!(r.events.contains(&ActuatorEvent::Active), "{:?}", r.events);
            let c = chair.lock().expect("chair");
            assert!(c.drive_log.iter().any(|d| !d.from_jsm && d.y == 20));
        }
    }
}

#[tokio::test(start_paused = true)]
async fn the_speed_setting_is_pinned_at_takeover_and_every_second_in_both_modes() {
    for mode in [TakeoverMode::FollowJsm, TakeoverMode::JsmError] {
        let r = rig(mode);
        sleep_ms(300).await;
        let first = r.chair.lock().expect("chair").max_speed_log.clone();
        assert_eq!(first, vec![MAX_SPEED_PERCENT], "{mode:?}: at takeover");
        sleep_ms(3000).await;
        let log = r.chair.lock().expect("chair").max_speed_log.clone();
        assert!((3..=5).contains(&log.len()), "{mode:?}: {log:?}");
        assert!(log.iter().all(|&p| p == MAX_SPEED_PERCENT));
        finish(r).await;
    }
}

/// `check drive` on its real writer thread: a bus that cannot be opened
/// ends it at once with the bus's own error, not a silent empty drive.
#[tokio::test]
async fn check_drive_names_the_bus_that_cannot_be_opened() {
    let r = opennav::actuation::check::drive(
        || -> Result<opennav::actuation::can::MemoryEndpoint, opennav::actuation::can::CanBusError> {
            Err(opennav::actuation::can::CanBusError::Open {
                iface: "can7".into(),
                source: std::io::Error::from(std::io::ErrorKind::NotFound),
            })
        },
        RnetSettings::new(TakeoverMode::JsmError, MAPPING),
        (0, 20),
        // never reached: the writer's end ends the drive
        Duration::from_secs(3600),
        CancellationToken::new(),
    )
    .await;
    let e = r.expect_err("no bus").to_string();
    assert!(e.contains("can7"), "{e}");
}
