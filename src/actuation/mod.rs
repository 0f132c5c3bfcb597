//! Actuation: the chair's R-Net motor interface. `rnet.rs` is the pure
//! codec, the velocity ↔ joystick mapping and the takeover state machine;
//! `can.rs` the SocketCAN adapter (and an in-memory bus for tests);
//! `writer.rs` the 100 Hz R-Net writer; `rebus.rs` the Rebus USB-serial
//! codec and `rebus_link.rs` its link and backend. Both backends implement
//! [`Actuator`] and are chosen in config (`[actuation] backend`).

use std::future::Future;
use std::sync::Arc;

use serde::Serialize;
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

use crate::msg::Clock;
use crate::msg::{FaultReason, SafeCmd, Stamp};

pub mod can;
pub mod check;
pub mod rebus;
pub mod rebus_link;
pub mod rnet;
pub mod writer;

/// What an actuator tells the supervisor (and the log).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum ActuatorEvent {
    /// The link to the chair is up (R-Net: the joystick id learned; Rebus:
    /// start-up acknowledged).
    Ready { joystick_id: Option<u32> },
    /// Our frames drive the chair (R-Net JSMerror: the JSM went quiet).
    Active,
    /// The user moved the real joystick: autonomy yields (supervisor stop).
    UserDeflection { x: i8, y: i8 },
    /// A bus or link fault: the supervisor latches a fault of this kind
    /// (CAN bus for R-Net, motor link for Rebus).
    Fault { kind: FaultReason, reason: String },
    /// The JSM's heartbeat is gone (chair switched off?).
    JsmLost,
    /// Shutdown finished: centred frames sent, then nothing.
    Released,
}

/// Period statistics of the writer, microseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct PeriodStats {
    pub count: usize,
    pub p50_us: f64,
    pub p99_us: f64,
    /// The 1st percentile (with p99: the spread around the period).
    pub p01_us: f64,
    pub max_us: f64,
}

impl PeriodStats {
    /// From measured intervals (seconds). Nearest-rank percentiles.
    pub fn from_intervals(intervals_s: &[f64]) -> PeriodStats {
        if intervals_s.is_empty() {
            return PeriodStats::default();
        }
        let mut v: Vec<f64> = intervals_s.iter().map(|s| s * 1e6).collect();
        v.sort_by(f64::total_cmp);
        let q = |p: f64| v[((p * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)];
        PeriodStats {
            count: v.len(),
            p50_us: q(0.5),
            p99_us: q(0.99),
            p01_us: q(0.01),
            max_us: v[v.len() - 1],
        }
    }
}

/// Durations (periods, step times) over a whole run in constant memory:
/// 10 µs bins up to 100 ms, longer ones counted apart, and the longest.
/// Percentiles are a bin's upper edge: at most 10 µs above the truth.
#[derive(Debug, Clone, PartialEq)]
pub struct DurationHistogram {
    bins: Vec<u32>,
    bin_s: f64,
    over: u64,
    count: u64,
    max_s: f64,
}

impl Default for DurationHistogram {
    fn default() -> Self {
        DurationHistogram::new()
    }
}

impl DurationHistogram {
    const BIN_S: f64 = 10e-6;
    const BINS: usize = 10_000;

    pub fn new() -> DurationHistogram {
        DurationHistogram::with_bins(Self::BIN_S, Self::BINS)
    }

    /// `bins` bins of `bin_s` seconds each.
    pub fn with_bins(bin_s: f64, bins: usize) -> DurationHistogram {
        DurationHistogram {
            bins: vec![0; bins.max(1)],
            bin_s,
            over: 0,
            count: 0,
            max_s: 0.0,
        }
    }

    /// One duration, seconds (a negative or NaN one counts as zero).
    pub fn record(&mut self, d_s: f64) {
        let d_s = if d_s > 0.0 { d_s } else { 0.0 };
        let bin = (d_s / self.bin_s) as usize;
        match self.bins.get_mut(bin) {
            Some(b) => *b = b.saturating_add(1),
            None => self.over += 1,
        }
        self.count += 1;
        self.max_s = self.max_s.max(d_s);
    }

    pub fn count(&self) -> u64 {
        self.count
    }

