//! Tests of the module above (split out to keep it readable).

use std::time::Duration;

use super::*;
use crate::msg::Pose2;

fn control(exit_on_arrival: bool) -> Control {
    Control::new(
        // no depth camera in these tests: the lasers decide; the rear
        // counts as seen (its own test turns the check on)
        Supervisor::new(crate::safety::SafetyLimits {
            camera_max_age: None,
            turn_needs_seen_rear: false,
            ..crate::config::Settings::defaults().safety_limits()
        }),
        GoalKeeper::new(crate::config::Settings::defaults().goal_settings()),
        Planner::new(
            crate::config::Settings::defaults().mpc,
            crate::config::Settings::defaults().field,
        ),
        None,
        exit_on_arrival,
    )
}

/// One step at `ms_` in an empty room, nothing tracked.
fn step_empty(c: &mut Control, ms_: u64) -> ControlOutput {
    step_with_inputs_of(c, ms_, ms_)
}

/// One step at `ms_` with the empty room's inputs stamped `inputs_ms`.
fn step_with_inputs_of(c: &mut Control, inputs_ms: u64, ms_: u64) -> ControlOutput {
    step_seeing(c, inputs_ms, ms_, None)
}

/// One step at `ms_` with the empty room's inputs stamped `inputs_ms` and
/// the depth camera's memory `camera`.
fn step_seeing(
    c: &mut Control,
    inputs_ms: u64,
    ms_: u64,
    camera: Option<&Stamped<MapObstacles>>,
) -> ControlOutput {
    let tracker = Tracker::new(crate::config::Settings::defaults().tracker);
    let now = at(ms_);
    let (o, odo) = fresh(at(inputs_ms));
    c.step(
        now,
        ControlInputs {
            obstacles: Some(&o),
            odometry: Some(&odo),
            tracker: &tracker,
            camera,
        },
    )
}

/// One step at `ms_`, the chair at rest at `pose` (odom), the lasers
/// seeing `points_base`.
fn step_at_pose(
    c: &mut Control,
    ms_: u64,
    tracker: &Tracker,
    pose: Pose2,
    points_base: Vec<[f32; 2]>,
) -> ControlOutput {
    let now = at(ms_);
    let (mut o, mut odo) = fresh(now);
    o.value.points_base = points_base;
    odo.value.pose = pose;
    c.step(
        now,
        ControlInputs {
            obstacles: Some(&o),
            odometry: Some(&odo),
            tracker,
            camera: None,
        },
    )
}

/// A control asked for "chair" and searching a place 2 m ahead, with an
/// empty tracker (`exit_on_arrival`: the trip ends on its outcome).
fn searching_two_metres_ahead(exit_on_arrival: bool) -> (Control, Tracker) {
    let mut c = control(exit_on_arrival);
    c.on_input(UserInput::Goto("chair".into()));
    step_empty(&mut c, 0);
    c.goal.explore(at(0), Some([2.0, 0.0]));
    (c, Tracker::new(crate::config::Settings::defaults().tracker))
}

fn at(ms: u64) -> Stamp {
    Stamp(Duration::from_millis(ms))
}

/// An empty room's inputs at `now`: fresh obstacles (none near) and
/// odometry at rest.
fn fresh(now: Stamp) -> (Stamped<Obstacles>, Stamped<Odometry>) {
    (
        Stamped::new(
            now,
            Obstacles {
                points_base: vec![[4.0, 0.0]],
                ..Default::default()
            },
        ),
        Stamped::new(
            now,
            Odometry {
                pose: Pose2::default(),
                v_mps: 0.0,
                omega_radps: 0.0,
                ..Default::default()
            },
        ),
    )
}

#[test]
fn a_word_starts_the_search_turn_and_a_stop_zeroes_it() {
    let mut c = control(false);
    c.on_input(UserInput::Goto("chair".into()));
    let mut turning = false;
    for k in 0..20 {
        let out = step_empty(&mut c, 50 * k);
        assert_eq!(out.wanted, vec!["chair".to_string()]);
        turning |= out.cmd.cmd.omega_radps > 0.0;
        assert_eq!(out.cmd.cmd.v_mps, 0.0, "turning on the spot");
    }
    assert!(turning, "the search turns the chair");
    c.on_input(UserInput::Stop);
    let out = step_empty(&mut c, 1000);
    assert_eq!(out.cmd.cmd, VelocityCmd::default());
    assert_eq!(out.said, vec!["Stopped.".to_string()]);
    assert!(out.wanted.is_empty());
    assert_eq!(out.done, None, "the daemon goes on after a stop");
}

