//! The control step's plan, in its parts: what the chair must not enter,
//! the goal keeper's step with what the control step adds to it (the
//! search going further, ended where held, an arrival as near as it
//! safely goes), and the drive to the place beside the object or to a
//! place to search (a doorway's own steering, the map's way, the MPC).

use super::{Control, ARRIVE_HELD_AFTER, NEAR_ENOUGH_M, STAND_STILL_FOR};
use crate::daemon::route::{CRAWL_MPS, TURN_FIRST_RAD, TURN_FIRST_RADPS};
use crate::estimation::goal::{GoalEvent, GoalState};
use crate::estimation::tracker::Tracker;
use crate::msg::{Obstacles, Pose2, Stamp, Stamped, SupervisorState, VelocityCmd};
use crate::navigation::doorway::PassageCmd;
use crate::navigation::mpc::UnicycleState;

/// What the chair must not enter, in base_link.
pub(super) struct Keep {
    /// Everything: the lasers' points, the camera's obstacles and its
    /// drop-offs (those that may lie out of its view too).
    pub(super) clear_of: Obstacles,
    /// What a turn on the spot must keep clear of: as `clear_of` (less
    /// the drop-offs that may lie out of the camera's view where the
    /// person said it is clear all around), and the rear the lasers saw
    /// before, which the supervisor checks a turn against too.
    pub(super) turn_clear_of: Obstacles,
}

/// What the goal's step made.
pub(super) struct GoalStep {
    /// The goal keeper's event (said already).
    pub(super) event: Option<GoalEvent>,
    /// Driving to an object after the goal keeper's update (before an
    /// arrival as near as it goes).
    pub(super) tracking: bool,
    /// Driving to an object, the chair has stood still for
    /// [`STAND_STILL_FOR`].
    pub(super) stood_still: bool,
}

/// Where the step drives, and how it gets its command there.
pub(super) struct Drive<'a> {
    pub(super) now: Stamp,
    pub(super) pose: Pose2,
    pub(super) v_mps: f64,
    pub(super) omega_radps: f64,
    /// The place (odom) and how near it is near enough, m.
    pub(super) to: [f64; 2],
    pub(super) within_m: f64,
    pub(super) state: SupervisorState,
    pub(super) lasers_base: &'a [[f32; 2]],
}

impl Control {
    /// What the chair must not enter now (`lasers`, `camera`, the rear the
    /// lasers saw before), seen from `pose`.
    pub(super) fn keep_clear_of(
        &self,
        now: Stamp,
        pose: &Pose2,
        lasers: &Stamped<Obstacles>,
        camera: Option<&Stamped<Obstacles>>,
        rear_points_base: &[[f32; 2]],
    ) -> Keep {
        let mut points_base = lasers.value.points_base.clone();
        if let Some(c) = camera {
            points_base.extend(&c.value.points_base);
            points_base.extend(&c.value.drop_offs_base);
            points_base.extend(&c.value.drop_offs_unseen_base);
        }
        let clear_of = Obstacles {
            points_base,
            ..Default::default()
        };
        // a turn on the spot the person said is clear all around: the
        // drop-offs that may lie out of the camera's view do not hold it
        let o_turn = camera
            .filter(|c| {
                !c.value.drop_offs_unseen_base.is_empty() && self.rear.around_vouched_at(now, pose)
            })
            .map(|c| {
                let mut points_base = lasers.value.points_base.clone();
                points_base.extend(&c.value.points_base);
                points_base.extend(&c.value.drop_offs_base);
                points_base
            });
        let mut o_turn = o_turn.unwrap_or_else(|| clear_of.points_base.clone());
        o_turn.extend(rear_points_base);
        Keep {
            clear_of,
            turn_clear_of: Obstacles {
                points_base: o_turn,
                ..Default::default()
            },
        }
    }

