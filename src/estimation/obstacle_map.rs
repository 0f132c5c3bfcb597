//! The depth camera's obstacles and drop-offs remembered in `odom`. A
//! level camera sees a 0.3 m box from about 1.4 m away and loses it as the
//! chair comes closer (it drops below the image): the cell stays an
//! obstacle in `odom` and the supervisor keeps stopping before it. A cell
//! is forgotten when the floor is seen there again (what moved away, a
//! person who walked on), when the chair stands on it (nothing can be
//! inside the chair), or when it is farther than the memory radius.
//! Pure: each frame's cells and the chair's pose at its stamp in.

use std::cmp::Ordering::{self, Greater};
use std::collections::{BTreeMap, BTreeSet};

use nalgebra::Isometry3;

use crate::estimation::view::CameraView;
use crate::msg::{hypot_cmp, Pose2};
use crate::perception::depth_obstacles::DepthScan;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellKind {
    Obstacle,
    DropOff,
    /// A drop-off that may lie out of view, where the floor was never
    /// seen ([`DepthScan::drop_offs_unseen_base`]).
    UnseenDropOff,
}

impl CellKind {
    /// What a frame puts in a cell that holds another kind: an obstacle
    /// over a drop-off, a seen drop-off over one that may lie out of view.
    fn rank(self) -> u8 {
        match self {
            CellKind::UnseenDropOff => 0,
            CellKind::DropOff => 1,
            CellKind::Obstacle => 2,
        }
    }
}

/// Cells in `odom`, each with the points the latest frame that saw it put
/// there (a depth frame's cell is its points farthest along ±x and ±y:
/// on the surface and out to its edges, not the cell's centre), at most
/// [`MAX_POINTS_PER_CELL`], again its extremes. With the camera's view
/// known, a cell a frame saw only part of keeps the points that frame
/// could not have seen, each at the lowest height its cell was seen at: a
/// box's near edge that dropped below the image as the chair came closer
/// stays where it was seen (replacing them made the remembered edge
/// recede by up to a cell, and a turn on the spot came within 7 mm of a
/// box in scene 1 of `opennav sim --seed 1`); what the frame could see is
/// replaced, so depth noise does not pile up at a cell's edges, nor does
/// a table's top that a nearer frame sees again.
#[derive(Debug, Clone, PartialEq)]
pub struct ObstacleMap {
    cell_m: f64,
    radius_m: f64,
    cells: Cells,
    view: Option<MapView>,
    /// Cells where the floor was seen (within the radius): a drop-off
    /// that may lie out of view ([`DepthScan::drop_offs_unseen_base`]) is
    /// not put where the floor is known.
    floor_seen: BTreeSet<(i32, i32)>,
    /// Obstacle cells a laser's return landed on ([`ObstacleMap::on_lasers`]),
    /// and those the latest scan's returns landed on (sorted): a cell the
    /// camera puts again keeps its mark only if that scan saw it too
    /// (what the camera sees there now may not be what the lasers saw).
    laser_seen: BTreeSet<(i32, i32)>,
    hit_last_scan: Vec<(i32, i32)>,
    /// Of those the lasers saw: how many scans have passed rays through
    /// the cell since the last that landed a return in it or beside it
    /// ([`ObstacleMap::on_lasers`]).
    unhit_scans: BTreeMap<(i32, i32), u32>,
    /// The lasers' plane above the floor, m (None: not known): a cell
    /// where a frame saw the thing from below it to above it is one the
    /// lasers see too, whether or not a return landed in that very cell.
    laser_plane_m: Option<f64>,
}

/// A thing spans the lasers' plane when a frame saw it this far below
/// and above it, m.
const SPANS_PLANE_BY_M: f64 = 0.1;

/// What a depth frame could see, for [`ObstacleMap::with_view`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapView {
    pub camera: CameraView,
    /// Points farther than this from base_link are not in a frame
    /// (metres).
    pub max_range_m: f64,
}

