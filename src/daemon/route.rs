//! The way to the goal for the control step (pure): the map of what the
//! chair has seen, kept up to date from the lasers and the camera; the way
//! through it, replanned as the goal moves; the point the local planner
//! heads for; doorways passed as their own manoeuvre.

use crate::msg::{MapObstacles, Obstacles, Stamp, Stamped, SupervisorState};
use crate::navigation::doorway::{self, Passage, PassageCmd, PassageSettings};
use crate::navigation::map::{GridMap, MapPath, MapSettings};

/// What is left for the camera to look at around the chair: the turn on
/// the spot that brings it all into view, counter-clockwise and clockwise,
/// rad (both 0: nothing is left outside the view).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LeftToSee {
    pub ccw_rad: f64,
    pub cw_rad: f64,
}

impl LeftToSee {
    pub fn nothing(&self) -> bool {
        self.ccw_rad == 0.0 && self.cw_rad == 0.0
    }
}

/// The map and the way to the goal through it.
pub struct Router {
    pub settings: MapSettings,
    /// Made at the first odometry, centred where the chair is.
    pub map: Option<GridMap>,
    /// The newest laser set and camera set in the map.
    scan: Option<Stamp>,
    camera: Option<Stamp>,
    /// The way, where it goes and when it was planned.
    pub path: Option<(MapPath, [f64; 2], Stamp)>,
    /// Where the last plan went and when, found or not (a plan that
    /// found no way is tried again as one that found it is replanned).
    last_plan: Option<([f64; 2], Stamp)>,
    /// Ways planned, and goals no way reached.
    pub planned: u64,
    pub no_way: u64,
    /// The doorway being passed, since when, and since when the
    /// supervisor has held the chair in it.
    passage: Option<(Passage, Stamp, Option<Stamp>)>,
    /// A doorway given up, not tried again until then.
    skip: Option<([f64; 2], Stamp)>,
    /// Where the chair stood (odom) when the person said it is not clear
    /// behind for a doorway's back-up: a passage begun again within
    /// [`BACK_UP_REFUSED_WITHIN_M`] of it does not back up, nor ask again.
    back_up_refused_at: Option<[f64; 2]>,
    pub doorways: u64,
    pub doorways_given_up: u64,
    pub last_given_up: Option<DoorwayGivenUp>,
    /// The doorway whose passage was given up this step, for the control
    /// step to work its way through on the map instead
    /// ([`Router::take_given_up_door`]).
    given_up_door: Option<doorway::Doorway>,
}

/// A doorway passage given up: the phase it was in, the doorway's width
/// and the chair's place about its middle (along its axis, positive
/// beyond; to its left) and heading off its axis, and whether the
/// supervisor held it there (else it ran out of time).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DoorwayGivenUp {
    pub phase: &'static str,
    pub width_m: f64,
    pub along_m: f64,
    pub left_m: f64,
    pub heading_err_rad: f64,
    pub held: bool,
}

/// A doorway given up after the chair stood blocked in it this long, or
/// took this long in all; not tried again for this long.
pub(super) const PASSAGE_BLOCKED_FOR: std::time::Duration = std::time::Duration::from_secs(5);
/// Held this long on the way to the point before a doorway, the chair
/// lines up from where it is ([`Passage::held_on_approach`]).
pub(super) const LINE_UP_HELD_AFTER: std::time::Duration = std::time::Duration::from_secs(2);
pub(super) const PASSAGE_AT_MOST: std::time::Duration = std::time::Duration::from_secs(60);
pub(super) const PASSAGE_SKIP_FOR: std::time::Duration = std::time::Duration::from_secs(20);
/// A back-up the person said no to holds for passages begun within this
/// of where the chair stood then, m.
pub(super) const BACK_UP_REFUSED_WITHIN_M: f64 = 0.15;
/// A gap measured narrower than this is no doorway for the chair: its
/// 0.70 m (the measurement is to a cell and measures short: an 0.81 m
/// doorway measured 0.725 m in scene 60 of `opennav sim --seed 1`, and the
/// chair, not passing it as a doorway, stood held before it; the lasers
/// measure the jambs once the passage begins); one that measures wide
/// enough but is not, the supervisor holds, and the passage is given up,
/// m.
pub(super) const MIN_DOORWAY_M: f64 = 0.70;

