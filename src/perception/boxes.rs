//! Step 6: 3D boxes of object clouds (axis-aligned as in the paper, and
//! oriented about the gravity axis), 3D IoU, and the cross-view merge.

use super::hull::{convex_hull, hull_candidates, min_area_rect};
use super::sweep::{ground_lanes, Ground, Sweep};
use nalgebra::Point3;
use serde::Serialize;

use crate::msg::Frame;

/// Axis-aligned box, metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Aabb {
    pub min_m: [f64; 3],
    pub max_m: [f64; 3],
}

impl Aabb {
    pub fn from_points(points: &[Point3<f32>]) -> Option<Aabb> {
        let first = points.first()?;
        let mut min = [first.x, first.y, first.z];
        let mut max = min;
        // plain comparisons (not f32::min, whose NaN rules are slow); the
        // points come from finite depths
        for p in points {
            let c = [p.x, p.y, p.z];
            for k in 0..3 {
                min[k] = if c[k] < min[k] { c[k] } else { min[k] };
                max[k] = if c[k] > max[k] { c[k] } else { max[k] };
            }
        }
        Some(Aabb {
            min_m: min.map(f64::from),
            max_m: max.map(f64::from),
        })
    }

    pub fn center_m(&self) -> [f64; 3] {
        std::array::from_fn(|i| 0.5 * (self.min_m[i] + self.max_m[i]))
    }

    pub fn size_m(&self) -> [f64; 3] {
        std::array::from_fn(|i| self.max_m[i] - self.min_m[i])
    }

    pub fn volume_m3(&self) -> f64 {
        self.size_m().iter().product()
    }

    /// Volume of the intersection with `other`, m³.
    pub fn intersection_m3(&self, other: &Aabb) -> f64 {
        let mut inter = 1.0;
        for i in 0..3 {
            let lo = self.min_m[i].max(other.min_m[i]);
            let hi = self.max_m[i].min(other.max_m[i]);
            if hi <= lo {
                return 0.0;
            }
            inter *= hi - lo;
        }
        inter
    }

    /// Intersection over union of two boxes (0 when both are empty).
    pub fn iou(&self, other: &Aabb) -> f64 {
        let inter = self.intersection_m3(other);
        let union = self.volume_m3() + other.volume_m3() - inter;
        if inter <= 0.0 || union <= 0.0 {
            0.0
        } else {
            inter / union
        }
    }

    /// Intersection over the smaller box's volume: 1 when one box lies
    /// inside the other.
    pub fn containment(&self, other: &Aabb) -> f64 {
        let inter = self.intersection_m3(other);
        let small = self.volume_m3().min(other.volume_m3());
        if inter <= 0.0 || small <= 0.0 {
            0.0
        } else {
            inter / small
        }
    }
}

/// A box oriented about the frame's z axis (gravity in `base_link`/`odom`):
/// `size_m` = (length along `yaw_rad`, width across it, height).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OrientedBox {
    pub center_m: [f64; 3],
    pub size_m: [f64; 3],
    pub yaw_rad: f64,
}

impl OrientedBox {
    /// A ground point (x, y in the box's frame) in the box's own axes:
    /// along its length, across it, from its centre.
    pub fn ground_local(&self, p: [f64; 2]) -> [f64; 2] {
        let (c, s) = (self.yaw_rad.cos(), self.yaw_rad.sin());
        let (x, y) = (p[0] - self.center_m[0], p[1] - self.center_m[1]);
        [x * c + y * s, -x * s + y * c]
    }

    /// Whether a ground point lies within the box's outline.
    pub fn ground_contains(&self, p: [f64; 2]) -> bool {
        let [x, y] = self.ground_local(p);
        x.abs() <= self.size_m[0] / 2.0 && y.abs() <= self.size_m[1] / 2.0
    }

    /// From a ground point to the box's outline (0 within it), m.
    pub fn ground_distance_m(&self, p: [f64; 2]) -> f64 {
        let gap = |d: f64, half: f64| (d.abs() - half).max(0.0);
        let [x, y] = self.ground_local(p);
        gap(x, self.size_m[0] / 2.0).hypot(gap(y, self.size_m[1] / 2.0))
    }

