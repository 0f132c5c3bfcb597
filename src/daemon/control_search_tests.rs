//! Tests of a search that cannot go on: the chair held in one place while
//! it looks for the word (split out of `control_tests`, whose helpers
//! they use).

use super::*;

/// A wall of points across the way 0.7 m ahead, and the room's far wall.
fn wall_ahead() -> Vec<[f32; 2]> {
    let mut points_base: Vec<[f32; 2]> = (-8..=8).map(|k| [0.7, k as f32 * 0.05]).collect();
    points_base.push([4.0, 0.0]);
    points_base
}

/// Held by a wall across its way to every place to look from, the chair
/// stays where it is: after `goal.search_held_s` there, and not
/// before, the search ends — it stops and says it is held, not that the
/// word is nowhere to be found.
#[test]
fn searching_held_in_one_place_the_search_ends_after_its_time() {
    let (mut c, tracker) = searching_two_metres_ahead(true);
    let limit_ms = c.goal.settings.search_held_for.as_millis() as u64;
    let mut said = Vec::new();
    let mut ended = None;
    // when the chair said it is held, and the wait it named (s)
    let mut told = None;
    for k in 1..=(limit_ms + 2_000) / 50 {
        let out = step_at_pose(&mut c, 50 * k, &tracker, Pose2::default(), wall_ahead());
        for s in &out.said {
            if let Some(wait) = s
                .split(" more seconds")
                .next()
                .filter(|_| s.contains(" more seconds"))
                .and_then(|head| head.rsplit(' ').next())
            {
                told.get_or_insert((50 * k, wait.to_string()));
            }
        }
        // each new place to look from is held too: the search goes on
        // looking (the keeper's own time, 240 s, is far off)
        if c.goal.state() == &GoalState::None && ended.is_none() {
            ended = Some(50 * k);
            assert_eq!(out.done, Some(Outcome::GaveUp), "{said:?}");
        }
        said.extend(out.said);
        if ended.is_some() {
            assert_eq!(out.cmd.cmd, VelocityCmd::default());
        }
    }
    let ended = ended.unwrap_or_else(|| panic!("the search never ended: {said:?}"));
    assert!(
        (limit_ms..=limit_ms + 200).contains(&ended),
        "ended at {ended} ms: {said:?}"
    );
    assert!(
        said.iter()
            .any(|s| s.starts_with("I cannot look further for a chair: I have been held")),
        "{said:?}"
    );
    assert!(
        !said.iter().any(|s| s.contains("cannot find a chair")),
        "{said:?}"
    );
    // told it is held, with how long it will wait there: the search's end
    // within a second of that
    assert!(
        !said.iter().any(|s| s.contains("go on when it is clear")),
        "{said:?}"
    );
    let (told_ms, wait) = told.unwrap_or_else(|| panic!("no wait named: {said:?}"));
    let wait_s: u64 = wait
        .parse()
        .unwrap_or_else(|_| panic!("the wait {wait:?} is no number: {said:?}"));
    let named_end_ms = told_ms + 1_000 * wait_s;
    assert!(
        named_end_ms.abs_diff(ended) <= 1_000,
        "said at {told_ms} ms it would wait {wait_s} s, ended at {ended} ms: {said:?}"
    );
}

/// The same search with the chair getting on (0.1 m further every 10 s,
/// more than the 5 cm that is one place): no end for being held.
#[test]
fn a_search_that_gets_on_is_not_ended_for_being_held() {
    let (mut c, tracker) = searching_two_metres_ahead(true);
    let limit_ms = c.goal.settings.search_held_for.as_millis() as u64;
    let mut said = Vec::new();
    for k in 1..=(2 * limit_ms) / 50 {
        let x_m = 0.1 * ((50 * k) / 10_000) as f64;
        let pose = Pose2 {
            x_m,
            ..Pose2::default()
        };
        let out = step_at_pose(&mut c, 50 * k, &tracker, pose, wall_ahead());
        assert_eq!(out.done, None, "step {k}: {said:?}");
        said.extend(out.said);
    }
    assert!(
        !said.iter().any(|s| s.contains("cannot look further")),
        "{said:?}"
    );
}
