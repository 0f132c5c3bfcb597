//! The chair's [`Devices`] from config: the two Hokuyos and the encoder
//! board on reader threads (reconnecting with back-off), the camera (the
//! RealSense, a recording, or none) with the configured detector and
//! segmenter, and the configured motor interface (R-Net on SocketCAN, or
//! the Rebus chipset) on its own real-time thread.

use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Isometry3;
use tokio_util::sync::CancellationToken;

use super::devices::{ActuatorStart, CameraDevice, DeviceError, Devices, OpenCamera, WatchSource};
use crate::actuation::spawn_actuator_thread;
use crate::actuation::writer::RnetActuator;
use crate::config::{ActuationBackend, Settings};
use crate::msg::Clock;
use crate::sensors::camera::{CameraError, CameraSource, ReplaySource};
use crate::sensors::encoders::EncoderDriver;
use crate::sensors::hokuyo::{HokuyoDriver, HokuyoSettings};
use crate::sensors::task::{spawn_source, Step};
use crate::setup::PerceptionChoice;

/// Where the chair's camera frames come from.
#[derive(Debug, Clone)]
pub enum CameraChoice {
    /// A recording in the TUM RGB-D layout, replayed in a loop and stamped
    /// on arrival (bench tests without a camera).
    Replay(PathBuf),
    /// The RealSense (cargo feature `realsense`).
    RealSense,
    /// No camera: the chair can be stopped, and words are never answered.
    None,
}

/// The device files and interfaces the configuration names, with what
/// each is; those missing on this machine are listed in the error.
pub fn missing_devices(settings: &Settings) -> Vec<String> {
    let motor = match settings.actuation.backend {
        ActuationBackend::Rnet => (
            "R-Net CAN interface",
            format!("/sys/class/net/{}", settings.actuation.rnet.iface),
        ),
        ActuationBackend::Rebus => (
            "Rebus motor interface",
            settings.actuation.rebus.port.clone(),
        ),
    };
    [
        ("left laser", settings.lasers.left.port.clone()),
        ("right laser", settings.lasers.right.port.clone()),
        ("encoder board", settings.encoders.port.clone()),
        motor,
    ]
    .into_iter()
    .filter(|(_, p)| !std::path::Path::new(p).exists())
    .map(|(what, p)| format!("{what} ({p})"))
    .collect()
}

/// Builds the chair's devices. Every configured device must be present.
pub fn devices(
    settings: &Settings,
    camera: CameraChoice,
    perception: &PerceptionChoice,
    clock: Arc<dyn Clock>,
) -> Result<Devices, DeviceError> {
    let missing = missing_devices(settings);
    if !missing.is_empty() {
        return Err(DeviceError::new(
            "chair",
            format!(
                "not found: {} (check the cables and the udev rules in systemd/99-opennav.rules; \
                 `opennav run --sim` runs the simulator)",
                missing.join(", ")
            ),
        ));
    }
    let readers = CancellationToken::new();
    let mut close: Vec<Box<dyn FnOnce() + Send>> = Vec::new();

    // the lasers, each on its reader thread
    let mut lasers = Vec::new();
    for (side, l) in [
        ("left", &settings.lasers.left),
        ("right", &settings.lasers.right),
    ] {
        let mut driver = HokuyoDriver::new(HokuyoSettings::new(l.port.clone()), clock.clone());
        let port = l.port.clone();
        let mut backoff = Duration::from_millis(100);
        let name = format!("laser-{side}");
        let task = spawn_source(&name, readers.clone(), move || match driver.next_scan() {
            Ok(scan) => {
                backoff = Duration::from_millis(100);
                Step::Value(scan)
            }
            Err(e) => {
                tracing::warn!(port = %port, error = %e, "laser: retrying in {backoff:?}");
                std::thread::sleep(backoff);
                backoff = (backoff * 2).min(Duration::from_secs(2));
                Step::Retry
            }
        })
        .map_err(|e| DeviceError::new(&name, e.to_string()))?;
        let source = WatchSource::new(&name, task.latest.clone());
        close.push(Box::new(move || task.join()));
        let base_from_laser: Isometry3<f64> = l.base_from_laser();
        lasers.push((
            Box::new(source) as Box<dyn super::Source<_>>,
            base_from_laser,
        ));
    }
    let [left, right]: [_; 2] = lasers
        .try_into()
        .map_err(|_| DeviceError::new("lasers", "expected two"))?;

    // the encoder board
    let enc_port = settings.encoders.port.clone();
    let mut enc = EncoderDriver::new(enc_port.clone(), clock.clone())
        .with_timeout(Duration::from_millis(200));
    let enc_task = spawn_source("encoders", readers.clone(), move || {
        match enc.next_ticks() {
            Ok(t) => Step::Value(t),
            Err(e) => {
                tracing::warn!(port = %enc_port, error = %e, "encoders: retrying");
                std::thread::sleep(Duration::from_millis(100));
                Step::Retry
            }
        }
    })
    .map_err(|e| DeviceError::new("encoders", e.to_string()))?;
    let wheels = WatchSource::new("encoders", enc_task.latest.clone());
    close.push(Box::new(move || enc_task.join()));

    let camera = camera_device(settings, camera, perception, clock.clone())?;
    let readers_stop = readers.clone();
    // readers stop first, then each is joined
    close.insert(0, Box::new(move || readers_stop.cancel()));
    Ok(Devices {
        lasers: [left, right],
        wheels: Box::new(wheels),
        gyro: None,
        camera,
        actuator: actuator(settings),
        background: Vec::new(),
        stop: CancellationToken::new(),
        close,
    })
}

