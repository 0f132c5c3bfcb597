//! What the lasers miss, from one depth frame: points above the floor and
//! below the chair's height (a box, a bed edge, a footstool under the
//! lasers' 0.66 m plane) and drop-offs — where the floor should be and is
//! not (a step down, a kerb, an open stair). Pure: the depth image, its
//! intrinsics and its pose in `base_link` in; cells on the floor plane of
//! `base_link` out.
//!
//! Each sampled pixel's point in `base_link` (z up, the floor at z = 0):
//! - `floor_band_m < z ≤ max_height_m`: an obstacle at its (x, y);
//! - `z < −drop_min_m`: the ray went through the floor, so the floor is
//!   missing where the ray crosses z = 0 — a drop-off there;
//! - `|z| ≤ floor_band_m`: floor, seen (used to forget what moved away).
//!
//! Pixels without depth are unknown, never free and never a drop-off (a
//! real camera loses depth on shiny or dark floors; treating that as a
//! step would stop the chair for nothing). Points are binned into
//! `cell_m` cells; a cell needs `min_hits` points to count (one noisy
//! pixel is not a box), and stands for its points farthest along ±x and
//! ±y (on the surface, out to its edges).

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Point3};

use crate::msg::{is_valid_depth, DepthImage, Intrinsics};

/// Config `[depth_obstacles]`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct DepthObstacleSettings {
    /// Look at the depth camera at all (false: lasers only, said at start).
    pub enabled: bool,
    /// Every n-th pixel in each direction (count, 1..16).
    pub stride_px: usize,
    /// Points this close to the floor plane are floor (metres, 0.01..0.2).
    pub floor_band_m: f64,
    /// Points higher than this are above the chair (metres, 0.5..2.5).
    pub max_height_m: f64,
    /// Points farther than this, horizontally from base_link, are ignored
    /// (metres, 0.5..6; depth noise grows with range).
    pub max_range_m: f64,
    /// A point this far below the floor plane means the floor is missing
    /// (metres, 0.02..0.5).
    pub drop_min_m: f64,
    /// Cell size on the floor (metres, 0.02..0.2).
    pub cell_m: f64,
    /// Points a cell needs to count (count, 1..100).
    pub min_hits: usize,
    /// Cells are remembered (in odom) while within this distance of the
    /// chair, so what leaves the camera's view near the chair stays an
    /// obstacle (metres, 1..10).
    pub memory_radius_m: f64,
    /// The chair's front edge, ahead of base_link (the daemon's
    /// `safety.front_offset_m`; not a config key): a floor missing in the
    /// image's bottom row may begin anywhere between it and where that
    /// row sees (None: only where the rays cross the floor plane).
    #[serde(skip)]
    pub chair_front_m: Option<f64>,
}

impl Default for DepthObstacleSettings {
    fn default() -> Self {
        DepthObstacleSettings {
            enabled: true,
            stride_px: 2,
            floor_band_m: 0.05,
            max_height_m: 1.5,
            max_range_m: 3.0,
            drop_min_m: 0.06,
            cell_m: 0.05,
            min_hits: 2,
            memory_radius_m: 4.0,
            chair_front_m: None,
        }
    }
}

/// One frame's cells in `base_link`, metres, in cell order: an obstacle
/// or drop-off cell as its points farthest along ±x and ±y (one to four),
/// a floor cell as its centre.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DepthScan {
    /// Obstacle points: x, y and the lowest height of the obstacle points
    /// in their cell (the height at which the cell can be seen at all).
    pub obstacles_base: Vec<[f32; 3]>,
    pub drop_offs_base: Vec<[f32; 2]>,
    /// Where the floor may end out of view, nearer than the image's
    /// bottom row sees through it (`chair_front_m`): drop-offs wherever
    /// the floor was not seen before ([`crate::estimation::obstacle_map`]).
    pub drop_offs_unseen_base: Vec<[f32; 2]>,
    pub floor_base: Vec<[f32; 2]>,
    /// The nearest surface in each block of the frame: what hides what.
    pub nearest: NearestDepth,
}