    /// Nearest-rank percentiles, as [`PeriodStats::from_intervals`].
    pub fn stats(&self) -> PeriodStats {
        if self.count == 0 {
            return PeriodStats::default();
        }
        let max_us = self.max_s * 1e6;
        let q = |p: f64| {
            let rank = (p * (self.count - 1) as f64).round() as u64;
            let mut seen = 0u64;
            for (i, &n) in self.bins.iter().enumerate() {
                seen += u64::from(n);
                if seen > rank {
                    return ((i + 1) as f64 * self.bin_s * 1e6).min(max_us);
                }
            }
            max_us
        };
        PeriodStats {
            count: self.count as usize,
            p50_us: q(0.5),
            p99_us: q(0.99),
            p01_us: q(0.01),
            max_us,
        }
    }
}

/// Frame-to-command latency: from a view's camera stamp to the first
/// frame the actuator sent carrying a command made after the tracker had
/// that view (100 µs bins up to 1 s).
#[derive(Debug, Clone, PartialEq)]
pub struct ViewLatency {
    /// The newest view of the commands not yet sent.
    pending: Option<Stamp>,
    /// The newest view already measured.
    measured: Option<Stamp>,
    latency: DurationHistogram,
}

impl Default for ViewLatency {
    fn default() -> Self {
        ViewLatency {
            pending: None,
            measured: None,
            latency: DurationHistogram::with_bins(100e-6, 10_000),
        }
    }
}

impl ViewLatency {
    /// The command the next frame carries.
    pub fn on_command(&mut self, cmd: &SafeCmd) {
        if let Some(v) = cmd.view {
            if self.measured.is_none_or(|m| v > m) {
                self.pending = Some(v);
            }
        }
    }

    /// A frame carrying the latest command went out at `now`.
    pub fn on_sent(&mut self, now: Stamp) {
        if let Some(v) = self.pending.take() {
            self.latency.record(v.age_at(now).as_secs_f64());
            self.measured = Some(v);
        }
    }

    pub fn stats(&self) -> PeriodStats {
        self.latency.stats()
    }
}

/// Live status of an actuator (for `opennav status`, logs and tests).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ActuatorStatus {
    pub backend: &'static str,
    pub state: String,
    pub joystick_id: Option<u32>,
    /// Frames (packets) sent.
    pub sent: u64,
    /// Frames not sent in their slot (TX queue full, write error): never
    /// sent late.
    pub dropped: u64,
    /// Writer slots missed (the task woke more than a period late).
    pub late: u64,
    /// Error frames / link errors seen.
    pub bus_errors: u64,
    /// Last joystick values sent (turn, forward).
    pub last_output: (i8, i8),
    /// Writer period over the last thousand periods (10 s).
    pub period: PeriodStats,
    /// Writer period over the whole run.
    pub period_run: PeriodStats,
    /// Camera stamp of each new view → the first frame carrying the
    /// command made after it, over the whole run.
    pub frame_to_command: PeriodStats,
}

/// The channels an actuator runs with.
pub struct ActuatorIo {
    /// The supervisor's latest output (its stamp is the freshness clock:
    /// older than the command limit → centred).
    pub commands: watch::Receiver<Option<SafeCmd>>,
    pub events: mpsc::Sender<ActuatorEvent>,
    pub status: watch::Sender<ActuatorStatus>,
    /// Cancelled on shutdown: the actuator centres, then releases.
    pub cancel: CancellationToken,
    pub clock: Arc<dyn Clock>,
}

#[derive(Debug, thiserror::Error)]
pub enum ActuatorError {
    #[error(transparent)]
    Can(#[from] can::CanBusError),
    #[error("Rebus link: {0}")]
    Rebus(String),
    #[error("actuator task: {0}")]
    Task(String),
    #[error("the takeover did not happen: {0}")]
    Takeover(String),
}

/// A motor interface: runs until cancelled (then centres and releases) or
/// until its device fails.
pub trait Actuator: Send + 'static {
    fn run(
        self,
        io: ActuatorIo,
    ) -> impl Future<Output = Result<ActuatorStatus, ActuatorError>> + Send;
}

/// Runs an actuator on its own OS thread with its own single-threaded
/// tokio runtime, so that nothing else on the async workers delays its
/// 10 ms ticks. `make` builds the actuator on that thread (a SocketCAN
/// socket registers with the runtime it is opened in). The thread asks
/// for real-time scheduling (`SCHED_FIFO`, priority `rt_priority`) when
/// `rt_priority > 0` and goes on at normal priority when refused.
pub fn spawn_actuator_thread<A, F>(
    name: &str,
    rt_priority: i32,
    make: F,
    io: ActuatorIo,
) -> std::io::Result<std::thread::JoinHandle<Result<ActuatorStatus, ActuatorError>>>
where
    A: Actuator,
    F: FnOnce() -> Result<A, ActuatorError> + Send + 'static,
{
    std::thread::Builder::new()
        .name(name.to_string())
        .spawn(move || {
            if rt_priority > 0 {
                set_realtime(rt_priority);
            }
            let rt = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .map_err(|e| ActuatorError::Task(format!("runtime: {e}")))?;
            rt.block_on(async move { make()?.run(io).await })
        })
}

