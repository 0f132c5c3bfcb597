//! Step 6's one pass over an object's points: their axis-aligned bounds
//! and the extreme points along eight ground directions (the oriented
//! box's hull starts from them), eight points at a time.

use nalgebra::Point3;
use wide::{f32x8, u32x8};

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
        let mut lanes = SweepLanes::new();
        let mut chunks = points.chunks_exact(SWEEP_LANES);
        let mut base = 0u32;
        let lane = |c: &[Point3<f32>], k: usize| {
            f32x8::new(std::array::from_fn(|l| c.get(l).map_or(f32::NAN, |p| p[k])))
        };
        for c in &mut chunks {
            lanes.add(base, lane(c, 0), lane(c, 1), lane(c, 2));
            base = base.wrapping_add(SWEEP_LANES as u32);
        }
        let rest = chunks.remainder();
        lanes.add(base, lane(rest, 0), lane(rest, 1), lane(rest, 2));
        lanes.finish(|i| points.get(i as usize).map(|p| [p.x, p.y]))
    }

    pub(crate) fn aabb(&self) -> Aabb {
        Aabb {
            min_m: self.min.map(f64::from),
            max_m: self.max.map(f64::from),
        }
    }
}

/// Points a [`SweepLanes`] takes at once.
pub(crate) const SWEEP_LANES: usize = 8;

/// A [`Sweep`] made [`SWEEP_LANES`] points at a time, each lane keeping
/// its own extremes (what the compiler turns into vector compares and
/// blends): along x, x+y, y and y−x the greatest and least value and the
/// index of the first point that reached it, and the z bounds. The lanes
/// are joined in [`finish`](Self::finish): the best value, and of the
/// lanes holding it the smallest index — the first point furthest, as a
/// point-by-point sweep finds it. The negative directions are the least
/// values of the positive ones (−x−y is exactly −(x+y) in floating point),
/// and the x and y bounds are the extremes along x and y.
pub(crate) struct SweepLanes {
    hi: [f32x8; 4],
    hi_at: [u32x8; 4],
    lo: [f32x8; 4],
    lo_at: [u32x8; 4],
    z_min: f32x8,
    z_max: f32x8,
}

impl SweepLanes {
    pub(crate) fn new() -> SweepLanes {
        SweepLanes {
            hi: [f32x8::splat(f32::NEG_INFINITY); 4],
            hi_at: [u32x8::splat(u32::MAX); 4],
            lo: [f32x8::splat(f32::INFINITY); 4],
            lo_at: [u32x8::splat(u32::MAX); 4],
            z_min: f32x8::splat(f32::INFINITY),
            z_max: f32x8::splat(f32::NEG_INFINITY),
        }
    }

    /// Points `first + l` for the lanes `l` (finite coordinates; indices
    /// increase from call to call). A lane whose coordinates are NaN is
    /// no point: NaN is neither greater nor less than anything.
    #[inline]
    pub(crate) fn add(&mut self, first: u32, x: f32x8, y: f32x8, z: f32x8) {
        let at = u32x8::splat(first) + u32x8::new([0, 1, 2, 3, 4, 5, 6, 7]);
        let s = [x, x + y, y, y - x];
        for (d, s) in s.into_iter().enumerate() {
            let up = s.simd_gt(self.hi[d]);
            self.hi[d] = up.select(s, self.hi[d]);
            self.hi_at[d] = bytemuck::cast::<f32x8, u32x8>(up).select(at, self.hi_at[d]);
            let down = s.simd_lt(self.lo[d]);
            self.lo[d] = down.select(s, self.lo[d]);
            self.lo_at[d] = bytemuck::cast::<f32x8, u32x8>(down).select(at, self.lo_at[d]);
        }
        self.z_min = z.simd_lt(self.z_min).select(z, self.z_min);
        self.z_max = z.simd_gt(self.z_max).select(z, self.z_max);
    }

    /// The sweep of every point added (None when there was none);
    /// `xy_of(i)` is point i's ground coordinates.
    pub(crate) fn finish(&self, xy_of: impl Fn(u32) -> Option<[f32; 2]>) -> Option<Sweep> {
        // the best value over the lanes, then the first point holding it
        let join =
            |vals: &[f32; SWEEP_LANES], at: &[u32; SWEEP_LANES], better: fn(f32, f32) -> bool| {
                let mut best: Option<(f32, u32)> = None;
                for l in 0..SWEEP_LANES {
                    if at[l] == u32::MAX {
                        continue;
                    }
                    best = match best {
                        Some((v, i)) if !(better(vals[l], v) || (vals[l] == v && at[l] < i)) => {
                            Some((v, i))
                        }
                        _ => Some((vals[l], at[l])),
                    };
                }
                best
            };
        let greater = |a: f32, b: f32| a > b;
        let less = |a: f32, b: f32| a < b;
        let mut extreme = [[0.0f32; 2]; 8];
        let mut value = [0.0f32; 8];
        for d in 0..4 {
            let (hv, hi) = join(&self.hi[d].to_array(), &self.hi_at[d].to_array(), greater)?;
            let (lv, li) = join(&self.lo[d].to_array(), &self.lo_at[d].to_array(), less)?;
            extreme[d] = xy_of(hi)?;
            extreme[d + 4] = xy_of(li)?;
            (value[d], value[d + 4]) = (hv, lv);
        }
        let z_min = self
            .z_min
            .to_array()
            .iter()
            .fold(f32::INFINITY, |m, &z| if z < m { z } else { m });
        let z_max = self
            .z_max
            .to_array()
            .iter()
            .fold(f32::NEG_INFINITY, |m, &z| if z > m { z } else { m });
        Some(Sweep {
            min: [value[4], value[6], z_min],
            max: [value[0], value[2], z_max],
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
}