/// The frame's nearest depth per [`NEAREST_BLOCK_PX`]-pixel block (the
/// sampled pixels above the floor band, metres along the optical axis;
/// infinite where there were none), with the camera that took it: whether
/// an object the tracker remembers is hidden behind something in this
/// frame.
#[derive(Debug, Clone, PartialEq)]
pub struct NearestDepth {
    pub base_from_depth: Isometry3<f64>,
    pub k: Intrinsics,
    pub cols: usize,
    pub rows: usize,
    pub nearest_m: Vec<f32>,
}

/// The blocks of [`NearestDepth`], px.
pub const NEAREST_BLOCK_PX: usize = 16;

/// A surface this much nearer than an object's box (beyond its
/// half-diagonal) hides it, m (depth noise at 5 m is a few centimetres).
pub const HIDES_BY_M: f64 = 0.15;

/// No frame: no blocks, nothing hidden.
impl Default for NearestDepth {
    fn default() -> Self {
        NearestDepth {
            base_from_depth: Isometry3::identity(),
            k: Intrinsics {
                width: 0,
                height: 0,
                fx: 1.0,
                fy: 1.0,
                cx: 0.0,
                cy: 0.0,
            },
            cols: 0,
            rows: 0,
            nearest_m: Vec::new(),
        }
    }
}

impl NearestDepth {
    fn new(k: &Intrinsics, base_from_depth: &Isometry3<f64>, w: usize, h: usize) -> Self {
        let (cols, rows) = (w.div_ceil(NEAREST_BLOCK_PX), h.div_ceil(NEAREST_BLOCK_PX));
        NearestDepth {
            base_from_depth: *base_from_depth,
            k: *k,
            cols,
            rows,
            nearest_m: vec![f32::INFINITY; cols * rows],
        }
    }

    fn add(&mut self, u: usize, v: usize, depth_m: f32) {
        let i = (v / NEAREST_BLOCK_PX) * self.cols + u / NEAREST_BLOCK_PX;
        if let Some(n) = self.nearest_m.get_mut(i) {
            *n = n.min(depth_m);
        }
    }

    /// Whether something in the frame stands in front of a box whose
    /// centre is `center_base` (base_link at the frame's stamp) and whose
    /// half-diagonal is `half_diagonal_m`: the nearest surface in the
    /// block its centre falls in is more than that and [`HIDES_BY_M`]
    /// nearer than the centre. False outside the image or where the block
    /// had no depth.
    pub fn hides(&self, center_base: &[f64; 3], half_diagonal_m: f64) -> bool {
        let q = self.base_from_depth.inverse()
            * Point3::new(center_base[0], center_base[1], center_base[2]);
        if q.z <= 0.0 {
            return false;
        }
        let u = self.k.fx * q.x / q.z + self.k.cx;
        let v = self.k.fy * q.y / q.z + self.k.cy;
        if !(u >= 0.0 && v >= 0.0) {
            return false;
        }
        let (bu, bv) = (u as usize / NEAREST_BLOCK_PX, v as usize / NEAREST_BLOCK_PX);
        if bu >= self.cols || bv >= self.rows {
            return false;
        }
        let nearest = self.nearest_m[bv * self.cols + bu] as f64;
        nearest.is_finite() && nearest < q.z - half_diagonal_m - HIDES_BY_M
    }
}

type Cell = (i32, i32);

fn cell_of(x: f64, y: f64, cell_m: f64) -> Option<Cell> {
    let (i, j) = ((x / cell_m).floor(), (y / cell_m).floor());
    let ok = |v: f64| v.is_finite() && v.abs() < 1e6;
    (ok(i) && ok(j)).then_some((i as i32, j as i32))
}

