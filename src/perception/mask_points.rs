//! Steps 3–5 for one mask in two passes over its pixels' depths, with
//! what step 6 needs gathered on the way: exactly the points (and boxes)
//! of the steps one after the other — [`Mask::eroded`] →
//! [`isolate_depth`](super::cloud::isolate_depth) and the depth range →
//! [`zscore_filter`](super::cloud::zscore_filter) →
//! [`back_project`](super::cloud::back_project) → [`Object3D::from_points`]
//! — bit for bit (`tests::fused_steps_are_the_steps_one_after_the_other`).
//!
//! Pass 1 walks the eroded rows eight pixels at a time and appends each
//! in-range depth's pixel and depth to three flat arrays (eight valid
//! pixels, as inside an object, as one block; a mix one by one into the
//! next free slot, which only a valid one keeps); pass 2 runs eight
//! samples at a time — the z-score test (as an interval of `f32` depths),
//! the projection and the sweep of the bounds and extreme points — as
//! vector instructions (`wide`), and keeps the points that passed.

use std::cell::RefCell;

use nalgebra::{Isometry3, Point3};
use wide::{f32x4, f32x8};

use super::boxes::Object3D;
use super::cloud::depth_stats_of;
use super::masks::Mask;
use super::sweep::{BlockValues, Ground, Sweep, SweepLanes, BLOCK_VECTORS, SWEEP_LANES};
use crate::msg::{DepthImage, Frame, Intrinsics};

/// The depth samples of one mask, as three arrays (pixel column, row and
/// depth in metres); the pixel coordinates as `f32`, exact below 2²⁴.
#[derive(Default)]
struct Samples {
    u: Vec<f32>,
    v: Vec<f32>,
    z_m: Vec<f32>,
    len: usize,
    /// The kept points' ground lanes (see [`Ground`]), by
    /// [`kept_points`].
    ground: Vec<[f32x8; 2]>,
    /// The sweep's blocks (see [`SweepLanes`]).
    blocks: Vec<[f32x4; 8]>,
}

impl Samples {
    /// Empty, with room for `n` more samples plus a row's worth of slots
    /// past the end (every pixel of a row is written before it is kept or
    /// not).
    fn clear_for(&mut self, n: usize) {
        self.len = 0;
        self.grow(n);
    }

    /// Slots for at least `n` samples in all.
    #[cold]
    fn grow(&mut self, n: usize) {
        for a in [&mut self.u, &mut self.v, &mut self.z_m] {
            if a.len() < n {
                a.resize(n, 0.0);
            }
        }
    }

    /// Appends the pixels of row `v` (columns from `x0`) set in `bits`
    /// whose depth in `depths` lies within `[lo, hi]`, eight at a time:
    /// eight valid ones (inside an object, most) are copied as a block,
    /// eight invalid ones skipped, a mix kept one by one.
    #[inline]
    fn push_row(&mut self, x0: usize, v: usize, bits: &[bool], depths: &[f32], lo: f32, hi: f32) {
        let n = bits.len().min(depths.len());
        let start = self.len;
        let (Some(us), Some(vs), Some(zs)) = (
            self.u.get_mut(start..start + n),
            self.v.get_mut(start..start + n),
            self.z_m.get_mut(start..start + n),
        ) else {
            // room is made for every pixel of the region beforehand
            // (`clear_for`); were it not, the row is not lost: room, again
            self.grow(start + n);
            return self.push_row(x0, v, bits, depths, lo, hi);
        };
        let (bits, depths) = (&bits[..n], &depths[..n]);
        let vf = v as f32;
        let (lo8, hi8) = (f32x8::splat(lo), f32x8::splat(hi));
        let mut k = 0usize;
        let mut x = 0usize;
        while x + 8 <= n {
            let (on, z) = (&bits[x..x + 8], &depths[x..x + 8]);
            let z8 = f32x8::new(std::array::from_fn(|l| z[l]));
            let valid = z8.simd_ge(lo8) & z8.simd_le(hi8);
            let keep = valid.to_bitmask() & bools_bitmask(on);
            if keep == 0xff {
                let u0 = (x0 + x) as f32;
                // below 2^24: every pixel column is exact
                us[k..k + 8].copy_from_slice(&std::array::from_fn::<f32, 8, _>(|l| u0 + l as f32));
                vs[k..k + 8].copy_from_slice(&[vf; 8]);
                zs[k..k + 8].copy_from_slice(z);
                k += 8;
            } else if keep != 0 {
                for (l, &zl) in z.iter().enumerate() {
                    // `k` never passes `x + l`: the slot is in the row's room
                    us[k] = (x0 + x + l) as f32;
                    vs[k] = vf;
                    zs[k] = zl;
                    k += ((keep >> l) & 1) as usize;
                }
            }
            x += 8;
        }
        for (x, (&on, &z)) in bits.iter().zip(depths).enumerate().skip(x) {
            us[k] = (x0 + x) as f32;
            vs[k] = vf;
            zs[k] = z;
            k += usize::from(on & (z >= lo) & (z <= hi));
        }
        self.len = start + k;
    }
}

