//! Tests of `navigation::map` (split out to keep it readable).

use super::*;

/// A wall along x = 2 (odom) from y = −6 to 6 with a doorway of
/// `door_m` centred on y = 1, as the camera would report it.
fn wall_with_door(door_m: f64) -> Vec<[f64; 2]> {
    let mut pts = Vec::new();
    let mut y: f64 = -6.0;
    while y <= 6.0 {
        if (y - 1.0).abs() > door_m / 2.0 {
            for dx in [0.0, 0.05] {
                pts.push([2.0 + dx, y]);
            }
        }
        y += 0.02;
    }
    pts
}

#[test]
fn a_path_goes_through_the_middle_of_a_doorway() {
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    map.set_camera(&wall_with_door(0.85), &[]);
    let p = map
        .path([0.0, -2.0], [4.0, -2.0], 0.1)
        .expect("a way through");
    // where it crosses the wall
    let at_wall = p
        .points
        .iter()
        .find(|q| (q[0] - 2.0).abs() < 0.05)
        .expect("crosses x = 2");
    assert!(
        (at_wall[1] - 1.0).abs() <= 0.06,
        "crossed at y = {}",
        at_wall[1]
    );
    // round the wall's end is far longer than the doorway
    assert!(p.length_m < 9.5, "{}", p.length_m);
    // a gap narrower than the chair: round the wall's end
    let mut closed = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    closed.set_camera(&wall_with_door(0.6), &[]);
    let q = closed
        .path([0.0, -2.0], [4.0, -2.0], 0.1)
        .expect("round the wall");
    assert!(
        q.points
            .iter()
            .all(|p| !((p[0] - 2.0).abs() < 0.05 && (p[1] - 1.0).abs() < 0.5)),
        "a 0.6 m gap is not a doorway for a 0.7 m chair"
    );
    assert!(
        q.length_m > p.length_m + 1.0,
        "{} vs {}",
        q.length_m,
        p.length_m
    );
}

#[test]
fn the_carrot_is_ahead_on_the_path() {
    let p = MapPath {
        points: vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [1.0, 2.0]],
        length_m: 3.0,
    };
    assert_eq!(p.carrot([0.0, 0.1], 0.5), Some([0.5, 0.0]));
    assert_eq!(p.carrot([1.0, 0.0], 1.5), Some([1.0, 1.5]));
    assert_eq!(p.carrot([1.0, 1.9], 5.0), Some([1.0, 2.0]));
}

fn ring(range_m: Option<f32>, blind: bool) -> Vec<LaserRay> {
    (0..720)
        .map(|k| {
            let a = k as f32 * std::f32::consts::TAU / 720.0;
            LaserRay {
                origin_m: [0.0, 0.0],
                dir: [a.cos(), a.sin()],
                blind,
                range_m,
            }
        })
        .collect()
}

#[test]
fn rays_clear_space_and_mark_what_they_hit() {
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    let pose = Pose2 {
        x_m: 1.0,
        y_m: 1.0,
        theta_rad: 0.3,
    };
    map.add_scan(pose, &ring(Some(2.0), false));
    let cell = |p| map.cell(p).expect("on the map");
    assert!(map.is_known(cell([1.5, 1.0])) && !map.is_blocked(cell([1.5, 1.0])));
    // the hit, 2 m away (a cell beside, where the ray's end rounds)
    assert!(
        [-0.05, 0.0, 0.05]
            .iter()
            .any(|dy| map.is_blocked(cell([2.99, 1.0 + dy]))),
        "the hit, 2 m away"
    );
    assert!(!map.is_known(cell([4.0, 1.0])), "beyond the hit");
    // by odom point: the same, and nothing off the map is seen
    assert!(map.is_known_at([1.5, 1.0]) && !map.is_known_at([4.0, 1.0]));
    assert!(!map.is_known_at([1e6, 1.0]));
    // blind rays say nothing
    let mut blind = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    blind.add_scan(pose, &ring(None, true));
    assert!(!blind.is_known(blind.cell([1.5, 1.0]).expect("on the map")));
    // nothing in range: free as far as free_range_m
    let mut open = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    open.add_scan(pose, &ring(None, false));
    let far = open.cell([4.5, 1.0]).expect("on the map");
    assert!(open.is_known(far) && !open.is_blocked(far));
}

