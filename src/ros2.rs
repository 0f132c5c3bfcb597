//! The ROS 2 bridge (cargo feature `ros2`): `ros2-client` over RustDDS,
//! pure Rust, no ROS installation. Topics (ROS 2 names; on the wire DDS
//! topics `rt/…` with types `std_msgs::msg::dds_::String_`):
//! - `/opennav/said` (`std_msgs/String`): every sentence the chair says;
//! - `/opennav/state` (`std_msgs/String`): the daemon's status as JSON (the
//!   control socket's `status`), when it changes;
//! - `/opennav/prompt` (`std_msgs/String`) in: a word, as on stdin ("chair",
//!   "take me to the desk", "stop", "yes");
//! - `/opennav/stop` (`std_msgs/String`) in: any message is a stop, always
//!   accepted.
//!
//! It runs on its own thread; the daemon hands it sentences and status and
//! never waits for it.

use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::Duration;

use ros2_client::{
    Context, MessageTypeName, Name, NodeName, NodeOptions, DEFAULT_PUBLISHER_QOS,
    DEFAULT_SUBSCRIPTION_QOS,
};

use crate::input::{DaemonStatus, InputHub};
use crate::msg::UserInput;

pub const NAMESPACE: &str = "/opennav";

/// Starts the bridge: sentences come on `said`, the status on `status`
/// (read when it changes); prompts and stops go to `hub`. An error names
/// what could not be made. Should the bridge's thread die, that is logged
/// and the chair stops (its stops would no longer arrive).
pub fn start(
    hub: InputHub,
    said: Receiver<String>,
    mut status: tokio::sync::watch::Receiver<DaemonStatus>,
) -> Result<std::thread::JoinHandle<()>, String> {
    let context = Context::new().map_err(|e| format!("ROS 2: DDS participant: {e:?}"))?;
    let mut node = context
        .new_node(
            NodeName::new(NAMESPACE, "opennav").map_err(|e| format!("ROS 2 node name: {e:?}"))?,
            NodeOptions::new().enable_rosout(false),
        )
        .map_err(|e| format!("ROS 2 node: {e:?}"))?;
    let string = || MessageTypeName::new("std_msgs", "String");
    let topic = |name: &str, qos| {
        let n = Name::new(NAMESPACE, name).map_err(|e| format!("ROS 2 topic {name}: {e:?}"))?;
        node.create_topic(&n, string(), qos)
            .map_err(|e| format!("ROS 2 topic {name}: {e:?}"))
    };
    let said_topic = topic("said", &DEFAULT_PUBLISHER_QOS)?;
    let state_topic = topic("state", &DEFAULT_PUBLISHER_QOS)?;
    let prompt_topic = topic("prompt", &DEFAULT_SUBSCRIPTION_QOS)?;
    let stop_topic = topic("stop", &DEFAULT_SUBSCRIPTION_QOS)?;
    let said_pub = node
        .create_publisher::<String>(&said_topic, None)
        .map_err(|e| format!("ROS 2 publisher /opennav/said: {e:?}"))?;
    let state_pub = node
        .create_publisher::<String>(&state_topic, None)
        .map_err(|e| format!("ROS 2 publisher /opennav/state: {e:?}"))?;
    let prompts = node
        .create_subscription::<String>(&prompt_topic, None)
        .map_err(|e| format!("ROS 2 subscription /opennav/prompt: {e:?}"))?;
    let stops = node
        .create_subscription::<String>(&stop_topic, None)
        .map_err(|e| format!("ROS 2 subscription /opennav/stop: {e:?}"))?;
    let watch_hub = hub.clone();
    let bridge = std::thread::Builder::new()
        .name("ros2".into())
        .spawn(move || {
            // the node and context live as long as the bridge
            let _keep = (context, node);
            let mut said_open = true;
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
                            tracing::warn!(error = ?e, "ROS 2: /opennav/stop unreadable: stopping");
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
                            tracing::warn!(error = ?e, "ROS 2: /opennav/prompt unreadable: dropped");
                            break;
                        }
                    }
                }
                if status.has_changed().unwrap_or(false) {
                    let json = serde_json::to_string(&*status.borrow_and_update());
                    match json {
                        Ok(j) => {
                            if let Err(e) = state_pub.publish(j) {
                                tracing::warn!(error = ?e, "ROS 2: /opennav/state not sent");
                            }
                        }
                        Err(e) => tracing::warn!(error = %e, "ROS 2: status as JSON"),
                    }
                }
                if !said_open {
                    std::thread::sleep(Duration::from_millis(20));
                    continue;
                }
                match said.recv_timeout(Duration::from_millis(20)) {
                    Ok(line) => {
                        if let Err(e) = said_pub.publish(line) {
                            tracing::warn!(error = ?e, "ROS 2: /opennav/said not sent");
                        }
                    }
                    Err(RecvTimeoutError::Timeout) => {}
                    // the daemon is ending: the process exits with it
                    Err(RecvTimeoutError::Disconnected) => said_open = false,
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
        .map_err(|e| format!("ROS 2 watch thread: {e}"))
}