/// The cells of one depth frame. `base_from_depth` is the depth camera's
/// optical frame (z forward, x right, y down) in `base_link`.
///
/// Where the image's bottom row sees through the floor, the floor's edge
/// lies somewhere between the chair's front and that row's view of the
/// floor plane, out of the camera's view (a chair started, or turned,
/// facing a step down a few decimetres ahead sees only beyond it): with
/// the chair's front known (`chair_front_m`), drop-offs are put along
/// the ray's track on the floor from its crossing back to the front
/// ([`DepthScan::drop_offs_unseen_base`]: where earlier frames saw the
/// floor, it is there).
pub fn scan(
    depth: &DepthImage,
    k: &Intrinsics,
    base_from_depth: &Isometry3<f64>,
    s: &DepthObstacleSettings,
) -> DepthScan {
    let stride = s.stride_px.max(1);
    let origin = base_from_depth.translation.vector;
    // per cell: its points' count and extremes
    // obstacles, drop-offs and floor, by `Kind`
    let mut maps: [BTreeMap<Cell, Extremes>; 3] = Default::default();
    let mut drops_unseen: BTreeMap<Cell, Extremes> = BTreeMap::new();
    let mut run: Option<(Kind, Cell, Extremes)> = None;
    let (w, h) = (depth.width().min(k.width), depth.height().min(k.height));
    let mut nearest = NearestDepth::new(k, base_from_depth, w, h);
    let data = depth.data();
    for v in (0..h).step_by(stride) {
        for u in (0..w).step_by(stride) {
            let d = data[v * depth.width() + u];
            if !is_valid_depth(d) {
                continue;
            }
            let depth_m = d;
            let d = d as f64;
            let p_cam = Point3::new(
                (u as f64 - k.cx) / k.fx * d,
                (v as f64 - k.cy) / k.fy * d,
                d,
            );
            let p = base_from_depth * p_cam;
            // what stands above the floor hides what is behind it, at any
            // range; the floor hides nothing standing on it
            if p.z > s.floor_band_m {
                nearest.add(u, v, depth_m);
            }
            if p.x * p.x + p.y * p.y > s.max_range_m * s.max_range_m {
                continue;
            }
            let (kind, at) = if p.z > s.floor_band_m && p.z <= s.max_height_m {
                (Kind::Obstacle, (p.x, p.y))
            } else if p.z < -s.drop_min_m {
                // where the ray crossed the floor plane
                let dz = origin.z - p.z;
                if origin.z <= 0.0 || dz <= 0.0 {
                    continue;
                }
                let t = origin.z / dz;
                let crossing = (
                    origin.x + t * (p.x - origin.x),
                    origin.y + t * (p.y - origin.y),
                );
                if v + stride >= h {
                    // the image's bottom row: the floor may end anywhere
                    // nearer, out of view
                    if let Some(front_m) = s.chair_front_m {
                        drops_out_of_view(
                            &mut drops_unseen,
                            origin,
                            crossing,
                            front_m,
                            p.z,
                            s.cell_m,
                        );
                    }
                }
                (Kind::Drop, crossing)
            } else if p.z.abs() <= s.floor_band_m {
                (Kind::Floor, (p.x, p.y))
            } else {
                continue;
            };
            if let Some(c) = cell_of(at.0, at.1, s.cell_m) {
                // neighbouring pixels mostly fall in one cell: a run of
                // them is gathered here and put in its map once
                if run.as_ref().is_some_and(|r| r.0 == kind && r.1 == c) {
                    if let Some(r) = run.as_mut() {
                        r.2.add([at.0, at.1], p.z);
                    }
                } else {
                    if let Some((kind, c, e)) = run.take() {
                        maps[kind as usize].entry(c).or_default().merge(&e);
                    }
                    let mut e = Extremes::default();
                    e.add([at.0, at.1], p.z);
                    run = Some((kind, c, e));
                }
            }
        }
    }
    if let Some((kind, c, e)) = run.take() {
        maps[kind as usize].entry(c).or_default().merge(&e);
    }
    let [obstacles, drops, floor] = maps;
    // each cell as its extreme points: on a surface seen at a slant a
    // cell's centre lies up to half its diagonal (3.5 cm) off it, and a
    // mean of its points lies inside an object's edge; the points
    // farthest along ±x and ±y lie on the surface and reach the edge
    let keep = |m: BTreeMap<Cell, Extremes>| -> Vec<[f32; 2]> {
        let mut out = Vec::with_capacity(m.len() * 2);
        for e in m.into_values().filter(|e| e.count >= s.min_hits.max(1)) {
            e.points_into(&mut out);
        }
        out
    };
    let keep_with_height = |m: BTreeMap<Cell, Extremes>| -> Vec<[f32; 3]> {
        let mut out = Vec::with_capacity(m.len() * 2);
        let mut cell = Vec::with_capacity(4);
        for e in m.into_values().filter(|e| e.count >= s.min_hits.max(1)) {
            cell.clear();
            e.points_into(&mut cell);
            let z = e.low_z_m as f32;
            out.extend(cell.iter().map(|p| [p[0], p[1], z]));
        }
        out
    };
    // seen floor only forgets cells: one point (the cell's centre) each
    let floor_cells = |m: BTreeMap<Cell, Extremes>| -> Vec<[f32; 2]> {
        m.into_iter()
            .filter(|(_, e)| e.count >= s.min_hits.max(1))
            .map(|(c, _)| {
                [
                    ((c.0 as f64 + 0.5) * s.cell_m) as f32,
                    ((c.1 as f64 + 0.5) * s.cell_m) as f32,
                ]
            })
            .collect()
    };
    DepthScan {
        obstacles_base: keep_with_height(obstacles),
        drop_offs_base: keep(drops),
        drop_offs_unseen_base: keep(drops_unseen),
        floor_base: floor_cells(floor),
        nearest,
    }
}

