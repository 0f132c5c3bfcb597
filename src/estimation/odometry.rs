//! Differential-drive odometry from the encoder board's counts (pure):
//! exact-arc integration, velocity from a windowed difference, glitch
//! rejection (a jump beyond physical speed is flagged and not integrated).

use std::collections::VecDeque;

use serde::Serialize;

use crate::msg::{Pose2, WheelTicks};

/// The chair's drive geometry (config `[odometry]`, read directly).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DiffDriveParams {
    pub wheel_radius_m: f64,
    /// Distance between the wheels' contact points, metres.
    pub track_m: f64,
    /// Encoder counts per encoder revolution (×4 decoding included).
    pub counts_per_rev: f64,
    /// Wheel revolutions per encoder revolution (pulleys), per side.
    pub left_ratio: f64,
    pub right_ratio: f64,
    /// +1 or −1: which count direction is forward, per side.
    pub left_sign: f64,
    pub right_sign: f64,
    /// A wheel faster than this between two frames is a glitch, m/s.
    pub max_wheel_speed_mps: f64,
}

impl DiffDriveParams {
    /// The paper group's chair: 500-line encoders (×4 = 2000), wheel radius
    /// 0.175 m, track 0.566 m, pulleys 26/71.53 right and 28/71.63 left,
    /// left counts negated.
    pub fn paper_chair() -> Self {
        DiffDriveParams {
            wheel_radius_m: 0.175,
            track_m: 0.566,
            counts_per_rev: 2000.0,
            left_ratio: 28.0 / 71.63,
            right_ratio: 26.0 / 71.53,
            left_sign: -1.0,
            right_sign: 1.0,
            max_wheel_speed_mps: 3.0,
        }
    }

    /// Metres of travel per count, per side.
    pub fn metres_per_count(&self) -> (f64, f64) {
        let k = std::f64::consts::TAU * self.wheel_radius_m / self.counts_per_rev;
        (
            k * self.left_ratio * self.left_sign,
            k * self.right_ratio * self.right_sign,
        )
    }
}

/// What one frame did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OdomUpdate {
    pub pose: Pose2,
    pub v_mps: f64,
    pub omega_radps: f64,
    /// This frame's jump was beyond physical speed and not integrated.
    pub glitch: bool,
}

#[derive(Debug, Clone)]
pub struct WheelOdometry {
    params: DiffDriveParams,
    pose: Pose2,
    last: Option<(i32, i32, u64)>,
    /// (mcu time s, left path m, right path m) over the velocity window
    window: VecDeque<(f64, f64, f64)>,
    path: (f64, f64),
    window_s: f64,
    pub glitches: u64,
}

impl WheelOdometry {
    pub fn new(params: DiffDriveParams) -> Self {
        WheelOdometry {
            params,
            pose: Pose2::default(),
            last: None,
            window: VecDeque::new(),
            path: (0.0, 0.0),
            window_s: 0.05,
            glitches: 0,
        }
    }

    pub fn pose(&self) -> Pose2 {
        self.pose
    }

    pub fn reset(&mut self, pose: Pose2) {
        self.pose = pose;
    }

