//! 3D instance-segmentation AP exactly as Open3DIS scores Replica (its
//! ScanNet-style `scannetv2_inst_eval.py`): ground-truth encoding and its
//! quirks, the 100-point minimum, ten IoU thresholds with numpy's floats and
//! a strict `>`, greedy matching, void/ignored predictions, AP as the sum
//! without interpolation, nanmean. The recipe is in the shared reference
//! `evaluation.md`; the code is our own. Pure: no I/O.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Replica's 48 evaluated classes, label id = index + 1.
pub const REPLICA_CLASSES: [&str; 48] = [
    "basket",
    "bed",
    "bench",
    "bin",
    "blanket",
    "blinds",
    "book",
    "bottle",
    "box",
    "bowl",
    "camera",
    "cabinet",
    "candle",
    "chair",
    "clock",
    "cloth",
    "comforter",
    "cushion",
    "desk",
    "desk-organizer",
    "door",
    "indoor-plant",
    "lamp",
    "monitor",
    "nightstand",
    "panel",
    "picture",
    "pillar",
    "pillow",
    "pipe",
    "plant-stand",
    "plate",
    "pot",
    "sculpture",
    "shelf",
    "sofa",
    "stool",
    "switch",
    "table",
    "tablet",
    "tissue-paper",
    "tv-screen",
    "tv-stand",
    "vase",
    "vent",
    "wall-plug",
    "window",
    "rug",
];

/// `np.append(np.arange(0.5, 0.95, 0.05), 0.25)` bit for bit.
pub const IOU_THRESHOLDS: [f64; 10] = [
    0.5,
    0.55,
    0.6000000000000001,
    0.6500000000000001,
    0.7000000000000002,
    0.7500000000000002,
    0.8000000000000003,
    0.8500000000000003,
    0.9000000000000004,
    0.25,
];
const T50: usize = 0;
const T25: usize = 9;
/// Instances (ground truth and predictions) below this many points do not count.
pub const MIN_REGION_POINTS: usize = 100;

#[derive(Debug, Error, PartialEq)]
pub enum EvalError {
    #[error("scene `{scene}`: `sem` has {sem} points, `inst` has {inst}")]
    Lengths {
        scene: String,
        sem: usize,
        inst: usize,
    },
    #[error("scene `{0}` appears twice")]
    DuplicateScene(String),
    #[error("scene `{scene}`: point {point}: {reason}")]
    Label {
        scene: String,
        point: usize,
        reason: String,
    },
    #[error("prediction {index}: {reason}")]
    Prediction { index: usize, reason: String },
}

/// One scene's ground truth: per point, semantic id and instance id.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    pub id: String,
    pub sem: Vec<i64>,
    pub inst: Vec<i64>,
}

/// Run-length mask: `counts = [start (1-based), length, start, length, …]`.
#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Rle {
    pub length: usize,
    pub counts: Vec<i64>,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct Prediction {
    pub scene: String,
    pub label_id: i64,
    pub score: f64,
    pub mask_rle: Rle,
}

#[derive(Debug, Clone, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct EvalCase {
    pub scenes: Vec<Scene>,
    pub predictions: Vec<Prediction>,
}