impl MapView {
    /// Whether the frame taken from `pose` could have seen the point `p`
    /// (odom, at the height its cell was seen lowest): had it still been
    /// there, that frame would have put it in the cell again.
    #[cfg(test)]
    fn could_see(&self, pose: &Pose2, p: &[f64; 3]) -> bool {
        self.could_see_from(pose, &self.camera.camera_from_odom(pose), p)
    }

    /// Whether the frame taken from `pose` (the camera at
    /// `camera_from_odom`, made once for the frame) could have seen the
    /// point `p` (odom, at the height its cell was seen lowest): had it
    /// still been there, that frame would have put it in the cell again.
    fn could_see_from(
        &self,
        pose: &Pose2,
        camera_from_odom: &Isometry3<f64>,
        p: &[f64; 3],
    ) -> bool {
        hypot_cmp(p[0] - pose.x_m, p[1] - pose.y_m, self.max_range_m).is_some_and(Ordering::is_le)
            && self.camera.sees_from(camera_from_odom, p)
    }
}

/// Each cell's kind and points: x, y (odom) and the height at which the
/// point's cell was seen lowest (a drop-off's: the floor, 0).
type Cells = BTreeMap<(i32, i32), (CellKind, Vec<[f64; 3]>)>;

const MAX_POINTS_PER_CELL: usize = 4;

/// Cell `k`'s centre in odom, for cells `cell_m` wide.
fn centre(cell_m: f64, k: (i32, i32)) -> [f64; 2] {
    [(k.0 as f64 + 0.5) * cell_m, (k.1 as f64 + 0.5) * cell_m]
}

/// The points farthest along −x, +x, −y and +y (distinct).
fn extremes(points: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let by = |i: usize, max: bool| {
        points
            .iter()
            .copied()
            .reduce(|a, b| if (b[i] > a[i]) == max { b } else { a })
    };
    let mut out: Vec<[f64; 3]> = Vec::with_capacity(4);
    for p in [by(0, false), by(0, true), by(1, false), by(1, true)]
        .into_iter()
        .flatten()
    {
        if !out.contains(&p) {
            out.push(p);
        }
    }
    out
}

/// The chair's footprint about base_link (metres): cells under it are
/// cleared.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootprintM {
    pub front_m: f64,
    pub rear_m: f64,
    pub half_width_m: f64,
}

impl FootprintM {
    /// How far its farthest corner lies from base_link: the circle a turn
    /// on the spot sweeps.
    pub fn corner_reach_m(&self) -> f64 {
        self.front_m.max(self.rear_m).hypot(self.half_width_m)
    }
}

impl ObstacleMap {
    pub fn new(cell_m: f64, radius_m: f64) -> Self {
        ObstacleMap {
            cell_m,
            radius_m,
            cells: BTreeMap::new(),
            view: None,
            floor_seen: BTreeSet::new(),
            laser_seen: BTreeSet::new(),
            hit_last_scan: Vec::new(),
            unhit_scans: BTreeMap::new(),
            laser_plane_m: None,
        }
    }

    /// The lasers' plane is `height_m` above the floor: a cell a frame saw
    /// something in from below it to above it counts as seen by the
    /// lasers ([`ObstacleMap::on_lasers`] forgets it when their rays later
    /// pass through it): the cells of a person who walked on, seen by the
    /// camera at their side and by the lasers only at their front.
    pub fn with_laser_plane(mut self, height_m: f64) -> Self {
        self.laser_plane_m = Some(height_m);
        self
    }

    /// Keeps, in a cell a frame saw part of, the points outside `view`.
    pub fn with_view(mut self, view: MapView) -> Self {
        self.view = Some(view);
        self
    }

    fn cell(&self, p: [f64; 2]) -> Option<(i32, i32)> {
        let (i, j) = ((p[0] / self.cell_m).floor(), (p[1] / self.cell_m).floor());
        let ok = |v: f64| v.is_finite() && v.abs() < 1e6;
        (ok(i) && ok(j)).then_some((i as i32, j as i32))
    }

