//! Sensors: pure codecs for the devices' byte protocols, and (later) the
//! async drivers around them.

pub mod camera;
pub mod clock;
pub mod encoders;
pub mod hokuyo;
pub mod laser;
pub mod scip;
pub mod task;
