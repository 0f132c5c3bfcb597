//! The scan matcher's tests.

use super::*;
use crate::sim::scene::SplitMix64;

#[test]
fn compose_and_inverse_are_consistent() {
    let a = Pose2 {
        x_m: 1.0,
        y_m: -2.0,
        theta_rad: 0.7,
    };
    let id = compose(&a, &inverse(&a));
    assert!(id.x_m.abs() < 1e-12 && id.y_m.abs() < 1e-12 && id.theta_rad.abs() < 1e-12);
}

#[test]
fn too_few_points_is_an_error_naming_the_scan() {
    let e = icp(
        &[[0.0, 0.0]; 10],
        &[[0.0, 0.0]; 100],
        Pose2::default(),
        &IcpParams::default(),
    )
    .expect_err("too few");
    assert!(
        e.to_string().contains("reference scan has 10 points"),
        "{e}"
    );
}

/// Straight walls of points and scattered clutter: `walls` walls of
/// `per_wall` points starting within ±`span` m, each point `spacing` on
/// from the wall's start times its number, m; then `clutter` points
/// within ±`clutter_span` m.
fn walls_and_clutter(
    rng: &mut SplitMix64,
    (walls, per_wall, span): (usize, usize, f64),
    spacing: &mut dyn FnMut(&mut SplitMix64) -> f64,
    (clutter, clutter_span): (usize, f64),
) -> Vec<[f64; 2]> {
    let mut pts = Vec::new();
    for _ in 0..walls {
        let (x0, y0, a) = (
            rng.range(-span, span),
            rng.range(-span, span),
            rng.range(0.0, 3.2),
        );
        for j in 0..per_wall {
            let s = j as f64 * spacing(rng);
            pts.push([x0 + s * a.cos(), y0 + s * a.sin()]);
        }
    }
    for _ in 0..clutter {
        pts.push([
            rng.range(-clutter_span, clutter_span),
            rng.range(-clutter_span, clutter_span),
        ]);
    }
    pts
}

#[test]
fn the_grid_finds_the_nearest_point_as_a_search_of_all_points_does() {
    // walls and clutter with empty stretches between them, queries
    // inside and outside the points' box, near and far
    let mut rng = SplitMix64::new(3);
    let mut pts = walls_and_clutter(&mut rng, (6, 80, 4.0), &mut |_| 0.02, (40, 5.0));
    // a point twice: ties go to the lower index
    pts.push(pts[17]);
    let grid = Grid::new(&pts, 0.03);
    let mut found = 0;
    for q in 0..4000 {
        let q = if q == 0 {
            pts[17]
        } else {
            [rng.range(-7.0, 7.0), rng.range(-7.0, 7.0)]
        };
        for max_d in [0.05, 0.3, 1.0, 2.5] {
            let brute = pts
                .iter()
                .enumerate()
                .map(|(i, p)| (i, (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)))
                .filter(|(_, d2)| *d2 <= max_d * max_d)
                .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
            assert_eq!(grid.nearest(&q, max_d), brute, "q {q:?} within {max_d}");
            found += usize::from(brute.is_some());
        }
    }
    assert!(found > 3000, "{found}");
    assert_eq!(grid.nearest(&[1e300, 0.0], 1.0), None);
}

#[test]
fn the_cells_candidates_give_the_grids_nearest_point() {
    // walls of points 1–2 cm apart and scattered points; queries close to
    // the walls (many to a cell, as scan after scan is matched), across
    // the whole box, outside it, and on cell corners
    let mut rng = SplitMix64::new(11);
    let mut pts = walls_and_clutter(
        &mut rng,
        (8, 120, 3.0),
        &mut |rng| rng.range(0.01, 0.02),
        (30, 4.0),
    );
    pts.push(pts[40]);
    let grid = Grid::new(&pts, 0.03);
    let mut cache = NearestCache::new(&grid);
    let mut gathered = 0;
    for k in 0..60_000 {
        let q = match k % 4 {
            0 | 1 => {
                let p = pts[rng.range(0.0, pts.len() as f64) as usize % pts.len()];
                [p[0] + rng.range(-0.08, 0.08), p[1] + rng.range(-0.08, 0.08)]
            }
            2 => [rng.range(-6.0, 6.0), rng.range(-6.0, 6.0)],
            _ => {
                // a cell corner of the grid
                let (ix, iy) = (rng.range(0.0, 400.0).floor(), rng.range(0.0, 400.0).floor());
                [
                    grid.origin[0] + ix * cache.cell,
                    grid.origin[1] + iy * cache.cell,
                ]
            }
        };
        let max_d = [0.02, 0.1, 0.3, 1.0][k % 4];
        assert_eq!(
            cache.nearest(&grid, &pts, &q, max_d),
            grid.nearest(&q, max_d),
            "q {q:?} within {max_d}"
        );
        if k == 0 {
            // the duplicate's tie goes to the lower index
            assert_eq!(cache.nearest(&grid, &pts, &pts[40], 0.1), Some((40, 0.0)));
        }
        gathered = cache.ranges.len();
    }
    // the cache was used: most queries fell in cells gathered before
    assert!(gathered > 1000 && gathered < 30_000, "{gathered}");
    assert_eq!(cache.nearest(&grid, &pts, &[f64::NAN, 0.0], 1.0), None);
}
