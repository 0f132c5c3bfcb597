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
            Move::Arc { .. } => panic!("a bend where turns and straight moves do: {moves:?}"),
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

/// Whether the footprint with `margin_m` all round at `pose` holds any of
/// `points`.
fn within(pose: &Pose2, points: &[[f64; 2]], margin_m: f64) -> bool {
    let (s, c) = pose.theta_rad.sin_cos();
    points.iter().any(|q| {
        let (dx, dy) = (q[0] - pose.x_m, q[1] - pose.y_m);
        let (x, y) = (c * dx + s * dy, -s * dx + c * dy);
        (-SHAPE.rear_m - margin_m..=SHAPE.front_m + margin_m).contains(&x)
            && y.abs() <= SHAPE.half_width_m + margin_m
    })
}

/// A wall 0.5 m to the chair's right all along its way: no circle for a
/// turn on the spot (0.68 m) is clear anywhere on its line, so turns and
/// straight crawls cannot shift it 0.45 m to the left; bends can, and the
/// footprint never touches the wall on them (driven by the follower).
#[test]
fn where_no_turn_fits_it_works_sideways_on_bends() {
    let points = wall([-3.0, -0.5], [4.0, -0.5]);
    let map = map_of(&points);
    let start = Pose2::default();
    let goal = [1.6, 0.45];
    let plan_at = |bends: bool| {
        let f = if bends { plan_with_bends } else { plan };
        f(&map, &[], &[], start, goal, 0.0, 0.08, 0.2, &SHAPE)
    };
    assert_eq!(plan_at(false), None, "no turn fits beside the wall");
    let moves = plan_at(true).expect("a way on bends");
    assert!(
        moves.iter().any(|m| matches!(m, Move::Arc { .. })),
        "{moves:?}"
    );
    assert!(
        !moves.iter().any(|m| matches!(m, Move::Turn { .. })),
        "no turn on the spot fits: {moves:?}"
    );
    let poses = drive(moves.clone(), start);
    assert!(
        poses.iter().all(|p| !touches(p, &points)),
        "touched the wall: {moves:?}"
    );
    let end = *poses.last().expect("poses");
    assert!(
        (end.x_m - goal[0]).hypot(end.y_m - goal[1]) <= 0.12 && end.theta_rad.abs() <= 0.25,
        "ended at {end:?}: {moves:?}"
    );
}

/// The search keeps a bend's footprint clear with the crawl's margin all
/// round, as the supervisor's arc check does: every pose along each bend
/// found, and on along it over the stop distance, is clear of the wall
/// by the margin (2 mm of rounding spared).
#[test]
fn a_bend_keeps_the_margin_the_supervisor_keeps() {
    let points = wall([-3.0, -0.5], [4.0, -0.5]);
    let map = map_of(&points);
    let start = Pose2::default();
    let moves = plan_with_bends(&map, &[], &[], start, [1.6, 0.45], 0.0, 0.08, 0.2, &SHAPE)
        .expect("a way on bends");
    let mut from = start;
    for m in &moves {
        match *m {
            Move::Arc {
                to,
                to_rad,
                forward,
                turn_rad_per_m,
            } => {
                let dir = if forward { 1.0 } else { -1.0 };
                let turn = wrap_angle(to_rad - from.theta_rad);
                let len_m = (turn / turn_rad_per_m).abs();
                let n = ((len_m + SHAPE.ahead_m) / 0.01).ceil() as usize;
                for i in 0..=n {
                    let s_m = (len_m + SHAPE.ahead_m) * i as f64 / n as f64;
                    let q = from.advanced(dir * s_m, turn_rad_per_m * s_m);
                    assert!(
                        !within(&q, &points, SHAPE.side_margin_m - 0.002),
                        "{q:?} on {m:?}"
                    );
                }
                from = Pose2 {
                    x_m: to[0],
                    y_m: to[1],
                    theta_rad: to_rad,
                };
            }
            Move::Straight {
                to, heading_rad, ..
            } => {
                from = Pose2 {
                    x_m: to[0],
                    y_m: to[1],
                    theta_rad: heading_rad,
                }
            }
            Move::Turn { to_rad } => from.theta_rad = to_rad,
        }
    }
}