/// Which score a prediction carries into AP.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ScoreMode {
    /// The detector's score.
    Detector,
    /// 1.0 for every prediction, as Open3DIS's Replica runs do.
    One,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ClassResult {
    pub ap: f64,
    #[serde(rename = "ap50%")]
    pub ap50: f64,
    #[serde(rename = "ap25%")]
    pub ap25: f64,
    pub rc: f64,
    #[serde(rename = "rc50%")]
    pub rc50: f64,
    #[serde(rename = "rc25%")]
    pub rc25: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvalResult {
    #[serde(rename = "mAP")]
    pub map: f64,
    #[serde(rename = "mAP50")]
    pub map50: f64,
    #[serde(rename = "mAP25")]
    pub map25: f64,
    pub score_mode: ScoreMode,
    /// Classes with ground truth, by name, in class-id order.
    pub classes: Vec<(String, ClassResult)>,
}

/// Ground-truth id per point: `sem*1000 + inst + 1`, 0 where `inst + 1 < 0`;
/// negative `sem` counts as 0. (A point with `inst = -1` and a valid `sem`
/// gets `sem*1000`, and counts: Open3DIS's quirk, kept.)
/// A label too large for the encoding is an error naming the point.
pub fn gt_ids(sem: &[i64], inst: &[i64]) -> Result<Vec<i64>, (usize, String)> {
    sem.iter()
        .zip(inst)
        .enumerate()
        .map(|(k, (&s, &i))| {
            let s = s.max(0);
            let Some(ins) = i.checked_add(1) else {
                return Err((k, format!("instance id {i} is out of range")));
            };
            if ins < 0 {
                return Ok(0);
            }
            if ins >= 1000 {
                return Err((
                    k,
                    format!("instance id {i}: at most 998 per class (ids are sem*1000 + inst + 1)"),
                ));
            }
            s.checked_mul(1000)
                .and_then(|v| v.checked_add(ins))
                .ok_or_else(|| (k, format!("semantic id {s} is out of range")))
        })
        .collect()
}

fn valid_class(id: i64) -> bool {
    let c = id.div_euclid(1000);
    (1..=48).contains(&c)
}

/// Decodes an RLE into sorted, disjoint half-open ranges of point indices
/// (runs are OR-ed as Open3DIS's decoder does). Errors name what is wrong.
pub fn decode_rle(rle: &Rle, n_points: usize) -> Result<Vec<(usize, usize)>, String> {
    if rle.length != n_points {
        return Err(format!(
            "mask length {} but the scene has {n_points} points",
            rle.length
        ));
    }
    if !rle.counts.len().is_multiple_of(2) {
        return Err(format!(
            "RLE has an odd number of counts ({})",
            rle.counts.len()
        ));
    }
    let mut runs = Vec::with_capacity(rle.counts.len() / 2);
    for (k, pair) in rle.counts.chunks_exact(2).enumerate() {
        let (start, len) = (pair[0], pair[1]);
        if start < 1 {
            return Err(format!("RLE run {k}: start {start} (starts are 1-based)"));
        }
        if len < 0 {
            return Err(format!("RLE run {k}: negative length {len}"));
        }
        let lo = (start - 1) as usize;
        let hi = lo + len as usize;
        if hi > n_points {
            return Err(format!(
                "RLE run {k}: points {}..{} run past the end ({n_points})",
                lo + 1,
                hi
            ));
        }
        if hi > lo {
            runs.push((lo, hi));
        }
    }
    runs.sort_unstable();
    let mut merged: Vec<(usize, usize)> = Vec::with_capacity(runs.len());
    for (lo, hi) in runs {
        match merged.last_mut() {
            Some(last) if lo <= last.1 => last.1 = last.1.max(hi),
            _ => merged.push((lo, hi)),
        }
    }
    Ok(merged)
}

struct GtInstance {
    id: i64,
    count: usize,
    /// (prediction uid, intersection, prediction point count, score), in prediction order
    matched: Vec<(usize, usize, usize, f64)>,
}

struct PredInstance {
    count: usize,
    score: f64,
    void_intersection: usize,
    /// (gt id, gt count, intersection)
    matched_gt: Vec<(i64, usize, usize)>,
}

/// Per scene, per class (0..48): ground truths (sorted by id) and predictions.
struct SceneMatches {
    gt: Vec<Vec<GtInstance>>,
    pred: Vec<Vec<PredInstance>>,
}

/// Scores a case. Label ids must be 1..48; scenes must be consistent.
pub fn evaluate(case: &EvalCase, mode: ScoreMode) -> Result<EvalResult, EvalError> {
    let mut index: HashMap<&str, usize> = HashMap::new();
    for (i, s) in case.scenes.iter().enumerate() {
        if s.sem.len() != s.inst.len() {
            return Err(EvalError::Lengths {
                scene: s.id.clone(),
                sem: s.sem.len(),
                inst: s.inst.len(),
            });
        }
        if index.insert(s.id.as_str(), i).is_some() {
            return Err(EvalError::DuplicateScene(s.id.clone()));
        }
    }
    let ids: Vec<Vec<i64>> = case
        .scenes
        .iter()
        .map(|s| {
            gt_ids(&s.sem, &s.inst).map_err(|(point, reason)| EvalError::Label {
                scene: s.id.clone(),
                point,
                reason,
            })
        })
        .collect::<Result<_, _>>()?;
    let mut matches: Vec<SceneMatches> = ids
        .iter()
        .map(|gt| {
            let mut counts: HashMap<i64, usize> = HashMap::new();
            for &id in gt {
                if id != 0 {
                    *counts.entry(id).or_default() += 1;
                }
            }
            let mut sorted: Vec<(i64, usize)> = counts
                .into_iter()
                .filter(|(id, _)| valid_class(*id))
                .collect();
            sorted.sort_unstable();
            let mut per_class: Vec<Vec<GtInstance>> = (0..48).map(|_| Vec::new()).collect();
            for (id, count) in sorted {
                per_class[(id / 1000 - 1) as usize].push(GtInstance {
                    id,
                    count,
                    matched: Vec::new(),
                });
            }
            SceneMatches {
                gt: per_class,
                pred: (0..48).map(|_| Vec::new()).collect(),
            }
        })
        .collect();

    for (pi, p) in case.predictions.iter().enumerate() {
        let perr = |reason: String| EvalError::Prediction { index: pi, reason };
        let &si = index
            .get(p.scene.as_str())
            .ok_or_else(|| perr(format!("scene `{}` is not in `scenes`", p.scene)))?;
        if !(1..=48).contains(&p.label_id) {
            return Err(perr(format!("label_id {} out of range 1..48", p.label_id)));
        }
        if !p.score.is_finite() {
            return Err(perr(format!("score {} is not finite", p.score)));
        }
        let gt = &ids[si];
        let runs = decode_rle(&p.mask_rle, gt.len())
            .map_err(|e| perr(format!("scene `{}`: {e}", p.scene)))?;
        let count: usize = runs.iter().map(|(lo, hi)| hi - lo).sum();
        if count < MIN_REGION_POINTS {
            continue;
        }
        let class = (p.label_id - 1) as usize;
        let mut void_intersection = 0usize;
        let mut inter: HashMap<i64, usize> = HashMap::new();
        for &(lo, hi) in &runs {
            for &id in &gt[lo..hi] {
                if !valid_class(id) {
                    void_intersection += 1;
                } else if id / 1000 - 1 == class as i64 {
                    *inter.entry(id).or_default() += 1;
                }
            }
        }
        let score = match mode {
            ScoreMode::Detector => p.score,
            ScoreMode::One => 1.0,
        };
        let scene = &mut matches[si];
        let mut matched_gt = Vec::new();
        for g in scene.gt[class].iter_mut() {
            if let Some(&n) = inter.get(&g.id) {
                g.matched.push((pi, n, count, score));
                matched_gt.push((g.id, g.count, n));
            }
        }
        scene.pred[class].push(PredInstance {
            count,
            score,
            void_intersection,
            matched_gt,
        });
    }

    // ap[class][threshold], rc[class][threshold]
    let mut ap = vec![[f64::NAN; 10]; 48];
    let mut rc = vec![[f64::NAN; 10]; 48];
    for (ti, &th) in IOU_THRESHOLDS.iter().enumerate() {
        let mut visited = vec![false; case.predictions.len()];
        for class in 0..48 {
            let mut y_true: Vec<bool> = Vec::new();
            let mut y_score: Vec<f64> = Vec::new();
            let mut hard_fn = 0usize;
            let (mut has_gt, mut has_pred) = (false, false);
            for scene in &matches {
                let gts: Vec<&GtInstance> = scene.gt[class]
                    .iter()
                    .filter(|g| g.id >= 1000 && g.count >= MIN_REGION_POINTS)
                    .collect();
                has_gt |= !gts.is_empty();
                has_pred |= !scene.pred[class].is_empty();
                // per gt: (true?, score, matched?) and appended false positives
                let mut cur: Vec<(bool, f64, bool)> =
                    vec![(true, f64::NEG_INFINITY, false); gts.len()];
                for (gi, g) in gts.iter().enumerate() {
                    let mut found = false;
                    for &(uid, n, pcount, score) in &g.matched {
                        if visited[uid] {
                            continue;
                        }
                        let iou = n as f64 / (g.count + pcount - n) as f64;
                        if iou > th {
                            if cur[gi].2 {
                                let hi = cur[gi].1.max(score);
                                let lo = cur[gi].1.min(score);
                                cur[gi].1 = hi;
                                cur.push((false, lo, true));
                            } else {
                                found = true;
                                cur[gi].2 = true;
                                cur[gi].1 = score;
                                visited[uid] = true;
                            }
                        }
                    }
                    if !found {
                        hard_fn += 1;
                    }
                }
                for (t, s, m) in cur {
                    if m {
                        y_true.push(t);
                        y_score.push(s);
                    }
                }
                for p in &scene.pred[class] {
                    let found_gt = p
                        .matched_gt
                        .iter()
                        .any(|&(_, gcount, n)| n as f64 / (gcount + p.count - n) as f64 > th);
                    if found_gt {
                        continue;
                    }
                    let mut ignore = p.void_intersection;
                    for &(gid, gcount, n) in &p.matched_gt {
                        if gid < 1000 {
                            ignore += n;
                        }
                        if gcount < MIN_REGION_POINTS {
                            ignore += n;
                        }
                    }
                    if ignore as f64 / p.count as f64 <= th {
                        y_true.push(false);
                        y_score.push(p.score);
                    }
                }
            }
            let (a, r) = if has_gt && has_pred {
                average_precision(&y_true, &y_score, hard_fn)
            } else if has_gt {
                (0.0, 0.0)
            } else {
                (f64::NAN, f64::NAN)
            };
            ap[class][ti] = a;
            rc[class][ti] = r;
        }
    }

    let nanmean = |vals: &mut dyn Iterator<Item = f64>| {
        let v: Vec<f64> = vals.filter(|x| !x.is_nan()).collect();
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    let mean9 = |row: &[f64; 10]| row[..9].iter().sum::<f64>() / 9.0;
    let mut classes = Vec::new();
    for (c, name) in REPLICA_CLASSES.iter().enumerate() {
        if ap[c].iter().all(|x| x.is_nan()) {
            continue;
        }
        classes.push((
            name.to_string(),
            ClassResult {
                ap: mean9(&ap[c]),
                ap50: ap[c][T50],
                ap25: ap[c][T25],
                rc: mean9(&rc[c]),
                rc50: rc[c][T50],
                rc25: rc[c][T25],
            },
        ));
    }
    Ok(EvalResult {
        map: nanmean(&mut ap.iter().flat_map(|r| r[..9].to_vec())),
        map50: nanmean(&mut ap.iter().map(|r| r[T50])),
        map25: nanmean(&mut ap.iter().map(|r| r[T25])),
        score_mode: mode,
        classes,
    })
}

/// AP as ScanNet's evaluation computes it: precision/recall at each unique
/// score (ascending), the artificial point (p 1, r 0), and
/// Σ pᵢ·½(rᵢ₋₁ − rᵢ₊₁) without interpolation. Also returns the recall at
/// the lowest score (the curve's first point).
pub fn average_precision(y_true: &[bool], y_score: &[f64], hard_fn: usize) -> (f64, f64) {
    let mut order: Vec<usize> = (0..y_score.len()).collect();
    order.sort_by(|&a, &b| y_score[a].total_cmp(&y_score[b]));
    let n = order.len();
    let total_true = y_true.iter().filter(|&&t| t).count() as f64;
    let mut precision = Vec::new();
    let mut recall = Vec::new();
    let mut true_below = 0.0f64;
    let mut i = 0;
    while i < n {
        let s = y_score[order[i]];
        // first index of this unique score: everything before it is lower
        let tp = total_true - true_below;
        let fp = (n - i) as f64 - tp;
        let fn_ = true_below + hard_fn as f64;
        precision.push(tp / (tp + fp));
        recall.push(tp / (tp + fn_));
        while i < n && y_score[order[i]] == s {
            if y_true[order[i]] {
                true_below += 1.0;
            }
            i += 1;
        }
    }
    precision.push(1.0);
    recall.push(0.0);
    let m = recall.len();
    let r_at = |k: isize| -> f64 {
        if k < 0 {
            recall[0]
        } else if k as usize >= m {
            0.0
        } else {
            recall[k as usize]
        }
    };
    let ap = (0..m)
        .map(|k| precision[k] * 0.5 * (r_at(k as isize - 1) - r_at(k as isize + 1)))
        .sum();
    (ap, recall[0])
}

#[cfg(test)]
#[path = "instances_tests.rs"]
mod tests;
