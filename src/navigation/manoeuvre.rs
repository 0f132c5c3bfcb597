//! A manoeuvre on the chair's map (pure): the way to a pose by turns on
//! the spot and straight crawls, forward or back, for where the planner's
//! arcs and the detours are held (a place beside the object past a low
//! table, a doorway to be left before the chair can turn). Each pose's
//! footprint keeps clear of every blocked cell as the supervisor would
//! keep it: its crawl's margin at the sides and its crawl's stop distance
//! ahead in the direction of travel; a turn on the spot only where the
//! circle its corners sweep, with that margin, is clear. Unseen cells
//! count as free: the supervisor still checks every command, and a
//! manoeuvre it holds is over ([`Follower`] only says what to do next).
//!
//! The search is over poses on a lattice of 4 cm and 5°, moves of 6 cm
//! and 5° (as the benchmark's `sim::drive` moves the true footprint),
//! costed in seconds at the crawl, a reverse and each change between
//! turning, driving forward and backing up costing more; it is guided by
//! a distance to the goal through cells where the chair's inscribed disc
//! fits, and bounded in space (about the start and the goal) and in
//! poses.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use super::map::GridMap;
use crate::msg::{wrap_angle, Pose2, VelocityCmd};

/// The chair's footprint about base_link and what it keeps clear.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ManoeuvreShape {
    pub front_m: f64,
    pub rear_m: f64,
    pub half_width_m: f64,
    /// Kept clear at the footprint's sides, m.
    pub side_margin_m: f64,
    /// Kept clear before the footprint's end in the direction of travel, m.
    pub ahead_m: f64,
    /// A turn on the spot needs this circle about base_link clear, m.
    pub turn_radius_m: f64,
}

impl ManoeuvreShape {
    /// The footprint the supervisor keeps clear at a crawl.
    pub fn at_a_crawl(supervisor: &crate::safety::Supervisor) -> ManoeuvreShape {
        let l = &supervisor.limits;
        let side_margin_m = l.corridor_margin_slow_m.min(l.corridor_margin_m);
        ManoeuvreShape {
            front_m: l.front_offset_m,
            rear_m: l.rear_offset_m,
            half_width_m: l.chair_width_m / 2.0,
            side_margin_m,
            ahead_m: l.stop_distance_slow_m.min(l.stop_distance_m),
            turn_radius_m: supervisor.corner_reach_m() + side_margin_m,
        }
    }
}

/// One part of a manoeuvre.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Move {
    /// Turn on the spot to this heading (odom, rad).
    Turn { to_rad: f64 },
    /// Drive straight along `heading_rad` (forward or back) to `to` (odom).
    Straight {
        to: [f64; 2],
        heading_rad: f64,
        forward: bool,
    },
}

const CELL_M: f64 = 0.04;
const HEADINGS: usize = 72;
const STEP_M: f64 = 0.06;
/// The search's bounds: poses expanded, and the margin about the start
/// and the goal that it may use, m.
const MAX_EXPANDED: usize = 150_000;
const WINDOW_M: f64 = 1.5;
/// Costs, s: a crawl's metre, a reverse's extra, a turn's degree (at a
/// crawl's turn, about 8.5°/s), and a change of move.
const S_PER_M: f64 = 1.0 / 0.08;
const REVERSE_FACTOR: f64 = 2.0;
const S_PER_TURN_STEP: f64 = 0.6;
const S_PER_CHANGE: f64 = 2.0;
/// The guide's weight (above 1: the search goes for the goal first and
/// finds a manoeuvre at most this much dearer than the cheapest, in far
/// fewer poses).
const GREED: f64 = 1.3;

#[derive(Clone, Copy, PartialEq, Eq)]
enum Kind {
    Start,
    Turn,
    Forward,
    Back,
}

#[derive(Clone, Copy)]
struct Node {
    p: [f64; 2],
    /// The lattice's heading, and the heading itself (the start's until
    /// the first turn: the chair drives on as it stands, not as the
    /// lattice rounds it), rad.
    k: usize,
    theta: f64,
    kind: Kind,
    parent: u32,
}

/// The search's cells: [`CELL_M`] squares from `lo` (odom), `nx` by `ny`.
#[derive(Clone, Copy)]
struct Window {
    lo: [f64; 2],
    nx: usize,
    ny: usize,
}

