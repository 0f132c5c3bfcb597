//! The simulated chair in a room, standing in for the hardware when none is
//! attached: the chair's true pose driven by the power module's motor
//! output (the joystick values it acts on, through the chair's calibrated
//! mapping, with a first-order motor lag), the wheel encoders' counts, the
//! two lasers' scans (2D ray casting at the lasers' height) and the RGB-D
//! camera's view (the room renderer). Pure: time steps and poses in.
//!
//! World frame: the room's (x, y on the floor, z up). The chair's odometry
//! frame is where it started; the simulator knows both, the daemon only
//! the odometry frame.

use nalgebra::{Isometry3, Point3, Vector3};
use serde::Serialize;

use super::room::{Rendered, Room};
use crate::actuation::rnet::JoystickMapping;
use crate::estimation::odometry::DiffDriveParams;
use crate::msg::ImageError;
use crate::msg::Intrinsics;
use crate::msg::LaserScan;
use crate::msg::Pose2;
use crate::msg::WheelTicks;
use crate::sensors::scip::SensorParams;

/// The chair's footprint about base_link, metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Footprint {
    pub front_m: f64,
    pub rear_m: f64,
    pub half_width_m: f64,
}

impl Footprint {
    /// The chair's: 1.0 × 0.7 m, base_link 0.45 m ahead of the rear edge.
    pub const CHAIR: Footprint = Footprint {
        front_m: 0.55,
        rear_m: 0.45,
        half_width_m: 0.35,
    };
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SimReport {
    pub truth: Pose2,
    /// The chair's actual speeds at the end, m/s and rad/s.
    pub v_mps: f64,
    pub omega_radps: f64,
    /// Steps in which the footprint overlapped an obstacle.
    pub collision_steps: u64,
    /// Smallest distance from the footprint to an obstacle, m.
    pub min_clearance_m: f64,
    /// Steps in which part of the footprint was over a step down.
    pub fell_steps: u64,
    /// Smallest distance from the footprint to a step down's edge, m
    /// (infinite without one; negative: over it).
    pub min_drop_clearance_m: f64,
    pub distance_travelled_m: f64,
    /// The first step in which the footprint touched something.
    pub first_contact: Option<Contact>,
}

/// What the footprint first touched, when, and how the chair moved.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Contact {
    /// Seconds since the start.
    pub time_s: f64,
    /// Index into the room's objects; None: a wall.
    pub object: Option<usize>,
    pub v_mps: f64,
    pub omega_radps: f64,
}

/// A person walking to and fro along a line (their box's lower corner
/// goes from `from_m` to `to_m` and back), who waits while the chair is
/// within [`WALKER_KEEPS_M`] of where they would step.
#[derive(Debug, Clone, PartialEq)]
pub struct Walker {
    /// Their box in `room.objects`.
    pub object: usize,
    pub from_m: [f64; 2],
    pub to_m: [f64; 2],
    pub speed_mps: f64,
    pub size_m: [f64; 3],
}

/// A walking person keeps this far from the chair's footprint, m.
pub const WALKER_KEEPS_M: f64 = 0.4;
/// A step that nears the chair by at most this fraction of its length is
/// along it (about 3 degrees off its edge), and taken within the keep-out.
pub const WALKER_ALONG_NEARS: f64 = 0.05;
/// ... while it leaves them this far from the chair or more (nearer, only
/// a step that does not near it at all is taken), m.
pub const WALKER_ALONG_FROM_M: f64 = 0.1;
/// A walking person who has waited this long for the chair (which may be
/// waiting for them) turns back and gives way, s.
pub const WALKER_GIVES_WAY_AFTER_S: f64 = 3.0;

#[derive(Debug, Clone)]
pub struct SimWorld {
    pub room: Room,
    /// base_link in the world.
    pub truth: Pose2,
    pub start: Pose2,
    pub v_mps: f64,
    pub omega_radps: f64,
    /// Motor time constant, s.
    pub motor_tau_s: f64,
    pub footprint: Footprint,
    pub drive: DiffDriveParams,
    counts: (f64, f64),
    mcu_us: u64,
    seq: u16,
    pub report: SimReport,
    /// The stamp of the last step (the daemon's clock).
    pub now: crate::msg::Stamp,
    /// Where base_link went (world), a point every 5 cm.
    pub trace: Vec<[f64; 2]>,
    /// People walking.
    pub walkers: Vec<Walking>,
}