/// Held this far past a doorway's middle (base_link; the chair's rear,
/// 0.45 m behind it, is out of the wall's half thickness), the passage is
/// through and the planner takes over, m.
pub(super) const HAND_BACK_HELD_PAST_M: f64 = 0.5;

/// Replan this often, or when the goal moved this far (s, m).
pub(super) const REPLAN_EVERY: std::time::Duration = std::time::Duration::from_secs(1);
pub(super) const REPLAN_MOVED_M: f64 = 0.3;
/// A new place to search is this far from the chair and from the places
/// searched, m.
pub(super) const EXPLORE_MIN_M: f64 = 1.0;
pub(super) const EXPLORE_APART_M: f64 = 1.5;
/// The camera is taken to have looked this far along the floor, m (the
/// tracker confirms objects within it).
pub(super) const LOOK_RANGE_M: f64 = 4.0;
/// The search turn's check of what is left to look at: bearings a whole
/// turn is cut into, and where the check starts from the chair's centre
/// (its corners reach 0.65 m), m.
pub(super) const LOOK_BINS: usize = 72;
pub(super) const LOOK_FROM_M: f64 = 0.7;
/// A search turn held by something in its circle goes on at least this
/// far away, m.
pub(super) const ROOM_TO_TURN_MIN_M: f64 = 0.6;
/// A place to search has this much room about it (to turn on the spot: the
/// chair's corners reach 0.65 m from base_link, the supervisor keeps 0.10 m
/// more), m.
pub(super) const EXPLORE_ROOM_M: f64 = 0.8;
/// The way more than this off the heading: turn on the spot first (rad),
/// at this rate (rad/s).
pub(super) const TURN_FIRST_RAD: f64 = 0.7;
pub(super) const TURN_FIRST_RADPS: f64 = 0.4;
/// Closer than this to something on the map just ahead: crawl (m, m/s).
pub(super) const TIGHT_M: f64 = 0.55;
pub(super) const CRAWL_MPS: f64 = 0.09;

impl Router {
    pub fn new(settings: MapSettings) -> Router {
        Router {
            settings,
            map: None,
            scan: None,
            camera: None,
            path: None,
            last_plan: None,
            planned: 0,
            no_way: 0,
            passage: None,
            skip: None,
            back_up_refused_at: None,
            doorways: 0,
            doorways_given_up: 0,
            last_given_up: None,
            given_up_door: None,
        }
    }

    /// Puts the newest laser set (seen from `pose`) and camera set in.
    pub(super) fn update(
        &mut self,
        pose: crate::msg::Pose2,
        lasers: Option<&Stamped<Obstacles>>,
        camera: Option<&Stamped<MapObstacles>>,
        view: Option<&crate::estimation::view::CameraView>,
    ) {
        let settings = self.settings;
        let map = self
            .map
            .get_or_insert_with(|| GridMap::new(settings, [pose.x_m, pose.y_m]));
        if let Some(l) = lasers.filter(|l| Some(l.stamp) != self.scan) {
            self.scan = Some(l.stamp);
            map.add_scan(pose, &l.value.rays_base);
        }
        if let Some(c) = camera.filter(|c| Some(c.stamp) != self.camera) {
            self.camera = Some(c.stamp);
            // a drop-off that may lie out of view is kept clear of as one
            // seen
            let drop_offs: Vec<[f64; 2]> = c
                .value
                .drop_offs_odom
                .iter()
                .chain(&c.value.drop_offs_unseen_odom)
                .copied()
                .collect();
            map.set_camera(&c.value.obstacles_odom, &drop_offs);
            // what the camera looked at, from where the chair is now
            if let Some(v) = view {
                let odom_from_camera = pose.to_isometry3() * v.base_from_camera;
                let o = odom_from_camera.translation.vector;
                let axis = odom_from_camera.rotation * nalgebra::Vector3::z();
                map.look(
                    [o.x, o.y],
                    axis.y.atan2(axis.x),
                    v.half_fov_h_rad(),
                    v.max_range_m.min(LOOK_RANGE_M),
                );
            }
        }
    }

