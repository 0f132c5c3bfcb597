//! What the sensors deliver: laser scans, obstacle points, wheel counts,
//! RGB-D frames. Each travels as a [`Stamped`](super::Stamped) value with its
//! acquisition stamp.

use serde::Serialize;

use super::Stamp;
use crate::msg::{DepthImage, RgbImage};

/// One scan in the sensor's frame: step angles counter-clockwise, 0 ahead.
#[derive(Debug, Clone, PartialEq)]
pub struct LaserScan {
    /// Sensor clock of the scan (24-bit ms, as sent).
    pub sensor_ms: u32,
    pub angle_min_rad: f64,
    pub angle_increment_rad: f64,
    /// Per step: metres, or None with the reason in `no_return`.
    pub ranges_m: Vec<Option<f32>>,
    pub readings: Vec<Reading>,
}

/// Why a step has no range.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoReturn {
    /// Code 0: nothing within range.
    NoObject,
    /// Codes 1–2: reflected light too weak.
    LowIntensity,
    /// Code 18: strong reflector saturated the receiver.
    StrongReflector,
    /// Code 19: step not measurable.
    NonMeasurable,
    /// Other codes below 20 mm.
    Other(u8),
}

/// A step's reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reading {
    RangeMm(u32),
    NoReturn(NoReturn),
}

/// Obstacle points on the ground plane of `base_link` (x forward, y left),
/// metres.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Obstacles {
    pub points_base: Vec<[f32; 2]>,
    /// Where the floor is missing (a step down, a kerb): cells the chair
    /// must not enter, same frame. The lasers never report any.
    pub drop_offs_base: Vec<[f32; 2]>,
    /// Where the floor may end out of the camera's view (floor it has
    /// never seen between the chair's front and where its view of the
    /// floor begins): the chair does not enter them either, but a turn on
    /// the spot over them may be vouched for by the person in the chair
    /// (`safety::rear`). Same frame; the lasers never report any.
    pub drop_offs_unseen_base: Vec<[f32; 2]>,
    /// Cells near the chair whose floor the camera never saw and where
    /// nothing is remembered (cell centres, same frame): not obstacles,
    /// but a turn on the spot that would sweep one waits for the person
    /// to say it is clear all around (`safety::rear`). The lasers never
    /// report any.
    pub floor_unseen_base: Vec<[f32; 2]>,
    /// Every laser step as a ray, to know what the lasers could not see.
    pub rays_base: Vec<LaserRay>,
}

/// One laser step in `base_link`: from the scanner, along `dir` (unit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserRay {
    pub origin_m: [f32; 2],
    pub dir: [f32; 2],
    /// A no-return that does not mean "nothing in range" (light too weak
    /// — a black or shiny surface, glass —, a saturating reflector, a step
    /// not measurable): something may be there unseen.
    pub blind: bool,
    /// Where the ray ended on something, m (None: no return — nothing in
    /// range, or blind).
    pub range_m: Option<f32>,
}

impl LaserRay {
    /// Whether the ray (t ≥ 0) passes through the axis-aligned box
    /// `[lo, hi]` (metres, base_link).
    pub fn crosses(&self, lo: [f64; 2], hi: [f64; 2]) -> bool {
        let o = [self.origin_m[0] as f64, self.origin_m[1] as f64];
        let d = [self.dir[0] as f64, self.dir[1] as f64];
        line_crosses_box(o, d, f64::INFINITY, lo, hi)
    }
}

/// Whether `o + t·d` for t in [0, `t_max`] passes through the axis-aligned
/// box `[lo, hi]` (the slab test).
pub fn line_crosses_box(o: [f64; 2], d: [f64; 2], t_max: f64, lo: [f64; 2], hi: [f64; 2]) -> bool {
    let (mut t0, mut t1) = (0.0f64, t_max);
    for a in 0..2 {
        if d[a].abs() < 1e-12 {
            if o[a] < lo[a] || o[a] > hi[a] {
                return false;
            }
            continue;
        }
        let (ta, tb) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
        let (near, far) = if ta < tb { (ta, tb) } else { (tb, ta) };
        t0 = t0.max(near);
        t1 = t1.min(far);
        if t0 > t1 {
            return false;
        }
    }
    true
}

/// The depth camera's remembered obstacles and drop-offs, cell centres in
/// `odom` (metres), stamped with the newest frame that went into them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MapObstacles {
    pub obstacles_odom: Vec<[f64; 2]>,
    /// Drop-offs the camera saw.
    pub drop_offs_odom: Vec<[f64; 2]>,
    /// Drop-offs that may lie out of its view, where it never saw the
    /// floor ([`Obstacles::drop_offs_unseen_base`]).
    pub drop_offs_unseen_odom: Vec<[f64; 2]>,
    /// Cells near the chair (at the newest frame) whose floor it never
    /// saw ([`Obstacles::floor_unseen_base`]).
    pub floor_unseen_odom: Vec<[f64; 2]>,
}

impl MapObstacles {
    /// In `base_link` at `odom_from_base`.
    pub fn to_base(&self, odom_from_base: &super::Pose2) -> Obstacles {
        let to_base = |p: &[f64; 2]| {
            let [x, y] = odom_from_base.base_from_odom(*p);
            [x as f32, y as f32]
        };
        Obstacles {
            points_base: self.obstacles_odom.iter().map(to_base).collect(),
            drop_offs_base: self.drop_offs_odom.iter().map(to_base).collect(),
            drop_offs_unseen_base: self.drop_offs_unseen_odom.iter().map(to_base).collect(),
            floor_unseen_base: self.floor_unseen_odom.iter().map(to_base).collect(),
            rays_base: Vec::new(),
        }
    }
}

/// Counts from the board, with the unwrapped MCU time.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WheelTicks {
    pub seq: u16,
    /// MCU microseconds since boot, unwrapped.
    pub mcu_time_us: u64,
    pub left: i32,
    pub right: i32,
    pub left_illegal: u16,
    pub right_illegal: u16,
    /// Frames missing before this one (sequence gap).
    pub gap: u16,
}

/// A colour frame and the depth frame paired with it.
#[derive(Debug, Clone)]
pub struct RgbdFrame {
    pub color: RgbImage,
    /// Depth in metres, in the depth camera's geometry (see the calibration).
    pub depth: DepthImage,
    pub color_stamp: Stamp,
    pub depth_stamp: Stamp,
}