#[test]
fn the_frontier_is_the_nearest_edge_of_what_was_seen() {
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    // a room seen out to 3 m all round, open on one side: to +x,
    // the rays find nothing within 2.5 m and the rest hit at 3 m
    let rays: Vec<LaserRay> = ring(Some(3.0), false)
        .into_iter()
        .map(|mut r| {
            if r.dir[0] > 0.9 {
                r.range_m = None;
            }
            r
        })
        .collect();
    map.settings = MapSettings {
        free_range_m: 2.5,
        ..Default::default()
    };
    map.add_scan(Pose2::default(), &rays);
    // not looked at by the camera: everywhere is worth a look, the
    // nearest place first
    let near = map
        .frontier([0.0, 0.0], 1.0, 0.5, &[], 1.0)
        .expect("a frontier");
    assert!(near[0].hypot(near[1]) < 1.2, "{near:?}");
    // the camera turned all round: what is left is beyond the seen
    map.look([0.0, 0.0], 0.0, std::f64::consts::PI, 4.0);
    let f = map
        .frontier([0.0, 0.0], 1.0, 0.5, &[], 1.0)
        .expect("a frontier");
    assert!(f[0] > 2.0 && f[1].abs() < 1.2, "{f:?}");
    // once visited, none is left that the chair can reach through seen
    // free space: the nearest beyond it, by a way across unseen space
    let beyond = map
        .frontier([0.0, 0.0], 1.0, 0.5, &[f], 1.5)
        .expect("a frontier beyond what was seen");
    assert!(beyond[0] > 2.5 && beyond[1].abs() < 1.5, "{beyond:?}");
}

#[test]
fn a_room_looked_at_all_round_has_its_frontier_beyond_its_doorway() {
    // walls 3 m all round but for a 0.8 m doorway to +x, seen edge-on:
    // the lasers' rays through it end at 2.9 m
    let rays: Vec<LaserRay> = ring(Some(3.0), false)
        .into_iter()
        .map(|mut r| {
            if r.dir[1].abs() < 0.13 && r.dir[0] > 0.0 {
                r.range_m = None;
            }
            r
        })
        .collect();
    let mut map = GridMap::new(
        MapSettings {
            free_range_m: 2.9,
            ..Default::default()
        },
        [0.0, 0.0],
    );
    map.add_scan(Pose2::default(), &rays);
    map.look([0.0, 0.0], 0.0, std::f64::consts::PI, 4.0);
    // no seen place with 0.8 m of room next to the unseen: the place is
    // beyond the doorway, reached through it
    let f = map
        .frontier([0.0, 0.0], 1.0, 0.8, &[], 1.5)
        .expect("a frontier beyond the doorway");
    assert!(f[0] > 3.0 && f[1].abs() < 0.5, "{f:?}");
    let way = map.path([0.0, 0.0], f, 0.1).expect("a way there");
    assert!(way.length_m < f[0] + 0.5, "{}", way.length_m);
    // closed all round: nowhere left
    let mut closed = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    closed.add_scan(Pose2::default(), &ring(Some(3.0), false));
    closed.look([0.0, 0.0], 0.0, std::f64::consts::PI, 4.0);
    assert_eq!(closed.frontier([0.0, 0.0], 1.0, 0.8, &[], 1.5), None);
}

#[test]
fn the_camera_looks_at_seen_free_cells_up_to_the_first_obstacle() {
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    // a ring of walls 2 m away
    map.add_scan(Pose2::default(), &ring(Some(2.0), false));
    map.look([0.0, 0.0], 0.0, 0.5, 4.0);
    let at = |map: &GridMap, p: [f64; 2]| map.is_looked(map.cell(p).expect("on the map"));
    // ahead, up to and including the wall; not beyond it, not behind
    assert!(at(&map, [1.0, 0.0]) && at(&map, [1.99, 0.0]));
    assert!(!at(&map, [2.5, 0.0]));
    assert!(!at(&map, [-1.0, 0.0]) && !at(&map, [0.0, 1.0]));
    // the view's edge: 0.5 rad either side
    assert!(at(&map, [1.0, 0.5]) && !at(&map, [1.0, 0.6]));
}

