//! The simulator: worlds, sensor models and device emulators standing in
//! for hardware behind the same traits as the real drivers.

pub mod devices;
pub mod hokuyo;
pub mod pty;
pub mod rebus;
pub mod replica;
pub mod rnet;
pub mod room;
pub mod world;
