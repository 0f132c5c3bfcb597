//! Properties of the Replica instance metric, and `opennav eval instances`.

mod common;

use std::process::Command;

use opennav::eval::instances::{evaluate, EvalCase, Prediction, Rle, Scene, ScoreMode};
use proptest::prelude::*;

/// A scene of consecutive instances: (class id 1..48, point count), then
/// `void` points of sem 0.
fn build(instances: &[(i64, usize)], void: usize) -> (Scene, Vec<(i64, usize, usize)>) {
    let mut sem = Vec::new();
    let mut inst = Vec::new();
    let mut ranges = Vec::new();
    for (k, &(c, n)) in instances.iter().enumerate() {
        ranges.push((c, sem.len(), sem.len() + n));
        sem.extend(std::iter::repeat_n(c, n));
        inst.extend(std::iter::repeat_n(k as i64, n));
    }
    sem.extend(std::iter::repeat_n(0, void));
    inst.extend(std::iter::repeat_n(-100, void));
    (
        Scene {
            id: "s".into(),
            sem,
            inst,
        },
        ranges,
    )
}

fn pred(n: usize, label: i64, score: f64, lo: usize, hi: usize) -> Prediction {
    Prediction {
        scene: "s".into(),
        label_id: label,
        score,
        mask_rle: Rle {
            length: n,
            counts: vec![lo as i64 + 1, (hi - lo) as i64],
        },
    }
}

fn instances() -> impl Strategy<Value = Vec<(i64, usize)>> {
    proptest::collection::vec((1i64..=48, 100usize..400), 1..8)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    #[test]
    fn perfect_predictions_score_one(inst in instances(), void in 0usize..300, score in 0.1f64..1.0) {
        let (scene, ranges) = build(&inst, void);
        let n = scene.sem.len();
        let predictions = ranges.iter().map(|&(c, lo, hi)| pred(n, c, score, lo, hi)).collect();
        let r = evaluate(&EvalCase { scenes: vec![scene], predictions }, ScoreMode::Detector).unwrap();
        prop_assert_eq!(r.map, 1.0);
        prop_assert_eq!(r.map50, 1.0);
        prop_assert_eq!(r.map25, 1.0);
    }

    #[test]
    fn no_predictions_score_zero(inst in instances()) {
        let (scene, _) = build(&inst, 50);
        let r = evaluate(&EvalCase { scenes: vec![scene], predictions: vec![] }, ScoreMode::One).unwrap();
        prop_assert_eq!(r.map, 0.0);
        prop_assert!(r.classes.iter().all(|(_, c)| c.ap == 0.0 && c.rc == 0.0));
    }

    #[test]
    fn predictions_on_void_points_are_ignored(inst in instances(), void in 100usize..300, label in 1i64..=48) {
        let (scene, ranges) = build(&inst, void);
        let n = scene.sem.len();
        let mut predictions: Vec<Prediction> = ranges.iter().map(|&(c, lo, hi)| pred(n, c, 0.9, lo, hi)).collect();
        predictions.push(pred(n, label, 0.95, n - void, n));
        let r = evaluate(&EvalCase { scenes: vec![scene], predictions }, ScoreMode::Detector).unwrap();
        prop_assert_eq!(r.map, 1.0);
    }

    #[test]
    fn a_duplicate_is_a_false_positive(inst in instances()) {
        let (scene, ranges) = build(&inst, 0);
        let n = scene.sem.len();
        let mut predictions: Vec<Prediction> = ranges.iter().map(|&(c, lo, hi)| pred(n, c, 1.0, lo, hi)).collect();
        let (c, lo, hi) = ranges[0];
        predictions.push(pred(n, c, 1.0, lo, hi));
        let r = evaluate(&EvalCase { scenes: vec![scene], predictions }, ScoreMode::One).unwrap();
        let name = opennav::eval::instances::REPLICA_CLASSES[(c - 1) as usize];
        let cls = &r.classes.iter().find(|(k, _)| k == name).unwrap().1;
        // that class: every gt found (r = 1), one extra false positive
        let n_gt = ranges.iter().filter(|x| x.0 == c).count() as f64;
        let p = n_gt / (n_gt + 1.0);
        prop_assert!((cls.ap50 - (1.0 + p) / 2.0).abs() < 1e-12, "{} vs {}", cls.ap50, (1.0 + p) / 2.0);
        prop_assert!(r.map < 1.0);
    }
}

fn opennav(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_opennav"))
        .args(args)
        .output()
        .expect("runs")
}

#[test]
fn cli_reproduces_case_a_and_rejects_bad_input() {
    let dir = tempfile::tempdir().unwrap();
    let mut sem = vec![0i64; 1000];
    let mut inst = vec![-100i64; 1000];
    for i in 0..700 {
        sem[i] = if i < 400 { 14 } else { 39 };
        inst[i] = if i < 200 {
            0
        } else if i < 400 {
            1
        } else {
            2
        };
    }
    let case = serde_json::json!({
        "scenes": [{"id": "s0", "sem": sem, "inst": inst}],
        "predictions": [
            {"scene": "s0", "label_id": 14, "score": 0.2, "mask_rle": {"length": 1000, "counts": [1, 200]}},
            {"scene": "s0", "label_id": 14, "score": 0.9, "mask_rle": {"length": 1000, "counts": [201, 100]}},
            {"scene": "s0", "label_id": 39, "score": 0.5, "mask_rle": {"length": 1000, "counts": [401, 240]}}
        ]
    });
    let f = dir.path().join("case.json");
    std::fs::write(&f, case.to_string()).unwrap();
    let o = opennav(&[
        "eval",
        "instances",
        f.to_str().unwrap(),
        "--score-mode",
        "one",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!((v["mAP"].as_f64().unwrap() - 0.520833).abs() < 1e-6, "{v}");
    assert!((v["mAP50"].as_f64().unwrap() - 0.6875).abs() < 1e-6);
    assert!((v["mAP25"].as_f64().unwrap() - 1.0).abs() < 1e-6);
    assert!((v["classes"]["chair"]["ap"].as_f64().unwrap() - 0.375).abs() < 1e-6);
    assert_eq!(v["score_mode"], "one");
    assert!(v["classes"].get("blanket").is_none());

    // bad inputs: exit 2, the prediction named
    let mut bad = case.clone();
    bad["predictions"][1]["mask_rle"]["counts"] = serde_json::json!([990, 20]);
    std::fs::write(&f, bad.to_string()).unwrap();
    let o = opennav(&["eval", "instances", f.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        e.contains("prediction 1") && e.contains("past the end"),
        "{e}"
    );

    std::fs::write(&f, "{\"scenes\": [").unwrap();
    let o = opennav(&["eval", "instances", f.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("case.json"));
}
