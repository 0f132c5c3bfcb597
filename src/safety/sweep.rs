//! The chair's footprint as a rectangle about base_link, and what a turn
//! on the spot sweeps of the floor beside it in the next moment: the
//! corners swing out; what lies beside a side's middle, the side comes
//! only slowly nearer to.
//! Pure geometry, base_link (x forward, y left), metres and radians.

/// The footprint: `front` ahead of base_link, `rear` behind it, `half`
/// to each side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rect {
    pub front: f64,
    pub rear: f64,
    pub half: f64,
}

impl Rect {
    /// How far its farthest corner lies from base_link: the circle a turn
    /// on the spot sweeps.
    pub fn corner_reach_m(&self) -> f64 {
        self.front.max(self.rear).hypot(self.half)
    }

    /// The signed distance of `(qx, qy)` from the footprint (negative
    /// inside).
    pub fn gap(&self, qx: f64, qy: f64) -> f64 {
        let dx = (-self.rear - qx).max(qx - self.front);
        let dy = qy.abs() - self.half;
        if dx > 0.0 || dy > 0.0 {
            dx.max(0.0).hypot(dy.max(0.0))
        } else {
            dx.max(dy)
        }
    }

    /// Whether turning on the spot by up to `angle_rad` (the sign gives
    /// the direction: positive to the left) brings the footprint within
    /// `margin_m` of a point and nearer to it than it is now: the floor a
    /// corner sweeps into. A point the turn leaves as far away or moves
    /// away from (beside a side's middle, behind a corner) is not swept.
    pub fn turn_sweeps(&self, p: [f64; 2], angle_rad: f64, margin_m: f64) -> bool {
        let reach = self.corner_reach_m() + margin_m;
        if p[0] * p[0] + p[1] * p[1] > reach * reach {
            return false;
        }
        let now = self.gap(p[0], p[1]);
        let steps = (angle_rad.abs() / SWEEP_STEP_RAD).ceil().max(1.0) as usize;
        (1..=steps).any(|k| {
            // the footprint turned by phi: the point turned by −phi
            let phi = angle_rad * k as f64 / steps as f64;
            let (c, s) = (phi.cos(), phi.sin());
            let (qx, qy) = (c * p[0] + s * p[1], -s * p[0] + c * p[1]);
            let g = self.gap(qx, qy);
            g < margin_m && g < now - 1e-4
        })
    }
}

impl Rect {
    /// Whether driving the arc `(v_mps, omega_radps)` for up to `t_s`
    /// brings the footprint's sides or rear within `margin_m` of a point
    /// beside or behind it (not ahead of its front edge: that is the
    /// travel's own way) and nearer to it than it is now: the floor the
    /// rear corner swings over on a bend, beside the chair. A point under
    /// the footprint now, or one the arc leaves as far away, is not swept.
    pub fn arc_sweeps(
        &self,
        p: [f64; 2],
        v_mps: f64,
        omega_radps: f64,
        t_s: f64,
        margin_m: f64,
    ) -> bool {
        if p[0] > self.front {
            return false;
        }
        let now = self.gap(p[0], p[1]);
        if now <= 0.0 {
            return false;
        }
        // no nearer than the corners reach, plus what the arc moves
        let reach = self.corner_reach_m() + margin_m + v_mps.abs() * t_s;
        if p[0] * p[0] + p[1] * p[1] > reach * reach {
            return false;
        }
        let steps = ((omega_radps * t_s).abs() / SWEEP_STEP_RAD)
            .max((v_mps * t_s).abs() / SWEEP_STEP_M)
            .ceil()
            .max(1.0) as usize;
        (1..=steps).any(|k| {
            let pose = arc_pose(v_mps, omega_radps, t_s * k as f64 / steps as f64);
            let [qx, qy] = pose.to_footprint(p);
            let g = self.gap(qx, qy);
            g < margin_m && g < now - 1e-4
        })
    }
}

/// Where base_link is after driving the arc `(v_mps, omega_radps)` for
/// `t_s` from base_link now: the unicycle's exact arc (a straight line
/// when it does not turn).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcPose {
    pub x_m: f64,
    pub y_m: f64,
    pub cos: f64,
    pub sin: f64,
}

impl ArcPose {
    /// A point in base_link now, in the footprint's frame at this pose.
    pub fn to_footprint(&self, p: [f64; 2]) -> [f64; 2] {
        let (dx, dy) = (p[0] - self.x_m, p[1] - self.y_m);
        [
            self.cos * dx + self.sin * dy,
            -self.sin * dx + self.cos * dy,
        ]
    }
}

/// The pose after `t_s` of the arc `(v_mps, omega_radps)`.
pub fn arc_pose(v_mps: f64, omega_radps: f64, t_s: f64) -> ArcPose {
    let end = crate::msg::Pose2::unicycle_from_origin(v_mps, omega_radps, t_s);
    ArcPose {
        x_m: end.x_m,
        y_m: end.y_m,
        cos: end.theta_rad.cos(),
        sin: end.theta_rad.sin(),
    }
}

/// The turn is sampled every this many radians (1.3 cm at the corners).
const SWEEP_STEP_RAD: f64 = 0.02;
/// An arc is sampled at least every this many metres along it.
const SWEEP_STEP_M: f64 = 0.01;

#[cfg(test)]
mod tests {
    use super::*;

    const CHAIR: Rect = Rect {
        front: 0.55,
        rear: 0.45,
        half: 0.35,
    };

