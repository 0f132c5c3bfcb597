//! The goal (pure): the track matching the user's word, its approach pose,
//! re-planned as the track updates; a goal that disappears from view is
//! held (the chair stands still and keeps looking) for a configured time,
//! then dropped — the chair stops and says so.

use std::time::Duration;

use serde::Serialize;

use super::tracker::{approach_pose, ApproachPose, Track, Tracker};
use crate::msg::{hypot_cmp, wrap_angle, Pose2, Stamp, VelocityCmd};
use crate::perception::boxes::OrientedBox;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GoalSettings {
    /// Gap between the chair's front edge and the object's box at the
    /// approach pose, m (0.6).
    pub standoff_m: f64,
    /// From base_link to the chair's front edge, m (safety.front_offset_m).
    pub front_offset_m: f64,
    /// The approach pose keeps this far from every obstacle point, m.
    pub clearance_m: f64,
    /// The goal's track unseen for longer than this (or dropped by the
    /// tracker, which drops tracks missed where they should be visible):
    /// out of view.
    pub unseen_after: Duration,
    /// Held this long out of view, then dropped.
    pub hold_for: Duration,
    /// Within this of the approach pose: reached, m.
    pub reached_within_m: f64,
    /// While searching, the chair turns on the spot at this rate so the
    /// camera sweeps the room, rad/s (until nothing around is left to look
    /// at, [`GoalKeeper::left_to_see`]; one full turn at most).
    pub search_turn_radps: f64,
    /// Held on the way to the object this long without a break (nothing
    /// it tries gets it nearer): that object is given up, and another of
    /// the word looked for or the chair stops ([`GoalKeeper::give_up`]).
    pub give_up_held_after: Duration,
    /// A search (turns on the spot and the places between) ends "not
    /// found" after this.
    pub search_at_most: Duration,
    /// A search that keeps the chair in one place this long (turning or
    /// not, held there) ends: the chair stops and says it is held.
    pub search_held_for: Duration,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "state", rename_all = "snake_case")]
pub enum GoalState {
    /// No word given.
    None,
    /// A word given, no confirmed track of it yet.
    Searching {
        label: String,
    },
    /// Driving to the approach pose of track `track`.
    Tracking {
        label: String,
        track: u64,
        approach: ApproachPose,
    },
    /// The track is out of view: standing still, looking, since `since`.
    Holding {
        label: String,
        track: u64,
        since: Stamp,
    },
    Reached {
        label: String,
        track: u64,
    },
    /// No word: turning once on the spot to see what is around.
    LookingAround,
    /// Not seen after a turn: driving to the edge of what the chair has
    /// seen (`target`, odom), to look again there.
    Exploring {
        label: String,
        target: [f64; 2],
        since: Stamp,
    },
}

impl GoalState {
    /// The goal's word, if there is a goal.
    pub fn label(&self) -> Option<&str> {
        match self {
            GoalState::None | GoalState::LookingAround => None,
            GoalState::Searching { label }
            | GoalState::Tracking { label, .. }
            | GoalState::Holding { label, .. }
            | GoalState::Reached { label, .. }
            | GoalState::Exploring { label, .. } => Some(label),
        }
    }

    /// The phase in a word (None without a goal).
    pub fn phase(&self) -> Option<&'static str> {
        match self {
            GoalState::None => None,
            GoalState::Searching { .. } => Some("searching"),
            GoalState::Tracking { .. } => Some("tracking"),
            GoalState::Holding { .. } => Some("holding"),
            GoalState::Reached { .. } => Some("reached"),
            GoalState::LookingAround => Some("looking around"),
            GoalState::Exploring { .. } => Some("exploring"),
        }
    }
}

/// What the user hears (and the log records): the goal's events and their
/// sentences.
#[path = "goal_events.rs"]
mod events;
pub use events::GoalEvent;

/// A track's box as the goal keeper last saw it (odom).
#[derive(Debug, Clone, Copy)]
struct SeenBox {
    center_m: [f64; 3],
    size_m: [f64; 3],
    footprint: OrientedBox,
}

