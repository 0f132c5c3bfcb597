//! Through a doorway (pure): a narrow passage on the way ahead is found on
//! the map (its two jambs, its middle and its axis), and the chair passes
//! it as a person steering a wheelchair would: to a point on the axis
//! before it, turned on the spot to face along the axis, then straight
//! through at a crawl, steering back onto the middle line. A 0.70 m chair
//! in a 0.80–0.90 m doorway has a few centimetres a side: driven at a
//! slant, its stop corridor (rightly) halts it at the jamb.
//!
//! The supervisor still checks every command; a passage that stays
//! blocked is given up and the planner's way is followed again.

use crate::msg::{wrap_angle, Pose2, VelocityCmd};

/// A passage between two jambs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Doorway {
    /// The middle, odom, m.
    pub center: [f64; 2],
    /// The direction of travel through it, odom, rad.
    pub axis_rad: f64,
    /// Between the jambs' faces, m.
    pub width_m: f64,
}

impl Doorway {
    /// `p` in the doorway's frame: along the axis (negative: before it)
    /// and to the left of the middle line, m.
    pub fn local(&self, p: [f64; 2]) -> (f64, f64) {
        let (c, s) = (self.axis_rad.cos(), self.axis_rad.sin());
        let (dx, dy) = (p[0] - self.center[0], p[1] - self.center[1]);
        (c * dx + s * dy, -s * dx + c * dy)
    }

    /// The point `along_m` along the axis from the middle.
    pub fn on_axis(&self, along_m: f64) -> [f64; 2] {
        [
            self.center[0] + along_m * self.axis_rad.cos(),
            self.center[1] + along_m * self.axis_rad.sin(),
        ]
    }
}

/// A passage narrower than this (twice the distance from the way to the
/// nearest thing) is a doorway, m.
pub const NARROW_M: f64 = 1.1;
#[path = "doorway_find.rs"]
mod finder;
pub use finder::find;

/// The passage's phase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Phase {
    /// To the point on the axis before the doorway.
    Approach,
    /// Off the middle line near that point: turned to face a point on the
    /// middle line ([`PassageSettings::line_up_m`] before the doorway, or
    /// nearer when the chair is already past that) and driven straight
    /// onto it, so that the passage starts centred (the gap leaves 2–7 cm
    /// a side, the approach is good to 15 cm).
    LineUp {
        /// The point's place along the axis, m (negative: before it).
        at_m: f64,
    },
    /// Turning on the spot to face along the axis.
    Align,
    /// Straight through at a crawl.
    Pass,
    /// Too near the doorway to line up, and off the middle line by more
    /// than the gap leaves a side (`squaring`); or held turning square to
    /// it on the spot, too near it and turned well off its axis (not
    /// `squaring`): back, until there is room to line up or to turn
    /// (`to_m` along the axis), m.
    BackUp {
        to_m: f64,
        /// Squaring to the axis as it backs (off the line, square enough
        /// already), or holding the heading (turned too far off the axis
        /// near the doorway: a corner turned there would reach a jamb).
        squaring: bool,
    },
    /// A turn on the spot to line up held further from the doorway, by
    /// something in the corners' circle: straight back, the heading held,
    /// `back_m` from `from_odom`, then the turn to the line-up's point
    /// (`at_m` along the axis) is tried again from there. Backing stops
    /// short of where the rear would near the doorway's wall.
    BackOut {
        from_odom: [f64; 2],
        back_m: f64,
        at_m: f64,
    },
}

impl Phase {
    /// The phase's name, as in the logs.
    pub fn name(&self) -> &'static str {
        match self {
            Phase::Approach => "approach",
            Phase::LineUp { .. } => "line_up",
            Phase::Align => "align",
            Phase::Pass => "pass",
            Phase::BackUp { .. } => "back_up",
            Phase::BackOut { .. } => "back_out",
        }
    }
}

