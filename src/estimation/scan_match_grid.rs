//! The scan matcher's nearest-point searches (pure): the reference's
//! points on a dense grid searched in rings of cells, and per cell the
//! points that can be the nearest to some place in it.

/// Reference points bucketed on a dense grid (counting sort: each cell's
/// points are contiguous, in index order), for fixed-radius nearest
/// neighbours.
#[derive(Clone)]
pub(super) struct Grid {
    pub(super) cell: f64,
    pub(super) origin: [f64; 2],
    nx: usize,
    ny: usize,
    /// Cell `c`'s points are `sorted[starts[c]..starts[c + 1]]`.
    starts: Vec<u32>,
    /// (index in the input, point), cell by cell.
    sorted: Vec<(u32, [f64; 2])>,
    /// Per cell, the Chebyshev distance in cells to the nearest cell with
    /// a point (saturating): a search skips the rings of cells nearer
    /// than that, which are empty.
    empty_rings: Vec<u16>,
}

/// Cells at most; a wider spread of points gets coarser cells (the
/// searches stay exact: they cover their radius whatever the cell).
const MAX_GRID_CELLS: usize = 1 << 20;

impl Grid {
    /// `pts` must be finite.
    pub(super) fn new(pts: &[[f64; 2]], cell: f64) -> Self {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in pts {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if pts.is_empty() {
            (lo, hi) = ([0.0; 2], [0.0; 2]);
        }
        let mut cell = cell;
        let dims = |cell: f64| {
            (
                ((hi[0] - lo[0]) / cell).floor() as usize + 1,
                ((hi[1] - lo[1]) / cell).floor() as usize + 1,
            )
        };
        let (mut nx, mut ny) = dims(cell);
        while nx.saturating_mul(ny) > MAX_GRID_CELLS {
            cell *= 2.0;
            (nx, ny) = dims(cell);
        }
        let key = |p: &[f64; 2]| {
            let ix = (((p[0] - lo[0]) / cell) as usize).min(nx - 1);
            let iy = (((p[1] - lo[1]) / cell) as usize).min(ny - 1);
            iy * nx + ix
        };
        let mut starts = vec![0u32; nx * ny + 1];
        for p in pts {
            starts[key(p) + 1] += 1;
        }
        for c in 0..nx * ny {
            starts[c + 1] += starts[c];
        }
        let mut fill = starts.clone();
        let mut sorted = vec![(0u32, [0.0; 2]); pts.len()];
        for (i, p) in pts.iter().enumerate() {
            let c = key(p);
            sorted[fill[c] as usize] = (i as u32, *p);
            fill[c] += 1;
        }
        let empty_rings = empty_rings(&starts, nx, ny);
        Grid {
            cell,
            origin: lo,
            nx,
            ny,
            starts,
            sorted,
            empty_rings,
        }
    }

    /// Calls `f(index, point, distance²)` for every point within `radius`
    /// of `q` (and a few beyond: the caller checks the distance).
    pub(super) fn for_each_near(
        &self,
        q: &[f64; 2],
        radius: f64,
        mut f: impl FnMut(u32, &[f64; 2], f64),
    ) {
        let cx = (q[0] - self.origin[0]) / self.cell;
        let cy = (q[1] - self.origin[1]) / self.cell;
        let r = radius / self.cell;
        let clamp = |v: f64, n: usize| v.floor().clamp(0.0, n as f64 - 1.0) as usize;
        if cx + r < 0.0 || cy + r < 0.0 || cx - r >= self.nx as f64 || cy - r >= self.ny as f64 {
            return;
        }
        let (x0, x1) = (clamp(cx - r, self.nx), clamp(cx + r, self.nx));
        let (y0, y1) = (clamp(cy - r, self.ny), clamp(cy + r, self.ny));
        for iy in y0..=y1 {
            let row = iy * self.nx;
            let (a, b) = (
                self.starts[row + x0] as usize,
                self.starts[row + x1 + 1] as usize,
            );
            for (i, p) in &self.sorted[a..b] {
                let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
                f(*i, p, d2);
            }
        }
    }

    /// The nearest point within `max_d` of `q`: (index, distance²); ties
    /// go to the lower index. Searches rings of cells outwards and stops
    /// once no farther ring can hold a closer point.
    pub(super) fn nearest(&self, q: &[f64; 2], max_d: f64) -> Option<(usize, f64)> {
        let max_d2 = max_d * max_d;
        let fx = (q[0] - self.origin[0]) / self.cell;
        let fy = (q[1] - self.origin[1]) / self.cell;
        if !(fx.is_finite() && fy.is_finite()) {
            return None;
        }
        let rings = (max_d / self.cell).ceil() as i64 + 1;
        // farther than the search reaches from every cell (and the cell
        // arithmetic below stays far from i64's ends)
        let (nx, ny) = (self.nx as i64, self.ny as i64);
        let far = |f: f64, n: i64| f < -((rings + 1) as f64) || f > (n + rings + 1) as f64;
        if far(fx, nx) || far(fy, ny) {
            return None;
        }
        let (cx, cy) = (fx.floor() as i64, fy.floor() as i64);
        // the first ring that can hold a point: q's cell clamped to the
        // grid is `out` rings away, and the nearest cell with a point is
        // at least its empty rings less that from q (triangle inequality
        // of the Chebyshev distance)
        let (kx, ky) = (cx.clamp(0, nx - 1), cy.clamp(0, ny - 1));
        let out = (cx - kx).abs().max((cy - ky).abs());
        let empty = self.empty_rings[ky as usize * self.nx + kx as usize] as i64;
        let first = out.max(empty - out);
        if first > rings {
            return None;
        }
        let mut best: Option<(u32, f64)> = None;
        let visit = |x0: i64, x1: i64, y: i64, best: &mut Option<(u32, f64)>| {
            let (x0, x1) = (x0.max(0), x1.min(nx - 1));
            if y < 0 || y >= ny || x0 > x1 {
                return;
            }
            let row = y as usize * self.nx;
            let (a, b) = (
                self.starts[row + x0 as usize] as usize,
                self.starts[row + x1 as usize + 1] as usize,
            );
            for (i, p) in &self.sorted[a..b] {
                let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
                if d2 <= max_d2 && best.is_none_or(|(bi, bd)| d2 < bd || (d2 == bd && *i < bi)) {
                    *best = Some((*i, d2));
                }
            }
        };
        for k in first..=rings {
            // the ring of cells at Chebyshev distance k from q's cell
            // (clipped to the grid)
            visit(cx - k, cx + k, cy - k, &mut best);
            if k > 0 {
                visit(cx - k, cx + k, cy + k, &mut best);
                for y in (cy - k + 1)..=(cy + k - 1) {
                    visit(cx - k, cx - k, y, &mut best);
                    visit(cx + k, cx + k, y, &mut best);
                }
            }
            // a point in ring k + 1 is at least k cells away
            if let Some((_, d2)) = best {
                let reach = k as f64 * self.cell;
                if d2 <= reach * reach {
                    break;
                }
            }
        }
        best.map(|(i, d2)| (i as usize, d2))
    }
}

/// Only cells whose middle lies within this of a reference point keep
/// their candidates ([`NearestCache`]); queries farther out search the
/// rings, m.
const CACHE_REACH_M: f64 = 0.3;

/// The cache's cells are the grid's divided by this each way (fewer
/// candidates each, so fewer comparisons a query), or by 2 where that
/// would make more than [`MAX_CACHE_CELLS`] (16 MiB of slots).
const CACHE_DIVISIONS: usize = 3;
const MAX_CACHE_CELLS: usize = 1 << 22;

/// The nearest-point searches of one reference, cell by cell: the first
/// query that falls in a cell gathers every reference point that can be
/// the nearest to some place in that cell, and every later query there
/// (the same walls are matched scan after scan, iteration after
/// iteration) compares only those. The answer is the grid's own
/// ([`Grid::nearest`]): the nearest point, ties to the lower index, None
/// beyond `max_d`.
#[derive(Clone, Default)]
pub(super) struct NearestCache {
    /// Its cells: the grid's divided each way ([`CACHE_DIVISIONS`]), m,
    /// and how many across and down.
    pub(super) cell: f64,
    nx: usize,
    ny: usize,
    /// Per cell: 0 not gathered yet, 1 too far from every point (search
    /// the grid's rings), `k + 2` the candidates `ranges[k]`.
    slot: Vec<u32>,
    pub(super) ranges: Vec<(u32, u32)>,
    candidates: Vec<(u32, [f64; 2])>,
}

impl NearestCache {
    pub(super) fn new(grid: &Grid) -> Self {
        let k = if (grid.nx * grid.ny).saturating_mul(CACHE_DIVISIONS.pow(2)) <= MAX_CACHE_CELLS {
            CACHE_DIVISIONS
        } else {
            2
        };
        let (nx, ny) = (grid.nx * k, grid.ny * k);
        NearestCache {
            cell: grid.cell / k as f64,
            nx,
            ny,
            slot: vec![0; nx * ny],
            ranges: Vec::new(),
            candidates: Vec::new(),
        }
    }