    /// Adds one frame seen from `pose` (odom_from_base at the frame's
    /// stamp): seen floor clears, obstacles and drop-offs are set, then
    /// cells under the footprint and beyond the radius are dropped.
    pub fn insert(&mut self, pose: Pose2, scan: &DepthScan, footprint: FootprintM) {
        let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
        let to_odom = |q: &[f32; 2]| {
            let (x, y) = (q[0] as f64, q[1] as f64);
            [pose.x_m + c * x - s * y, pose.y_m + s * x + c * y]
        };
        for q in &scan.floor_base {
            if let Some(k) = self.cell(to_odom(q)) {
                self.cells.remove(&k);
                self.floor_seen.insert(k);
            }
        }
        for q in &scan.drop_offs_base {
            if let Some(k) = self.cell(to_odom(q)) {
                self.floor_seen.remove(&k);
            }
        }
        // where the floor may end out of view: not where it was seen
        let unseen: Vec<[f32; 2]> = scan
            .drop_offs_unseen_base
            .iter()
            .filter(|q| {
                self.cell(to_odom(q))
                    .is_some_and(|k| !self.floor_seen.contains(&k))
            })
            .copied()
            .collect();
        // this frame's points by cell: they replace what the cell held
        // where this frame could see it
        let mut seen = Cells::new();
        let drop_offs = scan
            .drop_offs_base
            .iter()
            .map(|q| ([q[0], q[1]], 0.0, false));
        let unseen = unseen.iter().map(|q| ([q[0], q[1]], 0.0, false));
        // each obstacle point: whether its cell saw the thing across the
        // lasers' plane (its lowest and highest points)
        let tops = (scan.obstacle_tops_m.len() == scan.obstacles_base.len())
            .then_some(&scan.obstacle_tops_m);
        let obstacles = scan.obstacles_base.iter().enumerate().map(|(i, q)| {
            let spans = match (self.laser_plane_m, tops) {
                (Some(plane_m), Some(tops)) => {
                    f64::from(q[2]) < plane_m - SPANS_PLANE_BY_M
                        && f64::from(tops[i]) > plane_m + SPANS_PLANE_BY_M
                }
                _ => false,
            };
            ([q[0], q[1]], q[2], spans)
        });
        // the cells where this frame saw a thing across the lasers' plane
        let mut spans = BTreeSet::new();
        let points = drop_offs
            .map(|(q, z, across)| (q, z, across, CellKind::DropOff))
            .chain(unseen.map(|(q, z, across)| (q, z, across, CellKind::UnseenDropOff)))
            .chain(obstacles.map(|(q, z, across)| (q, z, across, CellKind::Obstacle)));
        for (q, z_m, across, kind) in points {
            let p = to_odom(&q);
            if let Some(k) = self.cell(p) {
                if across {
                    spans.insert(k);
                }
                // one that may lie out of view never replaces what was
                // seen in its cell before
                if kind == CellKind::UnseenDropOff
                    && self.cells.get(&k).is_some_and(|(old, _)| *old != kind)
                {
                    continue;
                }
                let e = seen.entry(k).or_insert((kind, Vec::new()));
                if e.0.rank() < kind.rank() {
                    // an obstacle over a drop-off: the obstacle
                    *e = (kind, Vec::new());
                } else if e.0.rank() > kind.rank() {
                    continue;
                }
                e.1.push([p[0], p[1], z_m as f64]);
            }
        }
        // the camera's transform at this frame, made once when needed
        let mut camera_from_odom: Option<Isometry3<f64>> = None;
        for (k, (kind, mut points)) in seen {
            if let (Some(view), Some((old_kind, old))) = (&self.view, self.cells.get(&k)) {
                // (a cell where the floor was seen now is gone already)
                if *old_kind == kind {
                    let camera_from_odom =
                        camera_from_odom.get_or_insert_with(|| view.camera.camera_from_odom(&pose));
                    points.extend(
                        old.iter()
                            .filter(|p| !view.could_see_from(&pose, camera_from_odom, p)),
                    );
                }
            }
            if points.len() > MAX_POINTS_PER_CELL {
                points = extremes(&points);
            }
            // put again: the lasers saw it if their latest scan did, or
            // would have (it spans their plane)
            if kind == CellKind::Obstacle && spans.contains(&k) {
                self.laser_seen.insert(k);
            } else if self.hit_last_scan.binary_search(&k).is_err() {
                self.laser_seen.remove(&k);
            }
            self.cells.insert(k, (kind, points));
        }
        self.forget(pose, footprint);
    }

