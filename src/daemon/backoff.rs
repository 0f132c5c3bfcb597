//! Backing off when the way is held (pure, for the control step): held by
//! something on the way to a goal for [`BACK_OFF_AFTER`], the chair backs
//! off about 12 cm straight — only with the rear seen (the caller's word)
//! and only onto floor it stood on (its trail: no sensor sees a step down
//! behind) or that the person said is clear — then the planner tries
//! again. The supervisor checks the
//! reverse like any motion.

use crate::msg::{Pose2, Stamp, VelocityCmd};
use crate::safety::SafetyLimits;

/// Held this long by an obstacle on the way to a goal: back off at this
/// speed for this long (about 12 cm).
pub const BACK_OFF_AFTER: std::time::Duration = std::time::Duration::from_secs(3);
pub const BACK_OFF_FOR: std::time::Duration = std::time::Duration::from_millis(1500);
pub const BACK_OFF_MPS: f64 = 0.08;
/// The trail keeps a pose every this far, this many (5 m).
const TRAIL_STEP_M: f64 = 0.05;
const TRAIL_POSES: usize = 100;

#[derive(Debug, Clone, Default)]
pub struct BackOff {
    /// Since when the way to a goal is held; backing off since when.
    held_since: Option<Stamp>,
    backing: Option<Stamp>,
    /// Where the chair has been (odom), a pose every 5 cm, the newest last.
    pub(super) trail: Vec<Pose2>,
    /// Times it backed off.
    pub count: u64,
}

impl BackOff {
    /// One step at `now`, the chair at `pose`: `going` — there is a goal
    /// to go to; `held` — the supervisor holds the chair for an obstacle;
    /// `rear` — whether the rear counts as seen, and whether the person
    /// said it is clear behind here (they would see a step down: the floor
    /// behind need not be on the trail). The reverse command while backing
    /// off, else None.
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
        if held
            && self.backing.is_none()
            && self.held_since.get_or_insert(now).age_at(now) >= BACK_OFF_AFTER
            && {
                let (rear_ok, floor_vouched) = rear();
                rear_ok && (floor_vouched || self.came_through_behind(pose, limits))
            }
        {
            self.held_since = None;
            self.backing = Some(now);
            self.count += 1;
            tracing::info!(?pose, "held by an obstacle: backing off");
        }
        if let Some(since) = self.backing {
            if going && since.age_at(now) < BACK_OFF_FOR {
                return Some(VelocityCmd {
                    v_mps: -BACK_OFF_MPS,
                    omega_radps: 0.0,
                });
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
        let back = l.rear_offset_m + BACK_OFF_MPS * BACK_OFF_FOR.as_secs_f64();
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