    /// From a ground point inside the box along direction `dir_rad`
    /// (the box's frame) to where its outline ends, m.
    pub fn ground_exit_m(&self, p: [f64; 2], dir_rad: f64) -> f64 {
        let [x, y] = self.ground_local(p);
        let (c, s) = (self.yaw_rad.cos(), self.yaw_rad.sin());
        let (dx, dy) = (
            dir_rad.cos() * c + dir_rad.sin() * s,
            -dir_rad.cos() * s + dir_rad.sin() * c,
        );
        let exit = |p: f64, d: f64, half: f64| {
            if d > 1e-9 {
                (half - p) / d
            } else if d < -1e-9 {
                (-half - p) / d
            } else {
                f64::INFINITY
            }
        };
        exit(x, dx, self.size_m[0] / 2.0).min(exit(y, dy, self.size_m[1] / 2.0))
    }

    /// The minimum-area rectangle of the points' ground projection (rotating
    /// calipers over the convex hull), extruded from min z to max z. The yaw
    /// is the direction of the longer side, in (−π/2, π/2].
    pub fn from_points(points: &[Point3<f32>]) -> Option<OrientedBox> {
        let sweep = Sweep::of(points)?;
        Some(Self::from_sweep(points, &sweep, None))
    }

    /// As [`from_points`](Self::from_points) when the points' axis-aligned
    /// box is known (its z range is the box's height).
    pub fn from_points_and_aabb(points: &[Point3<f32>], aabb: &Aabb) -> OrientedBox {
        match Sweep::of(points) {
            Some(sweep) => Self::from_sweep(points, &sweep, None).with_height(aabb),
            None => OrientedBox {
                center_m: [0.0, 0.0, 0.5 * (aabb.min_m[2] + aabb.max_m[2])],
                size_m: [0.0, 0.0, aabb.max_m[2] - aabb.min_m[2]],
                yaw_rad: 0.0,
            },
        }
    }

    /// The box's height from `aabb`'s z range.
    fn with_height(mut self, aabb: &Aabb) -> OrientedBox {
        let (zmin, zmax) = (aabb.min_m[2], aabb.max_m[2]);
        self.center_m[2] = 0.5 * (zmin + zmax);
        self.size_m[2] = zmax - zmin;
        self
    }

    fn from_sweep(points: &[Point3<f32>], sweep: &Sweep, ground: Option<Ground>) -> OrientedBox {
        let (zmin, zmax) = (sweep.min[2] as f64, sweep.max[2] as f64);
        let hull = convex_hull(hull_candidates(points, sweep, ground));
        let (cx, cy, len, wid, yaw) = min_area_rect(&hull);
        OrientedBox {
            center_m: [cx, cy, 0.5 * (zmin + zmax)],
            size_m: [len, wid, zmax - zmin],
            yaw_rad: yaw,
        }
    }
}
/// A detected object in 3D.
#[derive(Debug, Clone, PartialEq)]
pub struct Object3D {
    pub label: String,
    pub score: f32,
    pub frame: Frame,
    pub points: Vec<Point3<f32>>,
    pub aabb: Aabb,
    pub obb: OrientedBox,
    /// The 2D box it came from (colour pixels), when from one view.
    pub box_xyxy: Option<[f32; 4]>,
}

impl Object3D {
    /// Builds an object from its points; None when there are none.
    pub fn from_points(
        label: String,
        score: f32,
        frame: Frame,
        points: Vec<Point3<f32>>,
        box_xyxy: Option<[f32; 4]>,
    ) -> Option<Object3D> {
        // one pass for the bounds and the hull's extreme points
        let lanes = ground_lanes(&points);
        let (sweep, blocks) = Sweep::of_lanes(&points, &lanes);
        let ground = Ground {
            lanes: &lanes,
            blocks: &blocks,
        };
        Some(Self::from_swept_points(
            label,
            score,
            frame,
            points,
            &sweep?,
            Some(ground),
            box_xyxy,
        ))
    }

