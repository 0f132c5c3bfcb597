//! Tests of the chair held on the way: backing off, detours, asking about
//! the rear, arriving as near as it safely goes, giving up (split out of
//! `control_tests`, whose helpers they use).

use super::*;

/// One step at `ms_` with a box 0.7 m ahead (and the room's far wall).
fn step_with_a_box_ahead(c: &mut Control, ms_: u64, tracker: &Tracker) -> ControlOutput {
    step_with_points(c, ms_, tracker, vec![[0.7, 0.0], [4.0, 0.0]])
}

/// One step at `ms_`, the chair at rest at the origin, the lasers seeing
/// `points_base`.
pub(super) fn step_with_points(
    c: &mut Control,
    ms_: u64,
    tracker: &Tracker,
    points_base: Vec<[f32; 2]>,
) -> ControlOutput {
    step_facing(c, ms_, tracker, 0.0, points_base)
}

/// One step at `ms_`, the chair at rest at the origin facing `theta_rad`
/// (odom), the lasers seeing `points_base`.
fn step_facing(
    c: &mut Control,
    ms_: u64,
    tracker: &Tracker,
    theta_rad: f64,
    points_base: Vec<[f32; 2]>,
) -> ControlOutput {
    let pose = Pose2 {
        theta_rad,
        ..Pose2::default()
    };
    step_at_pose(c, ms_, tracker, pose, points_base)
}

#[test]
fn held_by_something_ahead_on_the_way_it_backs_off_a_little_then_tries_again() {
    // a place to search 2 m ahead, a box 0.7 m ahead in the way
    let (mut c, tracker) = searching_two_metres_ahead(false);
    // a chair that never moved does not back onto floor it has not stood
    // on (a step down behind is seen by nothing)
    let mut still = control(false);
    still.on_input(UserInput::Goto("chair".into()));
    step_empty(&mut still, 0);
    still.goal.explore(at(0), Some([2.0, 0.0]));
    for k in 1..=140u64 {
        let out = step_with_a_box_ahead(&mut still, 50 * k, &tracker);
        assert!(out.cmd.cmd.v_mps >= 0.0, "backed off at {k}");
    }
    assert_eq!(still.back_off.count, 0);
    // the same, with the person's word that it is clear behind (they see
    // a step down): it backs off
    let mut told = control(false);
    told.on_input(UserInput::Goto("chair".into()));
    step_empty(&mut told, 0);
    told.goal.explore(at(0), Some([2.0, 0.0]));
    told.rear.confirm(at(0), Pose2::default());
    let backed = (1..=140u64)
        .map(|k| step_with_a_box_ahead(&mut told, 50 * k, &tracker))
        .any(|out| out.cmd.cmd.v_mps < -0.01);
    assert!(backed && told.back_off.count >= 1);
    // this one came 0.4 m forward to where it stands
    for x in [-0.4, -0.3, -0.2, -0.1] {
        c.back_off.trail.push(Pose2 {
            x_m: x,
            y_m: 0.0,
            theta_rad: 0.0,
        });
    }
    let mut first_back = None;
    let mut last_back = None;
    for k in 1..=140u64 {
        let out = step_with_a_box_ahead(&mut c, 50 * k, &tracker);
        if out.cmd.cmd.v_mps < -0.01 {
            first_back.get_or_insert(50 * k);
            last_back = Some(50 * k);
        }
    }
    // held for 3 s first, then backing until 12 cm back (the chair never
    // moves in this test: it backs for as long as a back-off lasts)
    let first = first_back.expect("it backs off");
    assert!((3000..=3300).contains(&first), "{first} ms");
    assert!(c.back_off.count >= 1);
    assert!(last_back.expect("backing") >= first + 1300);
}