    /// What is left for the camera to look at around the chair at `pose`
    /// ([`GridMap::unlooked_bearings`] within [`LOOK_RANGE_M`]): the turn
    /// on the spot each way that brings all of it into view; None without
    /// a map.
    pub(super) fn left_to_see(
        &self,
        pose: crate::msg::Pose2,
        view: &crate::estimation::view::CameraView,
    ) -> Option<LeftToSee> {
        let map = self.map.as_ref()?;
        let odom_from_camera = pose.to_isometry3() * view.base_from_camera;
        let axis = odom_from_camera.rotation * nalgebra::Vector3::z();
        let yaw = axis.y.atan2(axis.x);
        let half = view.half_fov_h_rad();
        let tau = std::f64::consts::TAU;
        let mut left = LeftToSee::default();
        let bearings = map.unlooked_bearings(
            [pose.x_m, pose.y_m],
            LOOK_FROM_M,
            view.max_range_m.min(LOOK_RANGE_M),
            LOOK_BINS,
        );
        for (k, _) in bearings.iter().enumerate().filter(|(_, &l)| l) {
            let off = crate::msg::wrap_angle(tau * k as f64 / LOOK_BINS as f64 - yaw);
            if off.abs() <= half {
                continue;
            }
            left.ccw_rad = left.ccw_rad.max((off - half).rem_euclid(tau));
            left.cw_rad = left.cw_rad.max((-off - half).rem_euclid(tau));
        }
        Some(left)
    }

    /// The person said it is not clear behind while the chair, at `at`
    /// (odom), backed up before a doorway: the passage goes on without
    /// backing up, and so does one begun again from there. Whether a
    /// passage was backing up.
    pub(super) fn refuse_back_up(&mut self, at: [f64; 2]) -> bool {
        let backing = self
            .passage
            .as_mut()
            .is_some_and(|(p, _, _)| p.refuse_back_up());
        if backing {
            self.back_up_refused_at = Some(at);
        }
        backing
    }

    /// The doorway whose passage [`Router::through_doorway`] gave up
    /// (once).
    pub(super) fn take_given_up_door(&mut self) -> Option<doorway::Doorway> {
        self.given_up_door.take()
    }

    /// A new trip: the person's earlier "no" to a back-up no longer holds
    /// (asked afresh, as turns are).
    pub(super) fn new_trip(&mut self) {
        self.back_up_refused_at = None;
    }

    /// The person said no to a turn on the spot: a passage under way
    /// lines up and squares by arcs from now on.
    pub(super) fn refuse_turns(&mut self) {
        if let Some((p, _, _)) = self.passage.as_mut() {
            p.refuse_turns();
            tracing::info!(center = ?p.door.center, phase = ?p.phase, "doorway: turn on the spot refused, lining up on arcs");
        }
    }

    /// Whether the map has something within [`TIGHT_M`] of the chair's
    /// centre line up to 0.6 m ahead.
    pub(super) fn tight_ahead(&mut self, pose: crate::msg::Pose2) -> bool {
        let Some(map) = self.map.as_mut() else {
            return false;
        };
        let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
        [0.0, 0.3, 0.6].iter().any(|d| {
            map.cell([pose.x_m + c * d, pose.y_m + s * d])
                .is_some_and(|i| map.distance_near_m(i, TIGHT_M) < TIGHT_M)
        })
    }

    /// Whether the map has something within [`TIGHT_M`] of `at`.
    fn tight_ahead_at(&mut self, at: [f64; 2]) -> bool {
        self.map.as_mut().is_some_and(|m| {
            m.cell(at)
                .is_some_and(|i| m.distance_near_m(i, TIGHT_M) < TIGHT_M)
        })
    }

    /// Where the local planner should head now on the way from `from`
    /// to `to` (odom): a point `lookahead_m` along the map's way, or the
    /// goal itself when it is near or no way is known.
    pub(super) fn carrot(
        &mut self,
        now: Stamp,
        from: [f64; 2],
        to: [f64; 2],
        within_m: f64,
    ) -> [f64; 2] {
        // somewhere tight, a nearer point: the chair lines up with a
        // doorway before it, rather than cutting the corner
        let look = if self.tight_ahead_at(from) {
            (self.settings.lookahead_m / 2.0).max(0.4)
        } else {
            self.settings.lookahead_m
        };
        if (to[0] - from[0]).hypot(to[1] - from[1]) <= look {
            return to;
        }
        self.ensure_path(now, from, to, within_m);
        self.path
            .as_ref()
            .and_then(|(p, _, _)| p.carrot(from, look))
            .unwrap_or(to)
    }

