//! The Rebus link (pure) and the Rebus backend (serial I/O around it).
//!
//! Stop-and-wait as the chipset expects: one DATA packet outstanding at a
//! time; each waits at most `ack_timeout` (50 ms) for its ACK. Start-up
//! sends DATA `[01]` with the start-up flag; its ACK, answered with ours,
//! brings the link up.
//! Every 10 ms tick sends a velocity packet `[0B 00 00 vx vy]` carrying the
//! supervisor's command while younger than `command_max_age` (100 ms),
//! else centred; the first packet after start-up is centred. NACKs and
//! timeouts are counted; `max_failures` in a row take the link down (a
//! `Fault` for the supervisor) and start-up is retried after a back-off.
//! Every DATA from the chipset is ACKed. The decoder resynchronises after
//! garbage.

use std::io::{Read, Write};
use std::time::Duration;

use serde::Serialize;
use tokio::sync::mpsc::error::TrySendError;

use super::rebus::{Decoder, Kind, Packet};
use super::rnet::JoystickMapping;
use super::{Actuator, ActuatorError, ActuatorEvent, ActuatorIo, ActuatorStatus};
use crate::msg::{FaultReason, Stamp};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RebusSettings {
    pub mapping: JoystickMapping,
    pub period: Duration,
    pub ack_timeout: Duration,
    pub command_max_age: Duration,
    /// NACKs/timeouts in a row that take the link down.
    pub max_failures: u32,
    /// Wait before retrying start-up after the link went down.
    pub restart_after: Duration,
    /// Centred packets on shutdown before going quiet.
    pub release_after: Duration,
}

