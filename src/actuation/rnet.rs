//! R-Net over CAN (PGDT power chairs), as publicly reverse engineered (the
//! shared protocol notes, §1): frame codec, velocity ↔ joystick mapping,
//! and the takeover state machine. Pure: frames and time in, frames out.
//!
//! Joystick frame: 29-bit `0x02000X00`, DLC 2, byte 0 = X (turn, int8
//! −100..100, positive = right), byte 1 = Y (forward, positive = forward),
//! sent by the joystick module (JSM) every 10 ms. The device number X is
//! learned by listening, never hard-coded.

use std::time::Duration;

use serde::Serialize;

use crate::msg::Stamp;

/// A CAN frame as the codec sees it (the SocketCAN adapter converts).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CanFrame {
    /// 29-bit identifier when `extended`, else 11-bit.
    pub id: u32,
    pub extended: bool,
    pub len: u8,
    pub data: [u8; 8],
}

impl CanFrame {
    pub fn ext(id: u32, data: &[u8]) -> CanFrame {
        let mut d = [0u8; 8];
        let n = data.len().min(8);
        d[..n].copy_from_slice(&data[..n]);
        CanFrame {
            id: id & 0x1FFF_FFFF,
            extended: true,
            len: n as u8,
            data: d,
        }
    }

    pub fn payload(&self) -> &[u8] {
        &self.data[..(self.len as usize).min(8)]
    }
}

impl std::fmt::Display for CanFrame {
    /// candump's compact form: `02000100#0064`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.extended {
            write!(f, "{:08X}#", self.id)?;
        } else {
            write!(f, "{:03X}#", self.id)?;
        }
        for b in self.payload() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

pub const JOYSTICK_MASK: u32 = 0x1FFF_0000;
pub const JOYSTICK_BASE: u32 = 0x0200_0000;
pub const JSM_HEARTBEAT_ID: u32 = 0x03C3_0F0F;
/// Sent three times, it silences the JSM's joystick frames (JSMerror mode).
pub const JSM_SILENCE_ID: u32 = 0x0C00_0000;

/// The device nibble of a joystick id `0x02000X00` (for the max-speed and
/// horn frames of the same device).
pub fn device_of(joystick_id: u32) -> u8 {
    ((joystick_id >> 8) & 0x0F) as u8
}

pub fn joystick_frame(joystick_id: u32, x: i8, y: i8) -> CanFrame {
    CanFrame::ext(joystick_id, &[x as u8, y as u8])
}

/// Maximum speed, 0..100 %.
pub fn max_speed_frame(device: u8, percent: u8) -> CanFrame {
    CanFrame::ext(
        0x0A04_0000 | ((device as u32 & 0xF) << 8),
        &[percent.min(100)],
    )
}

pub fn horn_frame(device: u8, on: bool) -> CanFrame {
    CanFrame::ext(
        0x0C04_0000 | ((device as u32 & 0xF) << 8) | if on { 0 } else { 1 },
        &[],
    )
}

pub fn jsm_silence_frame() -> CanFrame {
    CanFrame::ext(JSM_SILENCE_ID, &[])
}

/// What a frame on the bus means.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum RnetMessage {
    /// A joystick position (the JSM's, or ours echoed).
    Joystick {
        id: u32,
        x: i8,
        y: i8,
    },
    JsmHeartbeat,
    PowerModuleHeartbeat {
        device: u8,
    },
    /// Battery charge, %.
    Battery {
        device: u8,
        percent: u8,
    },
    /// Motor current, raw little-endian u16.
    MotorCurrent {
        device: u8,
        raw: u16,
    },
    /// Odometer counters, raw little-endian u32 each.
    Distance {
        device: u8,
        left: u32,
        right: u32,
    },
    MaxSpeed {
        device: u8,
        percent: u8,
    },
    Other,
}