/// What to do now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PassageCmd {
    /// Head for this point with the planner (odom).
    Aim([f64; 2]),
    /// This command.
    Drive(VelocityCmd),
    /// Through (or given up): follow the way again.
    Done,
}

/// The manoeuvre's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassageSettings {
    /// The point before the doorway, on the axis, m.
    pub before_m: f64,
    /// Reached within this, m.
    pub at_m: f64,
    /// Aligned within this, rad.
    pub aligned_rad: f64,
    /// Turn rate while aligning, rad/s.
    pub turn_radps: f64,
    /// Speed through, m/s.
    pub crawl_mps: f64,
    /// Through when base_link is this far past the middle, m.
    pub past_m: f64,
    /// Steering: rad/s per metre off the middle line and per radian off
    /// the axis, capped.
    pub k_lateral: f64,
    pub k_heading: f64,
    pub omega_max_radps: f64,
    /// From this far before the middle on, only the heading is held, m.
    pub square_within_m: f64,
    /// base_link this far past the middle: the chair's rear (0.45 m behind
    /// it) is out of the doorway, m.
    pub clear_of_door_m: f64,
    /// The point on the middle line lined up on, this far before the
    /// middle, m; from nearer, a point `line_up_ahead_m` ahead of the
    /// chair, but never nearer than `line_up_nearest_m` (room to turn on
    /// the spot there: the corners' circle and the crawl's margin reach
    /// 0.68 m, the wall's face is 0.05 m before the middle); lined up when
    /// further off the line than `line_up_off_m`, from at most
    /// `line_up_from_m` off it, m.
    pub line_up_m: f64,
    pub line_up_ahead_m: f64,
    pub line_up_nearest_m: f64,
    pub line_up_off_m: f64,
    pub line_up_from_m: f64,
    /// What the gap must hold: the chair's width and the crawl's margin
    /// each side (0.70 + 2 × 0.03), m. Off the middle line by more than
    /// half the rest (or `line_up_off_m`), too near to line up, and with
    /// the front not yet at the wall (base_link `enter_m` before the
    /// middle), the chair backs up to make room, `back_ups` times at most.
    pub body_m: f64,
    pub enter_m: f64,
    pub back_ups: u32,
    /// Backs up this far at most (the person is asked about this much
    /// behind when the rear is unseen), m.
    pub back_up_m: f64,
}

impl PassageSettings {
    /// The point on the middle line to line up on from `along_m` along
    /// the axis: [`Self::line_up_m`] before the middle, or
    /// [`Self::line_up_ahead_m`] ahead of the chair when it is nearer, m.
    fn line_up_at(&self, along_m: f64) -> f64 {
        (-self.line_up_m).max(along_m + self.line_up_ahead_m)
    }
}

impl Default for PassageSettings {
    fn default() -> Self {
        PassageSettings {
            before_m: 1.3,
            at_m: 0.15,
            aligned_rad: 0.02,
            turn_radps: 0.3,
            crawl_mps: 0.09,
            past_m: 0.8,
            k_lateral: 4.0,
            k_heading: 1.5,
            omega_max_radps: 0.25,
            square_within_m: 0.85,
            clear_of_door_m: 0.6,
            line_up_m: 1.1,
            line_up_ahead_m: 0.2,
            line_up_nearest_m: 0.78,
            line_up_off_m: 0.03,
            line_up_from_m: 0.35,
            body_m: 0.76,
            enter_m: 0.5,
            back_ups: 2,
            back_up_m: 0.4,
        }
    }
}

/// Held on the way to the point before the doorway, the chair lines up
/// from at most this far off the middle line, m.
pub const LINE_UP_HELD_FROM_M: f64 = 1.0;

/// Passing steers back onto the axis from at most this far off it; more,
/// it squares again (`Phase::Align`), rad.
const PASS_STEERS_WITHIN_RAD: f64 = 0.35;

