//! The control step's search for the word: a search turn that ends once
//! nothing around is left to look at, and where the search goes on — a
//! place with room to turn when the turn is held, the nearest frontier
//! when it is done.

use super::{Control, CLOCKWISE_SHORTER_BY_RAD, TURN_HELD_FOR};
use crate::daemon::route::{EXPLORE_APART_M, EXPLORE_MIN_M, EXPLORE_ROOM_M, ROOM_TO_TURN_MIN_M};
use crate::estimation::goal::{GoalEvent, GoalState};
use crate::estimation::view::CameraView;
use crate::msg::{Pose2, Stamp, SupervisorState};

/// A search turn held: the place to turn elsewhere is sought first within
/// this of the chair's heading, rad.
const TURN_ELSEWHERE_AHEAD_RAD: f64 = std::f64::consts::FRAC_PI_3;

/// Searching, the chair staying within this of one place (turning or not)
/// for `goal.search_held_s` is held there for good, m: it is getting
/// nowhere (a back-off, a doorway tried again, move it further).
pub const SEARCH_HELD_WITHIN_M: f64 = 0.05;

impl Control {
    /// After the goal's update (`event`, its event): a search that kept
    /// the chair in one place ([`SEARCH_HELD_WITHIN_M`]) for
    /// `goal.search_held_s` ends there, held (every place to look from
    /// lies the way that is held); the event to say, else `event`.
    pub(super) fn end_search_if_held(
        &mut self,
        now: Stamp,
        pose: Pose2,
        event: Option<GoalEvent>,
    ) -> Option<GoalEvent> {
        let searching = matches!(
            self.goal.state(),
            GoalState::Searching { .. } | GoalState::Exploring { .. }
        );
        let held_for = self.goal.settings.search_held_for;
        let held = self.search_in_place.update(now, pose, searching, held_for);
        match event {
            None if held => {
                tracing::warn!(
                    ?pose,
                    "searching: held in one place too long; the search ends here"
                );
                self.goal.give_up_search(held_for.as_secs_f64())
            }
            e => e,
        }
    }

    /// Before the goal's update: what is left for the camera to look at
    /// around the chair, while searching (the turn's end and its way).
    pub(super) fn tell_goal_what_is_left(&mut self, pose: Pose2, view: Option<&CameraView>) {
        // a search turn ends once nothing around is left to look at
        if let (Some(r), Some(v), GoalState::Searching { .. }) =
            (self.route.as_ref(), view, self.goal.state())
        {
            if let Some(left) = r.left_to_see(pose, v) {
                self.goal.left_to_see(
                    left.nothing(),
                    left.cw_rad + CLOCKWISE_SHORTER_BY_RAD < left.ccw_rad,
                );
            }
        }
    }

    /// After the goal's update (`event`, its event): a search turn held
    /// by something in its circle, or one that is done, goes on elsewhere.
    pub(super) fn search_further(
        &mut self,
        now: Stamp,
        pose: Pose2,
        event: Option<GoalEvent>,
    ) -> Option<GoalEvent> {
        // a search turn held by something in the turn's circle: as good as
        // done from here; the keeper looks further, somewhere with room
        // (or one the person said no to here)
        use crate::msg::StopReason::{FloorUnseen, Obstacle, RearUnseen};
        let state = self.supervisor.state();
        let turn_held = matches!(self.goal.state(), GoalState::Searching { .. })
            && (state == SupervisorState::Stopped(Obstacle)
                || (matches!(state, SupervisorState::Stopped(RearUnseen | FloorUnseen))
                    && self.turn_refused_here(&pose)));
        if !turn_held {
            self.turn_held_since = None;
        }
        let held_long = turn_held
            && event.is_none()
            && self.turn_held_since.get_or_insert(now).age_at(now) >= TURN_HELD_FOR;
        match event {
            None if held_long => {
                self.turn_held_since = None;
                let from = [pose.x_m, pose.y_m];
                let place = self.route.as_mut().and_then(|r| {
                    // ahead of the chair where there is such a place (one
                    // behind it needs the turn that was just held), with
                    // room to spare where it can (it stops within 0.3 m
                    // of the place)
                    let map = r.map.as_mut()?;
                    let ahead = Some((pose.theta_rad, TURN_ELSEWHERE_AHEAD_RAD));
                    [ahead, None].into_iter().find_map(|cone| {
                        [EXPLORE_ROOM_M + 0.15, EXPLORE_ROOM_M]
                            .into_iter()
                            .find_map(|room_m| {
                                map.room_to_turn_within(from, ROOM_TO_TURN_MIN_M, room_m, cone)
                            })
                    })
                });
                tracing::info!(
                    ?pose,
                    ?place,
                    "search turn held by an obstacle: turning elsewhere"
                );
                self.goal.turn_done();
                self.goal.explore(now, place)
            }
            None if self.goal.wants_place() => {
                let from = [pose.x_m, pose.y_m];
                let place = self.route.as_mut().and_then(|r| {
                    let map = r.map.as_mut()?;
                    map.frontier(
                        from,
                        EXPLORE_MIN_M,
                        EXPLORE_ROOM_M,
                        &self.goal.searched,
                        EXPLORE_APART_M,
                    )
                });
                self.goal.explore(now, place)
            }
            e => e,
        }
    }
}
