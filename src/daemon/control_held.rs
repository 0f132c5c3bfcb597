//! What the control step does when the supervisor holds the way to a
//! goal: a detour the supervisor admits (`navigation::detour`), and
//! telling the person when there is none for a while.

use super::{Control, NEAR_ENOUGH_M, OTHER_SIDE_HELD_AFTER, SAY_HELD_AFTER};
use crate::msg::{Stamp, Stamped, VelocityCmd};
use crate::safety::SupervisorInputs;

impl Control {
    /// When the supervisor would hold the planner's command for something
    /// in the way, the planner's command becomes a detour it admits, if
    /// there is one (searched every step: a search skipped for even 100 ms
    /// after one that found none loses trips, e.g. scene 8 of seed 1).
    pub(super) fn detour_if_held(&mut self, now: Stamp, inputs: &SupervisorInputs) {
        if let Some(cmd) = self.detour_going_on(now, inputs) {
            self.planner_cmd = Some(Stamped::new(now, cmd));
            return;
        }
        if let Some(detour) = self.detour(inputs) {
            self.detours += 1;
            self.detour_since = Some((now, detour));
            self.planner_cmd = Some(Stamped::new(now, detour));
        }
    }

    /// A detour found is followed as it was scored, for the scoring's
    /// horizon: an arc as it is; a turn on the spot for half of it, then a
    /// crawl straight on. The planner's command, free again once the turn
    /// has put the obstacle aside, would turn straight back into the same
    /// hold (the two took turns for the whole trip, scene 113 of seed 1).
    /// Only while there is a command to replace, the place beside the
    /// object is not within reach, and the supervisor admits this step's
    /// part; else None, and the detour is over.
    fn detour_going_on(&mut self, now: Stamp, inputs: &SupervisorInputs) -> Option<VelocityCmd> {
        let (since, detour) = self.detour_since.take()?;
        let age_s = since.age_at(now).as_secs_f64();
        let (obs, odo) = (inputs.obstacles?, inputs.odometry?);
        inputs.command?;
        self.aim_odom?;
        if age_s >= crate::navigation::detour::HORIZON_S || self.near_the_place(&odo.value.pose) {
            return None;
        }
        let cmd = crate::navigation::detour::command_at(
            &detour,
            self.supervisor.limits.v_forward_max_mps,
            age_s,
        );
        if self
            .supervisor
            .hold_reason(inputs, obs, cmd.v_mps, cmd.omega_radps)
            .is_some()
        {
            return None;
        }
        self.detour_since = Some((since, detour));
        Some(cmd)
    }

    /// Whether the chair at `pose` is within [`NEAR_ENOUGH_M`] of the
    /// place beside the object.
    fn near_the_place(&self, pose: &crate::msg::Pose2) -> bool {
        self.goal
            .approach()
            .is_some_and(|a| (a.x_m - pose.x_m).hypot(a.y_m - pose.y_m) <= NEAR_ENOUGH_M)
    }

    /// The planner's command would be held for something in the way (or
    /// a drop-off): the cheapest detour toward the planner's aim that the
    /// supervisor would drive, if there is one (none either when nothing
    /// holds the command, or when the chair is within reach of the place
    /// beside the object).
    fn detour(&self, inputs: &SupervisorInputs) -> Option<VelocityCmd> {
        let aim = self.aim_odom?;
        let (cmd, obs, odo) = (inputs.command?, inputs.obstacles?, inputs.odometry?);
        let l = &self.supervisor.limits;
        let clamp = |c: &VelocityCmd| {
            (
                c.v_mps.clamp(-l.v_reverse_max_mps, l.v_forward_max_mps),
                c.omega_radps.clamp(-l.omega_max_radps, l.omega_max_radps),
            )
        };
        let (v, w) = clamp(&cmd.value);
        if !(v.is_finite() && w.is_finite()) {
            return None;
        }
        let held = self.supervisor.hold_reason(inputs, obs, v, w);
        let pose = odo.value.pose;
        use crate::msg::StopReason::{DropOff, FloorUnseen, Obstacle, RearUnseen};
        let refused =
            matches!(held, Some(RearUnseen | FloorUnseen)) && self.turn_refused_here(&pose);
        if !matches!(held, Some(Obstacle | DropOff)) && !refused {
            return None;
        }
        // within reach of the place beside the object: held there, the
        // trip ends as near as it safely goes (no manoeuvre for the rest)
        if self.near_the_place(&pose) {
            return None;
        }
        let (dx, dy) = (aim[0] - pose.x_m, aim[1] - pose.y_m);
        let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
        let aim_base = [c * dx + s * dy, -s * dx + c * dy];
        let limits = crate::navigation::detour::DetourLimits {
            v_forward_max_mps: l.v_forward_max_mps,
            omega_max_radps: l.omega_max_radps,
            crawl_turn_radps: self.supervisor.crawl_turn_radps(),
        };
        // everything the chair must not enter, base_link
        let no_points = &[][..];
        let points_base: Vec<[f32; 2]> = [
            &obs.value.points_base[..],
            &obs.value.drop_offs_base,
            inputs.camera.map_or(no_points, |c| &c.value.points_base),
            inputs.camera.map_or(no_points, |c| &c.value.drop_offs_base),
            inputs
                .camera
                .map_or(no_points, |c| &c.value.drop_offs_unseen_base),
            inputs.rear.map_or(no_points, |r| &r.points_base),
        ]
        .concat();
        let found = crate::navigation::detour::detour(aim_base, &limits, &points_base, |c| {
            let (v, w) = clamp(c);
            self.supervisor.hold_reason(inputs, obs, v, w).is_none()
        });
        match found {
            Some(d) => {
                tracing::debug!(?held, planned = ?cmd.value, detour = ?d, ?aim_base, "detour")
            }
            None => tracing::debug!(?held, planned = ?cmd.value, ?aim_base, "no detour"),
        }
        found
    }