/// A walking person and where they are in their walk.
#[derive(Debug, Clone, PartialEq)]
pub struct Walking {
    pub walker: Walker,
    /// On the way back (to `from_m`).
    pub back: bool,
    /// How long they have waited for the chair, s.
    pub waited_s: f64,
}

impl Walking {
    pub fn new(walker: Walker) -> Walking {
        Walking {
            walker,
            back: false,
            waited_s: 0.0,
        }
    }
}

/// 2D segments of everything a laser at `height_m` sees: the walls and the
/// footprints of objects spanning that height.
pub fn segments_at(room: &Room, height_m: f64) -> Vec<([f64; 2], [f64; 2])> {
    let [sx, sy, _] = room.size_m;
    let mut segs = rect(0.0, 0.0, sx, sy);
    for o in &room.objects {
        if o.min_m[2] <= height_m && o.max_m[2] >= height_m {
            segs.extend(rect(o.min_m[0], o.min_m[1], o.max_m[0], o.max_m[1]));
        }
    }
    segs
}

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<([f64; 2], [f64; 2])> {
    vec![
        ([x0, y0], [x1, y0]),
        ([x1, y0], [x1, y1]),
        ([x1, y1], [x0, y1]),
        ([x0, y1], [x0, y0]),
    ]
}

/// Signed distance from `p` to the rectangle `[lo, hi]` on the floor
/// (negative inside: how deep).
fn box_distance(lo: [f64; 2], hi: [f64; 2], p: [f64; 2]) -> f64 {
    let dx = (lo[0] - p[0]).max(p[0] - hi[0]);
    let dy = (lo[1] - p[1]).max(p[1] - hi[1]);
    if dx <= 0.0 && dy <= 0.0 {
        dx.max(dy)
    } else {
        let (dx, dy) = (dx.max(0.0), dy.max(0.0));
        (dx * dx + dy * dy).sqrt()
    }
}

/// The footprint `f` at `pose` as its four corners in the world, going
/// round.
fn footprint_corners(f: &Footprint, pose: &Pose2) -> [[f64; 2]; 4] {
    let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
    [
        [-f.rear_m, -f.half_width_m],
        [f.front_m, -f.half_width_m],
        [f.front_m, f.half_width_m],
        [-f.rear_m, f.half_width_m],
    ]
    .map(|q| {
        [
            pose.x_m + c * q[0] - s * q[1],
            pose.y_m + s * q[0] + c * q[1],
        ]
    })
}

/// Signed gap between the footprint `f` at `pose` and the rectangle
/// `[lo, hi]` on the floor, exact: apart, the distance between the two
/// outlines (for two convex outlines that do not meet, a corner of one to
/// the other); overlapping, not above zero (how deep the deepest corner
/// is, or zero when they cross with no corner inside the other).
pub fn footprint_gap(f: &Footprint, pose: &Pose2, lo: [f64; 2], hi: [f64; 2]) -> f64 {
    let corners = footprint_corners(f, pose);
    let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
    let (chair_lo, chair_hi) = ([-f.rear_m, -f.half_width_m], [f.front_m, f.half_width_m]);
    let theirs = [
        [lo[0], lo[1]],
        [hi[0], lo[1]],
        [hi[0], hi[1]],
        [lo[0], hi[1]],
    ];
    let gap = corners
        .iter()
        .map(|p| box_distance(lo, hi, *p))
        .chain(
            theirs
                .iter()
                // (the pose is the world's: base_from_odom's transform)
                .map(|p| box_distance(chair_lo, chair_hi, pose.base_from_odom(*p))),
        )
        .fold(f64::INFINITY, f64::min);
    if gap <= 0.0 {
        return gap;
    }
    // no corner inside the other: apart unless they cross, which they do
    // when no side of either separates them (two rectangles: the world's
    // axes and the chair's)
    let apart_along = |axis: [f64; 2]| {
        let span = |pts: &[[f64; 2]; 4]| {
            pts.iter()
                .map(|p| p[0] * axis[0] + p[1] * axis[1])
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(v), b.max(v))
                })
        };
        let (a, b) = (span(&corners), span(&theirs));
        a.1 < b.0 || b.1 < a.0
    };
    if [[1.0, 0.0], [0.0, 1.0], [c, s], [-s, c]]
        .into_iter()
        .any(apart_along)
    {
        gap
    } else {
        0.0
    }
}