impl SeenBox {
    fn of(t: &Track) -> SeenBox {
        SeenBox {
            center_m: t.center_m,
            size_m: t.size_m,
            footprint: t.footprint,
        }
    }

    /// From a point on the ground to the object's outline, m: its ground
    /// outline (oriented) where the track's centre lies in it, as
    /// [`approach_pose`] measures the place beside it; else its upright
    /// box, larger than a turned object (most at the corners).
    fn distance_m(&self, p: [f64; 2]) -> f64 {
        crate::estimation::tracker::outline(self.center_m, self.size_m, &self.footprint)
            .ground_distance_m(p)
    }
}

#[derive(Debug, Clone)]
pub struct GoalKeeper {
    pub settings: GoalSettings,
    state: GoalState,
    /// Where the goal's object was last seen (odom), to pick up its track
    /// again when the tracker re-identifies it.
    last_center: Option<[f64; 3]>,
    /// The goal's object's box when last seen.
    last_box: Option<SeenBox>,
    /// The goal's track's confidence at the last update (for
    /// [`GoalKeeper::arrive_near`]).
    last_confidence: f64,
    /// The search turn: the heading last seen and how far the chair has
    /// turned since the search began, rad.
    search_heading: Option<f64>,
    search_turned_rad: f64,
    /// How far the search turn had gone when the map first had nothing
    /// left to look at around the chair, rad (None: something is left).
    nothing_left_at_rad: Option<f64>,
    /// The search turn's way: 1 counter-clockwise, −1 clockwise.
    search_dir: f64,
    /// After a turn without the word, search further (the daemon's map
    /// gives the places, [`GoalKeeper::explore`]); false: "not found"
    /// after one turn.
    pub explores: bool,
    /// Where the search has been (odom): the start and each place reached.
    pub searched: Vec<[f64; 2]>,
    /// When the word was given (the search's time limit runs from it).
    search_since: Option<Stamp>,
    /// When the word was given (the first update after it), never reset by
    /// a search begun again: another object is looked for only early
    /// enough in the word's time.
    word_since: Option<Stamp>,
    /// The track "no free place beside it" was said of.
    said_no_approach: Option<u64>,
    /// The place "looking further" was last said of (odom): a search held
    /// in one place that picks the same place again goes there without
    /// saying it again.
    said_further_to: Option<[f64; 2]>,
    /// Searches begun again for this word after losing sight of it.
    searched_again: u32,
    /// Places beside the object the chair was held on its way to (odom):
    /// not chosen again for this word.
    refused: Vec<[f64; 2]>,
    /// A place was just refused: the next update looks for another.
    refusing: bool,
    /// Objects of the word given up, held on the way to them (their
    /// centres, odom): not the goal again for this word.
    given_up: Vec<[f64; 2]>,
}

/// Where no side fits on the map, the place moves only to a side within
/// this bearing from the object's centre of the place it had, rad (the
/// sides tried are 15° apart).
const SAME_SIDE_RAD: f64 = 0.4;
/// A place beside the object this near one refused is refused too, m
/// (the places tried are 15° apart about the object).
const REFUSED_WITHIN_M: f64 = 0.6;
/// At the place beside the object, it must have been seen this recently
/// (where the camera can see it) for the trip to end there: a false
/// detection's track, not seen again, is held, then looked for again.
pub const SEEN_ON_ARRIVAL: Duration = Duration::from_millis(1500);
/// The goal's track must hold this confidence for an arrival where the
/// camera cannot see the object, and for any arrival as near as the
/// chair safely goes ([`GoalKeeper::arrive_near`], which has no view to
/// ask). A true object's stays near 1 with a miss now and then; each
/// view that should have shown it and did not takes
/// [`crate::estimation::tracker::TrackerParams::miss_decay`] off.
pub const TRUSTED_OUT_OF_SIGHT: f64 = 0.5;
/// Held facing the object this near the place's distance from its box:
/// arrived, as near as it goes, m.
pub const AT_STANDOFF_WITHIN_M: f64 = 0.2;
/// Held until the goal would be given up, this near the place's distance
/// from the object's box, whatever the heading: the object is beside the
/// chair (within 0.35 m of where its front would stop), and the trip ends
/// there rather than with "I cannot get to it", m.
pub const BESIDE_AT_GIVE_UP_M: f64 = 0.35;
/// At most this many places refused a word (the object's other sides).
pub const REFUSED_AT_MOST: usize = 3;

