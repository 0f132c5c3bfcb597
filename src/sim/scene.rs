//! Seeded apartments for the closed-loop benchmark: 1–4 rooms in a row,
//! doorways 0.80–1.00 m wide in the walls between them, furniture of the
//! perception vocabulary against the walls (a table with chairs), clutter
//! and low objects, the chair's start pose in free space and the word to
//! ask for. Pure: the same seed gives the same scene, on any machine and
//! with any number of jobs (the generator is SplitMix64, written here so
//! that no dependency's change of algorithm can change a scene).

use crate::msg::Pose2;

use super::room::{Pit, Room, SimObject};
use super::world::Walker;

/// SplitMix64: small, fast, and fixed.
#[derive(Debug, Clone)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Uniform in 0..n (n > 0).
    pub fn below(&mut self, n: usize) -> usize {
        ((self.unit() * n as f64) as usize).min(n.saturating_sub(1))
    }

    pub fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }
}

/// Scene `k`'s own seed from the run's seed: any scene can be re-run alone.
pub fn scene_seed(seed: u64, k: u64) -> u64 {
    SplitMix64::new(seed ^ k.wrapping_mul(0xD1B5_4A32_D192_ED03)).next_u64()
}

/// Wall thickness, m, and height.
pub const WALL_M: f64 = 0.1;
const WALL_HEIGHT_M: f64 = 2.5;
/// Doorway widths, m.
pub const DOOR_MIN_M: f64 = 0.80;
pub const DOOR_MAX_M: f64 = 1.00;
/// Kept free in front of each side of a doorway, m.
const DOOR_APRON_M: f64 = 1.0;
/// Gap kept between pieces of furniture, m.
const GAP_M: f64 = 0.05;
/// The start pose keeps this far from every box, m (the chair's footprint
/// reaches 0.55 m ahead of base_link and 0.45 m behind).
pub const START_CLEARANCE_M: f64 = 0.75;
/// The start pose is at least this far from every object of the word, m
/// (a trip, not a chair already there).
pub const START_TO_TARGET_M: f64 = 1.5;

/// The label of the boxes that make walls between rooms.
pub const WALL_LABEL: &str = "wall";
/// The label of a person walking across a room (never the word asked for;
/// not in the yardstick's way: a person steps aside).
pub const WALKER_LABEL: &str = "person";
/// How often a scene has a step down against a wall, a sunken last room
/// (the word only there: unreachable by construction), a person walking.
const STEP_DOWN_CHANCE: f64 = 0.2;
const SUNKEN_ROOM_CHANCE: f64 = 0.08;
const WALKER_CHANCE: f64 = 0.25;

/// A kind of furniture: label, Replica class id, footprint range (x, y)
/// and height, m, and whether it stands against a wall.
struct Kind {
    label: &'static str,
    label_id: i64,
    size_m: ([f64; 2], [f64; 2], f64),
    color: [u8; 3],
}

const FURNITURE: [Kind; 8] = [
    Kind {
        label: "sofa",
        label_id: 36,
        size_m: ([1.6, 2.2], [0.8, 1.0], 0.8),
        color: [150, 60, 50],
    },
    Kind {
        label: "bed",
        label_id: 2,
        size_m: ([1.9, 2.1], [1.0, 1.6], 0.5),
        color: [220, 220, 230],
    },
    Kind {
        label: "cabinet",
        label_id: 12,
        size_m: ([0.5, 1.2], [0.4, 0.6], 1.8),
        color: [200, 180, 140],
    },
    Kind {
        label: "desk",
        label_id: 39,
        size_m: ([1.0, 1.4], [0.6, 0.8], 0.75),
        color: [130, 100, 60],
    },
    Kind {
        label: "bookshelf",
        label_id: 12,
        size_m: ([0.8, 1.2], [0.3, 0.4], 1.9),
        color: [160, 120, 80],
    },
    Kind {
        label: "tv",
        label_id: 42,
        size_m: ([1.0, 1.4], [0.3, 0.45], 1.2),
        color: [20, 20, 25],
    },
    Kind {
        label: "toilet",
        label_id: 45,
        size_m: ([0.4, 0.45], [0.65, 0.75], 0.8),
        color: [240, 240, 240],
    },
    Kind {
        label: "sink",
        label_id: 45,
        size_m: ([0.5, 0.7], [0.45, 0.55], 0.9),
        color: [235, 235, 235],
    },
];

