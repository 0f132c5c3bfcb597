//! ROS 2: the messages (pure, always built) and the bridge (cargo feature
//! `ros2`: `ros2-client` over RustDDS, no ROS installation).

pub mod messages;

#[cfg(feature = "ros2")]
mod bridge;
#[cfg(feature = "ros2")]
pub use bridge::*;

/// What the bridge did, for the run's end.
#[derive(Debug, Clone, Default, serde::Serialize, PartialEq)]
pub struct BridgeCounts {
    /// Live items the bridge's queue could not take.
    pub dropped: u64,
    /// Messages a publisher refused (each logged, then at powers of two).
    pub not_sent: u64,
}