#[test]
fn unseen_cells_at_the_camera_do_not_stop_its_look() {
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    // the lasers' rays begin 0.3 m ahead of the camera (the chair's own
    // place, which no laser sees), out to a wall 2 m from the camera
    let rays: Vec<LaserRay> = ring(Some(1.7), false)
        .into_iter()
        .map(|mut r| {
            r.origin_m = [0.3 * r.dir[0], 0.3 * r.dir[1]];
            r
        })
        .collect();
    map.add_scan(Pose2::default(), &rays);
    let at = |map: &GridMap, p: [f64; 2]| map.is_looked(map.cell(p).expect("on the map"));
    assert!(!map.is_known(map.cell([0.1, 0.0]).expect("on the map")));
    map.look([0.0, 0.0], 0.0, 0.5, 4.0);
    assert!(at(&map, [1.0, 0.0]) && at(&map, [1.99, 0.0]));
    // unseen space farther out still ends a ray: a wall with a gap
    let mut gap = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    gap.add_scan(Pose2::default(), &ring(Some(1.0), false));
    gap.look([0.0, 0.0], 0.0, 0.5, 4.0);
    assert!(!gap.is_known(gap.cell([1.5, 0.0]).expect("on the map")));
    assert!(!at(&gap, [1.5, 0.0]));
}

#[test]
fn bearings_left_to_look_at_are_those_the_camera_has_not_swept() {
    let bins = 72;
    // nothing seen: every way is left to look at
    let empty = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    assert!(empty
        .unlooked_bearings([0.0, 0.0], 0.7, 4.0, bins)
        .iter()
        .all(|&b| b));
    // a ring of walls 2 m away, the camera looking along +x ±0.5 rad
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    map.add_scan(Pose2::default(), &ring(Some(2.0), false));
    map.look([0.0, 0.0], 0.0, 0.5, 4.0);
    let left = map.unlooked_bearings([0.0, 0.0], 0.7, 4.0, bins);
    let bearing = |k: usize| crate::msg::wrap_angle(std::f64::consts::TAU * k as f64 / bins as f64);
    for (k, &l) in left.iter().enumerate() {
        let b = bearing(k).abs();
        if b < 0.45 {
            assert!(!l, "bin {k} ({b} rad) was looked along");
        } else if b > 0.55 {
            assert!(l, "bin {k} ({b} rad) was not looked along");
        }
    }
    // the camera turned all round: nothing left
    map.look([0.0, 0.0], 0.0, std::f64::consts::PI, 4.0);
    assert!(map
        .unlooked_bearings([0.0, 0.0], 0.7, 4.0, bins)
        .iter()
        .all(|&b| !b));
    // a looked-at room: nothing left; then a door in it opens (the
    // lasers see floor beyond it, the camera never looked there): its
    // bearing is left
    let rays: Vec<LaserRay> = ring(Some(2.0), false)
        .into_iter()
        .map(|mut r| {
            if r.dir[0] > 0.99 {
                r.range_m = Some(3.5);
            }
            r
        })
        .collect();
    let mut door = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    door.add_scan(Pose2::default(), &ring(Some(2.0), false));
    door.look([0.0, 0.0], 0.0, std::f64::consts::PI, 4.0);
    assert!(!door.unlooked_bearings([0.0, 0.0], 0.7, 4.0, bins)[0]);
    for _ in 0..5 {
        door.add_scan(Pose2::default(), &rays);
    }
    assert!(door.unlooked_bearings([0.0, 0.0], 0.7, 4.0, bins)[0]);
}

#[test]
fn room_to_turn_is_the_nearest_place_clear_all_round() {
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    // a wall 0.5 m to the left (y = 0.5), open elsewhere to 3 m
    let rays: Vec<LaserRay> = ring(Some(3.0), false)
        .into_iter()
        .map(|mut r| {
            if r.dir[1] > 0.2 {
                r.range_m = Some((0.5 / r.dir[1]).min(3.0));
            }
            r
        })
        .collect();
    map.add_scan(Pose2::default(), &rays);
    let p = map.room_to_turn([0.0, 0.0], 0.3, 0.8).expect("a place");
    // 0.8 m from the wall (and no farther than it needs)
    assert!(p[1] <= -0.25 && p[1] >= -0.45, "{p:?}");
    assert!(map.room_to_turn([0.0, 0.0], 0.3, 3.0).is_none());
    // ahead first: the nearest such place within 60 degrees of the
    // heading, whichever way the chair faces along the wall
    for yaw_rad in [0.0, std::f64::consts::PI] {
        let half_rad = std::f64::consts::FRAC_PI_3;
        let q = map
            .room_to_turn_within([0.0, 0.0], 0.3, 0.8, Some((yaw_rad, half_rad)))
            .expect("a place ahead");
        let bearing = crate::msg::wrap_angle(q[1].atan2(q[0]) - yaw_rad);
        assert!(bearing.abs() <= half_rad, "{q:?} facing {yaw_rad}");
        assert!(q[0] * yaw_rad.cos() > 0.1, "{q:?} facing {yaw_rad}");
        assert!(q[1] <= -0.25, "{q:?}");
    }
    // facing the wall, no place with room lies within 60 degrees ahead
    let facing_wall = Some((std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_3));
    assert!(map
        .room_to_turn_within([0.0, 0.0], 0.3, 0.8, facing_wall)
        .is_none());
}