/// Something the lasers saw before, now behind the chair in their blind
/// sector, 0.72 m from base_link: inside the corners' circle with the full
/// margin (0.75 m) but outside it with the crawl's (0.68 m). The search
/// turn is slowed to a crawl and turns; before the controller's turn
/// checks counted the remembered rear, it asked for the faster turn, which
/// the supervisor (counting it) held, step after step.
#[test]
fn a_turn_with_something_remembered_behind_just_outside_the_crawl_margin_crawls() {
    let mut c = control(false);
    let tracker = Tracker::new(crate::config::Settings::defaults().tracker);
    c.on_input(UserInput::Goto("chair".into()));
    let crawl = c.supervisor.crawl_turn_radps();
    // seen ahead facing the other way: behind now
    let pi = std::f64::consts::PI;
    step_facing(&mut c, 0, &tracker, pi, vec![[0.72, 0.0], [4.0, 0.0]]);
    let mut turned = 0;
    for k in 1..40 {
        let out = step_facing(&mut c, 50 * k, &tracker, 0.0, vec![[4.0, 0.0]]);
        let w = out.cmd.cmd.omega_radps.abs();
        assert!(w <= crawl + 1e-9, "step {k}: {w} rad/s, crawl {crawl}");
        assert_ne!(
            out.cmd.state,
            SupervisorState::Stopped(crate::msg::StopReason::Obstacle),
            "step {k}"
        );
        turned += usize::from(w > 0.01);
    }
    assert!(turned >= 30, "turned in {turned} of 39 steps");
}

/// Held by something ahead with the rear unseen (nothing seen behind,
/// nothing stood on there): the back-off is tried all the same, the
/// supervisor holds the reverse, and the person is asked whether it is
/// clear behind (they would see a step down too). "Yes": it backs.
/// "No": it stays held, says so, the trip goes on, and it is not asked
/// again from there. The person's "no" to a turn on the spot here before
/// does not stop the question: backing up straight is another question,
/// and unasked, the back-off would wait out its time with the chair held.
#[test]
fn held_with_the_rear_unseen_it_asks_before_backing_off() {
    let asked_after = |answer: UserInput, turn_refused_here: bool| {
        let (mut c, tracker) = searching_two_metres_ahead(false);
        c.supervisor.limits.turn_needs_seen_rear = true;
        if turn_refused_here {
            c.turn_refused_at = Some(crate::msg::Pose2::default());
        }
        let mut said = Vec::new();
        let mut k = 1;
        while k < 200 && !said.iter().any(|l: &String| l.contains("back up a little")) {
            let out = step_with_a_box_ahead(&mut c, 50 * k, &tracker);
            assert!(out.cmd.cmd.v_mps >= 0.0, "backed unasked at {k}");
            said.extend(out.said);
            k += 1;
        }
        assert!(
            said.iter().any(|l| l.contains("Is it clear behind?")),
            "never asked: {said:?}"
        );
        c.on_input(answer);
        let mut backed = false;
        for k in k..k + 100 {
            let out = step_with_a_box_ahead(&mut c, 50 * k, &tracker);
            backed |= out.cmd.cmd.v_mps < -0.01;
            said.extend(out.said);
        }
        (c, backed, said)
    };
    let asked_then = |answer: UserInput| asked_after(answer, false);
    let (c, backed, said) = asked_then(UserInput::Yes);
    assert!(backed, "{said:?}");
    assert!(
        said.iter().any(|l| l == "Thank you. Backing up."),
        "{said:?}"
    );
    assert_ne!(*c.goal_state(), GoalState::None);
    let (c, backed, said) = asked_then(UserInput::No);
    assert!(!backed, "{said:?}");
    assert!(said.iter().any(|l| l == "I will not back up."), "{said:?}");
    assert_eq!(
        said.iter()
            .filter(|l| l.contains("back up a little"))
            .count(),
        1,
        "{said:?}"
    );
    assert_ne!(*c.goal_state(), GoalState::None, "the trip goes on");
    let (_, backed, said) = asked_after(UserInput::Yes, true);
    assert!(backed, "a turn refused here: {said:?}");
}

/// A chair (0.5 m square, 0.9 m high) centred `x_m` ahead, in odom.
pub(super) fn chair_at(x_m: f32) -> crate::msg::Object3D {
    chair_at_xy(x_m, 0.0)
}

/// Goes to a chair centred `x_m` ahead with a box ahead and to the left
/// holding the way (off the line to the chair: the place beside it stays
/// straight ahead), for `steps` steps of 50 ms; the step at which the trip
/// ended and what was said.
fn held_on_the_way_to_a_chair_at(x_m: f32, steps: u64) -> (Option<u64>, Vec<String>) {
    trip_to(
        control(true),
        chair_at(x_m),
        vec![[0.68, 0.36], [4.0, 0.0]],
        steps,
    )
}