impl Window {
    /// The cell holding odom `p` (None: outside).
    fn cell(&self, p: [f64; 2]) -> Option<usize> {
        let (i, j) = (
            ((p[0] - self.lo[0]) / CELL_M).floor(),
            ((p[1] - self.lo[1]) / CELL_M).floor(),
        );
        (i >= 0.0 && j >= 0.0 && (i as usize) < self.nx && (j as usize) < self.ny)
            .then(|| j as usize * self.nx + i as usize)
    }

    /// Cell `c`'s centre (odom).
    fn centre(&self, c: usize) -> [f64; 2] {
        [
            self.lo[0] + ((c % self.nx) as f64 + 0.5) * CELL_M,
            self.lo[1] + ((c / self.nx) as f64 + 0.5) * CELL_M,
        ]
    }
}

/// Points (odom) sorted into the search's cells, to test a box against.
struct Buckets {
    lo: [f64; 2],
    nx: usize,
    ny: usize,
    /// Cell c's points are `points[first[c]..first[c + 1]]`.
    first: Vec<u32>,
    points: Vec<[f64; 2]>,
}

impl Buckets {
    fn new(all: &[[f64; 2]], w: Window) -> Self {
        let Window { lo, nx, ny } = w;
        let mut keyed: Vec<(usize, [f64; 2])> = all
            .iter()
            .filter_map(|p| w.cell(*p).map(|c| (c, *p)))
            .collect();
        keyed.sort_by_key(|(c, _)| *c);
        let mut first = vec![0u32; nx * ny + 1];
        for (c, _) in &keyed {
            first[c + 1] += 1;
        }
        for c in 0..nx * ny {
            first[c + 1] += first[c];
        }
        Buckets {
            lo,
            nx,
            ny,
            first,
            points: keyed.into_iter().map(|(_, p)| p).collect(),
        }
    }

    /// Whether any point in the box `blo`–`bhi` passes `test`.
    fn any_in(&self, blo: [f64; 2], bhi: [f64; 2], mut test: impl FnMut([f64; 2]) -> bool) -> bool {
        if self.points.is_empty() {
            return false;
        }
        let span = |a: f64, b: f64, o: f64, n: usize| {
            let i0 = ((a - o) / CELL_M).floor().max(0.0) as usize;
            let i1 = ((b - o) / CELL_M).floor().min(n as f64 - 1.0);
            (i0, i1)
        };
        let (x0, x1) = span(blo[0], bhi[0], self.lo[0], self.nx);
        let (y0, y1) = span(blo[1], bhi[1], self.lo[1], self.ny);
        if x1 < 0.0 || y1 < 0.0 {
            return false;
        }
        (y0..=y1 as usize).any(|y| {
            (x0..=x1 as usize).any(|x| {
                let c = y * self.nx + x;
                self.points[self.first[c] as usize..self.first[c + 1] as usize]
                    .iter()
                    .any(|p| test(*p))
            })
        })
    }
}

