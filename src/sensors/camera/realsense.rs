//! The RealSense D435/D455 source (cargo feature `realsense`, links
//! librealsense2 through `realsense-rust`; see docs/sensors.md for installing
//! the library on the chair's laptop).
//!
//! Colour and depth come from one pipeline, depth aligned to colour by
//! librealsense's `align` block (so the calibration is a registered one,
//! from the colour stream's own intrinsics); device timestamps (ms, the
//! device's clock or its global time) are mapped to the host's monotonic
//! clock with drift estimation; depth is converted to metres once, here,
//! with the device's depth units. Models with an IMU (D435i, D455) also
//! give the gyro's yaw rate for the odometry EKF.

use std::collections::HashSet;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Isometry3;
use realsense_rust::config::Config;
use realsense_rust::context::Context;
use realsense_rust::frame::{
    ColorFrame, CompositeFrame, DepthFrame, FrameEx, GyroFrame, PixelKind,
};
use realsense_rust::kind::{Rs2Format, Rs2StreamKind};
use realsense_rust::pipeline::{ActivePipeline, InactivePipeline};
use realsense_rust::processing_blocks::align::Align;

use super::{CameraError, CameraSource, RgbdFrame};
use crate::msg::{Clock, Stamp, Stamped};
use crate::msg::{DepthImage, RgbImage};
use crate::msg::{Intrinsics, RgbdCalibration};
use crate::sensors::clock::DeviceClock;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RealSenseSettings {
    pub width: usize,
    pub height: usize,
    pub fps: usize,
    /// Stream the gyro (D435i / D455).
    pub gyro: bool,
    pub frame_timeout: Duration,
}

impl Default for RealSenseSettings {
    fn default() -> Self {
        RealSenseSettings {
            width: 640,
            height: 480,
            fps: 30,
            gyro: true,
            frame_timeout: Duration::from_secs(2),
        }
    }
}

/// A gyro reading: angular velocity about the camera's IMU axes, rad/s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GyroReading {
    pub rate_radps: [f64; 3],
}

/// librealsense's align block behind a `Send` wrapper.
struct AlignBlock(Align);

// SAFETY: librealsense2's processing blocks and frame queues may be used
// from any thread (its C API is thread-safe); the source owns the block
// and is used by one thread at a time (`CameraSource: Send`, not `Sync`).
unsafe impl Send for AlignBlock {}

pub struct RealSenseSource {
    pipeline: ActivePipeline,
    align: AlignBlock,
    calibration: RgbdCalibration,
    clock: Arc<dyn Clock>,
    device_clock: DeviceClock,
    settings: RealSenseSettings,
    /// The newest gyro reading seen.
    pub gyro: Option<Stamped<GyroReading>>,
    pending: Option<Stamped<RgbdFrame>>,
}

fn dev(e: impl std::fmt::Display) -> CameraError {
    CameraError::Device(format!("RealSense: {e}"))
}

impl RealSenseSource {
    /// Opens the first D400-family camera and waits for its first frames
    /// (their intrinsics make the calibration).
    pub fn open(
        settings: RealSenseSettings,
        base_from_camera: Isometry3<f64>,
        clock: Arc<dyn Clock>,
    ) -> Result<RealSenseSource, CameraError> {
        let context = Context::new().map_err(dev)?;
        let devices = context.query_devices(HashSet::new());
        if devices.is_empty() {
            return Err(CameraError::Device(
                "RealSense: no camera found (is it plugged in, and are the udev rules installed?)"
                    .into(),
            ));
        }
        let pipeline = InactivePipeline::try_from(&context).map_err(dev)?;
        let mut config = Config::new();
        let (w, h, fps) = (settings.width, settings.height, settings.fps);
        config
            .enable_stream(Rs2StreamKind::Depth, None, w, h, Rs2Format::Z16, fps)
            .map_err(dev)?;
        config
            .enable_stream(Rs2StreamKind::Color, None, w, h, Rs2Format::Rgb8, fps)
            .map_err(dev)?;
        if settings.gyro {
            config
                .enable_stream(Rs2StreamKind::Gyro, None, 0, 0, Rs2Format::Any, 0)
                .map_err(dev)?;
        }
        let pipeline = pipeline.start(Some(config)).map_err(dev)?;
        let align = AlignBlock(Align::new(Rs2StreamKind::Color, 2).map_err(dev)?);
        // a placeholder until the first frame tells the intrinsics
        let placeholder = Intrinsics {
            width: w,
            height: h,
            fx: 1.0,
            fy: 1.0,
            cx: 0.0,
            cy: 0.0,
        };
        let mut source = RealSenseSource {
            pipeline,
            align,
            calibration: RgbdCalibration::registered(placeholder, base_from_camera)
                .with_floor_z(0.0),
            clock,
            // librealsense timestamps: milliseconds as f64; mapped in µs
            device_clock: DeviceClock::new(62, 1e-6, 120),
            settings,
            gyro: None,
            pending: None,
        };
        let first = source.read()?;
        source.pending = Some(first);
        Ok(source)
    }

