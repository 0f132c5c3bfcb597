//! The live view: what the chair senses, makes of it and does, streamed
//! to Foxglove over its WebSocket protocol (the `foxglove` crate's server)
//! in Foxglove's own schemas, so the app shows it without a plugin.
//!
//! Topics (schema):
//! - `/laser/left`, `/laser/right` (`foxglove.LaserScan`, frames
//!   `laser_left`, `laser_right`; a step with no return is NaN);
//! - `/camera/color` (`foxglove.RawImage`, `rgb8`), `/camera/depth`
//!   (`foxglove.RawImage`, `32FC1`, metres), frame `camera_optical`;
//! - `/camera/detections` (`foxglove.ImageAnnotations`): the detector's
//!   boxes and labels on the colour image;
//! - `/camera/obstacles` (`foxglove.PointCloud`, `odom`): the depth
//!   camera's remembered obstacles and drop-offs (`kind` 0 and 1);
//! - `/objects` (`foxglove.SceneUpdate`, `base_link`): the view's 3D boxes;
//! - `/tracks` (`foxglove.SceneUpdate`, `odom`): the tracker's objects (the
//!   goal's in green), the approach pose as an arrow;
//! - `/plan` (`foxglove.PosesInFrame`, `odom`): the MPC's predicted path;
//! - `/tf` (`foxglove.FrameTransforms`): `odom`→`base_link` at each control
//!   step; `base_link`→`laser_left`, `laser_right`, `camera_optical` once a
//!   second (a client that joins late gets them);
//! - `/said` (`foxglove.Log`): every sentence the chair says;
//! - `/supervisor` (JSON, schema `opennav.Supervisor`): state, stop reason,
//!   the command, the goal and its phase.
//!
//! Message times are wall-clock (the run's monotonic stamp plus the offset
//! taken at the start), so Foxglove shows the real date.
//!
//! It never blocks the tasks that feed it: they hand items to a bounded
//! queue ([`crate::sink::DropSink`]); what it cannot take is dropped, counted and
//! logged. The server's own queue per client drops the oldest messages of
//! a slow client.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use foxglove::messages as fg;
use foxglove::{Channel, ChannelBuilder, Context, PartialMetadata, Schema, WebSocketServer};
use nalgebra::{Isometry3, UnitQuaternion};
use serde::Serialize;

use crate::estimation::tracker::ApproachPose;
use crate::msg::{LaserScan, MapObstacles, Pose2, RgbdFrame, Stamp, Stamped, SupervisorState};
use crate::msg::{Object3D, VelocityCmd};
use crate::perception::detector::Detection;

pub const TOPIC_LASER_LEFT: &str = "/laser/left";
pub const TOPIC_LASER_RIGHT: &str = "/laser/right";
pub const TOPIC_COLOR: &str = "/camera/color";
pub const TOPIC_DEPTH: &str = "/camera/depth";
pub const TOPIC_DETECTIONS: &str = "/camera/detections";
pub const TOPIC_CAMERA_OBSTACLES: &str = "/camera/obstacles";
pub const TOPIC_OBJECTS: &str = "/objects";
pub const TOPIC_TRACKS: &str = "/tracks";
pub const TOPIC_PLAN: &str = "/plan";
pub const TOPIC_TF: &str = "/tf";
pub const TOPIC_SAID: &str = "/said";
pub const TOPIC_SUPERVISOR: &str = "/supervisor";

/// Every topic the live view streams.
pub const TOPICS: [&str; 12] = [
    TOPIC_LASER_LEFT,
    TOPIC_LASER_RIGHT,
    TOPIC_COLOR,
    TOPIC_DEPTH,
    TOPIC_DETECTIONS,
    TOPIC_CAMERA_OBSTACLES,
    TOPIC_OBJECTS,
    TOPIC_TRACKS,
    TOPIC_PLAN,
    TOPIC_TF,
    TOPIC_SAID,
    TOPIC_SUPERVISOR,
];

pub const FRAME_ODOM: &str = "odom";
pub const FRAME_BASE: &str = "base_link";
pub const FRAME_LASER_LEFT: &str = "laser_left";
pub const FRAME_LASER_RIGHT: &str = "laser_right";
pub const FRAME_CAMERA: &str = "camera_optical";