    #[test]
    fn the_arc_pose_follows_the_unicycle() {
        // a quarter circle of radius 1 m to the left: 1 m on, 1 m left,
        // turned a quarter
        let q = arc_pose(0.2, 0.2, std::f64::consts::FRAC_PI_2 / 0.2);
        assert!(
            (q.x_m - 1.0).abs() < 1e-12 && (q.y_m - 1.0).abs() < 1e-12,
            "{q:?}"
        );
        assert!(q.cos.abs() < 1e-12 && (q.sin - 1.0).abs() < 1e-12, "{q:?}");
        // a point 1 m ahead of the start lies 1 m straight behind the
        // footprint there (it faces the start's left now); the start
        // itself 1 m behind and 1 m to its left
        let [fx, fy] = q.to_footprint([1.0, 0.0]);
        assert!((fx + 1.0).abs() < 1e-12 && fy.abs() < 1e-12, "{fx} {fy}");
        let [sx, sy] = q.to_footprint([0.0, 0.0]);
        assert!(
            (sx + 1.0).abs() < 1e-12 && (sy - 1.0).abs() < 1e-12,
            "{sx} {sy}"
        );
        // straight on, and backwards, without a turn
        let s = arc_pose(0.3, 0.0, 2.0);
        assert!(
            (s.x_m - 0.6).abs() < 1e-12 && s.y_m == 0.0 && s.cos == 1.0,
            "{s:?}"
        );
        let b = arc_pose(-0.15, 0.0, 2.0);
        assert!((b.x_m + 0.3).abs() < 1e-12 && b.y_m == 0.0, "{b:?}");
        // turning on the spot: it stays, turned
        let t = arc_pose(0.0, -0.5, 1.0);
        assert!(
            t.x_m == 0.0 && t.y_m == 0.0 && (t.sin + 0.5f64.sin()).abs() < 1e-12,
            "{t:?}"
        );
    }

    #[test]
    fn the_gap_is_signed() {
        assert!((CHAIR.gap(0.65, 0.0) - 0.10).abs() < 1e-12);
        assert!((CHAIR.gap(0.0, -0.40) - 0.05).abs() < 1e-12);
        assert!((CHAIR.gap(0.58, 0.39) - 0.05).abs() < 1e-12);
        assert!((CHAIR.gap(0.0, 0.0) + 0.35).abs() < 1e-12);
    }

    /// Turning left, the front-left corner swings out to the left and the
    /// front-right corner forward; a point ahead of the front-left corner
    /// is not swept, and one beside the left side's middle only when the
    /// side comes within the margin of it.
    #[test]
    fn a_turn_sweeps_what_its_corners_swing_into() {
        let angle = 0.3;
        // beside the front-left corner, on its way
        assert!(CHAIR.turn_sweeps([0.45, 0.40], angle, 0.03));
        // ahead of the front-right corner, on its way
        assert!(CHAIR.turn_sweeps([0.60, -0.25], angle, 0.03));
        // beside the left side's middle: the side turns a little towards
        // it (4.4 cm from 10 cm away), not within the margin
        assert!(!CHAIR.turn_sweeps([0.0, 0.45], angle, 0.03));
        // 3 cm away, within it at once: closer as the side turns
        assert!(CHAIR.turn_sweeps([0.0, 0.38], angle, 0.03));
        // ahead of the front-left corner: it swings away
        assert!(!CHAIR.turn_sweeps([0.60, 0.30], angle, 0.03));
        // the other way round, the roles change
        assert!(CHAIR.turn_sweeps([0.60, 0.30], -angle, 0.03));
        assert!(!CHAIR.turn_sweeps([0.60, -0.25], -angle, 0.03));
        // beyond what the corners reach in the angle
        assert!(!CHAIR.turn_sweeps([0.10, 0.60], angle, 0.03));
        // a whole turn reaches it
        assert!(CHAIR.turn_sweeps([0.10, 0.60], std::f64::consts::PI, 0.03));
        // beyond the corners' circle: never
        assert!(!CHAIR.turn_sweeps([0.0, 0.70], std::f64::consts::TAU, 0.03));
    }

    /// On a forward bend to the right, the rear-left corner swings out to
    /// the left: a point beside it is swept; the same point is not on a
    /// bend to the left (the rear swings away), nor one beside the left
    /// side's middle that the side passes, nor one ahead of the front
    /// edge (the travel's own way), nor one under the chair.
    #[test]
    fn a_bend_sweeps_what_its_rear_corner_swings_into() {
        let (v, t, m) = (0.09, 0.8, 0.03);
        // beside the rear-left corner, 1 cm out
        assert!(CHAIR.arc_sweeps([-0.40, 0.36], v, -0.25, t, m));
        assert!(!CHAIR.arc_sweeps([-0.40, 0.36], v, 0.25, t, m));
        // 5 cm out behind the corner: it swings 0.45 · 0.2 = 9 cm out
        // while moving 7 cm on, to 4.3 cm of it: within a 5 cm margin,
        // not a 3 cm one
        assert!(CHAIR.arc_sweeps([-0.45, 0.40], v, -0.25, t, 0.05));
        assert!(!CHAIR.arc_sweeps([-0.45, 0.40], v, -0.25, t, m));
        // 20 cm out: beyond the swing and the margin
        assert!(!CHAIR.arc_sweeps([-0.40, 0.55], v, -0.25, t, 0.05));
        // beside the middle of the left side, 5 cm out: the side moves
        // along it and turns away from it
        assert!(!CHAIR.arc_sweeps([0.05, 0.40], v, -0.25, t, m));
        // ahead of the front edge: the corridor's, not this
        assert!(!CHAIR.arc_sweeps([0.60, 0.30], v, 0.25, t, m));
        // under the chair
        assert!(!CHAIR.arc_sweeps([-0.40, 0.30], v, -0.25, t, m));
        // straight on, nothing beside is swept
        assert!(!CHAIR.arc_sweeps([-0.40, 0.36], v, 0.0, t, m));
    }
}
