//! One MPC solve (clarabel) at N = 20 and N = 30, with 8 obstacle points.
//! Run: `cargo bench --bench mpc` (target: median ≤ 1 ms, p99 ≤ 3 ms).

use criterion::{criterion_group, criterion_main, Criterion};
use opennav::navigation::mpc::{solve, MpcParams, MpcProblem, UnicycleState};

fn problem() -> MpcProblem {
    MpcProblem {
        state: UnicycleState {
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.2,
            v_mps: 0.2,
            omega_radps: 0.1,
        },
        goal: [4.0, 1.0],
        heading_ref_rad: Some(0.25),
        v_ref_mps: 0.3,
        obstacles: (0..8)
            .map(|i| [1.5 + 0.1 * i as f64, -0.9 + 0.05 * i as f64])
            .collect(),
    }
}

fn bench(c: &mut Criterion) {
    let pr = problem();
    for n in [20usize, 30] {
        let p = MpcParams {
            horizon: n,
            ..opennav::config::Settings::defaults().mpc
        };
        assert!(solve(&pr, &p).is_ok());
        c.bench_function(&format!("mpc_solve_n{n}"), |b| {
            b.iter(|| solve(&pr, &p).expect("solves"))
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
