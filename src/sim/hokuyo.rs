//! An emulated Hokuyo URG-04LX on a pseudo-terminal, byte-exact to SCIP 2.0
//! (through the same codec the driver uses, from the other side): answers
//! QT, SCIP2.0, TM, PP, VV, II, BM and MD, streams recorded scans, and
//! injects faults on command. The pty's slave is published under a stable
//! link path (as udev's `/dev/hokuyo_*` links), so an "unplug" removes it
//! and a "replug" brings it back on a new pty.

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

use crate::sensors::scip::{build_key_value_reply, build_reply, encode_value, SensorParams};

/// A fault to inject into the stream.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// The next scan has one corrupted data byte (its line checksum fails).
    BadChecksum,
    /// Random bytes between two scans.
    Garbage,
    /// The next scan stops halfway, then a blank line.
    Truncated,
    /// The next scan carries this error status, then streaming stops.
    ErrorStatus(u8),
    /// Nothing is sent for this long (a stalled sensor).
    Silence(Duration),
    /// The device vanishes for this long, then comes back on a new pty.
    Unplug(Duration),
    /// Unplugged for this long and back powered up afresh: its clock
    /// restarts near zero and it speaks SCIP 2.0 with the stream stopped.
    PowerCycle(Duration),
}

/// The protocol state a sensor can be found in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EmuMode {
    /// SCIP 2.0, the stream stopped (a sensor powered up in SCIP 2.0).
    Scip20,
    /// SCIP 1.1 (an older firmware's default): every reply's status is
    /// one character; `SCIP2.0` switches to SCIP 2.0.
    Scip11,
    /// Left in time-stamp mode (`TM0`/`TM1` by a previous program): every
    /// command but `TM` answers `0E`; `TM2` leaves it.
    TimeStamp,
}

/// How the emulated sensor starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EmuOptions {
    pub mode: EmuMode,
    /// A serial URG's line speed: commands at another speed are lost (the
    /// pty's line settings, as the driver set them, are checked). None:
    /// USB (any speed works).
    pub baud: Option<u32>,
}

impl Default for EmuOptions {
    fn default() -> Self {
        EmuOptions {
            mode: EmuMode::Scip20,
            baud: None,
        }
    }
}

/// Loads the SENA laser CSV of the shared data: ranges in metres per scan
/// (NaN = invalid).
pub fn load_sena_csv(path: &Path) -> std::io::Result<Vec<Vec<f64>>> {
    let text = std::fs::read_to_string(path)?;
    let mut out = Vec::new();
    for (i, l) in text.lines().enumerate() {
        if l.starts_with('#') || l.trim().is_empty() {
            continue;
        }
        let row: Result<Vec<f64>, _> = l
            .split(',')
            .skip(1)
            .map(|v| {
                if v == "nan" {
                    Ok(f64::NAN)
                } else {
                    v.parse::<f64>()
                }
            })
            .collect();
        out.push(row.map_err(|e| {
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("{}: line {}: {e}", path.display(), i + 1),
            )
        })?);
    }
    Ok(out)
}

/// Resamples a scan of `n` rays over 180° (right to left) to the URG's
/// steps AMIN..=AMAX in millimetres: the nearest ray within half a ray's
/// spacing; no ray (outside ±90°) or an invalid one → 0 (no object);
/// beyond DMAX → clipped to DMAX.
pub fn resample_to_urg(scan_m: &[f64], p: &SensorParams) -> Vec<u32> {
    let n = scan_m.len();
    if n < 2 {
        return vec![0; (p.amax - p.amin + 1) as usize];
    }
    let spacing = std::f64::consts::PI / (n - 1) as f64;
    (p.amin..=p.amax)
        .map(|step| {
            let a = p.step_angle_rad(step);
            let k = ((a + std::f64::consts::FRAC_PI_2) / spacing).round();
            if k < 0.0 || k as usize >= n {
                return 0;
            }
            let r = scan_m[k as usize];
            if !r.is_finite() || r <= 0.0 {
                return 0;
            }
            ((r * 1000.0).round() as u32).clamp(p.dmin_mm, p.dmax_mm)
        })
        .collect()
}

