//! Whether the chair itself — its footprint, not a disc — can drive to a
//! place beside the word's object: the benchmark's test of "reachable" for
//! a chair that turns on the spot and drives straight, forwards or back.
//!
//! [`super::path::shortest_path_m`] keeps a disc of the chair's half-width
//! clear; a 1.0 × 0.7 m chair that must turn just past a doorway, with
//! furniture a metre beyond it, passes as a disc and not as itself. This
//! search moves the footprint itself: poses on a lattice of 4 cm and 5°,
//! moves of 6 cm forward or back along the heading and 5° turns on the
//! spot, each pose's rectangle tested exactly against every box taller than
//! the floor's clutter (as the simulated world counts contact), the outer
//! walls and the steps down. The caller gives the footprint with whatever
//! margin it must keep (the benchmark: the supervisor's crawl margin). A
//! pure core: no I/O, no clock.

use super::room::Room;
use super::scene::WALKER_LABEL;
use super::world::Footprint;
use crate::msg::Pose2;

const CELL_M: f64 = 0.04;
const HEADINGS: usize = 72;
const STEP_M: f64 = 0.06;
/// Objects this low or lower are driven over (the simulated world counts
/// contact with taller ones only).
const DRIVEN_OVER_M: f64 = 0.05;
/// At most this many poses are expanded (a bound on time; the largest
/// apartments hold about 4 million lattice poses).
const MAX_EXPANDED: usize = 6_000_000;

/// What the search found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Drivable {
    /// A pose beside the object (standoff ± tolerance, in sight, the
    /// footprint clear) was reached.
    Yes,
    /// Every pose the chair can reach from its start was searched and none
    /// is beside the object.
    No,
    /// The search ran past its bound (undecided).
    Undecided,
}

/// Obstacles as axis-aligned rectangles: (centre, half extents).
struct Obstacles {
    boxes: Vec<([f64; 2], [f64; 2])>,
    size_m: [f64; 2],
}

impl Obstacles {
    fn of(room: &Room) -> Self {
        let boxes = room
            .objects
            .iter()
            .filter(|o| o.label != WALKER_LABEL && o.max_m[2] > DRIVEN_OVER_M)
            .map(|o| ([o.min_m[0], o.min_m[1]], [o.max_m[0], o.max_m[1]]))
            .chain(room.pits.iter().map(|p| (p.min_m, p.max_m)))
            .map(|(lo, hi)| {
                (
                    [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0],
                    [(hi[0] - lo[0]) / 2.0, (hi[1] - lo[1]) / 2.0],
                )
            })
            .collect();
        Obstacles {
            boxes,
            size_m: [room.size_m[0], room.size_m[1]],
        }
    }

    /// Distance from a point to the nearest obstacle or outer wall.
    fn clearance(&self, p: [f64; 2]) -> f64 {
        let walls = p[0]
            .min(self.size_m[0] - p[0])
            .min(p[1])
            .min(self.size_m[1] - p[1]);
        self.boxes.iter().fold(walls, |m, (c, h)| {
            let dx = ((p[0] - c[0]).abs() - h[0]).max(0.0);
            let dy = ((p[1] - c[1]).abs() - h[1]).max(0.0);
            m.min((dx * dx + dy * dy).sqrt())
        })
    }
}

/// The footprint at one heading: its centre's offset from base_link, its
/// axes and half extents.
#[derive(Clone, Copy)]
struct Shape {
    centre_offset: [f64; 2],
    u: [f64; 2],
    v: [f64; 2],
    half_len_m: f64,
    half_width_m: f64,
}

impl Shape {
    fn at(f: Footprint, theta_rad: f64) -> Self {
        let (s, c) = theta_rad.sin_cos();
        let mid = (f.front_m - f.rear_m) / 2.0;
        Shape {
            centre_offset: [c * mid, s * mid],
            u: [c, s],
            v: [-s, c],
            half_len_m: (f.front_m + f.rear_m) / 2.0,
            half_width_m: f.half_width_m,
        }
    }