/// Step `k` (at 50·k ms) of the empty room with floor no camera frame saw
/// all round the chair: a ring of cells 0.6–0.75 m out.
fn step_with_unseen_ring(c: &mut Control, k: u64) -> ControlOutput {
    let ring: Vec<[f64; 2]> = (0..72)
        .flat_map(|i| {
            let a = i as f64 * 5f64.to_radians();
            [0.6, 0.675, 0.75].map(|r| [r * a.cos(), r * a.sin()])
        })
        .collect();
    let camera = Stamped::new(
        at(50 * k),
        MapObstacles {
            floor_unseen_odom: ring,
            ..Default::default()
        },
    );
    step_seeing(c, 50 * k, 50 * k, Some(&camera))
}

/// Floor no camera frame saw all round the chair (a ring of cells from
/// 0.6 to 0.75 m out): the search turn waits and the chair asks about all
/// around, once; "yes" lets it turn, and the floor stays vouched for there.
#[test]
fn floor_never_seen_around_the_chair_is_asked_about_and_yes_lets_the_search_turn() {
    let mut c = control(false);
    asked_once_then_yes_turns(
        &mut c,
        step_with_unseen_ring,
        "Is it clear around me?",
        crate::msg::StopReason::FloorUnseen,
    );
}

/// A search turn started by a word waits 2 s (`step(c, k)` at 50·k ms)
/// with the chair at rest, asking `question` once and held for `reason`;
/// a "yes" then lets it turn within 2 s, asking nothing more.
fn asked_once_then_yes_turns(
    c: &mut Control,
    mut step: impl FnMut(&mut Control, u64) -> ControlOutput,
    question: &str,
    reason: crate::msg::StopReason,
) {
    c.on_input(UserInput::Goto("chair".into()));
    let mut said = Vec::new();
    for k in 0..40 {
        let out = step(c, k);
        assert_eq!(out.cmd.cmd, VelocityCmd::default(), "step {k}");
        said.extend(out.said);
    }
    let asked = said.iter().filter(|l| l.contains(question)).count();
    assert_eq!(asked, 1, "{said:?}");
    assert_eq!(c.state(), SupervisorState::Stopped(reason));
    c.on_input(UserInput::Yes);
    let mut turning = false;
    for k in 40..80 {
        let out = step(c, k);
        turning |= out.cmd.cmd.omega_radps > 0.0;
        assert!(
            out.said.iter().all(|l| !l.contains("Is it clear")),
            "{:?}",
            out.said
        );
    }
    assert!(turning, "{:?}", c.state());
}

#[test]
fn an_unseen_rear_is_asked_about_once_and_yes_lets_the_search_turn() {
    let mut c = control(false);
    c.supervisor.limits.turn_needs_seen_rear = true;
    // a "yes" vouches for this spot: the search turn starts
    asked_once_then_yes_turns(
        &mut c,
        |c, k| step_empty(c, 50 * k),
        "cannot see behind me",
        crate::msg::StopReason::RearUnseen,
    );
    // "no": the trip goes on, not turning here and not asked again here;
    // a new word asks afresh
    let asked_in = |c: &mut Control, from: u64| {
        let mut said = Vec::new();
        for k in from..from + 40 {
            let out = step_empty(c, 50 * k);
            assert!(out.cmd.cmd.omega_radps.abs() < 1e-9 || out.cmd.cmd.v_mps.abs() >= 0.05);
            said.extend(out.said);
        }
        let n = said
            .iter()
            .filter(|l| l.contains("cannot see behind me"))
            .count();
        (n, said)
    };
    let mut c = control(false);
    c.supervisor.limits.turn_needs_seen_rear = true;
    c.on_input(UserInput::Goto("chair".into()));
    assert_eq!(asked_in(&mut c, 0).0, 1);
    c.on_input(UserInput::No);
    let (n, said) = asked_in(&mut c, 40);
    assert_eq!(n, 0, "{said:?}");
    assert!(
        said.iter().any(|l| l.starts_with("I will not turn here.")),
        "{said:?}"
    );
    assert_ne!(*c.goal_state(), GoalState::None, "the trip goes on");
    c.on_input(UserInput::Goto("chair".into()));
    assert_eq!(asked_in(&mut c, 80).0, 1);
    // "yes" with nothing asked changes nothing
    let mut c = control(false);
    c.supervisor.limits.turn_needs_seen_rear = true;
    c.on_input(UserInput::Yes);
    c.on_input(UserInput::Goto("chair".into()));
    for k in 0..10 {
        assert_eq!(step_empty(&mut c, 50 * k).cmd.cmd, VelocityCmd::default());
    }
}

