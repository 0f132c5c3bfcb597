//! Through a doorway (pure): a narrow passage on the way ahead is found on
//! the map (its two jambs, its middle and its axis), and the chair passes
//! it as a person steering a wheelchair would: to a point on the axis
//! before it, turned on the spot to face along the axis, then straight
//! through at a crawl, steering back onto the middle line. A 0.70 m chair
//! in a 0.80–0.90 m doorway has a few centimetres a side: driven at a
//! slant, its stop corridor (rightly) halts it at the jamb.
//!
//! The supervisor still checks every command; a passage that stays
//! blocked is given up and the planner's way is followed again.

use crate::msg::{wrap_angle, Pose2, VelocityCmd};

use super::map::{GridMap, MapPath};

/// A passage between two jambs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Doorway {
    /// The middle, odom, m.
    pub center: [f64; 2],
    /// The direction of travel through it, odom, rad.
    pub axis_rad: f64,
    /// Between the jambs' faces, m.
    pub width_m: f64,
}

impl Doorway {
    /// `p` in the doorway's frame: along the axis (negative: before it)
    /// and to the left of the middle line, m.
    pub fn local(&self, p: [f64; 2]) -> (f64, f64) {
        let (c, s) = (self.axis_rad.cos(), self.axis_rad.sin());
        let (dx, dy) = (p[0] - self.center[0], p[1] - self.center[1]);
        (c * dx + s * dy, -s * dx + c * dy)
    }

    /// The point `along_m` along the axis from the middle.
    pub fn on_axis(&self, along_m: f64) -> [f64; 2] {
        [
            self.center[0] + along_m * self.axis_rad.cos(),
            self.center[1] + along_m * self.axis_rad.sin(),
        ]
    }
}

/// A passage narrower than this (twice the distance from the way to the
/// nearest thing) is a doorway, m.
pub const NARROW_M: f64 = 1.1;
/// Doorways are looked for this far along the way, m.
const LOOK_M: f64 = 2.5;
/// Jambs are looked for this far from the narrowest point, m.
const JAMB_SEARCH_M: f64 = 0.8;
/// The wall's direction is looked for this far either side of the line
/// between the jambs, degrees (in steps of one), and its cells within a
/// band this thick (a wall's thickness and a cell), m.
const WALL_SEARCH_DEG: u32 = 35;
const WALL_BAND_M: f64 = 0.16;
/// A doorway's wall runs at least this far along on each side of it, m
/// (on the map, the walls beside the simulator's doorways ran 0.45 m and
/// more where the search reached 0.65 m; the far side of a gap between
/// furniture, 0-0.1 m).
const WALL_RUN_M: f64 = 0.25;

