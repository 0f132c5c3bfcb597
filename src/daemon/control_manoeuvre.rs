//! What the control step does when the way stays held with no detour: a
//! manoeuvre on the chair's map (`navigation::manoeuvre`: turns on the
//! spot where the corners' circle is clear, straight crawls forward or
//! back), followed move by move under the supervisor like any command. It
//! goes to the place beside the object, or, where that is further and out
//! of reach, to the map's way a little on (past a doorway, round the
//! furniture). Held for a while on it, or out of time, it is over, said,
//! and the hold goes on as before (the goal is given up in time).

use super::Control;
use crate::estimation::goal::GoalState;
use crate::msg::{Pose2, Stamp, SupervisorState, VelocityCmd};
use crate::navigation::doorway::Doorway;
use crate::navigation::manoeuvre::{self, Follower, ManoeuvreShape};

/// A manoeuvre held by the supervisor this long without a break is over
/// (long enough for the person to answer a question about the rear).
pub(super) const MANOEUVRE_HELD_FOR: std::time::Duration = std::time::Duration::from_secs(12);
/// A manoeuvre still going after this long is over.
pub(super) const MANOEUVRE_AT_MOST: std::time::Duration = std::time::Duration::from_secs(150);
/// Manoeuvres begun at most, per goal.
pub(super) const MANOEUVRES_PER_GOAL: u32 = 3;
/// The manoeuvre ends within this of the place beside the object, and
/// turned within this of facing it (m, rad): the planner does the rest.
const ENDS_WITHIN_M: f64 = 0.25;
const ENDS_TURNED_WITHIN_RAD: f64 = 0.6;
/// Where the place beside the object is further than this (and the
/// manoeuvre's end), the manoeuvre may end at the map's way this far on
/// instead, turned any way, m.
const WAY_POINT_M: f64 = 1.5;
/// A straight move's speed, m/s.
const MANOEUVRE_MPS: f64 = 0.08;

/// Manoeuvres through a doorway begun at most, per goal, and how long one
/// goes on at most (as long as a passage: the trip to an object is not
/// bounded by the search's time, only by being held, and a manoeuvre
/// moves the chair; scene 140 of `opennav sim --seed 1`, whose object
/// lies a step down beyond a doorway, ran past its trial's end with
/// three of 150 s).
pub(super) const DOORWAY_MANOEUVRES_PER_GOAL: u32 = 2;
pub(super) const DOORWAY_MANOEUVRE_AT_MOST: std::time::Duration =
    std::time::Duration::from_secs(60);
/// A manoeuvre through a doorway ends this far past its middle (base_link:
/// the chair's rear, 0.45 m behind it, out of the wall's half thickness
/// with room to turn on), within [`THROUGH_WITHIN_M`] of it and turned
/// within [`THROUGH_TURNED_WITHIN_RAD`] of the doorway's axis (m, rad).
const THROUGH_PAST_M: f64 = 0.8;
const THROUGH_WITHIN_M: f64 = 0.15;
const THROUGH_TURNED_WITHIN_RAD: f64 = 0.3;

/// A manoeuvre under way.
#[derive(Debug, Clone)]
pub(super) struct Manoeuvre {
    follower: Follower,
    since: Stamp,
    held_since: Option<Stamp>,
    /// Through a doorway (on the way to a place to look from too), not to
    /// the place beside the object.
    through_doorway: bool,
}

