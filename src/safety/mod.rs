//! The safety supervisor: the only path from the planner to the actuator.
//! Pure: inputs and the time in, a capped command and the state out.
//!
//! It outputs zero when laser data is older than 250 ms, odometry older
//! than 100 ms, the planner's command older than 200 ms (all from config),
//! when anything is inside the stop corridor in the direction of travel —
//! of the command, of the chair's actual motion (odometry) and of the last
//! output, so a chair still rolling forward keeps its front checked while
//! the planner asks for zero or reverse —, when a turn on the spot (asked
//! for or happening) would sweep into something, after a stop from any
//! input, when the user deflects the real joystick, on CAN bus faults, and
//! (latched) when the chair moves faster than the caps for longer than the
//! overspeed window. Otherwise it caps speeds and accelerations.

mod checks;
pub mod rear;
pub mod sweep;

use std::time::Duration;

use crate::msg::{
    FaultReason, Obstacles, Odometry, SafeCmd, Stamp, Stamped, StopReason, SupervisorState,
    VelocityCmd,
};

/// Limits (config `[safety]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SafetyLimits {
    pub v_forward_max_mps: f64,
    pub v_reverse_max_mps: f64,
    pub omega_max_radps: f64,
    pub a_linear_max_mps2: f64,
    pub a_angular_max_radps2: f64,
    pub laser_max_age: Duration,
    pub odometry_max_age: Duration,
    pub command_max_age: Duration,
    pub chair_width_m: f64,
    pub corridor_margin_m: f64,
    /// The corridor's margin at a crawl (≤ a third of the forward cap),
    /// so that a 0.8–0.9 m doorway can be passed slowly, m.
    pub corridor_margin_slow_m: f64,
    pub stop_distance_m: f64,
    /// The stop distance at a crawl (≤ a third of the forward cap, as for
    /// the margin), m: what the crawl needs to stop in, with room to
    /// spare (config validation), so that the chair creeps on through a
    /// doorway with furniture beyond it.
    pub stop_distance_slow_m: f64,
    /// From `base_link` to the chair's front edge / rear edge, metres.
    pub front_offset_m: f64,
    pub rear_offset_m: f64,
    /// Measured speed above a cap by more than these (m/s, rad/s) for
    /// longer than `overspeed_window`: a latched fault.
    pub overspeed_margin_mps: f64,
    pub overspeed_margin_radps: f64,
    pub overspeed_window: Duration,
    /// The depth camera's obstacles older than this stop the chair; None:
    /// no depth camera (the lasers alone, said at start).
    pub camera_max_age: Option<Duration>,
    /// Of the laser steps through the corridor (or the turn circle), the
    /// fraction that may be blind before the way counts as not seen.
    pub max_blind_fraction: f64,
    /// A turn on the spot needs the rear seen (remembered or vouched for
    /// by the person, [`rear`]).
    pub turn_needs_seen_rear: bool,
    /// A turn on the spot needs the floor its circle sweeps seen by the
    /// camera (or the chair stood there), or vouched for by the person
    /// ([`Obstacles::floor_unseen_base`]): a box under the lasers' plane
    /// beside the front corner is seen by neither sensor.
    pub turn_needs_seen_floor: bool,
}

/// The latest inputs, each with its acquisition stamp.
#[derive(Debug, Clone, Copy, Default)]
pub struct SupervisorInputs<'a> {
    pub obstacles: Option<&'a Stamped<Obstacles>>,
    /// The chair's measured motion.
    pub odometry: Option<&'a Stamped<Odometry>>,
    pub command: Option<&'a Stamped<VelocityCmd>>,
    /// The depth camera's obstacles and drop-offs in `base_link` now,
    /// stamped with their newest frame.
    pub camera: Option<&'a Stamped<Obstacles>>,
    /// What is known of the space behind the chair (None: nothing).
    pub rear: Option<&'a rear::RearView>,
}