/// One step at `ms_`, the chair at rest at the origin, the camera seeing
/// `chair` (into `tracker`) and the lasers `points_base`.
pub(super) fn step_seeing_chair(
    c: &mut Control,
    tracker: &mut Tracker,
    chair: &crate::msg::Object3D,
    ms_: u64,
    points_base: Vec<[f32; 2]>,
) -> ControlOutput {
    tracker.update(at(ms_), std::slice::from_ref(chair), |_| true);
    step_facing(c, ms_, tracker, 0.0, points_base)
}

/// Goes to `chair` with the lasers' points `points_base`, for `steps` steps
/// of 50 ms (the chair stands where it is); the step at which the trip
/// ended (arrived, at rest) and what was said.
fn trip_to(
    mut c: Control,
    chair: crate::msg::Object3D,
    points_base: Vec<[f32; 2]>,
    steps: u64,
) -> (Option<u64>, Vec<String>) {
    c.on_input(UserInput::Goto("chair".into()));
    let mut tracker = Tracker::new(crate::config::Settings::defaults().tracker);
    let mut said = Vec::new();
    for k in 0..steps {
        let out = step_seeing_chair(&mut c, &mut tracker, &chair, 50 * k, points_base.clone());
        said.extend(out.said);
        if out.done.is_some() {
            assert_eq!(out.done, Some(Outcome::Arrived));
            assert_eq!(out.cmd.cmd, VelocityCmd::default());
            return (Some(k), said);
        }
    }
    (None, said)
}

#[test]
fn held_near_the_place_beside_the_object_it_arrives_as_near_as_it_safely_goes() {
    // the place beside this chair is ~0.2 m ahead (not within the 0.1 m
    // of an arrival), the box holds the chair where it stands
    let (done, said) = held_on_the_way_to_a_chair_at(1.65, 100);
    let k = done.unwrap_or_else(|| panic!("no arrival: {said:?}"));
    // held for ARRIVE_HELD_AFTER (2 s) from the first held step
    assert!((40..=48).contains(&k), "ended at step {k}");
    assert!(
        said.iter()
            .any(|s| s.contains("as near the chair as I can safely go")),
        "{said:?}"
    );
    // the same hold 1.4 m short of the place: no arrival (it backs off and
    // tries again instead)
    let (done, said) = held_on_the_way_to_a_chair_at(3.0, 100);
    assert_eq!(done, None, "{said:?}");
    assert!(said.iter().any(|s| s == "Going to the chair."), "{said:?}");
}

#[test]
fn held_by_something_beside_the_way_it_drives_a_detour_the_supervisor_admits() {
    // a place to search 2 m ahead; a post ahead on the left, inside the
    // stop corridor of the straight way
    let (mut c, tracker) = searching_two_metres_ahead(false);
    let mut moved = 0;
    for k in 1..=40u64 {
        let out = step_with_points(&mut c, 50 * k, &tracker, vec![[0.68, 0.2], [4.0, 0.0]]);
        if out.cmd.cmd.v_mps > 0.0 || out.cmd.cmd.omega_radps != 0.0 {
            moved += 1;
            // away from the post: to the right
            assert!(out.cmd.cmd.omega_radps <= 0.0, "step {k}: {:?}", out.cmd);
        }
    }
    let stats = c.navigation_stats();
    assert!(stats.detours > 0, "{stats:?}");
    assert!(moved >= 30, "moved on {moved} of 40 steps");
    assert_eq!(c.back_off.count, 0, "no need to back off");
    // the same post dead ahead of a chair that cannot turn on the spot or
    // bend round it: no detour is driven, the supervisor holds the chair
    let mut held = control(false);
    held.on_input(UserInput::Goto("chair".into()));
    step_empty(&mut held, 0);
    held.goal.explore(at(0), Some([2.0, 0.0]));
    for k in 1..=20u64 {
        let out = step_with_a_box_ahead(&mut held, 50 * k, &tracker);
        if k > 2 {
            assert_eq!(out.cmd.cmd, VelocityCmd::default(), "step {k}");
        }
    }
}

