//! `opennav run`: the daemon. This folder only wires: a [`Devices`]
//! bundle (the chair's, from config by [`chair`]; or the simulator's, from
//! `sim::devices`) → tasks → channels, the same code for both, on the
//! clock it is given (the monotonic clock on the chair, tokio's paused
//! clock for a virtual-time simulation).
//!
//! Tasks (each owns its state; values move on channels):
//! - `laser-left`, `laser-right`, `encoders`, `gyro`: the sources'
//!   readings onto `watch` channels (and the recording); `lasers` merges
//!   the two scans into obstacles in `base_link`;
//! - `estimation` ([`estimation`]): odometry, gyro and scan matching into
//!   the EKF; publishes [`Odometry`]; places perception's objects with the
//!   pose at their stamp and owns the tracker;
//! - `perception` ([`perception`]): the camera's newest frame through the
//!   pipeline for the words the goal wants, on a blocking thread;
//! - `control` ([`control`]): 20 Hz — user input, goal keeper, planner,
//!   supervisor; its output goes to the actuator; it feeds the watchdog
//!   and tells systemd READY once every device has delivered;
//! - `actuator`: the R-Net writer (or the Rebus link) at its own cadence.
//!
//! Health: a task that panics, fails or ends on its own is a fault — the
//! control step outputs zero with a latched fault, the watchdog is no
//! longer fed, the chair is centred and released, and the run ends with
//! [`Outcome::Fault`] naming the task (the command line exits 1).
//! Shutdown order: the chair first (centred frames, then release), then the
//! devices, then the recording.

pub mod backoff;
pub mod chair;
pub mod control;
pub mod control_task;
pub mod devices;
pub mod estimation;
pub mod latch;
pub mod lock;
pub mod notify;
pub mod perception;
pub mod recorder;
pub mod route;
mod tasks;

use std::collections::BTreeSet;
use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;
use tokio::sync::{mpsc, watch};
use tokio_util::sync::CancellationToken;

use crate::actuation::{ActuatorIo, ActuatorStatus};
use crate::config::Settings;
use crate::estimation::fusion::Estimator;
use crate::estimation::goal::{GoalKeeper, GoalState};
use crate::estimation::obstacle_map::FootprintM;
use crate::estimation::tracker::Tracker;
use crate::estimation::view::CameraView;
use crate::msg::{
    Clock, LaserScan, MapObstacles, Obstacles, Odometry, SafeCmd, Stamped, SupervisorState,
    UserInput, WheelTicks,
};
use crate::navigation::planner::{Planner, PlannerStats};
use crate::perception::depth_obstacles::DepthScan;
use crate::perception::pipeline::Pipeline;
use crate::safety::Supervisor;
use crate::sensors::laser::merge_scans;

pub use control::{Control, ControlInputs, ControlOutput, Outcome};
use control_task::ControlEnd;
pub use devices::{CameraDevice, DeviceError, Devices, Source, WatchSource};
pub use estimation::EstimationStats;
pub use notify::sd_notify;
pub use recorder::RecordReport;
use recorder::{RecordItem, RecordSink, Recorder};
pub use tasks::panic_message;
use tasks::{injected_panic_after, panic_after, Tasks};

#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// End the run when the goal is reached, lost or not found.
    pub exit_on_arrival: bool,
    pub max_duration: Option<Duration>,
    /// Record the sensors and perception's output to this MCAP file.
    pub record: Option<std::path::PathBuf>,
    /// What the chair says goes here too, as it is said (the command line
    /// prints it; the voice output will speak it).
    pub speech: Option<mpsc::UnboundedSender<String>>,
    /// Where a latched fault is kept across restarts (the chair); None:
    /// nowhere (the simulator).
    pub state_dir: Option<std::path::PathBuf>,
    /// Fault-injection tests: this task panics after this long.
    pub inject_panic: Option<(String, Duration)>,
    /// Stops from the input hub (each change one stop, never queued).
    pub stops: Option<watch::Receiver<u64>>,
    /// Where the daemon publishes what it is doing (the control socket).
    pub status: Option<watch::Sender<crate::input::DaemonStatus>>,
    /// Stream the live view (Foxglove WebSocket) on this address.
    pub live: Option<std::net::SocketAddr>,
    /// The live view's address once it listens (port 0 in `live`: the port
    /// it got), for a client that waits for it.
    pub live_started: Option<std::sync::mpsc::Sender<std::net::SocketAddr>>,
    /// Start only once a viewer subscribed to every topic (at most this
    /// long): a trip on the virtual clock is over in seconds.
    pub live_wait: Option<Duration>,
    /// The configuration as given (file text and overrides), kept in a
    /// recording's metadata.
    pub config_text: Option<String>,
    /// Other consumers of the live items (the ROS 2 bridge).
    pub viewers: Option<crate::live::LiveSink>,
}

