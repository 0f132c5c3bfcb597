//! The ROS 2 bridge: `ros2-client` over RustDDS, pure Rust, no ROS
//! installation. Topic names come from `[ros2.topics]` (defaults below;
//! on the wire DDS topics `rt/…` with ROS 2's type names):
//! - `/opennav/said` (`std_msgs/String`): every sentence the chair says;
//! - `/opennav/state` (`std_msgs/String`): the daemon's status as JSON (the
//!   control socket's `status`), when it changes;
//! - `/scan_left`, `/scan_right` (`sensor_msgs/LaserScan`, frames
//!   `laser_left`, `laser_right`);
//! - `/odom` (`nav_msgs/Odometry`, `odom` → `base_link`, with the fused
//!   pose's covariance);
//! - `/tf` (`tf2_msgs/TFMessage`): `odom` → `base_link` at each control
//!   step; `/tf_static`: `base_link` → `laser_left`, `laser_right`,
//!   `camera_optical`, once, transient-local (a late subscriber gets it);
//! - `/opennav/objects` (`vision_msgs/Detection3DArray`): each view's 3D
//!   objects; `/opennav/tracks`: the tracked objects in `odom`, the id the
//!   track's number;
//! - `/opennav/prompt` (`std_msgs/String`) in: a word, as on stdin
//!   ("chair", "take me to the desk", "stop", "yes");
//! - `/opennav/stop` (`std_msgs/String`) in: any message is a stop, always
//!   accepted (even one that does not decode).
//!
//! It runs on its own thread, fed by the daemon's live items through its
//! own bounded queue ([`crate::live::LiveSink`]): the daemon never waits
//! for it; what it cannot take is dropped and counted. Stamps are
//! wall-clock (ROS time).

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, TryRecvError};
use std::sync::Arc;
use std::time::Duration;

use ros2_client::ros2::policy::{Durability, History, Reliability};
use ros2_client::ros2::{QosPolicies, QosPolicyBuilder};
use ros2_client::{
    Context, ContextOptions, MessageTypeName, Name, Node, NodeName, NodeOptions, Publisher,
};
use serde::Serialize;

use super::messages::{self as m, types};
use super::BridgeCounts;
use crate::config::{Reliability as ReliabilityChoice, Ros2Section};
use crate::input::{DaemonStatus, InputHub};
use crate::live::{ItemQueue, LiveItem, LiveSink, FRAME_LASER_LEFT, FRAME_LASER_RIGHT};
use crate::msg::UserInput;

/// The bridge's queue of live items.
const QUEUE: usize = 64;
/// Between creating two endpoints. RustDDS (0.11.4, 0.11.5) announces
/// each endpoint once; in a burst, a peer (Cyclone DDS here) missed some
/// of the announcements for good (measured: 3 of 9 writers unseen), so
/// their topics never matched. Spaced like this, every one arrives
/// (tests/ros2_interop.rs checks each topic).
const ANNOUNCE_SPACING: Duration = Duration::from_millis(50);

/// The running bridge: the daemon's handle to feed it and the count of
/// what it dropped.
pub struct Bridge {
    pub sink: LiveSink,
    pub dropped: Arc<AtomicU64>,
    not_sent: Arc<AtomicU64>,
}

impl Bridge {
    pub fn counts(&self) -> BridgeCounts {
        BridgeCounts {
            dropped: self.dropped.load(Ordering::SeqCst),
            not_sent: self.not_sent.load(Ordering::SeqCst),
        }
    }
}

fn qos(reliable: bool, depth: u32, transient_local: bool) -> QosPolicies {
    let reliability = if reliable {
        Reliability::Reliable {
            max_blocking_time: ros2_client::ros2::Duration::from_millis(100),
        }
    } else {
        Reliability::BestEffort
    };
    QosPolicyBuilder::new()
        .durability(if transient_local {
            Durability::TransientLocal
        } else {
            Durability::Volatile
        })
        .reliability(reliability)
        .history(History::KeepLast {
            depth: depth.min(i32::MAX as u32) as i32,
        })
        .build()
}

/// A publisher or a subscription on a configured topic.
struct Maker<'a> {
    node: &'a mut Node,
}

impl Maker<'_> {
    fn topic(
        &mut self,
        name: &str,
        ty: (&str, &str),
        qos: &QosPolicies,
    ) -> Result<rustdds::Topic, String> {
        let n = Name::parse(name).map_err(|e| format!("ROS 2 topic {name}: {e}"))?;
        self.node
            .create_topic(&n, MessageTypeName::new(ty.0, ty.1), qos)
            .map_err(|e| format!("ROS 2 topic {name}: {e:?}"))
    }

    fn publisher<T: Serialize>(
        &mut self,
        name: &str,
        ty: (&str, &str),
        qos: QosPolicies,
    ) -> Result<Publisher<T>, String> {
        let topic = self.topic(name, ty, &qos)?;
        std::thread::sleep(ANNOUNCE_SPACING);
        self.node
            .create_publisher::<T>(&topic, Some(qos))
            .map_err(|e| format!("ROS 2 publisher {name}: {e:?}"))
    }

    fn subscription(
        &mut self,
        name: &str,
        qos: QosPolicies,
    ) -> Result<ros2_client::Subscription<String>, String> {
        let topic = self.topic(name, types::STRING, &qos)?;
        std::thread::sleep(ANNOUNCE_SPACING);
        self.node
            .create_subscription::<String>(&topic, Some(qos))
            .map_err(|e| format!("ROS 2 subscription {name}: {e:?}"))
    }
}

