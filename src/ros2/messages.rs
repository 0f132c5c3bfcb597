//! ROS 2 messages as they go on the wire (CDR through serde: the fields in
//! the order of their `.msg` files), and what the chair knows as them.
//! Pure: no DDS here (the bridge sends them). Frames follow REP-103 and
//! REP-105: `odom` → `base_link` (x forward, y left, z up) →
//! `laser_left`, `laser_right`, `camera_optical` (z forward, x right,
//! y down); a scan's missing returns follow REP-117.

use nalgebra::{Isometry3, UnitQuaternion};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Serialize};

use crate::live::{
    Mounting, StepView, TrackView, FRAME_BASE, FRAME_CAMERA, FRAME_LASER_LEFT, FRAME_LASER_RIGHT,
    FRAME_ODOM,
};
use crate::msg::{Frame, NoReturn, Object3D, Reading};
use crate::perception::boxes::OrientedBox;

/// `builtin_interfaces/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

impl Time {
    /// From nanoseconds since the Unix epoch (the seconds saturate in 2038,
    /// as the message's `int32` does).
    pub fn from_unix_ns(ns: u64) -> Time {
        Time {
            sec: i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX),
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

/// `sensor_msgs/LaserScan`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct LaserScan {
    pub header: Header,
    pub angle_min: f32,
    pub angle_max: f32,
    pub angle_increment: f32,
    pub time_increment: f32,
    pub scan_time: f32,
    pub range_min: f32,
    pub range_max: f32,
    pub ranges: Vec<f32>,
    pub intensities: Vec<f32>,
}

/// `geometry_msgs/Vector3` (also `Point`: the same fields).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

impl From<UnitQuaternion<f64>> for Quaternion {
    fn from(q: UnitQuaternion<f64>) -> Self {
        Quaternion {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }
    }
}

/// `geometry_msgs/Pose` (position is a `Point`).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose {
    pub position: Vector3,
    pub orientation: Quaternion,
}

/// A 6×6 covariance, row-major over (x, y, z, roll, pitch, yaw):
/// `float64[36]`, a fixed array (no length on the wire).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covariance(pub [f64; 36]);

impl Default for Covariance {
    fn default() -> Self {
        Covariance([0.0; 36])
    }
}

impl Serialize for Covariance {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(36)?;
        for v in &self.0 {
            t.serialize_element(v)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit;
        impl<'de> serde::de::Visitor<'de> for Visit {
            type Value = Covariance;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("36 float64")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(
                self,
                mut a: A,
            ) -> Result<Covariance, A::Error> {
                let mut c = [0.0; 36];
                for (i, v) in c.iter_mut().enumerate() {
                    *v = a
                        .next_element()?
                        .ok_or_else(|| serde::de::Error::invalid_length(i, &self))?;
                }
                Ok(Covariance(c))
            }
        }
        d.deserialize_tuple(36, Visit)
    }
}

/// `geometry_msgs/PoseWithCovariance`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    pub pose: Pose,
    pub covariance: Covariance,
}

/// `geometry_msgs/Twist`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Twist {
    pub linear: Vector3,
    pub angular: Vector3,
}

/// `geometry_msgs/TwistWithCovariance`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    pub twist: Twist,
    pub covariance: Covariance,
}

/// `nav_msgs/Odometry`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Odometry {
    pub header: Header,
    pub child_frame_id: String,
    pub pose: PoseWithCovariance,
    pub twist: TwistWithCovariance,
}

/// `geometry_msgs/Transform`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Transform {
    pub translation: Vector3,
    pub rotation: Quaternion,
}

/// `geometry_msgs/TransformStamped`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TransformStamped {
    pub header: Header,
    pub child_frame_id: String,
    pub transform: Transform,
}

/// `tf2_msgs/TFMessage`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TfMessage {
    pub transforms: Vec<TransformStamped>,
}

/// `vision_msgs/ObjectHypothesis`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ObjectHypothesis {
    pub class_id: String,
    pub score: f64,
}

/// `vision_msgs/ObjectHypothesisWithPose`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ObjectHypothesisWithPose {
    pub hypothesis: ObjectHypothesis,
    pub pose: PoseWithCovariance,
}

