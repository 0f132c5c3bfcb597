//! What moved away out of the camera's view: a person who walked past the
//! chair leaves, in the camera's memory, the cells where the camera saw
//! them, and a cell is forgotten only when the camera sees the floor there
//! again. A trail across a room, in front of a doorway, closes the way in
//! the map until the camera looks there.
//!
//! The lasers settle it for what they see too. A remembered obstacle cell
//! where a laser's return lands is one the lasers see (its thing stands at
//! their 0.66 m plane: a person, a wall, a cupboard; never a box under the
//! plane, a table's top above it or a chair's seat, which the lasers pass
//! over or under). When, later, rays of one scan pass through such a cell
//! and on beyond it, and no ray ends at it or beside it, the thing the
//! lasers saw there has gone, and the cell is forgotten. Where one scan
//! cannot tell (the trail lies along the rays, as a wall seen at a slant
//! does, or the person's return lies just beyond it), time does: rays
//! through the cell, and no return in it or beside it, scan after scan.
//! Pure: a scan's rays (`base_link`) and the chair's pose at the scan's
//! stamp in.

use super::{centre, CellKind, ObstacleMap, MAX_POINTS_PER_CELL};
use crate::msg::{LaserRay, Pose2};

/// A ray passes a cell when it goes through the cell's middle and on at
/// least this far beyond it, m.
const CLEAR_BEYOND_M: f64 = 0.3;
/// A ray passes through a point the camera saw within this, m (through
/// the thing's surface, not the cell's free part beside a jamb's end).
const THROUGH_POINT_M: f64 = 0.015;
/// What keeps a cell: a return within this of its middle (the thing's
/// edge beside it: a jamb's end, where the rays through the doorway pass
/// the cell's free half), a return of a ray this near it that ends less
/// than [`CLEAR_BEYOND_M`] beyond it (a wall seen at a slant), or a blind
/// step this near it, m.
const KEEP_WITHIN_M: f64 = 0.25;
/// Rays of one scan that must pass a cell to forget it: a thing narrower
/// than the rays' spacing can slip between two of them.
const PASSES_TO_FORGET: usize = 2;
/// Scans whose rays pass through a cell the lasers saw, since the last
/// one that landed a return in it or in a cell beside it, that forget it
/// though a return lies within [`CLEAR_BEYOND_M`] beyond it or its
/// neighbours along the rays are remembered too: a person's trail along
/// the rays' way, with the person standing where they walked on to (a
/// wall seen at a slant lands a return within a cell of each of its cells
/// at the distances that matter). The estimation puts a scan at most
/// every 0.2 s: 4 s or more.
const UNHIT_SCANS_TO_FORGET: u32 = 20;

/// One scanner's rays: they share an origin and turn by a fixed step.
struct Fan<'a> {
    rays: &'a [LaserRay],
    origin: [f64; 2],
    first_rad: f64,
    step_rad: f64,
}

impl Fan<'_> {
    /// The rays whose bearings lie within `half_rad` of `bearing_rad`.
    fn about(&self, bearing_rad: f64, half_rad: f64) -> &[LaserRay] {
        let step = self.step_rad.abs();
        let tau = std::f64::consts::TAU;
        let off = ((bearing_rad - self.first_rad) * self.step_rad.signum()).rem_euclid(tau);
        // a bearing just before the first ray comes out near a full turn
        let off = if off > tau - half_rad - step {
            off - tau
        } else {
            off
        };
        let lo = ((off - half_rad) / step).floor().max(0.0);
        let hi = ((off + half_rad) / step).ceil();
        if hi < 0.0 || lo >= self.rays.len() as f64 {
            return &[];
        }
        let hi = hi.min(self.rays.len() as f64 - 1.0);
        &self.rays[lo as usize..=hi as usize]
    }
}

/// The scan's rays split by scanner (consecutive rays from one origin).
fn fans(rays: &[LaserRay]) -> Vec<Fan<'_>> {
    let mut out = Vec::new();
    let mut start = 0;
    while start < rays.len() {
        let o = rays[start].origin_m;
        let end = rays[start..]
            .iter()
            .position(|r| r.origin_m != o)
            .map_or(rays.len(), |n| start + n);
        let group = &rays[start..end];
        start = end;
        let angle = |r: &LaserRay| (r.dir[1] as f64).atan2(r.dir[0] as f64);
        if group.len() < 2 {
            continue;
        }
        let step_rad = crate::msg::wrap_angle(angle(&group[1]) - angle(&group[0]));
        if step_rad.abs() < 1e-6 || !step_rad.is_finite() {
            continue;
        }
        out.push(Fan {
            rays: group,
            origin: [o[0] as f64, o[1] as f64],
            first_rad: angle(&group[0]),
            step_rad,
        });
    }
    out
}

