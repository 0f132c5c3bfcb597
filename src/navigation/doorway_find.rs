//! Finding a doorway on the map (split out of `navigation::doorway`): the
//! narrowest point of the way ahead between two blocked cells, its jambs,
//! the wall they stand in and the axis across it.

use super::{Doorway, NARROW_M};
use crate::navigation::map::{GridMap, MapPath};

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
