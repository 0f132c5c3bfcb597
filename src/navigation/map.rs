//! The chair's map of what it has seen (pure): an occupancy grid in `odom`
//! from the lasers' rays (free along a ray, occupied where it ended) and
//! the depth camera's remembered obstacles and drop-offs; the distance
//! from each cell to the nearest blocked one; shortest paths (A*) that
//! keep the chair's half width from everything and prefer the middle of a
//! doorway; frontiers (seen free space next to unseen space) where a
//! search can go on.
//!
//! The local planner (MPC and field) still decides every command and the
//! supervisor still checks it: the map only says which way round.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use serde::Deserialize;

use crate::msg::{floor_fast, LaserRay, Pose2};

/// The map's settings (config `[map]`).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapSettings {
    /// Side of the square map about where the chair started, m.
    pub size_m: f64,
    /// Cell side, m.
    pub resolution_m: f64,
    /// A ray with no return marks free space this far, m.
    pub free_range_m: f64,
    /// Paths keep this far from every blocked cell (half the chair's
    /// width and a little; less one cell for the cells' rounding), m.
    pub half_width_m: f64,
    /// Closer than this to something costs more (the middle of a doorway
    /// is cheapest), m.
    pub comfort_m: f64,
    /// Weight of that cost (0: shortest paths hug walls).
    pub w_comfort: f64,
    /// Extra cost of a metre through unseen space (it may be blocked).
    pub w_unknown: f64,
    /// The local planner heads for the point this far along the way, m.
    pub lookahead_m: f64,
}

impl Default for MapSettings {
    fn default() -> Self {
        MapSettings {
            size_m: 30.0,
            resolution_m: 0.05,
            free_range_m: 4.0,
            half_width_m: 0.39,
            comfort_m: 0.7,
            w_comfort: 1.5,
            w_unknown: 0.5,
            lookahead_m: 1.2,
        }
    }
}

/// A grid cell's eight neighbours, as (column, row) steps.
pub const NEIGHBOURS_8: [(i64, i64); 8] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (1, -1),
    (-1, 1),
    (-1, -1),
];

/// Evidence per update and its bounds (log-odds in small integers).
const HIT: i8 = 3;
const MISS: i8 = 1;
const EVIDENCE_MAX: i8 = 20;
/// A search gives up after this many cells (a goal walled off would
/// otherwise cost a search of the whole map at every replan).
const MAX_EXPANDED: usize = 60_000;
/// Distances are kept up to the comfort distance and this beyond it, and
/// at least [`DIST_CAP_MIN_M`], m (beyond, all the same: no cost, doorway
/// or room to turn looks farther).
const DIST_CAP_OVER_M: f32 = 0.5;
const DIST_CAP_MIN_M: f32 = 1.5;
/// Unseen cells this near the camera are the chair's own place, which no
/// laser sees: the camera's rays go on past them, m.
pub const LOOK_PAST_UNSEEN_M: f64 = 0.5;
/// A bearing has something left to look at with this many seen cells on
/// it the camera has not looked at (fewer: the rays' rounding, the
/// camera's view from its own place beside the chair's centre).
pub const UNLOOKED_CELLS: usize = 3;

#[derive(Debug, Clone)]
pub struct GridMap {
    pub settings: MapSettings,
    /// odom of the lower-left corner of cell (0, 0).
    origin_m: [f64; 2],
    n: usize,
    /// > 0 occupied, ≤ 0 free, where `known`.
    evidence: Vec<i8>,
    known: Vec<bool>,
    /// The camera's obstacles and drop-offs (replaced at each update).
    camera: Vec<bool>,
    /// Seen free cells the camera has looked at (what it looks for would
    /// have been seen there).
    looked: Vec<bool>,
    camera_cells: Vec<usize>,
    /// Distance to the nearest blocked cell, m (valid when not dirty).
    dist: Vec<f32>,
    dist_dirty: bool,
    /// Every cell ever seen lies in [lo, hi] (x, y cell indices; lo > hi:
    /// none yet): the distance field is computed within it and
    /// the cap's reach about it, the rest stays at the cap.
    seen_lo: [usize; 2],
    seen_hi: [usize; 2],
    dist_cap_m: f32,
}