/// Decodes one frame; malformed frames of a known id are `Other` (never a
/// panic, never a guess).
pub fn decode(f: &CanFrame) -> RnetMessage {
    let p = f.payload();
    if !f.extended {
        return RnetMessage::Other;
    }
    let dev = ((f.id >> 8) & 0xF) as u8;
    match f.id & 0x1FFF_F0FF {
        _ if f.id & JOYSTICK_MASK == JOYSTICK_BASE && p.len() == 2 => RnetMessage::Joystick {
            id: f.id,
            x: p[0] as i8,
            y: p[1] as i8,
        },
        _ if f.id == JSM_HEARTBEAT_ID => RnetMessage::JsmHeartbeat,
        0x0C14_0000 => RnetMessage::PowerModuleHeartbeat { device: dev },
        0x1C0C_0000 if p.len() == 1 => RnetMessage::Battery {
            device: dev,
            percent: p[0],
        },
        0x1430_0000 if p.len() == 2 => RnetMessage::MotorCurrent {
            device: dev,
            raw: u16::from_le_bytes([p[0], p[1]]),
        },
        0x1C30_0004 if p.len() == 8 => RnetMessage::Distance {
            device: dev,
            left: u32::from_le_bytes([p[0], p[1], p[2], p[3]]),
            right: u32::from_le_bytes([p[4], p[5], p[6], p[7]]),
        },
        0x0A04_0000 if p.len() == 1 => RnetMessage::MaxSpeed {
            device: dev,
            percent: p[0],
        },
        _ => RnetMessage::Other,
    }
}

/// The chair's calibration: joystick full scale in physical units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JoystickMapping {
    /// Forward speed at Y = +100, m/s.
    pub forward_full_mps: f64,
    /// Reverse speed at Y = −100, m/s (positive number).
    pub reverse_full_mps: f64,
    /// Turn rate at |X| = 100, rad/s.
    pub turn_full_radps: f64,
    /// Joystick values with |v| below this are sent as 0.
    pub deadband: i8,
}

impl JoystickMapping {
    /// Velocity → joystick: Y from `v_mps` (forward positive), X from
    /// `omega_radps` (our positive = left = R-Net negative X), rounded,
    /// clamped to ±100, dead-banded.
    pub fn to_joystick(&self, v_mps: f64, omega_radps: f64) -> (i8, i8) {
        let y = if v_mps >= 0.0 {
            v_mps / self.forward_full_mps * 100.0
        } else {
            v_mps / self.reverse_full_mps * 100.0
        };
        let x = -omega_radps / self.turn_full_radps * 100.0;
        let q = |v: f64| -> i8 {
            if !v.is_finite() {
                return 0;
            }
            let r = v.round().clamp(-100.0, 100.0) as i8;
            if r.unsigned_abs() < self.deadband.unsigned_abs() {
                0
            } else {
                r
            }
        };
        (q(x), q(y))
    }

    /// Joystick → velocity (v m/s, ω rad/s), the inverse mapping.
    pub fn to_velocity(&self, x: i8, y: i8) -> (f64, f64) {
        let v = if y >= 0 {
            y as f64 / 100.0 * self.forward_full_mps
        } else {
            y as f64 / 100.0 * self.reverse_full_mps
        };
        (v, -(x as f64) / 100.0 * self.turn_full_radps)
    }
}

/// How we take over from the JSM.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TakeoverMode {
    /// Silence the JSM's joystick frames and send ours every 10 ms.
    JsmError,
    /// Send ours right after each JSM frame; any deflection of the real
    /// joystick means the user steers: we yield.
    FollowJsm,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum TakeoverState {
    /// Listening for the JSM to learn its joystick id.
    Listening,
    /// JSMerror: silence frames sent, waiting for the JSM to go quiet.
    Silencing,
    /// Our frames drive the chair.
    Active,
    /// The user deflected the real joystick (FollowJSM): we send nothing
    /// but centred frames until it returns to centre and autonomy restarts.
    Yielded,
    /// Released on shutdown: we send nothing.
    Released,
}

/// Why the takeover reports a problem to the supervisor.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum TakeoverEvent {
    /// The joystick id was learned.
    Learned(u32),
    /// The user moved the real joystick.
    UserDeflection { x: i8, y: i8 },
    /// The JSM's heartbeat stopped for longer than the limit.
    JsmLost,
    /// More frames on our joystick id in one window than the JSM and we
    /// account for: another program drives the chair too.
    OtherWriter { frames: u32, expected: u32 },
}

/// The window over which frames on our joystick id are counted.
pub const OTHER_WRITER_WINDOW: Duration = Duration::from_millis(100);
/// Frames beyond the expected count a window tolerates (a late frame
/// landing in the next window, bus jitter).
pub const OTHER_WRITER_SLACK: u32 = 3;

