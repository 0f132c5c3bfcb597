//! The perception task: the camera's newest frame through the pipeline
//! (detector → masks → erosion → z-score → back-projection → boxes) for
//! the words the goal keeper wants, on a blocking thread (inference never
//! runs on the async workers). Objects go to the estimation task in
//! `base_link` with the frame's stamp; the camera's gyro, when it has one,
//! goes to the estimator as the yaw rate about base z.

use std::time::Duration;

use nalgebra::{Isometry3, Vector3};
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

use super::recorder::{record, RecordItem, RecordSink};
use crate::msg::{Clock, Object3D, Stamped};
use crate::perception::depth_obstacles::{self, DepthObstacleSettings, DepthScan};
use crate::perception::pipeline::Pipeline;
use crate::sensors::camera::CameraSource;

pub struct PerceptionIo {
    /// The words to look for (the goal's), from the control task.
    pub prompts: watch::Receiver<Vec<String>>,
    pub objects: mpsc::Sender<Stamped<Vec<Object3D>>>,
    /// Every frame's obstacle and drop-off cells in `base_link`.
    pub depth_scans: mpsc::Sender<Stamped<DepthScan>>,
    /// The camera IMU's yaw rate about base z, rad/s.
    pub gyro: watch::Sender<Option<Stamped<f64>>>,
    /// The first frame arrived (for READY).
    pub first_frame: mpsc::UnboundedSender<&'static str>,
    pub record: Option<RecordSink>,
    /// The live view (Foxglove), when it is on.
    pub live: Option<crate::live::LiveSink>,
    /// The whole view's compute time over the run (registration,
    /// detector, masks, geometry), published with each view.
    pub view_time: watch::Sender<crate::actuation::PeriodStats>,
}

/// The camera's side of the loop.
pub struct CameraLoop {
    /// Opens the camera again (at the end of a recording).
    pub open: super::devices::OpenCamera,
    pub restamp: bool,
    pub period: Duration,
    pub latency: Duration,
    /// Obstacles and drop-offs from every depth frame (None: off).
    pub depth_obstacles: Option<DepthObstacleSettings>,
}

/// Camera errors in a row for this long: the camera is gone (a fault).
const CAMERA_GIVE_UP: Duration = Duration::from_secs(5);

/// What one blocking round returns.
enum Round {
    View(Box<ViewRound>),
    CameraError(String),
    Ended,
}

struct ViewRound {
    frame: Stamped<crate::msg::RgbdFrame>,
    /// None: nothing to look for.
    result: Result<Option<crate::perception::pipeline::ViewResult>, String>,
    depth_scan: Option<DepthScan>,
    gyro: Option<Stamped<[f64; 3]>>,
}

