//! Objects in the odometry frame over time (pure): association by label and
//! 3D overlap, centroid distance or lying inside a track's box (a part of
//! the object, which does not shrink it), a Kalman filter per track on
//! position and extent, confirmation after N hits in a row (no miss where
//! it should have been seen between them), confidence that decays when an
//! object should be visible but is not, last-seen time kept, several
//! instances of a label kept apart and fragments of one object merged.
//! Also the goal: the confirmed track matching the prompt, and an approach
//! pose at a standoff distance on the free side, facing it.

use serde::Serialize;

use crate::msg::Stamp;
use crate::perception::boxes::{Aabb, Object3D, OrientedBox};

/// The tracker's parameters (config `[tracker]`, read directly).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerParams {
    /// Hits in a row (no miss where it should have been seen between
    /// them) before a track is confirmed.
    pub confirm_hits: u32,
    /// Detections whose centroid is farther than this from a track (and
    /// whose box does not overlap it) start a new track, m.
    pub max_center_distance_m: f64,
    /// Same-label tracks whose boxes overlap more than this merge.
    pub merge_iou: f64,
    /// Confidence lost per missed detection where the track should be visible.
    pub miss_decay: f64,
    /// Tracks below this confidence are dropped.
    pub drop_confidence: f64,
    /// Position random walk, m² per second.
    pub process_noise_m2ps: f64,
    /// Detection position noise, m².
    pub measurement_noise_m2: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Track {
    pub id: u64,
    pub label: String,
    pub center_m: [f64; 3],
    pub size_m: [f64; 3],
    /// Position variance (isotropic), m².
    pub variance_m2: f64,
    pub hits: u32,
    pub misses: u32,
    /// Hits in a row, with no miss where it should have been seen between
    /// them: a track is confirmed after `confirm_hits` of them (a false box
    /// now and then that lands near an earlier one, on a wall, is not an
    /// object; a real one is seen frame after frame).
    pub streak: u32,
    pub confidence: f64,
    pub confirmed: bool,
    pub score: f32,
    pub first_seen: Stamp,
    pub last_seen: Stamp,
    /// Whether the latest view should have shown it: seen in it, or in
    /// the view and not hidden behind something (the goal keeper does not
    /// call a goal lost for being hidden).
    pub expected_seen: bool,
    /// The latest view's ground outline: its oriented box (odom). The
    /// upright box above is larger than a turned object (a desk at 30° to
    /// odom's axes: 1.29 × 1.10 m for 1.14 × 0.61 m), most at its corners.
    pub footprint: OrientedBox,
    last_update: Stamp,
}

impl Track {
    pub fn aabb(&self) -> Aabb {
        Aabb {
            min_m: std::array::from_fn(|i| self.center_m[i] - self.size_m[i] / 2.0),
            max_m: std::array::from_fn(|i| self.center_m[i] + self.size_m[i] / 2.0),
        }
    }
}

#[derive(Debug, Clone)]
pub struct Tracker {
    pub params: TrackerParams,
    tracks: Vec<Track>,
    next_id: u64,
    /// The stamp of the newest view updated into the tracker.
    newest_view: Option<Stamp>,
}

/// A detection's box this far outside a track's on any side is still
/// inside it, m.
const PART_MARGIN_M: f64 = 0.05;
/// A detection inside a track's box covering less than this share of its
/// ground area is a part of the object, not a better measure of it.
const PART_AREA_SHARE: f64 = 0.5;

/// Whether `seen` lies inside `track` (within [`PART_MARGIN_M`]) and
/// covers less than [`PART_AREA_SHARE`] of its ground.
fn is_part_of(seen: &Aabb, track: &Aabb) -> bool {
    let inside = (0..3).all(|i| {
        seen.min_m[i] >= track.min_m[i] - PART_MARGIN_M
            && seen.max_m[i] <= track.max_m[i] + PART_MARGIN_M
    });
    let area = |b: &Aabb| (b.max_m[0] - b.min_m[0]) * (b.max_m[1] - b.min_m[1]);
    inside && area(seen) < PART_AREA_SHARE * area(track)
}