    /// As `grid.nearest(q, max_d)`; `points` are the grid's, in their
    /// order.
    pub(super) fn nearest(
        &mut self,
        grid: &Grid,
        points: &[[f64; 2]],
        q: &[f64; 2],
        max_d: f64,
    ) -> Option<(usize, f64)> {
        let fx = (q[0] - grid.origin[0]) / self.cell;
        let fy = (q[1] - grid.origin[1]) / self.cell;
        // (NaN fails these too)
        if !(fx >= 0.0 && fy >= 0.0 && fx < self.nx as f64 && fy < self.ny as f64) {
            return grid.nearest(q, max_d);
        }
        let (ix, iy) = (fx as usize, fy as usize);
        let c = iy * self.nx + ix;
        if self.slot[c] == 0 {
            self.slot[c] = self.gather(grid, points, ix, iy);
        }
        let (a, b) = match self.slot[c] {
            1 => return grid.nearest(q, max_d),
            k => self.ranges[k as usize - 2],
        };
        // the candidates are in index order: the first of the nearest is
        // the lowest index, and it is the answer when within `max_d`
        let (mut best_i, mut best_d2) = (u32::MAX, f64::INFINITY);
        for (i, p) in &self.candidates[a as usize..b as usize] {
            let d2 = (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2);
            if d2 < best_d2 {
                (best_i, best_d2) = (*i, d2);
            }
        }
        (best_i != u32::MAX && best_d2 <= max_d * max_d).then_some((best_i as usize, best_d2))
    }