/// The queue between the tasks and the live thread.
const QUEUE: usize = 64;
/// The sensors' mounting is sent again this often (item time).
const STATIC_EVERY: Duration = Duration::from_secs(1);

/// A confirmed track, as the live view draws it.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackView {
    pub id: u64,
    pub label: String,
    pub center_m: [f64; 3],
    pub size_m: [f64; 3],
}

impl TrackView {
    /// The tracker's confirmed tracks.
    pub fn confirmed(tracker: &crate::estimation::tracker::Tracker) -> Vec<TrackView> {
        tracker
            .tracks()
            .iter()
            .filter(|t| t.confirmed)
            .map(|t| TrackView {
                id: t.id,
                label: t.label.clone(),
                center_m: t.center_m,
                size_m: t.size_m,
            })
            .collect()
    }
}

/// One control step, as the live view shows it.
#[derive(Debug, Clone, PartialEq)]
pub struct StepView {
    pub stamp: Stamp,
    /// odom→base_link.
    pub pose: Option<Pose2>,
    pub state: SupervisorState,
    /// What the supervisor let through.
    pub cmd: VelocityCmd,
    pub goal: Option<String>,
    pub phase: Option<String>,
    pub goal_track: Option<u64>,
    pub approach: Option<ApproachPose>,
    pub tracks: Vec<TrackView>,
    /// The MPC's predicted positions (odom).
    pub plan_odom: Vec<[f64; 2]>,
    /// The depth camera's remembered obstacles (odom).
    pub camera: Option<MapObstacles>,
    pub said: Vec<String>,
}

/// What the live view is fed.
pub enum LiveItem {
    Scans {
        left: Stamped<LaserScan>,
        right: Stamped<LaserScan>,
    },
    View {
        frame: Stamped<RgbdFrame>,
        detections: Vec<Detection>,
        objects: Vec<Object3D>,
    },
    Step(Box<StepView>),
}

/// Where the sensors sit on the chair (`base_link`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mounting {
    pub laser_left: Isometry3<f64>,
    pub laser_right: Isometry3<f64>,
    pub camera: Isometry3<f64>,
}

/// The tasks' handle on the live view (cheap to clone; never waits).
pub type LiveSink = crate::sink::DropSink<LiveItem>;

/// Wall-clock time minus the run's clock at `now`: a stamp plus this is
/// the wall-clock time. A system clock before 1970 is said and taken as 0.
pub fn wall_offset(now: Stamp) -> Duration {
    match std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH) {
        Ok(wall) => wall.saturating_sub(now.0),
        Err(e) => {
            tracing::warn!(error = %e, "the system clock is before 1970: wall-clock times start at 0");
            Duration::ZERO
        }
    }
}

/// Feeds the live view when there is one (the item is made only then).
pub fn show(sink: &Option<LiveSink>, item: impl FnOnce() -> LiveItem) {
    if let Some(s) = sink {
        s.put(item());
    }
}

#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct LiveReport {
    pub address: String,
    /// Items shown, and dropped (the live thread behind).
    pub shown: u64,
    pub dropped: u64,
}

/// The live server and its thread.
pub struct Live {
    address: SocketAddr,
    dropped: Arc<AtomicU64>,
    handle: std::thread::JoinHandle<u64>,
}

