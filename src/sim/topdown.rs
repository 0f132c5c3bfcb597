//! A top-down picture of one trip: the floor plan (walls, furniture, low
//! objects, steps down), the objects of the word, a walking person where
//! they ended over the line they walk, the chair's start, its path and
//! where it ended, and a caption. Pure: the picture from the
//! world; the caller writes it.

use crate::msg::{ImageError, RgbImage};
use crate::output::{draw_text, put};

use super::world::SimWorld;

/// Pixels per metre.
const PX_PER_M: f64 = 60.0;
/// Margin around the floor, px, and the caption's height.
const MARGIN_PX: usize = 12;
const CAPTION_PX: usize = 24;

const FLOOR: [u8; 3] = [245, 245, 240];
const WALL: [u8; 3] = [60, 60, 60];
const FURNITURE: [u8; 3] = [150, 150, 160];
const LOW: [u8; 3] = [205, 185, 150];
const PIT: [u8; 3] = [40, 60, 140];
const TARGET: [u8; 3] = [40, 170, 60];
const PATH: [u8; 3] = [215, 40, 40];
const START: [u8; 3] = [30, 110, 220];
const PERSON: [u8; 3] = [160, 60, 170];
const PERSON_WAY: [u8; 3] = [215, 175, 220];
const TEXT: [u8; 3] = [0, 0, 0];

