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
