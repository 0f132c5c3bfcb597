//! Tests of `sim::world` (split out to keep it readable).

use super::*;

fn mapping() -> JoystickMapping {
    JoystickMapping {
        forward_full_mps: 1.0,
        reverse_full_mps: 0.5,
        turn_full_radps: 1.5,
        deadband: 3,
    }
}

fn world() -> SimWorld {
    SimWorld::living_room(DiffDriveParams::paper_chair())
}

#[test]
fn casting_nearest_segments_first_finds_what_casting_against_all_does() {
    let mut rng = crate::sim::scene::SplitMix64::new(11);
    let segs: Vec<([f64; 2], [f64; 2])> = (0..120)
        .map(|_| {
            let p = [rng.range(-5.0, 5.0), rng.range(-5.0, 5.0)];
            let a = rng.range(-3.2, 3.2);
            let l = rng.range(0.0, 1.5);
            (p, [p[0] + l * a.cos(), p[1] + l * a.sin()])
        })
        .collect();
    let mut hits = 0;
    for _ in 0..50 {
        let o = [rng.range(-4.0, 4.0), rng.range(-4.0, 4.0)];
        let sorted = by_distance(o, &segs);
        for k in 0..360 {
            let a = (k as f64).to_radians();
            let brute = segs
                .iter()
                .filter_map(|s| ray_cast(o, a, std::slice::from_ref(s)))
                .min_by(f64::total_cmp);
            assert_eq!(
                ray_cast_nearest_first(o, a, &sorted),
                brute,
                "from {o:?} at {k}°"
            );
            hits += usize::from(brute.is_some());
        }
    }
    assert!(hits > 10_000, "{hits}");
}

#[test]
fn the_clearance_skipping_far_objects_is_the_clearance_to_every_object() {
    // the same measure over every object, nothing skipped
    let every = |w: &SimWorld| {
        let [sx, sy, _] = w.room.size_m;
        let wall = footprint_corners(&w.footprint, &w.truth)
            .iter()
            .map(|p| p[0].min(p[1]).min(sx - p[0]).min(sy - p[1]))
            .fold(f64::INFINITY, f64::min);
        let mut best = (wall, None);
        for (i, o) in w.room.objects.iter().enumerate() {
            let (lo, hi) = ([o.min_m[0], o.min_m[1]], [o.max_m[0], o.max_m[1]]);
            let d = footprint_gap(&w.footprint, &w.truth, lo, hi);
            if o.max_m[2] > 0.05 && d < best.0 {
                best = (d, Some(i));
            }
        }
        best
    };
    let mut rng = crate::sim::scene::SplitMix64::new(3);
    let (mut touching, mut objects) = (0, 0);
    for k in 0..20 {
        let scene = crate::sim::scene::generate(crate::sim::scene::scene_seed(1, k));
        let mut w = SimWorld::in_room(
            scene.room.clone(),
            scene.start,
            DiffDriveParams::paper_chair(),
        );
        for _ in 0..200 {
            let [sx, sy, _] = w.room.size_m;
            w.truth = Pose2 {
                x_m: rng.range(0.0, sx),
                y_m: rng.range(0.0, sy),
                theta_rad: rng.range(-3.2, 3.2),
            };
            let (got, want) = (w.clearance_to(), every(&w));
            assert_eq!(
                got.0.to_bits(),
                want.0.to_bits(),
                "scene {k} at {:?}",
                w.truth
            );
            assert_eq!(got.1, want.1, "scene {k} at {:?}", w.truth);
            touching += usize::from(want.0 <= 0.0);
            objects += usize::from(want.1.is_some());
        }
    }
    // overlapping objects and nearest objects (not walls) were among them
    assert!(touching > 100 && objects > 1000, "{touching} {objects}");
}

