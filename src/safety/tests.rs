//! Tests of the supervisor: swept circles, deadlines, corridors, floor never
//! seen (the rest in `faults_tests.rs`; split out to keep it readable).

use super::*;

pub(super) fn ms(v: u64) -> Stamp {
    Stamp(Duration::from_millis(v))
}

pub(super) struct World {
    pub(super) obstacles: Stamped<Obstacles>,
    /// The chair's measured motion: at rest unless a test says.
    pub(super) odom: Stamped<Odometry>,
    pub(super) cmd: Stamped<VelocityCmd>,
    /// The depth camera's obstacles: none, fresh.
    pub(super) camera: Stamped<Obstacles>,
    /// The rear: seen (as after driving here), nothing remembered.
    pub(super) rear: rear::RearView,
}

impl World {
    pub(super) fn new(t: u64, v: f64, w: f64) -> Self {
        World {
            obstacles: Stamped::new(
                ms(t),
                Obstacles {
                    points_base: vec![[3.0, 0.0]],
                    ..Default::default()
                },
            ),
            odom: Stamped::new(ms(t), Odometry::default()),
            camera: Stamped::new(ms(t), Obstacles::default()),
            rear: rear::RearView {
                seen: true,
                reverse_seen: true,
                around_vouched: false,
                points_base: Vec::new(),
            },
            cmd: Stamped::new(
                ms(t),
                VelocityCmd {
                    v_mps: v,
                    omega_radps: w,
                },
            ),
        }
    }
    pub(super) fn inputs(&self) -> SupervisorInputs<'_> {
        SupervisorInputs {
            obstacles: Some(&self.obstacles),
            odometry: Some(&self.odom),
            command: Some(&self.cmd),
            camera: Some(&self.camera),
            rear: Some(&self.rear),
        }
    }
}

/// A supervisor already moving at `v` (acceleration limits satisfied).
pub(super) fn moving(v: f64) -> Supervisor {
    let mut s = Supervisor::new(SafetyLimits {
        a_linear_max_mps2: 100.0,
        a_angular_max_radps2: 100.0,
        ..crate::config::Settings::defaults().safety_limits()
    });
    s.goal_active();
    let w = World::new(0, v, 0.0);
    s.step(ms(0), &w.inputs());
    let c = s.step(ms(10), &w.inputs());
    assert_eq!(c.state, SupervisorState::Navigating);
    assert!((c.cmd.v_mps - v).abs() < 1e-12);
    s
}

#[test]
fn turning_on_the_spot_stops_when_something_is_inside_the_swept_circle() {
    let mut s = moving(0.0);
    // beside the chair, 0.7 m from its centre: inside the corners'
    // circle (hypot(0.55, 0.35) + 0.10 = 0.75 m), outside the corridor
    let mut w = World::new(20, 0.0, 0.5);
    w.obstacles.value.points_base = vec![[0.0, 0.7]];
    let c = s.step(ms(20), &w.inputs());
    assert_eq!(c.state, SupervisorState::Stopped(StopReason::Obstacle));
    assert_eq!(c.cmd, VelocityCmd::default());
    // 0.8 m away: free to turn
    let mut s = moving(0.0);
    let mut w = World::new(20, 0.0, 0.5);
    w.obstacles.value.points_base = vec![[0.0, 0.8]];
    let c = s.step(ms(20), &w.inputs());
    assert_eq!(c.state, SupervisorState::Navigating);
    assert!(c.cmd.omega_radps > 0.0);
    // turning so slowly that the corners crawl (0.1 m/s / 0.652 m =
    // 0.153 rad/s): the crawl's margin, 0.652 + 0.03 m — 0.7 m is clear,
    // 0.67 m is not
    let mut s = moving(0.0);
    let crawl = s.crawl_turn_radps();
    assert!((crawl - 0.1 / 0.55f64.hypot(0.35)).abs() < 1e-3, "{crawl}");
    let mut w = World::new(20, 0.0, crawl);
    w.obstacles.value.points_base = vec![[0.0, 0.7]];
    let c = s.step(ms(20), &w.inputs());
    assert_eq!(c.state, SupervisorState::Navigating);
    let mut s = moving(0.0);
    let mut w = World::new(20, 0.0, crawl);
    w.obstacles.value.points_base = vec![[0.0, 0.67]];
    let c = s.step(ms(20), &w.inputs());
    assert_eq!(c.state, SupervisorState::Stopped(StopReason::Obstacle));
    // driving forward past it is the corridor's business, not this check
    let mut s = moving(0.2);
    let mut w = World::new(20, 0.2, 0.5);
    w.obstacles.value.points_base = vec![[0.0, 0.7]];
    assert_eq!(
        s.step(ms(20), &w.inputs()).state,
        SupervisorState::Navigating
    );
}

