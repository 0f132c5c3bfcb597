//! Tests of `navigation::manoeuvre` (split out to keep it readable).

use super::*;
use crate::navigation::map::MapSettings;

/// The chair's footprint as the supervisor keeps it at a crawl.
const SHAPE: ManoeuvreShape = ManoeuvreShape {
    front_m: 0.55,
    rear_m: 0.45,
    half_width_m: 0.35,
    side_margin_m: 0.03,
    ahead_m: 0.15,
    turn_radius_m: 0.68,
};

/// Points of a wall from `a` to `b` (odom), 2 cm apart.
fn wall(a: [f64; 2], b: [f64; 2]) -> Vec<[f64; 2]> {
    let len = (b[0] - a[0]).hypot(b[1] - a[1]);
    let n = (len / 0.02).ceil() as usize;
    (0..=n)
        .map(|k| {
            let t = k as f64 / n as f64;
            [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
        })
        .collect()
}

/// The manoeuvre from `start` to within 8 cm of `goal`, turned within
/// 0.2 rad of `yaw_rad`, for [`SHAPE`].
fn plan_to(
    map: &GridMap,
    seen_now: &[[f64; 2]],
    no_turns: &[([f64; 2], f64)],
    start: Pose2,
    goal: [f64; 2],
    yaw_rad: f64,
) -> Option<Vec<Move>> {
    plan(
        map, seen_now, no_turns, start, goal, yaw_rad, 0.08, 0.2, &SHAPE,
    )
}

fn map_of(points: &[[f64; 2]]) -> GridMap {
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    map.set_camera(points, &[]);
    map.update_distances();
    map
}

/// The chair driven by the follower at 20 Hz, as a unicycle; its poses.
fn drive(moves: Vec<Move>, start: Pose2) -> Vec<Pose2> {
    let mut f = Follower::new(moves);
    let mut pose = start;
    let mut poses = vec![pose];
    for _ in 0..20_000 {
        let Some(cmd) = f.command(pose, 0.08, 0.14) else {
            return poses;
        };
        let dt = 0.05;
        pose.x_m += cmd.v_mps * pose.theta_rad.cos() * dt;
        pose.y_m += cmd.v_mps * pose.theta_rad.sin() * dt;
        pose.theta_rad = wrap_angle(pose.theta_rad + cmd.omega_radps * dt);
        poses.push(pose);
    }
    panic!("the follower never finished");
}

/// Whether the footprint (no margins) at `pose` holds any of `points`.
fn touches(pose: &Pose2, points: &[[f64; 2]]) -> bool {
    let (s, c) = pose.theta_rad.sin_cos();
    points.iter().any(|q| {
        let (dx, dy) = (q[0] - pose.x_m, q[1] - pose.y_m);
        let (x, y) = (c * dx + s * dy, -s * dx + c * dy);
        (-SHAPE.rear_m..=SHAPE.front_m).contains(&x) && y.abs() <= SHAPE.half_width_m
    })
}

#[test]
fn in_the_open_it_is_a_turn_and_a_straight_drive() {
    let map = map_of(&[]);
    let start = Pose2::default();
    let moves = plan_to(
        &map,
        &[],
        &[],
        start,
        [0.0, 2.0],
        std::f64::consts::FRAC_PI_2,
    )
    .expect("a manoeuvre in the open");
    assert_eq!(moves.len(), 2, "{moves:?}");
    assert!(matches!(moves[0], Move::Turn { .. }), "{moves:?}");
    assert!(
        matches!(moves[1], Move::Straight { forward: true, .. }),
        "{moves:?}"
    );
    let end = *drive(moves, start).last().expect("poses");
    assert!(end.x_m.hypot(end.y_m - 2.0) <= 0.1, "{end:?}");
}

/// A 0.85 m doorway in a wall at x = 1 and a wall 1.5 m beyond it: the
/// chair, facing the doorway, must pass it whole before it can turn left
/// to the goal along the far wall. Every turn is made where the corners'
/// circle is clear, and the footprint never touches a wall.
#[test]
fn through_a_doorway_it_turns_only_once_past_it() {
    let mut points = wall([1.0, -4.0], [1.0, -0.425]);
    points.extend(wall([1.0, 0.425], [1.0, 4.0]));
    points.extend(wall([2.5 + 0.8, -4.0], [2.5 + 0.8, 4.0]));
    let map = map_of(&points);
    let start = Pose2 {
        x_m: 0.2,
        y_m: 0.0,
        theta_rad: 0.0,
    };
    let goal = [2.4, 2.0];
    let moves = plan_to(&map, &[], &[], start, goal, std::f64::consts::FRAC_PI_2)
        .expect("a manoeuvre through the doorway");
    let mut pose = start;
    for m in &moves {
        match *m {
            Move::Turn { .. } => {
                let nearest = points
                    .iter()
                    .map(|q| (q[0] - pose.x_m).hypot(q[1] - pose.y_m))
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    nearest >= SHAPE.turn_radius_m - 0.05,
                    "a turn at {pose:?} with a wall {nearest} m away: {moves:?}"
                );
            }
            Move::Straight {
                to, heading_rad, ..
            } => {
                pose = Pose2 {
                    x_m: to[0],
                    y_m: to[1],
                    theta_rad: heading_rad,
                };
            }
        }
    }
    let poses = drive(moves, start);
    for p in &poses {
        assert!(
            !touches(p, &points),
            "the footprint touches a wall at {p:?}"
        );
    }
    let end = *poses.last().expect("poses");
    assert!(
        (end.x_m - goal[0]).hypot(end.y_m - goal[1]) <= 0.12,
        "{end:?}"
    );
    assert!(
        wrap_angle(end.theta_rad - std::f64::consts::FRAC_PI_2).abs() <= 0.25,
        "{end:?}"
    );
}

