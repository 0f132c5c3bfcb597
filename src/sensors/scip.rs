//! Hokuyo SCIP 2.0 (URG-04LX-UG01): the pure codec. Command encoding, reply
//! framing (echo, status, timestamp, ≤ 64-char data lines each with its
//! checksum, blank-line end), 2/3/4-char decoding across line boundaries,
//! checksum verification (a bad line rejects the reply: no silent
//! acceptance), PP parsing, status codes and range error codes.
//! No I/O, no clock: the driver feeds bytes in and gets values out.

use std::collections::HashMap;

use thiserror::Error;

use crate::msg::{NoReturn, Reading};

#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ScipError {
    #[error("line {line}: checksum {got:?} but the line sums to {want:?}")]
    Checksum { line: usize, got: char, want: char },
    #[error("line {line}: {reason}")]
    Malformed { line: usize, reason: String },
    #[error("character {0:?} (0x{1:02x}) is outside SCIP's 6-bit alphabet")]
    BadChar(char, u8),
    #[error("{0} encoded characters do not divide into {1}-char values")]
    Length(usize, usize),
    #[error("PP reply lacks {0}")]
    MissingParameter(&'static str),
    #[error("PP parameter {key}: {reason}")]
    Parameter { key: String, reason: String },
    #[error("reply buffer exceeds {0} bytes without a blank line: stream out of step")]
    Overflow(usize),
}

/// SCIP's checksum of a line: the low 6 bits of the byte sum, plus 0x30.
pub fn checksum(bytes: &[u8]) -> u8 {
    let sum: u32 = bytes.iter().map(|&b| b as u32).sum();
    ((sum & 0x3F) as u8) + 0x30
}

/// Decodes 2, 3 or 4 SCIP characters (6 bits each, offset 0x30).
pub fn decode_value(chars: &[u8]) -> Result<u32, ScipError> {
    let mut v: u32 = 0;
    for &c in chars {
        if !(0x30..0x30 + 64).contains(&c) {
            return Err(ScipError::BadChar(c as char, c));
        }
        v = (v << 6) | (c - 0x30) as u32;
    }
    Ok(v)
}

/// Encodes `value` into `n` SCIP characters (the emulator's side).
/// Bits above 6·n are dropped.
pub fn encode_value(value: u32, n: usize) -> Vec<u8> {
    (0..n)
        .rev()
        .map(|k| (((value >> (6 * k)) & 0x3F) as u8) + 0x30)
        .collect()
}

