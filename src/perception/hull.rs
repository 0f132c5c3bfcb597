//! Step 6's oriented box: the convex hull of an object's ground
//! projection, from the few points that can be its vertices, and the
//! minimum-area rectangle around it.

use nalgebra::Point3;
use wide::f32x8;

use super::sweep::{ground_lanes, Ground, Sweep};

/// Akl–Toussaint: the ground projections of the points that can be hull
/// vertices. Points strictly inside the octagon of the extreme points (along
/// x, y, x+y, x−y), or on its edges between vertices, cannot be; they are
/// dropped in one pass after the sweep, eight points at a time, leaving few
/// points for the hull's sort; with the sweep's [`Ground`], a block of
/// points whose bounds lie inside is dropped without a look at its points,
/// and another's points are tested only against the edges its bounds
/// cross. Exact.
pub(super) fn hull_candidates(
    points: &[Point3<f32>],
    sweep: &Sweep,
    ground: Option<Ground>,
) -> Vec<u64> {
    let all = || points.iter().map(|p| ground_key(p.x, p.y)).collect();
    if points.len() < 64 {
        return all();
    }
    let mut poly: Vec<[f64; 2]> = Vec::with_capacity(8);
    for e in &sweep.extreme {
        let e = [e[0] as f64, e[1] as f64];
        if poly.last() != Some(&e) && poly.first() != Some(&e) {
            poly.push(e);
        }
    }
    if poly.len() < 3 {
        return all();
    }
    // inside: n·p ≥ c for every counter-clockwise edge (n its left normal).
    // Tested in f32 with a margin, so a point is dropped only when it is
    // inside beyond rounding: the hull stays exact.
    let scale = poly
        .iter()
        .fold(1.0f64, |m, p| m.max(p[0].abs()).max(p[1].abs()));
    let mut edges: Vec<[f32; 3]> = Vec::with_capacity(poly.len());
    for i in 0..poly.len() {
        let a = poly[i];
        let b = poly[(i + 1) % poly.len()];
        let (ex, ey) = (-(b[1] - a[1]), b[0] - a[0]);
        let len = (ex * ex + ey * ey).sqrt();
        if len == 0.0 {
            continue;
        }
        let c = (ex * a[0] + ey * a[1]) / len + 1e-5 * scale;
        edges.push([(ex / len) as f32, (ey / len) as f32, c as f32]);
    }
    let edges8: Vec<[f32x8; 3]> = edges.iter().map(|e| e.map(f32x8::splat)).collect();
    let mut out: Vec<u64> = poly
        .iter()
        .map(|p| ground_key(p[0] as f32, p[1] as f32))
        .collect();
    // eight points: those outside some edge of `edges` (a NaN lane is
    // outside none)
    let mut test = |edges: &[[f32x8; 3]], [x, y]: [f32x8; 2]| {
        let outside = outside_of(edges, x, y);
        if outside != 0 {
            let (x, y) = (x.to_array(), y.to_array());
            for l in 0..8 {
                if (outside >> l) & 1 == 1 {
                    out.push(ground_key(x[l], y[l]));
                }
            }
        }
    };
    match ground {
        Some(g) => {
            // a block's points lie within its bounds; along an edge's
            // normal the rectangle of the bounds is least at the corner the
            // normal's signs pick, and rounding keeps that order, so a
            // point of the block can lie outside only the edges that
            // corner lies outside: its points are tested against those
            // alone, and a block inside every edge is dropped whole
            let mut failing = [[f32x8::ZERO; 3]; 8];
            for b in 0..g.blocks.len() {
                let Some([x0, x1, y0, y1]) = g.block_bounds(b) else {
                    continue;
                };
                let mut n = 0;
                for (&[nx, ny, c], e8) in edges.iter().zip(&edges8) {
                    let x = if nx >= 0.0 { x0 } else { x1 };
                    let y = if ny >= 0.0 { y0 } else { y1 };
                    if nx * x + ny * y < c {
                        failing[n] = *e8;
                        n += 1;
                    }
                }
                // every edge crossed (thin strips): the edges as they are
                let crossed = if n == edges8.len() {
                    &edges8[..]
                } else {
                    &failing[..n]
                };
                if n > 0 {
                    for &lanes in g.block_lanes(b) {
                        test(crossed, lanes);
                    }
                }
            }
        }
        None => ground_lanes(points)
            .into_iter()
            .for_each(|lanes| test(&edges8, lanes)),
    }
    out
}

