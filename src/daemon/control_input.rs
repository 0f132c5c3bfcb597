//! What comes in to the control step besides the sensors (split out of
//! `control`): the person's words, presses and answers to the chair's
//! questions; the motor interface's events; a task's failure.

use super::*;

/// The motor interface up but not driving this long: the takeover failed.
const TAKEOVER_WITHIN: std::time::Duration = std::time::Duration::from_secs(1);
/// No joystick module heard this long: said once.
const JSM_WITHIN: std::time::Duration = std::time::Duration::from_secs(5);

#[derive(Debug, Default)]
pub(super) struct Motors {
    first_step: Option<Stamp>,
    ready_at: Option<Stamp>,
    /// When the Ready event arrived but no step has stamped it yet.
    ready_pending: bool,
    active: bool,
    said_no_answer: bool,
    said_no_takeover: bool,
}

impl Control {
    /// A word, a stop or a quit from the user.
    pub fn on_input(&mut self, input: UserInput) {
        match input {
            UserInput::Goto(word) if self.latched => {
                self.asked_goal = None;
                // a word alone does not clear a stop
                self.say(format!("Stopped. Say go to go to the {word}."));
                self.pending = Some(word);
            }
            UserInput::Goto(word) => {
                // a sure word answers the question too; a new trip asks
                // about turning afresh
                self.asked_goal = None;
                self.turn_refused_at = None;
                self.floor_refused_at = None;
                if let Some(r) = self.route.as_mut() {
                    r.new_trip();
                }
                self.goal.set_prompt(&word);
                self.say(format!("Looking for a {word}."));
            }
            UserInput::Stop => {
                self.supervisor.user_stop();
                self.latch();
                self.say("Stopped.".into());
                if self.exit_on_arrival {
                    self.done.get_or_insert(Outcome::Stopped);
                }
            }
            UserInput::Go if self.latched => {
                self.latched = false;
                self.supervisor.resume();
                match self.pending.take() {
                    Some(word) => {
                        self.goal.set_prompt(&word);
                        self.say(format!("Going on. Looking for a {word}."));
                    }
                    None => self.say("Going on. Say a word.".into()),
                }
            }
            UserInput::Go => tracing::info!("\"go\" while not stopped: nothing to clear"),
            UserInput::Heard(word) | UserInput::Unsure(word) if self.under_way() => {
                // any word heard while the chair drives itself stops it: a
                // misheard "stop" must never keep it going, or send it
                // elsewhere
                self.supervisor.user_stop();
                self.latch();
                self.asked_goal = None;
                self.say(format!(
                    "Stopped. Did you say the {word}? Say go to go there."
                ));
                self.pending = Some(word);
            }
            UserInput::Heard(word) => self.on_input(UserInput::Goto(word)),
            UserInput::Unsure(word) => {
                self.say(format!("Did you say the {word}? Say yes, or say it again."));
                self.asked_goal = Some(word);
            }
            UserInput::Yes if self.asked_goal.is_some() => {
                if let Some(word) = self.asked_goal.take() {
                    // as if the word had been said surely
                    self.on_input(UserInput::Goto(word));
                }
            }
            UserInput::No if self.asked_goal.take().is_some() => {
                self.say("Say the word again.".into());
            }
            UserInput::Yes if self.asked_rear.is_some() => {
                self.rear_yes = true;
                self.say(if self.asked_back_up {
                    "Thank you. Backing up.".into()
                } else {
                    "Thank you. Turning.".into()
                });
            }
            UserInput::No if self.asked_back_up && self.asked_rear.is_some() => {
                // backing up only made room to line up with a doorway:
                // the passage goes on without it (and one begun again
                // from here does not ask again)
                let asked_at = self.asked_rear.take();
                let at = asked_at.map(|p| [p.x_m, p.y_m]);
                let refused =
                    at.is_some_and(|at| self.route.as_mut().is_some_and(|r| r.refuse_back_up(at)));
                if refused {
                    self.say("I will not back up.".into());
                } else if self.manoeuvring() {
                    // a manoeuvre's reverse: it is over, and the chair
                    // stays held where it is (the goal given up in time)
                    self.end_manoeuvre("not clear behind");
                    self.say("I will not back up.".into());
                } else if let Some(p) = asked_at {
                    // backing off only made room for another try (or
                    // what asked is over: the back-off ended, a passage
                    // moved on to another phase): the chair stays held
                    // where it is, no back-off is asked for here again,
                    // and it goes on when the way clears (the goal given
                    // up in time), as for a back-off under way
                    self.back_off.refuse(p);
                    self.say("I will not back up.".into());
                }
            }
            UserInput::No if self.asked_rear.is_some() => {
                // not clear: no turn on the spot here; the trip goes on
                // another way (the planner's arcs, another place to look
                // from), and "stop" stays
                self.turn_refused_at = self.asked_rear.take();
                if self.manoeuvring() {
                    self.end_manoeuvre("not clear around");
                }
                if self.asked_around {
                    self.floor_refused_at = self.turn_refused_at;
                    tracing::info!(at = ?self.floor_refused_at, "not clear around: the floor never seen here holds the chair until seen");
                }
                if let Some(r) = self.route.as_mut() {
                    r.refuse_turns();
                }
                self.say(
                    "I will not turn here. I will look for another way; say stop to stay here."
                        .into(),
                );
            }
            UserInput::AckFault => match self.supervisor.state() {
                SupervisorState::Fault(FaultReason::Task) => self
                    .say("An internal fault cannot be acknowledged: the daemon restarts.".into()),
                SupervisorState::Fault(_) => {
                    self.supervisor.clear_fault();
                    self.fault_reason = None;
                    self.acknowledged = true;
                    self.say("Fault acknowledged. Say a word to go.".into());
                }
                _ => self.say("There is no fault to acknowledge.".into()),
            },
            UserInput::Yes | UserInput::No => {
                tracing::info!(input = ?input, "an answer while nothing was asked: ignored")
            }
            UserInput::Quit => {
                self.done.get_or_insert(Outcome::Quit);
            }
            UserInput::LookAround if self.latched => {
                self.say("Stopped. Say go first, then ask me to look around.".into());
            }
            UserInput::LookAround => {
                self.asked_goal = None;
                self.pending = None;
                self.goal.look_around();
                self.say("Looking around.".into());
            }
        }
    }

