//! The estimation core of the daemon (pure): wheel ticks predict the EKF,
//! the gyro's yaw rate (when fresh) is fused into each heading increment,
//! merged laser scans correct it through the keyframe matcher. Time comes
//! in with the data.

use std::time::Duration;

use super::ekf::{EkfNoise, PoseEkf};
use super::odometry::{DiffDriveParams, WheelOdometry};
use super::scan_match::{IcpResult, KeyframeMatcher, ScanMatchError};
use crate::msg::{wrap_angle, Odometry, Pose2, Stamp, Stamped, WheelTicks};

#[derive(Debug, Clone)]
pub struct Estimator {
    odo: WheelOdometry,
    pub ekf: PoseEkf,
    pub matcher: KeyframeMatcher,
    last: Option<(Pose2, u64, Stamp)>,
    /// The newest yaw rate about base z (rad/s) with its stamp.
    gyro: Option<Stamped<f64>>,
    /// A gyro sample older than this is not used.
    pub gyro_max_age: Duration,
    pub gyro_fused: u64,
}

impl Estimator {
    pub fn new(drive: DiffDriveParams) -> Estimator {
        Estimator {
            odo: WheelOdometry::new(drive),
            ekf: PoseEkf::new(Pose2::default(), EkfNoise::default()),
            matcher: KeyframeMatcher::default(),
            last: None,
            gyro: None,
            gyro_max_age: Duration::from_millis(100),
            gyro_fused: 0,
        }
    }

    /// A yaw rate about base_link's z axis, rad/s (counter-clockwise).
    pub fn on_gyro(&mut self, yaw_rate: Stamped<f64>) {
        if yaw_rate.value.is_finite() {
            self.gyro = Some(yaw_rate);
        }
    }

    /// A frame of the encoder board (stamped on the host).
    pub fn on_ticks(&mut self, t: &Stamped<WheelTicks>) -> Odometry {
        let u = self.odo.update(&t.value);
        if let Some((p0, t0_us, _)) = self.last {
            let dt = t.value.mcu_time_us.saturating_sub(t0_us) as f64 * 1e-6;
            let sign = if u.v_mps < 0.0 { -1.0 } else { 1.0 };
            let ds = (u.pose.x_m - p0.x_m).hypot(u.pose.y_m - p0.y_m) * sign;
            let dth = wrap_angle(u.pose.theta_rad - p0.theta_rad);
            let gyro = self
                .gyro
                .filter(|g| g.stamp.age_at(t.stamp) <= self.gyro_max_age)
                .map(|g| g.value * dt);
            if gyro.is_some() {
                self.gyro_fused += 1;
            }
            self.ekf.predict(ds, dth, gyro, dt);
        }
        self.last = Some((u.pose, t.value.mcu_time_us, t.stamp));
        Odometry {
            pose: self.ekf.pose,
            v_mps: u.v_mps,
            omega_radps: self
                .gyro
                .filter(|g| g.stamp.age_at(t.stamp) <= self.gyro_max_age)
                .map_or(u.omega_radps, |g| g.value),
            pose_cov: self.ekf.cov.transpose().into(),
        }
    }

    /// A merged scan (base_link points): scan matching corrects the pose.
    pub fn on_scan(
        &mut self,
        points_base: &[[f64; 2]],
    ) -> Option<Result<IcpResult, ScanMatchError>> {
        self.matcher.update(&mut self.ekf, points_base)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ticks(seq: u16, t_us: u64, left: f64, right: f64, stamp_ms: u64) -> Stamped<WheelTicks> {
        Stamped::new(
            Stamp(Duration::from_millis(stamp_ms)),
            WheelTicks {
                seq,
                mcu_time_us: t_us,
                left: left.round() as i32,
                right: right.round() as i32,
                left_illegal: 0,
                right_illegal: 0,
                gap: 0,
            },
        )
    }

    /// A spin on the spot the wheels under-report by 30 %: the gyro keeps
    /// the heading true.
    #[test]
    fn the_gyro_removes_wheel_slip_from_a_turn() {
        let drive = DiffDriveParams::paper_chair();
        let (ml, mr) = drive.metres_per_count();
        let half = drive.track_m / 2.0;
        let rate = 0.5; // rad/s, true
        let mut with = Estimator::new(drive);
        let mut without = Estimator::new(drive);
        let (mut cl, mut cr) = (0.0, 0.0);
        for k in 0..=200u64 {
            // wheels report 70 % of the turn
            let dth = if k == 0 { 0.0 } else { 0.7 * rate * 0.01 };
            cl += -dth * half / ml;
            cr += dth * half / mr;
            let t = ticks(k as u16, k * 10_000, cl, cr, k * 10);
            with.on_gyro(Stamped::new(t.stamp, rate));
            with.on_ticks(&t);
            without.on_ticks(&t);
        }
        let truth = 2.0 * rate; // 2 s
        let err_with = wrap_angle(with.ekf.pose.theta_rad - truth).abs();
        let err_without = wrap_angle(without.ekf.pose.theta_rad - truth).abs();
        assert!(err_without > 0.25, "{err_without}");
        assert!(err_with < 0.01, "{err_with}");
        assert_eq!(with.gyro_fused, 200);
    }

    #[test]
    fn a_stale_gyro_is_not_used() {
        let drive = DiffDriveParams::paper_chair();
        let mut e = Estimator::new(drive);
        e.on_gyro(Stamped::new(Stamp(Duration::from_millis(0)), 1.0));
        e.on_ticks(&ticks(0, 0, 0.0, 0.0, 0));
        e.on_ticks(&ticks(1, 10_000, 0.0, 0.0, 500));
        assert_eq!(e.gyro_fused, 0);
        assert!(e.ekf.pose.theta_rad.abs() < 1e-12);
    }
}
