//! The MPC's tests: bounds, obstacles, the rows left out, the front disc.

use super::*;
use crate::sim::scene::SplitMix64;

fn step(s: UnicycleState, cmd: VelocityCmd, dt: f64) -> UnicycleState {
    let (v, w) = (cmd.v_mps, cmd.omega_radps);
    let th = s.theta_rad;
    let (x, y) = if w.abs() < 1e-9 {
        (s.x_m + v * dt * th.cos(), s.y_m + v * dt * th.sin())
    } else {
        let r = v / w;
        (
            s.x_m + r * ((th + w * dt).sin() - th.sin()),
            s.y_m - r * ((th + w * dt).cos() - th.cos()),
        )
    };
    UnicycleState {
        x_m: x,
        y_m: y,
        theta_rad: th + w * dt,
        v_mps: v,
        omega_radps: w,
    }
}

#[test]
fn reaches_a_goal_in_open_space_within_bounds() {
    let p = crate::config::Settings::defaults().mpc;
    let mut s = UnicycleState::default();
    let goal = [3.0, 2.0];
    for _ in 0..300 {
        let bearing = (goal[1] - s.y_m).atan2(goal[0] - s.x_m);
        let plan = solve(
            &MpcProblem {
                state: s,
                goal,
                heading_ref_rad: Some(bearing),
                v_ref_mps: 0.3,
                obstacles: vec![],
            },
            &p,
        )
        .unwrap();
        assert!(plan.cmd.v_mps <= p.v_max_mps + 1e-6 && plan.cmd.v_mps >= p.v_min_mps - 1e-6);
        assert!(plan.cmd.omega_radps.abs() <= p.omega_max_radps + 1e-6);
        assert!((plan.cmd.v_mps - s.v_mps).abs() <= p.accel_max_mps2 * p.dt_s + 1e-6);
        s = step(s, plan.cmd, p.dt_s);
    }
    let d = (s.x_m - goal[0]).hypot(s.y_m - goal[1]);
    assert!(d < 0.15, "ended {d} m from the goal at {s:?}");
}

#[test]
fn keeps_clear_of_an_obstacle_on_the_way() {
    let p = crate::config::Settings::defaults().mpc;
    let mut s = UnicycleState::default();
    let goal = [4.0, 0.0];
    let obstacle = [2.0, 0.05];
    let mut closest = f64::INFINITY;
    for _ in 0..300 {
        let plan = match solve(
            &MpcProblem {
                state: s,
                goal,
                heading_ref_rad: None,
                v_ref_mps: 0.3,
                obstacles: vec![obstacle],
            },
            &p,
        ) {
            Ok(plan) => plan,
            Err(_) => break,
        };
        s = step(s, plan.cmd, p.dt_s);
        closest = closest.min((s.x_m - obstacle[0]).hypot(s.y_m - obstacle[1]));
    }
    assert!(closest > p.clearance_m - 0.1, "came within {closest} m");
}

/// A point just inside the line of the chair's side, ahead of it, and
/// a wall on the other side 1 m from it: the disc about base_link
/// keeps its eight nearest points, all on the wall, until the point is
/// abreast of base_link, by when the front corner has passed within a
/// centimetre of it (and the supervisor's corridor, 0.38 m a side at a
/// crawl, would have held the chair). The front disc has its own
/// nearest points: the corner passes 4 cm off, more than the crawl's
/// 3 cm margin.
#[test]
fn the_front_disc_keeps_the_front_corners_clear_of_a_point_beside_the_way() {
    // from the footprint (0.45 m behind base_link to 0.55 m ahead,
    // 0.35 m a side), m
    let footprint_gap = |s: &UnicycleState, o: [f64; 2]| {
        let (c, sn) = (s.theta_rad.cos(), s.theta_rad.sin());
        let (dx, dy) = (o[0] - s.x_m, o[1] - s.y_m);
        let (xb, yb) = (c * dx + sn * dy, -sn * dx + c * dy);
        let ex = (-0.45 - xb).max(xb - 0.55).max(0.0);
        let ey = (yb.abs() - 0.35).max(0.0);
        ex.hypot(ey)
    };
    let point = [1.2, -0.36];
    let wall = (0..200).map(|i| [-1.0 + 0.02 * i as f64, 0.65]);
    let obstacles: Vec<[f64; 2]> = std::iter::once(point).chain(wall).collect();
    let closest_with = |front_disc_m: f64| {
        let p = MpcParams {
            front_disc_m,
            ..crate::config::Settings::defaults().mpc
        };
        let mut s = UnicycleState::default();
        let mut closest = f64::INFINITY;
        for _ in 0..200 {
            let plan = solve(
                &MpcProblem {
                    state: s,
                    goal: [4.0, 0.0],
                    heading_ref_rad: Some(0.0),
                    v_ref_mps: 0.3,
                    obstacles: obstacles.clone(),
                },
                &p,
            )
            .expect("solves");
            s = step(s, plan.cmd, p.dt_s);
            closest = closest.min(footprint_gap(&s, point));
        }
        assert!(s.x_m > 3.5, "did not get past: {s:?}");
        closest
    };
    let without = closest_with(0.0);
    let with = closest_with(0.45);
    assert!(without < 0.015, "{without}");
    assert!(with > 0.04, "{with} (without the disc {without})");
}