/// A wall or a side of an object in the lasers' plane: its two ends, m.
type Segment = ([f64; 2], [f64; 2]);

/// Distance along the ray from `o` in direction `a` to the nearest
/// segment, or None.
pub fn ray_cast(o: [f64; 2], a: f64, segs: &[([f64; 2], [f64; 2])]) -> Option<f64> {
    let near: Vec<(f64, Segment)> = segs.iter().map(|s| (0.0, *s)).collect();
    ray_cast_nearest_first(o, a, &near)
}

/// The segments with their distance from `o`, nearest first: the casts
/// of one scan from `o` stop at the first segment farther than their hit.
fn by_distance(o: [f64; 2], segs: &[([f64; 2], [f64; 2])]) -> Vec<(f64, Segment)> {
    let mut near: Vec<(f64, Segment)> = segs
        .iter()
        .map(|&(p, q)| {
            let d = crate::estimation::tracker::segment_distance_sq(p, q, o).sqrt();
            (d, (p, q))
        })
        .collect();
    near.sort_by(|a, b| a.0.total_cmp(&b.0));
    near
}

/// [`ray_cast`] over segments each with a lower bound of its distance
/// from `o`, in increasing order: a segment whose bound lies beyond the
/// hit so far (by more than rounding) cannot be hit nearer.
fn ray_cast_nearest_first(o: [f64; 2], a: f64, segs: &[(f64, Segment)]) -> Option<f64> {
    let (dx, dy) = (a.cos(), a.sin());
    let mut best: Option<f64> = None;
    for (dist_m, (p, q)) in segs {
        if best.is_some_and(|b| dist_m - 1e-6 > b) {
            break;
        }
        let (ex, ey) = (q[0] - p[0], q[1] - p[1]);
        let den = dx * ey - dy * ex;
        if den.abs() < 1e-12 {
            continue;
        }
        let (wx, wy) = (p[0] - o[0], p[1] - o[1]);
        let t = (wx * ey - wy * ex) / den;
        let u = (wx * dy - wy * dx) / den;
        if t > 1e-6 && (0.0..=1.0).contains(&u) && best.is_none_or(|b| t < b) {
            best = Some(t);
        }
    }
    best
}

impl SimWorld {
    /// The living room, the chair in its free middle facing the two chairs
    /// by the wall.
    pub fn living_room(drive: DiffDriveParams) -> SimWorld {
        let start = Pose2 {
            x_m: 3.4,
            y_m: 2.6,
            theta_rad: -2.0,
        };
        SimWorld::in_room(Room::living_room(), start, drive)
    }

    /// The chair at `start` in `room` (a generated scene).
    pub fn in_room(room: Room, start: Pose2, drive: DiffDriveParams) -> SimWorld {
        SimWorld {
            room,
            truth: start,
            start,
            v_mps: 0.0,
            omega_radps: 0.0,
            motor_tau_s: 0.15,
            footprint: Footprint::CHAIR,
            drive,
            counts: (0.0, 0.0),
            mcu_us: 0,
            seq: 0,
            report: SimReport {
                truth: start,
                v_mps: 0.0,
                omega_radps: 0.0,
                collision_steps: 0,
                min_clearance_m: f64::INFINITY,
                fell_steps: 0,
                min_drop_clearance_m: f64::INFINITY,
                distance_travelled_m: 0.0,
                first_contact: None,
            },
            now: crate::msg::Stamp::ZERO,
            trace: vec![[start.x_m, start.y_m]],
            walkers: Vec::new(),
        }
    }