/// Whether the ray of `fan` along `dir` passes within [`THROUGH_POINT_M`]
/// of one of the points the camera saw (`points_base`): through the
/// thing's surface, not the cell's free part beside it.
fn through_a_point(fan: &Fan<'_>, dir: [f64; 2], points_base: &[[f64; 2]]) -> bool {
    points_base.iter().any(|q| {
        let (qx, qy) = (q[0] - fan.origin[0], q[1] - fan.origin[1]);
        (qx * dir[1] - qy * dir[0]).abs() <= THROUGH_POINT_M
    })
}

/// The rays that pass the cell whose middle is `p_base`: through it
/// (through a point the camera saw, `points_base`, and across the surface:
/// no obstacle cell remembered just before or after it along the ray,
/// `remembered_base`) and on well beyond it.
fn through(
    fans: &[Fan<'_>],
    p_base: [f64; 2],
    points_base: &[[f64; 2]],
    cell_m: f64,
    remembered_base: &dyn Fn([f64; 2]) -> bool,
) -> usize {
    let mut passes = 0;
    let reach = cell_m / 2.0;
    for fan in fans {
        let (dx, dy) = (p_base[0] - fan.origin[0], p_base[1] - fan.origin[1]);
        let d = dx.hypot(dy);
        if d <= KEEP_WITHIN_M {
            continue;
        }
        for r in fan.about(dy.atan2(dx), (reach / d).asin()) {
            let (ux, uy) = (r.dir[0] as f64, r.dir[1] as f64);
            let along = dx * ux + dy * uy;
            let across = (dx * uy - dy * ux).abs();
            if r.blind || across > reach {
                continue;
            }
            // no return and not blind: nothing within the laser's range
            let beyond = r.range_m.map_or(f64::INFINITY, f64::from) - along;
            let pass = beyond >= CLEAR_BEYOND_M
                && through_a_point(fan, [ux, uy], points_base)
                // across the surface, not along it: a ray along a wall, a
                // jamb's inner face, passes its points within a centimetre
                && !remembered_base([p_base[0] - ux * cell_m, p_base[1] - uy * cell_m])
                && !remembered_base([p_base[0] + ux * cell_m, p_base[1] + uy * cell_m]);
            passes += usize::from(pass);
        }
    }
    passes
}

/// Whether at least [`PASSES_TO_FORGET`] rays pass through the middle of
/// the cell `p_base`, within [`THROUGH_POINT_M`] of a point the camera saw
/// there (`points_base`), and end a cell or more beyond it, no ray beside
/// it is blind, and it lies farther than [`KEEP_WITHIN_M`] from the
/// scanners.
fn looked_through(
    fans: &[Fan<'_>],
    p_base: [f64; 2],
    points_base: &[[f64; 2]],
    cell_m: f64,
) -> bool {
    let reach = cell_m / 2.0;
    let mut passes = 0;
    for fan in fans {
        let (dx, dy) = (p_base[0] - fan.origin[0], p_base[1] - fan.origin[1]);
        let d = dx.hypot(dy);
        if d <= KEEP_WITHIN_M {
            return false;
        }
        for r in fan.about(dy.atan2(dx), (KEEP_WITHIN_M / d).asin()) {
            let (ux, uy) = (r.dir[0] as f64, r.dir[1] as f64);
            let along = dx * ux + dy * uy;
            let across = (dx * uy - dy * ux).abs();
            if across > KEEP_WITHIN_M {
                continue;
            }
            if r.blind {
                return false;
            }
            let beyond = r.range_m.map_or(f64::INFINITY, f64::from) - along;
            passes += usize::from(
                across <= reach && beyond >= cell_m && through_a_point(fan, [ux, uy], points_base),
            );
        }
    }
    passes >= PASSES_TO_FORGET
}

/// Whether a ray beside the cell whose middle is `p_base` says something
/// may still be there: a return within [`KEEP_WITHIN_M`] of it, one a
/// little beyond it ([`CLEAR_BEYOND_M`]), or a blind step.
fn kept(fans: &[Fan<'_>], p_base: [f64; 2]) -> bool {
    let near = KEEP_WITHIN_M;
    fans.iter().any(|fan| {
        let (dx, dy) = (p_base[0] - fan.origin[0], p_base[1] - fan.origin[1]);
        let d = dx.hypot(dy);
        d <= near
            || fan.about(dy.atan2(dx), (near / d).asin()).iter().any(|r| {
                let (ux, uy) = (r.dir[0] as f64, r.dir[1] as f64);
                let along = dx * ux + dy * uy;
                let across = (dx * uy - dy * ux).abs();
                if across > near {
                    return false;
                }
                let beyond = r.range_m.map_or(f64::INFINITY, f64::from) - along;
                r.blind || beyond.hypot(across) <= near || (beyond > 0.0 && beyond < CLEAR_BEYOND_M)
            })
    })
}

impl ObstacleMap {
    /// One scan of the lasers from `pose` (odom_from_base at its stamp):
    /// the obstacle cells a return lands on are marked as seen by the
    /// lasers; those marked before that the rays now pass through, with
    /// no return at or beside them, are forgotten. Returns whether any
    /// was.
    pub fn on_lasers(&mut self, pose: Pose2, rays_base: &[LaserRay]) -> bool {
        let fans = fans(rays_base);
        if fans.is_empty() {
            return false;
        }
        let cell_m = self.cell_m;
        // the pose's cosine and sine once for the scan
        let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
        let to_odom = |p: [f64; 2]| {
            [
                pose.x_m + c * p[0] - s * p[1],
                pose.y_m + s * p[0] + c * p[1],
            ]
        };
        let to_base = |p: [f64; 2]| {
            let (dx, dy) = (p[0] - pose.x_m, p[1] - pose.y_m);
            [c * dx + s * dy, -s * dx + c * dy]
        };
        // every cell a return landed in, obstacle or not
        let mut returns: Vec<(i32, i32)> = rays_base
            .iter()
            .filter(|r| !r.blind)
            .filter_map(|r| {
                let range = r.range_m? as f64;
                self.cell(to_odom([
                    r.origin_m[0] as f64 + range * r.dir[0] as f64,
                    r.origin_m[1] as f64 + range * r.dir[1] as f64,
                ]))
            })
            .collect();
        returns.sort_unstable();
        returns.dedup();
        // the obstacle cells among them (sorted still)
        let hit: Vec<(i32, i32)> = returns
            .iter()
            .copied()
            .filter(|k| matches!(self.cells.get(k), Some((CellKind::Obstacle, _))))
            .collect();
        let hit_beside = |k: (i32, i32)| {
            (-1..=1).any(|i| (-1..=1).any(|j| returns.binary_search(&(k.0 + i, k.1 + j)).is_ok()))
        };
        self.laser_seen.extend(hit.iter().copied());
        // the others the lasers saw before: gone where the rays now pass
        let mut gone = Vec::new();
        let mut unhit = Vec::new();
        let mut points_base = Vec::with_capacity(MAX_POINTS_PER_CELL);
        for k in &self.laser_seen {
            let Some((_, points)) = self.cells.get(k) else {
                continue;
            };
            if hit.binary_search(k).is_ok() {
                unhit.push((*k, None));
                continue;
            }
            points_base.clear();
            points_base.extend(points.iter().map(|q| to_base([q[0], q[1]])));
            let remembered_base = |q: [f64; 2]| {
                self.cell(to_odom(q))
                    .and_then(|k| self.cells.get(&k))
                    .is_some_and(|(kind, _)| *kind == CellKind::Obstacle)
            };
            let p_base = to_base(centre(cell_m, *k));
            let passes = through(&fans, p_base, &points_base, cell_m, &remembered_base);
            if passes >= PASSES_TO_FORGET && !kept(&fans, p_base) {
                gone.push(*k);
            } else if hit_beside(*k) {
                unhit.push((*k, None));
            } else if looked_through(&fans, p_base, &points_base, cell_m) {
                let n = self.unhit_scans.get(k).copied().unwrap_or(0) + 1;
                if n >= UNHIT_SCANS_TO_FORGET {
                    gone.push(*k);
                } else {
                    unhit.push((*k, Some(n)));
                }
            }
        }
        for (k, n) in unhit {
            match n {
                Some(n) => self.unhit_scans.insert(k, n),
                None => self.unhit_scans.remove(&k),
            };
        }
        for k in &gone {
            tracing::debug!(cell_odom = ?centre(cell_m, *k), ?pose, "camera memory: the lasers see through a cell they saw");
            self.cells.remove(k);
            self.laser_seen.remove(k);
            self.unhit_scans.remove(k);
        }
        self.hit_last_scan = hit;
        !gone.is_empty()
    }
}

#[cfg(test)]
#[path = "obstacle_map_lasers_tests.rs"]
mod tests;
