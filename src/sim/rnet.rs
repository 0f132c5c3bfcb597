//! A simulated R-Net chair on a CAN bus: the joystick module (JSM) and the
//! power module (PM), as the public reverse engineering describes them.
//!
//! - JSM: heartbeat `03C30F0F` every 100 ms; joystick frames (the user's
//!   deflection, scriptable) every 10 ms on its id; `0C000000` frames
//!   silence its joystick frames (JSMerror), the heartbeat goes on.
//! - PM: heartbeat `0C140X00` and battery `1C0C0X00` every second; drives
//!   the motors from the latest joystick frame on the JSM's id (the JSM's
//!   own or a frame from another node), and **stops the motors when no
//!   joystick frame came for more than 30 ms**.
//!
//! The model is pure (time in, frames out); [`run_sim_chair`] puts it on a
//! [`CanBus`].

use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

use crate::actuation::can::{BusEvent, CanBus};
use crate::actuation::rnet::{
    decode, joystick_frame, CanFrame, RnetMessage, JSM_HEARTBEAT_ID, JSM_SILENCE_ID,
};
use crate::actuation::ActuatorEvent;
use crate::msg::{Clock, Obstacles, Odometry, SafeCmd, Stamp, Stamped, VelocityCmd};
use crate::safety::{Supervisor, SupervisorInputs};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimChairSettings {
    /// The JSM's joystick id (`0x02000X00`).
    pub joystick_id: u32,
    pub joystick_period: Duration,
    pub heartbeat_period: Duration,
    pub pm_period: Duration,
    /// No joystick frame for longer than this → motors stop.
    pub motor_timeout: Duration,
    pub battery_percent: u8,
    /// A JSM that keeps talking after the silence frame (one that does not
    /// honour JSMerror): a takeover in that mode must fail loudly.
    pub ignores_silence: bool,
}

impl Default for SimChairSettings {
    fn default() -> Self {
        SimChairSettings {
            joystick_id: 0x0200_0100,
            joystick_period: Duration::from_millis(10),
            heartbeat_period: Duration::from_millis(100),
            pm_period: Duration::from_secs(1),
            motor_timeout: Duration::from_millis(30),
            battery_percent: 80,
            ignores_silence: false,
        }
    }
}

/// A joystick frame on the JSM's id as the PM saw it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DriveFrame {
    pub at: Stamp,
    pub x: i8,
    pub y: i8,
    /// Sent by the simulated JSM itself (else by another node).
    pub from_jsm: bool,
}

#[derive(Debug, Clone)]
pub struct SimChair {
    pub settings: SimChairSettings,
    /// The real joystick's deflection (turn, forward).
    pub user: (i8, i8),
    pub jsm_silenced: bool,
    /// Silence frames received.
    pub silence_frames: u32,
    next_joystick: Stamp,
    next_heartbeat: Stamp,
    next_pm: Stamp,
    last_drive: Option<DriveFrame>,
    /// Every drive frame seen by the PM, in order.
    pub drive_log: Vec<DriveFrame>,
    pub jsm_frames_sent: u64,
    /// Max-speed settings received (%), in order.
    pub max_speed_log: Vec<u8>,
}

impl SimChair {
    pub fn new(settings: SimChairSettings, start: Stamp) -> SimChair {
        SimChair {
            settings,
            user: (0, 0),
            jsm_silenced: false,
            silence_frames: 0,
            next_joystick: start,
            next_heartbeat: start,
            next_pm: start,
            last_drive: None,
            drive_log: Vec::new(),
            jsm_frames_sent: 0,
            max_speed_log: Vec::new(),
        }
    }

    fn device(&self) -> u32 {
        (self.settings.joystick_id >> 8) & 0xF
    }

    /// When the next frame is due.
    pub fn next_due(&self) -> Stamp {
        self.next_joystick
            .min(self.next_heartbeat)
            .min(self.next_pm)
    }