/// The takeover and the 10 ms writer rule, as a pure state machine.
///
/// - Commands (joystick x, y with their stamp) come from the supervisor;
///   a command older than `command_max_age` sends centred frames instead.
/// - It starts only from centred frames: the first frames after
///   activation are centred until the command arrives.
#[derive(Debug, Clone)]
pub struct Takeover {
    pub mode: TakeoverMode,
    pub state: TakeoverState,
    joystick_id: Option<u32>,
    silence_sent_at: Option<Stamp>,
    last_jsm_joystick: Option<Stamp>,
    last_jsm_heartbeat: Option<Stamp>,
    command: Option<(i8, i8, Stamp)>,
    /// Our frames sent since activation (the first ones are centred).
    sent: u64,
    pub command_max_age: Duration,
    pub period: Duration,
    last_sent: Option<Stamp>,
    /// Frames not sent because their slot had passed.
    pub late_frames: u64,
    /// Frames on our joystick id in the current window, and its start.
    window: Option<(Stamp, u32)>,
    /// The last whole window had more frames than accounted for.
    last_window_over: bool,
    other_writer_reported: bool,
}

impl Takeover {
    pub fn new(mode: TakeoverMode) -> Self {
        Takeover {
            mode,
            state: TakeoverState::Listening,
            joystick_id: None,
            silence_sent_at: None,
            last_jsm_joystick: None,
            last_jsm_heartbeat: None,
            command: None,
            sent: 0,
            command_max_age: Duration::from_millis(100),
            period: Duration::from_millis(10),
            last_sent: None,
            late_frames: 0,
            window: None,
            last_window_over: false,
            other_writer_reported: false,
        }
    }

    /// Frames on our joystick id the JSM accounts for in one window: one
    /// per period under FollowJSM (ours are not echoed back to us); none
    /// once JSMerror has silenced it.
    fn expected_per_window(&self) -> Option<u32> {
        let per_window = (OTHER_WRITER_WINDOW.as_nanos() / self.period.as_nanos().max(1)) as u32;
        match (self.mode, self.state) {
            (TakeoverMode::FollowJsm, TakeoverState::Active | TakeoverState::Yielded) => {
                Some(per_window)
            }
            (TakeoverMode::JsmError, TakeoverState::Active) => Some(0),
            _ => None,
        }
    }

    /// Counts a frame on our id at `now`: too many in two windows in a row
    /// → the event (once). Frames are stamped when they are read, so a
    /// reader that stalled reads the frames it missed in a burst: that
    /// fills one window and leaves the next short, where another writer
    /// fills every window.
    fn count_own_id(&mut self, now: Stamp) -> Option<TakeoverEvent> {
        let expected = self.expected_per_window()?;
        let limit = expected + OTHER_WRITER_SLACK;
        let (start, n) = match self.window {
            Some((start, n)) if start.age_at(now) < OTHER_WRITER_WINDOW => (start, n + 1),
            Some((start, n)) => {
                // the window closed: was it over, and is the next adjacent
                let adjacent = start.age_at(now) < OTHER_WRITER_WINDOW * 2;
                self.last_window_over = n > limit && adjacent;
                (now, 1)
            }
            None => (now, 1),
        };
        self.window = Some((start, n));
        if n > limit && self.last_window_over && !self.other_writer_reported {
            self.other_writer_reported = true;
            return Some(TakeoverEvent::OtherWriter {
                frames: n,
                expected,
            });
        }
        None
    }

    pub fn joystick_id(&self) -> Option<u32> {
        self.joystick_id
    }

    /// The supervisor's latest command (already capped and checked).
    pub fn set_command(&mut self, x: i8, y: i8, stamp: Stamp) {
        self.command = Some((x, y, stamp));
    }

    /// The frame values to send at `now`: the command if fresh, else centred.
    pub fn output_at(&self, now: Stamp) -> (i8, i8) {
        match self.command {
            Some((x, y, t)) if t.age_at(now) <= self.command_max_age && self.sent > 0 => (x, y),
            _ => (0, 0),
        }
    }