/// Which of a frame's maps a point goes to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Obstacle = 0,
    Drop = 1,
    Floor = 2,
}

/// A cell's point count, its points farthest along −x, +x, −y, +y and
/// the lowest height among its points.
#[derive(Debug, Clone, Copy, Default)]
struct Extremes {
    count: usize,
    /// min x, max x, min y, max y
    points: [[f64; 2]; 4],
    low_z_m: f64,
}

impl Extremes {
    fn add(&mut self, p: [f64; 2], z_m: f64) {
        if self.count == 0 {
            self.points = [p; 4];
            self.low_z_m = z_m;
        } else {
            self.low_z_m = self.low_z_m.min(z_m);
            let e = &mut self.points;
            if p[0] < e[0][0] {
                e[0] = p;
            }
            if p[0] > e[1][0] {
                e[1] = p;
            }
            if p[1] < e[2][1] {
                e[2] = p;
            }
            if p[1] > e[3][1] {
                e[3] = p;
            }
        }
        self.count += 1;
    }

    /// As if `later`'s points were added after this one's, one by one
    /// (an extreme tied keeps the earlier point, as `add` does).
    fn merge(&mut self, later: &Extremes) {
        if later.count == 0 {
            return;
        }
        if self.count == 0 {
            *self = *later;
            return;
        }
        self.low_z_m = self.low_z_m.min(later.low_z_m);
        let (e, l) = (&mut self.points, &later.points);
        if l[0][0] < e[0][0] {
            e[0] = l[0];
        }
        if l[1][0] > e[1][0] {
            e[1] = l[1];
        }
        if l[2][1] < e[2][1] {
            e[2] = l[2];
        }
        if l[3][1] > e[3][1] {
            e[3] = l[3];
        }
        self.count += later.count;
    }

