//! The Rebus backend (real serial I/O through `serialport`) against the
//! emulated chipset on a pty: start-up, exact velocity packets at 100 Hz,
//! NACKs and withheld ACKs, garbage on the line, the chipset's own DATA,
//! the link going down (a fault) and coming back, and shutdown. Timing
//! rules themselves (50 ms ACK timeout, 100 ms freshness) are tested on a
//! controlled clock in `rebus_link`'s unit tests; these check outcomes.

use std::sync::Arc;
use std::time::{Duration, Instant};

use opennav::actuation::rebus_link::{RebusActuator, RebusSettings};
use opennav::actuation::rnet::JoystickMapping;
use opennav::actuation::{
    spawn_actuator_thread, ActuatorError, ActuatorEvent, ActuatorIo, ActuatorStatus,
};
use opennav::msg::FaultReason;
use opennav::msg::{Clock, TokioClock};
use opennav::msg::{SafeCmd, SupervisorState, VelocityCmd};
use opennav::sim::rebus::{ChipsetFault, RebusChipset};
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

const MAPPING: JoystickMapping = JoystickMapping {
    forward_full_mps: 1.0,
    reverse_full_mps: 0.5,
    turn_full_radps: 1.5,
    deadband: 3,
};
/// v 0.2 m/s, ω −0.3 rad/s (right) → vy 20, vx 20.
const CMD: VelocityCmd = VelocityCmd {
    v_mps: 0.2,
    omega_radps: -0.3,
};
const CMD_XY: (i8, i8) = (20, 20);

struct Rig {
    _dir: tempfile::TempDir,
    chip: RebusChipset,
    events: mpsc::Receiver<ActuatorEvent>,
    status: watch::Receiver<ActuatorStatus>,
    cancel: CancellationToken,
    publisher: CancellationToken,
    writer: std::thread::JoinHandle<Result<ActuatorStatus, ActuatorError>>,
}

fn rig() -> Rig {
    let dir = tempfile::tempdir().expect("tempdir");
    let link = dir.path().join("rebus");
    let chip = RebusChipset::spawn(&link).expect("pty");
    let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
    let (cmd_tx, cmd_rx) = watch::channel(None);
    let (ev_tx, events) = mpsc::channel(64);
    let (status_tx, status) = watch::channel(ActuatorStatus::default());
    let cancel = CancellationToken::new();
    let publisher = CancellationToken::new();
    // the supervisor's output, refreshed every 20 ms
    let (p, c) = (publisher.clone(), clock.clone());
    tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_millis(20));
        loop {
            tokio::select! {
                _ = p.cancelled() => return,
                _ = tick.tick() => {
                    cmd_tx.send_replace(Some(SafeCmd {
                        cmd: CMD,
                        state: SupervisorState::Navigating,
                        stamp: c.now(),
                        view: None,
                    }));
                }
            }
        }
    });
    let port = link.to_string_lossy().to_string();
    let writer = spawn_actuator_thread(
        "rebus",
        0,
        move || {
            Ok(RebusActuator {
                port,
                settings: RebusSettings::new(MAPPING),
            })
        },
        ActuatorIo {
            commands: cmd_rx,
            events: ev_tx,
            status: status_tx,
            cancel: cancel.clone(),
            clock,
        },
    )
    .expect("thread");
    Rig {
        _dir: dir,
        chip,
        events,
        status,
        cancel,
        publisher,
        writer,
    }
}

impl Rig {
    fn drain_events(&mut self) -> Vec<ActuatorEvent> {
        let mut v = Vec::new();
        while let Ok(e) = self.events.try_recv() {
            v.push(e);
        }
        v
    }

    async fn stop(self) -> (RebusChipset, ActuatorStatus) {
        self.cancel.cancel();
        let w = self.writer;
        let st = tokio::task::spawn_blocking(move || w.join())
            .await
            .expect("join")
            .expect("no panic")
            .expect("clean release");
        self.publisher.cancel();
        (self.chip, st)
    }
}

