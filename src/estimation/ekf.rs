//! Pose fusion on SE(2) (pure): an EKF predicted with wheel odometry whose
//! heading increment is fused with the gyro's (so wheel slip on turns does
//! not bend the pose), corrected by absolute pose measurements (scan
//! matching) with covariances reported; and a pose history that places
//! every detection with the pose at its frame's stamp.

use std::collections::VecDeque;

use nalgebra::{Matrix3, Vector3};

use crate::msg::Stamp;
use crate::msg::{wrap_angle, Pose2};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EkfNoise {
    /// Variance of travel per metre travelled, m²/m.
    pub k_distance: f64,
    /// Variance of the odometry's heading change per radian turned, rad²/rad.
    pub k_turn: f64,
    /// Heading variance per metre travelled (e.g. uneven tyres), rad²/m.
    pub k_drift: f64,
    /// Gyro yaw-rate noise density: variance of the integrated heading per second, rad²/s.
    pub gyro_var_per_s: f64,
}

impl Default for EkfNoise {
    fn default() -> Self {
        EkfNoise {
            k_distance: 1e-4,
            k_turn: 4e-3,
            k_drift: 1e-4,
            gyro_var_per_s: 1e-6,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct PoseEkf {
    pub pose: Pose2,
    /// Covariance of (x, y, θ).
    pub cov: Matrix3<f64>,
    pub noise: EkfNoise,
}

impl PoseEkf {
    pub fn new(pose: Pose2, noise: EkfNoise) -> Self {
        PoseEkf {
            pose,
            cov: Matrix3::zeros(),
            noise,
        }
    }

    /// Predicts with an odometry increment (`ds` m, `dtheta_odom` rad) over
    /// `dt_s`, fusing the gyro's integrated heading change when given.
    /// Returns the heading change used.
    pub fn predict(
        &mut self,
        ds: f64,
        dtheta_odom: f64,
        dtheta_gyro: Option<f64>,
        dt_s: f64,
    ) -> f64 {
        let n = self.noise;
        let var_odom = n.k_turn * dtheta_odom.abs() + n.k_drift * ds.abs() + 1e-12;
        let (dtheta, var_dtheta) = match dtheta_gyro {
            Some(g) if g.is_finite() => {
                let var_g = n.gyro_var_per_s * dt_s.max(1e-4);
                let w_o = 1.0 / var_odom;
                let w_g = 1.0 / var_g;
                (
                    (dtheta_odom * w_o + g * w_g) / (w_o + w_g),
                    1.0 / (w_o + w_g),
                )
            }
            _ => (dtheta_odom, var_odom),
        };
        let th = self.pose.theta_rad;
        let mid = th + dtheta / 2.0;
        let f = Matrix3::new(
            1.0,
            0.0,
            -ds * mid.sin(),
            0.0,
            1.0,
            ds * mid.cos(),
            0.0,
            0.0,
            1.0,
        );
        // noise in (ds, dθ) mapped to the pose
        let g = nalgebra::Matrix3x2::new(
            mid.cos(),
            -0.5 * ds * mid.sin(),
            mid.sin(),
            0.5 * ds * mid.cos(),
            0.0,
            1.0,
        );
        let q = nalgebra::Matrix2::new(n.k_distance * ds.abs(), 0.0, 0.0, var_dtheta);
        self.cov = f * self.cov * f.transpose() + g * q * g.transpose();
        self.pose = self.pose.advanced(ds, dtheta);
        dtheta
    }

    /// Corrects with an absolute pose measurement (e.g. scan matching) of
    /// covariance `r`.
    pub fn correct(&mut self, z: Pose2, r: Matrix3<f64>) {
        let innov = Vector3::new(
            z.x_m - self.pose.x_m,
            z.y_m - self.pose.y_m,
            wrap_angle(z.theta_rad - self.pose.theta_rad),
        );
        let s = self.cov + r;
        let Some(s_inv) = s.try_inverse() else { return };
        let k = self.cov * s_inv;
        let dx = k * innov;
        self.pose = Pose2 {
            x_m: self.pose.x_m + dx[0],
            y_m: self.pose.y_m + dx[1],
            theta_rad: wrap_angle(self.pose.theta_rad + dx[2]),
        };
        self.cov = (Matrix3::identity() - k) * self.cov;
    }
}

/// Recent poses by stamp, interpolated.
#[derive(Debug, Clone)]
pub struct PoseHistory {
    poses: VecDeque<(Stamp, Pose2)>,
    capacity: usize,
}

impl PoseHistory {
    pub fn new(capacity: usize) -> Self {
        PoseHistory {
            poses: VecDeque::new(),
            capacity: capacity.max(2),
        }
    }

    /// Adds a pose; stamps must not go backwards (an older one is ignored).
    pub fn push(&mut self, stamp: Stamp, pose: Pose2) -> bool {
        if self.poses.back().is_some_and(|(t, _)| stamp < *t) {
            return false;
        }
        self.poses.push_back((stamp, pose));
        while self.poses.len() > self.capacity {
            self.poses.pop_front();
        }
        true
    }

    /// The newest stamp in the history.
    pub fn newest(&self) -> Option<Stamp> {
        self.poses.back().map(|(t, _)| *t)
    }

    /// The pose at `stamp`, interpolated between the poses around it (the
    /// heading along the shorter arc). None outside the history: a
    /// detection is never placed with a guessed pose.
    pub fn pose_at(&self, stamp: Stamp) -> Option<Pose2> {
        let i = self.poses.iter().position(|(t, _)| *t >= stamp)?;
        let (t1, p1) = self.poses[i];
        if t1 == stamp {
            return Some(p1);
        }
        let (t0, p0) = *self.poses.get(i.checked_sub(1)?)?;
        let a = (stamp.as_secs_f64() - t0.as_secs_f64()) / (t1.as_secs_f64() - t0.as_secs_f64());
        Some(Pose2 {
            x_m: p0.x_m + a * (p1.x_m - p0.x_m),
            y_m: p0.y_m + a * (p1.y_m - p0.y_m),
            theta_rad: wrap_angle(p0.theta_rad + a * wrap_angle(p1.theta_rad - p0.theta_rad)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gyro_fusion_removes_slip_on_a_turn() {
        // a quarter turn in place, 100 steps; the wheels slip: odometry
        // reports 30 % more turning than happened; the gyro is right
        let truth = std::f64::consts::FRAC_PI_2;
        let mut odom_only = PoseEkf::new(Pose2::default(), EkfNoise::default());
        let mut fused = PoseEkf::new(Pose2::default(), EkfNoise::default());
        for _ in 0..100 {
            let d_true = truth / 100.0;
            odom_only.predict(0.0, 1.3 * d_true, None, 0.02);
            fused.predict(0.0, 1.3 * d_true, Some(d_true), 0.02);
        }
        let err_odom = (odom_only.pose.theta_rad - truth).abs();
        let err_fused = (fused.pose.theta_rad - truth).abs();
        assert!(err_odom > 0.4, "{err_odom}");
        assert!(err_fused < 0.01, "{err_fused}");
        // the heading stays certain with the gyro, not without
        assert!(fused.cov[(2, 2)] < odom_only.cov[(2, 2)]);
    }

    #[test]
    fn covariance_grows_along_the_way_and_a_correction_shrinks_it() {
        let mut e = PoseEkf::new(Pose2::default(), EkfNoise::default());
        for _ in 0..100 {
            e.predict(0.01, 0.0, None, 0.02);
        }
        assert!((e.pose.x_m - 1.0).abs() < 1e-12);
        let before = e.cov;
        assert!(before[(0, 0)] > 0.0 && before[(1, 1)] > 0.0);
        // a scan match says we are at x = 0.9, with equal confidence
        let z = Pose2 {
            x_m: 0.9,
            y_m: 0.0,
            theta_rad: 0.0,
        };
        e.correct(z, before);
        assert!((e.pose.x_m - 0.95).abs() < 1e-9, "{}", e.pose.x_m);
        assert!(e.cov[(0, 0)] < before[(0, 0)]);
    }

    #[test]
    fn history_interpolates_by_stamp() {
        let s = |t: f64| Stamp::from_secs_f64(t);
        let mut h = PoseHistory::new(10);
        h.push(
            s(1.0),
            Pose2 {
                x_m: 0.0,
                y_m: 0.0,
                theta_rad: 3.0,
            },
        );
        h.push(
            s(2.0),
            Pose2 {
                x_m: 1.0,
                y_m: 2.0,
                theta_rad: -3.0,
            },
        );
        assert!(!h.push(s(1.5), Pose2::default()));
        let p = h.pose_at(s(1.25)).unwrap();
        assert!((p.x_m - 0.25).abs() < 1e-12 && (p.y_m - 0.5).abs() < 1e-12);
        // across ±π along the short way: 3.0 → −3.0 passes through π
        let expected = wrap_angle(3.0 + 0.25 * wrap_angle(-6.0));
        assert!((p.theta_rad - expected).abs() < 1e-12 && p.theta_rad.abs() > 3.0);
        assert_eq!(h.pose_at(s(2.0)).unwrap().x_m, 1.0);
        assert!(h.pose_at(s(0.5)).is_none());
        assert!(h.pose_at(s(2.5)).is_none());
    }
}