    /// Drops the cells under the footprint at `pose` and beyond the
    /// radius; the footprint's cells count as floor seen (the chair stands
    /// on them).
    pub fn forget(&mut self, pose: Pose2, f: FootprintM) {
        let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
        let r = self.radius_m;
        let keep = |p: &[f64; 3]| {
            let (dx, dy) = (p[0] - pose.x_m, p[1] - pose.y_m);
            if hypot_cmp(dx, dy, r) == Some(Greater) {
                return false;
            }
            // in base_link
            let (x, y) = (c * dx + s * dy, -s * dx + c * dy);
            !(x >= -f.rear_m && x <= f.front_m && y.abs() <= f.half_width_m)
        };
        self.cells.retain(|_, (_, points)| {
            points.retain(keep);
            !points.is_empty()
        });
        let cells = &self.cells;
        self.laser_seen.retain(|k| cells.contains_key(k));
        let seen = &self.laser_seen;
        self.unhit_scans.retain(|k, _| seen.contains(k));
        let cell_m = self.cell_m;
        self.floor_seen.retain(|&k| {
            let [x, y] = centre(cell_m, k);
            hypot_cmp(x - pose.x_m, y - pose.y_m, r).is_some_and(Ordering::is_le)
        });
        // the cells whose centres lie under the footprint
        for k in self.cells_within(&pose, f.corner_reach_m()) {
            let [x, y] = pose.base_from_odom(centre(self.cell_m, k));
            if x >= -f.rear_m && x <= f.front_m && y.abs() <= f.half_width_m {
                self.floor_seen.insert(k);
            }
        }
    }

    /// The cells whose centres lie within `radius_m` of `pose`.
    fn cells_within(&self, pose: &Pose2, radius_m: f64) -> Vec<(i32, i32)> {
        let (Some(lo), Some(hi)) = (
            self.cell([pose.x_m - radius_m, pose.y_m - radius_m]),
            self.cell([pose.x_m + radius_m, pose.y_m + radius_m]),
        ) else {
            return Vec::new();
        };
        let cell_m = self.cell_m;
        (lo.0..=hi.0)
            .flat_map(|i| (lo.1..=hi.1).map(move |j| (i, j)))
            .filter(|&k| {
                let [x, y] = centre(cell_m, k);
                hypot_cmp(x - pose.x_m, y - pose.y_m, radius_m).is_some_and(Ordering::is_le)
            })
            .collect()
    }

    /// The centres (odom) of the cells within `radius_m` of `pose` where
    /// no frame saw the floor and nothing is remembered, and the chair has
    /// not stood: what a turn on the spot there would sweep unseen (a box
    /// under the lasers' plane beside the front corner, out of the
    /// camera's view since before the chair came near).
    pub fn unseen_near(&self, pose: &Pose2, radius_m: f64) -> Vec<[f64; 2]> {
        self.cells_within(pose, radius_m)
            .into_iter()
            .filter(|k| !self.floor_seen.contains(k) && !self.cells.contains_key(k))
            .map(|k| centre(self.cell_m, k))
            .collect()
    }

    /// The remembered cells' points in `odom`, of one kind.
    pub fn points(&self, kind: CellKind) -> Vec<[f64; 2]> {
        self.cells
            .values()
            .filter(|(k, _)| *k == kind)
            .flat_map(|(_, p)| p.iter().map(|q| [q[0], q[1]]))
            .collect()
    }

    pub fn len(&self) -> usize {
        self.cells.len()
    }