/// Lining up, the chair turns on the spot to face the point when it is
/// more than this off the heading, rad.
const LINE_UP_TURNS_RAD: f64 = 0.12;

/// Backing up only this square to the doorway, rad.
const BACK_UP_SQUARE_RAD: f64 = 0.2;

/// Held passing this far before the middle (base_link) or more, the
/// chair's front is at the wall, not yet in the doorway: backing up and
/// lining up again is still possible, m.
const PASS_HELD_BACKS_BEFORE_M: f64 = 0.3;

/// Held passing and turned off the axis by more than this, the chair backs
/// up to line up again ([`Passage::held_passing`]), rad.
const PASS_HELD_TURNED_RAD: f64 = 0.1;

/// Held passing with the far corners of the crawl's stop corridor
/// (`PASS_HELD_REACH_M` ahead of base_link: the front, 0.55 m, and the
/// crawl's stop distance) within `PASS_HELD_SLACK_M` of using up what the
/// gap leaves a side, the chair backs up to line up again (in a 0.81 m
/// doorway 2 cm off the middle line and 1° turned is held), m.
const PASS_HELD_REACH_M: f64 = 0.7;
const PASS_HELD_SLACK_M: f64 = 0.01;

/// Backing out towards the doorway stops this far short of the line-up's
/// point, m.
const LINE_UP_PAST_M: f64 = 0.05;

/// Backing out to turn: worth it only this far back at least, m.
const BACK_OUT_MIN_M: f64 = 0.1;

/// One doorway being passed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Passage {
    /// The doorway as passed: the map's, its middle and width moved to
    /// the jambs the lasers measure now ([`Passage::observe`]).
    pub door: Doorway,
    /// The doorway as the map found it.
    pub found: Doorway,
    pub phase: Phase,
    pub settings: PassageSettings,
    /// Times it backed up to line up again.
    pub backed_up: u32,
    /// Whether it has lined up from where it was held on its way to the
    /// point before the doorway ([`Passage::held_on_approach`]).
    pub lined_up_where_held: bool,
    /// No turn on the spot for the rest of this passage: the person said
    /// no to one ([`Passage::refuse_turns`]), or one was held
    /// ([`Passage::held_turning`]); it lines up and squares by arcs.
    pub turns_refused: bool,
    /// The person said no to a turn on the spot ([`Passage::refuse_turns`]):
    /// turns stay refused wherever the chair backs to.
    pub turns_refused_by_person: bool,
}

/// Jamb points are taken within this of the wall's middle plane along the
/// axis (half the wall and 5 cm), m.
const JAMB_BAND_M: f64 = 0.10;
/// The measured jambs may move the map's middle this far at most, and
/// their gap may be this much narrower or this much wider than the map's
/// (which is good to a cell and measures short), m.
const JAMB_SHIFT_MAX_M: f64 = 0.10;
const JAMB_NARROWER_M: f64 = 0.05;
const JAMB_WIDER_M: f64 = 0.15;

/// The jambs' faces across the doorway, measured from points (odom): to
/// the right and to the left of `door`'s middle line (m, negative and
/// positive), each the nearest point to the middle line within the wall's
/// band on its side, with at least two points on each side. None when a
/// side is unseen, or the gap is implausible for `door` (something
/// standing in the doorway, a person passing).
pub fn jamb_faces(door: &Doorway, points_odom: &[[f64; 2]]) -> Option<(f64, f64)> {
    let reach = door.width_m / 2.0 + JAMB_SHIFT_MAX_M + JAMB_WIDER_M;
    let (mut right, mut left) = (f64::NEG_INFINITY, f64::INFINITY);
    let (mut n_right, mut n_left) = (0usize, 0usize);
    for p in points_odom {
        let (along, l) = door.local(*p);
        if along.abs() > JAMB_BAND_M || l.abs() > reach {
            continue;
        }
        if l < 0.0 {
            n_right += 1;
            right = right.max(l);
        } else {
            n_left += 1;
            left = left.min(l);
        }
    }
    let gap = left - right;
    (n_right >= 2
        && n_left >= 2
        && gap >= door.width_m - JAMB_NARROWER_M
        && gap <= door.width_m + JAMB_WIDER_M
        && ((left + right) / 2.0).abs() <= JAMB_SHIFT_MAX_M)
        .then_some((right, left))
}