/// Below this the chair counts as not moving along / not turning (m/s,
/// rad/s).
const MOVING_MPS: f64 = 0.02;
const TURNING_RADPS: f64 = 0.05;
/// A point within the crawl's margin of the footprint may not come nearer
/// over this much of the requested motion, by more than [`CLOSING_MIN_M`].
const CLOSING_S: f64 = 0.5;
const CLOSING_MIN_M: f64 = 1e-4;
/// The control step's period (20 Hz): how far the first output toward a
/// command gets from the last one.
const CONTROL_PERIOD_S: f64 = 0.05;
/// A turn on the spot is checked against the floor never seen over the
/// angle it turns in this long (s), its braking angle and
/// [`SWEEP_EXTRA_RAD`]: the check repeats every step as it turns.
const SWEEP_AHEAD_S: f64 = 0.25;
/// The angle added to a turn's next moment (rad; 6.5 cm at the corners).
const SWEEP_EXTRA_RAD: f64 = 0.1;
/// A bend's next moment is at most this long (s): a slow bend's angle
/// takes long to turn, and the check repeats every step.
const BEND_SWEEP_MAX_S: f64 = 1.0;
/// Floor never seen holds a bend only this near a thing the camera saw
/// (m): where the thing may go on out of view.
const BEND_UNSEEN_NEAR_THING_M: f64 = 0.3;

#[derive(Debug, Clone)]
pub struct Supervisor {
    pub limits: SafetyLimits,
    goal: GoalState,
    user_stop: bool,
    takeover: bool,
    fault: Option<FaultReason>,
    last: Option<(VelocityCmd, Stamp)>,
    state: SupervisorState,
    /// Since when the measured speed has been above a cap.
    overspeed_since: Option<Stamp>,
    /// Times the state went from navigating to a stop for what is around
    /// (an obstacle, a drop-off, the unseen rear, a blind laser, stale
    /// data): the stops on a trip.
    pub stops: u64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum GoalState {
    None,
    Active,
    Holding,
}

/// Obstacles and drop-offs alike: places the chair must not enter.
fn all_points(o: &Obstacles) -> impl Iterator<Item = &[f32; 2]> {
    o.points_base.iter().chain(o.drop_offs_base.iter())
}

/// Every point the chair must not enter, base_link: the lasers' points
/// and drop-offs, the depth camera's, the remembered rear; the drop-offs
/// that may lie out of the camera's view unless `vouched_turn` (a turn
/// on the spot the person said is clear all around).
fn all_inputs<'a>(
    inputs: &'a SupervisorInputs,
    obs: &'a Stamped<Obstacles>,
    vouched_turn: bool,
) -> impl Iterator<Item = &'a [[f32; 2]]> {
    let camera = inputs.camera.map(|c| &c.value);
    [
        &obs.value.points_base[..],
        &obs.value.drop_offs_base,
        camera.map_or(&[][..], |c| &c.points_base),
        camera.map_or(&[][..], |c| &c.drop_offs_base),
        if vouched_turn {
            &[][..]
        } else {
            camera.map_or(&[][..], |c| &c.drop_offs_unseen_base)
        },
        inputs.rear.map_or(&[][..], |r| &r.points_base),
    ]
    .into_iter()
}

/// Whether `(v, w)`, with the chair's motion now `v_now` and the last
/// output `v_last`, is a turn on the spot (or a stop) the person said is
/// clear all around here: drop-offs that may lie out of the camera's view
/// do not hold it.
fn vouched_turn(inputs: &SupervisorInputs, v: f64, v_now: f64, v_last: f64) -> bool {
    inputs.rear.is_some_and(|r| r.around_vouched)
        && v.abs() < 0.05
        && v_now.abs() < MOVING_MPS
        && v_last.abs() < MOVING_MPS
}

fn fresh(stamp: Option<Stamp>, now: Stamp, max: Duration) -> bool {
    stamp.is_some_and(|s| s.age_at(now) <= max)
}

impl Supervisor {
    pub fn new(limits: SafetyLimits) -> Self {
        Supervisor {
            limits,
            goal: GoalState::None,
            user_stop: false,
            takeover: false,
            fault: None,
            last: None,
            state: SupervisorState::Idle,
            overspeed_since: None,
            stops: 0,
        }
    }

    pub fn state(&self) -> SupervisorState {
        self.state
    }

    /// A goal is being driven to.
    pub fn goal_active(&mut self) {
        self.goal = GoalState::Active;
    }
    /// The goal is held (standing still).
    pub fn goal_holding(&mut self) {
        self.goal = GoalState::Holding;
    }
    pub fn goal_cleared(&mut self) {
        self.goal = GoalState::None;
    }
    /// A stop from any input; latched until `resume`.
    pub fn user_stop(&mut self) {
        self.user_stop = true;
    }
    /// The real joystick moved; latched until `resume`.
    pub fn user_takeover(&mut self) {
        self.takeover = true;
    }
    /// The user asks to go on (after a stop or a takeover).
    pub fn resume(&mut self) {
        self.user_stop = false;
        self.takeover = false;
    }
    pub fn can_fault(&mut self, reason: FaultReason) {
        self.fault = Some(reason);
    }
    /// A person cleared the fault.
    pub fn clear_fault(&mut self) {
        self.fault = None;
    }

