//! The passage through a doorway, tested on made doorways and a unicycle
//! chair (split out of `doorway_tests.rs`, the finder's tests).

use super::tests::door_at_x2;
use super::*;

/// The chair as a unicycle following the passage's commands.
fn drive(passage: &mut Passage, mut pose: Pose2, goal: [f64; 2]) -> (Pose2, f64, bool) {
    let dt = 0.05;
    let mut worst_left: f64 = 0.0;
    for _ in 0..2000 {
        let cmd = match passage.step(pose, goal) {
            PassageCmd::Done => return (pose, worst_left, true),
            PassageCmd::Drive(c) => c,
            PassageCmd::Aim(p) => {
                // a simple go-to for the approach
                let b = wrap_angle((p[1] - pose.y_m).atan2(p[0] - pose.x_m) - pose.theta_rad);
                if b.abs() > 0.2 {
                    VelocityCmd {
                        v_mps: 0.0,
                        omega_radps: 0.4f64.copysign(b),
                    }
                } else {
                    VelocityCmd {
                        v_mps: 0.15,
                        omega_radps: b,
                    }
                }
            }
        };
        pose = pose.advanced(cmd.v_mps * dt, cmd.omega_radps * dt);
        let (along, left) = passage.door.local([pose.x_m, pose.y_m]);
        if along.abs() < 0.6 {
            worst_left = worst_left.max(left.abs());
        }
    }
    (pose, worst_left, false)
}

#[test]
fn a_chair_off_the_middle_line_lines_up_before_it_passes() {
    let door = door_at_x2(0.82);
    // close before the doorway, 13 cm off its middle line, square to
    // it: too near to correct on the way through (held at the jamb
    // before the line-up)
    for (x_m, y_m) in [(0.95, 0.87), (0.6, 1.3), (0.7, 0.8)] {
        let start = Pose2 {
            x_m,
            y_m,
            theta_rad: 0.0,
        };
        let mut p = Passage::new(door, PassageSettings::default());
        let (end, worst_left, done) = drive(&mut p, start, [4.0, 1.0]);
        assert!(done, "from {start:?}: did not get through: {end:?}");
        // 4 cm a side for a 0.70 m chair with the crawl's 3 cm margin
        assert!(worst_left < 0.02, "from {start:?}: {worst_left}");
    }
    // without the line-up the first start passes 5 cm off the line
    let mut p = Passage::new(
        door,
        PassageSettings {
            line_up_off_m: 1.0,
            ..PassageSettings::default()
        },
    );
    let start = Pose2 {
        x_m: 0.95,
        y_m: 0.87,
        theta_rad: 0.0,
    };
    let (_, worst_left, _) = drive(&mut p, start, [4.0, 1.0]);
    assert!(worst_left > 0.04, "{worst_left}");
}