    /// As [`from_points`](Self::from_points) with the points' sweep made
    /// already, and their ground lanes when made (as the fused steps 3–5
    /// make both).
    pub(crate) fn from_swept_points(
        label: String,
        score: f32,
        frame: Frame,
        points: Vec<Point3<f32>>,
        sweep: &Sweep,
        ground: Option<Ground>,
        box_xyxy: Option<[f32; 4]>,
    ) -> Object3D {
        let aabb = sweep.aabb();
        let obb = OrientedBox::from_sweep(&points, sweep, ground);
        Object3D {
            label,
            score,
            frame,
            points,
            aabb,
            obb,
            box_xyxy,
        }
    }
}

/// Objects seen from the chair at `pose` (in `base_link`), placed in
/// `odom`; an object with no points is left out.
pub fn objects_in_odom(pose: crate::msg::Pose2, objects: Vec<Object3D>) -> Vec<Object3D> {
    let odom_from_base = pose.to_isometry3();
    objects
        .into_iter()
        .filter_map(|o| {
            let pts = o
                .points
                .iter()
                .map(|p| (odom_from_base * p.cast::<f64>()).cast::<f32>())
                .collect();
            Object3D::from_points(o.label, o.score, Frame::Odom, pts, o.box_xyxy)
        })
        .collect()
}

/// When two same-label objects are one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MergeRule {
    /// Merge when the boxes' 3D IoU exceeds this (the paper: 0.8).
    pub iou: f64,
    /// Also merge when the intersection exceeds this fraction of the
    /// smaller box (a fragment seen from a truncated view lies inside the
    /// whole); None: the paper's rule alone.
    pub containment: Option<f64>,
}

impl MergeRule {
    /// The paper's cross-view merge: same label, 3D IoU > `iou`.
    pub fn paper(iou: f64) -> Self {
        MergeRule {
            iou,
            containment: None,
        }
    }

    pub fn joins(&self, a: &Aabb, b: &Aabb) -> bool {
        a.iou(b) > self.iou || self.containment.is_some_and(|c| a.containment(b) > c)
    }
}

/// Cross-view merge: objects of the same label (and frame) whose boxes'
/// 3D IoU exceeds `iou_threshold` become one (union of points, boxes
/// recomputed, highest score kept). Repeats until no pair qualifies, so
/// chains of overlapping fragments collapse; order of the survivors follows
/// the first member of each group.
pub fn merge_objects(objects: Vec<Object3D>, iou_threshold: f64) -> Vec<Object3D> {
    merge_objects_by(objects, &MergeRule::paper(iou_threshold))
}

