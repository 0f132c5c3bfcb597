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

impl Odometry {
    /// The pose `dt_s` seconds before this one's (after, for a negative
    /// `dt_s`), driving on at this speed and yaw rate: where the chair was
    /// at a sensor's stamp a little older than the odometry's.
    pub fn pose_before(&self, dt_s: f64) -> Pose2 {
        let (v, w, p) = (self.v_mps, self.omega_radps, self.pose);
        let theta_rad = p.theta_rad - w * dt_s;
        // along the arc between the two headings (a straight line when
        // the yaw rate is nil)
        let (dx, dy) = if (w * dt_s).abs() < 1e-9 {
            (v * dt_s * p.theta_rad.cos(), v * dt_s * p.theta_rad.sin())
        } else {
            let r = v / w;
            (
                r * (p.theta_rad.sin() - theta_rad.sin()),
                -r * (p.theta_rad.cos() - theta_rad.cos()),
            )
        };
        Pose2 {
            x_m: p.x_m - dx,
            y_m: p.y_m - dy,
            theta_rad: wrap_angle(theta_rad),
        }
    }
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
    fn the_pose_before_follows_the_arc_back() {
        let odo = |v_mps: f64, omega_radps: f64| Odometry {
            pose: Pose2 {
                x_m: 1.0,
                y_m: 2.0,
                theta_rad: 0.5,
            },
            v_mps,
            omega_radps,
            ..Default::default()
        };
        let close = |a: Pose2, b: Pose2| {
            (a.x_m - b.x_m).abs() < 1e-9
                && (a.y_m - b.y_m).abs() < 1e-9
                && wrap_angle(a.theta_rad - b.theta_rad).abs() < 1e-9
        };
        // standing still: where it is
        assert!(close(odo(0.0, 0.0).pose_before(0.1), odo(0.0, 0.0).pose));
        // turning on the spot at 0.8 rad/s: 80 ms before, 0.064 rad back
        let turned = odo(0.0, 0.8).pose_before(0.08);
        assert!(
            (turned.theta_rad - (0.5 - 0.064)).abs() < 1e-12,
            "{turned:?}"
        );
        assert!(turned.x_m == 1.0 && turned.y_m == 2.0);
        // straight at 0.5 m/s: 0.05 m back along the heading
        let back = odo(0.5, 0.0).pose_before(0.1);
        assert!((back.x_m - (1.0 - 0.05 * 0.5f64.cos())).abs() < 1e-12);
        assert!((back.y_m - (2.0 - 0.05 * 0.5f64.sin())).abs() < 1e-12);
        // on a quarter circle of radius 1 m, a quarter period back: the
        // circle's centre lies to the left of the heading, 1 m off
        let w = 1.0;
        let arc = odo(1.0, w).pose_before(std::f64::consts::FRAC_PI_2 / w);
        let centre = [1.0 - 0.5f64.sin(), 2.0 + 0.5f64.cos()];
        let r = (arc.x_m - centre[0]).hypot(arc.y_m - centre[1]);
        assert!((r - 1.0).abs() < 1e-9, "{arc:?}");
        assert!((arc.theta_rad - (0.5 - std::f64::consts::FRAC_PI_2)).abs() < 1e-9);
        // and forward again: where it was
        let arc_odo = Odometry {
            pose: arc,
            ..odo(1.0, w)
        };
        assert!(close(
            arc_odo.pose_before(-std::f64::consts::FRAC_PI_2 / w),
            odo(0.0, 0.0).pose
        ));
    }

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