/// The goal past a wall with no gap the chair fits through (a 0.6 m one):
/// no manoeuvre.
#[test]
fn past_a_wall_with_no_gap_wide_enough_there_is_none() {
    let mut points = wall([1.0, -4.0], [1.0, -0.3]);
    points.extend(wall([1.0, 0.3], [1.0, 4.0]));
    let map = map_of(&points);
    let start = Pose2::default();
    assert_eq!(plan_to(&map, &[], &[], start, [2.0, 0.0], 0.0), None);
}

/// Backing up: the chair's front 5 cm from a wall, the goal behind it
/// facing the same way; the manoeuvre backs up (no turn needed, none
/// fits with the wall so near).
#[test]
fn against_a_wall_it_backs_away() {
    let points = wall([0.6, -3.0], [0.6, 3.0]);
    let map = map_of(&points);
    let start = Pose2::default();
    let moves = plan_to(&map, &[], &[], start, [-1.0, 0.0], 0.0).expect("a way back");
    assert!(
        matches!(moves[0], Move::Straight { forward: false, .. }),
        "{moves:?}"
    );
    let end = *drive(moves, start).last().expect("poses");
    assert!(
        (end.x_m + 1.0).abs() <= 0.1 && end.y_m.abs() <= 0.1,
        "{end:?}"
    );
}

/// What the supervisor sees now counts as the map does: the same wall
/// with no gap wide enough, given only as the points seen now (the map
/// empty), leaves no manoeuvre; a gap of 0.85 m in it leaves one.
#[test]
fn the_points_seen_now_are_kept_clear_as_the_map_is() {
    let map = map_of(&[]);
    let start = Pose2::default();
    let with_gap = |gap_m: f64| {
        let mut points = wall([1.0, -4.0], [1.0, -gap_m / 2.0]);
        points.extend(wall([1.0, gap_m / 2.0], [1.0, 4.0]));
        points
    };
    let narrow = with_gap(0.6);
    assert_eq!(plan_to(&map, &narrow, &[], start, [2.0, 0.0], 0.0), None);
    let wide = with_gap(0.85);
    let moves =
        plan_to(&map, &wide, &[], start, [2.0, 0.0], 0.0).expect("a manoeuvre through the gap");
    for p in drive(moves, start) {
        assert!(
            !touches(&p, &wide),
            "the footprint touches the wall at {p:?}"
        );
    }
}

