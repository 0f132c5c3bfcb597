//! Step 6's one pass over an object's points: their axis-aligned bounds
//! and the extreme points along eight ground directions (the oriented
//! box's hull starts from them), eight points at a time.

use nalgebra::Point3;
use wide::{f32x4, f32x8};

use super::boxes::Aabb;

/// One pass over the points: their axis-aligned bounds and, along each of
/// eight ground directions (counter-clockwise from +x: +x, +(x+y), +y,
/// +(y−x), −x, −(x+y), −y, +(x−y)), the first point furthest that way.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Sweep {
    pub(crate) min: [f32; 3],
    pub(crate) max: [f32; 3],
    pub(crate) extreme: [[f32; 2]; 8],
}

impl Sweep {
    pub(crate) fn of(points: &[Point3<f32>]) -> Option<Sweep> {
        Self::of_lanes(points, &ground_lanes(points)).0
    }

    /// [`of`](Self::of) with the points' [`ground_lanes`] made already;
    /// with the sweep's blocks (see [`Ground`]).
    pub(crate) fn of_lanes(
        points: &[Point3<f32>],
        lanes: &[[f32x8; 2]],
    ) -> (Option<Sweep>, Vec<[f32x4; 8]>) {
        let mut sweep = SweepLanes::new(Vec::new());
        let block_points = SWEEP_LANES * BLOCK_VECTORS;
        for (b, block_lanes) in points.chunks(block_points).zip(lanes.chunks(BLOCK_VECTORS)) {
            let mut block = BlockValues::EMPTY;
            for (c, xy) in b.chunks(SWEEP_LANES).zip(block_lanes) {
                let z = f32x8::new(std::array::from_fn(|l| c.get(l).map_or(f32::NAN, |p| p.z)));
                block.add(xy[0], xy[1], z);
            }
            sweep.add_block(block);
        }
        sweep.finish(lanes)
    }

    pub(crate) fn aabb(&self) -> Aabb {
        Aabb {
            min_m: self.min.map(f64::from),
            max_m: self.max.map(f64::from),
        }
    }
}

/// The points' ground coordinates (x, y), eight at a time in their order
/// (NaN past the end).
pub(crate) fn ground_lanes(points: &[Point3<f32>]) -> Vec<[f32x8; 2]> {
    points.chunks(SWEEP_LANES).map(ground_lanes_of).collect()
}

/// Up to eight points' ground coordinates as lanes (x, y), NaN past the
/// end.
fn ground_lanes_of(chunk: &[Point3<f32>]) -> [f32x8; 2] {
    let lane = |k: usize| {
        f32x8::new(std::array::from_fn(|l| {
            chunk.get(l).map_or(f32::NAN, |p| p[k])
        }))
    };
    [lane(0), lane(1)]
}

/// Points a [`SweepLanes`] takes at once.
pub(crate) const SWEEP_LANES: usize = 8;

/// Vectors of [`SWEEP_LANES`] points in one block of a [`SweepLanes`].
pub(crate) const BLOCK_VECTORS: usize = 8;

/// An object's points' ground coordinates as a [`SweepLanes`] took them:
/// `lanes`, (x, y) eight at a time in the points' order, a lane that is
/// no point NaN in both; `blocks`, what the sweep kept of each block of
/// [`BLOCK_VECTORS`] vectors (greatest values along x, x+y, y and y−x,
/// then least, each over the lanes of both halves of a vector that four
/// lanes keep).
#[derive(Clone, Copy)]
pub(crate) struct Ground<'a> {
    pub(crate) lanes: &'a [[f32x8; 2]],
    pub(crate) blocks: &'a [[f32x4; 8]],
}

