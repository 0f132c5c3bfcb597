//! The wheel-encoder board: host side of the protocol in
//! `firmware/encoder_bridge/protocol.h` (COBS frames ending in 0x00,
//! CRC-16/CCITT-FALSE, little-endian fields), as a pure codec and a driver
//! over a serial port. Sequence gaps, CRC and framing failures are counted
//! and reported, never absorbed; the MCU's 32-bit microsecond clock is
//! unwrapped and mapped to host time.

use std::collections::VecDeque;
use std::io::Read;
use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;
use thiserror::Error;

use super::clock::DeviceClock;
use crate::msg::{Clock, Stamped, WheelTicks};

pub const TYPE_COUNTS: u8 = 0x01;
pub const TYPE_HELLO: u8 = 0x02;
pub const COUNTS_PAYLOAD: usize = 20;
pub const HELLO_PAYLOAD: usize = 8;
/// Longest encoded frame accepted before a 0x00 (anything longer is noise).
pub const MAX_FRAME: usize = 64;

#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum FrameError {
    #[error("COBS: {0}")]
    Cobs(&'static str),
    #[error("frame of {0} bytes is too short")]
    Short(usize),
    #[error("CRC {got:#06x}, computed {want:#06x}")]
    Crc { got: u16, want: u16 },
    #[error("unknown message type {0:#04x}")]
    Type(u8),
    #[error("message type {kind:#04x} with {len} payload bytes, expected {want}")]
    Length { kind: u8, len: usize, want: usize },
    #[error("more than {0} bytes without a frame end: noise")]
    Overlong(usize),
}

/// CRC-16/CCITT-FALSE.
pub fn crc16(data: &[u8]) -> u16 {
    crate::crc::crc16_msb(0x1021, 0xFFFF, data)
}

pub fn cobs_encode(data: &[u8]) -> Vec<u8> {
    let mut out = vec![0u8];
    let mut code_at = 0;
    let mut code = 1u8;
    for &b in data {
        if b == 0 {
            out[code_at] = code;
            code_at = out.len();
            out.push(0);
            code = 1;
        } else {
            out.push(b);
            code += 1;
            if code == 0xFF {
                out[code_at] = code;
                code_at = out.len();
                out.push(0);
                code = 1;
            }
        }
    }
    out[code_at] = code;
    out
}

pub fn cobs_decode(data: &[u8]) -> Result<Vec<u8>, FrameError> {
    let mut out = Vec::with_capacity(data.len());
    let mut i = 0;
    while i < data.len() {
        let code = data[i] as usize;
        if code == 0 {
            return Err(FrameError::Cobs("zero inside a frame"));
        }
        if i + code > data.len() {
            return Err(FrameError::Cobs("block runs past the frame end"));
        }
        out.extend_from_slice(&data[i + 1..i + code]);
        i += code;
        if code < 0xFF && i < data.len() {
            out.push(0);
        }
    }
    Ok(out)
}

