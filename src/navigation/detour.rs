//! A way round what holds the planner (pure): when the safety supervisor
//! would hold the planner's command for something in its way, the control
//! step asks for the command, among a fan of arcs and turns on the spot,
//! that the supervisor would drive (the caller's `admits`, which is the
//! supervisor's own footprint check) and that brings the chair nearest its
//! aim. The MPC plans a point with a clearance; the supervisor checks the
//! chair's rectangle, its swept arc and its corners' circle: near furniture
//! the two disagree, and without this the chair stood still, held, until it
//! backed off and met the same hold again.

use crate::msg::VelocityCmd;

/// How far ahead a candidate is followed to score it, s.
pub const HORIZON_S: f64 = 1.5;
/// Metres of cost per radian of the end pose's bearing error to the aim:
/// facing the aim is worth a little, so a turn on the spot toward it can
/// win over standing still.
pub const BEARING_COST_M_PER_RAD: f64 = 0.3;
/// A detour must improve on standing still by this much, m.
pub const MIN_GAIN_M: f64 = 0.02;
/// The way's front point passing nearer than this to an obstacle point
/// costs [`NEAR_COST_PER_M`] per metre nearer, m.
pub const NEAR_M: f64 = 0.5;
pub const NEAR_COST_PER_M: f64 = 2.0;
/// From base_link to the point whose way is checked for nearness, m (the
/// middle of the chair's front edge).
pub const FRONT_M: f64 = 0.55;

/// The speeds a detour may use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetourLimits {
    pub v_forward_max_mps: f64,
    pub omega_max_radps: f64,
    /// The fastest turn on the spot that keeps the crawl's margin, rad/s.
    pub crawl_turn_radps: f64,
}

/// The command of candidate `c`, `t_s` into it, as [`predicted`] follows
/// it: an arc throughout; a turn on the spot for half the horizon, then
/// a crawl straight on at a third of `v_forward_max_mps` (what the control
/// step drives while it follows a detour it found).
pub fn command_at(c: &VelocityCmd, v_forward_max_mps: f64, t_s: f64) -> VelocityCmd {
    if c.v_mps.abs() < 0.05 && t_s >= HORIZON_S / 2.0 {
        VelocityCmd {
            v_mps: v_forward_max_mps / 3.0,
            omega_radps: 0.0,
        }
    } else {
        *c
    }
}

/// The pose a candidate is followed to after `t_s` of the horizon: the
/// arc itself, or for a turn on the spot, the turn for half the time and
/// then a crawl straight on (a turn is the first move of a way round).
fn predicted(c: &VelocityCmd, crawl_mps: f64, t_s: f64) -> (f64, f64, f64) {
    if c.v_mps.abs() < 0.05 {
        let turn_s = t_s.min(HORIZON_S / 2.0);
        let th = c.omega_radps * turn_s;
        let d = crawl_mps * (t_s - turn_s);
        (d * th.cos(), d * th.sin(), th)
    } else {
        let end = crate::msg::Pose2::unicycle_from_origin(c.v_mps, c.omega_radps, t_s);
        (end.x_m, end.y_m, end.theta_rad)
    }
}

/// The cost of ending at pose `(x, y, θ)` (base_link now) with the aim at
/// `aim_base`: the distance left plus the bearing error's weight.
fn cost(aim_base: [f64; 2], (x, y, th): (f64, f64, f64)) -> f64 {
    let (dx, dy) = (aim_base[0] - x, aim_base[1] - y);
    let bearing = crate::msg::wrap_angle(dy.atan2(dx) - th);
    dx.hypot(dy) + BEARING_COST_M_PER_RAD * bearing.abs()
}

/// What passing near the obstacle points costs on the way of a candidate
/// (its front point at eight times over the horizon).
fn nearness(c: &VelocityCmd, crawl_mps: f64, points_base: &[[f32; 2]]) -> f64 {
    const SAMPLES: usize = 8;
    // squared distances in the loop (one root at the end): this runs for
    // every candidate over every point, each control step the chair is held
    let fronts: [(f64, f64); SAMPLES] = std::array::from_fn(|i| {
        let (x, y, th) = predicted(c, crawl_mps, HORIZON_S * (i + 1) as f64 / SAMPLES as f64);
        (x + FRONT_M * th.cos(), y + FRONT_M * th.sin())
    });
    // a point outside the fronts' box widened by NEAR_M is farther than
    // NEAR_M from every front: it cannot change the cost
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for &(fx, fy) in &fronts {
        lo = [lo[0].min(fx - NEAR_M), lo[1].min(fy - NEAR_M)];
        hi = [hi[0].max(fx + NEAR_M), hi[1].max(fy + NEAR_M)];
    }
    let mut nearest_sq = f64::INFINITY;
    for p in points_base {
        let (px, py) = (p[0] as f64, p[1] as f64);
        if px < lo[0] || px > hi[0] || py < lo[1] || py > hi[1] {
            continue;
        }
        for &(fx, fy) in &fronts {
            let (dx, dy) = (px - fx, py - fy);
            nearest_sq = nearest_sq.min(dx * dx + dy * dy);
        }
    }
    NEAR_COST_PER_M * (NEAR_M - nearest_sq.sqrt()).max(0.0)
}