/// Clutter and low things the lasers' plane (0.3 m) does not cut.
const CLUTTER: [Kind; 3] = [
    Kind {
        label: "box",
        label_id: 9,
        size_m: ([0.3, 0.5], [0.3, 0.5], 0.2),
        color: [180, 140, 60],
    },
    Kind {
        label: "bin",
        label_id: 4,
        size_m: ([0.3, 0.35], [0.3, 0.35], 0.45),
        color: [90, 90, 90],
    },
    Kind {
        label: "footstool",
        label_id: 9,
        size_m: ([0.4, 0.5], [0.4, 0.5], 0.25),
        color: [100, 80, 140],
    },
];

/// One generated scene.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub seed: u64,
    pub room: Room,
    /// Rooms along x: each room's [x0, x1) (walls between them).
    pub rooms_x_m: Vec<[f64; 2]>,
    /// Each internal wall's doorway: (wall x, y from, y to).
    pub doorways: Vec<(f64, f64, f64)>,
    pub start: Pose2,
    /// The word the person asks for (an object of the scene).
    pub prompt: String,
    /// People walking across a room (their boxes are in `room.objects`).
    pub walkers: Vec<Walker>,
    /// The last room lies a step down and holds the only objects of the
    /// word: no place beside one can be reached.
    pub sunken_room: bool,
}

impl Scene {
    /// What the scene is, for an engineer reading a failed trip against
    /// its picture and log (`opennav sim --describe`): scene `index`'s
    /// seed and word, the chair's start and every box, step down,
    /// doorway and walking person in the scene's frame (the apartment's
    /// corner at the origin, x along its rooms; metres, radians). The
    /// trip's odom frame is the start pose: a pose `p` logged in odom
    /// lies at `start_world ∘ p` here.
    pub fn describe(&self, index: u64) -> serde_json::Value {
        // the standing boxes: a walking person's box moves (their way
        // is given apart)
        let objects: Vec<serde_json::Value> = self
            .room
            .objects
            .iter()
            .enumerate()
            .filter(|(i, _)| !self.walkers.iter().any(|w| w.object == *i))
            .map(|(_, o)| serde_json::json!({"label": o.label, "min_m": o.min_m, "max_m": o.max_m}))
            .collect();
        serde_json::json!({
            "scene": index,
            "seed": self.seed,
            "prompt": self.prompt,
            "size_m": self.room.size_m,
            "start_world": {
                "x_m": self.start.x_m,
                "y_m": self.start.y_m,
                "theta_rad": self.start.theta_rad,
            },
            "rooms_x_m": self.rooms_x_m,
            "doorways": self
                .doorways
                .iter()
                .map(|(x, y0, y1)| serde_json::json!({"x_m": x, "y_from_m": y0, "y_to_m": y1}))
                .collect::<Vec<_>>(),
            "objects": objects,
            "steps_down": self
                .room
                .pits
                .iter()
                .map(|p| serde_json::json!({"min_m": p.min_m, "max_m": p.max_m, "depth_m": p.depth_m}))
                .collect::<Vec<_>>(),
            "people_walking": self
                .walkers
                .iter()
                .map(|w| serde_json::json!({"from_m": w.from_m, "to_m": w.to_m, "speed_mps": w.speed_mps, "size_m": w.size_m}))
                .collect::<Vec<_>>(),
            "sunken_room": self.sunken_room,
        })
    }
}

