//! The instance metric at scale: one scene of 1 M points with 400 ground
//! truth instances and 500 predictions (the "well under a second").
//! Run: `cargo bench --bench eval`

use criterion::{criterion_group, criterion_main, Criterion};
use opennav::eval::instances::{evaluate, EvalCase, Prediction, Rle, Scene, ScoreMode};

fn case() -> EvalCase {
    let n = 1_000_000usize;
    let mut sem = vec![0i64; n];
    let mut inst = vec![-100i64; n];
    // 400 instances of 2000 points, classes cycling 1..48; the rest void
    for k in 0..400usize {
        for i in k * 2000..(k + 1) * 2000 {
            sem[i] = (k % 48) as i64 + 1;
            inst[i] = k as i64;
        }
    }
    let mut predictions = Vec::new();
    for j in 0..500usize {
        let k = (j * 7) % 400;
        // shifted masks: IoUs spread over the thresholds
        let shift = (j * 37) % 1500;
        let lo = k * 2000 + shift;
        predictions.push(Prediction {
            scene: "big".into(),
            label_id: (k % 48) as i64 + 1,
            score: (j % 97) as f64 / 97.0,
            mask_rle: Rle {
                length: n,
                counts: vec![lo as i64 + 1, 2000],
            },
        });
    }
    EvalCase {
        scenes: vec![Scene {
            id: "big".into(),
            sem,
            inst,
        }],
        predictions,
    }
}

fn bench(c: &mut Criterion) {
    let case = case();
    let r = evaluate(&case, ScoreMode::Detector).expect("valid case");
    assert!(r.map > 0.0 && r.map < 1.0);
    let mut g = c.benchmark_group("eval");
    g.sample_size(10);
    g.bench_function("instances_1m_points_500_predictions", |b| {
        b.iter(|| evaluate(&case, ScoreMode::Detector).expect("valid"))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