    /// The distinct extreme points, appended to `out`.
    fn points_into(&self, out: &mut Vec<[f32; 2]>) {
        let start = out.len();
        for p in self.points {
            let q = [p[0] as f32, p[1] as f32];
            if !out[start..].contains(&q) {
                out.push(q);
            }
        }
    }
}

/// Drop-offs every `cell_m` along the floor track of a bottom-row ray,
/// from its `crossing` of the floor plane back towards the camera's foot
/// (`origin`, base_link), no nearer than `front_m` ahead of base_link.
fn drops_out_of_view(
    drops: &mut BTreeMap<Cell, Extremes>,
    origin: nalgebra::Vector3<f64>,
    crossing: (f64, f64),
    front_m: f64,
    z_m: f64,
    cell_m: f64,
) {
    let (dx, dy) = (origin.x - crossing.0, origin.y - crossing.1);
    let len = dx.hypot(dy);
    if !(len.is_finite() && cell_m > 0.0) {
        return;
    }
    let steps = (len / cell_m).ceil() as usize;
    for k in 1..=steps {
        let f = (k as f64 * cell_m / len).min(1.0);
        let q = (crossing.0 + f * dx, crossing.1 + f * dy);
        if q.0 < front_m {
            break;
        }
        if let Some(c) = cell_of(q.0, q.1, cell_m) {
            drops.entry(c).or_default().add([q.0, q.1], z_m);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion};

    /// The fields of a cell's extremes, to compare them exactly.
    fn fields(e: &Extremes) -> (usize, [[u64; 2]; 4], u64) {
        (
            e.count,
            e.points.map(|p| p.map(f64::to_bits)),
            e.low_z_m.to_bits(),
        )
    }

    #[test]
    fn runs_merged_are_the_points_added_one_by_one() {
        let mut rng = crate::sim::scene::SplitMix64::new(5);
        let mut checked_ties = 0;
        for _ in 0..500 {
            // coarse values: ties on an extreme are frequent
            let n = 1 + rng.below(12);
            let pts: Vec<([f64; 2], f64)> = (0..n)
                .map(|_| {
                    let q = |rng: &mut crate::sim::scene::SplitMix64| rng.below(4) as f64 * 0.01;
                    ([q(&mut rng), q(&mut rng)], q(&mut rng))
                })
                .collect();
            let mut one_by_one = Extremes::default();
            for (p, z) in &pts {
                one_by_one.add(*p, *z);
            }
            // the same points cut into runs at random places
            let mut merged = Extremes::default();
            let mut run = Extremes::default();
            for (p, z) in &pts {
                if rng.chance(0.4) {
                    merged.merge(&run);
                    run = Extremes::default();
                }
                run.add(*p, *z);
            }
            merged.merge(&run);
            merged.merge(&Extremes::default());
            assert_eq!(fields(&merged), fields(&one_by_one), "{pts:?}");
            checked_ties += usize::from(pts.iter().filter(|(p, _)| p[0] == 0.0).count() > 1);
        }
        assert!(checked_ties > 50, "{checked_ties}");
    }

    fn k() -> Intrinsics {
        Intrinsics {
            width: 160,
            height: 120,
            fx: 80.0,
            fy: 80.0,
            cx: 79.5,
            cy: 59.5,
        }
    }

    /// A camera 0.9 m up at base x = 0.3, pitched down by `pitch_deg`.
    fn base_from_camera(pitch_deg: f64) -> Isometry3<f64> {
        let level = Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
        let level = Rotation3::from_matrix_unchecked(level);
        let pitch =
            Rotation3::from_axis_angle(&nalgebra::Vector3::y_axis(), pitch_deg.to_radians());
        Isometry3::from_parts(
            Translation3::new(0.3, 0.0, 0.9),
            UnitQuaternion::from_rotation_matrix(&(pitch * level)),
        )
    }

    /// Renders a floor at height `floor_z(x, y)` (a height field sampled
    /// along each ray) and a box [x0, x1] × [y0, y1] × [0, top].
    fn render(
        t: &Isometry3<f64>,
        floor_z: impl Fn(f64, f64) -> f64,
        boxed: Option<([f64; 4], f64)>,
    ) -> DepthImage {
        let k = k();
        let mut d = vec![0.0f32; k.width * k.height];
        let o = t.translation.vector;
        for v in 0..k.height {
            for u in 0..k.width {
                let dir_cam =
                    nalgebra::Vector3::new((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy, 1.0);
                let dir = t.rotation * dir_cam;
                // march along the ray in optical-z steps of 5 mm
                let mut z = 0.05;
                while z < 6.0 {
                    let p = o + dir * z;
                    let hit_box = boxed.is_some_and(|(b, top)| {
                        p.x >= b[0] && p.x <= b[1] && p.y >= b[2] && p.y <= b[3] && p.z <= top
                    });
                    if hit_box || p.z <= floor_z(p.x, p.y) {
                        d[v * k.width + u] = z as f32;
                        break;
                    }
                    z += 0.005;
                }
            }
        }
        DepthImage::new(k.width, k.height, d).expect("image")
    }

    fn any_in<const N: usize>(cells: &[[f32; N]], x: (f64, f64), y: (f64, f64)) -> bool {
        cells.iter().any(|c| {
            (c[0] as f64) >= x.0
                && (c[0] as f64) <= x.1
                && (c[1] as f64) >= y.0
                && (c[1] as f64) <= y.1
        })
    }

    #[test]
    fn a_flat_floor_is_floor_and_nothing_else() {
        let t = base_from_camera(30.0);
        let s = scan(
            &render(&t, |_, _| 0.0, None),
            &k(),
            &t,
            &DepthObstacleSettings::default(),
        );
        assert!(s.obstacles_base.is_empty(), "{:?}", s.obstacles_base);
        assert!(s.drop_offs_base.is_empty(), "{:?}", s.drop_offs_base);
        assert!(s.floor_base.len() > 100);
    }

    /// A cell reports where its points are: every obstacle point lies on
    /// the box (to the renderer's 5 mm steps), where a cell's centre lies
    /// up to half a cell off it — in front of a face that crosses the
    /// cell, or beside it — and the points reach the box's edges.
    #[test]
    fn obstacle_cells_lie_on_the_box_not_at_cell_centres() {
        let t = base_from_camera(30.0);
        // faces off the 5 cm grid: x 1.535 (the cell 1.50–1.55's centre
        // 1.525 is in front of it), y −0.213 (the cell's centre −0.225
        // beside it)
        let b = [1.535, 1.9, -0.213, 0.187];
        let s = scan(
            &render(&t, |_, _| 0.0, Some((b, 0.3))),
            &k(),
            &t,
            &DepthObstacleSettings {
                // every pixel: the points' spacing well under a centimetre
                stride_px: 1,
                ..DepthObstacleSettings::default()
            },
        );
        assert!(s.obstacles_base.len() > 10, "{:?}", s.obstacles_base);
        for p in &s.obstacles_base {
            let (x, y) = (p[0] as f64, p[1] as f64);
            assert!(
                x >= b[0] - 0.006 && x <= b[1] + 0.006 && y >= b[2] - 0.006 && y <= b[3] + 0.006,
                "{p:?} off the box {b:?}"
            );
        }
        // and reach its edges: the front face and both sides (a cell's
        // mean lies inside an edge by up to half a cell)
        let fold = |f: fn(f64, f64) -> f64, i: usize, from: f64| {
            s.obstacles_base.iter().map(|p| p[i] as f64).fold(from, f)
        };
        let nearest = fold(f64::min, 0, f64::INFINITY);
        let (right, left) = (
            fold(f64::min, 1, f64::INFINITY),
            fold(f64::max, 1, f64::NEG_INFINITY),
        );
        assert!((nearest - b[0]).abs() < 0.01, "{nearest}");
        assert!(
            (right - b[2]).abs() < 0.01 && (left - b[3]).abs() < 0.01,
            "{right} {left}"
        );
    }

    /// A 0.3 m box 1.5–1.9 m ahead, 0.4 m wide, seen by the camera 0.9 m
    /// up and pitched 30° down.
    fn low_box_scan() -> DepthScan {
        let t = base_from_camera(30.0);
        let b = [1.5, 1.9, -0.2, 0.2];
        scan(
            &render(&t, |_, _| 0.0, Some((b, 0.3))),
            &k(),
            &t,
            &DepthObstacleSettings::default(),
        )
    }

    #[test]
    fn a_low_box_under_the_lasers_is_an_obstacle_where_it_stands() {
        let s = low_box_scan();
        assert!(any_in(&s.obstacles_base, (1.45, 1.95), (-0.25, 0.25)));
        // nothing outside the box (its faces, within a cell)
        for c in &s.obstacles_base {
            assert!(
                any_in(&[*c], (1.45, 1.95), (-0.25, 0.25)),
                "obstacle outside the box at {c:?}"
            );
        }
        // each point carries its cell's lowest height: on the box, above
        // the floor band; the front face is seen down to the band's top
        let band = DepthObstacleSettings::default().floor_band_m;
        for c in &s.obstacles_base {
            let z = c[2] as f64;
            assert!(z > band && z <= 0.3 + 1e-6, "height {z} of {c:?}");
        }
        let front_low = s
            .obstacles_base
            .iter()
            .filter(|c| (c[0] as f64) < 1.55)
            .map(|c| c[2] as f64)
            .fold(f64::INFINITY, f64::min);
        assert!(front_low < band + 0.03, "front face lowest {front_low}");
    }

    /// The frame's nearest surfaces: a point behind the box (as the
    /// camera sees it) is hidden, one beside it is not, nor the box's own
    /// centre, nor a point outside the image.
    #[test]
    fn a_nearer_surface_hides_what_is_behind_it() {
        let s = low_box_scan();
        let n = &s.nearest;
        assert!(n.cols > 0 && n.rows > 0);
        // on the line from the camera (0.9 m up) over the box's top edge
        // (1.5, 0, 0.3) on to 2 m ahead, 6 cm up: behind the box
        let (eye, top) = ([0.3, 0.0, 0.9], [1.5, 0.0, 0.3]);
        let behind = [
            eye[0] + 1.4 * (top[0] - eye[0]),
            0.0,
            eye[2] + 1.4 * (top[2] - eye[2]),
        ];
        assert!(n.hides(&behind, 0.2), "{behind:?}");
        // the box itself (its centre 0.2 m behind its front face)
        assert!(!n.hides(&[1.7, 0.0, 0.15], 0.28));
        // beside the box, on the floor's level
        assert!(!n.hides(&[2.25, 1.2, 0.05], 0.2));
        // behind the camera
        assert!(!n.hides(&[-2.0, 0.0, 0.5], 0.2));
        // no frame: nothing is hidden
        assert!(!NearestDepth::default().hides(&behind, 0.2));
    }

    #[test]
    fn a_step_down_is_a_drop_off_at_its_edge() {
        let t = base_from_camera(30.0);
        // the floor drops 0.15 m from x = 2.0 on
        let s = scan(
            &render(&t, |x, _| if x >= 2.0 { -0.15 } else { 0.0 }, None),
            &k(),
            &t,
            &DepthObstacleSettings::default(),
        );
        assert!(!s.drop_offs_base.is_empty());
        for c in &s.drop_offs_base {
            assert!(c[0] >= 1.95, "drop-off before the edge at {c:?}");
        }
        // the first drop-off cells are at the edge
        let nearest = s
            .drop_offs_base
            .iter()
            .map(|c| c[0])
            .fold(f32::INFINITY, f32::min);
        assert!(nearest < 2.15, "nearest drop-off {nearest}");
        assert!(s.obstacles_base.is_empty());
    }

    #[test]
    fn a_step_down_out_of_view_ahead_of_the_chair_is_put_at_its_front() {
        // pitched 30° down, the bottom row sees the floor from x = 0.68 m
        // on; the floor drops 0.25 m from x = 0.62 m, 7 cm ahead of the
        // chair's front (0.55 m), out of the camera's view
        let t = base_from_camera(30.0);
        let step = render(&t, |x, _| if x >= 0.62 { -0.25 } else { 0.0 }, None);
        let nearest = |s: &DepthScan| {
            s.drop_offs_base
                .iter()
                .chain(&s.drop_offs_unseen_base)
                .filter(|c| c[1].abs() < 0.35)
                .map(|c| c[0])
                .fold(f32::INFINITY, f32::min)
        };
        // where the rays cross the floor plane alone: beyond the edge
        let plain = scan(&step, &k(), &t, &DepthObstacleSettings::default());
        assert!(nearest(&plain) > 0.66, "{}", nearest(&plain));
        assert!(plain.drop_offs_unseen_base.is_empty());
        // with the chair's front known: from there on, all across its width
        let front = DepthObstacleSettings {
            chair_front_m: Some(0.55),
            ..DepthObstacleSettings::default()
        };
        let s = scan(&step, &k(), &t, &front);
        let n = nearest(&s);
        assert!((0.55..0.61).contains(&n), "nearest drop-off {n}");
        assert!(s.drop_offs_unseen_base.iter().all(|c| c[0] >= 0.55));
        // (what the rays saw is apart from what may be there)
        assert_eq!(s.drop_offs_base, plain.drop_offs_base);
        for y in [-0.3f64, 0.0, 0.3] {
            assert!(
                any_in(&s.drop_offs_unseen_base, (0.55, 0.62), (y - 0.05, y + 0.05)),
                "none at y = {y}"
            );
        }
        // a step the camera sees, and a flat floor: nothing added
        let seen = scan(
            &render(&t, |x, _| if x >= 2.0 { -0.15 } else { 0.0 }, None),
            &k(),
            &t,
            &front,
        );
        assert!(seen.drop_offs_base.iter().all(|c| c[0] >= 1.95));
        assert!(seen.drop_offs_unseen_base.is_empty());
        let flat = scan(&render(&t, |_, _| 0.0, None), &k(), &t, &front);
        assert!(flat.drop_offs_base.is_empty() && flat.drop_offs_unseen_base.is_empty());
    }

    #[test]
    fn missing_depth_is_unknown_and_single_pixels_do_not_count() {
        let t = base_from_camera(30.0);
        let k = k();
        let mut d = vec![0.0f32; k.width * k.height];
        // one pixel says something stands 0.3 m high 1.5 m ahead
        let p_base = Point3::new(1.5, 0.0, 0.3);
        let p_cam = t.inverse() * p_base;
        let u = (p_cam.x / p_cam.z * k.fx + k.cx).round() as usize;
        let v = (p_cam.y / p_cam.z * k.fy + k.cy).round() as usize;
        let u = u - u % 2;
        let v = v - v % 2;
        d[v * k.width + u] = p_cam.z as f32;
        let img = DepthImage::new(k.width, k.height, d).expect("image");
        let s = scan(&img, &k, &t, &DepthObstacleSettings::default());
        assert!(s.obstacles_base.is_empty() && s.drop_offs_base.is_empty());
        assert!(s.floor_base.is_empty());
        // the one pixel is the only depth its frame had
        let known = s.nearest.nearest_m.iter().filter(|d| d.is_finite());
        assert_eq!(known.count(), 1);
        let one = DepthObstacleSettings {
            min_hits: 1,
            ..Default::default()
        };
        assert_eq!(scan(&img, &k, &t, &one).obstacles_base.len(), 1);
    }
}
