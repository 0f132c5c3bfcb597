//! The estimation task: it owns the estimator (wheel odometry, gyro, scan
//! matching into the EKF), the pose history and the object tracker. Wheel
//! counts predict and publish the chair's [`Odometry`]; merged scans
//! correct it; perception's objects (in `base_link` at their frame's
//! stamp) are placed in `odom` with the pose at that stamp and go into the
//! tracker, whose tracks it publishes.

use std::collections::VecDeque;

use serde::Serialize;
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

use crate::estimation::ekf::PoseHistory;
use crate::estimation::fusion::Estimator;
use crate::estimation::obstacle_map::{CellKind, FootprintM, MapView, ObstacleMap};
use crate::estimation::tracker::Tracker;
use crate::estimation::view::CameraView;
use crate::msg::{
    LaserRay, MapObstacles, Object3D, Obstacles, Odometry, Pose2, Stamp, Stamped, WheelTicks,
};
use crate::perception::depth_obstacles::{DepthScan, NearestDepth};

/// The floor never seen is reported this far beyond the circle a turn on
/// the spot sweeps (the supervisor's margin, the chair's motion between
/// frames, half a cell's diagonal), m.
const UNSEEN_FLOOR_BEYOND_M: f64 = 0.15;

/// Laser scans are put to the camera's memory this far apart at least
/// (what the lasers see through there: a person walking on).
const RAYS_EVERY: std::time::Duration = std::time::Duration::from_millis(200);

/// Counters for the report.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct EstimationStats {
    /// Scans matched into the EKF.
    pub scan_matches: u64,
    /// Odometry steps whose heading used the gyro.
    pub gyro_fused: u64,
    /// Views placed into the tracker.
    pub views_placed: u64,
    /// Views dropped: no pose at their stamp (odometry starting or
    /// behind; said in the log).
    pub views_without_pose: u64,
    /// Depth frames placed into the obstacle memory, and dropped (no pose
    /// at their stamp).
    pub depth_frames_placed: u64,
    pub depth_frames_without_pose: u64,
    /// Cells in the obstacle memory now.
    pub depth_cells: u64,
    /// Laser scans that forgot cells of the memory (what the lasers saw
    /// there has gone; scans, not cells), and scans dropped for the memory
    /// (no pose at their stamp).
    pub laser_scans_forgetting_cells: u64,
    pub laser_scans_without_pose: u64,
}

pub struct EstimationIo {
    pub ticks: watch::Receiver<Option<Stamped<WheelTicks>>>,
    pub obstacles: watch::Receiver<Option<Stamped<Obstacles>>>,
    pub gyro: watch::Receiver<Option<Stamped<f64>>>,
    /// Objects in `base_link`, stamped with their frame's acquisition.
    pub objects: mpsc::Receiver<Stamped<Vec<Object3D>>>,
    /// Each depth frame's cells in `base_link`.
    pub depth_scans: mpsc::Receiver<Stamped<DepthScan>>,
    /// The remembered cells in `odom`, stamped with the newest frame.
    pub camera_obstacles: watch::Sender<Option<Stamped<MapObstacles>>>,
    pub odometry: watch::Sender<Option<Stamped<Odometry>>>,
    pub tracks: watch::Sender<Tracker>,
    pub stats: watch::Sender<EstimationStats>,
}

/// Views waiting for odometry to pass their stamp.
const MAX_PENDING_VIEWS: usize = 8;

/// The pure part: places views with the pose history.
pub struct Estimation {
    pub estimator: Estimator,
    pub history: PoseHistory,
    pub tracker: Tracker,
    pub view: Option<CameraView>,
    pending: VecDeque<Stamped<Vec<Object3D>>>,
    /// The depth camera's memory (None: no depth obstacles).
    pub map: Option<(ObstacleMap, FootprintM)>,
    pending_scans: VecDeque<Stamped<DepthScan>>,
    /// The latest depth frames' nearest surfaces, for the views of the
    /// same frames: what hides a track.
    nearest: VecDeque<Stamped<NearestDepth>>,
    /// The newest frame placed into the map, and the chair's pose then.
    map_stamp: Option<(Stamp, Pose2)>,
    /// The newest laser scan's rays, waiting for odometry to pass its
    /// stamp (a newer scan replaces it).
    pending_rays: Option<Stamped<Vec<LaserRay>>>,
    /// The stamp of the last scan put to the memory.
    rays_placed_at: Option<Stamp>,
    pub stats: EstimationStats,
}