/// Runs until cancelled. `source` is the opened camera, `pipeline` built
/// on its calibration.
pub async fn run(
    mut camera: CameraLoop,
    mut source: Box<dyn CameraSource>,
    mut pipeline: Pipeline,
    mut io: PerceptionIo,
    clock: std::sync::Arc<dyn Clock>,
    cancel: CancellationToken,
) -> Result<(), String> {
    let base_from_camera: Isometry3<f64> = pipeline.calibration.base_from_camera;
    // the depth image's own camera in base_link
    let (depth_k, base_from_depth) = match pipeline.calibration.depth {
        Some((k, color_from_depth)) => (k, base_from_camera * color_from_depth),
        None => (pipeline.calibration.color, base_from_camera),
    };
    let depth_settings = camera.depth_obstacles;
    let mut words: Vec<String> = Vec::new();
    // the words the detector has now
    let mut active: Vec<String> = Vec::new();
    let mut tick = tokio::time::interval(camera.period);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut first = true;
    let inline = tokio::runtime::Handle::current().runtime_flavor()
        == tokio::runtime::RuntimeFlavor::CurrentThread;
    let mut failing_since: Option<crate::msg::Stamp> = None;
    let mut view_times = crate::actuation::DurationHistogram::with_bins(100e-6, 10_000);
    // the model run once before the first frame, so that the first word's
    // view does not wait for the runtime's start (on a GPU about 1.5 s); a
    // model that cannot run is a fault of the task, now rather than at
    // the first word
    let warm_up = move || {
        let took = pipeline.warm_up();
        (pipeline, took)
    };
    let (p, took) = blocking(inline, warm_up).await?;
    pipeline = p;
    match took {
        Ok(ms) => tracing::info!(
            detector = pipeline.detector.backend(),
            took_ms = ms,
            "perception: the detector's model warmed up"
        ),
        Err(e) => return Err(format!("perception: the detector cannot run: {e}")),
    }
    loop {
        tokio::select! {
            biased;
            _ = cancel.cancelled() => return Ok(()),
            _ = tick.tick() => {}
        }
        if io
            .prompts
            .has_changed()
            .map_err(|_| "the prompts' channel closed".to_string())?
        {
            words = io.prompts.borrow_and_update().clone();
        }
        // without a word the frame is still taken: the camera is checked
        // and its gyro read, but nothing is detected
        let look = !words.is_empty();
        let new_prompts = (look && words != active).then(|| words.clone());
        if let Some(w) = &new_prompts {
            active = w.clone();
        }
        let work = move || {
            let round = (|| {
                if let Some(prompts) = new_prompts {
                    if let Err(e) = pipeline.set_prompts(&prompts) {
                        tracing::warn!(error = %e, "perception: prompts not usable");
                    }
                }
                let frame = match source.next_frame() {
                    Ok(Some(f)) => f,
                    Ok(None) => return Round::Ended,
                    Err(e) => return Round::CameraError(e.to_string()),
                };
                let depth_scan = depth_settings.map(|s| {
                    depth_obstacles::scan(&frame.value.depth, &depth_k, &base_from_depth, &s)
                });
                let result = if look {
                    pipeline
                        .process(&frame.value.color, Some(&frame.value.depth))
                        .map(Some)
                        .map_err(|e| e.to_string())
                } else {
                    Ok(None)
                };
                Round::View(Box::new(ViewRound {
                    gyro: source.gyro(),
                    frame,
                    result,
                    depth_scan,
                }))
            })();
            (source, pipeline, round)
        };
        let (s, p, round) = blocking(inline, work).await?;
        source = s;
        pipeline = p;
        let now = clock.now();
        match round {
            Round::Ended => {
                // end of a recording: start it again
                source = (camera.open)().map_err(|e| format!("camera: cannot reopen: {e}"))?;
            }
            Round::CameraError(e) => {
                let since = *failing_since.get_or_insert(now);
                tracing::warn!(error = %e, "camera");
                if since.age_at(now) > CAMERA_GIVE_UP {
                    return Err(format!("camera: failing for {:?}: {e}", CAMERA_GIVE_UP));
                }
            }
            Round::View(round) => {
                let ViewRound {
                    frame,
                    result,
                    gyro,
                    depth_scan,
                } = *round;
                failing_since = None;
                if first {
                    first = false;
                    // the daemon may have finished waiting: nothing to tell
                    io.first_frame.send("camera").ok();
                }
                if let Some(g) = gyro {
                    let r = base_from_camera.rotation
                        * Vector3::new(g.value[0], g.value[1], g.value[2]);
                    io.gyro.send_replace(Some(Stamped::new(g.stamp, r.z)));
                }
                let stamp = if camera.restamp { now } else { frame.stamp };
                if let Some(scan) = depth_scan {
                    io.depth_scans
                        .send(Stamped::new(stamp, scan))
                        .await
                        .map_err(|_| "the estimation task is gone".to_string())?;
                }
                let view = match result {
                    Ok(Some(v)) => {
                        view_times.record(v.timing_ms.total / 1e3);
                        // a walk over the bins: microseconds, each view
                        io.view_time.send_replace(view_times.stats());
                        v
                    }
                    Ok(None) => continue,
                    Err(e) => {
                        tracing::warn!(error = %e, "perception");
                        continue;
                    }
                };
                crate::live::show(&io.live, || crate::live::LiveItem::View {
                    frame: Stamped::new(stamp, frame.value.clone()),
                    detections: view.detections.clone(),
                    objects: view.objects.clone(),
                });
                record(&io.record, || RecordItem::View {
                    frame: Stamped::new(stamp, frame.value),
                    detections: view.detections.clone(),
                    objects: view.objects.clone(),
                });
                // the simulator's stand-in for the compute time
                let age = stamp.age_at(clock.now());
                if camera.latency > age {
                    tokio::select! {
                        biased;
                        _ = cancel.cancelled() => return Ok(()),
                        _ = tokio::time::sleep(camera.latency - age) => {}
                    }
                }
                io.objects
                    .send(Stamped::new(stamp, view.objects))
                    .await
                    .map_err(|_| "the estimation task is gone".to_string())?;
            }
        }
    }
}

/// Perception's blocking work. A multi-threaded runtime (the chair, a
/// real-time simulation): on a blocking thread. The current-thread runtime
/// of a virtual-time simulation (`inline`): right here, so that nothing
/// else runs meanwhile and the run is deterministic (the clock stands
/// still either way). A blocking thread that died is an error naming it.
async fn blocking<T: Send + 'static>(
    inline: bool,
    work: impl FnOnce() -> T + Send + 'static,
) -> Result<T, String> {
    if inline {
        Ok(work())
    } else {
        tokio::task::spawn_blocking(work)
            .await
            .map_err(|e| format!("the perception thread failed: {e}"))
    }
}