/// The picture of `world` (its trace and its chair where it is now),
/// `target`: the word whose objects are drawn green, `caption`: a line.
pub fn render(world: &SimWorld, target: &str, caption: &str) -> Result<RgbImage, ImageError> {
    let [sx, sy, _] = world.room.size_m;
    let w = (sx * PX_PER_M).ceil() as usize + 2 * MARGIN_PX;
    let h = (sy * PX_PER_M).ceil() as usize + 2 * MARGIN_PX + CAPTION_PX;
    let mut img = RgbImage::new(w, h, vec![255; w * h * 3])?;
    // world (x right, y up) → pixel (u right, v down)
    let px = |p: [f64; 2]| -> (f64, f64) {
        (
            MARGIN_PX as f64 + p[0] * PX_PER_M,
            (h - MARGIN_PX) as f64 - p[1] * PX_PER_M,
        )
    };
    let fill = |img: &mut RgbImage, lo: [f64; 2], hi: [f64; 2], c: [u8; 3]| {
        let (u0, v1) = px(lo);
        let (u1, v0) = px(hi);
        for v in v0.round().max(0.0) as usize..v1.round().max(0.0) as usize {
            for u in u0.round().max(0.0) as usize..u1.round().max(0.0) as usize {
                put(img, u, v, c);
            }
        }
    };
    fill(&mut img, [0.0, 0.0], [sx, sy], FLOOR);
    for pit in &world.room.pits {
        fill(&mut img, pit.min_m, pit.max_m, PIT);
    }
    for o in &world.room.objects {
        let c = if o.label.eq_ignore_ascii_case(target) {
            TARGET
        } else if o.label == super::scene::WALL_LABEL {
            WALL
        } else if o.max_m[2] < 0.3 {
            LOW
        } else {
            FURNITURE
        };
        fill(
            &mut img,
            [o.min_m[0], o.min_m[1]],
            [o.max_m[0], o.max_m[1]],
            c,
        );
    }
    // a walking person where they were at the end, over the line they
    // walk to and fro (drawn after the line, below)
    let people: Vec<[[f64; 2]; 4]> = world
        .walkers
        .iter()
        .filter_map(|walking| {
            let w = &walking.walker;
            let o = world.room.objects.get(w.object)?;
            let mid = |p: [f64; 2]| [p[0] + w.size_m[0] / 2.0, p[1] + w.size_m[1] / 2.0];
            Some([
                mid(w.from_m),
                mid(w.to_m),
                [o.min_m[0], o.min_m[1]],
                [o.max_m[0], o.max_m[1]],
            ])
        })
        .collect();
    // the outer walls
    for t in 0..3 {
        let (u0, v1) = px([0.0, 0.0]);
        let (u1, v0) = px([sx, sy]);
        let (u0, v0, u1, v1) = (
            u0 as usize - t,
            v0 as usize - t,
            u1 as usize + t,
            v1 as usize + t,
        );
        for u in u0..=u1 {
            put(&mut img, u, v0, WALL);
            put(&mut img, u, v1, WALL);
        }
        for v in v0..=v1 {
            put(&mut img, u0, v, WALL);
            put(&mut img, u1, v, WALL);
        }
    }
    let line = |img: &mut RgbImage, a: [f64; 2], b: [f64; 2], c: [u8; 3], thick: i64| {
        let (pa, pb) = (px(a), px(b));
        let n = ((pb.0 - pa.0).hypot(pb.1 - pa.1).ceil() as usize).max(1);
        for i in 0..=n {
            let t = i as f64 / n as f64;
            let (u, v) = (pa.0 + t * (pb.0 - pa.0), pa.1 + t * (pb.1 - pa.1));
            for du in -thick / 2..=thick / 2 {
                for dv in -thick / 2..=thick / 2 {
                    let (uu, vv) = (u.round() as i64 + du, v.round() as i64 + dv);
                    if uu >= 0 && vv >= 0 {
                        put(img, uu as usize, vv as usize, c);
                    }
                }
            }
        }
    };
    for &[from, to, lo, hi] in &people {
        line(&mut img, from, to, PERSON_WAY, 1);
        fill(&mut img, lo, hi, PERSON);
    }
    // the start: the chair's heading as an arrow from a dot
    let s = world.start;
    let tip = [
        s.x_m + 0.4 * s.theta_rad.cos(),
        s.y_m + 0.4 * s.theta_rad.sin(),
    ];
    line(&mut img, [s.x_m, s.y_m], tip, START, 3);
    line(
        &mut img,
        [s.x_m - 0.05, s.y_m],
        [s.x_m + 0.05, s.y_m],
        START,
        7,
    );
    for pair in world.trace.windows(2) {
        line(&mut img, pair[0], pair[1], PATH, 2);
    }
    // the chair where it ended: its footprint's outline
    for p in world.outline_world() {
        line(&mut img, p, p, PATH, 1);
    }
    draw_text(&mut img, MARGIN_PX, 4, caption, TEXT);
    Ok(img)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimation::odometry::DiffDriveParams;
    use crate::msg::Pose2;

    /// The picture's colour at the floor point `p` (world, m).
    fn colour_at(img: &RgbImage, p: [f64; 2]) -> [u8; 3] {
        let u = MARGIN_PX + (p[0] * PX_PER_M) as usize;
        let v = img.height() - MARGIN_PX - (p[1] * PX_PER_M) as usize;
        let i = (v * img.width() + u) * 3;
        [img.data()[i], img.data()[i + 1], img.data()[i + 2]]
    }

    #[test]
    fn the_picture_shows_the_floor_the_target_and_the_start() {
        let scene = super::super::scene::generate(7);
        let world = SimWorld::in_room(
            scene.room.clone(),
            scene.start,
            DiffDriveParams::paper_chair(),
        );
        let img = render(&world, &scene.prompt, "scene 7").expect("a picture");
        let at = |p: [f64; 2]| colour_at(&img, p);
        let target = scene
            .room
            .objects
            .iter()
            .find(|o| o.label == scene.prompt)
            .expect("the word's object");
        let mid = [
            (target.min_m[0] + target.max_m[0]) / 2.0,
            (target.min_m[1] + target.max_m[1]) / 2.0,
        ];
        assert_eq!(at(mid), TARGET);
        let Pose2 { x_m, y_m, .. } = scene.start;
        assert_eq!(at([x_m, y_m]), START);
    }

    /// A walking person is drawn apart from the furniture, where they are.
    #[test]
    fn the_picture_shows_a_walking_person_where_they_are() {
        let scene = (0..200)
            .map(super::super::scene::generate)
            .find(|s| !s.walkers.is_empty())
            .expect("a scene with a person walking");
        let mut world = SimWorld::in_room(
            scene.room.clone(),
            scene.start,
            DiffDriveParams::paper_chair(),
        );
        world.walkers = scene
            .walkers
            .iter()
            .map(|w| super::super::world::Walking::new(w.clone()))
            .collect();
        let img = render(&world, &scene.prompt, "a person").expect("a picture");
        let at = |p: [f64; 2]| colour_at(&img, p);
        let o = &scene.room.objects[scene.walkers[0].object];
        let mid = [
            (o.min_m[0] + o.max_m[0]) / 2.0,
            (o.min_m[1] + o.max_m[1]) / 2.0,
        ];
        assert_eq!(at(mid), PERSON);
    }
}
