//! Sensors: pure codecs for the devices' byte protocols (`scip`, the
//! encoder board's frames in `encoders`), the blocking drivers around them
//! (`hokuyo`, `encoders`), run on reader threads by `task` and exposed to
//! the daemon as `daemon::Source`s; device clocks mapped to the host's
//! (`clock`); the two lasers merged into obstacles in `base_link`
//! (`laser`); RGB-D camera sources (`camera`: replay, RealSense).

pub mod camera;
pub mod clock;
pub mod encoders;
pub mod hokuyo;
pub mod laser;
pub mod scip;
pub mod task;
