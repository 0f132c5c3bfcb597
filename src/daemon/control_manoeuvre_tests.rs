//! Tests of the manoeuvre on the map: held with no way round, the chair
//! works its way round on its map (split out of `control_held_tests`,
//! whose helpers they use).

use super::held_on_the_way::{chair_at, step_seeing_chair, step_with_points};
use super::*;

/// A box across the way just before the chair's front (and the room's
/// far wall), as the lasers see it.
fn box_across() -> Vec<[f32; 2]> {
    let mut points_base: Vec<[f32; 2]> = (-8..=8).map(|k| [0.68, k as f32 * 0.05]).collect();
    points_base.push([4.0, 0.0]);
    points_base
}

/// Going to a chair 3 m ahead with the map of what it has seen, held by
/// [`box_across`] until a manoeuvre begins (None: none began in 30 s);
/// the control, the tracker, the step it began at, and what was said.
fn held_going_to_a_chair_3_m_ahead() -> (Control, Tracker, Option<u64>, Vec<String>) {
    let mut c = control(true).with_map(MapSettings::default());
    c.supervisor.limits.turn_needs_seen_rear = true;
    c.on_input(UserInput::Goto("chair".into()));
    let mut tracker = Tracker::new(crate::config::Settings::defaults().tracker);
    let chair = chair_at(3.0);
    let mut said = Vec::new();
    for k in 0..600u64 {
        let out = step_seeing_chair(&mut c, &mut tracker, &chair, 50 * k, box_across());
        let begun = out.said.iter().any(|s| s.contains("work my way round"));
        said.extend(out.said);
        if begun {
            return (c, tracker, Some(k), said);
        }
    }
    (c, tracker, None, said)
}

/// Held on the way to a chair by a box across the way, with the map of
/// what it has seen: after the wait with no way round, a manoeuvre on
/// the map begins (said; its first move backs away from the box, no turn
/// fitting with the box inside the corners' circle); the person's "no"
/// to its reverse ends it, and the chair stays held on its way to the
/// chair (the trip goes on: not "Staying here.").
#[test]
fn held_with_no_way_round_it_works_its_way_round_on_the_map() {
    let (mut c, _, began, said) = held_going_to_a_chair_3_m_ahead();
    let k = began.unwrap_or_else(|| panic!("no manoeuvre: {said:?}"));
    // after the hold's 10 s with no way round (the back-off asked about)
    assert!(
        k * 50 >= SAY_HELD_AFTER.as_millis() as u64,
        "began at step {k}"
    );
    assert!(c.manoeuvring());
    assert_eq!(c.navigation_stats().manoeuvres, 1);
    let first = c.manoeuvre_step(
        at(50 * k + 50),
        Pose2::default(),
        SupervisorState::Navigating,
    );
    assert!(first.is_some_and(|m| m.v_mps < 0.0), "{first:?}");
    // the person says it is not clear behind
    no_to_backing_up(&mut c);
    assert!(!c.manoeuvring());
    assert_eq!(c.navigation_stats().manoeuvres_given_up, 1);
    assert!(matches!(c.goal.state(), GoalState::Tracking { .. }));
}

/// "Stop" during a manoeuvre ends it at once: the chair's command is
/// zero from the next step, and the goal waits for "go".
#[test]
fn stop_during_a_manoeuvre_ends_it_at_once() {
    let (mut c, tracker, began, said) = held_going_to_a_chair_3_m_ahead();
    let k = began.unwrap_or_else(|| panic!("no manoeuvre: {said:?}"));
    c.on_input(UserInput::Stop);
    assert!(!c.manoeuvring());
    let out = step_with_points(&mut c, 50 * (k + 1), &tracker, box_across());
    assert_eq!(out.cmd.cmd, VelocityCmd::default());
    assert!(!c.manoeuvring());
}

/// Searching (a place to look from 2 m ahead), held by the same box with
/// no way round: no manoeuvre (the search gives a held place up for
/// another); the chair says it is held.
#[test]
fn held_with_no_way_round_while_searching_it_does_not_manoeuvre() {
    let mut c = control(false).with_map(MapSettings::default());
    c.on_input(UserInput::Goto("chair".into()));
    step_empty(&mut c, 0);
    c.goal.explore(at(0), Some([2.0, 0.0]));
    let tracker = Tracker::new(crate::config::Settings::defaults().tracker);
    let mut said = Vec::new();
    for k in 1..=300u64 {
        said.extend(step_with_points(&mut c, 50 * k, &tracker, box_across()).said);
        assert!(!c.manoeuvring(), "step {k}: {said:?}");
    }
    assert!(
        said.iter().any(|s| s.contains("cannot find a way round")),
        "{said:?}"
    );
    assert_eq!(c.navigation_stats().manoeuvres, 0);
}

/// Held far from the place beside the object, where no manoeuvre reaches
/// the place itself (something stands on it, seen now): the manoeuvre
/// ends on the map's way 1.5 m on instead (there the planner goes on).
#[test]
fn a_manoeuvre_to_a_place_out_of_reach_ends_on_the_way() {
    let mut c = control(true).with_map(MapSettings::default());
    c.on_input(UserInput::Goto("chair".into()));
    let mut tracker = Tracker::new(crate::config::Settings::defaults().tracker);
    let chair = chair_at(4.0);
    for k in 0..20u64 {
        step_seeing_chair(&mut c, &mut tracker, &chair, 50 * k, vec![[6.0, 0.0]]);
    }
    assert!(matches!(c.goal.state(), GoalState::Tracking { .. }));
    let place = c.goal.approach().expect("the place beside the chair");
    assert!(place.x_m > 2.5, "{place:?}");
    // something seen now on the place
    let on_the_place: Vec<[f32; 2]> = (-6..=6)
        .flat_map(|i| (-6..=6).map(move |j| (i, j)))
        .map(|(i, j)| {
            [
                (place.x_m + i as f64 * 0.05) as f32,
                (place.y_m + j as f64 * 0.05) as f32,
            ]
        })
        .collect();
    assert!(c.begin_manoeuvre(at(1000), Pose2::default(), &on_the_place));
    use crate::navigation::manoeuvre::Move;
    let end = match c.manoeuvre_left().and_then(|m| m.last()) {
        Some(Move::Straight { to, .. }) => to,
        last => panic!("the manoeuvre ends with {last:?}"),
    };
    assert!(
        (end[0] - 1.5).hypot(end[1]) <= 0.25 + 0.05,
        "ends at {end:?}, not on the way 1.5 m on"
    );
}