/// The first doorway on `path` within [`LOOK_M`] of the path point nearest
/// `from`: the narrowest point of the way there, if it lies between two
/// blocked cells on opposite sides.
pub fn find(map: &mut GridMap, path: &MapPath, from: [f64; 2]) -> Option<Doorway> {
    let pts = &path.points;
    let d = |p: &[f64; 2]| (p[0] - from[0]).hypot(p[1] - from[1]);
    let (i0, _) = pts
        .iter()
        .enumerate()
        .min_by(|a, b| d(a.1).total_cmp(&d(b.1)))?;
    // the narrowest point within reach along the way
    let mut along = 0.0;
    let mut best: Option<(usize, f64)> = None;
    for i in i0..pts.len() {
        if i > i0 {
            along += (pts[i][0] - pts[i - 1][0]).hypot(pts[i][1] - pts[i - 1][1]);
        }
        if along > LOOK_M {
            break;
        }
        let Some(cell) = map.cell(pts[i]) else {
            continue;
        };
        let clear = map.distance_m(cell);
        if 2.0 * clear < NARROW_M && best.is_none_or(|(_, b)| clear < b) {
            best = Some((i, clear));
        }
    }
    let (k, _) = best?;
    let c0 = pts[k];
    // the jambs: the nearest blocked cell, and the nearest on the other side
    let res = map.settings.resolution_m;
    let reach = (JAMB_SEARCH_M / res).ceil() as i64;
    let mut blocked: Vec<[f64; 2]> = Vec::new();
    for dy in -reach..=reach {
        for dx in -reach..=reach {
            let p = [c0[0] + dx as f64 * res, c0[1] + dy as f64 * res];
            if map.cell(p).is_some_and(|i| map.is_blocked(i)) {
                blocked.push(p);
            }
        }
    }
    let dist = |p: &[f64; 2]| (p[0] - c0[0]).hypot(p[1] - c0[1]);
    let j1 = *blocked.iter().min_by(|a, b| dist(a).total_cmp(&dist(b)))?;
    let v1 = [j1[0] - c0[0], j1[1] - c0[1]];
    let j2 = *blocked
        .iter()
        .filter(|p| (p[0] - c0[0]) * v1[0] + (p[1] - c0[1]) * v1[1] < 0.0)
        .min_by(|a, b| dist(a).total_cmp(&dist(b)))?;
    let (jx, jy) = (j2[0] - j1[0], j2[1] - j1[1]);
    let gap = jx.hypot(jy);
    if gap < 1e-6 {
        return None;
    }
    // the wall's direction: a few degrees off from two cells 0.85 m apart
    // would put a jamb in the stop corridor
    let across = [jx / gap, jy / gap];
    let side = |p: &[f64; 2]| (p[0] - c0[0]) * across[0] + (p[1] - c0[1]) * across[1];
    let sides: [Vec<&[f64; 2]>; 2] = [
        blocked.iter().filter(|p| side(p) < 0.0).collect(),
        blocked.iter().filter(|p| side(p) > 0.0).collect(),
    ];
    let (walls, depth) = wall_cells(&sides, [j1, j2], c0, across);
    // one line through both sides' wall cells: the doorway's width adds
    // to the baseline
    let cells: Vec<&[f64; 2]> = walls.iter().flatten().copied().collect();
    let w = match principal_direction(&cells) {
        // pointing from j1's side to j2's
        Some(d) if d[0] * across[0] + d[1] * across[1] < 0.0 => [-d[0], -d[1]],
        Some(d) => d,
        None => across,
    };
    // the jamb faces along the wall, and the wall's middle across it
    let along_wall = |p: &[f64; 2]| (p[0] - c0[0]) * w[0] + (p[1] - c0[1]) * w[1];
    let face_a = blocked
        .iter()
        .filter(|p| side(p) < 0.0)
        .map(along_wall)
        .fold(f64::NEG_INFINITY, f64::max);
    let face_b = blocked
        .iter()
        .filter(|p| side(p) > 0.0)
        .map(along_wall)
        .fold(f64::INFINITY, f64::min);
    if !face_a.is_finite() || !face_b.is_finite() || face_b <= face_a {
        return None;
    }
    // a wall either side, not the gap between two pieces of furniture
    // (the planner's way between them): blocked cells on the wall's line
    // from each face outwards, a cell's gap at most
    let normal = [-w[1], w[0]];
    let run = |face: f64, outwards: f64| -> f64 {
        let mut last = 0.0;
        let mut t = 0.0;
        while t <= WALL_RUN_M + res && t - last <= 2.0 * res {
            let on = (-1..=1).any(|k| {
                let off = depth + k as f64 * res;
                let p = [
                    c0[0] + (face + outwards * t) * w[0] + off * normal[0],
                    c0[1] + (face + outwards * t) * w[1] + off * normal[1],
                ];
                map.cell(p).is_some_and(|i| map.is_blocked(i))
            });
            if on {
                last = t;
            }
            t += res;
        }
        last
    };
    let (run_a, run_b) = (run(face_a, -1.0), run(face_b, 1.0));
    if run_a.min(run_b) < WALL_RUN_M {
        tracing::debug!(?c0, run_a, run_b, "doorway: not in a wall");
        return None;
    }
    let mut axis = [-w[1], w[0]];
    let mid = (face_a + face_b) / 2.0;
    let center = [
        c0[0] + mid * w[0] + depth * axis[0],
        c0[1] + mid * w[1] + depth * axis[1],
    ];
    // pointing the way the path goes
    let before = pts[k.saturating_sub(6)];
    let after = pts[(k + 6).min(pts.len() - 1)];
    let (px, py) = (after[0] - before[0], after[1] - before[1]);
    if axis[0] * px + axis[1] * py < 0.0 {
        axis = [-axis[0], -axis[1]];
    }
    Some(Doorway {
        center,
        axis_rad: axis[1].atan2(axis[0]),
        // each face's cell centre lies within half a cell of its surface,
        // either side: the centres' spacing is the width to a cell
        width_m: face_b - face_a - res,
    })
}