    /// Obstacle cells the lasers see too (a return landed on them).
    pub fn laser_seen_len(&self) -> usize {
        self.laser_seen.len()
    }

    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }
}

#[path = "obstacle_map_lasers.rs"]
mod lasers;

#[cfg(test)]
mod tests {
    use super::*;

    const F: FootprintM = FootprintM {
        front_m: 0.55,
        rear_m: 0.45,
        half_width_m: 0.35,
    };

    fn at(x: f64, y: f64, th: f64) -> Pose2 {
        Pose2 {
            x_m: x,
            y_m: y,
            theta_rad: th,
        }
    }

    /// Obstacle points seen as low as 5 cm.
    fn scan(obstacles: &[[f32; 2]], floor: &[[f32; 2]]) -> DepthScan {
        scan_at(obstacles, 0.05, floor)
    }

    fn scan_at(obstacles: &[[f32; 2]], z_m: f32, floor: &[[f32; 2]]) -> DepthScan {
        DepthScan {
            obstacles_base: obstacles.iter().map(|p| [p[0], p[1], z_m]).collect(),
            drop_offs_base: Vec::new(),
            floor_base: floor.to_vec(),
            ..Default::default()
        }
    }

    #[test]
    fn a_drop_off_that_may_lie_out_of_view_is_put_only_where_the_floor_was_not_seen() {
        let mut m = ObstacleMap::new(0.05, 4.0);
        let maybe = |at: &[[f32; 2]]| DepthScan {
            drop_offs_unseen_base: at.to_vec(),
            ..Default::default()
        };
        // never seen: a drop-off that may lie there, kept apart from the
        // seen ones
        m.insert(at(0.0, 0.0, 0.0), &maybe(&[[0.6, 0.0]]), F);
        assert_eq!(m.points(CellKind::UnseenDropOff).len(), 1);
        assert!(m.points(CellKind::DropOff).is_empty());
        // the floor seen there (from 1 m back, facing +x): gone, and not
        // put there again; a cell beside it still is
        m.insert(at(-1.0, 0.0, 0.0), &scan(&[], &[[1.625, 0.025]]), F);
        assert!(m.is_empty());
        m.insert(at(0.0, 0.0, 0.0), &maybe(&[[0.6, 0.0], [0.6, 0.2]]), F);
        let drops = m.points(CellKind::UnseenDropOff);
        assert_eq!(drops.len(), 1, "{drops:?}");
        assert!((drops[0][1] - 0.2).abs() < 1e-6);
        // a drop-off seen in that cell makes it unknown floor again, and
        // one seen where one may lie takes its cell
        let seen_drop = DepthScan {
            drop_offs_base: vec![[0.61, 0.01], [0.61, 0.21]],
            ..Default::default()
        };
        m.insert(at(0.0, 0.0, 0.0), &seen_drop, F);
        assert_eq!(m.points(CellKind::DropOff).len(), 2);
        assert!(m.points(CellKind::UnseenDropOff).is_empty());
        let cell = m.cell([0.6, 0.0]).expect("cell");
        assert!(!m.floor_seen.contains(&cell));
        // and a later guess there does not undo what was seen
        m.insert(at(0.0, 0.0, 0.0), &maybe(&[[0.6, 0.0], [0.6, 0.2]]), F);
        assert_eq!(m.points(CellKind::DropOff).len(), 2);
        assert!(m.points(CellKind::UnseenDropOff).is_empty());
    }