impl Estimation {
    pub fn new(estimator: Estimator, tracker: Tracker, view: Option<CameraView>) -> Self {
        Estimation {
            estimator,
            history: PoseHistory::new(400),
            tracker,
            view,
            pending: VecDeque::new(),
            map: None,
            pending_scans: VecDeque::new(),
            nearest: VecDeque::new(),
            map_stamp: None,
            pending_rays: None,
            rays_placed_at: None,
            stats: EstimationStats::default(),
        }
    }

    /// Remember the depth camera's cells (`d`'s cell size and memory
    /// radius), clearing those under `footprint`; with the camera's view,
    /// a cell a frame saw part of keeps what that frame could not see;
    /// with the lasers' plane's height, a cell seen across it counts as
    /// the lasers'.
    pub fn with_obstacle_map(
        mut self,
        d: &crate::perception::depth_obstacles::DepthObstacleSettings,
        footprint: FootprintM,
        laser_plane_m: Option<f64>,
    ) -> Self {
        let mut map = ObstacleMap::new(d.cell_m, d.memory_radius_m);
        if let Some(h) = laser_plane_m {
            map = map.with_laser_plane(h);
        }
        if let Some(camera) = self.view {
            map = map.with_view(MapView {
                camera,
                max_range_m: d.max_range_m,
            });
        }
        self.map = Some((map, footprint));
        self
    }

    /// Queues a depth frame's cells; returns the memory when it changed.
    pub fn on_depth_scan(&mut self, mut scan: Stamped<DepthScan>) -> Option<Stamped<MapObstacles>> {
        if self.nearest.len() == MAX_PENDING_VIEWS {
            self.nearest.pop_front();
        }
        let nearest = std::mem::take(&mut scan.value.nearest);
        self.nearest.push_back(Stamped::new(scan.stamp, nearest));
        if self.pending_scans.len() == MAX_PENDING_VIEWS {
            self.pending_scans.pop_front();
            self.stats.depth_frames_without_pose += 1;
            tracing::warn!("depth obstacles: frames wait for odometry; the oldest dropped");
        }
        self.pending_scans.push_back(scan);
        self.place_scans()
    }

    /// Places the depth frames the pose history now covers.
    pub fn place_scans(&mut self) -> Option<Stamped<MapObstacles>> {
        let mut changed = false;
        while let Some(front) = self.pending_scans.front() {
            let stamp = front.stamp;
            match self.history.pose_at(stamp) {
                Some(pose) => {
                    let Some(scan) = self.pending_scans.pop_front() else {
                        break;
                    };
                    if let Some((map, footprint)) = &mut self.map {
                        map.insert(pose, &scan.value, *footprint);
                        self.stats.depth_frames_placed += 1;
                        self.stats.depth_cells = map.len() as u64;
                        self.map_stamp = Some((stamp, pose));
                        changed = true;
                    }
                }
                None if self.history_covers_after(stamp) => {
                    self.pending_scans.pop_front();
                    self.stats.depth_frames_without_pose += 1;
                    tracing::info!("depth obstacles: no pose at the frame's stamp; frame skipped");
                }
                None => break,
            }
        }
        if !changed {
            return None;
        }
        self.map_obstacles()
    }

