//! Tests of `estimation::tracker` (split out to keep it readable).

use super::*;
use crate::msg::Frame;
use nalgebra::Point3;

fn obj(label: &str, c: [f32; 3], half: f32) -> Object3D {
    let pts = vec![
        Point3::new(c[0] - half, c[1] - half, c[2] - half),
        Point3::new(c[0] + half, c[1] + half, c[2] + half),
    ];
    Object3D::from_points(label.into(), 0.8, Frame::Odom, pts, None).unwrap()
}

fn s(t: f64) -> Stamp {
    Stamp::from_secs_f64(t)
}

#[test]
fn two_chairs_stay_apart_and_confirm() {
    let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
    for k in 0..3 {
        let j = 0.02 * k as f32;
        tr.update(
            s(k as f64 * 0.1),
            &[
                obj("chair", [2.0 + j, 0.0, 0.4], 0.25),
                obj("chair", [2.0, 2.0 - j, 0.4], 0.25),
            ],
            |_| true,
        );
    }
    assert_eq!(tr.tracks().len(), 2);
    assert!(tr.tracks().iter().all(|t| t.confirmed && t.hits == 3));
    let g = tr.goal("chair", [0.0, 0.0]).unwrap();
    assert!((g.center_m[1]).abs() < 0.1);
    assert!(tr.goal("table", [0.0, 0.0]).is_none());
    // the filter smooths: the first chair is between its detections
    assert!(tr.tracks()[0].center_m[0] > 2.0 && tr.tracks()[0].center_m[0] < 2.04);
}

#[test]
fn unseen_tracks_decay_only_when_they_should_be_visible() {
    let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
    tr.update(s(0.0), &[obj("sofa", [3.0, 0.0, 0.4], 0.5)], |_| true);
    tr.update(
        s(0.1),
        &[
            obj("sofa", [3.0, 0.0, 0.4], 0.5),
            obj("sofa", [3.0, 1.1, 0.4], 0.5),
        ],
        |_| true,
    );
    // a second sofa a metre away is another instance
    assert_eq!(tr.tracks().len(), 2);
    tr.update(s(0.2), &[obj("sofa", [3.0, 0.0, 0.4], 0.5)], |_| false);
    assert_eq!(tr.tracks().len(), 2);
    // out of view: confidence kept; in view but missed: decays until dropped
    let before = tr.tracks()[0].confidence;
    tr.update(s(0.3), &[], |_| false);
    assert_eq!(tr.tracks()[0].confidence, before);
    assert!(!tr.tracks()[0].expected_seen);
    tr.update(s(0.4), &[], |_| true);
    assert!(tr.tracks()[0].expected_seen);
    assert!(tr.tracks()[0].confidence < before);
    for k in 1..10 {
        tr.update(s(0.4 + 0.1 * k as f64), &[], |_| true);
    }
    assert!(tr.tracks().is_empty());
}

#[test]
fn a_false_box_now_and_then_on_one_wall_is_not_confirmed_but_an_object_seen_in_a_row_is() {
    let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
    // a false "chair" on the wall a metre away, every other view, its
    // boxes within association of each other (scene 444 of the bench)
    let walls = [
        [-0.63, -0.59, 0.70],
        [-0.50, -0.92, 0.68],
        [-0.47, -1.00, 0.64],
    ];
    for (k, c) in walls.iter().enumerate() {
        tr.update(s(k as f64), &[obj("chair", *c, 0.1)], |_| true);
        tr.update(s(k as f64 + 0.5), &[], |_| true);
    }
    let wall = &tr.tracks()[0];
    assert_eq!((wall.hits, wall.streak), (3, 0));
    assert!(!wall.confirmed, "three hits between misses confirmed it");
    assert!(tr.goal("chair", [0.0, 0.0]).is_none());
    // out of view between its hits, nothing is missed: the streak holds
    let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
    for (k, c) in walls.iter().enumerate() {
        tr.update(s(k as f64), &[obj("chair", *c, 0.1)], |_| true);
        tr.update(s(k as f64 + 0.5), &[], |_| false);
    }
    assert!(tr.tracks()[0].confirmed);
    // a real chair missed once, then seen three views in a row: confirmed
    let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
    tr.update(s(0.0), &[obj("chair", [2.0, 0.0, 0.4], 0.25)], |_| true);
    tr.update(s(0.5), &[], |_| true);
    for k in 1..=2 {
        tr.update(
            s(0.5 * k as f64 + 0.5),
            &[obj("chair", [2.0, 0.0, 0.4], 0.25)],
            |_| true,
        );
        assert!(!tr.tracks()[0].confirmed);
    }
    tr.update(s(2.0), &[obj("chair", [2.0, 0.0, 0.4], 0.25)], |_| true);
    assert_eq!(tr.tracks()[0].streak, 3);
    assert!(tr.tracks()[0].confirmed);
    // once confirmed, a miss does not unconfirm it
    tr.update(s(2.5), &[], |_| true);
    assert!(tr.tracks()[0].confirmed);
}

