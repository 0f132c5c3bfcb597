//! opennav: onboard software of a smart powered wheelchair.
//!
//! A person says or selects a word; the chair finds that object in 3D with
//! its RGB-D camera and drives there by itself. See `ARCHITECTURE.md` in the
//! shared design notes and the README for the map of modules.

pub mod actuation;
pub mod config;
pub mod crc;
pub mod daemon;
pub mod estimation;
pub mod eval;
pub mod input;
pub mod live;
pub mod memory;
pub mod msg;
pub mod navigation;
pub mod output;
pub mod perception;
pub mod record;
pub mod ros2;
pub mod safety;
pub mod sensors;
pub mod setup;
pub mod sim;
pub mod sink;
pub mod speech;
pub mod voice;
