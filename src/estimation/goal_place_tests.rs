//! Tests of `estimation::goal`: the place beside the object, the search
//! turn, and arriving (split out of `goal_tests.rs` to keep both readable).

use super::tests::{chair_obj, see_a_chair_ahead, t};
use super::*;
use crate::msg::Frame;
use crate::perception::boxes::Object3D;
use nalgebra::Point3;

#[test]
fn the_place_beside_the_object_is_one_the_map_admits_where_there_is_one() {
    let approach_with = |fits: &dyn Fn([f64; 2]) -> bool| {
        let mut g = GoalKeeper::new(crate::config::Settings::defaults().goal_settings());
        g.set_prompt("chair");
        see_a_chair_ahead(&mut g, &|_| true, fits);
        g.approach().expect("an approach")
    };
    // nothing against it: straight on, between the chair and the object
    let a = approach_with(&|_| true);
    assert!((a.x_m - 1.6).abs() < 1e-6 && a.y_m.abs() < 1e-6, "{a:?}");
    // the map has the near side blocked (something seen before, out of
    // sight now): another side, still facing the object
    let a = approach_with(&|p| p[0] > 2.0);
    assert!(a.x_m > 2.0, "{a:?}");
    assert!(
        (a.yaw_rad - (0.0 - a.y_m).atan2(3.0 - a.x_m)).abs() < 1e-9,
        "{a:?}"
    );
    // no side the map admits: as without the map
    let a = approach_with(&|_| false);
    assert!((a.x_m - 1.6).abs() < 1e-6 && a.y_m.abs() < 1e-6, "{a:?}");
}

/// Once driving to a place, the place moves only to a side the map
/// admits: with none admitted it keeps to its side (the sides a map
/// refuses are floor never seen, behind the wall an object stands
/// against, and the first of them from the chair flips as it moves);
/// another side, after one was refused, must be admitted.
#[test]
fn the_place_moves_only_to_a_side_the_map_admits() {
    let settings = crate::config::Settings::defaults().goal_settings();
    let mut g = GoalKeeper::new(settings);
    g.set_prompt("chair");
    let mut tracker = see_a_chair_ahead(&mut g, &|_| true, &|_| true);
    let first = g.approach().expect("an approach");
    let apart = |a: &ApproachPose, b: &ApproachPose| (a.x_m - b.x_m).hypot(a.y_m - b.y_m);
    // the chair now beside the object's -y face, 2 m off
    let beside = Pose2 {
        x_m: 3.0,
        y_m: -2.0,
        theta_rad: std::f64::consts::FRAC_PI_2,
    };
    let mut step = |g: &mut GoalKeeper, k: u32, fits: &dyn Fn([f64; 2]) -> bool| {
        let now = t(1.0 + k as f64 * 0.1);
        tracker.update(now, &[chair_obj(3.0)], |_| true);
        g.update(now, &tracker, beside, &[], &|_| true, fits)
    };
    // no side admitted: the place keeps to its side (-x), though the
    // -y side is nearest now
    step(&mut g, 0, &|_| false);
    let kept = g.approach().expect("a place");
    assert!(
        kept.x_m < 2.0 && apart(&first, &kept) < 0.5,
        "{first:?} {kept:?}"
    );
    // the -y side admitted: the place goes there, the side nearest now
    let minus_y_face = |p: [f64; 2]| p[1] < -0.5 && (p[0] - 3.0).abs() < 0.3;
    step(&mut g, 1, &minus_y_face);
    let moved = g.approach().expect("a place");
    assert!(
        moved.y_m < -0.5 && (moved.x_m - 3.0).abs() < 0.3,
        "{moved:?}"
    );
    // that side refused, and only it admitted: no other side, the place
    // stays
    assert!(g.refuse_approach());
    assert_eq!(step(&mut g, 2, &minus_y_face), None);
    let stayed = g.approach().expect("a place");
    assert!(apart(&moved, &stayed) < 0.3, "{moved:?} {stayed:?}");
    // and again, with nothing admitted at all
    assert!(g.refuse_approach());
    assert_eq!(step(&mut g, 3, &|_| false), None);
    let stayed = g.approach().expect("a place");
    assert!(apart(&moved, &stayed) < 0.3, "{moved:?} {stayed:?}");
}

