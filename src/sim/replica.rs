//! A synthetic scene in Replica's layout (see [`crate::eval::replica`]):
//! the living room rendered along an orbit, its ground-truth cloud, and the
//! simulator's ground-truth detector (optionally degraded) for evaluating
//! the pipeline end to end where the real Replica cannot be had.

use std::path::Path;

use nalgebra::Isometry3;

use super::room::Room;
use crate::eval::replica::{
    format_trajectory, write_gt_ply, CamParams, CamParamsFile, GroundTruthCloud, ReplicaError,
    ReplicaView, ViewDetector,
};
use crate::perception::detector::{Detection, DetectorError};

fn ferr(path: &Path, e: impl std::fmt::Display) -> ReplicaError {
    ReplicaError::File {
        path: path.display().to_string(),
        reason: e.to_string(),
    }
}

/// Camera of the synthetic scenes: Open3DIS's Replica frames are 640×360;
/// `scale_down` divides the size (2 → 320×180) for quick runs.
pub fn camera(scale_down: usize) -> CamParams {
    let s = scale_down.max(1) as f64;
    let (w, h) = ((640.0 / s) as usize, (360.0 / s) as usize);
    CamParams {
        w,
        h,
        fx: 320.0 / s,
        fy: 320.0 / s,
        cx: (w as f64 - 1.0) / 2.0,
        cy: (h as f64 - 1.0) / 2.0,
        scale: 6553.5,
    }
}

/// Writes scene `name` under `root`: `cam_params.json`, `<name>/traj.txt`,
/// `<name>/results/frame%06d.jpg` + `depth%06d.png`, and
/// `ground_truth/<name>.ply`. Returns the poses.
pub fn write_scene(
    root: &Path,
    name: &str,
    room: &Room,
    cam: &CamParams,
    views: usize,
) -> Result<Vec<Isometry3<f64>>, ReplicaError> {
    let results = root.join(name).join("results");
    std::fs::create_dir_all(&results).map_err(|e| ferr(&results, e))?;
    let gt_dir = root.join("ground_truth");
    std::fs::create_dir_all(&gt_dir).map_err(|e| ferr(&gt_dir, e))?;
    let cp = root.join("cam_params.json");
    let text =
        serde_json::to_string_pretty(&CamParamsFile { camera: *cam }).map_err(|e| ferr(&cp, e))?;
    std::fs::write(&cp, text).map_err(|e| ferr(&cp, e))?;
    let poses = room.orbit(views, 0.5, 1.4);
    let traj = root.join(name).join("traj.txt");
    std::fs::write(&traj, format_trajectory(&poses)).map_err(|e| ferr(&traj, e))?;
    let k = cam.intrinsics();
    for (i, pose) in poses.iter().enumerate() {
        let r = room.render(&k, pose)?;
        let cpath = results.join(format!("frame{i:06}.jpg"));
        image::save_buffer(
            &cpath,
            r.color.data(),
            k.width as u32,
            k.height as u32,
            image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| ferr(&cpath, e))?;
        let counts: Vec<u16> = r
            .depth
            .data()
            .iter()
            .map(|&z| (z as f64 * cam.scale).round().clamp(0.0, 65535.0) as u16)
            .collect();
        let dpath = results.join(format!("depth{i:06}.png"));
        let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(
            k.width as u32,
            k.height as u32,
            counts,
        )
        .ok_or_else(|| ferr(&dpath, "depth buffer size"))?;
        img.save(&dpath).map_err(|e| ferr(&dpath, e))?;
    }
    let mut gt = GroundTruthCloud::default();
    for (p, s, i) in room.ground_truth_cloud(0.02) {
        gt.points.push(p);
        gt.sem.push(s);
        gt.inst.push(i);
    }
    write_gt_ply(&gt_dir.join(format!("{name}.ply")), &gt)?;
    Ok(poses)
}

/// How the ground-truth detector is made worse, for tests of the metric's
/// sensitivity.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Degrade {
    /// Never report objects with an odd index.
    pub miss_every_other: bool,
    /// Shrink each box about its centre to this fraction of its size (1 = as is).
    pub box_fraction: f32,
}

/// The simulator's detector: boxes of the objects' visible pixels, from the
/// room and the view's pose (not from the image).
pub struct SimGtDetector {
    pub room: Room,
    pub camera: CamParams,
    pub degrade: Option<Degrade>,
    /// Objects with fewer visible pixels are not reported.
    pub min_pixels: usize,
}

impl SimGtDetector {
    pub fn new(room: Room, camera: CamParams) -> Self {
        SimGtDetector {
            room,
            camera,
            degrade: None,
            min_pixels: 50,
        }
    }
}

impl ViewDetector for SimGtDetector {
    fn name(&self) -> String {
        match self.degrade {
            None => "simulator ground truth".into(),
            Some(d) => format!("simulator ground truth, degraded ({d:?})"),
        }
    }

    fn detect_view(&mut self, view: &ReplicaView) -> Result<Vec<Detection>, DetectorError> {
        let k = self.camera.intrinsics();
        let r = self
            .room
            .render(&k, &view.world_from_camera)
            .map_err(|e| DetectorError::Prompt(format!("simulator: {e}")))?;
        Ok(self.detect_instances(&r.instance, k.width))
    }
}

impl SimGtDetector {
    /// Boxes of the objects' visible pixels in a rendered instance map
    /// (row-major, `width` pixels a row).
    pub fn detect_instances(&self, instance: &[i32], width: usize) -> Vec<Detection> {
        let width = width.max(1);
        let n = self.room.objects.len();
        let mut bounds = vec![(usize::MAX, usize::MAX, 0usize, 0usize, 0usize); n];
        for (i, &id) in instance.iter().enumerate() {
            let Some(b) = usize::try_from(id).ok().and_then(|id| bounds.get_mut(id)) else {
                continue;
            };
            let (u, v) = (i % width, i / width);
            b.0 = b.0.min(u);
            b.1 = b.1.min(v);
            b.2 = b.2.max(u + 1);
            b.3 = b.3.max(v + 1);
            b.4 += 1;
        }
        let mut out = Vec::new();
        for (idx, (x0, y0, x1, y1, count)) in bounds.into_iter().enumerate() {
            if count < self.min_pixels {
                continue;
            }
            let mut bx = [x0 as f32, y0 as f32, x1 as f32, y1 as f32];
            if let Some(d) = self.degrade {
                if d.miss_every_other && idx % 2 == 1 {
                    continue;
                }
                let f = d.box_fraction.clamp(0.05, 1.0);
                let (cx, cy) = ((bx[0] + bx[2]) / 2.0, (bx[1] + bx[3]) / 2.0);
                let (hw, hh) = ((bx[2] - bx[0]) * f / 2.0, (bx[3] - bx[1]) * f / 2.0);
                bx = [cx - hw, cy - hh, cx + hw, cy + hh];
            }
            let label = self.room.objects[idx].label.clone();
            out.push(Detection {
                class: label.clone(),
                label,
                score: 0.9,
                box_xyxy: bx,
            });
        }
        out
    }
}