/// Commands the host sends.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Command {
    /// Switch a SCIP 1.1 sensor to SCIP 2.0.
    Scip20,
    /// Version information.
    Vv,
    /// Sensor parameters.
    Pp,
    /// Status information.
    Ii,
    /// Laser on.
    Bm,
    /// Laser off, stop streaming.
    Qt,
    /// Reset.
    Rs,
    /// Time-stamp mode: 0 enter, 1 read, 2 leave.
    Tm(u8),
    /// Continuous or counted scans, 3-char (`MD`) or 2-char (`MS`) ranges.
    Md(ScanRequest),
    Ms(ScanRequest),
    /// One scan (laser must be on), 3-char (`GD`) or 2-char (`GS`).
    Gd {
        start: u16,
        end: u16,
        cluster: u8,
    },
    Gs {
        start: u16,
        end: u16,
        cluster: u8,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScanRequest {
    pub start: u16,
    pub end: u16,
    pub cluster: u8,
    /// Scans skipped between transmitted scans (0..9).
    pub interval: u8,
    /// Number of scans, 0 = continuous (0..99).
    pub scans: u8,
}

impl Command {
    /// The bytes on the wire, with an optional tag (≤ 16 printable
    /// characters, echoed back by the sensor). A longer or non-printable tag
    /// is cut to what is valid.
    pub fn encode(&self, tag: Option<&str>) -> Vec<u8> {
        let mut s = match self {
            Command::Scip20 => "SCIP2.0".to_string(),
            Command::Vv => "VV".into(),
            Command::Pp => "PP".into(),
            Command::Ii => "II".into(),
            Command::Bm => "BM".into(),
            Command::Qt => "QT".into(),
            Command::Rs => "RS".into(),
            Command::Tm(m) => format!("TM{}", m.min(&2)),
            Command::Md(r) | Command::Ms(r) => format!(
                "{}{:04}{:04}{:02}{:01}{:02}",
                if matches!(self, Command::Md(_)) {
                    "MD"
                } else {
                    "MS"
                },
                r.start.min(9999),
                r.end.min(9999),
                r.cluster.min(99),
                r.interval.min(9),
                r.scans.min(99)
            ),
            Command::Gd {
                start,
                end,
                cluster,
            }
            | Command::Gs {
                start,
                end,
                cluster,
            } => format!(
                "{}{:04}{:04}{:02}",
                if matches!(self, Command::Gd { .. }) {
                    "GD"
                } else {
                    "GS"
                },
                start.min(&9999),
                end.min(&9999),
                cluster.min(&99)
            ),
        };
        if let Some(t) = tag {
            let t: String = t
                .chars()
                .filter(|c| c.is_ascii_graphic() && *c != ';')
                .take(16)
                .collect();
            if !t.is_empty() {
                s.push(';');
                s.push_str(&t);
            }
        }
        s.push('\n');
        s.into_bytes()
    }
}

/// A reply's status code and what it means.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Status(pub [u8; 2]);

impl Status {
    pub fn code(&self) -> String {
        String::from_utf8_lossy(&self.0).into_owned()
    }

    pub fn is_ok(&self) -> bool {
        &self.0 == b"00" || &self.0 == b"99"
    }

    /// Meaning of the status, per the SCIP 2.0 specification.
    pub fn meaning(&self, command: &[u8]) -> String {
        let c = self.code();
        let n: Option<u32> = c.parse().ok();
        let scan = command.starts_with(b"MD") || command.starts_with(b"MS");
        match (c.as_str(), n) {
            ("00", _) => "command received without error".into(),
            ("99", _) => "scan data follows".into(),
            ("0A", _) | ("0B", _) | ("0C", _) | ("0D", _) | ("0F", _) | ("0H", _) | ("0I", _) => {
                format!("invalid command (status {c})")
            }
            ("0E", _) => "undefined command (sensor in SCIP 1.1 or bad command)".into(),
            ("0G", _) => "string (tag) too long".into(),
            (_, Some(1)) if command.starts_with(b"BM") => "laser malfunction".into(),
            (_, Some(2)) if command.starts_with(b"BM") => "laser already on".into(),
            (_, Some(1..=7)) if scan => format!("bad scan parameter (status {c})"),
            (_, Some(21..=49)) if scan => {
                "scan stopped: the sensor reports an abnormal condition".into()
            }
            (_, Some(50..=97)) => "hardware fault".into(),
            (_, Some(98)) => "resumed after a hardware fault".into(),
            _ => format!("status {c}"),
        }
    }
}

/// One reply, its lines checked and its data lines joined.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Reply {
    /// The command as echoed (without LF).
    pub echo: Vec<u8>,
    pub status: Status,
    /// The sensor's 24-bit millisecond counter, for scan replies.
    pub timestamp: Option<u32>,
    /// Data lines with their checksums stripped, concatenated (values may
    /// straddle lines).
    pub data: Vec<u8>,
    /// Data lines as sent, checksum removed (PP/VV/II parse these).
    pub lines: Vec<Vec<u8>>,
}

/// Verifies a line's checksum. `key_value` admits the `KEY:VALUE;S` form of
/// PP/VV/II lines whose sum excludes the ';'; scan data never gets that
/// leniency (';' is a valid data character, so a corrupted data line ending
/// in ';' would otherwise pass on the alternative sum).
fn check_line(line: &[u8], idx: usize, key_value: bool) -> Result<&[u8], ScipError> {
    let (&sum, body) = line.split_last().ok_or_else(|| ScipError::Malformed {
        line: idx,
        reason: "empty line where a checksummed line belongs".into(),
    })?;
    let want = checksum(body);
    if sum == want {
        return Ok(body);
    }
    // PP/VV/II lines `KEY:VALUE;S`: the sum excludes the ';' (urg_library
    // accepts both forms, so do we)
    if let Some((&semi, kv)) = body.split_last().filter(|_| key_value) {
        if semi == b';' && kv.contains(&b':') && checksum(kv) == sum {
            return Ok(body);
        }
    }
    Err(ScipError::Checksum {
        line: idx,
        got: sum as char,
        want: want as char,
    })
}

/// Parses one reply block: the bytes up to and including the blank line
/// (`…\n\n`). Scan replies (`MD`/`MS` with status 99, `GD`/`GS` with 00)
/// carry a timestamp line.
/// A SCIP 1.1 reply — the echo, a one-character status, a blank line —
/// to `echo`: its status character (SCIP 1.1 sensors answer `QT` so).
pub fn scip11_status(block: &[u8], echo: &[u8]) -> Option<u8> {
    let body = block.strip_suffix(b"\n\n")?;
    let mut lines = body.split(|&b| b == b'\n');
    let (e, st) = (lines.next()?, lines.next()?);
    (e == echo && st.len() == 1 && lines.next().is_none()).then_some(st[0])
}

