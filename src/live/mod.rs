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
//! - `/input` (`foxglove.Log`): every word or press the daemon took from
//!   the person (voice, switch, socket, stdin, ROS 2), as it took it;
//! - `/supervisor` (JSON, schema `opennav.Supervisor`): state, stop reason,
//!   the command, the goal and its phase, and the motor interface's state
//!   and last joystick output.
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
use nalgebra::Isometry3;
use serde::Serialize;

use crate::estimation::tracker::ApproachPose;
use crate::msg::{LaserScan, MapObstacles, Odometry, RgbdFrame, Stamp, Stamped, SupervisorState};
use crate::msg::{Object3D, VelocityCmd};
use crate::perception::detector::Detection;

mod messages;
use messages::timestamp;
pub use messages::*;

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
pub const TOPIC_INPUT: &str = "/input";
pub const TOPIC_SUPERVISOR: &str = "/supervisor";

/// Every topic the live view streams.
pub const TOPICS: [&str; 13] = [
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
    TOPIC_INPUT,
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
    /// odom→base_link, the speed and yaw rate (None: the wheels never
    /// reported).
    pub odometry: Option<Odometry>,
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
    /// What the person said or pressed since the last step, as the daemon
    /// took it (`Goto("chair")`, `Stop`).
    pub inputs: Vec<String>,
    /// The motor interface: its state and what it sent last.
    pub actuator: Option<crate::actuation::ActuatorStatus>,
}

/// What the live view (and the ROS 2 bridge) is fed.
pub enum LiveItem {
    /// Once, when the run starts: where the sensors sit, and the offset
    /// that turns a stamp into wall-clock time.
    Start {
        mounting: Mounting,
        wall_offset: Duration,
    },
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

/// One consumer's queue of items (shared: every consumer gets each).
pub type ItemQueue = crate::sink::DropSink<Arc<LiveItem>>;

/// The tasks' handle on the consumers of the live items (the Foxglove
/// view, the ROS 2 bridge): cheap to clone; never waits. Each consumer has
/// its own bounded queue: one that falls behind loses items, counted, and
/// does not hold back the others.
#[derive(Clone, Default)]
pub struct LiveSink {
    queues: Vec<ItemQueue>,
}

impl std::fmt::Debug for LiveSink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "LiveSink({} consumers)", self.queues.len())
    }
}

impl LiveSink {
    /// A sink feeding one consumer.
    pub fn one(queue: ItemQueue) -> LiveSink {
        LiveSink {
            queues: vec![queue],
        }
    }

    /// This sink and `other`'s consumers together.
    pub fn and(mut self, other: LiveSink) -> LiveSink {
        self.queues.extend(other.queues);
        self
    }

    /// Hands the item to every consumer; never waits.
    pub fn put(&self, item: LiveItem) {
        let item = Arc::new(item);
        for q in &self.queues {
            q.put(item.clone());
        }
    }
}

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
        let (queue, rx, dropped) = ItemQueue::channel(QUEUE, "live view");
        let sink = LiveSink::one(queue);
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
                    channels.show(&item);
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
    input: Channel<fg::Log>,
    supervisor: Arc<foxglove::RawChannel>,
    mounting: Mounting,
    wall_offset: Duration,
    static_sent: Option<Stamp>,
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
            input: typed(ctx, TOPIC_INPUT),
            supervisor,
            mounting,
            wall_offset,
            static_sent: None,
        }
    }

    fn ns(&self, stamp: Stamp) -> u64 {
        (self.wall_offset + stamp.0).as_nanos() as u64
    }

    fn show(&mut self, item: &LiveItem) {
        match item {
            LiveItem::Start {
                mounting,
                wall_offset,
            } => {
                self.mounting = *mounting;
                self.wall_offset = *wall_offset;
                self.static_sent = None;
            }
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
                    .log_with_time(&image_annotations(detections, timestamp(t)), t);
                self.objects
                    .log_with_time(&objects_scene(objects, timestamp(t)), t);
            }
            LiveItem::Step(step) => self.step(step),
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
                StepMessage::Log(m) if topic == TOPIC_INPUT => self.input.log_with_time(&m, t),
                StepMessage::Log(m) => self.said.log_with_time(&m, t),
                StepMessage::Supervisor(json) => self
                    .supervisor
                    .log_with_meta(&json, PartialMetadata { log_time: Some(t) }),
            }
            debug_assert!(TOPICS.contains(&topic));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_consumer_gets_each_item_and_a_full_one_loses_only_its_own() {
        let (slow, slow_rx, slow_dropped) = ItemQueue::channel(1, "slow");
        let (fast, fast_rx, fast_dropped) = ItemQueue::channel(4, "fast");
        let sink = LiveSink::one(slow).and(LiveSink::one(fast));
        for _ in 0..3 {
            sink.put(LiveItem::Start {
                mounting: Mounting {
                    laser_left: Isometry3::identity(),
                    laser_right: Isometry3::identity(),
                    camera: Isometry3::identity(),
                },
                wall_offset: Duration::ZERO,
            });
        }
        assert_eq!(slow_rx.try_iter().count(), 1);
        assert_eq!(slow_dropped.load(Ordering::SeqCst), 2);
        assert_eq!(fast_rx.try_iter().count(), 3);
        assert_eq!(fast_dropped.load(Ordering::SeqCst), 0);
    }
}
