//! The R-Net writer: the [`Takeover`] state machine on a CAN bus, ticking
//! every 10 ms on the monotonic clock.
//!
//! - JSMerror: after learning the joystick id and silencing the JSM, one
//!   joystick frame per tick; FollowJSM: one right after each JSM frame.
//! - The supervisor's latest command is sent only while younger than
//!   `command_max_age` (100 ms); otherwise centred. Frames start centred.
//! - A frame the bus cannot take in its slot is dropped and counted, never
//!   sent late; a slot the task missed is counted (`late`).
//! - Error frames: bus-off, error-passive and controller problems → a
//!   `Fault` event, and centred output at least until the supervisor
//!   acknowledges it (a command in its fault state), whose latch then
//!   holds the chair still.
//! - The user deflecting the real joystick → `UserDeflection`, we yield.
//! - Cancelled → centred frames for `release_after` (200 ms), then nothing.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::mpsc::error::TrySendError;
use tokio::time::MissedTickBehavior;

use super::can::{BusEvent, CanBus, CanBusError};
use super::rnet::{
    device_of, max_speed_frame, CanFrame, JoystickMapping, Takeover, TakeoverEvent, TakeoverMode,
    TakeoverState,
};
use super::{Actuator, ActuatorError, ActuatorEvent, ActuatorIo, ActuatorStatus, PeriodStats};
use crate::msg::{FaultReason, Stamp, SupervisorState};

/// R-Net writer settings (config `[actuation.rnet]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RnetSettings {
    pub mode: TakeoverMode,
    pub mapping: JoystickMapping,
    /// Joystick frame period (10 ms on R-Net).
    pub period: Duration,
    /// A command older than this is sent as centred (100 ms).
    pub command_max_age: Duration,
    /// Centred frames on shutdown before release (200 ms).
    pub release_after: Duration,
    /// The JSM heartbeat (every 100 ms) missing this long → `JsmLost`.
    pub jsm_lost_after: Duration,
    /// Tick from a thread sleeping to absolute deadlines on the monotonic
    /// clock (nanosecond timers) instead of tokio's millisecond timer
    /// wheel. On for the chair; off where tests control tokio's clock.
    pub precise_timer: bool,
    /// The chair's speed setting, pinned at takeover and every second
    /// after (R-Net max-speed frame, %); None leaves it alone.
    pub max_speed_percent: Option<u8>,
}

impl RnetSettings {
    pub fn new(mode: TakeoverMode, mapping: JoystickMapping) -> RnetSettings {
        RnetSettings {
            mode,
            mapping,
            period: Duration::from_millis(10),
            command_max_age: Duration::from_millis(100),
            release_after: Duration::from_millis(200),
            jsm_lost_after: Duration::from_millis(500),
            precise_timer: true,
            max_speed_percent: None,
        }
    }
}

/// The R-Net backend on any [`CanBus`] (SocketCAN on the chair).
pub struct RnetActuator<B: CanBus> {
    pub bus: B,
    pub settings: RnetSettings,
}

/// Where the writer's ticks come from.
enum Ticker {
    Tokio(tokio::time::Interval),
    Thread {
        rx: tokio::sync::mpsc::Receiver<()>,
        stop: Arc<AtomicBool>,
    },
}

impl Ticker {
    fn new(period: Duration, precise: bool) -> std::io::Result<Ticker> {
        if !precise {
            let mut i = tokio::time::interval(period);
            i.set_missed_tick_behavior(MissedTickBehavior::Skip);
            return Ok(Ticker::Tokio(i));
        }
        let (tx, rx) = tokio::sync::mpsc::channel(1);
        let stop = Arc::new(AtomicBool::new(false));
        let s = stop.clone();
        std::thread::Builder::new()
            .name("rnet-ticker".into())
            .spawn(move || {
                super::set_realtime(60);
                let mut next = std::time::Instant::now();
                while !s.load(Ordering::Relaxed) {
                    // a full channel means the writer has not taken the last
                    // tick: this slot is skipped, never sent late
                    if let Err(tokio::sync::mpsc::error::TrySendError::Closed(_)) = tx.try_send(())
                    {
                        return;
                    }
                    next += period;
                    let now = std::time::Instant::now();
                    if next <= now {
                        // missed slots: keep the grid, skip what passed
                        let behind = now - next;
                        let k = behind.as_nanos() / period.as_nanos().max(1) + 1;
                        next += period * k as u32;
                    }
                    std::thread::sleep(next - std::time::Instant::now().min(next));
                }
            })?;
        Ok(Ticker::Thread { rx, stop })
    }

    async fn tick(&mut self) {
        match self {
            Ticker::Tokio(i) => {
                i.tick().await;
            }
            Ticker::Thread { rx, .. } => {
                if rx.recv().await.is_none() {
                    // the ticker thread is gone: never tick again (the
                    // power module stops within 30 ms)
                    std::future::pending::<()>().await;
                }
            }
        }
    }
}

