//! Turning on the spot sweeps the chair's rear corners through the space
//! behind it, which the lasers never see now: they look forward from the
//! front corners (240° each), and the chair's own back and its user hide
//! the rest. So a turn on the spot needs the rear *seen*, one of two ways:
//!
//! - remembered: the blind sector behind the chair (±`blind_half_angle`
//!   about straight back, from base_link) was inside the lasers' view from
//!   about here (within `near_m`) in the last `memory`, and what they saw
//!   there is remembered (laser points in `odom` within `points_radius_m`,
//!   for the turn check). A chair that drove forward to here has seen its
//!   rear; one that just woke up has not.
//! - vouched: the person in the chair (or the carer) said it is clear
//!   behind ("yes" to the chair's question), for this spot (within
//!   [`TURN_WORD_WITHIN_M`]: what they looked at is the corners' circle
//!   there) and `confirm_for`.
//!
//! Otherwise the supervisor refuses the turn (`RearUnseen`) and the chair
//! asks. The same word, asked as "is it clear around me?", vouches for
//! the floor all round the turn where the camera never saw it (drop-offs
//! that may lie out of its view, `FloorUnseen`): a chair that starts
//! facing a step down has not seen the floor just before its front.
//! Pure: scans with the chair's pose and the time in.

use std::cmp::Ordering::Greater;
use std::collections::VecDeque;
use std::time::Duration;

use crate::msg::{hypot_cmp, Pose2, Stamp};

/// Config `[safety]` (rear keys).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RearSettings {
    /// Half the angle of the blind sector about straight back.
    pub blind_half_angle_rad: f64,
    /// Half the lasers' seen sector about straight ahead (the rest of the
    /// circle is blind).
    pub seen_half_angle_rad: f64,
    /// How far from here a past view still counts, metres.
    pub near_m: f64,
    /// How long a past view (and the points it saw) counts.
    pub memory: Duration,
    /// How long the person's "clear behind" counts, at this spot.
    pub confirm_for: Duration,
    /// Laser points kept this close to the chair, metres.
    pub points_radius_m: f64,
}

impl Default for RearSettings {
    fn default() -> Self {
        RearSettings {
            blind_half_angle_rad: 60f64.to_radians(),
            seen_half_angle_rad: 120f64.to_radians(),
            near_m: 0.15,
            memory: Duration::from_secs(30),
            confirm_for: Duration::from_secs(60),
            points_radius_m: 1.5,
        }
    }
}

/// What the supervisor needs about the rear now.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RearView {
    /// The blind sector was seen (remembered) or vouched for.
    pub seen: bool,
    /// Seen for a reverse: seen, or the person said it is clear for
    /// backing up along the line the chair is on.
    pub reverse_seen: bool,
    /// The person said it is clear all around the chair, here: a turn on
    /// the spot may sweep floor the camera never saw.
    pub around_vouched: bool,
    /// Remembered laser points near the chair, in `base_link` now.
    pub points_base: Vec<[f32; 2]>,
}

#[derive(Debug, Clone)]
pub struct RearWatch {
    pub settings: RearSettings,
    /// Where the lasers looked from: (stamp, pose), thinned.
    views: VecDeque<(Stamp, Pose2)>,
    /// Laser points in odom on a 5 cm grid, each cell's newest, with the
    /// stamp of the scan that last saw it: a wall seen scan after scan is
    /// remembered for `memory` after the last scan that saw it, not
    /// forgotten `memory` after the first while the chair still turns
    /// beside it.
    points: std::collections::BTreeMap<(i64, i64), (Stamp, [f64; 2])>,
    confirmed: Option<(Stamp, Pose2)>,
    /// Whether that word was for all around the chair, not only behind.
    confirmed_around: bool,
    /// Where the person said it is clear all around, and when (the
    /// newest [`MAX_FLOOR_VOUCHED`]).
    floor_vouched: VecDeque<(Stamp, Pose2)>,
    /// The person's word for backing up from a pose: when, from where,
    /// and how far straight back it holds (m). Not for a turn: they
    /// looked at the strip behind, not at the circle the corners sweep.
    confirmed_back: Option<(Stamp, Pose2, f64)>,
}

