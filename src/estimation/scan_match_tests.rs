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
