//! Asking the person whether it is clear behind: a turn on the spot the
//! supervisor refuses for an unseen rear is asked about after a while,
//! and their "yes" vouches for the rear the lasers cannot see. One it
//! refuses for floor the camera never saw in the turn's circle (a step
//! down may lie just before the front of a chair that started facing it)
//! is asked about as "is it clear around me?", and that "yes" vouches for
//! both.

use super::{Control, REFUSED_TURN_WITHIN_M};
use crate::msg::{Obstacles, Stamp, Stamped, SupervisorState};

/// A turn refused for an unseen rear this long: the person is asked.
pub(super) const ASK_REAR_AFTER: std::time::Duration = std::time::Duration::from_secs(1);
/// Turns no longer refused for an unseen rear this long: that wait is over.
pub(super) const REAR_WAIT_OVER_AFTER: std::time::Duration = std::time::Duration::from_secs(1);

impl Control {
    /// Whether the person said no to a turn on the spot here (`pose`).
    pub(super) fn turn_refused_here(&self, pose: &crate::msg::Pose2) -> bool {
        self.turn_refused_at
            .is_some_and(|p| (p.x_m - pose.x_m).hypot(p.y_m - pose.y_m) <= REFUSED_TURN_WITHIN_M)
    }

    /// Drops from `floor_unseen_base` (base_link at `pose`) the floor the
    /// person said is clear around the chair: it holds no turn.
    pub(super) fn drop_vouched_floor(
        &self,
        now: Stamp,
        pose: &crate::msg::Pose2,
        floor_unseen_base: &mut Vec<[f32; 2]>,
    ) {
        let vouched: Vec<[f64; 2]> = self
            .rear
            .floor_vouched_at(now)
            .map(|p| pose.base_from_odom(p))
            .collect();
        if vouched.is_empty() {
            return;
        }
        floor_unseen_base.retain(|q| {
            let (x, y) = (q[0] as f64, q[1] as f64);
            vouched
                .iter()
                .all(|v| (x - v[0]).hypot(y - v[1]) > crate::safety::rear::AROUND_VOUCHED_M)
        });
    }

    /// Where the person said it is not clear around the chair: the floor
    /// the camera never saw within [`crate::safety::rear::AROUND_VOUCHED_M`]
    /// of that spot joins the camera's obstacles (`o`, base_link at
    /// `pose`), so that no arc, turn or plan enters it before the camera
    /// has seen it.
    pub(super) fn hold_refused_floor(
        &self,
        pose: &crate::msg::Pose2,
        o: &mut crate::msg::sensors::Obstacles,
    ) {
        let Some(at) = self.floor_refused_at else {
            return;
        };
        let c = pose.base_from_odom([at.x_m, at.y_m]);
        let within = crate::safety::rear::AROUND_VOUCHED_M;
        let refused = o
            .floor_unseen_base
            .iter()
            .filter(|q| (q[0] as f64 - c[0]).hypot(q[1] as f64 - c[1]) <= within);
        o.points_base.extend(refused);
    }

    /// Feeds the rear watch the newest scan (seen from the pose now) and
    /// the person's "yes"; what it knows of the rear now.
    pub(super) fn watch_rear(
        &mut self,
        now: Stamp,
        obstacles: Option<&Stamped<Obstacles>>,
        pose: crate::msg::Pose2,
    ) -> crate::safety::rear::RearView {
        if let Some(o) = obstacles.filter(|o| Some(o.stamp) != self.rear_scan) {
            self.rear_scan = Some(o.stamp);
            self.rear.on_scan(o.stamp, pose, &o.value.points_base);
        }
        if std::mem::take(&mut self.rear_yes) {
            if let Some(at) = self.asked_rear.take() {
                if self.asked_back_up {
                    self.rear
                        .confirm_backing(now, at, crate::safety::rear::BACK_UP_VOUCHED_M);
                } else if self.asked_around {
                    self.rear.confirm_around(now, at);
                } else {
                    self.rear.confirm(now, at);
                }
            }
        }
        self.rear.view(now, pose)
    }

