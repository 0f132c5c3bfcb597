//! The simulator: the living room (`room`) and the chair's motion in it
//! (`world`); the simulated R-Net chair — JSM and power module (`rnet`);
//! the simulator's `Devices` for the daemon (`devices`: sensor models,
//! camera, ground-truth detector); byte-exact emulators on ptys for the
//! driver tests (`hokuyo`, `rebus`, `pty`); synthetic Replica scenes
//! (`replica`).

pub mod devices;
pub mod drive;
pub mod hokuyo;
pub mod path;
pub mod pty;
pub mod rebus;
pub mod replica;
pub mod rnet;
pub mod room;
pub mod scene;
mod still;
pub mod topdown;
pub mod trial;
pub mod world;

#[cfg(test)]
mod segment_tests;
