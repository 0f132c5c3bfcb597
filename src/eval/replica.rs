//! `opennav eval replica`: the paper's Replica protocol on a dataset in the
//! layout Open3DIS/OpenMask3D read (NICE-SLAM's Replica renders):
//!
//! ```text
//! ROOT/cam_params.json              {"camera": {"w","h","fx","fy","cx","cy","scale"}}
//! ROOT/<scene>/traj.txt             per frame: 16 numbers, row-major 4×4 camera-to-world
//!                                   (camera = optical frame: x right, y down, z forward)
//! ROOT/<scene>/results/frame%06d.jpg   colour
//! ROOT/<scene>/results/depth%06d.png   uint16 depth, metres × scale (6553.5)
//! ROOT/ground_truth/<scene>.ply     ground-truth cloud: vertex x y z (float), sem inst (int)
//! ```
//!
//! Each view goes through the perception pipeline (any detector and
//! segmenter) into the world frame; objects are fused across views with the
//! cross-view merge (same label, 3D IoU > `merge_iou`); each fused object
//! becomes a point mask on the ground-truth cloud by the rule
//! [`MASK_RULE`]; the masks are scored with [`super::instances::evaluate`].

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::time::Instant;

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::instances::{
    evaluate, EvalCase, EvalError, EvalResult, Prediction, Rle, Scene, ScoreMode, REPLICA_CLASSES,
};
use crate::msg::Frame;
use crate::msg::Intrinsics;
use crate::msg::{DepthImage, ImageError, RgbImage};
use crate::perception::boxes::{merge_objects_by, MergeRule, Object3D};
use crate::perception::detector::{Detection, Detector, DetectorError};
use crate::perception::pipeline::{lift_detections, GeometrySettings, PipelineError};
use crate::perception::segmenter::Segmenter;

#[path = "replica_ply.rs"]
mod ply;
pub use ply::{read_gt_ply, write_gt_ply, GroundTruthCloud};

/// How a fused object becomes a point mask on the ground-truth cloud.
pub const MASK_RULE: &str = "ground-truth points whose voxel (edge mask_voxel_m) or one of its 26 neighbours holds a point of the fused object";

#[derive(Debug, Error)]
pub enum ReplicaError {
    #[error("{path}: {reason}")]
    File { path: String, reason: String },
    #[error(transparent)]
    Image(#[from] ImageError),
    #[error(transparent)]
    Detector(#[from] DetectorError),
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    #[error(transparent)]
    Eval(#[from] EvalError),
}

fn ferr(path: &Path, reason: impl std::fmt::Display) -> ReplicaError {
    ReplicaError::File {
        path: path.display().to_string(),
        reason: reason.to_string(),
    }
}

/// `cam_params.json` as NICE-SLAM writes it.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct CamParamsFile {
    pub camera: CamParams,
}

#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct CamParams {
    pub w: usize,
    pub h: usize,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// Depth counts per metre (6553.5 for Replica).
    pub scale: f64,
}

impl CamParams {
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics {
            width: self.w,
            height: self.h,
            fx: self.fx,
            fy: self.fy,
            cx: self.cx,
            cy: self.cy,
        }
    }
}

pub fn read_cam_params(root: &Path) -> Result<CamParams, ReplicaError> {
    let p = root.join("cam_params.json");
    let text = std::fs::read_to_string(&p).map_err(|e| ferr(&p, e))?;
    let f: CamParamsFile = serde_json::from_str(&text).map_err(|e| ferr(&p, e))?;
    let c = f.camera;
    if c.w == 0 || c.h == 0 || !(c.fx > 0.0 && c.fy > 0.0 && c.scale > 0.0) {
        return Err(ferr(
            &p,
            "camera size, focal lengths and scale must be positive",
        ));
    }
    Ok(c)
}

