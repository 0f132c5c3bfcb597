//! The control task: the pure [`Control`] step at 20 Hz, fed from the
//! daemon's channels — user input, the actuator's events, task failures,
//! the devices' first readings (systemd READY and STATUS), the latest
//! obstacles, odometry and tracks — and publishing the supervisor's
//! command, the wanted words and the sentences; it feeds the watchdog.

use std::collections::BTreeSet;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

use super::control::{Control, ControlInputs, Outcome};
use super::latch;
use super::notify::{sd_notify, status_line, NotifyState};
use crate::actuation::ActuatorEvent;
use crate::estimation::goal::GoalState;
use crate::estimation::tracker::Tracker;
use crate::msg::{
    Clock, MapObstacles, Obstacles, Odometry, SafeCmd, Stamp, Stamped, SupervisorState, UserInput,
};

use crate::actuation::{DurationHistogram, PeriodStats};
pub use crate::config::CONTROL_PERIOD;

/// A trip ends (arrived, not found, lost, stopped) with the chair at rest:
/// odometry's speeds at most these, m/s and rad/s…
const AT_REST_MPS: f64 = 0.02;
const AT_REST_RADPS: f64 = 0.05;
/// …or this long after its end was decided, whatever odometry says.
const SETTLE_LIMIT: Duration = Duration::from_secs(2);

pub struct ControlTaskIo {
    pub inputs: mpsc::Receiver<UserInput>,
    /// A task that died: its name and why.
    pub faults: mpsc::UnboundedReceiver<(String, String)>,
    pub actuator_events: mpsc::Receiver<ActuatorEvent>,
    /// A device's first reading, by name.
    pub first_readings: mpsc::UnboundedReceiver<&'static str>,
    /// The devices READY waits for ("motors": the actuator's Ready event).
    pub waiting: BTreeSet<&'static str>,
    pub obstacles: watch::Receiver<Option<Stamped<Obstacles>>>,
    pub odometry: watch::Receiver<Option<Stamped<Odometry>>>,
    /// The depth camera's remembered obstacles (odom).
    pub camera: watch::Receiver<Option<Stamped<MapObstacles>>>,
    pub tracks: watch::Receiver<Tracker>,
    pub commands: watch::Sender<Option<SafeCmd>>,
    pub prompts: watch::Sender<Vec<String>>,
    pub speech: Option<mpsc::UnboundedSender<String>>,
    /// Where a latched fault is written (None: nowhere).
    pub state_dir: Option<std::path::PathBuf>,
    pub clock: Arc<dyn Clock>,
    pub cancel: CancellationToken,
    pub start: Stamp,
    pub max_duration: Option<Duration>,
    /// Stops from any input: each change is one (never queued).
    pub stops: Option<watch::Receiver<u64>>,
    /// What the daemon is doing, for the control socket.
    pub status: Option<watch::Sender<crate::input::DaemonStatus>>,
    /// The live view (Foxglove), when it is on.
    pub live: Option<crate::live::LiveSink>,
    /// The recording, when there is one.
    pub record: Option<super::recorder::RecordSink>,
    /// The motor interface's status (what it sent last), for the live view
    /// and the recording.
    pub actuator_status: Option<watch::Receiver<crate::actuation::ActuatorStatus>>,
    /// The views' compute time, for the status.
    pub view_time: Option<watch::Receiver<PeriodStats>>,
}

/// How the control task ended.
pub struct ControlEnd {
    pub control: Control,
    pub outcome: Outcome,
    /// Everything said, in order.
    pub said: Vec<String>,
    pub end: Stamp,
    pub timing: ControlTiming,
    /// The channels stay open until the daemon shuts the tasks down: a
    /// closed channel means a dead task.
    pub channels: (watch::Sender<Option<SafeCmd>>, watch::Sender<Vec<String>>),
}

/// How the control steps kept time over the run: the period between the
/// 20 Hz ticks' steps (on the run's clock) and the time each step took (of
/// the host's, whatever the clock).
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct ControlTiming {
    pub period: PeriodStats,
    pub step: PeriodStats,
}

