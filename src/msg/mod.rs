//! The messages every part of opennav speaks. Drivers, algorithms, the
//! recorder and the simulator depend on these types, not on each other.
//!
//! - [`time`]: [`Stamp`], [`Stamped`], the [`Clock`] handle;
//! - [`geometry`]: [`Frame`], [`Pose2`];
//! - [`sensors`]: [`LaserScan`], [`Obstacles`], [`WheelTicks`], [`RgbdFrame`];
//! - [`image`]: [`RgbImage`], [`DepthImage`]; [`calibration`]: [`Intrinsics`],
//!   [`RgbdCalibration`] and the calibration file;
//! - [`command`]: [`VelocityCmd`], [`SafeCmd`] and the supervisor's state;
//! - here: [`Odometry`], [`UserInput`], and perception's [`Object3D`]
//!   (defined with its box geometry in `perception::boxes`).

pub mod calibration;
pub mod command;
pub mod geometry;
pub mod image;
pub mod sensors;
pub mod time;

use serde::Serialize;

pub use calibration::{CalibrationError, Intrinsics, RgbdCalibration, TransformSpec};
pub use command::{FaultReason, SafeCmd, StopReason, SupervisorState, VelocityCmd};
pub use geometry::{wrap_angle, Frame, Pose2};
pub use image::{is_valid_depth, DepthImage, ImageError, RgbImage};
pub use sensors::{LaserScan, NoReturn, Obstacles, Reading, RgbdFrame, WheelTicks};
pub use time::{Clock, MonotonicClock, Stamp, Stamped, TokioClock};

pub use crate::perception::boxes::Object3D;

/// The chair's estimated motion in `odom`: pose, forward speed (m/s) and
/// yaw rate (rad/s, counter-clockwise).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Odometry {
    pub pose: Pose2,
    pub v_mps: f64,
    pub omega_radps: f64,
}

/// What a user can say or press.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum UserInput {
    /// Go to an object of this word.
    Goto(String),
    /// Stop now (voice "stop", a switch).
    Stop,
    /// Quit the daemon.
    Quit,
}

impl UserInput {
    /// A line of text: `stop`/`halt` (also a bare switch press, an empty
    /// line), `quit`/`exit`, else a word to go to.
    pub fn parse(line: &str) -> UserInput {
        let w = line.trim().to_lowercase();
        match w.as_str() {
            "" | "stop" | "halt" | "switch" => UserInput::Stop,
            "quit" | "exit" => UserInput::Quit,
            _ => UserInput::Goto(w),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn user_input_words() {
        assert_eq!(
            UserInput::parse(" Chair\n"),
            UserInput::Goto("chair".into())
        );
        assert_eq!(UserInput::parse("STOP"), UserInput::Stop);
        assert_eq!(
            UserInput::parse("\n"),
            UserInput::Stop,
            "a bare switch press stops"
        );
        assert_eq!(UserInput::parse("quit"), UserInput::Quit);
    }
}