#[test]
fn stale_laser_stops_one_step_after_its_deadline() {
    let mut s = moving(0.2);
    let mut w = World::new(0, 0.2, 0.0);
    // everything but the laser stays fresh
    w.odom.stamp = ms(250);
    w.cmd.stamp = ms(250);
    let c = s.step(ms(250), &w.inputs());
    assert_eq!(c.state, SupervisorState::Navigating);
    let c = s.step(
        Stamp(Duration::from_millis(250) + Duration::from_nanos(1)),
        &w.inputs(),
    );
    assert_eq!(c.state, SupervisorState::Stopped(StopReason::LaserStale));
    assert_eq!(c.cmd, VelocityCmd::default());
}

#[test]
fn a_chair_still_rolling_forward_keeps_its_front_checked_when_asked_to_stop_or_reverse() {
    for asked in [0.0, -0.1] {
        let mut s = moving(0.3);
        // something 0.2 m ahead of the front edge (inside the 0.30 m
        // corridor); the rear is clear; the planner asks for `asked`
        // while the chair still rolls forward at 0.25 m/s
        let mut w = World::new(20, asked, 0.0);
        w.obstacles.value.points_base = vec![[0.55 + 0.2, 0.0]];
        w.odom.value.v_mps = 0.25;
        let c = s.step(ms(20), &w.inputs());
        assert_eq!(
            c.state,
            SupervisorState::Stopped(StopReason::Obstacle),
            "asked {asked}"
        );
        assert_eq!(c.cmd, VelocityCmd::default(), "asked {asked}");
        // at rest, a reverse request is allowed again (the rear is clear)
        let mut w = World::new(200, -0.1, 0.0);
        w.obstacles.value.points_base = vec![[0.55 + 0.2, 0.0]];
        w.odom.value.v_mps = 0.0;
        let c = s.step(ms(200), &w.inputs());
        assert_eq!(c.state, SupervisorState::Navigating);
        assert!(c.cmd.v_mps < 0.0, "{c:?}");
    }
}

#[test]
fn a_turn_that_is_happening_is_checked_like_one_asked_for() {
    let mut s = moving(0.0);
    // asked to stand still, but the chair spins: something within the
    // swept circle beside it
    let mut w = World::new(20, 0.0, 0.0);
    w.obstacles.value.points_base = vec![[0.0, 0.6]];
    w.odom.value.omega_radps = 0.5;
    let c = s.step(ms(20), &w.inputs());
    assert_eq!(c.state, SupervisorState::Stopped(StopReason::Obstacle));
}

#[test]
fn sustained_overspeed_is_a_latched_fault_a_blip_is_not() {
    let mut s = moving(0.3);
    // 0.40 m/s measured (cap 0.30 + 0.05 margin) for 0.2 s: no fault
    for t in (20..=220).step_by(50) {
        let mut w = World::new(t, 0.3, 0.0);
        w.odom.value.v_mps = 0.40;
        assert_eq!(
            s.step(ms(t), &w.inputs()).state,
            SupervisorState::Navigating
        );
    }
    let w = World::new(270, 0.3, 0.0);
    assert_eq!(
        s.step(ms(270), &w.inputs()).state,
        SupervisorState::Navigating
    );
    // for longer than the 0.3 s window: latched
    let mut last = None;
    for t in (320..=720).step_by(50) {
        let mut w = World::new(t, 0.3, 0.0);
        w.odom.value.v_mps = 0.40;
        last = Some(s.step(ms(t), &w.inputs()));
    }
    let c = last.expect("stepped");
    assert_eq!(c.state, SupervisorState::Fault(FaultReason::Overspeed));
    assert_eq!(c.cmd, VelocityCmd::default());
    let w = World::new(800, 0.3, 0.0);
    let c = s.step(ms(800), &w.inputs());
    assert_eq!(
        c.state,
        SupervisorState::Fault(FaultReason::Overspeed),
        "latched"
    );
    // spinning too fast counts too
    let mut s = moving(0.0);
    for t in (20..=520).step_by(50) {
        let mut w = World::new(t, 0.0, 0.5);
        w.odom.value.omega_radps = 1.2;
        s.step(ms(t), &w.inputs());
    }
    assert_eq!(s.state(), SupervisorState::Fault(FaultReason::Overspeed));
}