/// A path in `odom`, from the chair to the goal.
#[derive(Debug, Clone, PartialEq)]
pub struct MapPath {
    pub points: Vec<[f64; 2]>,
    pub length_m: f64,
}

impl MapPath {
    /// The point `lookahead_m` along the path beyond the path point
    /// nearest `from` (the end when the rest is shorter).
    pub fn carrot(&self, from: [f64; 2], lookahead_m: f64) -> Option<[f64; 2]> {
        let d = |p: &[f64; 2]| (p[0] - from[0]).hypot(p[1] - from[1]);
        let (i0, _) = self
            .points
            .iter()
            .enumerate()
            .min_by(|a, b| d(a.1).total_cmp(&d(b.1)))?;
        let mut left = lookahead_m;
        for w in self.points[i0..].windows(2) {
            let seg = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
            if seg >= left && seg > 0.0 {
                let t = left / seg;
                return Some([
                    w[0][0] + t * (w[1][0] - w[0][0]),
                    w[0][1] + t * (w[1][1] - w[0][1]),
                ]);
            }
            left -= seg;
        }
        self.points.last().copied()
    }
}

impl GridMap {
    /// An empty (all unseen) map centred on `center_odom`.
    pub fn new(settings: MapSettings, center_odom: [f64; 2]) -> GridMap {
        let n = ((settings.size_m / settings.resolution_m).ceil() as usize).max(8);
        let half = n as f64 * settings.resolution_m / 2.0;
        let dist_cap_m = (settings.comfort_m as f32 + DIST_CAP_OVER_M).max(DIST_CAP_MIN_M);
        GridMap {
            settings,
            origin_m: [center_odom[0] - half, center_odom[1] - half],
            n,
            evidence: vec![0; n * n],
            known: vec![false; n * n],
            camera: vec![false; n * n],
            looked: vec![false; n * n],
            camera_cells: Vec::new(),
            dist: vec![dist_cap_m; n * n],
            dist_dirty: true,
            seen_lo: [n, n],
            seen_hi: [0, 0],
            dist_cap_m,
        }
    }

    /// Cells per side.
    pub fn side(&self) -> usize {
        self.n
    }

    fn cell_xy(&self, p: [f64; 2]) -> Option<(usize, usize)> {
        let r = self.settings.resolution_m;
        let (x, y) = (
            floor_fast((p[0] - self.origin_m[0]) / r),
            floor_fast((p[1] - self.origin_m[1]) / r),
        );
        (x >= 0.0 && y >= 0.0 && (x as usize) < self.n && (y as usize) < self.n)
            .then_some((x as usize, y as usize))
    }

    /// Whether any blocked cell whose centre lies in the odom box
    /// `lo`–`hi` passes `test` (its centre, odom).
    pub fn any_blocked_in(
        &self,
        lo: [f64; 2],
        hi: [f64; 2],
        mut test: impl FnMut([f64; 2]) -> bool,
    ) -> bool {
        let r = self.settings.resolution_m;
        let n = self.n as f64;
        let span = |a: f64, b: f64, o: f64| {
            let i0 = ((a - o) / r - 0.5).ceil().max(0.0);
            let i1 = ((b - o) / r - 0.5).floor().min(n - 1.0);
            (i0 as usize, i1 as usize, i0 <= i1)
        };
        let (x0, x1, xs) = span(lo[0], hi[0], self.origin_m[0]);
        let (y0, y1, ys) = span(lo[1], hi[1], self.origin_m[1]);
        if !(xs && ys) {
            return false;
        }
        (y0..=y1).any(|y| {
            (x0..=x1).any(|x| {
                let i = y * self.n + x;
                self.is_blocked(i) && test(self.center(i))
            })
        })
    }

    /// The distance field at odom `p`, m (None: off the map); it must be
    /// up to date ([`GridMap::update_distances`]).
    pub fn clearance_at_m(&self, p: [f64; 2]) -> Option<f64> {
        self.cell(p).map(|i| self.dist[i] as f64)
    }

