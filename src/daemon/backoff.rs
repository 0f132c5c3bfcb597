//! Backing off when the way is held (pure, for the control step): held by
//! something on the way to a goal for [`BACK_OFF_AFTER`], the chair backs
//! off about 12 cm straight — only onto floor it stood on (its trail: no
//! sensor sees a step down behind), or that the person said is clear, or
//! will be asked about — then the planner tries again. The supervisor
//! checks the reverse like any motion: with the rear unseen it holds it,
//! and the control step asks the person whether it is clear behind (they
//! look for a step down too); their "no" ends the back-off, and none is
//! tried again from there ([`BackOff::refuse`]).

use crate::msg::{Pose2, Stamp, VelocityCmd};
use crate::safety::SafetyLimits;

/// Held this long by an obstacle on the way to a goal: back off at this
/// speed.
pub const BACK_OFF_AFTER: std::time::Duration = std::time::Duration::from_secs(3);
pub const BACK_OFF_MPS: f64 = 0.08;
/// A back-off ends once this far from where it began, m, or this long
/// after it began (the person asked about the rear takes a few seconds
/// to answer; unanswered, the chair stays held).
pub const BACK_OFF_M: f64 = 0.12;
pub const BACK_OFF_AT_MOST: std::time::Duration = std::time::Duration::from_secs(10);
/// Where the person said it is not clear behind, no back-off within this,
/// m.
const REFUSED_WITHIN_M: f64 = 0.15;
/// A back-off is tried once from about one place (within this, m) for
/// this long: held there again, the chair stays held (and gives up in
/// time) rather than backing and asking over and over — each back-off
/// ends a hold, and the hold's time starts again.
const AGAIN_WITHIN_M: f64 = 0.3;
const AGAIN_AFTER: std::time::Duration = std::time::Duration::from_secs(60);
/// The trail keeps a pose every this far, this many (5 m).
const TRAIL_STEP_M: f64 = 0.05;
const TRAIL_POSES: usize = 100;

#[derive(Debug, Clone, Default)]
pub struct BackOff {
    /// Since when the way to a goal is held; backing off since when, and
    /// from where.
    held_since: Option<Stamp>,
    backing: Option<(Stamp, Pose2)>,
    /// Where the person said it is not clear behind.
    refused_at: Option<Pose2>,
    /// Where back-offs began, and when.
    began: Vec<(Stamp, Pose2)>,
    /// Where the chair has been (odom), a pose every 5 cm, the newest last.
    pub(super) trail: Vec<Pose2>,
    /// Times it backed off.
    pub count: u64,
}

impl BackOff {
    /// Whether it is backing off now.
    pub fn backing(&self) -> bool {
        self.backing.is_some()
    }

    /// The person said it is not clear behind (asked while backing off,
    /// at `at`): the back-off ends, and none is tried again near there.
    pub fn refuse(&mut self, at: Pose2) {
        self.backing = None;
        self.held_since = None;
        self.refused_at = Some(at);
        tracing::info!(?at, "not clear behind: no backing off here");
    }

    /// One step at `now`, the chair at `pose`: `going` — there is a goal
    /// to go to; `held` — the supervisor holds the chair for an obstacle;
    /// `rear` — whether the person said it is clear behind here (they
    /// would see a step down: the floor behind need not be on the trail),
    /// and whether the supervisor will hold a reverse for the rear unseen
    /// (the person is asked then, and their "yes" is that word). The
    /// reverse command while backing off, else None.
    pub fn step(
        &mut self,
        now: Stamp,
        pose: Pose2,
        going: bool,
        held: bool,
        rear: impl FnOnce() -> (bool, bool),
        limits: &SafetyLimits,
    ) -> Option<VelocityCmd> {
        if self
            .trail
            .last()
            .is_none_or(|p| (p.x_m - pose.x_m).hypot(p.y_m - pose.y_m) >= TRAIL_STEP_M)
        {
            self.trail.push(pose);
            if self.trail.len() > TRAIL_POSES {
                self.trail.remove(0);
            }
        }
        let held = going && held;
        if !held {
            self.held_since = None;
        }
        let refused_here = self
            .refused_at
            .is_some_and(|r| (r.x_m - pose.x_m).hypot(r.y_m - pose.y_m) <= REFUSED_WITHIN_M);
        self.began.retain(|(t, _)| t.age_at(now) < AGAIN_AFTER);
        let backed_here = self
            .began
            .iter()
            .any(|(_, p)| (p.x_m - pose.x_m).hypot(p.y_m - pose.y_m) <= AGAIN_WITHIN_M);
        if held
            && self.backing.is_none()
            && !refused_here
            && !backed_here
            && self.held_since.get_or_insert(now).age_at(now) >= BACK_OFF_AFTER
        {
            let (floor_vouched, to_be_asked) = rear();
            // (asked, the person's answer covers the floor too)
            let start = to_be_asked || floor_vouched || self.came_through_behind(pose, limits);
            if start {
                self.began.push((now, pose));
                self.held_since = None;
                self.backing = Some((now, pose));
                self.count += 1;
                tracing::info!(
                    ?pose,
                    asking = to_be_asked,
                    "held by an obstacle: backing off"
                );
            }
        }
        if let Some((since, from)) = self.backing {
            let backed_m = (pose.x_m - from.x_m).hypot(pose.y_m - from.y_m);
            if going && backed_m < BACK_OFF_M && since.age_at(now) < BACK_OFF_AT_MOST {
                return Some(VelocityCmd {
                    v_mps: -BACK_OFF_MPS,
                    omega_radps: 0.0,
                });
            }
            if going && backed_m < BACK_OFF_M {
                // the person did not answer, or the reverse stayed held:
                // the chair stays held where it is
                tracing::info!(
                    backed_m,
                    "back-off ended at its time limit short of its distance"
                );
            }
            self.backing = None;
        }
        None
    }