    /// Whether the footprint with base_link at `p` overlaps nothing: inside
    /// the outer walls and, by separating axes, apart from every box.
    fn clear(&self, p: [f64; 2], obstacles: &Obstacles, reach_m: f64) -> bool {
        let c = [p[0] + self.centre_offset[0], p[1] + self.centre_offset[1]];
        let (a, b) = (self.half_len_m, self.half_width_m);
        let ex = a * self.u[0].abs() + b * self.v[0].abs();
        let ey = a * self.u[1].abs() + b * self.v[1].abs();
        if c[0] - ex < 0.0
            || c[1] - ey < 0.0
            || c[0] + ex > obstacles.size_m[0]
            || c[1] + ey > obstacles.size_m[1]
        {
            return false;
        }
        obstacles.boxes.iter().all(|(bc, h)| {
            let d = [c[0] - bc[0], c[1] - bc[1]];
            // far boxes first, cheaply
            if d[0].abs() > h[0] + reach_m || d[1].abs() > h[1] + reach_m {
                return true;
            }
            d[0].abs() >= h[0] + ex
                || d[1].abs() >= h[1] + ey
                || (d[0] * self.u[0] + d[1] * self.u[1]).abs()
                    >= a + h[0] * self.u[0].abs() + h[1] * self.u[1].abs()
                || (d[0] * self.v[0] + d[1] * self.v[1]).abs()
                    >= b + h[0] * self.v[0].abs() + h[1] * self.v[1].abs()
        })
    }
}

