//! The stopping distance, closed loop: the simulated chair (its power
//! module's first-order motor lag) at full speed towards a wall, its two
//! lasers merged into obstacles at 10 Hz, the supervisor at 20 Hz, its
//! output through the joystick mapping. A planner that keeps asking for
//! full speed (a planner bug), or one that asks for reverse while the chair
//! still rolls forward: either way the chair comes to rest before the wall,
//! inside the stop corridor. Prints the figures.

use std::time::Duration;

use opennav::config::Settings;
use opennav::msg::{Odometry, Pose2, Stamp, Stamped, StopReason, SupervisorState, VelocityCmd};
use opennav::safety::rear::RearView;
use opennav::safety::{Supervisor, SupervisorInputs};
use opennav::sensors::laser::merge_scans;
use opennav::sim::room::Room;
use opennav::sim::world::SimWorld;

const WALL_X_M: f64 = 6.0;

struct Trip {
    /// The chair's front when the supervisor first stopped it, m from the wall.
    gap_at_stop_m: f64,
    /// The closest the chair's front came to the wall, m.
    closest_m: f64,
    speed_at_stop_mps: f64,
    collisions: u64,
}

/// Drives at the planner's `asked` (given the time and the chair's front
/// gap to the wall) until at rest after a stop, or 30 s.
fn trip(asked: impl Fn(f64, f64) -> VelocityCmd) -> Trip {
    let settings = Settings::defaults();
    let mapping = settings.joystick_mapping();
    let lasers = [
        settings.lasers.left.base_from_laser(),
        settings.lasers.right.base_from_laser(),
    ];
    let mut world = SimWorld::living_room(settings.drive_params());
    world.room = Room {
        size_m: [WALL_X_M, 3.0, 2.8],
        objects: Vec::new(),
        pits: Vec::new(),
    };
    let start = Pose2 {
        x_m: 1.0,
        y_m: 1.5,
        theta_rad: 0.0,
    };
    world.truth = start;
    world.start = start;
    let mut sup = Supervisor::new(opennav::safety::SafetyLimits {
        camera_max_age: None,
        ..settings.safety_limits()
    });
    sup.goal_active();
    let front = settings.safety.front_offset_m;
    let rear = RearView {
        seen: true,
        reverse_seen: true,
        around_vouched: false,
        points_base: Vec::new(),
    };
    let mut obstacles = None;
    let mut joystick = (0i8, 0i8);
    let mut first_stop: Option<(f64, f64)> = None;
    let mut closest = f64::INFINITY;
    for k in 0..3000u64 {
        let t = Stamp(Duration::from_millis(10 * k));
        world.step(0.01, Some(joystick), &mapping);
        let gap = WALL_X_M - (world.truth.x_m + front);
        closest = closest.min(gap);
        if k % 10 == 0 {
            let scans: Vec<_> = lasers
                .iter()
                .map(|l| Stamped::new(t, world.laser_scan(l, k as u32)))
                .collect();
            obstacles = merge_scans(&[(&scans[0], &lasers[0]), (&scans[1], &lasers[1])]);
        }
        if k % 5 == 0 {
            let odom = Stamped::new(
                t,
                Odometry {
                    pose: world.truth,
                    v_mps: world.v_mps,
                    omega_radps: world.omega_radps,
                    ..Default::default()
                },
            );
            let cmd = Stamped::new(t, asked(t.as_secs_f64(), gap));
            let out = sup.step(
                t,
                &SupervisorInputs {
                    obstacles: obstacles.as_ref(),
                    odometry: Some(&odom),
                    command: Some(&cmd),
                    camera: None,
                    rear: Some(&rear),
                },
            );
            if out.state == SupervisorState::Stopped(StopReason::Obstacle) && first_stop.is_none() {
                first_stop = Some((gap, world.v_mps));
            }
            joystick = mapping.to_joystick(out.cmd.v_mps, out.cmd.omega_radps);
        }
        if first_stop.is_some() && world.v_mps.abs() < 1e-3 && joystick == (0, 0) {
            break;
        }
    }
    let (gap_at_stop_m, speed_at_stop_mps) = first_stop.expect("the supervisor stopped the chair");
    Trip {
        gap_at_stop_m,
        closest_m: closest,
        speed_at_stop_mps,
        collisions: world.report.collision_steps,
    }
}

fn check(name: &str, t: &Trip) {
    let settings = Settings::defaults();
    let travelled = t.gap_at_stop_m - t.closest_m;
    eprintln!(
        "{name}: stopped at {:.3} m from the wall at {:.2} m/s, came within {:.3} m of it: {:.3} m to stop",
        t.gap_at_stop_m, t.speed_at_stop_mps, t.closest_m, travelled
    );
    assert_eq!(t.collisions, 0, "{name}");
    assert!(t.closest_m > 0.05, "{name}: {:.3} m", t.closest_m);
    // the stop began inside the corridor (within its depth plus one laser
    // period at full speed), the chair still fast
    assert!(
        t.gap_at_stop_m <= settings.safety.stop_distance_m + 0.05,
        "{name}: {:.3}",
        t.gap_at_stop_m
    );
    assert!(
        t.speed_at_stop_mps > 0.2,
        "{name}: {:.2}",
        t.speed_at_stop_mps
    );
    // and took less than the corridor's depth
    assert!(
        travelled < settings.safety.stop_distance_m,
        "{name}: {travelled:.3} m"
    );
}

#[test]
fn at_full_speed_towards_a_wall_the_chair_stops_inside_the_corridor() {
    // a planner that never slows down
    let t = trip(|_, _| VelocityCmd {
        v_mps: 0.3,
        omega_radps: 0.0,
    });
    check("planner asking full speed", &t);
}

#[test]
fn asked_to_reverse_while_rolling_forward_the_chair_stops_first() {
    // the planner asks for reverse once the wall is 0.35 m off, while the
    // chair still rolls forward at full speed: the front stays checked, the
    // output is zero (no reverse) until the chair is at rest
    let t = trip(|_, gap| VelocityCmd {
        v_mps: if gap > 0.35 { 0.3 } else { -0.15 },
        omega_radps: 0.0,
    });
    check("planner asking reverse while rolling", &t);
}
