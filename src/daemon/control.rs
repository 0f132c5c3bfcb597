//! The control step (pure, 20 Hz): user input, the goal keeper, the
//! planner and the safety supervisor. `Control::step(now, inputs)` takes
//! the latest obstacles, odometry and tracks and returns the supervisor's
//! command, the words perception should look for, what to say, and
//! whether the trip is over. The async task around it only moves values
//! between channels.

use serde::Serialize;

use super::backoff::BackOff;
use crate::actuation::ActuatorEvent;
use crate::estimation::goal::{GoalEvent, GoalKeeper, GoalState};
use crate::estimation::tracker::Tracker;
use crate::estimation::view::CameraView;
use crate::msg::{
    FaultReason, MapObstacles, Obstacles, Odometry, SafeCmd, Stamp, Stamped, SupervisorState,
    UserInput, VelocityCmd,
};
use crate::navigation::map::MapSettings;
use crate::navigation::planner::Planner;
use rear_question::before_unseen;

use super::route::Router;
use crate::safety::rear::{RearSettings, RearWatch};
use crate::safety::{Supervisor, SupervisorInputs};

/// How a run ended.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// At the approach pose of the prompted object.
    Arrived,
    /// The object went out of view and did not come back.
    Lost,
    /// A full search turn without seeing the word.
    NotFound,
    /// Held on the way to the object too long (`goal.give_up_held_s`):
    /// nothing it tried got it nearer.
    GaveUp,
    /// A stop from the user (with `exit_on_arrival`).
    Stopped,
    /// The user quit.
    Quit,
    /// SIGTERM / Ctrl-C.
    Signal,
    /// `max_duration` passed.
    Timeout,
    /// A task or thread died: the chair was stopped.
    Fault { task: String, reason: String },
}

/// The latest inputs of one step.
#[derive(Clone, Copy)]
pub struct ControlInputs<'a> {
    pub obstacles: Option<&'a Stamped<Obstacles>>,
    pub odometry: Option<&'a Stamped<Odometry>>,
    pub tracker: &'a Tracker,
    /// The depth camera's remembered obstacles and drop-offs (odom).
    pub camera: Option<&'a Stamped<MapObstacles>>,
}

/// What one step decided.
#[derive(Debug, Clone, PartialEq)]
pub struct ControlOutput {
    /// The supervisor's output, for the actuator.
    pub cmd: SafeCmd,
    /// The words perception should look for.
    pub wanted: Vec<String>,
    /// Sentences for the user, in order.
    pub said: Vec<String>,
    /// The trip is over (with `exit_on_arrival`, or the user's quit).
    pub done: Option<Outcome>,
}

use super::route::DoorwayGivenUp;

/// What the chair did on its way besides following the planner.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct NavigationStats {
    /// Doorway passages begun, and given up (held in them, or too long).
    pub doorways: u64,
    pub doorways_given_up: u64,
    /// Times it backed off, held by something on the way.
    pub back_offs: u64,
    /// Steps whose planned command the supervisor would have held and
    /// that drove a detour instead (`navigation::detour`).
    pub detours: u64,
    /// Plans of the way on the map that found none (the local planner
    /// then heads straight for the place).
    pub no_way: u64,
    /// The last doorway passage given up: where and how (None: none was).
    pub last_doorway_given_up: Option<DoorwayGivenUp>,
    /// Manoeuvres on the map begun (held with no way round), and given up
    /// (held on them, or out of time).
    pub manoeuvres: u64,
    pub manoeuvres_given_up: u64,
    /// Of those, begun through a doorway whose passage was given up.
    pub doorway_manoeuvres: u64,
}