/// Eight booleans as the low eight bits of a mask (bit `l` for `on[l]`):
/// their bytes (0 or 1) as one word, gathered into its top byte by one
/// multiplication (byte `l` lands on bit `56 + l`, no two products meet).
#[inline(always)]
fn bools_bitmask(on: &[bool]) -> u32 {
    let bytes: [u8; 8] = std::array::from_fn(|l| u8::from(on[l]));
    (u64::from_le_bytes(bytes).wrapping_mul(0x0102_0408_1020_4080) >> 56) as u32
}

thread_local! {
    /// Reused between masks and views: fresh arrays per mask cost more in
    /// page faults than the work itself.
    static SAMPLES: RefCell<Samples> = RefCell::new(Samples::default());
}

/// What steps 3–6 made of one mask.
pub struct MaskObject {
    /// The object; None when no point passed.
    pub object: Option<Object3D>,
    /// The points it has (0 without an object).
    pub points: usize,
    /// Pixels of the eroded mask.
    pub eroded_px: usize,
    /// Of those, pixels with a depth within the range.
    pub depth_samples: usize,
}

/// Settings of steps 3–5 for [`mask_object`].
pub struct MaskGeometry<'a> {
    /// 3×3 erosions (the paper: 1).
    pub erosion_iterations: usize,
    pub min_depth_m: f32,
    pub max_depth_m: f32,
    /// The z-score threshold τ.
    pub zscore_tau: f64,
    /// The colour camera's (the mask's and depth image's).
    pub intrinsics: &'a Intrinsics,
    pub target_from_camera: &'a Isometry3<f64>,
    pub frame: Frame,
}

/// Steps 3–6 for one mask: erosion, the depths within range under it, the
/// z-score filter, back-projection into the target frame, and the object's
/// boxes; `label`, `score` and `box_xyxy` are the detection's.
pub fn mask_object(
    mask: &Mask,
    depth: &DepthImage,
    g: &MaskGeometry,
    label: &str,
    score: f32,
    box_xyxy: Option<[f32; 4]>,
) -> MaskObject {
    SAMPLES.with(|buf| {
        let mut samples = buf.borrow_mut();
        let (_, _, w, h) = mask.region();
        samples.clear_for(w * h);
        let eroded_px = if g.erosion_iterations == 1 {
            gather_eroded_once(mask, depth, g.min_depth_m, g.max_depth_m, &mut samples)
        } else {
            let eroded = mask.eroded(g.erosion_iterations);
            gather(&eroded, depth, g.min_depth_m, g.max_depth_m, &mut samples);
            eroded.count()
        };
        let depth_samples = samples.len;
        let mut ground = std::mem::take(&mut samples.ground);
        let mut blocks = std::mem::take(&mut samples.blocks);
        let (points, sweep) = kept_points(&samples, &mut ground, &mut blocks, g);
        let n = points.len();
        let object = sweep.map(|s| {
            Object3D::from_swept_points(
                label.to_string(),
                score,
                g.frame,
                points,
                &s,
                Some(Ground {
                    lanes: &ground,
                    blocks: &blocks,
                }),
                box_xyxy,
            )
        });
        samples.ground = ground;
        samples.blocks = blocks;
        MaskObject {
            points: if object.is_some() { n } else { 0 },
            object,
            eroded_px,
            depth_samples,
        }
    })
}

/// The closed depth range as one test per pixel: a positive finite range
/// holds only finite positive depths (a NaN fails every comparison).
fn depth_range(min_m: f32, max_m: f32) -> (f32, f32) {
    if min_m > 0.0 && max_m.is_finite() {
        (min_m, max_m)
    } else {
        (min_m.max(f32::from_bits(1)), max_m.min(f32::MAX))
    }
}