/// The wall's cells on each side of the doorway: of the lines within
/// [`WALL_SEARCH_DEG`] of `across` (the first jamb to the second), the one
/// along which the most cells of both sides lie within a band of the
/// wall's thickness, each side's band holding its jamb. A cabinet or a
/// television standing beside the doorway is left out, which would
/// otherwise turn the wall's direction by tens of degrees. Also returns
/// the bands' middle across the wall, from `c0` along `across`'s normal
/// (the doorway's depth).
fn wall_cells<'a>(
    sides: &[Vec<&'a [f64; 2]>; 2],
    jambs: [[f64; 2]; 2],
    c0: [f64; 2],
    across: [f64; 2],
) -> ([Vec<&'a [f64; 2]>; 2], f64) {
    // the most offsets within one band: (count, band start)
    let densest = |offsets: &mut Vec<f64>| -> (usize, f64) {
        offsets.sort_by(f64::total_cmp);
        let (mut best, mut start, mut j) = (0usize, 0.0, 0usize);
        for i in 0..offsets.len() {
            while offsets[i] - offsets[j] > WALL_BAND_M {
                j += 1;
            }
            if i + 1 - j > best {
                best = i + 1 - j;
                start = offsets[j];
            }
        }
        (best, start)
    };
    let mut best: Option<(usize, [f64; 2], [f64; 2])> = None;
    let mut offsets = Vec::new();
    for step in 0..=2 * WALL_SEARCH_DEG {
        // nearest `across` first: ties keep the smaller turn
        let k = step.div_ceil(2) as f64 * if step % 2 == 0 { 1.0 } else { -1.0 };
        let (sa, ca) = k.to_radians().sin_cos();
        let d = [
            ca * across[0] - sa * across[1],
            sa * across[0] + ca * across[1],
        ];
        let normal = [-d[1], d[0]];
        let mut count = 0;
        let mut starts = [0.0; 2];
        for ((cells, start), jamb) in sides.iter().zip(starts.iter_mut()).zip(jambs) {
            let at = |p: &[f64; 2]| (p[0] - c0[0]) * normal[0] + (p[1] - c0[1]) * normal[1];
            let o_jamb = at(&jamb);
            offsets.clear();
            offsets.extend(
                cells
                    .iter()
                    .map(|p| at(p))
                    .filter(|o| (o - o_jamb).abs() <= WALL_BAND_M),
            );
            let (n, s) = densest(&mut offsets);
            count += n;
            *start = s;
        }
        if best.is_none_or(|(c, _, _)| count > c) {
            best = Some((count, normal, starts));
        }
    }
    let Some((_, normal, starts)) = best else {
        return ([Vec::new(), Vec::new()], 0.0);
    };
    let offset = |p: &[f64; 2]| (p[0] - c0[0]) * normal[0] + (p[1] - c0[1]) * normal[1];
    let in_band = |cells: &Vec<&'a [f64; 2]>, start: f64| -> Vec<&'a [f64; 2]> {
        cells
            .iter()
            .copied()
            .filter(|p| (start..=start + WALL_BAND_M).contains(&offset(p)))
            .collect()
    };
    let walls = [in_band(&sides[0], starts[0]), in_band(&sides[1], starts[1])];
    let n = walls[0].len() + walls[1].len();
    let depth = if n == 0 {
        0.0
    } else {
        walls.iter().flatten().map(|p| offset(p)).sum::<f64>() / n as f64
    };
    (walls, depth)
}

/// The principal direction of points (unit), None for fewer than 3.
fn principal_direction(points: &[&[f64; 2]]) -> Option<[f64; 2]> {
    if points.len() < 3 {
        return None;
    }
    let n = points.len() as f64;
    let (mx, my) = (
        points.iter().map(|p| p[0]).sum::<f64>() / n,
        points.iter().map(|p| p[1]).sum::<f64>() / n,
    );
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in points {
        let (dx, dy) = (p[0] - mx, p[1] - my);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    Some([angle.cos(), angle.sin()])
}

/// The passage's phase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Phase {
    /// To the point on the axis before the doorway.
    Approach,
    /// Off the middle line near that point: turned to face a point on the
    /// middle line ([`PassageSettings::line_up_m`] before the doorway, or
    /// nearer when the chair is already past that) and driven straight
    /// onto it, so that the passage starts centred (the gap leaves 2–7 cm
    /// a side, the approach is good to 15 cm).
    LineUp {
        /// The point's place along the axis, m (negative: before it).
        at_m: f64,
    },
    /// Turning on the spot to face along the axis.
    Align,
    /// Straight through at a crawl.
    Pass,
    /// Too near the doorway to line up, and off the middle line by more
    /// than the gap leaves a side: straight back, the heading held, until
    /// there is room to line up (`to_m` along the axis), m.
    BackUp { to_m: f64 },
}

/// What to do now.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PassageCmd {
    /// Head for this point with the planner (odom).
    Aim([f64; 2]),
    /// This command.
    Drive(VelocityCmd),
    /// Through (or given up): follow the way again.
    Done,
}