    /// Held on the way (by the supervisor, or standing still with nothing
    /// holding it: the planner's commands came to nothing) for
    /// [`SAY_HELD_AFTER`] without a break: said once (a carer can move
    /// what is in the way; the chair goes on by itself when the way
    /// clears, or stays on "stop"), with how long it will wait: driving
    /// to an object, until the goal is given up; searching, until the
    /// search ends for staying in one place. Held for the goal's
    /// `give_up_held_after` without a break, driving to an object: the
    /// goal is given up (the event to say and end the trip with).
    pub(super) fn tell_if_held(
        &mut self,
        now: Stamp,
        pose: crate::msg::Pose2,
        seen_now_base: &[[f32; 2]],
        held: Option<Held>,
    ) -> Option<crate::estimation::goal::GoalEvent> {
        let Some(held) = held else {
            self.held_since = None;
            self.said_held = false;
            self.tried_other_side = false;
            return None;
        };
        let since = *self.held_since.get_or_insert(now);
        let held_for = since.age_at(now);
        // held on the way to the place beside the object: another side
        // of it, once a hold (a new hold begins when the chair moves on)
        if held_for >= OTHER_SIDE_HELD_AFTER && !self.tried_other_side {
            self.tried_other_side = true;
            if self.goal.refuse_approach() {
                tracing::info!(?held, "held on the way: trying another side of the object");
            }
        }
        // no way round: a manoeuvre on the map, where one is found (the
        // hold starts again)
        if held_for >= SAY_HELD_AFTER
            && !self.said_held
            && held == Held::Supervisor
            && self.begin_manoeuvre(now, pose, seen_now_base)
        {
            self.held_since = None;
            return None;
        }
        if held_for >= SAY_HELD_AFTER && !self.said_held {
            self.said_held = true;
            // driving to an object, the wait has an end; searching, so
            // has staying in this one place (`end_search_if_held`)
            use crate::estimation::goal::GoalState;
            let left = match self.goal.state() {
                GoalState::Tracking { .. } => Some(
                    self.goal
                        .settings
                        .give_up_held_after
                        .saturating_sub(held_for),
                ),
                GoalState::Searching { .. } | GoalState::Exploring { .. } => Some(
                    self.goal
                        .settings
                        .search_held_for
                        .saturating_sub(self.search_in_place.for_how_long(now)),
                ),
                _ => None,
            };
            let until = left
                .map(|d| format!(" for {:.0} more seconds", d.as_secs_f64()))
                .unwrap_or_default();
            match held {
                Held::Supervisor => {
                    tracing::warn!("held on the way with no way round");
                    let wait = if until.is_empty() {
                        "go on when it is clear".to_string()
                    } else {
                        format!("wait{until} for it to clear")
                    };
                    self.say(format!(
                        "Something is in my way and I cannot find a way round it. I will \
                         {wait}; say stop to stay here."
                    ));
                }
                Held::StandingStill => {
                    tracing::warn!("standing still on the way, far from the place");
                    self.say(format!(
                        "I have stopped on the way and cannot find how to get nearer. I will \
                         keep trying{until}; say stop to stay here."
                    ));
                }
            }
        }
        if held_for >= self.goal.settings.give_up_held_after {
            let e = self.goal.give_up(now, held_for.as_secs_f64(), pose);
            if e.is_some() {
                self.held_since = None;
                self.said_held = false;
            }
            return e;
        }
        None
    }
}

/// What keeps the chair from going on to its goal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Held {
    /// The safety supervisor holds it for something in the way.
    Supervisor,
    /// It stands still with nothing holding it ([`StandStill`]).
    StandingStill,
}