#[test]
fn a_chair_too_near_to_line_up_backs_up_first() {
    // 0.89 m between the jambs: 6.5 cm a side for the chair and its margin
    let door = door_at_x2(0.89);
    // 0.95 m before the middle, 11 cm off its line, square to it: no room
    // to line up (a turn there would sweep a corner into the wall)
    let start = Pose2 {
        x_m: 1.05,
        y_m: 1.11,
        theta_rad: 0.0,
    };
    let mut p = Passage::new(door, PassageSettings::default());
    let mut pose = start;
    let mut backed_to = f64::INFINITY;
    for _ in 0..100 {
        match p.step(pose, [4.0, 1.0]) {
            PassageCmd::Drive(c) if c.v_mps < 0.0 => {
                assert!(c.omega_radps.abs() < 1e-9, "{c:?}");
                pose = pose.advanced(c.v_mps * 0.05, c.omega_radps * 0.05);
                backed_to = backed_to.min(pose.x_m);
            }
            _ => break,
        }
    }
    // straight back to where a line-up no steeper than 45 degrees fits
    assert_eq!(p.backed_up, 1);
    assert!(backed_to < 2.0 - 0.78 - 0.2 - 0.11 + 0.01, "{backed_to}");
    assert!(backed_to > 0.85, "{backed_to}");
    let mut p = Passage::new(door, PassageSettings::default());
    let (end, worst_left, done) = drive(&mut p, start, [4.0, 1.0]);
    assert!(done, "did not get through: {end:?}");
    assert!(worst_left < 0.03, "{worst_left}");
    // without backing up (none left, or the person said no) it steers
    // onto the line until its front is at the wall, and passes the jambs
    // within the 6.5 cm the gap leaves a side, though further off the
    // line than backing up gets it (squared from 0.85 m on, as before,
    // it passed them 10 cm off: the jamb held it)
    let mut p = Passage::new(
        door,
        PassageSettings {
            back_ups: 0,
            ..PassageSettings::default()
        },
    );
    let (end, worst_left, done) = drive(&mut p, start, [4.0, 1.0]);
    assert!(done, "did not get through: {end:?}");
    assert!(worst_left > 0.04 && worst_left < 0.065, "{worst_left}");
    // on the line, or off it by less than the gap leaves, no backing up
    for y_m in [1.0, 1.05] {
        let mut p = Passage::new(door, PassageSettings::default());
        let (_, _, done) = drive(&mut p, Pose2 { y_m, ..start }, [4.0, 1.0]);
        assert!(done);
        assert_eq!(p.backed_up, 0, "from {y_m}");
    }
    // pushed off the line in the passage, where it no longer steers onto
    // it: back up, at most twice
    let mut p = Passage::new(door, PassageSettings::default());
    p.phase = Phase::Pass;
    let near = Pose2 {
        x_m: 1.3,
        y_m: 0.88,
        theta_rad: 0.0,
    };
    assert!(matches!(
        p.step(near, [4.0, 1.0]),
        PassageCmd::Drive(c) if c.v_mps < 0.0
    ));
    assert!(matches!(p.phase, Phase::BackUp { .. }));
    p.backed_up = 2;
    p.phase = Phase::Pass;
    assert!(matches!(
        p.step(near, [4.0, 1.0]),
        PassageCmd::Drive(c) if c.v_mps > 0.0
    ));
    // the person says it is not clear behind: aligned where it is, and
    // no more backing up
    let mut p = Passage::new(door, PassageSettings::default());
    p.phase = Phase::Pass;
    assert!(matches!(p.step(near, [4.0, 1.0]), PassageCmd::Drive(c) if c.v_mps < 0.0));
    assert!(p.refuse_back_up());
    assert_eq!(p.phase, Phase::Align);
    assert!(matches!(p.step(near, [4.0, 1.0]), PassageCmd::Drive(c) if c.v_mps > 0.0));
    assert!(!p.refuse_back_up(), "not backing up");
    // at a slant to the doorway, it aligns before it backs up (backing
    // at a slant takes it further off the line)
    let mut p = Passage::new(door, PassageSettings::default());
    let slanted = Pose2 {
        theta_rad: 0.4,
        ..start
    };
    assert!(matches!(
        p.step(slanted, [4.0, 1.0]),
        PassageCmd::Drive(c) if c.v_mps == 0.0
    ));
    assert_eq!(p.phase, Phase::Align);
}

/// A passage begun with the chair already near the doorway, near the
/// middle line but turned well off the axis (it came there on the
/// planner's way, at a slant): it squares on the spot; where that turn is
/// held (a corner's circle reaches a jamb), it backs up straight, its
/// heading held, to where there is room to turn, then squares and goes
/// through. Square enough to steer out while passing, or nearer than
/// that room allows back, it turns on arcs instead, as before.
#[test]
fn a_turn_held_near_the_doorway_at_a_slant_backs_up_straight_first() {
    let door = door_at_x2(0.85);
    let s = PassageSettings::default();
    let near = Pose2 {
        x_m: 2.0 - 0.47,
        y_m: 1.0 + 0.13,
        theta_rad: -0.53,
    };
    let mut p = Passage::new(door, s);
    assert!(matches!(
        p.step(near, [4.0, 1.0]),
        PassageCmd::Drive(c) if c.v_mps == 0.0 && c.omega_radps > 0.0
    ));
    assert_eq!(p.phase, Phase::Align);
    // the turn held there
    assert!(p.held_turning(near));
    assert!(!p.turns_refused);
    assert!(
        matches!(p.phase, Phase::BackUp { to_m, squaring: false } if (to_m + s.line_up_nearest_m + 0.05).abs() < 1e-9),
        "{:?}",
        p.phase
    );
    // straight back to where a turn on the spot fits, then through
    let mut backed_to = f64::INFINITY;
    let mut pose = near;
    while let PassageCmd::Drive(c) = p.step(pose, [4.0, 1.0]) {
        if c.v_mps >= 0.0 {
            break;
        }
        assert_eq!(c.omega_radps, 0.0, "{c:?}");
        pose = pose.advanced(c.v_mps * 0.05, c.omega_radps * 0.05);
        backed_to = backed_to.min(door.local([pose.x_m, pose.y_m]).0);
    }
    assert!(backed_to <= -s.line_up_nearest_m, "{backed_to}");
    assert!(backed_to > -0.47 - s.back_up_m - 0.01, "{backed_to}");
    assert_eq!(p.backed_up, 1);
    let (end, _, done) = drive(&mut p, pose, [4.0, 1.0]);
    assert!(done, "did not get through: {end:?}");
    // square enough to steer out while passing, or held again from where
    // it backed to with no back-up left: on arcs
    for (at, backed_up) in [
        (
            Pose2 {
                theta_rad: -0.2,
                ..near
            },
            0,
        ),
        (pose, s.back_ups),
    ] {
        let mut p = Passage::new(door, s);
        p.phase = Phase::Align;
        p.backed_up = backed_up;
        assert!(p.held_turning(at));
        assert!(p.turns_refused, "from {at:?}");
        assert_eq!(p.phase, Phase::Align);
    }
}