/// Runs until the trip is over, the user quits, `cancel` or a fault; the
/// last command it sends is zero.
pub async fn run(mut control: Control, mut io: ControlTaskIo) -> ControlEnd {
    let mut said: Vec<String> = Vec::new();
    let mut tick = tokio::time::interval(CONTROL_PERIOD);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut ready = false;
    let mut persisted: Option<crate::msg::FaultReason> = None;
    let mut status_sent = String::new();
    // the last stop's reason, for systemd's status line
    let mut last_stop: Option<String> = None;
    let mut inputs_open = true;
    let mut tracks_open = true;
    let mut stops = io.stops.take();
    let mut last_said: std::collections::VecDeque<String> = Default::default();
    let mut ending: Option<(Outcome, Stamp)> = None;
    // what the person said or pressed since the last step (for the live
    // view and the recording)
    let mut taken: Vec<String> = Vec::new();
    let keep_inputs = io.live.is_some() || io.record.is_some();
    let (mut periods, mut step_times) = (DurationHistogram::new(), DurationHistogram::new());
    let mut last_tick: Option<Stamp> = None;
    let mut memory: Option<(Stamp, Option<crate::memory::MemoryUse>)> = None;
    let outcome = loop {
        let mut ticked = false;
        tokio::select! {
            biased;
            Some((task, reason)) = io.faults.recv() => control.on_task_failure(&task, &reason),
            _ = io.cancel.cancelled() => break Outcome::Signal,
            r = async {
                match stops.as_mut() {
                    Some(s) => s.changed().await,
                    None => std::future::pending().await,
                }
            } => {
                match r {
                    Ok(()) => {
                        if let Some(s) = stops.as_mut() {
                            s.borrow_and_update();
                        }
                        if keep_inputs {
                            taken.push(format!("{:?}", UserInput::Stop));
                        }
                        control.on_input(UserInput::Stop);
                    }
                    // every sender gone (the daemon ending): no more stops
                    // can come; the words' channel says the same
                    Err(_) => stops = None,
                }
            }
            i = io.inputs.recv(), if inputs_open => match i {
                Some(i) => {
                    if keep_inputs {
                        taken.push(format!("{i:?}"));
                    }
                    control.on_input(i)
                }
                None => inputs_open = false,
            },
            Some(ev) = io.actuator_events.recv() => {
                if matches!(ev, ActuatorEvent::Ready { .. }) {
                    io.waiting.remove("motors");
                }
                control.on_actuator_event(&ev);
            }
            Some(first) = io.first_readings.recv() => { io.waiting.remove(first); }
            // a new view in the tracker: a step at once, so that its command
            // does not wait for the tick (frame-to-command latency)
            r = io.tracks.changed(), if tracks_open => match r {
                Ok(()) => {
                    io.tracks.borrow_and_update();
                }
                // the estimation task gone: its failure reaches `faults`
                Err(_) => tracks_open = false,
            },
            _ = tick.tick() => ticked = true,
        }
        let now = io.clock.now();
        if ticked {
            if let Some(prev) = last_tick {
                periods.record(prev.age_at(now).as_secs_f64());
            }
            last_tick = Some(now);
        }
        let step_started = std::time::Instant::now();
        let obstacles = io.obstacles.borrow().clone();
        let odometry = *io.odometry.borrow();
        let camera = io.camera.borrow().clone();
        let out = {
            let tracker = io.tracks.borrow();
            let mut out = control.step(
                now,
                ControlInputs {
                    obstacles: obstacles.as_ref(),
                    odometry: odometry.as_ref(),
                    tracker: &tracker,
                    camera: camera.as_ref(),
                },
            );
            out.cmd.view = tracker.newest_view();
            out
        };
        step_times.record(step_started.elapsed().as_secs_f64());
        io.commands.send_replace(Some(out.cmd));
        io.prompts.send_if_modified(|p| {
            let changed = *p != out.wanted;
            if changed {
                p.clone_from(&out.wanted);
            }
            changed
        });
        if std::mem::take(&mut control.acknowledged) {
            persisted = None;
            if let Some(dir) = &io.state_dir {
                match latch::acknowledge(dir) {
                    Ok(Some(f)) => tracing::warn!(fault = ?f.fault, "latched fault acknowledged"),
                    Ok(None) => {}
                    Err(e) => tracing::error!(error = %e, "the latched fault could not be cleared"),
                }
            }
        }
        for s in &out.said {
            if last_said.len() == 5 {
                last_said.pop_front();
            }
            last_said.push_back(s.clone());
        }
        if let Some(tx) = &io.status {
            if memory.is_none_or(|(at, _)| at.age_at(now) >= Duration::from_secs(1)) {
                memory = Some((now, crate::memory::own_memory()));
            }
            let goal = control.goal_state();
            tx.send_replace(crate::input::DaemonStatus {
                state: Some(out.cmd.state),
                goal: goal.label().map(str::to_string),
                goal_phase: goal.phase().map(str::to_string),
                pose: odometry.map(|o| o.value.pose),
                fault: control.fault_reason(),
                waiting_for: io.waiting.iter().map(|w| w.to_string()).collect(),
                asking: control.asking(),
                moving: out.cmd.cmd.v_mps.abs() > 0.0
                    || out.cmd.cmd.omega_radps.abs() > 0.0
                    || odometry.is_some_and(|o| {
                        o.value.v_mps.abs() > 0.02 || o.value.omega_radps.abs() > 0.05
                    }),
                seen: {
                    let tracks = io.tracks.borrow();
                    let here = odometry.map(|o| o.value.pose).unwrap_or_default();
                    let mut seen: Vec<(f64, String)> = tracks
                        .tracks()
                        .iter()
                        .filter(|t| t.confirmed)
                        .map(|t| {
                            (
                                (t.center_m[0] - here.x_m).hypot(t.center_m[1] - here.y_m),
                                t.label.clone(),
                            )
                        })
                        .collect();
                    seen.sort_by(|a, b| a.0.total_cmp(&b.0));
                    let mut labels: Vec<String> = Vec::new();
                    for (_, l) in seen {
                        if !labels.contains(&l) {
                            labels.push(l);
                        }
                    }
                    labels
                },
                said: last_said.iter().cloned().collect(),
                memory: memory.and_then(|(_, m)| m),
                view_time: io.view_time.as_ref().map(|v| *v.borrow()),
                frame_to_command: io
                    .actuator_status
                    .as_ref()
                    .map(|a| a.borrow().frame_to_command),
            });
        }
        if io.live.is_some() || io.record.is_some() {
            let goal = control.goal_state();
            let tracks = io.tracks.borrow();
            let step = Box::new(crate::live::StepView {
                stamp: now,
                odometry: odometry.map(|o| o.value),
                state: out.cmd.state,
                cmd: out.cmd.cmd,
                goal: goal.label().map(str::to_string),
                phase: goal.phase().map(str::to_string),
                goal_track: match goal {
                    GoalState::Tracking { track, .. }
                    | GoalState::Holding { track, .. }
                    | GoalState::Reached { track, .. } => Some(*track),
                    _ => None,
                },
                approach: control.goal.approach(),
                tracks: crate::live::TrackView::confirmed(&tracks),
                plan_odom: control.planned_path.clone(),
                camera: camera.as_ref().map(|c| c.value.clone()),
                said: out.said.clone(),
                inputs: std::mem::take(&mut taken),
                actuator: io.actuator_status.as_ref().map(|a| a.borrow().clone()),
            });
            drop(tracks);
            if let Some(r) = &io.record {
                r.put(super::recorder::RecordItem::Step(step.clone()));
            }
            crate::live::show(&io.live, || crate::live::LiveItem::Step(step));
        }
        for s in out.said {
            tracing::info!(say = %s, "opennav");
            if let Some(tx) = &io.speech {
                // the listener gone (its process ending) loses nothing: the report has it
                tx.send(s.clone()).ok();
            }
            said.push(s);
        }
        // a fault a restart must not clear: on disk at once
        if let (SupervisorState::Fault(kind), Some(dir)) = (out.cmd.state, &io.state_dir) {
            if latch::persists(kind) && persisted != Some(kind) {
                persisted = Some(kind);
                let record = latch::LatchedFault {
                    fault: kind,
                    reason: control
                        .fault_reason()
                        .unwrap_or_else(|| format!("{kind:?}")),
                    since_unix_s: latch::now_unix_s(),
                };
                if let Err(e) = latch::store(dir, &record) {
                    // the fault holds in this run; a restart would not know it
                    tracing::error!(error = %e, "the latched fault could not be written");
                }
            }
        }
        match &out.cmd.state {
            SupervisorState::Stopped(r) => last_stop = Some(format!("{r:?}")),
            SupervisorState::Fault(r) => last_stop = Some(format!("fault {r:?}")),
            _ => {}
        }
        if !ready && io.waiting.is_empty() {
            ready = true;
            sd_notify(NotifyState::Ready);
        }
        let status = if ready {
            let goal = control.goal_state();
            status_line(
                &out.cmd.state,
                goal.label(),
                goal.phase(),
                last_stop.as_deref(),
            )
        } else {
            format!(
                "waiting for a first reading from: {}",
                io.waiting.iter().copied().collect::<Vec<_>>().join(", ")
            )
        };
        if status != status_sent {
            sd_notify(NotifyState::Status(&status));
            status_sent = status;
        }
        // the trip is over once the chair is at rest: it was told to stop
        // (a stop's outcome is the first one)
        if let Some(o) = out.done {
            ending.get_or_insert((o, now));
        }
        if let Some((o, since)) = ending.clone() {
            let at_rest = odometry.is_none_or(|d| {
                d.value.v_mps.abs() <= AT_REST_MPS && d.value.omega_radps.abs() <= AT_REST_RADPS
            });
            if at_rest || now.0.saturating_sub(since.0) >= SETTLE_LIMIT {
                break o;
            }
        }
        if io
            .max_duration
            .is_some_and(|m| now.0.saturating_sub(io.start.0) > m)
        {
            break Outcome::Timeout;
        }
        // fed only while every task runs and nothing is faulted
        if !matches!(out.cmd.state, SupervisorState::Fault(_)) {
            sd_notify(NotifyState::Watchdog);
        }
    };
    // the last word to the actuator: zero
    let now = io.clock.now();
    io.commands.send_replace(Some(SafeCmd {
        cmd: Default::default(),
        state: control.state(),
        stamp: now,
        view: None,
    }));
    sd_notify(NotifyState::Stopping);
    // the channels stay open until the daemon shuts the tasks down: a
    // closed channel means a dead task
    ControlEnd {
        control,
        outcome,
        said,
        end: now,
        timing: ControlTiming {
            period: periods.stats(),
            step: step_times.stats(),
        },
        channels: (io.commands, io.prompts),
    }
}

#[cfg(test)]
#[path = "control_task_tests.rs"]
mod tests;