/// The manoeuvre from `start` to base_link within `within_m` of `goal` and
/// heading within `yaw_tol_rad` of `goal_yaw_rad` (odom) on `map` (its
/// distance field up to date), or None where none is found within the
/// bounds. `seen_now`: the points the supervisor holds the chair for now
/// (odom: the lasers', the camera's, the rear it remembers, the
/// drop-offs), kept clear as the map's blocked cells are; the map may
/// have let go of some of them, or never held them. `no_turns`: places
/// (odom centre, radius m) where no turn on the spot is made (the person
/// said it is not clear around there).
#[allow(clippy::too_many_arguments)]
pub fn plan(
    map: &GridMap,
    seen_now: &[[f64; 2]],
    no_turns: &[([f64; 2], f64)],
    start: Pose2,
    goal: [f64; 2],
    goal_yaw_rad: f64,
    within_m: f64,
    yaw_tol_rad: f64,
    shape: &ManoeuvreShape,
) -> Option<Vec<Move>> {
    let lo = [
        start.x_m.min(goal[0]) - WINDOW_M,
        start.y_m.min(goal[1]) - WINDOW_M,
    ];
    let hi = [
        start.x_m.max(goal[0]) + WINDOW_M,
        start.y_m.max(goal[1]) + WINDOW_M,
    ];
    let (nx, ny) = (
        ((hi[0] - lo[0]) / CELL_M).ceil() as usize,
        ((hi[1] - lo[1]) / CELL_M).ceil() as usize,
    );
    let window = Window { lo, nx, ny };
    let cell = |p: [f64; 2]| window.cell(p);
    let centre = |c: usize| window.centre(c);
    let r = map.settings.resolution_m;
    // the guide: seconds at a crawl to the goal through cells where the
    // chair's inscribed disc could be
    let inner_m = shape.front_m.min(shape.rear_m).min(shape.half_width_m);
    let passable: Vec<bool> = (0..nx * ny)
        .map(|c| {
            map.clearance_at_m(centre(c))
                .is_some_and(|d| d + r + CELL_M >= inner_m)
        })
        .collect();
    let mut to_goal = vec![f64::INFINITY; nx * ny];
    let mut heap = BinaryHeap::new();
    for (c, t) in to_goal.iter_mut().enumerate() {
        let q = centre(c);
        if passable[c] && (q[0] - goal[0]).hypot(q[1] - goal[1]) <= within_m + CELL_M {
            *t = 0.0;
            heap.push(Reverse((0u64, c)));
        }
    }
    while let Some(Reverse((d_ms, c))) = heap.pop() {
        let d = d_ms as f64 / 1000.0;
        if d > to_goal[c] {
            continue;
        }
        let (x, y) = ((c % nx) as i64, (c / nx) as i64);
        for (dx, dy) in super::map::NEIGHBOURS_8 {
            let (x2, y2) = (x + dx, y + dy);
            if x2 < 0 || y2 < 0 || x2 >= nx as i64 || y2 >= ny as i64 {
                continue;
            }
            let n = y2 as usize * nx + x2 as usize;
            let step = if dx != 0 && dy != 0 {
                CELL_M * std::f64::consts::SQRT_2
            } else {
                CELL_M
            };
            let nd = d + step * S_PER_M;
            if passable[n] && nd < to_goal[n] {
                to_goal[n] = nd;
                heap.push(Reverse(((nd * 1000.0) as u64, n)));
            }
        }
    }
    // the lattice's headings hold the goal's heading itself (a doorway's
    // axis: a few degrees off it, the footprint sweeps a jamb)
    let turn_step = std::f64::consts::TAU / HEADINGS as f64;
    let offset = goal_yaw_rad.rem_euclid(turn_step);
    let heading = |k: usize| offset + k as f64 * turn_step;
    let heading_index = |theta: f64| -> usize {
        let t = (theta - offset).rem_euclid(std::f64::consts::TAU);
        ((t / turn_step).round() as usize) % HEADINGS
    };
    let reach_m = (shape.front_m.max(shape.rear_m) + shape.ahead_m)
        .hypot(shape.half_width_m + shape.side_margin_m);
    // the footprint at `p`, heading k, moving `dir` (+1 forward, -1 back)
    let seen_now = Buckets::new(seen_now, window);
    let straight_clear = |p: [f64; 2], theta: f64, dir: f64| -> bool {
        let (s, c) = theta.sin_cos();
        let x_lo = -shape.rear_m - if dir < 0.0 { shape.ahead_m } else { 0.0 };
        let x_hi = shape.front_m + if dir > 0.0 { shape.ahead_m } else { 0.0 };
        let half = shape.half_width_m + shape.side_margin_m;
        let box_lo = [p[0] - reach_m, p[1] - reach_m];
        let box_hi = [p[0] + reach_m, p[1] + reach_m];
        let inside = |q: [f64; 2]| {
            let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
            let (x, y) = (c * dx + s * dy, -s * dx + c * dy);
            x >= x_lo && x <= x_hi && y.abs() <= half
        };
        let map_clear = map.clearance_at_m(p).is_some_and(|d| d - r >= reach_m)
            || !map.any_blocked_in(box_lo, box_hi, inside);
        map_clear && !seen_now.any_in(box_lo, box_hi, inside)
    };
    let turn_clear = |p: [f64; 2]| -> bool {
        if no_turns
            .iter()
            .any(|(c, r)| (p[0] - c[0]).hypot(p[1] - c[1]) <= *r)
        {
            return false;
        }
        let rr = shape.turn_radius_m;
        let (box_lo, box_hi) = ([p[0] - rr, p[1] - rr], [p[0] + rr, p[1] + rr]);
        let inside = |q: [f64; 2]| (q[0] - p[0]).hypot(q[1] - p[1]) < rr;
        let map_clear = map.clearance_at_m(p).is_some_and(|d| d - r >= rr)
            || !map.any_blocked_in(box_lo, box_hi, inside);
        map_clear && !seen_now.any_in(box_lo, box_hi, inside)
    };
    // every turn is a move of its own: the heading left to turn to the
    // goal's costs at least its turn steps (the guide stays a lower bound)
    let turn_left = |k: usize| {
        let off = wrap_angle(heading(k) - goal_yaw_rad).abs() - yaw_tol_rad;
        (off.max(0.0) / turn_step).floor() * S_PER_TURN_STEP
    };
    let c0 = cell([start.x_m, start.y_m])?;
    if !to_goal[c0].is_finite() {
        tracing::debug!(
            start_passable = passable[c0],
            "manoeuvre search: no way from the start to the goal for the chair's inscribed disc"
        );
        return None;
    }
    let k0 = heading_index(start.theta_rad);
    let key = |c: usize, k: usize| c * HEADINGS + k;
    let mut best = vec![f64::INFINITY; nx * ny * HEADINGS];
    let mut nodes = vec![Node {
        p: [start.x_m, start.y_m],
        k: k0,
        theta: start.theta_rad,
        kind: Kind::Start,
        parent: u32::MAX,
    }];
    best[key(c0, k0)] = 0.0;
    let mut open: BinaryHeap<Reverse<(u64, u64, u32)>> = BinaryHeap::new();
    let ms = |s: f64| (s * 1000.0) as u64;
    open.push(Reverse((ms(GREED * to_goal[c0]), 0, 0)));
    let mut turn_ok: Vec<Option<bool>> = vec![None; nx * ny];
    let mut expanded = 0usize;
    while let Some(Reverse((_, g_ms, id))) = open.pop() {
        let node = nodes[id as usize];
        let g = g_ms as f64 / 1000.0;
        let c = cell(node.p)?;
        if g > best[key(c, node.k)] + 1e-3 {
            continue;
        }
        let yaw_off = wrap_angle(node.theta - goal_yaw_rad).abs();
        if (node.p[0] - goal[0]).hypot(node.p[1] - goal[1]) <= within_m && yaw_off <= yaw_tol_rad {
            return Some(moves(&nodes, id as usize));
        }
        expanded += 1;
        if expanded > MAX_EXPANDED {
            tracing::debug!(expanded, "manoeuvre search: over its bound of poses");
            return None;
        }
        let (s, co) = node.theta.sin_cos();
        let mut next: Vec<(Kind, [f64; 2], usize, f64, f64)> = Vec::with_capacity(4);
        for (kind, dir) in [(Kind::Forward, 1.0), (Kind::Back, -1.0)] {
            let p = [node.p[0] + dir * STEP_M * co, node.p[1] + dir * STEP_M * s];
            let factor = if dir < 0.0 { REVERSE_FACTOR } else { 1.0 };
            next.push((kind, p, node.k, node.theta, STEP_M * S_PER_M * factor));
        }
        for dk in [1, HEADINGS - 1] {
            let k = (node.k + dk) % HEADINGS;
            next.push((Kind::Turn, node.p, k, heading(k), S_PER_TURN_STEP));
        }
        for (kind, p, k, theta, cost) in next {
            let Some(c2) = cell(p) else { continue };
            if !to_goal[c2].is_finite() {
                continue;
            }
            let change = if node.kind != kind && node.kind != Kind::Start {
                S_PER_CHANGE
            } else {
                0.0
            };
            let g2 = g + cost + change;
            let kk = key(c2, k);
            if g2 >= best[kk] {
                continue;
            }
            let clear = match kind {
                Kind::Turn => *turn_ok[c2].get_or_insert_with(|| turn_clear(p)),
                Kind::Forward => straight_clear(p, theta, 1.0),
                Kind::Back => straight_clear(p, theta, -1.0),
                Kind::Start => false,
            };
            if !clear {
                continue;
            }
            best[kk] = g2;
            nodes.push(Node {
                p,
                k,
                theta,
                kind,
                parent: id,
            });
            let h = to_goal[c2] + turn_left(k);
            open.push(Reverse((
                ms(g2 + GREED * h),
                ms(g2),
                (nodes.len() - 1) as u32,
            )));
        }
    }
    tracing::debug!(
        expanded,
        turn_at_start = turn_clear([start.x_m, start.y_m]),
        forward_at_start = straight_clear([start.x_m, start.y_m], start.theta_rad, 1.0),
        back_at_start = straight_clear([start.x_m, start.y_m], start.theta_rad, -1.0),
        "manoeuvre search: every pose within its bounds tried"
    );
    None
}