fn overlaps(a: &SimObject, b: &SimObject, gap: f64) -> bool {
    a.min_m[0] < b.max_m[0] + gap
        && b.min_m[0] < a.max_m[0] + gap
        && a.min_m[1] < b.max_m[1] + gap
        && b.min_m[1] < a.max_m[1] + gap
}

/// Distance from (x, y) to the nearest box or outer wall of `room`, m.
pub fn clearance_at(room: &Room, x: f64, y: f64) -> f64 {
    let [sx, sy, _] = room.size_m;
    let walls = x.min(sx - x).min(y).min(sy - y);
    let pits = room.pits.iter().map(|p| {
        let dx = (p.min_m[0] - x).max(x - p.max_m[0]).max(0.0);
        let dy = (p.min_m[1] - y).max(y - p.max_m[1]).max(0.0);
        (dx * dx + dy * dy).sqrt()
    });
    room.objects
        .iter()
        .filter(|o| o.label != WALKER_LABEL)
        .map(|o| distance_to_box(x, y, o))
        .chain(pits)
        .fold(walls, f64::min)
}

/// Distance from a point to a box's footprint, m (0 inside).
pub fn distance_to_box(x: f64, y: f64, o: &SimObject) -> f64 {
    let dx = (o.min_m[0] - x).max(x - o.max_m[0]).max(0.0);
    let dy = (o.min_m[1] - y).max(y - o.max_m[1]).max(0.0);
    // (no overflow to guard against here: a plain root is several times
    // quicker than hypot, and this runs for every box at every step)
    (dx * dx + dy * dy).sqrt()
}

