//! What the camera can see from a pose: its field of view from the
//! calibration's intrinsics and its working range. The tracker decays a
//! track only where it should have been seen; the goal keeper does not
//! call a goal lost for being outside the view.

use nalgebra::{Isometry3, Point3};

use crate::msg::Pose2;
use crate::msg::{Intrinsics, RgbdCalibration};

/// The colour camera's view cone.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraView {
    pub base_from_camera: Isometry3<f64>,
    pub intrinsics: Intrinsics,
    /// Depth range in which objects are detected and placed, m.
    pub min_range_m: f64,
    pub max_range_m: f64,
}

impl CameraView {
    /// The view of a calibrated camera (0.3–5 m: the depth cameras'
    /// useful range indoors).
    pub fn from_calibration(calibration: &RgbdCalibration) -> CameraView {
        CameraView {
            base_from_camera: calibration.base_from_camera,
            intrinsics: calibration.color,
            min_range_m: 0.3,
            max_range_m: 5.0,
        }
    }

    /// Whether a point in `odom` is inside the image and the range with the
    /// chair at `pose` (`odom`).
    pub fn sees(&self, pose: &Pose2, point_odom: &[f64; 3]) -> bool {
        self.sees_from(&self.camera_from_odom(pose), point_odom)
    }

    /// The camera's optical frame from `odom` with the chair at `pose`.
    pub fn camera_from_odom(&self, pose: &Pose2) -> Isometry3<f64> {
        (pose.to_isometry3() * self.base_from_camera).inverse()
    }

    /// [`CameraView::sees`] with the pose's transform made once
    /// ([`CameraView::camera_from_odom`]), for many points of one frame.
    pub fn sees_from(&self, camera_from_odom: &Isometry3<f64>, point_odom: &[f64; 3]) -> bool {
        let q = camera_from_odom * Point3::new(point_odom[0], point_odom[1], point_odom[2]);
        if !(q.z > self.min_range_m && q.z < self.max_range_m) {
            return false;
        }
        let k = &self.intrinsics;
        let u = k.fx * q.x / q.z + k.cx;
        let v = k.fy * q.y / q.z + k.cy;
        (0.0..k.width as f64).contains(&u) && (0.0..k.height as f64).contains(&v)
    }

    /// Horizontal half-angle of the view, rad.
    pub fn half_fov_h_rad(&self) -> f64 {
        let k = &self.intrinsics;
        (k.cx.max(k.width as f64 - k.cx) / k.fx).atan()
    }
}

/// A level D435i-like colour camera (640×480, fx 615: ±27.5° … ±35°
/// wide), 1 m up and `ahead_m` in front of base_link, for tests.
#[cfg(test)]
pub(crate) fn level_test_view(ahead_m: f64) -> CameraView {
    // optical frame (z forward, x right, y down) in base_link
    let r = nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
        0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0,
    ));
    CameraView {
        base_from_camera: Isometry3::from_parts(
            nalgebra::Vector3::new(ahead_m, 0.0, 1.0).into(),
            nalgebra::UnitQuaternion::from_rotation_matrix(&r),
        ),
        intrinsics: Intrinsics {
            width: 640,
            height: 480,
            fx: 615.0,
            fy: 615.0,
            cx: 320.0,
            cy: 240.0,
        },
        min_range_m: 0.3,
        max_range_m: 5.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A D435i-like colour camera (640×480, fx 615): ±27.5° … ±35° wide.
    fn d435_view() -> CameraView {
        level_test_view(0.3)
    }

    #[test]
    fn the_field_of_view_comes_from_the_intrinsics() {
        let v = d435_view();
        let half = v.half_fov_h_rad().to_degrees();
        assert!((half - 27.5).abs() < 0.1, "{half}");
        let pose = Pose2::default();
        // 3 m ahead at the camera's height: seen; 40° to the side: not
        // (a ±45° view would see it)
        assert!(v.sees(&pose, &[3.3, 0.0, 1.0]));
        let a = 40f64.to_radians();
        assert!(!v.sees(&pose, &[0.3 + 3.0 * a.cos(), 3.0 * a.sin(), 1.0]));
        let a = 25f64.to_radians();
        assert!(v.sees(&pose, &[0.3 + 3.0 * a.cos(), 3.0 * a.sin(), 1.0]));
        // behind, too close, too far
        assert!(!v.sees(&pose, &[-2.0, 0.0, 1.0]));
        assert!(!v.sees(&pose, &[0.5, 0.0, 1.0]));
        assert!(!v.sees(&pose, &[6.0, 0.0, 1.0]));
        // the chair turned left by 90°: the point to its left is ahead
        let turned = Pose2 {
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: std::f64::consts::FRAC_PI_2,
        };
        assert!(v.sees(&turned, &[0.0, 3.3, 1.0]));
        assert!(!v.sees(&turned, &[3.3, 0.0, 1.0]));
    }
}