/// [`merge_objects`] with any [`MergeRule`].
pub fn merge_objects_by(objects: Vec<Object3D>, rule: &MergeRule) -> Vec<Object3D> {
    let mut objs = objects;
    loop {
        let mut merged_any = false;
        let mut out: Vec<Object3D> = Vec::with_capacity(objs.len());
        for o in objs {
            let hit = out
                .iter_mut()
                .find(|m| m.label == o.label && m.frame == o.frame && rule.joins(&m.aabb, &o.aabb));
            match hit {
                Some(m) => {
                    m.points.extend_from_slice(&o.points);
                    m.score = m.score.max(o.score);
                    if let Some(a) = Aabb::from_points(&m.points) {
                        m.obb = OrientedBox::from_points_and_aabb(&m.points, &a);
                        m.aabb = a;
                    }
                    m.box_xyxy = None;
                    merged_any = true;
                }
                None => out.push(o),
            }
        }
        objs = out;
        if !merged_any {
            return objs;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(min: [f32; 3], max: [f32; 3]) -> Vec<Point3<f32>> {
        let mut v = Vec::new();
        for &x in &[min[0], max[0]] {
            for &y in &[min[1], max[1]] {
                for &z in &[min[2], max[2]] {
                    v.push(Point3::new(x, y, z));
                }
            }
        }
        v
    }

    #[test]
    fn aabb_center_size_and_iou_are_exact() {
        let a = Aabb::from_points(&cube([0.0, 0.0, 0.0], [2.0, 1.0, 1.0])).unwrap();
        assert_eq!(a.center_m(), [1.0, 0.5, 0.5]);
        assert_eq!(a.size_m(), [2.0, 1.0, 1.0]);
        let b = Aabb::from_points(&cube([1.0, 0.0, 0.0], [3.0, 1.0, 1.0])).unwrap();
        // inter 1, union 2 + 2 − 1 = 3
        assert!((a.iou(&b) - 1.0 / 3.0).abs() < 1e-12);
        assert_eq!(a.iou(&a), 1.0);
        let c = Aabb::from_points(&cube([5.0, 5.0, 5.0], [6.0, 6.0, 6.0])).unwrap();
        assert_eq!(a.iou(&c), 0.0);
    }

    #[test]
    fn oriented_box_recovers_a_rotated_rectangle() {
        // a 2 m × 0.5 m rectangle rotated by 30°, centred at (1, −1), z 0..0.8
        let yaw = 30f64.to_radians();
        let (c, s) = (yaw.cos(), yaw.sin());
        let mut pts = Vec::new();
        for i in 0..=20 {
            for j in 0..=5 {
                let a = -1.0 + 2.0 * i as f64 / 20.0;
                let b = -0.25 + 0.5 * j as f64 / 5.0;
                for z in [0.0, 0.8] {
                    pts.push(Point3::new(
                        (1.0 + a * c - b * s) as f32,
                        (-1.0 + a * s + b * c) as f32,
                        z,
                    ));
                }
            }
        }
        let o = OrientedBox::from_points(&pts).unwrap();
        assert!((o.yaw_rad - yaw).abs() < 1e-5, "{}", o.yaw_rad);
        assert!((o.size_m[0] - 2.0).abs() < 1e-5 && (o.size_m[1] - 0.5).abs() < 1e-5);
        assert!((o.size_m[2] - 0.8).abs() < 1e-6);
        assert!((o.center_m[0] - 1.0).abs() < 1e-5 && (o.center_m[1] + 1.0).abs() < 1e-5);
    }

    #[test]
    fn oriented_box_of_degenerate_input() {
        let one = [Point3::new(1.0f32, 2.0, 3.0)];
        let o = OrientedBox::from_points(&one).unwrap();
        assert_eq!(o.center_m, [1.0, 2.0, 3.0]);
        assert_eq!(o.size_m, [0.0, 0.0, 0.0]);
        let line = [Point3::new(0.0f32, 0.0, 0.0), Point3::new(0.0, 2.0, 0.0)];
        let o = OrientedBox::from_points(&line).unwrap();
        assert!((o.size_m[0] - 2.0).abs() < 1e-12 && o.size_m[1] == 0.0);
        assert!((o.yaw_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
        assert!(OrientedBox::from_points(&[]).is_none());
    }

    fn obj(label: &str, min: [f32; 3], max: [f32; 3], score: f32) -> Object3D {
        Object3D::from_points(label.into(), score, Frame::Odom, cube(min, max), None).unwrap()
    }

    #[test]
    fn merge_joins_overlapping_same_label_only() {
        let objs = vec![
            obj("chair", [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], 0.5),
            obj("chair", [0.05, 0.0, 0.0], [1.05, 1.0, 1.0], 0.9), // IoU 0.905
            obj("table", [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], 0.7),   // other label
            obj("chair", [3.0, 0.0, 0.0], [4.0, 1.0, 1.0], 0.6),   // other instance
            obj("chair", [0.5, 0.0, 0.0], [1.5, 1.0, 1.0], 0.6),   // IoU 0.33: apart
        ];
        let m = merge_objects(objs, 0.8);
        assert_eq!(m.len(), 4);
        assert_eq!(m[0].label, "chair");
        assert_eq!(m[0].points.len(), 16);
        assert_eq!(m[0].score, 0.9);
        assert_eq!(m[0].aabb.min_m, [0.0, 0.0, 0.0]);
        assert!((m[0].aabb.max_m[0] - 1.05).abs() < 1e-6);
        assert_eq!(m[1].label, "table");
        assert_eq!(m[2].aabb.min_m[0], 3.0);
        assert_eq!(m[3].aabb.min_m[0], 0.5);
    }

    #[test]
    fn containment_rule_joins_a_fragment_inside_the_whole() {
        let objs = vec![
            obj("sofa", [0.0, 0.0, 0.0], [2.0, 1.0, 1.0], 0.5),
            obj("sofa", [0.1, 0.1, 0.1], [0.6, 0.9, 0.9], 0.7), // inside, IoU 0.16
        ];
        assert_eq!(merge_objects(objs.clone(), 0.8).len(), 2);
        let rule = MergeRule {
            iou: 0.8,
            containment: Some(0.8),
        };
        let m = merge_objects_by(objs, &rule);
        assert_eq!(m.len(), 1);
        assert_eq!(m[0].score, 0.7);
        assert_eq!(m[0].aabb.max_m, [2.0, 1.0, 1.0]);
    }

    #[test]
    fn merge_is_strictly_greater_than_threshold() {
        // IoU exactly 0.75: [0,1] vs [0,0.75] in x → 0.75 / 1.0
        let objs = vec![
            obj("a", [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], 0.5),
            obj("a", [0.0, 0.0, 0.0], [0.75, 1.0, 1.0], 0.5),
        ];
        assert_eq!(merge_objects(objs.clone(), 0.75).len(), 2);
        assert_eq!(merge_objects(objs, 0.7499).len(), 1);
    }

    #[test]
    fn a_turned_box_is_left_where_its_outline_ends() {
        // 2 × 1 m, turned 30°, centred at (1, 2)
        let b = OrientedBox {
            center_m: [1.0, 2.0, 0.5],
            size_m: [2.0, 1.0, 1.0],
            yaw_rad: 30f64.to_radians(),
        };
        let centre = [1.0, 2.0];
        // along its length and across it, from the centre: the half sizes
        assert!((b.ground_exit_m(centre, 30f64.to_radians()) - 1.0).abs() < 1e-12);
        assert!((b.ground_exit_m(centre, 120f64.to_radians()) - 0.5).abs() < 1e-12);
        assert!((b.ground_exit_m(centre, -150f64.to_radians()) - 1.0).abs() < 1e-12);
        // along odom's x axis the 0.5 m half width ends it: 0.5 / sin 30°
        assert!((b.ground_exit_m(centre, 0.0) - 1.0).abs() < 1e-12);
        // and where it ends, the point is on the outline
        for dir in [0.3, 1.1, 2.5, -0.7] {
            let r = b.ground_exit_m(centre, dir);
            let edge = [centre[0] + r * f64::cos(dir), centre[1] + r * f64::sin(dir)];
            assert!(b.ground_contains([edge[0] - 1e-9 * dir.cos(), edge[1] - 1e-9 * dir.sin()]));
            assert!(!b.ground_contains([edge[0] + 1e-6 * dir.cos(), edge[1] + 1e-6 * dir.sin()]));
            assert!(b.ground_distance_m(edge) < 1e-9);
        }
        // from a point off the centre, along the length
        assert!((b.ground_exit_m(b_point(&b, 0.5, 0.0), 30f64.to_radians()) - 0.5).abs() < 1e-12);
    }

    /// The ground point `along` m along the box's length and `across` m
    /// across it from its centre.
    fn b_point(b: &OrientedBox, along: f64, across: f64) -> [f64; 2] {
        let (c, s) = (b.yaw_rad.cos(), b.yaw_rad.sin());
        [
            b.center_m[0] + along * c - across * s,
            b.center_m[1] + along * s + across * c,
        ]
    }

    #[test]
    fn an_upright_box_measures_the_gap_to_its_sides() {
        let b = OrientedBox {
            center_m: [1.0, 2.0, 0.5],
            size_m: [2.0, 1.0, 1.0],
            yaw_rad: 0.0,
        };
        // beside a side, beyond a corner, inside
        assert_eq!(b.ground_distance_m([3.0, 2.2]), 1.0);
        assert!((b.ground_distance_m([3.0, 3.5]) - 2f64.sqrt()).abs() < 1e-12);
        assert_eq!(b.ground_distance_m([1.5, 2.1]), 0.0);
    }
}
