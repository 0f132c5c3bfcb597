//! The command line: one file per subcommand. Library errors become
//! one-line messages; bad input exits with code 2, other failures with 1.

pub mod check;
pub mod detect;
pub mod eval;
pub mod run;
pub mod sim;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand, ValueEnum};

use opennav::config::Settings;

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Evaluation: the paper's Replica metric.
    #[command(subcommand)]
    Eval(eval::EvalCommand),
    /// The simulator: synthetic data.
    #[command(subcommand)]
    Sim(sim::SimCommand),
    /// Technician checks of the chair's devices: decoded readings as JSON lines.
    #[command(subcommand)]
    Check(check::CheckCommand),
    /// The daemon: sensors → detection → goal → planner → supervisor →
    /// motors, on the chair's devices (or the simulator with --sim). Words
    /// on stdin (or --prompt): an object to go to, `stop`, `quit`.
    Run(run::RunArgs),
    /// Detect prompted objects in one RGB(-D) image: 2D boxes, and 3D objects with depth.
    Detect(detect::DetectArgs),
    /// A person checked the chair after a latched fault (CAN bus, motor
    /// link, overspeed): clears it so the daemon may drive again.
    AckFault,
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
    version,
    about = "Smart wheelchair: open-vocabulary 3D object detection and navigation"
)]
pub struct Cli {
    /// Configuration file (TOML) layered over the built-in defaults.
    #[arg(long, global = true)]
    pub config: Option<PathBuf>,
    #[command(subcommand)]
    pub command: Command,
}

pub fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
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
        Command::Sim(cmd) => sim::run(cmd),
        Command::Check(cmd) => check::run(config, cmd),
        Command::Run(args) => run::run(config, args),
        Command::Detect(args) => detect::run(Settings::load(config).map_err(bad_input)?, args),
        Command::AckFault => ack_fault(&Settings::load(config).map_err(bad_input)?),
    }
}

/// `opennav ack-fault`: what was latched, cleared; one JSON line.
fn ack_fault(settings: &Settings) -> Result<(), Failure> {
    let dir = settings.state_dir().ok_or_else(|| {
        failed(anyhow::anyhow!(
            "no state directory: set runtime.state_dir (or $STATE_DIRECTORY, $HOME)"
        ))
    })?;
    let cleared = opennav::daemon::latch::acknowledge(&dir).map_err(failed)?;
    let line = serde_json::json!({ "state_dir": dir, "acknowledged": cleared });
    println!("{line}");
    Ok(())
}