#[test]
fn stale_odometry_and_command_stop() {
    let mut s = moving(0.2);
    let mut w = World::new(100, 0.2, 0.0);
    w.odom.stamp = ms(0);
    assert_eq!(
        s.step(ms(100), &w.inputs()).state,
        SupervisorState::Navigating
    );
    let c = s.step(ms(101), &w.inputs());
    assert_eq!(c.state, SupervisorState::Stopped(StopReason::OdometryStale));
    assert_eq!(c.cmd, VelocityCmd::default());

    let mut s = moving(0.2);
    let mut w = World::new(200, 0.2, 0.0);
    w.cmd.stamp = ms(0);
    assert_eq!(
        s.step(ms(200), &w.inputs()).state,
        SupervisorState::Navigating
    );
    let c = s.step(ms(201), &w.inputs());
    assert_eq!(c.state, SupervisorState::Stopped(StopReason::CommandStale));
    assert_eq!(c.cmd, VelocityCmd::default());
    // missing inputs are stale too
    let c = s.step(ms(202), &SupervisorInputs::default());
    assert_eq!(c.state, SupervisorState::Stopped(StopReason::LaserStale));
}

#[test]
fn obstacle_in_the_corridor_stops_in_the_direction_of_travel() {
    let mut s = moving(0.2);
    let mut w = World::new(20, 0.2, 0.0);
    // 0.55 front + 0.30 stop = 0.85 m; half width 0.45 m
    w.obstacles.value.points_base = vec![[0.84, 0.44]];
    let c = s.step(ms(20), &w.inputs());
    assert_eq!(c.state, SupervisorState::Stopped(StopReason::Obstacle));
    assert_eq!(c.cmd, VelocityCmd::default());
    // just outside, or behind while going forward: clear
    for p in [[0.86, 0.0], [0.5, 0.46], [-0.6, 0.0]] {
        let mut s = moving(0.2);
        w.obstacles.value.points_base = vec![p];
        assert_eq!(
            s.step(ms(20), &w.inputs()).state,
            SupervisorState::Navigating,
            "{p:?}"
        );
    }
    // reversing towards something behind
    let mut s = moving(-0.1);
    let mut w = World::new(20, -0.1, 0.0);
    w.obstacles.value.points_base = vec![[-0.6, 0.1]];
    assert_eq!(
        s.step(ms(20), &w.inputs()).state,
        SupervisorState::Stopped(StopReason::Obstacle)
    );
}

#[test]
fn at_a_crawl_the_corridor_reaches_the_crawls_stop_distance_only() {
    // 0.20 m ahead of the front, in the middle: inside the full stop
    // distance (0.30 m), beyond the crawl's (0.15 m)
    let beyond = [0.55 + 0.20, 0.0];
    let step = |v_cmd: f64, v_measured: f64, p: [f32; 2]| {
        let mut s = moving(v_cmd);
        let mut w = World::new(20, v_cmd, 0.0);
        w.odom.value.v_mps = v_measured;
        w.obstacles.value.points_base = vec![p];
        s.step(ms(20), &w.inputs()).state
    };
    // creeping on (0.09 m/s, a third of the cap or less): goes on
    assert_eq!(step(0.09, 0.09, beyond), SupervisorState::Navigating);
    // faster: held
    let held = SupervisorState::Stopped(StopReason::Obstacle);
    assert_eq!(step(0.2, 0.2, beyond), held);
    // asked to creep while still rolling at 0.2 m/s: the motion keeps
    // the full corridor
    assert_eq!(step(0.09, 0.2, beyond), held);
    // within the crawl's distance: held at a crawl too
    assert_eq!(step(0.09, 0.09, [0.55 + 0.14, 0.0]), held);
}

#[test]
fn the_depth_cameras_obstacles_and_drop_offs_stop_like_the_lasers() {
    // a box under the lasers' plane, seen only by the camera
    let mut s = moving(0.2);
    let mut w = World::new(20, 0.2, 0.0);
    w.camera.value.points_base = vec![[0.8, 0.0]];
    let c = s.step(ms(20), &w.inputs());
    assert_eq!(c.state, SupervisorState::Stopped(StopReason::Obstacle));
    assert_eq!(c.cmd, VelocityCmd::default());
    // a step down ahead
    let mut s = moving(0.2);
    w.camera.value = Obstacles {
        drop_offs_base: vec![[0.8, 0.3]],
        ..Default::default()
    };
    let c = s.step(ms(20), &w.inputs());
    assert_eq!(c.state, SupervisorState::Stopped(StopReason::DropOff));
    assert_eq!(c.cmd, VelocityCmd::default());
    // and a turn on the spot next to it
    let mut s = moving(0.0);
    let mut w = World::new(20, 0.0, 0.5);
    w.camera.value.drop_offs_base = vec![[0.0, 0.7]];
    assert_eq!(
        s.step(ms(20), &w.inputs()).state,
        SupervisorState::Stopped(StopReason::DropOff)
    );
}

