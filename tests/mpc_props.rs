//! The MPC in randomised cases: every plan respects every bound and every
//! obstacle half-plane it was given.

use opennav::navigation::mpc::{solve, MpcParams, MpcProblem, UnicycleState};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(60))]

    #[test]
    fn plans_respect_bounds_and_obstacles(
        x in -2.0f64..2.0, y in -2.0f64..2.0, th in -3.1f64..3.1,
        v in 0.0f64..0.3, w in -0.8f64..0.8,
        gx in -5.0f64..5.0, gy in -5.0f64..5.0,
        obs in proptest::collection::vec((-4.0f64..4.0, -4.0f64..4.0), 0..6),
        n in 10usize..30,
    ) {
        let p = MpcParams { horizon: n, ..opennav::config::Settings::defaults().mpc };
        let obstacles: Vec<[f64; 2]> = obs.iter().map(|&(a, b)| [a, b])
            // the start itself must be clear for a feasible problem
            .filter(|o| (o[0] - x).hypot(o[1] - y) > p.clearance_m + 0.5)
            .collect();
        let problem = MpcProblem {
            state: UnicycleState { x_m: x, y_m: y, theta_rad: th, v_mps: v, omega_radps: w },
            goal: [gx, gy],
            heading_ref_rad: None,
            v_ref_mps: 0.3,
            obstacles,
        };
        // infeasible cases are reported, never a panic or a silent plan
        if let Ok(plan) = solve(&problem, &p) {
            let tol = 1e-5;
            let mut prev_v = v;
            let mut prev_w = w;
            for (k, s) in plan.states.iter().enumerate() {
                prop_assert!(s.v_mps >= p.v_min_mps - tol && s.v_mps <= p.v_max_mps + tol);
                prop_assert!(s.omega_radps.abs() <= p.omega_max_radps + tol);
                prop_assert!((s.v_mps - prev_v).abs() <= p.accel_max_mps2 * p.dt_s + tol);
                prop_assert!((s.omega_radps - prev_w).abs() <= p.alpha_max_radps2 * p.dt_s + tol);
                prev_v = s.v_mps;
                prev_w = s.omega_radps;
                for (nrm, b) in &plan.half_planes[k] {
                    prop_assert!(nrm[0] * s.x_m + nrm[1] * s.y_m >= b - tol, "step {} violates a half-plane", k + 1);
                }
            }
            for u in &plan.inputs {
                prop_assert!(u[0].abs() <= p.accel_max_mps2 + tol && u[1].abs() <= p.alpha_max_radps2 + tol);
            }
        }
    }
}
