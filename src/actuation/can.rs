//! The CAN bus behind a trait: the real SocketCAN adapter (`socketcan` 4.x,
//! tokio), and an in-memory bus that stands in for it in tests and the
//! simulator. Error frames are enabled on the real socket and decoded here
//! (pure) into [`BusError`]: bus-off, error-passive and controller problems
//! are faults for the supervisor; the rest are counted.
//!
//! Sending never waits: a frame the kernel cannot take now (TX queue full)
//! is dropped and counted by the caller — a joystick frame is only worth
//! sending in its own 10 ms slot.

use std::future::Future;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use serde::Serialize;
use tokio::sync::broadcast;

use super::rnet::CanFrame;

/// Linux `can/error.h`: error classes in the id word of an error frame.
pub mod err {
    pub const TX_TIMEOUT: u32 = 0x001;
    pub const LOSTARB: u32 = 0x002;
    pub const CRTL: u32 = 0x004;
    pub const PROT: u32 = 0x008;
    pub const TRX: u32 = 0x010;
    pub const ACK: u32 = 0x020;
    pub const BUSOFF: u32 = 0x040;
    pub const BUSERROR: u32 = 0x080;
    pub const RESTARTED: u32 = 0x100;
    pub const CNT: u32 = 0x200;
    /// data[1] for CRTL
    pub const CRTL_RX_OVERFLOW: u8 = 0x01;
    pub const CRTL_TX_OVERFLOW: u8 = 0x02;
    pub const CRTL_RX_WARNING: u8 = 0x04;
    pub const CRTL_TX_WARNING: u8 = 0x08;
    pub const CRTL_RX_PASSIVE: u8 = 0x10;
    pub const CRTL_TX_PASSIVE: u8 = 0x20;
    pub const CRTL_ACTIVE: u8 = 0x40;
    /// The error flag and mask of the id word.
    pub const FLAG: u32 = 0x2000_0000;
    pub const MASK: u32 = 0x1FFF_FFFF;
}

/// One decoded error frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct BusError {
    /// Error classes (`err::*` bits).
    pub class: u32,
    /// Controller status (data[1]) when `class` has CRTL.
    pub controller: u8,
    /// Protocol violation type and location (data[2], data[3]).
    pub protocol: [u8; 2],
    /// TX and RX error counters (data[6], data[7]) when reported.
    pub tx_errors: u8,
    pub rx_errors: u8,
}

impl BusError {
    /// Decodes an error frame from its id word (flag included or not) and
    /// payload. Pure; any bytes are accepted (missing bytes read as 0).
    pub fn decode(id_word: u32, data: &[u8]) -> BusError {
        let b = |i: usize| data.get(i).copied().unwrap_or(0);
        BusError {
            class: id_word & err::MASK,
            controller: b(1),
            protocol: [b(2), b(3)],
            tx_errors: b(6),
            rx_errors: b(7),
        }
    }

    /// The inverse of [`BusError::decode`], for injecting errors in tests.
    pub fn encode(&self) -> (u32, [u8; 8]) {
        let mut d = [0u8; 8];
        d[1] = self.controller;
        d[2] = self.protocol[0];
        d[3] = self.protocol[1];
        d[6] = self.tx_errors;
        d[7] = self.rx_errors;
        (self.class & err::MASK, d)
    }

    pub fn bus_off() -> BusError {
        BusError::decode(err::BUSOFF, &[])
    }

    pub fn error_passive() -> BusError {
        BusError::decode(
            err::CRTL,
            &[
                0,
                err::CRTL_TX_PASSIVE | err::CRTL_RX_PASSIVE,
                0,
                0,
                0,
                0,
                128,
                128,
            ],
        )
    }

