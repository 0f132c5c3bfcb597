//! The instance evaluation's tests.

use super::*;

#[test]
fn labels_too_large_for_the_id_encoding_are_errors_naming_the_point() {
    assert_eq!(
        gt_ids(&[i64::MAX], &[0]),
        Err((0, "semantic id 9223372036854775807 is out of range".into()))
    );
    assert!(gt_ids(&[3, 3], &[0, i64::MAX]).is_err_and(|(k, _)| k == 1));
    assert!(gt_ids(&[3], &[999]).is_err());
    assert_eq!(gt_ids(&[3], &[998]), Ok(vec![3999]));
}

fn rle(ranges: &[(usize, usize)], n: usize) -> Rle {
    Rle {
        length: n,
        counts: ranges
            .iter()
            .flat_map(|&(lo, hi)| [lo as i64 + 1, (hi - lo) as i64])
            .collect(),
    }
}

/// The reference scene: 1000 points; chair (14) instance 0 on 0..200,
/// instance 1 on 200..400, table (39) instance 2 on 400..700, the rest
/// sem 0, inst −100.
fn scene() -> Scene {
    let mut sem = vec![0i64; 1000];
    let mut inst = vec![-100i64; 1000];
    for i in 0..200 {
        sem[i] = 14;
        inst[i] = 0;
    }
    for i in 200..400 {
        sem[i] = 14;
        inst[i] = 1;
    }
    for i in 400..700 {
        sem[i] = 39;
        inst[i] = 2;
    }
    Scene {
        id: "s0".into(),
        sem,
        inst,
    }
}

fn pred(label_id: i64, score: f64, lo: usize, hi: usize) -> Prediction {
    Prediction {
        scene: "s0".into(),
        label_id,
        score,
        mask_rle: rle(&[(lo, hi)], 1000),
    }
}

fn class<'a>(r: &'a EvalResult, name: &str) -> &'a ClassResult {
    &r.classes
        .iter()
        .find(|(n, _)| n == name)
        .expect("class present")
        .1
}

fn close(a: f64, b: f64) {
    assert!((a - b).abs() < 1e-6, "{a} vs {b}");
}

#[test]
fn reference_case_a() {
    let case = EvalCase {
        scenes: vec![scene()],
        predictions: vec![
            pred(14, 1.0, 0, 200),
            pred(14, 1.0, 200, 300),
            pred(39, 1.0, 400, 640),
        ],
    };
    let r = evaluate(&case, ScoreMode::One).unwrap();
    close(r.map, 0.520833);
    close(r.map50, 0.6875);
    close(r.map25, 1.0);
    let c = class(&r, "chair");
    close(c.ap, 0.375);
    close(c.ap50, 0.375);
    close(c.ap25, 1.0);
    let t = class(&r, "table");
    close(t.ap, 0.666667);
    close(t.ap50, 1.0);
    close(t.ap25, 1.0);
    assert_eq!(r.classes.len(), 2);
}

#[test]
fn reference_case_b() {
    let case = EvalCase {
        scenes: vec![scene()],
        predictions: vec![
            pred(14, 0.9, 0, 200),
            pred(14, 0.3, 200, 300),
            pred(14, 0.6, 0, 180),
            pred(14, 0.8, 800, 950),
            pred(39, 0.7, 400, 640),
            pred(5, 0.5, 700, 900),
        ],
    };
    let r = evaluate(&case, ScoreMode::Detector).unwrap();
    close(r.map, 0.583333);
    close(r.map50, 0.75);
    close(r.map25, 0.895833);
    let c = class(&r, "chair");
    close(c.ap, 0.5);
    close(c.ap50, 0.5);
    close(c.ap25, 0.791667);
    let t = class(&r, "table");
    close(t.ap, 0.666667);
    close(t.ap50, 1.0);
    close(t.ap25, 1.0);
    // blanket has no ground truth: omitted
    assert!(r.classes.iter().all(|(n, _)| n != "blanket"));
}

#[test]
fn constant_scores_give_r_one_plus_p_over_two() {
    // 3 gt matched out of 4, 2 false positives: p = 3/5, r = 3/4
    let (ap, rc) = average_precision(&[true, true, true, false, false], &[1.0; 5], 1);
    close(ap, 0.75 * (1.0 + 0.6) / 2.0);
    close(rc, 0.75);
}

#[test]
fn thresholds_are_numpys() {
    // numpy's float arange: delta = (start + step) − start, then start + i·delta
    let delta = (0.5f64 + 0.05) - 0.5;
    let v: Vec<f64> = (0..9).map(|i| 0.5 + i as f64 * delta).collect();
    assert!(0.5 + 9.0 * delta >= 0.95);
    assert_eq!(&IOU_THRESHOLDS[..9], &v[..]);
    assert_eq!(IOU_THRESHOLDS[9], 0.25);
}

#[test]
fn gt_encoding_quirks() {
    assert_eq!(
        gt_ids(&[14, 14, -3, 14], &[0, -1, 5, -100]).expect("in range"),
        vec![14001, 14000, 6, 0]
    );
}

#[test]
fn rle_errors_are_named() {
    assert!(decode_rle(&rle(&[(0, 10)], 10), 20)
        .unwrap_err()
        .contains("length"));
    let past = Rle {
        length: 10,
        counts: vec![5, 10],
    };
    assert!(decode_rle(&past, 10).unwrap_err().contains("past the end"));
    let zero = Rle {
        length: 10,
        counts: vec![0, 1],
    };
    assert!(decode_rle(&zero, 10).unwrap_err().contains("1-based"));
    let odd = Rle {
        length: 10,
        counts: vec![1],
    };
    assert!(decode_rle(&odd, 10).is_err());
    let over = Rle {
        length: 10,
        counts: vec![1, 5, 3, 5],
    };
    assert_eq!(decode_rle(&over, 10).unwrap(), vec![(0, 7)]);
}

#[test]
fn bad_predictions_are_named() {
    let mut case = EvalCase {
        scenes: vec![scene()],
        predictions: vec![pred(49, 1.0, 0, 200)],
    };
    let e = evaluate(&case, ScoreMode::One).unwrap_err().to_string();
    assert!(
        e.contains("prediction 0") && e.contains("label_id 49"),
        "{e}"
    );
    case.predictions = vec![
        pred(14, 1.0, 0, 200),
        Prediction {
            scene: "nope".into(),
            ..pred(14, 1.0, 0, 200)
        },
    ];
    let e = evaluate(&case, ScoreMode::One).unwrap_err().to_string();
    assert!(e.contains("prediction 1") && e.contains("nope"), "{e}");
    case.scenes[0].inst.pop();
    assert!(matches!(
        evaluate(&case, ScoreMode::One),
        Err(EvalError::Lengths { .. })
    ));
}
