//! A room of labelled boxes: ray-cast RGB-D rendering with an instance
//! buffer, and ground-truth point sampling of its surfaces. Pure: the
//! camera pose and intrinsics come in, images and points come out.
//!
//! World frame: x, y on the floor, z up, metres; the room spans
//! `[0, size]` on each axis. Cameras use the optical convention (z forward,
//! x right, y down) and poses are `world_from_camera`.

use nalgebra::{Isometry3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::msg::Intrinsics;
use crate::msg::{DepthImage, ImageError, RgbImage};

/// A labelled box in the room.
#[derive(Debug, Clone, PartialEq)]
pub struct SimObject {
    /// Class id in the evaluation's class list (Replica: 1..48).
    pub label_id: i64,
    pub label: String,
    pub min_m: [f64; 3],
    pub max_m: [f64; 3],
    pub color: [u8; 3],
}

/// A step down: the floor inside `[min_m, max_m]` (x, y) lies `depth_m`
/// lower, with vertical sides (a sunken area, a stairwell, a kerb).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pit {
    pub min_m: [f64; 2],
    pub max_m: [f64; 2],
    pub depth_m: f64,
}

impl Pit {
    pub fn contains(&self, x: f64, y: f64) -> bool {
        x > self.min_m[0] && x < self.max_m[0] && y > self.min_m[1] && y < self.max_m[1]
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Room {
    pub size_m: [f64; 3],
    pub objects: Vec<SimObject>,
    /// Steps down in the floor (the lasers' plane is above them: only the
    /// depth camera sees them).
    pub pits: Vec<Pit>,
}

/// One rendered view.
#[derive(Debug, Clone)]
pub struct Rendered {
    pub color: RgbImage,
    pub depth: DepthImage,
    /// Object index per pixel, −1 for walls, floor and ceiling.
    pub instance: Vec<i32>,
}

fn obj(label_id: i64, label: &str, min: [f64; 3], size: [f64; 3], color: [u8; 3]) -> SimObject {
    SimObject {
        label_id,
        label: label.into(),
        min_m: min,
        max_m: [min[0] + size[0], min[1] + size[1], min[2] + size[2]],
        color,
    }
}

impl Room {
    /// A 6 × 5 × 2.8 m living room with furniture along the walls (label
    /// ids in Replica's class order).
    pub fn living_room() -> Room {
        Room {
            size_m: [6.0, 5.0, 2.8],
            objects: vec![
                obj(36, "sofa", [0.0, 1.5, 0.0], [0.9, 2.0, 0.8], [150, 60, 50]),
                obj(
                    39,
                    "table",
                    [1.05, 1.9, 0.0],
                    [0.8, 1.2, 0.75],
                    [120, 90, 40],
                ),
                obj(
                    14,
                    "chair",
                    [2.6, 0.3, 0.0],
                    [0.5, 0.5, 0.9],
                    [40, 120, 160],
                ),
                obj(
                    14,
                    "chair",
                    [4.0, 0.3, 0.0],
                    [0.5, 0.5, 0.9],
                    [40, 140, 120],
                ),
                obj(
                    12,
                    "cabinet",
                    [5.5, 0.4, 0.0],
                    [0.5, 1.0, 1.8],
                    [200, 180, 140],
                ),
                obj(2, "bed", [3.8, 3.4, 0.0], [2.0, 1.6, 0.5], [220, 220, 230]),
                obj(9, "box", [5.6, 2.2, 0.0], [0.4, 0.4, 0.3], [180, 140, 60]),
                obj(
                    42,
                    "tv-screen",
                    [2.4, 4.9, 1.0],
                    [1.2, 0.1, 0.7],
                    [20, 20, 25],
                ),
                obj(
                    23,
                    "lamp",
                    [0.3, 4.4, 0.0],
                    [0.3, 0.3, 1.5],
                    [240, 230, 120],
                ),
                obj(4, "bin", [0.0, 0.0, 0.0], [0.35, 0.35, 0.45], [90, 90, 90]),
            ],
            pits: Vec::new(),
        }
    }

    /// `n` camera poses (optical frame in the world) on a circle of radius
    /// `radius_m` about the room's centre at height `height_m`, looking
    /// outward with a 20° downward pitch, turning once around.
    pub fn orbit(&self, n: usize, radius_m: f64, height_m: f64) -> Vec<Isometry3<f64>> {
        let (cx, cy) = (self.size_m[0] / 2.0, self.size_m[1] / 2.0);
        (0..n)
            .map(|i| {
                let yaw = std::f64::consts::TAU * i as f64 / n.max(1) as f64;
                let pos = Vector3::new(
                    cx + radius_m * yaw.cos(),
                    cy + radius_m * yaw.sin(),
                    height_m,
                );
                look_direction(pos, yaw, -20f64.to_radians())
            })
            .collect()
    }

    /// Ray-casts the view: depth is the optical z of the nearest surface.
    pub fn render(
        &self,
        k: &Intrinsics,
        world_from_camera: &Isometry3<f64>,
    ) -> Result<Rendered, ImageError> {
        let (w, h) = (k.width, k.height);
        let mut rgb = vec![0u8; w * h * 3];
        let mut depth = vec![0.0f32; w * h];
        let mut instance = vec![-1i32; w * h];
        let r = world_from_camera.rotation.to_rotation_matrix();
        let o = world_from_camera.translation.vector;
        // the objects in front of the camera, nearest first, with their
        // distance: a ray (|d| ≤ its longest over the image) cannot hit
        // one farther than `distance / |d|` before that
        let forward = r * Vector3::z();
        let mut order: Vec<(f64, usize)> = self
            .objects
            .iter()
            .enumerate()
            .filter(|(_, b)| {
                (0..8).any(|c| {
                    let corner = Vector3::new(
                        if c & 1 == 0 { b.min_m[0] } else { b.max_m[0] },
                        if c & 2 == 0 { b.min_m[1] } else { b.max_m[1] },
                        if c & 4 == 0 { b.min_m[2] } else { b.max_m[2] },
                    );
                    (corner - o).dot(&forward) > 0.0
                })
            })
            .map(|(i, b)| {
                let mut d2 = 0.0;
                for a in 0..3 {
                    let e = (b.min_m[a] - o[a]).max(o[a] - b.max_m[a]).max(0.0);
                    d2 += e * e;
                }
                (d2.sqrt(), i)
            })
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // each object's pixel rectangle: a ray can hit a box only through
        // a pixel inside its corners' projection (all corners in front of
        // the camera; otherwise the whole image), with a pixel's margin
        let camera_from_world = r.transpose();
        // (and the corners' pixels: None where one is not in front)
        let projected: Vec<(PixelRect, Option<[[f64; 2]; 8]>)> = order
            .iter()
            .map(|&(_, idx)| {
                let b = &self.objects[idx];
                let mut rect = PixelRect::EMPTY;
                let mut corners = [[0.0; 2]; 8];
                for (c, px) in corners.iter_mut().enumerate() {
                    let corner = Vector3::new(
                        if c & 1 == 0 { b.min_m[0] } else { b.max_m[0] },
                        if c & 2 == 0 { b.min_m[1] } else { b.max_m[1] },
                        if c & 4 == 0 { b.min_m[2] } else { b.max_m[2] },
                    );
                    let p = camera_from_world * (corner - o);
                    if p.z.is_nan() || p.z <= 1e-6 {
                        return (PixelRect::ALL, None);
                    }
                    *px = [k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy];
                    rect.grow(px[0], px[1]);
                }
                (rect.widened(1.0), Some(corners))
            })
            .collect();
        // per row, the objects whose rectangle spans it, nearest first,
        // each with the columns its corners' convex hull spans there
        let mut row: Vec<Candidate> = Vec::with_capacity(order.len());
        let mut dirs: Vec<Vector3<f64>> = Vec::with_capacity(w);
        let mut t_wall: [Vec<f64>; 3] = std::array::from_fn(|_| Vec::with_capacity(w));
        for v in 0..h {
            row.clear();
            row.extend(
                order
                    .iter()
                    .zip(&projected)
                    .filter(|(_, (rect, _))| (v as f64) >= rect.lo[1] && (v as f64) <= rect.hi[1])
                    .filter_map(|(&(dist_m, idx), (rect, corners))| {
                        let (u_lo, u_hi) = match corners {
                            Some(c) => hull_columns(c, v as f64)?,
                            None => (rect.lo[0], rect.hi[0]),
                        };
                        Some(Candidate {
                            dist_m,
                            idx,
                            u_lo,
                            u_hi,
                        })
                    }),
            );
            // the row's rays, and each one's length to the wall it heads
            // for along each axis: one pass per axis over the row, whose
            // divisions run side by side (one at a time they would wait
            // for each other)
            dirs.clear();
            dirs.extend((0..w).map(|u| {
                r * Vector3::new((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy, 1.0)
            }));
            for (a, t_axis) in t_wall.iter_mut().enumerate() {
                let (size, o_a) = (self.size_m[a], o[a]);
                t_axis.clear();
                t_axis.extend(dirs.iter().map(|d| {
                    let wall = if d[a] > 0.0 { size } else { 0.0 };
                    (wall - o_a) / d[a]
                }));
            }
            for (u, d) in dirs.iter().enumerate() {
                let leave = nearest_wall(d, &[t_wall[0][u], t_wall[1][u], t_wall[2][u]]);
                let (t, face, id) = self.cast_beyond_walls(&o, d, leave, &row, u as f64);
                let i = v * w + u;
                if !t.is_finite() {
                    continue;
                }
                depth[i] = t as f32;
                instance[i] = id;
                let base = if id >= 0 {
                    self.objects[id as usize].color
                } else {
                    match face {
                        2 => [170, 160, 150], // floor / ceiling
                        _ => [205, 200, 190],
                    }
                };
                // simple shading by the face's axis
                let shade = [0.8, 0.9, 1.0][face];
                for c in 0..3 {
                    rgb[i * 3 + c] = (base[c] as f64 * shade) as u8;
                }
            }
        }
        Ok(Rendered {
            color: RgbImage::new(w, h, rgb)?,
            depth: DepthImage::new(w, h, depth)?,
            instance,
        })
    }

    /// Nearest hit along `o + t·d`: (t, axis of the face hit, object index
    /// or −1), among the `candidates` (nearest first) whose pixel columns
    /// hold `u`, the ray's pixel column (the render does the same a row
    /// at a time).
    #[cfg(test)]
    fn cast(
        &self,
        o: &Vector3<f64>,
        d: &Vector3<f64>,
        candidates: &[Candidate],
        u: f64,
    ) -> (f64, usize, i32) {
        let t_wall: [f64; 3] = std::array::from_fn(|a| {
            let wall = if d[a] > 0.0 { self.size_m[a] } else { 0.0 };
            (wall - o[a]) / d[a]
        });
        self.cast_beyond_walls(o, d, nearest_wall(d, &t_wall), candidates, u)
    }

    /// As [`Room::cast`], with where the ray leaves the room from inside
    /// found already (`leave`: t and axis, by [`nearest_wall`]).
    fn cast_beyond_walls(
        &self,
        o: &Vector3<f64>,
        d: &Vector3<f64>,
        leave: (f64, usize),
        candidates: &[Candidate],
        u: f64,
    ) -> (f64, usize, i32) {
        let d_norm = d.norm();
        let mut best = (leave.0, leave.1, -1i32);
        // the floor hit inside a pit: on through its open top to the pit's
        // floor or one of its sides
        if best.1 == 2 && d.z < 0.0 && best.0.is_finite() {
            let hit = o + d * best.0;
            if let Some(pit) = self.pits.iter().find(|p| p.contains(hit.x, hit.y)) {
                let lo = [pit.min_m[0], pit.min_m[1], -pit.depth_m];
                let hi = [pit.max_m[0], pit.max_m[1], 0.0];
                let mut exit = (f64::INFINITY, 2usize);
                for a in 0..3 {
                    if d[a].abs() < 1e-12 {
                        continue;
                    }
                    let bound = if d[a] > 0.0 { hi[a] } else { lo[a] };
                    let t = (bound - o[a]) / d[a];
                    if t > best.0 && t < exit.0 {
                        exit = (t, a);
                    }
                }
                if exit.0.is_finite() {
                    best = (exit.0, exit.1, -1);
                }
            }
        }
        // the axes the ray runs along (not parallel to their faces)
        let along: [bool; 3] = std::array::from_fn(|a| d[a].abs() >= 1e-12);
        for c in candidates {
            if c.dist_m >= best.0 * d_norm {
                break;
            }
            if !(u >= c.u_lo && u <= c.u_hi) {
                continue;
            }
            let idx = c.idx;
            let ob = &self.objects[idx];
            // the slabs' entry and exit, all three axes without branches
            // (the entry only grows and the exit only shrinks, so a miss
            // at any axis is a miss at the end)
            // (the six divisions side by side: one at a time they would
            // wait for each other)
            let ta: [f64; 3] = std::array::from_fn(|a| (ob.min_m[a] - o[a]) / d[a]);
            let tb: [f64; 3] = std::array::from_fn(|a| (ob.max_m[a] - o[a]) / d[a]);
            let (mut t0, mut t1, mut axis) = (0.0f64, f64::INFINITY, 0usize);
            let mut inside = true;
            for a in 0..3 {
                if !along[a] {
                    inside &= o[a] >= ob.min_m[a] && o[a] <= ob.max_m[a];
                    continue;
                }
                // (finite: the nearer face's the smaller along d, the
                // division rounding monotonically)
                let (lo, hi) = if d[a] > 0.0 {
                    (ta[a], tb[a])
                } else {
                    (tb[a], ta[a])
                };
                let enters_later = lo > t0;
                t0 = if enters_later { lo } else { t0 };
                axis = if enters_later { a } else { axis };
                t1 = if hi < t1 { hi } else { t1 };
            }
            let hit = inside && t0 <= t1;
            if hit && t0 > 0.0 && t0 < best.0 {
                best = (t0, axis, idx as i32);
            }
        }
        best
    }

    /// Ground-truth points, as a reconstructed mesh has them: the objects'
    /// faces every `spacing_m` except those lying on the floor or against a
    /// wall (no camera sees them), labelled `(sem, inst)` = (class id,
    /// object index); the room's walls, floor and ceiling every
    /// `4·spacing_m`, labelled void (sem 0, inst −100).
    pub fn ground_truth_cloud(&self, spacing_m: f64) -> Vec<(Point3<f32>, i64, i64)> {
        let mut out = Vec::new();
        for (idx, ob) in self.objects.iter().enumerate() {
            let hidden: [[bool; 2]; 3] = std::array::from_fn(|a| {
                [ob.min_m[a] <= 1e-9, ob.max_m[a] >= self.size_m[a] - 1e-9]
            });
            for p in box_surface(ob.min_m, ob.max_m, spacing_m, hidden) {
                out.push((p, ob.label_id, idx as i64));
            }
        }
        for p in box_surface([0.0; 3], self.size_m, 4.0 * spacing_m, [[false; 2]; 3]) {
            out.push((p, 0, -100));
        }
        out
    }
}

/// Optical-frame pose at `pos` looking along `yaw` (about z) with `pitch`
/// (negative = down).
pub fn look_direction(pos: Vector3<f64>, yaw: f64, pitch: f64) -> Isometry3<f64> {
    let fwd = Vector3::new(
        yaw.cos() * pitch.cos(),
        yaw.sin() * pitch.cos(),
        pitch.sin(),
    );
    let right = Vector3::new(yaw.sin(), -yaw.cos(), 0.0);
    let down = fwd.cross(&right);
    // columns: optical x (right), y (down), z (forward) in the world
    let m = nalgebra::Matrix3::from_columns(&[right, down, fwd]);
    let rot = Rotation3::from_matrix_unchecked(m);
    Isometry3::from_parts(
        Translation3::from(pos),
        UnitQuaternion::from_rotation_matrix(&rot),
    )
}

/// Points on the faces of a box every `s`; `hidden[axis][0 = min, 1 = max]` skips a face.
fn box_surface(min: [f64; 3], max: [f64; 3], s: f64, hidden: [[bool; 2]; 3]) -> Vec<Point3<f32>> {
    let mut out = Vec::new();
    let steps = |lo: f64, hi: f64| -> Vec<f64> {
        let n = ((hi - lo) / s).round().max(1.0) as usize;
        (0..=n)
            .map(|i| lo + (hi - lo) * i as f64 / n as f64)
            .collect()
    };
    for a in 0..3 {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        for (side, val) in [(0, min[a]), (1, max[a])] {
            if hidden[a][side] {
                continue;
            }
            for &x in &steps(min[b], max[b]) {
                for &y in &steps(min[c], max[c]) {
                    let mut p = [0.0; 3];
                    p[a] = val;
                    p[b] = x;
                    p[c] = y;
                    out.push(Point3::new(p[0] as f32, p[1] as f32, p[2] as f32));
                }
            }
        }
    }
    out
}

/// Where a ray along `d` leaves the room from inside, from each axis's
/// `t_wall` (the ray's length to that axis's wall it heads for): (t,
/// axis), the nearest in front; (∞, 2) for none. Chosen without branches
/// (which way a pixel's ray leaves changes from pixel to pixel: a branch
/// there is mispredicted often).
fn nearest_wall(d: &Vector3<f64>, t_wall: &[f64; 3]) -> (f64, usize) {
    let mut best = (f64::INFINITY, 2usize);
    for (a, &t) in t_wall.iter().enumerate() {
        let take = d[a].abs() >= 1e-12 && t > 0.0 && t < best.0;
        best.0 = if take { t } else { best.0 };
        best.1 = if take { a } else { best.1 };
    }
    best
}

/// The pixel columns, a pixel's margin about them, that the convex hull
/// of `corners` (pixels) spans in the band of rows `v` ± 1; None where it
/// does not reach the band. A ray through pixel (u, v) can hit a box only
/// where its corners' hull holds (u, v): the margin covers the rounding
/// of the projection.
fn hull_columns(corners: &[[f64; 2]; 8], v: f64) -> Option<(f64, f64)> {
    let (top, bottom) = (v - 1.0, v + 1.0);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    // the hull's extent in a band is reached at a corner inside it or
    // where an edge crosses one of its bounds (every segment between two
    // corners lies in the hull, and the hull's edges are among them)
    for (i, a) in corners.iter().enumerate() {
        if a[1] >= top && a[1] <= bottom {
            lo = lo.min(a[0]);
            hi = hi.max(a[0]);
        }
        for b in &corners[i + 1..] {
            for bound in [top, bottom] {
                if (a[1] - bound) * (b[1] - bound) < 0.0 {
                    let u = a[0] + (bound - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
                    lo = lo.min(u);
                    hi = hi.max(u);
                }
            }
        }
    }
    (lo <= hi).then_some((lo - 1.0, hi + 1.0))
}

/// An object a ray may hit: its distance from the camera (no ray with
/// |d| ≤ 1 hits it before `dist_m`), its index, and the pixel columns its
/// rectangle spans (bounds included).
#[derive(Debug, Clone, Copy)]
struct Candidate {
    dist_m: f64,
    idx: usize,
    u_lo: f64,
    u_hi: f64,
}

/// A rectangle of pixel coordinates (u, v), bounds included.
#[derive(Debug, Clone, Copy)]
struct PixelRect {
    lo: [f64; 2],
    hi: [f64; 2],
}

impl PixelRect {
    const EMPTY: PixelRect = PixelRect {
        lo: [f64::INFINITY; 2],
        hi: [f64::NEG_INFINITY; 2],
    };
    const ALL: PixelRect = PixelRect {
        lo: [f64::NEG_INFINITY; 2],
        hi: [f64::INFINITY; 2],
    };

    fn grow(&mut self, u: f64, v: f64) {
        self.lo = [self.lo[0].min(u), self.lo[1].min(v)];
        self.hi = [self.hi[0].max(u), self.hi[1].max(v)];
    }

    fn widened(self, by: f64) -> PixelRect {
        PixelRect {
            lo: [self.lo[0] - by, self.lo[1] - by],
            hi: [self.hi[0] + by, self.hi[1] + by],
        }
    }
}

#[cfg(test)]
#[path = "room_tests.rs"]
mod tests;