impl Ground<'_> {
    /// Block `b`'s lanes.
    pub(crate) fn block_lanes(&self, b: usize) -> &[[f32x8; 2]] {
        let from = (b * BLOCK_VECTORS).min(self.lanes.len());
        let to = (from + BLOCK_VECTORS).min(self.lanes.len());
        &self.lanes[from..to]
    }

    /// The bounds of block `b`'s points, [x_min, x_max, y_min, y_max];
    /// None when it has none.
    pub(crate) fn block_bounds(&self, b: usize) -> Option<[f32; 4]> {
        let values = self.blocks.get(b)?;
        let x_max = greatest(values[0]);
        let x_min = least(values[4]);
        let y_max = greatest(values[2]);
        let y_min = least(values[6]);
        (x_min <= x_max && y_min <= y_max).then_some([x_min, x_max, y_min, y_max])
    }
}

/// The values along the four ground directions x, x+y, y and y−x of eight
/// points (the negative directions are their least values: −x−y is
/// exactly −(x+y) in floating point).
#[inline(always)]
fn directions(x: f32x8, y: f32x8) -> [f32x8; 4] {
    [x, x + y, y, y - x]
}

/// The greatest of the lanes, the first lane's of equal ones (−∞ when
/// every lane is NaN or −∞).
fn greatest(v: f32x4) -> f32 {
    v.to_array()
        .into_iter()
        .fold(f32::NEG_INFINITY, |m, x| if x > m { x } else { m })
}

/// The least of the lanes, the first lane's of equal ones (+∞ when every
/// lane is NaN or +∞).
fn least(v: f32x4) -> f32 {
    v.to_array()
        .into_iter()
        .fold(f32::INFINITY, |m, x| if x < m { x } else { m })
}

/// Eight lanes as their two halves of four.
#[inline(always)]
fn halves(v: f32x8) -> [f32x4; 2] {
    bytemuck::cast(v)
}

/// `s > acc ? s : acc` lane by lane: a NaN in `s` (no point) keeps `acc`,
/// as does a tie. On x86-64 one instruction: MAXPS returns its second
/// operand unless the first is greater, which `fast_max(s, acc)` is.
#[inline(always)]
fn raise(s: f32x4, acc: f32x4) -> f32x4 {
    #[cfg(target_arch = "x86_64")]
    {
        s.fast_max(acc)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        s.simd_gt(acc).select(s, acc)
    }
}

/// `s < acc ? s : acc` lane by lane (see [`raise`]).
#[inline(always)]
fn lower(s: f32x4, acc: f32x4) -> f32x4 {
    #[cfg(target_arch = "x86_64")]
    {
        s.fast_min(acc)
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        s.simd_lt(acc).select(s, acc)
    }
}

/// [`raise`] by both halves of eight lanes.
#[inline(always)]
fn raise8(s: f32x8, acc: f32x4) -> f32x4 {
    let [a, b] = halves(s);
    raise(b, raise(a, acc))
}

/// [`lower`] by both halves of eight lanes.
#[inline(always)]
fn lower8(s: f32x8, acc: f32x4) -> f32x4 {
    let [a, b] = halves(s);
    lower(b, lower(a, acc))
}

/// One block's values while it is filled: four lanes keeping the
/// greatest and least value of both halves' lanes along x, x+y, y and y−x,
/// and the z bounds (a compare-and-keep per value, no index; four lanes, so
/// that a loop filling a block keeps them all in the registers of a plain
/// x86-64).
#[derive(Clone, Copy)]
pub(crate) struct BlockValues {
    hi: [f32x4; 4],
    lo: [f32x4; 4],
    z_min: f32x4,
    z_max: f32x4,
}

impl BlockValues {
    /// No point yet.
    pub(crate) const EMPTY: BlockValues = BlockValues {
        hi: [f32x4::splat(f32::NEG_INFINITY); 4],
        lo: [f32x4::splat(f32::INFINITY); 4],
        z_min: f32x4::splat(f32::INFINITY),
        z_max: f32x4::splat(f32::NEG_INFINITY),
    };