impl Live {
    /// Starts the server on `address` (port 0: any free port) on its own
    /// thread; an address that cannot be bound is an error naming it.
    /// `wall_offset` turns a stamp into wall-clock time. The address it
    /// listens on goes to `started`; with `wait`, it returns once a viewer
    /// has subscribed to every topic (or, said in the log, after `wait`).
    pub fn start(
        address: SocketAddr,
        mounting: Mounting,
        wall_offset: Duration,
        started: Option<&std::sync::mpsc::Sender<SocketAddr>>,
        wait: Option<Duration>,
    ) -> Result<(Live, LiveSink), String> {
        let (sink, rx, dropped) = LiveSink::channel(QUEUE, "live view");
        let (ready_tx, ready_rx) = std::sync::mpsc::channel::<Result<u16, String>>();
        let subscribed = Arc::new(Subscribed::default());
        let listener = subscribed.clone();
        let handle = std::thread::Builder::new()
            .name("live".into())
            .spawn(move || {
                let ctx = Context::new();
                // the channels first: a viewer sees them all when it joins
                let mut channels = Channels::new(&ctx, mounting, wall_offset);
                let server = WebSocketServer::new()
                    .name("opennav")
                    .bind(address.ip().to_string(), address.port())
                    .context(&ctx)
                    .listener(listener)
                    .start_blocking();
                let server = match server {
                    Ok(s) => {
                        ready_tx.send(Ok(s.port())).ok();
                        s
                    }
                    Err(e) => {
                        ready_tx
                            .send(Err(format!("live view on {address}: {e}")))
                            .ok();
                        return 0;
                    }
                };
                let mut shown = 0u64;
                for item in rx {
                    channels.show(item);
                    shown += 1;
                }
                server.stop().wait_blocking();
                shown
            })
            .map_err(|e| format!("live view thread: {e}"))?;
        let port = ready_rx
            .recv()
            .map_err(|_| "the live view's thread ended before its server started".to_string())??;
        let bound = SocketAddr::new(address.ip(), port);
        tracing::info!(address = %bound, "live view: open it in Foxglove (Open connection → Foxglove WebSocket, ws://{bound})");
        if let Some(s) = started {
            s.send(bound).ok();
        }
        if let Some(limit) = wait {
            let (lock, cv) = (&subscribed.topics, &subscribed.changed);
            let mut topics = lock.lock().map_err(|_| "live view: poisoned".to_string())?;
            let deadline = std::time::Instant::now() + limit;
            while topics.len() < TOPICS.len() {
                let left = deadline.saturating_duration_since(std::time::Instant::now());
                if left.is_zero() {
                    tracing::warn!(
                        subscribed = topics.len(),
                        "live view: no viewer subscribed to every topic; going on"
                    );
                    break;
                }
                topics = cv
                    .wait_timeout(topics, left)
                    .map_err(|_| "live view: poisoned".to_string())?
                    .0;
            }
        }
        Ok((
            Live {
                address: SocketAddr::new(address.ip(), port),
                dropped,
                handle,
            },
            sink,
        ))
    }

    /// Where the server listens (with the port it got).
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// Stops the server once every sink is gone.
    pub fn finish(self) -> LiveReport {
        let shown = self.handle.join().unwrap_or_else(|_| {
            tracing::error!("the live view's thread panicked");
            0
        });
        LiveReport {
            address: self.address.to_string(),
            shown,
            dropped: self.dropped.load(Ordering::SeqCst),
        }
    }
}

/// The topics some viewer subscribed to.
#[derive(Default)]
struct Subscribed {
    topics: std::sync::Mutex<std::collections::BTreeSet<String>>,
    changed: std::sync::Condvar,
}

impl foxglove::websocket::ServerListener for Subscribed {
    fn on_subscribe(
        &self,
        _client: foxglove::websocket::Client,
        channel: foxglove::websocket::ChannelView,
    ) {
        if let Ok(mut t) = self.topics.lock() {
            t.insert(channel.topic().to_string());
            self.changed.notify_all();
        }
    }
}

/// The channels, and what the live thread keeps between items.
struct Channels {
    laser_left: Channel<fg::LaserScan>,
    laser_right: Channel<fg::LaserScan>,
    color: Channel<fg::RawImage>,
    depth: Channel<fg::RawImage>,
    detections: Channel<fg::ImageAnnotations>,
    camera_obstacles: Channel<fg::PointCloud>,
    objects: Channel<fg::SceneUpdate>,
    tracks: Channel<fg::SceneUpdate>,
    plan: Channel<fg::PosesInFrame>,
    tf: Channel<fg::FrameTransforms>,
    said: Channel<fg::Log>,
    supervisor: Arc<foxglove::RawChannel>,
    mounting: Mounting,
    wall_offset: Duration,
    static_sent: Option<Stamp>,
}

/// The JSON schema of `/supervisor`.
pub const SUPERVISOR_SCHEMA: &str = r#"{
  "type": "object",
  "properties": {
    "state": {"type": "string"},
    "reason": {"type": ["string", "null"]},
    "v_mps": {"type": "number"},
    "omega_radps": {"type": "number"},
    "goal": {"type": ["string", "null"]},
    "phase": {"type": ["string", "null"]}
  }
}"#;

#[derive(Serialize)]
struct SupervisorMsg<'a> {
    state: &'a str,
    reason: Option<String>,
    v_mps: f64,
    omega_radps: f64,
    goal: Option<&'a str>,
    phase: Option<&'a str>,
}