impl Control {
    /// Held on the way to the place beside the object with no way round:
    /// a manoeuvre there on the map, or, the place more than
    /// [`WAY_POINT_M`] off and out of reach, to the map's way that far on;
    /// begun if one is found (true). It keeps clear of `seen_now_base` too
    /// (base_link: what the supervisor checks a turn on the spot against
    /// now).
    pub(super) fn begin_manoeuvre(
        &mut self,
        now: Stamp,
        pose: Pose2,
        seen_now_base: &[[f32; 2]],
    ) -> bool {
        if self.manoeuvres_for_goal >= MANOEUVRES_PER_GOAL {
            return false;
        }
        // to the place beside the object, facing it (searching, a held way
        // to a place to look from is given up for another place: a
        // manoeuvre there took the time the search had, measured over the
        // 500 scenes, and where the chair had been held with no way round
        // before, 1 trip gained and 3 lost)
        if !matches!(self.goal.state(), GoalState::Tracking { .. }) {
            return false;
        }
        let Some(a) = self.goal.approach() else {
            return false;
        };
        // the object beside it already: held on, the trip ends here as
        // near as it safely goes (a manoeuvre would take it away)
        if self.goal.beside_at_give_up(pose) {
            return false;
        }
        let place = [a.x_m, a.y_m];
        let shape = ManoeuvreShape::at_a_crawl(&self.supervisor);
        // where the person said it is not clear around: no turn there
        let no_turns = self.no_turns();
        let Some(route) = self.route.as_mut() else {
            return false;
        };
        // the way's point a little on, where the place is further (a
        // doorway, furniture on the way): any heading there
        let from = [pose.x_m, pose.y_m];
        let far = (place[0] - pose.x_m).hypot(place[1] - pose.y_m) > WAY_POINT_M + ENDS_WITHIN_M;
        let on_the_way = route
            .path
            .as_ref()
            .filter(|_| far)
            .and_then(|(p, _, _)| p.carrot(from, WAY_POINT_M));
        let Some(map) = route.map.as_mut() else {
            return false;
        };
        map.update_distances();
        self.manoeuvres_for_goal += 1;
        let seen_now = seen_now_base
            .iter()
            .map(|q| pose.odom_from_base([q[0] as f64, q[1] as f64]))
            .collect::<Vec<_>>();
        let to_place = (place, a.yaw_rad, ENDS_TURNED_WITHIN_RAD);
        let to_way = on_the_way.map(|p| (p, 0.0, std::f64::consts::PI));
        let found = [Some(to_place), to_way]
            .into_iter()
            .flatten()
            .find_map(|(to, yaw, tol)| {
                manoeuvre::plan(
                    map,
                    &seen_now,
                    &no_turns,
                    pose,
                    to,
                    yaw,
                    ENDS_WITHIN_M,
                    tol,
                    &shape,
                )
                .map(|moves| (to, moves))
            });
        let Some((to, moves)) = found else {
            tracing::info!(
                ?pose,
                ?place,
                ?on_the_way,
                "manoeuvre: none found on the map"
            );
            return false;
        };
        tracing::info!(?pose, ?place, ?to, ?moves, "manoeuvre: begun");
        self.start_manoeuvre(
            now,
            moves,
            false,
            "Something is in my way. I will work my way round it, turning on the spot and \
             driving straight; say stop to stay here.",
        );
        true
    }

    /// Where the person said it is not clear around: no turn on the spot
    /// there (odom centre, radius m).
    fn no_turns(&self) -> Vec<([f64; 2], f64)> {
        self.turn_refused_at
            .map(|p| ([p.x_m, p.y_m], super::REFUSED_TURN_WITHIN_M))
            .into_iter()
            .collect()
    }

    /// The manoeuvre of `moves` under way from `now` (through a doorway,
    /// or not), counted and said.
    fn start_manoeuvre(
        &mut self,
        now: Stamp,
        moves: Vec<manoeuvre::Move>,
        through_doorway: bool,
        said: &str,
    ) {
        self.manoeuvres += 1;
        if through_doorway {
            self.doorway_manoeuvres += 1;
        }
        self.manoeuvre = Some(Manoeuvre {
            follower: Follower::new(moves),
            since: now,
            held_since: None,
            through_doorway,
        });
        self.say(said.to_string());
    }