    /// The next eight points (finite coordinates). A lane whose
    /// coordinates are NaN is no point: NaN is neither greater nor less
    /// than anything.
    #[inline(always)]
    pub(crate) fn add(&mut self, x: f32x8, y: f32x8, z: f32x8) {
        for (d, s) in directions(x, y).into_iter().enumerate() {
            self.hi[d] = raise8(s, self.hi[d]);
            self.lo[d] = lower8(s, self.lo[d]);
        }
        self.z_min = lower8(z, self.z_min);
        self.z_max = raise8(z, self.z_max);
    }
}

/// A [`Sweep`] made a block of [`BLOCK_VECTORS`] vectors of
/// [`SWEEP_LANES`] points at a time ([`BlockValues`]: each block filled
/// apart, its values in registers). Each block's
/// values are kept as well, so that [`finish`](Self::finish) finds the
/// first point holding each extreme by looking into the first block that
/// holds it — the first point furthest, as a point-by-point sweep finds
/// it. The x and y bounds are the extremes along x and y.
pub(crate) struct SweepLanes {
    all: BlockValues,
    /// Each block's values: greatest along the four directions, then
    /// least.
    blocks: Vec<[f32x4; 8]>,
}

impl SweepLanes {
    /// An empty sweep keeping its blocks in `blocks` (cleared; handed back
    /// by [`finish`](Self::finish) for the next one).
    pub(crate) fn new(mut blocks: Vec<[f32x4; 8]>) -> SweepLanes {
        blocks.clear();
        SweepLanes {
            all: BlockValues::EMPTY,
            blocks,
        }
    }

    /// The next block's values, filled apart (see [`BlockValues`]): a
    /// whole block of [`BLOCK_VECTORS`] vectors, or fewer for the last one.
    pub(crate) fn add_block(&mut self, b: BlockValues) {
        let all = &mut self.all;
        let mut kept = [f32x4::ZERO; 8];
        for d in 0..4 {
            all.hi[d] = raise(b.hi[d], all.hi[d]);
            all.lo[d] = lower(b.lo[d], all.lo[d]);
            kept[d] = b.hi[d];
            kept[d + 4] = b.lo[d];
        }
        all.z_min = lower(b.z_min, all.z_min);
        all.z_max = raise(b.z_max, all.z_max);
        self.blocks.push(kept);
    }

    /// The sweep of every point added (None when there was none), and the
    /// block list back; `lanes[i]` are the ground lanes (x, y) of the
    /// `i`-th vector added.
    pub(crate) fn finish(self, lanes: &[[f32x8; 2]]) -> (Option<Sweep>, Vec<[f32x4; 8]>) {
        let sweep = self.sweep(lanes);
        (sweep, self.blocks)
    }