    /// Watches the measured speed: above a cap (+ margin) for longer than
    /// the window → a latched overspeed fault.
    fn watch_speed(&mut self, now: Stamp, odometry: Option<&Stamped<Odometry>>) {
        let l = &self.limits;
        let Some(o) = odometry.filter(|o| o.stamp.age_at(now) <= l.odometry_max_age) else {
            return;
        };
        let v = o.value.v_mps;
        let over = !v.is_finite()
            || !o.value.omega_radps.is_finite()
            || v > l.v_forward_max_mps + l.overspeed_margin_mps
            || v < -(l.v_reverse_max_mps + l.overspeed_margin_mps)
            || o.value.omega_radps.abs() > l.omega_max_radps + l.overspeed_margin_radps;
        if !over {
            self.overspeed_since = None;
            return;
        }
        let since = *self.overspeed_since.get_or_insert(o.stamp);
        if o.stamp.age_at(now) + since.age_at(o.stamp) > l.overspeed_window && self.fault.is_none()
        {
            tracing::error!(
                v_mps = v,
                omega_radps = o.value.omega_radps,
                "overspeed: fault"
            );
            self.fault = Some(FaultReason::Overspeed);
        }
    }

    /// What would hold a request for `(v_mps, omega_radps)` (already
    /// within the caps) given the inputs: something in the way of it or of
    /// the chair's motion now, the unseen rear for a turn on the spot or a
    /// reverse, a drop-off, a blind laser. None: it would be driven (the
    /// freshness of the inputs and the person's stops aside). The control
    /// step asks this of candidate commands before it sends one.
    pub fn hold_reason(
        &self,
        inputs: &SupervisorInputs,
        obs: &Stamped<Obstacles>,
        v: f64,
        w: f64,
    ) -> Option<StopReason> {
        self.hold_reason_logged(inputs, obs, v, w, false)
    }

