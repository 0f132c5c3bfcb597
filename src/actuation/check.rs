//! `opennav check rnet`: what a maintainer runs at the chair. Listening
//! reports the joystick id, heartbeats, battery and frame rates seen;
//! driving sends joystick frames through the real writer for a bounded
//! time (wheels lifted), then centres and releases. SIGTERM or Ctrl-C
//! centre and release at once.

use std::collections::BTreeMap;
use std::future::Future;
use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

use super::can::{BusEvent, CanBus, CanBusError};
use super::rnet::{decode, JoystickMapping, RnetMessage, TakeoverMode};
use super::writer::{RnetActuator, RnetSettings};
use super::{
    spawn_actuator_thread, thread_result, ActuatorError, ActuatorEvent, ActuatorIo, ActuatorStatus,
};
use crate::msg::{Clock, TokioClock};
use crate::msg::{SafeCmd, SupervisorState, VelocityCmd};

#[derive(Debug, Clone, Default, Serialize)]
pub struct IdReport {
    pub frames: u64,
    pub rate_hz: f64,
    /// Last (turn, forward) seen.
    pub last: (i8, i8),
}

#[derive(Debug, Clone, Default, Serialize)]
pub struct ListenReport {
    pub seconds: f64,
    pub frames_total: u64,
    /// Joystick ids seen (`02000X00`), with their rates.
    pub joystick: BTreeMap<String, IdReport>,
    pub jsm_heartbeat_hz: f64,
    pub power_module_heartbeat_hz: f64,
    pub battery_percent: Option<u8>,
    pub motor_current_raw: Option<u16>,
    pub other_frames: u64,
    pub error_frames: u64,
    /// Each kind of bus error seen, described.
    pub errors: Vec<String>,
}

/// Listens on `bus` for `duration` (tokio time).
pub async fn listen<B: CanBus>(bus: &B, duration: Duration) -> Result<ListenReport, CanBusError> {
    let mut r = ListenReport {
        seconds: duration.as_secs_f64(),
        ..Default::default()
    };
    let (mut jsm_hb, mut pm_hb) = (0u64, 0u64);
    let end = tokio::time::sleep(duration);
    tokio::pin!(end);
    loop {
        tokio::select! {
            _ = &mut end => break,
            ev = bus.recv() => match ev? {
                BusEvent::Frame(f) => {
                    r.frames_total += 1;
                    match decode(&f) {
                        RnetMessage::Joystick { id, x, y } => {
                            let e = r.joystick.entry(format!("{id:08X}")).or_default();
                            e.frames += 1;
                            e.last = (x, y);
                        }
                        RnetMessage::JsmHeartbeat => jsm_hb += 1,
                        RnetMessage::PowerModuleHeartbeat { .. } => pm_hb += 1,
                        RnetMessage::Battery { percent, .. } => r.battery_percent = Some(percent),
                        RnetMessage::MotorCurrent { raw, .. } => r.motor_current_raw = Some(raw),
                        _ => r.other_frames += 1,
                    }
                }
                BusEvent::Error(e) => {
                    r.error_frames += 1;
                    let d = e.describe();
                    if !r.errors.contains(&d) {
                        r.errors.push(d);
                    }
                }
            }
        }
    }
    let secs = duration.as_secs_f64().max(1e-9);
    for e in r.joystick.values_mut() {
        e.rate_hz = e.frames as f64 / secs;
    }
    r.jsm_heartbeat_hz = jsm_hb as f64 / secs;
    r.power_module_heartbeat_hz = pm_hb as f64 / secs;
    Ok(r)
}

#[derive(Debug, Clone, Serialize)]
pub struct DriveReport {
    pub joystick: (i8, i8),
    pub seconds: f64,
    pub events: Vec<ActuatorEvent>,
    pub status: ActuatorStatus,
}