    /// The memory as the supervisor and the planner take it, stamped with
    /// the newest frame placed (None: no frame yet).
    fn map_obstacles(&self) -> Option<Stamped<MapObstacles>> {
        let (map, footprint) = self.map.as_ref()?;
        let (stamp, pose) = self.map_stamp?;
        // the floor never seen where a turn on the spot from about here
        // would sweep (the chair moves on between frames)
        let floor_unseen_odom =
            map.unseen_near(&pose, footprint.corner_reach_m() + UNSEEN_FLOOR_BEYOND_M);
        Some(Stamped::new(
            stamp,
            MapObstacles {
                obstacles_odom: map.points(CellKind::Obstacle),
                drop_offs_odom: map.points(CellKind::DropOff),
                drop_offs_unseen_odom: map.points(CellKind::UnseenDropOff),
                floor_unseen_odom,
            },
        ))
    }

    pub fn on_ticks(&mut self, t: &Stamped<WheelTicks>) -> Stamped<Odometry> {
        let e = self.estimator.on_ticks(t);
        self.history.push(t.stamp, e.pose);
        self.stats.gyro_fused = self.estimator.gyro_fused;
        Stamped::new(t.stamp, e)
    }

    /// A merged laser scan: scan matching, and what the lasers now see
    /// through in the camera's memory ([`ObstacleMap::on_lasers`]);
    /// returns the memory when that changed it.
    pub fn on_scan(&mut self, o: &Stamped<Obstacles>) -> Option<Stamped<MapObstacles>> {
        self.match_scan(o);
        if self.map.is_none() || self.map_stamp.is_none() {
            return None;
        }
        // every few scans is enough for a person walking past
        if self
            .rays_placed_at
            .is_some_and(|t| t.age_at(o.stamp) < RAYS_EVERY)
        {
            return None;
        }
        self.pending_rays = Some(Stamped::new(o.stamp, o.value.rays_base.clone()));
        self.place_rays()
    }

    /// Puts the waiting scan's rays to the memory once the pose history
    /// covers their stamp; a scan older than the history is dropped.
    pub fn place_rays(&mut self) -> Option<Stamped<MapObstacles>> {
        let stamp = self.pending_rays.as_ref()?.stamp;
        let pose = match self.history.pose_at(stamp) {
            Some(p) => p,
            None if self.history_covers_after(stamp) => {
                self.pending_rays = None;
                self.stats.laser_scans_without_pose += 1;
                return None;
            }
            None => return None,
        };
        let rays = self.pending_rays.take()?;
        self.rays_placed_at = Some(stamp);
        let (map, _) = self.map.as_mut()?;
        let forgot = map.on_lasers(pose, &rays.value);
        self.stats.depth_cells = map.len() as u64;
        if !forgot {
            return None;
        }
        self.stats.laser_scans_forgetting_cells += 1;
        self.map_obstacles()
    }

    fn match_scan(&mut self, o: &Stamped<Obstacles>) {
        let pts: Vec<[f64; 2]> = o
            .value
            .points_base
            .iter()
            .map(|p| [p[0] as f64, p[1] as f64])
            .collect();
        match self.estimator.on_scan(&pts) {
            Some(Ok(_)) => self.stats.scan_matches += 1,
            Some(Err(e)) => tracing::debug!(error = %e, "scan matching"),
            None => {}
        }
    }

    /// Queues a view; returns whether the tracker changed.
    pub fn on_objects(&mut self, objects: Stamped<Vec<Object3D>>) -> bool {
        if self.pending.len() == MAX_PENDING_VIEWS {
            self.pending.pop_front();
            self.stats.views_without_pose += 1;
            tracing::warn!("perception: views wait for odometry; the oldest dropped");
        }
        self.pending.push_back(objects);
        self.place_pending()
    }

    /// Places the views whose stamp the pose history now covers; views
    /// older than the history are dropped (and counted).
    pub fn place_pending(&mut self) -> bool {
        let mut changed = false;
        while let Some(front) = self.pending.front() {
            let stamp = front.stamp;
            match self.history.pose_at(stamp) {
                Some(pose) => {
                    let Some(view) = self.pending.pop_front() else {
                        break;
                    };
                    self.place(stamp, pose, view.value);
                    changed = true;
                }
                None if self.history_covers_after(stamp) => {
                    self.pending.pop_front();
                    self.stats.views_without_pose += 1;
                    tracing::info!("perception: no pose at the view's stamp (odometry starting?); view skipped");
                }
                None => break,
            }
        }
        changed
    }

