//! Model-predictive control of the chair as a unicycle with accelerations
//! as inputs (as the paper group's MATMPC): state [x, y, θ, v, ω], inputs
//! [v̇, ω̇], linearised along a constant-velocity rollout, horizon N at
//! `dt_s`, bounds on v, ω and their rates, obstacles as half-planes from
//! the nearest obstacle points; one QP per cycle, solved with clarabel.
//! Pure: the problem in, the plan out.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettingsBuilder, DefaultSolver, IPSolver, SolverStatus, SupportedConeT,
};
use serde::Serialize;
use thiserror::Error;

use crate::msg::VelocityCmd;

/// The MPC's parameters (config `[mpc]`, read directly).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MpcParams {
    pub horizon: usize,
    pub dt_s: f64,
    pub v_min_mps: f64,
    pub v_max_mps: f64,
    pub omega_max_radps: f64,
    pub accel_max_mps2: f64,
    pub alpha_max_radps2: f64,
    pub w_position: f64,
    pub w_terminal: f64,
    pub w_heading: f64,
    pub w_speed: f64,
    pub w_omega: f64,
    pub w_accel: f64,
    pub w_alpha: f64,
    /// Keep this far from obstacle points (chair radius + margin), m.
    pub clearance_m: f64,
    /// A second disc of the same radius this far ahead of base_link on
    /// the chair's axis keeps the clearance too: the front corners and
    /// the stop corridor ahead of them, which the disc about base_link
    /// leaves out (0: none), m.
    pub front_disc_m: f64,
    /// Obstacle points considered (the nearest ones within `obstacle_range_m`).
    pub max_obstacles: usize,
    pub obstacle_range_m: f64,
}

/// [x, y, θ, v, ω] in the odometry frame.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct UnicycleState {
    pub x_m: f64,
    pub y_m: f64,
    pub theta_rad: f64,
    pub v_mps: f64,
    pub omega_radps: f64,
}