/// Drives joystick values (turn, forward) through the writer for
/// `duration`, then centres and releases; `stop` (a signal) ends it early
/// the same way. The command is refreshed every 20 ms as the supervisor
/// would, so the writer's freshness rule is exercised as on the chair.
/// The writer runs on its own real-time thread, as in the daemon.
pub async fn drive<B: CanBus, F>(
    make_bus: F,
    settings: RnetSettings,
    joystick: (i8, i8),
    duration: Duration,
    stop: CancellationToken,
) -> Result<DriveReport, ActuatorError>
where
    F: FnOnce() -> Result<B, CanBusError> + Send + 'static,
{
    let mode = settings.mode;
    let mapping = settings.mapping;
    let start_writer = move |io: ActuatorIo| {
        let spawned = spawn_actuator_thread(
            "rnet-writer",
            50,
            move || {
                Ok(RnetActuator {
                    bus: make_bus()?,
                    settings,
                })
            },
            io,
        );
        async move {
            let writer = spawned.map_err(|e| ActuatorError::Task(format!("rnet-writer: {e}")))?;
            thread_result(writer).await
        }
    };
    drive_with(
        start_writer,
        mode,
        mapping,
        joystick,
        duration,
        Arc::new(TokioClock::new()),
        stop,
    )
    .await
}

/// [`drive`] with the writer started by `start_writer`: it must start the
/// writer at once on the `ActuatorIo` it is given, and return a future of
/// the writer's end. Tests start it as a task on tokio's paused clock.
pub async fn drive_with<W, Fut>(
    start_writer: W,
    mode: TakeoverMode,
    mapping: JoystickMapping,
    joystick: (i8, i8),
    duration: Duration,
    clock: Arc<dyn Clock>,
    stop: CancellationToken,
) -> Result<DriveReport, ActuatorError>
where
    W: FnOnce(ActuatorIo) -> Fut,
    Fut: Future<Output = Result<ActuatorStatus, ActuatorError>>,
{
    let (v_mps, omega_radps) = mapping.to_velocity(joystick.0, joystick.1);
    let settings_mode = mode;
    let (cmd_tx, cmd_rx) = watch::channel(None);
    let (ev_tx, mut ev_rx) = mpsc::channel(64);
    let (status_tx, _status_rx) = watch::channel(ActuatorStatus::default());
    let writer_cancel = CancellationToken::new();
    let writer = start_writer(ActuatorIo {
        commands: cmd_rx,
        events: ev_tx,
        status: status_tx,
        cancel: writer_cancel.clone(),
        clock: clock.clone(),
    });
    let mut events = Vec::new();
    let end = tokio::time::sleep(duration);
    tokio::pin!(end);
    let mut tick = tokio::time::interval(Duration::from_millis(20));
    let mut yielded = false;
    loop {
        tokio::select! {
            biased;
            _ = stop.cancelled() => break,
            _ = &mut end => break,
            ev = ev_rx.recv() => match ev {
                Some(e) => {
                    if matches!(e, ActuatorEvent::UserDeflection { .. } | ActuatorEvent::Fault { .. }) {
                        yielded = true;
                    }
                    events.push(e);
                }
                None => break,
            },
            _ = tick.tick() => {
                let cmd = if yielded {
                    VelocityCmd::default()
                } else {
                    VelocityCmd { v_mps, omega_radps }
                };
                cmd_tx.send_replace(Some(SafeCmd {
                    cmd,
                    state: SupervisorState::Navigating,
                    stamp: clock.now(),
                    view: None,
                }));
            }
        }
    }
    cmd_tx.send_replace(None);
    writer_cancel.cancel();
    let status = writer.await?;
    while let Ok(e) = ev_rx.try_recv() {
        events.push(e);
    }
    // a drive whose takeover never happened drove nothing: an error
    if !stop.is_cancelled() && !events.iter().any(|e| matches!(e, ActuatorEvent::Active)) {
        let why = match (settings_mode, status.joystick_id) {
            (_, None) => "no joystick module answered (is the chair on, the bus up?)".to_string(),
            (TakeoverMode::JsmError, Some(_)) => format!(
                "the joystick module kept talking through {} frames of ours (silence \
                 requests): it does not honour JSMerror (try --mode followjsm)",
                status.sent
            ),
            (TakeoverMode::FollowJsm, Some(_)) => {
                "the joystick module's frames were never followed".to_string()
            }
        };
        return Err(ActuatorError::Takeover(why));
    }
    Ok(DriveReport {
        joystick,
        seconds: duration.as_secs_f64(),
        events,
        status,
    })
}