    /// The goal keeper's step at `pose` with the tracks and what the chair
    /// must not enter (`clear_of`, base_link): the search going further
    /// or ended where held, an arrival as near as it safely goes when
    /// held close to the place; the event said, the supervisor told
    /// whether a goal is active.
    pub(super) fn goal_step(
        &mut self,
        now: Stamp,
        pose: Pose2,
        clear_of: &Obstacles,
        tracker: &Tracker,
    ) -> GoalStep {
        let odom_from_base = pose.to_isometry3();
        let obstacles_odom: Vec<[f64; 2]> = clear_of
            .points_base
            .iter()
            .map(|q| {
                let p = odom_from_base * nalgebra::Point3::new(q[0] as f64, q[1] as f64, 0.0);
                [p.x, p.y]
            })
            .collect();
        let view = self.view;
        self.tell_goal_what_is_left(pose, view.as_ref());
        // the place beside the object where the chair fits on the map of
        // everything it has seen (not only what it sees now), on floor it
        // has seen (never seen, it may lie behind a wall); the map's
        // distance field brought up to date when the goal keeper first
        // asks (with no track to go to, it does not)
        let map = std::cell::RefCell::new(self.route.as_mut().and_then(|r| r.map.as_mut()));
        let event = self.goal.update(
            now,
            tracker,
            pose,
            &obstacles_odom,
            &|t| t.expected_seen && view.is_some_and(|v| v.sees(&pose, &t.center_m)),
            &|p| {
                map.borrow_mut().as_mut().is_none_or(|m| {
                    m.update_distances();
                    m.fits(p) && m.is_known_at(p)
                })
            },
        );
        let event = self.search_further(now, pose, event);
        let event = self.end_search_if_held(now, pose, event);
        // held on the way, close to the place beside the object: as near
        // as it safely goes
        // (for something in the way, or asked whether it is clear behind
        // and not answered: the last turn to face the object could wait
        // for a "yes" that never comes)
        let tracking = matches!(self.goal.state(), GoalState::Tracking { .. });
        let stood_still = self
            .stand_still
            .update(now, pose, tracking, STAND_STILL_FOR);
        let goal_held = tracking
            && (self.supervisor.state()
                == SupervisorState::Stopped(crate::msg::StopReason::Obstacle)
                || self.asked_rear.is_some()
                || stood_still);
        if !goal_held {
            self.goal_held_since = None;
        }
        let event = match event {
            None if goal_held
                && self.goal_held_since.get_or_insert(now).age_at(now) >= ARRIVE_HELD_AFTER =>
            {
                self.goal.arrive_near(pose, NEAR_ENOUGH_M)
            }
            e => e,
        };
        if let Some(e) = &event {
            tracing::debug!(event = ?e, approach = ?self.goal.approach(), ?pose, "goal");
            self.say(e.say());
        }
        match self.goal.state() {
            GoalState::Tracking { .. }
            | GoalState::Searching { .. }
            | GoalState::LookingAround
            | GoalState::Exploring { .. } => self.supervisor.goal_active(),
            GoalState::Holding { .. } => self.supervisor.goal_holding(),
            GoalState::None | GoalState::Reached { .. } => self.supervisor.goal_cleared(),
        }
        GoalStep {
            event,
            tracking,
            stood_still,
        }
    }

    /// The command on the way to `d.to`: through a doorway by its own
    /// steering; otherwise to the doorway's aim or the map's way, turned
    /// to face it first on the spot where it lies off to the side (and
    /// there is room), else the planner's, at a crawl somewhere tight.
    pub(super) fn drive_to(&mut self, d: Drive, keep: &Keep) -> Stamped<VelocityCmd> {
        let Drive {
            now,
            pose,
            v_mps,
            omega_radps,
            to,
            within_m,
            state,
            lasers_base,
        } = d;
        let (o, o_turn) = (&keep.clear_of, &keep.turn_clear_of);
        let from = [pose.x_m, pose.y_m];
        let door = self
            .route
            .as_mut()
            .and_then(|r| r.through_doorway(now, pose, to, within_m, state, lasers_base));
        // its passage given up just now: worked through on the map
        // instead, where a way is found (the manoeuvre drives from the
        // next step; still this one)
        let given_up = self.route.as_mut().and_then(|r| r.take_given_up_door());
        if let Some(d) = given_up {
            if self.begin_doorway_manoeuvre(now, pose, d, &o_turn.points_base) {
                return Stamped::new(now, VelocityCmd::default());
            }
        }
        let aim = match (door, self.route.as_mut()) {
            (Some(PassageCmd::Drive(cmd)), _) => {
                // through a doorway: its own steering
                return Stamped::new(now, self.turn_within_room(cmd, o_turn));
            }
            (Some(PassageCmd::Aim(p)), _) => p,
            (_, Some(r)) => r.carrot(now, from, to, within_m),
            (_, None) => to,
        };
        self.aim_odom = Some(aim);
        let bearing =
            crate::msg::wrap_angle((aim[1] - pose.y_m).atan2(aim[0] - pose.x_m) - pose.theta_rad);
        let far = (aim[0] - pose.x_m).hypot(aim[1] - pose.y_m) > 0.3;
        // somewhere tight the chair lines up more closely before it moves
        // on
        let tight = self.route.as_mut().is_some_and(|r| r.tight_ahead(pose));
        let limit = if tight {
            TURN_FIRST_RAD / 2.0
        } else {
            TURN_FIRST_RAD
        };
        // no room to turn on the spot (something in the corners' circle):
        // the planner's arc instead, which keeps its clearance
        let crawl_turn = self.supervisor.crawl_turn_radps();
        let room_to_turn = !self.supervisor.turn_blocked(o_turn, 0.0, crawl_turn);
        let turn_first = self.route.is_some()
            && far
            && bearing.abs() > limit
            && room_to_turn
            && !self.turn_refused_here(&pose);
        let mut out = self.planner.step(
            UnicycleState {
                x_m: pose.x_m,
                y_m: pose.y_m,
                theta_rad: pose.theta_rad,
                v_mps,
                omega_radps,
            },
            aim,
            o,
        );
        self.planned_path = std::mem::take(&mut out.path_odom);
        tracing::trace!(
            ?pose,
            ?aim,
            planned = ?out.cmd,
            source = ?out.source,
            goal_m = out.goal_distance_m,
            turn_first,
            tight,
            "planner: step"
        );
        if turn_first {
            // the way goes off to the side: face it first, on the spot
            out.cmd = VelocityCmd {
                v_mps: 0.0,
                omega_radps: TURN_FIRST_RADPS.copysign(bearing),
            };
        } else if tight {
            // somewhere tight (a doorway): a crawl, whose stop corridor is
            // the narrow one
            out.cmd.v_mps = out.cmd.v_mps.min(CRAWL_MPS);
        }
        Stamped::new(now, self.turn_within_room(out.cmd, o_turn))
    }
}