    /// The passage through `door` was given up (held in it, or out of
    /// time): a manoeuvre on the map through it, to
    /// [`THROUGH_PAST_M`] past its middle facing along its axis, as a
    /// person would work a chair through a tight doorway by turns on the
    /// spot and straight crawls, forward and back. Begun if one is found
    /// (true); else the planner's way is followed again, as before. It
    /// keeps clear of `seen_now_base` too (base_link).
    pub(super) fn begin_doorway_manoeuvre(
        &mut self,
        now: Stamp,
        pose: Pose2,
        door: Doorway,
        seen_now_base: &[[f32; 2]],
    ) -> bool {
        if self.doorway_manoeuvres_for_goal >= DOORWAY_MANOEUVRES_PER_GOAL || self.manoeuvring() {
            return false;
        }
        let shape = ManoeuvreShape::at_a_crawl(&self.supervisor);
        let no_turns = self.no_turns();
        let Some(map) = self.route.as_mut().and_then(|r| r.map.as_mut()) else {
            return false;
        };
        map.update_distances();
        self.doorway_manoeuvres_for_goal += 1;
        let seen_now = seen_now_base
            .iter()
            .map(|q| pose.odom_from_base([q[0] as f64, q[1] as f64]))
            .collect::<Vec<_>>();
        let to = door.on_axis(THROUGH_PAST_M);
        let Some(moves) = manoeuvre::plan(
            map,
            &seen_now,
            &no_turns,
            pose,
            to,
            door.axis_rad,
            THROUGH_WITHIN_M,
            THROUGH_TURNED_WITHIN_RAD,
            &shape,
        ) else {
            tracing::info!(?pose, center = ?door.center, width_m = door.width_m, "manoeuvre: none found through the doorway");
            return false;
        };
        tracing::info!(?pose, center = ?door.center, width_m = door.width_m, ?to, ?moves, "manoeuvre: through the doorway, begun");
        self.start_manoeuvre(
            now,
            moves,
            true,
            "The doorway is tight. I will work my way through it, turning on the spot and \
             driving straight; say stop to stay here.",
        );
        true
    }

    /// The manoeuvre's command this step (None: there is none, or it is
    /// over). `state`: the supervisor's state after the last step.
    pub(super) fn manoeuvre_step(
        &mut self,
        now: Stamp,
        pose: Pose2,
        state: SupervisorState,
    ) -> Option<VelocityCmd> {
        if matches!(
            self.goal.state(),
            GoalState::None | GoalState::Reached { .. }
        ) {
            self.manoeuvres_for_goal = 0;
            self.doorway_manoeuvres_for_goal = 0;
        }
        // through a doorway: on the way to the object or to a place to
        // look from; else only to the object
        let through_doorway = self.manoeuvre.as_ref().is_some_and(|m| m.through_doorway);
        let going = match self.goal.state() {
            GoalState::Tracking { .. } => true,
            GoalState::Searching { .. } | GoalState::Exploring { .. } => through_doorway,
            _ => false,
        };
        if !going {
            if self.manoeuvre.take().is_some() {
                tracing::info!("manoeuvre: over, no place to go to");
            }
            return None;
        }
        let turn_radps = self.supervisor.crawl_turn_radps();
        let m = self.manoeuvre.as_mut()?;
        let held = state != SupervisorState::Navigating;
        if !held {
            m.held_since = None;
        }
        let held_for = m.held_since.get_or_insert(now).age_at(now);
        let over = if held && held_for >= MANOEUVRE_HELD_FOR {
            Some("held")
        } else if m.since.age_at(now)
            >= if m.through_doorway {
                DOORWAY_MANOEUVRE_AT_MOST
            } else {
                MANOEUVRE_AT_MOST
            }
        {
            Some("out of time")
        } else {
            None
        };
        let cmd = match over {
            None => m.follower.command(pose, MANOEUVRE_MPS, turn_radps),
            Some(_) => None,
        };
        if cmd.is_none() {
            let left = m.follower.left().len();
            let through_doorway = m.through_doorway;
            self.manoeuvre = None;
            match over {
                Some(why) => {
                    self.manoeuvres_held += 1;
                    tracing::warn!(?pose, why, left, through_doorway, "manoeuvre: given up");
                    self.say(if through_doorway {
                        "I could not work my way through the doorway.".to_string()
                    } else {
                        "I could not work my way round it.".to_string()
                    });
                }
                None => tracing::info!(?pose, "manoeuvre: done"),
            }
        }
        cmd
    }

    /// The person said no to a manoeuvre's move (`why`): it is over.
    pub(super) fn end_manoeuvre(&mut self, why: &str) {
        if let Some(m) = self.manoeuvre.take() {
            self.manoeuvres_held += 1;
            tracing::warn!(why, left = m.follower.left().len(), "manoeuvre: given up");
        }
    }

    /// A manoeuvre is under way.
    pub(super) fn manoeuvring(&self) -> bool {
        self.manoeuvre.is_some()
    }

    /// The moves left of the manoeuvre under way.
    #[cfg(test)]
    pub(super) fn manoeuvre_left(&self) -> Option<&[manoeuvre::Move]> {
        self.manoeuvre.as_ref().map(|m| m.follower.left())
    }
}
