//! Hokuyo URG-04LX-UG01 driver over SCIP 2.0 (codec in [`super::scip`]).
//!
//! The driver is blocking I/O on a serial port (USB CDC-ACM) and runs on its
//! own thread: connect (QT, SCIP 1.1 → `SCIP2.0`, timestamp mode → `TM2`,
//! mid-stream → QT and flush), `PP` for the angle table, `MD` continuous
//! streaming; every checksum error, garbage block, error status and
//! silence is counted, reported and recovered from (re-arming the laser),
//! and an unplugged device is reopened with backoff. The sensor's 24-bit
//! millisecond clock is unwrapped and mapped to the host's monotonic clock
//! with drift estimation ([`TimestampMapper`], pure).

use std::io::{Read, Write};
use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;
use thiserror::Error;

use super::clock::DeviceClock;
use super::scip::{
    classify, decode_ranges, parse_pp, parse_reply, scip11_status, Command, Reply, ReplyFramer,
    ScanRequest, ScipError, SensorParams,
};
use crate::msg::{Clock, LaserScan, Reading, Stamped};

impl LaserScan {
    pub fn from_values(
        params: &SensorParams,
        first_step: u32,
        values: &[u32],
        sensor_ms: u32,
    ) -> Self {
        let readings: Vec<Reading> = values.iter().map(|&v| classify(v)).collect();
        let ranges_m = readings
            .iter()
            .map(|r| match r {
                Reading::RangeMm(mm) if *mm <= params.dmax_mm => Some(*mm as f32 / 1000.0),
                _ => None,
            })
            .collect();
        LaserScan {
            sensor_ms,
            angle_min_rad: params.step_angle_rad(first_step),
            angle_increment_rad: std::f64::consts::TAU / params.ares as f64,
            ranges_m,
            readings,
        }
    }
}

/// JSON line of `opennav check hokuyo`.
#[derive(Debug, Serialize)]
pub struct ScanJson<'a> {
    pub stamp_s: f64,
    pub angle_min_rad: f64,
    pub angle_increment_rad: f64,
    pub ranges_m: &'a [Option<f32>],
}

/// The URG's clock: 24-bit milliseconds.
pub fn sensor_clock() -> DeviceClock {
    DeviceClock::new(24, 1e-3, 200)
}

#[derive(Debug, Error)]
pub enum HokuyoError {
    #[error("{port}: cannot open: {reason}")]
    Open { port: String, reason: String },
    #[error("{port}: device gone: {reason}")]
    Disconnected { port: String, reason: String },
    #[error("{port}: no answer to {command} within {timeout_ms} ms")]
    Silent {
        port: String,
        command: String,
        timeout_ms: u64,
    },
    #[error("{port}: {command} answered status {status}: {meaning}")]
    Status {
        port: String,
        command: String,
        status: String,
        meaning: String,
    },
    #[error("{port}: bad reply: {0}", port = .1)]
    Protocol(ScipError, String),
}

/// Counters of everything that went wrong, for status and logs.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct HokuyoStats {
    pub scans: u64,
    pub checksum_errors: u64,
    pub malformed_replies: u64,
    pub error_statuses: u64,
    pub silences: u64,
    pub rearms: u64,
    pub reconnects: u64,
}

/// The line speeds a serial URG may have been left at.
pub const STANDARD_BAUDS: [u32; 6] = [19_200, 57_600, 115_200, 250_000, 500_000, 750_000];

/// What a sensor's answer to `QT` says about the state it is in.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Probe {
    /// SCIP 2.0, stopped.
    Ready,
    /// A one-character status: SCIP 1.1 (send `SCIP2.0`).
    Scip11,
    /// `0E`: left in time-stamp mode (send `TM2`).
    TimeStamp,
    /// Another status.
    Status(Reply),
    /// Nothing within the reply timeout.
    Silent,
}

/// Driver settings.
#[derive(Debug, Clone)]
pub struct HokuyoSettings {
    pub port: String,
    pub baud: u32,
    /// No scan for this long: silence, the laser is re-armed.
    pub silence_timeout: Duration,
    /// Replies to commands must come within this.
    pub reply_timeout: Duration,
    /// A serial URG that does not answer at `baud` is tried at these
    /// (urg_library's list); a USB URG answers at any.
    pub try_bauds: Vec<u32>,
    /// Reopen attempts back off from `backoff_min` doubling to `backoff_max`.
    pub backoff_min: Duration,
    pub backoff_max: Duration,
}

impl HokuyoSettings {
    pub fn new(port: impl Into<String>) -> Self {
        HokuyoSettings {
            port: port.into(),
            baud: 115_200,
            silence_timeout: Duration::from_millis(500),
            reply_timeout: Duration::from_millis(500),
            try_bauds: STANDARD_BAUDS.to_vec(),
            backoff_min: Duration::from_millis(50),
            backoff_max: Duration::from_secs(2),
        }
    }
}