    /// Whether the history's newest pose is past `stamp` (so no pose for
    /// it will come).
    fn history_covers_after(&self, stamp: Stamp) -> bool {
        self.history.newest().is_some_and(|t| t >= stamp)
    }

    fn place(&mut self, stamp: Stamp, pose: crate::msg::Pose2, objects: Vec<Object3D>) {
        let objects = crate::perception::boxes::objects_in_odom(pose, objects);
        let view = self.view;
        // the same frame's depth: a track behind something is not missed
        let nearest = self.nearest.iter().rev().find(|n| n.stamp == stamp);
        let base_from_odom = pose.to_isometry3().inverse();
        self.tracker.update(stamp, &objects, |t| {
            let in_view = view.is_some_and(|v| v.sees(&pose, &t.center_m));
            in_view
                && !nearest.is_some_and(|n| {
                    let c = base_from_odom
                        * nalgebra::Point3::new(t.center_m[0], t.center_m[1], t.center_m[2]);
                    let half_diagonal_m = 0.5 * t.size_m[0].hypot(t.size_m[1]);
                    n.value.hides(&[c.x, c.y, c.z], half_diagonal_m)
                })
        });
        self.stats.views_placed += 1;
    }
}

/// Runs until cancelled; an input channel closing is a fault.
pub async fn run(
    mut est: Estimation,
    mut io: EstimationIo,
    cancel: CancellationToken,
) -> Result<(), String> {
    // no camera, or one without an IMU: the gyro's sender goes away
    let mut gyro_open = true;
    let mut objects_open = true;
    let mut scans_open = true;
    loop {
        tokio::select! {
            biased;
            _ = cancel.cancelled() => return Ok(()),
            r = io.gyro.changed(), if gyro_open => {
                if r.is_err() {
                    gyro_open = false;
                    continue;
                }
                if let Some(g) = *io.gyro.borrow_and_update() {
                    est.estimator.on_gyro(g);
                }
            }
            r = io.ticks.changed() => {
                r.map_err(|_| "the wheel counts' channel closed".to_string())?;
                let Some(t) = *io.ticks.borrow_and_update() else { continue };
                let odometry = est.on_ticks(&t);
                io.odometry.send_replace(Some(odometry));
                if est.place_pending() {
                    io.tracks.send_replace(est.tracker.clone());
                }
                if let Some(m) = est.place_scans() {
                    io.camera_obstacles.send_replace(Some(m));
                }
                if let Some(m) = est.place_rays() {
                    io.camera_obstacles.send_replace(Some(m));
                }
                io.stats.send_replace(est.stats);
            }
            r = io.obstacles.changed() => {
                r.map_err(|_| "the obstacles' channel closed".to_string())?;
                let Some(o) = io.obstacles.borrow_and_update().clone() else { continue };
                if let Some(m) = est.on_scan(&o) {
                    io.camera_obstacles.send_replace(Some(m));
                }
                io.stats.send_replace(est.stats);
            }
            v = io.objects.recv(), if objects_open => match v {
                Some(v) => {
                    if est.on_objects(v) {
                        io.tracks.send_replace(est.tracker.clone());
                    }
                    io.stats.send_replace(est.stats);
                }
                // no camera: perception never sends
                None => objects_open = false,
            },
            v = io.depth_scans.recv(), if scans_open => match v {
                Some(v) => {
                    if let Some(m) = est.on_depth_scan(v) {
                        io.camera_obstacles.send_replace(Some(m));
                    }
                    io.stats.send_replace(est.stats);
                }
                None => scans_open = false,
            },
        }
    }
}
