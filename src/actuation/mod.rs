//! Actuation: the chair's R-Net motor interface. `rnet.rs` is the pure
//! codec, the velocity ↔ joystick mapping and the takeover state machine;
//! the SocketCAN adapter and the Rebus serial backend wrap it.

pub mod rebus;
pub mod rnet;