    /// Near the chair: the floor no frame saw is reported, not where a
    /// frame saw the floor, something is remembered, or the chair stood.
    #[test]
    fn floor_never_seen_near_the_chair_is_reported_until_seen_or_stood_on() {
        let mut m = ObstacleMap::new(0.05, 4.0);
        let here = at(0.0, 0.0, 0.0);
        let near = |m: &ObstacleMap, p: Pose2| m.unseen_near(&p, 0.8);
        let has = |cells: &[[f64; 2]], q: [f64; 2]| {
            cells
                .iter()
                .any(|c| (c[0] - q[0]).abs() <= 0.025 && (c[1] - q[1]).abs() <= 0.025)
        };
        // nothing seen yet: all round, but not under the chair
        m.forget(here, F);
        let cells = near(&m, here);
        assert!(has(&cells, [0.625, -0.325]) && has(&cells, [-0.525, 0.375]));
        assert!(!has(&cells, [0.025, 0.025]) && !has(&cells, [0.525, -0.325]));
        assert!(cells.iter().all(|c| c[0].hypot(c[1]) <= 0.8));
        // the floor seen ahead of the front corner, a box beside it
        m.insert(here, &scan(&[[0.62, 0.42]], &[[0.625, -0.325]]), F);
        let cells = near(&m, here);
        assert!(!has(&cells, [0.625, -0.325]) && !has(&cells, [0.625, 0.425]));
        assert!(has(&cells, [0.625, -0.225]));
        // where the chair stood 0.5 m on, never reported again
        m.forget(at(0.5, 0.0, 0.0), F);
        assert!(!has(&near(&m, here), [0.925, 0.025]));
        assert!(has(&near(&m, here), [-0.525, 0.375]));
    }

    #[test]
    fn an_obstacle_out_of_view_is_remembered_in_odom() {
        let mut m = ObstacleMap::new(0.05, 4.0);
        // seen 1.5 m ahead from a chair at (1, 0) facing +y
        m.insert(
            at(1.0, 0.0, std::f64::consts::FRAC_PI_2),
            &scan(&[[1.51, 0.04]], &[]),
            F,
        );
        let p = m.points(CellKind::Obstacle);
        assert_eq!(p.len(), 1);
        // the point itself in odom, not its cell's centre (0.975, 1.525)
        assert!(
            (p[0][0] - 0.96).abs() < 1e-6 && (p[0][1] - 1.51).abs() < 1e-6,
            "{p:?}"
        );
        // the next frame does not see it (out of view): still there
        m.insert(
            at(1.0, 0.8, std::f64::consts::FRAC_PI_2),
            &scan(&[], &[]),
            F,
        );
        assert_eq!(m.points(CellKind::Obstacle).len(), 1);
    }

    #[test]
    fn seen_floor_clears_and_the_radius_forgets() {
        let mut m = ObstacleMap::new(0.05, 2.0);
        m.insert(at(0.0, 0.0, 0.0), &scan(&[[1.525, 0.025]], &[]), F);
        // the person walked on: floor seen there
        m.insert(at(0.0, 0.0, 0.0), &scan(&[], &[[1.525, 0.025]]), F);
        assert!(m.is_empty());
        m.insert(at(0.0, 0.0, 0.0), &scan(&[[1.525, 0.025]], &[]), F);
        // an obstacle in the same frame as floor in its cell wins
        m.insert(
            at(0.0, 0.0, 0.0),
            &scan(&[[1.525, 0.025]], &[[1.525, 0.025]]),
            F,
        );
        assert_eq!(m.len(), 1);
        // 2 m past it: beyond the radius
        m.insert(at(-1.0, 0.0, 0.0), &scan(&[], &[]), F);
        assert!(m.is_empty());
    }

    #[test]
    fn nothing_is_kept_under_the_chair() {
        let mut m = ObstacleMap::new(0.05, 4.0);
        m.insert(at(0.0, 0.0, 0.0), &scan(&[[0.2, 0.0], [0.8, 0.0]], &[]), F);
        let p = m.points(CellKind::Obstacle);
        assert_eq!(p.len(), 1, "{p:?}");
        assert!(p[0][0] > 0.55);
    }

    /// A level camera 1 m up at base_link's origin, 640×480, f 615: the
    /// image's bottom edge meets 5 cm above the floor 2.43 m ahead.
    fn level_view() -> MapView {
        MapView {
            camera: crate::estimation::view::level_test_view(0.0),
            max_range_m: 3.0,
        }
    }