/// A detour is followed as it was scored — a turn on the spot for half
/// the horizon, then a crawl straight on; an arc as it is — even once the
/// planner's own command is free again (it would turn straight back into
/// the hold), and then the planner's command is the chair's again.
#[test]
fn a_detour_is_followed_for_its_horizon_then_the_planner_drives_again() {
    use crate::navigation::detour::HORIZON_S;
    let (mut c, tracker) = searching_two_metres_ahead(false);
    step_with_points(&mut c, 50, &tracker, vec![[0.68, 0.2], [4.0, 0.0]]);
    let (since, detour) = c.detour_since.expect("held by the post: a detour");
    assert_eq!(since, at(50));
    let crawl = VelocityCmd {
        v_mps: c.supervisor.limits.v_forward_max_mps / 3.0,
        omega_radps: 0.0,
    };
    let horizon_ms = (HORIZON_S * 1000.0) as u64;
    let mut planner_again = 0;
    // the post gone (a person who walked on): the planner's way is free
    for k in 2..=50u64 {
        step_with_points(&mut c, 50 * k, &tracker, vec![[4.0, 0.0]]);
        let sent = c.planner_cmd.map(|p| p.value);
        let age_ms = 50 * k - 50;
        if age_ms < horizon_ms {
            let want = if detour.v_mps.abs() < 0.05 && age_ms >= horizon_ms / 2 {
                crawl
            } else {
                detour
            };
            assert_eq!(sent, Some(want), "step {k}, {age_ms} ms into the detour");
        } else {
            assert!(c.detour_since.is_none(), "step {k}: over after the horizon");
            assert!(sent.is_some_and(|s| s != detour && s != crawl), "step {k}");
            planner_again += 1;
        }
    }
    assert!(planner_again >= 15, "{planner_again}");
}

#[test]
fn held_on_the_way_with_no_way_round_it_says_so_once_and_goes_on_when_clear() {
    let (mut c, tracker) = searching_two_metres_ahead(false);
    let told = |said: &[String]| {
        said.iter()
            .filter(|s| s.contains("cannot find a way round"))
            .count()
    };
    // a box dead ahead, no floor behind to back onto: held for 15 s
    let mut said = Vec::new();
    let mut first_told = None;
    for k in 1..=300u64 {
        let out = step_with_a_box_ahead(&mut c, 50 * k, &tracker);
        assert_eq!(out.cmd.cmd, VelocityCmd::default(), "step {k}");
        if told(&out.said) > 0 {
            first_told.get_or_insert(50 * k);
        }
        said.extend(out.said);
    }
    assert_eq!(told(&said), 1, "{said:?}");
    let first = first_told.expect("told");
    assert!(
        (SAY_HELD_AFTER.as_millis() as u64..=SAY_HELD_AFTER.as_millis() as u64 + 300)
            .contains(&first),
        "told at {first} ms"
    );
    // the box is taken away: it drives on by itself
    let moved = (301..=320u64).any(|k| step_empty(&mut c, 50 * k).cmd.cmd.v_mps > 0.0);
    assert!(moved, "did not go on when the way cleared");
    // held again: told again, after another full wait
    let again: usize = (321..=321 + 220u64)
        .map(|k| told(&step_with_a_box_ahead(&mut c, 50 * k, &tracker).said))
        .sum();
    assert_eq!(again, 1);
}

/// The living-room trip on the real-time clock: close to the place beside
/// the chair, the planner's command switched each step between a crawl
/// (allowed) and a turn on the spot (refused, the rear unseen). The wait
/// restarted at every allowed step, so the chair never asked and never
/// arrived, and said nothing for 25 s.
#[test]
fn turns_refused_between_crawls_still_ask_about_the_rear_once() {
    let rear_unseen = SupervisorState::Stopped(crate::msg::StopReason::RearUnseen);
    let pose = Some(Pose2::default());
    let asked = |c: &Control| {
        c.said
            .iter()
            .filter(|l| l.contains("cannot see behind me"))
            .count()
    };
    let mut c = control(false);
    for k in 0..40u64 {
        let state = if k % 2 == 0 {
            rear_unseen
        } else {
            SupervisorState::Navigating
        };
        c.ask_about_rear(at(50 * k), state, pose, false, false);
    }
    assert_eq!(asked(&c), 1, "{:?}", c.said);
    assert!(c.asking(), "waits for the answer");
    // turns allowed for a second: that wait is over, a later one asks again
    for k in 40..62u64 {
        c.ask_about_rear(at(50 * k), SupervisorState::Navigating, pose, false, false);
    }
    assert!(!c.asking());
    for k in 62..90u64 {
        c.ask_about_rear(at(50 * k), rear_unseen, pose, false, false);
    }
    assert_eq!(asked(&c), 2, "{:?}", c.said);
    // floor never seen in the turn's circle: asked about all around
    let floor_unseen = SupervisorState::Stopped(crate::msg::StopReason::FloorUnseen);
    // (about what lies low before the chair only where the camera never
    // saw the floor there)
    for (state, unseen) in [(rear_unseen, true), (floor_unseen, false)] {
        for before in [false, true] {
            let mut c = control(false);
            for k in 0..30u64 {
                c.ask_about_rear(at(50 * k), state, pose, unseen, before);
            }
            let around: Vec<_> = c
                .said
                .iter()
                .filter(|l| l.contains("Is it clear around me?"))
                .collect();
            assert_eq!(around.len(), 1, "{:?}", c.said);
            assert_eq!(around[0].contains("before me"), before, "{:?}", c.said);
            assert!(around[0].contains("nothing low beside"), "{:?}", c.said);
            assert!(c.asked_around && c.asking());
        }
    }
}

