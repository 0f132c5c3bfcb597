//! Frames and planar poses (REP-103/REP-105: metres, radians).

use serde::Serialize;

/// Coordinate frames (REP-103/REP-105).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Frame {
    /// The chair: x forward, y left, z up, metres.
    BaseLink,
    /// Fixed odometry frame.
    Odom,
    /// The colour camera's optical frame: z forward, x right, y down.
    CameraOptical,
}

impl Frame {
    pub fn name(self) -> &'static str {
        match self {
            Frame::BaseLink => "base_link",
            Frame::Odom => "odom",
            Frame::CameraOptical => "camera_optical",
        }
    }
}

/// A planar pose in the odometry frame: metres and radians.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Pose2 {
    pub x_m: f64,
    pub y_m: f64,
    pub theta_rad: f64,
}

impl Pose2 {
    /// The point `p_odom` (this pose being odom_from_base) in base_link.
    pub fn base_from_odom(&self, p_odom: [f64; 2]) -> [f64; 2] {
        let (c, s) = (self.theta_rad.cos(), self.theta_rad.sin());
        let (dx, dy) = (p_odom[0] - self.x_m, p_odom[1] - self.y_m);
        [c * dx + s * dy, -s * dx + c * dy]
    }

    /// The point `p_base` (base_link; this pose being odom_from_base) in
    /// odom: the inverse of [`Pose2::base_from_odom`].
    pub fn odom_from_base(&self, p_base: [f64; 2]) -> [f64; 2] {
        let (c, s) = (self.theta_rad.cos(), self.theta_rad.sin());
        [
            self.x_m + c * p_base[0] - s * p_base[1],
            self.y_m + s * p_base[0] + c * p_base[1],
        ]
    }

    /// The unicycle's pose after `t_s` at `(v, ω)` from the origin facing
    /// +x (base_link at the start): exact on the arc, straight on with the
    /// heading exactly 0 where |ω| is below 1e-9. The heading is ω·t, not
    /// wrapped.
    pub fn unicycle_from_origin(v_mps: f64, omega_radps: f64, t_s: f64) -> Pose2 {
        let th = omega_radps * t_s;
        if omega_radps.abs() < 1e-9 {
            Pose2 {
                x_m: v_mps * t_s,
                y_m: 0.0,
                theta_rad: 0.0,
            }
        } else {
            Pose2 {
                x_m: v_mps / omega_radps * th.sin(),
                y_m: v_mps / omega_radps * (1.0 - th.cos()),
                theta_rad: th,
            }
        }
    }

    /// Moves by `ds` along an arc turning by `dtheta` (exact when
    /// |dθ| is not tiny, the midpoint rule otherwise).
    pub fn advanced(&self, ds: f64, dtheta: f64) -> Pose2 {
        let (x, y, th) = (self.x_m, self.y_m, self.theta_rad);
        let (nx, ny) = if dtheta.abs() < 1e-9 {
            let mid = th + dtheta / 2.0;
            (x + ds * mid.cos(), y + ds * mid.sin())
        } else {
            let r = ds / dtheta;
            (
                x + r * ((th + dtheta).sin() - th.sin()),
                y - r * ((th + dtheta).cos() - th.cos()),
            )
        };
        Pose2 {
            x_m: nx,
            y_m: ny,
            theta_rad: wrap_angle(th + dtheta),
        }
    }
}

/// `dx.hypot(dy).partial_cmp(&r_m)`, bit for bit, with the root taken
/// only where the squares cannot tell (within a relative 1e-9 of the
/// boundary, or where the squares would overflow or lose precision): the
/// hot loops' distance tests. `is_some_and(Ordering::is_le)` is
/// `hypot <= r_m`, `== Some(Greater)` is `hypot > r_m`.
pub fn hypot_cmp(dx: f64, dy: f64, r_m: f64) -> Option<std::cmp::Ordering> {
    const MARGIN: f64 = 1e-9;
    let (d2, r2) = (dx * dx + dy * dy, r_m * r_m);
    if r_m >= 0.0 && (1e-200..=1e200).contains(&r2) && d2.is_finite() {
        if d2 < r2 * (1.0 - MARGIN) {
            return Some(std::cmp::Ordering::Less);
        }
        if d2 > r2 * (1.0 + MARGIN) {
            return Some(std::cmp::Ordering::Greater);
        }
    }
    dx.hypot(dy).partial_cmp(&r_m)
}

/// `x.floor()`, bit for bit, without the library call that the baseline
/// x86-64 target makes of it (no rounding instruction before SSE4.1): a
/// conversion to an integer and back where `x` has a fraction, `x`
/// itself where it cannot (|x| ≥ 2⁵², infinities, NaN).
#[inline]
pub fn floor_fast(x: f64) -> f64 {
    if x.abs() < 4_503_599_627_370_496.0 {
        let t = x as i64 as f64;
        if t > x {
            t - 1.0
        } else {
            // (−0.0 stays −0.0)
            t.copysign(x)
        }
    } else {
        x
    }
}

/// Angle in (−π, π].
pub fn wrap_angle(a: f64) -> f64 {
    let t = a.rem_euclid(std::f64::consts::TAU);
    if t > std::f64::consts::PI {
        t - std::f64::consts::TAU
    } else {
        t
    }
}