    /// Integrates one frame (counts and MCU time from the board).
    pub fn update(&mut self, t: &WheelTicks) -> OdomUpdate {
        let now_s = t.mcu_time_us as f64 * 1e-6;
        let Some((l0, r0, t0)) = self.last else {
            self.last = Some((t.left, t.right, t.mcu_time_us));
            self.window.push_back((now_s, 0.0, 0.0));
            return OdomUpdate {
                pose: self.pose,
                v_mps: 0.0,
                omega_radps: 0.0,
                glitch: false,
            };
        };
        let (kl, kr) = self.params.metres_per_count();
        let dl = t.left.wrapping_sub(l0) as f64 * kl;
        let dr = t.right.wrapping_sub(r0) as f64 * kr;
        let dt = t.mcu_time_us.saturating_sub(t0) as f64 * 1e-6;
        self.last = Some((t.left, t.right, t.mcu_time_us));
        let limit = self.params.max_wheel_speed_mps * dt.max(1e-3);
        let glitch = dt <= 0.0 || dl.abs() > limit || dr.abs() > limit;
        if glitch {
            self.glitches += 1;
            tracing::warn!(
                dl,
                dr,
                dt,
                "odometry: wheel jump beyond physical speed, not integrated"
            );
        } else {
            let ds = 0.5 * (dl + dr);
            let dtheta = (dr - dl) / self.params.track_m;
            self.pose = self.pose.advanced(ds, dtheta);
            self.path.0 += dl;
            self.path.1 += dr;
        }
        self.window.push_back((now_s, self.path.0, self.path.1));
        while self.window.len() > 2
            && self
                .window
                .front()
                .is_some_and(|w| now_s - w.0 > self.window_s)
        {
            self.window.pop_front();
        }
        let (v, w) = match (self.window.front(), self.window.back()) {
            (Some(a), Some(b)) if b.0 > a.0 => {
                let vl = (b.1 - a.1) / (b.0 - a.0);
                let vr = (b.2 - a.2) / (b.0 - a.0);
                (0.5 * (vl + vr), (vr - vl) / self.params.track_m)
            }
            _ => (0.0, 0.0),
        };
        OdomUpdate {
            pose: self.pose,
            v_mps: v,
            omega_radps: w,
            glitch,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::wrap_angle;

    fn params() -> DiffDriveParams {
        // 1 mm per count on both sides, track 0.5 m
        DiffDriveParams {
            wheel_radius_m: 1.0 / std::f64::consts::TAU,
            track_m: 0.5,
            counts_per_rev: 1000.0,
            left_ratio: 1.0,
            right_ratio: 1.0,
            left_sign: 1.0,
            right_sign: 1.0,
            max_wheel_speed_mps: 3.0,
        }
    }

    fn ticks(t_ms: u64, l: i32, r: i32) -> WheelTicks {
        WheelTicks {
            seq: 0,
            mcu_time_us: t_ms * 1000,
            left: l,
            right: r,
            left_illegal: 0,
            right_illegal: 0,
            gap: 0,
        }
    }

    #[test]
    fn straight_line() {
        let mut o = WheelOdometry::new(params());
        for k in 0..=100 {
            o.update(&ticks(10 * k, 5 * k as i32, 5 * k as i32));
        }
        // 100 frames × 5 mm = 0.5 m in 1 s
        let p = o.pose();
        assert!((p.x_m - 0.5).abs() < 1e-12 && p.y_m.abs() < 1e-12 && p.theta_rad.abs() < 1e-12);
        let u = o.update(&ticks(1010, 505, 505));
        assert!((u.v_mps - 0.5).abs() < 1e-9 && u.omega_radps.abs() < 1e-9);
    }

    #[test]
    fn quarter_circle_arc_is_exact() {
        // radius 1 m to the left: inner (left) wheel on r = 0.75, outer on 1.25
        let mut o = WheelOdometry::new(params());
        let quarter = std::f64::consts::FRAC_PI_2;
        let (sl, sr) = (0.75 * quarter, 1.25 * quarter); // metres
        o.update(&ticks(0, 0, 0));
        // in one step: exact arc
        let u = o.update(&ticks(1000, (sl * 1000.0) as i32, (sr * 1000.0) as i32));
        let p = u.pose;
        // rounding to whole counts: within 1 mm
        assert!(
            (p.x_m - 1.0).abs() < 2e-3 && (p.y_m - 1.0).abs() < 2e-3,
            "{p:?}"
        );
        assert!((p.theta_rad - quarter).abs() < 3e-3);
    }

    #[test]
    fn spin_in_place_and_angle_wrap() {
        let mut o = WheelOdometry::new(params());
        // one full turn: each wheel travels π·track = 1.5708 m, opposite ways
        let n = (std::f64::consts::PI * 0.5 * 1000.0).round() as i32;
        o.update(&ticks(0, 0, 0));
        for k in 1..=100 {
            o.update(&ticks(20 * k as u64, -(n * k) / 100, (n * k) / 100));
        }
        let p = o.pose();
        assert!(p.x_m.abs() < 1e-9 && p.y_m.abs() < 1e-9);
        assert!(wrap_angle(p.theta_rad).abs() < 2e-3, "{}", p.theta_rad);
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn a_glitch_is_flagged_and_not_integrated() {
        let mut o = WheelOdometry::new(params());
        o.update(&ticks(0, 0, 0));
        o.update(&ticks(10, 5, 5));
        // 10 m in 10 ms
        let u = o.update(&ticks(20, 10_005, 10));
        assert!(u.glitch);
        assert_eq!(o.glitches, 1);
        assert!((o.pose().x_m - 0.005).abs() < 1e-12);
        // the next normal frame integrates from the new baseline
        let u = o.update(&ticks(30, 10_010, 15));
        assert!(!u.glitch);
        assert!((o.pose().x_m - 0.010).abs() < 1e-12);
    }

    #[test]
    fn counter_wrap_is_a_small_step() {
        let mut o = WheelOdometry::new(params());
        o.update(&ticks(0, i32::MAX - 2, i32::MAX - 2));
        let u = o.update(&ticks(10, i32::MIN + 2, i32::MIN + 2));
        assert!(!u.glitch);
        assert!((o.pose().x_m - 0.005).abs() < 1e-12);
    }

    #[test]
    fn paper_chair_geometry() {
        let (kl, kr) = DiffDriveParams::paper_chair().metres_per_count();
        // forward on the left is negative counts
        assert!(kl < 0.0 && kr > 0.0);
        assert!((kr - std::f64::consts::TAU * 0.175 / 2000.0 * 26.0 / 71.53).abs() < 1e-15);
    }
}