/// The moves from the start to node `end`, each run of one kind as one.
fn moves(nodes: &[Node], end: usize) -> Vec<Move> {
    let mut chain = vec![end];
    let mut i = end;
    while nodes[i].parent != u32::MAX {
        i = nodes[i].parent as usize;
        chain.push(i);
    }
    chain.reverse();
    let mut out: Vec<Move> = Vec::new();
    let mut last = Kind::Start;
    for &i in &chain[1..] {
        let n = nodes[i];
        let m = match n.kind {
            Kind::Turn => Move::Turn {
                to_rad: wrap_angle(n.theta),
            },
            Kind::Forward | Kind::Back => Move::Straight {
                to: n.p,
                heading_rad: wrap_angle(n.theta),
                forward: n.kind == Kind::Forward,
            },
            Kind::Start => continue,
        };
        if n.kind == last {
            if let Some(l) = out.last_mut() {
                *l = m;
                continue;
            }
        }
        out.push(m);
        last = n.kind;
    }
    out
}

/// Within this of a turn's heading, the turn is done, rad.
const TURN_DONE_RAD: f64 = 0.03;
/// Within this of a straight move's end, it is done, m.
const STRAIGHT_DONE_M: f64 = 0.015;
/// Steering while driving straight: per metre off the line and per radian
/// off its heading, and the most, rad/s.
const K_LATERAL: f64 = 1.0;
const K_HEADING: f64 = 1.0;
const STEER_MAX_RADPS: f64 = 0.1;

