//! The scan matcher's tests.

use super::*;

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

#[test]
fn the_grid_finds_the_nearest_point_as_a_search_of_all_points_does() {
    // walls and clutter with empty stretches between them, queries
    // inside and outside the points' box, near and far
    let mut rng = crate::sim::scene::SplitMix64::new(3);
    let mut pts: Vec<[f64; 2]> = Vec::new();
    for _ in 0..6 {
        let (x0, y0, a) = (
            rng.range(-4.0, 4.0),
            rng.range(-4.0, 4.0),
            rng.range(0.0, 3.2),
        );
        for j in 0..80 {
            let s = j as f64 * 0.02;
            pts.push([x0 + s * a.cos(), y0 + s * a.sin()]);
        }
    }
    for _ in 0..40 {
        pts.push([rng.range(-5.0, 5.0), rng.range(-5.0, 5.0)]);
    }
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
    let mut rng = crate::sim::scene::SplitMix64::new(11);
    let mut pts: Vec<[f64; 2]> = Vec::new();
    for _ in 0..8 {
        let (x0, y0, a) = (
            rng.range(-3.0, 3.0),
            rng.range(-3.0, 3.0),
            rng.range(0.0, 3.2),
        );
        for j in 0..120 {
            let s = j as f64 * rng.range(0.01, 0.02);
            pts.push([x0 + s * a.cos(), y0 + s * a.sin()]);
        }
    }
    for _ in 0..30 {
        pts.push([rng.range(-4.0, 4.0), rng.range(-4.0, 4.0)]);
    }
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