/// The publishers of what the chair senses and does.
struct Outputs {
    said: Publisher<String>,
    state: Publisher<String>,
    scan_left: Publisher<m::LaserScan>,
    scan_right: Publisher<m::LaserScan>,
    odom: Publisher<m::Odometry>,
    tf: Publisher<m::TfMessage>,
    tf_static: Publisher<m::TfMessage>,
    objects: Publisher<m::Detection3DArray>,
    tracks: Publisher<m::Detection3DArray>,
    /// Wall-clock minus the run's clock (from the run's first item).
    wall_offset: Option<Duration>,
    /// Items before the run's start item (none expected), logged once.
    unplaced: u64,
    /// Messages a publisher refused.
    not_sent: Arc<AtomicU64>,
}

/// Counts a publish that failed and logs it (the first, then at each
/// power of two: a topic that keeps failing does not flood the log).
fn sent<T, E: std::fmt::Debug>(not_sent: &AtomicU64, what: &str, r: Result<T, E>) {
    if let Err(e) = r {
        let n = not_sent.fetch_add(1, Ordering::SeqCst) + 1;
        if n.is_power_of_two() {
            tracing::warn!(error = ?e, not_sent = n, "ROS 2: {what} not sent");
        }
    }
}

impl Outputs {
    fn time(&self, stamp: crate::msg::Stamp) -> Option<m::Time> {
        self.wall_offset
            .map(|o| m::Time::from_unix_ns((o + stamp.0).as_nanos() as u64))
    }

    fn show(&mut self, item: &LiveItem) {
        if let LiveItem::Start {
            mounting,
            wall_offset,
        } = item
        {
            self.wall_offset = Some(*wall_offset);
            // static: stamped now, as tf2's static broadcaster does
            // now, wall-clock (a system clock before 1970 is said there,
            // not silently taken as 0)
            let wall_now = crate::live::wall_offset(crate::msg::Stamp(Duration::ZERO));
            let now = m::Time::from_unix_ns(wall_now.as_nanos() as u64);
            sent(
                &self.not_sent,
                "/tf_static",
                self.tf_static.publish(m::static_transforms(mounting, now)),
            );
            return;
        }
        if self.wall_offset.is_none() {
            self.unplaced += 1;
            if self.unplaced == 1 {
                tracing::warn!("ROS 2: items before the run's start: not sent");
            }
            return;
        }
        match item {
            LiveItem::Start { .. } => {}
            LiveItem::Scans { left, right } => {
                if let Some(t) = self.time(left.stamp) {
                    sent(
                        &self.not_sent,
                        "scan_left",
                        self.scan_left
                            .publish(m::laser_scan(&left.value, FRAME_LASER_LEFT, t)),
                    );
                }
                if let Some(t) = self.time(right.stamp) {
                    sent(
                        &self.not_sent,
                        "scan_right",
                        self.scan_right
                            .publish(m::laser_scan(&right.value, FRAME_LASER_RIGHT, t)),
                    );
                }
            }
            LiveItem::View { frame, objects, .. } => {
                if let Some(t) = self.time(frame.stamp) {
                    sent(
                        &self.not_sent,
                        "objects",
                        self.objects.publish(m::objects(objects, t)),
                    );
                }
            }
            LiveItem::Step(s) => {
                let Some(t) = self.time(s.stamp) else { return };
                if let Some(o) = &s.odometry {
                    sent(&self.not_sent, "odom", self.odom.publish(m::odometry(o, t)));
                }
                if let Some(tf) = m::odom_transform(s, t) {
                    sent(&self.not_sent, "tf", self.tf.publish(tf));
                }
                sent(
                    &self.not_sent,
                    "tracks",
                    self.tracks.publish(m::tracks(&s.tracks, t)),
                );
            }
        }
    }
}