    /// Plans the way from `from` to `to` when it is old or the goal moved.
    fn ensure_path(&mut self, now: Stamp, from: [f64; 2], to: [f64; 2], within_m: f64) {
        let stale = self.last_plan.is_none_or(|(goal, at)| {
            at.age_at(now) >= REPLAN_EVERY
                || (goal[0] - to[0]).hypot(goal[1] - to[1]) > REPLAN_MOVED_M
        });
        let Some(map) = self.map.as_mut() else {
            return;
        };
        if stale {
            self.planned += 1;
            self.last_plan = Some((to, now));
            self.path = map.path(from, to, within_m).map(|p| (p, to, now));
            if self.path.is_none() {
                self.no_way += 1;
                tracing::debug!(?from, ?to, "map: no way");
            }
        }
    }

    /// A doorway on the way ahead is passed as its own manoeuvre (see
    /// `navigation::doorway`): what to do now, or None (follow the way).
    /// `lasers_base`: the lasers' points now, which measure the jambs.
    pub(super) fn through_doorway(
        &mut self,
        now: Stamp,
        pose: crate::msg::Pose2,
        to: [f64; 2],
        within_m: f64,
        state: SupervisorState,
        lasers_base: &[[f32; 2]],
    ) -> Option<PassageCmd> {
        let from = [pose.x_m, pose.y_m];
        if self.passage.is_none() {
            self.ensure_path(now, from, to, within_m);
            let (path, _, _) = self.path.as_ref()?;
            let map = self.map.as_mut()?;
            let door = doorway::find(map, path, from)?;
            let skipped = self.skip.is_some_and(|(c, until)| {
                now < until && (c[0] - door.center[0]).hypot(c[1] - door.center[1]) < 0.5
            });
            // a gap the chair fits through at a crawl, before it, and the
            // goal beyond it
            if door.width_m < MIN_DOORWAY_M
                || skipped
                || door.local(from).0 > -0.3
                || door.local(to).0 < 0.3
            {
                tracing::debug!(?door, ?from, ?to, skipped, "doorway: not passing");
                return None;
            }
            self.doorways += 1;
            tracing::info!(center = ?door.center, axis_rad = door.axis_rad, width_m = door.width_m, "doorway: passing");
            let mut passage = Passage::new(door, PassageSettings::default());
            if self
                .back_up_refused_at
                .is_some_and(|p| (p[0] - from[0]).hypot(p[1] - from[1]) <= BACK_UP_REFUSED_WITHIN_M)
            {
                // the person said it is not clear behind, here
                passage.refuse_back_up();
                tracing::info!(center = ?door.center, "doorway: backing up refused here before; passing without");
            }
            self.passage = Some((passage, now, None));
        }
        let (passage, since, blocked) = self.passage.as_mut()?;
        let odom_from_base = pose.to_isometry3();
        let lasers_odom: Vec<[f64; 2]> = lasers_base
            .iter()
            .map(|q| {
                let p = odom_from_base * nalgebra::Point3::new(q[0] as f64, q[1] as f64, 0.0);
                [p.x, p.y]
            })
            .collect();
        passage.observe(&lasers_odom);
        // (a step down beyond the doorway holds it as an obstacle does)
        let held = matches!(
            state,
            SupervisorState::Stopped(
                crate::msg::StopReason::Obstacle | crate::msg::StopReason::DropOff
            )
        );
        *blocked = if held { blocked.or(Some(now)) } else { None };
        let out_of_time = since.age_at(now) >= PASSAGE_AT_MOST;
        if (held || out_of_time) && passage.door.local(from).0 > HAND_BACK_HELD_PAST_M {
            // through, the straight way on held (or out of its time
            // there, a search having turned the chair): the planner takes
            // over from here (a turn or an arc the supervisor admits),
            // nothing given up
            tracing::info!(center = ?passage.door.center, along_m = passage.door.local(from).0, held, out_of_time, "doorway: through, beyond it");
            self.end_passage();
            return None;
        }
        // held a while: on the way to the point before it, lined up from
        // here; passing with a corner on a jamb (turned or off the middle
        // line), backed up squaring to line up again; a turn on the spot
        // held (a corner's circle reaches a jamb or something beside the
        // chair), backed up or out to turn, or on a crawl's arcs instead
        let held_a_while = blocked.is_some_and(|b| b.age_at(now) >= LINE_UP_HELD_AFTER);
        let manoeuvre = if !held_a_while {
            None
        } else if passage.held_on_approach(pose) {
            Some("doorway: held on the way to it, lining up from here")
        } else if passage.held_passing(pose) {
            Some("doorway: held passing off the line, backing up to line up again")
        } else if passage.held_turning(pose) {
            Some("doorway: turn on the spot held, backing up to turn or lining up on arcs")
        } else {
            None
        };
        if let Some(what) = manoeuvre {
            let (along_m, left_m) = passage.door.local(from);
            tracing::info!(along_m, left_m, phase = ?passage.phase, "{what}");
            *blocked = None;
        }
        let give_up = blocked.is_some_and(|b| b.age_at(now) >= PASSAGE_BLOCKED_FOR) || out_of_time;
        if give_up {
            self.doorways_given_up += 1;
            let (along_m, left_m) = passage.door.local(from);
            let given_up = DoorwayGivenUp {
                phase: passage.phase.name(),
                width_m: passage.door.width_m,
                along_m,
                left_m,
                heading_err_rad: crate::msg::wrap_angle(pose.theta_rad - passage.door.axis_rad),
                held: blocked.is_some(),
            };
            tracing::warn!(
                center = ?passage.door.center,
                phase = ?passage.phase,
                ?given_up,
                "doorway: given up"
            );
            self.last_given_up = Some(given_up);
            self.given_up_door = Some(passage.door);
            self.skip = Some((passage.door.center, Stamp(now.0 + PASSAGE_SKIP_FOR)));
            self.passage = None;
            return None;
        }
        let phase = passage.phase;
        let cmd = passage.step(pose, to);
        if passage.phase != phase {
            let (along_m, left_m) = passage.door.local(from);
            tracing::debug!(from = ?phase, to = ?passage.phase, along_m, left_m, width_m = passage.door.width_m, "doorway: phase");
        }
        match cmd {
            PassageCmd::Done => {
                self.end_passage();
                None
            }
            cmd => Some(cmd),
        }
    }