/// Whether the chair, with footprint `f`, can drive from `start` to a place
/// where base_link is `standoff_m` ± `tol_m` from a box labelled `label`, in
/// sight of it (as [`super::path::shortest_path_m`] asks of the disc), by
/// turns on the spot and straight moves forward or back with its footprint
/// overlapping nothing.
pub fn drivable(
    room: &Room,
    start: Pose2,
    label: &str,
    standoff_m: f64,
    tol_m: f64,
    f: Footprint,
) -> Drivable {
    use std::cmp::Reverse;
    use std::collections::BinaryHeap;
    let targets: Vec<_> = room.objects.iter().filter(|o| o.label == label).collect();
    let (nx, ny) = (
        (room.size_m[0] / CELL_M).ceil() as usize,
        (room.size_m[1] / CELL_M).ceil() as usize,
    );
    if targets.is_empty() || nx == 0 || ny == 0 {
        return Drivable::No;
    }
    let obstacles = Obstacles::of(room);
    let centre = |i: usize, j: usize| [(i as f64 + 0.5) * CELL_M, (j as f64 + 0.5) * CELL_M];
    let half_diag_m = CELL_M * std::f64::consts::FRAC_1_SQRT_2;
    // the footprint holds the disc of this radius about base_link, and lies
    // within the one of `reach_m`
    let inner_m = f.front_m.min(f.rear_m).min(f.half_width_m);
    let reach_m = f.front_m.max(f.rear_m).hypot(f.half_width_m);
    let mut clearance = vec![0.0f64; nx * ny];
    let mut goal = vec![false; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let p = centre(i, j);
            clearance[j * nx + i] = obstacles.clearance(p);
            goal[j * nx + i] = targets.iter().any(|o| {
                (super::scene::distance_to_box(p[0], p[1], o) - standoff_m).abs() <= tol_m
                    && super::path::in_sight(room, p, o)
            });
        }
    }
    // the cells base_link may pass through (its disc could be clear there)
    let passable: Vec<bool> = clearance
        .iter()
        .map(|d| d + half_diag_m >= inner_m)
        .collect();
    // distance to a goal cell through passable cells: the search's guide,
    // and a pose from whose cell no goal is so reached is not searched on
    let mut to_goal = vec![f64::INFINITY; nx * ny];
    let mut heap = BinaryHeap::new();
    for (k, g) in goal.iter().enumerate() {
        if *g && passable[k] {
            to_goal[k] = 0.0;
            heap.push(Reverse((0u64, k)));
        }
    }
    while let Some(Reverse((d_mm, k))) = heap.pop() {
        let d = d_mm as f64 / 1000.0;
        if d > to_goal[k] {
            continue;
        }
        for (n, diagonal) in super::path::cells_beside(k, nx, ny) {
            let nd = d + if diagonal {
                CELL_M * std::f64::consts::SQRT_2
            } else {
                CELL_M
            };
            if passable[n] && nd < to_goal[n] {
                to_goal[n] = nd;
                heap.push(Reverse(((nd * 1000.0) as u64, n)));
            }
        }
    }
    let cell = |p: [f64; 2]| -> Option<usize> {
        let (i, j) = ((p[0] / CELL_M).floor(), (p[1] / CELL_M).floor());
        (i >= 0.0 && j >= 0.0 && (i as usize) < nx && (j as usize) < ny)
            .then(|| j as usize * nx + i as usize)
    };
    let shapes: Vec<Shape> = (0..HEADINGS)
        .map(|k| Shape::at(f, k as f64 * std::f64::consts::TAU / HEADINGS as f64))
        .collect();
    let heading_index = |theta: f64| -> usize {
        let t = theta.rem_euclid(std::f64::consts::TAU);
        ((t / std::f64::consts::TAU * HEADINGS as f64).round() as usize) % HEADINGS
    };
    let clear = |p: [f64; 2], k: usize| -> bool {
        let Some(c) = cell(p) else { return false };
        // the cell's clearance, less how far p may lie from its centre
        let q = centre(c % nx, c / nx);
        let off = (p[0] - q[0]).hypot(p[1] - q[1]);
        if clearance[c] - off >= reach_m {
            return true;
        }
        if clearance[c] + off < inner_m {
            return false;
        }
        shapes[k].clear(p, &obstacles, reach_m)
    };
    // the search: poses keyed by lattice cell and heading, each cell's first
    // pose kept (its continuous position moved on from)
    let mut seen = vec![false; nx * ny * HEADINGS];
    let mut open: BinaryHeap<Reverse<Open>> = BinaryHeap::new();
    let Some(c0) = cell([start.x_m, start.y_m]) else {
        return Drivable::No;
    };
    let k0 = heading_index(start.theta_rad);
    let key = |c: usize, k: usize| c * HEADINGS + k;
    seen[key(c0, k0)] = true;
    let push = |open: &mut BinaryHeap<_>, g_m: f64, p: [f64; 2], k: usize, h: f64| {
        open.push(Reverse((
            ((g_m + h) * 1e4) as u64,
            (g_m * 1e4) as u64,
            [p[0].to_bits(), p[1].to_bits()],
            k,
        )));
    };
    push(&mut open, 0.0, [start.x_m, start.y_m], k0, to_goal[c0]);
    let mut expanded = 0usize;
    while let Some(Reverse((_, g_e4, [xb, yb], k))) = open.pop() {
        let p = [f64::from_bits(xb), f64::from_bits(yb)];
        let g_m = g_e4 as f64 / 1e4;
        let Some(c) = cell(p) else { continue };
        if goal[c] {
            return Drivable::Yes;
        }
        expanded += 1;
        if expanded > MAX_EXPANDED {
            return Drivable::Undecided;
        }
        // a turn on the spot costs as a tenth of its corners' travel
        let turn_m = 0.1 * reach_m * std::f64::consts::TAU / HEADINGS as f64;
        for (next, k_next, cost_m) in [
            (p, (k + 1) % HEADINGS, turn_m),
            (p, (k + HEADINGS - 1) % HEADINGS, turn_m),
            (
                [
                    p[0] + STEP_M * shapes[k].u[0],
                    p[1] + STEP_M * shapes[k].u[1],
                ],
                k,
                STEP_M,
            ),
            (
                [
                    p[0] - STEP_M * shapes[k].u[0],
                    p[1] - STEP_M * shapes[k].u[1],
                ],
                k,
                STEP_M,
            ),
        ] {
            let Some(cn) = cell(next) else { continue };
            if seen[key(cn, k_next)] || !to_goal[cn].is_finite() {
                continue;
            }
            // a move is taken when its end is clear, and a step's middle
            // (a turn's corners move 5.7 cm, a step's 6 cm: the end and the
            // middle leave no box thinner than 3 cm passed through)
            let mid = [(p[0] + next[0]) / 2.0, (p[1] + next[1]) / 2.0];
            if !clear(next, k_next) || (k_next == k && !clear(mid, k)) {
                continue;
            }
            seen[key(cn, k_next)] = true;
            push(&mut open, g_m + cost_m, next, k_next, to_goal[cn]);
        }
    }
    Drivable::No
}

