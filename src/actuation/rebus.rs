//! The R-Net "Rebus" chipset on USB serial (the paper's own chair; FTDI,
//! 115200 8N1): the pure packet codec.
//!
//! Packet: `0x55`, `seq<<3 | startup<<2 | type` (seq 5 bits; ACK 0, NACK 1,
//! DATA 2), data length, CRC-8 over bytes 1–2 (poly 0x2F, init 0xFF,
//! MSB-first, no reflection, no final xor), then — when there is data — the
//! data and a CRC-16 over it (poly 0x90D9, init 0xFFFF, MSB-first), high
//! byte first. Velocity payload `[0B 00 00 vx vy]` (int8 ±100, vx turn
//! positive right, vy forward). Every DATA is ACKed with the same seq.

use thiserror::Error;

pub const HEADER: u8 = 0x55;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Ack = 0,
    Nack = 1,
    Data = 2,
}

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Packet {
    pub seq: u8,
    pub startup: bool,
    pub kind: Kind,
    pub data: Vec<u8>,
}

#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum RebusError {
    #[error("header CRC-8 {got:#04x}, computed {want:#04x}")]
    HeaderCrc { got: u8, want: u8 },
    #[error("data CRC-16 {got:#06x}, computed {want:#06x}")]
    DataCrc { got: u16, want: u16 },
    #[error("packet type {0} is not ACK, NACK or DATA")]
    Kind(u8),
}

pub fn crc8(data: &[u8]) -> u8 {
    crate::crc::crc8_msb(0x2F, 0xFF, data)
}

pub fn crc16(data: &[u8]) -> u16 {
    crate::crc::crc16_msb(0x90D9, 0xFFFF, data)
}

impl Packet {
    pub fn startup(seq: u8) -> Packet {
        Packet {
            seq,
            startup: true,
            kind: Kind::Data,
            data: vec![0x01],
        }
    }

    pub fn ack(seq: u8) -> Packet {
        Packet {
            seq,
            startup: false,
            kind: Kind::Ack,
            data: vec![],
        }
    }

    pub fn nack(seq: u8) -> Packet {
        Packet {
            seq,
            startup: false,
            kind: Kind::Nack,
            data: vec![],
        }
    }

    /// Joystick values (R-Net convention: `vx` turn, positive right; `vy`
    /// forward), clamped to ±100.
    pub fn velocity(seq: u8, vx: i8, vy: i8) -> Packet {
        Packet {
            seq,
            startup: false,
            kind: Kind::Data,
            data: vec![
                0x0B,
                0x00,
                0x00,
                vx.clamp(-100, 100) as u8,
                vy.clamp(-100, 100) as u8,
            ],
        }
    }

    pub fn encode(&self) -> Vec<u8> {
        let ctl = ((self.seq & 0x1F) << 3) | ((self.startup as u8) << 2) | self.kind as u8;
        let len = self.data.len().min(255) as u8;
        let mut out = vec![HEADER, ctl, len, crc8(&[ctl, len])];
        if len > 0 {
            out.extend_from_slice(&self.data[..len as usize]);
            out.extend_from_slice(&crc16(&self.data[..len as usize]).to_be_bytes());
        }
        out
    }
}

/// Splits a byte stream into packets, resynchronising on the header after
/// garbage or a bad CRC (each reported).
#[derive(Debug, Clone, Default)]
pub struct Decoder {
    buf: Vec<u8>,
}

impl Decoder {
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Result<Packet, RebusError>> {
        self.buf.extend_from_slice(bytes);
        let mut out = Vec::new();
        loop {
            // drop everything before a header
            match self.buf.iter().position(|&b| b == HEADER) {
                Some(0) => {}
                Some(i) => {
                    self.buf.drain(..i);
                }
                None => {
                    self.buf.clear();
                    return out;
                }
            }
            if self.buf.len() < 4 {
                return out;
            }
            let (ctl, len, c8) = (self.buf[1], self.buf[2], self.buf[3]);
            let want = crc8(&[ctl, len]);
            if c8 != want {
                out.push(Err(RebusError::HeaderCrc { got: c8, want }));
                self.buf.drain(..1);
                continue;
            }
            let total = 4 + if len > 0 { len as usize + 2 } else { 0 };
            if self.buf.len() < total {
                return out;
            }
            let kind = match ctl & 0x03 {
                0 => Kind::Ack,
                1 => Kind::Nack,
                2 => Kind::Data,
                k => {
                    out.push(Err(RebusError::Kind(k)));
                    self.buf.drain(..total);
                    continue;
                }
            };
            let data = self.buf[4..4 + len as usize].to_vec();
            if len > 0 {
                let got = u16::from_be_bytes([self.buf[total - 2], self.buf[total - 1]]);
                let want = crc16(&data);
                if got != want {
                    out.push(Err(RebusError::DataCrc { got, want }));
                    self.buf.drain(..1);
                    continue;
                }
            }
            self.buf.drain(..total);
            out.push(Ok(Packet {
                seq: ctl >> 3,
                startup: ctl & 0x04 != 0,
                kind,
                data,
            }));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(b: &[u8]) -> String {
        b.iter()
            .map(|x| format!("{x:02X}"))
            .collect::<Vec<_>>()
            .join(" ")
    }

    #[test]
    fn golden_bytes_from_the_reference() {
        assert_eq!(hex(&Packet::startup(0).encode()), "55 06 01 BF 01 7A AF");
        assert_eq!(hex(&Packet::ack(0).encode()), "55 00 00 B8");
        assert_eq!(
            hex(&Packet::velocity(1, 0, 20).encode()),
            "55 0A 05 53 0B 00 00 00 14 4F 63"
        );
    }

    #[test]
    fn decoder_resynchronises_after_garbage_and_bad_crcs() {
        let mut stream = vec![0x00, 0x13, 0x55, 0x99]; // garbage with a false header
        stream.extend(Packet::ack(3).encode());
        let mut bad = Packet::velocity(4, 10, 20).encode();
        bad[8] ^= 0x01;
        stream.extend(bad);
        stream.extend(Packet::velocity(5, -10, 30).encode());
        let mut d = Decoder::default();
        let mut got = Vec::new();
        for chunk in stream.chunks(3) {
            got.extend(d.push(chunk));
        }
        let ok: Vec<Packet> = got
            .iter()
            .filter_map(|r| r.as_ref().ok().cloned())
            .collect();
        assert_eq!(ok, vec![Packet::ack(3), Packet::velocity(5, -10, 30)]);
        assert!(got
            .iter()
            .any(|r| matches!(r, Err(RebusError::DataCrc { .. }))));
        assert!(got
            .iter()
            .any(|r| matches!(r, Err(RebusError::HeaderCrc { .. }))));
    }
}