/// The candidates, cheapest first, each with its cost; only those better
/// than standing still by [`MIN_GAIN_M`]. `points_base`: what the chair
/// must not enter (base_link), so that of two ways the one clear of it
/// comes first.
pub fn candidates(
    aim_base: [f64; 2],
    l: &DetourLimits,
    points_base: &[[f32; 2]],
) -> Vec<(VelocityCmd, f64)> {
    let crawl = l.v_forward_max_mps / 3.0;
    let v_max = l.v_forward_max_mps;
    // Only points within NEAR_M of some candidate's front can cost
    // anything: a front point is never farther from base_link than the
    // fastest way's length plus FRONT_M (an arc's chord is no longer than
    // the arc), so the rest are left out once here, not per candidate.
    let reach_m = v_max.abs().max(crawl.abs()) * HORIZON_S + FRONT_M + NEAR_M;
    let reach_sq = reach_m * reach_m;
    let near_points: Vec<[f32; 2]> = points_base
        .iter()
        .filter(|p| {
            let (x, y) = (p[0] as f64, p[1] as f64);
            x * x + y * y <= reach_sq
        })
        .copied()
        .collect();
    let points_base = &near_points[..];
    let still =
        cost(aim_base, (0.0, 0.0, 0.0)) + nearness(&VelocityCmd::default(), 0.0, points_base);
    let w_max = l.omega_max_radps;
    let mut out = Vec::new();
    // forward arcs at four speeds (the slowest above the supervisor's
    // 5 cm/s turn-on-the-spot bound), thirteen curvatures each
    for v in [v_max, v_max * 2.0 / 3.0, v_max / 3.0, 0.06_f64.min(v_max)] {
        for k in -6..=6 {
            let w = w_max * k as f64 / 6.0;
            out.push(VelocityCmd {
                v_mps: v,
                omega_radps: w,
            });
        }
    }
    // turns on the spot, at a crawl and faster
    for w in [l.crawl_turn_radps, (2.0 * l.crawl_turn_radps).min(w_max)] {
        for s in [-1.0, 1.0] {
            out.push(VelocityCmd {
                v_mps: 0.0,
                omega_radps: s * w,
            });
        }
    }
    let mut scored: Vec<(VelocityCmd, f64)> = out
        .into_iter()
        .map(|c| {
            // a turn on the spot counts as good as its better end: facing
            // the aim, or on its way after the turn
            let end = cost(aim_base, predicted(&c, crawl, HORIZON_S));
            let turned = cost(aim_base, predicted(&c, crawl, HORIZON_S / 2.0));
            let c_end = if c.v_mps.abs() < 0.05 {
                end.min(turned)
            } else {
                end
            };
            (c, c_end + nearness(&c, crawl, points_base))
        })
        .filter(|(_, c)| *c < still - MIN_GAIN_M)
        .collect();
    scored.sort_by(|a, b| a.1.total_cmp(&b.1));
    scored
}

/// The cheapest candidate `admits` lets through (None: nothing better than
/// standing still is free).
pub fn detour(
    aim_base: [f64; 2],
    limits: &DetourLimits,
    points_base: &[[f32; 2]],
    mut admits: impl FnMut(&VelocityCmd) -> bool,
) -> Option<VelocityCmd> {
    candidates(aim_base, limits, points_base)
        .into_iter()
        .map(|(c, _)| c)
        .find(|c| admits(c))
}

#[cfg(test)]
mod tests {
    use super::*;

    const L: DetourLimits = DetourLimits {
        v_forward_max_mps: 0.3,
        omega_max_radps: 0.6,
        crawl_turn_radps: 0.15,
    };

    /// Followed as scored: a turn on the spot for half the horizon, then
    /// a crawl straight on; an arc throughout.
    #[test]
    fn a_detour_is_driven_as_it_was_scored() {
        let turn = VelocityCmd {
            v_mps: 0.0,
            omega_radps: 0.15,
        };
        let arc = VelocityCmd {
            v_mps: 0.1,
            omega_radps: -0.3,
        };
        let crawl = VelocityCmd {
            v_mps: 0.3 / 3.0,
            omega_radps: 0.0,
        };
        assert_eq!(command_at(&turn, 0.3, 0.0), turn);
        assert_eq!(command_at(&turn, 0.3, HORIZON_S / 2.0 - 0.05), turn);
        assert_eq!(command_at(&turn, 0.3, HORIZON_S / 2.0), crawl);
        for t in [0.0, HORIZON_S / 2.0, HORIZON_S - 0.05] {
            assert_eq!(command_at(&arc, 0.3, t), arc);
        }
    }