/// Where the front disc leaves no plan, the plan is the one without it
/// (said in the plan), not none: at full speed towards a point 0.5 m
/// ahead of the front disc, its rollout passes the point within the
/// horizon and the disc's rows before and after it cannot both hold.
#[test]
fn without_a_plan_for_the_front_disc_the_plan_is_the_one_without_it() {
    let p = MpcParams {
        front_disc_m: 0.45,
        ..crate::config::Settings::defaults().mpc
    };
    let problem = MpcProblem {
        state: UnicycleState {
            v_mps: 0.3,
            ..Default::default()
        },
        goal: [4.0, 0.0],
        heading_ref_rad: Some(0.0),
        v_ref_mps: 0.3,
        obstacles: vec![[p.front_disc_m + 0.5, 0.0]],
    };
    assert!(solve_discs(&problem, &p).is_err());
    let plan = solve(&problem, &p).expect("a plan");
    let alone = solve_discs(
        &problem,
        &MpcParams {
            front_disc_m: 0.0,
            ..p
        },
    )
    .expect("a plan without the disc");
    assert!(!plan.front_disc && alone.front_disc == plan.front_disc);
    assert_eq!(plan.cmd, alone.cmd);
    // braking for the point
    assert!(plan.cmd.v_mps < 0.3, "{:?}", plan.cmd);
}

/// The rows left out rest on `position_reach_m`: every rollout of the
/// QP's linearised dynamics with inputs and speeds within their
/// bounds (here at the extremes, bang-bang, where the reach is
/// largest) stays within it.
#[test]
fn the_position_reach_bounds_every_rollout_of_the_linearised_dynamics() {
    let p = MpcParams {
        horizon: 30,
        ..crate::config::Settings::defaults().mpc
    };
    let (n, dt) = (p.horizon, p.dt_s);
    let mut r = SplitMix64::new(0x4EAC_0001);
    let mut largest_share: f64 = 0.0;
    for _ in 0..2000 {
        let s0 = UnicycleState {
            x_m: r.range(-2.0, 2.0),
            y_m: r.range(-2.0, 2.0),
            theta_rad: r.range(-3.1, 3.1),
            v_mps: r.range(-0.1, 0.35),
            omega_radps: r.range(-0.8, 0.8),
        };
        let reach = position_reach_m(&s0, &p, n);
        let (mut x, mut y, mut th, mut v, mut w) =
            (s0.x_m, s0.y_m, s0.theta_rad, s0.v_mps, s0.omega_radps);
        let extreme = r.unit() < 0.5;
        for k in 0..n {
            // the reference rollout at k (constant speeds)
            let th_ref = s0.theta_rad + dt * s0.omega_radps * k as f64;
            let (st, ct) = th_ref.sin_cos();
            let (nx, ny) = (
                x + dt * ct * v - dt * s0.v_mps * st * (th - th_ref),
                y + dt * st * v + dt * s0.v_mps * ct * (th - th_ref),
            );
            th += dt * w;
            (x, y) = (nx, ny);
            let d = (x - s0.x_m).hypot(y - s0.y_m);
            assert!(
                d <= reach[k + 1] + 1e-12,
                "step {}: {d} > {}",
                k + 1,
                reach[k + 1]
            );
            largest_share = largest_share.max(d / reach[k + 1].max(1e-9));
            // inputs, then the next speeds kept within the QP's bounds
            let pick = |r: &mut SplitMix64, m: f64| {
                if extreme {
                    if r.unit() < 0.5 {
                        -m
                    } else {
                        m
                    }
                } else {
                    r.range(-m, m)
                }
            };
            let ramp = p.accel_max_mps2 * dt * (k + 1) as f64;
            let (v_lo, v_hi) = (
                p.v_min_mps.min(s0.v_mps + ramp),
                p.v_max_mps.max(s0.v_mps - ramp),
            );
            let a = pick(&mut r, p.accel_max_mps2);
            v = (v + dt * a)
                .clamp(v_lo, v_hi)
                .clamp(v - dt * p.accel_max_mps2, v + dt * p.accel_max_mps2);
            let alpha = pick(&mut r, p.alpha_max_radps2);
            w = (w + dt * alpha)
                .clamp(-p.omega_max_radps, p.omega_max_radps)
                .clamp(w - dt * p.alpha_max_radps2, w + dt * p.alpha_max_radps2);
        }
    }
    // the bound is not vacuous: some rollouts come near it
    assert!(largest_share > 0.5, "{largest_share}");
}