/// The scene for `seed`.
pub fn generate(seed: u64) -> Scene {
    let mut rng = SplitMix64::new(seed);
    let n_rooms = 1 + rng.below(4);
    let depth = rng.range(3.5, 5.0);
    let mut rooms_x_m = Vec::with_capacity(n_rooms);
    let mut x = 0.0;
    for i in 0..n_rooms {
        let w = rng.range(3.0, 4.5);
        rooms_x_m.push([x, x + w]);
        x += w;
        if i + 1 < n_rooms {
            x += WALL_M;
        }
    }
    let size_x = x;
    let mut objects: Vec<SimObject> = Vec::new();
    let mut doorways = Vec::new();
    // the walls between rooms, each with a doorway
    for r in rooms_x_m.iter().take(n_rooms - 1) {
        let wx = r[1];
        let width = rng.range(DOOR_MIN_M, DOOR_MAX_M);
        let y0 = rng.range(0.4, depth - 0.4 - width);
        doorways.push((wx, y0, y0 + width));
        let wall = |y_from: f64, y_to: f64| SimObject {
            label_id: 0,
            label: WALL_LABEL.into(),
            min_m: [wx, y_from, 0.0],
            max_m: [wx + WALL_M, y_to, WALL_HEIGHT_M],
            color: [235, 230, 220],
        };
        objects.push(wall(0.0, y0));
        objects.push(wall(y0 + width, depth));
    }
    // the aprons in front of the doorways stay free
    let aprons: Vec<SimObject> = doorways
        .iter()
        .map(|&(wx, y0, y1)| SimObject {
            label_id: -1,
            label: String::new(),
            min_m: [wx - DOOR_APRON_M, y0 - 0.2, 0.0],
            max_m: [wx + WALL_M + DOOR_APRON_M, y1 + 0.2, 0.0],
            color: [0, 0, 0],
        })
        .collect();
    let n_walls = objects.len();
    // furniture against the walls, room by room
    for r in &rooms_x_m {
        let pieces = 2 + rng.below(3);
        for _ in 0..pieces {
            let k = &FURNITURE[rng.below(FURNITURE.len())];
            place_against_wall(&mut rng, k, *r, depth, &aprons, &mut objects);
        }
        // sometimes a table with chairs, in the open
        if rng.chance(0.6) {
            place_table_with_chairs(&mut rng, *r, depth, &aprons, &mut objects);
        }
        // clutter
        for _ in 0..rng.below(3) {
            let k = &CLUTTER[rng.below(CLUTTER.len())];
            place_anywhere(&mut rng, k, *r, depth, &aprons, &mut objects);
        }
    }
    let mut pits = Vec::new();
    // sometimes a step down against a wall (a sunken corner, a stairwell)
    if rng.chance(STEP_DOWN_CHANCE) {
        let r = rooms_x_m[rng.below(n_rooms)];
        for _ in 0..20 {
            let (w, d) = (rng.range(0.8, 1.6), rng.range(0.8, 1.4));
            let x0 = rng.range(r[0], (r[1] - w).max(r[0]));
            let y0 = if rng.chance(0.5) { 0.0 } else { depth - d };
            let area = SimObject {
                label_id: -1,
                label: String::new(),
                min_m: [x0, y0, 0.0],
                max_m: [(x0 + w).min(r[1]), y0 + d, 0.0],
                color: [0, 0, 0],
            };
            if fits(&area, &aprons, &objects) {
                pits.push(Pit {
                    min_m: [area.min_m[0], area.min_m[1]],
                    max_m: [area.max_m[0], area.max_m[1]],
                    depth_m: rng.range(0.1, 0.3),
                });
                break;
            }
        }
    }
    // the word: an object of the scene (a wall or clutter is not asked for)
    let askable = |objects: &[SimObject], within: Option<[f64; 2]>| -> Vec<String> {
        objects[n_walls..]
            .iter()
            .filter(|o| !CLUTTER.iter().any(|c| c.label == o.label))
            .filter(|o| within.is_none_or(|r| o.min_m[0] >= r[0] && o.max_m[0] <= r[1]))
            .map(|o| o.label.clone())
            .collect()
    };
    // sometimes the last room lies a step down, and only it has the word
    let last = rooms_x_m[n_rooms - 1];
    let only_there: Vec<String> = askable(&objects, Some(last))
        .into_iter()
        .filter(|l| {
            !objects[n_walls..]
                .iter()
                .any(|o| &o.label == l && o.max_m[0] <= last[0])
        })
        .collect();
    let sunken_room = n_rooms >= 2 && !only_there.is_empty() && rng.chance(SUNKEN_ROOM_CHANCE);
    let prompt = if sunken_room {
        let depth_m = rng.range(0.15, 0.3);
        pits.retain(|p| p.max_m[0] <= last[0]);
        pits.push(Pit {
            min_m: [last[0], 0.0],
            max_m: [last[1], depth],
            depth_m,
        });
        // the furniture down there stands on its floor
        for o in objects[n_walls..]
            .iter_mut()
            .filter(|o| o.min_m[0] >= last[0])
        {
            o.min_m[2] = -depth_m;
        }
        only_there[rng.below(only_there.len())].clone()
    } else {
        let all = askable(&objects, None);
        if all.is_empty() {
            "chair".to_string()
        } else {
            all[rng.below(all.len())].clone()
        }
    };
    let mut room = Room {
        size_m: [size_x, depth, 2.8],
        objects,
        pits,
    };
    let start = free_pose(
        &mut rng,
        &mut room,
        n_walls,
        &prompt,
        &rooms_x_m,
        sunken_room,
    );
    // sometimes a person walks to and fro across a room
    let mut walkers = Vec::new();
    if rng.chance(WALKER_CHANCE) {
        let r = rooms_x_m[rng.below(n_rooms)];
        for _ in 0..60 {
            let x0 = rng.range(r[0] + 0.3, r[1] - 0.75);
            let length = rng.range(1.5, depth - 0.6);
            let ya = rng.range(0.3, depth - 0.3 - length);
            let lane = SimObject {
                label_id: 0,
                label: WALKER_LABEL.into(),
                min_m: [x0, ya, 0.0],
                max_m: [x0 + 0.45, ya + length, 1.7],
                color: [200, 120, 90],
            };
            let on_pit = room.pits.iter().any(|p| {
                lane.min_m[0] < p.max_m[0]
                    && p.min_m[0] < lane.max_m[0]
                    && lane.min_m[1] < p.max_m[1]
                    && p.min_m[1] < lane.max_m[1]
            });
            let start_gap = distance_to_box(start.x_m, start.y_m, &lane);
            if !on_pit && start_gap > START_CLEARANCE_M && fits(&lane, &[], &room.objects) {
                let y0 = rng.range(ya, ya + length - 0.3);
                walkers.push(Walker {
                    object: room.objects.len(),
                    from_m: [x0, ya],
                    to_m: [x0, ya + length - 0.3],
                    speed_mps: rng.range(0.4, 0.8),
                    size_m: [0.45, 0.3, 1.7],
                });
                room.objects.push(SimObject {
                    min_m: [x0, y0, 0.0],
                    max_m: [x0 + 0.45, y0 + 0.3, 1.7],
                    ..lane
                });
                break;
            }
        }
    }
    Scene {
        seed,
        room,
        rooms_x_m,
        doorways,
        start,
        prompt,
        walkers,
        sunken_room,
    }
}

