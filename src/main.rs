//! `opennav`: the command line. Library errors become one-line messages;
//! bad input exits with code 2, other failures with 1.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand, ValueEnum};

use opennav::config::Settings;
use opennav::output::{overlay, slug, write_ply, DetectReport};
use opennav::perception::calibration::RgbdCalibration;
use opennav::perception::detector::parse_prompts;
use opennav::perception::image::{DepthImage, RgbImage};
use opennav::perception::pipeline::Pipeline;
use opennav::perception::setup::{
    open_configured_detector, open_configured_segmenter, PerceptionChoice,
};

#[derive(Parser, Debug)]
#[command(
    name = "opennav",
    version,
    about = "Smart wheelchair: open-vocabulary 3D object detection and navigation"
)]
struct Cli {
    /// Configuration file (TOML) layered over the built-in defaults.
    #[arg(long, global = true)]
    config: Option<PathBuf>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum Format {
    Json,
    Text,
}

#[derive(Subcommand, Debug)]
enum EvalCommand {
    /// Open3DIS's 3D instance AP on one case file (scenes + RLE predictions), JSON out.
    Instances {
        /// Case JSON: {"scenes":[{"id","sem","inst"}],"predictions":[{"scene","label_id","score","mask_rle"}]}.
        case: PathBuf,
        /// `detector`: the predictions' scores; `one`: 1.0 for all (Open3DIS's Replica runs).
        #[arg(long, value_enum, default_value = "detector")]
        score_mode: ScoreModeArg,
    },
    /// The paper's Replica protocol on a dataset in Replica's layout (see the README).
    Replica {
        /// Dataset root (cam_params.json, <scene>/traj.txt, <scene>/results/, ground_truth/).
        #[arg(long)]
        root: PathBuf,
        /// Scenes, comma-separated (default: every folder with a traj.txt).
        #[arg(long)]
        scenes: Option<String>,
        /// Views per scene, evenly spaced (default: all).
        #[arg(long)]
        views: Option<usize>,
        /// Detector model file (default: the configured one).
        #[arg(long)]
        detector: Option<PathBuf>,
        /// Use the simulator's ground-truth detector (synthetic scenes only).
        #[arg(long, conflicts_with = "detector")]
        sim_gt: bool,
        /// With --sim-gt: miss every other object.
        #[arg(long, requires = "sim_gt")]
        degraded: bool,
        /// Segmenter: depth, sam, auto, or a directory with the SAM encoder and decoder.
        #[arg(long)]
        segmenter: Option<String>,
        /// Models directory (overrides models.dir).
        #[arg(long)]
        models: Option<PathBuf>,
        /// Cross-view merge rule.
        #[arg(long, value_enum, default_value = "paper")]
        merge: MergeArg,
        /// `one`: every score 1.0 (Open3DIS's Replica runs); `detector`: the scores.
        #[arg(long, value_enum, default_value = "one")]
        score_mode: ScoreModeArg,
        /// Minimum detection score (overrides perception.score_threshold).
        #[arg(long)]
        score_threshold: Option<f32>,
        /// Where to write the JSON report.
        #[arg(long, default_value = "eval_replica.json")]
        out: PathBuf,
    },
}

#[derive(Debug, Clone, Copy, ValueEnum, PartialEq)]
enum MergeArg {
    /// The paper's: same label, 3D IoU > 0.8.
    Paper,
    /// Also when one box lies mostly (> 80 %) inside the other.
    Containment,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum TakeoverArg {
    Jsmerror,
    Followjsm,
}

/// "5s", "500ms", "2.5" (seconds).
fn parse_duration(s: &str) -> Result<std::time::Duration, String> {
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

#[derive(Subcommand, Debug)]
enum CheckCommand {
    /// Reads RGB-D frames (a RealSense, or a recording with --replay) and prints one JSON line per frame.
    Camera {
        /// A recording in the TUM RGB-D layout (rgb.txt, depth.txt, calibration.json).
        #[arg(long)]
        replay: Option<PathBuf>,
        /// Frames to print before exiting.
        #[arg(long, default_value_t = 10)]
        count: u64,
    },
    /// Reads the wheel-encoder board and prints each frame as a JSON line.
    Encoders {
        /// Serial port (e.g. /dev/ttyACM1 or the udev link /dev/opennav_encoders).
        #[arg(long)]
        port: String,
        /// Frames to print before exiting.
        #[arg(long, default_value_t = 100)]
        count: u64,
    },
    /// R-Net over SocketCAN: listens and reports what the chair says, or
    /// drives joystick values for a bounded time (wheels lifted!).
    Rnet {
        /// CAN interface (default: config actuation.rnet.iface).
        #[arg(long)]
        iface: Option<String>,
        /// How long to listen, e.g. 5s or 500ms.
        #[arg(long, default_value = "5s", value_parser = parse_duration)]
        listen: std::time::Duration,
        /// Joystick values to drive: TURN,FORWARD (each −100..100; turn positive = right).
        #[arg(long, allow_hyphen_values = true)]
        drive: Option<String>,
        /// How long to drive (at most 30 s), then centre and release.
        #[arg(long = "for", default_value = "2s", value_parser = parse_duration)]
        drive_for: std::time::Duration,
        /// Takeover mode (default: config actuation.rnet.mode).
        #[arg(long)]
        mode: Option<TakeoverArg>,
    },
    /// Reads a Hokuyo URG over SCIP 2.0 and prints each scan as a JSON line.
    Hokuyo {
        /// Serial port (e.g. /dev/ttyACM0 or the udev link /dev/hokuyo_left).
        #[arg(long)]
        port: String,
        /// Scans to print before exiting.
        #[arg(long, default_value_t = 10)]
        count: u64,
    },
}

#[derive(Subcommand, Debug)]
enum SimCommand {
    /// Writes a synthetic scene in Replica's layout (rendered RGB-D views, traj.txt, ground-truth cloud).
    ReplicaScene {
        /// Dataset root to write.
        #[arg(long)]
        out: PathBuf,
        /// Scene names (comma-separated); each is the same living room.
        #[arg(long, default_value = "office0")]
        scenes: String,
        /// Views along the orbit.
        #[arg(long, default_value_t = 60)]
        views: usize,
        /// Divide the 640×360 frame size by this.
        #[arg(long, default_value_t = 1)]
        scale_down: usize,
    },
}

#[derive(Debug, Clone, Copy, ValueEnum)]
enum ScoreModeArg {
    Detector,
    One,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Evaluation: the paper's Replica metric.
    #[command(subcommand)]
    Eval(EvalCommand),
    /// The simulator: synthetic data.
    #[command(subcommand)]
    Sim(SimCommand),
    /// Technician checks of the chair's devices: decoded readings as JSON lines.
    #[command(subcommand)]
    Check(CheckCommand),
    /// The daemon: sensors → detection → goal → planner → supervisor →
    /// motors. Words on stdin (or --prompt): an object to go to, `stop`,
    /// `quit`. Without the chair's devices it runs the simulator.
    Run {
        /// Run the simulator (the living room) even if devices are present.
        #[arg(long)]
        sim: bool,
        /// A word to go to at start (repeatable: said in order).
        #[arg(long)]
        prompt: Vec<String>,
        /// Exit when the goal is reached or lost (prints the report).
        #[arg(long)]
        exit_on_arrival: bool,
        /// Stop after this long, e.g. 90s.
        #[arg(long, value_parser = parse_duration)]
        max_duration: Option<std::time::Duration>,
        /// Do not read words from stdin.
        #[arg(long)]
        no_stdin: bool,
        /// On the chair's devices: camera frames from a recording (TUM
        /// RGB-D layout) instead of the RealSense.
        #[arg(long, conflicts_with = "no_camera")]
        camera_replay: Option<PathBuf>,
        /// On the chair's devices: no camera (stop and safety only).
        #[arg(long)]
        no_camera: bool,
        /// Record the sensors and perception's output to this MCAP file.
        #[arg(long)]
        record: Option<PathBuf>,
    },
    /// Detect prompted objects in one RGB(-D) image: 2D boxes, and 3D objects with depth.
    Detect {
        /// Colour image (PNG or JPEG).
        #[arg(long)]
        rgb: PathBuf,
        /// Depth image, 16-bit PNG (scale from the calibration).
        #[arg(long, requires = "calibration")]
        depth: Option<PathBuf>,
        /// Calibration JSON (opennav-calibration/1).
        #[arg(long, requires = "depth")]
        calibration: Option<PathBuf>,
        /// What to find, comma-separated: "chair, person".
        #[arg(long)]
        prompt: String,
        /// Detector model file (backend recognised from its inputs/outputs).
        #[arg(long)]
        detector: Option<PathBuf>,
        /// Segmenter: depth, sam, auto, or a directory with the SAM encoder and decoder.
        #[arg(long)]
        segmenter: Option<String>,
        /// Models directory (overrides models.dir).
        #[arg(long)]
        models: Option<PathBuf>,
        /// Minimum detection score (overrides perception.score_threshold).
        #[arg(long)]
        score_threshold: Option<f32>,
        /// Write an overlay PNG and a PLY per object here.
        #[arg(long)]
        out: Option<PathBuf>,
        #[arg(long, value_enum, default_value = "json")]
        format: Format,
    },
}

/// An error with its exit code.
struct Failure {
    code: u8,
    error: anyhow::Error,
}

fn bad_input(e: impl Into<anyhow::Error>) -> Failure {
    Failure {
        code: 2,
        error: e.into(),
    }
}

fn failed(e: impl Into<anyhow::Error>) -> Failure {
    Failure {
        code: 1,
        error: e.into(),
    }
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn")),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            let chain: Vec<String> = f.error.chain().map(|e| e.to_string()).collect();
            eprintln!("opennav: {}", chain.join(": "));
            ExitCode::from(f.code)
        }
    }
}

fn eval_instances(case: &std::path::Path, mode: ScoreModeArg) -> Result<(), Failure> {
    use opennav::eval::instances::{evaluate, EvalCase, ScoreMode};
    let text = std::fs::read_to_string(case)
        .with_context(|| case.display().to_string())
        .map_err(bad_input)?;
    let case_data: EvalCase = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a valid case", case.display()))
        .map_err(bad_input)?;
    let mode = match mode {
        ScoreModeArg::Detector => ScoreMode::Detector,
        ScoreModeArg::One => ScoreMode::One,
    };
    let r = evaluate(&case_data, mode)
        .with_context(|| case.display().to_string())
        .map_err(bad_input)?;
    let classes: serde_json::Map<String, serde_json::Value> = r
        .classes
        .iter()
        .map(|(n, c)| Ok((n.clone(), serde_json::to_value(c)?)))
        .collect::<Result<_, serde_json::Error>>()
        .map_err(failed)?;
    let out = serde_json::json!({
        "mAP": r.map, "mAP50": r.map50, "mAP25": r.map25,
        "score_mode": r.score_mode,
        "classes": classes,
    });
    println!("{}", serde_json::to_string_pretty(&out).map_err(failed)?);
    Ok(())
}

struct EvalReplicaArgs {
    root: PathBuf,
    scenes: Option<String>,
    views: Option<usize>,
    choice: PerceptionChoice,
    sim_gt: bool,
    degraded: bool,
    merge: MergeArg,
    score_mode: ScoreModeArg,
    out: PathBuf,
}

fn eval_replica(settings: &Settings, a: EvalReplicaArgs) -> Result<(), Failure> {
    use opennav::eval::instances::{ScoreMode, REPLICA_CLASSES};
    use opennav::eval::replica::{
        list_scenes, read_cam_params, run, ModelViewDetector, RunSettings, ViewDetector,
    };
    use opennav::perception::boxes::MergeRule;
    use std::io::IsTerminal;

    let root_arg = || format!("--root {}", a.root.display());
    let scenes = match &a.scenes {
        Some(s) => parse_prompts(s),
        None => list_scenes(&a.root)
            .context(root_arg())
            .map_err(bad_input)?,
    };
    if scenes.is_empty() {
        return Err(bad_input(anyhow::anyhow!(
            "{}: no scenes (folders with a traj.txt)",
            root_arg()
        )));
    }
    let mut detector: Box<dyn ViewDetector> = if a.sim_gt {
        let cam = read_cam_params(&a.root)
            .context(root_arg())
            .map_err(bad_input)?;
        let mut d =
            opennav::sim::replica::SimGtDetector::new(opennav::sim::room::Room::living_room(), cam);
        if a.degraded {
            d.degrade = Some(opennav::sim::replica::Degrade {
                miss_every_other: true,
                box_fraction: 1.0,
            });
        }
        Box::new(d)
    } else {
        let mut det = open_configured_detector(settings, &a.choice).map_err(bad_input)?;
        let prompts: Vec<String> = REPLICA_CLASSES
            .iter()
            .map(|c| c.replace('-', " "))
            .collect();
        let report = det.set_prompts(&prompts).map_err(bad_input)?;
        if !report.unmatched.is_empty() {
            eprintln!(
                "the detector has no class for: {}",
                report.unmatched.join(", ")
            );
        }
        Box::new(ModelViewDetector(det))
    };
    let mut segmenter = open_configured_segmenter(settings, &a.choice).map_err(bad_input)?;
    let run_settings = RunSettings {
        views: a.views,
        merge: match a.merge {
            MergeArg::Paper => MergeRule::paper(settings.perception.merge_iou),
            MergeArg::Containment => MergeRule {
                iou: settings.perception.merge_iou,
                containment: Some(0.8),
            },
        },
        geometry: settings.geometry_settings(),
        mask_voxel_m: 0.03,
        score_mode: match a.score_mode {
            ScoreModeArg::Detector => ScoreMode::Detector,
            ScoreModeArg::One => ScoreMode::One,
        },
    };
    let tty = std::io::stderr().is_terminal();
    let mut progress = |scene: &str, i: usize, n: usize| {
        if tty {
            eprint!("\r{scene}: {i}/{n} views");
            if i == n {
                eprintln!();
            }
        } else if i == n || i.is_multiple_of((n / 10).max(1)) {
            eprintln!("{scene}: {i}/{n} views");
        }
    };
    let report = run(
        &a.root,
        &scenes,
        detector.as_mut(),
        segmenter.as_mut(),
        &run_settings,
        &mut progress,
    )
    .map_err(|e| match e {
        opennav::eval::replica::ReplicaError::File { .. }
        | opennav::eval::replica::ReplicaError::Image(_) => bad_input(e),
        other => failed(other),
    })?;
    let json = report.to_json(&run_settings);
    let text = serde_json::to_string_pretty(&json).map_err(failed)?;
    std::fs::write(&a.out, text)
        .with_context(|| format!("--out {}", a.out.display()))
        .map_err(bad_input)?;
    print!("{}", report.table());
    for s in &report.scenes {
        println!(
            "{}: {} views, {:.3} s per view (median {:.3}), {:.2} s per scene, {} fused objects",
            s.scene,
            s.views,
            s.secs_per_view_mean,
            s.secs_per_view_median,
            s.secs_per_scene,
            s.fused_objects
        );
    }
    println!(
        "detector: {}; masks: {}; report: {}",
        report.detector,
        opennav::eval::replica::MASK_RULE,
        a.out.display()
    );
    Ok(())
}

fn check_camera(
    config: Option<&std::path::Path>,
    replay: Option<&std::path::Path>,
    count: u64,
) -> Result<(), Failure> {
    use opennav::sensors::camera::{CameraSource, ReplaySource};
    use std::io::Write;
    let mut src: Box<dyn CameraSource> = match replay {
        Some(dir) => Box::new(ReplaySource::open(dir).map_err(bad_input)?),
        None => open_realsense(config)?,
    };
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let mut frames = 0u64;
    for _ in 0..count {
        let Some(f) = src.next_frame().map_err(failed)? else {
            break;
        };
        frames += 1;
        let d = f.value.depth.data();
        let valid: Vec<f32> = d.iter().copied().filter(|z| *z > 0.0).collect();
        let line = serde_json::json!({
            "stamp_s": f.stamp.as_secs_f64(),
            "color_stamp_s": f.value.color_stamp.as_secs_f64(),
            "depth_stamp_s": f.value.depth_stamp.as_secs_f64(),
            "width": f.value.color.width(),
            "height": f.value.color.height(),
            "depth_width": f.value.depth.width(),
            "depth_height": f.value.depth.height(),
            "valid_depth_fraction": valid.len() as f64 / d.len().max(1) as f64,
            "depth_min_m": valid.iter().copied().fold(f32::INFINITY, f32::min),
            "depth_max_m": valid.iter().copied().fold(0.0f32, f32::max),
        });
        writeln!(out, "{line}").map_err(failed)?;
    }
    match replay {
        Some(dir) => {
            let r = ReplaySource::open(dir).map_err(bad_input)?;
            eprintln!(
                "{}: {} paired frames, {} colour and {} depth frames without a partner",
                dir.display(),
                r.len(),
                r.unpaired_color,
                r.unpaired_depth
            );
        }
        None => eprintln!("RealSense: {frames} frames"),
    }
    Ok(())
}

#[cfg(feature = "realsense")]
fn open_realsense(
    config: Option<&std::path::Path>,
) -> Result<Box<dyn opennav::sensors::camera::CameraSource>, Failure> {
    use opennav::sensors::camera::realsense::{RealSenseSettings, RealSenseSource};
    let settings = Settings::load(config).map_err(bad_input)?;
    let base_from_camera = settings
        .camera
        .base_from_camera
        .to_isometry("camera.base_from_camera")
        .map_err(bad_input)?;
    let clock = std::sync::Arc::new(opennav::msg::MonotonicClock::new());
    Ok(Box::new(
        RealSenseSource::open(RealSenseSettings::default(), base_from_camera, clock)
            .map_err(failed)?,
    ))
}

#[cfg(not(feature = "realsense"))]
fn open_realsense(
    _config: Option<&std::path::Path>,
) -> Result<Box<dyn opennav::sensors::camera::CameraSource>, Failure> {
    Err(failed(anyhow::anyhow!(
        "no camera: this build has no RealSense support (build with --features realsense; see the README); read a recording with --replay DIR"
    )))
}

fn check_encoders(port: &str, count: u64) -> Result<(), Failure> {
    use opennav::sensors::encoders::EncoderDriver;
    use std::io::Write;
    let clock = std::sync::Arc::new(opennav::msg::MonotonicClock::new());
    let mut driver =
        EncoderDriver::new(port, clock).with_timeout(std::time::Duration::from_secs(1));
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    for _ in 0..count {
        let t = driver.next_ticks().map_err(failed)?;
        let line = serde_json::json!({
            "stamp_s": t.stamp.as_secs_f64(),
            "seq": t.value.seq,
            "mcu_time_us": t.value.mcu_time_us,
            "left": t.value.left,
            "right": t.value.right,
            "left_illegal": t.value.left_illegal,
            "right_illegal": t.value.right_illegal,
            "gap": t.value.gap,
        });
        writeln!(out, "{line}").map_err(failed)?;
    }
    let s = &driver.decoder.stats;
    eprintln!(
        "{port}: {} frames, {} CRC errors, {} framing errors, {} frames lost, firmware {:?}",
        s.frames,
        s.crc_errors,
        s.framing_errors,
        s.frames_lost,
        driver.decoder.hello.map(|h| h.firmware)
    );
    Ok(())
}

fn run_daemon(
    config: Option<&std::path::Path>,
    sim: bool,
    camera: opennav::daemon::CameraChoice,
    opts: opennav::daemon::RunOptions,
) -> Result<(), Failure> {
    let settings = Settings::load(config).map_err(bad_input)?;
    let mut hardware = false;
    if !sim {
        let devices = [
            settings.lasers.left.port.clone(),
            settings.lasers.right.port.clone(),
            settings.encoders.port.clone(),
            match settings.actuation.backend {
                opennav::config::ActuationBackend::Rnet => {
                    format!("/sys/class/net/{}", settings.actuation.rnet.iface)
                }
                opennav::config::ActuationBackend::Rebus => settings.actuation.rebus.port.clone(),
            },
        ];
        hardware = devices
            .iter()
            .any(|d| std::path::Path::new(d.as_str()).exists());
        if !hardware {
            eprintln!(
                "opennav: no chair devices found ({}): running the simulator",
                devices.join(", ")
            );
        }
    }
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(failed)?;
    let report = rt.block_on(async move {
        let cancel = tokio_util::sync::CancellationToken::new();
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
        if hardware {
            opennav::daemon::run_hardware(
                &settings,
                opts,
                camera,
                PerceptionChoice::default(),
                cancel,
            )
            .await
            .map_err(failed)
        } else {
            opennav::daemon::run_sim(&settings, opts, cancel)
                .await
                .map_err(failed)
        }
    })?;
    println!("{}", serde_json::to_string(&report).map_err(failed)?);
    // the process exits even while the stdin reader waits for a line
    std::process::exit(0);
}

/// "X,Y" joystick values, each −100..100.
fn parse_joystick(s: &str) -> Result<(i8, i8), Failure> {
    let bad = || {
        bad_input(anyhow::anyhow!(
            "--drive {s:?}: expected TURN,FORWARD, each -100..100"
        ))
    };
    let (x, y) = s.split_once(',').ok_or_else(bad)?;
    let p = |v: &str| -> Result<i8, Failure> {
        let n: i32 = v.trim().parse().map_err(|_| bad())?;
        if (-100..=100).contains(&n) {
            Ok(n as i8)
        } else {
            Err(bad())
        }
    };
    Ok((p(x)?, p(y)?))
}

fn check_rnet(
    config: Option<&std::path::Path>,
    iface: Option<String>,
    listen: std::time::Duration,
    drive: Option<&str>,
    drive_for: std::time::Duration,
    mode: Option<TakeoverArg>,
) -> Result<(), Failure> {
    use opennav::actuation::can::SocketCanBus;
    use opennav::actuation::check;
    use opennav::actuation::rnet::TakeoverMode;
    let settings = Settings::load(config).map_err(bad_input)?;
    let iface = iface.unwrap_or_else(|| settings.actuation.rnet.iface.clone());
    let joystick = drive.map(parse_joystick).transpose()?;
    if joystick.is_some() && drive_for > std::time::Duration::from_secs(30) {
        return Err(bad_input(anyhow::anyhow!(
            "--for {drive_for:?}: at most 30 s of driving from the command line"
        )));
    }
    let mut rnet = settings.rnet_settings();
    if let Some(m) = mode {
        rnet.mode = match m {
            TakeoverArg::Jsmerror => TakeoverMode::JsmError,
            TakeoverArg::Followjsm => TakeoverMode::FollowJsm,
        };
    }
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(failed)?;
    rt.block_on(async move {
        let report = match joystick {
            None => {
                let bus = SocketCanBus::open(&iface).map_err(failed)?;
                serde_json::to_value(check::listen(&bus, listen).await.map_err(failed)?)
            }
            Some(xy) => {
                let stop = tokio_util::sync::CancellationToken::new();
                let s = stop.clone();
                let mut term =
                    tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
                        .map_err(failed)?;
                tokio::spawn(async move {
                    tokio::select! {
                        _ = term.recv() => {}
                        _ = tokio::signal::ctrl_c() => {}
                    }
                    tracing::warn!("signal: centring and releasing");
                    s.cancel();
                });
                serde_json::to_value(
                    check::drive(
                        move || SocketCanBus::open(&iface),
                        rnet,
                        xy,
                        drive_for,
                        stop,
                    )
                    .await
                    .map_err(failed)?,
                )
            }
        }
        .map_err(failed)?;
        println!("{report}");
        Ok(())
    })
}

fn check_hokuyo(port: &str, count: u64) -> Result<(), Failure> {
    use opennav::sensors::hokuyo::{HokuyoDriver, HokuyoSettings, ScanJson};
    use std::io::Write;
    let clock = std::sync::Arc::new(opennav::msg::MonotonicClock::new());
    let mut driver = HokuyoDriver::new(HokuyoSettings::new(port), clock);
    let params = driver.connect().map_err(failed)?;
    tracing::info!(?params, "connected");
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    for _ in 0..count {
        let scan = driver.next_scan().map_err(failed)?;
        let line = serde_json::to_string(&ScanJson {
            stamp_s: scan.stamp.as_secs_f64(),
            angle_min_rad: scan.value.angle_min_rad,
            angle_increment_rad: scan.value.angle_increment_rad,
            ranges_m: &scan.value.ranges_m,
        })
        .map_err(failed)?;
        writeln!(out, "{line}").map_err(failed)?;
    }
    let s = &driver.stats;
    eprintln!(
        "{port}: {} scans, {} checksum errors, {} malformed, {} error statuses, {} silences",
        s.scans, s.checksum_errors, s.malformed_replies, s.error_statuses, s.silences
    );
    Ok(())
}

fn run(cli: Cli) -> Result<(), Failure> {
    let mut settings = Settings::load(cli.config.as_deref()).map_err(bad_input)?;
    match cli.command {
        Command::Eval(EvalCommand::Instances { case, score_mode }) => {
            eval_instances(&case, score_mode)
        }
        Command::Eval(EvalCommand::Replica {
            root,
            scenes,
            views,
            detector,
            sim_gt,
            degraded,
            segmenter,
            models,
            merge,
            score_mode,
            score_threshold,
            out,
        }) => {
            if let Some(t) = score_threshold {
                settings.perception.score_threshold = t;
                settings
                    .validate()
                    .map_err(|e| bad_input(anyhow::anyhow!("--score-threshold: {e}")))?;
            }
            eval_replica(
                &settings,
                EvalReplicaArgs {
                    root,
                    scenes,
                    views,
                    choice: PerceptionChoice {
                        detector,
                        segmenter,
                        models_dir: models,
                    },
                    sim_gt,
                    degraded,
                    merge,
                    score_mode,
                    out,
                },
            )
        }
        Command::Run {
            sim,
            prompt,
            exit_on_arrival,
            max_duration,
            no_stdin,
            camera_replay,
            no_camera,
            record,
        } => run_daemon(
            cli.config.as_deref(),
            sim,
            match (camera_replay, no_camera) {
                (Some(d), _) => opennav::daemon::CameraChoice::Replay(d),
                (None, true) => opennav::daemon::CameraChoice::None,
                (None, false) => opennav::daemon::CameraChoice::RealSense,
            },
            opennav::daemon::RunOptions {
                prompts: prompt,
                stdin_prompts: !no_stdin,
                exit_on_arrival,
                max_duration,
                record,
            },
        ),
        Command::Check(CheckCommand::Hokuyo { port, count }) => check_hokuyo(&port, count),
        Command::Check(CheckCommand::Rnet {
            iface,
            listen,
            drive,
            drive_for,
            mode,
        }) => check_rnet(
            cli.config.as_deref(),
            iface,
            listen,
            drive.as_deref(),
            drive_for,
            mode,
        ),
        Command::Check(CheckCommand::Encoders { port, count }) => check_encoders(&port, count),
        Command::Check(CheckCommand::Camera { replay, count }) => {
            check_camera(cli.config.as_deref(), replay.as_deref(), count)
        }
        Command::Sim(SimCommand::ReplicaScene {
            out,
            scenes,
            views,
            scale_down,
        }) => {
            if views == 0 {
                return Err(bad_input(anyhow::anyhow!("--views: at least 1")));
            }
            let cam = opennav::sim::replica::camera(scale_down);
            let room = opennav::sim::room::Room::living_room();
            for name in parse_prompts(&scenes) {
                opennav::sim::replica::write_scene(&out, &name, &room, &cam, views)
                    .map_err(failed)?;
                eprintln!(
                    "wrote {} ({views} views, {}x{})",
                    out.join(&name).display(),
                    cam.w,
                    cam.h
                );
            }
            Ok(())
        }
        Command::Detect {
            rgb,
            depth,
            calibration,
            prompt,
            detector,
            segmenter,
            models,
            score_threshold,
            out,
            format,
        } => {
            if let Some(t) = score_threshold {
                settings.perception.score_threshold = t;
                settings
                    .validate()
                    .map_err(|e| bad_input(anyhow::anyhow!("--score-threshold: {e}")))?;
            }
            let prompts = parse_prompts(&prompt);
            if prompts.is_empty() {
                return Err(bad_input(anyhow::anyhow!(
                    "--prompt: empty; name at least one object, e.g. --prompt \"chair\""
                )));
            }
            let color = RgbImage::load(&rgb).map_err(bad_input)?;
            let rgbd = match (&depth, &calibration) {
                (Some(d), Some(c)) => {
                    let cal = RgbdCalibration::load(c).map_err(bad_input)?;
                    let depth =
                        DepthImage::load_png(d, cal.depth_scale_m as f32).map_err(bad_input)?;
                    Some((cal, depth))
                }
                _ => None,
            };
            let choice = PerceptionChoice {
                detector,
                segmenter,
                models_dir: models,
            };
            let det = open_configured_detector(&settings, &choice).map_err(bad_input)?;
            let seg = if rgbd.is_some() {
                open_configured_segmenter(&settings, &choice).map_err(bad_input)?
            } else {
                Box::new(opennav::perception::segmenter::DepthBoxSegmenter::default())
            };
            let calib = match &rgbd {
                Some((c, _)) => c.clone(),
                None => RgbdCalibration::registered(
                    opennav::perception::calibration::Intrinsics {
                        width: color.width(),
                        height: color.height(),
                        fx: color.width() as f64,
                        fy: color.width() as f64,
                        cx: color.width() as f64 / 2.0,
                        cy: color.height() as f64 / 2.0,
                    },
                    nalgebra::Isometry3::identity(),
                ),
            };
            let mut pipeline = Pipeline::new(det, seg, calib, settings.geometry_settings());
            let report = pipeline.set_prompts(&prompts).map_err(bad_input)?;
            for p in &report.unmatched {
                tracing::warn!(prompt = %p, "the detector has no class for this prompt");
            }
            let view = pipeline
                .process(&color, rgbd.as_ref().map(|(_, d)| d))
                .map_err(|e| match e {
                    opennav::perception::pipeline::PipelineError::Input(_) => bad_input(e),
                    other => failed(other),
                })?;
            if let Some(dir) = out {
                std::fs::create_dir_all(&dir)
                    .with_context(|| format!("--out {}", dir.display()))
                    .map_err(bad_input)?;
                let img = overlay(&color, &view.detections, &view.masks);
                img.save_png(&dir.join("overlay.png")).map_err(failed)?;
                for (i, o) in view.objects.iter().enumerate() {
                    let p = dir.join(format!("object_{i:02}_{}.ply", slug(&o.label)));
                    write_ply(&p, o)
                        .with_context(|| p.display().to_string())
                        .map_err(failed)?;
                }
            }
            let report = DetectReport::from(&view);
            match format {
                Format::Json => {
                    let s = serde_json::to_string_pretty(&report).map_err(failed)?;
                    println!("{s}");
                }
                Format::Text => {
                    for p in &report.prompts.unmatched {
                        println!("prompt \"{p}\": the detector has no class for it");
                    }
                    for d in &report.detections {
                        println!(
                            "2D {:<12} {:.2}  [{:.0}, {:.0}, {:.0}, {:.0}]",
                            d.label,
                            d.score,
                            d.box_xyxy[0],
                            d.box_xyxy[1],
                            d.box_xyxy[2],
                            d.box_xyxy[3]
                        );
                    }
                    for o in &report.objects {
                        println!(
                            "3D {:<12} {:.2}  centre ({:.2}, {:.2}, {:.2}) m  size ({:.2}, {:.2}, {:.2}) m  {} points  [{}]",
                            o.label,
                            o.score,
                            o.center_m[0],
                            o.center_m[1],
                            o.center_m[2],
                            o.size_m[0],
                            o.size_m[1],
                            o.size_m[2],
                            o.points,
                            o.frame
                        );
                    }
                    for d in &report.dropped {
                        println!("dropped {} {:.2}: {}", d.label, d.score, d.reason);
                    }
                    let t = report.timing_ms;
                    println!(
                        "timing: detector {:.1} ms, segmenter {:.1} ms, geometry {:.1} ms, total {:.1} ms",
                        t.detector, t.segmenter, t.geometry, t.total
                    );
                }
            }
            Ok(())
        }
    }
}
