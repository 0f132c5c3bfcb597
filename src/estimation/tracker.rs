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
    /// The latest whole view's ground outline (a part of the object seen
    /// up close leaves it): its oriented box (odom). The
    /// upright box above is larger than a turned object (a desk at 30° to
    /// odom's axes: 1.29 × 1.10 m for 1.14 × 0.61 m), most at its corners.
    pub footprint: OrientedBox,
    last_update: Stamp,
}

/// An object's ground outline (odom): its ground outline (`footprint`,
/// oriented) where the box's centre lies in it; else its upright box
/// (`center_m`, `size_m`, yaw 0), larger than a turned object (most at
/// the corners). The place beside an object, the places along its sides
/// and the goal keeper's arrival all measure from it.
pub fn outline(center_m: [f64; 3], size_m: [f64; 3], footprint: &OrientedBox) -> OrientedBox {
    if footprint.ground_contains([center_m[0], center_m[1]]) {
        *footprint
    } else {
        OrientedBox {
            center_m,
            size_m,
            yaw_rad: 0.0,
        }
    }
}

impl Track {
    /// Its ground outline (see [`outline`]).
    pub fn outline(&self) -> OrientedBox {
        outline(self.center_m, self.size_m, &self.footprint)
    }

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
            // view's edge) does not shrink its box, nor its outline, to
            // that part
            let part = is_part_of(&o.aabb, &t.aabb());
            if !part {
                let k = t.variance_m2 / (t.variance_m2 + p.measurement_noise_m2);
                let c = o.aabb.center_m();
                let s = o.aabb.size_m();
                for i in 0..3 {
                    t.center_m[i] += k * (c[i] - t.center_m[i]);
                    t.size_m[i] += k * (s[i] - t.size_m[i]);
                }
                t.variance_m2 *= 1.0 - k;
                t.footprint = o.obb;
            }
            t.hits += 1;
            t.streak += 1;
            t.misses = 0;
            t.confidence = 1.0 - (1.0 - t.confidence) * 0.5;
            t.confirmed |= t.streak >= p.confirm_hits;
            t.score = t.score.max(o.score);
            t.last_seen = stamp;
            t.expected_seen = true;
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
        self.goal_where(label, from, |_| true)
    }

    /// The confirmed track of `label` closest to `from` (odom, x y) among
    /// those `keep` keeps.
    pub fn goal_where(
        &self,
        label: &str,
        from: [f64; 2],
        keep: impl Fn(&Track) -> bool,
    ) -> Option<&Track> {
        self.tracks
            .iter()
            .filter(|t| t.confirmed && t.label.eq_ignore_ascii_case(label) && keep(t))
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

/// The place beside an object may be this much nearer its outline than
/// the standoff, m.
const STANDOFF_SLACK_M: f64 = 0.02;

/// Where the chair stops beside `track`: `standoff_m` from its edge,
/// facing it, on the free side nearest the way from `from`, clear of
/// `obstacles` by `clearance_m` with the object in sight; only places
/// `fits` admits (odom: e.g. where the chair fits on the map of everything
/// it has seen; `&|_| true` for any). `body_m`: from the place to the
/// chair's front edge (of `standoff_m`, from the place to the object).
/// The place faces the object's centre from the side towards `from`, else
/// from the nearest direction round it that passes (15° steps); where
/// none does, it is square to a side of the object anywhere along it,
/// the nearest to `from` that passes. None when no place passes.
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
    // from the centre to the upright box's edge along direction a
    let upright = OrientedBox {
        center_m: track.center_m,
        size_m: track.size_m,
        yaw_rad: 0.0,
    };
    let reach = |a: f64| upright.ground_exit_m([cx, cy], a);
    // the outline: the footprint where it holds the centre, else the
    // upright box
    let outline = track.outline();
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
        let r = outline.ground_exit_m([cx, cy], a).min(reach(a));
        // (and whether its own points set it, nearer than the outline)
        if seen.is_finite() && seen < r {
            (seen.max(0.0), true)
        } else {
            (r, false)
        }
    };
    // a place `r` from the object's edge along `out` (unit, from the
    // object to the place), facing `edge`: clear of every obstacle point
    // by `clearance_m`, admitted by `fits`, the chair's body and its view
    // of the object clear of everything else
    let clearance_sq = clearance_m.max(0.0).powi(2);
    let passes = |[x, y]: [f64; 2], r: f64, out: [f64; 2], edge: [f64; 2], yaw_rad: f64| {
        // (squared distances: this runs for every candidate over every
        // obstacle point, each control step)
        let free = obstacles.iter().all(|o| {
            let (dx, dy) = (o[0] - x, o[1] - y);
            dx * dx + dy * dy >= clearance_sq
        });
        let body = body_m.clamp(0.0, r);
        let front = [x - body * out[0], y - body * out[1]];
        let in_sight = || {
            obstacles.iter().all(|o| {
                is_own(o)
                    || (segment_distance_sq([x, y], front, *o) >= LINE_OF_SIGHT_M.powi(2)
                        && segment_distance_sq(front, edge, *o) >= VIEW_CLEAR_M.powi(2))
            })
        };
        (free && fits([x, y]) && in_sight()).then_some(ApproachPose {
            x_m: x,
            y_m: y,
            yaw_rad,
        })
    };
    for k in 0..=12 {
        for sign in [1.0, -1.0] {
            if k == 0 && sign < 0.0 {
                continue;
            }
            let a = base + sign * (k as f64) * 15f64.to_radians();
            let (edge_m, own_edge) = edge_along(a);
            let mut r = edge_m + standoff_m;
            // off the line from the centre, another part of the object
            // can lie nearer than its edge on the line (a sofa's corner,
            // the place at 45° to it): the place moves out until the
            // whole outline is the standoff away (not where the object's
            // own points put its edge inside the outline)
            for _ in 0..if own_edge { 0 } else { 3 } {
                let (x, y) = (cx + r * a.cos(), cy + r * a.sin());
                let short_m = standoff_m - outline.ground_distance_m([x, y]);
                if short_m <= STANDOFF_SLACK_M {
                    break;
                }
                r += short_m;
            }
            let (x, y) = (cx + r * a.cos(), cy + r * a.sin());
            // the chair's body and its view of the object clear of
            // everything else
            let edge = [cx + reach(a) * a.cos(), cy + reach(a) * a.sin()];
            let yaw_rad = (cy - y).atan2(cx - x);
            if let Some(place) = passes([x, y], r, [a.cos(), a.sin()], edge, yaw_rad) {
                return Some(place);
            }
        }
    }
    // none round the centre: square to a side of the object, anywhere
    // along it (a bed or a sofa whose places facing its centre are taken
    // by a low box or a cabinet), the nearest to `from` first
    let mut sides = side_places(&outline, standoff_m);
    sides.sort_by(|a, b| {
        let d = |c: &SidePlace| (c.place[0] - from[0]).hypot(c.place[1] - from[1]);
        d(a).total_cmp(&d(b))
    });
    sides.into_iter().find_map(|c| {
        let yaw_rad = (-c.normal[1]).atan2(-c.normal[0]);
        passes(c.place, standoff_m, c.normal, c.edge, yaw_rad)
    })
}