pub fn parse_reply(block: &[u8]) -> Result<Reply, ScipError> {
    let body = block
        .strip_suffix(b"\n\n")
        .ok_or_else(|| ScipError::Malformed {
            line: 0,
            reason: "reply does not end with a blank line".into(),
        })?;
    let lines: Vec<&[u8]> = body.split(|&b| b == b'\n').collect();
    let echo = lines[0].to_vec();
    let status_line = lines.get(1).ok_or_else(|| ScipError::Malformed {
        line: 1,
        reason: "no status line".into(),
    })?;
    if status_line.len() != 3 {
        return Err(ScipError::Malformed {
            line: 1,
            reason: format!("status line has {} bytes, expected 3", status_line.len()),
        });
    }
    let st = check_line(status_line, 1, false)?;
    let status = Status([st[0], st[1]]);
    let scan_reply = ((echo.starts_with(b"MD") || echo.starts_with(b"MS")) && &status.0 == b"99")
        || ((echo.starts_with(b"GD") || echo.starts_with(b"GS")) && &status.0 == b"00");
    let mut rest = 2;
    let mut timestamp = None;
    if scan_reply {
        let l = lines.get(2).ok_or_else(|| ScipError::Malformed {
            line: 2,
            reason: "scan reply without a timestamp line".into(),
        })?;
        if l.len() != 5 {
            return Err(ScipError::Malformed {
                line: 2,
                reason: format!("timestamp line has {} bytes, expected 5", l.len()),
            });
        }
        timestamp = Some(decode_value(check_line(l, 2, false)?)?);
        rest = 3;
    }
    let mut data = Vec::new();
    let mut out_lines = Vec::new();
    for (i, l) in lines.iter().enumerate().skip(rest) {
        if l.len() > 65 {
            return Err(ScipError::Malformed {
                line: i,
                reason: format!("data line of {} bytes (at most 64 + checksum)", l.len()),
            });
        }
        let b = check_line(l, i, !scan_reply)?;
        data.extend_from_slice(b);
        out_lines.push(b.to_vec());
    }
    Ok(Reply {
        echo,
        status,
        timestamp,
        data,
        lines: out_lines,
    })
}

/// Splits a byte stream into reply blocks (each ending in a blank line).
/// Bounded: a stream with no blank line for `max_len` bytes is out of step.
#[derive(Debug, Clone)]
pub struct ReplyFramer {
    buf: Vec<u8>,
    max_len: usize,
}

impl Default for ReplyFramer {
    fn default() -> Self {
        // a full 3-char URG-04LX scan is about 2.2 kB
        ReplyFramer::new(16 * 1024)
    }
}

impl ReplyFramer {
    pub fn new(max_len: usize) -> Self {
        ReplyFramer {
            buf: Vec::new(),
            max_len,
        }
    }

    /// Appends bytes; returns the complete blocks now available. On
    /// overflow the buffer is cleared and the error returned.
    pub fn push(&mut self, bytes: &[u8]) -> Result<Vec<Vec<u8>>, ScipError> {
        self.buf.extend_from_slice(bytes);
        let mut out = Vec::new();
        while let Some(pos) = self.buf.windows(2).position(|w| w == b"\n\n") {
            let block: Vec<u8> = self.buf.drain(..pos + 2).collect();
            // a lone LF left over after a resync is not a reply
            if block != b"\n\n" {
                out.push(block);
            }
        }
        if self.buf.len() > self.max_len {
            self.buf.clear();
            return Err(ScipError::Overflow(self.max_len));
        }
        Ok(out)
    }

    /// Drops buffered bytes (after QT, to resynchronise).
    pub fn clear(&mut self) {
        self.buf.clear();
    }

    pub fn pending(&self) -> usize {
        self.buf.len()
    }
}

/// Values below this are error codes, not distances.
pub const MIN_VALID_MM: u32 = 20;

pub fn classify(value: u32) -> Reading {
    if value >= MIN_VALID_MM {
        return Reading::RangeMm(value);
    }
    Reading::NoReturn(match value {
        0 => NoReturn::NoObject,
        1 | 2 => NoReturn::LowIntensity,
        18 => NoReturn::StrongReflector,
        19 => NoReturn::NonMeasurable,
        c => NoReturn::Other(c as u8),
    })
}

/// Decodes joined data into values of `width` (2 or 3) characters.
pub fn decode_ranges(data: &[u8], width: usize) -> Result<Vec<u32>, ScipError> {
    if width == 0 || !data.len().is_multiple_of(width) {
        return Err(ScipError::Length(data.len(), width));
    }
    data.chunks_exact(width).map(decode_value).collect()
}

/// The sensor's geometry from `PP`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SensorParams {
    pub dmin_mm: u32,
    pub dmax_mm: u32,
    /// Steps per full turn.
    pub ares: u32,
    pub amin: u32,
    pub amax: u32,
    /// Step straight ahead.
    pub afrt: u32,
    /// Motor speed, rpm.
    pub scan_rpm: u32,
}

