//! Navigation: the proximity grid of the lasers and the paper group's
//! shared-dynamics potential field (pure). The MPC on clarabel follows.

pub mod apf;
pub mod grid;
pub mod mpc;
pub mod planner;