    /// Whether the supervisor must latch a fault: bus-off, a controller
    /// in error-passive or losing frames (overflow), a transceiver problem,
    /// or a TX timeout. Lost arbitration, protocol errors, missing ACKs,
    /// warnings and restarts are counted, not faults.
    pub fn is_fault(&self) -> bool {
        let ctrl_bad = self.class & err::CRTL != 0
            && self.controller
                & (err::CRTL_RX_OVERFLOW
                    | err::CRTL_TX_OVERFLOW
                    | err::CRTL_RX_PASSIVE
                    | err::CRTL_TX_PASSIVE)
                != 0;
        self.class & (err::BUSOFF | err::TRX | err::TX_TIMEOUT) != 0 || ctrl_bad
    }

    /// Words for the log and status: "bus-off", "controller: tx passive", ….
    pub fn describe(&self) -> String {
        let mut parts: Vec<String> = Vec::new();
        let names = [
            (err::TX_TIMEOUT, "tx timeout"),
            (err::LOSTARB, "lost arbitration"),
            (err::PROT, "protocol violation"),
            (err::TRX, "transceiver"),
            (err::ACK, "no ack"),
            (err::BUSOFF, "bus-off"),
            (err::BUSERROR, "bus error"),
            (err::RESTARTED, "controller restarted"),
        ];
        for (bit, name) in names {
            if self.class & bit != 0 {
                parts.push(name.into());
            }
        }
        if self.class & err::CRTL != 0 {
            let flags = [
                (err::CRTL_RX_OVERFLOW, "rx overflow"),
                (err::CRTL_TX_OVERFLOW, "tx overflow"),
                (err::CRTL_RX_WARNING, "rx warning"),
                (err::CRTL_TX_WARNING, "tx warning"),
                (err::CRTL_RX_PASSIVE, "rx passive"),
                (err::CRTL_TX_PASSIVE, "tx passive"),
                (err::CRTL_ACTIVE, "back to error-active"),
            ];
            let f: Vec<&str> = flags
                .iter()
                .filter(|(b, _)| self.controller & b != 0)
                .map(|(_, n)| *n)
                .collect();
            parts.push(format!("controller: {}", f.join(", ")));
        }
        if parts.is_empty() {
            parts.push(format!("error class {:#x}", self.class));
        }
        parts.join("; ")
    }
}

/// What the bus delivers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BusEvent {
    Frame(CanFrame),
    Error(BusError),
}

#[derive(Debug, thiserror::Error)]
pub enum CanBusError {
    #[error("CAN interface {iface} cannot be opened (does it exist and is it up? `ip link set {iface} up type can bitrate 125000`)")]
    Open {
        iface: String,
        source: std::io::Error,
    },
    /// The kernel's TX queue is full: the frame was not sent.
    #[error("CAN TX queue full: frame dropped")]
    QueueFull,
    #[error("CAN frame {0} cannot be sent (bad id or length)")]
    BadFrame(String),
    #[error("CAN {op} on {iface}")]
    Io {
        op: &'static str,
        iface: String,
        source: std::io::Error,
    },
    #[error("CAN bus closed")]
    Closed,
}

/// A CAN bus endpoint: what the R-Net writer and the simulated chair use.
pub trait CanBus: Send + Sync + 'static {
    /// Sends now or not at all ([`CanBusError::QueueFull`]).
    fn try_send(&self, frame: &CanFrame) -> Result<(), CanBusError>;
    /// The next frame or error frame from the bus (not our own frames).
    fn recv(&self) -> impl Future<Output = Result<BusEvent, CanBusError>> + Send;
}

/// The real adapter: a raw SocketCAN socket on `iface` (e.g. `can0`,
/// `vcan0`), extended and standard frames, every error class reported.
pub struct SocketCanBus {
    socket: socketcan::tokio::CanSocket,
    iface: String,
}

impl SocketCanBus {
    /// Opens `iface`; needs a tokio runtime with I/O enabled.
    pub fn open(iface: &str) -> Result<SocketCanBus, CanBusError> {
        use socketcan::SocketOptions;
        let open_err = |source| CanBusError::Open {
            iface: iface.to_string(),
            source,
        };
        let socket = socketcan::tokio::CanSocket::open(iface).map_err(open_err)?;
        socket.set_error_filter_accept_all().map_err(open_err)?;
        Ok(SocketCanBus {
            socket,
            iface: iface.to_string(),
        })
    }