    /// The cell index of an odom point (None: off the map).
    pub fn cell(&self, p: [f64; 2]) -> Option<usize> {
        self.cell_xy(p).map(|(x, y)| y * self.n + x)
    }

    /// The odom centre of cell `i`.
    pub fn center(&self, i: usize) -> [f64; 2] {
        let r = self.settings.resolution_m;
        [
            self.origin_m[0] + ((i % self.n) as f64 + 0.5) * r,
            self.origin_m[1] + ((i / self.n) as f64 + 0.5) * r,
        ]
    }

    /// Seen (by a laser or the camera) at all.
    pub fn is_known(&self, i: usize) -> bool {
        self.known[i] || self.camera[i]
    }

    /// Whether odom `p` lies in a cell seen at all (false off the map).
    pub fn is_known_at(&self, p: [f64; 2]) -> bool {
        self.cell(p).is_some_and(|i| self.is_known(i))
    }

    /// Something is there (a laser's return, the camera's obstacle or
    /// drop-off).
    pub fn is_blocked(&self, i: usize) -> bool {
        self.camera[i] || (self.known[i] && self.evidence[i] > 0)
    }

    /// A laser's return is there (known, occupied evidence).
    fn laser_blocked(&self, i: usize) -> bool {
        self.known[i] && self.evidence[i] > 0
    }

    /// Adds evidence to cell `i`; its blocked state before, if this
    /// changed it.
    fn nudge(&mut self, i: usize, by: i8) -> Option<bool> {
        let was = self.is_blocked(i);
        self.known[i] = true;
        self.evidence[i] = self.evidence[i]
            .saturating_add(by)
            .clamp(-EVIDENCE_MAX, EVIDENCE_MAX);
        (was != self.is_blocked(i)).then_some(was)
    }

    /// One merged laser scan seen from `pose` (odom): free along each ray,
    /// occupied where it ended; blind rays say nothing.
    pub fn add_scan(&mut self, pose: Pose2, rays_base: &[LaserRay]) {
        let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
        let to_odom = |p: [f64; 2]| {
            [
                pose.x_m + c * p[0] - s * p[1],
                pose.y_m + s * p[0] + c * p[1],
            ]
        };
        // the cells whose blocked state a nudge changed, with their state
        // before (a cell one ray ends in and others cross can flip back
        // and forth within one scan)
        let mut flipped: Vec<(usize, bool)> = Vec::new();
        for ray in rays_base.iter().filter(|r| !r.blind) {
            let o = to_odom([ray.origin_m[0] as f64, ray.origin_m[1] as f64]);
            let d = [
                c * ray.dir[0] as f64 - s * ray.dir[1] as f64,
                s * ray.dir[0] as f64 + c * ray.dir[1] as f64,
            ];
            let (len, hit) = match ray.range_m {
                Some(m) => (m as f64, true),
                None => (self.settings.free_range_m, false),
            };
            let end = self.cell([o[0] + d[0] * len, o[1] + d[1] * len]);
            let hit_cell = if hit { end } else { None };
            // the cells the ray crosses
            let mut ends: Option<(usize, usize)> = None;
            for i in self.ray_walk(o, d, len) {
                ends = Some((ends.map_or(i, |e| e.0), i));
                let by = if Some(i) == hit_cell { HIT } else { -MISS };
                // a free cell as sure as it gets stays as it is (and is
                // known: only a nudge gives evidence); most of a ray's
                if by < 0 && self.evidence[i] == -EVIDENCE_MAX {
                    continue;
                }
                if let Some(was) = self.nudge(i, by) {
                    flipped.push((i, was));
                }
            }
            // a straight ray: its cells lie in the box of its first and last
            if let Some((a, b)) = ends {
                self.seen(a);
                self.seen(b);
            }
        }
        // the distance field depends only on which cells are blocked: it
        // is out of date only when one of them ends the scan changed (the
        // seen box growing alone leaves it as it is: the cells it adds are
        // beyond the cap of every blocked cell, at the cap already)
        flipped.sort_by_key(|f| f.0);
        flipped.dedup_by_key(|f| f.0);
        if flipped.iter().any(|&(i, was)| was != self.is_blocked(i)) {
            self.dist_dirty = true;
        }
    }