    /// Advances `dt_s` with the power module driving `joystick` (None:
    /// motors stopped).
    pub fn step(&mut self, dt_s: f64, joystick: Option<(i8, i8)>, mapping: &JoystickMapping) {
        let (v_cmd, w_cmd) = match joystick {
            Some((x, y)) => mapping.to_velocity(x, y),
            None => (0.0, 0.0),
        };
        let k = (dt_s / self.motor_tau_s).min(1.0);
        self.v_mps += (v_cmd - self.v_mps) * k;
        self.omega_radps += (w_cmd - self.omega_radps) * k;
        let (ds, dth) = (self.v_mps * dt_s, self.omega_radps * dt_s);
        self.truth = self.truth.advanced(ds, dth);
        // wheels: left and right arc lengths → counts (the board's signs)
        let d = &self.drive;
        let half = d.track_m / 2.0;
        let (sl, sr) = (ds - dth * half, ds + dth * half);
        // metres per count carry the board's count direction (sign)
        let (ml, mr) = d.metres_per_count();
        self.counts.0 += sl / ml;
        self.counts.1 += sr / mr;
        self.mcu_us += (dt_s * 1e6) as u64;
        self.report.truth = self.truth;
        self.report.v_mps = self.v_mps;
        self.report.omega_radps = self.omega_radps;
        self.report.distance_travelled_m += ds.abs();
        let here = [self.truth.x_m, self.truth.y_m];
        if self
            .trace
            .last()
            .is_none_or(|p| (p[0] - here[0]).hypot(p[1] - here[1]) >= 0.05)
        {
            self.trace.push(here);
        }
        self.walk(dt_s);
        let (c, nearest) = self.clearance_to();
        self.report.min_clearance_m = self.report.min_clearance_m.min(c);
        if c <= 0.0 {
            self.report.collision_steps += 1;
            if self.report.first_contact.is_none() {
                tracing::warn!(
                    time_s = self.mcu_us as f64 * 1e-6,
                    object = ?nearest,
                    v_mps = self.v_mps,
                    omega_radps = self.omega_radps,
                    "simulated world: the chair's footprint touched something"
                );
                self.report.first_contact = Some(Contact {
                    time_s: self.mcu_us as f64 * 1e-6,
                    object: nearest,
                    v_mps: self.v_mps,
                    omega_radps: self.omega_radps,
                });
            }
        }
        let dc = self.drop_clearance();
        self.report.min_drop_clearance_m = self.report.min_drop_clearance_m.min(dc);
        if dc <= 0.0 {
            self.report.fell_steps += 1;
        }
    }

    /// Moves the walking people on by `dt_s` (each waits while a step
    /// would take them nearer the chair within [`WALKER_KEEPS_M`], and
    /// after [`WALKER_GIVES_WAY_AFTER_S`] turns back).
    fn walk(&mut self, dt_s: f64) {
        if self.walkers.is_empty() {
            return;
        }
        let (f, pose) = (self.footprint, self.truth);
        for walking in self.walkers.iter_mut() {
            let (w, back) = (&walking.walker, &mut walking.back);
            let Some(o) = self.room.objects.get(w.object) else {
                continue;
            };
            let here = [o.min_m[0], o.min_m[1]];
            let goal = if *back { w.from_m } else { w.to_m };
            let (dx, dy) = (goal[0] - here[0], goal[1] - here[1]);
            let left = (dx * dx + dy * dy).sqrt();
            let step = (w.speed_mps * dt_s).min(left);
            let next = if left > 1e-9 {
                [here[0] + dx / left * step, here[1] + dy / left * step]
            } else {
                here
            };
            let (lo, hi) = (next, [next[0] + w.size_m[0], next[1] + w.size_m[1]]);
            let gap = |lo: [f64; 2], hi: [f64; 2]| footprint_gap(&f, &pose, lo, hi);
            // a step within the keep-out that takes them nearer the chair
            // waits (one away from it, or along it, is taken: the chair
            // may have come nearer than the keep-out to them, and a person
            // standing just before a waiting chair walks on past it rather
            // than wait there with it for good; along a chair turned a
            // little, each step nears it by a little of its length)
            let gap_next = gap(lo, hi);
            let nears = gap_next < WALKER_KEEPS_M && {
                let gap_here = gap(here, [here[0] + w.size_m[0], here[1] + w.size_m[1]]);
                let along = if gap_next >= WALKER_ALONG_FROM_M {
                    WALKER_ALONG_NEARS * step
                } else {
                    0.0
                };
                gap_next < gap_here - along
            };
            if nears {
                walking.waited_s += dt_s;
                if walking.waited_s >= WALKER_GIVES_WAY_AFTER_S {
                    *back = !*back;
                    walking.waited_s = 0.0;
                }
                continue;
            }
            walking.waited_s = 0.0;
            if let Some(o) = self.room.objects.get_mut(w.object) {
                o.min_m[0] = lo[0];
                o.min_m[1] = lo[1];
                o.max_m[0] = hi[0];
                o.max_m[1] = hi[1];
            }
            if left - step <= 1e-9 {
                *back = !*back;
            }
        }
    }