    /// Frames due at `now` (the JSM's and the PM's).
    pub fn poll(&mut self, now: Stamp) -> Vec<CanFrame> {
        let s = self.settings;
        let mut out = Vec::new();
        if now >= self.next_heartbeat {
            out.push(CanFrame::ext(JSM_HEARTBEAT_ID, &[0x87; 8]));
            self.next_heartbeat = advance(self.next_heartbeat, s.heartbeat_period, now);
        }
        if now >= self.next_joystick {
            if !self.jsm_silenced {
                let (x, y) = self.user;
                out.push(joystick_frame(s.joystick_id, x, y));
                self.jsm_frames_sent += 1;
                self.record(DriveFrame {
                    at: now,
                    x,
                    y,
                    from_jsm: true,
                });
            }
            self.next_joystick = advance(self.next_joystick, s.joystick_period, now);
        }
        if now >= self.next_pm {
            let dev = self.device();
            out.push(CanFrame::ext(0x0C14_0000 | (dev << 8), &[0x00]));
            out.push(CanFrame::ext(
                0x1C0C_0000 | (dev << 8),
                &[s.battery_percent],
            ));
            self.next_pm = advance(self.next_pm, s.pm_period, now);
        }
        out
    }

    fn record(&mut self, d: DriveFrame) {
        self.last_drive = Some(d);
        self.drive_log.push(d);
    }

    /// A frame from another node at `now`.
    pub fn on_frame(&mut self, f: &CanFrame, now: Stamp) {
        if f.extended && f.id == JSM_SILENCE_ID && f.len == 0 {
            self.silence_frames += 1;
            self.jsm_silenced = !self.settings.ignores_silence;
            return;
        }
        if let RnetMessage::MaxSpeed { device, percent } = decode(f) {
            if u32::from(device) == self.device() {
                self.max_speed_log.push(percent);
            }
            return;
        }
        if let RnetMessage::Joystick { id, x, y } = decode(f) {
            if id == self.settings.joystick_id {
                self.record(DriveFrame {
                    at: now,
                    x,
                    y,
                    from_jsm: false,
                });
            }
        }
    }

    /// What the PM drives at `now`: the latest frame while younger than the
    /// motor timeout, else stopped (`None`).
    pub fn motor_output(&self, now: Stamp) -> Option<(i8, i8)> {
        self.last_drive
            .filter(|d| d.at.age_at(now) <= self.settings.motor_timeout)
            .map(|d| (d.x, d.y))
    }
}

/// The next slot after `now` on a fixed grid from `t` (missed slots skipped).
pub(super) fn advance(t: Stamp, period: Duration, now: Stamp) -> Stamp {
    let mut n = t.0 + period;
    if n <= now.0 {
        let behind = now.0 - t.0;
        let k = behind.as_nanos() / period.as_nanos().max(1) + 1;
        n = t.0 + period * k as u32;
    }
    Stamp(n)
}

/// Runs the chair on `bus` until cancelled; the shared model can be read
/// (and the user's joystick moved) from outside meanwhile.
pub async fn run_sim_chair<B: CanBus>(
    bus: B,
    chair: Arc<Mutex<SimChair>>,
    clock: Arc<dyn Clock>,
    cancel: CancellationToken,
) {
    let origin_instant = tokio::time::Instant::now();
    let origin_stamp = clock.now();
    loop {
        let due = match chair.lock() {
            Ok(c) => c.next_due(),
            Err(_) => return,
        };
        let wake = origin_instant + due.0.saturating_sub(origin_stamp.0);
        tokio::select! {
            biased;
            _ = cancel.cancelled() => return,
            _ = tokio::time::sleep_until(wake) => {
                let now = clock.now();
                let frames = match chair.lock() {
                    Ok(mut c) => c.poll(now),
                    Err(_) => return,
                };
                for f in frames {
                    if let Err(e) = bus.try_send(&f) {
                        tracing::warn!(frame = %f, error = %e, "sim chair: frame not sent");
                    }
                }
            }
            ev = bus.recv() => {
                let now = clock.now();
                match ev {
                    Ok(BusEvent::Frame(f)) => {
                        if let Ok(mut c) = chair.lock() {
                            c.on_frame(&f, now);
                        }
                    }
                    Ok(BusEvent::Error(_)) => {}
                    Err(_) => return,
                }
            }
        }
    }
}