/// A place square to a side of an object: the place, its outward normal
/// (from the object to the place) and the point of the side it faces.
#[derive(Debug, Clone, Copy)]
struct SidePlace {
    place: [f64; 2],
    normal: [f64; 2],
    edge: [f64; 2],
}

/// Places along the sides of an object's `outline` (see [`outline`])
/// `standoff_m` out from them, every [`SIDE_STEP_M`] along each side,
/// corners included.
fn side_places(outline: &OrientedBox, standoff_m: f64) -> Vec<SidePlace> {
    let center = [outline.center_m[0], outline.center_m[1]];
    let half = [outline.size_m[0] / 2.0, outline.size_m[1] / 2.0];
    let yaw = outline.yaw_rad;
    let (c, s) = (yaw.cos(), yaw.sin());
    let (u, v) = ([c, s], [-s, c]);
    let mut out = Vec::new();
    // each side: its outward normal, the direction along it, the half
    // depth across and the half length along
    for (normal, along, depth, length) in [
        (u, v, half[0], half[1]),
        ([-u[0], -u[1]], v, half[0], half[1]),
        (v, u, half[1], half[0]),
        ([-v[0], -v[1]], u, half[1], half[0]),
    ] {
        if !(depth.is_finite() && length.is_finite()) {
            continue;
        }
        let steps = (2.0 * length / SIDE_STEP_M).ceil().clamp(1.0, 200.0) as usize;
        for i in 0..=steps {
            let t = -length + 2.0 * length * i as f64 / steps as f64;
            let edge = [
                center[0] + depth * normal[0] + t * along[0],
                center[1] + depth * normal[1] + t * along[1],
            ];
            out.push(SidePlace {
                place: [
                    edge[0] + standoff_m * normal[0],
                    edge[1] + standoff_m * normal[1],
                ],
                normal,
                edge,
            });
        }
    }
    out
}

/// The places along an object's side are this far apart, m.
const SIDE_STEP_M: f64 = 0.1;

#[cfg(test)]
#[path = "tracker_tests.rs"]
mod tests;