/// The motor interface from `[actuation] backend`, on its own thread.
fn actuator(settings: &Settings) -> ActuatorStart {
    match settings.actuation.backend {
        ActuationBackend::Rnet => {
            let iface = settings.actuation.rnet.iface.clone();
            let rnet = settings.rnet_settings();
            Box::new(move |io| {
                let h = spawn_actuator_thread(
                    "rnet-writer",
                    50,
                    move || {
                        Ok(RnetActuator {
                            bus: crate::actuation::can::SocketCanBus::open(&iface)?,
                            settings: rnet,
                        })
                    },
                    io,
                )
                .map_err(|e| DeviceError::new("rnet-writer", e.to_string()))?;
                Ok(Box::pin(crate::actuation::thread_result(h)))
            })
        }
        ActuationBackend::Rebus => {
            let port = settings.actuation.rebus.port.clone();
            let mut rebus =
                crate::actuation::rebus_link::RebusSettings::new(settings.joystick_mapping());
            rebus.ack_timeout = Duration::from_secs_f64(settings.actuation.rebus.ack_timeout_s);
            rebus.command_max_age = Duration::from_secs_f64(settings.actuation.command_max_age_s);
            rebus.release_after = Duration::from_secs_f64(settings.actuation.release_s);
            Box::new(move |io| {
                let h = spawn_actuator_thread(
                    "rebus",
                    50,
                    move || {
                        Ok(crate::actuation::rebus_link::RebusActuator {
                            port,
                            settings: rebus,
                        })
                    },
                    io,
                )
                .map_err(|e| DeviceError::new("rebus", e.to_string()))?;
                Ok(Box::pin(crate::actuation::thread_result(h)))
            })
        }
    }
}

fn camera_device(
    settings: &Settings,
    camera: CameraChoice,
    perception: &PerceptionChoice,
    clock: Arc<dyn Clock>,
) -> Result<Option<CameraDevice>, DeviceError> {
    let base_from_camera = settings
        .camera
        .base_from_camera
        .to_isometry("camera.base_from_camera")
        .map_err(|e| DeviceError::new("camera", e.to_string()))?;
    let (open, restamp): (OpenCamera, bool) = match camera {
        CameraChoice::None => return Ok(None),
        CameraChoice::Replay(dir) => (
            Box::new(move || Ok(Box::new(ReplaySource::open(&dir)?) as Box<dyn CameraSource>)),
            true,
        ),
        CameraChoice::RealSense => (
            Box::new(move || open_realsense(base_from_camera, clock.clone())),
            false,
        ),
    };
    let detector = crate::setup::open_configured_detector(settings, perception)
        .map_err(|e| DeviceError::new("detector", e.to_string()))?;
    let segmenter = crate::setup::open_configured_segmenter(settings, perception)
        .map_err(|e| DeviceError::new("segmenter", e.to_string()))?;
    Ok(Some(CameraDevice {
        open,
        detector,
        segmenter,
        restamp,
        period: Duration::from_millis(33),
        latency: Duration::ZERO,
    }))
}

#[cfg(feature = "realsense")]
fn open_realsense(
    base_from_camera: Isometry3<f64>,
    clock: Arc<dyn Clock>,
) -> Result<Box<dyn CameraSource>, CameraError> {
    use crate::sensors::camera::realsense::{RealSenseSettings, RealSenseSource};
    Ok(Box::new(RealSenseSource::open(
        RealSenseSettings::default(),
        base_from_camera,
        clock,
    )?))
}

#[cfg(not(feature = "realsense"))]
fn open_realsense(
    _base_from_camera: Isometry3<f64>,
    _clock: Arc<dyn Clock>,
) -> Result<Box<dyn CameraSource>, CameraError> {
    Err(CameraError::Device(
        "this build has no RealSense support (build with --features realsense); \
         give --camera-replay DIR, or --no-camera"
            .into(),
    ))
}