impl Passage {
    /// Starts at the phase that fits where the chair is: already on the
    /// axis close before it, straight to aligning.
    pub fn new(door: Doorway, settings: PassageSettings) -> Passage {
        Passage {
            door,
            found: door,
            phase: Phase::Approach,
            settings,
            backed_up: 0,
            lined_up_where_held: false,
            turns_refused: false,
            turns_refused_by_person: false,
        }
    }

    /// No turn on the spot (the person said it is not clear around the
    /// chair, where it wanted to turn to line up or to square): for the
    /// rest of this passage it turns on a crawl's arc instead, each
    /// checked by the supervisor as any arc (the stop corridor along it).
    pub fn refuse_turns(&mut self) {
        self.turns_refused = true;
        self.turns_refused_by_person = true;
    }

    /// Held on the way to the point before the doorway (something stands
    /// between the chair and it, or at it): where the chair is already
    /// level with that point or nearer the doorway, and off the middle
    /// line by at most [`LINE_UP_HELD_FROM_M`], it lines up from there,
    /// on a line steeper than the 45 degrees an approach allows (turned
    /// on the spot to face it, at a crawl), once a passage. Whether it
    /// does.
    pub fn held_on_approach(&mut self, pose: Pose2) -> bool {
        let s = self.settings;
        let (along, left) = self.door.local([pose.x_m, pose.y_m]);
        let line_up_at = s.line_up_at(along);
        let lines_up = self.phase == Phase::Approach
            && !self.lined_up_where_held
            && along > -s.before_m - s.at_m
            && line_up_at <= -s.line_up_nearest_m
            && left.abs() <= LINE_UP_HELD_FROM_M;
        if lines_up {
            self.lined_up_where_held = true;
            self.phase = Phase::LineUp { at_m: line_up_at };
        }
        lines_up
    }

    /// Held lining up or squaring to the doorway with `pose`, where the
    /// manoeuvre turns on the spot (turns still allowed, a line-up's point
    /// off the heading, or squaring): squaring too near the doorway and
    /// turned well off its axis, it first backs up straight to where a
    /// turn on the spot fits ([`Phase::BackUp`], not squaring); lining up
    /// with the point well off the heading, it first backs out straight,
    /// away from what holds the turn, and turns again from there
    /// ([`Phase::BackOut`]; not squaring: backing across the axis would
    /// take the chair off the line it is on); otherwise,
    /// from now on it turns on a crawl's arcs instead
    /// ([`Passage::refuse_turns`]), each checked by the supervisor as any
    /// arc. Whether it does either.
    pub fn held_turning(&mut self, pose: Pose2) -> bool {
        let turning = match self.phase {
            Phase::LineUp { at_m } => self.line_up_bearing(pose, at_m).abs() > LINE_UP_TURNS_RAD,
            Phase::Align => true,
            _ => false,
        };
        if turning && !self.turns_refused {
            let (along, _) = self.door.local([pose.x_m, pose.y_m]);
            let heading_err = wrap_angle(pose.theta_rad - self.door.axis_rad);
            let back = match self.phase {
                Phase::Align => self.back_up_to_turn(along, heading_err),
                Phase::LineUp { at_m } => self.back_out_to_turn(pose, at_m),
                _ => None,
            };
            if let Some(back) = back {
                self.phase = back;
                return true;
            }
        }
        let arcs = turning && !self.turns_refused;
        if arcs {
            self.turns_refused = true;
        }
        arcs
    }