/// The lanes of eight ground points (x, y) lying outside some edge
/// (n·p < c; a NaN lane lies outside none), as a bit mask.
#[inline(always)]
fn outside_of(edges: &[[f32x8; 3]], x: f32x8, y: f32x8) -> u32 {
    let mut outside = f32x8::ZERO;
    for [nx, ny, c] in edges {
        outside |= (*nx * x + *ny * y).simd_lt(*c);
    }
    outside.to_bitmask()
}

/// A ground point (finite `f32` coordinates) as one integer whose order
/// is the points' order by x, then y: each coordinate's bits made
/// monotone (negative values flipped, the sign bit set on the rest), −0
/// taken as +0 (they are equal). Integers sort several times faster than
/// pairs of floats compared field by field, and the hull needs its
/// candidates sorted.
fn ground_key(x: f32, y: f32) -> u64 {
    let monotone = |v: f32| {
        let b = (v + 0.0).to_bits();
        if b >> 31 == 1 {
            !b
        } else {
            b | 1 << 31
        }
    };
    (u64::from(monotone(x)) << 32) | u64::from(monotone(y))
}

/// The point a [`ground_key`] stands for.
fn ground_point(key: u64) -> [f64; 2] {
    let value = |m: u32| {
        let b = if m >> 31 == 1 { m & !(1 << 31) } else { !m };
        f32::from_bits(b) as f64
    };
    [value((key >> 32) as u32), value(key as u32)]
}

/// Andrew's monotone chain over the points of `keys` ([`ground_key`]);
/// returns the hull counter-clockwise without repeating the first point
/// (1 or 2 points for degenerate input).
pub(super) fn convex_hull(mut keys: Vec<u64>) -> Vec<[f64; 2]> {
    keys.sort_unstable();
    keys.dedup();
    let pts: Vec<[f64; 2]> = keys.into_iter().map(ground_point).collect();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut lower: Vec<[f64; 2]> = Vec::new();
    for &p in &pts {
        while lower.len() >= 2 && cross(lower[lower.len() - 2], lower[lower.len() - 1], p) <= 0.0 {
            lower.pop();
        }
        lower.push(p);
    }
    let mut upper: Vec<[f64; 2]> = Vec::new();
    for &p in pts.iter().rev() {
        while upper.len() >= 2 && cross(upper[upper.len() - 2], upper[upper.len() - 1], p) <= 0.0 {
            upper.pop();
        }
        upper.push(p);
    }
    lower.pop();
    upper.pop();
    lower.extend(upper);
    lower
}

