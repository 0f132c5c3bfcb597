//! FollowJSM's answer: our joystick frame must follow each of the joystick
//! module's within 1 ms (the power module acts on the newest frame). The
//! real writer (`RnetActuator` with its precise ticker) started as the
//! chair starts it — its own thread and single-threaded runtime at
//! SCHED_FIFO 50 (`spawn_actuator_thread`), off the daemon's workers — or,
//! for comparison, as a task on the daemon's two-worker runtime; on the
//! in-memory bus; a
//! JSM thread sends a centred frame every 10 ms and its heartbeat every
//! 100 ms; an observer on the bus stamps every frame as it arrives. The
//! latency is from the JSM frame's send to our answer's arrival (so it
//! includes the bus's own delivery to the observer: an upper bound).
//! Measured idle and with both cores busy (two spinning threads standing
//! in for perception).
//!
//!
//! `--jsmerror PERIODS`: the writer in JSMerror mode instead (the JSM goes
//! quiet at the silence frame, the writer's own 10 ms ticker sends every
//! frame): the period between our frames as they arrive at the observer,
//! PERIODS of them, idle and with both cores busy.
//!
//!   cargo bench --bench followjsm_latency [-- FRAMES]
//!   cargo bench --bench followjsm_latency -- --jsmerror 10000

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use opennav::actuation::can::{BusEvent, CanBus, MemoryBus};
use opennav::actuation::rnet::{
    joystick_frame, CanFrame, JoystickMapping, TakeoverMode, JSM_HEARTBEAT_ID, JSM_SILENCE_ID,
};
use opennav::actuation::writer::{RnetActuator, RnetSettings};
use opennav::actuation::{
    spawn_actuator_thread, thread_result, Actuator, ActuatorIo, ActuatorStatus,
};
use opennav::msg::{Clock, MonotonicClock, SafeCmd, SupervisorState, VelocityCmd};
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

const JSM_ID: u32 = 0x0200_0000;

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i]
}

/// Latencies (µs) of `frames` answers (FollowJSM), or with `jsmerror`
/// the periods (µs) between `frames + 1` of our frames.
fn measure(frames: usize, load: bool, own_thread: bool, jsmerror: bool) -> Vec<f64> {
    let stop_load = Arc::new(AtomicBool::new(false));
    let mut spinners = Vec::new();
    if load {
        for _ in 0..2 {
            let s = stop_load.clone();
            spinners.push(std::thread::spawn(move || {
                let mut x = 0u64;
                while !s.load(Ordering::Relaxed) {
                    x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
                    std::hint::black_box(x);
                }
            }));
        }
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    let out = rt.block_on(async {
        let clock: Arc<dyn Clock> = Arc::new(MonotonicClock::new());
        let bus = MemoryBus::new();
        let jsm = bus.endpoint();
        let observer = bus.endpoint();
        // the supervisor's command, fresh every 20 ms
        let (cmd_tx, cmd_rx) = watch::channel(None);
        let cancel = CancellationToken::new();
        {
            let (clock, cancel) = (clock.clone(), cancel.clone());
            tokio::spawn(async move {
                let mut tick = tokio::time::interval(Duration::from_millis(20));
                while !cancel.is_cancelled() {
                    tick.tick().await;
                    cmd_tx.send_replace(Some(SafeCmd {
                        cmd: VelocityCmd {
                            v_mps: 0.2,
                            omega_radps: 0.0,
                        },
                        state: SupervisorState::Navigating,
                        stamp: clock.now(),
                        view: None,
                    }));
                }
            });
        }
        let (ev_tx, mut ev_rx) = mpsc::channel(64);
        tokio::spawn(async move { while ev_rx.recv().await.is_some() {} });
        let (status_tx, _status) = watch::channel(ActuatorStatus::default());
        let actuator = RnetActuator {
            bus: bus.endpoint(),
            settings: RnetSettings::new(
                if jsmerror {
                    TakeoverMode::JsmError
                } else {
                    TakeoverMode::FollowJsm
                },
                JoystickMapping {
                    forward_full_mps: 0.6,
                    reverse_full_mps: 0.3,
                    turn_full_radps: 1.6,
                    deadband: 0,
                },
            ),
        };
        let io = ActuatorIo {
            commands: cmd_rx,
            events: ev_tx,
            status: status_tx,
            cancel: cancel.clone(),
            clock: clock.clone(),
        };
        let writer = if own_thread {
            let h = spawn_actuator_thread("rnet-writer", 50, move || Ok(actuator), io)
                .expect("writer thread");
            tokio::spawn(thread_result(h))
        } else {
            tokio::spawn(actuator.run(io))
        };
        // the JSM: its own thread (real-time, as the chair's JSM is its own
        // device), absolute 10 ms deadlines
        let sent: Arc<Mutex<Vec<Instant>>> = Arc::new(Mutex::new(Vec::new()));
        let jsm_stop = Arc::new(AtomicBool::new(false));
        // JSMerror: the silence frame seen, the JSM's joystick frames stop
        let silenced = Arc::new(AtomicBool::new(false));
        let jsm_thread = {
            let (sent, stop, silenced) = (sent.clone(), jsm_stop.clone(), silenced.clone());
            std::thread::spawn(move || {
                let param = libc::sched_param { sched_priority: 70 };
                // SAFETY: plain syscall on this thread; refusal is fine
                unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
                let mut next = Instant::now();
                let mut k = 0u64;
                while !stop.load(Ordering::Relaxed) {
                    let now = Instant::now();
                    if k.is_multiple_of(10) {
                        let _ = jsm.try_send(&CanFrame::ext(JSM_HEARTBEAT_ID, &[0x87; 8]));
                    }
                    if !silenced.load(Ordering::Relaxed) {
                        sent.lock().expect("sent").push(now);
                        let _ = jsm.try_send(&joystick_frame(JSM_ID, 0, 0));
                    }
                    k += 1;
                    next += Duration::from_millis(10);
                    std::thread::sleep(next.saturating_duration_since(Instant::now()));
                }
            })
        };
        // the observer: every answer as it arrives, on its own thread at a
        // higher real-time priority than the writer (so the spinners do
        // not delay the measurement itself)
        let observer_thread = {
            let (sent, silenced) = (sent.clone(), silenced.clone());
            std::thread::spawn(move || {
                let param = libc::sched_param { sched_priority: 70 };
                // SAFETY: plain syscall on this thread; refusal is fine
                unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &param) };
                let rt = tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .build()
                    .expect("observer runtime");
                rt.block_on(async move {
                    let mut latencies = Vec::with_capacity(frames);
                    let warmup = Instant::now() + Duration::from_secs(1);
                    let mut last_ours: Option<Instant> = None;
                    while latencies.len() < frames {
                        let Ok(ev) = observer.recv().await else { break };
                        let at = Instant::now();
                        let BusEvent::Frame(f) = ev else { continue };
                        if jsmerror {
                            if f.id == JSM_SILENCE_ID {
                                silenced.store(true, Ordering::Relaxed);
                            }
                            // after the silence only ours carry the id
                            if f.id != JSM_ID || !silenced.load(Ordering::Relaxed) || at < warmup {
                                continue;
                            }
                            if let Some(prev) = last_ours.replace(at) {
                                latencies.push((at - prev).as_secs_f64() * 1e6);
                            }
                            continue;
                        }
                        // ours carry the command (the JSM's and our first
                        // frames are centred)
                        if f.id != JSM_ID || f.data[..2] == [0, 0] || at < warmup {
                            continue;
                        }
                        // the JSM frame it answers: the newest sent before
                        let sent = sent.lock().expect("sent");
                        let i = sent.partition_point(|t| *t <= at);
                        if let Some(t) = i.checked_sub(1).map(|i| sent[i]) {
                            latencies.push((at - t).as_secs_f64() * 1e6);
                        }
                    }
                    latencies
                })
            })
        };
        let latencies = tokio::task::spawn_blocking(move || observer_thread.join())
            .await
            .expect("joined")
            .expect("observer");
        jsm_stop.store(true, Ordering::Relaxed);
        let _ = jsm_thread.join();
        cancel.cancel();
        let _ = writer.await;
        latencies
    });
    stop_load.store(true, Ordering::Relaxed);
    for s in spinners {
        let _ = s.join();
    }
    out
}