    /// Held passing with the front at the doorway's wall, before the
    /// chair is in it (base_link more than [`PASS_HELD_BACKS_BEFORE_M`]
    /// before the middle), turned off the axis by more than
    /// [`PASS_HELD_TURNED_RAD`], off the middle line by more than the gap
    /// leaves a side, or, in a narrow doorway, with the stop corridor's
    /// far corners within [`PASS_HELD_SLACK_M`] of what the gap leaves a
    /// side: a corner on a jamb. It backs up, squaring to the
    /// axis as it backs, to where there is room to line up again (as
    /// [`Passage::back_up`] does for a chair square to it), while back-ups
    /// are left. Whether it does.
    pub fn held_passing(&mut self, pose: Pose2) -> bool {
        let s = self.settings;
        let (along, left) = self.door.local([pose.x_m, pose.y_m]);
        let heading_err = wrap_angle(pose.theta_rad - self.door.axis_rad);
        let backs = self.phase == Phase::Pass
            && along < -PASS_HELD_BACKS_BEFORE_M
            && (heading_err.abs() > PASS_HELD_TURNED_RAD
                || left.abs() > self.passes_off_m() + 0.01
                || left.abs() + PASS_HELD_REACH_M * heading_err.abs().sin()
                    > (self.door.width_m - s.body_m) / 2.0 - PASS_HELD_SLACK_M)
            && self.backed_up < s.back_ups;
        if backs {
            self.backed_up += 1;
            // a turn held nearer the doorway may fit where it backs to
            self.turns_refused = self.turns_refused_by_person;
            self.phase = self.back_up_to_line_up(along, left);
        }
        backs
    }

    /// The bearing of the line-up point `at_m` along the axis from
    /// `pose`'s heading, rad (positive: to the left).
    fn line_up_bearing(&self, pose: Pose2, at_m: f64) -> f64 {
        let to = self.door.on_axis(at_m);
        wrap_angle((to[1] - pose.y_m).atan2(to[0] - pose.x_m) - pose.theta_rad)
    }

    /// No backing up (the person said it is not clear behind): from a
    /// backing up, on to aligning where the chair is. Whether it was
    /// backing up.
    pub fn refuse_back_up(&mut self) -> bool {
        self.backed_up = self.settings.back_ups;
        let backing = matches!(self.phase, Phase::BackUp { .. } | Phase::BackOut { .. });
        if let Phase::BackOut { at_m, .. } = self.phase {
            // the same turn from here, on arcs if held again
            self.phase = Phase::LineUp { at_m };
        } else if backing {
            self.phase = Phase::Align;
        }
        backing
    }

    /// How far off the middle line the chair may pass: half what the gap
    /// leaves beside the chair's body, never less than the line-up's own
    /// tolerance, m.
    fn passes_off_m(&self) -> f64 {
        ((self.door.width_m - self.settings.body_m) / 2.0).max(self.settings.line_up_off_m)
    }

    /// Off the line by more than the gap allows, where backing up would
    /// make room to line up (front not yet at the wall, backings left):
    /// the phase that backs up to there.
    fn back_up(&mut self, along: f64, left: f64, heading_err: f64) -> Option<Phase> {
        let s = self.settings;
        // (square to the doorway: backing up at a slant would take the
        // chair further off the line)
        (left.abs() > self.passes_off_m() + 0.01
            && along < -s.enter_m
            && heading_err.abs() <= BACK_UP_SQUARE_RAD
            && self.backed_up < s.back_ups)
            .then(|| {
                self.backed_up += 1;
                self.back_up_to_line_up(along, left)
            })
    }

    /// Backing up, squaring, from `along`, `left` to where there is room
    /// to line up, on a line no steeper than 45 degrees
    /// ([`PassageSettings::back_up_m`] along the axis at most).
    fn back_up_to_line_up(&self, along: f64, left: f64) -> Phase {
        let s = self.settings;
        Phase::BackUp {
            to_m: (-s.line_up_nearest_m - s.line_up_ahead_m - left.abs().max(0.05))
                .max(along - s.back_up_m),
            squaring: true,
        }
    }

