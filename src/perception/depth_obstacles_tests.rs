//! Tests of `perception::depth_obstacles` (split out to keep it readable).

use super::*;
use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion};

/// The fields of a cell's extremes, to compare them exactly.
fn fields(e: &Extremes) -> (usize, [[u64; 2]; 4], u64, u64) {
    (
        e.count,
        e.points.map(|p| p.map(f64::to_bits)),
        e.low_z_m.to_bits(),
        e.high_z_m.to_bits(),
    )
}

#[test]
fn runs_merged_are_the_points_added_one_by_one() {
    let mut rng = crate::sim::scene::SplitMix64::new(5);
    let mut checked_ties = 0;
    for _ in 0..500 {
        // coarse values: ties on an extreme are frequent
        let n = 1 + rng.below(12);
        let pts: Vec<([f64; 2], f64)> = (0..n)
            .map(|_| {
                let q = |rng: &mut crate::sim::scene::SplitMix64| rng.below(4) as f64 * 0.01;
                ([q(&mut rng), q(&mut rng)], q(&mut rng))
            })
            .collect();
        let mut one_by_one = Extremes::default();
        for (p, z) in &pts {
            one_by_one.add(*p, *z);
        }
        // the same points cut into runs at random places
        let mut merged = Extremes::default();
        let mut run = Extremes::default();
        for (p, z) in &pts {
            if rng.chance(0.4) {
                merged.merge(&run);
                run = Extremes::default();
            }
            run.add(*p, *z);
        }
        merged.merge(&run);
        merged.merge(&Extremes::default());
        assert_eq!(fields(&merged), fields(&one_by_one), "{pts:?}");
        checked_ties += usize::from(pts.iter().filter(|(p, _)| p[0] == 0.0).count() > 1);
    }
    assert!(checked_ties > 50, "{checked_ties}");
}

fn k() -> Intrinsics {
    Intrinsics {
        width: 160,
        height: 120,
        fx: 80.0,
        fy: 80.0,
        cx: 79.5,
        cy: 59.5,
    }
}

/// A camera 0.9 m up at base x = 0.3, pitched down by `pitch_deg`.
fn base_from_camera(pitch_deg: f64) -> Isometry3<f64> {
    let level = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
    let level = Rotation3::from_matrix_unchecked(level);
    let pitch = Rotation3::from_axis_angle(&nalgebra::Vector3::y_axis(), pitch_deg.to_radians());
    Isometry3::from_parts(
        Translation3::new(0.3, 0.0, 0.9),
        UnitQuaternion::from_rotation_matrix(&(pitch * level)),
    )
}