#[test]
fn the_chair_goes_through_on_the_middle_line_from_a_slant() {
    let door = door_at_x2(0.85);
    let start = Pose2 {
        x_m: 0.3,
        y_m: -0.5,
        theta_rad: 1.0,
    };
    let mut p = Passage::new(door, PassageSettings::default());
    let (end, worst_left, done) = drive(&mut p, start, [4.0, 1.0]);
    assert!(done, "did not get through: {end:?}");
    assert!(end.x_m > 2.7, "{end:?}");
    // within 5 cm of the middle line in it (a 0.85 m doorway leaves a
    // 0.70 m chair 7.5 cm a side)
    assert!(worst_left < 0.05, "{worst_left}");
    // a goal beyond the doorway: handed back level with it, once the
    // chair's rear is out of the doorway
    let mut p = Passage::new(door, PassageSettings::default());
    let (end, _, done) = drive(&mut p, start, [2.75, 1.0]);
    assert!(done && (end.x_m - 2.65).abs() < 0.05, "{end:?}");
    let mut p = Passage::new(door, PassageSettings::default());
    let (end, _, done) = drive(&mut p, start, [2.3, 1.0]);
    assert!(done && (end.x_m - 2.6).abs() < 0.05, "{end:?}");
}

/// Held on its way to the point before the doorway, level with that point
/// or nearer and off the line by at most a metre, the chair lines up from
/// where it is, on a steeper line than an approach allows; once a
/// passage, and not from further back or further off.
#[test]
fn held_on_the_way_to_the_point_before_it_the_chair_lines_up_from_there() {
    let door = door_at_x2(0.85);
    let at = |along: f64, left: f64| Pose2 {
        x_m: 2.0 + along,
        y_m: 1.0 + left,
        theta_rad: -2.0,
    };
    let mut p = Passage::new(door, PassageSettings::default());
    assert!(p.held_on_approach(at(-1.06, 0.5)));
    assert!(
        matches!(p.phase, Phase::LineUp { at_m } if (at_m + 0.86).abs() < 1e-9),
        "{:?}",
        p.phase
    );
    // it drives there: a turn on the spot towards the point first
    let cmd = p.step(at(-1.06, 0.5), [4.0, 1.0]);
    assert!(
        matches!(cmd, PassageCmd::Drive(c) if c.v_mps == 0.0 && c.omega_radps != 0.0),
        "{cmd:?}"
    );
    // once a passage
    p.phase = Phase::Approach;
    assert!(!p.held_on_approach(at(-1.06, 0.5)));
    // not from further back, further off, or too near to turn on the line
    for (along, left) in [(-1.6, 0.3), (-1.0, 1.2), (-0.5, 0.3)] {
        let mut p = Passage::new(door, PassageSettings::default());
        assert!(!p.held_on_approach(at(along, left)), "{along} {left}");
        assert_eq!(p.phase, Phase::Approach);
    }
}

