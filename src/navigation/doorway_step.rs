//! A doorway passage's step ([`Passage::step`]): the command at a pose,
//! phase by phase — the approach, lining up, squaring to the axis, the
//! straight run through at a crawl, and backing up or out where held.

use super::*;

impl Passage {
    /// The command at `pose` (odom) on the way to `goal` (odom): through
    /// once past the doorway, or level with a goal just beyond it (the
    /// planner makes the last metres).
    pub fn step(&mut self, pose: Pose2, goal: [f64; 2]) -> PassageCmd {
        let s = self.settings;
        let p = [pose.x_m, pose.y_m];
        let (along, left) = self.door.local(p);
        let heading_err = wrap_angle(pose.theta_rad - self.door.axis_rad);
        let goal_along = self.door.local(goal).0;
        // handed back only with the chair's rear out of the doorway: a
        // turn there would sweep a corner into a jamb
        if along > s.past_m || (along > s.clear_of_door_m && along >= goal_along - 0.1) {
            return PassageCmd::Done;
        }
        loop {
            match self.phase {
                Phase::Approach => {
                    let pre = self.door.on_axis(-s.before_m);
                    // close enough, or already between the point and the
                    // doorway and near the middle line
                    let near = (pre[0] - p[0]).hypot(pre[1] - p[1]) <= s.at_m
                        || (along > -s.before_m - s.at_m && along < -0.2 && left.abs() <= s.at_m);
                    // the point to line up on, where there is room
                    let line_up_at = s.line_up_at(along);
                    let room_to_line_up = line_up_at <= -s.line_up_nearest_m;
                    // off the line, but near enough to drive onto it at
                    // 45 degrees or less (steeper, the stop corridor sweeps
                    // across whatever stands beside the way)
                    let onto_line = room_to_line_up
                        && along > -s.before_m - s.at_m - 0.2
                        && left.abs() <= s.line_up_from_m.min(line_up_at - along);
                    if !near && !onto_line {
                        return PassageCmd::Aim(pre);
                    }
                    self.phase = if left.abs() > s.line_up_off_m && room_to_line_up {
                        Phase::LineUp { at_m: line_up_at }
                    } else if let Some(back) = self.back_up(along, left, heading_err) {
                        back
                    } else {
                        Phase::Align
                    };
                }
                Phase::LineUp { at_m } => {
                    if along >= at_m - 0.02 {
                        self.phase = Phase::Align;
                        continue;
                    }
                    let bearing = self.line_up_bearing(pose, at_m);
                    // face it on the spot (or, no turn on the spot
                    // allowed, on a crawl's arc), then straight on,
                    // steering onto it
                    return PassageCmd::Drive(
                        if bearing.abs() > LINE_UP_TURNS_RAD && !self.turns_refused {
                            VelocityCmd {
                                v_mps: 0.0,
                                omega_radps: s.turn_radps.copysign(bearing),
                            }
                        } else {
                            VelocityCmd {
                                v_mps: s.crawl_mps,
                                omega_radps: (2.0 * bearing)
                                    .clamp(-s.omega_max_radps, s.omega_max_radps),
                            }
                        },
                    );
                }
                Phase::Align => {
                    if self.turns_refused && heading_err.abs() <= PASS_STEERS_WITHIN_RAD {
                        // no turn on the spot: squared while passing
                        self.phase = Phase::Pass;
                        continue;
                    }
                    if self.turns_refused {
                        return PassageCmd::Drive(VelocityCmd {
                            v_mps: s.crawl_mps,
                            omega_radps: (-s.k_heading * heading_err)
                                .clamp(-s.omega_max_radps, s.omega_max_radps),
                        });
                    }
                    if heading_err.abs() > s.aligned_rad {
                        return PassageCmd::Drive(VelocityCmd {
                            v_mps: 0.0,
                            omega_radps: -s.turn_radps.copysign(heading_err),
                        });
                    }
                    self.phase = Phase::Pass;
                }
                Phase::Pass => {
                    if heading_err.abs() > PASS_STEERS_WITHIN_RAD {
                        // pushed off the line: line up again
                        self.phase = Phase::Align;
                        continue;
                    }
                    // off the line where it no longer steers onto it:
                    // the jamb would hold it
                    if along >= -s.square_within_m {
                        if let Some(back) = self.back_up(along, left, heading_err) {
                            self.phase = back;
                            continue;
                        }
                    }
                    // onto the middle line while far; square to the
                    // doorway once the front nears it (the stop corridor
                    // ahead is a few centimetres narrower than the gap) —
                    // unless still off the line by more than the gap
                    // holds with no back-up left to line up again: then
                    // onto the line until the front is at the wall, or
                    // the jamb holds it there for good
                    let off_line = left.abs() > self.passes_off_m();
                    let no_back_up = self.backed_up >= s.back_ups;
                    let k_lateral = if along < -s.square_within_m
                        || (off_line && no_back_up && along < -s.enter_m)
                    {
                        s.k_lateral
                    } else {
                        0.0
                    };
                    let omega = (-k_lateral * left - s.k_heading * heading_err)
                        .clamp(-s.omega_max_radps, s.omega_max_radps);
                    return PassageCmd::Drive(VelocityCmd {
                        v_mps: s.crawl_mps,
                        omega_radps: omega,
                    });
                }
                Phase::BackOut {
                    from_odom,
                    back_m,
                    at_m,
                } => {
                    if (p[0] - from_odom[0]).hypot(p[1] - from_odom[1]) >= back_m {
                        // the line-up's turn again, from here
                        self.phase = Phase::LineUp { at_m };
                        continue;
                    }
                    return PassageCmd::Drive(VelocityCmd {
                        v_mps: -s.crawl_mps,
                        omega_radps: 0.0,
                    });
                }
                Phase::BackUp { to_m, squaring } => {
                    if along <= to_m {
                        self.phase = Phase::Approach;
                        continue;
                    }
                    let omega_radps = if squaring {
                        (-s.k_heading * heading_err).clamp(-s.omega_max_radps, s.omega_max_radps)
                    } else {
                        0.0
                    };
                    return PassageCmd::Drive(VelocityCmd {
                        v_mps: -s.crawl_mps,
                        omega_radps,
                    });
                }
            }
        }
    }
}