    /// The depth camera's remembered obstacles and drop-offs (odom),
    /// replacing the previous set.
    pub fn set_camera(&mut self, obstacles_odom: &[[f64; 2]], drop_offs_odom: &[[f64; 2]]) {
        let new_cells: Vec<usize> = obstacles_odom
            .iter()
            .chain(drop_offs_odom)
            .filter_map(|p| self.cell(*p))
            .collect();
        // a cell the camera adds or takes away changes what is blocked
        // unless a laser's return blocks it anyway
        let added = new_cells
            .iter()
            .any(|&i| !self.camera[i] && !self.laser_blocked(i));
        let old_cells = std::mem::replace(&mut self.camera_cells, new_cells);
        for &i in &old_cells {
            self.camera[i] = false;
        }
        for k in 0..self.camera_cells.len() {
            let i = self.camera_cells[k];
            self.camera[i] = true;
            self.seen(i);
        }
        let removed = old_cells
            .iter()
            .any(|&i| !self.camera[i] && !self.laser_blocked(i));
        if added || removed {
            self.dist_dirty = true;
        }
    }

    /// Widens the seen box to cell `i`.
    fn seen(&mut self, i: usize) {
        let (x, y) = (i % self.n, i / self.n);
        self.seen_lo = [self.seen_lo[0].min(x), self.seen_lo[1].min(y)];
        self.seen_hi = [self.seen_hi[0].max(x), self.seen_hi[1].max(y)];
    }

    /// Brings the distance field up to date (two-pass chamfer, 1 and √2)
    /// within the seen box and the cap's reach about it: beyond, no
    /// blocked cell is within the cap (the field stays at the cap there).
    pub fn update_distances(&mut self) {
        if !self.dist_dirty {
            return;
        }
        self.dist_dirty = false;
        let n = self.n;
        if self.seen_lo[0] > self.seen_hi[0] {
            return;
        }
        let r = self.settings.resolution_m as f32;
        let cap = self.dist_cap_m;
        let reach = (cap / r).ceil() as usize + 1;
        let (x0, y0) = (
            self.seen_lo[0].saturating_sub(reach),
            self.seen_lo[1].saturating_sub(reach),
        );
        let (x1, y1) = (
            (self.seen_hi[0] + reach).min(n - 1),
            (self.seen_hi[1] + reach).min(n - 1),
        );
        let (d1, d2) = (r, r * std::f32::consts::SQRT_2);
        for y in y0..=y1 {
            for i in y * n + x0..=y * n + x1 {
                self.dist[i] = if self.is_blocked(i) { 0.0 } else { cap };
            }
        }
        // each pass a row at a time: first what the row beside it (done)
        // offers every cell, then along the row, each cell from the one
        // before it (done); the minimum of the same sums as cell by cell
        let width = x1 - x0 + 1;
        let dist = &mut self.dist;
        for y in y0..=y1 {
            let (done, rest) = dist.split_at_mut(y * n);
            let cur = &mut rest[x0..x0 + width];
            if y > y0 {
                let above = &done[(y - 1) * n + x0..(y - 1) * n + x0 + width];
                from_row_beside(cur, above, d1, d2);
            }
            for x in 1..width {
                cur[x] = min_of(cur[x], cur[x - 1] + d1);
            }
        }
        for y in (y0..=y1).rev() {
            let (rest, done) = dist.split_at_mut((y + 1) * n);
            let cur = &mut rest[y * n + x0..y * n + x0 + width];
            if y < y1 {
                let below = &done[x0..x0 + width];
                from_row_beside(cur, below, d1, d2);
            }
            for x in (0..width - 1).rev() {
                cur[x] = min_of(cur[x], cur[x + 1] + d1);
            }
        }
    }

