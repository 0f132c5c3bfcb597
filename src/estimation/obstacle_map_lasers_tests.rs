use super::*;
use crate::estimation::obstacle_map::FootprintM;
use crate::msg::LaserScan;
use crate::perception::depth_obstacles::DepthScan;
use crate::sensors::laser::scan_rays;
use crate::sensors::scip::SensorParams;
use nalgebra::{Isometry3, Vector3};

const F: FootprintM = FootprintM {
    front_m: 0.55,
    rear_m: 0.45,
    half_width_m: 0.35,
};

const HERE: Pose2 = Pose2 {
    x_m: 0.0,
    y_m: 0.0,
    theta_rad: 0.0,
};

/// The chair's two URG-04LX (as in `config/opennav.toml`): front corners,
/// 0.66 m up, looking left and right.
fn mounts() -> [Isometry3<f64>; 2] {
    [
        Isometry3::new(
            Vector3::new(0.33, 0.2, 0.66),
            Vector3::z() * std::f64::consts::FRAC_PI_2,
        ),
        Isometry3::new(
            Vector3::new(0.33, -0.2, 0.66),
            Vector3::z() * -std::f64::consts::FRAC_PI_2,
        ),
    ]
}

/// Both lasers' rays (base_link) in a round room 3.5 m about base_link,
/// with upright cylinders (centre, radius; m) standing at the lasers'
/// plane; steps in `blind_about` (a bearing from base_link and a half
/// width, rad) come back blind.
fn scan(cylinders: &[([f64; 2], f64)], blind_about: Option<(f64, f64)>) -> Vec<LaserRay> {
    scan_with_walls(cylinders, &[], blind_about)
}

/// As [`scan`], with wall segments too (ends, m).
fn scan_with_walls(
    cylinders: &[([f64; 2], f64)],
    walls: &[([f64; 2], [f64; 2])],
    blind_about: Option<(f64, f64)>,
) -> Vec<LaserRay> {
    let p = SensorParams::URG_04LX;
    let mut rays = Vec::new();
    for mount in mounts() {
        let o = mount.translation.vector;
        let values: Vec<u32> = (p.amin..=p.amax)
            .map(|step| {
                let a = p.step_angle_rad(step);
                let d = mount.rotation * Vector3::new(a.cos(), a.sin(), 0.0);
                let mut range = f64::INFINITY;
                // the room's wall: |o + t d| = 3.5
                let b = o.x * d.x + o.y * d.y;
                let c = o.x * o.x + o.y * o.y - 3.5 * 3.5;
                range = range.min(-b + (b * b - c).sqrt());
                for (centre, radius) in cylinders {
                    let (fx, fy) = (o.x - centre[0], o.y - centre[1]);
                    let b = fx * d.x + fy * d.y;
                    let c = fx * fx + fy * fy - radius * radius;
                    let disc = b * b - c;
                    if disc >= 0.0 && -b - disc.sqrt() > 0.0 {
                        range = range.min(-b - disc.sqrt());
                    }
                }
                for (a, b) in walls {
                    // o + t d = a + u (b − a), 0 ≤ u ≤ 1
                    let e = [b[0] - a[0], b[1] - a[1]];
                    let den = d.x * e[1] - d.y * e[0];
                    if den.abs() < 1e-12 {
                        continue;
                    }
                    let w = [a[0] - o.x, a[1] - o.y];
                    let t = (w[0] * e[1] - w[1] * e[0]) / den;
                    let u = (w[0] * d.y - w[1] * d.x) / den;
                    if t > 0.0 && (0.0..=1.0).contains(&u) {
                        range = range.min(t);
                    }
                }
                let end = [o.x + range * d.x, o.y + range * d.y];
                let bearing = end[1].atan2(end[0]);
                let blind = blind_about
                    .is_some_and(|(at, half)| crate::msg::wrap_angle(bearing - at).abs() <= half);
                // 1: no return, the light too weak (a blind step)
                if blind {
                    1
                } else {
                    (range * 1000.0).round() as u32
                }
            })
            .collect();
        let scan = LaserScan::from_values(&p, p.amin, &values, 0);
        rays.extend(scan_rays(&scan, &mount));
    }
    rays
}

/// A person's front as the camera sees it: the points of the cells on
/// the near half of a 0.2 m circle about `centre`.
fn person_seen(centre: [f64; 2]) -> DepthScan {
    let obstacles = (0..9)
        .map(|i| {
            let a = std::f64::consts::FRAC_PI_2 + i as f64 * std::f64::consts::PI / 8.0;
            [
                (centre[0] + 0.2 * a.cos()) as f32,
                (centre[1] + 0.2 * a.sin()) as f32,
                0.02,
            ]
        })
        .collect();
    DepthScan {
        obstacles_base: obstacles,
        ..Default::default()
    }
}