/// Held on the way to an object of the word for good, the chair looks for
/// another one (a "chair" is any chair), at most this many times a word.
pub const GIVEN_UP_AT_MOST: usize = 2;
/// A track this near an object given up is that object, m (chairs about a
/// table stand further apart).
const GIVEN_UP_WITHIN_M: f64 = 0.5;
/// Another object is looked for only while this much of the word's search
/// time is left (a search turn takes about 21 s, a doorway up to a
/// minute).
const ANOTHER_WITH_SEARCH_LEFT: Duration = Duration::from_secs(60);

/// A word's object lost from sight (held out of view for
/// [`GoalSettings::hold_for`]) is looked for again this many times before
/// the goal is dropped: a false detection the chair set off towards, or the
/// object hidden as the chair moved, need not end the trip.
pub const SEARCH_AGAIN_AT_MOST: u32 = 2;

/// A search turn goes on this far after the map first has nothing left to
/// look at around the chair, rad: what came into view last is seen in
/// enough frames to be confirmed (three at the simulated camera's 2 Hz and
/// the 0.3 rad/s turn).
pub const LOOK_SETTLE_RAD: f64 = 0.5;

/// At most this many places searched after the first turn.
pub const MAX_EXPLORATIONS: usize = 6;
/// A place to search is reached this close, m.
const EXPLORED_WITHIN_M: f64 = 0.3;
/// A place to look from within this of the one "looking further" was
/// last said of is the same place: not said again (m).
const SAME_PLACE_TO_LOOK_FROM_M: f64 = 0.3;
/// Driving to a place to search gives up after this long (and searches
/// where it is).
const EXPLORE_FOR: Duration = Duration::from_secs(40);

/// A track of the same word this close to where the goal was last seen is
/// the goal (the tracker split or renumbered it), m.
const REACQUIRE_M: f64 = 0.6;
/// Another object of the word, seen now, whose place beside it is this
/// much nearer than the goal's (straight from the chair), becomes the
/// goal: the first one seen is often not the nearest, m. Two about as near
/// never take turns.
pub const NEARER_BY_M: f64 = 1.0;

impl GoalKeeper {
    pub fn new(settings: GoalSettings) -> GoalKeeper {
        GoalKeeper {
            settings,
            state: GoalState::None,
            last_center: None,
            last_box: None,
            last_confidence: 0.0,
            search_heading: None,
            search_turned_rad: 0.0,
            nothing_left_at_rad: None,
            search_dir: 1.0,
            explores: false,
            searched: Vec::new(),
            search_since: None,
            word_since: None,
            said_no_approach: None,
            said_further_to: None,
            searched_again: 0,
            refused: Vec::new(),
            refusing: false,
            given_up: Vec::new(),
        }
    }

    /// A search turn begins afresh: nothing turned yet, counter-clockwise.
    fn new_turn(&mut self) {
        self.search_heading = None;
        self.search_turned_rad = 0.0;
        self.nothing_left_at_rad = None;
        self.search_dir = 1.0;
    }

    pub fn state(&self) -> &GoalState {
        &self.state
    }

    /// The user said a word.
    pub fn set_prompt(&mut self, label: &str) {
        self.new_turn();
        self.searched.clear();
        self.search_since = None;
        self.word_since = None;
        self.said_no_approach = None;
        self.said_further_to = None;
        self.searched_again = 0;
        self.refused.clear();
        self.refusing = false;
        self.given_up.clear();
        self.state = GoalState::Searching {
            label: label.trim().to_lowercase(),
        };
    }