/// Parses `traj.txt`: one row-major 4×4 camera-to-world per line.
pub fn parse_trajectory(text: &str, path: &Path) -> Result<Vec<Isometry3<f64>>, ReplicaError> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|x| x.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| ferr(path, format!("line {}: {e}", i + 1)))?;
        if v.len() != 16 {
            return Err(ferr(
                path,
                format!("line {}: {} numbers, expected 16", i + 1, v.len()),
            ));
        }
        let m = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
        let ortho = (m.transpose() * m - Matrix3::identity()).abs().max();
        if ortho > 1e-3 || (m.determinant() - 1.0).abs() > 1e-3 {
            return Err(ferr(
                path,
                format!("line {}: the rotation part is not a rotation", i + 1),
            ));
        }
        let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix(&m));
        out.push(Isometry3::from_parts(
            Translation3::new(v[3], v[7], v[11]),
            rot,
        ));
    }
    Ok(out)
}

pub fn format_trajectory(poses: &[Isometry3<f64>]) -> String {
    let mut s = String::new();
    for p in poses {
        let m = p.to_homogeneous();
        let row: Vec<String> = (0..4)
            .flat_map(|r| (0..4).map(move |c| (r, c)))
            .map(|(r, c)| format!("{:.9e}", m[(r, c)]))
            .collect();
        s.push_str(&row.join(" "));
        s.push('\n');
    }
    s
}

/// One view of a scene.
#[derive(Debug, Clone)]
pub struct ReplicaView {
    pub index: usize,
    pub color: RgbImage,
    pub depth: DepthImage,
    pub world_from_camera: Isometry3<f64>,
}

/// A scene of the dataset.
#[derive(Debug, Clone)]
pub struct ReplicaScene {
    pub name: String,
    pub dir: PathBuf,
    pub gt_path: PathBuf,
    pub camera: CamParams,
    pub poses: Vec<Isometry3<f64>>,
}

impl ReplicaScene {
    pub fn open(root: &Path, name: &str) -> Result<Self, ReplicaError> {
        let camera = read_cam_params(root)?;
        let dir = root.join(name);
        let traj = dir.join("traj.txt");
        let text = std::fs::read_to_string(&traj).map_err(|e| ferr(&traj, e))?;
        let poses = parse_trajectory(&text, &traj)?;
        if poses.is_empty() {
            return Err(ferr(&traj, "no poses"));
        }
        let gt_path = root.join("ground_truth").join(format!("{name}.ply"));
        if !gt_path.is_file() {
            return Err(ferr(&gt_path, "ground-truth cloud missing"));
        }
        Ok(ReplicaScene {
            name: name.into(),
            dir,
            gt_path,
            camera,
            poses,
        })
    }

    pub fn frame_paths(&self, i: usize) -> (PathBuf, PathBuf) {
        let r = self.dir.join("results");
        (
            r.join(format!("frame{i:06}.jpg")),
            r.join(format!("depth{i:06}.png")),
        )
    }

    pub fn load_view(&self, i: usize) -> Result<ReplicaView, ReplicaError> {
        let (c, d) = self.frame_paths(i);
        let color = RgbImage::load(&c)?;
        let depth = DepthImage::load_png(&d, (1.0 / self.camera.scale) as f32)?;
        let k = self.camera;
        for (what, w, h) in [
            ("colour", color.width(), color.height()),
            ("depth", depth.width(), depth.height()),
        ] {
            if (w, h) != (k.w, k.h) {
                return Err(ferr(
                    &c,
                    format!("{what} is {w}x{h}, cam_params.json says {}x{}", k.w, k.h),
                ));
            }
        }
        let world_from_camera = *self
            .poses
            .get(i)
            .ok_or_else(|| ferr(&self.dir.join("traj.txt"), format!("no pose for frame {i}")))?;
        Ok(ReplicaView {
            index: i,
            color,
            depth,
            world_from_camera,
        })
    }
}

/// A detector for dataset views: a model on the colour image, or a
/// simulator's ground truth that knows the pose.
pub trait ViewDetector {
    fn name(&self) -> String;
    fn detect_view(&mut self, view: &ReplicaView) -> Result<Vec<Detection>, DetectorError>;
}

/// Any [`Detector`] on the view's colour image.
pub struct ModelViewDetector(pub Box<dyn Detector>);

impl ViewDetector for ModelViewDetector {
    fn name(&self) -> String {
        self.0.backend().to_string()
    }
    fn detect_view(&mut self, view: &ReplicaView) -> Result<Vec<Detection>, DetectorError> {
        self.0.detect(&view.color)
    }
}