impl SensorParams {
    /// URG-04LX values, for tests and the emulator.
    pub const URG_04LX: SensorParams = SensorParams {
        dmin_mm: 20,
        dmax_mm: 5600,
        ares: 1024,
        amin: 44,
        amax: 725,
        afrt: 384,
        scan_rpm: 600,
    };

    /// Angle of step `i`, radians, counter-clockwise positive, 0 ahead.
    pub fn step_angle_rad(&self, step: u32) -> f64 {
        (step as f64 - self.afrt as f64) * std::f64::consts::TAU / self.ares as f64
    }

    /// Time of one scan, seconds.
    pub fn scan_period_s(&self) -> f64 {
        60.0 / self.scan_rpm as f64
    }
}

/// `KEY:VALUE` pairs of a PP/VV/II reply (the trailing `;` removed).
pub fn key_values(reply: &Reply) -> Result<HashMap<String, String>, ScipError> {
    let mut out = HashMap::new();
    for (i, l) in reply.lines.iter().enumerate() {
        let text = String::from_utf8_lossy(l);
        let text = text.strip_suffix(';').unwrap_or(&text);
        let (k, v) = text.split_once(':').ok_or_else(|| ScipError::Malformed {
            line: i + 2,
            reason: format!("`{text}` is not KEY:VALUE"),
        })?;
        out.insert(k.to_string(), v.to_string());
    }
    Ok(out)
}

pub fn parse_pp(reply: &Reply) -> Result<SensorParams, ScipError> {
    let kv = key_values(reply)?;
    let get = |key: &'static str| -> Result<u32, ScipError> {
        let v = kv.get(key).ok_or(ScipError::MissingParameter(key))?;
        // values may carry units or comments after a space: "600 [rpm]"
        let num = v.split_whitespace().next().unwrap_or("");
        num.parse().map_err(|_| ScipError::Parameter {
            key: key.into(),
            reason: format!("`{v}` is not a number"),
        })
    };
    let p = SensorParams {
        dmin_mm: get("DMIN")?,
        dmax_mm: get("DMAX")?,
        ares: get("ARES")?,
        amin: get("AMIN")?,
        amax: get("AMAX")?,
        afrt: get("AFRT")?,
        scan_rpm: get("SCAN")?,
    };
    let bad = |key: &str, reason: &str| {
        Err(ScipError::Parameter {
            key: key.into(),
            reason: reason.into(),
        })
    };
    if p.ares == 0 {
        return bad("ARES", "zero steps per turn");
    }
    if p.amin > p.amax || u64::from(p.amax) >= u64::from(p.ares) * 2 {
        return bad("AMAX", "step range empty or beyond a turn");
    }
    if p.amax > 9999 {
        // MD/MS address steps with 4 decimal digits
        return bad("AMAX", "beyond the 4 digits a scan request can address");
    }
    if p.dmin_mm >= p.dmax_mm {
        return bad("DMAX", "not above DMIN");
    }
    if p.scan_rpm == 0 {
        return bad("SCAN", "zero rpm");
    }
    Ok(p)
}

/// Builds a key-value reply as the sensor sends one to PP, VV and II
/// (emulator and tests): echo, status `00`, a `KEY:value;` line with its
/// checksum per pair, blank line — what [`key_values`] reads.
pub fn build_key_value_reply(echo: &[u8], pairs: &[(&str, &str)]) -> Vec<u8> {
    let mut out = build_reply(echo, b"00", None, &[]);
    // the blank line goes after the pairs
    out.pop();
    for (k, v) in pairs {
        let kv = format!("{k}:{v}");
        out.extend_from_slice(kv.as_bytes());
        out.push(b';');
        out.push(checksum(kv.as_bytes()));
        out.push(b'\n');
    }
    out.push(b'\n');
    out
}

/// Builds a reply block as the sensor would send it (emulator and tests):
/// echo, status, optional timestamp, data split in 64-char lines, blank line.
pub fn build_reply(echo: &[u8], status: &[u8; 2], timestamp: Option<u32>, data: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(data.len() + data.len() / 64 * 2 + 32);
    out.extend_from_slice(echo);
    out.push(b'\n');
    out.extend_from_slice(status);
    out.push(checksum(status));
    out.push(b'\n');
    if let Some(t) = timestamp {
        let enc = encode_value(t & 0xFF_FFFF, 4);
        out.extend_from_slice(&enc);
        out.push(checksum(&enc));
        out.push(b'\n');
    }
    for chunk in data.chunks(64) {
        out.extend_from_slice(chunk);
        out.push(checksum(chunk));
        out.push(b'\n');
    }
    out.push(b'\n');
    out
}

#[cfg(test)]
#[path = "scip_tests.rs"]
mod tests;