/// A search turn ends once the map has nothing left around the chair to
/// look at, and [`LOOK_SETTLE_RAD`] more; it goes the shorter way to what
/// is left; with something always left, a whole turn.
#[test]
fn a_search_turn_ends_once_nothing_is_left_to_look_at() {
    let settings = crate::config::Settings::defaults().goal_settings();
    let tracker = Tracker::new(crate::config::Settings::defaults().tracker);
    // turns the chair as commanded, 0.1 s a step, with the map's word
    // `left(turned_rad)` before each step; how far it turned when the
    // keeper wanted a place to search next, and the turn's way
    let turn = |left: &dyn Fn(f64) -> (bool, bool)| {
        let mut g = GoalKeeper::new(settings);
        g.explores = true;
        g.set_prompt("chair");
        let (mut heading, mut turned, mut way) = (0.0_f64, 0.0_f64, 0.0_f64);
        for k in 0..1000 {
            let (nothing, cw) = left(turned);
            g.left_to_see(nothing, cw);
            g.update(
                t(k as f64 * 0.1),
                &tracker,
                Pose2 {
                    theta_rad: heading,
                    ..Default::default()
                },
                &[],
                &|_| true,
                &|_| true,
            );
            if g.wants_place() {
                return (turned, way);
            }
            let cmd = g.search_command().expect("turning");
            way = cmd.omega_radps.signum();
            heading = wrap_angle(heading + cmd.omega_radps * 0.1);
            turned += cmd.omega_radps.abs() * 0.1;
        }
        panic!("the turn did not end");
    };
    let tau = std::f64::consts::TAU;
    // something is left until the turn has gone 2 rad
    let (turned, way) = turn(&|turned| (turned >= 2.0, false));
    assert_eq!(way, 1.0, "counter-clockwise by default");
    assert!(
        (turned - (2.0 + LOOK_SETTLE_RAD)).abs() < 0.05,
        "{turned} rad"
    );
    // nearer clockwise: that way
    let (turned, way) = turn(&|turned| (turned >= 1.0, true));
    assert_eq!(way, -1.0);
    assert!((turned - 1.5).abs() < 0.05, "{turned} rad");
    // always something left: a whole turn
    let (turned, _) = turn(&|_| (false, false));
    assert!((turned - tau).abs() < 0.05, "{turned} rad");
    // nothing left, then something again (a person walked into the
    // camera's memory): the settle starts over
    let (turned, _) = turn(&|turned| (!(0.3..1.5).contains(&turned), false));
    assert!((turned - 2.0).abs() < 0.05, "{turned} rad");
}

/// Held facing the object at the place's distance from it, on another
/// side than the place: as near as it goes too; facing away, not.
#[test]
fn held_at_the_standoff_on_another_side_ends_as_near_as_it_goes() {
    let settings = crate::config::Settings::defaults().goal_settings();
    let standoff = settings.standoff_m + settings.front_offset_m;
    let mut g = GoalKeeper::new(settings);
    g.set_prompt("chair");
    see_a_chair_ahead(&mut g, &|_| true, &|_| true);
    let a = g.approach().expect("an approach");
    // beside the chair's −y face (the place is on its −x side)
    let beside = |theta_rad: f64| Pose2 {
        x_m: 3.0,
        y_m: -0.25 - standoff - 0.1,
        theta_rad,
    };
    assert!((a.x_m - 3.0).hypot(a.y_m - beside(0.0).y_m) > 1.0);
    assert_eq!(
        g.arrive_near(beside(-std::f64::consts::FRAC_PI_2), 0.3),
        None
    );
    assert_eq!(
        g.arrive_near(
            Pose2 {
                y_m: -0.25 - standoff - 0.5,
                ..beside(std::f64::consts::FRAC_PI_2)
            },
            0.3
        ),
        None,
        "0.5 m short"
    );
    assert!(matches!(
        g.arrive_near(beside(std::f64::consts::FRAC_PI_2), 0.3),
        Some(GoalEvent::ReachedNear { .. })
    ));
    assert!(matches!(g.state(), GoalState::Reached { .. }));
}