/// The running emulator.
pub struct HokuyoEmulator {
    link: PathBuf,
    faults: Sender<Fault>,
    stop: Arc<AtomicBool>,
    sent: Arc<AtomicU64>,
    commands: Arc<AtomicU64>,
    thread: Option<std::thread::JoinHandle<()>>,
}

use super::pty::PtyDevice as Device;

fn plug(link: &Path) -> std::io::Result<Device> {
    super::pty::plug(link, Duration::from_millis(2))
}

impl HokuyoEmulator {
    /// Starts the emulator at `link` streaming `scans` (URG values, mm,
    /// AMIN..=AMAX) in a loop every `period`; the sensor clock starts at
    /// `clock_start_ms` (24-bit).
    pub fn spawn(
        link: &Path,
        scans: Vec<Vec<u32>>,
        period: Duration,
        clock_start_ms: u32,
    ) -> std::io::Result<Self> {
        Self::spawn_with(link, scans, period, clock_start_ms, EmuOptions::default())
    }

    /// As `spawn`, the sensor found in `options`' state.
    pub fn spawn_with(
        link: &Path,
        scans: Vec<Vec<u32>>,
        period: Duration,
        clock_start_ms: u32,
        options: EmuOptions,
    ) -> std::io::Result<Self> {
        let device = plug(link)?;
        let (tx, rx) = channel();
        let stop = Arc::new(AtomicBool::new(false));
        let sent = Arc::new(AtomicU64::new(0));
        let commands = Arc::new(AtomicU64::new(0));
        let (s2, n2, c2, l2) = (
            stop.clone(),
            sent.clone(),
            commands.clone(),
            link.to_path_buf(),
        );
        let thread = std::thread::Builder::new()
            .name("hokuyo-emulator".into())
            .spawn(move || {
                let mut emu = Emu {
                    link: l2,
                    device: Some(device),
                    scans,
                    period,
                    clock_ms: clock_start_ms & 0xFF_FFFF,
                    streaming: false,
                    next: 0,
                    line: Vec::new(),
                    faults: rx,
                    pending: Vec::new(),
                    sent: n2,
                    commands: c2,
                    garbage_seed: 0x1234_5678,
                    mode: options.mode,
                    baud: options.baud,
                };
                emu.run(&s2);
            })?;
        Ok(HokuyoEmulator {
            link: link.to_path_buf(),
            faults: tx,
            stop,
            sent,
            commands,
            thread: Some(thread),
        })
    }

    pub fn link(&self) -> &Path {
        &self.link
    }

    pub fn inject(&self, fault: Fault) {
        let _ = self.faults.send(fault);
    }

    /// Scans sent so far.
    pub fn scans_sent(&self) -> u64 {
        self.sent.load(Ordering::SeqCst)
    }

    /// Commands received so far.
    pub fn commands_received(&self) -> u64 {
        self.commands.load(Ordering::SeqCst)
    }
}

impl Drop for HokuyoEmulator {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        let _ = std::fs::remove_file(&self.link);
    }
}

struct Emu {
    link: PathBuf,
    device: Option<Device>,
    scans: Vec<Vec<u32>>,
    period: Duration,
    clock_ms: u32,
    streaming: bool,
    next: usize,
    line: Vec<u8>,
    faults: Receiver<Fault>,
    pending: Vec<Fault>,
    sent: Arc<AtomicU64>,
    commands: Arc<AtomicU64>,
    garbage_seed: u32,
    mode: EmuMode,
    baud: Option<u32>,
}