pub struct Control {
    pub supervisor: Supervisor,
    pub goal: GoalKeeper,
    pub planner: Planner,
    /// The camera's view (None without a camera: nothing is ever in view).
    pub view: Option<CameraView>,
    /// End the trip when the goal is reached, lost or not found.
    pub exit_on_arrival: bool,
    /// What perception looks for without a goal (the words a person can
    /// ask for), so the switch menu and the status can offer what is
    /// around; empty: nothing is looked for until a word comes.
    pub idle_words: Vec<String>,
    planner_cmd: Option<Stamped<VelocityCmd>>,
    said: Vec<String>,
    done: Option<Outcome>,
    /// Stopped by the user (a stop, the joystick): only "go" clears it.
    latched: bool,
    /// The word to go to once "go" clears the stop.
    pending: Option<String>,
    /// The motor interface: when it came up, whether it took over, and
    /// what has been said about it.
    motors: input::Motors,
    /// What the latest fault was, in words.
    fault_reason: Option<String>,
    /// What is known of the space behind the chair.
    pub rear: RearWatch,
    /// The newest laser scan the rear watch has seen.
    rear_scan: Option<Stamp>,
    /// Since when a turn on the spot waits for the rear to be seen.
    rear_blocked_since: Option<Stamp>,
    /// Since when turns have not been refused for it (the wait ends after
    /// [`rear_question::REAR_WAIT_OVER_AFTER`]).
    rear_clear_since: Option<Stamp>,
    /// The chair asked whether it is clear behind (the pose it asked at).
    asked_rear: Option<crate::msg::Pose2>,
    /// What was asked about the rear was backing up, not a turn.
    asked_back_up: bool,
    /// What was asked was whether it is clear all around (the floor the
    /// turn sweeps was never seen), not only behind.
    asked_around: bool,
    /// The person said no to a turn on the spot here: the chair neither
    /// turns nor asks again within [`REFUSED_TURN_WITHIN_M`] of it, and
    /// looks for another way (arcs, another place to search from).
    turn_refused_at: Option<crate::msg::Pose2>,
    /// Where the person said it is not clear around the chair: the floor
    /// the camera never saw within [`crate::safety::rear::AROUND_VOUCHED_M`]
    /// of it is an obstacle until the camera sees it (something low may
    /// lie there that no sensor sees).
    floor_refused_at: Option<crate::msg::Pose2>,
    /// "yes" arrived: vouch for the rear at the next step.
    rear_yes: bool,
    /// Since when a search turn is held by an obstacle.
    turn_held_since: Option<Stamp>,
    /// Backing off when the way is held.
    pub back_off: BackOff,
    /// Since when the chair, going to the object, is held by an obstacle.
    goal_held_since: Option<Stamp>,
    /// Standing still on the way with nothing holding the chair.
    stand_still: held::StandStill,
    /// The chair staying in one place on the way, turning or not.
    in_place: held::StandStill,
    /// The chair held in one place while searching.
    search_in_place: held::StandStill,
    /// The MPC's last predicted path (odom), for the live view.
    pub planned_path: Vec<[f64; 2]>,
    /// The chair asked "Did you say the X?" (an unsure utterance).
    asked_goal: Option<String>,
    /// A person acknowledged the fault (the latch file goes too).
    pub acknowledged: bool,
    /// The map of what the chair has seen, and the way through it to the
    /// goal (None: drive straight at the goal, the local planner alone).
    pub route: Option<Router>,
    /// Where the planner steered this step (odom): a detour aims there
    /// when the supervisor would hold the planner's command.
    aim_odom: Option<[f64; 2]>,
    detours: u64,
    /// The detour being followed and since when (it is followed as it
    /// was scored, not dropped the step the planner's command is free).
    detour_since: Option<(Stamp, VelocityCmd)>,
    /// Since when the way to a goal has been held without a break, and
    /// whether the person has been told.
    held_since: Option<Stamp>,
    said_held: bool,
    /// Whether this hold has had the object's other side tried.
    tried_other_side: bool,
    /// The manoeuvre under way; manoeuvres begun for this goal, begun in
    /// all, and given up.
    manoeuvre: Option<manoeuvre::Manoeuvre>,
    manoeuvres_for_goal: u32,
    manoeuvres: u64,
    manoeuvres_held: u64,
    /// Manoeuvres through a doorway begun for this goal, and in all.
    doorway_manoeuvres_for_goal: u32,
    doorway_manoeuvres: u64,
}

