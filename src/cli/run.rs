//! `opennav run`: the daemon, on the chair's devices or (with `--sim`) on
//! the simulator — the same `daemon::run` either way. Prints the run's
//! report as one JSON line at the end; a task that failed exits 1 naming
//! it, missing devices exit 1 naming them.

use std::path::PathBuf;
use std::sync::Arc;

use clap::{Args, ValueEnum};
use serde::Serialize;
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

use opennav::config::Settings;
use opennav::daemon::chair::CameraChoice;
use opennav::daemon::{Outcome, RunOptions, RunReport};
use opennav::input::{DaemonStatus, InputHub};
use opennav::msg::{Clock, TokioClock, UserInput};
use opennav::setup::PerceptionChoice;
use opennav::sim::devices::SimSummary;

use super::{bad_input, failed, parse_duration, Failure};

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ClockArg {
    /// Simulated time, as fast as the computation allows, deterministic.
    Virtual,
    /// The host's monotonic clock (for a person watching).
    Realtime,
}

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Run on the simulator (the living room) instead of the chair's devices.
    #[arg(long)]
    pub sim: bool,
    /// With --sim: the simulator's clock (default virtual).
    #[arg(long, value_enum, requires = "sim")]
    pub clock: Option<ClockArg>,
    /// A word to go to at start (repeatable: said in order).
    #[arg(long)]
    pub prompt: Vec<String>,
    /// Exit when the goal is reached, lost or not found (prints the report).
    #[arg(long)]
    pub exit_on_arrival: bool,
    /// Stop after this long (on the run's clock), e.g. 90s.
    #[arg(long, value_parser = parse_duration)]
    pub max_duration: Option<std::time::Duration>,
    /// Do not read words from stdin.
    #[arg(long)]
    pub no_stdin: bool,
    /// On the chair's devices: camera frames from a recording (TUM RGB-D
    /// layout) instead of the RealSense.
    #[arg(long, conflicts_with_all = ["no_camera", "sim"])]
    pub camera_replay: Option<PathBuf>,
    /// On the chair's devices: no camera (stop and safety only).
    #[arg(long, conflicts_with = "sim")]
    pub no_camera: bool,
    /// Record the sensors and perception's output to this MCAP file.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// The control socket (one JSON request per line: go, stop, resume,
    /// yes, no, ack_fault, status). On the chair's devices it is always
    /// open, here or at `input.control_socket` (default
    /// $RUNTIME_DIRECTORY/control.sock); with --sim only when given.
    #[arg(long)]
    pub control_socket: Option<PathBuf>,
    /// Listen to this audio file (16 kHz mono WAV or .raw) as if it came
    /// from the microphone (needs the `voice` feature).
    #[arg(long)]
    pub voice_wav: Option<PathBuf>,
    /// Stream the live view to Foxglove (WebSocket) on ADDR, default
    /// `[live] address` (127.0.0.1:8765); `[live] enabled` turns it on
    /// without the flag.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "")]
    pub live: Option<String>,
    /// Bridge to ROS 2 (the `ros2` feature; no ROS install): sentences on
    /// /opennav/said, status on /opennav/state, words from /opennav/prompt,
    /// stops from /opennav/stop.
    #[arg(long)]
    pub ros2: bool,
    /// With --sim: speak the sentences too (espeak-ng, `[speech]`); on
    /// the chair they are spoken unless speech.enabled = false.
    #[arg(long)]
    pub speak: bool,
    /// Fault-injection tests: the named task panics after this long
    /// (TASK@DURATION, e.g. perception@2s).
    #[arg(long, hide = true)]
    pub inject_panic: Option<String>,
}