/// The end of an actuator thread (its result, or its panic as an error) as
/// a future, without blocking an async worker: a small thread joins it.
pub fn thread_result(
    h: std::thread::JoinHandle<Result<ActuatorStatus, ActuatorError>>,
) -> impl Future<Output = Result<ActuatorStatus, ActuatorError>> + Send + 'static {
    let (tx, rx) = tokio::sync::oneshot::channel();
    let spawned = std::thread::Builder::new()
        .name("actuator-join".into())
        .spawn(move || {
            let r = h.join().unwrap_or_else(|p| {
                Err(ActuatorError::Task(format!(
                    "panicked: {}",
                    crate::daemon::panic_message(p)
                )))
            });
            // the daemon may be gone already: nobody left to tell
            tx.send(r).ok();
        });
    async move {
        spawned.map_err(|e| ActuatorError::Task(format!("joiner thread: {e}")))?;
        rx.await.unwrap_or_else(|_| {
            Err(ActuatorError::Task(
                "the actuator thread's result was lost".into(),
            ))
        })
    }
}

/// Best effort: SCHED_FIFO for the calling thread.
pub(crate) fn set_realtime(priority: i32) {
    let param = libc::sched_param {
        sched_priority: priority,
    };
    // SAFETY: plain syscall on the calling thread with a valid parameter
    let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
    if rc != 0 {
        tracing::info!(
            priority,
            error = %std::io::Error::last_os_error(),
            "real-time scheduling refused; writer runs at normal priority"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The histogram's percentiles are the exact ones rounded up to its
    /// 10 µs bins; beyond 100 ms only the maximum is kept exactly.
    #[test]
    fn histogram_percentiles_are_the_exact_ones_to_a_bin() {
        let mut h = DurationHistogram::new();
        let mut seed = 3u64;
        let mut all = Vec::new();
        for i in 0..20_000 {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let jitter = (seed >> 40) as f64 / (1u64 << 24) as f64; // 0..1
            let d = if i % 500 == 0 {
                0.25
            } else {
                0.010 + 0.002 * (jitter - 0.5)
            };
            h.record(d);
            all.push(d);
        }
        let exact = PeriodStats::from_intervals(&all);
        let got = h.stats();
        assert_eq!(got.count, 20_000);
        for (g, e) in [
            (got.p01_us, exact.p01_us),
            (got.p50_us, exact.p50_us),
            (got.p99_us, exact.p99_us),
        ] {
            assert!(g >= e && g - e <= 10.0 + 1e-6, "{g} vs {e}");
        }
        assert_eq!(got.max_us, 250_000.0);
        assert_eq!(DurationHistogram::new().stats(), PeriodStats::default());
    }

    fn cmd_of(view_ms: Option<u64>) -> SafeCmd {
        SafeCmd {
            cmd: Default::default(),
            state: crate::msg::SupervisorState::Navigating,
            stamp: Stamp(std::time::Duration::ZERO),
            view: view_ms.map(|ms| Stamp(std::time::Duration::from_millis(ms))),
        }
    }

    /// Each view is measured once, at the first frame after a command
    /// that carries it; commands without a view, an older view or the
    /// same view again measure nothing.
    #[test]
    fn frame_to_command_measures_each_view_once_at_its_first_frame() {
        let ms = |m: u64| Stamp(std::time::Duration::from_millis(m));
        let mut l = ViewLatency::default();
        l.on_sent(ms(5));
        l.on_command(&cmd_of(None));
        l.on_sent(ms(10));
        assert_eq!(l.stats().count, 0);
        l.on_command(&cmd_of(Some(100)));
        l.on_command(&cmd_of(Some(100)));
        l.on_sent(ms(134));
        l.on_sent(ms(144));
        l.on_command(&cmd_of(Some(100)));
        l.on_sent(ms(154));
        l.on_command(&cmd_of(Some(90)));
        l.on_sent(ms(164));
        let s = l.stats();
        assert_eq!(s.count, 1);
        assert_eq!(s.max_us, 34_000.0);
        // a newer view; two views before one frame: the newest is measured
        l.on_command(&cmd_of(Some(200)));
        l.on_command(&cmd_of(Some(233)));
        l.on_sent(ms(270));
        let s = l.stats();
        assert_eq!(s.count, 2);
        // percentiles are a 100 µs bin's upper edge, the maximum exact
        assert!((34_000.0..=34_100.0).contains(&s.p01_us), "{s:?}");
        assert_eq!(s.max_us, 37_000.0);
    }
}