/// Follows a manoeuvre's moves one after another (pure: the pose passed
/// in each step).
#[derive(Debug, Clone, PartialEq)]
pub struct Follower {
    moves: Vec<Move>,
    next: usize,
}

impl Follower {
    pub fn new(moves: Vec<Move>) -> Self {
        Follower { moves, next: 0 }
    }

    /// The moves left, the current one first.
    pub fn left(&self) -> &[Move] {
        &self.moves[self.next.min(self.moves.len())..]
    }

    /// The command at `pose`: turns at `turn_radps`, straight moves at
    /// `v_mps` (slower over their last centimetres) keeping to their line;
    /// None when every move is done.
    pub fn command(&mut self, pose: Pose2, v_mps: f64, turn_radps: f64) -> Option<VelocityCmd> {
        while let Some(m) = self.moves.get(self.next).copied() {
            match m {
                Move::Turn { to_rad } => {
                    let err = wrap_angle(to_rad - pose.theta_rad);
                    if err.abs() <= TURN_DONE_RAD {
                        self.next += 1;
                        continue;
                    }
                    return Some(VelocityCmd {
                        v_mps: 0.0,
                        omega_radps: turn_radps.copysign(err),
                    });
                }
                Move::Straight {
                    to,
                    heading_rad,
                    forward,
                } => {
                    let (s, c) = heading_rad.sin_cos();
                    let (dx, dy) = (to[0] - pose.x_m, to[1] - pose.y_m);
                    let dir = if forward { 1.0 } else { -1.0 };
                    let left_m = dir * (c * dx + s * dy);
                    if left_m <= STRAIGHT_DONE_M {
                        self.next += 1;
                        continue;
                    }
                    // the chair's offset to the left of the line, and its
                    // heading off it: steered back (backing up, the
                    // offset's correction turns the other way)
                    let off_m = -(-s * dx + c * dy);
                    let yaw_err = wrap_angle(pose.theta_rad - heading_rad);
                    let v = v_mps.min((left_m * 2.0).max(0.03));
                    // below 5 cm/s the supervisor judges a turn as one on
                    // the spot above 0.05 rad/s: kept below it
                    let steer_max = if v < 0.05 { 0.04 } else { STEER_MAX_RADPS };
                    let omega = (-K_LATERAL * off_m * dir - K_HEADING * yaw_err)
                        .clamp(-steer_max, steer_max);
                    return Some(VelocityCmd {
                        v_mps: dir * v,
                        omega_radps: omega,
                    });
                }
            }
        }
        None
    }
}

#[cfg(test)]
#[path = "manoeuvre_tests.rs"]
mod tests;