/// The manoeuvre's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PassageSettings {
    /// The point before the doorway, on the axis, m.
    pub before_m: f64,
    /// Reached within this, m.
    pub at_m: f64,
    /// Aligned within this, rad.
    pub aligned_rad: f64,
    /// Turn rate while aligning, rad/s.
    pub turn_radps: f64,
    /// Speed through, m/s.
    pub crawl_mps: f64,
    /// Through when base_link is this far past the middle, m.
    pub past_m: f64,
    /// Steering: rad/s per metre off the middle line and per radian off
    /// the axis, capped.
    pub k_lateral: f64,
    pub k_heading: f64,
    pub omega_max_radps: f64,
    /// From this far before the middle on, only the heading is held, m.
    pub square_within_m: f64,
    /// base_link this far past the middle: the chair's rear (0.45 m behind
    /// it) is out of the doorway, m.
    pub clear_of_door_m: f64,
    /// The point on the middle line lined up on, this far before the
    /// middle, m; from nearer, a point `line_up_ahead_m` ahead of the
    /// chair, but never nearer than `line_up_nearest_m` (room to turn on
    /// the spot there: the corners' circle and the crawl's margin reach
    /// 0.68 m, the wall's face is 0.05 m before the middle); lined up when
    /// further off the line than `line_up_off_m`, from at most
    /// `line_up_from_m` off it, m.
    pub line_up_m: f64,
    pub line_up_ahead_m: f64,
    pub line_up_nearest_m: f64,
    pub line_up_off_m: f64,
    pub line_up_from_m: f64,
    /// What the gap must hold: the chair's width and the crawl's margin
    /// each side (0.70 + 2 × 0.03), m. Off the middle line by more than
    /// half the rest (or `line_up_off_m`), too near to line up, and with
    /// the front not yet at the wall (base_link `enter_m` before the
    /// middle), the chair backs up to make room, `back_ups` times at most.
    pub body_m: f64,
    pub enter_m: f64,
    pub back_ups: u32,
    /// Backs up this far at most (the person is asked about this much
    /// behind when the rear is unseen), m.
    pub back_up_m: f64,
}

impl PassageSettings {
    /// The point on the middle line to line up on from `along_m` along
    /// the axis: [`Self::line_up_m`] before the middle, or
    /// [`Self::line_up_ahead_m`] ahead of the chair when it is nearer, m.
    fn line_up_at(&self, along_m: f64) -> f64 {
        (-self.line_up_m).max(along_m + self.line_up_ahead_m)
    }
}