/// A chair (0.5 m square, 0.9 m high) centred at (`x_m`, `y_m`) in odom.
fn chair_at_xy(x_m: f32, y_m: f32) -> crate::msg::Object3D {
    use nalgebra::Point3;
    let pts = vec![
        Point3::new(x_m - 0.25, y_m - 0.25, 0.0),
        Point3::new(x_m + 0.25, y_m + 0.25, 0.9),
    ];
    crate::msg::Object3D::from_points("chair".into(), 0.9, crate::msg::Frame::Odom, pts, None)
        .expect("object")
}

/// Goes to a chair at (`x_m`, `y_m`) with the rear unseen and nobody
/// answering, for `steps` steps of 50 ms (the chair stands where it is);
/// the step at which the trip ended and what was said.
fn unanswered_about_the_rear_going_to_a_chair_at(
    x_m: f32,
    y_m: f32,
    steps: u64,
) -> (Option<u64>, Vec<String>) {
    let mut c = control(true);
    c.supervisor.limits.turn_needs_seen_rear = true;
    trip_to(c, chair_at_xy(x_m, y_m), vec![[4.0, 0.0]], steps)
}

#[test]
fn asked_about_the_rear_near_the_object_and_not_answered_it_arrives_as_near_as_it_goes() {
    // the place beside this chair is within 0.3 m, but facing it needs a
    // turn on the spot, refused with the rear unseen: asked once, then 2 s
    // without an answer ends the trip there
    let (done, said) = unanswered_about_the_rear_going_to_a_chair_at(0.9, 0.9, 120);
    let k = done.unwrap_or_else(|| panic!("no arrival: {said:?}"));
    let asked = said
        .iter()
        .filter(|s| s.contains("cannot see behind me"))
        .count();
    assert_eq!(asked, 1, "{said:?}");
    // asked after 1 s of waiting, arrived 2 s after
    assert!((55..=70).contains(&k), "ended at step {k}: {said:?}");
    assert!(
        said.iter()
            .any(|s| s.contains("as near the chair as I can safely go")),
        "{said:?}"
    );
    // the same question far from the place: it waits for the answer
    let (done, said) = unanswered_about_the_rear_going_to_a_chair_at(2.5, 2.5, 120);
    assert_eq!(done, None, "{said:?}");
    assert!(
        said.iter().any(|s| s.contains("cannot see behind me")),
        "{said:?}"
    );
}

#[test]
fn held_or_standing_still_on_the_way_is_said_once_after_the_time() {
    let mut c = control(false);
    let said = |c: &mut Control| std::mem::take(&mut c.said);
    let held_at = |c: &mut Control, ms: u64, held: Option<held::Held>| {
        c.tell_if_held(at(ms), Pose2::default(), &[], held);
    };
    use held::Held::{StandingStill, Supervisor};
    // standing still with nothing holding it: said after SAY_HELD_AFTER
    held_at(&mut c, 0, Some(StandingStill));
    held_at(&mut c, 9_900, Some(StandingStill));
    assert!(said(&mut c).is_empty());
    held_at(&mut c, 10_000, Some(StandingStill));
    let s = said(&mut c);
    assert_eq!(s.len(), 1, "{s:?}");
    assert!(s[0].contains("cannot find how to get nearer"), "{s:?}");
    // once, though it goes on (and a hold after it is the same wait)
    held_at(&mut c, 12_000, Some(Supervisor));
    assert!(said(&mut c).is_empty());
    // moving again ends it; a supervisor's hold is its own sentence
    held_at(&mut c, 13_000, None);
    held_at(&mut c, 14_000, Some(Supervisor));
    held_at(&mut c, 24_000, Some(Supervisor));
    let s = said(&mut c);
    assert_eq!(s.len(), 1, "{s:?}");
    assert!(s[0].contains("Something is in my way"), "{s:?}");
}