/// Held on the way to the place beside the object: another side of it,
/// never the refused one again; where there is no other side, the place
/// stays; at most [`REFUSED_AT_MOST`] refused.
#[test]
fn held_on_the_way_to_the_place_the_chair_tries_another_side() {
    let mut g = GoalKeeper::new(crate::config::Settings::defaults().goal_settings());
    assert!(!g.refuse_approach(), "no goal");
    g.set_prompt("chair");
    assert!(!g.refuse_approach(), "searching");
    let mut tracker = see_a_chair_ahead(&mut g, &|_| true, &|_| true);
    let first = g.approach().expect("an approach");
    let step = |g: &mut GoalKeeper, tracker: &mut Tracker, k: u32, obstacles: &[[f64; 2]]| {
        let now = t(1.0 + k as f64 * 0.1);
        tracker.update(now, &[chair_obj(3.0)], |_| true);
        g.update(
            now,
            tracker,
            Pose2::default(),
            obstacles,
            &|_| true,
            &|_| true,
        )
    };
    assert!(g.refuse_approach());
    assert!(!g.refuse_approach(), "one refusal at a time");
    let e = step(&mut g, &mut tracker, 0, &[]);
    assert!(
        matches!(&e, Some(GoalEvent::OtherSide { label }) if label == "chair"),
        "{e:?}"
    );
    assert_eq!(
        e.expect("an event").say(),
        "I cannot get to this side of the chair. Trying another side."
    );
    let second = g.approach().expect("another place");
    let apart = |a: &ApproachPose, b: &ApproachPose| (a.x_m - b.x_m).hypot(a.y_m - b.y_m);
    assert!(apart(&first, &second) > 0.6, "{first:?} {second:?}");
    // from the origin the first side stays the nearest: never chosen again
    for k in 1..5 {
        assert_eq!(step(&mut g, &mut tracker, k, &[]), None);
        assert!(apart(&first, &g.approach().expect("a place")) > 0.6);
    }
    assert!(g.refuse_approach());
    assert!(step(&mut g, &mut tracker, 5, &[]).is_some());
    assert!(g.refuse_approach());
    assert!(step(&mut g, &mut tracker, 6, &[]).is_some());
    assert!(!g.refuse_approach(), "at most {REFUSED_AT_MOST}");

    // something all round the chair but on its −x side (towards the
    // origin): no other side; the place stays the goal's
    let mut g = GoalKeeper::new(crate::config::Settings::defaults().goal_settings());
    g.set_prompt("chair");
    let mut tracker = see_a_chair_ahead(&mut g, &|_| true, &|_| true);
    let only = g.approach().expect("an approach");
    let ring: Vec<[f64; 2]> = (0..360)
        .step_by(3)
        .map(|d| (d as f64).to_radians())
        .filter(|a| wrap_angle(a - std::f64::consts::PI).abs() >= 40f64.to_radians())
        .flat_map(|a| [1.0, 1.2, 1.4, 1.6].map(|r| [3.0 + r * a.cos(), r * a.sin()]))
        .collect();
    assert_eq!(step(&mut g, &mut tracker, 0, &ring), None);
    assert!(apart(&only, &g.approach().expect("a place")) < 0.3);
    assert!(g.refuse_approach());
    assert_eq!(step(&mut g, &mut tracker, 1, &ring), None);
    let kept = g.approach().expect("the place stays");
    assert!(apart(&only, &kept) < 0.3, "{only:?} {kept:?}");
    // and it is not refused: the next update keeps it as well
    assert_eq!(step(&mut g, &mut tracker, 2, &ring), None);
    assert!(apart(&only, &g.approach().expect("a place")) < 0.3);
}

/// At the place beside the object, it must be seen now (where the camera
/// can see it) for the trip to end: a false detection's track, not seen
/// again, is not arrived at.
#[test]
fn arrived_only_where_the_object_is_seen_now() {
    let at = Pose2 {
        x_m: 1.57,
        y_m: 0.02,
        theta_rad: 0.0,
    };
    let mut g = GoalKeeper::new(crate::config::Settings::defaults().goal_settings());
    g.set_prompt("chair");
    let mut tracker = see_a_chair_ahead(&mut g, &|_| true, &|_| true);
    // last seen at 0.2 s; at the place 2 s later, nothing seen since
    let later = 0.2 + SEEN_ON_ARRIVAL.as_secs_f64() + 0.3;
    tracker.update(t(later), &[], |_| false);
    assert_eq!(
        g.update(t(later), &tracker, at, &[], &|_| true, &|_| true),
        None
    );
    assert!(matches!(g.state(), GoalState::Tracking { .. }));
    // where the camera cannot see it (too close, below the view): arrived
    assert!(matches!(
        g.update(t(later), &tracker, at, &[], &|_| false, &|_| true),
        Some(GoalEvent::Reached { .. })
    ));
    // a track missed in most views where it could be seen (a false
    // detection's): not arrived at where the camera cannot see it
    let mut g = GoalKeeper::new(crate::config::Settings::defaults().goal_settings());
    g.set_prompt("chair");
    let mut tracker = see_a_chair_ahead(&mut g, &|_| true, &|_| true);
    for k in 0..3 {
        tracker.update(t(0.3 + 0.1 * k as f64), &[], |_| true);
    }
    let c = tracker.tracks()[0].confidence;
    assert!((0.1..TRUSTED_OUT_OF_SIGHT).contains(&c), "{c}");
    assert_eq!(
        g.update(t(later), &tracker, at, &[], &|_| false, &|_| true),
        None
    );
    assert!(matches!(g.state(), GoalState::Tracking { .. }));
    // seen again at the place: arrived
    let mut g = GoalKeeper::new(crate::config::Settings::defaults().goal_settings());
    g.set_prompt("chair");
    let mut tracker = see_a_chair_ahead(&mut g, &|_| true, &|_| true);
    tracker.update(t(later), &[], |_| false);
    assert_eq!(
        g.update(t(later), &tracker, at, &[], &|_| true, &|_| true),
        None
    );
    tracker.update(t(later + 0.5), &[chair_obj(3.0)], |_| true);
    assert!(matches!(
        g.update(t(later + 0.5), &tracker, at, &[], &|_| true, &|_| true),
        Some(GoalEvent::Reached { .. })
    ));
}