/// A COUNTS frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct CountsFrame {
    pub seq: u16,
    pub mcu_time_us: u32,
    pub left: i32,
    pub right: i32,
    pub left_illegal: u16,
    pub right_illegal: u16,
    /// The board dropped a frame (UART could not keep up).
    pub overrun: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Hello {
    pub protocol: u8,
    pub firmware: [u8; 3],
    pub frame_rate_hz: u16,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Message {
    Counts(CountsFrame),
    Hello(Hello),
}

fn u16le(b: &[u8]) -> u16 {
    u16::from_le_bytes([b[0], b[1]])
}
fn u32le(b: &[u8]) -> u32 {
    u32::from_le_bytes([b[0], b[1], b[2], b[3]])
}

/// Decodes one frame (its bytes without the terminating 0x00).
pub fn decode_frame(encoded: &[u8]) -> Result<Message, FrameError> {
    let raw = cobs_decode(encoded)?;
    if raw.len() < 3 {
        return Err(FrameError::Short(raw.len()));
    }
    let (body, crc) = raw.split_at(raw.len() - 2);
    let got = u16le(crc);
    let want = crc16(body);
    if got != want {
        return Err(FrameError::Crc { got, want });
    }
    let (kind, p) = (body[0], &body[1..]);
    let need = match kind {
        TYPE_COUNTS => COUNTS_PAYLOAD,
        TYPE_HELLO => HELLO_PAYLOAD,
        k => return Err(FrameError::Type(k)),
    };
    if p.len() != need {
        return Err(FrameError::Length {
            kind,
            len: p.len(),
            want: need,
        });
    }
    Ok(match kind {
        TYPE_COUNTS => Message::Counts(CountsFrame {
            seq: u16le(&p[0..]),
            mcu_time_us: u32le(&p[2..]),
            left: u32le(&p[6..]) as i32,
            right: u32le(&p[10..]) as i32,
            left_illegal: u16le(&p[14..]),
            right_illegal: u16le(&p[16..]),
            overrun: p[18] & 1 != 0,
        }),
        _ => Message::Hello(Hello {
            protocol: p[0],
            firmware: [p[1], p[2], p[3]],
            frame_rate_hz: u16le(&p[4..]),
        }),
    })
}

/// Encodes a message as the firmware does (tests and emulation).
pub fn encode_message(m: &Message) -> Vec<u8> {
    let mut raw = Vec::with_capacity(24);
    match m {
        Message::Counts(c) => {
            raw.push(TYPE_COUNTS);
            raw.extend_from_slice(&c.seq.to_le_bytes());
            raw.extend_from_slice(&c.mcu_time_us.to_le_bytes());
            raw.extend_from_slice(&c.left.to_le_bytes());
            raw.extend_from_slice(&c.right.to_le_bytes());
            raw.extend_from_slice(&c.left_illegal.to_le_bytes());
            raw.extend_from_slice(&c.right_illegal.to_le_bytes());
            raw.push(c.overrun as u8);
            raw.push(0);
        }
        Message::Hello(h) => {
            raw.push(TYPE_HELLO);
            raw.push(h.protocol);
            raw.extend_from_slice(&h.firmware);
            raw.extend_from_slice(&h.frame_rate_hz.to_le_bytes());
            raw.extend_from_slice(&[0, 0]);
        }
    }
    let crc = crc16(&raw);
    raw.extend_from_slice(&crc.to_le_bytes());
    let mut out = cobs_encode(&raw);
    out.push(0);
    out
}

/// Splits a byte stream at 0x00 into frames; bounded.
#[derive(Debug, Clone, Default)]
pub struct FrameSplitter {
    buf: Vec<u8>,
    discarding: bool,
}

impl FrameSplitter {
    /// Feeds bytes; returns complete frames (or an error per overlong run).
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Result<Vec<u8>, FrameError>> {
        let mut out = Vec::new();
        for &b in bytes {
            if b == 0 {
                if self.discarding {
                    self.discarding = false;
                } else if !self.buf.is_empty() {
                    out.push(Ok(std::mem::take(&mut self.buf)));
                }
                self.buf.clear();
            } else if !self.discarding {
                self.buf.push(b);
                if self.buf.len() > MAX_FRAME {
                    self.buf.clear();
                    self.discarding = true;
                    out.push(Err(FrameError::Overlong(MAX_FRAME)));
                }
            }
        }
        out
    }

    pub fn clear(&mut self) {
        self.buf.clear();
        self.discarding = false;
    }
}

#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct EncoderStats {
    pub frames: u64,
    pub crc_errors: u64,
    pub framing_errors: u64,
    pub seq_gaps: u64,
    pub frames_lost: u64,
    pub board_overruns: u64,
    pub hellos: u64,
    pub reconnects: u64,
}

/// The pure part of the driver: frames in, ticks out, statistics kept.
#[derive(Debug, Clone)]
pub struct EncoderDecoder {
    splitter: FrameSplitter,
    last_seq: Option<u16>,
    clock: DeviceClock,
    mcu: DeviceClock,
    pub stats: EncoderStats,
    pub hello: Option<Hello>,
}

impl Default for EncoderDecoder {
    fn default() -> Self {
        EncoderDecoder {
            splitter: FrameSplitter::default(),
            last_seq: None,
            clock: DeviceClock::new(32, 1e-6, 200),
            mcu: DeviceClock::new(32, 1e-6, 2),
            stats: EncoderStats::default(),
            hello: None,
        }
    }
}