/// Steps 3–4 for one erosion, fused: the eroded rows (never the eroded
/// mask) straight into the samples; returns the eroded mask's pixel count.
fn gather_eroded_once(
    mask: &Mask,
    depth: &DepthImage,
    min_m: f32,
    max_m: f32,
    out: &mut Samples,
) -> usize {
    let (x0, y0, w, _) = mask.region();
    let (dw, dh) = (depth.width(), depth.height());
    let data = depth.data();
    let cols = w.min(dw.saturating_sub(x0));
    let (lo, hi) = depth_range(min_m, max_m);
    let mut eroded = 0usize;
    mask.for_each_eroded_row(|y, bits| {
        eroded += super::masks::count_set(bits);
        let v = y0 + y;
        if v < dh {
            out.push_row(x0, v, bits, &data[v * dw + x0..v * dw + x0 + cols], lo, hi);
        }
    });
    eroded
}

/// Step 4 under a mask eroded already.
fn gather(mask: &Mask, depth: &DepthImage, min_m: f32, max_m: f32, out: &mut Samples) {
    let (x0, y0, _, h) = mask.region();
    let (dw, dh) = (depth.width(), depth.height());
    let data = depth.data();
    let cols = mask.region().2.min(dw.saturating_sub(x0));
    let (lo, hi) = depth_range(min_m, max_m);
    for y in 0..h.min(dh.saturating_sub(y0)) {
        let v = y0 + y;
        out.push_row(
            x0,
            v,
            mask.region_row(y),
            &data[v * dw + x0..v * dw + x0 + cols],
            lo,
            hi,
        );
    }
}

/// The depths the z-score keeps, |z − mean| < τσ in f64, as a closed
/// interval of `f32` depths (every depth when they have no spread), so
/// that eight are tested at once in `f32` with the same outcome: the test
/// is monotone on either side of the mean (rounding is), so the depths it
/// keeps are an interval, whose ends lie within an ulp or two of
/// mean ± τσ rounded to `f32`. An empty interval has `lo > hi`.
fn kept_depths(zs: &[f32], tau: f64) -> (f32, f32) {
    let (mean, limit) = match depth_stats_of(zs) {
        Some((mean, std)) if std > 1e-9 * mean.abs().max(1.0) => (mean, tau * std),
        _ => return (f32::NEG_INFINITY, f32::INFINITY),
    };
    let keep = |z: f32| (z as f64 - mean).abs() < limit;
    // the least kept depth, searched up from a few ulps below mean − τσ,
    // the greatest down from above mean + τσ (none is kept: empty)
    let end = |from: f64, outward: fn(f32) -> f32, inward: fn(f32) -> f32| {
        let mut z = from as f32;
        for _ in 0..4 {
            z = outward(z);
        }
        for _ in 0..12 {
            if keep(z) {
                return Some(z);
            }
            z = inward(z);
        }
        None
    };
    match (
        end(mean - limit, f32::next_down, f32::next_up),
        end(mean + limit, f32::next_up, f32::next_down),
    ) {
        (Some(lo), Some(hi)) => (lo, hi),
        _ => (f32::INFINITY, f32::NEG_INFINITY),
    }
}