impl Default for PassageSettings {
    fn default() -> Self {
        PassageSettings {
            before_m: 1.3,
            at_m: 0.15,
            aligned_rad: 0.02,
            turn_radps: 0.3,
            crawl_mps: 0.09,
            past_m: 0.8,
            k_lateral: 4.0,
            k_heading: 1.5,
            omega_max_radps: 0.25,
            square_within_m: 0.85,
            clear_of_door_m: 0.6,
            line_up_m: 1.1,
            line_up_ahead_m: 0.2,
            line_up_nearest_m: 0.78,
            line_up_off_m: 0.03,
            line_up_from_m: 0.35,
            body_m: 0.76,
            enter_m: 0.5,
            back_ups: 2,
            back_up_m: 0.4,
        }
    }
}

/// Held on the way to the point before the doorway, the chair lines up
/// from at most this far off the middle line, m.
pub const LINE_UP_HELD_FROM_M: f64 = 1.0;

/// Backing up only this square to the doorway, rad.
const BACK_UP_SQUARE_RAD: f64 = 0.2;

/// One doorway being passed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Passage {
    /// The doorway as passed: the map's, its middle and width moved to
    /// the jambs the lasers measure now ([`Passage::observe`]).
    pub door: Doorway,
    /// The doorway as the map found it.
    pub found: Doorway,
    pub phase: Phase,
    pub settings: PassageSettings,
    /// Times it backed up to line up again.
    pub backed_up: u32,
    /// Whether it has lined up from where it was held on its way to the
    /// point before the doorway ([`Passage::held_on_approach`]).
    pub lined_up_where_held: bool,
}

/// Jamb points are taken within this of the wall's middle plane along the
/// axis (half the wall and 5 cm), m.
const JAMB_BAND_M: f64 = 0.10;
/// The measured jambs may move the map's middle this far at most, and
/// their gap may be this much narrower or this much wider than the map's
/// (which is good to a cell and measures short), m.
const JAMB_SHIFT_MAX_M: f64 = 0.10;
const JAMB_NARROWER_M: f64 = 0.05;
const JAMB_WIDER_M: f64 = 0.15;

/// The jambs' faces across the doorway, measured from points (odom): to
/// the right and to the left of `door`'s middle line (m, negative and
/// positive), each the nearest point to the middle line within the wall's
/// band on its side, with at least two points on each side. None when a
/// side is unseen, or the gap is implausible for `door` (something
/// standing in the doorway, a person passing).
pub fn jamb_faces(door: &Doorway, points_odom: &[[f64; 2]]) -> Option<(f64, f64)> {
    let reach = door.width_m / 2.0 + JAMB_SHIFT_MAX_M + JAMB_WIDER_M;
    let (mut right, mut left) = (f64::NEG_INFINITY, f64::INFINITY);
    let (mut n_right, mut n_left) = (0usize, 0usize);
    for p in points_odom {
        let (along, l) = door.local(*p);
        if along.abs() > JAMB_BAND_M || l.abs() > reach {
            continue;
        }
        if l < 0.0 {
            n_right += 1;
            right = right.max(l);
        } else {
            n_left += 1;
            left = left.min(l);
        }
    }
    let gap = left - right;
    (n_right >= 2
        && n_left >= 2
        && gap >= door.width_m - JAMB_NARROWER_M
        && gap <= door.width_m + JAMB_WIDER_M
        && ((left + right) / 2.0).abs() <= JAMB_SHIFT_MAX_M)
        .then_some((right, left))
}

impl Passage {
    /// Starts at the phase that fits where the chair is: already on the
    /// axis close before it, straight to aligning.
    pub fn new(door: Doorway, settings: PassageSettings) -> Passage {
        Passage {
            door,
            found: door,
            phase: Phase::Approach,
            settings,
            backed_up: 0,
            lined_up_where_held: false,
        }
    }