/// The person's "clear around me" holds for the floor within this of
/// base_link where it was said: the circle the corners sweep turning on
/// the spot (0.65 m) and a margin, m.
pub const AROUND_VOUCHED_M: f64 = 0.70;

/// The person's "clear behind" for backing up holds this far straight
/// back from where it was said (base_link; a doorway's back-up is 0.4 m at
/// most), and not beyond: the question says how far ("up to half a
/// metre"), and a reverse held at this end stops within the rest, m.
pub const BACK_UP_VOUCHED_M: f64 = 0.45;

/// The person's words for the floor around the chair, kept at most.
const MAX_FLOOR_VOUCHED: usize = 32;

const CELL_M: f64 = 0.05;
/// The person's word for backing up holds facing within this of the
/// chair's heading when they gave it, and with base_link within
/// [`BACKING_ASIDE_M`] of the line straight back from there, rad and m:
/// they looked at the strip behind, the chair's width and 0.05 m a side,
/// and turned 0.05 rad over the 0.45 m the rear corners reach 0.023 m
/// aside, 0.043 m with the line's 0.02 m.
const BACKING_HEADING_RAD: f64 = 0.05;
const BACKING_ASIDE_M: f64 = 0.02;
/// The person's word for a turn on the spot holds with base_link this
/// near where they gave it, m: they looked at the circle the corners
/// sweep there (0.65 m), to [`AROUND_VOUCHED_M`].
pub const TURN_WORD_WITHIN_M: f64 = 0.04;
/// A new view is kept when the chair turned this much (or moved `near_m`/2).
const VIEW_STEP_RAD: f64 = 0.09;
/// Remembered points this far inside the edge of the lasers' seen sector
/// (about base_link; the lasers look from the front corners) are left to
/// the live scan.
const IN_SIGHT_MARGIN_RAD: f64 = 0.35;
/// The blind sector is checked every this many radians.
const CHECK_STEP_RAD: f64 = 0.05;

fn wrap(a: f64) -> f64 {
    crate::msg::wrap_angle(a)
}

impl RearWatch {
    pub fn new(settings: RearSettings) -> Self {
        RearWatch {
            settings,
            views: VecDeque::new(),
            points: Default::default(),
            confirmed: None,
            confirmed_around: false,
            floor_vouched: VecDeque::new(),
            confirmed_back: None,
        }
    }

    /// A merged scan at `stamp` seen from `pose` (odom), its points in
    /// `base_link`.
    pub fn on_scan(&mut self, stamp: Stamp, pose: Pose2, points_base: &[[f32; 2]]) {
        self.forget(stamp, pose);
        let keep = self.views.back().is_none_or(|(_, p)| {
            wrap(p.theta_rad - pose.theta_rad).abs() >= VIEW_STEP_RAD
                || (p.x_m - pose.x_m).hypot(p.y_m - pose.y_m) >= self.settings.near_m / 2.0
        });
        if keep {
            self.views.push_back((stamp, pose));
        }
        let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
        for q in points_base {
            let (x, y) = (q[0] as f64, q[1] as f64);
            if hypot_cmp(x, y, self.settings.points_radius_m) == Some(Greater) {
                continue;
            }
            let p = [pose.x_m + c * x - s * y, pose.y_m + s * x + c * y];
            let cell = (
                (p[0] / CELL_M).floor() as i64,
                (p[1] / CELL_M).floor() as i64,
            );
            self.points.insert(cell, (stamp, p));
        }
    }

    /// The person said it is clear behind, with the chair at `pose`.
    pub fn confirm(&mut self, stamp: Stamp, pose: Pose2) {
        self.confirmed = Some((stamp, pose));
        self.confirmed_around = false;
    }