/// Step 4's z-score and step 5, with the sweep of step 6: the samples
/// within τσ of the mean depth, back-projected and moved into the target
/// frame, in the samples' order, and their sweep (None without points);
/// their ground lanes into `ground`; `blocks`: the sweep's, reused.
fn kept_points(
    samples: &Samples,
    ground: &mut Vec<[f32x8; 2]>,
    blocks: &mut Vec<[f32x4; 8]>,
    g: &MaskGeometry,
) -> (Vec<Point3<f32>>, Option<Sweep>) {
    const L: usize = SWEEP_LANES;
    let n = samples.len;
    let (us, vs, zs) = (&samples.u[..n], &samples.v[..n], &samples.z_m[..n]);
    let (lo, hi) = kept_depths(zs, g.zscore_tau);
    let (lo, hi) = (f32x8::splat(lo), f32x8::splat(hi));
    let p = Projector::new(g.intrinsics, g.target_from_camera);
    // with capacity, not zeroed: a zeroed block this size is fresh pages
    // from the kernel, each a fault when written. Eight slots past the
    // samples: every block's eight points are written, kept or not, at
    // the next free slot (`written` never passes `i`, so `written + 8`
    // never passes `n + 8`), and only the kept ones advance it.
    let mut points: Vec<Point3<f32>> = Vec::with_capacity(n + L);
    let mut written = 0usize;
    let slots = points.spare_capacity_mut();
    let mut sweep = SweepLanes::new(std::mem::take(blocks));
    ground.clear();
    ground.reserve(n.div_ceil(L));
    // eight samples; past the end a NaN depth, never kept
    let load = |a: &[f32], i: usize, pad: f32| match a.get(i..i + L) {
        Some(c) => f32x8::new(std::array::from_fn(|l| c[l])),
        None => f32x8::new(std::array::from_fn(|l| {
            a.get(i + l).copied().unwrap_or(pad)
        })),
    };
    let mut i = 0usize;
    while i < n {
        // a block of the sweep at a time, its values kept in registers
        let mut block = BlockValues::EMPTY;
        let block_end = n.min(i + L * BLOCK_VECTORS);
        while i < block_end {
            let (u, v, z) = (load(us, i, 0.0), load(vs, i, 0.0), load(zs, i, f32::NAN));
            let kept = z.simd_ge(lo) & z.simd_le(hi);
            let [x, y, zt] = p.point8(u, v, z);
            // a lane not kept as all ones, a NaN: no point
            let dropped = !kept;
            let (gx, gy) = (x | dropped, y | dropped);
            block.add(gx, gy, zt | dropped);
            ground.push([gx, gy]);
            let keep = kept.to_bitmask();
            let (x, y, zt) = (x.to_array(), y.to_array(), zt.to_array());
            let out = &mut slots[written..written + L];
            if keep == 0xff {
                for (l, slot) in out.iter_mut().enumerate() {
                    slot.write(Point3::new(x[l], y[l], zt[l]));
                }
                written += L;
            } else if keep != 0 {
                let mut k = 0usize;
                for l in 0..L {
                    out[k].write(Point3::new(x[l], y[l], zt[l]));
                    k += ((keep >> l) & 1) as usize;
                }
                written += k;
            }
            i += L;
        }
        sweep.add_block(block);
    }
    // SAFETY: the first `written` slots were each written above (a slot
    // is passed only after its point was written and kept), and
    // `written <= n < capacity`
    unsafe { points.set_len(written) };
    let (sweep, spent) = sweep.finish(ground);
    *blocks = spent;
    (points, sweep)
}

/// A pixel's point in the target frame: p = R·(z·ray(u, v)) + t with
/// ray(u, v) = ((u−cx)/fx, (v−cy)/fy, 1), linear in u and v, so
/// p = z·(a + u·b + v·c) + t with a, b, c, t made once — the arithmetic of
/// [`back_project`](super::cloud::back_project), operation for operation.
pub(crate) struct Projector {
    a: [f32; 3],
    b: [f32; 3],
    c: [f32; 3],
    t: [f32; 3],
}

impl Projector {
    pub(crate) fn new(intrinsics: &Intrinsics, target_from_camera: &Isometry3<f64>) -> Projector {
        let r = target_from_camera.rotation.to_rotation_matrix();
        let m = r.matrix();
        let col = |j: usize| nalgebra::Vector3::new(m[(0, j)], m[(1, j)], m[(2, j)]);
        let b = col(0) / intrinsics.fx;
        let c = col(1) / intrinsics.fy;
        let a = col(2) - b * intrinsics.cx - c * intrinsics.cy;
        let t = target_from_camera.translation.vector;
        let f = |v: nalgebra::Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
        Projector {
            a: f(a),
            b: f(b),
            c: f(c),
            t: f(t),
        }
    }

    #[inline(always)]
    pub(crate) fn point(&self, u: f32, v: f32, z_m: f32) -> [f32; 3] {
        std::array::from_fn(|k| (self.a[k] + self.b[k] * u + self.c[k] * v) * z_m + self.t[k])
    }