/// The footprint's outline and a box's, each as points every `step_m`
/// along its sides, and whether any footprint point is in the box or any
/// box point in the footprint.
fn sampled_gap(
    f: &Footprint,
    pose: &Pose2,
    lo: [f64; 2],
    hi: [f64; 2],
    step_m: f64,
) -> (f64, bool) {
    let (c, s) = (pose.theta_rad.cos(), pose.theta_rad.sin());
    let sides = |a: [f64; 2], b: [f64; 2], out: &mut Vec<[f64; 2]>| {
        let n = ((b[0] - a[0]).hypot(b[1] - a[1]) / step_m).ceil().max(1.0) as usize;
        out.extend((0..=n).map(|i| {
            let t = i as f64 / n as f64;
            [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
        }));
    };
    let (mut chair, mut theirs) = (Vec::new(), Vec::new());
    let fc = [
        [-f.rear_m, -f.half_width_m],
        [f.front_m, -f.half_width_m],
        [f.front_m, f.half_width_m],
        [-f.rear_m, f.half_width_m],
    ];
    let bc = [
        [lo[0], lo[1]],
        [hi[0], lo[1]],
        [hi[0], hi[1]],
        [lo[0], hi[1]],
    ];
    for k in 0..4 {
        sides(fc[k], fc[(k + 1) % 4], &mut chair);
        sides(bc[k], bc[(k + 1) % 4], &mut theirs);
    }
    let to_world = |q: [f64; 2]| {
        [
            pose.x_m + c * q[0] - s * q[1],
            pose.y_m + s * q[0] + c * q[1],
        ]
    };
    let chair: Vec<[f64; 2]> = chair.into_iter().map(to_world).collect();
    let mut gap = f64::INFINITY;
    let mut inside = false;
    for p in &chair {
        let d = box_distance(lo, hi, *p);
        inside |= d <= 0.0;
        for q in &theirs {
            gap = gap.min((p[0] - q[0]).hypot(p[1] - q[1]));
        }
    }
    for q in &theirs {
        inside |= box_distance(fc[0], fc[2], pose.base_from_odom(*q)) <= 0.0;
    }
    (gap, inside)
}

/// The exact gap between the footprint and a box: apart, the distance
/// between their outlines to within the sampling; overlapping, never
/// above zero, also when they cross like a plus with no corner of either
/// inside the other (where the corners' distances all read apart).
#[test]
fn the_footprint_gap_is_the_distance_between_the_outlines() {
    let f = Footprint {
        front_m: 0.55,
        rear_m: 0.6,
        half_width_m: 0.35,
    };
    let mut rng = crate::sim::scene::SplitMix64::new(5);
    let (mut apart, mut overlapping) = (0, 0);
    for _ in 0..3000 {
        let pose = Pose2 {
            x_m: rng.range(-1.5, 1.5),
            y_m: rng.range(-1.5, 1.5),
            theta_rad: rng.range(-3.2, 3.2),
        };
        let lo = [rng.range(-1.0, 0.5), rng.range(-1.0, 0.5)];
        let hi = [lo[0] + rng.range(0.02, 1.5), lo[1] + rng.range(0.02, 1.5)];
        let got = footprint_gap(&f, &pose, lo, hi);
        let (sampled, inside) = sampled_gap(&f, &pose, lo, hi, 0.002);
        if got > 0.0 {
            apart += 1;
            assert!(
                !inside,
                "{got} apart, yet a point inside: {pose:?} {lo:?} {hi:?}"
            );
            // the sampled outlines are never nearer than the true ones, and
            // no more than a sample spacing further
            assert!(
                got <= sampled + 1e-12,
                "{got} > {sampled}: {pose:?} {lo:?} {hi:?}"
            );
            assert!(
                got > sampled - 0.002,
                "{got} ≪ {sampled}: {pose:?} {lo:?} {hi:?}"
            );
        } else {
            overlapping += 1;
            assert!(
                inside || sampled < 0.002,
                "{got} overlapping, yet apart by {sampled}: {pose:?} {lo:?} {hi:?}"
            );
        }
    }
    assert!(apart > 500 && overlapping > 500, "{apart} {overlapping}");
    // a long thin box across the chair's middle, its ends outside: no
    // corner of either is inside the other
    let pose = Pose2 {
        x_m: 0.0,
        y_m: 0.0,
        theta_rad: 0.0,
    };
    let (lo, hi) = ([-0.05, -1.0], [0.05, 1.0]);
    let corners_apart = footprint_corners(&f, &pose)
        .iter()
        .all(|p| box_distance(lo, hi, *p) > 0.0);
    assert!(corners_apart);
    assert_eq!(footprint_gap(&f, &pose, lo, hi), 0.0);
    // and the same box beside the chair is as far as its side
    let (lo, hi) = ([-0.05, 0.45], [0.05, 1.0]);
    assert!((footprint_gap(&f, &pose, lo, hi) - 0.1).abs() < 1e-12);
}

#[test]
fn the_start_is_free_and_a_wall_is_where_the_laser_says() {
    let w = world();
    assert!(w.clearance() > 0.3, "{}", w.clearance());
    // a laser at the base, looking along the chair's heading
    let scan = w.laser_scan(&Isometry3::identity(), 0);
    let ahead = scan.ranges_m[(SensorParams::URG_04LX.afrt - SensorParams::URG_04LX.amin) as usize]
        .expect("a return ahead");
    let truth = ray_cast(
        [w.truth.x_m, w.truth.y_m],
        w.truth.theta_rad,
        &segments_at(&w.room, 0.0),
    )
    .expect("hit");
    assert!((ahead as f64 - truth).abs() < 0.002, "{ahead} vs {truth}");
}

/// A person 0.45 × 0.3 m and 1.7 m tall walking to and fro at 0.5 m/s
/// between `from_m` and `to_m` (their box's low corner), the world's only
/// walker: their object's index.
fn add_walker(w: &mut SimWorld, from_m: [f64; 2], to_m: [f64; 2]) -> usize {
    let size_m = [0.45, 0.3, 1.7];
    let idx = w.room.objects.len();
    w.room.objects.push(crate::sim::room::SimObject {
        label_id: 0,
        label: "person".into(),
        min_m: [from_m[0], from_m[1], 0.0],
        max_m: [from_m[0] + size_m[0], from_m[1] + size_m[1], size_m[2]],
        color: [0, 0, 0],
    });
    w.walkers = vec![Walking::new(Walker {
        object: idx,
        from_m,
        to_m,
        speed_mps: 0.5,
        size_m,
    })];
    idx
}

#[test]
fn a_walking_person_walks_to_and_fro_and_waits_for_the_chair() {
    let mut w = world();
    let mapping = mapping();
    // across the room's free middle, the chair out of the way
    w.truth = Pose2 {
        x_m: 4.6,
        y_m: 1.9,
        theta_rad: 0.0,
    };
    let idx = add_walker(&mut w, [3.2, 1.0], [3.2, 3.0]);
    // 2 m at 0.5 m/s: there in 4 s, and back in another 4
    for _ in 0..400 {
        w.step(0.01, None, &mapping);
    }
    assert!((w.room.objects[idx].min_m[1] - 3.0).abs() < 0.01);
    for _ in 0..400 {
        w.step(0.01, None, &mapping);
    }
    assert!((w.room.objects[idx].min_m[1] - 1.0).abs() < 0.01);
    // the chair in their way: they stop short of it
    w.truth = Pose2 {
        x_m: 3.425,
        y_m: 2.5,
        theta_rad: 0.0,
    };
    let gap = |w: &SimWorld| {
        let o = &w.room.objects[idx];
        let (lo, hi) = ([o.min_m[0], o.min_m[1]], [o.max_m[0], o.max_m[1]]);
        footprint_gap(&w.footprint, &w.truth, lo, hi)
    };
    // (at 0.5 m/s from 1.0 they meet the chair's keep-out at 1.45,
    // within 1 s)
    for _ in 0..120 {
        w.step(0.01, None, &mapping);
    }
    let waiting_at = w.room.objects[idx].min_m[1];
    for _ in 0..130 {
        w.step(0.01, None, &mapping);
    }
    let g = gap(&w);
    assert!(
        (WALKER_KEEPS_M - 0.01..WALKER_KEEPS_M + 0.02).contains(&g),
        "{g}"
    );
    assert_eq!(w.room.objects[idx].min_m[1], waiting_at, "they waited");
    // the chair waits too: after WALKER_GIVES_WAY_AFTER_S they turn
    // back and give way
    for _ in 0..210 {
        w.step(0.01, None, &mapping);
    }
    assert!(w.walkers[0].back, "{:?}", w.walkers[0]);
    assert!(
        w.room.objects[idx].min_m[1] < waiting_at - 0.25,
        "{} vs {waiting_at}",
        w.room.objects[idx].min_m[1]
    );
    assert!(gap(&w) > WALKER_KEEPS_M + 0.25, "{}", gap(&w));
    assert_eq!(w.report.collision_steps, 0);
}

/// A person just before the front of a chair standing in a doorway,
/// walking across its way (along its front, at the same distance), walks
/// on past it: before, each step within the keep-out that did not take
/// them further away waited, and turning back after
/// [`WALKER_GIVES_WAY_AFTER_S`] was no better, so they stood there with
/// the chair for good (scene 168 of seed 1, the chair held in a doorway
/// 40 s by a person 0.14 m before it).
#[test]
fn a_person_just_before_a_waiting_chair_walks_on_past_it() {
    let mut w = world();
    let mapping = mapping();
    w.truth = Pose2 {
        x_m: 3.0,
        y_m: 2.0,
        theta_rad: 0.0,
    };
    // the front at x 3.55; the person 0.14 m before it, across its way
    let idx = add_walker(&mut w, [3.69, 1.4], [3.69, 2.9]);
    let before = w.room.objects[idx].min_m;
    for _ in 0..300 {
        w.step(0.01, None, &mapping);
    }
    let after = w.room.objects[idx].min_m;
    assert!(after[1] > before[1] + 1.0, "{before:?} → {after:?}");
    assert_eq!(after[0], before[0], "along its line");
    assert_eq!(w.report.collision_steps, 0);
}

/// The same with the chair turned a little (0.01 rad, as a chair that has
/// just lined up stands): along its front, each step nears the front by
/// a hundredth of its length, and they walk on past it all the same —
/// before, that hundredth made every step wait, and a person at the end
/// of their walk before the chair's front stood there with it for good
/// (scene 60 of seed 1: a person 0.135 m before a chair in a doorway for
/// 70 s, the chair held until it gave up).
#[test]
fn a_person_just_before_a_chair_turned_a_little_walks_on_past_it() {
    for theta_rad in [0.01, -0.01] {
        let mut w = world();
        let mapping = mapping();
        w.truth = Pose2 {
            x_m: 3.0,
            y_m: 2.0,
            theta_rad,
        };
        let idx = add_walker(&mut w, [3.69, 1.4], [3.69, 2.9]);
        let before = w.room.objects[idx].min_m;
        for _ in 0..300 {
            w.step(0.01, None, &mapping);
        }
        let after = w.room.objects[idx].min_m;
        assert!(
            after[1] > before[1] + 1.0,
            "{theta_rad}: {before:?} → {after:?}"
        );
        assert_eq!(w.report.collision_steps, 0);
    }
}

/// A person beside a chair turned to their way, walking on towards its
/// side, never comes nearer to it than they were (they wait, then turn
/// back): their distance is to the footprint's edges, not to points along
/// them, between which a step can near the edge.
#[test]
fn a_person_beside_a_slanted_chair_never_comes_nearer_its_side() {
    let mut w = world();
    let mapping = mapping();
    w.truth = Pose2 {
        x_m: 3.0,
        y_m: 2.0,
        theta_rad: -0.3,
    };
    // the left side runs up to the left: walking −x nears it
    let idx = add_walker(&mut w, [3.05, 2.43], [1.5, 2.43]);
    // the box's distance to the footprint, measured on its edges every mm
    let edge_gap = |w: &SimWorld| {
        let o = &w.room.objects[idx];
        let (c, s) = (w.truth.theta_rad.cos(), w.truth.theta_rad.sin());
        let f = w.footprint;
        let mut best = f64::INFINITY;
        for i in 0..=1000 {
            let t = i as f64 / 1000.0;
            let a = -f.rear_m + t * (f.front_m + f.rear_m);
            let b = -f.half_width_m + t * 2.0 * f.half_width_m;
            for q in [
                [a, f.half_width_m],
                [a, -f.half_width_m],
                [f.front_m, b],
                [-f.rear_m, b],
            ] {
                let p = [
                    w.truth.x_m + c * q[0] - s * q[1],
                    w.truth.y_m + s * q[0] + c * q[1],
                ];
                let dx = (o.min_m[0] - p[0]).max(p[0] - o.max_m[0]).max(0.0);
                let dy = (o.min_m[1] - p[1]).max(p[1] - o.max_m[1]).max(0.0);
                best = best.min(dx.hypot(dy));
            }
        }
        best
    };
    let start = edge_gap(&w);
    assert!(start < WALKER_KEEPS_M, "{start}");
    let mut nearest = start;
    for _ in 0..800 {
        w.step(0.01, None, &mapping);
        nearest = nearest.min(edge_gap(&w));
    }
    assert!(nearest > start - 1e-3, "{nearest} < {start}");
    assert_eq!(w.report.collision_steps, 0);
}

#[test]
fn driving_forward_moves_the_chair_and_the_wheels_agree() {
    let mut w = world();
    let mapping = mapping();
    let mut odo = crate::estimation::odometry::WheelOdometry::new(w.drive);
    odo.update(&w.wheel_ticks());
    for _ in 0..200 {
        w.step(0.01, Some((0, 30)), &mapping);
        odo.update(&w.wheel_ticks());
    }
    let moved = (w.truth.x_m - w.start.x_m).hypot(w.truth.y_m - w.start.y_m);
    assert!((moved - 0.555).abs() < 0.03, "{moved}");
    let p = odo.pose();
    assert!((p.x_m - moved).abs() < 0.01 && p.y_m.abs() < 0.01, "{p:?}");
    // motors stopped: the chair comes to rest
    for _ in 0..200 {
        w.step(0.01, None, &mapping);
    }
    assert!(w.v_mps.abs() < 1e-3);
}

#[test]
fn the_first_contact_says_what_was_touched_and_how_the_chair_moved() {
    let mut w = world();
    let mapping = mapping();
    // a low box 0.3 m ahead of the chair's front
    let (c, s) = (w.truth.theta_rad.cos(), w.truth.theta_rad.sin());
    let at = [
        w.truth.x_m + c * (w.footprint.front_m + 0.4),
        w.truth.y_m + s * (w.footprint.front_m + 0.4),
    ];
    let idx = w.room.objects.len();
    w.room.objects.push(crate::sim::room::SimObject {
        label_id: 0,
        label: "footstool".into(),
        min_m: [at[0] - 0.1, at[1] - 0.1, 0.0],
        max_m: [at[0] + 0.1, at[1] + 0.1, 0.25],
        color: [0, 0, 0],
    });
    assert!(w.report.first_contact.is_none());
    for _ in 0..300 {
        w.step(0.01, Some((0, 30)), &mapping);
    }
    let contact = w
        .report
        .first_contact
        .expect("the chair drove into the box");
    assert_eq!(contact.object, Some(idx));
    assert!(contact.v_mps > 0.1 && contact.time_s > 0.5, "{contact:?}");
    assert!(w.report.collision_steps > 0);
}
