//! An emulated R-Net Rebus chipset on a pty: decodes the host's packets,
//! ACKs each DATA (start-up and velocity) with its sequence number, records
//! the velocity packets, and misbehaves on command — ACKs withheld (the host
//! times out), NACKs, garbage bytes on the line, DATA of its own that the
//! host must ACK.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serialport::TTYPort;

use crate::actuation::rebus::{Decoder, Kind, Packet};

#[derive(Debug, Clone)]
pub enum ChipsetFault {
    /// Answer nothing to the next `n` DATA packets.
    WithholdAcks(u32),
    /// NACK the next `n` DATA packets.
    Nack(u32),
    /// Put these bytes on the line now.
    Garbage(Vec<u8>),
    /// Send a DATA packet of our own (the host must ACK it).
    SendData(Vec<u8>),
}

/// A velocity packet as the chipset received it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct VelocityPacket {
    pub at: Instant,
    pub seq: u8,
    pub vx: i8,
    pub vy: i8,
    /// Whether it was ACKed.
    pub acked: bool,
}

#[derive(Debug, Clone, Default)]
pub struct ChipsetLog {
    pub startups: u32,
    pub velocity: Vec<VelocityPacket>,
    /// ACKs from the host (for our own DATA, and the start-up handshake's).
    pub host_acks: u32,
    /// Velocity packets refused because the host never finished the
    /// start-up handshake (no ACK after ours).
    pub before_handshake: u32,
    pub decode_errors: u32,
}

pub struct RebusChipset {
    link: PathBuf,
    faults: Sender<ChipsetFault>,
    log: Arc<Mutex<ChipsetLog>>,
    stop: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl RebusChipset {
    /// Starts the chipset on a new pty whose slave is linked at `link`.
    pub fn spawn(link: &Path) -> std::io::Result<RebusChipset> {
        let super::pty::PtyDevice {
            mut master, slave, ..
        } = super::pty::plug(link, Duration::from_millis(1))?;
        let (tx, rx) = channel();
        let log = Arc::new(Mutex::new(ChipsetLog::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let (l2, s2) = (log.clone(), stop.clone());
        let thread = std::thread::Builder::new()
            .name("rebus-chipset".into())
            .spawn(move || {
                let _slave = slave;
                run(&mut master, &rx, &l2, &s2);
            })?;
        Ok(RebusChipset {
            link: link.to_path_buf(),
            faults: tx,
            log,
            stop,
            thread: Some(thread),
        })
    }

    pub fn link(&self) -> &Path {
        &self.link
    }

    pub fn inject(&self, f: ChipsetFault) {
        let _ = self.faults.send(f);
    }

    pub fn log(&self) -> ChipsetLog {
        self.log.lock().map(|l| l.clone()).unwrap_or_default()
    }
}

impl Drop for RebusChipset {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        let _ = std::fs::remove_file(&self.link);
    }
}

fn run(
    port: &mut TTYPort,
    faults: &Receiver<ChipsetFault>,
    log: &Mutex<ChipsetLog>,
    stop: &AtomicBool,
) {
    let mut decoder = Decoder::default();
    let (mut withhold, mut nack) = (0u32, 0u32);
    let mut own_seq = 0u8;
    // the start-up handshake: our ACK of the host's start-up is answered
    // by the host's ACK; until then its velocity packets are not ours to
    // act on (they go unacknowledged)
    let mut handshake_done = false;
    let mut buf = [0u8; 256];
    while !stop.load(Ordering::SeqCst) {
        while let Ok(f) = faults.try_recv() {
            match f {
                ChipsetFault::WithholdAcks(n) => withhold += n,
                ChipsetFault::Nack(n) => nack += n,
                ChipsetFault::Garbage(b) => {
                    let _ = port.write_all(&b);
                }
                ChipsetFault::SendData(d) => {
                    let p = Packet {
                        seq: own_seq,
                        startup: false,
                        kind: Kind::Data,
                        data: d,
                    };
                    own_seq = (own_seq + 1) & 0x1F;
                    let _ = port.write_all(&p.encode());
                }
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
                continue
            }
            // the host closed its side: wait for it to come back
            Err(_) => {
                std::thread::sleep(Duration::from_millis(5));
                continue;
            }
        };
        let now = Instant::now();
        for r in decoder.push(&buf[..n]) {
            let Ok(mut l) = log.lock() else { return };
            let p = match r {
                Ok(p) => p,
                Err(_) => {
                    l.decode_errors += 1;
                    continue;
                }
            };
            match p.kind {
                Kind::Ack => {
                    l.host_acks += 1;
                    handshake_done = true;
                }
                Kind::Nack => {}
                Kind::Data => {
                    if p.startup {
                        handshake_done = false;
                    } else if !handshake_done {
                        l.before_handshake += 1;
                        continue;
                    }
                    let reply = if withhold > 0 {
                        withhold -= 1;
                        None
                    } else if nack > 0 {
                        nack -= 1;
                        Some(Packet::nack(p.seq))
                    } else {
                        Some(Packet::ack(p.seq))
                    };
                    let acked = reply.as_ref().is_some_and(|r| r.kind == Kind::Ack);
                    if p.startup {
                        l.startups += 1;
                    } else if p.data.len() == 5 && p.data[0] == 0x0B {
                        l.velocity.push(VelocityPacket {
                            at: now,
                            seq: p.seq,
                            vx: p.data[3] as i8,
                            vy: p.data[4] as i8,
                            acked,
                        });
                    }
                    drop(l);
                    if let Some(r) = reply {
                        let _ = port.write_all(&r.encode());
                    }
                }
            }
        }
    }
}