/// Starts the bridge in `domain`: sentences come on `said`, the status on
/// `status` (read when it changes), the rest through the returned sink;
/// prompts and stops go to `hub`. An error names what could not be made.
/// Should the bridge's thread die, that is logged and the chair stops (its
/// stops would no longer arrive).
pub fn start(
    settings: &Ros2Section,
    domain: u16,
    hub: InputHub,
    said: Receiver<String>,
    mut status: tokio::sync::watch::Receiver<DaemonStatus>,
) -> Result<Bridge, String> {
    let context = Context::with_options(ContextOptions::new().domain_id(domain))
        .map_err(|e| format!("ROS 2: DDS participant in domain {domain}: {e:?}"))?;
    let mut node = context
        .new_node(
            NodeName::new("/", "opennav").map_err(|e| format!("ROS 2 node name: {e:?}"))?,
            NodeOptions::new().enable_rosout(false),
        )
        .map_err(|e| format!("ROS 2 node: {e:?}"))?;
    let t = &settings.topics;
    let depth = settings.depth;
    let sensors_reliable = settings.sensor_reliability == ReliabilityChoice::Reliable;
    let mut make = Maker { node: &mut node };
    // the way in first, the stop first of all; best effort in: matches
    // writers of either reliability
    let stops = make.subscription(&t.stop, qos(false, depth, false))?;
    let prompts = make.subscription(&t.prompt, qos(false, depth, false))?;
    let mut outputs = Outputs {
        said: make.publisher(&t.said, types::STRING, qos(true, depth, false))?,
        state: make.publisher(&t.state, types::STRING, qos(true, depth, false))?,
        scan_left: make.publisher(
            &t.scan_left,
            types::LASER_SCAN,
            qos(sensors_reliable, depth, false),
        )?,
        scan_right: make.publisher(
            &t.scan_right,
            types::LASER_SCAN,
            qos(sensors_reliable, depth, false),
        )?,
        odom: make.publisher(
            &t.odom,
            types::ODOMETRY,
            qos(sensors_reliable, depth, false),
        )?,
        tf: make.publisher(&t.tf, types::TF_MESSAGE, qos(true, depth, false))?,
        tf_static: make.publisher(&t.tf_static, types::TF_MESSAGE, qos(true, 1, true))?,
        objects: make.publisher(
            &t.objects,
            types::DETECTION_3D_ARRAY,
            qos(true, depth, false),
        )?,
        tracks: make.publisher(
            &t.tracks,
            types::DETECTION_3D_ARRAY,
            qos(true, depth, false),
        )?,
        wall_offset: None,
        unplaced: 0,
        not_sent: Arc::new(AtomicU64::new(0)),
    };
    let not_sent = outputs.not_sent.clone();
    let (stop_topic, prompt_topic) = (t.stop.clone(), t.prompt.clone());
    let (queue, items, dropped) = ItemQueue::channel(QUEUE, "ROS 2 bridge");
    let watch_hub = hub.clone();
    let bridge = std::thread::Builder::new()
        .name("ros2".into())
        .spawn(move || {
            // the node and context live as long as the bridge
            let _keep = (context, node);
            let (mut said_open, mut items_open) = (true, true);
            loop {
                // stops first: always taken
                loop {
                    match stops.take() {
                        Ok(Some(_)) => {
                            tracing::info!("ROS 2: stop");
                            hub.stop();
                        }
                        Ok(None) => break,
                        Err(e) => {
                            // a message that did not decode on the stop
                            // topic is still a stop
                            tracing::warn!(error = ?e, topic = %stop_topic, "ROS 2: unreadable stop: stopping");
                            hub.stop();
                            break;
                        }
                    }
                }
                loop {
                    match prompts.take() {
                        Ok(Some((word, _))) => {
                            let input = UserInput::parse(&word);
                            tracing::info!(word = %word, ?input, "ROS 2: prompt");
                            if let Err(e) = hub.send(input) {
                                tracing::warn!(word = %word, error = %e, "ROS 2: prompt not taken");
                            }
                        }
                        Ok(None) => break,
                        Err(e) => {
                            tracing::warn!(error = ?e, topic = %prompt_topic, "ROS 2: unreadable prompt: dropped");
                            break;
                        }
                    }
                }
                if status.has_changed().unwrap_or(false) {
                    let json = serde_json::to_string(&*status.borrow_and_update());
                    match json {
                        Ok(j) => sent(&outputs.not_sent, "state", outputs.state.publish(j)),
                        Err(e) => tracing::warn!(error = %e, "ROS 2: status as JSON"),
                    }
                }
                while said_open {
                    match said.try_recv() {
                        Ok(line) => sent(&outputs.not_sent, "said", outputs.said.publish(line)),
                        Err(TryRecvError::Empty) => break,
                        // the daemon is ending: the process exits with it
                        Err(TryRecvError::Disconnected) => said_open = false,
                    }
                }
                if !items_open {
                    std::thread::sleep(Duration::from_millis(20));
                    continue;
                }
                match items.recv_timeout(Duration::from_millis(20)) {
                    Ok(item) => {
                        outputs.show(&item);
                        while let Ok(item) = items.try_recv() {
                            outputs.show(&item);
                        }
                    }
                    Err(RecvTimeoutError::Timeout) => {}
                    Err(RecvTimeoutError::Disconnected) => items_open = false,
                }
            }
        })
        .map_err(|e| format!("ROS 2 thread: {e}"))?;
    std::thread::Builder::new()
        .name("ros2-watch".into())
        .spawn(move || {
            // the bridge only ends by dying (its loop has no way out)
            let why = match bridge.join() {
                Ok(()) => "ended".to_string(),
                Err(_) => "panicked".to_string(),
            };
            tracing::error!(why = %why, "ROS 2 bridge died: its stops cannot arrive; stopping the chair");
            watch_hub.stop();
        })
        .map_err(|e| format!("ROS 2 watch thread: {e}"))?;
    Ok(Bridge {
        sink: LiveSink::one(queue),
        dropped,
        not_sent,
    })
}