/// The follower keeps to a bend, forward and back: a quarter circle of
/// 0.69 m driven from its start ends within 2 cm of its end, turned
/// within a degree, and every pose on the way lies within 2 cm of the
/// circle; backing up on a right bend turns the heading left.
#[test]
fn the_follower_keeps_to_a_bend_forward_and_back() {
    let per_m = 1.0 / 0.69;
    let quarter = std::f64::consts::FRAC_PI_2;
    for (forward, turn_rad_per_m) in [(true, per_m), (true, -per_m), (false, -per_m)] {
        let dir = if forward { 1.0 } else { -1.0 };
        let start = Pose2::default();
        let len_m = quarter / per_m;
        let end = start.advanced(dir * len_m, turn_rad_per_m * dir * len_m);
        let m = Move::Arc {
            to: [end.x_m, end.y_m],
            to_rad: end.theta_rad,
            forward,
            turn_rad_per_m,
        };
        let poses = drive(vec![m], start);
        let last = *poses.last().expect("poses");
        assert!(
            (last.x_m - end.x_m).hypot(last.y_m - end.y_m) <= 0.02,
            "{last:?} against {end:?}"
        );
        assert!(
            wrap_angle(last.theta_rad - end.theta_rad).abs() <= 0.02,
            "{last:?} against {end:?}"
        );
        let centre = [0.0, 1.0 / turn_rad_per_m];
        for p in &poses {
            let off = (p.x_m - centre[0]).hypot(p.y_m - centre[1]) - centre[1].abs();
            assert!(off.abs() <= 0.02, "{p:?} off the circle by {off}");
        }
        if !forward {
            assert!(last.theta_rad > 1.5, "{last:?}");
        }
    }
}

/// The bends the search finds are driven under the supervisor itself: the
/// wall 0.5, 0.49 and 0.48 m to the right given to it as the lasers' points each 50 ms
/// step, the follower's command through it (its outputs, ramped, drive
/// the chair), the chair never held on the way and at the goal in the
/// end — the search keeps a bend clear as the supervisor checks it.
#[test]
fn the_supervisor_lets_the_bends_found_be_driven() {
    for wall_y in [-0.5, -0.49, -0.48] {
        bends_driven_under_the_supervisor(wall_y);
    }
}

fn bends_driven_under_the_supervisor(wall_y: f64) {
    use crate::msg::{Obstacles, Odometry, Stamp, Stamped, SupervisorState};
    use crate::safety::{rear::RearView, Supervisor, SupervisorInputs};
    let mut supervisor = Supervisor::new(crate::config::Settings::defaults().safety_limits());
    let shape = ManoeuvreShape::at_a_crawl(&supervisor);
    let points = wall([-3.0, wall_y], [4.0, wall_y]);
    let map = map_of(&points);
    let start = Pose2::default();
    let goal = [1.6, 0.45];
    // the wall seen now as well, as the control step gives the search
    // what the supervisor holds the chair for
    let moves = plan_with_bends(&map, &points, &[], start, goal, 0.0, 0.08, 0.2, &shape)
        .unwrap_or_else(|| panic!("a way on bends, the wall at {wall_y}"));
    supervisor.goal_active();
    let mut follower = Follower::new(moves.clone());
    let mut pose = start;
    let mut out = crate::msg::VelocityCmd::default();
    let rear = RearView {
        seen: true,
        reverse_seen: true,
        around_vouched: false,
        points_base: Vec::new(),
    };
    let turn_radps = supervisor.crawl_turn_radps();
    let mut done = false;
    for k in 0..4000u64 {
        let now = Stamp(std::time::Duration::from_millis(50 * k));
        let Some(cmd) = follower.command(pose, 0.08, turn_radps) else {
            done = true;
            break;
        };
        let points_base: Vec<[f32; 2]> = points
            .iter()
            .map(|q| {
                let b = pose.base_from_odom(*q);
                [b[0] as f32, b[1] as f32]
            })
            .collect();
        let lasers = Stamped::new(
            now,
            Obstacles {
                points_base,
                ..Default::default()
            },
        );
        let camera = Stamped::new(now, Obstacles::default());
        let odometry = Stamped::new(
            now,
            Odometry {
                pose,
                v_mps: out.v_mps,
                omega_radps: out.omega_radps,
                ..Default::default()
            },
        );
        let command = Stamped::new(now, cmd);
        let safe = supervisor.step(
            now,
            &SupervisorInputs {
                obstacles: Some(&lasers),
                odometry: Some(&odometry),
                command: Some(&command),
                camera: Some(&camera),
                rear: Some(&rear),
            },
        );
        assert_eq!(
            safe.state,
            SupervisorState::Navigating,
            "the wall at {wall_y}: held at {pose:?} asked {cmd:?}: {moves:?}"
        );
        out = safe.cmd;
        pose = pose.advanced(out.v_mps * 0.05, out.omega_radps * 0.05);
        assert!(!touches(&pose, &points), "{pose:?}");
    }
    assert!(done, "the manoeuvre never ended: at {pose:?}");
    assert!(
        (pose.x_m - goal[0]).hypot(pose.y_m - goal[1]) <= 0.12,
        "ended at {pose:?}: {moves:?}"
    );
}
