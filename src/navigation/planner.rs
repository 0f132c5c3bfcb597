//! The 20 Hz planner step: the potential field gives the direction and
//! speed to track, the MPC plans within the chair's bounds and around
//! obstacles; a failed solve falls back to the field at reduced speed, and
//! repeated failures stop the chair. Every outcome is counted.

use nalgebra::{Isometry2, Point2, Vector2};
use serde::Serialize;

use super::apf::{apf, ApfParams};
use super::grid::ProximityGrid;
use super::mpc::{solve, MpcParams, MpcProblem, UnicycleState};
use crate::msg::Obstacles;
use crate::msg::VelocityCmd;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum CommandSource {
    Mpc,
    /// The MPC failed: the potential field, slowed down.
    ApfFallback,
    /// Repeated MPC failures, or the goal reached.
    Stop,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlanOutput {
    pub cmd: VelocityCmd,
    pub source: CommandSource,
    pub goal_distance_m: f64,
    pub reached: bool,
    /// The MPC's predicted positions (odom); empty when it did not solve.
    pub path_odom: Vec<[f64; 2]>,
}

#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize)]
pub struct PlannerStats {
    pub cycles: u64,
    pub mpc_solved: u64,
    pub mpc_failed: u64,
    pub fallbacks: u64,
    pub stops: u64,
    /// Solves whose front disc ([`MpcParams::front_disc_m`]) left no plan:
    /// the plan was the one without it.
    pub front_disc_dropped: u64,
}

#[derive(Debug, Clone)]
pub struct Planner {
    pub mpc: MpcParams,
    pub apf: ApfParams,
    pub grid: ProximityGrid,
    /// Consecutive MPC failures that stop the chair.
    pub max_failures: u32,
    /// Speed factor of the fallback.
    pub fallback_speed_factor: f64,
    /// Closer than this to the goal: reached, m.
    pub goal_tolerance_m: f64,
    failures_in_row: u32,
    pub stats: PlannerStats,
}

impl Planner {
    pub fn new(mpc: MpcParams, apf: ApfParams) -> Self {
        Planner {
            mpc,
            apf,
            grid: ProximityGrid::paper(),
            max_failures: 5,
            fallback_speed_factor: 0.5,
            goal_tolerance_m: 0.1,
            failures_in_row: 0,
            stats: PlannerStats::default(),
        }
    }

    /// One cycle: `state` in odom, `goal_odom` the approach position,
    /// `obstacles` in base_link (as the lasers give them).
    pub fn step(
        &mut self,
        state: UnicycleState,
        goal_odom: [f64; 2],
        obstacles: &Obstacles,
    ) -> PlanOutput {
        self.stats.cycles += 1;
        let odom_from_base = Isometry2::new(Vector2::new(state.x_m, state.y_m), state.theta_rad);
        let goal_base = odom_from_base.inverse() * Point2::new(goal_odom[0], goal_odom[1]);
        let dist = goal_base.coords.norm();
        if dist < self.goal_tolerance_m {
            return PlanOutput {
                cmd: VelocityCmd::default(),
                source: CommandSource::Stop,
                goal_distance_m: dist,
                reached: true,
                path_odom: Vec::new(),
            };
        }
        self.grid.update(obstacles);
        let bearing = goal_base.y.atan2(goal_base.x);
        let field = apf(&self.grid, Some(bearing), &self.apf);
        let obstacles_odom: Vec<[f64; 2]> = obstacles
            .points_base
            .iter()
            .map(|p| {
                let q = odom_from_base * Point2::new(p[0] as f64, p[1] as f64);
                [q.x, q.y]
            })
            .collect();
        let problem = MpcProblem {
            state,
            goal: goal_odom,
            heading_ref_rad: Some(state.theta_rad + bearing),
            v_ref_mps: field.v_mps.max(0.0),
            obstacles: obstacles_odom,
        };
        let mut path_odom = Vec::new();
        let (cmd, source) = match solve(&problem, &self.mpc) {
            Ok(plan) => {
                self.stats.mpc_solved += 1;
                if self.mpc.front_disc_m > 0.0 && !plan.front_disc {
                    self.stats.front_disc_dropped += 1;
                    tracing::debug!(
                        dropped = self.stats.front_disc_dropped,
                        "MPC: no plan with the front disc; the plan without it"
                    );
                }
                self.failures_in_row = 0;
                path_odom = plan.states.iter().map(|s| [s.x_m, s.y_m]).collect();
                (plan.cmd, CommandSource::Mpc)
            }
            Err(e) => {
                self.stats.mpc_failed += 1;
                self.failures_in_row += 1;
                if self.failures_in_row >= self.max_failures {
                    self.stats.stops += 1;
                    tracing::warn!(error = %e, failures = self.failures_in_row, "MPC failing repeatedly: stop");
                    (VelocityCmd::default(), CommandSource::Stop)
                } else {
                    self.stats.fallbacks += 1;
                    tracing::warn!(error = %e, "MPC failed: potential field at reduced speed");
                    (
                        VelocityCmd {
                            v_mps: field.v_mps * self.fallback_speed_factor,
                            omega_radps: field.omega_radps,
                        },
                        CommandSource::ApfFallback,
                    )
                }
            }
        };
        PlanOutput {
            cmd,
            source,
            goal_distance_m: dist,
            reached: false,
            path_odom,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn open_space_uses_the_mpc_and_reaches_the_goal() {
        let mut p = Planner::new(
            crate::config::Settings::defaults().mpc,
            crate::config::Settings::defaults().field,
        );
        let mut s = UnicycleState::default();
        let goal = [2.0, 1.0];
        let mut reached = false;
        for _ in 0..400 {
            let o = p.step(s, goal, &Obstacles::default());
            if o.reached {
                reached = true;
                break;
            }
            assert_eq!(o.source, CommandSource::Mpc);
            // the chair follows the command exactly (unicycle, 0.1 s)
            let (v, w) = (o.cmd.v_mps, o.cmd.omega_radps);
            s.x_m += v * 0.1 * (s.theta_rad + w * 0.05).cos();
            s.y_m += v * 0.1 * (s.theta_rad + w * 0.05).sin();
            s.theta_rad += w * 0.1;
            s.v_mps = v;
            s.omega_radps = w;
        }
        assert!(reached, "{s:?}");
        assert_eq!(p.stats.mpc_failed, 0);
    }

    #[test]
    fn failures_fall_back_then_stop() {
        let mut p = Planner::new(
            crate::config::Settings::defaults().mpc,
            crate::config::Settings::defaults().field,
        );
        // an obstacle inside the clearance ahead: the MPC cannot satisfy it
        let s = UnicycleState {
            v_mps: 0.2,
            ..Default::default()
        };
        let obstacles = Obstacles {
            points_base: vec![[0.3, 0.0]],
            ..Default::default()
        };
        let mut sources = Vec::new();
        for _ in 0..6 {
            sources.push(p.step(s, [3.0, 0.0], &obstacles).source);
        }
        assert_eq!(
            sources,
            vec![
                CommandSource::ApfFallback,
                CommandSource::ApfFallback,
                CommandSource::ApfFallback,
                CommandSource::ApfFallback,
                CommandSource::Stop,
                CommandSource::Stop
            ]
        );
        assert_eq!(
            (p.stats.mpc_failed, p.stats.fallbacks, p.stats.stops),
            (6, 4, 2)
        );
    }

    #[test]
    fn a_plan_made_without_the_front_disc_is_counted() {
        let defaults = crate::config::Settings::defaults();
        let mpc = MpcParams {
            front_disc_m: 0.45,
            ..defaults.mpc
        };
        let mut p = Planner::new(mpc, defaults.field);
        let s = UnicycleState {
            v_mps: 0.3,
            ..Default::default()
        };
        // open space: the disc's plan
        p.step(s, [4.0, 0.0], &Obstacles::default());
        assert_eq!((p.stats.mpc_solved, p.stats.front_disc_dropped), (1, 0));
        // a point half a metre ahead of the disc at full speed: no plan
        // keeps the disc's clearance, the one without it is used and
        // counted
        let obstacles = Obstacles {
            points_base: vec![[(mpc.front_disc_m + 0.5) as f32, 0.0]],
            ..Default::default()
        };
        let out = p.step(s, [4.0, 0.0], &obstacles);
        assert_eq!(out.source, CommandSource::Mpc);
        assert_eq!((p.stats.mpc_solved, p.stats.front_disc_dropped), (2, 1));
        // off: never counted
        let mut off = Planner::new(defaults.mpc, defaults.field);
        off.step(s, [4.0, 0.0], &obstacles);
        assert_eq!(off.stats.front_disc_dropped, 0);
    }
}