/// The configuration as given, for a recording's metadata: the file's
/// text (or that the built-in defaults apply) and the `OPENNAV_`
/// environment overrides.
fn config_as_given(config: Option<&std::path::Path>) -> String {
    let mut out = match config {
        Some(p) => match std::fs::read_to_string(p) {
            Ok(t) => format!("# {}\n{t}", p.display()),
            Err(e) => format!("# {}: {e}", p.display()),
        },
        None => "# the built-in defaults (config/opennav.toml)\n".to_string(),
    };
    let mut env: Vec<(String, String)> = std::env::vars()
        .filter(|(k, _)| k.starts_with("OPENNAV_") && k.contains("__"))
        .collect();
    env.sort();
    for (k, v) in env {
        out.push_str(&format!("# env {k}={v}\n"));
    }
    out
}

/// The report printed at the end.
#[derive(Serialize)]
struct Printed<'a> {
    #[serde(flatten)]
    report: &'a RunReport,
    sim: Option<SimSummary>,
    /// The ROS 2 bridge's drops (None: no bridge).
    #[serde(skip_serializing_if = "Option::is_none")]
    ros2: Option<opennav::ros2::BridgeCounts>,
}

pub fn run(config: Option<&std::path::Path>, args: RunArgs) -> Result<(), Failure> {
    let settings = Settings::load(config).map_err(bad_input)?;
    let virtual_clock = args.sim && args.clock.unwrap_or(ClockArg::Virtual) == ClockArg::Virtual;
    let inject_panic = match &args.inject_panic {
        Some(s) => {
            let (task, after) = s.split_once('@').ok_or_else(|| {
                bad_input(anyhow::anyhow!(
                    "--inject-panic {s:?}: expected TASK@DURATION"
                ))
            })?;
            let after = parse_duration(after)
                .map_err(|e| bad_input(anyhow::anyhow!("--inject-panic: {e}")))?;
            Some((task.to_string(), after))
        }
        None => None,
    };
    // what the chair says: spoken (espeak-ng) and on stderr, as it is said
    let speaker = if settings.speech.enabled && (!args.sim || args.speak) {
        Some(opennav::speech::Speaker::start(&settings.speech).map_err(failed)?)
    } else {
        None
    };
    let (speech_tx, mut speech_rx) = mpsc::unbounded_channel::<String>();
    // the sentences for the ROS 2 bridge too
    let (ros2_said_tx, ros2_said_rx) = std::sync::mpsc::channel::<String>();
    let ros2 = args.ros2 || settings.ros2.enabled;
    let ros2_said_tx = ros2.then_some(ros2_said_tx);
    let speech = std::thread::Builder::new()
        .name("sentences".into())
        .spawn(move || {
            while let Some(s) = speech_rx.blocking_recv() {
                if let Some(tx) = &ros2_said_tx {
                    // the bridge gone: it said why when it started
                    tx.send(s.clone()).ok();
                }
                // in the journal the control task's event says it already
                if !super::TO_JOURNAL.load(std::sync::atomic::Ordering::SeqCst) {
                    eprintln!("opennav says: {s}");
                }
                if let Some(sp) = &speaker {
                    sp.say(&s);
                }
            }
            if let Some(sp) = speaker {
                sp.finish();
            }
        })
        .map_err(failed)?;
    let (hub, receivers) = opennav::input::hub();
    let (status_tx, status_rx) = watch::channel(DaemonStatus::default());
    let switch_sentences = speech_tx.clone();
    let voice_sentences = speech_tx.clone();
    let voice_wav = args.voice_wav.clone();
    let live = match args.live.as_deref() {
        Some("") => Some(settings.live.socket_addr().map_err(bad_input)?),
        Some(a) => Some(a.parse().map_err(|e| {
            bad_input(anyhow::anyhow!(
                "--live {a:?}: not host:port with an IP address ({e})"
            ))
        })?),
        None if settings.live.enabled => Some(settings.live.socket_addr().map_err(bad_input)?),
        None => None,
    };
    let mut opts = RunOptions {
        exit_on_arrival: args.exit_on_arrival,
        max_duration: args.max_duration,
        record: args.record.clone(),
        speech: Some(speech_tx),
        // the simulator's faults are not the chair's
        state_dir: if args.sim {
            None
        } else {
            let dir = settings.state_dir();
            if dir.is_none() {
                tracing::warn!(
                    "no state directory (runtime.state_dir, $STATE_DIRECTORY, $HOME): \
                     a latched fault will not survive a restart"
                );
            }
            dir
        },
        inject_panic,
        stops: Some(receivers.stops),
        status: Some(status_tx),
        live,
        live_started: live.map(|_| {
            // where to point Foxglove, on stderr as the run starts
            let (tx, rx) = std::sync::mpsc::channel::<std::net::SocketAddr>();
            std::thread::spawn(move || {
                if let Ok(a) = rx.recv() {
                    eprintln!(
                        "opennav: live view on ws://{a} (Foxglove: Open connection → Foxglove WebSocket)"
                    );
                }
            });
            tx
        }),
        live_wait: None,
        config_text: Some(config_as_given(config)),
        // the ROS 2 bridge, once it runs
        viewers: None,
    };
    let input_rx = receivers.words;
    for p in &args.prompt {
        hub.send(UserInput::parse(p)).map_err(|_| {
            bad_input(anyhow::anyhow!(
                "--prompt: at most {} words",
                opennav::input::WORDS_QUEUED
            ))
        })?;
    }
    if !args.no_stdin {
        let tx = hub.clone();
        std::thread::Builder::new()
            .name("stdin".into())
            .spawn(move || read_words(std::io::stdin().lock(), &tx))
            .map_err(failed)?;
    }
    // the control socket: always on the chair, on request in the simulator
    let socket_path = match (&args.control_socket, args.sim) {
        (Some(p), _) => Some(p.clone()),
        (None, false) => Some(opennav::input::socket::default_path(
            &settings.input.control_socket,
        )),
        (None, true) => None,
    };
    let rt = if virtual_clock {
        tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .start_paused(true)
            .build()
    } else {
        tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .enable_all()
            .build()
    }
    .map_err(failed)?;
    let camera = match (args.camera_replay, args.no_camera) {
        (Some(d), _) => CameraChoice::Replay(d),
        (None, true) => CameraChoice::None,
        (None, false) => CameraChoice::RealSense,
    };
    let sim = args.sim;
    // on the chair: the one opennav driving it (held until the process
    // ends; the kernel lets go however it ends)
    let _lock = if sim {
        None
    } else {
        Some(opennav::daemon::lock::InstanceLock::acquire(&settings.lock_path()).map_err(failed)?)
    };
    let (report, summary, ros2) = rt.block_on(async move {
        let cancel = CancellationToken::new();
        let c = cancel.clone();
        let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
            .map_err(failed)?;
        tokio::spawn(async move {
            tokio::select! {
                _ = term.recv() => {}
                _ = tokio::signal::ctrl_c() => {}
            }
            tracing::warn!("signal: stopping the chair and shutting down");
            c.cancel();
        });
        let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
        // at the wall clock's pace the writer runs as on the chair
        let writer = if virtual_clock {
            opennav::sim::devices::SimWriter::Task
        } else {
            opennav::sim::devices::SimWriter::OwnThread
        };
        let (devices, world) = if sim {
            let world = opennav::sim::world::SimWorld::living_room(settings.drive_params());
            let (d, h) =
                opennav::sim::devices::devices_with(&settings, world, clock.clone(), writer)
                    .map_err(failed)?;
            (d, Some(h))
        } else {
            let d = opennav::daemon::chair::devices(
                &settings,
                camera,
                &PerceptionChoice::default(),
                clock.clone(),
            )
            .map_err(failed)?;
            (d, None)
        };
        // the devices are there: open the control socket (inside the
        // runtime: its listener registers with it)
        let socket = match &socket_path {
            Some(p) => Some(opennav::input::socket::ControlSocket::bind(p).map_err(failed)?),
            None => None,
        };
        let socket_stop = CancellationToken::new();
        if let Some(s) = socket {
            tracing::info!(path = %s.path().display(), "control socket open");
            tokio::spawn(s.serve(hub.clone(), status_rx.clone(), socket_stop.clone()));
        }
        let bridge = if ros2 {
            let b = start_ros2(&settings, hub.clone(), ros2_said_rx, status_rx.clone())?;
            opts.viewers = Some(b.sink.clone());
            Some(b)
        } else {
            None
        };
        // the person's switch: configured means required
        let switch_settings = &settings.input.switch;
        let switch_stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
        if switch_settings.configured() {
            let edges = opennav::input::switch::spawn_reader(switch_settings, switch_stop.clone())
                .map_err(failed)?;
            tracing::info!(device = %switch_settings.device, "switch open");
            tokio::spawn(opennav::input::switch::run(
                switch_settings.scan_settings(),
                edges,
                hub.clone(),
                status_rx,
                switch_sentences,
                clock.clone(),
                socket_stop.clone(),
            ));
        } else {
            drop(switch_sentences);
        }
        // the person's voice
        let voice_input = match (&voice_wav, settings.voice.enabled) {
            (Some(f), _) => Some(VoiceInput::File(f.clone())),
            (None, true) => Some(VoiceInput::Device(settings.voice.capture_device.clone())),
            (None, false) => None,
        };
        if let Some(input) = voice_input {
            start_voice(&settings, input, hub.clone(), voice_sentences.clone())?;
        }
        drop(hub);
        let report = opennav::daemon::run(devices, &settings, opts, input_rx, clock, cancel)
            .await
            .map_err(failed);
        socket_stop.cancel();
        // gone with the daemon (the process may end before the serving
        // task sees the cancel and drops the socket)
        if let Some(p) = &socket_path {
            match std::fs::remove_file(p) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => {
                    tracing::warn!(path = %p.display(), error = %e, "control socket not removed")
                }
            }
        }
        switch_stop.store(true, std::sync::atomic::Ordering::Relaxed);
        let report = report?;
        let label = report.goal.label().map(str::to_string);
        let summary = world.and_then(|w| w.summary(label.as_deref()));
        Ok::<_, Failure>((report, summary, bridge.map(|b| b.counts())))
    })?;
    // every sentence printed before the report (the daemon's senders are gone)
    if speech.join().is_err() {
        tracing::error!("the thread printing the chair's sentences died");
    }
    let line = serde_json::to_string(&Printed {
        report: &report,
        sim: summary,
        ros2,
    })
    .map_err(failed)?;
    println!("{line}");
    if let Outcome::Fault { task, reason } = &report.outcome {
        eprintln!("opennav: the {task} task failed ({reason}): the chair was stopped");
        // the process ends even while the stdin reader waits for a line
        std::process::exit(1);
    }
    std::process::exit(0);
}