#[test]
fn the_distance_field_is_redone_only_when_a_blocked_cell_changes_and_matches_a_fresh_one() {
    // laser scans from a moving pose and a camera set that changes,
    // shrinks and stays: the field is marked out of date exactly when
    // the blocked cells changed, and after each step the kept field
    // equals one computed from scratch
    let ray = |a: f64, range_m: Option<f32>| LaserRay {
        origin_m: [0.3, 0.0],
        dir: [a.cos() as f32, a.sin() as f32],
        blind: false,
        range_m,
    };
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    let mut redone = 0;
    let mut was_blocked = vec![false; map.dist.len()];
    for step in 0..30 {
        // a new pose every sixth step, the same scan in between
        let at = (step / 6) as f64;
        let pose = Pose2 {
            x_m: 0.1 * at,
            y_m: 0.02 * at,
            theta_rad: 0.05 * at,
        };
        let rays: Vec<LaserRay> = (0..181)
            .map(|j| {
                let a = (j as f64 - 90.0).to_radians();
                let range = if j % 7 == 0 {
                    None
                } else {
                    Some(2.0 + (a * 3.0).sin() as f32)
                };
                ray(a, range)
            })
            .collect();
        map.add_scan(pose, &rays);
        let camera: Vec<[f64; 2]> = match step % 3 {
            0 => wall_with_door(0.85),
            _ => wall_with_door(0.85)[..100].to_vec(),
        };
        map.set_camera(&camera, &[]);
        let blocked: Vec<bool> = (0..map.dist.len()).map(|i| map.is_blocked(i)).collect();
        assert_eq!(map.dist_dirty, blocked != was_blocked, "step {step}");
        was_blocked = blocked;
        redone += usize::from(map.dist_dirty);
        map.update_distances();
        let mut fresh = map.clone();
        fresh.dist = vec![fresh.dist_cap_m; fresh.dist.len()];
        fresh.dist_dirty = true;
        fresh.update_distances();
        assert!(map.dist == fresh.dist, "step {step}");
    }
    // with the same scan and camera set again, some steps changed
    // nothing blocked
    assert!((1..30).contains(&redone), "{redone}");
}

#[test]
fn the_chair_fits_where_a_way_would_pass_and_not_against_a_wall() {
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    map.set_camera(&wall_with_door(0.85), &[]);
    map.update_distances();
    // far from the wall, in the doorway's middle, and off the map
    assert!(map.fits([0.0, -2.0]));
    assert!(map.fits([2.0, 1.0]));
    assert!(map.fits([100.0, 0.0]));
    // against the wall, and on it: the chair's half width does not fit
    assert!(!map.fits([1.8, -2.0]));
    assert!(!map.fits([2.0, -2.0]));
    // as a way through the map has it: none ends against the wall
    assert!(map.path([0.0, -2.0], [1.8, -2.0], 0.1).is_none());
}