#[test]
fn floor_never_seen_holds_a_turn_until_the_person_vouches_for_all_around() {
    // a step down may lie just before the front (the camera sees the
    // floor only from 1.1 m ahead): 0.6 m ahead, inside the corners'
    // circle, outside the crawl's stop corridor at rest
    let unseen =
        |w: &mut World| w.camera.value.drop_offs_unseen_base = vec![[0.6, 0.0], [0.6, 0.2]];
    // a turn on the spot: held for the unseen floor (the chair asks)
    let mut s = moving(0.0);
    let mut w = World::new(20, 0.0, 0.5);
    unseen(&mut w);
    let c = s.step(ms(20), &w.inputs());
    assert_eq!(c.state, SupervisorState::Stopped(StopReason::FloorUnseen));
    assert_eq!(c.cmd, VelocityCmd::default());
    // a word for behind only does not cover it
    w.rear.seen = true;
    assert_eq!(
        s.step(ms(30), &w.inputs()).state,
        SupervisorState::Stopped(StopReason::FloorUnseen)
    );
    // "clear around me": the turn goes
    let mut s = moving(0.0);
    w.rear.around_vouched = true;
    let c = s.step(ms(20), &w.inputs());
    assert_eq!(c.state, SupervisorState::Navigating);
    assert!(c.cmd.omega_radps > 0.0);
    // driving onto it is a drop-off, vouched or not
    for vouched in [false, true] {
        let mut s = moving(0.2);
        let mut w = World::new(20, 0.2, 0.0);
        unseen(&mut w);
        w.rear.around_vouched = vouched;
        assert_eq!(
            s.step(ms(20), &w.inputs()).state,
            SupervisorState::Stopped(StopReason::DropOff),
            "vouched {vouched}"
        );
    }
    // and a turn while still rolling forward is not on the spot
    let mut s = moving(0.2);
    let mut w = World::new(20, 0.0, 0.5);
    unseen(&mut w);
    w.rear.around_vouched = true;
    w.odom.value.v_mps = 0.2;
    assert_eq!(
        s.step(ms(20), &w.inputs()).state,
        SupervisorState::Stopped(StopReason::DropOff)
    );
    // a drop-off the camera saw holds the turn whatever the person says
    let mut s = moving(0.0);
    let mut w = World::new(20, 0.0, 0.5);
    w.camera.value.drop_offs_base = vec![[0.6, 0.0]];
    w.rear.around_vouched = true;
    assert_eq!(
        s.step(ms(20), &w.inputs()).state,
        SupervisorState::Stopped(StopReason::DropOff)
    );
}

/// Floor the camera never saw (no step down suspected there, just not
/// seen: a box under the lasers' plane could stand on it) holds a turn on
/// the spot whose corners would swing over it, until the person says it is
/// clear around the chair; it holds neither driving nor a turn that swings
/// away from it, nor anything with the check off.
#[test]
fn a_turn_that_would_sweep_floor_never_seen_waits_for_the_persons_word() {
    // just ahead of the front-right corner (0.55, −0.35): turning left
    // swings that corner onto it
    const AHEAD_RIGHT: [[f32; 2]; 1] = [[0.60, -0.30]];
    // the state after a step asking (v, w), with floor never seen at
    // `unseen`, the person's word for all around, and the check on or off
    let state = |v: f64, w: f64, unseen: &[[f32; 2]], vouched: bool, check: bool| {
        let mut s = moving(v);
        s.limits.turn_needs_seen_floor = check;
        let mut world = World::new(20, v, w);
        world.camera.value.floor_unseen_base = unseen.to_vec();
        world.rear.around_vouched = vouched;
        let c = s.step(ms(20), &world.inputs());
        if c.state != SupervisorState::Navigating {
            assert_eq!(c.cmd, VelocityCmd::default());
        }
        c.state
    };
    let held = SupervisorState::Stopped(StopReason::FloorUnseen);
    let goes = SupervisorState::Navigating;
    // turning left: held (the chair asks)
    assert_eq!(state(0.0, 0.5, &AHEAD_RIGHT, false, true), held);
    // turning right, that corner swings back from it: the turn goes
    assert_eq!(state(0.0, -0.5, &AHEAD_RIGHT, false, true), goes);
    // "clear around me": the left turn goes
    assert_eq!(state(0.0, 0.5, &AHEAD_RIGHT, true, true), goes);
    // driving on: not an obstacle (the camera sees what stands ahead
    // before the chair gets there)
    assert_eq!(state(0.2, 0.0, &AHEAD_RIGHT, false, true), goes);
    // beyond what the corners reach: the turn goes
    assert_eq!(
        state(0.0, 0.5, &[[0.0, 0.75], [0.75, 0.0]], false, true),
        goes
    );
    // with the check off (a chair with sensors that see beside it)
    assert_eq!(state(0.0, 0.5, &AHEAD_RIGHT, false, false), goes);
}