impl Channels {
    fn new(ctx: &Arc<Context>, mounting: Mounting, wall_offset: Duration) -> Channels {
        fn typed<T: foxglove::Encode>(ctx: &Arc<Context>, topic: &str) -> Channel<T> {
            ChannelBuilder::new(topic).context(ctx).build::<T>()
        }
        let supervisor = ChannelBuilder::new(TOPIC_SUPERVISOR)
            .context(ctx)
            .message_encoding("json")
            .schema(Schema::new(
                "opennav.Supervisor",
                "jsonschema",
                SUPERVISOR_SCHEMA.as_bytes().to_vec(),
            ))
            .build_raw();
        let supervisor = match supervisor {
            Ok(c) => c,
            // the topic is unique in this context: cannot happen
            Err(e) => unreachable!("the supervisor's channel: {e}"),
        };
        Channels {
            laser_left: typed(ctx, TOPIC_LASER_LEFT),
            laser_right: typed(ctx, TOPIC_LASER_RIGHT),
            color: typed(ctx, TOPIC_COLOR),
            depth: typed(ctx, TOPIC_DEPTH),
            detections: typed(ctx, TOPIC_DETECTIONS),
            camera_obstacles: typed(ctx, TOPIC_CAMERA_OBSTACLES),
            objects: typed(ctx, TOPIC_OBJECTS),
            tracks: typed(ctx, TOPIC_TRACKS),
            plan: typed(ctx, TOPIC_PLAN),
            tf: typed(ctx, TOPIC_TF),
            said: typed(ctx, TOPIC_SAID),
            supervisor,
            mounting,
            wall_offset,
            static_sent: None,
        }
    }

    fn ns(&self, stamp: Stamp) -> u64 {
        (self.wall_offset + stamp.0).as_nanos() as u64
    }

    fn show(&mut self, item: LiveItem) {
        match item {
            LiveItem::Scans { left, right } => {
                let t = self.ns(left.stamp);
                self.laser_left
                    .log_with_time(&laser_scan(&left.value, FRAME_LASER_LEFT, timestamp(t)), t);
                let t = self.ns(right.stamp);
                self.laser_right.log_with_time(
                    &laser_scan(&right.value, FRAME_LASER_RIGHT, timestamp(t)),
                    t,
                );
            }
            LiveItem::View {
                frame,
                detections,
                objects,
            } => {
                let t = self.ns(frame.stamp);
                let (color, depth) = images(&frame.value, timestamp(t));
                self.color.log_with_time(&color, t);
                self.depth.log_with_time(&depth, t);
                self.detections
                    .log_with_time(&image_annotations(&detections, timestamp(t)), t);
                self.objects
                    .log_with_time(&objects_scene(&objects, timestamp(t)), t);
            }
            LiveItem::Step(step) => self.step(&step),
        }
    }

    fn step(&mut self, s: &StepView) {
        let t = self.ns(s.stamp);
        let ts = timestamp(t);
        if self
            .static_sent
            .is_none_or(|at| at.age_at(s.stamp) >= STATIC_EVERY)
        {
            self.static_sent = Some(s.stamp);
            self.tf
                .log_with_time(&mounting_transforms(&self.mounting, ts), t);
        }
        for (topic, msg) in step_messages(s, ts) {
            match msg {
                StepMessage::Tf(m) => self.tf.log_with_time(&m, t),
                StepMessage::Scene(m) => self.tracks.log_with_time(&m, t),
                StepMessage::Path(m) => self.plan.log_with_time(&m, t),
                StepMessage::Cloud(m) => self.camera_obstacles.log_with_time(&m, t),
                StepMessage::Log(m) => self.said.log_with_time(&m, t),
                StepMessage::Supervisor(json) => self
                    .supervisor
                    .log_with_meta(&json, PartialMetadata { log_time: Some(t) }),
            }
            debug_assert!(TOPICS.contains(&topic));
        }
    }
}

/// One message of a control step, by its schema.
pub enum StepMessage {
    Tf(fg::FrameTransforms),
    Scene(fg::SceneUpdate),
    Path(fg::PosesInFrame),
    Cloud(fg::PointCloud),
    Log(fg::Log),
    /// `opennav.Supervisor`, JSON.
    Supervisor(Vec<u8>),
}