/// The line speed the pty's slave is set to (the driver's choice): the
/// master shares the slave's termios on Linux; termios2 carries any speed.
fn line_baud(device: &Device) -> Option<u32> {
    use std::os::fd::AsRawFd;
    // SAFETY: TCGETS2 on an open descriptor into a zeroed termios2
    let mut t: libc::termios2 = unsafe { std::mem::zeroed() };
    if unsafe { libc::ioctl(device.master.as_raw_fd(), libc::TCGETS2, &mut t) } != 0 {
        return None;
    }
    Some(t.c_ospeed)
}

const MD_ECHO: &[u8] = b"MD0044072501000";

impl Emu {
    fn write(&mut self, bytes: &[u8]) {
        if let Some(d) = self.device.as_mut() {
            let _ = d.master.write_all(bytes);
        }
    }

    fn pp_block() -> Vec<u8> {
        let p = SensorParams::URG_04LX;
        let values = [
            (
                "MODL",
                "URG-04LX-UG01(Simple-URG)(Hokuyo Automatic Co.,Ltd.)".to_string(),
            ),
            ("DMIN", p.dmin_mm.to_string()),
            ("DMAX", p.dmax_mm.to_string()),
            ("ARES", p.ares.to_string()),
            ("AMIN", p.amin.to_string()),
            ("AMAX", p.amax.to_string()),
            ("AFRT", p.afrt.to_string()),
            ("SCAN", p.scan_rpm.to_string()),
        ];
        let pairs: Vec<(&str, &str)> = values.iter().map(|(k, v)| (*k, v.as_str())).collect();
        build_key_value_reply(b"PP", &pairs)
    }

    fn handle(&mut self, cmd: Vec<u8>) {
        self.commands.fetch_add(1, Ordering::SeqCst);
        if let (Some(want), Some(d)) = (self.baud, self.device.as_ref()) {
            if line_baud(d) != Some(want) {
                // at the wrong speed the sensor hears noise: no answer
                return;
            }
        }
        // the echo is the command as received (tag included)
        let body: Vec<u8> = cmd.split(|&b| b == b';').next().unwrap_or(&[]).to_vec();
        let reply = |status: &[u8; 2]| build_reply(&cmd, status, None, &[]);
        match self.mode {
            EmuMode::Scip20 => {}
            EmuMode::Scip11 => {
                // SCIP 1.1: echo, a one-character status, a blank line
                let ok = body.as_slice() == b"SCIP2.0";
                if ok {
                    self.mode = EmuMode::Scip20;
                }
                let mut out = cmd.clone();
                out.extend_from_slice(if ok { b"\n0\n\n" } else { b"\nE\n\n" });
                self.write(&out);
                return;
            }
            EmuMode::TimeStamp => {
                let out = match body.as_slice() {
                    b"TM2" => {
                        self.mode = EmuMode::Scip20;
                        reply(b"00")
                    }
                    b"TM0" => reply(b"02"),
                    b"TM1" => build_reply(&cmd, b"00", Some(self.clock_ms), &[]),
                    _ => reply(b"0E"),
                };
                self.write(&out);
                return;
            }
        }
        let out = match body.as_slice() {
            b"QT" => {
                self.streaming = false;
                reply(b"00")
            }
            b"SCIP2.0" | b"BM" | b"RS" | b"TM2" => reply(b"00"),
            b"TM0" => {
                self.mode = EmuMode::TimeStamp;
                reply(b"00")
            }
            b"PP" => Self::pp_block(),
            b"VV" | b"II" => build_key_value_reply(
                &cmd,
                &[
                    ("VEND", "Hokuyo Automatic Co.,Ltd."),
                    ("PROD", "SOKUIKI Sensor URG-04LX-UG01 (opennav emulator)"),
                ],
            ),
            b if b.starts_with(b"MD") && b.len() == MD_ECHO.len() => {
                if b == MD_ECHO {
                    self.streaming = true;
                    reply(b"00")
                } else {
                    // only the full-range request is emulated
                    reply(b"01")
                }
            }
            _ => reply(b"0E"),
        };
        self.write(&out);
    }