/// Floor the camera never saw beside the chair, near a thing it saw part
/// of, holds a bend whose rear corner would swing over it (a bed's corner under the lasers' plane,
/// beside a chair that started there, is seen by neither sensor: seed 2
/// scene 57 of `opennav sim` touched it so), until the person's word
/// takes that floor off the list; it holds neither the bend the other way
/// (the rear swings away), nor driving straight on, nor floor ahead of the
/// front edge (the travel's own way), nor anything with the check off.
#[test]
fn a_bend_that_would_swing_the_rear_over_floor_never_seen_waits() {
    // 1 cm out beside the rear-left corner (−0.45, 0.35)
    const BESIDE_REAR_LEFT: [[f32; 2]; 1] = [[-0.40, 0.36]];
    // what the camera saw of the bed, 0.25 m from that floor, 0.23 m from
    // the footprint
    const BED: [f32; 2] = [-0.55, 0.56];
    let state_near = |v: f64, w: f64, unseen: &[[f32; 2]], things: &[[f32; 2]], check: bool| {
        let mut s = moving(v);
        s.limits.turn_needs_seen_floor = check;
        let mut world = World::new(20, v, w);
        world.odom.value.v_mps = v;
        world.camera.value.points_base = things.to_vec();
        world.camera.value.floor_unseen_base = unseen.to_vec();
        let c = s.step(ms(20), &world.inputs());
        if c.state != SupervisorState::Navigating {
            assert_eq!(c.cmd, VelocityCmd::default());
        }
        c.state
    };
    let state =
        |v: f64, w: f64, unseen: &[[f32; 2]], check: bool| state_near(v, w, unseen, &[BED], check);
    let held = SupervisorState::Stopped(StopReason::Obstacle);
    let goes = SupervisorState::Navigating;
    // the bed alone holds nothing: the bends go
    assert_eq!(state_near(0.09, -0.25, &[], &[BED], true), goes);
    assert_eq!(state_near(0.3, -0.5, &[], &[BED], true), goes);
    // floor never seen with nothing the camera saw near it: the bend goes
    // (floor beside the rear is seldom seen; only where a thing may go on
    // out of view does it hold)
    assert_eq!(state_near(0.09, -0.25, &BESIDE_REAR_LEFT, &[], true), goes);
    assert_eq!(
        state_near(0.09, -0.25, &BESIDE_REAR_LEFT, &[[-0.70, 0.60]], true),
        goes
    );
    // the crawl's bend to the right: the rear-left corner swings out
    assert_eq!(state(0.09, -0.25, &BESIDE_REAR_LEFT, true), held);
    // and a faster one
    assert_eq!(state(0.3, -0.5, &BESIDE_REAR_LEFT, true), held);
    // to the left, it swings away
    assert_eq!(state(0.09, 0.25, &BESIDE_REAR_LEFT, true), goes);
    // straight on, the side passes along it
    assert_eq!(state(0.09, 0.0, &BESIDE_REAR_LEFT, true), goes);
    // the person's word took it off the list: nothing holds the bend
    assert_eq!(state(0.09, -0.25, &[], true), goes);
    // ahead of the front edge: the travel's own way, as driving straight
    assert_eq!(state(0.09, 0.25, &[[0.60, 0.30]], true), goes);
    // with the check off (a chair with sensors that see beside it)
    assert_eq!(state(0.09, -0.25, &BESIDE_REAR_LEFT, false), goes);
}