#[derive(Debug, Clone, Serialize)]
pub struct RunReport {
    pub outcome: Outcome,
    pub duration_s: f64,
    pub goal: GoalState,
    pub supervisor: SupervisorState,
    /// The last odometry (None: the wheels never reported).
    pub odometry: Option<Odometry>,
    pub planner: PlannerStats,
    /// Stops on the way (see `Supervisor::stops`).
    pub stops: u64,
    /// Doorways passed or given up, back-offs when held.
    pub navigation: control::NavigationStats,
    pub estimation: EstimationStats,
    pub actuator: ActuatorStatus,
    /// What the chair said, in order.
    pub said: Vec<String>,
    pub record: Option<RecordReport>,
    pub live: Option<crate::live::LiveReport>,
    /// The control steps' period and duration.
    pub control: control_task::ControlTiming,
    /// Each view's compute time (registration, detector, masks, geometry);
    /// beside `actuator.frame_to_command`.
    pub view_time: crate::actuation::PeriodStats,
    /// The daemon's resident memory at the end and at its peak.
    pub memory: Option<crate::memory::MemoryUse>,
}

#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    #[error("{0}")]
    Setup(String),
}

/// A task of the daemon: its name and the error that ended it.
type TaskResult = Result<(), String>;

/// The control step from config.
fn new_control(settings: &Settings, view: Option<CameraView>, exit_on_arrival: bool) -> Control {
    let mut control = Control::new(
        Supervisor::new(settings.safety_limits()),
        GoalKeeper::new(settings.goal_settings()),
        Planner::new(settings.mpc, settings.field),
        view,
        exit_on_arrival,
    )
    .with_map(settings.map);
    // without a goal perception looks for every word a person may ask
    // for: the switch menu offers what is around
    control.idle_words = settings.voice.vocabulary.clone();
    control
}

/// Where a source's readings are recorded, and as what.
type RecordAs<T> = Option<(RecordSink, fn(Stamped<T>) -> RecordItem)>;

/// A source's readings onto a watch channel; the first one is announced
/// (READY waits for it).
async fn pump<T: Clone + Send + Sync + 'static>(
    mut source: Box<dyn Source<T>>,
    tx: watch::Sender<Option<Stamped<T>>>,
    first: mpsc::UnboundedSender<&'static str>,
    label: &'static str,
    rec: RecordAs<T>,
    cancel: CancellationToken,
) -> TaskResult {
    let mut announced = false;
    loop {
        let v = tokio::select! {
            biased;
            _ = cancel.cancelled() => return Ok(()),
            v = source.next() => v.map_err(|e| e.to_string())?,
        };
        if !announced {
            announced = true;
            // the control task gone: nobody waits for READY any more
            first.send(label).ok();
        }
        if let Some((sink, item)) = &rec {
            sink.put(item(v.clone()));
        }
        tx.send_replace(Some(v));
    }
}