    /// Distance from cell `i`'s centre to the nearest blocked cell's
    /// centre, m, looked up to `max_m` only (beyond: `max_m`); does not
    /// need the distance field (a quick look about the chair between
    /// plans).
    pub fn distance_near_m(&self, i: usize, max_m: f64) -> f64 {
        let r = self.settings.resolution_m;
        let k = (max_m / r).ceil() as i64;
        let (cx, cy) = ((i % self.n) as i64, (i / self.n) as i64);
        let n = self.n as i64;
        let mut best2 = max_m * max_m;
        for y in (cy - k).max(0)..=(cy + k).min(n - 1) {
            for x in (cx - k).max(0)..=(cx + k).min(n - 1) {
                let (dx, dy) = ((x - cx) as f64 * r, (y - cy) as f64 * r);
                let d2 = dx * dx + dy * dy;
                if d2 < best2 && self.is_blocked(y as usize * self.n + x as usize) {
                    best2 = d2;
                }
            }
        }
        best2.sqrt()
    }

    pub fn distance_m(&mut self, i: usize) -> f64 {
        self.update_distances();
        self.dist[i] as f64
    }

    /// Whether the chair fits at `p` (odom) as a way through the map
    /// would pass there (off the map: nothing is known against it). The
    /// distance field must be up to date ([`GridMap::update_distances`]).
    pub fn fits(&self, p: [f64; 2]) -> bool {
        self.cell(p)
            .is_none_or(|i| self.cost_per_m(i, &|_| false).is_some())
    }

    /// The cost of a metre through cell `i` (None: the chair does not fit).
    fn cost_per_m(&self, i: usize, escape: &dyn Fn(usize) -> bool) -> Option<f64> {
        let s = &self.settings;
        let d = self.dist[i] as f64;
        // distances run between cell centres: a jamb's cell reaches up to
        // half a cell into a doorway and the middle cell lies up to half a
        // cell off its middle, so a 0.80 m doorway can measure 0.35 m from
        // its middle cell — one cell of slack, or it would seem closed
        if d + s.resolution_m < s.half_width_m && (self.is_blocked(i) || !escape(i)) {
            return None;
        }
        let tight = ((s.comfort_m - d) / (s.comfort_m - s.half_width_m)).clamp(0.0, 1.0);
        let unknown = if self.is_known(i) { 0.0 } else { s.w_unknown };
        Some(1.0 + s.w_comfort * tight * tight + unknown)
    }

    /// Whether cell `i` lies under a chair at cell `start` (a way out of a
    /// tight spot may pass there).
    fn escape_cells(&self, start: usize) -> impl Fn(usize) -> bool {
        let n = self.n;
        let start_xy = (start % n, start / n);
        let cells = (self.settings.half_width_m / self.settings.resolution_m).ceil() as usize + 1;
        move |i: usize| {
            (i % n).abs_diff(start_xy.0) <= cells && (i / n).abs_diff(start_xy.1) <= cells
        }
    }