impl EncoderDecoder {
    /// Bytes received at host time `now` → ticks stamped in host time.
    pub fn push(&mut self, bytes: &[u8], now: crate::msg::Stamp) -> Vec<Stamped<WheelTicks>> {
        let mut out = Vec::new();
        for frame in self.splitter.push(bytes) {
            let msg = frame.and_then(|f| decode_frame(&f));
            match msg {
                Ok(Message::Hello(h)) => {
                    // a (re)booted board: counts and sequence restart
                    self.stats.hellos += 1;
                    self.hello = Some(h);
                    self.last_seq = None;
                    self.clock = DeviceClock::new(32, 1e-6, 200);
                    self.mcu = DeviceClock::new(32, 1e-6, 2);
                }
                Ok(Message::Counts(c)) => {
                    self.stats.frames += 1;
                    if c.overrun {
                        self.stats.board_overruns += 1;
                    }
                    let gap = match self.last_seq {
                        Some(prev) => c.seq.wrapping_sub(prev).wrapping_sub(1),
                        None => 0,
                    };
                    if gap > 0 {
                        self.stats.seq_gaps += 1;
                        self.stats.frames_lost += gap as u64;
                        tracing::warn!(gap, seq = c.seq, "encoder frames lost");
                    }
                    self.last_seq = Some(c.seq);
                    let stamp = self.clock.map(c.mcu_time_us as u64, now);
                    out.push(Stamped::new(
                        stamp,
                        WheelTicks {
                            seq: c.seq,
                            mcu_time_us: self.mcu.unwrap(c.mcu_time_us as u64),
                            left: c.left,
                            right: c.right,
                            left_illegal: c.left_illegal,
                            right_illegal: c.right_illegal,
                            gap,
                        },
                    ));
                }
                Err(FrameError::Crc { .. }) => {
                    self.stats.crc_errors += 1;
                    tracing::warn!("encoder frame with a CRC error dropped");
                }
                Err(e) => {
                    self.stats.framing_errors += 1;
                    tracing::warn!(error = %e, "encoder frame dropped");
                }
            }
        }
        out
    }

    pub fn reset_stream(&mut self) {
        self.splitter.clear();
        self.last_seq = None;
    }
}

#[derive(Debug, Error)]
pub enum EncoderError {
    #[error("{port}: cannot open: {reason}")]
    Open { port: String, reason: String },
    #[error("{port}: device gone: {reason}")]
    Disconnected { port: String, reason: String },
    #[error("{port}: no frame within {timeout_ms} ms")]
    Silent { port: String, timeout_ms: u64 },
}

/// The encoder board on a serial port.
pub struct EncoderDriver {
    port_name: String,
    baud: u32,
    timeout: Duration,
    clock: Arc<dyn Clock>,
    port: Option<Box<dyn serialport::SerialPort>>,
    pending: VecDeque<Stamped<WheelTicks>>,
    pub decoder: EncoderDecoder,
}

impl EncoderDriver {
    pub fn new(port: impl Into<String>, clock: Arc<dyn Clock>) -> Self {
        EncoderDriver {
            port_name: port.into(),
            baud: 115_200,
            timeout: Duration::from_millis(200),
            clock,
            port: None,
            pending: VecDeque::new(),
            decoder: EncoderDecoder::default(),
        }
    }

