//! Estimation: where the chair is and what is around it.
//!
//! `odometry` (wheel counts → pose and speeds), `ekf` (SE(2) EKF with the
//! gyro, corrected by scan matching; the pose history by stamp),
//! `scan_match` (laser ICP and the keyframe matcher), `fusion` (the three
//! together as one pure `Estimator`), `tracker` (objects in `odom`),
//! `view` (what the camera sees from a pose) and `goal` (the prompted
//! object, its approach pose, the search turn, hold and arrival).

pub mod ekf;
pub mod fusion;
pub mod goal;
pub mod obstacle_map;
pub mod odometry;
pub mod scan_match;
pub mod tracker;
pub mod view;