/// The chair standing still on the way to a goal with nothing holding it:
/// the planner's commands have come to nothing (its obstacle model keeps
/// it short of the place beside the object). Near enough, that is an
/// arrival as when the supervisor holds it; it was a silent stand-still
/// before (the real-time living-room trip stood 0.13 m short for 22 s).
/// Pure: time and pose passed in.
#[derive(Debug, Clone, Default)]
pub(super) struct StandStill {
    since: Option<(Stamp, crate::msg::Pose2)>,
    /// Staying in place: within this of one place, m, whatever the
    /// heading (turning on the spot and creeping count,
    /// [`StandStill::in_place`]); None: standing still, within
    /// [`STILL_WITHIN_M`] and [`STILL_WITHIN_RAD`].
    in_place_within_m: Option<f64>,
}

/// Staying within this of one place is staying in place (m).
pub(super) const IN_PLACE_WITHIN_M: f64 = 0.15;

/// Moving less than this from where it stood is standing still (m, rad).
pub(super) const STILL_WITHIN_M: f64 = 0.02;
pub(super) const STILL_WITHIN_RAD: f64 = 0.05;

impl StandStill {
    /// Staying in one place ([`IN_PLACE_WITHIN_M`]), whatever the
    /// heading: a chair that only turns this way and that and creeps (a
    /// detour turning on the spot where the way on stays held, a drop-off
    /// before it) is getting nowhere.
    pub(super) fn in_place() -> Self {
        Self::in_place_within(IN_PLACE_WITHIN_M)
    }

    /// Staying within `within_m` of one place, whatever the heading.
    pub(super) fn in_place_within(within_m: f64) -> Self {
        StandStill {
            since: None,
            in_place_within_m: Some(within_m),
        }
    }

    /// How long the chair has stood (or stayed in place) so far, as of
    /// the last [`update`](Self::update); zero when it has not.
    pub(super) fn for_how_long(&self, now: Stamp) -> std::time::Duration {
        self.since.map(|(t, _)| t.age_at(now)).unwrap_or_default()
    }

    /// Whether the chair, `driving` to a goal, has stood within
    /// [`STILL_WITHIN_M`] and [`STILL_WITHIN_RAD`] of one pose for at least
    /// `long`.
    pub(super) fn update(
        &mut self,
        now: Stamp,
        pose: crate::msg::Pose2,
        driving: bool,
        long: std::time::Duration,
    ) -> bool {
        if !driving {
            self.since = None;
            return false;
        }
        match self.since {
            Some((t, p))
                if (p.x_m - pose.x_m).hypot(p.y_m - pose.y_m)
                    <= self.in_place_within_m.unwrap_or(STILL_WITHIN_M)
                    && (self.in_place_within_m.is_some()
                        || crate::msg::wrap_angle(p.theta_rad - pose.theta_rad).abs()
                            <= STILL_WITHIN_RAD) =>
            {
                t.age_at(now) >= long
            }
            _ => {
                self.since = Some((now, pose));
                false
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::Pose2;
    use std::time::Duration;

    #[test]
    fn standing_still_while_driving_counts_after_the_time_and_moving_resets_it() {
        let at = |s: f64| Stamp::from_secs_f64(s);
        let pose = |x: f64, th: f64| Pose2 {
            x_m: x,
            y_m: 0.0,
            theta_rad: th,
        };
        let long = Duration::from_secs(2);
        let mut s = StandStill::default();
        assert!(!s.update(at(0.0), pose(0.0, 0.0), true, long));
        assert!(!s.update(at(1.9), pose(0.015, 0.03), true, long));
        assert!(s.update(at(2.0), pose(0.01, 0.0), true, long));
        // turning on the spot: not standing still, but in place
        let mut turning = StandStill::default();
        let mut in_place = StandStill::in_place();
        for k in 0..=20 {
            let p = pose(0.005 * k as f64, 0.3 * (k % 2) as f64);
            assert!(!turning.update(at(0.1 * k as f64), p, true, long));
            assert_eq!(in_place.update(at(0.1 * k as f64), p, true, long), k == 20);
        }
        // it moved: the time starts again
        assert!(!s.update(at(2.1), pose(0.05, 0.0), true, long));
        assert!(!s.update(at(4.0), pose(0.05, 0.0), true, long));
        assert!(s.update(at(4.1), pose(0.05, 0.0), true, long));
        // turning on the spot is moving
        assert!(!s.update(at(4.2), pose(0.05, 0.1), true, long));
        // not driving to a goal: never
        assert!(!s.update(at(9.0), pose(0.05, 0.1), false, long));
        assert!(!s.update(at(9.1), pose(0.05, 0.1), true, long));
    }
}
