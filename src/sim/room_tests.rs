//! Tests of `sim::room` (split out to keep it readable).

use super::*;

fn k() -> Intrinsics {
    Intrinsics {
        width: 64,
        height: 36,
        fx: 32.0,
        fy: 32.0,
        cx: 31.5,
        cy: 17.5,
    }
}

#[test]
fn a_hulls_columns_in_a_row_are_its_width_there() {
    // a diamond (four corners twice): 20 px wide at row 10, narrower
    // above and below, nothing beyond its rows
    let c = [
        [10.0, 0.0],
        [20.0, 10.0],
        [10.0, 20.0],
        [0.0, 10.0],
        [10.0, 0.0],
        [20.0, 10.0],
        [10.0, 20.0],
        [0.0, 10.0],
    ];
    assert_eq!(hull_columns(&c, 10.0), Some((-1.0, 21.0)));
    // rows 2..4 (the band about row 3): 6 to 14 at row 4, a pixel
    // more a side
    assert_eq!(hull_columns(&c, 3.0), Some((5.0, 15.0)));
    assert_eq!(hull_columns(&c, 20.5), Some((8.5, 11.5)));
    assert_eq!(hull_columns(&c, 21.5), None);
    assert_eq!(hull_columns(&c, -1.5), None);
}

#[test]
fn look_direction_is_a_rotation_looking_where_asked() {
    let p = look_direction(Vector3::new(1.0, 2.0, 1.5), 0.3, -0.2);
    let r = p.rotation.to_rotation_matrix();
    assert!((r.matrix().determinant() - 1.0).abs() < 1e-12);
    let fwd = r * Vector3::z();
    assert!((fwd.z - (-0.2f64).sin()).abs() < 1e-12);
    // optical y (down) points down-ish
    assert!((r * Vector3::y()).z < 0.0);
}

#[test]
fn empty_room_depth_is_the_wall_distance() {
    let room = Room {
        size_m: [4.0, 4.0, 3.0],
        objects: vec![],
        pits: vec![],
    };
    // at (1, 2, 1.5) looking along +x: the far wall is 3 m ahead
    let pose = look_direction(Vector3::new(1.0, 2.0, 1.5), 0.0, 0.0);
    let r = room.render(&k(), &pose).unwrap();
    let c = r.depth.at(31, 17).unwrap();
    assert!((c - 3.0).abs() < 0.01, "{c}");
    assert!(r.instance.iter().all(|&i| i == -1));
}

#[test]
fn a_pit_shows_its_lower_floor_and_its_far_side() {
    let room = Room {
        size_m: [6.0, 4.0, 3.0],
        objects: vec![],
        pits: vec![Pit {
            min_m: [3.0, 0.0],
            max_m: [4.0, 4.0],
            depth_m: 0.2,
        }],
    };
    // 1 m up at x = 1 looking down 45°: the floor would be hit 1 m
    // ahead (x = 2, before the pit): unchanged
    let pose = look_direction(Vector3::new(1.0, 2.0, 1.0), 0.0, -45f64.to_radians());
    let r = room.render(&k(), &pose).unwrap();
    let c = r.depth.at(31, 17).unwrap() as f64;
    // (pixel 31, 17 is half a pixel off the optical axis: 3 %)
    assert!((c / 2f64.sqrt() - 1.0).abs() < 0.03, "{c}");
    // from x = 2.5: the floor at x = 3.5 is in the pit: the ray goes on
    // to z = -0.2 at x = 3.7
    let pose = look_direction(Vector3::new(2.5, 2.0, 1.0), 0.0, -45f64.to_radians());
    let r = room.render(&k(), &pose).unwrap();
    let c = r.depth.at(31, 17).unwrap() as f64;
    assert!((c / (1.2 * 2f64.sqrt()) - 1.0).abs() < 0.03, "{c}");
    // looking down more steeply into the pit's far side (x = 4)
    let pose = look_direction(Vector3::new(3.2, 2.0, 1.0), 0.0, -60f64.to_radians());
    let r = room.render(&k(), &pose).unwrap();
    let c = r.depth.at(31, 17).unwrap() as f64;
    // along the ray: z = 1 - t·sin60, x = 3.2 + t·cos60; the pit's
    // floor at t = 1.2/sin60 = 1.386 (x = 3.89 < 4)
    assert!(
        (c / (1.2 / 60f64.to_radians().sin()) - 1.0).abs() < 0.03,
        "{c}"
    );
}

#[test]
fn an_object_in_front_hides_the_wall() {
    let room = Room {
        size_m: [4.0, 4.0, 3.0],
        objects: vec![obj(
            14,
            "chair",
            [2.0, 1.5, 1.0],
            [0.5, 1.0, 1.0],
            [1, 2, 3],
        )],
        pits: vec![],
    };
    let pose = look_direction(Vector3::new(1.0, 2.0, 1.5), 0.0, 0.0);
    let r = room.render(&k(), &pose).unwrap();
    let i = 17 * 64 + 31;
    assert_eq!(r.instance[i], 0);
    assert!((r.depth.data()[i] - 1.0).abs() < 1e-6);
    let cloud = room.ground_truth_cloud(0.1);
    assert!(cloud.iter().any(|(_, s, i)| *s == 14 && *i == 0));
    assert!(cloud.iter().any(|(_, s, i)| *s == 0 && *i == -100));
}

#[test]
fn skipping_objects_outside_their_pixel_rectangle_changes_no_pixel() {
    // random boxes, some beside or behind the camera, seen from
    // random poses inside the room: each pixel as a cast against every
    // object (no rectangles, no order) gives
    let mut rng = crate::sim::scene::SplitMix64::new(7);
    let k = Intrinsics {
        width: 96,
        height: 72,
        fx: 60.0,
        fy: 60.0,
        cx: 47.5,
        cy: 35.5,
    };
    let mut hits = 0;
    for _ in 0..20 {
        let objects = (0..12)
            .map(|_| {
                let min = [
                    rng.range(0.0, 5.0),
                    rng.range(0.0, 4.0),
                    rng.range(0.0, 1.0),
                ];
                let size = [
                    rng.range(0.1, 1.2),
                    rng.range(0.1, 1.2),
                    rng.range(0.1, 1.5),
                ];
                obj(1, "box", min, size, [100, 100, 100])
            })
            .collect();
        let room = Room {
            size_m: [6.0, 5.0, 2.8],
            objects,
            pits: vec![],
        };
        let eye = Vector3::new(
            rng.range(0.5, 5.5),
            rng.range(0.5, 4.5),
            rng.range(0.3, 1.5),
        );
        let pose = look_direction(eye, rng.range(-3.1, 3.1), rng.range(-0.6, 0.2));
        let rendered = room.render(&k, &pose).unwrap();
        let r = pose.rotation.to_rotation_matrix();
        let o = pose.translation.vector;
        let all: Vec<Candidate> = (0..room.objects.len())
            .map(|idx| Candidate {
                dist_m: 0.0,
                idx,
                u_lo: f64::NEG_INFINITY,
                u_hi: f64::INFINITY,
            })
            .collect();
        for v in 0..k.height {
            for u in 0..k.width {
                let d = r * Vector3::new((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy, 1.0);
                let (t, _, id) = room.cast(&o, &d, &all, u as f64);
                let i = v * k.width + u;
                assert_eq!(rendered.instance[i], id, "pixel ({u}, {v})");
                assert_eq!(rendered.depth.data()[i], t as f32, "pixel ({u}, {v})");
                hits += usize::from(id >= 0);
            }
        }
    }
    // the boxes were in view
    assert!(hits > 10_000, "{hits}");
}