    /// Turn once on the spot (the search turn, with no word) and then say
    /// what is around.
    pub fn look_around(&mut self) {
        self.new_turn();
        self.state = GoalState::LookingAround;
    }

    pub fn clear(&mut self) {
        self.state = GoalState::None;
    }

    /// Whether a turn found nothing and the keeper waits for a place to
    /// search next ([`GoalKeeper::explore`]).
    pub fn wants_place(&self) -> bool {
        self.explores && matches!(self.state, GoalState::Searching { .. }) && self.turned_enough()
    }

    /// The map's word on the search turn: `nothing_left` when, outside
    /// the camera's view, nothing around the chair is left to look at; the
    /// turn then ends [`LOOK_SETTLE_RAD`] later (a whole turn at most), and
    /// something left again starts that over. `clockwise_shorter`: the
    /// turn that brings what is left into view is shorter clockwise — a
    /// turn not yet begun goes that way.
    pub fn left_to_see(&mut self, nothing_left: bool, clockwise_shorter: bool) {
        if !matches!(self.state, GoalState::Searching { .. }) {
            self.nothing_left_at_rad = None;
            return;
        }
        if self.search_turned_rad == 0.0 {
            self.search_dir = if clockwise_shorter { -1.0 } else { 1.0 };
        }
        if !nothing_left {
            self.nothing_left_at_rad = None;
            return;
        }
        self.nothing_left_at_rad
            .get_or_insert(self.search_turned_rad);
    }

    /// The search turn has seen what it can from here: a whole turn, or
    /// [`LOOK_SETTLE_RAD`] beyond where nothing was left to look at.
    fn turned_enough(&self) -> bool {
        self.search_turned_rad >= std::f64::consts::TAU
            || self
                .nothing_left_at_rad
                .is_some_and(|at| self.search_turned_rad >= at + LOOK_SETTLE_RAD)
    }

    /// The search turn cannot go on (something in its circle): what it
    /// has seen is all it will see from here, as after a whole turn.
    pub fn turn_done(&mut self) {
        if matches!(self.state, GoalState::Searching { .. }) {
            self.search_turned_rad = self.search_turned_rad.max(std::f64::consts::TAU);
        }
    }

    /// The chair is held by something on the way (the caller knows how
    /// long): within `within_m` of the place beside the object — or facing
    /// the object (within 90° of the heading) at the place's distance from
    /// its box, give or take [`AT_STANDOFF_WITHIN_M`] (the box as seen: a
    /// box seen large ends a trip short), on another side of it —, the trip
    /// ends there, as near as it safely goes. None otherwise (not
    /// tracking, too far, or the track's confidence below
    /// [`TRUSTED_OUT_OF_SIGHT`]: the caller backs off and tries again).
    pub fn arrive_near(&mut self, chair: Pose2, within_m: f64) -> Option<GoalEvent> {
        let GoalState::Tracking { approach, .. } = &self.state else {
            return None;
        };
        let off_m = (approach.x_m - chair.x_m).hypot(approach.y_m - chair.y_m);
        let at_standoff = self.last_box.is_some_and(|b| {
            let c = b.center_m;
            let bearing = (c[1] - chair.y_m).atan2(c[0] - chair.x_m);
            self.off_standoff_m(chair)
                .is_some_and(|d| d <= within_m.min(AT_STANDOFF_WITHIN_M))
                && wrap_angle(bearing - chair.theta_rad).abs() <= std::f64::consts::FRAC_PI_2
        });
        // (a false detection's track, missed in most views that could
        // have shown it, is not arrived at)
        if (off_m > within_m && !at_standoff) || self.last_confidence < TRUSTED_OUT_OF_SIGHT {
            return None;
        }
        self.end_here(chair)
    }

    /// How far the chair at `chair` is from the place's distance to the
    /// tracked object's box (either way), m; None without a box.
    fn off_standoff_m(&self, chair: Pose2) -> Option<f64> {
        let standoff = self.settings.standoff_m + self.settings.front_offset_m;
        self.last_box
            .map(|b| (b.distance_m([chair.x_m, chair.y_m]) - standoff).abs())
    }