fn dist3(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

impl Tracker {
    pub fn new(params: TrackerParams) -> Self {
        Tracker {
            params,
            tracks: Vec::new(),
            next_id: 1,
            newest_view: None,
        }
    }

    pub fn tracks(&self) -> &[Track] {
        &self.tracks
    }

    /// The camera stamp of the newest view updated into the tracker.
    pub fn newest_view(&self) -> Option<Stamp> {
        self.newest_view
    }

    /// One view's objects (already in odom, stamped `stamp`); `visible`
    /// says whether a track should have been seen in it (in view, not
    /// hidden: tracks that should have been seen but were not lose
    /// confidence).
    pub fn update(&mut self, stamp: Stamp, objects: &[Object3D], visible: impl Fn(&Track) -> bool) {
        let p = self.params;
        self.newest_view = self.newest_view.max(Some(stamp));
        // predict: uncertainty grows with time
        for t in &mut self.tracks {
            let dt = t.last_update.age_at(stamp).as_secs_f64();
            t.variance_m2 += p.process_noise_m2ps * dt;
            t.last_update = stamp;
        }
        // candidate pairs (cost = centroid distance), greedy from the cheapest
        let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
        for (di, o) in objects.iter().enumerate() {
            let c = o.aabb.center_m();
            for (ti, t) in self.tracks.iter().enumerate() {
                if t.label != o.label {
                    continue;
                }
                let d = dist3(&c, &t.center_m);
                let ta = t.aabb();
                if d <= p.max_center_distance_m || ta.iou(&o.aabb) > 0.1 || is_part_of(&o.aabb, &ta)
                {
                    pairs.push((d, di, ti));
                }
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut det_used = vec![false; objects.len()];
        let mut trk_used = vec![false; self.tracks.len()];
        for (_, di, ti) in pairs {
            if det_used[di] || trk_used[ti] {
                continue;
            }
            det_used[di] = true;
            trk_used[ti] = true;
            let o = &objects[di];
            let t = &mut self.tracks[ti];
            // a part of the object (a corner seen up close, or at the
            // view's edge) does not shrink its box to that part
            if !is_part_of(&o.aabb, &t.aabb()) {
                let k = t.variance_m2 / (t.variance_m2 + p.measurement_noise_m2);
                let c = o.aabb.center_m();
                let s = o.aabb.size_m();
                for i in 0..3 {
                    t.center_m[i] += k * (c[i] - t.center_m[i]);
                    t.size_m[i] += k * (s[i] - t.size_m[i]);
                }
                t.variance_m2 *= 1.0 - k;
            }
            t.hits += 1;
            t.streak += 1;
            t.misses = 0;
            t.confidence = 1.0 - (1.0 - t.confidence) * 0.5;
            t.confirmed |= t.streak >= p.confirm_hits;
            t.score = t.score.max(o.score);
            t.last_seen = stamp;
            t.expected_seen = true;
            t.footprint = o.obb;
        }
        // misses where the track should have been seen
        for (ti, t) in self.tracks.iter_mut().enumerate() {
            if trk_used[ti] {
                continue;
            }
            t.expected_seen = visible(t);
            if t.expected_seen {
                t.misses += 1;
                t.streak = 0;
                t.confidence -= p.miss_decay;
            }
        }
        self.tracks.retain(|t| t.confidence >= p.drop_confidence);
        // new tracks: several instances of a label stay apart
        for (di, o) in objects.iter().enumerate() {
            if det_used[di] {
                continue;
            }
            self.tracks.push(Track {
                id: self.next_id,
                label: o.label.clone(),
                center_m: o.aabb.center_m(),
                size_m: o.aabb.size_m(),
                variance_m2: p.measurement_noise_m2,
                hits: 1,
                misses: 0,
                streak: 1,
                confidence: 0.5,
                confirmed: p.confirm_hits <= 1,
                score: o.score,
                first_seen: stamp,
                last_seen: stamp,
                expected_seen: true,
                footprint: o.obb,
                last_update: stamp,
            });
            self.next_id += 1;
        }
        self.merge_fragments();
    }

    /// Same-label tracks whose boxes overlap beyond `merge_iou` become one:
    /// the older id, the union of the boxes, the hits added.
    fn merge_fragments(&mut self) {
        let mut i = 0;
        while i < self.tracks.len() {
            let mut j = i + 1;
            while j < self.tracks.len() {
                let (a, b) = (&self.tracks[i], &self.tracks[j]);
                if a.label == b.label && a.aabb().iou(&b.aabb()) > self.params.merge_iou {
                    let b = self.tracks.remove(j);
                    let a = &mut self.tracks[i];
                    let (ba, bb) = (a.aabb(), b.aabb());
                    let lo: [f64; 3] = std::array::from_fn(|k| ba.min_m[k].min(bb.min_m[k]));
                    let hi: [f64; 3] = std::array::from_fn(|k| ba.max_m[k].max(bb.max_m[k]));
                    a.center_m = std::array::from_fn(|k| 0.5 * (lo[k] + hi[k]));
                    a.size_m = std::array::from_fn(|k| hi[k] - lo[k]);
                    a.id = a.id.min(b.id);
                    a.hits += b.hits;
                    a.streak = a.streak.max(b.streak);
                    a.confirmed |= b.confirmed;
                    a.confidence = a.confidence.max(b.confidence);
                    a.first_seen = a.first_seen.min(b.first_seen);
                    a.last_seen = a.last_seen.max(b.last_seen);
                    a.score = a.score.max(b.score);
                    continue;
                }
                j += 1;
            }
            i += 1;
        }
    }

    /// The confirmed track of `label` closest to `from` (odom, x y).
    pub fn goal(&self, label: &str, from: [f64; 2]) -> Option<&Track> {
        self.tracks
            .iter()
            .filter(|t| t.confirmed && t.label.eq_ignore_ascii_case(label))
            .min_by(|a, b| {
                let da = (a.center_m[0] - from[0]).hypot(a.center_m[1] - from[1]);
                let db = (b.center_m[0] - from[0]).hypot(b.center_m[1] - from[1]);
                da.total_cmp(&db)
            })
    }
}

/// A pose on the ground plane: x, y (m) and yaw (rad).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ApproachPose {
    pub x_m: f64,
    pub y_m: f64,
    pub yaw_rad: f64,
}

/// The pose `standoff_m` from the object's box edge, facing its centre: on
/// the side towards `from` when that spot is at least `clearance_m` from
/// every obstacle point, else the nearest free direction around the
/// object (15° steps). None when no side is free.
/// The line from a stopping place to its object keeps this far from every
/// obstacle point but the object's own along the chair's body (from the
/// place to its front edge): the body (half its width) fits there, facing
/// the object, m.
const LINE_OF_SIGHT_M: f64 = 0.36;
/// And this far along the rest, the gap between the chair's front and the
/// object: nothing stands between (a wall beside a doorway the object is
/// seen through), m.
const VIEW_CLEAR_M: f64 = 0.2;
/// An obstacle point this close to the object's box is the object's own, m.
const OWN_POINT_M: f64 = 0.1;
/// The object's own points within this of the line from its centre to
/// the stopping place make its edge there (about the chair's half
/// width), m.
const OWN_FACE_HALF_M: f64 = 0.35;

/// The squared distance from `p` to the segment `a`–`b`.
pub(crate) fn segment_distance_sq(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (ex, ey) = (a[0] + t * dx - p[0], a[1] + t * dy - p[1]);
    ex * ex + ey * ey
}

/// Where the chair stops beside `track`: `standoff_m` from its edge,
/// facing it, on the free side nearest the way from `from`, clear of
/// `obstacles` by `clearance_m` with the object in sight; only places
/// `fits` admits (odom: e.g. where the chair fits on the map of everything
/// it has seen; `&|_| true` for any). `body_m`: from the place to the
/// chair's front edge (of `standoff_m`, from the place to the object).
pub fn approach_pose(
    track: &Track,
    from: [f64; 2],
    standoff_m: f64,
    body_m: f64,
    obstacles: &[[f64; 2]],
    clearance_m: f64,
    fits: &dyn Fn([f64; 2]) -> bool,
) -> Option<ApproachPose> {
    let (cx, cy) = (track.center_m[0], track.center_m[1]);
    let base = (from[1] - cy).atan2(from[0] - cx);
    let reach = |a: f64| {
        // distance from the centre to the box edge along direction a
        let (hx, hy) = (track.size_m[0] / 2.0, track.size_m[1] / 2.0);
        let (c, s) = (a.cos().abs(), a.sin().abs());
        let tx = if c > 1e-9 { hx / c } else { f64::INFINITY };
        let ty = if s > 1e-9 { hy / s } else { f64::INFINITY };
        tx.min(ty)
    };
    // along a from the centre, where the footprint ends (None: the centre
    // is not inside it)
    let footprint_reach = |a: f64| -> Option<f64> {
        let f = &track.footprint;
        if !f.ground_contains([cx, cy]) {
            return None;
        }
        // the centre and the direction in the footprint's own axes
        let [x, y] = f.ground_local([cx, cy]);
        let (c, s) = (f.yaw_rad.cos(), f.yaw_rad.sin());
        let (dx, dy) = (a.cos() * c + a.sin() * s, -a.cos() * s + a.sin() * c);
        let (hl, hw) = (f.size_m[0] / 2.0, f.size_m[1] / 2.0);
        let exit = |p: f64, d: f64, half: f64| {
            if d > 1e-9 {
                (half - p) / d
            } else if d < -1e-9 {
                (-half - p) / d
            } else {
                f64::INFINITY
            }
        };
        Some(exit(x, dx, hl).min(exit(y, dy, hw)))
    };
    let (hx, hy) = (track.size_m[0] / 2.0, track.size_m[1] / 2.0);
    let is_own = |o: &[f64; 2]| {
        (o[0] - cx).abs() - hx <= OWN_POINT_M && (o[1] - cy).abs() - hy <= OWN_POINT_M
    };
    let own: Vec<[f64; 2]> = obstacles.iter().filter(|o| is_own(o)).copied().collect();
    // the box is upright in odom: an object turned in it is smaller than
    // its box, most at the box's corners. Its footprint (the latest view's
    // oriented box) ends where the object does; and where the object's own
    // obstacle points lie across the chair's way in (within its half width
    // of the line from the centre), the farthest of them along the line is
    // its real edge there.
    let edge_along = |a: f64| {
        let (c, s) = (a.cos(), a.sin());
        let seen = own
            .iter()
            .filter(|o| ((o[0] - cx) * s - (o[1] - cy) * c).abs() <= OWN_FACE_HALF_M)
            .map(|o| (o[0] - cx) * c + (o[1] - cy) * s)
            .fold(f64::NEG_INFINITY, f64::max);
        let r = footprint_reach(a).map_or(reach(a), |f| f.min(reach(a)));
        if seen.is_finite() {
            seen.clamp(0.0, r)
        } else {
            r
        }
    };
    for k in 0..=12 {
        for sign in [1.0, -1.0] {
            if k == 0 && sign < 0.0 {
                continue;
            }
            let a = base + sign * (k as f64) * 15f64.to_radians();
            let r = edge_along(a) + standoff_m;
            let (x, y) = (cx + r * a.cos(), cy + r * a.sin());
            // (squared distances: this runs for every candidate over
            // every obstacle point, each control step)
            let clearance_sq = clearance_m.max(0.0).powi(2);
            let free = obstacles.iter().all(|o| {
                let (dx, dy) = (o[0] - x, o[1] - y);
                dx * dx + dy * dy >= clearance_sq
            });
            // and the chair's body and its view of the object clear of
            // everything else
            let edge = [cx + reach(a) * a.cos(), cy + reach(a) * a.sin()];
            let body = body_m.clamp(0.0, r);
            let front = [x - body * a.cos(), y - body * a.sin()];
            let in_sight = || {
                obstacles.iter().all(|o| {
                    is_own(o)
                        || (segment_distance_sq([x, y], front, *o) >= LINE_OF_SIGHT_M.powi(2)
                            && segment_distance_sq(front, edge, *o) >= VIEW_CLEAR_M.powi(2))
                })
            };
            if free && fits([x, y]) && in_sight() {
                return Some(ApproachPose {
                    x_m: x,
                    y_m: y,
                    yaw_rad: (cy - y).atan2(cx - x),
                });
            }
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::Frame;
    use nalgebra::Point3;

    fn obj(label: &str, c: [f32; 3], half: f32) -> Object3D {
        let pts = vec![
            Point3::new(c[0] - half, c[1] - half, c[2] - half),
            Point3::new(c[0] + half, c[1] + half, c[2] + half),
        ];
        Object3D::from_points(label.into(), 0.8, Frame::Odom, pts, None).unwrap()
    }

    fn s(t: f64) -> Stamp {
        Stamp::from_secs_f64(t)
    }

    #[test]
    fn two_chairs_stay_apart_and_confirm() {
        let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
        for k in 0..3 {
            let j = 0.02 * k as f32;
            tr.update(
                s(k as f64 * 0.1),
                &[
                    obj("chair", [2.0 + j, 0.0, 0.4], 0.25),
                    obj("chair", [2.0, 2.0 - j, 0.4], 0.25),
                ],
                |_| true,
            );
        }
        assert_eq!(tr.tracks().len(), 2);
        assert!(tr.tracks().iter().all(|t| t.confirmed && t.hits == 3));
        let g = tr.goal("chair", [0.0, 0.0]).unwrap();
        assert!((g.center_m[1]).abs() < 0.1);
        assert!(tr.goal("table", [0.0, 0.0]).is_none());
        // the filter smooths: the first chair is between its detections
        assert!(tr.tracks()[0].center_m[0] > 2.0 && tr.tracks()[0].center_m[0] < 2.04);
    }

    #[test]
    fn unseen_tracks_decay_only_when_they_should_be_visible() {
        let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
        tr.update(s(0.0), &[obj("sofa", [3.0, 0.0, 0.4], 0.5)], |_| true);
        tr.update(
            s(0.1),
            &[
                obj("sofa", [3.0, 0.0, 0.4], 0.5),
                obj("sofa", [3.0, 1.1, 0.4], 0.5),
            ],
            |_| true,
        );
        // a second sofa a metre away is another instance
        assert_eq!(tr.tracks().len(), 2);
        tr.update(s(0.2), &[obj("sofa", [3.0, 0.0, 0.4], 0.5)], |_| false);
        assert_eq!(tr.tracks().len(), 2);
        // out of view: confidence kept; in view but missed: decays until dropped
        let before = tr.tracks()[0].confidence;
        tr.update(s(0.3), &[], |_| false);
        assert_eq!(tr.tracks()[0].confidence, before);
        assert!(!tr.tracks()[0].expected_seen);
        tr.update(s(0.4), &[], |_| true);
        assert!(tr.tracks()[0].expected_seen);
        assert!(tr.tracks()[0].confidence < before);
        for k in 1..10 {
            tr.update(s(0.4 + 0.1 * k as f64), &[], |_| true);
        }
        assert!(tr.tracks().is_empty());
    }

    #[test]
    fn a_false_box_now_and_then_on_one_wall_is_not_confirmed_but_an_object_seen_in_a_row_is() {
        let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
        // a false "chair" on the wall a metre away, every other view, its
        // boxes within association of each other (scene 444 of the bench)
        let walls = [
            [-0.63, -0.59, 0.70],
            [-0.50, -0.92, 0.68],
            [-0.47, -1.00, 0.64],
        ];
        for (k, c) in walls.iter().enumerate() {
            tr.update(s(k as f64), &[obj("chair", *c, 0.1)], |_| true);
            tr.update(s(k as f64 + 0.5), &[], |_| true);
        }
        let wall = &tr.tracks()[0];
        assert_eq!((wall.hits, wall.streak), (3, 0));
        assert!(!wall.confirmed, "three hits between misses confirmed it");
        assert!(tr.goal("chair", [0.0, 0.0]).is_none());
        // out of view between its hits, nothing is missed: the streak holds
        let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
        for (k, c) in walls.iter().enumerate() {
            tr.update(s(k as f64), &[obj("chair", *c, 0.1)], |_| true);
            tr.update(s(k as f64 + 0.5), &[], |_| false);
        }
        assert!(tr.tracks()[0].confirmed);
        // a real chair missed once, then seen three views in a row: confirmed
        let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
        tr.update(s(0.0), &[obj("chair", [2.0, 0.0, 0.4], 0.25)], |_| true);
        tr.update(s(0.5), &[], |_| true);
        for k in 1..=2 {
            tr.update(
                s(0.5 * k as f64 + 0.5),
                &[obj("chair", [2.0, 0.0, 0.4], 0.25)],
                |_| true,
            );
            assert!(!tr.tracks()[0].confirmed);
        }
        tr.update(s(2.0), &[obj("chair", [2.0, 0.0, 0.4], 0.25)], |_| true);
        assert_eq!(tr.tracks()[0].streak, 3);
        assert!(tr.tracks()[0].confirmed);
        // once confirmed, a miss does not unconfirm it
        tr.update(s(2.5), &[], |_| true);
        assert!(tr.tracks()[0].confirmed);
    }

    #[test]
    fn a_corner_seen_up_close_does_not_shrink_the_box_but_a_box_beyond_it_moves_it() {
        let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
        // a bed seen whole: 1.6 m square about (3, 0)
        for k in 0..3 {
            tr.update(
                s(0.5 * k as f64),
                &[obj("bed", [3.0, 0.0, 0.3], 0.8)],
                |_| true,
            );
        }
        let whole = tr.tracks()[0].clone();
        // then only its near corner, 0.3 m across, many times over
        for k in 3..20 {
            tr.update(
                s(0.5 * k as f64),
                &[obj("bed", [2.35, -0.65, 0.3], 0.15)],
                |_| true,
            );
        }
        let t = &tr.tracks()[0];
        assert_eq!((t.center_m, t.size_m), (whole.center_m, whole.size_m));
        assert_eq!(t.hits, 20);
        assert!(t.last_seen == s(9.5) && t.misses == 0);
        // a detection reaching out of the box is a measure: the box follows
        tr.update(s(10.0), &[obj("bed", [3.3, 0.0, 0.3], 0.8)], |_| true);
        assert!(tr.tracks()[0].center_m[0] > whole.center_m[0] + 0.01);
        // as is one inside it covering most of it (a tighter outline)
        let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
        tr.update(s(0.0), &[obj("bed", [3.0, 0.0, 0.3], 0.8)], |_| true);
        tr.update(s(0.5), &[obj("bed", [3.0, 0.0, 0.3], 0.7)], |_| true);
        assert!(tr.tracks()[0].size_m[0] < 1.6 - 0.01);
    }

    #[test]
    fn overlapping_same_label_tracks_merge() {
        let mut tr = Tracker::new(TrackerParams {
            max_center_distance_m: 0.01,
            ..crate::config::Settings::defaults().tracker
        });
        // two detections of one table, boxes overlapping (IoU ≈ 0.9) but
        // centres apart beyond association: two tracks, then one
        tr.update(
            s(0.0),
            &[
                obj("table", [1.0, 1.0, 0.4], 0.5),
                obj("table", [1.02, 1.0, 0.4], 0.5),
            ],
            |_| true,
        );
        assert_eq!(tr.tracks().len(), 1);
        assert_eq!(tr.tracks()[0].hits, 2);
    }

    /// The confirmed track of one box `label` of half size `half` about
    /// `c`, seen once.
    fn one_track(label: &str, c: [f32; 3], half: f32) -> Track {
        let mut tr = Tracker::new(TrackerParams {
            confirm_hits: 1,
            ..crate::config::Settings::defaults().tracker
        });
        tr.update(s(0.0), &[obj(label, c, half)], |_| true);
        tr.goal(label, [0.0, 0.0]).unwrap().clone()
    }

    #[test]
    fn approach_pose_faces_the_object_from_the_free_side() {
        let t = one_track("chair", [3.0, 0.0, 0.4], 0.25);
        let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &[], 0.4, &|_| true).unwrap();
        assert!(
            (p.x_m - (3.0 - 0.25 - 0.6)).abs() < 1e-6
                && p.y_m.abs() < 1e-6
                && p.yaw_rad.abs() < 1e-9
        );
        // something stands there: the next free direction, still facing it
        let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &[[2.15, 0.0]], 0.4, &|_| true).unwrap();
        assert!(p.y_m.abs() > 0.1);
        let to_obj = (0.0 - p.y_m).atan2(3.0 - p.x_m);
        assert!((p.yaw_rad - to_obj).abs() < 1e-9);
        // surrounded: none
        let ring: Vec<[f64; 2]> = (0..72)
            .map(|k| {
                let a = k as f64 * 5f64.to_radians();
                [3.0 + 0.9 * a.cos(), 0.9 * a.sin()]
            })
            .collect();
        assert!(approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &ring, 0.4, &|_| true).is_none());
    }

    #[test]
    fn only_the_chairs_body_needs_room_beside_the_line_to_the_object() {
        let t = one_track("chair", [3.0, 0.0, 0.4], 0.25);
        // a table's corner beside the gap between the chair's front and
        // the object (0.3 m off the line), not beside the chair's body
        let corner = [[2.62, 0.3]];
        let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.2, &corner, 0.4, &|_| true).unwrap();
        assert!(p.y_m.abs() < 1e-6 && (p.x_m - 2.15).abs() < 1e-6, "{p:?}");
        // the body reaching past it: another side
        let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &corner, 0.4, &|_| true).unwrap();
        assert!(p.y_m.abs() > 0.1, "{p:?}");
        // something right on the line in the gap: nothing is seen past it
        let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.2, &[[2.6, 0.05]], 0.4, &|_| true).unwrap();
        assert!(p.y_m.abs() > 0.1, "{p:?}");
    }

    #[test]
    fn approach_pose_stops_at_a_turned_objects_own_outline() {
        // a desk 1.2 × 0.6 m turned 45° about (3, 0): its upright box is
        // 1.27 m square, and towards the chair at the origin the desk
        // ends 0.42 m from its centre, the box 0.64 m
        let yaw = 45f64.to_radians();
        let mut pts = Vec::new();
        for i in 0..=24 {
            for j in 0..=12 {
                for z in [0.0f32, 0.75] {
                    let (l, w) = (-0.6 + 0.05 * i as f64, -0.3 + 0.05 * j as f64);
                    pts.push(Point3::new(
                        (3.0 + l * yaw.cos() - w * yaw.sin()) as f32,
                        (l * yaw.sin() + w * yaw.cos()) as f32,
                        z,
                    ));
                }
            }
        }
        let desk = Object3D::from_points("desk".into(), 0.8, Frame::Odom, pts, None).unwrap();
        let mut tr = Tracker::new(TrackerParams {
            confirm_hits: 1,
            ..crate::config::Settings::defaults().tracker
        });
        tr.update(s(0.0), &[desk], |_| true);
        let t = tr.goal("desk", [0.0, 0.0]).unwrap().clone();
        assert!((t.size_m[0] - 0.9 * 2f64.sqrt()).abs() < 0.01, "{t:?}");
        let edge = 0.3 * 2f64.sqrt();
        let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &[], 0.4, &|_| true).unwrap();
        assert!(
            (p.x_m - (3.0 - edge - 0.6)).abs() < 0.01 && p.y_m.abs() < 1e-6,
            "{p:?}"
        );
        // something low in front of it, inside its upright box but not in
        // its outline: the desk's edge all the same
        let low = [[2.45, -0.05], [2.45, 0.05]];
        let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &low, 0.4, &|_| true).unwrap();
        assert!(
            (p.x_m - (3.0 - edge - 0.6)).abs() < 0.01 && p.y_m.abs() < 1e-6,
            "{p:?}"
        );
    }

    #[test]
    fn approach_pose_stops_at_the_objects_own_points_inside_its_box() {
        // a box 1 m square about (3, 0): the object turned in it, its face
        // towards the chair seen by the lasers 0.3 m inside the box
        let t = one_track("desk", [3.0, 0.0, 0.4], 0.5);
        let face: Vec<[f64; 2]> = (-3..=3).map(|k| [2.8, k as f64 * 0.1]).collect();
        let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &face, 0.4, &|_| true).unwrap();
        assert!((p.x_m - (2.8 - 0.6)).abs() < 1e-6, "{p:?}");
        // its points beside the way in, or nothing seen: the box's edge
        let aside: Vec<[f64; 2]> = vec![[2.8, 0.45]];
        let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &aside, 0.4, &|_| true).unwrap();
        assert!((p.x_m - (2.5 - 0.6)).abs() < 1e-6, "{p:?}");
        // a point outside the box (0.1 m short of it) is not the object's
        // edge: never beyond the box
        let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &[[2.45, 0.0]], 0.3, &|_| true).unwrap();
        assert!((p.x_m - (2.5 - 0.6)).abs() < 1e-6, "{p:?}");
    }
}