    pub fn iface(&self) -> &str {
        &self.iface
    }

    /// Puts an error frame on the bus (only a virtual bus passes it on):
    /// how the HIL tests inject bus faults.
    pub fn inject_error(&self, e: &BusError) -> Result<(), CanBusError> {
        let (id, data) = e.encode();
        let f = socketcan::CanErrorFrame::new_error(id, &data)
            .map_err(|_| CanBusError::BadFrame(format!("error {id:#x}")))?;
        self.socket
            .try_write_frame(socketcan::CanFrame::Error(f))
            .map_err(|source| CanBusError::Io {
                op: "write",
                iface: self.iface.clone(),
                source,
            })
    }
}

fn to_socketcan(f: &CanFrame) -> Result<socketcan::CanFrame, CanBusError> {
    use socketcan::{EmbeddedFrame, ExtendedId, StandardId};
    let bad = || CanBusError::BadFrame(f.to_string());
    let id: socketcan::Id = if f.extended {
        ExtendedId::new(f.id).ok_or_else(bad)?.into()
    } else {
        StandardId::new(u16::try_from(f.id).map_err(|_| bad())?)
            .ok_or_else(bad)?
            .into()
    };
    socketcan::CanFrame::new(id, f.payload()).ok_or_else(bad)
}

/// Converts a received frame: data frames to [`CanFrame`], error frames to
/// [`BusError`]; remote frames are ignored (`None`).
pub fn from_socketcan(f: &socketcan::CanFrame) -> Option<BusEvent> {
    use socketcan::{EmbeddedFrame, Frame};
    match f {
        socketcan::CanFrame::Data(d) => {
            let mut frame = CanFrame::ext(d.raw_id(), d.data());
            frame.extended = d.is_extended();
            Some(BusEvent::Frame(frame))
        }
        socketcan::CanFrame::Error(e) => {
            Some(BusEvent::Error(BusError::decode(e.error_bits(), e.data())))
        }
        socketcan::CanFrame::Remote(_) => None,
    }
}

impl CanBus for SocketCanBus {
    fn try_send(&self, frame: &CanFrame) -> Result<(), CanBusError> {
        let f = to_socketcan(frame)?;
        match self.socket.try_write_frame(f) {
            Ok(()) => Ok(()),
            Err(e)
                if e.kind() == std::io::ErrorKind::WouldBlock
                    || e.raw_os_error() == Some(105 /* ENOBUFS */) =>
            {
                Err(CanBusError::QueueFull)
            }
            Err(source) => Err(CanBusError::Io {
                op: "write",
                iface: self.iface.clone(),
                source,
            }),
        }
    }

    async fn recv(&self) -> Result<BusEvent, CanBusError> {
        loop {
            let f = self
                .socket
                .read_frame()
                .await
                .map_err(|source| CanBusError::Io {
                    op: "read",
                    iface: self.iface.clone(),
                    source,
                })?;
            if let Some(ev) = from_socketcan(&f) {
                return Ok(ev);
            }
        }
    }
}

/// An in-memory CAN bus: every endpoint sees what the others send (not its
/// own frames, as with SocketCAN's defaults). Stands in for the hardware in
/// tests and the simulator.
#[derive(Clone)]
pub struct MemoryBus {
    tx: broadcast::Sender<(usize, BusEvent)>,
    next_id: Arc<AtomicUsize>,
}

impl Default for MemoryBus {
    fn default() -> Self {
        Self::new()
    }
}

impl MemoryBus {
    pub fn new() -> MemoryBus {
        let (tx, _) = broadcast::channel(4096);
        MemoryBus {
            tx,
            next_id: Arc::new(AtomicUsize::new(1)),
        }
    }

    /// A new node on the bus.
    pub fn endpoint(&self) -> MemoryEndpoint {
        MemoryEndpoint {
            id: self.next_id.fetch_add(1, Ordering::SeqCst),
            tx: self.tx.clone(),
            rx: tokio::sync::Mutex::new(self.tx.subscribe()),
            full: Arc::new(std::sync::atomic::AtomicBool::new(false)),
        }
    }