/// A seeded problem from the origin: a heading, speed and turn, a goal
/// within 4 m, a heading to track near the heading, and up to twelve
/// points within `spread_rad` of the heading, `near_m` to 3 m away.
fn seeded_problem(r: &mut SplitMix64, spread_rad: f64, near_m: f64) -> MpcProblem {
    let theta = r.range(-3.1, 3.1);
    let state = UnicycleState {
        x_m: 0.0,
        y_m: 0.0,
        theta_rad: theta,
        v_mps: r.range(0.0, 0.3),
        omega_radps: r.range(-0.5, 0.5),
    };
    MpcProblem {
        state,
        goal: [r.range(-4.0, 4.0), r.range(-4.0, 4.0)],
        heading_ref_rad: Some(theta + r.range(-0.8, 0.8)),
        v_ref_mps: r.range(0.05, 0.3),
        obstacles: (0..(r.unit() * 12.0) as usize)
            .map(|_| {
                let a = theta + r.range(-spread_rad, spread_rad);
                let d = r.range(near_m, 3.0);
                [d * a.cos(), d * a.sin()]
            })
            .collect(),
    }
}

/// The plans keep every constraint of the full problem, the rows left
/// out included: all the half-planes and both speed bounds at every
/// step, over seeded cases with obstacles near and far.
#[test]
fn plans_keep_the_constraints_whose_rows_were_left_out() {
    let p = MpcParams {
        horizon: 30,
        ..crate::config::Settings::defaults().mpc
    };
    let mut r = SplitMix64::new(0x4EAC_0002);
    let mut binding = 0;
    for _ in 0..200 {
        let problem = seeded_problem(&mut r, 1.5, 0.6);
        let state = problem.state;
        let Ok(plan) = solve(&problem, &p) else {
            continue;
        };
        for (k, s) in plan.states.iter().enumerate() {
            for (nrm, bb) in &plan.half_planes[k] {
                let side = nrm[0] * s.x_m + nrm[1] * s.y_m - bb;
                assert!(side >= -1e-4, "step {}: {side}", k + 1);
                if side < 1e-3 {
                    binding += 1;
                }
            }
            let ramp = p.accel_max_mps2 * p.dt_s * (k + 1) as f64;
            let v_lo = p.v_min_mps.min(state.v_mps + ramp);
            let v_hi = p.v_max_mps.max(state.v_mps - ramp);
            assert!(s.v_mps >= v_lo - 1e-4 && s.v_mps <= v_hi + 1e-4, "{s:?}");
            assert!(s.omega_radps.abs() <= p.omega_max_radps + 1e-4, "{s:?}");
        }
    }
    // obstacles shaped some plans
    assert!(binding > 0);
}

/// The front disc's rows left out rest on the same reach and on how far
/// its centre can swing (`swing_per_m`): the plans that kept the disc
/// keep every one of its rows, those left out included, over seeded
/// cases with points beside and ahead of the way.
#[test]
fn plans_with_the_front_disc_keep_its_rows_that_were_left_out() {
    let p = MpcParams {
        horizon: 30,
        front_disc_m: 0.45,
        ..crate::config::Settings::defaults().mpc
    };
    let mut r = SplitMix64::new(0x4EAC_0003);
    let (mut with_disc, mut binding, mut rows) = (0, 0, 0);
    for _ in 0..200 {
        let problem = seeded_problem(&mut r, 1.2, 0.7);
        let Ok(plan) = solve(&problem, &p) else {
            continue;
        };
        if !plan.front_disc {
            assert!(plan.front_rows.is_empty());
            continue;
        }
        with_disc += 1;
        assert_eq!(plan.front_rows.len(), plan.states.len());
        for (k, s) in plan.states.iter().enumerate() {
            for (nrm, g, bb) in &plan.front_rows[k] {
                rows += 1;
                let side = nrm[0] * s.x_m + nrm[1] * s.y_m + g * s.theta_rad - bb;
                assert!(side >= -1e-4, "step {}: {side}", k + 1);
                if side < 1e-3 {
                    binding += 1;
                }
            }
        }
    }
    // most cases kept the disc, and its rows shaped some plans
    assert!(with_disc > 100, "{with_disc}");
    assert!(rows > 0 && binding > 0, "{rows} {binding}");
}

#[test]
fn nearest_points_are_a_stable_sort_by_distance_cut_short() {
    let mut r = SplitMix64::new(0x4EAC_0002);
    for case in 0..200 {
        // points on a coarse lattice: many at the same distance
        let n = (r.next_u64() % 40) as usize;
        let pts: Vec<[f64; 2]> = (0..n)
            .map(|_| {
                [
                    r.range(-3.0, 3.0).round() / 2.0,
                    r.range(-3.0, 3.0).round() / 2.0,
                ]
            })
            .collect();
        let c = [0.0, if case % 2 == 0 { 0.0 } else { 0.25 }];
        let max = (r.next_u64() % 15) as usize;
        let mut want = pts.clone();
        want.sort_by(|a, b| dist_sq(a, &c).total_cmp(&dist_sq(b, &c)));
        want.truncate(max);
        assert_eq!(
            nearest_points(&pts, c, max),
            want,
            "case {case}: {n} points, {max} kept"
        );
    }
}