async fn sleep_ms(ms: u64) {
    tokio::time::sleep(Duration::from_millis(ms)).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn starts_up_drives_exact_values_and_releases_centred() {
    let mut r = rig();
    sleep_ms(600).await;
    assert_eq!(
        r.drain_events(),
        vec![
            ActuatorEvent::Ready { joystick_id: None },
            ActuatorEvent::Active
        ]
    );
    let log = r.chip.log();
    assert_eq!(log.startups, 1);
    let v = &log.velocity;
    assert!(v.len() >= 30, "{} velocity packets in 0.6 s", v.len());
    assert_eq!((v[0].vx, v[0].vy), (0, 0), "first packet centred");
    assert!(v[1..].iter().all(|p| (p.vx, p.vy) == CMD_XY), "{v:?}");
    assert!(v.iter().all(|p| p.acked));
    // sequence numbers count up modulo 32
    for w in v.windows(2) {
        assert_eq!(w[1].seq, (w[0].seq + 1) & 0x1F);
    }
    let stop_at = Instant::now();
    let (chip, st) = r.stop().await;
    assert_eq!(st.state, "released");
    assert_eq!(st.dropped, 0);
    sleep_ms(100).await;
    let after: Vec<_> = chip
        .log()
        .velocity
        .into_iter()
        .filter(|p| p.at > stop_at + Duration::from_millis(15))
        .collect();
    assert!(
        after.len() >= 10,
        "{} centred packets on release",
        after.len()
    );
    assert!(after.iter().all(|p| (p.vx, p.vy) == (0, 0)), "{after:?}");
    let last = after.last().expect("packets").at - stop_at;
    assert!(last < Duration::from_millis(260), "packets until {last:?}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn nacks_withheld_acks_garbage_and_chipset_data_are_survived() {
    let mut r = rig();
    sleep_ms(300).await;
    r.chip.inject(ChipsetFault::Nack(2));
    sleep_ms(100).await;
    r.chip.inject(ChipsetFault::WithholdAcks(2));
    sleep_ms(300).await;
    r.chip.inject(ChipsetFault::Garbage(vec![
        0x55, 0x13, 0x00, 0xFF, 0x00, 0x55,
    ]));
    r.chip.inject(ChipsetFault::SendData(vec![0x22, 0x01]));
    sleep_ms(300).await;
    let events = r.drain_events();
    assert_eq!(
        events,
        vec![
            ActuatorEvent::Ready { joystick_id: None },
            ActuatorEvent::Active
        ],
        "fewer than 5 failures in a row keep the link up"
    );
    let st = r.status.borrow().clone();
    assert!(st.dropped >= 4, "2 NACKs + 2 timeouts: {st:?}");
    assert!(st.bus_errors >= 1, "garbage counted: {st:?}");
    assert_eq!(st.state, "up");
    let log = r.chip.log();
    assert_eq!(
        log.host_acks, 2,
        "the host ACKs the start-up handshake and the chipset's DATA"
    );
    assert_eq!(log.before_handshake, 0);
    let n = log.velocity.len();
    // 10 more packets (100 ms of the writer's period; a loaded machine
    // may take longer, so up to 3 s)
    let mut log = r.chip.log();
    for _ in 0..60 {
        if log.velocity.len() > n + 10 {
            break;
        }
        sleep_ms(50).await;
        log = r.chip.log();
    }
    assert!(
        log.velocity.len() > n + 10,
        "packets keep flowing after the garbage: {} after {n}",
        log.velocity.len()
    );
    assert!(log.velocity[n..].iter().all(|p| (p.vx, p.vy) == CMD_XY));
    r.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn five_unanswered_packets_are_a_fault_then_the_link_restarts() {
    let mut r = rig();
    sleep_ms(300).await;
    r.chip.inject(ChipsetFault::WithholdAcks(5));
    sleep_ms(900).await;
    let events = r.drain_events();
    // up, driving; the fault; up and driving again
    assert_eq!(events.len(), 5, "{events:?}");
    assert!(
        matches!(&events[2], ActuatorEvent::Fault { kind: FaultReason::MotorLink, reason } if reason.contains("5 packets in a row")),
        "{events:?}"
    );
    assert_eq!(events[3], ActuatorEvent::Ready { joystick_id: None });
    assert_eq!(events[4], ActuatorEvent::Active);
    let log = r.chip.log();
    assert_eq!(log.startups, 2, "start-up retried");
    // after the restart: centred first, then the command again
    let last = log.velocity.last().expect("packets");
    assert_eq!((last.vx, last.vy), CMD_XY);
    r.stop().await;
}

#[tokio::test]
async fn a_missing_port_is_an_error_naming_it() {
    let (_c, cmd_rx) = watch::channel(None);
    let (ev_tx, _ev) = mpsc::channel(4);
    let (st_tx, _st) = watch::channel(ActuatorStatus::default());
    let err = spawn_actuator_thread(
        "rebus",
        0,
        || {
            Ok(RebusActuator {
                port: "/dev/opennav-no-such-rebus".into(),
                settings: RebusSettings::new(MAPPING),
            })
        },
        ActuatorIo {
            commands: cmd_rx,
            events: ev_tx,
            status: st_tx,
            cancel: CancellationToken::new(),
            clock: Arc::new(TokioClock::new()),
        },
    )
    .expect("thread")
    .join()
    .expect("no panic")
    .expect_err("no such port");
    assert!(
        err.to_string().contains("/dev/opennav-no-such-rebus"),
        "{err}"
    );
}