    /// The trip driving to a tracked object ends with the chair at
    /// `chair`, as near as it safely goes; None when not tracking.
    fn end_here(&mut self, chair: Pose2) -> Option<GoalEvent> {
        let GoalState::Tracking {
            label,
            track,
            approach,
        } = &self.state
        else {
            return None;
        };
        let off_m = (approach.x_m - chair.x_m).hypot(approach.y_m - chair.y_m);
        let label = label.clone();
        self.state = GoalState::Reached {
            label: label.clone(),
            track: *track,
        };
        Some(GoalEvent::ReachedNear { label, off_m })
    }

    /// Held on the way to the place beside the object (the caller times
    /// it): that place is not chosen again for this word, and the next
    /// update looks for another side ([`GoalEvent::OtherSide`]; where
    /// there is none, the place stays). False when not driving to one, or
    /// [`REFUSED_AT_MOST`] places were refused already.
    pub fn refuse_approach(&mut self) -> bool {
        let GoalState::Tracking { approach, .. } = &self.state else {
            return false;
        };
        if self.refusing || self.refused.len() >= REFUSED_AT_MOST {
            return false;
        }
        self.refused.push([approach.x_m, approach.y_m]);
        self.refusing = true;
        true
    }

    /// Held on the way for `held_s` (the caller times it against
    /// [`GoalSettings::give_up_held_after`]) at `now`, the chair at
    /// `chair`: a goal being driven to is dropped — unless the chair
    /// stands at the place's distance from the object's box, give or take
    /// [`BESIDE_AT_GIVE_UP_M`], on whatever side and however turned (the
    /// object is beside it, and the way on to face it stayed held): then
    /// the trip ends there, as near as it safely goes. Dropped, another
    /// object of the word is searched for ([`GoalEvent::LookingForAnother`];
    /// never that one again) while [`GIVEN_UP_AT_MOST`] were not given up
    /// yet and [`ANOTHER_WITH_SEARCH_LEFT`] of the word's search time is
    /// left; else the chair stops ([`GoalEvent::GaveUp`]). None in any
    /// other state.
    pub fn give_up(&mut self, now: Stamp, held_s: f64, chair: Pose2) -> Option<GoalEvent> {
        let GoalState::Tracking { label, .. } = &self.state else {
            return None;
        };
        let label = label.clone();
        if self.beside_at_give_up(chair) {
            return self.end_here(chair);
        }
        let search_left = self.word_since.map_or(self.settings.search_at_most, |s| {
            self.settings.search_at_most.saturating_sub(s.age_at(now))
        });
        if let Some(c) = self.last_center.filter(|_| {
            self.given_up.len() < GIVEN_UP_AT_MOST && search_left >= ANOTHER_WITH_SEARCH_LEFT
        }) {
            self.given_up.push([c[0], c[1]]);
            self.refused.clear();
            self.refusing = false;
            self.said_no_approach = None;
            self.searched.clear();
            self.new_turn();
            self.state = GoalState::Searching {
                label: label.clone(),
            };
            return Some(GoalEvent::LookingForAnother { label, held_s });
        }
        self.state = GoalState::None;
        Some(GoalEvent::GaveUp { label, held_s })
    }

    /// Whether an object centred at `center_m` (odom) was given up for this
    /// word ([`GoalKeeper::give_up`]).
    #[cfg(test)]
    pub fn is_given_up(&self, center_m: [f64; 3]) -> bool {
        given_up_at(&self.given_up, center_m)
    }

    /// A search (turning to look, or driving to a place to look from)
    /// that kept the chair in one place for `held_s` (the caller times it:
    /// held there, every place to look from lies the way that is held):
    /// given up, the chair stops. None in any other state.
    pub fn give_up_search(&mut self, held_s: f64) -> Option<GoalEvent> {
        let (GoalState::Searching { label } | GoalState::Exploring { label, .. }) = &self.state
        else {
            return None;
        };
        let label = label.clone();
        self.state = GoalState::None;
        Some(GoalEvent::SearchHeld { label, held_s })
    }