pub struct HokuyoDriver {
    settings: HokuyoSettings,
    clock: Arc<dyn Clock>,
    port: Option<Box<dyn serialport::SerialPort>>,
    framer: ReplyFramer,
    pending: std::collections::VecDeque<Vec<u8>>,
    params: Option<SensorParams>,
    request: ScanRequest,
    mapper: DeviceClock,
    pub stats: HokuyoStats,
    streaming: bool,
}

impl HokuyoDriver {
    pub fn new(settings: HokuyoSettings, clock: Arc<dyn Clock>) -> Self {
        HokuyoDriver {
            settings,
            clock,
            port: None,
            framer: ReplyFramer::default(),
            pending: Default::default(),
            params: None,
            request: ScanRequest {
                start: 44,
                end: 725,
                cluster: 1,
                interval: 0,
                scans: 0,
            },
            mapper: sensor_clock(),
            stats: HokuyoStats::default(),
            streaming: false,
        }
    }

    pub fn params(&self) -> Option<SensorParams> {
        self.params
    }

    fn port_name(&self) -> String {
        self.settings.port.clone()
    }

    fn gone(&mut self, e: impl std::fmt::Display) -> HokuyoError {
        self.port = None;
        self.streaming = false;
        HokuyoError::Disconnected {
            port: self.port_name(),
            reason: e.to_string(),
        }
    }

    fn open(&mut self, baud: u32) -> Result<(), HokuyoError> {
        let p = serialport::new(&self.settings.port, baud)
            .timeout(Duration::from_millis(20))
            .open()
            .map_err(|e| HokuyoError::Open {
                port: self.port_name(),
                reason: super::serial_open_reason(&self.settings.port, &e),
            })?;
        self.port = Some(p);
        self.framer.clear();
        self.pending.clear();
        Ok(())
    }

    fn send(&mut self, cmd: &Command) -> Result<(), HokuyoError> {
        let bytes = cmd.encode(None);
        let r = match self.port.as_mut() {
            Some(p) => p.write_all(&bytes).and_then(|_| p.flush()),
            None => return Err(self.gone("not open")),
        };
        r.map_err(|e| self.gone(e))
    }

    /// Reads until one reply block arrives or `timeout` passes (None).
    fn read_block(&mut self, timeout: Duration) -> Result<Option<Vec<u8>>, HokuyoError> {
        if let Some(b) = self.pending.pop_front() {
            return Ok(Some(b));
        }
        let start = self.clock.now();
        let mut buf = [0u8; 4096];
        loop {
            let n = match self.port.as_mut() {
                Some(p) => match p.read(&mut buf) {
                    Ok(0) => return Err(self.gone("end of file")),
                    Ok(n) => n,
                    Err(e)
                        if matches!(
                            e.kind(),
                            std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                        ) =>
                    {
                        0
                    }
                    Err(e) => return Err(self.gone(e)),
                },
                None => return Err(self.gone("not open")),
            };
            if n > 0 {
                match self.framer.push(&buf[..n]) {
                    Ok(blocks) => self.pending.extend(blocks),
                    Err(_) => self.stats.malformed_replies += 1,
                }
                if let Some(b) = self.pending.pop_front() {
                    return Ok(Some(b));
                }
            }
            if start.age_at(self.clock.now()) >= timeout {
                return Ok(None);
            }
        }
    }

    /// Sends `cmd` and waits for its reply (other blocks, e.g. leftover
    /// scans, are skipped).
    fn command(&mut self, cmd: &Command) -> Result<Reply, HokuyoError> {
        let echo = cmd.encode(None);
        let echo = &echo[..echo.len() - 1];
        self.send(cmd)?;
        let deadline = self.settings.reply_timeout;
        let start = self.clock.now();
        loop {
            let left = deadline.saturating_sub(start.age_at(self.clock.now()));
            let Some(block) = self.read_block(left)? else {
                return Err(HokuyoError::Silent {
                    port: self.port_name(),
                    command: String::from_utf8_lossy(echo).into_owned(),
                    timeout_ms: deadline.as_millis() as u64,
                });
            };
            match parse_reply(&block) {
                Ok(r) if r.echo == echo => return Ok(r),
                Ok(_) => continue,
                Err(ScipError::Checksum { .. }) => {
                    self.stats.checksum_errors += 1;
                    continue;
                }
                Err(_) => {
                    self.stats.malformed_replies += 1;
                    continue;
                }
            }
        }
    }

    fn expect_ok(&mut self, cmd: &Command, reply: &Reply) -> Result<(), HokuyoError> {
        if reply.status.is_ok() {
            return Ok(());
        }
        self.stats.error_statuses += 1;
        Err(HokuyoError::Status {
            port: self.port_name(),
            command: String::from_utf8_lossy(&reply.echo).into_owned(),
            status: reply.status.code(),
            meaning: reply.status.meaning(&cmd.encode(None)),
        })
    }