fn chair_at(x: f32, y: f32) -> Object3D {
    let pts = vec![
        Point3::new(x - 0.25, y - 0.25, 0.0),
        Point3::new(x + 0.25, y + 0.25, 0.9),
    ];
    Object3D::from_points("chair".into(), 0.9, Frame::Odom, pts, None).expect("object")
}

/// The first object of the word seen is the goal; another seen later
/// whose place is more than [`NEARER_BY_M`] nearer becomes the goal (and
/// the person hears it), and the far one does not take it back; one
/// about as near does not take it.
#[test]
fn a_nearer_object_of_the_word_becomes_the_goal() {
    let mut g = GoalKeeper::new(crate::config::Settings::defaults().goal_settings());
    let mut tracker = Tracker::new(crate::config::Settings::defaults().tracker);
    let chair = Pose2::default();
    g.set_prompt("chair");
    let mut k = 0;
    let mut step = |g: &mut GoalKeeper, tracker: &mut Tracker, seen: &[Object3D]| {
        let now = t(k as f64 * 0.1);
        k += 1;
        tracker.update(now, seen, |_| true);
        g.update(now, tracker, chair, &[], &|_| true, &|_| true)
    };
    let far = chair_at(6.0, 0.0);
    let mut events = Vec::new();
    for _ in 0..3 {
        events.extend(step(&mut g, &mut tracker, std::slice::from_ref(&far)));
    }
    assert!(
        matches!(&events[..], [GoalEvent::Acquired { .. }]),
        "{events:?}"
    );
    let far_id = match g.state() {
        GoalState::Tracking { track, .. } => *track,
        s => panic!("{s:?}"),
    };
    // about as near, beside it: stays
    let beside = chair_at(5.8, 1.0);
    for _ in 0..5 {
        let e = step(&mut g, &mut tracker, &[far.clone(), beside.clone()]);
        assert_eq!(e, None);
    }
    assert!(matches!(g.state(), GoalState::Tracking { track, .. } if *track == far_id));
    // a nearer one, once confirmed: the goal, said
    let near = chair_at(2.5, 1.5);
    let mut events = Vec::new();
    for _ in 0..4 {
        events.extend(step(
            &mut g,
            &mut tracker,
            &[far.clone(), beside.clone(), near.clone()],
        ));
    }
    assert!(
        matches!(&events[..], [GoalEvent::Nearer { label }] if label == "chair"),
        "{events:?}"
    );
    assert_eq!(events[0].say(), "There is a nearer chair. Going to it.");
    let (near_id, a) = match g.state() {
        GoalState::Tracking {
            track, approach, ..
        } => (*track, *approach),
        s => panic!("{s:?}"),
    };
    assert_ne!(near_id, far_id);
    assert!(a.x_m.hypot(a.y_m) < 2.0, "{a:?}");
    // the far one seen on: no switch back
    for _ in 0..5 {
        assert_eq!(
            step(
                &mut g,
                &mut tracker,
                &[far.clone(), beside.clone(), near.clone()]
            ),
            None
        );
    }
    assert!(matches!(g.state(), GoalState::Tracking { track, .. } if *track == near_id));
}