#[test]
fn the_distance_field_is_the_cell_by_cell_chamfer_to_the_bit() {
    // the field's passes go a row at a time; the same two passes cell by
    // cell (1 and √2, capped) give every value bit for bit
    let mut map = GridMap::new(MapSettings::default(), [0.0, 0.0]);
    let mut points = wall_with_door(0.85);
    points.extend((0..40).map(|k| [-1.0 + 0.037 * k as f64, 0.8 + 0.011 * k as f64]));
    points.push([-2.5, -2.9]);
    map.set_camera(&points, &[]);
    map.update_distances();
    let (n, cap) = (map.n, map.dist_cap_m);
    let r = map.settings.resolution_m as f32;
    let (d1, d2) = (r, r * std::f32::consts::SQRT_2);
    let reach = (cap / r).ceil() as usize + 1;
    let (x0, y0) = (
        map.seen_lo[0].saturating_sub(reach),
        map.seen_lo[1].saturating_sub(reach),
    );
    let (x1, y1) = (
        (map.seen_hi[0] + reach).min(n - 1),
        (map.seen_hi[1] + reach).min(n - 1),
    );
    let mut want = vec![cap; n * n];
    for y in y0..=y1 {
        for x in x0..=x1 {
            let i = y * n + x;
            want[i] = if map.is_blocked(i) { 0.0 } else { cap };
        }
    }
    for y in y0..=y1 {
        for x in x0..=x1 {
            let i = y * n + x;
            let mut v = want[i];
            if x > x0 {
                v = v.min(want[i - 1] + d1);
            }
            if y > y0 {
                v = v.min(want[i - n] + d1);
                if x > x0 {
                    v = v.min(want[i - n - 1] + d2);
                }
                if x < x1 {
                    v = v.min(want[i - n + 1] + d2);
                }
            }
            want[i] = v;
        }
    }
    for y in (y0..=y1).rev() {
        for x in (x0..=x1).rev() {
            let i = y * n + x;
            let mut v = want[i];
            if x < x1 {
                v = v.min(want[i + 1] + d1);
            }
            if y < y1 {
                v = v.min(want[i + n] + d1);
                if x < x1 {
                    v = v.min(want[i + n + 1] + d2);
                }
                if x > x0 {
                    v = v.min(want[i + n - 1] + d2);
                }
            }
            want[i] = v;
        }
    }
    assert!(want.iter().any(|&d| d > 0.0 && d < cap));
    let differ = (0..n * n)
        .filter(|&i| want[i].to_bits() != map.dist[i].to_bits())
        .count();
    assert_eq!(differ, 0, "cells differing from the cell-by-cell passes");
}

/// The grid walk as first written: a bounds check and an index product
/// per cell.
fn ray_cells_reference(map: &GridMap, o: [f64; 2], d: [f64; 2], len: f64) -> Vec<usize> {
    let mut out = Vec::new();
    let r = map.settings.resolution_m;
    let g = [(o[0] - map.origin_m[0]) / r, (o[1] - map.origin_m[1]) / r];
    let n = map.n as i64;
    if !(g[0].is_finite() && g[1].is_finite() && len.is_finite()) {
        return out;
    }
    let mut c = [g[0].floor() as i64, g[1].floor() as i64];
    let mut step = [0i64; 2];
    let mut t_next = [f64::INFINITY; 2];
    let mut t_delta = [f64::INFINITY; 2];
    for a in 0..2 {
        if d[a] > 0.0 {
            step[a] = 1;
            t_next[a] = ((c[a] as f64 + 1.0) - g[a]) * r / d[a];
            t_delta[a] = r / d[a];
        } else if d[a] < 0.0 {
            step[a] = -1;
            t_next[a] = (g[a] - c[a] as f64) * r / -d[a];
            t_delta[a] = r / -d[a];
        }
    }
    loop {
        if c[0] < 0 || c[1] < 0 || c[0] >= n || c[1] >= n {
            return out;
        }
        out.push(c[1] as usize * map.n + c[0] as usize);
        let a = if t_next[0] < t_next[1] { 0 } else { 1 };
        if t_next[a] > len {
            return out;
        }
        c[a] += step[a];
        t_next[a] += t_delta[a];
    }
}

#[test]
fn a_rays_cells_are_the_grid_walks_to_the_cell_and_stop_at_the_maps_edge() {
    let map = GridMap::new(MapSettings::default(), [0.3, -0.2]);
    let half = map.n as f64 * map.settings.resolution_m / 2.0;
    let mut rng = crate::sim::scene::SplitMix64::new(5);
    let mut cells = Vec::new();
    let mut left_the_map = 0;
    for k in 0..20_000 {
        // from inside the map, near its edges, and off it; along the
        // axes and diagonals too
        let o = [
            0.3 + rng.range(-half - 1.0, half + 1.0),
            -0.2 + rng.range(-half - 1.0, half + 1.0),
        ];
        let a = if k % 10 == 0 {
            (k / 10 % 8) as f64 * std::f64::consts::FRAC_PI_4
        } else {
            rng.range(-3.2, 3.2)
        };
        let d = [a.cos(), a.sin()];
        let len = rng.range(0.0, 6.0);
        map.ray_cells(o, d, len, &mut cells);
        let want = ray_cells_reference(&map, o, d, len);
        assert_eq!(cells, want, "from {o:?} at {a} rad for {len} m");
        let end = [o[0] + d[0] * len, o[1] + d[1] * len];
        left_the_map += usize::from(!cells.is_empty() && map.cell(end).is_none());
    }
    assert!(left_the_map > 100, "{left_the_map}");
    map.ray_cells([f64::NAN, 0.0], [1.0, 0.0], 1.0, &mut cells);
    assert!(cells.is_empty());
}
