//! The command line: one file per subcommand. Library errors become
//! one-line messages; bad input exits with code 2, other failures with 1.

pub mod check;
pub mod client;
pub mod detect;
pub mod eval;
pub mod replay;
pub mod run;
pub mod sim;
pub mod voice;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};

use opennav::config::Settings;

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Evaluation: the paper's Replica metric.
    #[command(subcommand)]
    Eval(eval::EvalCommand),
    /// The simulator: the closed loop over seeded apartments (`--scenes N
    /// --seed S`), or synthetic data (`replica-scene`).
    Sim(sim::SimArgs),
    /// Technician checks of the chair's devices: decoded readings as JSON lines.
    #[command(subcommand)]
    Check(check::CheckCommand),
    /// The daemon: sensors → detection → goal → planner → supervisor →
    /// motors, on the chair's devices (or the simulator with --sim). Words
    /// on stdin (or --prompt): an object to go to, `stop`, `quit`.
    Run(run::RunArgs),
    /// The person's own voice: the sentences to read, and the speaker
    /// adaptation made from their recordings.
    #[command(subcommand)]
    Voice(voice::VoiceCommand),
    /// Detect prompted objects in one RGB(-D) image: 2D boxes, and 3D objects with depth.
    Detect(detect::DetectArgs),
    /// Play a recording back through perception and the tracker: one JSON
    /// line per view (its objects, the same as recorded?), then the tracks;
    /// `--live` streams it to Foxglove at the recording's pace.
    Replay(replay::ReplayArgs),
    /// A person checked the chair after a latched fault (CAN bus, motor
    /// link, overspeed, another writer): clears it — in the running daemon
    /// (its control socket) and on disk — so the chair may drive again.
    AckFault(client::SocketArg),
    /// Tell the running daemon to go to an object (its control socket).
    Go {
        /// The word, e.g. "chair".
        word: String,
        #[command(flatten)]
        socket: client::SocketArg,
    },
    /// Stop the chair (latched until `opennav resume`).
    Stop(client::SocketArg),
    /// Go on after a stop.
    Resume(client::SocketArg),
    /// Answer the chair's question with yes.
    Yes(client::SocketArg),
    /// Answer the chair's question with no.
    No(client::SocketArg),
    /// What the running daemon is doing: state, goal, pose, stop reason,
    /// devices not heard yet, last sentences (one JSON line).
    Status(client::SocketArg),
}

/// An error with its exit code.
pub struct Failure {
    pub code: u8,
    pub error: anyhow::Error,
}

pub fn bad_input(e: impl Into<anyhow::Error>) -> Failure {
    Failure {
        code: 2,
        error: e.into(),
    }
}

pub fn failed(e: impl Into<anyhow::Error>) -> Failure {
    Failure {
        code: 1,
        error: e.into(),
    }
}

/// "5s", "500ms", "2.5" (seconds).
pub fn parse_duration(s: &str) -> Result<std::time::Duration, String> {
    let t = s.trim();
    let (num, scale) = if let Some(n) = t.strip_suffix("ms") {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix('s') {
        (n, 1.0)
    } else {
        (t, 1.0)
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("{s:?} is not a duration (e.g. 5s, 500ms)"))?;
    let secs = v * scale;
    if !secs.is_finite() || !(0.0..=86_400.0).contains(&secs) {
        return Err(format!("{s:?}: out of range (0 to 1 day)"));
    }
    Ok(std::time::Duration::from_secs_f64(secs))
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum Format {
    Json,
    Text,
}

#[derive(Parser, Debug)]
#[command(
    name = "opennav",
    version = concat!(env!("CARGO_PKG_VERSION"), " (git ", env!("OPENNAV_GIT_REV"), ")"),
    about = "Smart wheelchair: open-vocabulary 3D object detection and navigation"
)]
pub struct Cli {
    /// Configuration file (TOML) layered over the built-in defaults.
    #[arg(long, global = true)]
    pub config: Option<PathBuf>,
    #[command(subcommand)]
    pub command: Command,
}

/// The log goes to journald natively (under systemd): the sentences are
/// log events there, not lines on stderr as well.
pub static TO_JOURNAL: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Whether stderr is the journal stream systemd connected
/// (`JOURNAL_STREAM` = its device and inode).
fn stderr_is_journal() -> bool {
    let Some((dev, ino)) = std::env::var("JOURNAL_STREAM").ok().and_then(|v| {
        v.split_once(':')
            .map(|(d, i)| (d.to_string(), i.to_string()))
    }) else {
        return false;
    };
    // SAFETY: fstat on fd 2 writes only into the zeroed struct given
    let mut st: libc::stat = unsafe { std::mem::zeroed() };
    if unsafe { libc::fstat(2, &mut st) } != 0 {
        return false;
    }
    dev.parse::<u64>().ok() == Some(st.st_dev) && ino.parse::<u64>().ok() == Some(st.st_ino)
}