    /// A frame that sees only the far part of a cell (its near edge below
    /// the image) keeps the near edge; a frame that could see the near
    /// edge and did not replaces it (no pile-up of depth noise).
    #[test]
    fn a_cell_keeps_what_the_frame_could_not_see_of_it() {
        let v = level_view();
        let mut m = ObstacleMap::new(0.05, 4.0).with_view(v);
        let back = at(-0.5, 0.0, 0.0);
        // from 0.5 m back the whole cell [2.40, 2.45) is in view
        m.insert(back, &scan(&[[2.91, 0.02], [2.945, 0.03]], &[]), F);
        assert_eq!(m.points(CellKind::Obstacle).len(), 2);
        // from the origin its near edge is below the image
        let origin = at(0.0, 0.0, 0.0);
        assert!(!v.could_see(&origin, &[2.41, 0.02, 0.05]));
        assert!(v.could_see(&origin, &[2.445, 0.03, 0.05]));
        m.insert(origin, &scan(&[[2.445, 0.03]], &[]), F);
        let p = m.points(CellKind::Obstacle);
        assert_eq!(p.len(), 2, "the near edge stays: {p:?}");
        assert!(p.iter().any(|q| (q[0] - 2.41).abs() < 1e-6), "{p:?}");
        // seen again from back, where the near edge is in view: replaced
        m.insert(back, &scan(&[[2.945, 0.03]], &[]), F);
        let p = m.points(CellKind::Obstacle);
        assert_eq!(p.len(), 1, "{p:?}");
        assert!((p[0][0] - 2.445).abs() < 1e-6, "{p:?}");
        // a cell seen no lower than 0.5 m (a table's top) is in view from
        // the origin even where its floor-band part would not be: replaced
        let mut m = ObstacleMap::new(0.05, 4.0).with_view(v);
        m.insert(back, &scan_at(&[[2.91, 0.02], [2.945, 0.03]], 0.5, &[]), F);
        assert!(v.could_see(&origin, &[2.41, 0.02, 0.5]));
        m.insert(origin, &scan_at(&[[2.445, 0.03]], 0.5, &[]), F);
        assert_eq!(m.points(CellKind::Obstacle).len(), 1);
        // without a view, the latest frame's points replace the cell's
        let mut m = ObstacleMap::new(0.05, 4.0);
        m.insert(back, &scan(&[[2.91, 0.02], [2.945, 0.03]], &[]), F);
        m.insert(origin, &scan(&[[2.445, 0.03]], &[]), F);
        assert_eq!(m.points(CellKind::Obstacle).len(), 1);
    }

    /// A frame's points replace what their cell held; a cell keeps at
    /// most four, its extremes; the chair standing on a point forgets it.
    #[test]
    fn a_cell_keeps_the_latest_frames_extreme_points() {
        let mut m = ObstacleMap::new(0.05, 4.0);
        let pts: Vec<[f32; 2]> = (0..6)
            .map(|i| [2.01 + 0.007 * i as f32, 0.01 + 0.006 * i as f32])
            .collect();
        m.insert(at(0.0, 0.0, 0.0), &scan(&pts, &[]), F);
        let p = m.points(CellKind::Obstacle);
        // one cell: its points farthest along ±x and ±y (here two)
        assert_eq!(p.len(), 2, "{p:?}");
        assert!(p.iter().any(|q| (q[0] - 2.01).abs() < 1e-6), "{p:?}");
        assert!(p.iter().any(|q| (q[0] - 2.045).abs() < 1e-6), "{p:?}");
        m.insert(at(0.0, 0.0, 0.0), &scan(&[[2.02, 0.02]], &[]), F);
        let p = m.points(CellKind::Obstacle);
        assert_eq!(p.len(), 1, "{p:?}");
        assert!(
            (p[0][0] - 2.02).abs() < 1e-6 && (p[0][1] - 0.02).abs() < 1e-6,
            "{p:?}"
        );
        // the chair drives onto it
        m.forget(at(1.8, 0.0, 0.0), F);
        assert!(m.is_empty());
    }
}