    /// Sends `QT` and reads what comes back until its answer or the reply
    /// timeout (scans in flight are skipped).
    fn probe(&mut self) -> Result<Probe, HokuyoError> {
        self.send(&Command::Qt)?;
        let start = self.clock.now();
        loop {
            let left = self
                .settings
                .reply_timeout
                .saturating_sub(start.age_at(self.clock.now()));
            let Some(block) = self.read_block(left)? else {
                return Ok(Probe::Silent);
            };
            if scip11_status(&block, b"QT").is_some() {
                return Ok(Probe::Scip11);
            }
            match parse_reply(&block) {
                Ok(r) if r.echo == b"QT" => {
                    return Ok(if r.status.is_ok() {
                        Probe::Ready
                    } else if &r.status.0 == b"0E" {
                        Probe::TimeStamp
                    } else {
                        Probe::Status(r)
                    });
                }
                // a scan or a leftover reply: skipped
                Ok(_) => continue,
                Err(ScipError::Checksum { .. }) => self.stats.checksum_errors += 1,
                Err(_) => self.stats.malformed_replies += 1,
            }
        }
    }

    /// Opens the port at `baud` and finds out the sensor's state; None
    /// when nothing answers.
    fn open_and_probe(&mut self, baud: u32) -> Result<Option<Probe>, HokuyoError> {
        self.port = None;
        self.open(baud)?;
        // stop whatever runs and drop what is in flight
        self.send(&Command::Qt)?;
        let _ = self.read_until_quiet(Duration::from_millis(60))?;
        match self.probe()? {
            Probe::Silent => Ok(None),
            p => Ok(Some(p)),
        }
    }

