//! Estimation: wheel odometry (and, later, the EKF and the object tracker).

pub mod ekf;
pub mod fusion;
pub mod goal;
pub mod odometry;
pub mod scan_match;
pub mod tracker;