/// A pose to move on from: cost and estimate to a goal (0.1 mm), cost so
/// far (0.1 mm), base_link's position (bits of its f64s), heading index.
type Open = (u64, u64, [u64; 2], usize);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::path::shortest_path_m;
    use crate::sim::path::tests::thing;
    use crate::sim::scene::WALL_LABEL;

    fn pose(x_m: f64, y_m: f64, theta_rad: f64) -> Pose2 {
        Pose2 {
            x_m,
            y_m,
            theta_rad,
        }
    }

    /// Two rooms, 4 × 4 m each, a wall at x = 4 with a doorway of
    /// `width_m` centred at y = 2, and a chair in the far room.
    fn two_rooms(width_m: f64) -> Room {
        let (lo, hi) = (2.0 - width_m / 2.0, 2.0 + width_m / 2.0);
        Room {
            size_m: [8.0, 4.0, 2.5],
            objects: vec![
                thing(WALL_LABEL, [3.95, 0.0], [4.05, lo]),
                thing(WALL_LABEL, [3.95, hi], [4.05, 4.0]),
                thing("chair", [6.8, 1.7], [7.4, 2.3]),
            ],
            pits: Vec::new(),
        }
    }

    #[test]
    fn the_chair_passes_a_doorway_wider_than_itself_that_a_wider_disc_does_not() {
        // 0.76 m: 3 cm a side of the 0.70 m chair
        let room = two_rooms(0.76);
        let start = pose(1.5, 2.0, 0.0);
        assert_eq!(
            drivable(&room, start, "chair", 1.15, 0.35, Footprint::CHAIR),
            Drivable::Yes
        );
        assert!(shortest_path_m(&room, [1.5, 2.0], "chair", 1.15, 0.35, 0.4).is_none());
        // started facing away, it turns first
        let back = pose(1.5, 2.0, 3.0);
        assert_eq!(
            drivable(&room, back, "chair", 1.15, 0.35, Footprint::CHAIR),
            Drivable::Yes
        );
        // 0.66 m: narrower than the chair
        let narrow = two_rooms(0.66);
        assert_eq!(
            drivable(&narrow, start, "chair", 1.15, 0.35, Footprint::CHAIR),
            Drivable::No
        );
    }

    #[test]
    fn a_corner_a_disc_rounds_is_too_tight_for_the_chair_to_turn_in() {
        // a corridor 0.8 m wide along x, turning up into one 0.8 m wide
        // along y: a 0.7 m disc rounds the corner; a 1.0 m long chair
        // cannot turn in it (a rectangle 0.7 m wide rounds a corner of two
        // 0.8 m corridors only if shorter than 2·√2·0.8 − 2·0.7 = 0.86 m)
        let room = Room {
            size_m: [6.0, 6.0, 2.5],
            objects: vec![
                // below the corridor along x, y < 1
                thing(WALL_LABEL, [0.0, 0.0], [6.0, 1.0]),
                // above it, left of the one along y (x < 4.2)
                thing(WALL_LABEL, [0.0, 1.8], [4.2, 6.0]),
                // right of the one along y (x > 5.0)
                thing(WALL_LABEL, [5.0, 1.0], [6.0, 6.0]),
                thing("chair", [4.3, 5.4], [4.9, 5.9]),
            ],
            pits: Vec::new(),
        };
        let start = pose(1.0, 1.4, 0.0);
        assert!(
            shortest_path_m(&room, [1.0, 1.4], "chair", 1.15, 0.35, 0.35).is_some(),
            "the disc rounds the corner"
        );
        assert_eq!(
            drivable(&room, start, "chair", 1.15, 0.35, Footprint::CHAIR),
            Drivable::No
        );
        // widened to 1.2 m, the chair turns there
        let mut wide = room.clone();
        wide.objects[1].min_m[1] = 2.2;
        wide.objects[2].min_m[0] = 5.4;
        wide.objects[3].min_m[0] = 4.5;
        wide.objects[3].max_m[0] = 5.1;
        assert_eq!(
            drivable(&wide, start, "chair", 1.15, 0.35, Footprint::CHAIR),
            Drivable::Yes
        );
    }

    #[test]
    fn a_step_down_and_low_clutter_count_as_the_world_counts_them() {
        // the doorway's room beyond is cut off by a step down across it
        let mut room = two_rooms(0.9);
        room.pits.push(crate::sim::room::Pit {
            min_m: [4.05, 0.0],
            max_m: [5.0, 4.0],
            depth_m: 0.1,
        });
        let start = pose(1.5, 2.0, 0.0);
        assert_eq!(
            drivable(&room, start, "chair", 1.15, 0.35, Footprint::CHAIR),
            Drivable::No
        );
        // a mat 2 cm high across the doorway is driven over
        let mut mat = two_rooms(0.9);
        let mut low = thing("rug", [3.5, 1.0], [4.6, 3.0]);
        low.max_m[2] = 0.02;
        mat.objects.push(low);
        assert_eq!(
            drivable(&mat, start, "chair", 1.15, 0.35, Footprint::CHAIR),
            Drivable::Yes
        );
    }
}