    /// What the motor interface reported.
    pub fn on_actuator_event(&mut self, ev: &ActuatorEvent) {
        match ev {
            ActuatorEvent::Ready { .. } => self.motors.ready_pending = true,
            ActuatorEvent::Active => self.motors.active = true,
            ActuatorEvent::Fault { kind, reason } => {
                self.supervisor.can_fault(*kind);
                self.fault_reason = Some(reason.clone());
                self.goal.clear();
                self.say(format!("Motor interface fault: {reason}. Stopped."));
            }
            ActuatorEvent::UserDeflection { .. } => {
                self.supervisor.user_takeover();
                self.latch();
                self.say("You have the joystick. Say go to let me drive again.".into());
            }
            other @ (ActuatorEvent::JsmLost | ActuatorEvent::Released) => {
                tracing::info!(event = ?other, "actuator")
            }
        }
    }

    /// A task or thread died: stop for good and say so.
    pub fn on_task_failure(&mut self, task: &str, reason: &str) {
        self.supervisor.can_fault(FaultReason::Task);
        self.goal.clear();
        self.say(format!("Internal fault in {task}. Stopped."));
        self.done = Some(Outcome::Fault {
            task: task.to_string(),
            reason: reason.to_string(),
        });
    }

    /// A takeover that does not happen is said and latched as a fault; a
    /// chair whose joystick module never answers is said once.
    pub(super) fn watch_motors(&mut self, now: Stamp) {
        let m = &mut self.motors;
        let first = *m.first_step.get_or_insert(now);
        if m.ready_pending {
            m.ready_pending = false;
            m.ready_at.get_or_insert(now);
        }
        if m.active {
            return;
        }
        match m.ready_at {
            Some(t) if t.age_at(now) > TAKEOVER_WITHIN && !m.said_no_takeover => {
                m.said_no_takeover = true;
                self.supervisor.can_fault(FaultReason::Takeover);
                self.goal.clear();
                self.say(
                    "I cannot take over the chair's joystick: its joystick module keeps \
                     control. Stopped."
                        .into(),
                );
            }
            None if first.age_at(now) > JSM_WITHIN && !m.said_no_answer => {
                m.said_no_answer = true;
                self.say("The chair's joystick module does not answer: I cannot drive.".into());
            }
            _ => {}
        }
    }
}