    fn send_scan(&mut self) {
        if self.scans.is_empty() {
            return;
        }
        let values = self.scans[self.next % self.scans.len()].clone();
        self.next += 1;
        let data: Vec<u8> = values.iter().flat_map(|&v| encode_value(v, 3)).collect();
        let ts = self.clock_ms;
        self.clock_ms = (self.clock_ms + self.period.as_millis() as u32) & 0xFF_FFFF;
        let fault = if self.pending.is_empty() {
            None
        } else {
            Some(self.pending.remove(0))
        };
        let mut block = build_reply(MD_ECHO, b"99", Some(ts), &data);
        match fault {
            Some(Fault::BadChecksum) => {
                // a data byte of the third data line
                let lf: Vec<usize> = block
                    .iter()
                    .enumerate()
                    .filter(|(_, &b)| b == b'\n')
                    .map(|(i, _)| i)
                    .collect();
                let i = lf[4] + 5;
                block[i] = if block[i] == b'0' { b'1' } else { b'0' };
            }
            Some(Fault::Truncated) => {
                block.truncate(block.len() / 2);
                block.extend_from_slice(b"\n\n");
            }
            Some(Fault::ErrorStatus(code)) => {
                let st = [b'0' + (code / 10) % 10, b'0' + code % 10];
                block = build_reply(MD_ECHO, &st, None, &[]);
                self.streaming = false;
            }
            Some(Fault::Garbage) => {
                let mut g = Vec::new();
                for _ in 0..300 {
                    self.garbage_seed = self
                        .garbage_seed
                        .wrapping_mul(1_103_515_245)
                        .wrapping_add(12345);
                    g.push((self.garbage_seed >> 16) as u8);
                }
                g.extend_from_slice(b"\n\n");
                self.write(&g);
            }
            Some(Fault::Silence(d)) => {
                std::thread::sleep(d);
                return;
            }
            Some(f @ (Fault::Unplug(d) | Fault::PowerCycle(d))) => {
                self.device = None;
                let _ = std::fs::remove_file(&self.link);
                self.streaming = false;
                std::thread::sleep(d);
                if matches!(f, Fault::PowerCycle(_)) {
                    // its millisecond counter starts again from power-up
                    self.clock_ms = 17;
                    self.mode = EmuMode::Scip20;
                }
                match plug(&self.link) {
                    Ok(dev) => self.device = Some(dev),
                    Err(e) => tracing::error!(error = %e, "emulator could not replug"),
                }
                return;
            }
            None => {}
        }
        self.write(&block);
        self.sent.fetch_add(1, Ordering::SeqCst);
    }

    fn run(&mut self, stop: &AtomicBool) {
        let mut next_scan = Instant::now() + self.period;
        let mut buf = [0u8; 512];
        while !stop.load(Ordering::SeqCst) {
            while let Ok(f) = self.faults.try_recv() {
                self.pending.push(f);
            }
            // commands
            let n = match self.device.as_mut() {
                Some(d) => d.master.read(&mut buf).unwrap_or(0),
                None => 0,
            };
            for &b in &buf[..n] {
                if b == b'\n' || b == b'\r' {
                    if !self.line.is_empty() {
                        let cmd = std::mem::take(&mut self.line);
                        self.handle(cmd);
                    }
                } else if self.line.len() < 64 {
                    self.line.push(b);
                }
            }
            // stream (faults like silence and unplug act when the scan is due,
            // and also while stopped)
            let now = Instant::now();
            if now >= next_scan {
                next_scan = now + self.period;
                let urgent = matches!(
                    self.pending.first(),
                    Some(Fault::Unplug(_)) | Some(Fault::PowerCycle(_)) | Some(Fault::Garbage)
                );
                if self.streaming || urgent {
                    self.send_scan();
                }
            }
            if n == 0 {
                std::thread::sleep(Duration::from_millis(1));
            }
        }
    }
}