    /// The person said it is clear all around the chair (behind it and
    /// the floor the corners sweep), with the chair at `pose`.
    pub fn confirm_around(&mut self, stamp: Stamp, pose: Pose2) {
        self.confirmed = Some((stamp, pose));
        self.confirmed_around = true;
        self.floor_vouched
            .retain(|(t, _)| t.age_at(stamp) <= self.settings.confirm_for);
        if self.floor_vouched.len() == MAX_FLOOR_VOUCHED {
            self.floor_vouched.pop_front();
        }
        self.floor_vouched.push_back((stamp, pose));
    }

    /// Where (odom) the person said it is clear around the chair within
    /// `confirm_for`: the floor within [`AROUND_VOUCHED_M`] of each needs
    /// no new word, wherever the chair turns.
    pub fn floor_vouched_at(&self, now: Stamp) -> impl Iterator<Item = [f64; 2]> + '_ {
        self.floor_vouched
            .iter()
            .filter(move |(t, _)| t.age_at(now) <= self.settings.confirm_for)
            .map(|(_, at)| [at.x_m, at.y_m])
    }

    /// The person said it is clear behind for backing up `back_m`
    /// straight from `pose`: the word holds for a reverse along that
    /// line ([`RearView::reverse_seen`]), not for a turn.
    pub fn confirm_backing(&mut self, stamp: Stamp, pose: Pose2, back_m: f64) {
        self.confirmed_back = Some((stamp, pose, back_m.max(0.0)));
    }

    fn forget(&mut self, now: Stamp, pose: Pose2) {
        let s = self.settings;
        while self
            .views
            .front()
            .is_some_and(|(t, _)| t.age_at(now) > s.memory)
        {
            self.views.pop_front();
        }
        let radius = s.points_radius_m + 1.0;
        self.points.retain(|_, (t, p)| {
            t.age_at(now) <= s.memory && (p[0] - pose.x_m).hypot(p[1] - pose.y_m) <= radius
        });
    }

    fn near(&self, a: &Pose2, b: &Pose2) -> bool {
        (a.x_m - b.x_m).hypot(a.y_m - b.y_m) <= self.settings.near_m
    }

    /// Whether the person said it is clear behind (a look that sees a
    /// step down too), and that holds at `pose` now.
    pub fn vouched_at(&self, now: Stamp, pose: &Pose2) -> bool {
        self.vouched(now, pose)
    }

    /// Whether the person said it is clear all around the chair, and
    /// that holds at `pose` now.
    pub fn around_vouched_at(&self, now: Stamp, pose: &Pose2) -> bool {
        self.confirmed_around && self.vouched(now, pose)
    }

    /// Whether the person's "clear behind" holds at `pose` now.
    fn vouched(&self, now: Stamp, pose: &Pose2) -> bool {
        self.confirmed.is_some_and(|(t, p)| {
            t.age_at(now) <= self.settings.confirm_for
                && (p.x_m - pose.x_m).hypot(p.y_m - pose.y_m) <= TURN_WORD_WITHIN_M
        })
    }

    /// Whether the person's word for backing up holds at `pose`: within
    /// [`BACKING_ASIDE_M`] of the line straight back from where they gave
    /// it and no further back than its length, facing within
    /// [`BACKING_HEADING_RAD`] of the way it faced then (turned further or
    /// further aside, its rear would back into space they did not look
    /// at).
    fn vouched_backing(&self, now: Stamp, pose: &Pose2) -> bool {
        self.confirmed_back.is_some_and(|(t, p, back_m)| {
            if t.age_at(now) > self.settings.confirm_for
                || wrap(pose.theta_rad - p.theta_rad).abs() > BACKING_HEADING_RAD
            {
                return false;
            }
            let (c, s) = (p.theta_rad.cos(), p.theta_rad.sin());
            let behind = -(c * (pose.x_m - p.x_m) + s * (pose.y_m - p.y_m));
            if behind > back_m {
                // past the line's end: the person did not look there
                return false;
            }
            // (forward of where it was said: its own trail)
            let aside = -s * (pose.x_m - p.x_m) + c * (pose.y_m - p.y_m);
            aside.abs() <= BACKING_ASIDE_M
        })
    }

    /// Whether every direction of the blind sector behind `pose` was in
    /// the lasers' view from about here within the memory.
    fn remembered(&self, now: Stamp, pose: &Pose2) -> bool {
        let s = self.settings;
        let views: Vec<&Pose2> = self
            .views
            .iter()
            .filter(|(t, p)| t.age_at(now) <= s.memory && self.near(p, pose))
            .map(|(_, p)| p)
            .collect();
        if views.is_empty() {
            return false;
        }
        let back = pose.theta_rad + std::f64::consts::PI;
        let n = (2.0 * s.blind_half_angle_rad / CHECK_STEP_RAD).ceil() as usize;
        (0..=n).all(|k| {
            let dir = back - s.blind_half_angle_rad
                + k as f64 * (2.0 * s.blind_half_angle_rad / n as f64);
            views
                .iter()
                .any(|v| wrap(dir - v.theta_rad).abs() < s.seen_half_angle_rad)
        })
    }

    /// The rear as the supervisor needs it at `now`, the chair at `pose`.
    pub fn view(&self, now: Stamp, pose: Pose2) -> RearView {
        let seen = self.vouched(now, &pose) || self.remembered(now, &pose);
        let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
        RearView {
            seen,
            reverse_seen: seen || self.vouched_backing(now, &pose),
            around_vouched: self.around_vouched_at(now, &pose),
            // only what lies out of the lasers' sight now: where they look,
            // the live scan says what is there (a person who walked past
            // in front no longer holds the chair)
            points_base: self
                .points
                .values()
                .filter(|(t, _)| t.age_at(now) <= self.settings.memory)
                .map(|(_, p)| {
                    let (dx, dy) = (p[0] - pose.x_m, p[1] - pose.y_m);
                    [(c * dx + s * dy) as f32, (-s * dx + c * dy) as f32]
                })
                .filter(|q| {
                    (q[1] as f64).atan2(q[0] as f64).abs()
                        > self.settings.seen_half_angle_rad - IN_SIGHT_MARGIN_RAD
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(s: f64) -> Stamp {
        Stamp::from_secs_f64(s)
    }

    fn pose(x: f64, th_deg: f64) -> Pose2 {
        Pose2 {
            x_m: x,
            y_m: 0.0,
            theta_rad: th_deg.to_radians(),
        }
    }

    #[test]
    fn a_chair_that_just_woke_up_has_not_seen_its_rear() {
        let mut w = RearWatch::new(RearSettings::default());
        w.on_scan(at(0.0), pose(0.0, 0.0), &[]);
        assert!(!w.view(at(0.1), pose(0.0, 0.0)).seen);
    }

    #[test]
    fn driving_forward_to_here_or_having_turned_here_has() {
        // drove 1 m forward (+x) to here: behind (-x) was ahead at the start
        // — but far away; what counts is the view from about here
        let mut w = RearWatch::new(RearSettings::default());
        for k in 0..=10 {
            w.on_scan(at(k as f64 * 0.1), pose(k as f64 * 0.1, 0.0), &[]);
        }
        assert!(!w.view(at(1.1), pose(1.0, 0.0)).seen);
        // here, facing back the way it came, then turned to face +x again
        let mut w = RearWatch::new(RearSettings::default());
        w.on_scan(at(0.0), pose(1.0, 180.0), &[]);
        w.on_scan(at(1.0), pose(1.0, 0.0), &[]);
        assert!(w.view(at(1.1), pose(1.0, 0.0)).seen);
        // a view from 0.5 m away does not count, nor one older than the memory
        assert!(!w.view(at(1.1), pose(1.5, 0.0)).seen);
        assert!(!w.view(at(40.0), pose(1.0, 0.0)).seen);
    }

    #[test]
    fn a_half_turn_seen_covers_only_part_of_the_sector() {
        let mut w = RearWatch::new(RearSettings::default());
        // facing +90°, then 0°: back (180° ± 60°) was seen from +90° up to
        // 210°; 210..240° never
        w.on_scan(at(0.0), pose(0.0, 90.0), &[]);
        w.on_scan(at(0.5), pose(0.0, 0.0), &[]);
        assert!(!w.view(at(0.6), pose(0.0, 0.0)).seen);
        w.on_scan(at(0.7), pose(0.0, -90.0), &[]);
        w.on_scan(at(0.8), pose(0.0, 0.0), &[]);
        assert!(w.view(at(0.9), pose(0.0, 0.0)).seen);
    }

    #[test]
    fn the_persons_word_vouches_for_this_spot_for_a_while() {
        let mut w = RearWatch::new(RearSettings::default());
        w.confirm(at(0.0), pose(0.0, 0.0));
        // turning on the spot keeps it
        assert!(w.view(at(5.0), pose(0.0, 120.0)).seen);
        assert!(!w.view(at(5.0), pose(0.5, 0.0)).seen, "another spot");
        // the person looked at the corners' circle here (0.65 m, to 0.70
        // m): a few centimetres off it still lies inside, 0.1 m off not
        assert!(w.view(at(5.0), pose(0.03, 0.0)).seen, "a creep");
        assert!(!w.view(at(5.0), pose(0.1, 0.0)).seen, "0.1 m off");
        assert!(!w.view(at(61.0), pose(0.0, 0.0)).seen, "expired");
        // a word for behind is not one for all around
        assert!(!w.view(at(5.0), pose(0.0, 0.0)).around_vouched);
    }

    #[test]
    fn the_persons_word_for_all_around_vouches_for_the_floor_too_here_for_a_while() {
        let mut w = RearWatch::new(RearSettings::default());
        w.confirm_around(at(0.0), pose(0.0, 0.0));
        let v = w.view(at(5.0), pose(0.0, 120.0));
        assert!(v.seen && v.around_vouched);
        assert!(
            !w.view(at(5.0), pose(0.5, 0.0)).around_vouched,
            "another spot"
        );
        assert!(!w.view(at(61.0), pose(0.0, 0.0)).around_vouched, "expired");
        // a later word for behind only replaces it
        w.confirm(at(6.0), pose(0.0, 0.0));
        let v = w.view(at(7.0), pose(0.0, 0.0));
        assert!(v.seen && !v.around_vouched);
    }

    /// The word for all around vouches for the floor within its circle
    /// wherever the chair is later (each spot's floor stays vouched for
    /// the word's time), not beyond it, and not after that time.
    #[test]
    fn the_persons_word_for_all_around_holds_for_the_floor_there_wherever_the_chair_turns() {
        let mut w = RearWatch::new(RearSettings::default());
        // whether the floor at `p` (odom) lies within the word's circle
        let vouched = |w: &RearWatch, now: Stamp, p: [f64; 2]| {
            w.floor_vouched_at(now)
                .any(|at| (p[0] - at[0]).hypot(p[1] - at[1]) <= AROUND_VOUCHED_M)
        };
        assert!(!vouched(&w, at(1.0), [0.6, 0.0]));
        w.confirm_around(at(0.0), pose(0.0, 0.0));
        w.confirm_around(at(10.0), pose(2.0, 90.0));
        for p in [[0.6, 0.0], [0.0, -0.69], [2.0, 0.65]] {
            assert!(vouched(&w, at(20.0), p), "{p:?}");
        }
        for p in [[0.0, 0.75], [1.0, 0.0], [2.0, 0.75]] {
            assert!(!vouched(&w, at(20.0), p), "{p:?}");
        }
        // a word for behind only leaves the floor's word as it was
        w.confirm(at(30.0), pose(0.0, 0.0));
        assert!(vouched(&w, at(31.0), [0.6, 0.0]));
        // each word for its time
        assert!(!vouched(&w, at(61.0), [0.6, 0.0]));
        assert!(vouched(&w, at(61.0), [2.0, 0.65]));
        assert!(!vouched(&w, at(71.0), [2.0, 0.65]));
    }

    #[test]
    fn the_persons_word_for_backing_up_holds_along_the_line_behind_for_a_reverse_only() {
        let mut w = RearWatch::new(RearSettings::default());
        w.confirm_backing(at(0.0), pose(1.0, 0.0), 0.45);
        for x in [1.0, 0.8, 0.6] {
            let v = w.view(at(5.0), pose(x, 0.0));
            assert!(v.reverse_seen, "at {x}");
            // they looked at the strip behind, not the corners' circle
            assert!(!v.seen, "at {x}");
        }
        // beyond the line's end (not even a few centimetres: the person
        // looked as far as the question said), beside it, or expired
        assert!(!w.view(at(5.0), pose(0.3, 0.0)).reverse_seen);
        assert!(!w.view(at(5.0), pose(0.5, 0.0)).reverse_seen);
        assert!(w.view(at(5.0), pose(0.56, 0.0)).reverse_seen);
        let aside = Pose2 {
            y_m: 0.3,
            ..pose(0.8, 0.0)
        };
        assert!(!w.view(at(5.0), aside).reverse_seen);
        assert!(!w.view(at(61.0), pose(0.8, 0.0)).reverse_seen);
        // turned away from the way it faced: its rear backs elsewhere
        assert!(w.view(at(5.0), pose(0.8, 2.0)).reverse_seen);
        assert!(!w.view(at(5.0), pose(0.8, 8.0)).reverse_seen);
        // a centimetre or two aside of the line: the strip they looked at
        // is the chair's width and 0.05 m a side
        let just_aside = Pose2 {
            y_m: 0.015,
            ..pose(0.8, 0.0)
        };
        assert!(w.view(at(5.0), just_aside).reverse_seen);
        let aside = Pose2 {
            y_m: 0.05,
            ..pose(0.8, 0.0)
        };
        assert!(!w.view(at(5.0), aside).reverse_seen);
        // a word for a turn holds for both at its spot
        w.confirm(at(10.0), pose(2.0, 0.0));
        let v = w.view(at(11.0), pose(2.0, 0.0));
        assert!(v.seen && v.reverse_seen);
    }

    #[test]
    fn laser_points_are_remembered_where_they_were() {
        let mut w = RearWatch::new(RearSettings::default());
        // a wall 0.8 m ahead while facing back
        w.on_scan(at(0.0), pose(0.0, 180.0), &[[0.8, 0.0], [3.0, 0.0]]);
        let v = w.view(at(1.0), pose(0.0, 0.0));
        // now behind: at -0.8 m; the far point is not kept
        assert_eq!(v.points_base.len(), 1);
        assert!((v.points_base[0][0] + 0.8).abs() < 1e-3, "{v:?}");
        assert!(w.view(at(31.0), pose(0.0, 0.0)).points_base.is_empty());
        // seen scan after scan (facing it, 0 s to 20 s), then turned away
        // from: remembered for the memory after the last scan that saw it
        let mut w = RearWatch::new(RearSettings::default());
        for k in 0..=200 {
            w.on_scan(at(0.1 * k as f64), pose(0.0, 180.0), &[[0.8, 0.0]]);
        }
        let v = w.view(at(31.0), pose(0.0, 0.0));
        assert_eq!(v.points_base.len(), 1, "{v:?}");
        assert!((v.points_base[0][0] + 0.8).abs() < 1e-3, "{v:?}");
        assert!(w.view(at(50.5), pose(0.0, 0.0)).points_base.is_empty());
    }

    #[test]
    fn what_the_lasers_see_now_is_left_to_the_live_scan() {
        let mut w = RearWatch::new(RearSettings::default());
        // a person 0.7 m ahead, then gone from the scan
        w.on_scan(at(0.0), pose(0.0, 0.0), &[[0.7, 0.0], [0.5, 0.5]]);
        w.on_scan(at(0.1), pose(0.0, 0.0), &[]);
        assert!(w.view(at(0.2), pose(0.0, 0.0)).points_base.is_empty());
        // the same points after a half turn lie behind: remembered
        let v = w.view(at(0.2), pose(0.0, 180.0));
        assert_eq!(v.points_base.len(), 2, "{v:?}");
        // beside the chair, at the edge of the lasers' sight (110° off
        // ahead, within the margin): kept as well
        let v = w.view(at(0.2), pose(0.0, 110.0));
        assert!(v.points_base.iter().any(|q| q[1] < 0.0), "{v:?}");
    }
}