#[test]
fn a_corner_seen_up_close_does_not_shrink_the_box_but_a_box_beyond_it_moves_it() {
    let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
    // a bed seen whole: 1.6 m square about (3, 0)
    for k in 0..3 {
        tr.update(
            s(0.5 * k as f64),
            &[obj("bed", [3.0, 0.0, 0.3], 0.8)],
            |_| true,
        );
    }
    let whole = tr.tracks()[0].clone();
    // then only its near corner, 0.3 m across, many times over
    for k in 3..20 {
        tr.update(
            s(0.5 * k as f64),
            &[obj("bed", [2.35, -0.65, 0.3], 0.15)],
            |_| true,
        );
    }
    let t = &tr.tracks()[0];
    assert_eq!((t.center_m, t.size_m), (whole.center_m, whole.size_m));
    assert_eq!(t.footprint, whole.footprint);
    assert_eq!(t.hits, 20);
    assert!(t.last_seen == s(9.5) && t.misses == 0);
    // a detection reaching out of the box is a measure: the box follows
    tr.update(s(10.0), &[obj("bed", [3.3, 0.0, 0.3], 0.8)], |_| true);
    assert!(tr.tracks()[0].center_m[0] > whole.center_m[0] + 0.01);
    // as is one inside it covering most of it (a tighter outline)
    let mut tr = Tracker::new(crate::config::Settings::defaults().tracker);
    tr.update(s(0.0), &[obj("bed", [3.0, 0.0, 0.3], 0.8)], |_| true);
    tr.update(s(0.5), &[obj("bed", [3.0, 0.0, 0.3], 0.7)], |_| true);
    assert!(tr.tracks()[0].size_m[0] < 1.6 - 0.01);
}

#[test]
fn overlapping_same_label_tracks_merge() {
    let mut tr = Tracker::new(TrackerParams {
        max_center_distance_m: 0.01,
        ..crate::config::Settings::defaults().tracker
    });
    // two detections of one table, boxes overlapping (IoU ≈ 0.9) but
    // centres apart beyond association: two tracks, then one
    tr.update(
        s(0.0),
        &[
            obj("table", [1.0, 1.0, 0.4], 0.5),
            obj("table", [1.02, 1.0, 0.4], 0.5),
        ],
        |_| true,
    );
    assert_eq!(tr.tracks().len(), 1);
    assert_eq!(tr.tracks()[0].hits, 2);
}

/// The confirmed track of one box `label` of half size `half` about
/// `c`, seen once.
fn one_track(label: &str, c: [f32; 3], half: f32) -> Track {
    track_of(obj(label, c, half))
}

/// The confirmed track of `object`, seen once.
fn track_of(object: Object3D) -> Track {
    let label = object.label.clone();
    let mut tr = Tracker::new(TrackerParams {
        confirm_hits: 1,
        ..crate::config::Settings::defaults().tracker
    });
    tr.update(s(0.0), &[object], |_| true);
    tr.goal(&label, [0.0, 0.0]).unwrap().clone()
}

#[test]
fn approach_pose_faces_the_object_from_the_free_side() {
    let t = one_track("chair", [3.0, 0.0, 0.4], 0.25);
    let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &[], 0.4, &|_| true).unwrap();
    assert!(
        (p.x_m - (3.0 - 0.25 - 0.6)).abs() < 1e-6 && p.y_m.abs() < 1e-6 && p.yaw_rad.abs() < 1e-9
    );
    // something stands there: the next free direction, still facing it
    let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &[[2.15, 0.0]], 0.4, &|_| true).unwrap();
    assert!(p.y_m.abs() > 0.1);
    let to_obj = (0.0 - p.y_m).atan2(3.0 - p.x_m);
    assert!((p.yaw_rad - to_obj).abs() < 1e-9);
    // surrounded: none
    let ring: Vec<[f64; 2]> = (0..72)
        .map(|k| {
            let a = k as f64 * 5f64.to_radians();
            [3.0 + 0.9 * a.cos(), 0.9 * a.sin()]
        })
        .collect();
    assert!(approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &ring, 0.4, &|_| true).is_none());
}