impl Drop for Ticker {
    fn drop(&mut self) {
        if let Ticker::Thread { stop, .. } = self {
            stop.store(true, Ordering::Relaxed);
        }
    }
}

/// How many recent periods the status statistics cover.
const PERIOD_WINDOW: usize = 1000;

struct WriterState {
    status: ActuatorStatus,
    last_send: Option<Stamp>,
    intervals: VecDeque<f64>,
    /// Every period of the run.
    periods: super::DurationHistogram,
    fault_at: Option<Stamp>,
    latency: super::ViewLatency,
}

impl WriterState {
    fn send<B: CanBus>(&mut self, bus: &B, f: &CanFrame, now: Stamp, joystick: bool) {
        match bus.try_send(f) {
            Ok(()) => {
                self.status.sent += 1;
                if joystick {
                    let p = f.payload();
                    if p.len() == 2 {
                        self.status.last_output = (p[0] as i8, p[1] as i8);
                    }
                    if let Some(prev) = self.last_send {
                        if self.intervals.len() == PERIOD_WINDOW {
                            self.intervals.pop_front();
                        }
                        let period_s = prev.age_at(now).as_secs_f64();
                        self.intervals.push_back(period_s);
                        self.periods.record(period_s);
                    }
                    self.last_send = Some(now);
                    self.latency.on_sent(now);
                }
            }
            Err(e) => {
                self.status.dropped += 1;
                tracing::warn!(frame = %f, error = %e, "R-Net frame dropped");
            }
        }
    }
}

fn emit(io: &ActuatorIo, ev: ActuatorEvent) {
    tracing::info!(event = ?ev, "R-Net");
    match io.events.try_send(ev) {
        Ok(()) | Err(TrySendError::Closed(_)) => {}
        Err(TrySendError::Full(ev)) => {
            tracing::error!(event = ?ev, "actuator event queue full: event lost")
        }
    }
}

fn state_name(s: TakeoverState) -> &'static str {
    match s {
        TakeoverState::Listening => "listening",
        TakeoverState::Silencing => "silencing",
        TakeoverState::Active => "active",
        TakeoverState::Yielded => "yielded",
        TakeoverState::Released => "released",
    }
}

impl<B: CanBus> RnetActuator<B> {
    /// The supervisor's latest command into the takeover (or nothing, when
    /// a bus fault has not yet been seen by the supervisor).
    fn apply_command(&self, tk: &mut Takeover, w: &mut WriterState, io: &ActuatorIo) {
        let cmd = *io.commands.borrow();
        let Some(cmd) = cmd else {
            tk.clear_command();
            return;
        };
        if let Some(at) = w.fault_at {
            // centred until the supervisor acknowledges the fault; from then
            // on its latch holds the chair (and a person clears it)
            if cmd.stamp >= at && matches!(cmd.state, SupervisorState::Fault(_)) {
                w.fault_at = None;
            }
            tk.clear_command();
            return;
        }
        let (x, y) = self
            .settings
            .mapping
            .to_joystick(cmd.cmd.v_mps, cmd.cmd.omega_radps);
        tk.set_command(x, y, cmd.stamp);
        w.latency.on_command(&cmd);
    }
}