/// Where the voice comes from.
enum VoiceInput {
    File(PathBuf),
    Device(String),
}

#[cfg(feature = "voice")]
fn start_voice(
    settings: &Settings,
    input: VoiceInput,
    hub: InputHub,
    say: mpsc::UnboundedSender<String>,
) -> Result<(), Failure> {
    use opennav::voice::listen::{spawn, AudioInput};
    let input = match input {
        VoiceInput::File(f) => AudioInput::File(f),
        VoiceInput::Device(d) => AudioInput::Device(d),
    };
    // the thread runs until the process ends
    spawn(&settings.voice, input, &settings.voice.vocabulary, hub, say)
        .map(drop)
        .map_err(|e| failed(anyhow::anyhow!("voice: {e}")))
}

#[cfg(not(feature = "voice"))]
fn start_voice(
    _: &Settings,
    input: VoiceInput,
    _: InputHub,
    _: mpsc::UnboundedSender<String>,
) -> Result<(), Failure> {
    let from = match input {
        VoiceInput::File(f) => f.display().to_string(),
        VoiceInput::Device(d) => format!("the microphone {d}"),
    };
    Err(failed(anyhow::anyhow!(
        "voice: cannot listen to {from}: this build has no speech recognition \
         (build with --features voice, or set voice.enabled = false)"
    )))
}