/// Where the person stands in the tests (odom, m) and their radius.
const PERSON: [f64; 2] = [2.0, 0.3];
const PERSON_R: f64 = 0.2;

/// A memory with the person seen by the camera from `HERE` and then by
/// the lasers; its cells' count.
fn person_seen_by_both() -> (ObstacleMap, usize) {
    let mut m = ObstacleMap::new(0.05, 4.0);
    m.insert(HERE, &person_seen(PERSON), F);
    let cells = m.len();
    m.on_lasers(HERE, &scan(&[(PERSON, PERSON_R)], None));
    (m, cells)
}

#[test]
fn a_person_the_lasers_saw_is_forgotten_once_their_rays_pass_where_they_stood() {
    let mut m = ObstacleMap::new(0.05, 4.0);
    let person = PERSON;
    m.insert(HERE, &person_seen(person), F);
    let cells = m.len();
    assert!(cells >= 5, "{cells}");
    // the lasers see the person where the camera did: nothing goes
    assert!(!m.on_lasers(HERE, &scan(&[(person, 0.2)], None)));
    assert_eq!(m.len(), cells);
    assert!(m.laser_seen_len() >= cells / 2, "{}", m.laser_seen_len());
    // they walk on, out of the camera's view: the rays pass
    assert!(m.on_lasers(HERE, &scan(&[], None)));
    assert!(
        m.points(CellKind::Obstacle).len() < 4,
        "{:?}",
        m.points(CellKind::Obstacle)
    );
    // (the marks go with their cells)
    assert!(m.laser_seen_len() <= m.len());
}

#[test]
fn a_box_under_the_lasers_plane_is_kept_when_the_rays_pass_over_it() {
    // the camera saw it; no laser's return ever landed on it
    let mut m = ObstacleMap::new(0.05, 4.0);
    m.insert(HERE, &person_seen([2.0, 0.3]), F);
    let cells = m.len();
    for _ in 0..3 {
        assert!(!m.on_lasers(HERE, &scan(&[], None)));
    }
    assert_eq!(m.len(), cells);
    assert_eq!(m.laser_seen_len(), 0);
}

/// [`person_seen`] with each cell's points seen from `low_m` up to
/// `top_m`.
fn seen_from_to(centre: [f64; 2], low_m: f32, top_m: f32) -> DepthScan {
    let mut d = person_seen(centre);
    for q in &mut d.obstacles_base {
        q[2] = low_m;
    }
    d.obstacle_tops_m = vec![top_m; d.obstacles_base.len()];
    d
}

/// A thing the camera saw from below the lasers' plane (0.66 m) to above
/// it counts as the lasers' though no return landed in its cells (the
/// camera saw a person's side, the lasers their front in the cells
/// beside): once the rays pass there, it is forgotten. One seen only
/// below the plane (a box the rays pass over), only above it (a table's
/// top the rays pass under) or barely across it stays, as does any
/// without the lasers' plane given.
#[test]
fn a_thing_seen_across_the_lasers_plane_is_forgotten_once_their_rays_pass_there() {
    let passes = |m: &mut ObstacleMap| {
        let cells = m.len();
        assert!(cells >= 5, "{cells}");
        let forgot = m.on_lasers(HERE, &scan(&[], None));
        (forgot, cells, m.len())
    };
    let mut person = ObstacleMap::new(0.05, 4.0).with_laser_plane(0.66);
    person.insert(HERE, &seen_from_to(PERSON, 0.06, 1.5), F);
    assert!(person.laser_seen_len() >= 5, "{}", person.laser_seen_len());
    let (forgot, before, after) = passes(&mut person);
    assert!(forgot && after < 4 && after < before, "{before} → {after}");
    for (what, low_m, top_m) in [
        ("a box", 0.06, 0.4),
        ("a table's top", 0.72, 0.75),
        ("a thing barely across", 0.6, 0.7),
    ] {
        let mut m = ObstacleMap::new(0.05, 4.0).with_laser_plane(0.66);
        m.insert(HERE, &seen_from_to(PERSON, low_m, top_m), F);
        assert_eq!(m.laser_seen_len(), 0, "{what}");
        let (forgot, before, after) = passes(&mut m);
        assert!(!forgot && after == before, "{what}: {before} → {after}");
    }
    let mut unknown_plane = ObstacleMap::new(0.05, 4.0);
    unknown_plane.insert(HERE, &seen_from_to(PERSON, 0.06, 1.5), F);
    let (forgot, before, after) = passes(&mut unknown_plane);
    assert!(!forgot && after == before, "{before} → {after}");
}