/// A doorway whose passage was given up, the chair before it turned well
/// off its axis and off its middle line: a manoeuvre through it on the
/// map begins (said), ending past it facing along its axis; it goes on
/// while the goal is a search (a place to look from beyond the doorway),
/// no second one begins while it is under way, and after its minute it
/// is over (said).
#[test]
fn a_doorway_given_up_is_worked_through_on_the_map() {
    let mut c = control(true).with_map(MapSettings::default());
    c.on_input(UserInput::Goto("chair".into()));
    assert!(matches!(c.goal.state(), GoalState::Searching { .. }));
    // a wall at x = 1 m with a 0.84 m doorway about y = 0
    let mut wall: Vec<[f64; 2]> = Vec::new();
    for k in 0..=120 {
        let y_m = -3.0 + k as f64 * 0.05;
        if y_m.abs() > 0.42 {
            wall.push([1.0, y_m]);
        }
    }
    let mut map = crate::navigation::map::GridMap::new(MapSettings::default(), [0.0, 0.0]);
    map.set_camera(&wall, &[]);
    if let Some(r) = c.route.as_mut() {
        r.map = Some(map);
    }
    let door = crate::navigation::doorway::Doorway {
        center: [1.0, 0.0],
        axis_rad: 0.0,
        width_m: 0.84,
    };
    let pose = Pose2 {
        x_m: -0.2,
        y_m: 0.4,
        theta_rad: 1.2,
    };
    assert!(c.begin_doorway_manoeuvre(at(0), pose, door, &[]));
    let said: Vec<String> = std::mem::take(&mut c.said);
    assert!(
        said.iter().any(|s| s.starts_with("The doorway is tight.")),
        "{said:?}"
    );
    assert_eq!(c.navigation_stats().doorway_manoeuvres, 1);
    let moves = c.manoeuvre_left().map(<[_]>::to_vec).unwrap_or_default();
    let last = moves.iter().rev().find_map(|m| match *m {
        crate::navigation::manoeuvre::Move::Straight {
            to, heading_rad, ..
        } => Some((to, heading_rad)),
        crate::navigation::manoeuvre::Move::Turn { .. } => None,
    });
    let (to, heading_rad) = last.unwrap_or_else(|| panic!("no straight move: {moves:?}"));
    assert!(
        to[0] > 1.6 && to[1].abs() < 0.2,
        "ends at {to:?}: {moves:?}"
    );
    assert!(
        heading_rad.abs() < 0.3,
        "ends turned {heading_rad}: {moves:?}"
    );
    // searching, the manoeuvre drives on; no second one begins
    assert!(c
        .manoeuvre_step(at(50), pose, SupervisorState::Navigating)
        .is_some());
    assert!(!c.begin_doorway_manoeuvre(at(100), pose, door, &[]));
    assert_eq!(c.navigation_stats().doorway_manoeuvres, 1);
    // its minute out (the chair never moved): over, said, the hold goes on
    let late = crate::daemon::control::manoeuvre::DOORWAY_MANOEUVRE_AT_MOST.as_millis() as u64;
    assert!(c
        .manoeuvre_step(at(late - 50), pose, SupervisorState::Navigating)
        .is_some());
    assert_eq!(
        c.manoeuvre_step(at(late), pose, SupervisorState::Navigating),
        None
    );
    assert!(!c.manoeuvring());
    assert_eq!(c.navigation_stats().manoeuvres_given_up, 1);
    let said: Vec<String> = std::mem::take(&mut c.said);
    assert_eq!(said, ["I could not work my way through the doorway."]);
}

/// "No" to backing up after what asked has ended (the back-off over, a
/// passage on to another phase): the chair stays held on its way, no
/// back-off is asked for there again, and the trip goes on (not "Staying
/// here.", which ends it).
#[test]
fn no_to_a_back_up_no_longer_under_way_keeps_the_trip() {
    let (mut c, _, began, said) = held_going_to_a_chair_3_m_ahead();
    began.unwrap_or_else(|| panic!("no manoeuvre: {said:?}"));
    c.end_manoeuvre("test: over");
    assert!(!c.manoeuvring() && !c.back_off.backing());
    no_to_backing_up(&mut c);
    assert!(matches!(c.goal.state(), GoalState::Tracking { .. }));
}

/// The person says "no" to backing up: the chair says "I will not back
/// up.", not "Staying here." (the trip goes on).
fn no_to_backing_up(c: &mut Control) {
    c.asked_rear = Some(Pose2::default());
    c.asked_back_up = true;
    c.on_input(UserInput::No);
    let said: Vec<String> = std::mem::take(&mut c.said);
    assert!(said.iter().any(|s| s == "I will not back up."), "{said:?}");
    assert!(!said.iter().any(|s| s.contains("Staying here")), "{said:?}");
}