    /// Near the middle line but too near the doorway to turn on the spot
    /// (a corner's circle would reach a jamb), and turned off the axis by
    /// more than passing steers out: the phase that backs up straight, its
    /// heading held, to where there is room to turn
    /// (`line_up_nearest_m` before the middle, at most `back_up_m` back).
    fn back_up_to_turn(&mut self, along: f64, heading_err: f64) -> Option<Phase> {
        let s = self.settings;
        (along > -s.line_up_nearest_m
            && heading_err.abs() > PASS_STEERS_WITHIN_RAD
            && !self.turns_refused
            && self.backed_up < s.back_ups)
            .then(|| {
                self.backed_up += 1;
                Phase::BackUp {
                    to_m: (-s.line_up_nearest_m - 0.05).max(along - s.back_up_m),
                    squaring: false,
                }
            })
    }

    /// A turn on the spot to face the line-up's point `at_m` held at
    /// `pose`, with the doorway not near (see [`Self::back_up_to_turn`]):
    /// the phase that backs out straight, its heading held, away from
    /// what holds the turn — [`PassageSettings::back_up_m`] at most, less
    /// where backing nears the doorway (base_link no nearer than
    /// `line_up_nearest_m` before the middle, nor than [`LINE_UP_PAST_M`]
    /// before the line-up's point), none where that leaves
    /// less than [`BACK_OUT_MIN_M`]; then the same turn from there. Only
    /// for a turn larger than passing steers out, and while back-ups are
    /// left.
    fn back_out_to_turn(&mut self, pose: Pose2, at_m: f64) -> Option<Phase> {
        let s = self.settings;
        if self.line_up_bearing(pose, at_m).abs() <= PASS_STEERS_WITHIN_RAD
            || self.turns_refused
            || self.backed_up >= s.back_ups
        {
            return None;
        }
        let (along, _) = self.door.local([pose.x_m, pose.y_m]);
        // along the axis per metre backed (positive: towards the doorway)
        let towards = -wrap_angle(pose.theta_rad - self.door.axis_rad).cos();
        // (nor past the line-up's point: lining up from beyond it would
        // square to the axis wherever the chair is off the line)
        let room_m = (-s.line_up_nearest_m).min(at_m - LINE_UP_PAST_M) - along;
        let back_m = if towards > 1e-6 {
            s.back_up_m.min(room_m / towards)
        } else {
            s.back_up_m
        };
        (back_m >= BACK_OUT_MIN_M).then(|| {
            self.backed_up += 1;
            Phase::BackOut {
                from_odom: [pose.x_m, pose.y_m],
                back_m,
                at_m,
            }
        })
    }

    /// The doorway's middle and width from the jambs in `points_odom`
    /// (the lasers' points now), measured about the map's doorway: the
    /// map's cells put the middle within a cell, the lasers to a
    /// centimetre. Where the jambs are not both seen, the last measure
    /// stands. Returns whether they were.
    pub fn observe(&mut self, points_odom: &[[f64; 2]]) -> bool {
        let Some((right, left)) = jamb_faces(&self.found, points_odom) else {
            return false;
        };
        let mid = (left + right) / 2.0;
        let (c, s) = (self.found.axis_rad.cos(), self.found.axis_rad.sin());
        self.door = Doorway {
            center: [
                self.found.center[0] - s * mid,
                self.found.center[1] + c * mid,
            ],
            axis_rad: self.found.axis_rad,
            width_m: left - right,
        };
        true
    }
}

/// The passage's step, phase by phase.
#[path = "doorway_step.rs"]
mod step;

#[cfg(test)]
#[path = "doorway_passage_tests.rs"]
mod passage_tests;
#[cfg(test)]
#[path = "doorway_tests.rs"]
mod tests;