/// A turn on the spot refused this long for an unseen rear: the chair asks.
/// Held this long on the way to the object within [`NEAR_ENOUGH_M`] of
/// the place beside it: the trip ends there, as near as the chair safely
/// goes (before it would back off and try again).
pub const ARRIVE_HELD_AFTER: std::time::Duration = std::time::Duration::from_secs(2);
pub const NEAR_ENOUGH_M: f64 = 0.3;
/// Standing still this long on the way with nothing holding the chair
/// counts as held (then [`ARRIVE_HELD_AFTER`] as for a hold).
pub const STAND_STILL_FOR: std::time::Duration = std::time::Duration::from_secs(2);
/// A "no" to a turn on the spot holds within this of where it was said
/// (the rear watch's spot), m.
pub const REFUSED_TURN_WITHIN_M: f64 = 0.15;
/// Staying in one place this long on the way to an object, turning this
/// way and that, is held too (the hold's time counts from then).
pub const IN_PLACE_FOR: std::time::Duration = std::time::Duration::from_secs(10);

/// Held on the way this long without a break (no detour, no room to back
/// off): the person is told, once per hold; the chair keeps trying.
pub const SAY_HELD_AFTER: std::time::Duration = std::time::Duration::from_secs(10);
/// Held this long on the way to the place beside the object: another side
/// of it is tried (before the person is told of the hold).
pub const OTHER_SIDE_HELD_AFTER: std::time::Duration = std::time::Duration::from_secs(8);

/// A search turn goes clockwise when what is left to look at is nearer
/// that way by this much, rad (counter-clockwise otherwise: at a trip's
/// start, when all round is left, the way does not depend on a few cells).
pub(super) const CLOCKWISE_SHORTER_BY_RAD: f64 = 0.5;
/// A search turn held this long by an obstacle ends there.
pub(super) const TURN_HELD_FOR: std::time::Duration = std::time::Duration::from_secs(3);

impl Control {
    pub fn new(
        supervisor: Supervisor,
        goal: GoalKeeper,
        planner: Planner,
        view: Option<CameraView>,
        exit_on_arrival: bool,
    ) -> Control {
        Control {
            supervisor,
            goal,
            planner,
            view,
            exit_on_arrival,
            idle_words: Vec::new(),
            planner_cmd: None,
            said: Vec::new(),
            done: None,
            latched: false,
            pending: None,
            motors: input::Motors::default(),
            fault_reason: None,
            rear: RearWatch::new(RearSettings::default()),
            rear_scan: None,
            rear_blocked_since: None,
            rear_clear_since: None,
            asked_rear: None,
            asked_back_up: false,
            asked_around: false,
            turn_refused_at: None,
            floor_refused_at: None,
            rear_yes: false,
            turn_held_since: None,
            back_off: BackOff::default(),
            goal_held_since: None,
            stand_still: held::StandStill::default(),
            in_place: held::StandStill::in_place(),
            search_in_place: held::StandStill::in_place_within(search::SEARCH_HELD_WITHIN_M),
            planned_path: Vec::new(),
            asked_goal: None,
            acknowledged: false,
            route: None,
            aim_odom: None,
            detours: 0,
            detour_since: None,
            held_since: None,
            said_held: false,
            tried_other_side: false,
            manoeuvre: None,
            manoeuvres_for_goal: 0,
            manoeuvres: 0,
            manoeuvres_held: 0,
            doorway_manoeuvres_for_goal: 0,
            doorway_manoeuvres: 0,
        }
    }

    /// Plan the way on a map of what the chair sees (and search further
    /// than one turn when the word is not in view).
    pub fn with_map(mut self, settings: MapSettings) -> Control {
        self.route = Some(Router::new(settings));
        self.goal.explores = true;
        self
    }