impl RebusSettings {
    pub fn new(mapping: JoystickMapping) -> RebusSettings {
        RebusSettings {
            mapping,
            period: Duration::from_millis(10),
            ack_timeout: Duration::from_millis(50),
            command_max_age: Duration::from_millis(100),
            max_failures: 5,
            restart_after: Duration::from_millis(200),
            release_after: Duration::from_millis(200),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum LinkState {
    Starting,
    Up,
    /// Down after repeated failures; start-up is retried after a back-off.
    Down,
    Released,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct RebusStats {
    pub sent: u64,
    pub acked: u64,
    pub nacked: u64,
    pub timeouts: u64,
    /// ACK/NACK for a packet not outstanding.
    pub stray: u64,
    pub decode_errors: u64,
    /// DATA packets from the chipset (each ACKed).
    pub chipset_data: u64,
}

#[derive(Debug, Clone, Copy)]
struct Outstanding {
    seq: u8,
    sent_at: Stamp,
    startup: bool,
}

/// What the link tells its owner.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkEvent {
    Up,
    Down(String),
}

#[derive(Debug, Clone)]
pub struct RebusLink {
    pub settings: RebusSettings,
    pub state: LinkState,
    pub stats: RebusStats,
    next_seq: u8,
    outstanding: Option<Outstanding>,
    command: Option<(i8, i8, Stamp)>,
    sent_since_up: u64,
    failures: u32,
    down_since: Option<Stamp>,
    /// Values of the last velocity packet sent.
    pub last_output: (i8, i8),
}

impl RebusLink {
    pub fn new(settings: RebusSettings) -> RebusLink {
        RebusLink {
            settings,
            state: LinkState::Starting,
            stats: RebusStats::default(),
            next_seq: 0,
            outstanding: None,
            command: None,
            sent_since_up: 0,
            failures: 0,
            down_since: None,
            last_output: (0, 0),
        }
    }

    fn take_seq(&mut self) -> u8 {
        let s = self.next_seq;
        self.next_seq = (self.next_seq + 1) & 0x1F;
        s
    }

    pub fn set_command(&mut self, x: i8, y: i8, stamp: Stamp) {
        self.command = Some((x, y, stamp));
    }

    pub fn clear_command(&mut self) {
        self.command = None;
    }

    pub fn release(&mut self) {
        self.command = None;
        self.state = LinkState::Released;
    }

    /// The values due at `now`: the command while fresh (never the first
    /// packet after start-up), else centred.
    pub fn output_at(&self, now: Stamp) -> (i8, i8) {
        match self.command {
            Some((x, y, t))
                if t.age_at(now) <= self.settings.command_max_age && self.sent_since_up > 0 =>
            {
                (x, y)
            }
            _ => (0, 0),
        }
    }

    fn failure(&mut self, now: Stamp, why: &str) -> Option<LinkEvent> {
        self.failures += 1;
        if self.failures >= self.settings.max_failures
            && matches!(self.state, LinkState::Up | LinkState::Starting)
        {
            let starting = self.state == LinkState::Starting;
            self.state = LinkState::Down;
            self.down_since = Some(now);
            let n = self.failures;
            self.failures = 0;
            if starting {
                // the chipset accepts one controlling program per power-up
                // (rnet-serial-interface's README): retrying will not help
                return Some(LinkEvent::Down(format!(
                    "the chipset does not answer start-up ({n} tries, last: {why}): restart it \
                     with its button (it must be restarted whenever its controlling program is)"
                )));
            }
            return Some(LinkEvent::Down(format!(
                "{n} packets in a row not acknowledged (last: {why})"
            )));
        }
        None
    }

    /// The 10 ms tick: the packet to write now, if any.
    pub fn tick(&mut self, now: Stamp) -> (Option<Packet>, Option<LinkEvent>) {
        let mut event = None;
        if let Some(o) = self.outstanding {
            if o.sent_at.age_at(now) < self.settings.ack_timeout {
                return (None, None); // still waiting for its ACK
            }
            self.outstanding = None;
            self.stats.timeouts += 1;
            event = self.failure(now, "ACK timeout");
        }
        let packet = match self.state {
            LinkState::Released => None,
            LinkState::Down => {
                if self
                    .down_since
                    .is_some_and(|t| t.age_at(now) >= self.settings.restart_after)
                {
                    self.state = LinkState::Starting;
                }
                None
            }
            LinkState::Starting => {
                let seq = self.take_seq();
                self.outstanding = Some(Outstanding {
                    seq,
                    sent_at: now,
                    startup: true,
                });
                Some(Packet::startup(seq))
            }
            LinkState::Up => {
                let (x, y) = self.output_at(now);
                let seq = self.take_seq();
                self.outstanding = Some(Outstanding {
                    seq,
                    sent_at: now,
                    startup: false,
                });
                self.sent_since_up += 1;
                self.last_output = (x, y);
                Some(Packet::velocity(seq, x, y))
            }
        };
        if packet.is_some() {
            self.stats.sent += 1;
        }
        (packet, event)
    }

    /// A packet from the chipset: returns the reply (an ACK for DATA).
    pub fn on_packet(&mut self, p: &Packet, now: Stamp) -> (Option<Packet>, Option<LinkEvent>) {
        match p.kind {
            Kind::Data => {
                self.stats.chipset_data += 1;
                (Some(Packet::ack(p.seq)), None)
            }
            Kind::Ack | Kind::Nack => {
                let Some(o) = self.outstanding.filter(|o| o.seq == p.seq) else {
                    self.stats.stray += 1;
                    return (None, None);
                };
                self.outstanding = None;
                if p.kind == Kind::Nack {
                    self.stats.nacked += 1;
                    return (None, self.failure(now, "NACK"));
                }
                self.stats.acked += 1;
                self.failures = 0;
                if o.startup && self.state == LinkState::Starting {
                    self.state = LinkState::Up;
                    self.sent_since_up = 0;
                    // the handshake ends with our ACK of the chipset's
                    // (rnet-serial-interface's Connect)
                    return (Some(Packet::ack(p.seq)), Some(LinkEvent::Up));
                }
                (None, None)
            }
        }
    }
}

/// The Rebus backend on a serial port (FTDI, 115200 8N1).
pub struct RebusActuator {
    pub port: String,
    pub settings: RebusSettings,
}

fn emit(io: &ActuatorIo, ev: ActuatorEvent) {
    tracing::info!(event = ?ev, "Rebus");
    if let Err(TrySendError::Full(ev)) = io.events.try_send(ev) {
        tracing::error!(event = ?ev, "actuator event queue full: event lost");
    }
}

impl RebusActuator {
    fn status(&self, link: &RebusLink, latency: &super::ViewLatency) -> ActuatorStatus {
        ActuatorStatus {
            backend: "rebus",
            state: format!("{:?}", link.state).to_lowercase(),
            joystick_id: None,
            sent: link.stats.sent,
            dropped: link.stats.timeouts + link.stats.nacked,
            late: 0,
            bus_errors: link.stats.decode_errors,
            last_output: link.last_output,
            period: Default::default(),
            period_run: Default::default(),
            frame_to_command: latency.stats(),
        }
    }

    /// The blocking loop (its own thread): ticks on the clock, reads with a
    /// 1 ms timeout in between.
    pub fn run_blocking(self, io: ActuatorIo) -> Result<ActuatorStatus, ActuatorError> {
        let s = self.settings;
        let mut port = serialport::new(&self.port, 115_200)
            .timeout(Duration::from_millis(1))
            .open()
            .map_err(|e| {
                ActuatorError::Rebus(format!(
                    "{}: {}",
                    self.port,
                    crate::sensors::serial_open_reason(&self.port, &e)
                ))
            })?;
        let mut link = RebusLink::new(s);
        let mut decoder = Decoder::default();
        let mut next_tick = io.clock.now();
        let mut release_at: Option<Stamp> = None;
        let mut buf = [0u8; 256];
        let mut ticks = 0u64;
        let mut latency = super::ViewLatency::default();
        let io_err = |what: &str, e: std::io::Error| {
            ActuatorError::Rebus(format!("{}: {what}: {e}", self.port))
        };
        loop {
            let now = io.clock.now();
            if release_at.is_none() && io.cancel.is_cancelled() {
                link.clear_command();
                release_at = Some(Stamp(now.0 + s.release_after));
            }
            if now >= next_tick {
                match release_at {
                    Some(at) if now >= at => {
                        link.release();
                        let st = self.status(&link, &latency);
                        io.status.send_replace(st.clone());
                        emit(&io, ActuatorEvent::Released);
                        return Ok(st);
                    }
                    Some(_) => link.clear_command(),
                    None => match *io.commands.borrow() {
                        Some(c) => {
                            let (x, y) = s.mapping.to_joystick(c.cmd.v_mps, c.cmd.omega_radps);
                            link.set_command(x, y, c.stamp);
                            latency.on_command(&c);
                        }
                        None => link.clear_command(),
                    },
                }
                let (packet, event) = link.tick(now);
                if let Some(p) = packet {
                    port.write_all(&p.encode())
                        .map_err(|e| io_err("write", e))?;
                    if link.state == LinkState::Up {
                        latency.on_sent(now);
                    }
                }
                self.link_event(&io, event);
                next_tick = Stamp(next_tick.0 + s.period);
                if next_tick <= now {
                    next_tick = Stamp(now.0 + s.period); // missed slots skipped
                }
                ticks += 1;
                if ticks.is_multiple_of(10) {
                    io.status.send_replace(self.status(&link, &latency));
                }
            }
            let n = match port.read(&mut buf) {
                Ok(n) => n,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                    ) =>
                {
                    0
                }
                Err(e) => {
                    emit(
                        &io,
                        ActuatorEvent::Fault {
                            kind: FaultReason::MotorLink,
                            reason: format!("{}: read: {e}", self.port),
                        },
                    );
                    return Err(io_err("read", e));
                }
            };
            let now = io.clock.now();
            for r in decoder.push(&buf[..n]) {
                match r {
                    Ok(p) => {
                        let (reply, event) = link.on_packet(&p, now);
                        if let Some(r) = reply {
                            port.write_all(&r.encode())
                                .map_err(|e| io_err("write", e))?;
                        }
                        self.link_event(&io, event);
                    }
                    Err(e) => {
                        link.stats.decode_errors += 1;
                        tracing::warn!(error = %e, "Rebus: bad bytes skipped");
                    }
                }
            }
        }
    }

    fn link_event(&self, io: &ActuatorIo, event: Option<LinkEvent>) {
        match event {
            Some(LinkEvent::Up) => {
                emit(io, ActuatorEvent::Ready { joystick_id: None });
                // the chipset drives from our packets once up: no takeover step
                emit(io, ActuatorEvent::Active);
            }
            Some(LinkEvent::Down(reason)) => emit(
                io,
                ActuatorEvent::Fault {
                    kind: FaultReason::MotorLink,
                    reason: format!("Rebus {}: {reason}", self.port),
                },
            ),
            None => {}
        }
    }
}

impl Actuator for RebusActuator {
    async fn run(self, io: ActuatorIo) -> Result<ActuatorStatus, ActuatorError> {
        tokio::task::spawn_blocking(move || self.run_blocking(io))
            .await
            .map_err(|e| ActuatorError::Task(e.to_string()))?
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: u64) -> Stamp {
        Stamp(Duration::from_millis(v))
    }

    fn link() -> RebusLink {
        RebusLink::new(RebusSettings::new(JoystickMapping {
            forward_full_mps: 1.0,
            reverse_full_mps: 0.5,
            turn_full_radps: 1.5,
            deadband: 3,
        }))
    }

    fn up(l: &mut RebusLink) {
        let (p, _) = l.tick(ms(0));
        let p = p.expect("startup");
        assert_eq!(p, Packet::startup(0));
        assert_eq!(p.encode(), vec![0x55, 0x06, 0x01, 0xBF, 0x01, 0x7A, 0xAF]);
        let (reply, ev) = l.on_packet(&Packet::ack(0), ms(2));
        assert_eq!(ev, Some(LinkEvent::Up));
        // the handshake's last step: our ACK of the chipset's ACK
        assert_eq!(reply, Some(Packet::ack(0)));
        assert_eq!(l.state, LinkState::Up);
    }

    #[test]
    fn startup_then_velocity_starting_centred_with_fresh_commands_only() {
        let mut l = link();
        up(&mut l);
        l.set_command(0, 20, ms(5));
        let (p, _) = l.tick(ms(10));
        assert_eq!(p, Some(Packet::velocity(1, 0, 0)), "first packet centred");
        // waiting for the ACK: nothing more is sent
        assert_eq!(l.tick(ms(20)).0, None);
        l.on_packet(&Packet::ack(1), ms(21));
        let (p, _) = l.tick(ms(30));
        assert_eq!(p, Some(Packet::velocity(2, 0, 20)));
        l.on_packet(&Packet::ack(2), ms(31));
        // 100 ms after its stamp the command is stale
        assert_eq!(l.tick(ms(105)).0, Some(Packet::velocity(3, 0, 20)));
        l.on_packet(&Packet::ack(3), ms(106));
        assert_eq!(l.tick(ms(106)).0, Some(Packet::velocity(4, 0, 0)));
    }

    #[test]
    fn a_chipset_that_never_answers_start_up_asks_for_its_restart_button() {
        let mut l = link();
        let mut down = None;
        for k in 0..40 {
            if let (_, Some(ev)) = l.tick(ms(10 * k)) {
                down = Some(ev);
                break;
            }
        }
        match down {
            Some(LinkEvent::Down(r)) => {
                assert!(r.contains("does not answer start-up"), "{r}");
                assert!(r.contains("restart it with its button"), "{r}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn ack_timeout_is_50_ms_and_five_failures_take_the_link_down() {
        let mut l = link();
        up(&mut l);
        let mut t = 10;
        let mut down = None;
        for _ in 0..40 {
            let (_, ev) = l.tick(ms(t));
            if ev.is_some() {
                down = Some((t, ev));
                break;
            }
            t += 10;
        }
        // packets at 10, 60, 110, 160, 210 ms time out at +50 ms each
        let (t_down, ev) = down.expect("link down");
        assert_eq!(t_down, 260);
        assert!(matches!(ev, Some(LinkEvent::Down(ref r)) if r.contains("5 packets")));
        assert_eq!(l.stats.timeouts, 5);
        assert_eq!(l.state, LinkState::Down);
        // start-up retried after 200 ms
        assert_eq!(l.tick(ms(300)).0, None);
        assert_eq!(l.tick(ms(460)).0, None);
        let (p, _) = l.tick(ms(470));
        assert!(p.expect("restart").startup);
    }

    #[test]
    fn nacks_count_as_failures_and_an_ack_resets_them() {
        let mut l = link();
        up(&mut l);
        for i in 0..4u64 {
            let (p, _) = l.tick(ms(10 + 10 * i));
            let seq = p.expect("packet").seq;
            let (_, ev) = l.on_packet(&Packet::nack(seq), ms(11 + 10 * i));
            assert_eq!(ev, None);
        }
        let (p, _) = l.tick(ms(50));
        l.on_packet(&Packet::ack(p.expect("packet").seq), ms(51));
        assert_eq!(l.stats.nacked, 4);
        assert_eq!(l.state, LinkState::Up);
        // a stray ACK changes nothing
        l.on_packet(&Packet::ack(30), ms(52));
        assert_eq!(l.stats.stray, 1);
    }

    #[test]
    fn chipset_data_is_acked_and_sequence_numbers_wrap_at_32() {
        let mut l = link();
        up(&mut l);
        let (reply, _) = l.on_packet(
            &Packet {
                seq: 9,
                startup: false,
                kind: Kind::Data,
                data: vec![1, 2],
            },
            ms(3),
        );
        assert_eq!(reply, Some(Packet::ack(9)));
        let mut t = 10;
        let mut seqs = Vec::new();
        for _ in 0..40 {
            let (p, _) = l.tick(ms(t));
            let seq = p.expect("packet").seq;
            seqs.push(seq);
            l.on_packet(&Packet::ack(seq), ms(t + 1));
            t += 10;
        }
        assert_eq!(seqs[30], 31);
        assert_eq!(seqs[31], 0);
    }
}