#[test]
fn a_thing_the_rays_still_end_at_or_beside_is_kept() {
    let (mut m, cells) = person_seen_by_both();
    // the lasers now find its surface 4 cm farther (the chair's pose a
    // little off, noise): rays end beside each cell
    let farther = [PERSON[0] + 0.04, PERSON[1]];
    assert!(!m.on_lasers(HERE, &scan(&[(farther, PERSON_R)], None)));
    assert_eq!(m.len(), cells);
}

#[test]
fn blind_steps_never_forget_anything() {
    // a black coat: the steps toward where the person stood come back
    // blind, and the others pass nowhere near
    let (mut m, cells) = person_seen_by_both();
    let person = PERSON;
    let toward = person[1].atan2(person[0]);
    // scan after scan: not even in time
    for _ in 0..2 * UNHIT_SCANS_TO_FORGET {
        assert!(!m.on_lasers(HERE, &scan(&[], Some((toward, 0.2)))));
    }
    assert_eq!(m.len(), cells);
}

#[test]
fn a_cell_the_camera_puts_again_keeps_its_mark_only_if_the_latest_scan_saw_it() {
    let (mut m, _) = person_seen_by_both();
    let person = PERSON;
    let marked = m.laser_seen_len();
    assert!(marked > 0);
    // the person still there: the camera puts the cells again, the marks
    // stay (they walk out of the camera's view next, the lasers see them go)
    m.insert(HERE, &person_seen(person), F);
    assert_eq!(m.laser_seen_len(), marked);
    // the person gone behind something the lasers cannot see through, and
    // what the camera sees there now is not what the lasers saw: unmarked
    m.on_lasers(HERE, &scan(&[([1.0, 0.15], 0.1)], None));
    m.insert(HERE, &person_seen(person), F);
    assert_eq!(m.laser_seen_len(), 0);
    let cells = m.len();
    assert!(!m.on_lasers(HERE, &scan(&[], None)));
    assert_eq!(m.len(), cells);
}

#[test]
fn the_chair_turned_the_rays_are_placed_with_its_pose() {
    // seen from the origin; the chair then turns a quarter left and moves:
    // the person, still there, is now to its right
    let (mut m, cells) = person_seen_by_both();
    let person = PERSON;
    let turned = Pose2 {
        x_m: 0.5,
        y_m: -0.5,
        theta_rad: std::f64::consts::FRAC_PI_2,
    };
    let in_base = turned.base_from_odom(person);
    assert!(in_base[1] < -1.0, "{in_base:?}");
    assert!(!m.on_lasers(turned, &scan(&[(in_base, 0.2)], None)));
    assert_eq!(m.len(), cells);
    assert!(m.on_lasers(turned, &scan(&[], None)));
}