    /// Opens the port (if needed), brings the sensor into SCIP 2.0 with the
    /// stream stopped — from SCIP 1.1 (`SCIP2.0`), from time-stamp mode
    /// (`TM2`), at whatever standard speed a serial URG was left at —,
    /// reads PP, and starts MD streaming. The sensor clock's mapping starts
    /// afresh: a power-cycled sensor counts from zero again.
    pub fn connect(&mut self) -> Result<SensorParams, HokuyoError> {
        self.streaming = false;
        self.mapper = sensor_clock();
        let mut bauds = vec![self.settings.baud];
        bauds.extend(
            self.settings
                .try_bauds
                .iter()
                .filter(|b| **b != self.settings.baud),
        );
        let mut found = None;
        for baud in bauds {
            if let Some(p) = self.open_and_probe(baud)? {
                if baud != self.settings.baud {
                    tracing::warn!(port = %self.settings.port, baud, configured = self.settings.baud, "laser answers at another line speed");
                }
                found = Some(p);
                break;
            }
        }
        let Some(probe) = found else {
            self.port = None;
            return Err(HokuyoError::Silent {
                port: self.port_name(),
                command: "QT".into(),
                timeout_ms: self.settings.reply_timeout.as_millis() as u64,
            });
        };
        match probe {
            Probe::Ready => {}
            Probe::Scip11 => {
                tracing::info!(port = %self.settings.port, "laser speaks SCIP 1.1: switching to SCIP 2.0");
                self.send(&Command::Scip20)?;
                let _ = self.read_until_quiet(Duration::from_millis(60))?;
                match self.probe()? {
                    Probe::Ready => {}
                    other => return Err(self.not_ready("SCIP2.0", other)),
                }
            }
            Probe::TimeStamp => {
                tracing::info!(port = %self.settings.port, "laser left in time-stamp mode: leaving it (TM2)");
                let r = self.command(&Command::Tm(2))?;
                self.expect_ok(&Command::Tm(2), &r)?;
                match self.probe()? {
                    Probe::Ready => {}
                    other => return Err(self.not_ready("TM2", other)),
                }
            }
            Probe::Status(r) => self.expect_ok(&Command::Qt, &r)?,
            Probe::Silent => {}
        }
        let pp = self.command(&Command::Pp)?;
        self.expect_ok(&Command::Pp, &pp)?;
        let params = parse_pp(&pp).map_err(|e| HokuyoError::Protocol(e, self.port_name()))?;
        // parse_pp keeps AMAX within 4 digits
        let port = self.port_name();
        let step = |v: u32, key: &'static str| {
            u16::try_from(v).map_err(|_| {
                HokuyoError::Protocol(
                    ScipError::Parameter {
                        key: key.into(),
                        reason: format!("{v} beyond a scan request's range"),
                    },
                    port.clone(),
                )
            })
        };
        self.request.start = step(params.amin, "AMIN")?;
        self.request.end = step(params.amax, "AMAX")?;
        self.params = Some(params);
        self.start_stream()?;
        Ok(params)
    }

    /// The sensor still not ready after `after`.
    fn not_ready(&mut self, after: &str, p: Probe) -> HokuyoError {
        match p {
            Probe::Status(r) => {
                self.stats.error_statuses += 1;
                HokuyoError::Status {
                    port: self.port_name(),
                    command: format!("QT after {after}"),
                    status: r.status.code(),
                    meaning: r.status.meaning(b"QT"),
                }
            }
            Probe::Silent => HokuyoError::Silent {
                port: self.port_name(),
                command: format!("QT after {after}"),
                timeout_ms: self.settings.reply_timeout.as_millis() as u64,
            },
            other => HokuyoError::Status {
                port: self.port_name(),
                command: format!("QT after {after}"),
                status: format!("{other:?}"),
                meaning: "the sensor did not come into SCIP 2.0".into(),
            },
        }
    }

    fn start_stream(&mut self) -> Result<(), HokuyoError> {
        let md = Command::Md(self.request);
        let r = self.command(&md)?;
        self.expect_ok(&md, &r)?;
        self.streaming = true;
        Ok(())
    }

    fn read_until_quiet(&mut self, quiet: Duration) -> Result<usize, HokuyoError> {
        let mut n = 0;
        while self.read_block(quiet)?.is_some() {
            n += 1;
        }
        self.framer.clear();
        self.pending.clear();
        Ok(n)
    }

    /// Stops the stream and re-arms it (after errors or silence).
    pub fn rearm(&mut self) -> Result<(), HokuyoError> {
        self.stats.rearms += 1;
        self.streaming = false;
        self.send(&Command::Qt)?;
        let _ = self.read_until_quiet(Duration::from_millis(60))?;
        self.start_stream()
    }

    /// The next scan. Bad lines, garbage and error statuses are counted and
    /// recovered from here; a vanished device returns `Disconnected`.
    pub fn next_scan(&mut self) -> Result<Stamped<LaserScan>, HokuyoError> {
        loop {
            if self.port.is_none() || !self.streaming || self.params.is_none() {
                self.connect()?;
            }
            let Some(params) = self.params else { continue };
            let Some(block) = self.read_block(self.settings.silence_timeout)? else {
                self.stats.silences += 1;
                tracing::warn!(port = %self.settings.port, "laser silent: re-arming");
                self.rearm()?;
                continue;
            };
            let received = self.clock.now();
            let reply = match parse_reply(&block) {
                Ok(r) => r,
                Err(ScipError::Checksum { .. }) => {
                    self.stats.checksum_errors += 1;
                    tracing::warn!(port = %self.settings.port, "scan with a checksum error rejected");
                    continue;
                }
                Err(e) => {
                    self.stats.malformed_replies += 1;
                    tracing::warn!(port = %self.settings.port, error = %e, "malformed reply: resynchronising");
                    self.rearm()?;
                    continue;
                }
            };
            if !reply.echo.starts_with(b"MD") {
                self.stats.malformed_replies += 1;
                self.rearm()?;
                continue;
            }
            if !reply.status.is_ok() {
                self.stats.error_statuses += 1;
                tracing::warn!(port = %self.settings.port, status = %reply.status.code(), meaning = %reply.status.meaning(b"MD"), "scan error status: re-arming");
                self.rearm()?;
                continue;
            }
            let Some(ts) = reply.timestamp else {
                // the first MD reply (status 00) carries no scan
                continue;
            };
            let values = match decode_ranges(&reply.data, 3) {
                Ok(v) if v.len() == (self.request.end - self.request.start + 1) as usize => v,
                _ => {
                    self.stats.malformed_replies += 1;
                    continue;
                }
            };
            self.stats.scans += 1;
            let stamp = self.mapper.map(ts as u64, received);
            return Ok(Stamped::new(
                stamp,
                LaserScan::from_values(&params, self.request.start as u32, &values, ts),
            ));
        }
    }

    /// Reads scans, reconnecting with backoff after the device vanishes,
    /// until `keep_going` says stop. Each scan goes to `sink`.
    pub fn run(&mut self, mut sink: impl FnMut(Stamped<LaserScan>) -> bool) {
        let mut backoff = self.settings.backoff_min;
        loop {
            match self.next_scan() {
                Ok(scan) => {
                    backoff = self.settings.backoff_min;
                    if !sink(scan) {
                        let _ = self.send(&Command::Qt);
                        return;
                    }
                }
                Err(e) => {
                    tracing::warn!(error = %e, "laser: reconnecting in {:?}", backoff);
                    self.stats.reconnects += 1;
                    self.port = None;
                    std::thread::sleep(backoff);
                    backoff = (backoff * 2).min(self.settings.backoff_max);
                }
            }
        }
    }
}