fn fits(o: &SimObject, aprons: &[SimObject], objects: &[SimObject]) -> bool {
    !aprons.iter().any(|a| overlaps(o, a, 0.0)) && !objects.iter().any(|b| overlaps(o, b, GAP_M))
}

fn boxed(k: &Kind, min: [f64; 2], size: [f64; 2], height: f64) -> SimObject {
    SimObject {
        label_id: k.label_id,
        label: k.label.into(),
        min_m: [min[0], min[1], 0.0],
        max_m: [min[0] + size[0], min[1] + size[1], height],
        color: k.color,
    }
}

/// Against one of the room's walls (its long side along the wall); a few
/// tries, then left out.
fn place_against_wall(
    rng: &mut SplitMix64,
    k: &Kind,
    r: [f64; 2],
    depth: f64,
    aprons: &[SimObject],
    objects: &mut Vec<SimObject>,
) {
    let (sx, sy, h) = k.size_m;
    for _ in 0..20 {
        let (long, short) = (rng.range(sx[0], sx[1]), rng.range(sy[0], sy[1]));
        let wall = rng.below(4);
        let (min, size) = match wall {
            // y = 0 and y = depth: long side along x
            0 | 1 => {
                let x0 = rng.range(r[0] + GAP_M, (r[1] - long - GAP_M).max(r[0] + GAP_M));
                let y0 = if wall == 0 {
                    GAP_M
                } else {
                    depth - short - GAP_M
                };
                ([x0, y0], [long, short])
            }
            // the room's side walls: long side along y
            _ => {
                let y0 = rng.range(GAP_M, (depth - long - GAP_M).max(GAP_M));
                let x0 = if wall == 2 {
                    r[0] + GAP_M
                } else {
                    r[1] - short - GAP_M
                };
                ([x0, y0], [short, long])
            }
        };
        let o = boxed(k, min, size, h);
        if o.max_m[0] <= r[1] && o.max_m[1] <= depth && fits(&o, aprons, objects) {
            objects.push(o);
            return;
        }
    }
}