/// Stands in for the daemon's control loop in actuator tests: the real
/// [`Supervisor`] stepped every `period` with fresh sensor inputs (an empty
/// room) and the planner command from `planner`, publishing its output on
/// `commands`, with the actuator's events applied as the daemon does
/// (fault → latched fault, user deflection → takeover stop). Every event is
/// also appended to `seen`. `planner` set to `None` stops the planner (its
/// command goes stale).
pub struct ControlStandIn {
    pub supervisor: Supervisor,
    pub planner: watch::Receiver<Option<VelocityCmd>>,
    pub commands: watch::Sender<Option<SafeCmd>>,
    pub events: mpsc::Receiver<ActuatorEvent>,
    pub seen: Arc<Mutex<Vec<(Stamp, ActuatorEvent)>>>,
    pub clock: Arc<dyn Clock>,
    pub period: Duration,
    pub cancel: CancellationToken,
}

/// Runs the stand-in until cancelled; returns its supervisor.
pub async fn run_control_stand_in(c: ControlStandIn) -> Supervisor {
    let ControlStandIn {
        mut supervisor,
        planner,
        commands,
        mut events,
        seen,
        clock,
        period,
        cancel,
    } = c;
    // no camera here: the stand-in checks the writer, not perception
    supervisor.limits.camera_max_age = None;
    supervisor.limits.turn_needs_seen_rear = false;
    supervisor.goal_active();
    let mut tick = tokio::time::interval(period);
    let mut last_planner: Option<Stamped<VelocityCmd>> = None;
    loop {
        tokio::select! {
            biased;
            _ = cancel.cancelled() => return supervisor,
            ev = events.recv() => {
                let Some(ev) = ev else { return supervisor };
                match ev {
                    ActuatorEvent::Fault { kind, .. } => supervisor.can_fault(kind),
                    ActuatorEvent::UserDeflection { .. } => supervisor.user_takeover(),
                    _ => {}
                }
                if let Ok(mut s) = seen.lock() {
                    s.push((clock.now(), ev));
                }
            }
            _ = tick.tick() => {
                let now = clock.now();
                if let Some(v) = *planner.borrow() {
                    last_planner = Some(Stamped::new(now, v));
                }
                let obstacles = Stamped::new(now, Obstacles::default());
                let out = supervisor.step(now, &SupervisorInputs {
                    obstacles: Some(&obstacles),
                    odometry: Some(&Stamped::new(now, Odometry::default())),
                    command: last_planner.as_ref(),
                    // this harness checks the writer, not perception
                    camera: None,
                    rear: None,
                });
                commands.send_replace(Some(out));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: u64) -> Stamp {
        Stamp(Duration::from_millis(v))
    }

    #[test]
    fn jsm_sends_on_schedule_and_goes_quiet_when_silenced() {
        let mut c = SimChair::new(SimChairSettings::default(), ms(0));
        let mut joystick = 0;
        let mut heartbeats = 0;
        for t in 0..100 {
            for f in c.poll(ms(t)) {
                match decode(&f) {
                    RnetMessage::Joystick { .. } => joystick += 1,
                    RnetMessage::JsmHeartbeat => heartbeats += 1,
                    _ => {}
                }
            }
        }
        assert_eq!(joystick, 10);
        assert_eq!(heartbeats, 1);
        c.on_frame(&CanFrame::ext(JSM_SILENCE_ID, &[]), ms(100));
        let quiet: usize = (100..200)
            .flat_map(|t| c.poll(ms(t)))
            .filter(|f| matches!(decode(f), RnetMessage::Joystick { .. }))
            .count();
        assert_eq!(quiet, 0);
    }

    #[test]
    fn motors_stop_thirty_ms_after_the_last_joystick_frame() {
        let mut c = SimChair::new(SimChairSettings::default(), ms(0));
        c.on_frame(&CanFrame::ext(JSM_SILENCE_ID, &[]), ms(0));
        c.on_frame(&joystick_frame(0x0200_0100, 5, 40), ms(10));
        assert_eq!(c.motor_output(ms(40)), Some((5, 40)));
        assert_eq!(c.motor_output(ms(41)), None);
        // a frame on another id does not drive
        c.on_frame(&joystick_frame(0x0200_0200, 5, 40), ms(50));
        assert_eq!(c.motor_output(ms(50)), None);
    }

    #[test]
    fn missed_slots_are_skipped() {
        assert_eq!(advance(ms(0), Duration::from_millis(10), ms(5)), ms(10));
        assert_eq!(advance(ms(0), Duration::from_millis(10), ms(35)), ms(40));
    }
}
