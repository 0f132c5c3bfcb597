//! `opennav run`: the daemon that ties the parts into one program.
//!
//! Tasks and channels (ARCHITECTURE.md): sensor sources publish their
//! latest value on `watch` channels; the estimation task fuses wheel
//! odometry and scan matching into the pose (with a history by stamp);
//! perception runs on its own OS thread, places each view's objects with
//! the pose at the frame's stamp and updates the tracker; the 20 Hz control
//! task runs the goal keeper, the planner and the safety supervisor and
//! publishes the supervisor's output; the actuator (R-Net writer or Rebus)
//! runs on its own thread. Prompts arrive on an `mpsc` channel (stdin
//! lines: a word, `stop`, `quit`). One cancellation token reaches every
//! task; shutdown stops the chair first (centred frames, then release),
//! then the sources. The systemd watchdog is fed by the control task only
//! while it is healthy.
//!
//! With `--sim` (or no hardware) the simulator stands in for the devices:
//! the chair in the living room, its power module and JSM on an in-memory
//! CAN bus driven by the real R-Net writer, lasers by ray casting, encoders
//! from the true motion, camera views rendered with the simulator's
//! detector feeding the real geometry pipeline.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use nalgebra::{Isometry3, Point3, Vector3};
use serde::Serialize;
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

use crate::actuation::can::MemoryBus;
use crate::actuation::rnet::TakeoverMode;
use crate::actuation::writer::RnetActuator;
use crate::actuation::{spawn_actuator_thread, ActuatorEvent, ActuatorIo, ActuatorStatus};
use crate::config::Settings;
use crate::estimation::ekf::PoseHistory;
use crate::estimation::fusion::Estimator;
use crate::estimation::goal::{GoalEvent, GoalKeeper, GoalState};
use crate::estimation::tracker::{Tracker, TrackerParams};
use crate::msg::Obstacles;
use crate::msg::Pose2;
use crate::msg::WheelTicks;
use crate::msg::{Clock, Frame, Stamp, Stamped, TokioClock};
use crate::msg::{FaultReason, SafeCmd, SupervisorState, VelocityCmd};
use crate::navigation::apf::ApfParams;
use crate::navigation::mpc::{MpcParams, UnicycleState};
use crate::navigation::planner::{Planner, PlannerStats};
use crate::perception::boxes::Object3D;
use crate::perception::pipeline::lift_detections;
use crate::perception::segmenter::DepthBoxSegmenter;
use crate::safety::{Supervisor, SupervisorInputs};
use crate::sensors::laser::merge_scans;
use crate::sim::rnet::{run_sim_chair, SimChair, SimChairSettings};
use crate::sim::world::{SimReport, SimWorld};

#[derive(Debug, Clone)]
pub struct RunOptions {
    /// Words said at start (as if typed), in order.
    pub prompts: Vec<String>,
    /// Read prompts from stdin, one per line.
    pub stdin_prompts: bool,
    /// Stop the daemon when the goal is reached (or lost).
    pub exit_on_arrival: bool,
    pub max_duration: Option<Duration>,
    /// Record the sensors and perception's output to this MCAP file.
    pub record: Option<std::path::PathBuf>,
}

/// What the recorder thread writes.
enum RecordItem {
    Scan(bool, Stamped<crate::msg::LaserScan>),
    Ticks(Stamped<WheelTicks>),
    View {
        frame: Stamped<crate::msg::RgbdFrame>,
        detections: Vec<crate::perception::detector::Detection>,
        objects: Vec<Object3D>,
    },
}

/// The recorder's side of the tasks: never blocks them; what it cannot
/// take is counted and logged.
struct RecordSink {
    tx: std::sync::mpsc::SyncSender<RecordItem>,
    dropped: std::sync::atomic::AtomicU64,
}