/// A bed 0.6 m deep and 2 m long (along y) about (3, 0): where any place
/// is admitted, the one facing its centre from the chair; where the map
/// admits only places off its near side's middle (a low box there), none
/// of those facing the centre passes and the place is square to the
/// side, the one nearest the chair, facing +x; none where nothing is
/// admitted.
#[test]
fn a_long_object_is_approached_square_to_its_side_where_no_place_facing_its_centre_passes() {
    let mut pts = Vec::new();
    for i in 0..=12 {
        for j in 0..=40 {
            for z in [0.0f32, 0.5] {
                pts.push(Point3::new(
                    2.7 + 0.05 * i as f32,
                    -1.0 + 0.05 * j as f32,
                    z,
                ));
            }
        }
    }
    let t = track_of(Object3D::from_points("bed".into(), 0.8, Frame::Odom, pts, None).unwrap());
    let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &[], 0.4, &|_| true).unwrap();
    assert!((p.x_m - 2.1).abs() < 1e-4 && p.y_m.abs() < 1e-4, "{p:?}");
    let off_the_middle = |p: [f64; 2]| (p[0] - 2.1).abs() < 1e-4 && p[1].abs() > 0.5;
    let p = approach_pose(&t, [0.0, -0.2], 0.6, 0.6, &[], 0.4, &off_the_middle).unwrap();
    assert!(
        (p.x_m - 2.1).abs() < 1e-4 && (p.y_m + 0.6).abs() < 1e-4,
        "{p:?}"
    );
    assert!(p.yaw_rad.abs() < 1e-6, "{p:?}");
    // from beyond the bed's far end: that end of the side
    let p = approach_pose(&t, [0.0, 1.5], 0.6, 0.6, &[], 0.4, &off_the_middle).unwrap();
    assert!(
        (p.x_m - 2.1).abs() < 1e-4 && (p.y_m - 1.0).abs() < 1e-4,
        "{p:?}"
    );
    // a cabinet 0.32 m from that place: the next one along
    let p = approach_pose(
        &t,
        [0.0, 1.5],
        0.6,
        0.6,
        &[[1.9, 1.25]],
        0.4,
        &off_the_middle,
    );
    let p = p.unwrap();
    assert!(
        (p.x_m - 2.1).abs() < 1e-4 && (p.y_m - 0.9).abs() < 1e-4,
        "{p:?}"
    );
    assert!(approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &[], 0.4, &|_| false).is_none());
}

#[test]
fn only_the_chairs_body_needs_room_beside_the_line_to_the_object() {
    let t = one_track("chair", [3.0, 0.0, 0.4], 0.25);
    // a table's corner beside the gap between the chair's front and
    // the object (0.3 m off the line), not beside the chair's body
    let corner = [[2.62, 0.3]];
    let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.2, &corner, 0.4, &|_| true).unwrap();
    assert!(p.y_m.abs() < 1e-6 && (p.x_m - 2.15).abs() < 1e-6, "{p:?}");
    // the body reaching past it: another side
    let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &corner, 0.4, &|_| true).unwrap();
    assert!(p.y_m.abs() > 0.1, "{p:?}");
    // something right on the line in the gap: nothing is seen past it
    let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.2, &[[2.6, 0.05]], 0.4, &|_| true).unwrap();
    assert!(p.y_m.abs() > 0.1, "{p:?}");
}