/// The person said no to a turn on the spot: the passage lines up and
/// squares on a crawl's arcs, never a turn on the spot, and still gets
/// through near the middle line.
#[test]
fn with_turns_refused_the_chair_lines_up_on_arcs_and_gets_through() {
    let door = door_at_x2(0.90);
    // before the doorway, off its middle line, facing 30 degrees off it
    let start = Pose2 {
        x_m: 0.4,
        y_m: 1.3,
        theta_rad: -0.5,
    };
    let turns_on_the_spot = |p: &mut Passage| {
        let mut pose = start;
        let mut turns = 0;
        for _ in 0..2000 {
            let cmd = match p.step(pose, [4.0, 1.0]) {
                PassageCmd::Done => break,
                PassageCmd::Drive(c) => c,
                PassageCmd::Aim(_) => panic!("{:?} at {pose:?}: lined up from here", p.phase),
            };
            if cmd.v_mps.abs() < 0.05 && cmd.omega_radps.abs() > 0.0 {
                turns += 1;
            }
            pose = pose.advanced(cmd.v_mps * 0.05, cmd.omega_radps * 0.05);
        }
        (turns, pose)
    };
    // the same start: it turns on the spot to line up
    let mut p = Passage::new(door, PassageSettings::default());
    p.phase = Phase::LineUp { at_m: -1.1 };
    let (turns, _) = turns_on_the_spot(&mut p);
    assert!(turns > 0);
    // refused: on arcs only, and through
    let mut p = Passage::new(door, PassageSettings::default());
    p.phase = Phase::LineUp { at_m: -1.1 };
    p.refuse_turns();
    let (turns, end) = turns_on_the_spot(&mut p);
    assert_eq!(turns, 0);
    let (along, left) = door.local([end.x_m, end.y_m]);
    assert!(along > 0.6, "{end:?}");
    assert!(left.abs() < 0.05, "{end:?}");
}

/// A turn on the spot held (lining up, or squaring): the passage goes on
/// on arcs; held while it already drives on arcs, or while it drives
/// straight onto the line, nothing changes.
#[test]
fn a_held_turn_on_the_spot_goes_on_on_arcs() {
    let door = door_at_x2(0.90);
    // lining up, the point 60 degrees off the heading: a turn on the spot
    let facing = |theta_rad: f64| Pose2 {
        x_m: 0.7,
        y_m: 1.3,
        theta_rad,
    };
    let s = PassageSettings::default();
    let mut p = Passage::new(door, s);
    // (no back-up left: see the next test)
    p.backed_up = s.back_ups;
    p.phase = Phase::LineUp { at_m: -1.1 };
    let turn = |p: &mut Passage, pose: Pose2| match p.step(pose, [4.0, 1.0]) {
        PassageCmd::Drive(c) => c,
        other => panic!("{other:?}"),
    };
    assert_eq!(turn(&mut p, facing(-2.0)).v_mps, 0.0);
    assert!(p.held_turning(facing(-2.0)));
    assert!(p.turns_refused);
    let arc = turn(&mut p, facing(-2.0));
    assert!(arc.v_mps > 0.05 && arc.omega_radps > 0.0, "{arc:?}");
    // held again: already on arcs
    assert!(!p.held_turning(facing(-2.0)));
    // facing the point, it drives straight at it: held there, it is no
    // turn that is held
    let mut p = Passage::new(door, PassageSettings::default());
    p.phase = Phase::LineUp { at_m: -1.1 };
    let towards = (-0.3f64).atan2(0.2);
    assert!(turn(&mut p, facing(towards)).v_mps > 0.05);
    assert!(!p.held_turning(facing(towards)));
    assert!(!p.turns_refused);
    // squaring to the axis at the line-up point: a turn on the spot, held
    let mut p = Passage::new(door, PassageSettings::default());
    p.backed_up = s.back_ups;
    p.phase = Phase::Align;
    let at = Pose2 {
        x_m: 0.9,
        y_m: 1.0,
        theta_rad: 0.5,
    };
    assert_eq!(turn(&mut p, at).v_mps, 0.0);
    assert!(p.held_turning(at));
    let arc = turn(&mut p, at);
    assert!(arc.v_mps > 0.05, "{arc:?}");
    // passing: nothing turns on the spot
    let mut p = Passage::new(door, PassageSettings::default());
    p.phase = Phase::Pass;
    assert!(!p.held_turning(at));
}

