//! `opennav check`: the technician's checks of the chair's devices, decoded
//! readings as JSON lines; a device that does not answer exits 1.

use std::path::PathBuf;

use clap::{Subcommand, ValueEnum};

use opennav::config::Settings;

use super::parse_duration;
use super::{bad_input, failed, Failure};

#[derive(Subcommand, Debug)]
pub enum CheckCommand {
    /// Speech recognition on audio files (16 kHz mono WAV, or .raw s16le):
    /// one JSON line per file {"file", "heard", "confidence", "intent",
    /// "label"}, as the daemon hears (needs the `voice` feature).
    Voice {
        /// The audio files.
        #[arg(long, num_args = 1.., required = true)]
        wav: Vec<PathBuf>,
        /// The words that may be asked for, comma separated (default:
        /// config voice.vocabulary).
        #[arg(long)]
        vocabulary: Option<String>,
        /// Output: json (one line per file; the only format).
        #[arg(long, default_value = "json")]
        format: String,
    },
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
        /// Serial port (default: config encoders.port, the udev link
        /// /dev/opennav_encoders).
        #[arg(long)]
        port: Option<String>,
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
        /// Serial port (default: config lasers.left.port or
        /// lasers.right.port, by --laser).
        #[arg(long)]
        port: Option<String>,
        /// Which configured laser's port, without --port.
        #[arg(long, value_enum, default_value = "left", conflicts_with = "port")]
        laser: LaserArg,
        /// Scans to print before exiting.
        #[arg(long, default_value_t = 10)]
        count: u64,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum LaserArg {
    Left,
    Right,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum TakeoverArg {
    Jsmerror,
    Followjsm,
}

pub fn check_camera(
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
pub fn open_realsense(
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
pub fn open_realsense(
    _config: Option<&std::path::Path>,
) -> Result<Box<dyn opennav::sensors::camera::CameraSource>, Failure> {
    Err(failed(anyhow::anyhow!(
        "no camera: this build has no RealSense support (build with --features realsense; see docs/sensors.md); read a recording with --replay DIR"
    )))
}

pub fn check_encoders(port: &str, count: u64) -> Result<(), Failure> {
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

pub fn parse_joystick(s: &str) -> Result<(i8, i8), Failure> {
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

pub fn check_rnet(
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
    // driving: the one writer on the bus (held until the process ends)
    let _lock = match joystick {
        Some(_) => Some(
            opennav::daemon::lock::InstanceLock::acquire(&settings.lock_path()).map_err(failed)?,
        ),
        None => None,
    };
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

pub fn check_hokuyo(port: &str, count: u64) -> Result<(), Failure> {
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

pub fn run(config: Option<&std::path::Path>, cmd: CheckCommand) -> Result<(), Failure> {
    match cmd {
        CheckCommand::Hokuyo { port, laser, count } => {
            let port = match port {
                Some(p) => p,
                None => {
                    let s = Settings::load(config).map_err(super::bad_input)?;
                    match laser {
                        LaserArg::Left => s.lasers.left.port,
                        LaserArg::Right => s.lasers.right.port,
                    }
                }
            };
            check_hokuyo(&port, count)
        }
        CheckCommand::Rnet {
            iface,
            listen,
            drive,
            drive_for,
            mode,
        } => check_rnet(config, iface, listen, drive.as_deref(), drive_for, mode),
        CheckCommand::Encoders { port, count } => {
            let port = match port {
                Some(p) => p,
                None => {
                    Settings::load(config)
                        .map_err(super::bad_input)?
                        .encoders
                        .port
                }
            };
            check_encoders(&port, count)
        }
        CheckCommand::Camera { replay, count } => check_camera(config, replay.as_deref(), count),
        CheckCommand::Voice {
            wav,
            vocabulary,
            format,
        } => {
            if format != "json" {
                return Err(super::bad_input(anyhow::anyhow!(
                    "--format {format:?}: only json"
                )));
            }
            let settings = Settings::load(config).map_err(super::bad_input)?;
            check_voice(&settings, &wav, vocabulary.as_deref())
        }
    }
}

#[cfg(not(feature = "voice"))]
fn check_voice(_: &Settings, _: &[PathBuf], _: Option<&str>) -> Result<(), Failure> {
    Err(failed(anyhow::anyhow!(
        "this build has no speech recognition: build with --features voice \
         (Debian: libpocketsphinx-dev libsphinxbase-dev pocketsphinx-en-us)"
    )))
}

#[cfg(feature = "voice")]
fn check_voice(
    settings: &Settings,
    files: &[PathBuf],
    vocabulary: Option<&str>,
) -> Result<(), Failure> {
    use opennav::voice::{listen, wav};
    let v = &settings.voice;
    let words: Vec<String> = match vocabulary {
        Some(list) => list
            .split(',')
            .map(|w| w.trim().to_string())
            .filter(|w| !w.is_empty())
            .collect(),
        None => v.vocabulary.clone(),
    };
    let (mut r, g) =
        listen::recogniser(v, &words).map_err(|e| super::bad_input(anyhow::anyhow!(e)))?;
    if !g.skipped.is_empty() {
        eprintln!(
            "opennav: not in the pronunciation dictionary, left out: {}",
            g.skipped.join(", ")
        );
    }
    for f in files {
        let samples = wav::read_audio(f).map_err(|e| super::bad_input(anyhow::anyhow!(e)))?;
        let h = listen::hear(&mut r, &g, v, &samples).map_err(|e| failed(anyhow::anyhow!(e)))?;
        println!("{}", h.json(f, v.min_confidence));
    }
    Ok(())
}