impl<B: CanBus> Actuator for RnetActuator<B> {
    async fn run(self, io: ActuatorIo) -> Result<ActuatorStatus, ActuatorError> {
        let s = self.settings;
        let mut tk = Takeover::new(s.mode);
        tk.command_max_age = s.command_max_age;
        tk.period = s.period;
        let mut w = WriterState {
            status: ActuatorStatus {
                backend: "rnet",
                state: state_name(tk.state).into(),
                ..Default::default()
            },
            last_send: None,
            intervals: VecDeque::with_capacity(PERIOD_WINDOW),
            periods: super::DurationHistogram::new(),
            fault_at: None,
            latency: Default::default(),
        };
        let mut interval = Ticker::new(s.period, s.precise_timer)
            .map_err(|e| ActuatorError::Task(format!("ticker thread: {e}")))?;
        let mut release_at: Option<Stamp> = None;
        let mut jsm_lost_reported = false;
        let mut ticks: u64 = 0;
        loop {
            tokio::select! {
                biased;
                _ = io.cancel.cancelled(), if release_at.is_none() => {
                    let now = io.clock.now();
                    tracing::info!("R-Net writer: shutdown, centred frames then release");
                    tk.clear_command();
                    release_at = Some(Stamp(now.0 + s.release_after));
                }
                _ = interval.tick() => {
                    let now = io.clock.now();
                    ticks += 1;
                    match release_at {
                        Some(at) if now >= at => {
                            tk.release();
                            w.status.state = state_name(tk.state).into();
                            w.status.period_run = w.periods.stats();
                            w.status.frame_to_command = w.latency.stats();
                            io.status.send_replace(w.status.clone());
                            emit(&io, ActuatorEvent::Released);
                            return Ok(w.status);
                        }
                        Some(_) => tk.clear_command(),
                        None => self.apply_command(&mut tk, &mut w, &io),
                    }
                    let before = tk.state;
                    if let Some(f) = tk.tick(now) {
                        w.send(&self.bus, &f, now, true);
                    }
                    if before == TakeoverState::Silencing && tk.state == TakeoverState::Active {
                        emit(&io, ActuatorEvent::Active);
                    }
                    let lost = tk.jsm_lost(now, s.jsm_lost_after);
                    if lost && !jsm_lost_reported && tk.joystick_id().is_some() {
                        emit(&io, ActuatorEvent::JsmLost);
                    }
                    jsm_lost_reported = lost;
                    // the speed setting again every second (a turned dial,
                    // a changed profile)
                    if let (Some(p), Some(id), true) =
                        (s.max_speed_percent, tk.joystick_id(), ticks.is_multiple_of(100))
                    {
                        if release_at.is_none() {
                            w.send(&self.bus, &max_speed_frame(device_of(id), p), now, false);
                        }
                    }
                    if ticks.is_multiple_of(10) {
                        w.status.state = state_name(tk.state).into();
                        w.status.joystick_id = tk.joystick_id();
                        w.status.late = tk.late_frames;
                        w.status.period = PeriodStats::from_intervals(w.intervals.make_contiguous());
                        // the whole run's: a walk over its 10 000 bins,
                        // once a second (and at release) is enough
                        if ticks.is_multiple_of(100) {
                            w.status.period_run = w.periods.stats();
                            w.status.frame_to_command = w.latency.stats();
                        }
                        io.status.send_replace(w.status.clone());
                    }
                }
                ev = self.bus.recv() => {
                    let now = io.clock.now();
                    match ev {
                        Ok(BusEvent::Frame(f)) => {
                            if release_at.is_none() {
                                self.apply_command(&mut tk, &mut w, &io);
                            }
                            let (out, event) = tk.on_frame(&f, now);
                            for o in &out {
                                let joystick = o.len == 2;
                                w.send(&self.bus, o, now, joystick);
                            }
                            match event {
                                Some(TakeoverEvent::Learned(id)) => {
                                    w.status.joystick_id = Some(id);
                                    if let Some(p) = s.max_speed_percent {
                                        w.send(&self.bus, &max_speed_frame(device_of(id), p), now, false);
                                    }
                                    emit(&io, ActuatorEvent::Ready { joystick_id: Some(id) });
                                    if s.mode == TakeoverMode::FollowJsm {
                                        emit(&io, ActuatorEvent::Active);
                                    }
                                }
                                Some(TakeoverEvent::UserDeflection { x, y }) => {
                                    emit(&io, ActuatorEvent::UserDeflection { x, y });
                                }
                                Some(TakeoverEvent::JsmLost) => emit(&io, ActuatorEvent::JsmLost),
                                Some(TakeoverEvent::OtherWriter { frames, expected }) => {
                                    let reason = format!(
                                        "another program sends joystick frames on {:08X} ({frames} in {} ms where the joystick module accounts for {expected})",
                                        tk.joystick_id().unwrap_or(0),
                                        crate::actuation::rnet::OTHER_WRITER_WINDOW.as_millis()
                                    );
                                    tracing::error!(%reason, "R-Net");
                                    w.fault_at = Some(now);
                                    tk.clear_command();
                                    emit(&io, ActuatorEvent::Fault { kind: FaultReason::OtherWriter, reason });
                                }
                                None => {}
                            }
                        }
                        Ok(BusEvent::Error(e)) => {
                            w.status.bus_errors += 1;
                            if e.is_fault() {
                                tracing::error!(error = %e.describe(), "CAN bus fault");
                                w.fault_at = Some(now);
                                tk.clear_command();
                                emit(&io, ActuatorEvent::Fault { kind: FaultReason::CanBus, reason: e.describe() });
                            } else {
                                tracing::warn!(error = %e.describe(), "CAN bus error");
                            }
                        }
                        Err(e @ (CanBusError::Closed | CanBusError::Io { .. })) => {
                            emit(&io, ActuatorEvent::Fault { kind: FaultReason::CanBus, reason: e.to_string() });
                            w.status.state = "failed".into();
                            io.status.send_replace(w.status.clone());
                            return Err(e.into());
                        }
                        Err(e) => tracing::warn!(error = %e, "CAN receive"),
                    }
                }
            }
        }
    }
}