    /// Whether the floor the chair would back onto is floor it stood on:
    /// the rear edge's middle and corners after backing off lie inside the
    /// footprint at some pose of its trail (a step down behind that no
    /// sensor saw cannot be there).
    fn came_through_behind(&self, pose: Pose2, l: &SafetyLimits) -> bool {
        let back = l.rear_offset_m + BACK_OFF_M;
        let half = l.chair_width_m / 2.0 - 0.05;
        let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
        [-half, 0.0, half].iter().all(|side| {
            let p = [
                pose.x_m - c * back - s * side,
                pose.y_m - s * back + c * side,
            ];
            self.trail.iter().any(|q| {
                let (dx, dy) = (p[0] - q.x_m, p[1] - q.y_m);
                let (qc, qs) = (q.theta_rad.cos(), q.theta_rad.sin());
                let (x, y) = (qc * dx + qs * dy, -qs * dx + qc * dy);
                x >= -l.rear_offset_m && x <= l.front_offset_m && y.abs() <= l.chair_width_m / 2.0
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(ms: u64) -> Stamp {
        Stamp::from_secs_f64(ms as f64 / 1000.0)
    }

    fn x(x_m: f64) -> Pose2 {
        Pose2 {
            x_m,
            y_m: 0.0,
            theta_rad: 0.0,
        }
    }

    /// Held with the rear unseen (the supervisor will ask the person):
    /// it backs off 12 cm, measured from where it began, then stops; held
    /// again about there within the minute, it does not back off again
    /// (the hold runs on to its end); a metre on, it may. The person's
    /// "no" ends a back-off at once, and none begins near there again.
    #[test]
    fn a_back_off_ends_12_cm_back_and_is_tried_once_a_place() {
        let limits = crate::config::Settings::defaults().safety_limits();
        let mut b = BackOff::default();
        let ask = || (false, true);
        // held 3 s, then backing
        let mut ms = 0;
        while b.step(at(ms), x(0.0), true, true, ask, &limits).is_none() {
            ms += 50;
            assert!(ms <= 3000, "never backed off");
        }
        assert_eq!(ms, 3000);
        let mut pose = x(0.0);
        let mut steps = 0;
        while let Some(c) = b.step(at(ms), pose, true, false, ask, &limits) {
            assert!(c.v_mps < 0.0 && c.omega_radps == 0.0, "{c:?}");
            pose = x(pose.x_m + c.v_mps * 0.05);
            ms += 50;
            steps += 1;
            assert!(steps < 100, "never ended");
        }
        assert!((-pose.x_m - BACK_OFF_M).abs() < 0.005, "{pose:?}");
        assert!(!b.backing());
        // back where it was held, held again: no second back-off
        for k in 0..200 {
            assert!(b
                .step(at(ms + 50 * k), x(0.05), true, true, ask, &limits)
                .is_none());
        }
        assert_eq!(b.count, 1);
        // a metre on: it backs off again
        let from = ms + 10_000;
        assert!((0..=70).any(|k| b
            .step(at(from + 50 * k), x(1.0), true, true, ask, &limits)
            .is_some()));
        assert_eq!(b.count, 2);
        b.refuse(x(1.0));
        assert!(!b.backing());
        assert!(b
            .step(at(from + 4000), x(1.0), true, true, ask, &limits)
            .is_none());
        // a minute later, the place is free again, but not where the
        // person said no
        let later = from + 70_000;
        assert!((0..=70).any(|k| b
            .step(at(later + 50 * k), x(0.0), true, true, ask, &limits)
            .is_some()));
        let mut b2 = b.clone();
        assert!((0..=70).all(|k| b2
            .step(
                at(later + 10_000 + 50 * k),
                x(1.05),
                true,
                true,
                ask,
                &limits
            )
            .is_none()));
        // with the rear seen (no one asked), only onto floor it stood on or
        // the person vouched for
        let mut b = BackOff::default();
        assert!((0..=100).all(|k| b
            .step(at(50 * k), x(0.0), true, true, || (false, false), &limits)
            .is_none()));
        assert!((0..=100).any(|k| b
            .step(
                at(50 * k + 6000),
                x(0.0),
                true,
                true,
                || (true, false),
                &limits
            )
            .is_some()));
    }
}