#[test]
fn an_unsure_word_is_asked_back_and_only_yes_goes() {
    let mut c = control(false);
    c.on_input(UserInput::Unsure("door".into()));
    assert!(c.asking());
    let out = step_empty(&mut c, 0);
    assert_eq!(
        out.said,
        vec!["Did you say the door? Say yes, or say it again.".to_string()]
    );
    // nothing is looked for until the answer
    assert!(out.wanted.is_empty(), "{:?}", out.wanted);
    assert!(step_empty(&mut c, 50).wanted.is_empty());
    c.on_input(UserInput::Yes);
    let out = step_empty(&mut c, 100);
    assert_eq!(out.wanted, vec!["door".to_string()]);
    assert!(!c.asking());
    // "no": asked to say it again, nothing looked for
    let mut c = control(false);
    c.on_input(UserInput::Unsure("toilet".into()));
    c.on_input(UserInput::No);
    let out = step_empty(&mut c, 0);
    assert!(
        out.said.iter().any(|l| l == "Say the word again."),
        "{:?}",
        out.said
    );
    assert!(out.wanted.is_empty());
}

#[test]
fn any_word_heard_while_the_chair_drives_itself_stops_it_and_go_goes_to_it() {
    // a sure word, an unsure one, and the very goal's word (a "stop" in
    // noise can come out as "door" while the chair drives to the door)
    for (goal, heard) in [
        ("chair", UserInput::Heard("door".into())),
        ("chair", UserInput::Unsure("door".into())),
        ("door", UserInput::Heard("door".into())),
    ] {
        let mut c = control(false);
        c.on_input(UserInput::Heard(goal.into()));
        step_empty(&mut c, 0);
        assert!(
            step_empty(&mut c, 50).cmd.cmd.omega_radps > 0.0,
            "at rest a sure word goes: searching for the {goal}"
        );
        c.on_input(heard.clone());
        let out = step_empty(&mut c, 100);
        assert_eq!(out.cmd.cmd, VelocityCmd::default(), "{heard:?}");
        assert_eq!(
            out.cmd.state,
            SupervisorState::Stopped(crate::msg::StopReason::UserStop)
        );
        assert_eq!(
            out.said,
            vec!["Stopped. Did you say the door? Say go to go there.".to_string()]
        );
        // it stays at rest until "go", then goes to the word it heard
        for k in 3..10 {
            assert_eq!(step_empty(&mut c, 50 * k).cmd.cmd, VelocityCmd::default());
        }
        c.on_input(UserInput::Go);
        let out = step_empty(&mut c, 600);
        assert_eq!(out.wanted, vec!["door".to_string()], "{heard:?}");
        assert!(step_empty(&mut c, 650).cmd.cmd.omega_radps > 0.0);
    }
    // typed or chosen words (the socket, the switch menu) change the goal
    // without a stop: only the recogniser can mishear
    let mut c = control(false);
    c.on_input(UserInput::Goto("chair".into()));
    step_empty(&mut c, 0);
    step_empty(&mut c, 50);
    c.on_input(UserInput::Goto("door".into()));
    let out = step_empty(&mut c, 100);
    assert_eq!(out.wanted, vec!["door".to_string()]);
    assert!(out.cmd.cmd.omega_radps > 0.0);
}

#[test]
fn a_stop_latches_until_go_and_a_word_alone_does_not_clear_it() {
    let mut c = control(false);
    c.on_input(UserInput::Goto("chair".into()));
    step_empty(&mut c, 0);
    assert!(
        step_empty(&mut c, 50).cmd.cmd.omega_radps > 0.0,
        "searching"
    );
    c.on_input(UserInput::Stop);
    assert_eq!(step_empty(&mut c, 100).cmd.cmd, VelocityCmd::default());
    // a new word: remembered, but the chair stays stopped
    c.on_input(UserInput::Goto("desk".into()));
    for k in 3..10 {
        let out = step_empty(&mut c, 50 * k);
        assert_eq!(out.cmd.cmd, VelocityCmd::default());
        assert_eq!(
            out.cmd.state,
            SupervisorState::Stopped(crate::msg::StopReason::UserStop)
        );
    }
    // "go": the desk is looked for
    c.on_input(UserInput::Go);
    let out = step_empty(&mut c, 600);
    assert!(
        out.said
            .iter()
            .any(|s| s == "Going on. Looking for a desk."),
        "{:?}",
        out.said
    );
    assert_eq!(out.wanted, vec!["desk".to_string()]);
    assert!(
        step_empty(&mut c, 650).cmd.cmd.omega_radps > 0.0,
        "searching again"
    );
    // the joystick takes over: latched the same way
    c.on_actuator_event(&ActuatorEvent::UserDeflection { x: 0, y: 40 });
    c.on_input(UserInput::Goto("desk".into()));
    assert_eq!(step_empty(&mut c, 700).cmd.cmd, VelocityCmd::default());
}