/// A track of the word in the line of sight before the goal's object,
/// while that is still seen (the depth segmenter took what hides part of
/// it for the object): not "a nearer one", however long it is seen; the
/// same track off to the side is.
#[test]
fn what_stands_before_the_goals_object_is_not_a_nearer_one() {
    for (y_m, nearer) in [(0.2, false), (2.0, true)] {
        let mut g = GoalKeeper::new(crate::config::Settings::defaults().goal_settings());
        let mut tracker = Tracker::new(crate::config::Settings::defaults().tracker);
        let chair = Pose2::default();
        g.set_prompt("chair");
        let far = chair_at(6.0, 0.0);
        let before = chair_at(3.0, y_m);
        let mut events = Vec::new();
        for k in 0..40 {
            let now = t(k as f64 * 0.1);
            let seen = if k < 3 {
                vec![far.clone()]
            } else {
                vec![far.clone(), before.clone()]
            };
            tracker.update(now, &seen, |_| true);
            events.extend(g.update(now, &tracker, chair, &[], &|_| true, &|_| true));
        }
        let switched = events.iter().any(|e| matches!(e, GoalEvent::Nearer { .. }));
        assert_eq!(switched, nearer, "before the goal at y {y_m} m: {events:?}");
    }
}

/// An object turned to odom's axes (a 2 × 1.6 m bed at 45°), held
/// facing it at the place's distance from its side: as near as it goes.
/// Its upright box reaches 1 m nearer there, at its corner; the distance
/// is taken to its outline, as the place beside it is.
#[test]
fn held_at_the_standoff_of_a_turned_object_ends_as_near_as_it_goes() {
    let defaults = crate::config::Settings::defaults();
    let settings = defaults.goal_settings();
    let standoff = settings.standoff_m + settings.front_offset_m;
    let mut tracker = Tracker::new(defaults.tracker);
    let mut g = GoalKeeper::new(settings);
    g.set_prompt("bed");
    let yaw = std::f64::consts::FRAC_PI_4;
    let (c, s) = (yaw.cos(), yaw.sin());
    let mut pts = Vec::new();
    for (x, y) in [(1.0, 0.8), (-1.0, 0.8), (-1.0, -0.8), (1.0, -0.8)] {
        for z in [0.0, 0.5] {
            pts.push(Point3::new(
                (4.0 + x * c - y * s) as f32,
                (x * s + y * c) as f32,
                z,
            ));
        }
    }
    let bed = Object3D::from_points("bed".into(), 0.9, Frame::Odom, pts, None).expect("object");
    let mut events = Vec::new();
    for k in 0..3 {
        tracker.update(t(k as f64 * 0.1), std::slice::from_ref(&bed), |_| true);
        events.extend(g.update(
            t(k as f64 * 0.1),
            &tracker,
            Pose2::default(),
            &[],
            &|_| true,
            &|_| true,
        ));
    }
    assert!(
        matches!(&events[..], [GoalEvent::Acquired { .. }]),
        "{events:?}"
    );
    // beside its long side (outward normal at 135°), facing it; the place
    // is on the side towards the chair's start
    let normal = yaw + std::f64::consts::FRAC_PI_2;
    let beside = |gap_m: f64| Pose2 {
        x_m: 4.0 + (0.8 + gap_m) * normal.cos(),
        y_m: (0.8 + gap_m) * normal.sin(),
        theta_rad: normal - std::f64::consts::PI,
    };
    let a = g.approach().expect("an approach");
    assert!((a.x_m - beside(standoff).x_m).hypot(a.y_m - beside(standoff).y_m) > 1.0);
    assert_eq!(
        g.arrive_near(beside(standoff + 0.5), 0.3),
        None,
        "0.5 m short"
    );
    assert!(matches!(
        g.arrive_near(beside(standoff + 0.1), 0.3),
        Some(GoalEvent::ReachedNear { .. })
    ));
}

#[test]
fn a_search_ends_not_found_at_the_configured_limit() {
    // a chair that never gets its search turn done (held where it
    // stands): the search's time limit ends it, and only that
    let tracker = Tracker::new(crate::config::Settings::defaults().tracker);
    let mut g = GoalKeeper::new(GoalSettings {
        search_at_most: Duration::from_secs(30),
        ..crate::config::Settings::defaults().goal_settings()
    });
    g.set_prompt("piano");
    let mut not_found = Vec::new();
    for k in 0..=400 {
        let now_s = k as f64 * 0.1;
        let ev = g.update(
            t(now_s),
            &tracker,
            Pose2::default(),
            &[],
            &|_| true,
            &|_| true,
        );
        if let Some(GoalEvent::NotFound { label }) = ev {
            not_found.push((now_s, label));
        }
    }
    assert_eq!(not_found.len(), 1, "{not_found:?}");
    let (at_s, label) = &not_found[0];
    assert_eq!(label, "piano");
    assert!((30.0..30.2).contains(at_s), "ended at {at_s} s");
}