/// Runs the daemon on `devices` until the user quits, the trip ends (with
/// `exit_on_arrival`), `shutdown` is cancelled or a task fails.
pub async fn run(
    devices: Devices,
    settings: &Settings,
    opts: RunOptions,
    inputs: mpsc::Receiver<UserInput>,
    clock: Arc<dyn Clock>,
    shutdown: CancellationToken,
) -> Result<RunReport, DaemonError> {
    let start = clock.now();
    let Devices {
        lasers,
        wheels,
        gyro,
        camera,
        actuator,
        background,
        stop: devices_stop,
        close,
    } = devices;
    let base_from_camera = settings
        .camera
        .base_from_camera
        .to_isometry("camera.base_from_camera")
        .map_err(|e| DaemonError::Setup(e.to_string()))?;
    let mounting = crate::live::Mounting {
        laser_left: lasers[0].1,
        laser_right: lasers[1].1,
        camera: base_from_camera,
    };
    // stamps are the run's clock: wall time = stamp + offset
    let offset = crate::live::wall_offset(start);
    let (recorder, sink) = match &opts.record {
        Some(p) => {
            let info = crate::record::RecordingInfo {
                wall_minus_monotonic_ns: offset.as_nanos() as u64,
                config: opts.config_text.clone().unwrap_or_default(),
                mounting: Some(mounting),
            };
            let (r, s) = Recorder::start(p, &info).map_err(DaemonError::Setup)?;
            (Some(r), Some(s))
        }
        None => (None, None),
    };
    let (live, live_sink) = match opts.live {
        Some(address) => {
            let (started, wait) = (opts.live_started.clone(), opts.live_wait);
            let (l, s) = tokio::task::spawn_blocking(move || {
                crate::live::Live::start(address, mounting, offset, started.as_ref(), wait)
            })
            .await
            .map_err(|e| DaemonError::Setup(format!("live view: {e}")))?
            .map_err(DaemonError::Setup)?;
            (Some(l), Some(s))
        }
        None => (None, None),
    };
    let live_sink = match (live_sink, opts.viewers.clone()) {
        (Some(a), Some(b)) => Some(a.and(b)),
        (a, b) => a.or(b),
    };
    crate::live::show(&live_sink, || crate::live::LiveItem::Start {
        mounting,
        wall_offset: offset,
    });
    let sources = CancellationToken::new();
    let mut tasks = Tasks::new(opts.inject_panic.clone());
    let (first_tx, first_rx) = mpsc::unbounded_channel::<&'static str>();
    let mut waiting: BTreeSet<&'static str> = BTreeSet::new();

    // device-side tasks (the simulated world and chair)
    for (name, fut) in background {
        tasks.spawn(&name, async move { fut.await.map_err(|e| e.to_string()) });
    }

    // the lasers, then their merge into obstacles in base_link
    let [(left_source, left_pose), (right_source, right_pose)] = lasers;
    let mut laser =
        |label: &'static str, source, to_record: fn(Stamped<LaserScan>) -> RecordItem| {
            let (tx, rx) = watch::channel::<Option<Stamped<LaserScan>>>(None);
            waiting.insert(label);
            tasks.spawn(
                label,
                pump(
                    source,
                    tx,
                    first_tx.clone(),
                    label,
                    sink.clone().map(|s| (s, to_record)),
                    sources.clone(),
                ),
            );
            rx
        };
    let mut left = laser("laser-left", left_source, |s| RecordItem::Scan(true, s));
    let mut right = laser("laser-right", right_source, |s| RecordItem::Scan(false, s));
    let (obst_tx, obst_rx) = watch::channel::<Option<Stamped<Obstacles>>>(None);
    {
        let poses = [left_pose, right_pose];
        let cancel = sources.clone();
        let live = live_sink.clone();
        tasks.spawn("lasers", async move {
            loop {
                tokio::select! {
                    biased;
                    _ = cancel.cancelled() => return Ok(()),
                    r = left.changed() => r.map_err(|_| "the left laser's channel closed")?,
                    r = right.changed() => r.map_err(|_| "the right laser's channel closed")?,
                }
                let (l, r) = (
                    left.borrow_and_update().clone(),
                    right.borrow_and_update().clone(),
                );
                // both scanners or none: the merged stamp is the older one,
                // so a dead scanner makes the set stale and the chair stops
                if let (Some(l), Some(r)) = (l, r) {
                    obst_tx.send_replace(merge_scans(&[(&l, &poses[0]), (&r, &poses[1])]));
                    crate::live::show(&live, || crate::live::LiveItem::Scans {
                        left: l.clone(),
                        right: r.clone(),
                    });
                }
            }
        });
    }

    // the wheels and the gyro
    let (ticks_tx, ticks_rx) = watch::channel::<Option<Stamped<WheelTicks>>>(None);
    waiting.insert("encoders");
    tasks.spawn(
        "encoders",
        pump(
            wheels,
            ticks_tx,
            first_tx.clone(),
            "encoders",
            sink.clone().map(|s| (s, RecordItem::Ticks as fn(_) -> _)),
            sources.clone(),
        ),
    );
    let (gyro_tx, gyro_rx) = watch::channel::<Option<Stamped<f64>>>(None);
    let camera_gyro = match gyro {
        Some(g) => {
            tasks.spawn(
                "gyro",
                pump(g, gyro_tx, first_tx.clone(), "gyro", None, sources.clone()),
            );
            // the camera's IMU, if any, goes nowhere: one yaw-rate source
            watch::channel(None).0
        }
        None => gyro_tx,
    };

    // the motor interface
    let (cmd_tx, cmd_rx) = watch::channel::<Option<SafeCmd>>(None);
    let (act_ev_tx, act_ev_rx) = mpsc::channel(64);
    let (status_tx, status_rx) = watch::channel(ActuatorStatus::default());
    let (view_time_tx, view_time_rx) = watch::channel(crate::actuation::PeriodStats::default());
    let writer_cancel = CancellationToken::new();
    let actuator_run = actuator(ActuatorIo {
        commands: cmd_rx,
        events: act_ev_tx,
        status: status_tx,
        cancel: writer_cancel.clone(),
        clock: clock.clone(),
    })
    .map_err(|e| DaemonError::Setup(e.to_string()))?;
    let mut actuator_task = tokio::spawn(actuator_run);
    waiting.insert("motors");

    // perception and estimation
    let (objects_tx, objects_rx) = mpsc::channel::<Stamped<Vec<crate::msg::Object3D>>>(4);
    let (prompts_tx, prompts_rx) = watch::channel::<Vec<String>>(Vec::new());
    let (scans_tx, scans_rx) = mpsc::channel::<Stamped<DepthScan>>(4);
    let depth_obstacles = settings.depth_obstacles.enabled.then_some(
        crate::perception::depth_obstacles::DepthObstacleSettings {
            chair_front_m: Some(settings.safety.front_offset_m),
            ..settings.depth_obstacles
        },
    );
    let view = match camera {
        Some(CameraDevice {
            mut open,
            detector,
            segmenter,
            restamp,
            period,
            latency,
        }) => {
            let (open_back, source) = tokio::task::spawn_blocking(move || {
                let s = open();
                (open, s)
            })
            .await
            .map_err(|e| DaemonError::Setup(format!("camera: {e}")))?;
            let source = source.map_err(|e| DaemonError::Setup(format!("camera: {e}")))?;
            let mut calibration = source.calibration().clone();
            calibration.base_from_camera = base_from_camera;
            // the chair's base_link stands on the floor ([camera], the
            // lasers and the depth obstacles all take z = 0 as the floor)
            calibration.floor_z_m = Some(0.0);
            recorder::record(&sink, || {
                RecordItem::Calibration(
                    clock.now(),
                    Box::new(crate::msg::calibration::CalibrationFile::of(
                        &calibration,
                        Some("the camera, as the run used it".into()),
                    )),
                )
            });
            let view = CameraView::from_calibration(&calibration);
            let cam = perception::CameraLoop {
                open: open_back,
                restamp,
                period,
                latency,
                depth_obstacles,
            };
            let pipeline = Pipeline::new(
                detector,
                segmenter,
                calibration,
                settings.geometry_settings(),
            );
            waiting.insert("camera");
            tasks.spawn(
                "perception",
                perception::run(
                    cam,
                    source,
                    pipeline,
                    perception::PerceptionIo {
                        prompts: prompts_rx,
                        objects: objects_tx,
                        depth_scans: scans_tx,
                        gyro: camera_gyro,
                        first_frame: first_tx.clone(),
                        record: sink.clone(),
                        live: live_sink.clone(),
                        view_time: view_time_tx.clone(),
                    },
                    clock.clone(),
                    sources.clone(),
                ),
            );
            Some(view)
        }
        None => {
            drop((objects_tx, scans_tx, prompts_rx, camera_gyro));
            None
        }
    };
    // obstacles from the depth camera: only with a camera and when enabled
    let depth_map = depth_obstacles.filter(|_| view.is_some());
    let (odo_tx, odo_rx) = watch::channel::<Option<Stamped<Odometry>>>(None);
    let (camera_obst_tx, camera_obst_rx) = watch::channel::<Option<Stamped<MapObstacles>>>(None);
    let odo_report = odo_rx.clone();
    let (tracks_tx, tracks_rx) = watch::channel(Tracker::new(settings.tracker));
    let (stats_tx, stats_rx) = watch::channel(EstimationStats::default());
    tasks.spawn(
        "estimation",
        estimation::run(
            {
                let est = estimation::Estimation::new(
                    Estimator::new(settings.drive_params()),
                    Tracker::new(settings.tracker),
                    view,
                );
                match depth_map {
                    Some(d) => {
                        let sf = &settings.safety;
                        // one plane when both lasers scan at one height
                        let (hl, hr) = (
                            settings.lasers.left.translation_m[2],
                            settings.lasers.right.translation_m[2],
                        );
                        let laser_plane_m = ((hl - hr).abs() <= 0.05).then_some((hl + hr) / 2.0);
                        if laser_plane_m.is_none() {
                            tracing::info!(
                                left_m = hl,
                                right_m = hr,
                                "the lasers scan at heights more than 5 cm apart: the camera's \
                                 memory forgets by the lasers only the cells their returns land on"
                            );
                        }
                        est.with_obstacle_map(
                            &d,
                            FootprintM {
                                front_m: sf.front_offset_m,
                                rear_m: sf.rear_offset_m,
                                half_width_m: sf.chair_width_m / 2.0,
                            },
                            laser_plane_m,
                        )
                    }
                    None => est,
                }
            },
            estimation::EstimationIo {
                ticks: ticks_rx,
                obstacles: obst_rx.clone(),
                gyro: gyro_rx,
                objects: objects_rx,
                depth_scans: scans_rx,
                camera_obstacles: camera_obst_tx,
                odometry: odo_tx,
                tracks: tracks_tx,
                stats: stats_tx,
            },
            sources.clone(),
        ),
    );

    // the control task, watched together with the others
    let mut control = new_control(settings, view, opts.exit_on_arrival);
    control.rear = crate::safety::rear::RearWatch::new(settings.rear_settings());
    if depth_map.is_none() {
        // the lasers alone decide: nothing below their plane is seen
        control.supervisor.limits.camera_max_age = None;
        control.say_at_start(if view.is_none() {
            "No depth camera: I cannot see low obstacles or steps down; the lasers alone watch the way."
        } else {
            "Depth obstacles are off: I cannot see low obstacles or steps down; the lasers alone watch the way."
        });
    }
    if let Some(f) = opts.state_dir.as_deref().and_then(latch::load) {
        control.on_latched_fault(&f);
    }
    let (fault_tx, faults) = mpsc::unbounded_channel::<(String, String)>();
    let control_panic = injected_panic_after(&opts.inject_panic, "control");
    let mut control_task = tokio::spawn(panic_after(
        control_panic,
        control_task::run(
            control,
            control_task::ControlTaskIo {
                inputs,
                faults,
                actuator_events: act_ev_rx,
                first_readings: first_rx,
                waiting,
                obstacles: obst_rx,
                odometry: odo_rx,
                camera: camera_obst_rx,
                tracks: tracks_rx,
                commands: cmd_tx,
                prompts: prompts_tx,
                speech: opts.speech.clone(),
                state_dir: opts.state_dir.clone(),
                clock: clock.clone(),
                cancel: shutdown.clone(),
                start,
                max_duration: opts.max_duration,
                stops: opts.stops.clone(),
                status: opts.status.clone(),
                live: live_sink,
                record: sink,
                actuator_status: Some(status_rx.clone()),
                view_time: Some(view_time_rx.clone()),
            },
        ),
    ));

    // watch every task until the control task ends
    let mut failure: Option<(String, String)> = None;
    let mut actuator_result = None;
    let control_end = loop {
        tokio::select! {
            biased;
            r = &mut control_task => break r,
            Some((name, r)) = tasks.next_end() => {
                let reason = match r {
                    Ok(()) => "ended on its own".to_string(),
                    Err(e) => e,
                };
                tracing::error!(task = %name, reason = %reason, "task failed: stopping the chair");
                failure.get_or_insert((name.clone(), reason.clone()));
                // the control task gone too: the failure above still ends the run
                fault_tx.send((name, reason)).ok();
            }
            r = &mut actuator_task, if actuator_result.is_none() => {
                let reason = match &r {
                    Ok(Ok(_)) => "ended on its own".to_string(),
                    Ok(Err(e)) => e.to_string(),
                    Err(e) if e.is_panic() => "panicked".to_string(),
                    Err(e) => e.to_string(),
                };
                tracing::error!(task = "actuator", reason = %reason, "the motor interface stopped");
                actuator_result = Some(r);
                failure.get_or_insert(("actuator".into(), reason.clone()));
                fault_tx.send(("actuator".into(), reason)).ok();
            }
        }
    };
    let ControlEnd {
        control,
        mut outcome,
        said,
        end,
        timing,
        channels: _channels,
    } = match control_end {
        Ok(c) => c,
        Err(e) => {
            let why = if e.is_panic() {
                format!("panicked: {}", panic_message(e.into_panic()))
            } else {
                e.to_string()
            };
            tracing::error!(task = "control", reason = %why, "task failed");
            // no command any more: the writer centres when the last one
            // goes stale
            failure.get_or_insert(("control".into(), why.clone()));
            ControlEnd {
                control: new_control(settings, None, false),
                outcome: Outcome::Fault {
                    task: "control".into(),
                    reason: why,
                },
                said: Vec::new(),
                end: clock.now(),
                timing: Default::default(),
                channels: (watch::channel(None).0, watch::channel(Vec::new()).0),
            }
        }
    };
    if let Some((task, reason)) = &failure {
        outcome = Outcome::Fault {
            task: task.clone(),
            reason: reason.clone(),
        };
    }

    // shutdown: the chair first (centred, then released), then the devices
    writer_cancel.cancel();
    let actuator = match actuator_result {
        Some(r) => r,
        None => actuator_task.await,
    };
    let actuator_status = match actuator {
        Ok(Ok(s)) => s,
        Ok(Err(e)) => {
            tracing::error!(error = %e, "actuator");
            status_rx.borrow().clone()
        }
        Err(_) => status_rx.borrow().clone(),
    };
    sources.cancel();
    devices_stop.cancel();
    while let Some((name, r)) = tasks.next_end().await {
        if let Err(e) = r {
            tracing::warn!(task = %name, error = %e, "task ended with an error during shutdown");
        }
    }
    let estimation = *stats_rx.borrow();
    if !close.is_empty() {
        tokio::task::spawn_blocking(move || close.into_iter().for_each(|c| c()))
            .await
            .map_err(|e| DaemonError::Setup(format!("closing devices: {e}")))?;
    }
    let record = match recorder {
        Some(r) => Some(
            tokio::task::spawn_blocking(move || r.finish())
                .await
                .map_err(|e| DaemonError::Setup(format!("recorder: {e}")))?,
        ),
        None => None,
    };
    let live = match live {
        Some(l) => Some(
            tokio::task::spawn_blocking(move || l.finish())
                .await
                .map_err(|e| DaemonError::Setup(format!("live view: {e}")))?,
        ),
        None => None,
    };
    let odometry = odo_report.borrow().map(|o| o.value);
    let view_time = *view_time_rx.borrow();
    Ok(RunReport {
        outcome,
        duration_s: end.0.saturating_sub(start.0).as_secs_f64(),
        goal: control.goal_state().clone(),
        supervisor: control.state(),
        odometry,
        planner: control.planner.stats.clone(),
        stops: control.supervisor.stops,
        navigation: control.navigation_stats(),
        estimation,
        actuator: actuator_status,
        said,
        record,
        control: timing,
        view_time,
        memory: crate::memory::own_memory(),
        live,
    })
}