    /// Held on the way to the point before the doorway (something stands
    /// between the chair and it, or at it): where the chair is already
    /// level with that point or nearer the doorway, and off the middle
    /// line by at most [`LINE_UP_HELD_FROM_M`], it lines up from there,
    /// on a line steeper than the 45 degrees an approach allows (turned
    /// on the spot to face it, at a crawl), once a passage. Whether it
    /// does.
    pub fn held_on_approach(&mut self, pose: Pose2) -> bool {
        let s = self.settings;
        let (along, left) = self.door.local([pose.x_m, pose.y_m]);
        let line_up_at = s.line_up_at(along);
        let lines_up = self.phase == Phase::Approach
            && !self.lined_up_where_held
            && along > -s.before_m - s.at_m
            && line_up_at <= -s.line_up_nearest_m
            && left.abs() <= LINE_UP_HELD_FROM_M;
        if lines_up {
            self.lined_up_where_held = true;
            self.phase = Phase::LineUp { at_m: line_up_at };
        }
        lines_up
    }

    /// No backing up (the person said it is not clear behind): from a
    /// backing up, on to aligning where the chair is. Whether it was
    /// backing up.
    pub fn refuse_back_up(&mut self) -> bool {
        self.backed_up = self.settings.back_ups;
        let backing = matches!(self.phase, Phase::BackUp { .. });
        if backing {
            self.phase = Phase::Align;
        }
        backing
    }

    /// How far off the middle line the chair may pass: half what the gap
    /// leaves beside the chair's body, never less than the line-up's own
    /// tolerance, m.
    fn passes_off_m(&self) -> f64 {
        ((self.door.width_m - self.settings.body_m) / 2.0).max(self.settings.line_up_off_m)
    }

    /// Off the line by more than the gap allows, where backing up would
    /// make room to line up (front not yet at the wall, backings left):
    /// the phase that backs up to there.
    fn back_up(&mut self, along: f64, left: f64, heading_err: f64) -> Option<Phase> {
        let s = self.settings;
        // (square to the doorway: backing up at a slant would take the
        // chair further off the line)
        (left.abs() > self.passes_off_m() + 0.01
            && along < -s.enter_m
            && heading_err.abs() <= BACK_UP_SQUARE_RAD
            && self.backed_up < s.back_ups)
            .then(|| {
                self.backed_up += 1;
                Phase::BackUp {
                    // room to line up from there, on a line no steeper
                    // than 45 degrees
                    to_m: (-s.line_up_nearest_m - s.line_up_ahead_m - left.abs().max(0.05))
                        .max(along - s.back_up_m),
                }
            })
    }

    /// The doorway's middle and width from the jambs in `points_odom`
    /// (the lasers' points now), measured about the map's doorway: the
    /// map's cells put the middle within a cell, the lasers to a
    /// centimetre. Where the jambs are not both seen, the last measure
    /// stands. Returns whether they were.
    pub fn observe(&mut self, points_odom: &[[f64; 2]]) -> bool {
        let Some((right, left)) = jamb_faces(&self.found, points_odom) else {
            return false;
        };
        let mid = (left + right) / 2.0;
        let (c, s) = (self.found.axis_rad.cos(), self.found.axis_rad.sin());
        self.door = Doorway {
            center: [
                self.found.center[0] - s * mid,
                self.found.center[1] + c * mid,
            ],
            axis_rad: self.found.axis_rad,
            width_m: left - right,
        };
        true
    }