/// A turn on the spot to line up held further from the doorway
/// (something low in the corners' circle, a piece of furniture beside the
/// way): the chair backs out straight, its heading held, away from it,
/// and tries the same turn from there; held again with no back-up left,
/// or the person saying it is not clear behind, on arcs. Backing that
/// would take the chair towards the doorway stops where a turn still
/// fits before it, and none is tried where that leaves too little.
/// Squaring is not backed out of.
#[test]
fn a_turn_held_away_from_the_doorway_backs_out_and_turns_again() {
    let door = door_at_x2(0.90);
    let s = PassageSettings::default();
    // lining up from beside the line, turned away from it (the point
    // 150 degrees to the right)
    let beside = Pose2 {
        x_m: 1.0,
        y_m: 1.5,
        theta_rad: 1.4,
    };
    let mut p = Passage::new(door, s);
    p.phase = Phase::LineUp { at_m: -0.8 };
    assert!(matches!(
        p.step(beside, [4.0, 1.0]),
        PassageCmd::Drive(c) if c.v_mps == 0.0 && c.omega_radps < 0.0
    ));
    assert!(p.held_turning(beside));
    assert!(!p.turns_refused);
    assert_eq!(p.backed_up, 1);
    let mut pose = beside;
    let mut backed_m = 0.0;
    loop {
        match p.step(pose, [4.0, 1.0]) {
            PassageCmd::Drive(c) if c.v_mps < 0.0 => {
                assert_eq!(c.omega_radps, 0.0, "{c:?}");
                pose = pose.advanced(c.v_mps * 0.05, 0.0);
                backed_m -= c.v_mps * 0.05;
            }
            PassageCmd::Drive(c) => {
                // the same turn on the spot, from further back
                assert!(c.v_mps == 0.0 && c.omega_radps < 0.0, "{c:?}");
                break;
            }
            other => panic!("{other:?}"),
        }
        assert!(backed_m < 1.0, "never stopped backing");
    }
    assert!((backed_m - s.back_up_m).abs() < 0.01, "{backed_m}");
    assert_eq!(p.phase, Phase::LineUp { at_m: -0.8 });
    // and from there it gets through
    let (end, _, done) = drive(&mut p, pose, [4.0, 1.0]);
    assert!(done, "did not get through: {end:?}");
    // held again there, and again: the last back-up, then arcs
    let mut p = Passage::new(door, s);
    p.phase = Phase::LineUp { at_m: -0.8 };
    p.backed_up = s.back_ups - 1;
    assert!(p.held_turning(beside));
    assert!(matches!(p.phase, Phase::BackOut { .. }));
    p.phase = Phase::LineUp { at_m: -0.8 };
    assert!(p.held_turning(beside));
    assert!(p.turns_refused);
    // the person said no to backing: the same turn, on arcs
    let mut p = Passage::new(door, s);
    p.phase = Phase::LineUp { at_m: -0.8 };
    assert!(p.held_turning(beside));
    assert!(p.refuse_back_up());
    assert_eq!(p.phase, Phase::LineUp { at_m: -0.8 });
    assert!(p.held_turning(beside));
    assert!(p.turns_refused);
    // turned away from the doorway 0.95 m before it: backing nears it,
    // so only as far as stops short of the line-up's point (0.05 m before
    // it, 0.85 m before the middle; past it, lining up would square to
    // the axis wherever the chair is off the line)
    let away = Pose2 {
        x_m: 2.0 - 0.95,
        y_m: 1.3,
        theta_rad: 2.6,
    };
    let mut p = Passage::new(door, s);
    p.phase = Phase::LineUp { at_m: -0.8 };
    assert!(p.held_turning(away));
    let Phase::BackOut { back_m, at_m, .. } = p.phase else {
        panic!("{:?}", p.phase);
    };
    assert_eq!(at_m, -0.8);
    let after = away.advanced(-back_m, 0.0);
    let along_after = door.local([after.x_m, after.y_m]).0;
    assert!((along_after + 0.85).abs() < 1e-6, "{along_after}");
    // 0.83 m before it: too little room to back towards it; on arcs
    let mut p = Passage::new(door, s);
    p.phase = Phase::LineUp { at_m: -0.63 };
    let nearer = Pose2 {
        x_m: 2.0 - 0.83,
        ..away
    };
    assert!(p.held_turning(nearer));
    assert!(p.turns_refused);
    assert_eq!(p.phase, Phase::LineUp { at_m: -0.63 });
    // squaring, a turn held away from the doorway: no backing across the
    // axis (it would take the chair off the line it is on); on arcs
    let mut p = Passage::new(door, s);
    p.phase = Phase::Align;
    assert!(p.held_turning(Pose2 {
        x_m: 1.0,
        y_m: 1.0,
        theta_rad: 1.2,
    }));
    assert!(p.turns_refused);
    assert_eq!(p.backed_up, 0);
}