    /// [`point`](Self::point) of eight pixels, the same operations.
    #[inline(always)]
    fn point8(&self, u: f32x8, v: f32x8, z_m: f32x8) -> [f32x8; 3] {
        let s = f32x8::splat;
        std::array::from_fn(|k| {
            (s(self.a[k]) + s(self.b[k]) * u + s(self.c[k]) * v) * z_m + s(self.t[k])
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::cloud::{back_project, isolate_depth, zscore_filter};

    /// The steps one after the other, as the paper gives them.
    fn steps(mask: &Mask, depth: &DepthImage, g: &MaskGeometry) -> Option<Object3D> {
        let eroded = mask.eroded(g.erosion_iterations);
        let samples: Vec<_> = isolate_depth(&eroded, depth)
            .into_iter()
            .filter(|s| s.z_m >= g.min_depth_m && s.z_m <= g.max_depth_m)
            .collect();
        let kept = zscore_filter(samples, g.zscore_tau);
        let points = back_project(&kept, g.intrinsics, g.target_from_camera);
        Object3D::from_points("x".into(), 0.5, g.frame, points, None)
    }

    /// Every pattern of eight booleans gives its own bits.
    #[test]
    fn bools_bitmask_is_bit_l_for_bool_l() {
        for m in 0u32..256 {
            let on: [bool; 8] = std::array::from_fn(|l| (m >> l) & 1 == 1);
            assert_eq!(bools_bitmask(&on), m);
        }
    }

    /// The interval of kept depths is the z-score test itself: every f32
    /// depth within a few thousand ulps of both ends, for spreads from
    /// wide to a few ulps (where the interval can be empty).
    #[test]
    fn kept_depths_are_the_depths_the_zscore_keeps() {
        for (k, spread) in [0.3f32, 0.01, 1e-5, 3e-7].into_iter().enumerate() {
            let zs: Vec<f32> = (0..101)
                .map(|i| 2.0 + spread * ((i * 37 + k) % 101) as f32 / 100.0)
                .collect();
            let (mean, std) = depth_stats_of(&zs).unwrap();
            let (lo, hi) = kept_depths(&zs, 2.0);
            for end in [mean - 2.0 * std, mean + 2.0 * std] {
                let mut z = (end as f32).next_down();
                for _ in 0..2000 {
                    z = z.next_down();
                }
                for _ in 0..4000 {
                    let zscore_keeps = (z as f64 - mean).abs() < 2.0 * std;
                    assert_eq!(z >= lo && z <= hi, zscore_keeps, "z {z} spread {spread}");
                    z = z.next_up();
                }
            }
        }
    }

    /// Random masks (touching the image's edges or not, holes, one and two
    /// erosions) over random depths (outliers, zeros, NaNs, out of range):
    /// the fused path gives the steps' points and boxes bit for bit.
    #[test]
    fn fused_steps_are_the_steps_one_after_the_other() {
        let mut next = crate::perception::test_sequence(7);
        let k = Intrinsics {
            width: 64,
            height: 48,
            fx: 60.0,
            fy: 61.0,
            cx: 31.5,
            cy: 23.5,
        };
        let t = Isometry3::new(
            nalgebra::Vector3::new(0.3, -0.1, 0.9),
            nalgebra::Vector3::new(-1.2, 0.1, -1.5),
        );
        let mut objects = 0;
        for case in 0..400 {
            let (iw, ih) = (64, 48);
            let data: Vec<f32> = (0..iw * ih)
                .map(|_| match next() % 40 {
                    0 => 0.0,
                    1 => f32::NAN,
                    2 => 12.0 + (next() % 100) as f32 * 0.1,
                    3..=5 => 6.0 + (next() % 100) as f32 * 0.01,
                    _ => 2.0 + (next() % 1000) as f32 * 0.0005,
                })
                .collect();
            let depth = DepthImage::new(iw, ih, data).unwrap();
            let (x0, y0) = (next() % iw, next() % ih);
            let (x1, y1) = (x0 + next() % (iw - x0 + 1), y0 + next() % (ih - y0 + 1));
            let mut mask = Mask::empty_in(iw, ih, x0, y0, x1, y1);
            for v in y0..y1 {
                for u in x0..x1 {
                    mask.set(u, v, !next().is_multiple_of(10));
                }
            }
            let g = MaskGeometry {
                erosion_iterations: 1 + case % 2,
                min_depth_m: 0.1,
                max_depth_m: 10.0,
                zscore_tau: 2.0,
                intrinsics: &k,
                target_from_camera: &t,
                frame: Frame::BaseLink,
            };
            let fused = mask_object(&mask, &depth, &g, "x", 0.5, None);
            let want = steps(&mask, &depth, &g);
            assert_eq!(fused.object, want, "case {case}");
            assert_eq!(fused.eroded_px, mask.eroded(g.erosion_iterations).count());
            objects += usize::from(want.is_some());
        }
        assert!(objects > 100, "only {objects} cases made an object");
    }
}