/// `vision_msgs/BoundingBox3D`: the box's centre and orientation, its
/// full size along its own axes, metres.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct BoundingBox3D {
    pub center: Pose,
    pub size: Vector3,
}

/// `vision_msgs/Detection3D` (vision_msgs 3 and later: no source cloud).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Detection3D {
    pub header: Header,
    pub results: Vec<ObjectHypothesisWithPose>,
    pub bbox: BoundingBox3D,
    pub id: String,
}

/// `vision_msgs/Detection3DArray`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Detection3DArray {
    pub header: Header,
    pub detections: Vec<Detection3D>,
}

/// The ROS 2 type names (package, type) of the messages above.
pub mod types {
    pub const STRING: (&str, &str) = ("std_msgs", "String");
    pub const LASER_SCAN: (&str, &str) = ("sensor_msgs", "LaserScan");
    pub const ODOMETRY: (&str, &str) = ("nav_msgs", "Odometry");
    pub const TF_MESSAGE: (&str, &str) = ("tf2_msgs", "TFMessage");
    pub const DETECTION_3D_ARRAY: (&str, &str) = ("vision_msgs", "Detection3DArray");
}

/// The URG-04LX's measuring range and timing (its `PP` answer): a scan
/// takes 100 ms (600 rpm) over 1024 steps a turn.
pub const LASER_RANGE_MIN_M: f32 = 0.02;
pub const LASER_RANGE_MAX_M: f32 = 5.6;
pub const LASER_SCAN_TIME_S: f32 = 0.1;
pub const LASER_TIME_INCREMENT_S: f32 = 0.1 / 1024.0;

fn header(stamp: Time, frame: &str) -> Header {
    Header {
        stamp,
        frame_id: frame.into(),
    }
}

/// A scan in its laser's frame. A step without a return is, per REP-117,
/// +∞ when nothing was within range (code 0) and NaN otherwise (too weak,
/// saturated, not measurable: a blind step, not free space).
pub fn laser_scan(s: &crate::msg::LaserScan, frame: &str, stamp: Time) -> LaserScan {
    let n = s.ranges_m.len();
    let ranges = s
        .ranges_m
        .iter()
        .enumerate()
        .map(|(i, r)| match (r, s.readings.get(i)) {
            (Some(m), _) => *m,
            (None, Some(Reading::NoReturn(NoReturn::NoObject))) => f32::INFINITY,
            (None, _) => f32::NAN,
        })
        .collect();
    LaserScan {
        header: header(stamp, frame),
        angle_min: s.angle_min_rad as f32,
        angle_max: (s.angle_min_rad + s.angle_increment_rad * n.saturating_sub(1) as f64) as f32,
        angle_increment: s.angle_increment_rad as f32,
        time_increment: LASER_TIME_INCREMENT_S,
        scan_time: LASER_SCAN_TIME_S,
        range_min: LASER_RANGE_MIN_M,
        range_max: LASER_RANGE_MAX_M,
        ranges,
        intensities: Vec::new(),
    }
}

/// What is not estimated in the plane (z, roll, pitch) gets this variance:
/// large, as REP-105 consumers (robot_localization) expect of a 2D source.
pub const UNESTIMATED_VARIANCE: f64 = 1e6;

/// A planar covariance over (x, y, yaw) in the 6×6 layout.
fn planar_covariance(xy_yaw: &[[f64; 3]; 3]) -> Covariance {
    let mut c = [0.0; 36];
    let at = [0usize, 1, 5];
    for (i, &r) in at.iter().enumerate() {
        for (j, &k) in at.iter().enumerate() {
            c[r * 6 + k] = xy_yaw[i][j];
        }
    }
    for d in [2usize, 3, 4] {
        c[d * 6 + d] = UNESTIMATED_VARIANCE;
    }
    Covariance(c)
}