    fn hold_reason_logged(
        &self,
        inputs: &SupervisorInputs,
        obs: &Stamped<Obstacles>,
        v: f64,
        w: f64,
        log: bool,
    ) -> Option<StopReason> {
        let l = &self.limits;
        // the motion now (measured) and the last output are
        // checked as well as the request: a chair still rolling
        // forward keeps its front checked while asked to stop or
        // reverse
        let (v_now, w_now) = inputs
            .odometry
            .map(|o| (o.value.v_mps, o.value.omega_radps))
            .unwrap_or((0.0, 0.0));
        let v_last = self.last.map(|(c, _)| c.v_mps).unwrap_or(0.0);
        let rolling = |x: f64| if x.abs() >= MOVING_MPS { x } else { 0.0 };
        // the first output toward (v, w) at the acceleration limits
        let first = self.ramp(v, w, CONTROL_PERIOD_S);
        // the motion now on its way from rest to the requested arc (the
        // turn rate ramps up faster than the speed, so for a few steps it
        // reads as a turn on the spot): judged as that arc, with the
        // closing check on the first output, not by the whole circle a
        // turn on the spot sweeps (which holds every crawl's arc beside a
        // jamb before it starts)
        let ramping_to_arc = v.abs() >= 0.05
            && v_now * v >= 0.0
            && w_now * w >= 0.0
            && w_now.abs() <= w.abs() + l.a_angular_max_radps2 * CONTROL_PERIOD_S;
        let turning_now = w_now.abs() > TURNING_RADPS && !ramping_to_arc;
        // the checks, each over the points of `pts`: the corridors, the
        // turn's circle, the arcs, a side closing on a point
        let check = |which: usize, pts: &[&[[f32; 2]]]| {
            let all = || pts.iter().flat_map(|p| p.iter());
            match which {
                0 => [v, rolling(v_now), rolling(v_last)]
                    .into_iter()
                    .any(|d| self.corridor_hits(all(), d)),
                1 => {
                    self.turn_hits(all(), v, w)
                        || (turning_now && self.turn_hits(all(), v_now, w_now))
                }
                2 => self.arc_hits(all(), v, w) || self.arc_hits(all(), v_now, w_now),
                _ => {
                    self.closing_hits(all(), v, w)
                        || self.closing_hits(all(), first.v_mps, first.omega_radps)
                }
            }
        };
        let blocked_by = |pts: &[&[[f32; 2]]]| (0..4).any(|which| check(which, pts));
        let camera = inputs.camera.map(|c| &c.value);
        let no_points: &[[f32; 2]] = &[];
        let turns = [(v, w), (v_now, w_now)];
        let turns = if turning_now { &turns[..] } else { &turns[..1] };
        let turning_on_the_spot = turns.iter().any(|(v, w)| v.abs() < 0.05 && w.abs() > 0.05);
        let rear_seen = inputs.rear.is_some_and(|r| r.seen);
        let rear_seen_for_reverse = inputs.rear.is_some_and(|r| r.reverse_seen);
        // the lasers' points and steps down, the camera's obstacles, the
        // remembered rear
        let pts = [
            &obs.value.points_base[..],
            &obs.value.drop_offs_base,
            camera.map_or(no_points, |c| &c.points_base),
            inputs.rear.map_or(no_points, |r| &r.points_base),
        ];
        if blocked_by(&pts) {
            if log && tracing::enabled!(tracing::Level::DEBUG) {
                let by = |source: usize| blocked_by(&pts[source..=source]);
                let [corridor, turn, arc, closing] = [0, 1, 2, 3].map(|which| check(which, &pts));
                // the first point that holds the chair alone (base_link, m)
                let first_point_base = pts.iter().flat_map(|p| p.iter()).find(|p| {
                    let one: &[[f32; 2]] = std::slice::from_ref(*p);
                    blocked_by(&[one])
                });
                tracing::debug!(
                    ?first_point_base,
                    corridor,
                    turn,
                    arc,
                    closing,
                    lasers = by(0),
                    laser_drops = by(1),
                    camera = by(2),
                    rear = by(3),
                    v,
                    w,
                    "blocked by"
                );
            }
            Some(StopReason::Obstacle)
        } else if l.turn_needs_seen_rear
            && ((turning_on_the_spot && !rear_seen) || (v < -MOVING_MPS && !rear_seen_for_reverse))
        {
            // a turn on the spot sweeps the rear; reversing drives
            // into it: neither without the rear seen or vouched for
            Some(StopReason::RearUnseen)
        } else if blocked_by(&[camera.map_or(no_points, |c| &c.drop_offs_base)]) {
            Some(StopReason::DropOff)
        } else if !vouched_turn(inputs, v, v_now, v_last)
            && blocked_by(&[camera.map_or(no_points, |c| &c.drop_offs_unseen_base)])
        {
            // floor never seen, where a step down may lie: driven onto,
            // a drop-off; swept by a turn on the spot, the person may
            // vouch for it
            let turn_only = v.abs() < 0.05 && rolling(v_now) == 0.0 && rolling(v_last) == 0.0;
            Some(if turn_only {
                StopReason::FloorUnseen
            } else {
                StopReason::DropOff
            })
        } else if l.turn_needs_seen_floor
            && turning_on_the_spot
            && !vouched_turn(inputs, v, v_now, v_last)
            && turns.iter().any(|&(v, w)| {
                self.turn_sweep_hits(camera.map_or(no_points, |c| &c.floor_unseen_base), v, w)
            })
        {
            // floor the camera never saw in the turn's circle: a box
            // under the lasers' plane may lie there; the person may vouch
            Some(StopReason::FloorUnseen)
        } else if l.turn_needs_seen_floor
            && [(v, w), (v_now, w_now)].iter().any(|&(v, w)| {
                let (unseen, things) = camera.map_or((no_points, no_points), |c| {
                    (&c.floor_unseen_base[..], &c.points_base[..])
                });
                self.bend_sweep_hits(unseen, things, v, w)
            })
        {
            // floor the camera never saw beside the chair, next to a
            // thing it saw, where a bend swings its rear corner: the
            // thing (a bed's corner under the lasers' plane) may go on
            // there. Held as an obstacle, not asked about: the control
            // step's detours try the other motions (asking "is it clear
            // around me?" was answered "no" for the thing itself, and
            // the floor never seen around then boxed the chair in)
            Some(StopReason::Obstacle)
        } else if self.way_unseen(
            &obs.value.rays_base,
            &[v, rolling(v_now), rolling(v_last)],
            turns,
        ) {
            Some(StopReason::LaserBlind)
        } else {
            None
        }
    }