/// Where the person said it is not clear around, no turn on the spot:
/// in the open, the goal to the left, the manoeuvre drives away before it
/// turns.
#[test]
fn no_turn_where_the_person_said_no() {
    let map = map_of(&[]);
    let start = Pose2::default();
    let goal = [0.0, 2.0];
    let no_turns = [([0.0, 0.0], 0.15)];
    let moves = plan_to(
        &map,
        &[],
        &no_turns,
        start,
        goal,
        std::f64::consts::FRAC_PI_2,
    )
    .expect("a manoeuvre");
    assert!(
        matches!(moves[0], Move::Straight { .. }),
        "turned where it was told not to: {moves:?}"
    );
    let end = *drive(moves, start).last().expect("poses");
    assert!(
        (end.x_m - goal[0]).hypot(end.y_m - goal[1]) <= 0.1,
        "{end:?}"
    );
}

/// The narrowest doorway of the benchmark, 0.80 m, on the map alone and
/// turned to the grid at twelve angles (its jambs' cells fall differently
/// at each): 5 cm a side for the chair and its crawl's margins (0.76 m).
/// The manoeuvre goes through, and the chair driven by the follower never
/// touches a wall.
#[test]
fn through_the_narrowest_doorway_on_the_map() {
    for k in 0..12 {
        let turned_rad = 0.3 + k as f64 * 0.1;
        let (s, c) = turned_rad.sin_cos();
        let turn = |p: [f64; 2]| [c * p[0] - s * p[1], s * p[0] + c * p[1]];
        let mut points = wall([1.0, -4.0], [1.0, -0.40]);
        points.extend(wall([1.0, 0.40], [1.0, 4.0]));
        let points: Vec<[f64; 2]> = points.into_iter().map(turn).collect();
        let map = map_of(&points);
        let from = turn([0.0, 0.0]);
        let start = Pose2 {
            x_m: from[0],
            y_m: from[1],
            theta_rad: turned_rad,
        };
        let goal = turn([2.2, 0.0]);
        let moves = plan_to(&map, &[], &[], start, goal, turned_rad)
            .unwrap_or_else(|| panic!("no manoeuvre through the doorway turned {turned_rad} rad"));
        for p in drive(moves, start) {
            assert!(
                !touches(&p, &points),
                "the footprint touches a wall at {p:?}"
            );
        }
    }
}

/// Through a 0.82 m doorway whose axis lies between the lattice's 5°
/// steps, from before it turned 1 rad off its axis: the turns end on the
/// axis itself (the lattice holds the goal's heading), and the footprint
/// never touches a wall.
#[test]
fn through_a_doorway_turned_off_its_axis_the_turns_end_on_it() {
    for k in 0..6 {
        let axis_rad = 0.37 + k as f64 * 0.61;
        let (s, c) = axis_rad.sin_cos();
        let turn = |p: [f64; 2]| [c * p[0] - s * p[1], s * p[0] + c * p[1]];
        let mut points = wall([1.0, -4.0], [1.0, -0.41]);
        points.extend(wall([1.0, 0.41], [1.0, 4.0]));
        let points: Vec<[f64; 2]> = points.into_iter().map(turn).collect();
        let map = map_of(&points);
        let from = turn([-0.1, 0.3]);
        let start = Pose2 {
            x_m: from[0],
            y_m: from[1],
            theta_rad: wrap_angle(axis_rad + 1.0),
        };
        let goal = turn([1.8, 0.0]);
        let moves = plan(&map, &[], &[], start, goal, axis_rad, 0.15, 0.3, &SHAPE)
            .unwrap_or_else(|| panic!("no manoeuvre through the doorway on axis {axis_rad} rad"));
        for m in &moves {
            if let Move::Straight { heading_rad, .. } = m {
                let off = wrap_angle(heading_rad - axis_rad).abs();
                assert!(
                    !(1e-9..=0.05).contains(&off),
                    "a straight move {off} rad off the axis: {moves:?}"
                );
            }
        }
        for p in drive(moves, start) {
            assert!(
                !touches(&p, &points),
                "the footprint touches a wall at {p:?} (axis {axis_rad} rad)"
            );
        }
    }
}
