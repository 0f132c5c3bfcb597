//! Tests of the person's "no" to the question about all around the chair
//! (split out of `control_tests`, whose helpers they use).

use super::*;

/// "No" to "is it clear around me?": the chair neither turns nor drives
/// into the floor it never saw there (something may lie on it that no
/// sensor sees); a new word clears the refusal with the trip.
#[test]
fn after_a_no_about_all_around_the_unseen_floor_there_holds_the_chair() {
    let mut c = control(false);
    let step = step_with_unseen_ring;
    c.on_input(UserInput::Goto("chair".into()));
    let mut said = Vec::new();
    for k in 0..40 {
        said.extend(step(&mut c, k).said);
    }
    assert!(
        said.iter().any(|l| l.contains("Is it clear around me?")),
        "{said:?}"
    );
    c.on_input(UserInput::No);
    let mut said = Vec::new();
    for k in 40..120 {
        let out = step(&mut c, k);
        assert_eq!(out.cmd.cmd, VelocityCmd::default(), "step {k}");
        said.extend(out.said);
    }
    assert!(
        said.iter().any(|l| l.starts_with("I will not turn here.")),
        "{said:?}"
    );
    // the ring is an obstacle now, in the camera's points the supervisor
    // and the planner take
    let pose = Pose2::default();
    let mut o = Obstacles {
        floor_unseen_base: vec![[0.65, 0.0], [0.0, -0.7], [0.9, 0.0]],
        ..Default::default()
    };
    c.hold_refused_floor(&pose, &mut o);
    assert_eq!(o.points_base, vec![[0.65, 0.0], [0.0, -0.7]]);
    // a new word: a new trip, asked afresh
    c.on_input(UserInput::Goto("chair".into()));
    let mut o = Obstacles {
        floor_unseen_base: vec![[0.65, 0.0]],
        ..Default::default()
    };
    c.hold_refused_floor(&pose, &mut o);
    assert!(o.points_base.is_empty());
}

/// "No" to "is it clear behind?" says nothing of the floor: it stays
/// as it was.
#[test]
fn a_no_about_behind_only_leaves_the_floor_as_it_was() {
    let mut c = control(false);
    c.supervisor.limits.turn_needs_seen_rear = true;
    c.on_input(UserInput::Goto("chair".into()));
    let mut said = Vec::new();
    for k in 0..40 {
        said.extend(step_empty(&mut c, 50 * k).said);
    }
    assert!(
        said.iter().any(|l| l.contains("Is it clear behind?")),
        "{said:?}"
    );
    c.on_input(UserInput::No);
    step_empty(&mut c, 2000);
    let mut o = Obstacles {
        floor_unseen_base: vec![[0.65, 0.0]],
        ..Default::default()
    };
    c.hold_refused_floor(&Pose2::default(), &mut o);
    assert!(o.points_base.is_empty());
}