/// What a control step shows, topic by topic (the live view and the
/// recording write the same): `odom`→`base_link`, the tracks and approach,
/// the MPC's path, the camera's obstacles, each sentence, the supervisor.
pub fn step_messages(s: &StepView, ts: fg::Timestamp) -> Vec<(&'static str, StepMessage)> {
    let mut out = Vec::new();
    if let Some(p) = s.pose {
        out.push((
            TOPIC_TF,
            StepMessage::Tf(fg::FrameTransforms {
                transforms: vec![transform(FRAME_ODOM, FRAME_BASE, &p.to_isometry3(), ts)],
            }),
        ));
    }
    out.push((TOPIC_TRACKS, StepMessage::Scene(tracks_scene(s, ts))));
    out.push((
        TOPIC_PLAN,
        StepMessage::Path(fg::PosesInFrame {
            timestamp: Some(ts),
            frame_id: FRAME_ODOM.into(),
            poses: s
                .plan_odom
                .iter()
                .map(|p| pose([p[0], p[1], 0.0], UnitQuaternion::identity()))
                .collect(),
        }),
    ));
    if let Some(c) = &s.camera {
        out.push((
            TOPIC_CAMERA_OBSTACLES,
            StepMessage::Cloud(camera_cloud(c, ts)),
        ));
    }
    for line in &s.said {
        out.push((
            TOPIC_SAID,
            StepMessage::Log(fg::Log {
                timestamp: Some(ts),
                level: fg::log::Level::Info as i32,
                message: line.clone(),
                name: "opennav".into(),
                file: String::new(),
                line: 0,
            }),
        ));
    }
    let (state, reason) = state_words(&s.state);
    let msg = SupervisorMsg {
        state,
        reason,
        v_mps: s.cmd.v_mps,
        omega_radps: s.cmd.omega_radps,
        goal: s.goal.as_deref(),
        phase: s.phase.as_deref(),
    };
    match serde_json::to_vec(&msg) {
        Ok(bytes) => out.push((TOPIC_SUPERVISOR, StepMessage::Supervisor(bytes))),
        Err(e) => tracing::warn!(error = %e, "the supervisor's state as JSON"),
    }
    out
}

/// The supervisor's state as a word, and the reason of a stop or fault.
pub fn state_words(s: &SupervisorState) -> (&'static str, Option<String>) {
    match s {
        SupervisorState::Idle => ("idle", None),
        SupervisorState::Navigating => ("navigating", None),
        SupervisorState::Holding => ("holding", None),
        SupervisorState::Stopped(r) => ("stopped", Some(format!("{r:?}"))),
        SupervisorState::Fault(r) => ("fault", Some(format!("{r:?}"))),
    }
}

fn timestamp(ns: u64) -> fg::Timestamp {
    fg::Timestamp::new((ns / 1_000_000_000) as u32, (ns % 1_000_000_000) as u32)
}

fn pose(p: [f64; 3], q: UnitQuaternion<f64>) -> fg::Pose {
    fg::Pose {
        position: Some(fg::Vector3 {
            x: p[0],
            y: p[1],
            z: p[2],
        }),
        orientation: Some(fg::Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    }
}

fn transform(
    parent: &str,
    child: &str,
    iso: &Isometry3<f64>,
    ts: fg::Timestamp,
) -> fg::FrameTransform {
    let t = iso.translation.vector;
    let q = iso.rotation;
    fg::FrameTransform {
        timestamp: Some(ts),
        parent_frame_id: parent.into(),
        child_frame_id: child.into(),
        translation: Some(fg::Vector3 {
            x: t.x,
            y: t.y,
            z: t.z,
        }),
        rotation: Some(fg::Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }),
    }
}

/// `base_link` → the lasers and the camera.
pub fn mounting_transforms(m: &Mounting, ts: fg::Timestamp) -> fg::FrameTransforms {
    fg::FrameTransforms {
        transforms: vec![
            transform(FRAME_BASE, FRAME_LASER_LEFT, &m.laser_left, ts),
            transform(FRAME_BASE, FRAME_LASER_RIGHT, &m.laser_right, ts),
            transform(FRAME_BASE, FRAME_CAMERA, &m.camera, ts),
        ],
    }
}