    /// Cell (ix, iy)'s slot: its candidates are the points no farther
    /// from the cell than the farthest of its corners from the point
    /// nearest its middle (any place in the cell has that point at most
    /// that far, so its nearest point is at most that far too).
    fn gather(&mut self, grid: &Grid, points: &[[f64; 2]], ix: usize, iy: usize) -> u32 {
        // a hair wider than the cell: a query's cell comes from a
        // division, whose rounding may put it just outside
        const SLACK_M: f64 = 1e-7;
        let x0 = grid.origin[0] + ix as f64 * self.cell - SLACK_M;
        let x1 = grid.origin[0] + (ix + 1) as f64 * self.cell + SLACK_M;
        let y0 = grid.origin[1] + iy as f64 * self.cell - SLACK_M;
        let y1 = grid.origin[1] + (iy + 1) as f64 * self.cell + SLACK_M;
        let mid = [(x0 + x1) / 2.0, (y0 + y1) / 2.0];
        let Some((near, _)) = grid.nearest(&mid, CACHE_REACH_M) else {
            return 1;
        };
        let p = points[near];
        let reach2 = [[x0, y0], [x0, y1], [x1, y0], [x1, y1]]
            .iter()
            .map(|k| (k[0] - p[0]).powi(2) + (k[1] - p[1]).powi(2))
            .fold(0.0, f64::max)
            * (1.0 + 1e-9);
        let half_diag = (x1 - x0).hypot(y1 - y0) / 2.0;
        let start = self.candidates.len() as u32;
        let candidates = &mut self.candidates;
        grid.for_each_near(&mid, reach2.sqrt() + half_diag, |i, q, _| {
            let dx = (x0 - q[0]).max(q[0] - x1).max(0.0);
            let dy = (y0 - q[1]).max(q[1] - y1).max(0.0);
            if dx * dx + dy * dy <= reach2 {
                candidates.push((i, *q));
            }
        });
        // in index order ([`NearestCache::nearest`] takes the first of
        // the nearest)
        self.candidates[start as usize..].sort_unstable_by_key(|c| c.0);
        self.ranges.push((start, self.candidates.len() as u32));
        self.ranges.len() as u32 + 1
    }
}

/// Per cell of an `nx` × `ny` grid whose cell `c` holds
/// `starts[c + 1] - starts[c]` points: the Chebyshev distance in cells to
/// the nearest cell with a point, saturating at `u16::MAX` (two raster
/// passes with the 3×3 neighbourhood, exact for this metric).
fn empty_rings(starts: &[u32], nx: usize, ny: usize) -> Vec<u16> {
    let mut e: Vec<u16> = (0..nx * ny)
        .map(|c| {
            if starts[c + 1] > starts[c] {
                0
            } else {
                u16::MAX
            }
        })
        .collect();
    for y in 0..ny {
        for x in 0..nx {
            let i = y * nx + x;
            let mut v = e[i];
            if x > 0 {
                v = v.min(e[i - 1].saturating_add(1));
            }
            if y > 0 {
                v = v.min(e[i - nx].saturating_add(1));
                if x > 0 {
                    v = v.min(e[i - nx - 1].saturating_add(1));
                }
                if x + 1 < nx {
                    v = v.min(e[i - nx + 1].saturating_add(1));
                }
            }
            e[i] = v;
        }
    }
    for y in (0..ny).rev() {
        for x in (0..nx).rev() {
            let i = y * nx + x;
            let mut v = e[i];
            if x + 1 < nx {
                v = v.min(e[i + 1].saturating_add(1));
            }
            if y + 1 < ny {
                v = v.min(e[i + nx].saturating_add(1));
                if x + 1 < nx {
                    v = v.min(e[i + nx + 1].saturating_add(1));
                }
                if x > 0 {
                    v = v.min(e[i + nx - 1].saturating_add(1));
                }
            }
            e[i] = v;
        }
    }
    e
}
