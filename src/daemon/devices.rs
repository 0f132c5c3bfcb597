//! The devices the daemon runs on, behind traits: the same wiring drives
//! the chair (drivers over serial, SocketCAN, the RealSense) and the
//! simulator (its sensor models and the simulated chair on an in-memory
//! bus). A [`Devices`] bundle is built from config by [`chair`](super::chair)
//! or by `sim::devices` for a scene.

use std::future::Future;
use std::pin::Pin;
use std::time::Duration;

use tokio::sync::watch;

use crate::actuation::{ActuatorError, ActuatorIo, ActuatorStatus};
use crate::msg::{LaserScan, Stamped, WheelTicks};
use crate::perception::detector::Detector;
use crate::perception::segmenter::Segmenter;
use crate::sensors::camera::{CameraError, CameraSource};

/// A boxed future a device hands the daemon.
pub type DeviceFuture<'a, T> = Pin<Box<dyn Future<Output = T> + Send + 'a>>;

#[derive(Debug, Clone, thiserror::Error, PartialEq, Eq)]
#[error("{device}: {reason}")]
pub struct DeviceError {
    pub device: String,
    pub reason: String,
}

impl DeviceError {
    pub fn new(device: impl Into<String>, reason: impl Into<String>) -> DeviceError {
        DeviceError {
            device: device.into(),
            reason: reason.into(),
        }
    }
}

/// A stream of stamped readings (a laser's scans, the wheel counts, a
/// gyro's yaw rate). `next` waits for the next reading; an error means the
/// source is gone for good (its reader died, the simulation ended): the
/// daemon treats it as a fault.
pub trait Source<T>: Send {
    fn name(&self) -> &str;
    fn next(&mut self) -> DeviceFuture<'_, Result<Stamped<T>, DeviceError>>;
}

/// A source fed through a `watch` channel: by a reader thread on the
/// chair ([`crate::sensors::task::spawn_source`]), by a sensor model in
/// the simulator. Latest value wins; nothing queues.
pub struct WatchSource<T> {
    name: String,
    rx: watch::Receiver<Option<Stamped<T>>>,
}

impl<T> WatchSource<T> {
    pub fn new(name: impl Into<String>, rx: watch::Receiver<Option<Stamped<T>>>) -> Self {
        WatchSource {
            name: name.into(),
            rx,
        }
    }
}

impl<T: Clone + Send + Sync + 'static> Source<T> for WatchSource<T> {
    fn name(&self) -> &str {
        &self.name
    }

    fn next(&mut self) -> DeviceFuture<'_, Result<Stamped<T>, DeviceError>> {
        Box::pin(async move {
            loop {
                if self.rx.changed().await.is_err() {
                    return Err(DeviceError::new(
                        self.name.clone(),
                        "its reader ended (thread died or device closed)",
                    ));
                }
                if let Some(v) = self.rx.borrow_and_update().clone() {
                    return Ok(v);
                }
            }
        })
    }
}

/// Opens a camera (again, at the end of a recording).
pub type OpenCamera = Box<dyn FnMut() -> Result<Box<dyn CameraSource>, CameraError> + Send>;

/// The camera and what turns its frames into objects.
pub struct CameraDevice {
    /// Opens the camera (again, at the end of a recording).
    pub open: OpenCamera,
    pub detector: Box<dyn Detector>,
    pub segmenter: Box<dyn Segmenter>,
    /// A replayed frame is stamped on arrival; a live one keeps its
    /// acquisition stamp.
    pub restamp: bool,
    /// Views taken at most this often (the camera may deliver faster).
    pub period: Duration,
    /// The simulator's stand-in for the detector's compute time: objects
    /// are published this long after the frame's stamp. Zero on the chair,
    /// where the time is real.
    pub latency: Duration,
}

/// Starts the motor interface with the daemon's channels; the future
/// resolves when it has stopped (after centring and releasing on
/// cancellation, or on a fault).
pub type ActuatorStart = Box<
    dyn FnOnce(
            ActuatorIo,
        )
            -> Result<DeviceFuture<'static, Result<ActuatorStatus, ActuatorError>>, DeviceError>
        + Send,
>;

/// Everything the daemon needs from the outside world.
pub struct Devices {
    /// Left and right lasers, with their mounting in `base_link`.
    pub lasers: [(Box<dyn Source<LaserScan>>, nalgebra::Isometry3<f64>); 2],
    pub wheels: Box<dyn Source<WheelTicks>>,
    /// A yaw-rate source about base z (rad/s) besides the camera's IMU.
    pub gyro: Option<Box<dyn Source<f64>>>,
    pub camera: Option<CameraDevice>,
    pub actuator: ActuatorStart,
    /// Tasks of the devices themselves (the simulated world and chair):
    /// run by the daemon and watched like its own.
    pub background: Vec<(String, DeviceFuture<'static, Result<(), DeviceError>>)>,
    /// Cancelled by the daemon at shutdown, after the chair is released:
    /// the background tasks end.
    pub stop: tokio_util::sync::CancellationToken,
    /// Called at shutdown, after the chair is released: joins reader
    /// threads, closes ports.
    pub close: Vec<Box<dyn FnOnce() + Send>>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::Stamp;

    #[tokio::test]
    async fn a_watch_source_delivers_each_new_reading_and_says_when_its_reader_died() {
        let (tx, rx) = watch::channel::<Option<Stamped<u32>>>(None);
        let mut s = WatchSource::new("laser-left", rx);
        tx.send_replace(Some(Stamped::new(Stamp::ZERO, 7)));
        assert_eq!(s.next().await.map(|v| v.value), Ok(7));
        // the reader thread dies: its sender goes away
        drop(tx);
        let e = s.next().await.expect_err("ended");
        assert_eq!(e.device, "laser-left");
        assert!(e.to_string().contains("reader ended"), "{e}");
    }
}