    /// A turn on the spot refused for an unseen rear or unseen floor for
    /// a second: ask the person whether it is clear behind, or all around
    /// where `floor_unseen` (floor the camera never saw in the turn's
    /// circle), once per wait. All around is behind and low beside the
    /// chair, and low before it where `before_unseen` (floor never seen
    /// in the strip ahead: what the camera saw there, it remembers).
    pub(super) fn ask_about_rear(
        &mut self,
        now: Stamp,
        state: SupervisorState,
        pose: Option<crate::msg::Pose2>,
        floor_unseen: bool,
        before_unseen: bool,
    ) {
        use crate::msg::StopReason::{FloorUnseen, RearUnseen};
        let backing = self
            .planner_cmd
            .as_ref()
            .is_some_and(|c| c.value.v_mps < 0.0);
        // where the person said no to a turn, not asked about a turn
        // again; backing up straight is another question (the strip
        // behind, not the circle a turn sweeps), asked even there — a
        // back-off that waited for an answer never asked would time out
        // with the chair held in front of what holds it
        let refused = !backing && pose.is_some_and(|p| self.turn_refused_here(&p));
        let waiting = !refused
            && matches!(
                state,
                SupervisorState::Stopped(RearUnseen) | SupervisorState::Stopped(FloorUnseen)
            );
        if !waiting {
            // the wait is over (turned, or no turn needed any more) once
            // it has been over a while: a chair creeping on between
            // refused turns (the planner's command switching between a
            // crawl and a turn) is still waiting, and must still ask
            let clear = *self.rear_clear_since.get_or_insert(now);
            if clear.age_at(now) >= REAR_WAIT_OVER_AFTER {
                // a later one asks again
                self.rear_blocked_since = None;
                self.asked_rear = None;
            }
            return;
        }
        self.rear_clear_since = None;
        let since = *self.rear_blocked_since.get_or_insert(now);
        if since.age_at(now) >= ASK_REAR_AFTER && self.asked_rear.is_none() {
            if let Some(p) = pose {
                self.asked_rear = Some(p);
                self.asked_back_up = backing;
                let around =
                    !backing && (state == SupervisorState::Stopped(FloorUnseen) || floor_unseen);
                self.asked_around = around;
                self.say(if backing {
                    "I need to back up a little, up to half a metre, and I cannot see \
                     behind me. Is it clear behind? Say yes to let me back up, or no."
                        .into()
                } else if around && before_unseen {
                    "I need to turn on the spot, and I cannot see behind me or the floor near \
                     me. Is it clear around me? Nothing behind me, nothing low beside or \
                     before me. Say yes to let me turn, or no."
                        .into()
                } else if around {
                    "I need to turn on the spot, and I cannot see behind me or the floor \
                     beside me. Is it clear around me? Nothing behind me, nothing low beside \
                     me. Say yes to let me turn, or no."
                        .into()
                } else {
                    "I need to turn on the spot, and I cannot see behind me. \
                     Is it clear behind? Say yes to let me turn, or no."
                        .into()
                });
            }
        }
    }
}

/// Whether the camera never saw floor (or may miss a step down) straight
/// ahead in the circle a turn on the spot sweeps — the strip of the
/// chair's width before it, within
/// [`crate::safety::rear::AROUND_VOUCHED_M`] of base_link (`camera`, in
/// base_link): only then is the person asked about what lies low before
/// it; seen, the camera's memory holds it.
pub(super) fn before_unseen(
    camera: Option<&Stamped<Obstacles>>,
    limits: &crate::safety::SafetyLimits,
) -> bool {
    camera.is_some_and(|c| {
        let half_m = limits.chair_width_m / 2.0;
        c.value
            .floor_unseen_base
            .iter()
            .chain(&c.value.drop_offs_unseen_base)
            .any(|q| {
                let (x, y) = (f64::from(q[0]), f64::from(q[1]));
                x > 0.0 && y.abs() <= half_m && x.hypot(y) <= crate::safety::rear::AROUND_VOUCHED_M
            })
    })
}