/// Words from a stream, one a line, until it ends. Bytes that are not
/// UTF-8 are replaced, never fatal. The end of the stream or a read error
/// is a stop (this is the only input), with a log line.
fn read_words(mut input: impl std::io::BufRead, tx: &InputHub) {
    let mut line = Vec::new();
    loop {
        line.clear();
        let input = match input.read_until(b'\n', &mut line) {
            Ok(0) => {
                tracing::warn!("stdin closed: no more words can come; stopping the chair");
                UserInput::Stop
            }
            Ok(_) => UserInput::parse(&String::from_utf8_lossy(&line)),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => {
                tracing::error!(error = %e, "stdin cannot be read: stopping the chair");
                UserInput::Stop
            }
        };
        let last = input == UserInput::Stop && line.is_empty();
        // the daemon gone: nobody left to tell
        if tx.blocking_send(input).is_err() || last {
            return;
        }
    }
}

/// The running bridge, as the daemon needs it.
#[cfg(feature = "ros2")]
type Bridge = opennav::ros2::Bridge;
#[cfg(not(feature = "ros2"))]
struct Bridge {
    sink: opennav::live::LiveSink,
}
#[cfg(not(feature = "ros2"))]
impl Bridge {
    fn counts(&self) -> opennav::ros2::BridgeCounts {
        Default::default()
    }
}