    /// A frame received from the bus at `now`; returns frames to send now
    /// and an event for the supervisor.
    pub fn on_frame(&mut self, f: &CanFrame, now: Stamp) -> (Vec<CanFrame>, Option<TakeoverEvent>) {
        let mut out = Vec::new();
        let mut event = None;
        match decode(f) {
            RnetMessage::JsmHeartbeat => self.last_jsm_heartbeat = Some(now),
            RnetMessage::Joystick { id, x, y } => {
                // our own frames are not echoed by SocketCAN by default; a
                // joystick frame on the bus is the JSM's
                if self.joystick_id.is_none() && self.state == TakeoverState::Listening {
                    self.joystick_id = Some(id);
                    event = Some(TakeoverEvent::Learned(id));
                    if self.mode == TakeoverMode::JsmError {
                        out.extend([jsm_silence_frame(); 3]);
                        self.silence_sent_at = Some(now);
                        self.state = TakeoverState::Silencing;
                    } else {
                        self.state = TakeoverState::Active;
                    }
                }
                if Some(id) == self.joystick_id {
                    let other = self.count_own_id(now);
                    self.last_jsm_joystick = Some(now);
                    let deflected = x != 0 || y != 0;
                    match (self.mode, self.state) {
                        (TakeoverMode::FollowJsm, TakeoverState::Active) if deflected => {
                            self.state = TakeoverState::Yielded;
                            self.command = None;
                            event = Some(TakeoverEvent::UserDeflection { x, y });
                        }
                        (TakeoverMode::FollowJsm, TakeoverState::Yielded) if !deflected => {
                            // back at centre: autonomy may resume from centred frames
                            self.state = TakeoverState::Active;
                            self.sent = 0;
                        }
                        (TakeoverMode::FollowJsm, TakeoverState::Active) => {
                            // ours right after theirs
                            let (ox, oy) = self.output_at(now);
                            out.push(joystick_frame(id, ox, oy));
                            self.sent += 1;
                            self.last_sent = Some(now);
                        }
                        (TakeoverMode::JsmError, TakeoverState::Active) if deflected => {
                            // the JSM is not silenced any more: the user steers
                            self.state = TakeoverState::Yielded;
                            self.command = None;
                            event = Some(TakeoverEvent::UserDeflection { x, y });
                        }
                        _ => {}
                    }
                    // a second writer outranks what its frames look like
                    if other.is_some() {
                        event = other;
                    }
                }
            }
            _ => {}
        }
        (out, event)
    }

    /// The 10 ms tick of the writer at `now`: in JSMerror mode, our frame
    /// (or none when not active); also moves Silencing → Active once the
    /// JSM has been quiet for two periods.
    pub fn tick(&mut self, now: Stamp) -> Option<CanFrame> {
        if self.state == TakeoverState::Silencing {
            let quiet_since = self.last_jsm_joystick.max(self.silence_sent_at);
            if quiet_since.is_some_and(|t| t.age_at(now) >= self.period * 2) {
                self.state = TakeoverState::Active;
                self.sent = 0;
            }
        }
        if self.mode != TakeoverMode::JsmError || self.state != TakeoverState::Active {
            return None;
        }
        let id = self.joystick_id?;
        // a slot missed by more than a period is not sent late
        if let Some(last) = self.last_sent {
            if last.age_at(now) > self.period * 2 {
                self.late_frames += 1;
            }
        }
        let (x, y) = self.output_at(now);
        self.sent += 1;
        self.last_sent = Some(now);
        Some(joystick_frame(id, x, y))
    }

    /// Shutdown: centred frames are due for a while (the caller sends
    /// `tick` output for 200 ms with the command cleared), then release.
    pub fn clear_command(&mut self) {
        self.command = None;
    }

    pub fn release(&mut self) {
        self.command = None;
        self.state = TakeoverState::Released;
    }

