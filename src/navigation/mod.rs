//! Navigation (pure): the lasers' proximity grid (`grid`), the paper
//! group's shared-dynamics potential field (`apf`), the MPC on clarabel
//! (`mpc`), the 20 Hz planner step that combines them with its
//! fallback and stop rules (`planner`), and the way round what the
//! supervisor would hold (`detour`).

pub mod apf;
pub mod detour;
pub mod doorway;
pub mod grid;
pub mod manoeuvre;
pub mod map;
pub mod mpc;
pub mod planner;