/// Logs: to journald with each event's fields (task, reason, device…) as
/// journal fields when stderr is the journal; else to stderr, coloured
/// only for a person at a terminal (files would keep the escape codes).
fn init_logs() {
    use tracing_subscriber::layer::SubscriberExt;
    use tracing_subscriber::util::SubscriberInitExt;
    // a live-view client too slow for its queue loses messages: the
    // foxglove crate says so at info ("outbox for client … full"); kept
    const LIVE_DROPS: &str = "foxglove::websocket::connected_client=info";
    let filter = |default: &str| {
        tracing_subscriber::EnvFilter::try_from_default_env()
            .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default))
    };
    let journal = if stderr_is_journal() {
        Some(tracing_journald::layer())
    } else {
        None
    };
    let fallback = match journal {
        Some(Ok(j)) => {
            // the sentences are info events: kept by default
            tracing_subscriber::registry()
                .with(filter(&format!("info,rustdds=error,{LIVE_DROPS}")))
                .with(j.with_syslog_identifier("opennav".into()))
                .init();
            TO_JOURNAL.store(true, std::sync::atomic::Ordering::SeqCst);
            return;
        }
        Some(Err(e)) => Some(e),
        None => None,
    };
    tracing_subscriber::fmt()
        // RustDDS (the ROS 2 bridge) warns of every unreachable address
        .with_env_filter(filter(&format!("warn,rustdds=error,{LIVE_DROPS}")))
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    if let Some(e) = fallback {
        tracing::warn!(error = %e, "stderr is the journal but journald cannot be reached: logging as text");
    }
}

pub fn main() -> ExitCode {
    init_logs();
    // each view's arrays from pages already mapped (see the function)
    if !opennav::memory::keep_freed_heap() {
        tracing::debug!("the allocator keeps its own policy for freed memory");
    }
    let cli = Cli::parse();
    match dispatch(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            let chain: Vec<String> = f.error.chain().map(|e| e.to_string()).collect();
            eprintln!("opennav: {}", chain.join(": "));
            ExitCode::from(f.code)
        }
    }
}

fn dispatch(cli: Cli) -> Result<(), Failure> {
    let config = cli.config.as_deref();
    match cli.command {
        Command::Eval(cmd) => eval::run(Settings::load(config).map_err(bad_input)?, cmd),
        Command::Sim(args) => sim::run(config, args),
        Command::Check(cmd) => check::run(config, cmd),
        Command::Run(args) => run::run(config, args),
        Command::Voice(cmd) => voice::run(config, cmd),
        Command::Detect(args) => detect::run(Settings::load(config).map_err(bad_input)?, args),
        Command::Replay(args) => replay::run(config, args),
        Command::AckFault(socket) => {
            ack_fault(&Settings::load(config).map_err(bad_input)?, &socket)
        }
        Command::Go { word, socket } => {
            let s = Settings::load(config).map_err(bad_input)?;
            client::send(&s, &socket, serde_json::json!({ "go": word }))
        }
        Command::Stop(socket) => request(config, &socket, "stop"),
        Command::Resume(socket) => request(config, &socket, "resume"),
        Command::Yes(socket) => request(config, &socket, "yes"),
        Command::No(socket) => request(config, &socket, "no"),
        Command::Status(socket) => request(config, &socket, "status"),
    }
}

/// `{"<key>": true}` to the daemon.
fn request(
    config: Option<&std::path::Path>,
    socket: &client::SocketArg,
    key: &str,
) -> Result<(), Failure> {
    let s = Settings::load(config).map_err(bad_input)?;
    client::send(&s, socket, serde_json::json!({ key: true }))
}

/// `opennav ack-fault`: the running daemon told (when one listens), the
/// record on disk cleared; one JSON line.
fn ack_fault(settings: &Settings, socket: &client::SocketArg) -> Result<(), Failure> {
    let dir = settings.state_dir().ok_or_else(|| {
        failed(anyhow::anyhow!(
            "no state directory: set runtime.state_dir (or $STATE_DIRECTORY, $HOME)"
        ))
    })?;
    let path = socket.path(settings);
    let daemon = match opennav::input::socket::request(
        &path,
        &serde_json::json!({"ack_fault": true}),
        std::time::Duration::from_secs(2),
    ) {
        Ok(reply) => reply,
        // no daemon running: the record on disk is all there is
        Err(e) => serde_json::json!({ "not_running": e.to_string() }),
    };
    let cleared = opennav::daemon::latch::acknowledge(&dir).map_err(failed)?;
    let line = serde_json::json!({ "state_dir": dir, "acknowledged": cleared, "daemon": daemon });
    println!("{line}");
    Ok(())
}