    /// True when the JSM heartbeat is older than `limit` (or never seen).
    pub fn jsm_lost(&self, now: Stamp, limit: Duration) -> bool {
        self.last_jsm_heartbeat
            .is_none_or(|t| t.age_at(now) > limit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: u64) -> Stamp {
        Stamp(Duration::from_millis(v))
    }

    #[test]
    fn golden_frames_from_the_reference() {
        let id = 0x0200_0100;
        assert_eq!(joystick_frame(id, 0, 100).to_string(), "02000100#0064");
        assert_eq!(joystick_frame(id, 0, -100).to_string(), "02000100#009C");
        assert_eq!(joystick_frame(id, 100, 0).to_string(), "02000100#6400");
        assert_eq!(joystick_frame(id, -100, 0).to_string(), "02000100#9C00");
        assert_eq!(joystick_frame(id, 0, 0).to_string(), "02000100#0000");
        assert_eq!(max_speed_frame(1, 50).to_string(), "0A040100#32");
        assert_eq!(horn_frame(1, true).to_string(), "0C040100#");
        assert_eq!(horn_frame(1, false).to_string(), "0C040101#");
        assert_eq!(jsm_silence_frame().to_string(), "0C000000#");
        assert_eq!(device_of(0x0200_1100), 1);
    }

    #[test]
    fn decoding_what_the_chair_says() {
        let f = |id: u32, d: &[u8]| decode(&CanFrame::ext(id, d));
        assert_eq!(
            f(0x0200_0200, &[0x9C, 0x64]),
            RnetMessage::Joystick {
                id: 0x0200_0200,
                x: -100,
                y: 100
            }
        );
        assert_eq!(f(JSM_HEARTBEAT_ID, &[0x87; 8]), RnetMessage::JsmHeartbeat);
        assert_eq!(
            f(0x1C0C_0100, &[77]),
            RnetMessage::Battery {
                device: 1,
                percent: 77
            }
        );
        assert_eq!(
            f(0x1430_0100, &[0x34, 0x12]),
            RnetMessage::MotorCurrent {
                device: 1,
                raw: 0x1234
            }
        );
        assert_eq!(
            f(0x1C30_0104, &[1, 0, 0, 0, 2, 0, 0, 0]),
            RnetMessage::Distance {
                device: 1,
                left: 1,
                right: 2
            }
        );
        assert_eq!(
            f(0x0C14_0100, &[0]),
            RnetMessage::PowerModuleHeartbeat { device: 1 }
        );
        // wrong lengths are not guessed
        assert_eq!(f(0x0200_0100, &[1]), RnetMessage::Other);
        assert_eq!(f(0x1C0C_0100, &[]), RnetMessage::Other);
        let std = CanFrame {
            id: 0x0E,
            extended: false,
            len: 8,
            data: [0; 8],
        };
        assert_eq!(decode(&std), RnetMessage::Other);
    }

    #[test]
    fn velocity_mapping_signs_clamps_and_deadband() {
        let m = JoystickMapping {
            forward_full_mps: 1.0,
            reverse_full_mps: 0.5,
            turn_full_radps: 1.0,
            deadband: 3,
        };
        assert_eq!(m.to_joystick(0.3, 0.0), (0, 30));
        assert_eq!(m.to_joystick(-0.25, 0.0), (0, -50));
        // our omega positive = left = R-Net X negative
        assert_eq!(m.to_joystick(0.0, 0.4), (-40, 0));
        assert_eq!(m.to_joystick(5.0, -5.0), (100, 100));
        assert_eq!(m.to_joystick(0.02, 0.0), (0, 0));
        assert_eq!(m.to_joystick(f64::NAN, f64::INFINITY), (0, 0));
        let (v, w) = m.to_velocity(-40, 30);
        assert!((v - 0.3).abs() < 1e-12 && (w - 0.4).abs() < 1e-12);
    }

    #[test]
    fn jsm_error_takeover_learns_silences_then_drives_from_centre() {
        let mut t = Takeover::new(TakeoverMode::JsmError);
        assert_eq!(t.tick(ms(0)), None);
        let (out, ev) = t.on_frame(&joystick_frame(0x0200_0100, 0, 0), ms(5));
        assert_eq!(ev, Some(TakeoverEvent::Learned(0x0200_0100)));
        assert_eq!(out, vec![jsm_silence_frame(); 3]);
        assert_eq!(t.state, TakeoverState::Silencing);
        assert_eq!(t.tick(ms(15)), None);
        // quiet for two periods → active; the first frame is centred even with a command
        t.set_command(10, 40, ms(24));
        assert_eq!(t.tick(ms(25)).unwrap().to_string(), "02000100#0000");
        assert_eq!(t.state, TakeoverState::Active);
        assert_eq!(t.tick(ms(35)).unwrap().to_string(), "02000100#0A28");
        // a command is used up to 100 ms old, then centred frames
        assert_eq!(t.tick(ms(124)).unwrap().to_string(), "02000100#0A28");
        assert_eq!(t.tick(ms(125)).unwrap().to_string(), "02000100#0000");
        // release: nothing more
        t.release();
        assert_eq!(t.tick(ms(145)), None);
    }

    #[test]
    fn follow_jsm_sends_after_each_jsm_frame_and_yields_to_the_user() {
        let mut t = Takeover::new(TakeoverMode::FollowJsm);
        let id = 0x0200_0100;
        let (out, _) = t.on_frame(&joystick_frame(id, 0, 0), ms(0));
        assert!(out.is_empty() || out[0].to_string() == "02000100#0000");
        t.set_command(0, 50, ms(5));
        let (out, _) = t.on_frame(&joystick_frame(id, 0, 0), ms(10));
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].to_string(), "02000100#0032");
        // the user pushes the real joystick: yield at once, nothing sent
        let (out, ev) = t.on_frame(&joystick_frame(id, 0, 30), ms(20));
        assert!(out.is_empty());
        assert_eq!(ev, Some(TakeoverEvent::UserDeflection { x: 0, y: 30 }));
        assert_eq!(t.state, TakeoverState::Yielded);
        // while yielded, even a fresh command is not sent
        t.set_command(0, 50, ms(25));
        let (out, _) = t.on_frame(&joystick_frame(id, 0, 30), ms(30));
        assert!(out.is_empty());
        // back at centre: active again, starting from a centred frame
        let (out, _) = t.on_frame(&joystick_frame(id, 0, 0), ms(40));
        assert!(out.is_empty());
        assert_eq!(t.state, TakeoverState::Active);
        t.set_command(0, 50, ms(45));
        let (out, _) = t.on_frame(&joystick_frame(id, 0, 0), ms(50));
        assert_eq!(out[0].to_string(), "02000100#0000");
        let (out, _) = t.on_frame(&joystick_frame(id, 0, 0), ms(60));
        assert_eq!(out[0].to_string(), "02000100#0032");
        // the tick sends nothing in this mode
        assert_eq!(t.tick(ms(65)), None);
    }

    #[test]
    fn another_writer_on_our_joystick_id_is_reported_once() {
        // FollowJSM: the JSM's one frame per 10 ms is expected
        let mut t = Takeover::new(TakeoverMode::FollowJsm);
        let id = 0x0200_0000;
        let mut events = Vec::new();
        for k in 0..100u64 {
            let (_, e) = t.on_frame(&joystick_frame(id, 0, 0), ms(k * 10));
            events.extend(e);
        }
        assert_eq!(events, vec![TakeoverEvent::Learned(id)]);
        // a second program sends on the same id every 10 ms as well
        let mut events = Vec::new();
        for k in 100..200u64 {
            events.extend(t.on_frame(&joystick_frame(id, 0, 0), ms(k * 10)).1);
            events.extend(t.on_frame(&joystick_frame(id, 10, 0), ms(k * 10 + 3)).1);
        }
        let other: Vec<_> = events
            .iter()
            .filter(|e| matches!(e, TakeoverEvent::OtherWriter { .. }))
            .collect();
        assert_eq!(
            other,
            vec![&TakeoverEvent::OtherWriter {
                frames: 14,
                expected: 10
            }]
        );

        // a reader that stalled 60 ms reads the frames it missed at once:
        // one full window, then a short one — not another writer
        let mut t = Takeover::new(TakeoverMode::FollowJsm);
        let mut events = Vec::new();
        for k in 0..100u64 {
            events.extend(t.on_frame(&joystick_frame(id, 0, 0), ms(k * 10)).1);
        }
        for _ in 0..6 {
            events.extend(t.on_frame(&joystick_frame(id, 0, 0), ms(1060)).1);
        }
        for k in 107..300u64 {
            events.extend(t.on_frame(&joystick_frame(id, 0, 0), ms(k * 10)).1);
        }
        assert_eq!(events, vec![TakeoverEvent::Learned(id)]);

        // JSMerror: once the JSM is silent, any steady stream on our id is
        // another writer
        let mut t = Takeover::new(TakeoverMode::JsmError);
        t.on_frame(&joystick_frame(id, 0, 0), ms(0));
        assert_eq!(t.state, TakeoverState::Silencing);
        t.tick(ms(30));
        assert_eq!(t.state, TakeoverState::Active);
        let mut events = Vec::new();
        for k in 4..20u64 {
            events.extend(t.on_frame(&joystick_frame(id, 0, 0), ms(k * 10)).1);
        }
        assert_eq!(
            events,
            vec![TakeoverEvent::OtherWriter {
                frames: 4,
                expected: 0
            }]
        );
    }

    #[test]
    fn heartbeat_watch() {
        let mut t = Takeover::new(TakeoverMode::JsmError);
        assert!(t.jsm_lost(ms(0), Duration::from_millis(300)));
        t.on_frame(&CanFrame::ext(JSM_HEARTBEAT_ID, &[0x87; 8]), ms(100));
        assert!(!t.jsm_lost(ms(350), Duration::from_millis(300)));
        assert!(t.jsm_lost(ms(401), Duration::from_millis(300)));
    }
}