    /// The footprint's outline in the world, points 0.1 of a side apart
    /// (to draw it; distances to it are [`footprint_gap`]'s, exact).
    pub fn outline_world(&self) -> Vec<[f64; 2]> {
        let f = self.footprint;
        let (c, s) = (self.truth.theta_rad.cos(), self.truth.theta_rad.sin());
        let mut outline = Vec::new();
        for i in 0..=10 {
            let u = i as f64 / 10.0;
            let x = -f.rear_m + u * (f.front_m + f.rear_m);
            let y = -f.half_width_m + u * 2.0 * f.half_width_m;
            outline.extend([
                [x, f.half_width_m],
                [x, -f.half_width_m],
                [f.front_m, y],
                [-f.rear_m, y],
            ]);
        }
        outline
            .into_iter()
            .map(|q| {
                [
                    self.truth.x_m + c * q[0] - s * q[1],
                    self.truth.y_m + s * q[0] + c * q[1],
                ]
            })
            .collect()
    }

    /// Smallest distance from the footprint to the edge of a step down
    /// (negative: part of the chair is over it).
    pub fn drop_clearance(&self) -> f64 {
        self.room
            .pits
            .iter()
            .map(|pit| footprint_gap(&self.footprint, &self.truth, pit.min_m, pit.max_m))
            .fold(f64::INFINITY, f64::min)
    }

    /// What the encoder board would send now.
    pub fn wheel_ticks(&mut self) -> WheelTicks {
        self.seq = self.seq.wrapping_add(1);
        WheelTicks {
            seq: self.seq,
            mcu_time_us: self.mcu_us,
            left: self.counts.0.round() as i32,
            right: self.counts.1.round() as i32,
            left_illegal: 0,
            right_illegal: 0,
            gap: 0,
        }
    }

    /// A URG-04LX scan from the laser at `base_from_laser`.
    pub fn laser_scan(&self, base_from_laser: &Isometry3<f64>, sensor_ms: u32) -> LaserScan {
        let p = SensorParams::URG_04LX;
        LaserScan::from_values(&p, p.amin, &self.laser_values(base_from_laser), sensor_ms)
    }

    /// The ranges of [`SimWorld::laser_scan`], mm (0: no return), step by
    /// step from the first.
    pub fn laser_values(&self, base_from_laser: &Isometry3<f64>) -> Vec<u32> {
        let p = SensorParams::URG_04LX;
        let t = base_from_laser.translation.vector;
        let laser_yaw = base_from_laser.rotation.euler_angles().2;
        let (c, s) = (self.truth.theta_rad.cos(), self.truth.theta_rad.sin());
        let origin = [
            self.truth.x_m + c * t.x - s * t.y,
            self.truth.y_m + s * t.x + c * t.y,
        ];
        let segs = by_distance(origin, &segments_at(&self.room, t.z));
        (p.amin..=p.amax)
            .map(|step| {
                let a = self.truth.theta_rad + laser_yaw + p.step_angle_rad(step);
                match ray_cast_nearest_first(origin, a, &segs) {
                    Some(r) if r * 1000.0 <= p.dmax_mm as f64 => {
                        ((r * 1000.0).round() as u32).max(p.dmin_mm)
                    }
                    // no return: the URG's code for "nothing in range"
                    _ => 0,
                }
            })
            .collect()
    }

