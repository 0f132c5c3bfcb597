//! Per-solve MPC times (clarabel), N = 20 and N = 30: 2 000 solves each
//! over varied states, goals and obstacle sets (seeded), every solve timed
//! on its own, so the p99 is a per-solve p99 (criterion's is of means).
//! Run: `cargo bench --bench mpc_solve_times` (target at N = 30: median
//! ≤ 0.5 ms, p99 ≤ 1 ms on one core).

use std::time::Instant;

use opennav::navigation::mpc::{solve, MpcParams, MpcProblem, UnicycleState};

/// xorshift64*: a fixed sequence, no dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

fn problem(r: &mut Rng) -> MpcProblem {
    let theta = r.range(-3.1, 3.1);
    let n_obs = (r.next() * 12.0) as usize;
    MpcProblem {
        state: UnicycleState {
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: theta,
            v_mps: r.range(0.0, 0.3),
            omega_radps: r.range(-0.5, 0.5),
        },
        goal: [r.range(-4.0, 4.0), r.range(-4.0, 4.0)],
        heading_ref_rad: Some(theta + r.range(-0.8, 0.8)),
        v_ref_mps: r.range(0.05, 0.3),
        obstacles: (0..n_obs)
            .map(|_| {
                let a = theta + r.range(-1.5, 1.5);
                let d = r.range(0.8, 3.0);
                [d * a.cos(), d * a.sin()]
            })
            .collect(),
    }
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((p * (sorted.len() - 1) as f64).round() as usize).min(sorted.len() - 1)]
}

fn main() {
    // `cargo test --benches` runs this with --bench absent: keep it short
    let solves = if std::env::args().any(|a| a == "--bench") {
        2000
    } else {
        20
    };
    for n in [20usize, 30] {
        let params = MpcParams {
            horizon: n,
            ..opennav::config::Settings::defaults().mpc
        };
        let mut rng = Rng(0x5EED_0000 + n as u64);
        let problems: Vec<MpcProblem> = (0..solves).map(|_| problem(&mut rng)).collect();
        // warm-up
        for p in problems.iter().take(50) {
            let _ = solve(p, &params);
        }
        let mut times_ms = Vec::with_capacity(solves);
        let mut failed = 0;
        let mut iterations = 0u64;
        let mut cmds = Vec::new();
        for p in &problems {
            let t = Instant::now();
            let r = solve(p, &params);
            times_ms.push(t.elapsed().as_secs_f64() * 1e3);
            match r {
                Ok(plan) => {
                    iterations += u64::from(plan.iterations);
                    cmds.push(format!("{:.6} {:.6}", plan.cmd.v_mps, plan.cmd.omega_radps));
                }
                Err(_) => {
                    failed += 1;
                    cmds.push("failed".into());
                }
            }
        }
        // OPENNAV_MPC_DUMP=PREFIX: each solve's first command, one per
        // line, in PREFIX{N} (to compare solver settings command by command)
        if let Some(prefix) = std::env::var_os("OPENNAV_MPC_DUMP") {
            let path = format!("{}{n}", prefix.to_string_lossy());
            if let Err(e) = std::fs::write(&path, cmds.join("\n")) {
                eprintln!("{path}: {e}");
            }
        }
        let solved = (solves - failed).max(1) as f64;
        times_ms.sort_by(f64::total_cmp);
        println!(
            "mpc N={n}: {} solves ({failed} infeasible/failed, {:.1} iterations on average): median {:.3} ms, p90 {:.3} ms, p99 {:.3} ms, max {:.3} ms",
            times_ms.len(),
            iterations as f64 / solved,
            percentile(&times_ms, 0.5),
            percentile(&times_ms, 0.9),
            percentile(&times_ms, 0.99),
            times_ms[times_ms.len() - 1]
        );
    }
}