#[test]
fn a_fan_finds_the_rays_about_a_bearing_across_the_turn() {
    // 11 rays from 170° on, 2° apart: the last at −170°
    let rays: Vec<LaserRay> = (0..11)
        .map(|i| {
            let a = (170.0 + 2.0 * i as f64).to_radians();
            LaserRay {
                origin_m: [0.0, 0.0],
                dir: [a.cos() as f32, a.sin() as f32],
                blind: false,
                range_m: Some(1.0),
            }
        })
        .collect();
    let f = fans(&rays);
    assert_eq!(f.len(), 1);
    let at = |deg: f64| {
        let got = f[0].about(deg.to_radians(), 1.5_f64.to_radians());
        got.iter()
            .map(|r| {
                (r.dir[1] as f64)
                    .atan2(r.dir[0] as f64)
                    .to_degrees()
                    .round() as i64
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(at(180.0), vec![178, 180, -178]);
    assert_eq!(at(-172.0), vec![-174, -172, -170]);
    // (a ray more at the window's edge at most: each is judged after)
    let near = at(170.5);
    assert!(near.starts_with(&[170, 172]) && near.len() <= 3, "{near:?}");
    assert!(at(90.0).is_empty());
    assert!(at(168.0).len() <= 1);
    // a clockwise fan the same
    let back: Vec<LaserRay> = rays.iter().rev().copied().collect();
    let f = fans(&back);
    let got = f[0].about(180_f64.to_radians(), 1.5_f64.to_radians());
    assert_eq!(got.len(), 3);
}

/// The estimation task's part: a scan that forgets cells sends the
/// memory again (with the newest frame's stamp: the camera's age is the
/// camera's), scans are put at most every 0.2 s, and a scan newer than
/// the odometry waits for it.
#[test]
fn the_estimation_sends_the_memory_the_lasers_changed() {
    use crate::daemon::estimation::Estimation;
    use crate::estimation::fusion::Estimator;
    use crate::estimation::tracker::Tracker;
    use crate::msg::{Obstacles, Stamp, Stamped};
    let s = crate::config::Settings::defaults();
    let mut est = Estimation::new(
        Estimator::new(s.drive_params()),
        Tracker::new(s.tracker),
        None,
    )
    .with_obstacle_map(&s.depth_obstacles, F, None);
    let t = Stamp::from_secs_f64;
    for i in 0..=10 {
        est.history.push(t(i as f64 * 0.1), HERE);
    }
    let person = PERSON;
    let rays = |cylinders: &[([f64; 2], f64)]| Obstacles {
        rays_base: scan(cylinders, None),
        ..Default::default()
    };
    let frame = est
        .on_depth_scan(Stamped::new(t(0.1), person_seen(person)))
        .expect("the frame placed");
    let seen = frame.value.obstacles_odom.len();
    assert!(seen >= 5, "{seen}");
    // the lasers see the person where the camera did
    assert!(est
        .on_scan(&Stamped::new(t(0.2), rays(&[(person, 0.2)])))
        .is_none());
    // gone, but 0.1 s on: not looked at yet
    assert!(est.on_scan(&Stamped::new(t(0.3), rays(&[]))).is_none());
    // 0.2 s on: forgotten, sent with the frame's stamp
    let after = est
        .on_scan(&Stamped::new(t(0.4), rays(&[])))
        .expect("the memory sent again");
    assert_eq!(after.stamp, t(0.1));
    assert!(
        after.value.obstacles_odom.len() < 4,
        "{:?}",
        after.value.obstacles_odom
    );
    assert_eq!(est.stats.laser_scans_forgetting_cells, 1);

    // a person seen again; a scan newer than the odometry waits for it
    est.on_depth_scan(Stamped::new(t(0.9), person_seen(person)));
    assert!(est
        .on_scan(&Stamped::new(t(0.95), rays(&[(person, 0.2)])))
        .is_none());
    assert!(est.on_scan(&Stamped::new(t(1.3), rays(&[]))).is_none());
    assert!(est.place_rays().is_none(), "no pose at 1.3 s yet");
    for i in 11..=14 {
        est.history.push(t(i as f64 * 0.1), HERE);
    }
    let after = est.place_rays().expect("placed once odometry passed it");
    assert!(after.value.obstacles_odom.len() < 4);
}

/// A memory with a wall's face at `y_m` to the left, from 0.8 m ahead to
/// `to_m`, seen by the camera from `HERE` (a point every 5 cm); the wall
/// and the memory's cell count.
fn wall_seen(y_m: f64, to_m: f64) -> (ObstacleMap, ([f64; 2], [f64; 2]), usize) {
    let n = ((to_m - 0.8) / 0.05).round() as usize;
    let face: Vec<[f32; 3]> = (0..=n)
        .map(|i| [(0.8 + 0.05 * i as f64) as f32, y_m as f32, 0.02])
        .collect();
    let mut m = ObstacleMap::new(0.05, 4.0);
    m.insert(
        HERE,
        &DepthScan {
            obstacles_base: face,
            ..Default::default()
        },
        F,
    );
    let cells = m.len();
    (m, ([0.8, y_m], [to_m, y_m]), cells)
}

#[test]
fn a_wall_the_rays_run_along_is_kept() {
    // a wall's face 0.52 m to the left (in the middle of its cells), from
    // 0.8 m to 2.5 m ahead, seen by the camera and hit by the lasers face on
    let (mut m, wall, cells) = wall_seen(0.52, 2.5);
    m.on_lasers(HERE, &scan_with_walls(&[], &[wall], None));
    assert!(
        m.laser_seen_len() > cells / 2,
        "{} of {cells}",
        m.laser_seen_len()
    );
    // the chair moves beside it: the left laser 12 mm from the face's
    // plane, its rays along the face pass within a centimetre of the
    // camera's points, and those at a slant end on it far apart
    let beside = Pose2 {
        x_m: 0.0,
        y_m: 0.52 - 0.2 - 0.012,
        theta_rad: 0.0,
    };
    let in_base = |p: [f64; 2]| beside.base_from_odom(p);
    let wall_base = (in_base(wall.0), in_base(wall.1));
    assert!(!m.on_lasers(beside, &scan_with_walls(&[], &[wall_base], None)));
    assert_eq!(m.len(), cells);
}
/// Where the scene was too tight for the rays beside a wall to keep its
/// cells (the other laser's view blocked, the returns along the face far
/// apart), the rays that run along a face do not count as passing it.
#[test]
fn rays_along_a_surface_do_not_pass_its_cells() {
    // a face 12 mm beside the left laser's straight-ahead ray, its
    // points in the middle of their cells
    let wall = ([0.8, 0.212], [2.5, 0.212]);
    let rays = scan_with_walls(&[], &[wall], None);
    let f = fans(&rays);
    let cell = [1.725, 0.225];
    let points = [[1.70, 0.212], [1.74, 0.212]];
    // alone (what a person's trail is to a ray across it): passed
    assert!(through(&f, cell, &points, 0.05, &|_| false) >= PASSES_TO_FORGET);
    // the face's cells before and after it along the rays remembered:
    // the rays run along the surface
    let face = |q: [f64; 2]| (q[1] - 0.225).abs() < 0.025 && (0.8..2.5).contains(&q[0]);
    assert_eq!(through(&f, cell, &points, 0.05, &face), 0);
}

/// A person who walked straight away from the chair, along the rays,
/// and stands 2 m ahead (seen across the lasers' plane): the cells where
/// the camera and the lasers saw them on the way lie along the rays, each
/// with its neighbours before and after it remembered and the person's
/// return within 0.3 m beyond the last, as a wall seen at a slant would.
/// No return lands in them or beside them any more: after
/// [`UNHIT_SCANS_TO_FORGET`] scans in a row they are forgotten, and the
/// cells of the person's surface stay.
#[test]
fn a_persons_trail_along_the_rays_is_forgotten_once_scans_land_nowhere_on_it() {
    let mut m = ObstacleMap::new(0.05, 4.0).with_laser_plane(0.66);
    let at = |x: f64| [x, PERSON[1]];
    // a frame every 5 cm of their way
    for x in (0..=16).map(|i| 1.2 + 0.05 * f64::from(i)) {
        m.insert(HERE, &seen_from_to(at(x), 0.06, 1.5), F);
        m.on_lasers(HERE, &scan(&[(at(x), PERSON_R)], None));
    }
    let standing = scan(&[(at(2.0), PERSON_R)], None);
    // the trail: points farther than two cells from the person's circle
    // (a cell beside the returns on them stays: noise, or a step)
    let trail = |m: &ObstacleMap| {
        m.points(CellKind::Obstacle)
            .into_iter()
            .filter(|p| (p[0] - 2.0).hypot(p[1] - PERSON[1]) > PERSON_R + 0.1)
            .count()
    };
    // the person's surface, where the returns land, and the cell before it
    let person = |m: &ObstacleMap| {
        m.points(CellKind::Obstacle)
            .into_iter()
            .filter(|p| (p[0] - 2.0).hypot(p[1] - PERSON[1]) <= PERSON_R + 0.05)
            .count()
    };
    let (trail_before, person_before) = (trail(&m), person(&m));
    assert!(
        trail_before >= 5 && person_before >= 3,
        "{trail_before} {person_before}"
    );
    // what one scan's rays cannot tell from a wall: all still there
    m.on_lasers(HERE, &standing);
    let kept = trail(&m);
    assert_eq!(kept, trail_before);
    // (the counts began as the person walked on)
    for _ in 1..UNHIT_SCANS_TO_FORGET {
        m.on_lasers(HERE, &standing);
    }
    // all but a point in a cell's corner, which one ray alone passes
    // within 1.5 cm of and through the cell's middle
    assert!(trail(&m) <= 1, "{kept} → {}", trail(&m));
    assert_eq!(person(&m), person_before);
}

/// The other side of that rule: a wall beside the chair, its face 0.33 m
/// from the left laser and in the far half of its cells (the rays through
/// the cells' middles pass on and end on the face beyond), keeps its
/// cells scan after scan: the rays at a slant land a return within a cell
/// of each (blind steps keep a cell too: `blind_steps_never_forget_anything`).
#[test]
fn a_wall_beside_the_chair_is_kept_scan_after_scan() {
    let (mut m, wall, cells) = wall_seen(0.545, 2.0);
    let rays = scan_with_walls(&[], &[wall], None);
    for _ in 0..3 * UNHIT_SCANS_TO_FORGET {
        m.on_lasers(HERE, &rays);
    }
    assert!(
        m.laser_seen_len() > cells / 2,
        "{} of {cells}",
        m.laser_seen_len()
    );
    assert_eq!(m.len(), cells);
}