/// A table in the open with two to four chairs around it.
fn place_table_with_chairs(
    rng: &mut SplitMix64,
    r: [f64; 2],
    depth: f64,
    aprons: &[SimObject],
    objects: &mut Vec<SimObject>,
) {
    let table = Kind {
        label: "table",
        label_id: 39,
        size_m: ([0.8, 1.4], [0.8, 1.0], 0.75),
        color: [120, 90, 40],
    };
    let chair = Kind {
        label: "chair",
        label_id: 14,
        size_m: ([0.45, 0.5], [0.45, 0.5], 0.9),
        color: [40, 120, 160],
    };
    for _ in 0..20 {
        let (w, d) = (rng.range(0.8, 1.4), rng.range(0.8, 1.0));
        // room for chairs (0.5 m) and a way round (0.9 m) on every side
        let margin = 1.4;
        if r[1] - r[0] < w + 2.0 * margin || depth < d + 2.0 * margin {
            return;
        }
        let x0 = rng.range(r[0] + margin, r[1] - margin - w);
        let y0 = rng.range(margin, depth - margin - d);
        let t = boxed(&table, [x0, y0], [w, d], 0.75);
        let mut chairs = vec![
            boxed(&chair, [x0 + w / 2.0 - 0.25, y0 - 0.55], [0.5, 0.5], 0.9),
            boxed(
                &chair,
                [x0 + w / 2.0 - 0.25, y0 + d + 0.05],
                [0.5, 0.5],
                0.9,
            ),
            boxed(&chair, [x0 - 0.55, y0 + d / 2.0 - 0.25], [0.5, 0.5], 0.9),
            boxed(
                &chair,
                [x0 + w + 0.05, y0 + d / 2.0 - 0.25],
                [0.5, 0.5],
                0.9,
            ),
        ];
        chairs.truncate(2 + rng.below(3));
        let all_fit = fits(&t, aprons, objects) && chairs.iter().all(|c| fits(c, aprons, objects));
        if all_fit {
            objects.push(t);
            objects.extend(chairs);
            return;
        }
    }
}

/// Anywhere in the room (clutter).
fn place_anywhere(
    rng: &mut SplitMix64,
    k: &Kind,
    r: [f64; 2],
    depth: f64,
    aprons: &[SimObject],
    objects: &mut Vec<SimObject>,
) {
    let (sx, sy, h) = k.size_m;
    for _ in 0..20 {
        let size = [rng.range(sx[0], sx[1]), rng.range(sy[0], sy[1])];
        let min = [
            rng.range(r[0] + GAP_M, r[1] - size[0] - GAP_M),
            rng.range(GAP_M, depth - size[1] - GAP_M),
        ];
        let o = boxed(k, min, size, h);
        if fits(&o, aprons, objects) {
            objects.push(o);
            return;
        }
    }
}

/// A start pose at least `START_CLEARANCE_M` from every box and the outer
/// walls and `START_TO_TARGET_M` from the word's objects, facing
/// anywhere; in a room too full for one, the last pieces
/// placed (never a wall, never the last of the prompted word) go until
/// there is.
fn free_pose(
    rng: &mut SplitMix64,
    room: &mut Room,
    n_walls: usize,
    prompt: &str,
    rooms_x_m: &[[f64; 2]],
    sunken_room: bool,
) -> Pose2 {
    let [sx, sy, _] = room.size_m;
    // on the upper floor, before the sunken room
    let sx = match rooms_x_m.last() {
        Some(last) if sunken_room => last[0] - WALL_M,
        _ => sx,
    };
    let mut keep_away = true;
    loop {
        for _ in 0..1000 {
            let (x, y) = (rng.range(0.0, sx), rng.range(0.0, sy));
            let clear = clearance_at(room, x, y);
            let theta_rad = rng.range(-std::f64::consts::PI, std::f64::consts::PI);
            let away = !keep_away
                || room
                    .objects
                    .iter()
                    .filter(|o| o.label == prompt)
                    .all(|o| distance_to_box(x, y, o) >= START_TO_TARGET_M);
            if clear >= START_CLEARANCE_M && away {
                return Pose2 {
                    x_m: x,
                    y_m: y,
                    theta_rad,
                };
            }
        }
        let prompted = room.objects.iter().filter(|o| o.label == prompt).count();
        let removable = (n_walls..room.objects.len())
            .rev()
            .find(|&i| room.objects[i].label != prompt || prompted > 1);
        match removable {
            Some(i) => {
                room.objects.remove(i);
            }
            // only walls and the one prompted object, and no place far
            // from it: a small room; closer, then
            None if keep_away => keep_away = false,
            // the apartment is at least 3 m wide: not reached
            None => {
                return Pose2 {
                    x_m: sx / 2.0,
                    y_m: sy / 2.0,
                    theta_rad: 0.0,
                }
            }
        }
    }
}

#[cfg(test)]
#[path = "scene_tests.rs"]
mod tests;