    fn stamp(&mut self, device_ms: f64) -> Stamp {
        let now = self.clock.now();
        if !device_ms.is_finite() || device_ms < 0.0 {
            return now;
        }
        self.device_clock.map((device_ms * 1000.0) as u64, now)
    }

    fn take_gyro(&mut self, frames: &CompositeFrame) {
        if let Some(g) = frames.frames_of_type::<GyroFrame>().pop() {
            let r = g.rotational_velocity();
            let stamp = self.stamp(g.timestamp());
            self.gyro = Some(Stamped::new(
                stamp,
                GyroReading {
                    rate_radps: [r[0] as f64, r[1] as f64, r[2] as f64],
                },
            ));
        }
    }

    fn read(&mut self) -> Result<Stamped<RgbdFrame>, CameraError> {
        loop {
            let frames = self
                .pipeline
                .wait(Some(self.settings.frame_timeout))
                .map_err(dev)?;
            self.take_gyro(&frames);
            self.align.0.queue(frames).map_err(dev)?;
            let aligned = self
                .align
                .0
                .wait(self.settings.frame_timeout)
                .map_err(dev)?;
            let (Some(color), Some(depth)) = (
                aligned.frames_of_type::<ColorFrame>().pop(),
                aligned.frames_of_type::<DepthFrame>().pop(),
            ) else {
                continue; // a motion-only frameset
            };
            let (w, h) = (color.width(), color.height());
            if depth.width() != w || depth.height() != h {
                return Err(CameraError::Device(format!(
                    "RealSense: aligned depth {}×{} does not match colour {w}×{h}",
                    depth.width(),
                    depth.height()
                )));
            }
            let k = color.stream_profile().intrinsics().map_err(dev)?;
            self.calibration.color = Intrinsics {
                width: w,
                height: h,
                fx: k.fx() as f64,
                fy: k.fy() as f64,
                cx: k.ppx() as f64,
                cy: k.ppy() as f64,
            };
            let units = depth.depth_units().map_err(dev)?;
            let mut rgb = Vec::with_capacity(w * h * 3);
            for p in color.iter() {
                match p {
                    PixelKind::Rgb8 { r, g, b } | PixelKind::Bgr8 { r, g, b } => {
                        rgb.extend_from_slice(&[*r, *g, *b])
                    }
                    _ => {
                        return Err(CameraError::Device(
                            "RealSense: colour stream is not RGB8/BGR8".into(),
                        ))
                    }
                }
            }
            let mut depth_m = Vec::with_capacity(w * h);
            for p in depth.iter() {
                match p {
                    PixelKind::Z16 { depth } => depth_m.push(*depth as f32 * units),
                    _ => {
                        return Err(CameraError::Device(
                            "RealSense: depth stream is not Z16".into(),
                        ))
                    }
                }
            }
            let color_stamp = self.stamp(color.timestamp());
            let depth_stamp = self.stamp(depth.timestamp());
            return Ok(Stamped::new(
                color_stamp,
                RgbdFrame {
                    color: RgbImage::new(w, h, rgb)?,
                    depth: DepthImage::new(w, h, depth_m)?,
                    color_stamp,
                    depth_stamp,
                },
            ));
        }
    }
}

impl CameraSource for RealSenseSource {
    fn calibration(&self) -> &RgbdCalibration {
        &self.calibration
    }

    fn next_frame(&mut self) -> Result<Option<Stamped<RgbdFrame>>, CameraError> {
        if let Some(f) = self.pending.take() {
            return Ok(Some(f));
        }
        self.read().map(Some)
    }

    fn gyro(&self) -> Option<Stamped<[f64; 3]>> {
        self.gyro
            .as_ref()
            .map(|g| Stamped::new(g.stamp, g.value.rate_radps))
    }
}