    /// What the latest fault was, in words.
    pub fn fault_reason(&self) -> Option<String> {
        match self.supervisor.state() {
            SupervisorState::Fault(FaultReason::Overspeed) => {
                Some("the chair moved faster than its speed caps".into())
            }
            _ => self.fault_reason.clone(),
        }
    }

    /// A fault latched before this start (a restart): stopped until a
    /// person acknowledges it.
    pub fn on_latched_fault(&mut self, f: &super::latch::LatchedFault) {
        self.supervisor.can_fault(f.fault);
        self.fault_reason = Some(f.reason.clone());
        self.say(format!(
            "A fault from before the restart holds: {}. A person must check the chair and \
             acknowledge it (opennav ack-fault). Stopped.",
            f.reason
        ));
    }

    /// The chair is driving itself: a goal it searches for, drives to or
    /// looks around for, and no stop latched.
    fn under_way(&self) -> bool {
        !self.latched
            && !matches!(
                self.goal.state(),
                GoalState::None | GoalState::Reached { .. }
            )
    }

    /// Stopped by the user: the goal is put aside until "go".
    fn latch(&mut self) {
        self.latched = true;
        if let Some(label) = self.goal.state().label() {
            self.pending = Some(label.to_string());
        }
        self.goal.clear();
        self.planner_cmd = None;
        self.manoeuvre = None;
    }

    fn say(&mut self, s: String) {
        self.said.push(s);
    }

    /// A sentence for the user before the first step (a limitation of
    /// this configuration).
    pub fn say_at_start(&mut self, s: &str) {
        self.say(s.to_string());
    }

    /// One step at `now`.
    pub fn step(&mut self, now: Stamp, inputs: ControlInputs) -> ControlOutput {
        self.watch_motors(now);
        // the camera's cells where the chair is now (its stamp stays the
        // frame's: the deadline is about what the camera last saw)
        let camera = inputs.camera.zip(inputs.odometry).map(|(c, odo)| {
            let pose = odo.value.pose;
            let mut o = c.value.to_base(&pose);
            self.drop_vouched_floor(now, &pose, &mut o.floor_unseen_base);
            self.hold_refused_floor(&pose, &mut o);
            Stamped::new(c.stamp, o)
        });
        if let (Some(r), Some(odo)) = (self.route.as_mut(), inputs.odometry) {
            r.update(
                odo.value.pose,
                inputs.obstacles,
                inputs.camera,
                self.view.as_ref(),
            );
        }
        // what the lasers saw of the rear, before the plan: its turns on
        // the spot are checked against the points the supervisor holds
        // them for
        let rear = inputs
            .odometry
            .map(|odo| self.watch_rear(now, inputs.obstacles, odo.value.pose));
        if let (Some(o), Some(odo)) = (inputs.obstacles, inputs.odometry) {
            let rear_points = rear.as_ref().map_or(&[][..], |r| &r.points_base[..]);
            self.plan(now, o, camera.as_ref(), rear_points, odo, inputs.tracker);
        }
        let planned = self.planner_cmd;
        let supervisor_inputs = SupervisorInputs {
            obstacles: inputs.obstacles,
            odometry: inputs.odometry,
            command: planned.as_ref(),
            camera: camera.as_ref(),
            rear: rear.as_ref(),
        };
        if !self.manoeuvring() {
            self.detour_if_held(now, &supervisor_inputs);
        }
        let mut cmd = self.supervisor.step(
            now,
            &SupervisorInputs {
                command: self.planner_cmd.as_ref(),
                ..supervisor_inputs
            },
        );
        // each step's command as the supervisor let it out, beside the
        // velocity the odometry measured (a chair that does not follow
        // its commands shows here)
        tracing::trace!(
            sent = ?cmd.cmd,
            state = ?cmd.state,
            measured = ?inputs.odometry.map(|o| (o.value.v_mps, o.value.omega_radps)),
            "supervisor: step"
        );
        // floor never seen in the circle a turn on the spot sweeps (only
        // asked about a turn held for the rear: held for that floor, the
        // question is about it anyway)
        let held_for_rear =
            cmd.state == SupervisorState::Stopped(crate::msg::StopReason::RearUnseen);
        let floor_unseen = held_for_rear
            && camera.as_ref().is_some_and(|c| {
                let unseen = Obstacles {
                    drop_offs_base: c.value.drop_offs_unseen_base.clone(),
                    points_base: c.value.floor_unseen_base.clone(),
                    ..Default::default()
                };
                let crawl = self.supervisor.crawl_turn_radps();
                self.supervisor.turn_blocked(&unseen, 0.0, crawl)
            });
        self.ask_about_rear(
            now,
            cmd.state,
            inputs.odometry.map(|o| o.value.pose),
            floor_unseen,
            before_unseen(camera.as_ref(), &self.supervisor.limits),
        );
        if self.done.is_some() {
            // the trip is over: the last command the chair gets is zero
            cmd.cmd = VelocityCmd::default();
        }
        ControlOutput {
            cmd,
            wanted: match self.goal.wanted() {
                w if w.is_empty() => self.idle_words.clone(),
                w => w,
            },
            said: std::mem::take(&mut self.said),
            done: self.done.clone(),
        }
    }