/// The chair's odometry: `odom` → `base_link` with the fused pose's
/// covariance, and its speed and yaw rate in `base_link` (the twist's
/// covariance is not estimated: z, roll, pitch marked unknown, the rest 0).
pub fn odometry(o: &crate::msg::Odometry, stamp: Time) -> Odometry {
    let p = o.pose;
    Odometry {
        header: header(stamp, FRAME_ODOM),
        child_frame_id: FRAME_BASE.into(),
        pose: PoseWithCovariance {
            pose: Pose {
                position: Vector3 {
                    x: p.x_m,
                    y: p.y_m,
                    z: 0.0,
                },
                orientation: UnitQuaternion::from_euler_angles(0.0, 0.0, p.theta_rad).into(),
            },
            covariance: planar_covariance(&o.pose_cov),
        },
        twist: TwistWithCovariance {
            twist: Twist {
                linear: Vector3 {
                    x: o.v_mps,
                    ..Default::default()
                },
                angular: Vector3 {
                    z: o.omega_radps,
                    ..Default::default()
                },
            },
            covariance: planar_covariance(&[[0.0; 3]; 3]),
        },
    }
}

fn transform(parent: &str, child: &str, iso: &Isometry3<f64>, stamp: Time) -> TransformStamped {
    let t = iso.translation.vector;
    TransformStamped {
        header: header(stamp, parent),
        child_frame_id: child.into(),
        transform: Transform {
            translation: Vector3 {
                x: t.x,
                y: t.y,
                z: t.z,
            },
            rotation: iso.rotation.into(),
        },
    }
}

/// `/tf`: `odom` → `base_link` at a control step.
pub fn odom_transform(s: &StepView, stamp: Time) -> Option<TfMessage> {
    let p = s.odometry?.pose;
    Some(TfMessage {
        transforms: vec![transform(FRAME_ODOM, FRAME_BASE, &p.to_isometry3(), stamp)],
    })
}

/// `/tf_static`: `base_link` → the lasers and the camera's optical frame.
pub fn static_transforms(m: &Mounting, stamp: Time) -> TfMessage {
    TfMessage {
        transforms: vec![
            transform(FRAME_BASE, FRAME_LASER_LEFT, &m.laser_left, stamp),
            transform(FRAME_BASE, FRAME_LASER_RIGHT, &m.laser_right, stamp),
            transform(FRAME_BASE, FRAME_CAMERA, &m.camera, stamp),
        ],
    }
}

fn frame_id(f: Frame) -> &'static str {
    match f {
        Frame::BaseLink => FRAME_BASE,
        Frame::Odom => FRAME_ODOM,
        Frame::CameraOptical => FRAME_CAMERA,
    }
}

fn detection(
    label: &str,
    score: f64,
    b: &OrientedBox,
    frame: &str,
    id: String,
    stamp: Time,
) -> Detection3D {
    let (center_m, size_m, yaw_rad) = (b.center_m, b.size_m, b.yaw_rad);
    let center = Pose {
        position: Vector3 {
            x: center_m[0],
            y: center_m[1],
            z: center_m[2],
        },
        orientation: UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_rad).into(),
    };
    Detection3D {
        header: header(stamp, frame),
        results: vec![ObjectHypothesisWithPose {
            hypothesis: ObjectHypothesis {
                class_id: label.into(),
                score,
            },
            pose: PoseWithCovariance {
                pose: center,
                covariance: Covariance::default(),
            },
        }],
        bbox: BoundingBox3D {
            center,
            size: Vector3 {
                x: size_m[0],
                y: size_m[1],
                z: size_m[2],
            },
        },
        id,
    }
}

/// A view's 3D objects (each its oriented box, in its own frame; the
/// array's frame is the first object's, `base_link` when there is none).
/// Ids are empty: a view's objects are not tracked (see [`tracks`]).
pub fn objects(objects: &[Object3D], stamp: Time) -> Detection3DArray {
    let frame = objects.first().map_or(FRAME_BASE, |o| frame_id(o.frame));
    Detection3DArray {
        header: header(stamp, frame),
        detections: objects
            .iter()
            .map(|o| {
                detection(
                    &o.label,
                    f64::from(o.score),
                    &o.obb,
                    frame_id(o.frame),
                    String::new(),
                    stamp,
                )
            })
            .collect(),
    }
}