/// A scan in its laser's frame; a step with no return is NaN (Foxglove
/// draws nothing there).
pub fn laser_scan(s: &LaserScan, frame: &str, ts: fg::Timestamp) -> fg::LaserScan {
    let n = s.ranges_m.len();
    fg::LaserScan {
        timestamp: Some(ts),
        frame_id: frame.into(),
        pose: Some(pose([0.0; 3], UnitQuaternion::identity())),
        start_angle: s.angle_min_rad,
        end_angle: s.angle_min_rad + s.angle_increment_rad * n.saturating_sub(1) as f64,
        ranges: s
            .ranges_m
            .iter()
            .map(|r| r.map_or(f64::NAN, f64::from))
            .collect(),
        intensities: Vec::new(),
    }
}

/// Colour (`rgb8`) and depth (`32FC1`, metres: exact) in the camera's
/// optical frame.
pub fn images(f: &RgbdFrame, ts: fg::Timestamp) -> (fg::RawImage, fg::RawImage) {
    let (cw, ch) = (f.color.width() as u32, f.color.height() as u32);
    let (dw, dh) = (f.depth.width() as u32, f.depth.height() as u32);
    let depth: Vec<u8> = f
        .depth
        .data()
        .iter()
        .flat_map(|d| d.to_le_bytes())
        .collect();
    (
        fg::RawImage {
            timestamp: Some(ts),
            frame_id: FRAME_CAMERA.into(),
            width: cw,
            height: ch,
            encoding: "rgb8".into(),
            step: cw * 3,
            data: f.color.data().to_vec().into(),
        },
        fg::RawImage {
            timestamp: Some(ts),
            frame_id: FRAME_CAMERA.into(),
            width: dw,
            height: dh,
            encoding: "32FC1".into(),
            step: dw * 4,
            data: depth.into(),
        },
    )
}

fn color(r: f64, g: f64, b: f64, a: f64) -> fg::Color {
    fg::Color { r, g, b, a }
}

/// The detector's boxes (closed outlines) and their labels with scores.
pub fn image_annotations(dets: &[Detection], ts: fg::Timestamp) -> fg::ImageAnnotations {
    let outline = color(0.1, 0.9, 0.2, 1.0);
    fg::ImageAnnotations {
        points: dets
            .iter()
            .map(|d| {
                let [x1, y1, x2, y2] = d.box_xyxy.map(f64::from);
                fg::PointsAnnotation {
                    timestamp: Some(ts),
                    r#type: fg::points_annotation::Type::LineLoop as i32,
                    points: [(x1, y1), (x2, y1), (x2, y2), (x1, y2)]
                        .iter()
                        .map(|&(x, y)| fg::Point2 { x, y })
                        .collect(),
                    outline_color: Some(outline),
                    thickness: 2.0,
                    ..Default::default()
                }
            })
            .collect(),
        texts: dets
            .iter()
            .map(|d| fg::TextAnnotation {
                timestamp: Some(ts),
                position: Some(fg::Point2 {
                    x: f64::from(d.box_xyxy[0]),
                    y: f64::from(d.box_xyxy[1]),
                }),
                text: format!("{} {:.2}", d.label, d.score),
                font_size: 14.0,
                text_color: Some(color(1.0, 1.0, 1.0, 1.0)),
                background_color: Some(color(0.0, 0.0, 0.0, 0.6)),
                ..Default::default()
            })
            .collect(),
        ..Default::default()
    }
}

fn cube(
    id: String,
    frame: &str,
    ts: fg::Timestamp,
    lo: [f64; 3],
    hi: [f64; 3],
    label: &str,
    c: fg::Color,
) -> fg::SceneEntity {
    let center = [0, 1, 2].map(|i| (lo[i] + hi[i]) / 2.0);
    let size = [0, 1, 2].map(|i| (hi[i] - lo[i]).max(0.01));
    fg::SceneEntity {
        timestamp: Some(ts),
        frame_id: frame.into(),
        id,
        cubes: vec![fg::CubePrimitive {
            pose: Some(pose(center, UnitQuaternion::identity())),
            size: Some(fg::Vector3 {
                x: size[0],
                y: size[1],
                z: size[2],
            }),
            color: Some(c),
        }],
        texts: vec![fg::TextPrimitive {
            pose: Some(pose(
                [center[0], center[1], hi[2] + 0.1],
                UnitQuaternion::identity(),
            )),
            billboard: true,
            font_size: 14.0,
            scale_invariant: true,
            color: Some(color(1.0, 1.0, 1.0, 1.0)),
            text: label.into(),
        }],
        ..Default::default()
    }
}