/// Minimum-area enclosing rectangle of a convex polygon: (cx, cy, length,
/// width, yaw of the length side).
pub(super) fn min_area_rect(hull: &[[f64; 2]]) -> (f64, f64, f64, f64, f64) {
    match hull.len() {
        0 => return (0.0, 0.0, 0.0, 0.0, 0.0),
        1 => return (hull[0][0], hull[0][1], 0.0, 0.0, 0.0),
        _ => {}
    }
    let mut best: Option<(f64, f64, f64, f64, f64, f64)> = None; // area, cx, cy, a, b, angle
    for i in 0..hull.len() {
        let p = hull[i];
        let q = hull[(i + 1) % hull.len()];
        let (dx, dy) = (q[0] - p[0], q[1] - p[1]);
        let n = (dx * dx + dy * dy).sqrt();
        if n == 0.0 {
            continue;
        }
        let (ux, uy) = (dx / n, dy / n);
        let (mut amin, mut amax, mut bmin, mut bmax) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for h in hull {
            let a = h[0] * ux + h[1] * uy;
            let b = -h[0] * uy + h[1] * ux;
            amin = amin.min(a);
            amax = amax.max(a);
            bmin = bmin.min(b);
            bmax = bmax.max(b);
        }
        let area = (amax - amin) * (bmax - bmin);
        if best.is_none_or(|b| area < b.0 - 1e-12) {
            let (ac, bc) = (0.5 * (amin + amax), 0.5 * (bmin + bmax));
            let cx = ac * ux - bc * uy;
            let cy = ac * uy + bc * ux;
            best = Some((area, cx, cy, amax - amin, bmax - bmin, uy.atan2(ux)));
        }
    }
    let Some((_, cx, cy, a, b, ang)) = best else {
        return (hull[0][0], hull[0][1], 0.0, 0.0, 0.0);
    };
    let (len, wid, mut yaw) = if a >= b {
        (a, b, ang)
    } else {
        (b, a, ang + std::f64::consts::FRAC_PI_2)
    };
    // a box is symmetric under a half turn: fold the yaw into (−π/2, π/2]
    while yaw > std::f64::consts::FRAC_PI_2 + 1e-12 {
        yaw -= std::f64::consts::PI;
    }
    while yaw <= -std::f64::consts::FRAC_PI_2 + 1e-12 {
        yaw += std::f64::consts::PI;
    }
    (cx, cy, len, wid, yaw)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The integer keys order ground points as comparing x then y does
    /// (`total_cmp`, −0 as +0), and give the points back exactly: the
    /// hull's sort and dedup are those of the points themselves.
    #[test]
    fn ground_keys_sort_as_the_points_and_give_them_back() {
        let mut next = crate::perception::test_sequence(5);
        let mut value = || -> f32 {
            match next() % 6 {
                0 => 0.0,
                1 => -0.0,
                2 => f32::from_bits(1) * if next().is_multiple_of(2) { 1.0 } else { -1.0 },
                3 => (next() % 7) as f32 * 0.25 - 0.75,
                _ => (next() % 2_000_001) as f32 * 1e-3 - 1000.0,
            }
        };
        let pts: Vec<[f32; 2]> = (0..3000).map(|_| [value(), value()]).collect();
        let canon = |v: f32| (v + 0.0) as f64;
        for a in &pts {
            let back = ground_point(ground_key(a[0], a[1]));
            assert_eq!(
                back.map(f64::to_bits),
                [canon(a[0]), canon(a[1])].map(f64::to_bits)
            );
        }
        for w in pts.windows(2) {
            let (a, b) = (w[0].map(canon), w[1].map(canon));
            let by_points = a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1]));
            let by_keys = ground_key(w[0][0], w[0][1]).cmp(&ground_key(w[1][0], w[1][1]));
            assert_eq!(by_keys, by_points, "{:?} {:?}", w[0], w[1]);
        }
    }

    /// The hull from the candidates (the octagon's test, and blocks whose
    /// bounds lie inside dropped whole) is the hull of every point: clouds
    /// of rectangles, rotated ones, thin strips, rings, on coarse and fine
    /// grids (ties, repeated points), as rows of pixels arrive.
    #[test]
    fn the_candidates_hull_is_every_points_hull() {
        let mut next = crate::perception::test_sequence(11);
        for case in 0..300 {
            let n = 64 + next() % 3000;
            let yaw = (next() % 360) as f64 * std::f64::consts::PI / 180.0;
            let (len, wid) = (
                0.1 + (next() % 200) as f64 * 0.01,
                0.02 + (next() % 100) as f64 * 0.01,
            );
            let grid = [0.05f64, 0.001, 1e-6][case % 3];
            let ring = case % 5 == 0;
            let row = 1 + next() % 90;
            let points: Vec<Point3<f32>> = (0..n)
                .map(|i| {
                    // a raster: rows of `row` points across the shape
                    let (a, b) = (
                        (i % row) as f64 / row as f64 - 0.5,
                        (i / row) as f64 / (n / row + 1) as f64 - 0.5,
                    );
                    let (a, b) = if ring && a.abs() < 0.3 && b.abs() < 0.3 {
                        (a.signum() * 0.45, b)
                    } else {
                        (a, b)
                    };
                    let (x, y) = (a * len, b * wid);
                    let (c, s) = (yaw.cos(), yaw.sin());
                    let snap = |v: f64| (v / grid).round() * grid;
                    Point3::new(
                        snap(1.5 + x * c - y * s) as f32,
                        snap(-0.7 + x * s + y * c) as f32,
                        0.1 * (i % 7) as f32,
                    )
                })
                .collect();
            let lanes = ground_lanes(&points);
            let (sweep, blocks) = Sweep::of_lanes(&points, &lanes);
            let sweep = sweep.unwrap();
            let ground = Ground {
                lanes: &lanes,
                blocks: &blocks,
            };
            let every = convex_hull(points.iter().map(|p| ground_key(p.x, p.y)).collect());
            // the blocks' candidates are exactly the point-by-point test's
            let set = |mut keys: Vec<u64>| {
                keys.sort_unstable();
                keys.dedup();
                keys
            };
            let by_blocks = hull_candidates(&points, &sweep, Some(ground));
            let by_points = hull_candidates(&points, &sweep, None);
            assert_eq!(
                set(by_blocks.clone()),
                set(by_points.clone()),
                "case {case}"
            );
            let from_blocks = convex_hull(by_blocks);
            let from_points = convex_hull(by_points);
            assert_eq!(from_blocks, every, "case {case}");
            assert_eq!(from_points, every, "case {case}");
        }
    }
}