    /// The command `(v, w)` within the acceleration limits from the last
    /// output, `dt_s` after it.
    fn ramp(&self, v: f64, w: f64, dt_s: f64) -> VelocityCmd {
        let l = &self.limits;
        let prev = self.last.map_or(VelocityCmd::default(), |(p, _)| p);
        let (dv, dw) = (l.a_linear_max_mps2 * dt_s, l.a_angular_max_radps2 * dt_s);
        VelocityCmd {
            v_mps: v.clamp(prev.v_mps - dv, prev.v_mps + dv),
            omega_radps: w.clamp(prev.omega_radps - dw, prev.omega_radps + dw),
        }
    }

    /// One control cycle at `now`.
    pub fn step(&mut self, now: Stamp, inputs: &SupervisorInputs) -> SafeCmd {
        self.watch_speed(now, inputs.odometry);
        let l = self.limits;
        let state = if let Some(f) = self.fault {
            SupervisorState::Fault(f)
        } else if self.user_stop {
            SupervisorState::Stopped(StopReason::UserStop)
        } else if self.takeover {
            SupervisorState::Stopped(StopReason::UserTakeover)
        } else if self.goal == GoalState::None {
            SupervisorState::Idle
        } else if self.goal == GoalState::Holding {
            SupervisorState::Holding
        } else if !fresh(inputs.obstacles.map(|o| o.stamp), now, l.laser_max_age) {
            SupervisorState::Stopped(StopReason::LaserStale)
        } else if !fresh(inputs.odometry.map(|o| o.stamp), now, l.odometry_max_age) {
            SupervisorState::Stopped(StopReason::OdometryStale)
        } else if !fresh(inputs.command.map(|c| c.stamp), now, l.command_max_age) {
            SupervisorState::Stopped(StopReason::CommandStale)
        } else if l
            .camera_max_age
            .is_some_and(|max| !fresh(inputs.camera.map(|c| c.stamp), now, max))
        {
            SupervisorState::Stopped(StopReason::CameraStale)
        } else {
            SupervisorState::Navigating
        };
        let mut out = VelocityCmd::default();
        let mut state = state;
        if state == SupervisorState::Navigating {
            if let (Some(cmd), Some(obs)) = (inputs.command, inputs.obstacles) {
                let c = cmd.value;
                let finite = c.v_mps.is_finite() && c.omega_radps.is_finite();
                let v = if finite {
                    c.v_mps.clamp(-l.v_reverse_max_mps, l.v_forward_max_mps)
                } else {
                    0.0
                };
                let w = if finite {
                    c.omega_radps.clamp(-l.omega_max_radps, l.omega_max_radps)
                } else {
                    0.0
                };
                let blocked = self.hold_reason_logged(inputs, obs, v, w, true);
                if let Some(reason) = blocked {
                    state = SupervisorState::Stopped(reason);
                } else {
                    // acceleration limits from the last output
                    let dt = self
                        .last
                        .map_or(0.0, |(_, t)| t.age_at(now).as_secs_f64().min(0.1));
                    out = self.ramp(v, w, dt);
                    // what the chair starts to do is the ramped command, a
                    // different arc from the one asked for when it starts
                    // from rest: it must not close on a point either
                    let v_now = inputs.odometry.map_or(0.0, |o| o.value.v_mps);
                    let v_last = self.last.map_or(0.0, |(c, _)| c.v_mps);
                    let vouched = vouched_turn(inputs, out.v_mps, v_now, v_last);
                    if self.closing_hits(
                        all_inputs(inputs, obs, vouched).flat_map(|p| p.iter()),
                        out.v_mps,
                        out.omega_radps,
                    ) {
                        tracing::debug!(
                            v = out.v_mps,
                            w = out.omega_radps,
                            "blocked by: the ramped output closes on a point"
                        );
                        state = SupervisorState::Stopped(StopReason::Obstacle);
                        out = VelocityCmd::default();
                    }
                }
            }
        }
        if state != self.state {
            tracing::info!(from = ?self.state, to = ?state, "supervisor state");
            if self.state == SupervisorState::Navigating
                && matches!(state, SupervisorState::Stopped(_))
            {
                self.stops += 1;
            }
        }
        self.state = state;
        self.last = Some((out, now));
        SafeCmd {
            cmd: out,
            state,
            stamp: now,
            view: None,
        }
    }
}

#[cfg(test)]
mod faults_tests;
#[cfg(test)]
mod tests;