/// The view's 3D objects (upright boxes) in their frame, replacing the
/// last view's.
pub fn objects_scene(objects: &[Object3D], ts: fg::Timestamp) -> fg::SceneUpdate {
    fg::SceneUpdate {
        deletions: vec![fg::SceneEntityDeletion {
            timestamp: Some(ts),
            r#type: fg::scene_entity_deletion::Type::All as i32,
            id: String::new(),
        }],
        entities: objects
            .iter()
            .enumerate()
            .map(|(i, o)| {
                let frame = match o.frame {
                    crate::msg::Frame::BaseLink => FRAME_BASE,
                    crate::msg::Frame::Odom => FRAME_ODOM,
                    crate::msg::Frame::CameraOptical => FRAME_CAMERA,
                };
                cube(
                    format!("object-{i}"),
                    frame,
                    ts,
                    o.aabb.min_m,
                    o.aabb.max_m,
                    &format!("{} {:.2}", o.label, o.score),
                    color(0.2, 0.6, 1.0, 0.4),
                )
            })
            .collect(),
    }
}

/// The tracks (the goal's in green) and the approach pose (an arrow), in
/// odom, replacing the last step's.
pub fn tracks_scene(s: &StepView, ts: fg::Timestamp) -> fg::SceneUpdate {
    let mut entities: Vec<fg::SceneEntity> = s
        .tracks
        .iter()
        .map(|t| {
            let lo = [0, 1, 2].map(|i| t.center_m[i] - t.size_m[i] / 2.0);
            let hi = [0, 1, 2].map(|i| t.center_m[i] + t.size_m[i] / 2.0);
            let c = if Some(t.id) == s.goal_track {
                color(0.1, 0.9, 0.2, 0.5)
            } else {
                color(0.9, 0.7, 0.2, 0.35)
            };
            cube(
                format!("track-{}", t.id),
                FRAME_ODOM,
                ts,
                lo,
                hi,
                &t.label,
                c,
            )
        })
        .collect();
    if let Some(a) = s.approach {
        entities.push(fg::SceneEntity {
            timestamp: Some(ts),
            frame_id: FRAME_ODOM.into(),
            id: "approach".into(),
            arrows: vec![fg::ArrowPrimitive {
                pose: Some(pose(
                    [a.x_m, a.y_m, 0.05],
                    UnitQuaternion::from_euler_angles(0.0, 0.0, a.yaw_rad),
                )),
                shaft_length: 0.4,
                shaft_diameter: 0.05,
                head_length: 0.15,
                head_diameter: 0.12,
                color: Some(color(0.1, 0.9, 0.2, 1.0)),
            }],
            ..Default::default()
        });
    }
    fg::SceneUpdate {
        deletions: vec![fg::SceneEntityDeletion {
            timestamp: Some(ts),
            r#type: fg::scene_entity_deletion::Type::All as i32,
            id: String::new(),
        }],
        entities,
    }
}

/// The camera's remembered obstacles (`kind` 0) and drop-offs (1), in
/// odom: x, y, z (0), kind as f32.
pub fn camera_cloud(c: &MapObstacles, ts: fg::Timestamp) -> fg::PointCloud {
    let mut data = Vec::with_capacity((c.obstacles_odom.len() + c.drop_offs_odom.len()) * 16);
    for (points, kind) in [(&c.obstacles_odom, 0.0f32), (&c.drop_offs_odom, 1.0)] {
        for p in points {
            for v in [p[0] as f32, p[1] as f32, 0.0, kind] {
                data.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    let field = |name: &str, offset: u32| fg::PackedElementField {
        name: name.into(),
        offset,
        r#type: fg::packed_element_field::NumericType::Float32 as i32,
    };
    fg::PointCloud {
        timestamp: Some(ts),
        frame_id: FRAME_ODOM.into(),
        pose: Some(pose([0.0; 3], UnitQuaternion::identity())),
        point_stride: 16,
        fields: vec![
            field("x", 0),
            field("y", 4),
            field("z", 8),
            field("kind", 12),
        ],
        data: data.into(),
    }
}