    /// The command at `pose` (odom) on the way to `goal` (odom): through
    /// once past the doorway, or level with a goal just beyond it (the
    /// planner makes the last metres).
    pub fn step(&mut self, pose: Pose2, goal: [f64; 2]) -> PassageCmd {
        let s = self.settings;
        let p = [pose.x_m, pose.y_m];
        let (along, left) = self.door.local(p);
        let heading_err = wrap_angle(pose.theta_rad - self.door.axis_rad);
        let goal_along = self.door.local(goal).0;
        // handed back only with the chair's rear out of the doorway: a
        // turn there would sweep a corner into a jamb
        if along > s.past_m || (along > s.clear_of_door_m && along >= goal_along - 0.1) {
            return PassageCmd::Done;
        }
        loop {
            match self.phase {
                Phase::Approach => {
                    let pre = self.door.on_axis(-s.before_m);
                    // close enough, or already between the point and the
                    // doorway and near the middle line
                    let near = (pre[0] - p[0]).hypot(pre[1] - p[1]) <= s.at_m
                        || (along > -s.before_m - s.at_m && along < -0.2 && left.abs() <= s.at_m);
                    // the point to line up on, where there is room
                    let line_up_at = s.line_up_at(along);
                    let room_to_line_up = line_up_at <= -s.line_up_nearest_m;
                    // off the line, but near enough to drive onto it at
                    // 45 degrees or less (steeper, the stop corridor sweeps
                    // across whatever stands beside the way)
                    let onto_line = room_to_line_up
                        && along > -s.before_m - s.at_m - 0.2
                        && left.abs() <= s.line_up_from_m.min(line_up_at - along);
                    if !near && !onto_line {
                        return PassageCmd::Aim(pre);
                    }
                    self.phase = if left.abs() > s.line_up_off_m && room_to_line_up {
                        Phase::LineUp { at_m: line_up_at }
                    } else if let Some(back) = self.back_up(along, left, heading_err) {
                        back
                    } else {
                        Phase::Align
                    };
                }
                Phase::LineUp { at_m } => {
                    let to = self.door.on_axis(at_m);
                    if along >= at_m - 0.02 {
                        self.phase = Phase::Align;
                        continue;
                    }
                    let bearing = wrap_angle((to[1] - p[1]).atan2(to[0] - p[0]) - pose.theta_rad);
                    // face it on the spot, then straight on, steering onto it
                    return PassageCmd::Drive(if bearing.abs() > 0.12 {
                        VelocityCmd {
                            v_mps: 0.0,
                            omega_radps: s.turn_radps.copysign(bearing),
                        }
                    } else {
                        VelocityCmd {
                            v_mps: s.crawl_mps,
                            omega_radps: (2.0 * bearing)
                                .clamp(-s.omega_max_radps, s.omega_max_radps),
                        }
                    });
                }
                Phase::Align => {
                    if heading_err.abs() > s.aligned_rad {
                        return PassageCmd::Drive(VelocityCmd {
                            v_mps: 0.0,
                            omega_radps: -s.turn_radps.copysign(heading_err),
                        });
                    }
                    self.phase = Phase::Pass;
                }
                Phase::Pass => {
                    if heading_err.abs() > 0.35 {
                        // pushed off the line: line up again
                        self.phase = Phase::Align;
                        continue;
                    }
                    // off the line where it no longer steers onto it:
                    // the jamb would hold it
                    if along >= -s.square_within_m {
                        if let Some(back) = self.back_up(along, left, heading_err) {
                            self.phase = back;
                            continue;
                        }
                    }
                    // onto the middle line while far; square to the
                    // doorway once the front nears it (the stop corridor
                    // ahead is a few centimetres narrower than the gap)
                    let k_lateral = if along < -s.square_within_m {
                        s.k_lateral
                    } else {
                        0.0
                    };
                    let omega = (-k_lateral * left - s.k_heading * heading_err)
                        .clamp(-s.omega_max_radps, s.omega_max_radps);
                    return PassageCmd::Drive(VelocityCmd {
                        v_mps: s.crawl_mps,
                        omega_radps: omega,
                    });
                }
                Phase::BackUp { to_m } => {
                    if along <= to_m {
                        self.phase = Phase::Approach;
                        continue;
                    }
                    return PassageCmd::Drive(VelocityCmd {
                        v_mps: -s.crawl_mps,
                        omega_radps: (-s.k_heading * heading_err)
                            .clamp(-s.omega_max_radps, s.omega_max_radps),
                    });
                }
            }
        }
    }
}

#[cfg(test)]
#[path = "doorway_tests.rs"]
mod tests;