fn main() {
    let frames: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(3000);
    if std::env::args().any(|a| a == "--jsmerror") {
        for load in [false, true] {
            let mut l = measure(frames, load, true, true);
            l.sort_by(f64::total_cmp);
            let off = |us: &f64| (us - 10_000.0).abs();
            let mut jitter: Vec<f64> = l.iter().map(off).collect();
            jitter.sort_by(f64::total_cmp);
            let over_1ms = jitter.iter().filter(|j| **j > 1000.0).count();
            println!(
                "jsmerror writer period (writer thread SCHED_FIFO, {}, {} periods): p1 {:.0} µs, p50 {:.0} µs, p99 {:.0} µs, max {:.0} µs; |period − 10 ms| p99 {:.0} µs, max {:.0} µs, over 1 ms: {} ({:.2} %)",
                if load { "both cores busy" } else { "idle" },
                l.len(),
                percentile(&l, 0.01),
                percentile(&l, 0.5),
                percentile(&l, 0.99),
                l.last().copied().unwrap_or(f64::NAN),
                percentile(&jitter, 0.99),
                jitter.last().copied().unwrap_or(f64::NAN),
                over_1ms,
                100.0 * over_1ms as f64 / l.len().max(1) as f64
            );
        }
        return;
    }
    for (own_thread, load) in [(true, false), (true, true), (false, false), (false, true)] {
        let mut l = measure(frames, load, own_thread, false);
        l.sort_by(f64::total_cmp);
        let over_1ms = l.iter().filter(|v| **v > 1000.0).count();
        println!(
            "followjsm answer ({}, {}, {} frames): p50 {:.0} µs, p99 {:.0} µs, max {:.0} µs, over 1 ms: {} ({:.2} %)",
            if own_thread {
                "writer thread SCHED_FIFO (as on the chair)"
            } else {
                "writer on the async workers"
            },
            if load { "both cores busy" } else { "idle" },
            l.len(),
            percentile(&l, 0.5),
            percentile(&l, 0.99),
            l.last().copied().unwrap_or(f64::NAN),
            over_1ms,
            100.0 * over_1ms as f64 / l.len().max(1) as f64
        );
    }
}