    #[test]
    fn straight_ahead_when_free() {
        let c = detour([3.0, 0.0], &L, &[], |_| true).expect("a detour");
        assert_eq!(c.v_mps, 0.3);
        assert_eq!(c.omega_radps, 0.0);
    }

    #[test]
    fn bends_round_what_holds_the_straight_way() {
        // everything that turns less than 0.2 rad/s is held
        let c = detour([3.0, 0.5], &L, &[], |c| c.omega_radps.abs() >= 0.2).expect("a detour");
        assert!(c.omega_radps > 0.0, "toward the aim's side: {c:?}");
        assert!(c.v_mps > 0.0);
    }

    #[test]
    fn turns_on_the_spot_toward_an_aim_behind() {
        // the aim straight behind, on the left: no forward arc gets nearer
        // in 1.5 s, a turn on the spot faces it
        let c = detour([-2.0, 0.1], &L, &[], |c| c.v_mps == 0.0).expect("a turn");
        assert_eq!(c.v_mps, 0.0);
        assert!(c.omega_radps > 0.0, "{c:?}");
    }

    #[test]
    fn with_only_turns_free_it_turns_away_from_what_is_in_the_way() {
        // a post ahead on the left, the aim straight ahead: turning right
        // and then on leaves it aside
        for post in [[0.84_f32, 0.2_f32], [0.8, 0.1]] {
            let c = detour([2.0, 0.0], &L, &[post], |c| c.v_mps == 0.0).expect("a turn");
            assert!(c.omega_radps < 0.0, "{post:?}: {c:?}");
            let mirrored = [post[0], -post[1]];
            let c = detour([2.0, 0.0], &L, &[mirrored], |c| c.v_mps == 0.0).expect("a turn");
            assert!(c.omega_radps > 0.0, "{mirrored:?}: {c:?}");
        }
    }

    #[test]
    fn nothing_when_all_is_held_or_nothing_helps() {
        assert_eq!(detour([3.0, 0.0], &L, &[], |_| false), None);
        // at the aim already: standing still is best
        assert_eq!(detour([0.0, 0.0], &L, &[], |_| true), None);
    }

    #[test]
    fn candidates_are_cheapest_first_and_all_better_than_standing_still() {
        let cs = candidates([2.0, -1.0], &L, &[]);
        assert!(!cs.is_empty());
        assert!(cs.windows(2).all(|w| w[0].1 <= w[1].1));
        let still = cost([2.0, -1.0], (0.0, 0.0, 0.0));
        assert!(cs.iter().all(|(_, c)| *c < still - MIN_GAIN_M));
        // never a reverse: backing off has its own rules (the trail)
        assert!(cs.iter().all(|(c, _)| c.v_mps >= 0.0));
    }

    #[test]
    fn leaving_out_far_points_changes_no_cost() {
        // the cost of every candidate against a cloud of points near and
        // far, as the full search over every point and front gives
        let mut rng = crate::sim::scene::SplitMix64::new(5);
        let pts: Vec<[f32; 2]> = (0..600)
            .map(|_| [rng.range(-3.0, 3.0) as f32, rng.range(-3.0, 3.0) as f32])
            .collect();
        let crawl = L.v_forward_max_mps / 3.0;
        let mut costly = 0;
        for v in [0.0, 0.06, 0.1, 0.2, 0.3] {
            for k in -6..=6 {
                let c = VelocityCmd {
                    v_mps: v,
                    omega_radps: L.omega_max_radps * k as f64 / 6.0,
                };
                let mut nearest_sq = f64::INFINITY;
                for i in 0..8 {
                    let (x, y, th) = predicted(&c, crawl, HORIZON_S * (i + 1) as f64 / 8.0);
                    let (fx, fy) = (x + FRONT_M * th.cos(), y + FRONT_M * th.sin());
                    for p in &pts {
                        let (dx, dy) = (p[0] as f64 - fx, p[1] as f64 - fy);
                        nearest_sq = nearest_sq.min(dx * dx + dy * dy);
                    }
                }
                let brute = NEAR_COST_PER_M * (NEAR_M - nearest_sq.sqrt()).max(0.0);
                assert_eq!(nearness(&c, crawl, &pts), brute, "{c:?}");
                costly += usize::from(brute > 0.0);
            }
        }
        assert!(costly > 10, "{costly}");
        // and the candidates with the far points left out as without them
        let far: Vec<[f32; 2]> = pts
            .iter()
            .filter(|p| p[0].hypot(p[1]) > 1.6)
            .copied()
            .collect();
        let near: Vec<[f32; 2]> = pts
            .iter()
            .filter(|p| p[0].hypot(p[1]) <= 1.6)
            .copied()
            .collect();
        assert!(!far.is_empty());
        assert_eq!(
            candidates([2.0, 1.0], &L, &pts),
            candidates([2.0, 1.0], &L, &near)
        );
    }
}