#[test]
fn approach_pose_stops_at_a_turned_objects_own_outline() {
    // a desk 1.2 × 0.6 m turned 45° about (3, 0): its upright box is
    // 1.27 m square, and towards the chair at the origin the desk's
    // long side crosses the line 0.42 m from its centre, the box 0.64 m;
    // its nearest corner lies off the line, nearer a place 0.6 m on
    // from the crossing
    let yaw = 45f64.to_radians();
    let mut pts = Vec::new();
    for i in 0..=24 {
        for j in 0..=12 {
            for z in [0.0f32, 0.75] {
                let (l, w) = (-0.6 + 0.05 * i as f64, -0.3 + 0.05 * j as f64);
                pts.push(Point3::new(
                    (3.0 + l * yaw.cos() - w * yaw.sin()) as f32,
                    (l * yaw.sin() + w * yaw.cos()) as f32,
                    z,
                ));
            }
        }
    }
    let t = track_of(Object3D::from_points("desk".into(), 0.8, Frame::Odom, pts, None).unwrap());
    assert!((t.size_m[0] - 0.9 * 2f64.sqrt()).abs() < 0.01, "{t:?}");
    let crossing = 3.0 - 0.3 * 2f64.sqrt();
    let upright = 3.0 - 0.45 * 2f64.sqrt();
    // the desk's outline: the corner, at 1.2 m from the centre along the
    // line, is 0.6 m off
    let outline = |p: &ApproachPose| {
        let [x, y] = t.footprint.ground_local([p.x_m, p.y_m]);
        ((x.abs() - 0.6).max(0.0)).hypot((y.abs() - 0.3).max(0.0))
    };
    let check = |p: &ApproachPose| {
        assert!(p.y_m.abs() < 1e-6, "{p:?}");
        assert!(
            outline(p) >= 0.6 - STANDOFF_SLACK_M - 0.005 && outline(p) <= 0.6 + 0.005,
            "{p:?}: {} m from the desk",
            outline(p)
        );
        // further than the crossing puts it, nearer than the upright box
        assert!(
            p.x_m < crossing - 0.6 - 0.1 && p.x_m > upright - 0.6,
            "{p:?}"
        );
    };
    check(&approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &[], 0.4, &|_| true).unwrap());
    // something low in front of it, inside its upright box but not in
    // its outline: the desk's outline all the same
    let low = [[2.45, -0.05], [2.45, 0.05]];
    check(&approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &low, 0.4, &|_| true).unwrap());
}

#[test]
fn approach_pose_stops_at_the_objects_own_points_inside_its_box() {
    // a box 1 m square about (3, 0): the object turned in it, its face
    // towards the chair seen by the lasers 0.3 m inside the box
    let t = one_track("desk", [3.0, 0.0, 0.4], 0.5);
    let face: Vec<[f64; 2]> = (-3..=3).map(|k| [2.8, k as f64 * 0.1]).collect();
    let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &face, 0.4, &|_| true).unwrap();
    assert!((p.x_m - (2.8 - 0.6)).abs() < 1e-6, "{p:?}");
    // its points beside the way in, or nothing seen: the box's edge
    let aside: Vec<[f64; 2]> = vec![[2.8, 0.45]];
    let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &aside, 0.4, &|_| true).unwrap();
    assert!((p.x_m - (2.5 - 0.6)).abs() < 1e-6, "{p:?}");
    // a point outside the box (0.1 m short of it) is not the object's
    // edge: never beyond the box
    let p = approach_pose(&t, [0.0, 0.0], 0.6, 0.6, &[[2.45, 0.0]], 0.3, &|_| true).unwrap();
    assert!((p.x_m - (2.5 - 0.6)).abs() < 1e-6, "{p:?}");
}

#[test]
fn the_outline_is_the_footprint_where_it_holds_the_centre_else_the_upright_box() {
    let center_m = [3.0, 1.0, 0.4];
    let size_m = [1.2, 0.8, 0.8];
    let turned = OrientedBox {
        center_m: [3.05, 1.0, 0.4],
        size_m: [1.0, 0.5, 0.8],
        yaw_rad: 0.3,
    };
    assert_eq!(outline(center_m, size_m, &turned), turned);
    // a footprint of a part seen up close, off the centre: the upright box
    let part = OrientedBox {
        center_m: [3.5, 1.3, 0.4],
        size_m: [0.2, 0.2, 0.8],
        yaw_rad: 0.3,
    };
    let upright = outline(center_m, size_m, &part);
    assert_eq!(upright.yaw_rad, 0.0);
    assert_eq!(upright.center_m, center_m);
    assert_eq!(upright.size_m, size_m);
    // 0.5 m beyond the upright box's +x side
    assert!((upright.ground_distance_m([4.1, 1.0]) - 0.5).abs() < 1e-12);
}