#[test]
fn a_takeover_that_does_not_happen_is_said_and_latched() {
    let mut c = control(false);
    c.on_input(UserInput::Goto("chair".into()));
    step_empty(&mut c, 0);
    // the writer learned the joystick id, but never became active
    c.on_actuator_event(&ActuatorEvent::Ready {
        joystick_id: Some(0x0200_0100),
    });
    let mut said = Vec::new();
    for k in 1..40 {
        said.extend(step_empty(&mut c, 50 * k).said);
    }
    assert!(
        said.iter()
            .any(|s| s.starts_with("I cannot take over the chair's joystick")),
        "{said:?}"
    );
    let out = step_empty(&mut c, 2000);
    assert_eq!(out.cmd.state, SupervisorState::Fault(FaultReason::Takeover));
    assert_eq!(out.cmd.cmd, VelocityCmd::default());
    // taken over in time: nothing said
    let mut c = control(false);
    step_empty(&mut c, 0);
    c.on_actuator_event(&ActuatorEvent::Ready { joystick_id: None });
    c.on_actuator_event(&ActuatorEvent::Active);
    let said: Vec<String> = (1..200)
        .flat_map(|k| step_empty(&mut c, 50 * k).said)
        .collect();
    assert!(said.is_empty(), "{said:?}");
    // no joystick module at all: said once
    let mut c = control(false);
    let said: Vec<String> = (0..200)
        .flat_map(|k| step_empty(&mut c, 50 * k).said)
        .collect();
    assert_eq!(
        said,
        vec!["The chair's joystick module does not answer: I cannot drive.".to_string()]
    );
}

#[test]
fn a_motor_link_fault_is_latched_as_one_and_a_bus_fault_as_a_bus_fault() {
    for kind in [FaultReason::MotorLink, FaultReason::CanBus] {
        let mut c = control(false);
        let tracker = Tracker::new(crate::config::Settings::defaults().tracker);
        c.on_actuator_event(&ActuatorEvent::Fault {
            kind,
            reason: "link down".into(),
        });
        let (o, odo) = fresh(at(0));
        let out = c.step(
            at(0),
            ControlInputs {
                obstacles: Some(&o),
                odometry: Some(&odo),
                tracker: &tracker,
                camera: None,
            },
        );
        assert_eq!(out.cmd.state, SupervisorState::Fault(kind));
        assert_eq!(
            out.said,
            vec!["Motor interface fault: link down. Stopped.".to_string()]
        );
    }
}

#[test]
fn stale_inputs_give_zero_and_a_dead_task_latches_a_fault() {
    let mut c = control(true);
    c.on_input(UserInput::Goto("chair".into()));
    // odometry 300 ms old: nothing moves
    let out = step_with_inputs_of(&mut c, 0, 300);
    assert_eq!(out.cmd.cmd, VelocityCmd::default());
    c.on_task_failure("perception", "panicked");
    let out = step_empty(&mut c, 350);
    assert_eq!(out.cmd.cmd, VelocityCmd::default());
    assert_eq!(out.cmd.state, SupervisorState::Fault(FaultReason::Task));
    assert_eq!(
        out.done,
        Some(Outcome::Fault {
            task: "perception".into(),
            reason: "panicked".into()
        })
    );
    assert_eq!(
        out.said,
        vec!["Internal fault in perception. Stopped.".to_string()]
    );
    // a word does not clear the fault
    c.on_input(UserInput::Goto("chair".into()));
    let out = step_empty(&mut c, 400);
    assert_eq!(out.cmd.cmd, VelocityCmd::default());
}

#[path = "control_held_tests.rs"]
mod held_on_the_way;

#[path = "control_manoeuvre_tests.rs"]
mod manoeuvre;

#[path = "control_floor_tests.rs"]
mod floor;

#[path = "control_search_tests.rs"]
mod search_held;