#[derive(Debug, Clone)]
pub struct RunSettings {
    /// Use this many views, evenly spaced (None: all).
    pub views: Option<usize>,
    /// Cross-view merge (the paper's: same label, IoU > 0.8).
    pub merge: MergeRule,
    pub geometry: GeometrySettings,
    /// Voxel edge of the mask rule, metres.
    pub mask_voxel_m: f64,
    pub score_mode: ScoreMode,
}

impl Default for RunSettings {
    fn default() -> Self {
        RunSettings {
            views: None,
            merge: MergeRule::paper(0.8),
            geometry: GeometrySettings::default(),
            mask_voxel_m: 0.03,
            score_mode: ScoreMode::One,
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct SceneRun {
    pub scene: String,
    pub views: usize,
    /// Per view: detection + segmentation + geometry, seconds.
    pub secs_per_view_mean: f64,
    pub secs_per_view_median: f64,
    /// All views, the cross-view merge and the point masks, seconds.
    pub secs_per_scene: f64,
    pub objects_per_view: f64,
    pub fused_objects: usize,
}

#[derive(Debug, Clone)]
pub struct ReplicaReport {
    pub result: EvalResult,
    pub scenes: Vec<SceneRun>,
    pub detector: String,
}

impl ReplicaReport {
    pub fn to_json(&self, settings: &RunSettings) -> serde_json::Value {
        let classes: serde_json::Map<String, serde_json::Value> = self
            .result
            .classes
            .iter()
            .map(|(n, c)| {
                (
                    n.clone(),
                    serde_json::to_value(c).unwrap_or(serde_json::Value::Null),
                )
            })
            .collect();
        serde_json::json!({
            "mAP": self.result.map,
            "mAP50": self.result.map50,
            "mAP25": self.result.map25,
            "score_mode": self.result.score_mode,
            "detector": self.detector,
            "mask_rule": MASK_RULE,
            "mask_voxel_m": settings.mask_voxel_m,
            "merge_iou": settings.merge.iou,
            "merge_containment": settings.merge.containment,
            "timing_definition": "secs_per_view: detection + segmentation + geometry of one view (reading files excluded); secs_per_scene: all views + cross-view merge + point masks",
            "scenes": self.scenes,
            "classes": classes,
        })
    }

    /// A per-class table (AP in %).
    pub fn table(&self) -> String {
        let mut s = format!("{:<16} {:>7} {:>7} {:>7}\n", "class", "AP", "AP50", "AP25");
        for (n, c) in &self.result.classes {
            s.push_str(&format!(
                "{:<16} {:>7.1} {:>7.1} {:>7.1}\n",
                n,
                100.0 * c.ap,
                100.0 * c.ap50,
                100.0 * c.ap25
            ));
        }
        s.push_str(&format!(
            "{:<16} {:>7.1} {:>7.1} {:>7.1}   (score mode: {:?})\n",
            "mean",
            100.0 * self.result.map,
            100.0 * self.result.map50,
            100.0 * self.result.map25,
            self.result.score_mode
        ));
        s
    }
}

fn view_indices(total: usize, wanted: Option<usize>) -> Vec<usize> {
    match wanted {
        Some(n) if n < total && n > 0 => (0..n).map(|k| k * total / n).collect(),
        _ => (0..total).collect(),
    }
}

fn voxel(p: &Point3<f32>, edge: f64) -> (i64, i64, i64) {
    (
        (p.x as f64 / edge).floor() as i64,
        (p.y as f64 / edge).floor() as i64,
        (p.z as f64 / edge).floor() as i64,
    )
}

/// The point mask of `object` on the ground-truth cloud, as sorted indices
/// (see [`MASK_RULE`]).
pub fn object_mask(object: &Object3D, gt: &GroundTruthCloud, edge: f64) -> Vec<usize> {
    let occupied: HashSet<(i64, i64, i64)> = object.points.iter().map(|p| voxel(p, edge)).collect();
    let lo = object.aabb.min_m.map(|v| v - 2.0 * edge);
    let hi = object.aabb.max_m.map(|v| v + 2.0 * edge);
    gt.points
        .iter()
        .enumerate()
        .filter(|(_, p)| {
            let c = [p.x as f64, p.y as f64, p.z as f64];
            (0..3).all(|k| c[k] >= lo[k] && c[k] <= hi[k])
        })
        .filter(|(_, p)| {
            let (x, y, z) = voxel(p, edge);
            (-1..=1).any(|dx| {
                (-1..=1).any(|dy| (-1..=1).any(|dz| occupied.contains(&(x + dx, y + dy, z + dz))))
            })
        })
        .map(|(i, _)| i)
        .collect()
}

/// Sorted indices → RLE with 1-based starts.
pub fn indices_to_rle(indices: &[usize], length: usize) -> Rle {
    let mut counts = Vec::new();
    let mut k = 0;
    while k < indices.len() {
        let start = indices[k];
        let mut end = start + 1;
        k += 1;
        while k < indices.len() && indices[k] == end {
            end += 1;
            k += 1;
        }
        counts.push(start as i64 + 1);
        counts.push((end - start) as i64);
    }
    Rle { length, counts }
}

/// The Replica class id of a label ("tv screen" and "tv-screen" alike).
fn label_id(label: &str) -> Option<i64> {
    let norm = |s: &str| s.trim().to_lowercase().replace(['-', '_'], " ");
    let l = norm(label);
    REPLICA_CLASSES
        .iter()
        .position(|c| norm(c) == l)
        .map(|i| i as i64 + 1)
}

/// Runs one scene: every selected view through detection and steps 2–6 in
/// the world frame, the cross-view merge, and the point masks.
pub fn run_scene(
    scene: &ReplicaScene,
    detector: &mut dyn ViewDetector,
    segmenter: &mut dyn Segmenter,
    settings: &RunSettings,
    progress: &mut dyn FnMut(usize, usize),
) -> Result<(Scene, Vec<Prediction>, SceneRun), ReplicaError> {
    let gt = read_gt_ply(&scene.gt_path)?;
    let k = scene.camera.intrinsics();
    let idx = view_indices(scene.poses.len(), settings.views);
    let mut objects: Vec<Object3D> = Vec::new();
    let mut view_secs = Vec::with_capacity(idx.len());
    let mut scene_secs = 0.0;
    for (n, &i) in idx.iter().enumerate() {
        let view = scene.load_view(i)?;
        let t = Instant::now();
        let dets = detector.detect_view(&view)?;
        let v = lift_detections(
            segmenter,
            &view.color,
            &view.depth,
            dets,
            &k,
            &view.world_from_camera,
            Frame::Odom,
            &settings.geometry,
            None,
        )?;
        let secs = t.elapsed().as_secs_f64();
        view_secs.push(secs);
        scene_secs += secs;
        objects.extend(
            v.objects
                .into_iter()
                .filter(|o| label_id(&o.label).is_some()),
        );
        progress(n + 1, idx.len());
    }
    let per_view_objects = objects.len() as f64 / idx.len().max(1) as f64;
    let t = Instant::now();
    let fused = merge_objects_by(objects, &settings.merge);
    let mut predictions = Vec::new();
    for o in &fused {
        let Some(id) = label_id(&o.label) else {
            continue;
        };
        let mask = object_mask(o, &gt, settings.mask_voxel_m);
        tracing::debug!(label = %o.label, points = o.points.len(), mask = mask.len(), min = ?o.aabb.min_m, max = ?o.aabb.max_m, "fused object");
        predictions.push(Prediction {
            scene: scene.name.clone(),
            label_id: id,
            score: o.score as f64,
            mask_rle: indices_to_rle(&mask, gt.points.len()),
        });
    }
    scene_secs += t.elapsed().as_secs_f64();
    let mut sorted = view_secs.clone();
    sorted.sort_by(|a, b| a.total_cmp(b));
    let run = SceneRun {
        scene: scene.name.clone(),
        views: idx.len(),
        secs_per_view_mean: view_secs.iter().sum::<f64>() / view_secs.len().max(1) as f64,
        secs_per_view_median: sorted.get(sorted.len() / 2).copied().unwrap_or(0.0),
        secs_per_scene: scene_secs,
        objects_per_view: per_view_objects,
        fused_objects: fused.len(),
    };
    Ok((
        Scene {
            id: scene.name.clone(),
            sem: gt.sem,
            inst: gt.inst,
        },
        predictions,
        run,
    ))
}

/// Runs and scores several scenes.
pub fn run(
    root: &Path,
    scenes: &[String],
    detector: &mut dyn ViewDetector,
    segmenter: &mut dyn Segmenter,
    settings: &RunSettings,
    progress: &mut dyn FnMut(&str, usize, usize),
) -> Result<ReplicaReport, ReplicaError> {
    let mut case = EvalCase {
        scenes: Vec::new(),
        predictions: Vec::new(),
    };
    let mut runs = Vec::new();
    for name in scenes {
        let scene = ReplicaScene::open(root, name)?;
        let (gt, preds, r) = run_scene(&scene, detector, segmenter, settings, &mut |i, n| {
            progress(name, i, n)
        })?;
        case.scenes.push(gt);
        case.predictions.extend(preds);
        runs.push(r);
    }
    let result = evaluate(&case, settings.score_mode)?;
    Ok(ReplicaReport {
        result,
        scenes: runs,
        detector: detector.name(),
    })
}

/// Scene names under `root` (folders with a `traj.txt`), sorted.
pub fn list_scenes(root: &Path) -> Result<Vec<String>, ReplicaError> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(root).map_err(|e| ferr(root, e))? {
        let e = e.map_err(|e| ferr(root, e))?;
        if e.path().join("traj.txt").is_file() {
            out.push(e.file_name().to_string_lossy().into_owned());
        }
    }
    out.sort();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trajectory_round_trip_and_errors() {
        let p = crate::sim::room::look_direction(nalgebra::Vector3::new(1.0, 2.0, 3.0), 0.4, -0.3);
        let text = format_trajectory(&[p, Isometry3::identity()]);
        let back = parse_trajectory(&text, Path::new("traj.txt")).unwrap();
        assert_eq!(back.len(), 2);
        assert!((back[0].to_homogeneous() - p.to_homogeneous()).abs().max() < 1e-8);
        let e = parse_trajectory("1 2 3\n", Path::new("traj.txt"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("traj.txt") && e.contains("line 1"), "{e}");
        let e = parse_trajectory(&"2 ".repeat(16), Path::new("t"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a rotation"), "{e}");
    }

    #[test]
    fn rle_of_indices() {
        let r = indices_to_rle(&[0, 1, 2, 5, 7, 8], 10);
        assert_eq!(r.counts, vec![1, 3, 6, 1, 8, 2]);
        assert!(indices_to_rle(&[], 4).counts.is_empty());
    }

    #[test]
    fn ply_round_trip_binary_and_ascii() {
        let dir = tempfile::tempdir().unwrap();
        let gt = GroundTruthCloud {
            points: vec![Point3::new(1.0, 2.0, 3.0), Point3::new(-1.5, 0.25, 9.0)],
            sem: vec![14, 0],
            inst: vec![3, -100],
        };
        let p = dir.path().join("g.ply");
        write_gt_ply(&p, &gt).unwrap();
        assert_eq!(read_gt_ply(&p).unwrap(), gt);
        let ascii = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty int sem\nproperty int inst\nend_header\n1 2 3 200 14 3\n-1.5 0.25 9 0 0 -100\n";
        std::fs::write(&p, ascii).unwrap();
        assert_eq!(read_gt_ply(&p).unwrap(), gt);
        std::fs::write(
            &p,
            "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
        )
        .unwrap();
        assert!(read_gt_ply(&p)
            .unwrap_err()
            .to_string()
            .contains("`y` missing"));
    }

    #[test]
    fn mask_rule_takes_points_near_the_object() {
        let gt = GroundTruthCloud {
            points: vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(0.05, 0.0, 0.0),
                Point3::new(0.5, 0.0, 0.0),
            ],
            sem: vec![14, 14, 14],
            inst: vec![0, 0, 0],
        };
        let o = Object3D::from_points(
            "chair".into(),
            1.0,
            Frame::Odom,
            vec![Point3::new(0.01, 0.01, 0.01)],
            None,
        )
        .unwrap();
        assert_eq!(object_mask(&o, &gt, 0.03), vec![0, 1]);
    }
}
