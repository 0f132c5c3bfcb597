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

use crate::msg::{floor_fast, is_valid_depth, DepthImage, Intrinsics};

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
    /// The highest of the obstacle points in each point's cell, m (one
    /// per point of `obstacles_base`; empty: not known): with the lowest,
    /// whether the thing seen there spans the lasers' plane.
    pub obstacle_tops_m: Vec<f32>,
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
    let (i, j) = (floor_fast(x / cell_m), floor_fast(y / cell_m));
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
                match &mut run {
                    Some((k, rc, e)) if *k == kind && *rc == c => e.add([at.0, at.1], p.z),
                    _ => {
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
    let keep_with_height = |m: BTreeMap<Cell, Extremes>| -> (Vec<[f32; 3]>, Vec<f32>) {
        let mut out = Vec::with_capacity(m.len() * 2);
        let mut tops = Vec::with_capacity(m.len() * 2);
        let mut cell = Vec::with_capacity(4);
        for e in m.into_values().filter(|e| e.count >= s.min_hits.max(1)) {
            cell.clear();
            e.points_into(&mut cell);
            let z = e.low_z_m as f32;
            out.extend(cell.iter().map(|p| [p[0], p[1], z]));
            tops.extend(cell.iter().map(|_| e.high_z_m as f32));
        }
        (out, tops)
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
    let (obstacles_base, obstacle_tops_m) = keep_with_height(obstacles);
    DepthScan {
        obstacles_base,
        obstacle_tops_m,
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
/// the lowest and highest heights among its points.
#[derive(Debug, Clone, Copy, Default)]
struct Extremes {
    count: usize,
    /// min x, max x, min y, max y
    points: [[f64; 2]; 4],
    low_z_m: f64,
    high_z_m: f64,
}

impl Extremes {
    fn add(&mut self, p: [f64; 2], z_m: f64) {
        if self.count == 0 {
            self.points = [p; 4];
            self.low_z_m = z_m;
            self.high_z_m = z_m;
        } else {
            self.low_z_m = self.low_z_m.min(z_m);
            self.high_z_m = self.high_z_m.max(z_m);
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
        self.high_z_m = self.high_z_m.max(later.high_z_m);
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
#[path = "depth_obstacles_tests.rs"]
mod tests;