    /// No frame for this long is an error (the board sends at 100 Hz).
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }

    /// The next ticks; opens the port when needed. A vanished device gives
    /// `Disconnected`, a silent one `Silent` (the port is closed either way;
    /// call again to reconnect).
    pub fn next_ticks(&mut self) -> Result<Stamped<WheelTicks>, EncoderError> {
        if let Some(t) = self.pending.pop_front() {
            return Ok(t);
        }
        if self.port.is_none() {
            let p = serialport::new(&self.port_name, self.baud)
                .timeout(Duration::from_millis(20))
                .open()
                .map_err(|e| EncoderError::Open {
                    port: self.port_name.clone(),
                    reason: super::serial_open_reason(&self.port_name, &e),
                })?;
            self.port = Some(p);
            self.decoder.reset_stream();
        }
        let start = self.clock.now();
        let mut buf = [0u8; 1024];
        loop {
            let n = match self.port.as_mut().map(|p| p.read(&mut buf)) {
                Some(Ok(0)) | None => return Err(self.gone("end of file")),
                Some(Ok(n)) => n,
                Some(Err(e))
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
                    ) =>
                {
                    0
                }
                Some(Err(e)) => return Err(self.gone(e)),
            };
            if n > 0 {
                let now = self.clock.now();
                self.pending.extend(self.decoder.push(&buf[..n], now));
                if let Some(t) = self.pending.pop_front() {
                    return Ok(t);
                }
            }
            if start.age_at(self.clock.now()) >= self.timeout {
                // a stalled link is reopened on the next call (a USB serial
                // device can stall without reporting a hang-up)
                self.port = None;
                return Err(EncoderError::Silent {
                    port: self.port_name.clone(),
                    timeout_ms: self.timeout.as_millis() as u64,
                });
            }
        }
    }

    fn gone(&mut self, e: impl std::fmt::Display) -> EncoderError {
        self.port = None;
        self.decoder.stats.reconnects += 1;
        EncoderError::Disconnected {
            port: self.port_name.clone(),
            reason: e.to_string(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::Stamp;

    fn counts(seq: u16, t: u32, l: i32, r: i32) -> Message {
        Message::Counts(CountsFrame {
            seq,
            mcu_time_us: t,
            left: l,
            right: r,
            left_illegal: 1,
            right_illegal: 2,
            overrun: false,
        })
    }

    #[test]
    fn crc_and_cobs_golden_values() {
        // CRC-16/CCITT-FALSE check value
        assert_eq!(crc16(b"123456789"), 0x29B1);
        assert_eq!(
            cobs_encode(&[0x11, 0x22, 0x00, 0x33]),
            vec![0x03, 0x11, 0x22, 0x02, 0x33]
        );
        assert_eq!(cobs_encode(&[0x00]), vec![0x01, 0x01]);
        assert_eq!(
            cobs_decode(&[0x03, 0x11, 0x22, 0x02, 0x33]).unwrap(),
            vec![0x11, 0x22, 0x00, 0x33]
        );
        let long: Vec<u8> = (1..=255u8).collect();
        assert_eq!(cobs_decode(&cobs_encode(&long)).unwrap(), long);
        assert!(cobs_decode(&[0x05, 0x11]).is_err());
    }

    #[test]
    fn golden_bytes_of_a_counts_frame() {
        // the same bytes the firmware's C code produces (protocol.h); checked
        // against the harness's output in the firmware-in-the-loop test
        let bytes = encode_message(&counts(1, 10_000, -5, 300));
        assert_eq!(*bytes.last().unwrap(), 0);
        assert!(!bytes[..bytes.len() - 1].contains(&0));
        assert_eq!(
            decode_frame(&bytes[..bytes.len() - 1]).unwrap(),
            counts(1, 10_000, -5, 300)
        );
    }

    #[test]
    fn decoder_counts_gaps_crc_and_noise_and_recovers() {
        let mut d = EncoderDecoder::default();
        let mut stream = Vec::new();
        stream.extend(encode_message(&Message::Hello(Hello {
            protocol: 1,
            firmware: [1, 0, 0],
            frame_rate_hz: 100,
        })));
        stream.extend(encode_message(&counts(0, 0, 0, 0)));
        stream.extend(encode_message(&counts(1, 10_000, 1, 1)));
        let mut bad = encode_message(&counts(2, 20_000, 2, 2));
        bad[5] ^= 0x40; // CRC error
        stream.extend(bad);
        stream.extend(vec![0x55; 100]); // noise without a 0x00
        stream.push(0);
        stream.extend(encode_message(&counts(4, 40_000, 4, 4))); // seq 3 lost
        let ticks = d.push(&stream, Stamp::from_secs_f64(1.0));
        let seqs: Vec<u16> = ticks.iter().map(|t| t.value.seq).collect();
        assert_eq!(seqs, vec![0, 1, 4]);
        assert_eq!(ticks[2].value.gap, 2);
        assert_eq!(d.stats.crc_errors, 1);
        assert_eq!(d.stats.framing_errors, 1);
        assert_eq!(d.stats.seq_gaps, 1);
        assert_eq!(d.stats.frames_lost, 2);
        assert_eq!(d.hello.unwrap().protocol, 1);
    }

    #[test]
    fn mcu_clock_unwraps() {
        let mut d = EncoderDecoder::default();
        let mut s = encode_message(&counts(0, u32::MAX - 4_999, 0, 0));
        s.extend(encode_message(&counts(1, 5_000, 0, 0)));
        let t = d.push(&s, Stamp::from_secs_f64(5.0));
        assert_eq!(t[1].value.mcu_time_us - t[0].value.mcu_time_us, 10_000);
    }
}