/// Held on the way to the only chair in the room for
/// `give_up_held_after`: the goal is given up and another chair looked
/// for (a search turn); none found, the chair stops and says so.
#[test]
fn held_on_the_way_to_an_object_without_a_break_it_gives_the_goal_up_and_stops() {
    let give_up = crate::config::Settings::defaults()
        .goal_settings()
        .give_up_held_after;
    let give_up_ms = give_up.as_millis() as u64;
    for exit_on_arrival in [true, false] {
        let mut c = control(exit_on_arrival);
        c.on_input(UserInput::Goto("chair".into()));
        let mut tracker = Tracker::new(crate::config::Settings::defaults().tracker);
        let chair = chair_at(3.0);
        let mut said = Vec::new();
        let mut gave_up_at = None;
        let mut stopped_at = None;
        // a box 0.7 m ahead holds the way to the place beside the chair
        // (1.85 m ahead); no floor behind to back onto, no way round
        // (the chair turns in place as told: the search turn)
        let mut theta_rad = 0.0f64;
        for k in 0..=(give_up_ms + 60_000) / 50 {
            let now = at(50 * k);
            tracker.update(now, std::slice::from_ref(&chair), |_| true);
            let seen = [0.7f64, 4.0].map(|x_m| {
                [
                    (x_m * theta_rad.cos()) as f32,
                    (-x_m * theta_rad.sin()) as f32,
                ]
            });
            let out = step_facing(&mut c, 50 * k, &tracker, theta_rad, seen.to_vec());
            theta_rad += out.cmd.cmd.omega_radps * 0.05;
            // (the search turn's first steps until the track is confirmed,
            // and the search turn for another chair after the give-up)
            if k > 5 && gave_up_at.is_none() || stopped_at.is_some() {
                assert_eq!(out.cmd.cmd, VelocityCmd::default(), "step {k}");
            }
            if out.said.iter().any(|s| s.contains("blocked for")) {
                assert!(gave_up_at.is_none(), "given up twice: {said:?}");
                gave_up_at = Some(50 * k);
                assert_eq!(out.done, None, "{said:?}");
            }
            if out.said.iter().any(|s| s.contains("cannot find another")) {
                assert!(stopped_at.is_none(), "stopped twice: {said:?}");
                stopped_at = Some(50 * k);
                assert_eq!(
                    out.done,
                    exit_on_arrival.then_some(Outcome::GaveUp),
                    "{said:?}"
                );
            }
            said.extend(out.said);
        }
        assert!(said.iter().any(|s| s == "Going to the chair."), "{said:?}");
        // told first, with how long it will wait
        let told = said
            .iter()
            .position(|s| s.contains("cannot find a way round it"))
            .unwrap_or_else(|| panic!("not told: {said:?}"));
        assert!(
            said[told].contains(&format!(
                "wait for {} more seconds",
                (give_up - SAY_HELD_AFTER).as_secs()
            )),
            "{said:?}"
        );
        // then given up after the hold (which began a few steps in, once
        // the track was confirmed and the supervisor held the way)
        let at_ms = gave_up_at.unwrap_or_else(|| panic!("not given up: {said:?}"));
        assert!(
            (give_up_ms..=give_up_ms + 500).contains(&at_ms),
            "given up at {at_ms} ms"
        );
        assert!(
            said.iter().any(|s| s
                == "I cannot get to this chair: my way has been blocked for 40 seconds. \
                    Looking for another chair."),
            "{said:?}"
        );
        // the search turn finds no other chair: stopped, and said so
        let stopped_ms = stopped_at.unwrap_or_else(|| panic!("not stopped: {said:?}"));
        assert!(stopped_ms > at_ms, "{stopped_ms} ms");
        assert_eq!(
            said.last().map(String::as_str),
            Some("I cannot get to the chair I found, and I cannot find another chair. Stopped."),
            "{said:?}"
        );
        assert_eq!(*c.goal_state(), GoalState::None);
    }
}