    /// Dijkstra (A* with `heuristic`) from `from` over passable cells; a
    /// chair too close to something may leave the cells under it.
    fn search(
        &self,
        from: [f64; 2],
        is_goal: &dyn Fn(usize) -> bool,
        heuristic: &dyn Fn(usize) -> f64,
        unknown_ok: bool,
    ) -> Option<(usize, Vec<u32>)> {
        let start = self.cell(from)?;
        let n = self.n;
        let r = self.settings.resolution_m;
        let escape = self.escape_cells(start);
        let mut g = vec![f32::INFINITY; n * n];
        let mut parent = vec![u32::MAX; n * n];
        let mut heap = BinaryHeap::new();
        g[start] = 0.0;
        heap.push(Reverse((0u32, start as u32)));
        let key = |f: f64| (f.max(0.0) * 1000.0).min(u32::MAX as f64 / 2.0) as u32;
        let mut expanded = 0usize;
        while let Some(Reverse((f, i))) = heap.pop() {
            let i = i as usize;
            expanded += 1;
            if expanded > MAX_EXPANDED {
                return None;
            }
            if f > key(g[i] as f64 + heuristic(i)) + 1 {
                continue; // stale
            }
            if is_goal(i) {
                return Some((i, parent));
            }
            let (x, y) = ((i % n) as i64, (i / n) as i64);
            for (dx, dy) in NEIGHBOURS_8 {
                let (nx, ny) = (x + dx, y + dy);
                if nx < 0 || ny < 0 || nx >= n as i64 || ny >= n as i64 {
                    continue;
                }
                let j = ny as usize * n + nx as usize;
                // the cells under the chair are free, seen or not
                if !unknown_ok && !self.is_known(j) && !escape(j) {
                    continue;
                }
                let Some(c) = self.cost_per_m(j, &escape) else {
                    continue;
                };
                let step = if dx != 0 && dy != 0 {
                    r * std::f64::consts::SQRT_2
                } else {
                    r
                };
                let ng = g[i] as f64 + step * c;
                if (ng as f32) < g[j] {
                    g[j] = ng as f32;
                    parent[j] = i as u32;
                    heap.push(Reverse((key(ng + heuristic(j)), j as u32)));
                }
            }
        }
        None
    }

    fn trace(&self, end: usize, parent: &[u32]) -> MapPath {
        let mut cells = vec![end];
        let mut i = end;
        while parent[i] != u32::MAX {
            i = parent[i] as usize;
            cells.push(i);
        }
        cells.reverse();
        let points: Vec<[f64; 2]> = cells.iter().map(|&i| self.center(i)).collect();
        let length_m = points
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .sum();
        MapPath { points, length_m }
    }

    /// The cheapest path from `from` to within `within_m` of `to` (odom),
    /// through seen or unseen space (None: the chair fits nowhere there).
    pub fn path(&mut self, from: [f64; 2], to: [f64; 2], within_m: f64) -> Option<MapPath> {
        self.update_distances();
        let goal = self.cell(to)?;
        let n = self.n;
        let r = self.settings.resolution_m;
        let (gx, gy) = ((goal % n) as f64, (goal / n) as f64);
        let within = (within_m / r).max(0.5);
        let cells_from_goal = |i: usize| {
            let (dx, dy) = ((i % n) as f64 - gx, (i / n) as f64 - gy);
            (dx * dx + dy * dy).sqrt()
        };
        let is_goal = |i: usize| cells_from_goal(i) <= within;
        let heuristic = |i: usize| (cells_from_goal(i) - within).max(0.0) * r;
        let (end, parent) = self.search(from, &is_goal, &heuristic, true)?;
        let mut p = self.trace(end, &parent);
        p.points.push(to);
        Some(p)
    }
}

/// Where to search: what the camera has looked at, what is left to look
/// at, frontiers and places with room to turn.
#[path = "map_search.rs"]
mod search;

/// The cells a ray crosses, in order (a grid walk).
#[path = "map_ray.rs"]
mod ray;

/// The chamfer step from the row beside (above or below, already done):
/// each cell of `cur` takes the least of itself, the cell beside it plus
/// `d1` and the two diagonal ones plus `d2`.
fn from_row_beside(cur: &mut [f32], beside: &[f32], d1: f32, d2: f32) {
    let w = cur.len();
    cur[0] = min_of(cur[0], beside[0] + d1);
    if w > 1 {
        cur[0] = min_of(cur[0], beside[1] + d2);
        cur[w - 1] = min_of(min_of(cur[w - 1], beside[w - 1] + d1), beside[w - 2] + d2);
    }
    for x in 1..w.saturating_sub(1) {
        cur[x] = min_of(
            min_of(min_of(cur[x], beside[x] + d1), beside[x - 1] + d2),
            beside[x + 1] + d2,
        );
    }
}

/// The smaller of two distances (never NaN in the field: `f32::min`'s
/// care for NaN would only slow its passes, and packs as one
/// instruction).
fn min_of(a: f32, b: f32) -> f32 {
    if b < a {
        b
    } else {
        a
    }
}

#[cfg(test)]
#[path = "map_tests.rs"]
mod tests;