impl UnicycleState {
    fn to_array(self) -> [f64; 5] {
        [
            self.x_m,
            self.y_m,
            self.theta_rad,
            self.v_mps,
            self.omega_radps,
        ]
    }
    fn from_array(a: &[f64]) -> Self {
        UnicycleState {
            x_m: a[0],
            y_m: a[1],
            theta_rad: a[2],
            v_mps: a[3],
            omega_radps: a[4],
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct MpcProblem {
    pub state: UnicycleState,
    /// Where to go (the approach pose's position), same frame as the state.
    pub goal: [f64; 2],
    /// Heading to hold (e.g. the potential field's direction); None: free.
    pub heading_ref_rad: Option<f64>,
    /// Speed to track (e.g. the potential field's).
    pub v_ref_mps: f64,
    /// Obstacle points, same frame.
    pub obstacles: Vec<[f64; 2]>,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MpcPlan {
    /// The velocity to command now (the plan's first step).
    pub cmd: VelocityCmd,
    /// First input [v̇, ω̇].
    pub input: [f64; 2],
    /// Predicted states 1..=N.
    pub states: Vec<UnicycleState>,
    /// Inputs 0..N−1.
    pub inputs: Vec<[f64; 2]>,
    /// Obstacle half-planes used: per step k (1-based), (n, b) with n·p ≥ b.
    pub half_planes: Vec<Vec<([f64; 2], f64)>>,
    /// The front disc's rows, those left out included: per step k
    /// (1-based), (n, g, b) with n·p + g θ ≥ b (its centre linearised in
    /// the heading); empty without the disc.
    pub front_rows: Vec<Vec<([f64; 2], f64, f64)>>,
    pub iterations: u32,
    /// Whether the front disc kept its clearance in this plan (false:
    /// none set, or no plan with it, [`solve`]).
    pub front_disc: bool,
}

#[derive(Debug, Error, PartialEq)]
pub enum MpcError {
    #[error("MPC QP not solved: {0}")]
    NotSolved(String),
    #[error("MPC setup: {0}")]
    Setup(String),
}

const NX: usize = 5;
const NU: usize = 2;

/// Appends `lo ≤ z[var] ≤ hi` as two rows of `A z ≤ b`.
#[allow(clippy::too_many_arguments)]
fn push_bound(
    var: usize,
    lo: f64,
    hi: f64,
    ai: &mut Vec<usize>,
    aj: &mut Vec<usize>,
    av: &mut Vec<f64>,
    b: &mut Vec<f64>,
    row: &mut usize,
) {
    ai.push(*row);
    aj.push(var);
    av.push(1.0);
    b.push(hi);
    ai.push(*row + 1);
    aj.push(var);
    av.push(-1.0);
    b.push(-lo);
    *row += 2;
}

/// Appends `lo ≤ z[var]` and `z[var] ≤ hi`, each only where given.
#[allow(clippy::too_many_arguments)]
fn push_bound_rows(
    var: usize,
    lo: Option<f64>,
    hi: Option<f64>,
    ai: &mut Vec<usize>,
    aj: &mut Vec<usize>,
    av: &mut Vec<f64>,
    b: &mut Vec<f64>,
    row: &mut usize,
) {
    if let Some(hi) = hi {
        ai.push(*row);
        aj.push(var);
        av.push(1.0);
        b.push(hi);
        *row += 1;
    }
    if let Some(lo) = lo {
        ai.push(*row);
        aj.push(var);
        av.push(-1.0);
        b.push(-lo);
        *row += 1;
    }
}

/// The `max` points of `points` nearest `c`, nearest first, ties in
/// their order in `points` (as a stable sort by distance, truncated,
/// without sorting the rest).
fn nearest_points(points: &[[f64; 2]], c: [f64; 2], max: usize) -> Vec<[f64; 2]> {
    if max == 0 {
        return Vec::new();
    }
    let mut keyed: Vec<(f64, usize)> = points
        .iter()
        .enumerate()
        .map(|(j, o)| (dist_sq(o, &c), j))
        .collect();
    let order = |a: &(f64, usize), b: &(f64, usize)| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1));
    if keyed.len() > max {
        keyed.select_nth_unstable_by(max - 1, order);
        keyed.truncate(max);
    }
    keyed.sort_unstable_by(order);
    keyed.into_iter().map(|(_, j)| points[j]).collect()
}

/// The squared distance between two points (for comparisons: no root).
fn dist_sq(a: &[f64; 2], b: &[f64]) -> f64 {
    let (dx, dy) = (a[0] - b[0], a[1] - b[1]);
    dx * dx + dy * dy
}

/// How far from the chair's position state k's position (k = 0..=n) can
/// be in the QP's linearised dynamics with its speed and rate bounds: each
/// step moves `dt·(|v_k| + |v̄|·|θ_k − θ̄_k|)` at most (v̄ = v0 along the
/// reference rollout), with `|v_k|` and `θ_k − θ̄_k = dt·Σ_{i=1}^{k−1}
/// (ω_i − ω0)` bounded by the bounds and by what the rate limits reach
/// from the current speeds.
pub fn position_reach_m(state: &UnicycleState, p: &MpcParams, n: usize) -> Vec<f64> {
    let dt = p.dt_s;
    let (v0, w0) = (state.v_mps, state.omega_radps);
    let mut reach = vec![0.0; n + 1];
    let (mut heading_off, mut travelled) = (0.0f64, 0.0f64);
    for (k, reach_k) in reach.iter_mut().enumerate().skip(1) {
        // speed k − 1: within its bounds and its reach from v0
        let v_prev = if k == 1 {
            v0.abs()
        } else {
            let r = p.accel_max_mps2 * dt * (k - 1) as f64;
            let lo = p.v_min_mps.min(v0 + r).max(v0 - r);
            let hi = p.v_max_mps.max(v0 - r).min(v0 + r);
            lo.abs().max(hi.abs())
        };
        travelled += dt * (v_prev + v0.abs() * heading_off);
        *reach_k = travelled;
        // turn rate k: within ±ω_max and its reach from ω0
        let turn = p.alpha_max_radps2 * dt * k as f64;
        let w_lo = (-p.omega_max_radps).max(w0 - turn);
        let w_hi = p.omega_max_radps.min(w0 + turn);
        heading_off += dt * (w_lo - w0).abs().max((w_hi - w0).abs());
    }
    reach
}

/// Solves one cycle. Where the front disc ([`MpcParams::front_disc_m`])
/// leaves no plan (a point it nears head-on that it cannot turn from
/// within the rate limits: the linearised problem is infeasible), the
/// plan is made with the disc about base_link alone, as without it.
pub fn solve(problem: &MpcProblem, p: &MpcParams) -> Result<MpcPlan, MpcError> {
    match solve_discs(problem, p) {
        Err(MpcError::NotSolved(_)) if p.front_disc_m > 0.0 => {
            let plan = solve_discs(
                problem,
                &MpcParams {
                    front_disc_m: 0.0,
                    ..*p
                },
            )?;
            Ok(MpcPlan {
                front_disc: false,
                ..plan
            })
        }
        r => r,
    }
}

/// One solve with the discs `p` sets.
fn solve_discs(problem: &MpcProblem, p: &MpcParams) -> Result<MpcPlan, MpcError> {
    let n = p.horizon.max(1);
    let dt = p.dt_s;
    let nz = n * (NX + NU);
    let sx = |k: usize, i: usize| (k - 1) * NX + i; // state k (1..=n)
    let ux = |k: usize, i: usize| n * NX + k * NU + i; // input k (0..n-1)

    // reference: constant-velocity rollout from the current state
    let s0 = problem.state.to_array();
    let mut sbar = vec![s0];
    for k in 0..n {
        let s = sbar[k];
        sbar.push([
            s[0] + dt * s[3] * s[2].cos(),
            s[1] + dt * s[3] * s[2].sin(),
            s[2] + dt * s[4],
            s[3],
            s[4],
        ]);
    }

    // cost
    let (mut pi, mut pj, mut pv) = (Vec::new(), Vec::new(), Vec::new());
    let mut q = vec![0.0; nz];
    let mut quad = |i: usize, w: f64, r: f64, q: &mut Vec<f64>| {
        if w > 0.0 {
            pi.push(i);
            pj.push(i);
            pv.push(2.0 * w);
            q[i] += -2.0 * w * r;
        }
    };
    let theta_ref = problem.heading_ref_rad.map(|h| {
        // the branch of the heading nearest the current one
        let d = (h - s0[2] + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        s0[2] + d
    });
    for k in 1..=n {
        let wp = if k == n { p.w_terminal } else { p.w_position };
        quad(sx(k, 0), wp, problem.goal[0], &mut q);
        quad(sx(k, 1), wp, problem.goal[1], &mut q);
        if let Some(h) = theta_ref {
            quad(sx(k, 2), p.w_heading, h, &mut q);
        }
        quad(sx(k, 3), p.w_speed, problem.v_ref_mps, &mut q);
        quad(sx(k, 4), p.w_omega, 0.0, &mut q);
    }
    for k in 0..n {
        quad(ux(k, 0), p.w_accel, 0.0, &mut q);
        quad(ux(k, 1), p.w_alpha, 0.0, &mut q);
    }
    let pmat = CscMatrix::new_from_triplets(nz, nz, pi, pj, pv);

    // constraints: rows of A z (+ s) = b
    let (mut ai, mut aj, mut av) = (Vec::new(), Vec::new(), Vec::new());
    let mut b = Vec::new();
    let mut row = 0usize;
    // dynamics: s_{k+1} − A_k s_k − B u_k = c_k (s_0 known, moved to b)
    for (k, s) in sbar.iter().take(n).enumerate() {
        let (st, ct) = (s[2].sin(), s[2].cos());
        // A_k = I + dt·J
        let mut a = [[0.0; NX]; NX];
        for (i, r) in a.iter_mut().enumerate() {
            r[i] = 1.0;
        }
        a[0][2] = -dt * s[3] * st;
        a[0][3] = dt * ct;
        a[1][2] = dt * s[3] * ct;
        a[1][3] = dt * st;
        a[2][4] = dt;
        let c = [dt * s[3] * st * s[2], -dt * s[3] * ct * s[2], 0.0, 0.0, 0.0];
        for i in 0..NX {
            ai.push(row + i);
            aj.push(sx(k + 1, i));
            av.push(1.0);
            let mut rhs = c[i];
            if k == 0 {
                rhs += (0..NX).map(|j| a[i][j] * s0[j]).sum::<f64>();
            } else {
                for (j, &aij) in a[i].iter().enumerate() {
                    if aij != 0.0 {
                        ai.push(row + i);
                        aj.push(sx(k, j));
                        av.push(-aij);
                    }
                }
            }
            b.push(rhs);
        }
        // B: v̇ → v, ω̇ → ω
        ai.push(row + 3);
        aj.push(ux(k, 0));
        av.push(-dt);
        ai.push(row + 4);
        aj.push(ux(k, 1));
        av.push(-dt);
        row += NX;
    }
    let n_eq = row;
    let (v0, w0) = (problem.state.v_mps, problem.state.omega_radps);
    // Speed bounds. State k's speed is v0 plus k steps of bounded
    // acceleration, so it lies in [v0 − ramp_k, v0 + ramp_k]: a bound
    // outside that interval cannot bind and its row is left out (the
    // feasible set, and so the solution, is the same; the KKT system is
    // smaller). Same for the turn rate.
    let reach = position_reach_m(&problem.state, p, n);
    for k in 1..=n {
        // a chair moving outside the speed bounds (backing off, which the
        // plan does not do) gets back inside them at the rate limit
        let ramp = p.accel_max_mps2 * dt * k as f64;
        let (v_lo, v_hi) = (p.v_min_mps.min(v0 + ramp), p.v_max_mps.max(v0 - ramp));
        let turn = p.alpha_max_radps2 * dt * k as f64;
        let w_max = p.omega_max_radps;
        push_bound_rows(
            sx(k, 3),
            (v_lo > v0 - ramp).then_some(v_lo),
            (v_hi < v0 + ramp).then_some(v_hi),
            &mut ai,
            &mut aj,
            &mut av,
            &mut b,
            &mut row,
        );
        push_bound_rows(
            sx(k, 4),
            (-w_max > w0 - turn).then_some(-w_max),
            (w_max < w0 + turn).then_some(w_max),
            &mut ai,
            &mut aj,
            &mut av,
            &mut b,
            &mut row,
        );
    }
    for k in 0..n {
        push_bound(
            ux(k, 0),
            -p.accel_max_mps2,
            p.accel_max_mps2,
            &mut ai,
            &mut aj,
            &mut av,
            &mut b,
            &mut row,
        );
        push_bound(
            ux(k, 1),
            -p.alpha_max_radps2,
            p.alpha_max_radps2,
            &mut ai,
            &mut aj,
            &mut av,
            &mut b,
            &mut row,
        );
    }
    // obstacles: the nearest points; per step a half-plane through the point
    // pushed out by the clearance, facing the reference position
    let obs: Vec<[f64; 2]> = problem
        .obstacles
        .iter()
        .copied()
        .filter(|o| o[0].is_finite() && o[1].is_finite())
        .filter(|o| dist_sq(o, &s0) <= p.obstacle_range_m.max(0.0).powi(2))
        .collect();
    // the discs: about base_link, and (where set) one ahead of it; each
    // keeps the clearance from its own nearest points
    let disc_at = |s: &[f64; 5], d: f64| [s[0] + d * s[2].cos(), s[1] + d * s[2].sin()];
    let mut discs = vec![0.0];
    if p.front_disc_m > 0.0 {
        discs.push(p.front_disc_m);
    }
    // how far a disc's centre, linearised in the heading, can swing by
    // step k beyond where base_link can go, per metre ahead of it: the
    // rollout's turn and the plan's, each at most the fastest turn
    let swing_per_m: Vec<f64> = (0..=n)
        .map(|k| (p.omega_max_radps + 2.0 * s0[4].abs()) * dt * k as f64)
        .collect();
    let mut half_planes = vec![Vec::new(); n];
    let mut front_rows = vec![Vec::new(); if discs.len() > 1 { n } else { 0 }];
    for &d_m in &discs {
        let c0 = disc_at(&s0, d_m);
        let near = nearest_points(&obs, c0, p.max_obstacles);
        for k in 1..=n {
            let th = sbar[k][2];
            let (px, py) = (sbar[k][0], sbar[k][1]);
            let c = disc_at(&sbar[k], d_m);
            for o in &near {
                let (dx, dy) = (c[0] - o[0], c[1] - o[1]);
                let d = dx.hypot(dy);
                let (nx, ny) = if d > 1e-6 {
                    (dx / d, dy / d)
                } else {
                    (1.0, 0.0)
                };
                // a point already closer than the clearance (a doorway's
                // jamb, a turn beside furniture): not closer than now, so
                // that the problem stays feasible and the plan moves away
                let now_m = (c0[0] - o[0]) * nx + (c0[1] - o[1]) * ny;
                let clearance = p.clearance_m.min((now_m - 0.05).max(0.0));
                // n·(p + d_m (cos θ, sin θ)) ≥ n·o + clearance, the disc's
                // centre linearised about the rollout's heading θ̄:
                // n·p + g θ ≥ bb with g = d_m n·(−sin θ̄, cos θ̄)
                let g = d_m * (-nx * th.sin() + ny * th.cos());
                let bb = nx * o[0] + ny * o[1] + clearance - (nx * (c[0] - px) + ny * (c[1] - py))
                    + g * th;
                if d_m == 0.0 {
                    half_planes[k - 1].push(([nx, ny], bb));
                } else {
                    front_rows[k - 1].push(([nx, ny], g, bb));
                }
                // every position state k can reach keeps the clearance:
                // the row cannot bind and is left out
                if now_m - reach[k] - d_m * swing_per_m[k] > clearance + 1e-9 {
                    continue;
                }
                // −n·p − g θ ≤ −b
                ai.push(row);
                aj.push(sx(k, 0));
                av.push(-nx);
                ai.push(row);
                aj.push(sx(k, 1));
                av.push(-ny);
                if g != 0.0 {
                    ai.push(row);
                    aj.push(sx(k, 2));
                    av.push(-g);
                }
                b.push(-bb);
                row += 1;
            }
        }
    }
    let n_ineq = row - n_eq;
    let amat = CscMatrix::new_from_triplets(row, nz, ai, aj, av);
    let cones = [
        SupportedConeT::ZeroConeT(n_eq),
        SupportedConeT::NonnegativeConeT(n_ineq),
    ];
    let settings = DefaultSettingsBuilder::default()
        .verbose(false)
        .max_iter(100)
        // one solve a cycle at 20 Hz: direct solves are accurate enough here
        // and iterative refinement costs about a third of the time
        .iterative_refinement_enable(false)
        // the problem is scaled by construction (metres, seconds, radians,
        // weights of one order): equilibration changed no command by more
        // than 3e-5 and cost a tenth of the time. Gaps and residuals of
        // 1e-6 (not 1e-8) move the first command by at most 3e-4 m/s and
        // rad/s over `cargo bench --bench mpc_solve_times`'s 2 000
        // problems, far below what the R-Net joystick resolves, in 1–2
        // fewer iterations
        .equilibrate_enable(false)
        .tol_gap_abs(1e-6)
        .tol_gap_rel(1e-6)
        .tol_feas(1e-6)
        .build()
        .map_err(|e| MpcError::Setup(format!("{e:?}")))?;
    let mut solver = DefaultSolver::new(&pmat, &q, &amat, &b, &cones, settings)
        .map_err(|e| MpcError::Setup(e.to_string()))?;
    solver.solve();
    let sol = &solver.solution;
    match sol.status {
        SolverStatus::Solved | SolverStatus::AlmostSolved => {}
        other => return Err(MpcError::NotSolved(format!("{other:?}"))),
    }
    let z = &sol.x;
    let states: Vec<UnicycleState> = (1..=n)
        .map(|k| UnicycleState::from_array(&z[sx(k, 0)..sx(k, 0) + NX]))
        .collect();
    let inputs: Vec<[f64; 2]> = (0..n).map(|k| [z[ux(k, 0)], z[ux(k, 1)]]).collect();
    let first = states[0];
    Ok(MpcPlan {
        cmd: VelocityCmd {
            v_mps: first.v_mps,
            omega_radps: first.omega_radps,
        },
        input: inputs[0],
        states,
        inputs,
        half_planes,
        front_rows,
        iterations: sol.iterations,
        front_disc: p.front_disc_m > 0.0,
    })
}

#[cfg(test)]
#[path = "mpc_tests.rs"]
mod tests;
