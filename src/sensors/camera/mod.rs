//! RGB-D cameras: a trait, a replay source (TUM RGB-D layout), colour /
//! depth pairing by timestamp, and the RealSense source behind the
//! `realsense` cargo feature (it links librealsense2; see docs/sensors.md).

#[cfg(feature = "realsense")]
pub mod realsense;
pub mod replay;

use thiserror::Error;

use crate::msg::ImageError;
use crate::msg::{CalibrationError, RgbdCalibration};
use crate::msg::{RgbdFrame, Stamped};

pub use replay::ReplaySource;

#[derive(Debug, Error)]
pub enum CameraError {
    #[error("{path}: {reason}")]
    Recording { path: String, reason: String },
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    #[error("camera: {0}")]
    Device(String),
}

/// A source of paired RGB-D frames.
pub trait CameraSource: Send {
    fn calibration(&self) -> &RgbdCalibration;
    /// The next frame (stamped with the colour frame's acquisition time);
    /// None at the end of a recording.
    fn next_frame(&mut self) -> Result<Option<Stamped<RgbdFrame>>, CameraError>;
    /// The newest gyro reading, rad/s about the camera's optical axes
    /// (x right, y down, z forward; librealsense reports the D435i/D455
    /// IMU in that orientation), for cameras with an IMU.
    fn gyro(&self) -> Option<Stamped<[f64; 3]>> {
        None
    }
}

/// Pairs colour and depth frames by timestamp as TUM's `associate.py`:
/// every pair closer than `max_dt_s`, taken greedily from the closest, each
/// frame used once. Returns (colour index, depth index), by colour time.
pub fn associate(color_s: &[f64], depth_s: &[f64], max_dt_s: f64) -> Vec<(usize, usize)> {
    let mut cands: Vec<(f64, usize, usize)> = Vec::new();
    for (i, &c) in color_s.iter().enumerate() {
        // depth times need not be sorted: check all within reach
        for (j, &d) in depth_s.iter().enumerate() {
            let dt = (c - d).abs();
            if dt < max_dt_s {
                cands.push((dt, i, j));
            }
        }
    }
    cands.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut used_c = vec![false; color_s.len()];
    let mut used_d = vec![false; depth_s.len()];
    let mut out = Vec::new();
    for (_, i, j) in cands {
        if !used_c[i] && !used_d[j] {
            used_c[i] = true;
            used_d[j] = true;
            out.push((i, j));
        }
    }
    out.sort_unstable();
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn association_pairs_nearest_within_reach() {
        let c = [0.000, 0.033, 0.066, 0.100];
        let d = [0.010, 0.040, 0.043, 0.200];
        // 0.033 takes 0.040 (7 ms) before 0.043; 0.066 could take 0.043 (23 ms) only if within reach
        assert_eq!(associate(&c, &d, 0.02), vec![(0, 0), (1, 1)]);
        assert_eq!(associate(&c, &d, 0.03), vec![(0, 0), (1, 1), (2, 2)]);
        assert!(associate(&c, &[], 1.0).is_empty());
    }
}
