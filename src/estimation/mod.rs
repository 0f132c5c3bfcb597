//! Estimation: wheel odometry (and, later, the EKF and the object tracker).

pub mod odometry;
pub mod tracker;