    /// Whether a trip held for good with the chair at `chair` would end
    /// there, as near as it safely goes ([`GoalKeeper::give_up`]: the
    /// object beside it, at the place's distance from its box).
    pub fn beside_at_give_up(&self, chair: Pose2) -> bool {
        self.last_confidence >= TRUSTED_OUT_OF_SIGHT
            && self
                .off_standoff_m(chair)
                .is_some_and(|d| d <= BESIDE_AT_GIVE_UP_M)
    }

    /// The next place to search (odom), or None: no place is left, and the
    /// word was not found.
    pub fn explore(&mut self, now: Stamp, place: Option<[f64; 2]>) -> Option<GoalEvent> {
        let GoalState::Searching { label } = self.state.clone() else {
            return None;
        };
        match place {
            Some(target) if self.searched.len() <= MAX_EXPLORATIONS => {
                self.state = GoalState::Exploring {
                    label: label.clone(),
                    target,
                    since: now,
                };
                let again = self.said_further_to.is_some_and(|p| {
                    hypot_cmp(
                        p[0] - target[0],
                        p[1] - target[1],
                        SAME_PLACE_TO_LOOK_FROM_M,
                    )
                    .is_some_and(std::cmp::Ordering::is_le)
                });
                self.said_further_to = Some(target);
                (!again).then_some(GoalEvent::LookingFurther { label })
            }
            _ => {
                self.state = GoalState::None;
                Some(word_not_found(&self.given_up, label))
            }
        }
    }

    /// Where to drive to search (only while exploring).
    pub fn explore_target(&self) -> Option<[f64; 2]> {
        match &self.state {
            GoalState::Exploring { target, .. } => Some(*target),
            _ => None,
        }
    }

    /// While searching: turn on the spot (counter-clockwise, unless what is
    /// left to see is nearer clockwise: [`GoalKeeper::left_to_see`]).
    pub fn search_command(&self) -> Option<VelocityCmd> {
        matches!(
            self.state,
            GoalState::Searching { .. } | GoalState::LookingAround
        )
        .then_some(VelocityCmd {
            v_mps: 0.0,
            omega_radps: self.search_dir * self.settings.search_turn_radps,
        })
    }

    /// The words perception should look for now (the goal's, while it is
    /// being searched for, driven to or held).
    pub fn wanted(&self) -> Vec<String> {
        match &self.state {
            GoalState::Searching { label }
            | GoalState::Tracking { label, .. }
            | GoalState::Holding { label, .. }
            | GoalState::Exploring { label, .. } => vec![label.clone()],
            GoalState::None | GoalState::Reached { .. } | GoalState::LookingAround => Vec::new(),
        }
    }

    /// Where to drive now (only while tracking).
    pub fn approach(&self) -> Option<ApproachPose> {
        match &self.state {
            GoalState::Tracking { approach, .. } => Some(*approach),
            _ => None,
        }
    }
}

#[path = "goal_update.rs"]
mod update;

#[cfg(test)]
#[path = "goal_place_tests.rs"]
mod place_tests;
#[cfg(test)]
#[path = "goal_tests.rs"]
mod tests;

/// The word not found: after an object of it was given up (`given_up`
/// non-empty), no other one found.
fn word_not_found(given_up: &[[f64; 2]], label: String) -> GoalEvent {
    if given_up.is_empty() {
        GoalEvent::NotFound { label }
    } else {
        GoalEvent::NoOtherFound { label }
    }
}

/// Whether `center_m` lies within [`GIVEN_UP_WITHIN_M`] of one of `given_up`.
fn given_up_at(given_up: &[[f64; 2]], center_m: [f64; 3]) -> bool {
    given_up
        .iter()
        .any(|g| (center_m[0] - g[0]).hypot(center_m[1] - g[1]) <= GIVEN_UP_WITHIN_M)
}