/// Renders a floor at height `floor_z(x, y)` (a height field sampled
/// along each ray) and a box [x0, x1] × [y0, y1] × [0, top].
fn render(
    t: &Isometry3<f64>,
    floor_z: impl Fn(f64, f64) -> f64,
    boxed: Option<([f64; 4], f64)>,
) -> DepthImage {
    let k = k();
    let mut d = vec![0.0f32; k.width * k.height];
    let o = t.translation.vector;
    for v in 0..k.height {
        for u in 0..k.width {
            let dir_cam =
                nalgebra::Vector3::new((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy, 1.0);
            let dir = t.rotation * dir_cam;
            // march along the ray in optical-z steps of 5 mm
            let mut z = 0.05;
            while z < 6.0 {
                let p = o + dir * z;
                let hit_box = boxed.is_some_and(|(b, top)| {
                    p.x >= b[0] && p.x <= b[1] && p.y >= b[2] && p.y <= b[3] && p.z <= top
                });
                if hit_box || p.z <= floor_z(p.x, p.y) {
                    d[v * k.width + u] = z as f32;
                    break;
                }
                z += 0.005;
            }
        }
    }
    DepthImage::new(k.width, k.height, d).expect("image")
}

fn any_in<const N: usize>(cells: &[[f32; N]], x: (f64, f64), y: (f64, f64)) -> bool {
    cells.iter().any(|c| {
        (c[0] as f64) >= x.0 && (c[0] as f64) <= x.1 && (c[1] as f64) >= y.0 && (c[1] as f64) <= y.1
    })
}

#[test]
fn a_flat_floor_is_floor_and_nothing_else() {
    let t = base_from_camera(30.0);
    let s = scan(
        &render(&t, |_, _| 0.0, None),
        &k(),
        &t,
        &DepthObstacleSettings::default(),
    );
    assert!(s.obstacles_base.is_empty(), "{:?}", s.obstacles_base);
    assert!(s.drop_offs_base.is_empty(), "{:?}", s.drop_offs_base);
    assert!(s.floor_base.len() > 100);
}

/// A cell reports where its points are: every obstacle point lies on
/// the box (to the renderer's 5 mm steps), where a cell's centre lies
/// up to half a cell off it — in front of a face that crosses the
/// cell, or beside it — and the points reach the box's edges.
#[test]
fn obstacle_cells_lie_on_the_box_not_at_cell_centres() {
    let t = base_from_camera(30.0);
    // faces off the 5 cm grid: x 1.535 (the cell 1.50–1.55's centre
    // 1.525 is in front of it), y −0.213 (the cell's centre −0.225
    // beside it)
    let b = [1.535, 1.9, -0.213, 0.187];
    let s = scan(
        &render(&t, |_, _| 0.0, Some((b, 0.3))),
        &k(),
        &t,
        &DepthObstacleSettings {
            // every pixel: the points' spacing well under a centimetre
            stride_px: 1,
            ..DepthObstacleSettings::default()
        },
    );
    assert!(s.obstacles_base.len() > 10, "{:?}", s.obstacles_base);
    for p in &s.obstacles_base {
        let (x, y) = (p[0] as f64, p[1] as f64);
        assert!(
            x >= b[0] - 0.006 && x <= b[1] + 0.006 && y >= b[2] - 0.006 && y <= b[3] + 0.006,
            "{p:?} off the box {b:?}"
        );
    }
    // and reach its edges: the front face and both sides (a cell's
    // mean lies inside an edge by up to half a cell)
    let fold = |f: fn(f64, f64) -> f64, i: usize, from: f64| {
        s.obstacles_base.iter().map(|p| p[i] as f64).fold(from, f)
    };
    let nearest = fold(f64::min, 0, f64::INFINITY);
    let (right, left) = (
        fold(f64::min, 1, f64::INFINITY),
        fold(f64::max, 1, f64::NEG_INFINITY),
    );
    assert!((nearest - b[0]).abs() < 0.01, "{nearest}");
    assert!(
        (right - b[2]).abs() < 0.01 && (left - b[3]).abs() < 0.01,
        "{right} {left}"
    );
}

/// A 0.3 m box 1.5–1.9 m ahead, 0.4 m wide, seen by the camera 0.9 m
/// up and pitched 30° down.
fn low_box_scan() -> DepthScan {
    let t = base_from_camera(30.0);
    let b = [1.5, 1.9, -0.2, 0.2];
    scan(
        &render(&t, |_, _| 0.0, Some((b, 0.3))),
        &k(),
        &t,
        &DepthObstacleSettings::default(),
    )
}

#[test]
fn a_low_box_under_the_lasers_is_an_obstacle_where_it_stands() {
    let s = low_box_scan();
    assert!(any_in(&s.obstacles_base, (1.45, 1.95), (-0.25, 0.25)));
    // nothing outside the box (its faces, within a cell)
    for c in &s.obstacles_base {
        assert!(
            any_in(&[*c], (1.45, 1.95), (-0.25, 0.25)),
            "obstacle outside the box at {c:?}"
        );
    }
    // each point carries its cell's lowest height: on the box, above
    // the floor band; the front face is seen down to the band's top
    let band = DepthObstacleSettings::default().floor_band_m;
    for c in &s.obstacles_base {
        let z = c[2] as f64;
        assert!(z > band && z <= 0.3 + 1e-6, "height {z} of {c:?}");
    }
    let front_low = s
        .obstacles_base
        .iter()
        .filter(|c| (c[0] as f64) < 1.55)
        .map(|c| c[2] as f64)
        .fold(f64::INFINITY, f64::min);
    assert!(front_low < band + 0.03, "front face lowest {front_low}");
    // and its cell's highest: the box's top, 0.3 m, on the cells of its
    // top; none above it, none below its cell's lowest
    assert_eq!(s.obstacle_tops_m.len(), s.obstacles_base.len());
    for (c, top) in s.obstacles_base.iter().zip(&s.obstacle_tops_m) {
        assert!(*top >= c[2] && *top <= 0.3 + 1e-6, "top {top} of {c:?}");
    }
    let highest = s.obstacle_tops_m.iter().copied().fold(0.0, f32::max);
    assert!(highest > 0.28, "highest {highest}");
}

/// The frame's nearest surfaces: a point behind the box (as the
/// camera sees it) is hidden, one beside it is not, nor the box's own
/// centre, nor a point outside the image.
#[test]
fn a_nearer_surface_hides_what_is_behind_it() {
    let s = low_box_scan();
    let n = &s.nearest;
    assert!(n.cols > 0 && n.rows > 0);
    // on the line from the camera (0.9 m up) over the box's top edge
    // (1.5, 0, 0.3) on to 2 m ahead, 6 cm up: behind the box
    let (eye, top) = ([0.3, 0.0, 0.9], [1.5, 0.0, 0.3]);
    let behind = [
        eye[0] + 1.4 * (top[0] - eye[0]),
        0.0,
        eye[2] + 1.4 * (top[2] - eye[2]),
    ];
    assert!(n.hides(&behind, 0.2), "{behind:?}");
    // the box itself (its centre 0.2 m behind its front face)
    assert!(!n.hides(&[1.7, 0.0, 0.15], 0.28));
    // beside the box, on the floor's level
    assert!(!n.hides(&[2.25, 1.2, 0.05], 0.2));
    // behind the camera
    assert!(!n.hides(&[-2.0, 0.0, 0.5], 0.2));
    // no frame: nothing is hidden
    assert!(!NearestDepth::default().hides(&behind, 0.2));
}

#[test]
fn a_step_down_is_a_drop_off_at_its_edge() {
    let t = base_from_camera(30.0);
    // the floor drops 0.15 m from x = 2.0 on
    let s = scan(
        &render(&t, |x, _| if x >= 2.0 { -0.15 } else { 0.0 }, None),
        &k(),
        &t,
        &DepthObstacleSettings::default(),
    );
    assert!(!s.drop_offs_base.is_empty());
    for c in &s.drop_offs_base {
        assert!(c[0] >= 1.95, "drop-off before the edge at {c:?}");
    }
    // the first drop-off cells are at the edge
    let nearest = s
        .drop_offs_base
        .iter()
        .map(|c| c[0])
        .fold(f32::INFINITY, f32::min);
    assert!(nearest < 2.15, "nearest drop-off {nearest}");
    assert!(s.obstacles_base.is_empty());
}

#[test]
fn a_step_down_out_of_view_ahead_of_the_chair_is_put_at_its_front() {
    // pitched 30° down, the bottom row sees the floor from x = 0.68 m
    // on; the floor drops 0.25 m from x = 0.62 m, 7 cm ahead of the
    // chair's front (0.55 m), out of the camera's view
    let t = base_from_camera(30.0);
    let step = render(&t, |x, _| if x >= 0.62 { -0.25 } else { 0.0 }, None);
    let nearest = |s: &DepthScan| {
        s.drop_offs_base
            .iter()
            .chain(&s.drop_offs_unseen_base)
            .filter(|c| c[1].abs() < 0.35)
            .map(|c| c[0])
            .fold(f32::INFINITY, f32::min)
    };
    // where the rays cross the floor plane alone: beyond the edge
    let plain = scan(&step, &k(), &t, &DepthObstacleSettings::default());
    assert!(nearest(&plain) > 0.66, "{}", nearest(&plain));
    assert!(plain.drop_offs_unseen_base.is_empty());
    // with the chair's front known: from there on, all across its width
    let front = DepthObstacleSettings {
        chair_front_m: Some(0.55),
        ..DepthObstacleSettings::default()
    };
    let s = scan(&step, &k(), &t, &front);
    let n = nearest(&s);
    assert!((0.55..0.61).contains(&n), "nearest drop-off {n}");
    assert!(s.drop_offs_unseen_base.iter().all(|c| c[0] >= 0.55));
    // (what the rays saw is apart from what may be there)
    assert_eq!(s.drop_offs_base, plain.drop_offs_base);
    for y in [-0.3f64, 0.0, 0.3] {
        assert!(
            any_in(&s.drop_offs_unseen_base, (0.55, 0.62), (y - 0.05, y + 0.05)),
            "none at y = {y}"
        );
    }
    // a step the camera sees, and a flat floor: nothing added
    let seen = scan(
        &render(&t, |x, _| if x >= 2.0 { -0.15 } else { 0.0 }, None),
        &k(),
        &t,
        &front,
    );
    assert!(seen.drop_offs_base.iter().all(|c| c[0] >= 1.95));
    assert!(seen.drop_offs_unseen_base.is_empty());
    let flat = scan(&render(&t, |_, _| 0.0, None), &k(), &t, &front);
    assert!(flat.drop_offs_base.is_empty() && flat.drop_offs_unseen_base.is_empty());
}

#[test]
fn missing_depth_is_unknown_and_single_pixels_do_not_count() {
    let t = base_from_camera(30.0);
    let k = k();
    let mut d = vec![0.0f32; k.width * k.height];
    // one pixel says something stands 0.3 m high 1.5 m ahead
    let p_base = Point3::new(1.5, 0.0, 0.3);
    let p_cam = t.inverse() * p_base;
    let u = (p_cam.x / p_cam.z * k.fx + k.cx).round() as usize;
    let v = (p_cam.y / p_cam.z * k.fy + k.cy).round() as usize;
    let u = u - u % 2;
    let v = v - v % 2;
    d[v * k.width + u] = p_cam.z as f32;
    let img = DepthImage::new(k.width, k.height, d).expect("image");
    let s = scan(&img, &k, &t, &DepthObstacleSettings::default());
    assert!(s.obstacles_base.is_empty() && s.drop_offs_base.is_empty());
    assert!(s.floor_base.is_empty());
    // the one pixel is the only depth its frame had
    let known = s.nearest.nearest_m.iter().filter(|d| d.is_finite());
    assert_eq!(known.count(), 1);
    let one = DepthObstacleSettings {
        min_hits: 1,
        ..Default::default()
    };
    assert_eq!(scan(&img, &k, &t, &one).obstacles_base.len(), 1);
}