    fn plan(
        &mut self,
        now: Stamp,
        lasers: &Stamped<Obstacles>,
        camera: Option<&Stamped<Obstacles>>,
        rear_points_base: &[[f32; 2]],
        odo: &Stamped<Odometry>,
        tracker: &Tracker,
    ) {
        self.planned_path.clear();
        self.aim_odom = None;
        let Odometry {
            pose,
            v_mps,
            omega_radps,
            ..
        } = odo.value;
        let keep = self.keep_clear_of(now, &pose, lasers, camera, rear_points_base);
        let plan::GoalStep {
            event,
            tracking,
            stood_still,
        } = self.goal_step(now, pose, &keep.clear_of, tracker);
        let target = self
            .goal
            .approach()
            .map(|a| ([a.x_m, a.y_m], self.goal.settings.reached_within_m))
            .or_else(|| self.goal.explore_target().map(|t| (t, 0.3)));
        let state = self.supervisor.state();
        // held by something ahead on the way for a while: back off a
        // little, straight (the supervisor checks the way behind; only with
        // the rear seen: it refuses a blind reverse), then the planner tries
        // again from there
        let held = state == SupervisorState::Stopped(crate::msg::StopReason::Obstacle);
        let in_place = self.in_place.update(now, pose, tracking, IN_PLACE_FOR);
        let gave_up = self.tell_if_held(
            now,
            pose,
            &keep.turn_clear_of.points_base,
            match (target.is_some(), held, stood_still || in_place) {
                (false, _, _) => None,
                (true, true, _) => Some(held::Held::Supervisor),
                // (not while waiting for an answer about the rear)
                (true, false, true) if self.asked_rear.is_none() => Some(held::Held::StandingStill),
                (true, false, _) => None,
            },
        );
        if let Some(e) = gave_up.filter(|_| event.is_none()) {
            tracing::warn!(event = ?e, ?pose, "held on the way too long: the goal is given up, or ends here beside the object");
            self.say(e.say());
            self.supervisor.goal_cleared();
            self.planner_cmd = None;
            return self.finish_step(Some(e));
        }
        // a manoeuvre under way drives (the back-off only keeps its trail)
        let manoeuvre = self.manoeuvre_step(now, pose, state);
        let rear = || {
            (
                self.rear.vouched_at(now, &pose),
                self.supervisor.limits.turn_needs_seen_rear
                    && !self.rear.view(now, pose).reverse_seen,
            )
        };
        let backing = self.back_off.step(
            now,
            pose,
            target.is_some() && manoeuvre.is_none(),
            held,
            rear,
            &self.supervisor.limits,
        );
        if let Some(cmd) = manoeuvre.or(backing) {
            self.planner_cmd = Some(Stamped::new(now, cmd));
            return self.finish_step(event);
        }
        self.planner_cmd = match target {
            Some((to, within_m)) => Some(self.drive_to(
                plan::Drive {
                    now,
                    pose,
                    v_mps,
                    omega_radps,
                    to,
                    within_m,
                    state,
                    lasers_base: &lasers.value.points_base,
                },
                &keep,
            )),
            None => self
                .goal
                .search_command()
                .map(|c| Stamped::new(now, self.turn_within_room(c, &keep.turn_clear_of))),
        };
        self.finish_step(event);
    }