    fn sweep(&self, lanes: &[[f32x8; 2]]) -> Option<Sweep> {
        // the first point along slot `k` (0–3 greatest, 4–7 least) whose
        // value is `best`: in the first block holding it, its first
        // vector holding it, its first lane
        let first = |k: usize, best: f32| -> Option<([f32; 2], f32)> {
            let block = self
                .blocks
                .iter()
                .position(|b| b[k].simd_eq(f32x4::splat(best)).to_bitmask() != 0)?;
            let wanted = f32x8::splat(best);
            let from = block * BLOCK_VECTORS;
            let to = (from + BLOCK_VECTORS).min(lanes.len());
            lanes.get(from..to)?.iter().find_map(|&[x, y]| {
                let s = directions(x, y)[k % 4];
                let hit = s.simd_eq(wanted).to_bitmask();
                (hit != 0).then(|| {
                    let l = hit.trailing_zeros() as usize;
                    ([x.to_array()[l], y.to_array()[l]], s.to_array()[l])
                })
            })
        };
        let mut extreme = [[0.0f32; 2]; 8];
        let mut value = [0.0f32; 8];
        for d in 0..4 {
            let best_hi = greatest(self.all.hi[d]);
            let best_lo = least(self.all.lo[d]);
            if !best_hi.is_finite() || !best_lo.is_finite() {
                return None;
            }
            (extreme[d], value[d]) = first(d, best_hi)?;
            (extreme[d + 4], value[d + 4]) = first(d + 4, best_lo)?;
        }
        Some(Sweep {
            min: [value[4], value[6], least(self.all.z_min)],
            max: [value[0], value[2], greatest(self.all.z_max)],
            extreme,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sweep point by point, as it was first written: the reference
    /// for the lane-wise one.
    fn sweep_point_by_point(points: &[Point3<f32>]) -> Option<Sweep> {
        let first = points.first()?;
        let mut min = [first.x, first.y, first.z];
        let mut max = min;
        let mut best = [f32::MIN; 8];
        let mut extreme = [[first.x, first.y]; 8];
        for p in points {
            let c = [p.x, p.y, p.z];
            for k in 0..3 {
                min[k] = if c[k] < min[k] { c[k] } else { min[k] };
                max[k] = if c[k] > max[k] { c[k] } else { max[k] };
            }
            let (x, y) = (p.x, p.y);
            let s = [x, x + y, y, y - x, -x, -x - y, -y, x - y];
            for k in 0..8 {
                if s[k] > best[k] {
                    best[k] = s[k];
                    extreme[k] = [x, y];
                }
            }
        }
        Some(Sweep { min, max, extreme })
    }

    /// Lane by lane is point by point, bit for bit, ties (coordinates on
    /// a coarse grid, so many points are equally far) and every length's
    /// remainder included.
    #[test]
    fn the_lane_sweep_is_the_point_sweep() {
        let mut sequence = crate::perception::test_sequence(99);
        let mut next = || sequence() as u32;
        for n in 0..200usize {
            let grid = if n % 2 == 0 { 0.25 } else { 0.001 };
            let points: Vec<Point3<f32>> = (0..n)
                .map(|_| {
                    let mut c = || (next() % 17) as f32 * grid - 2.0;
                    Point3::new(c(), c(), c())
                })
                .collect();
            assert_eq!(
                Sweep::of(&points),
                sweep_point_by_point(&points),
                "{n} points"
            );
        }
    }

    /// Lanes that are no point (NaN, as the z-score drops samples) change
    /// nothing: the sweep of the lanes is the sweep of the points kept,
    /// blocks and ties included.
    #[test]
    fn lanes_without_a_point_are_skipped() {
        let mut next = crate::perception::test_sequence(3);
        for n in 1..400usize {
            let grid = if n % 2 == 0 { 0.25 } else { 0.001 };
            let all: Vec<Option<Point3<f32>>> = (0..n)
                .map(|_| {
                    let mut c = || (next() % 17) as f32 * grid - 2.0;
                    let p = Point3::new(c(), c(), c());
                    (!next().is_multiple_of(4)).then_some(p)
                })
                .collect();
            let kept: Vec<Point3<f32>> = all.iter().flatten().copied().collect();
            let lane = |c: &[Option<Point3<f32>>], k: usize| {
                f32x8::new(std::array::from_fn(|l| {
                    c.get(l).copied().flatten().map_or(f32::NAN, |p| p[k])
                }))
            };
            let lanes: Vec<[f32x8; 2]> = all.chunks(8).map(|c| [lane(c, 0), lane(c, 1)]).collect();
            let mut sweep = SweepLanes::new(Vec::new());
            for b in all.chunks(8 * BLOCK_VECTORS) {
                let mut block = BlockValues::EMPTY;
                for c in b.chunks(8) {
                    block.add(lane(c, 0), lane(c, 1), lane(c, 2));
                }
                sweep.add_block(block);
            }
            let (got, blocks) = sweep.finish(&lanes);
            assert_eq!(got, sweep_point_by_point(&kept), "{n} samples");
            assert_eq!(blocks.len(), lanes.len().div_ceil(BLOCK_VECTORS));
        }
    }
}