    /// Through the doorway: the planner's way again, planned afresh.
    fn end_passage(&mut self) {
        self.passage = None;
        self.path = None;
        self.last_plan = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(ms: u64) -> Stamp {
        Stamp::from_secs_f64(ms as f64 / 1000.0)
    }

    #[test]
    fn a_goal_no_way_reaches_is_planned_again_when_a_replan_is_due_not_every_step() {
        let mut r = Router::new(MapSettings::default());
        // a ring of wall about the goal: no way in
        let mut map = GridMap::new(r.settings, [0.0, 0.0]);
        let ring: Vec<[f64; 2]> = (0..720)
            .map(|k| {
                let a = (k as f64 / 2.0).to_radians();
                [3.0 + 0.6 * a.cos(), 0.6 * a.sin()]
            })
            .collect();
        map.set_camera(&ring, &[]);
        r.map = Some(map);
        let period_ms = REPLAN_EVERY.as_millis() as u64;
        for k in 0..period_ms / 50 {
            // no way: the local planner heads for the goal itself
            assert_eq!(
                r.carrot(at(50 * k), [0.0, 0.0], [3.0, 0.0], 0.1),
                [3.0, 0.0]
            );
        }
        assert_eq!((r.planned, r.no_way), (1, 1));
        r.carrot(at(period_ms), [0.0, 0.0], [3.0, 0.0], 0.1);
        assert_eq!((r.planned, r.no_way), (2, 2));
        // the goal moved: planned at once
        r.carrot(at(period_ms + 50), [0.0, 0.0], [0.0, 3.0], 0.1);
        assert_eq!((r.planned, r.no_way), (3, 2));
        assert!(r.path.is_some());
    }

    /// A map of a wall along x = 2 with a 0.9 m doorway centred on y = 1.
    fn map_with_door(settings: MapSettings) -> GridMap {
        let wall: Vec<[f64; 2]> = (0..=600)
            .map(|k| -6.0 + k as f64 * 0.02)
            .filter(|y| (y - 1.0).abs() > 0.45)
            .flat_map(|y| [[2.0, y], [2.05, y]])
            .collect();
        let mut map = GridMap::new(settings, [0.0, 0.0]);
        map.set_camera(&wall, &[]);
        map
    }

    #[test]
    fn held_or_out_of_time_past_a_doorway_with_its_rear_out_the_planner_takes_over() {
        let start = |r: &mut Router| {
            r.map = Some(map_with_door(r.settings));
            let pose = crate::msg::Pose2 {
                x_m: 0.6,
                y_m: 1.0,
                theta_rad: 0.0,
            };
            let cmd = r.through_doorway(
                at(0),
                pose,
                [4.0, 1.0],
                0.1,
                SupervisorState::Navigating,
                &[],
            );
            assert!(cmd.is_some(), "passing the doorway");
            assert_eq!(r.doorways, 1);
        };
        let held = SupervisorState::Stopped(crate::msg::StopReason::DropOff);
        let at_x = |x_m: f64| crate::msg::Pose2 {
            x_m,
            y_m: 1.0,
            theta_rad: 0.0,
        };
        // held in the doorway (base_link 0.3 m past its middle): the
        // passage goes on
        let mut r = Router::new(MapSettings::default());
        start(&mut r);
        assert!(r
            .through_doorway(at(50), at_x(2.33), [4.0, 1.0], 0.1, held, &[])
            .is_some());
        assert!(r.passage.is_some());
        // held with the chair's rear out of it (0.6 m past): through, the
        // planner takes over, nothing given up
        let mut r = Router::new(MapSettings::default());
        start(&mut r);
        assert_eq!(
            r.through_doorway(at(50), at_x(2.63), [4.0, 1.0], 0.1, held, &[]),
            None
        );
        assert!(r.passage.is_none());
        assert_eq!(r.doorways_given_up, 0);
        // out of the passage's time, the rear out of the doorway and the
        // chair turned across it (a search turned it there): through,
        // nothing given up; still in the doorway: given up
        let turned = |x_m: f64| crate::msg::Pose2 {
            theta_rad: 1.6,
            ..at_x(x_m)
        };
        let late = at(PASSAGE_AT_MOST.as_millis() as u64 + 50);
        for (x_m, given_up) in [(2.63, 0), (2.33, 1)] {
            let mut r = Router::new(MapSettings::default());
            start(&mut r);
            let nav = SupervisorState::Navigating;
            assert_eq!(
                r.through_doorway(late, turned(x_m), [4.0, 1.0], 0.1, nav, &[]),
                None
            );
            assert!(r.passage.is_none());
            assert_eq!(r.doorways_given_up, given_up, "at {x_m}");
            // the one given up says where and how: out of time, not held
            match (given_up, r.last_given_up) {
                (0, None) => {}
                (1, Some(g)) => {
                    assert!(!g.held, "{g:?}");
                    assert!(
                        g.along_m < 0.5 && (g.heading_err_rad - 1.6).abs() < 0.1,
                        "{g:?}"
                    );
                }
                (n, g) => panic!("{n} given up, last {g:?}"),
            }
        }
    }

    /// The person said it is not clear behind for a doorway's back-up: a
    /// passage begun again from where the chair stood then does not back
    /// up (nor ask again); one begun from elsewhere, or on a new trip,
    /// may.
    #[test]
    fn a_back_up_the_person_refused_is_not_asked_again_from_the_same_place() {
        let mut r = Router::new(MapSettings::default());
        r.map = Some(map_with_door(r.settings));
        let pose = |y_m: f64| crate::msg::Pose2 {
            x_m: 0.6,
            y_m,
            theta_rad: 0.0,
        };
        let begin = |r: &mut Router, y_m: f64, ms: u64| {
            r.passage = None;
            r.skip = None;
            let cmd = r.through_doorway(
                at(ms),
                pose(y_m),
                [4.0, 1.0],
                0.1,
                SupervisorState::Navigating,
                &[],
            );
            assert!(cmd.is_some(), "passing the doorway");
            r.passage.as_ref().map(|(p, _, _)| p.backed_up)
        };
        let back_ups = PassageSettings::default().back_ups;
        assert_eq!(begin(&mut r, 1.0, 0), Some(0));
        // not backing up: nothing to refuse, nothing remembered
        assert!(!r.refuse_back_up([0.6, 1.0]));
        assert_eq!(begin(&mut r, 1.0, 50), Some(0));
        // backing up, refused
        if let Some((p, _, _)) = r.passage.as_mut() {
            p.phase = crate::navigation::doorway::Phase::BackUp {
                to_m: -1.6,
                squaring: true,
            };
        }
        assert!(r.refuse_back_up([0.6, 1.0]));
        assert_eq!(begin(&mut r, 1.0, 100), Some(back_ups));
        assert_eq!(begin(&mut r, 1.1, 150), Some(back_ups));
        // from 0.3 m away: backing up allowed again
        assert_eq!(begin(&mut r, 1.3, 200), Some(0));
        // a new trip asks afresh, from the same place too
        r.new_trip();
        assert_eq!(begin(&mut r, 1.0, 250), Some(0));
    }
}