#[cfg(feature = "ros2")]
fn start_ros2(
    settings: &Settings,
    hub: opennav::input::InputHub,
    said: std::sync::mpsc::Receiver<String>,
    status: watch::Receiver<DaemonStatus>,
) -> Result<Bridge, Failure> {
    let env = std::env::var("ROS_DOMAIN_ID").ok();
    let domain = settings.ros2.domain(env.as_deref()).map_err(bad_input)?;
    let bridge = opennav::ros2::start(&settings.ros2, domain, hub, said, status)
        .map_err(|e| failed(anyhow::anyhow!(e)))?;
    let t = &settings.ros2.topics;
    eprintln!(
        "opennav: ROS 2 bridge in domain {domain}: out {}, {}, {}, {}, {}, {}, {}, {}, {}; in {}, {}",
        t.said, t.state, t.scan_left, t.scan_right, t.odom, t.tf, t.tf_static, t.objects, t.tracks,
        t.prompt, t.stop
    );
    Ok(bridge)
}

#[cfg(not(feature = "ros2"))]
fn start_ros2(
    _: &Settings,
    _: opennav::input::InputHub,
    _: std::sync::mpsc::Receiver<String>,
    _: watch::Receiver<DaemonStatus>,
) -> Result<Bridge, Failure> {
    Err(bad_input(anyhow::anyhow!(
        "ROS 2 (--ros2 or ros2.enabled): this build has no ROS 2 bridge: build with --features ros2"
    )))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The words and the number of stops read from `input`.
    fn read(input: impl std::io::BufRead) -> (Vec<UserInput>, u64) {
        let (hub, mut rx) = opennav::input::hub();
        read_words(input, &hub);
        drop(hub);
        let mut out = Vec::new();
        while let Ok(w) = rx.words.try_recv() {
            out.push(w);
        }
        let stops = *rx.stops.borrow_and_update();
        (out, stops)
    }

    #[test]
    fn bad_bytes_do_not_end_the_words_and_the_end_of_input_stops() {
        assert_eq!(
            read(&b"chair\n\xff\xfe desk\nSTOP!\n"[..]),
            (
                vec![
                    UserInput::Goto("chair".into()),
                    UserInput::Goto("desk".into()),
                ],
                // STOP! and the end of the input
                2
            )
        );
        assert_eq!(read(&b""[..]), (vec![], 1));
    }

    struct Broken;
    impl std::io::Read for Broken {
        fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
            Err(std::io::Error::other("device gone"))
        }
    }

    #[test]
    fn a_read_error_stops() {
        assert_eq!(read(std::io::BufReader::new(Broken)), (vec![], 1));
    }
}