/// The tracker's confirmed objects in `odom`, upright boxes, the track's
/// number as the id (stable while the track lives; score 1).
pub fn tracks(tracks: &[TrackView], stamp: Time) -> Detection3DArray {
    Detection3DArray {
        header: header(stamp, FRAME_ODOM),
        detections: tracks
            .iter()
            .map(|t| {
                let upright = OrientedBox {
                    center_m: t.center_m,
                    size_m: t.size_m,
                    yaw_rad: 0.0,
                };
                detection(&t.label, 1.0, &upright, FRAME_ODOM, t.id.to_string(), stamp)
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::{Odometry as Odo, Pose2};

    #[test]
    fn time_splits_nanoseconds_and_saturates_in_2038() {
        assert_eq!(
            Time::from_unix_ns(1_795_000_000_123_456_789),
            Time {
                sec: 1_795_000_000,
                nanosec: 123_456_789
            }
        );
        assert_eq!(Time::from_unix_ns(u64::MAX).sec, i32::MAX);
    }

    #[test]
    fn a_scan_marks_out_of_range_as_infinity_and_blind_steps_as_nan() {
        let s = crate::msg::LaserScan {
            sensor_ms: 0,
            angle_min_rad: -0.5,
            angle_increment_rad: 0.25,
            ranges_m: vec![Some(1.5), None, None],
            readings: vec![
                Reading::RangeMm(1500),
                Reading::NoReturn(NoReturn::NoObject),
                Reading::NoReturn(NoReturn::LowIntensity),
            ],
        };
        let m = laser_scan(&s, FRAME_LASER_LEFT, Time::default());
        assert_eq!(m.header.frame_id, "laser_left");
        assert_eq!(m.ranges[0], 1.5);
        assert_eq!(m.ranges[1], f32::INFINITY);
        assert!(m.ranges[2].is_nan());
        assert_eq!((m.angle_min, m.angle_max), (-0.5, 0.0));
        assert_eq!(m.angle_increment, 0.25);
    }

    #[test]
    fn odometry_is_odom_to_base_link_with_the_planar_covariance() {
        let o = Odo {
            pose: Pose2 {
                x_m: 1.0,
                y_m: 2.0,
                theta_rad: std::f64::consts::FRAC_PI_2,
            },
            v_mps: 0.4,
            omega_radps: -0.1,
            pose_cov: [[0.01, 0.002, 0.0], [0.002, 0.02, 0.0], [0.0, 0.0, 0.03]],
        };
        let m = odometry(&o, Time::default());
        assert_eq!(m.header.frame_id, "odom");
        assert_eq!(m.child_frame_id, "base_link");
        let q = m.pose.pose.orientation;
        assert!((q.z - (0.5f64).sqrt()).abs() < 1e-12 && (q.w - (0.5f64).sqrt()).abs() < 1e-12);
        let c = m.pose.covariance.0;
        assert_eq!((c[0], c[1], c[6], c[7]), (0.01, 0.002, 0.002, 0.02));
        assert_eq!(c[35], 0.03);
        assert_eq!(c[14], UNESTIMATED_VARIANCE);
        assert_eq!(m.twist.twist.linear.x, 0.4);
        assert_eq!(m.twist.twist.angular.z, -0.1);
    }

    #[test]
    fn the_covariance_is_36_numbers_without_a_length() {
        // serde's view of a fixed array: a tuple of 36 (CDR writes no length)
        let json = serde_json::to_value(Covariance([1.0; 36])).expect("serialises");
        assert_eq!(json.as_array().map(Vec::len), Some(36));
        let back: Covariance = serde_json::from_value(json).expect("reads back");
        assert_eq!(back, Covariance([1.0; 36]));
        let short = serde_json::from_value::<Covariance>(serde_json::json!([1.0, 2.0]));
        assert!(short.is_err());
    }

    #[test]
    fn tracks_carry_their_number_and_odom() {
        let t = TrackView {
            id: 7,
            label: "chair".into(),
            center_m: [2.0, 1.0, 0.4],
            size_m: [0.5, 0.5, 0.8],
        };
        let m = tracks(&[t], Time::default());
        assert_eq!(m.header.frame_id, "odom");
        assert_eq!(m.detections[0].id, "7");
        assert_eq!(m.detections[0].results[0].hypothesis.class_id, "chair");
        assert_eq!(m.detections[0].bbox.size.z, 0.8);
    }
}