    /// Injects an error frame seen by every endpoint.
    pub fn inject_error(&self, e: BusError) {
        let _ = self.tx.send((0, BusEvent::Error(e)));
    }
}

pub struct MemoryEndpoint {
    id: usize,
    tx: broadcast::Sender<(usize, BusEvent)>,
    rx: tokio::sync::Mutex<broadcast::Receiver<(usize, BusEvent)>>,
    full: Arc<std::sync::atomic::AtomicBool>,
}

impl MemoryEndpoint {
    /// A switch that makes `try_send` report a full TX queue (tests).
    pub fn queue_full_switch(&self) -> Arc<std::sync::atomic::AtomicBool> {
        self.full.clone()
    }
}

impl CanBus for MemoryEndpoint {
    fn try_send(&self, frame: &CanFrame) -> Result<(), CanBusError> {
        if self.full.load(Ordering::SeqCst) {
            return Err(CanBusError::QueueFull);
        }
        // no receivers is fine: nobody on the bus
        let _ = self.tx.send((self.id, BusEvent::Frame(*frame)));
        Ok(())
    }

    async fn recv(&self) -> Result<BusEvent, CanBusError> {
        let mut rx = self.rx.lock().await;
        loop {
            match rx.recv().await {
                Ok((from, ev)) if from != self.id => return Ok(ev),
                Ok(_) => {}
                Err(broadcast::error::RecvError::Lagged(_)) => {}
                Err(broadcast::error::RecvError::Closed) => return Err(CanBusError::Closed),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_frames_decode_and_classify() {
        let off = BusError::bus_off();
        assert!(off.is_fault());
        assert_eq!(off.describe(), "bus-off");
        let passive = BusError::error_passive();
        assert!(passive.is_fault());
        assert!(passive.describe().contains("tx passive"));
        assert_eq!(passive.tx_errors, 128);
        let warn = BusError::decode(err::CRTL | err::FLAG, &[0, err::CRTL_TX_WARNING]);
        assert!(!warn.is_fault());
        assert_eq!(warn.class, err::CRTL);
        let arb = BusError::decode(err::LOSTARB, &[3]);
        assert!(!arb.is_fault());
        let (id, d) = passive.encode();
        assert_eq!(BusError::decode(id, &d), passive);
        assert!(BusError::decode(0, &[]).describe().contains("error class"));
    }

    #[test]
    fn frames_convert_both_ways() {
        let f = super::super::rnet::joystick_frame(0x0200_0100, -5, 20);
        let s = to_socketcan(&f).expect("valid");
        assert_eq!(from_socketcan(&s), Some(BusEvent::Frame(f)));
        let mut std = CanFrame::ext(0x00E, &[1, 2, 3, 4, 0, 0, 0, 0]);
        std.extended = false;
        let s = to_socketcan(&std).expect("valid");
        assert_eq!(from_socketcan(&s), Some(BusEvent::Frame(std)));
        let mut bad = std;
        bad.id = 0x900;
        assert!(matches!(to_socketcan(&bad), Err(CanBusError::BadFrame(_))));
    }

    #[tokio::test]
    async fn memory_bus_delivers_to_others_not_self() {
        let bus = MemoryBus::new();
        let a = bus.endpoint();
        let b = bus.endpoint();
        let f = CanFrame::ext(0x03C3_0F0F, &[0x87; 8]);
        a.try_send(&f).expect("sent");
        assert_eq!(b.recv().await.expect("frame"), BusEvent::Frame(f));
        b.try_send(&f).expect("sent");
        assert_eq!(a.recv().await.expect("frame"), BusEvent::Frame(f));
        a.queue_full_switch().store(true, Ordering::SeqCst);
        assert!(matches!(a.try_send(&f), Err(CanBusError::QueueFull)));
        bus.inject_error(BusError::bus_off());
        assert_eq!(
            b.recv().await.expect("error"),
            BusEvent::Error(BusError::bus_off())
        );
    }
}