    /// The camera's pose in the world.
    pub fn world_from_camera(&self, base_from_camera: &Isometry3<f64>) -> Isometry3<f64> {
        let world_from_base = Isometry3::new(
            Vector3::new(self.truth.x_m, self.truth.y_m, 0.0),
            Vector3::z() * self.truth.theta_rad,
        );
        world_from_base * base_from_camera
    }

    pub fn render(
        &self,
        k: &Intrinsics,
        base_from_camera: &Isometry3<f64>,
    ) -> Result<Rendered, ImageError> {
        self.room
            .render(k, &self.world_from_camera(base_from_camera))
    }

    /// The true pose of the start (odometry origin) → world transform of a
    /// point in odometry coordinates.
    pub fn world_from_odom(&self, p: [f64; 2]) -> [f64; 2] {
        let (c, s) = (self.start.theta_rad.cos(), self.start.theta_rad.sin());
        [
            self.start.x_m + c * p[0] - s * p[1],
            self.start.y_m + s * p[0] + c * p[1],
        ]
    }

    /// Smallest distance from the chair's footprint to the walls and to
    /// objects taller than 5 cm (negative: overlapping).
    pub fn clearance(&self) -> f64 {
        self.clearance_to().0
    }

    /// [`Self::clearance`] and what is nearest: an object's index in the
    /// room, or None for a wall.
    pub fn clearance_to(&self) -> (f64, Option<usize>) {
        let [sx, sy, _] = self.room.size_m;
        let (f, pose) = (&self.footprint, &self.truth);
        // the room is convex, so the footprint's nearest point to a wall
        // is one of its corners
        let wall = footprint_corners(f, pose)
            .iter()
            .map(|p| p[0].min(p[1]).min(sx - p[0]).min(sy - p[1]))
            .fold(f64::INFINITY, f64::min);
        let mut best = (wall, None);
        // each object's distance from base_link less the footprint's reach
        // from it: the footprint is no nearer than that, so an object whose
        // bound is no nearer than the best so far is not measured (the
        // answer is the same)
        let here = [pose.x_m, pose.y_m];
        let reach_m = f.front_m.max(f.rear_m).hypot(f.half_width_m) + 1e-6;
        for (i, o) in self.room.objects.iter().enumerate() {
            if o.max_m[2] <= 0.05 {
                continue;
            }
            let (lo, hi) = ([o.min_m[0], o.min_m[1]], [o.max_m[0], o.max_m[1]]);
            if box_distance(lo, hi, here) - reach_m >= best.0 {
                continue;
            }
            let d = footprint_gap(f, pose, lo, hi);
            if d < best.0 {
                best = (d, Some(i));
            }
        }
        best
    }

    /// The world position of the nearest object labelled `label`, to
    /// judge arrival.
    pub fn nearest_object(&self, label: &str) -> Option<Point3<f64>> {
        self.room
            .objects
            .iter()
            .filter(|o| o.label.eq_ignore_ascii_case(label))
            .map(|o| {
                Point3::new(
                    (o.min_m[0] + o.max_m[0]) / 2.0,
                    (o.min_m[1] + o.max_m[1]) / 2.0,
                    (o.min_m[2] + o.max_m[2]) / 2.0,
                )
            })
            .min_by(|a, b| {
                let da = (a.x - self.truth.x_m).hypot(a.y - self.truth.y_m);
                let db = (b.x - self.truth.x_m).hypot(b.y - self.truth.y_m);
                da.total_cmp(&db)
            })
    }
}

#[cfg(test)]
#[path = "world_tests.rs"]
mod tests;