impl RecordSink {
    fn put(&self, item: RecordItem) {
        if self.tx.try_send(item).is_err() {
            let n = self
                .dropped
                .fetch_add(1, std::sync::atomic::Ordering::SeqCst)
                + 1;
            if n.is_power_of_two() {
                tracing::warn!(
                    dropped = n,
                    "recording: the writer falls behind; items dropped"
                );
            }
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct RecordReport {
    pub path: String,
    pub written: u64,
    pub dropped: u64,
    pub error: Option<String>,
}

/// The recorder thread: messages written, and the error that stopped it.
type RecorderThread = std::thread::JoinHandle<(u64, Option<String>)>;

/// Starts the recorder thread.
fn start_recorder(path: &std::path::Path) -> Result<(RecordSink, RecorderThread), DaemonError> {
    let mut rec =
        crate::record::Recorder::create(path).map_err(|e| DaemonError::Setup(e.to_string()))?;
    let (tx, rx) = std::sync::mpsc::sync_channel::<RecordItem>(512);
    let handle = std::thread::Builder::new()
        .name("recorder".into())
        .spawn(move || {
            let mut written = 0u64;
            let mut error = None;
            for item in rx {
                let r = match item {
                    RecordItem::Scan(left, s) => rec.scan(left, &s),
                    RecordItem::Ticks(t) => rec.ticks(&t),
                    RecordItem::View {
                        frame,
                        detections,
                        objects,
                    } => rec
                        .rgbd(&frame)
                        .and_then(|_| rec.detections(frame.stamp, &detections))
                        .and_then(|_| rec.objects(frame.stamp, &objects)),
                };
                match r {
                    Ok(()) => written += 1,
                    Err(e) => {
                        tracing::error!(error = %e, "recording stopped");
                        error = Some(e.to_string());
                        break;
                    }
                }
            }
            if let Err(e) = rec.finish() {
                error.get_or_insert(e.to_string());
            }
            (written, error)
        })
        .map_err(|e| DaemonError::Setup(format!("recorder thread: {e}")))?;
    Ok((
        RecordSink {
            tx,
            dropped: std::sync::atomic::AtomicU64::new(0),
        },
        handle,
    ))
}

/// What a user can say or press.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum UserInput {
    /// Go to an object of this word.
    Goto(String),
    /// Stop now (voice "stop", a switch).
    Stop,
    /// Quit the daemon.
    Quit,
}

impl UserInput {
    /// A line of text: `stop`/`halt` (also a bare switch press, an empty
    /// line), `quit`/`exit`, else a word to go to.
    pub fn parse(line: &str) -> UserInput {
        let w = line.trim().to_lowercase();
        match w.as_str() {
            "" | "stop" | "halt" | "switch" => UserInput::Stop,
            "quit" | "exit" => UserInput::Quit,
            _ => UserInput::Goto(w),
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct RunReport {
    /// "arrived", "lost", "not found", "stopped", "quit", "signal", "timeout".
    pub outcome: String,
    pub duration_s: f64,
    pub goal: GoalState,
    pub supervisor: SupervisorState,
    pub pose_odom: Pose2,
    pub planner: PlannerStats,
    pub actuator: ActuatorStatus,
    /// What the chair said, in order.
    pub said: Vec<String>,
    pub sim: Option<SimSummary>,
    pub record: Option<RecordReport>,
}

#[derive(Debug, Clone, Serialize)]
pub struct SimSummary {
    pub world: SimReport,
    /// Distance from the chair to the nearest object of the goal's word, m.
    pub distance_to_goal_object_m: Option<f64>,
    pub scan_matches: u64,
    /// Odometry steps whose heading used the gyro.
    pub gyro_fused: u64,
}

#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    #[error("{0}")]
    Setup(String),
}

/// Shared state the tasks publish.
struct Shared {
    history: Mutex<PoseHistory>,
    tracker: Mutex<Tracker>,
    world: Option<Arc<Mutex<SimWorld>>>,
    matches: std::sync::atomic::AtomicU64,
    gyro_fused: std::sync::atomic::AtomicU64,
    record: Mutex<Option<RecordSink>>,
}

impl Shared {
    fn record(&self, item: RecordItem) {
        if let Ok(r) = self.record.lock() {
            if let Some(sink) = r.as_ref() {
                sink.put(item);
            }
        }
    }

    /// Closes the sink (the recorder thread then finishes the file).
    fn close_record(&self) -> u64 {
        self.record
            .lock()
            .ok()
            .and_then(|mut r| r.take())
            .map(|s| s.dropped.load(std::sync::atomic::Ordering::SeqCst))
            .unwrap_or(0)
    }
}

/// Whether a point (odom) is in the camera's view with the chair at
/// `pose`: in front within 0.3–5 m, inside the horizontal (±45°) and
/// vertical (±29°) field of view of the simulator's camera.
fn camera_sees(pose: &Pose2, base_from_camera: &Isometry3<f64>, p: &[f64; 3]) -> bool {
    let odom_from_base = Isometry3::new(
        Vector3::new(pose.x_m, pose.y_m, 0.0),
        Vector3::z() * pose.theta_rad,
    );
    let q = (odom_from_base * base_from_camera).inverse() * Point3::new(p[0], p[1], p[2]);
    q.z > 0.3 && q.z < 5.0 && (q.x / q.z).abs() < 1.0 && (q.y / q.z).abs() < 0.56
}

/// sd_notify for the systemd watchdog (a no-op outside systemd).
fn sd_notify(msg: &str) {
    let Ok(path) = std::env::var("NOTIFY_SOCKET") else {
        return;
    };
    if let Ok(sock) = std::os::unix::net::UnixDatagram::unbound() {
        let _ = sock.send_to(msg.as_bytes(), path);
    }
}

/// Runs the daemon on the simulator until the options or `cancel` end it.
pub async fn run_sim(
    settings: &Settings,
    opts: RunOptions,
    cancel: CancellationToken,
) -> Result<RunReport, DaemonError> {
    let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
    let start = clock.now();
    let world = Arc::new(Mutex::new(SimWorld::living_room(settings.drive_params())));
    let (shared, recorder) = new_shared(Some(world.clone()), opts.record.as_deref())?;
    let sources = CancellationToken::new();

    // the chair's R-Net bus: JSM + power module, and the real writer
    let bus = MemoryBus::new();
    let chair = Arc::new(Mutex::new(SimChair::new(
        SimChairSettings::default(),
        clock.now(),
    )));
    tokio::spawn(run_sim_chair(
        bus.endpoint(),
        chair.clone(),
        clock.clone(),
        sources.clone(),
    ));
    let (cmd_tx, cmd_rx) = watch::channel::<Option<SafeCmd>>(None);
    let (act_ev_tx, act_ev_rx) = mpsc::channel(64);
    let (status_tx, status_rx) = watch::channel(ActuatorStatus::default());
    let writer_cancel = CancellationToken::new();
    let mut rnet = settings.rnet_settings();
    rnet.mode = TakeoverMode::JsmError;
    let endpoint = bus.endpoint();
    let writer = spawn_actuator_thread(
        "rnet-writer",
        50,
        move || {
            Ok(RnetActuator {
                bus: endpoint,
                settings: rnet,
            })
        },
        ActuatorIo {
            commands: cmd_rx,
            events: act_ev_tx,
            status: status_tx,
            cancel: writer_cancel.clone(),
            clock: clock.clone(),
        },
    )
    .map_err(|e| DaemonError::Setup(format!("actuator thread: {e}")))?;

    // the world: 100 Hz, driven by what the power module does
    let (ticks_tx, ticks_rx) = watch::channel::<Option<Stamped<WheelTicks>>>(None);
    let (obst_tx, obst_rx) = watch::channel::<Option<Stamped<Obstacles>>>(None);
    let (gyro_tx, gyro_rx) = watch::channel::<Option<Stamped<f64>>>(None);
    let mapping = settings.joystick_mapping();
    let lasers = [
        settings.lasers.left.base_from_laser(),
        settings.lasers.right.base_from_laser(),
    ];
    {
        let (world, chair, clock, cancel) =
            (world.clone(), chair.clone(), clock.clone(), sources.clone());
        let shared_w = shared.clone();
        tokio::spawn(async move {
            let mut tick = tokio::time::interval(Duration::from_millis(10));
            let mut k: u64 = 0;
            loop {
                tokio::select! {
                    _ = cancel.cancelled() => return,
                    _ = tick.tick() => {}
                }
                let now = clock.now();
                let motor = chair.lock().ok().and_then(|c| c.motor_output(now));
                let Ok(mut w) = world.lock() else { return };
                w.step(0.01, motor, &mapping);
                // the camera's IMU: the true yaw rate
                gyro_tx.send_replace(Some(Stamped::new(now, w.omega_radps)));
                let t = Stamped::new(now, w.wheel_ticks());
                shared_w.record(RecordItem::Ticks(t.clone()));
                ticks_tx.send_replace(Some(t));
                if k.is_multiple_of(10) {
                    let ms = (now.0.as_millis() & 0xFF_FFFF) as u32;
                    let l = Stamped::new(now, w.laser_scan(&lasers[0], ms));
                    let r = Stamped::new(now, w.laser_scan(&lasers[1], ms));
                    obst_tx.send_replace(merge_scans(&[(&l, &lasers[0]), (&r, &lasers[1])]));
                    shared_w.record(RecordItem::Scan(true, l));
                    shared_w.record(RecordItem::Scan(false, r));
                }
                k += 1;
            }
        });
    }

    let (pose_tx, pose_rx) = watch::channel::<Option<Stamped<(Pose2, f64, f64)>>>(None);
    spawn_estimation(
        settings,
        ticks_rx,
        obst_rx.clone(),
        gyro_rx,
        pose_tx,
        shared.clone(),
        sources.clone(),
    );
    let perception =
        spawn_sim_perception(settings, shared.clone(), clock.clone(), sources.clone())?;

    let (prompts_tx, _prompts_rx) = watch::channel(Vec::new());
    let report = control_loop(
        settings,
        &opts,
        ControlIo {
            prompts: prompts_tx,
            obstacles: obst_rx,
            pose: pose_rx,
            commands: cmd_tx,
            actuator_events: act_ev_rx,
            actuator_status: status_rx.clone(),
            shared: shared.clone(),
            clock: clock.clone(),
            cancel: cancel.clone(),
            start,
        },
    )
    .await;

    // shutdown: the chair first, then the sources
    writer_cancel.cancel();
    let actuator = join_actuator(writer, &status_rx).await;
    sources.cancel();
    let _ = tokio::task::spawn_blocking(move || perception.join()).await;
    let mut report = report;
    report.record = finish_recording(&shared, recorder).await;
    report.actuator = actuator;
    if let Ok(w) = world.lock() {
        let label = match &report.goal {
            GoalState::Tracking { label, .. }
            | GoalState::Holding { label, .. }
            | GoalState::Reached { label, .. }
            | GoalState::Searching { label } => Some(label.clone()),
            GoalState::None => opts.prompts.last().map(|p| p.to_lowercase()),
        };
        let dist = label.and_then(|l| w.nearest_object(&l)).and_then(|c| {
            w.room
                .objects
                .iter()
                .find(|o| {
                    (o.min_m[0] + o.max_m[0]) / 2.0 == c.x && (o.min_m[1] + o.max_m[1]) / 2.0 == c.y
                })
                .map(|o| {
                    let dx = (o.min_m[0] - w.truth.x_m)
                        .max(w.truth.x_m - o.max_m[0])
                        .max(0.0);
                    let dy = (o.min_m[1] - w.truth.y_m)
                        .max(w.truth.y_m - o.max_m[1])
                        .max(0.0);
                    dx.hypot(dy)
                })
        });
        report.sim = Some(SimSummary {
            world: w.report,
            distance_to_goal_object_m: dist,
            scan_matches: shared.matches.load(std::sync::atomic::Ordering::SeqCst),
            gyro_fused: shared.gyro_fused.load(std::sync::atomic::Ordering::SeqCst),
        });
    }
    Ok(report)
}

/// A recording in progress: its path and its writer thread.
type Recording = Option<(String, RecorderThread)>;

/// The tasks' shared state, and the recorder thread when recording.
fn new_shared(
    world: Option<Arc<Mutex<SimWorld>>>,
    record: Option<&std::path::Path>,
) -> Result<(Arc<Shared>, Recording), DaemonError> {
    let shared = Arc::new(Shared {
        history: Mutex::new(PoseHistory::new(400)),
        tracker: Mutex::new(Tracker::new(TrackerParams::default())),
        world,
        matches: std::sync::atomic::AtomicU64::new(0),
        gyro_fused: std::sync::atomic::AtomicU64::new(0),
        record: Mutex::new(None),
    });
    let recorder = match record {
        Some(p) => {
            let (sink, handle) = start_recorder(p)?;
            if let Ok(mut r) = shared.record.lock() {
                *r = Some(sink);
            }
            Some((p.display().to_string(), handle))
        }
        None => None,
    };
    Ok((shared, recorder))
}

/// Waits for the actuator thread (after its cancellation): its final
/// status, or the last one it published if it failed.
async fn join_actuator(
    writer: std::thread::JoinHandle<Result<ActuatorStatus, crate::actuation::ActuatorError>>,
    status: &watch::Receiver<ActuatorStatus>,
) -> ActuatorStatus {
    tokio::task::spawn_blocking(move || writer.join())
        .await
        .ok()
        .and_then(|r| r.ok())
        .and_then(|r| r.ok())
        .unwrap_or_else(|| status.borrow().clone())
}

/// Last in the shutdown order: the recording is flushed and closed.
async fn finish_recording(shared: &Shared, recorder: Recording) -> Option<RecordReport> {
    let (path, handle) = recorder?;
    let dropped = shared.close_record();
    let (written, error) = tokio::task::spawn_blocking(move || handle.join())
        .await
        .ok()
        .and_then(|r| r.ok())
        .unwrap_or((0, Some("recorder thread failed".into())));
    Some(RecordReport {
        path,
        written,
        dropped,
        error,
    })
}

/// Wheel odometry → EKF predict; merged scans → scan matching → EKF
/// correct. Publishes (pose, v, ω) and keeps the pose history.
fn spawn_estimation(
    settings: &Settings,
    mut ticks: watch::Receiver<Option<Stamped<WheelTicks>>>,
    mut obstacles: watch::Receiver<Option<Stamped<Obstacles>>>,
    mut gyro: watch::Receiver<Option<Stamped<f64>>>,
    pose_tx: watch::Sender<Option<Stamped<(Pose2, f64, f64)>>>,
    shared: Arc<Shared>,
    cancel: CancellationToken,
) {
    let mut est = Estimator::new(settings.drive_params());
    tokio::spawn(async move {
        // no camera, or one without an IMU: its sender goes away
        let mut gyro_open = true;
        loop {
            tokio::select! {
                _ = cancel.cancelled() => return,
                r = gyro.changed(), if gyro_open => {
                    if r.is_err() {
                        gyro_open = false;
                        continue;
                    }
                    if let Some(g) = gyro.borrow_and_update().clone() {
                        est.on_gyro(g);
                    }
                }
                r = ticks.changed() => {
                    if r.is_err() { return; }
                    let Some(t) = ticks.borrow_and_update().clone() else { continue };
                    let e = est.on_ticks(&t);
                    if let Ok(mut h) = shared.history.lock() {
                        h.push(t.stamp, e.pose);
                    }
                    pose_tx.send_replace(Some(Stamped::new(t.stamp, (e.pose, e.v_mps, e.omega_radps))));
                }
                r = obstacles.changed() => {
                    if r.is_err() { return; }
                    let Some(o) = obstacles.borrow_and_update().clone() else { continue };
                    let pts: Vec<[f64; 2]> = o.value.points_base.iter().map(|p| [p[0] as f64, p[1] as f64]).collect();
                    match est.on_scan(&pts) {
                        Some(Ok(_)) => {
                            shared.matches.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                        }
                        Some(Err(e)) => tracing::debug!(error = %e, "scan matching"),
                        None => {}
                    }
                    shared.gyro_fused.store(est.gyro_fused, std::sync::atomic::Ordering::SeqCst);
                }
            }
        }
    });
}

/// Perception on its own thread (2 Hz): the simulator's camera view, its
/// ground-truth boxes through the real geometry (depth segmentation,
/// erosion, z-score, back-projection), objects placed in odom with the
/// pose at the frame's stamp, into the tracker.
fn spawn_sim_perception(
    settings: &Settings,
    shared: Arc<Shared>,
    clock: Arc<dyn Clock>,
    cancel: CancellationToken,
) -> Result<std::thread::JoinHandle<()>, DaemonError> {
    let base_from_camera = settings
        .camera
        .base_from_camera
        .to_isometry("camera.base_from_camera")
        .map_err(|e| DaemonError::Setup(e.to_string()))?;
    let geometry = settings.geometry_settings();
    let mut segmenter = DepthBoxSegmenter::new(settings.depth_segmenter_settings());
    let cam = crate::sim::replica::camera(2);
    std::thread::Builder::new()
        .name("perception".into())
        .spawn(move || {
            let Some(world) = shared.world.clone() else {
                return;
            };
            let room = match world.lock() {
                Ok(w) => w.room.clone(),
                Err(_) => return,
            };
            let mut detector = crate::sim::replica::SimGtDetector::new(room, cam);
            let k = cam.intrinsics();
            while !cancel.is_cancelled() {
                let t0 = std::time::Instant::now();
                let stamp = clock.now();
                let (view, w_from_c) = {
                    let Ok(w) = world.lock() else { return };
                    let wfc = w.world_from_camera(&base_from_camera);
                    (w.render(&k, &base_from_camera), wfc)
                };
                let Ok(view) = view else { return };
                let rv = crate::eval::replica::ReplicaView {
                    index: 0,
                    color: view.color.clone(),
                    depth: view.depth.clone(),
                    world_from_camera: w_from_c,
                };
                use crate::eval::replica::ViewDetector;
                let dets = detector.detect_view(&rv).unwrap_or_default();
                let lifted = lift_detections(
                    &mut segmenter,
                    &view.color,
                    &view.depth,
                    dets.clone(),
                    &k,
                    &base_from_camera,
                    Frame::BaseLink,
                    &geometry,
                );
                if let Ok(v) = lifted {
                    shared.record(RecordItem::View {
                        frame: Stamped::new(
                            stamp,
                            crate::msg::RgbdFrame {
                                color: view.color.clone(),
                                depth: view.depth.clone(),
                                color_stamp: stamp,
                                depth_stamp: stamp,
                            },
                        ),
                        detections: dets,
                        objects: v.objects.clone(),
                    });
                    place_objects(&shared, stamp, v.objects, &base_from_camera, &cancel);
                }
                let spent = t0.elapsed();
                if spent < Duration::from_millis(500) {
                    std::thread::sleep(Duration::from_millis(500) - spent);
                }
            }
        })
        .map_err(|e| DaemonError::Setup(format!("perception thread: {e}")))
}

/// Turn rate while searching for the prompted object, rad/s.
const SEARCH_TURN_RADPS: f64 = 0.3;

#[derive(Debug, Default)]
struct SearchTurn {
    last_theta: Option<f64>,
    turned_rad: f64,
}

struct ControlIo {
    /// The words perception should look for (the goal's).
    prompts: watch::Sender<Vec<String>>,
    obstacles: watch::Receiver<Option<Stamped<Obstacles>>>,
    pose: watch::Receiver<Option<Stamped<(Pose2, f64, f64)>>>,
    commands: watch::Sender<Option<SafeCmd>>,
    actuator_events: mpsc::Receiver<ActuatorEvent>,
    actuator_status: watch::Receiver<ActuatorStatus>,
    shared: Arc<Shared>,
    clock: Arc<dyn Clock>,
    cancel: CancellationToken,
    start: Stamp,
}

/// The 20 Hz control task: user input, goal, planner, supervisor.
async fn control_loop(settings: &Settings, opts: &RunOptions, mut io: ControlIo) -> RunReport {
    let base_from_camera = settings
        .camera
        .base_from_camera
        .to_isometry("camera.base_from_camera")
        .unwrap_or_else(|_| Isometry3::identity());
    let mut supervisor = Supervisor::new(settings.safety_limits());
    let mut goal = GoalKeeper::new(settings.goal_settings());
    let mut planner = Planner::new(MpcParams::default(), ApfParams::default());
    let (input_tx, mut input_rx) = mpsc::channel::<UserInput>(16);
    for p in &opts.prompts {
        let _ = input_tx.try_send(UserInput::parse(p));
    }
    if opts.stdin_prompts {
        let tx = input_tx.clone();
        std::thread::spawn(move || {
            let stdin = std::io::stdin();
            let mut line = String::new();
            while stdin.read_line(&mut line).is_ok_and(|n| n > 0) {
                if tx.blocking_send(UserInput::parse(&line)).is_err() {
                    return;
                }
                line.clear();
            }
        });
    }
    let mut said: Vec<String> = Vec::new();
    let say = |said: &mut Vec<String>, s: String| {
        tracing::info!(say = %s, "opennav");
        eprintln!("opennav says: {s}");
        said.push(s);
    };
    let mut tick = tokio::time::interval(Duration::from_millis(50));
    let mut planner_cmd: Option<Stamped<VelocityCmd>> = None;
    let mut search = SearchTurn::default();
    let mut outcome = String::from("signal");
    sd_notify("READY=1");
    loop {
        tokio::select! {
            biased;
            _ = io.cancel.cancelled() => break,
            Some(input) = input_rx.recv() => match input {
                UserInput::Goto(word) => {
                    supervisor.resume();
                    goal.set_prompt(&word);
                    say(&mut said, format!("Looking for a {word}."));
                }
                UserInput::Stop => {
                    supervisor.user_stop();
                    goal.clear();
                    say(&mut said, "Stopped.".into());
                    if opts.exit_on_arrival {
                        outcome = "stopped".into();
                        break;
                    }
                }
                UserInput::Quit => {
                    outcome = "quit".into();
                    break;
                }
            },
            Some(ev) = io.actuator_events.recv() => match ev {
                ActuatorEvent::Fault { reason } => {
                    supervisor.can_fault(FaultReason::CanBus);
                    say(&mut said, format!("Motor interface fault: {reason}. Stopped."));
                }
                ActuatorEvent::UserDeflection { .. } => {
                    supervisor.user_takeover();
                    goal.clear();
                    say(&mut said, "You have the joystick.".into());
                }
                other => tracing::info!(event = ?other, "actuator"),
            },
            _ = tick.tick() => {
                let now = io.clock.now();
                if opts.max_duration.is_some_and(|m| now.0.saturating_sub(io.start.0) > m) {
                    outcome = "timeout".into();
                    break;
                }
                let obstacles = io.obstacles.borrow().clone();
                let pose = io.pose.borrow().clone();
                if let (Some(o), Some(p)) = (&obstacles, &pose) {
                    let (pose, v, w) = p.value;
                    let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
                    let obstacles_odom: Vec<[f64; 2]> = o.value.points_base.iter()
                        .map(|q| {
                            let (x, y) = (q[0] as f64, q[1] as f64);
                            [pose.x_m + c * x - s * y, pose.y_m + s * x + c * y]
                        })
                        .collect();
                    let event = match io.shared.tracker.lock() {
                        Ok(t) => goal.update(now, &t, pose, &obstacles_odom, &|p| {
                            camera_sees(&pose, &base_from_camera, p)
                        }),
                        Err(_) => None,
                    };
                    if let Some(e) = &event {
                        if let Ok(t) = io.shared.tracker.lock() {
                            tracing::debug!(
                                goal = ?goal.state(),
                                tracks = ?t.tracks().iter().map(|k| (k.id, k.last_seen.age_at(now), camera_sees(&pose, &base_from_camera, &k.center_m))).collect::<Vec<_>>(),
                                "goal event"
                            );
                        }
                        say(&mut said, e.say());
                    }
                    let wanted: Vec<String> = match goal.state() {
                        GoalState::Searching { label }
                        | GoalState::Tracking { label, .. }
                        | GoalState::Holding { label, .. } => vec![label.clone()],
                        _ => Vec::new(),
                    };
                    io.prompts.send_if_modified(|p| {
                        if *p != wanted {
                            *p = wanted;
                            true
                        } else {
                            false
                        }
                    });
                    // searching: turn slowly on the spot (one full turn at
                    // most) so the camera sweeps the room
                    let searching = matches!(goal.state(), GoalState::Searching { .. });
                    if searching {
                        if let Some(prev) = search.last_theta {
                            search.turned_rad += crate::msg::wrap_angle(pose.theta_rad - prev).abs();
                        }
                        search.last_theta = Some(pose.theta_rad);
                    } else {
                        search = SearchTurn::default();
                    }
                    if searching && search.turned_rad >= std::f64::consts::TAU {
                        if let GoalState::Searching { label } = goal.state() {
                            let label = label.clone();
                            say(&mut said, format!("I cannot find a {label} here. Stopped."));
                        }
                        goal.clear();
                        search = SearchTurn::default();
                        if opts.exit_on_arrival {
                            outcome = "not found".into();
                        }
                    }
                    match goal.state() {
                        GoalState::Tracking { .. } | GoalState::Searching { .. } => supervisor.goal_active(),
                        GoalState::Holding { .. } => supervisor.goal_holding(),
                        GoalState::None | GoalState::Reached { .. } => supervisor.goal_cleared(),
                    }
                    if let Some(a) = goal.approach() {
                        let out = planner.step(
                            UnicycleState { x_m: pose.x_m, y_m: pose.y_m, theta_rad: pose.theta_rad, v_mps: v, omega_radps: w },
                            [a.x_m, a.y_m],
                            &o.value,
                        );
                        planner_cmd = Some(Stamped::new(now, out.cmd));
                    } else if matches!(goal.state(), GoalState::Searching { .. }) {
                        planner_cmd = Some(Stamped::new(now, VelocityCmd { v_mps: 0.0, omega_radps: SEARCH_TURN_RADPS }));
                    } else {
                        planner_cmd = None;
                    }
                    if opts.exit_on_arrival {
                        match event {
                            Some(GoalEvent::Reached { .. }) => { outcome = "arrived".into(); }
                            Some(GoalEvent::Lost { .. }) => { outcome = "lost".into(); }
                            _ => {}
                        }
                    }
                }
                let out = supervisor.step(now, &SupervisorInputs {
                    obstacles: obstacles.as_ref(),
                    odometry_stamp: pose.as_ref().map(|p| p.stamp),
                    command: planner_cmd.as_ref(),
                });
                io.commands.send_replace(Some(out));
                // fed only while the loop runs and nothing is faulted
                if !matches!(out.state, SupervisorState::Fault(_)) {
                    sd_notify("WATCHDOG=1");
                }
                if outcome == "arrived" || outcome == "lost" || outcome == "not found" {
                    // let the centred command reach the chair before leaving
                    io.commands.send_replace(Some(SafeCmd { cmd: VelocityCmd::default(), state: out.state, stamp: now }));
                    break;
                }
            }
        }
    }
    sd_notify("STOPPING=1");
    let now = io.clock.now();
    let pose = io
        .pose
        .borrow()
        .as_ref()
        .map(|p| p.value.0)
        .unwrap_or_default();
    RunReport {
        outcome,
        duration_s: now.0.saturating_sub(io.start.0).as_secs_f64(),
        goal: goal.state().clone(),
        supervisor: supervisor.state(),
        pose_odom: pose,
        planner: planner.stats.clone(),
        actuator: io.actuator_status.borrow().clone(),
        said,
        sim: None,
        record: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn user_input_words() {
        assert_eq!(
            UserInput::parse(" Chair\n"),
            UserInput::Goto("chair".into())
        );
        assert_eq!(UserInput::parse("STOP"), UserInput::Stop);
        assert_eq!(
            UserInput::parse("\n"),
            UserInput::Stop,
            "a bare switch press stops"
        );
        assert_eq!(UserInput::parse("quit"), UserInput::Quit);
    }
}

/// Where the hardware daemon's camera frames come from.
#[derive(Debug, Clone)]
pub enum CameraChoice {
    /// A recording in the TUM RGB-D layout, replayed in a loop and stamped
    /// on arrival (for bench tests without a camera).
    Replay(std::path::PathBuf),
    /// The RealSense (cargo feature `realsense`).
    RealSense,
    /// No camera: the chair can be stopped and driven by nothing else;
    /// prompts are never answered.
    None,
}

/// Runs the daemon on the chair's devices from config: the two Hokuyos,
/// the encoder board, the camera and the configured motor interface.
pub async fn run_hardware(
    settings: &Settings,
    opts: RunOptions,
    camera: CameraChoice,
    perception: crate::perception::setup::PerceptionChoice,
    cancel: CancellationToken,
) -> Result<RunReport, DaemonError> {
    use crate::sensors::encoders::EncoderDriver;
    use crate::sensors::hokuyo::{HokuyoDriver, HokuyoSettings};
    use crate::sensors::task::{spawn_source, Step};

    let clock: Arc<dyn Clock> = Arc::new(TokioClock::new());
    let start = clock.now();
    let (shared, recorder) = new_shared(None, opts.record.as_deref())?;
    let sources = CancellationToken::new();

    // lasers: one reader thread each (reconnecting with back-off), merged
    // in the base frame whenever either delivers
    let mut laser_rx = Vec::new();
    let mut laser_tasks = Vec::new();
    for (side, l) in [
        ("left", &settings.lasers.left),
        ("right", &settings.lasers.right),
    ] {
        let mut driver = HokuyoDriver::new(HokuyoSettings::new(l.port.clone()), clock.clone());
        let port = l.port.clone();
        let mut backoff = Duration::from_millis(100);
        let task = spawn_source(
            &format!("laser-{side}"),
            sources.clone(),
            move || match driver.next_scan() {
                Ok(scan) => {
                    backoff = Duration::from_millis(100);
                    Step::Value(scan)
                }
                Err(e) => {
                    tracing::warn!(port = %port, error = %e, "laser: retrying in {backoff:?}");
                    std::thread::sleep(backoff);
                    backoff = (backoff * 2).min(Duration::from_secs(2));
                    Step::Retry
                }
            },
        )
        .map_err(|e| DaemonError::Setup(format!("laser {side}: {e}")))?;
        laser_rx.push(task.latest.clone());
        laser_tasks.push(task);
    }
    let (obst_tx, obst_rx) = watch::channel::<Option<Stamped<Obstacles>>>(None);
    {
        let poses = [
            settings.lasers.left.base_from_laser(),
            settings.lasers.right.base_from_laser(),
        ];
        let (mut left, mut right) = (laser_rx[0].clone(), laser_rx[1].clone());
        let shared_l = shared.clone();
        let cancel = sources.clone();
        tokio::spawn(async move {
            loop {
                let changed_left = tokio::select! {
                    _ = cancel.cancelled() => return,
                    r = left.changed() => if r.is_err() { return } else { true },
                    r = right.changed() => if r.is_err() { return } else { false },
                };
                let (l, r) = (
                    left.borrow_and_update().clone(),
                    right.borrow_and_update().clone(),
                );
                match (changed_left, &l, &r) {
                    (true, Some(s), _) => shared_l.record(RecordItem::Scan(true, s.clone())),
                    (false, _, Some(s)) => shared_l.record(RecordItem::Scan(false, s.clone())),
                    _ => {}
                }
                // both scanners or none: the merged stamp is the older one,
                // so a dead scanner makes the set stale and the chair stops
                if let (Some(l), Some(r)) = (l, r) {
                    obst_tx.send_replace(merge_scans(&[(&l, &poses[0]), (&r, &poses[1])]));
                }
            }
        });
    }

    // the encoder board
    let enc_port = settings.encoders.port.clone();
    let mut enc = EncoderDriver::new(enc_port.clone(), clock.clone())
        .with_timeout(Duration::from_millis(200));
    let enc_task = spawn_source("encoders", sources.clone(), move || {
        match enc.next_ticks() {
            Ok(t) => Step::Value(t),
            Err(e) => {
                tracing::warn!(port = %enc_port, error = %e, "encoders: retrying");
                std::thread::sleep(Duration::from_millis(100));
                Step::Retry
            }
        }
    })
    .map_err(|e| DaemonError::Setup(format!("encoders: {e}")))?;
    let (ticks_tx, ticks_rx) = watch::channel::<Option<Stamped<WheelTicks>>>(None);
    {
        let mut rx = enc_task.latest.clone();
        let shared_t = shared.clone();
        let cancel = sources.clone();
        tokio::spawn(async move {
            loop {
                tokio::select! {
                    _ = cancel.cancelled() => return,
                    r = rx.changed() => if r.is_err() { return },
                }
                let v = rx.borrow_and_update().clone();
                if let Some(t) = &v {
                    shared_t.record(RecordItem::Ticks(t.clone()));
                }
                ticks_tx.send_replace(v);
            }
        });
    }

    // the motor interface
    let (cmd_tx, cmd_rx) = watch::channel::<Option<SafeCmd>>(None);
    let (act_ev_tx, act_ev_rx) = mpsc::channel(64);
    let (status_tx, status_rx) = watch::channel(ActuatorStatus::default());
    let writer_cancel = CancellationToken::new();
    let io = ActuatorIo {
        commands: cmd_rx,
        events: act_ev_tx,
        status: status_tx,
        cancel: writer_cancel.clone(),
        clock: clock.clone(),
    };
    let writer = match settings.actuation.backend {
        crate::config::ActuationBackend::Rnet => {
            let iface = settings.actuation.rnet.iface.clone();
            let rnet = settings.rnet_settings();
            spawn_actuator_thread(
                "rnet-writer",
                50,
                move || {
                    Ok(RnetActuator {
                        bus: crate::actuation::can::SocketCanBus::open(&iface)?,
                        settings: rnet,
                    })
                },
                io,
            )
        }
        crate::config::ActuationBackend::Rebus => {
            let port = settings.actuation.rebus.port.clone();
            let mut rebus =
                crate::actuation::rebus_link::RebusSettings::new(settings.joystick_mapping());
            rebus.ack_timeout = Duration::from_secs_f64(settings.actuation.rebus.ack_timeout_s);
            rebus.command_max_age = Duration::from_secs_f64(settings.actuation.command_max_age_s);
            rebus.release_after = Duration::from_secs_f64(settings.actuation.release_s);
            spawn_actuator_thread(
                "rebus",
                50,
                move || {
                    Ok(crate::actuation::rebus_link::RebusActuator {
                        port,
                        settings: rebus,
                    })
                },
                io,
            )
        }
    }
    .map_err(|e| DaemonError::Setup(format!("actuator thread: {e}")))?;

    let (pose_tx, pose_rx) = watch::channel::<Option<Stamped<(Pose2, f64, f64)>>>(None);
    let (gyro_tx, gyro_rx) = watch::channel::<Option<Stamped<f64>>>(None);
    spawn_estimation(
        settings,
        ticks_rx,
        obst_rx.clone(),
        gyro_rx,
        pose_tx,
        shared.clone(),
        sources.clone(),
    );
    let (prompts_tx, prompts_rx) = watch::channel(Vec::new());
    let perception_thread = spawn_camera_perception(
        settings,
        camera,
        perception,
        PerceptionIo {
            prompts: prompts_rx,
            gyro: gyro_tx,
            shared: shared.clone(),
            clock: clock.clone(),
            cancel: sources.clone(),
        },
    )?;

    let mut report = control_loop(
        settings,
        &opts,
        ControlIo {
            prompts: prompts_tx,
            obstacles: obst_rx,
            pose: pose_rx,
            commands: cmd_tx,
            actuator_events: act_ev_rx,
            actuator_status: status_rx.clone(),
            shared: shared.clone(),
            clock: clock.clone(),
            cancel: cancel.clone(),
            start,
        },
    )
    .await;

    // shutdown: the chair first (centred, then released), then the devices
    writer_cancel.cancel();
    report.actuator = join_actuator(writer, &status_rx).await;
    sources.cancel();
    let _ = tokio::task::spawn_blocking(move || {
        if let Some(t) = perception_thread {
            let _ = t.join();
        }
        for t in laser_tasks {
            t.join();
        }
        enc_task.join();
    })
    .await;
    report.record = finish_recording(&shared, recorder).await;
    Ok(report)
}

/// Perception on its own thread over a real camera source and the
/// configured detector and segmenter; the goal's word comes from the
/// control task.
/// The perception thread's channels.
struct PerceptionIo {
    /// The goal's words, from the control task.
    prompts: watch::Receiver<Vec<String>>,
    /// The camera IMU's yaw rate about base z, to the estimation task.
    gyro: watch::Sender<Option<Stamped<f64>>>,
    shared: Arc<Shared>,
    clock: Arc<dyn Clock>,
    cancel: CancellationToken,
}

fn spawn_camera_perception(
    settings: &Settings,
    camera: CameraChoice,
    choice: crate::perception::setup::PerceptionChoice,
    io: PerceptionIo,
) -> Result<Option<std::thread::JoinHandle<()>>, DaemonError> {
    let PerceptionIo {
        mut prompts,
        gyro: gyro_tx,
        shared,
        clock,
        cancel,
    } = io;
    use crate::perception::pipeline::Pipeline;
    use crate::sensors::camera::{CameraSource, ReplaySource};
    let base_from_camera = settings
        .camera
        .base_from_camera
        .to_isometry("camera.base_from_camera")
        .map_err(|e| DaemonError::Setup(e.to_string()))?;
    let restamp = matches!(camera, CameraChoice::Replay(_));
    let stamp_clock = clock.clone();
    let replay_dir = match camera {
        CameraChoice::None => return Ok(None),
        CameraChoice::Replay(d) => Some(d),
        CameraChoice::RealSense => None,
    };
    let open_camera = move || -> Result<Box<dyn CameraSource>, DaemonError> {
        match &replay_dir {
            Some(d) => Ok(Box::new(
                ReplaySource::open(d).map_err(|e| DaemonError::Setup(e.to_string()))?,
            )),
            None => open_realsense(base_from_camera, clock.clone()),
        }
    };
    let mut source = open_camera()?;
    let mut calibration = source.calibration().clone();
    calibration.base_from_camera = base_from_camera;
    let detector = crate::perception::setup::open_configured_detector(settings, &choice)
        .map_err(|e| DaemonError::Setup(e.to_string()))?;
    let segmenter = crate::perception::setup::open_configured_segmenter(settings, &choice)
        .map_err(|e| DaemonError::Setup(e.to_string()))?;
    let mut pipeline = Pipeline::new(
        detector,
        segmenter,
        calibration,
        settings.geometry_settings(),
    );
    let handle = std::thread::Builder::new()
        .name("perception".into())
        .spawn(move || {
            let mut words: Vec<String> = Vec::new();
            while !cancel.is_cancelled() {
                if prompts.has_changed().unwrap_or(false) {
                    words = prompts.borrow_and_update().clone();
                    if !words.is_empty() {
                        if let Err(e) = pipeline.set_prompts(&words) {
                            tracing::warn!(error = %e, "perception: prompts not usable");
                        }
                    }
                }
                if words.is_empty() {
                    std::thread::sleep(Duration::from_millis(50));
                    continue;
                }
                let frame = match source.next_frame() {
                    Ok(Some(f)) => f,
                    Ok(None) => {
                        // end of a recording: start it again
                        match open_camera() {
                            Ok(s) => source = s,
                            Err(e) => {
                                tracing::error!(error = %e, "camera: cannot reopen");
                                return;
                            }
                        }
                        continue;
                    }
                    Err(e) => {
                        tracing::warn!(error = %e, "camera");
                        std::thread::sleep(Duration::from_millis(100));
                        continue;
                    }
                };
                // the camera's gyro: the yaw rate about base_link's z
                if let Some(g) = source.gyro() {
                    let r = base_from_camera.rotation
                        * Vector3::new(g.value[0], g.value[1], g.value[2]);
                    gyro_tx.send_replace(Some(Stamped::new(g.stamp, r.z)));
                }
                // a replayed frame is stamped on arrival; a live one keeps
                // its acquisition stamp
                let stamp = if restamp {
                    stamp_clock.now()
                } else {
                    frame.stamp
                };
                let view = match pipeline.process(&frame.value.color, Some(&frame.value.depth)) {
                    Ok(v) => v,
                    Err(e) => {
                        tracing::warn!(error = %e, "perception");
                        continue;
                    }
                };
                shared.record(RecordItem::View {
                    frame: Stamped::new(stamp, frame.value.clone()),
                    detections: view.detections.clone(),
                    objects: view.objects.clone(),
                });
                place_objects(&shared, stamp, view.objects, &base_from_camera, &cancel);
            }
        })
        .map_err(|e| DaemonError::Setup(format!("perception thread: {e}")))?;
    Ok(Some(handle))
}

/// Objects in base_link at `stamp` → odom with the pose at that stamp →
/// the tracker.
fn place_objects(
    shared: &Shared,
    stamp: Stamp,
    objects: Vec<Object3D>,
    base_from_camera: &Isometry3<f64>,
    cancel: &CancellationToken,
) {
    let mut pose = None;
    for _ in 0..20 {
        pose = shared.history.lock().ok().and_then(|h| h.pose_at(stamp));
        if pose.is_some() || cancel.is_cancelled() {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let Some(pose) = pose else {
        tracing::info!(
            "perception: no pose at the frame's stamp yet (odometry starting?); view skipped"
        );
        return;
    };
    let odom_from_base = Isometry3::new(
        Vector3::new(pose.x_m, pose.y_m, 0.0),
        Vector3::z() * pose.theta_rad,
    );
    let objects: Vec<Object3D> = objects
        .into_iter()
        .filter_map(|o| {
            let pts: Vec<Point3<f32>> = o
                .points
                .iter()
                .map(|p| (odom_from_base * p.cast::<f64>()).cast::<f32>())
                .collect();
            Object3D::from_points(o.label, o.score, Frame::Odom, pts, o.box_xyxy)
        })
        .collect();
    let visible = |p: &[f64; 3]| camera_sees(&pose, base_from_camera, p);
    if let Ok(mut t) = shared.tracker.lock() {
        t.update(stamp, &objects, visible);
        tracing::debug!(
            objects = ?objects.iter().map(|o| (o.label.as_str(), o.aabb.center_m())).collect::<Vec<_>>(),
            tracks = ?t.tracks().iter().map(|k| (k.id, k.label.as_str(), k.center_m, k.confirmed, k.confidence)).collect::<Vec<_>>(),
            "perception"
        );
    }
}

#[cfg(feature = "realsense")]
fn open_realsense(
    base_from_camera: Isometry3<f64>,
    clock: Arc<dyn Clock>,
) -> Result<Box<dyn crate::sensors::camera::CameraSource>, DaemonError> {
    use crate::sensors::camera::realsense::{RealSenseSettings, RealSenseSource};
    Ok(Box::new(
        RealSenseSource::open(RealSenseSettings::default(), base_from_camera, clock)
            .map_err(|e| DaemonError::Setup(e.to_string()))?,
    ))
}

#[cfg(not(feature = "realsense"))]
fn open_realsense(
    _base_from_camera: Isometry3<f64>,
    _clock: Arc<dyn Clock>,
) -> Result<Box<dyn crate::sensors::camera::CameraSource>, DaemonError> {
    Err(DaemonError::Setup(
        "no camera: this build has no RealSense support (build with --features realsense), \
         and no --camera-replay DIR was given (or run with --no-camera)"
            .into(),
    ))
}
