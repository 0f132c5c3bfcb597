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
pub use geometry::{floor_fast, hypot_cmp, wrap_angle, Frame, Pose2};
pub use image::{is_valid_depth, DepthImage, ImageError, RgbImage};
pub use sensors::{
    LaserRay, LaserScan, MapObstacles, NoReturn, Obstacles, Reading, RgbdFrame, WheelTicks,
};
pub use time::{Clock, MonotonicClock, Stamp, Stamped, TokioClock};

pub use crate::perception::boxes::Object3D;

/// The chair's estimated motion in `odom`: pose, forward speed (m/s) and
/// yaw rate (rad/s, counter-clockwise).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Odometry {
    pub pose: Pose2,
    pub v_mps: f64,
    pub omega_radps: f64,
    /// The pose's covariance over (x m, y m, θ rad), row-major.
    pub pose_cov: [[f64; 3]; 3],
}

/// What a user can say or press.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum UserInput {
    /// Go to an object of this word.
    Goto(String),
    /// Stop now (voice "stop", a switch); latched until [`UserInput::Go`].
    Stop,
    /// Go on after a stop (the explicit word that clears it).
    Go,
    /// Quit the daemon.
    Quit,
    /// Turn once on the spot and say what is around (the switch menu's
    /// "look around", or the words).
    LookAround,
    /// "yes" to the chair's question (e.g. is it clear behind).
    Yes,
    /// "no" to the chair's question.
    No,
    /// A person checked the chair: clear a latched fault (the control
    /// socket, `opennav ack-fault`; never from free speech).
    AckFault,
    /// The recogniser is unsure it heard this word: ask "Did you say the
    /// X?" and go only after "yes" (never from typed text).
    Unsure(String),
    /// The recogniser heard this target word surely: at rest it is a
    /// [`UserInput::Goto`]; while the chair drives itself it stops the
    /// chair first, as any switch press does (a "stop" in noise can come
    /// out as a target: "stop" as "door"), and "go" then goes to it.
    Heard(String),
}

/// Words that stop the chair wherever they appear in what was said.
const STOP_WORDS: [&str; 5] = ["stop", "halt", "switch", "wait", "freeze"];
/// What may come before the object's word.
const GOTO_PREFIXES: [&[&str]; 5] = [
    &["go", "to"],
    &["take", "me", "to"],
    &["drive", "to"],
    &["find"],
    &["to"],
];
const ARTICLES: [&str; 4] = ["the", "a", "an", "my"];

impl UserInput {
    /// A line of text, normalised (case, punctuation, spacing): a stop word
    /// anywhere ("STOP!", "stop please", "halt") or an empty line — a bare
    /// switch press — stops; `go`, `go on`, `continue`, `resume` go on
    /// after a stop; `quit`/`exit` quits; anything else is the word to go
    /// to, with "go to / take me to / find" and an article taken off.
    pub fn parse(line: &str) -> UserInput {
        let words: Vec<String> = line
            .split(|c: char| !(c.is_alphanumeric() || c == '\'' || c == '-'))
            .filter(|w| !w.is_empty())
            .map(str::to_lowercase)
            .collect();
        if words.is_empty() || words.iter().any(|w| STOP_WORDS.contains(&w.as_str())) {
            return UserInput::Stop;
        }
        let w: Vec<&str> = words.iter().map(String::as_str).collect();
        match w.as_slice() {
            ["quit"] | ["exit"] => return UserInput::Quit,
            ["look", "around"] => return UserInput::LookAround,
            ["yes"]
            | ["yeah"]
            | ["yep"]
            | ["yes", "please"]
            | ["ok"]
            | ["okay"]
            | ["clear"]
            | ["it's", "clear"]
            | ["all", "clear"] => return UserInput::Yes,
            ["no"] | ["nope"] | ["no", "thanks"] | ["not", "clear"] => return UserInput::No,
            ["go"] | ["go", "on"] | ["continue"] | ["resume"] | ["carry", "on"] => {
                return UserInput::Go
            }
            _ => {}
        }
        let mut rest: &[&str] = &w;
        if let Some(p) = GOTO_PREFIXES
            .iter()
            .find(|p| rest.starts_with(p) && rest.len() > p.len())
        {
            rest = &rest[p.len()..];
        }
        if rest.len() > 1 && ARTICLES.contains(&rest[0]) {
            rest = &rest[1..];
        }
        UserInput::Goto(rest.join(" "))
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
        assert_eq!(UserInput::parse("Yes."), UserInput::Yes);
        assert_eq!(UserInput::parse("it's clear"), UserInput::Yes);
        assert_eq!(UserInput::parse("no"), UserInput::No);
        // "no" inside a goal phrase is not an answer
        assert_eq!(
            UserInput::parse("go to the nook"),
            UserInput::Goto("nook".into())
        );
    }

    #[test]
    fn stop_words_are_normalised_and_win_anywhere() {
        for s in [
            "STOP!",
            "stop please",
            "please stop",
            "Halt.",
            "  wait ",
            "...",
            "\t",
        ] {
            assert_eq!(UserInput::parse(s), UserInput::Stop, "{s:?}");
        }
        for s in ["go", "Go on!", "continue", "resume"] {
            assert_eq!(UserInput::parse(s), UserInput::Go, "{s:?}");
        }
        for (s, w) in [
            ("Go to the chair.", "chair"),
            ("take me to my desk", "desk"),
            ("find a person", "person"),
            ("dining table", "dining table"),
            ("the", "the"),
        ] {
            assert_eq!(UserInput::parse(s), UserInput::Goto(w.into()), "{s:?}");
        }
    }
}