/// In the narrowest doorways what the gap leaves a side is 2–3 cm: held
/// passing with its front at the wall 2 cm off the middle line and 1°
/// turned (scenes 28 and 60 of `opennav sim --seed 1`, 0.81 m), the
/// chair backs up to line up again; in a 0.85 m doorway, the same pose
/// leaves room, and it does not (something else holds it).
#[test]
fn held_passing_near_the_line_of_a_narrow_doorway_backs_up() {
    let held_at = Pose2 {
        x_m: 2.0 - 0.66,
        y_m: 1.0 + 0.02,
        theta_rad: 0.017,
    };
    let passing = |width_m: f64| {
        let mut p = Passage::new(door_at_x2(width_m), PassageSettings::default());
        p.phase = Phase::Pass;
        p
    };
    let mut narrow = passing(0.81);
    assert!(narrow.held_passing(held_at));
    assert!(
        matches!(narrow.phase, Phase::BackUp { squaring: true, .. }),
        "{:?}",
        narrow.phase
    );
    let mut wider = passing(0.85);
    assert!(!wider.held_passing(held_at));
    assert_eq!(wider.phase, Phase::Pass);
}

/// Passing on arcs (turns held), the chair came onto the middle line at
/// 0.3 rad and its front corner met a jamb 0.58 m before the middle: it
/// backs up, squaring as it backs, to where it can line up again (turns
/// on the spot allowed again, unless the person refused them), and gets
/// through. Not in the doorway already, not square and on the line
/// (something else holds it), nor with no back-up left.
#[test]
fn held_passing_at_a_slant_with_the_front_at_the_wall_backs_up_and_lines_up_again() {
    let door = door_at_x2(0.85);
    let s = PassageSettings::default();
    let held_at = Pose2 {
        x_m: 2.0 - 0.58,
        y_m: 1.0 + 0.10,
        theta_rad: -0.3,
    };
    let passing = |backed_up: u32| {
        let mut p = Passage::new(door, s);
        p.phase = Phase::Pass;
        p.turns_refused = true;
        p.backed_up = backed_up;
        p
    };
    // turns refused by a held turn nearer the doorway; the person's no
    // to a turn holds wherever the chair backs to
    let mut said_no = passing(0);
    said_no.refuse_turns();
    assert!(said_no.held_passing(held_at));
    assert!(said_no.turns_refused);
    let mut p = passing(0);
    assert!(p.held_passing(held_at));
    assert!(
        !p.turns_refused,
        "a turn on the spot may fit where it backs to"
    );
    assert_eq!(p.backed_up, 1);
    // room to line up (1.08 m before the middle), or back_up_m at most
    let to = (-s.line_up_nearest_m - s.line_up_ahead_m - 0.10).max(-0.58 - s.back_up_m);
    assert!(
        matches!(p.phase, Phase::BackUp { to_m, squaring: true } if (to_m - to).abs() < 1e-9),
        "{:?}",
        p.phase
    );
    // back, squaring, to where it lines up again
    let mut pose = held_at;
    while let PassageCmd::Drive(c) = p.step(pose, [4.0, 1.0]) {
        if c.v_mps >= 0.0 {
            break;
        }
        pose = pose.advanced(c.v_mps * 0.05, c.omega_radps * 0.05);
    }
    let (along, left) = door.local([pose.x_m, pose.y_m]);
    assert!(along <= to + 0.01 && along > to - 0.05, "{along}");
    assert!(left.abs() < 0.15, "{left}");
    assert!(pose.theta_rad.abs() < 0.1, "squared as it backed: {pose:?}");
    assert!(matches!(p.phase, Phase::LineUp { .. }), "{:?}", p.phase);
    let (end, worst_left, done) = drive(&mut p, pose, [4.0, 1.0]);
    assert!(done, "did not get through: {end:?}");
    assert!(worst_left < 0.05, "{worst_left}");
    // in the doorway already, square and on the line, no back-up left,
    // or not passing: held there, it does not back up
    let in_it = Pose2 {
        x_m: 2.0 - 0.2,
        ..held_at
    };
    let square = Pose2 {
        y_m: 1.01,
        theta_rad: 0.02,
        ..held_at
    };
    for (mut p, at) in [
        (passing(0), in_it),
        (passing(0), square),
        (passing(s.back_ups), held_at),
    ] {
        assert!(!p.held_passing(at), "{at:?}");
        assert_eq!(p.phase, Phase::Pass);
    }
    let mut p = Passage::new(door, s);
    p.phase = Phase::Align;
    assert!(!p.held_passing(held_at));
    assert_eq!(p.phase, Phase::Align);
}