impl Pose2 {
    /// This planar pose as a 3D transform (`odom_from_base` for the
    /// chair's pose in `odom`).
    pub fn to_isometry3(&self) -> nalgebra::Isometry3<f64> {
        nalgebra::Isometry3::new(
            nalgebra::Vector3::new(self.x_m, self.y_m, 0.0),
            nalgebra::Vector3::z() * self.theta_rad,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::scene::SplitMix64;

    /// odom_from_base and base_from_odom undo each other, and a point 1 m
    /// ahead of a chair at (1, 2) facing +y lies at (1, 3).
    #[test]
    fn odom_from_base_inverts_base_from_odom() {
        let pose = Pose2 {
            x_m: 1.0,
            y_m: 2.0,
            theta_rad: std::f64::consts::FRAC_PI_2,
        };
        let ahead = pose.odom_from_base([1.0, 0.0]);
        assert!((ahead[0] - 1.0).abs() < 1e-12 && (ahead[1] - 3.0).abs() < 1e-12);
        let turned = Pose2 {
            x_m: -0.4,
            y_m: 0.7,
            theta_rad: 2.3,
        };
        let p = [0.35, -1.2];
        let back = turned.base_from_odom(turned.odom_from_base(p));
        assert!((back[0] - p[0]).abs() < 1e-12 && (back[1] - p[1]).abs() < 1e-12);
    }

    /// A quarter circle of radius 1 m ends at (1, 1) facing +y; straight on
    /// the heading is exactly 0; and any arc ends where `Pose2::advanced`
    /// from the origin does with the same length and turn.
    #[test]
    fn the_unicycle_from_the_origin_follows_its_arc() {
        let half_pi = std::f64::consts::FRAC_PI_2;
        let quarter = Pose2::unicycle_from_origin(half_pi, half_pi, 1.0);
        assert!((quarter.x_m - 1.0).abs() < 1e-12, "{quarter:?}");
        assert!((quarter.y_m - 1.0).abs() < 1e-12, "{quarter:?}");
        assert!((quarter.theta_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let straight = Pose2::unicycle_from_origin(0.5, 1e-12, 2.0);
        assert_eq!(
            (straight.x_m, straight.y_m, straight.theta_rad),
            (1.0, 0.0, 0.0)
        );
        for (v, w, t) in [(0.4, -0.7, 1.5), (-0.3, 0.2, 2.0), (0.0, 0.9, 1.0)] {
            let a = Pose2::unicycle_from_origin(v, w, t);
            let b = Pose2::default().advanced(v * t, w * t);
            assert!((a.x_m - b.x_m).abs() < 1e-12 && (a.y_m - b.y_m).abs() < 1e-12);
            assert!((wrap_angle(a.theta_rad) - b.theta_rad).abs() < 1e-12);
        }
    }

    #[test]
    fn floor_fast_is_floor_bit_for_bit() {
        let mut rng = SplitMix64::new(0x4790_0002);
        let check = |x: f64| {
            if x.is_nan() {
                assert!(floor_fast(x).is_nan());
            } else {
                assert_eq!(floor_fast(x).to_bits(), x.floor().to_bits(), "{x:e}");
            }
        };
        for x in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            -1e-300,
            1e-300,
            f64::MIN_POSITIVE,
            -f64::MIN_POSITIVE,
            4_503_599_627_370_495.5,
            -4_503_599_627_370_495.5,
            4_503_599_627_370_496.0,
            -4_503_599_627_370_497.0,
            9.3e18,
            -9.3e18,
            1e300,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ] {
            check(x);
            check(x.next_up());
            check(x.next_down());
        }
        for _ in 0..100_000 {
            let x = rng.range(-1000.0, 1000.0);
            check(x);
            check(x.round());
            check(x.round().next_down());
            check(f64::from_bits(rng.next_u64()));
        }
    }

    #[test]
    fn hypot_cmp_answers_as_the_root_does() {
        let mut rng = SplitMix64::new(0x4790_0001);
        let mut near_boundary = 0;
        for k in 0..200_000 {
            let r = match k % 5 {
                0 => rng.range(0.0, 5.0),
                1 => 0.3,
                2 => rng.range(1e-160, 1e-150),
                3 => rng.range(1e150, 1e160),
                _ => -rng.range(0.0, 1.0),
            };
            let a = rng.range(0.0, std::f64::consts::TAU);
            // on the circle, a hair either side, or anywhere
            let scale = match k % 4 {
                0 => 1.0,
                1 => 1.0 + rng.range(-1e-12, 1e-12),
                2 => 1.0 + rng.range(-1e-8, 1e-8),
                _ => rng.range(0.0, 3.0),
            };
            let (dx, dy) = (r.abs() * scale * a.cos(), r.abs() * scale * a.sin());
            let want = dx.hypot(dy).partial_cmp(&r);
            assert_eq!(hypot_cmp(dx, dy, r), want, "({dx}, {dy}) against {r}");
            near_boundary += usize::from(want == Some(std::cmp::Ordering::Equal));
        }
        // the exact boundary was met, not only missed
        assert!(near_boundary > 0);
        for (dx, dy, r) in [
            (f64::NAN, 0.0, 1.0),
            (0.0, 0.0, f64::NAN),
            (f64::INFINITY, f64::NAN, 1.0),
            (f64::INFINITY, 0.0, f64::INFINITY),
            (1e200, 1e200, 1.0),
            (0.0, 0.0, 0.0),
            (-0.0, 0.0, 0.0),
            (1e-170, 0.0, 1e-170),
            (3.0, 4.0, 5.0),
        ] {
            assert_eq!(
                hypot_cmp(dx, dy, r),
                dx.hypot(dy).partial_cmp(&r),
                "({dx}, {dy}) against {r}"
            );
        }
    }
}