    /// A turn on the spot with something inside the corners' circle and
    /// its margin, but not within the crawl's margin: slowed to a crawl
    /// (the supervisor would hold the faster one).
    fn turn_within_room(&self, cmd: VelocityCmd, o: &Obstacles) -> VelocityCmd {
        let crawl = self.supervisor.crawl_turn_radps();
        if cmd.omega_radps.abs() > crawl
            && self.supervisor.turn_blocked(o, cmd.v_mps, cmd.omega_radps)
            && !self
                .supervisor
                .turn_blocked(o, cmd.v_mps, crawl.copysign(cmd.omega_radps))
        {
            VelocityCmd {
                v_mps: cmd.v_mps,
                omega_radps: crawl.copysign(cmd.omega_radps),
            }
        } else {
            cmd
        }
    }

    /// The trip's end on the goal's event (with `exit_on_arrival`).
    fn finish_step(&mut self, event: Option<GoalEvent>) {
        if self.exit_on_arrival {
            let outcome = match event {
                Some(GoalEvent::Reached { .. } | GoalEvent::ReachedNear { .. }) => {
                    Some(Outcome::Arrived)
                }
                Some(GoalEvent::Lost { .. }) => Some(Outcome::Lost),
                Some(GoalEvent::NotFound { .. }) => Some(Outcome::NotFound),
                Some(
                    GoalEvent::GaveUp { .. }
                    | GoalEvent::SearchHeld { .. }
                    | GoalEvent::NoOtherFound { .. }
                    | GoalEvent::AnotherOutOfTime { .. },
                ) => Some(Outcome::GaveUp),
                _ => None,
            };
            if let Some(o) = outcome {
                self.done.get_or_insert(o);
            }
        }
    }

    pub fn navigation_stats(&self) -> NavigationStats {
        NavigationStats {
            doorways: self.route.as_ref().map_or(0, |r| r.doorways),
            doorways_given_up: self.route.as_ref().map_or(0, |r| r.doorways_given_up),
            back_offs: self.back_off.count,
            detours: self.detours,
            no_way: self.route.as_ref().map_or(0, |r| r.no_way),
            last_doorway_given_up: self.route.as_ref().and_then(|r| r.last_given_up),
            manoeuvres: self.manoeuvres,
            manoeuvres_given_up: self.manoeuvres_held,
            doorway_manoeuvres: self.doorway_manoeuvres,
        }
    }

    pub fn state(&self) -> SupervisorState {
        self.supervisor.state()
    }

    /// The chair asked a question and waits for "yes" or "no".
    pub fn asking(&self) -> bool {
        self.asked_rear.is_some() || self.asked_goal.is_some()
    }

    pub fn goal_state(&self) -> &GoalState {
        self.goal.state()
    }
}

/// What the step does when the supervisor holds the way.
#[path = "control_held.rs"]
mod held;

/// A manoeuvre on the map where the way stays held.
#[path = "control_manoeuvre.rs"]
mod manoeuvre;

/// The plan's parts: what to keep clear of, the goal's step, the drive.
#[path = "control_plan.rs"]
mod plan;

/// The search: its turns and where it goes on.
#[path = "control_search.rs"]
mod search;

/// Asking the person whether it is clear behind (or all around) before a
/// turn, and where they said no.
#[path = "control_rear.rs"]
mod rear_question;

/// What comes in besides the sensors: the person's words, presses and
/// answers, the motor interface's events, a task's failure.
#[path = "control_input.rs"]
mod input;

#[cfg(test)]
#[path = "control_tests.rs"]
mod tests;
