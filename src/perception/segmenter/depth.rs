//! Depth-guided box segmentation (no model): inside each box, the dominant
//! depth mode of the central region seeds a region grown over depth
//! continuity, bounded by the box.
//!
//! 1. Histogram the valid depths in the central part of the box
//!    (`center_fraction` of its width and height) in `bin_m` bins; the
//!    fullest bin (ties: nearer) is the object's depth mode.
//! 2. Seeds: central pixels within `mode_tolerance_m` of the mode.
//! 3. Grow 4-connected from the seeds while neighbouring depths differ by at
//!    most `step_m + step_per_m · z` (a relative step, for depth noise that
//!    grows with range), staying inside the box.
//! 4. A detector's box hugs its object: the region spans the box and stops
//!    at its edges. A region that spans little of the box or runs on past
//!    its edges (a chair before the boxed bookshelf, a table before the
//!    boxed chair, the wall behind a thin object) fits it poorly; then the
//!    fullest depth modes of the box's other pixels are grown too (from
//!    all their pixels in the box), and one that fits the box clearly
//!    better replaces it.
//!
//! With the floor known ([`Segmenter::set_floor`]), pixels within
//! `floor_band_m` of it or below it neither vote, seed nor join: the floor
//! runs on at one depth from an object's foot to whatever stands in front
//! of it, and would join them.

use rayon::prelude::*;

use super::{FloorInImage, Segmenter, SegmenterError};
use crate::msg::{DepthImage, RgbImage};
use crate::perception::masks::Mask;

#[derive(Debug, Clone, PartialEq)]
pub struct DepthSegmenterSettings {
    /// Width of the depth histogram bins, metres.
    pub bin_m: f32,
    /// Part of the box (width and height, centred) whose depths vote, 0..1.
    pub center_fraction: f32,
    /// Seeds lie within this distance of the mode, metres.
    pub mode_tolerance_m: f32,
    /// Largest depth step between neighbours at 0 m, metres.
    pub step_m: f32,
    /// Added step per metre of depth.
    pub step_per_m: f32,
    /// With the floor known, pixels this near it (or below it) are floor,
    /// metres.
    pub floor_band_m: f32,
}

impl Default for DepthSegmenterSettings {
    fn default() -> Self {
        DepthSegmenterSettings {
            bin_m: 0.05,
            center_fraction: 0.5,
            mode_tolerance_m: 0.05,
            step_m: 0.02,
            step_per_m: 0.02,
            floor_band_m: 0.05,
        }
    }
}

#[derive(Debug, Clone, Default)]
pub struct DepthBoxSegmenter {
    pub settings: DepthSegmenterSettings,
    /// Where the floor is in the image, when known.
    pub floor: Option<FloorInImage>,
}

impl DepthBoxSegmenter {
    pub fn new(settings: DepthSegmenterSettings) -> Self {
        DepthBoxSegmenter {
            settings,
            floor: None,
        }
    }

    /// The mask of one box: the region grown from the central depth
    /// mode ([`Self::central_region`]), unless it fits the box poorly (it
    /// spans little of the box, or runs on past the box's edges, as what
    /// stands in front or the wall behind does) and the region of another
    /// of the box's depth modes fits it clearly better (a detector's box
    /// hugs its object).
    pub fn segment_box(&self, depth: &DepthImage, xyxy: [f32; 4]) -> Mask {
        let Some(primary) = self.central_region(depth, xyxy) else {
            return Mask::for_box(depth.width(), depth.height(), xyxy);
        };
        let primary_fit = self.box_fit(depth, &primary);
        if primary_fit >= GOOD_BOX_FIT {
            return primary;
        }
        let mask = Mask::for_box(depth.width(), depth.height(), xyxy);
        let (x0, y0, bw, bh) = mask.region();
        // the fullest depth mode of the box's pixels in no region grown
        // so far, grown from those pixels, a few times
        let whole = [x0, y0, x0 + bw, y0 + bh];
        let mut taken = primary.clone();
        let total = self.depths_in(depth, whole).count();
        let mut best = (primary_fit, primary);
        for _ in 0..OTHER_MODES {
            let free = self
                .depths_in_where(depth, whole, |u, v| !taken.get(u, v))
                .map(|z| self.bin_of(z));
            let n = free.clone().count();
            if (n as f64) < OTHER_MODE_SHARE * total as f64 {
                break;
            }
            let Some(bin) = fullest_bin(free) else {
                break;
            };
            let other = self.mode_of(bin);
            let grown = self.grow_where(depth, mask.clone(), whole, other, |u, v| !taken.get(u, v));
            let fit = self.box_fit(depth, &grown);
            for (u, v) in grown.pixels() {
                taken.set(u, v, true);
            }
            if fit > best.0 + BETTER_BOX_FIT {
                best = (fit, grown);
            }
        }
        best.1
    }

    /// Steps 1–3 as the module says: the region grown from the central
    /// depth mode (None when the box is empty or holds no depth above the
    /// floor).
    pub fn central_region(&self, depth: &DepthImage, xyxy: [f32; 4]) -> Option<Mask> {
        let (w, h) = (depth.width(), depth.height());
        let mask = Mask::for_box(w, h, xyxy);
        let (x0, y0, bw, bh) = mask.region();
        if bw == 0 || bh == 0 {
            return None;
        }
        let s = &self.settings;
        let cf = s.center_fraction.clamp(0.05, 1.0);
        let cx0 = x0 + ((bw as f32 * (1.0 - cf) / 2.0) as usize);
        let cy0 = y0 + ((bh as f32 * (1.0 - cf) / 2.0) as usize);
        let cx1 = (x0 + bw - ((bw as f32 * (1.0 - cf) / 2.0) as usize))
            .max(cx0 + 1)
            .min(w);
        let cy1 = (y0 + bh - ((bh as f32 * (1.0 - cf) / 2.0) as usize))
            .max(cy0 + 1)
            .min(h);

        // 1. mode of the central depths: bins counted in a flat table
        // (nearest first; a bin width so small that the table would be
        // huge counts in an ordered map instead)
        let bin = fullest_bin(
            self.depths_in(depth, [cx0, cy0, cx1, cy1])
                .map(|z| self.bin_of(z)),
        )?;
        let mode = self.mode_of(bin);
        Some(self.grow(depth, mask, [cx0, cy0, cx1, cy1], mode))
    }

    fn bin_of(&self, z: f32) -> u32 {
        (z / self.settings.bin_m) as u32
    }

    fn mode_of(&self, bin: u32) -> f32 {
        (bin as f32 + 0.5) * self.settings.bin_m
    }

    fn tolerance(&self) -> f32 {
        let s = &self.settings;
        s.mode_tolerance_m.max(s.bin_m / 2.0)
    }

    /// Above the floor's band (everything when the floor is not known).
    #[inline]
    fn above(&self, u: usize, v: usize, z: f32) -> bool {
        self.floor
            .is_none_or(|f| f.height_m(u, v, z) > self.settings.floor_band_m)
    }

    /// The valid depths above the floor in `[x0, y0, x1, y1)` (clipped).
    fn depths_in<'a>(
        &'a self,
        depth: &'a DepthImage,
        area: [usize; 4],
    ) -> impl Iterator<Item = f32> + Clone + 'a {
        self.depths_in_where(depth, area, |_, _| true)
    }

    /// [`Self::depths_in`] at the pixels where `keep` holds.
    fn depths_in_where<'a>(
        &'a self,
        depth: &'a DepthImage,
        [x0, y0, x1, y1]: [usize; 4],
        keep: impl Fn(usize, usize) -> bool + Clone + 'a,
    ) -> impl Iterator<Item = f32> + Clone + 'a {
        let (w, h) = (depth.width(), depth.height());
        (y0..y1.min(h))
            .flat_map(move |v| (x0..x1.min(w)).map(move |u| (u, v)))
            .filter(move |&(u, v)| keep(u, v))
            .filter_map(move |(u, v)| depth.at(u, v).filter(|&z| self.above(u, v, z)))
    }

    /// Steps 2 and 3: the seeds are the pixels of `seeds` (image
    /// coordinates, clipped to the mask's region) within the tolerance of
    /// `mode`, grown over region indices. A pixel joins once and is grown
    /// from once, so the mask is every pixel reachable from the seeds
    /// whatever the order (a stack here).
    fn grow(&self, depth: &DepthImage, mask: Mask, seeds: [usize; 4], mode: f32) -> Mask {
        self.grow_where(depth, mask, seeds, mode, |_, _| true)
    }

    /// [`Self::grow`] seeded only where `seed` holds.
    fn grow_where(
        &self,
        depth: &DepthImage,
        mut mask: Mask,
        seeds: [usize; 4],
        mode: f32,
        seed: impl Fn(usize, usize) -> bool,
    ) -> Mask {
        let (x0, y0, bw, bh) = mask.region();
        let s = &self.settings;
        let stride = depth.width();
        let data = depth.data();
        let mut stack: Vec<(u32, u32, f32)> = Vec::new();
        let tolerance = self.tolerance();
        for v in seeds[1].max(y0)..seeds[3].min(y0 + bh) {
            for u in seeds[0].max(x0)..seeds[2].min(x0 + bw) {
                if let Some(z) = depth.at(u, v) {
                    if (z - mode).abs() <= tolerance
                        && self.above(u, v, z)
                        && seed(u, v)
                        && mask.set(u, v, true)
                    {
                        stack.push(((u - x0) as u32, (v - y0) as u32, z));
                    }
                }
            }
        }
        let bits = mask.region_bits_mut();
        while let Some((x, y, z)) = stack.pop() {
            let (x, y) = (x as usize, y as usize);
            let i = y * bw + x;
            let step = s.step_m + s.step_per_m * z;
            let mut visit = |j: usize, nx: usize, ny: usize| {
                if bits[j] {
                    return;
                }
                let nz = data[(y0 + ny) * stride + x0 + nx];
                if crate::msg::is_valid_depth(nz)
                    && (nz - z).abs() <= step
                    && self.above(x0 + nx, y0 + ny, nz)
                {
                    bits[j] = true;
                    stack.push((nx as u32, ny as u32, nz));
                }
            };
            if x > 0 {
                visit(i - 1, x - 1, y);
            }
            if x + 1 < bw {
                visit(i + 1, x + 1, y);
            }
            if y > 0 {
                visit(i - bw, x, y - 1);
            }
            if y + 1 < bh {
                visit(i + bw, x, y + 1);
            }
        }
        mask
    }

    /// How well a grown mask fits its box, 0–1: the share of the box its
    /// set pixels' bounds span, times the share of a ring around the box
    /// ([`RING_FRACTION`] of the box's smaller side wide) that the same
    /// growth would reach past the box's edges, taken from one. An object
    /// its box hugs spans the box and stops at its edges; what stands in
    /// front spans part of it or runs on past it, and a wall behind runs
    /// on all round.
    fn box_fit(&self, depth: &DepthImage, mask: &Mask) -> f64 {
        let (x0, y0, bw, bh) = mask.region();
        let (mut lo, mut hi) = ([usize::MAX; 2], [0usize; 2]);
        for y in 0..bh {
            let row = mask.region_row(y);
            if let (Some(a), Some(b)) = (row.iter().position(|&b| b), row.iter().rposition(|&b| b))
            {
                lo = [lo[0].min(a), lo[1].min(y)];
                hi = [hi[0].max(b + 1), hi[1].max(y + 1)];
            }
        }
        if lo[0] == usize::MAX {
            return 0.0;
        }
        let spans = ((hi[0] - lo[0]) * (hi[1] - lo[1])) as f64 / (bw * bh) as f64;
        // the ring, clipped to the image
        let (w, h) = (depth.width(), depth.height());
        let m = ((RING_FRACTION * bw.min(bh) as f64).ceil() as usize).max(2);
        let (rx0, ry0) = (x0.saturating_sub(m), y0.saturating_sub(m));
        let (rx1, ry1) = ((x0 + bw + m).min(w), (y0 + bh + m).min(h));
        let (rw, rh) = (rx1 - rx0, ry1 - ry0);
        let ring_px = rw * rh - bw * bh;
        if ring_px == 0 {
            return spans;
        }
        let inside = |u: usize, v: usize| u >= x0 && u < x0 + bw && v >= y0 && v < y0 + bh;
        let s = &self.settings;
        let data = depth.data();
        let mut reached = vec![false; rw * rh];
        let mut stack: Vec<(usize, usize, f32)> = Vec::new();
        // from the mask's pixels on the box's edges
        for (u, v) in mask.pixels() {
            if u == x0 || v == y0 || u + 1 == x0 + bw || v + 1 == y0 + bh {
                if let Some(z) = depth.at(u, v) {
                    stack.push((u, v, z));
                }
            }
        }
        let mut count = 0usize;
        while let Some((u, v, z)) = stack.pop() {
            let step = s.step_m + s.step_per_m * z;
            let neighbours = [
                (u.wrapping_sub(1), v),
                (u + 1, v),
                (u, v.wrapping_sub(1)),
                (u, v + 1),
            ];
            for (nu, nv) in neighbours {
                if nu < rx0 || nu >= rx1 || nv < ry0 || nv >= ry1 || inside(nu, nv) {
                    continue;
                }
                let j = (nv - ry0) * rw + (nu - rx0);
                if reached[j] {
                    continue;
                }
                let nz = data[nv * w + nu];
                if crate::msg::is_valid_depth(nz)
                    && (nz - z).abs() <= step
                    && self.above(nu, nv, nz)
                {
                    reached[j] = true;
                    count += 1;
                    stack.push((nu, nv, nz));
                }
            }
        }
        spans * (1.0 - count as f64 / ring_px as f64)
    }
}

/// A region fitting its box this well is kept without looking further.
const GOOD_BOX_FIT: f64 = 0.6;
/// Another depth mode's region replaces the central one's when it fits
/// the box better by this much.
const BETTER_BOX_FIT: f64 = 0.2;
/// Other depth modes tried, at most.
const OTHER_MODES: usize = 3;
/// The least share of the box's depths another mode holds to be tried.
const OTHER_MODE_SHARE: f64 = 0.05;
/// The ring around a box whose reach measures a region running on past
/// it: this share of the box's smaller side.
const RING_FRACTION: f64 = 0.2;

/// The fullest bin of these (ties: the lowest, the nearer depth); None
/// when there are none.
fn fullest_bin(bins: impl Iterator<Item = u32> + Clone) -> Option<u32> {
    const FLAT_BINS: u32 = 1 << 16;
    let max = bins.clone().max()?;
    if max < FLAT_BINS {
        let mut counts = vec![0u32; max as usize + 1];
        for b in bins {
            counts[b as usize] += 1;
        }
        let mut best = (0, 0);
        for (b, &n) in counts.iter().enumerate() {
            if n > best.1 {
                best = (b as u32, n);
            }
        }
        return Some(best.0);
    }
    let mut counts: std::collections::BTreeMap<u32, usize> = Default::default();
    for b in bins {
        *counts.entry(b).or_default() += 1;
    }
    // iterated near to far: strict > keeps the nearer on ties
    let mut best: Option<(u32, usize)> = None;
    for (&b, &n) in &counts {
        if best.is_none_or(|(_, bn)| n > bn) {
            best = Some((b, n));
        }
    }
    best.map(|(b, _)| b)
}

impl Segmenter for DepthBoxSegmenter {
    fn backend(&self) -> &'static str {
        "depth-box"
    }

    fn set_floor(&mut self, floor: Option<FloorInImage>) {
        self.floor = floor;
    }

    fn segment(
        &mut self,
        _image: &RgbImage,
        depth: Option<&DepthImage>,
        boxes: &[[f32; 4]],
    ) -> Result<Vec<Mask>, SegmenterError> {
        let depth = depth.ok_or_else(|| {
            SegmenterError::Input("the depth-guided segmenter needs a depth image".into())
        })?;
        // each box on its own (the pool's threads; the order kept)
        let segment = |b: &[f32; 4]| self.segment_box(depth, *b);
        Ok(
            if crate::perception::pool_is_parallel() && boxes.len() > 1 {
                boxes.par_iter().map(segment).collect()
            } else {
                boxes.iter().map(segment).collect()
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::Intrinsics;
    use nalgebra::Isometry3;

    /// A desk on the floor, seen by a camera 0.9 m up and pitched 20° down
    /// (160×120, f = 120 px), and a low box (0.1 m) on the floor in front
    /// of it, with floor in sight between them; the detector's box runs
    /// below the desk's foot over the low box, as a loose box does. The
    /// floor runs on at one depth from the desk's foot to the low box.
    /// Returns the depth image, the intrinsics, base_from_camera and the
    /// detector's box.
    fn desk_and_low_box() -> (DepthImage, Intrinsics, Isometry3<f64>, [f32; 4]) {
        let k = crate::msg::calibration::tests::intr_160x120();
        let p = 20f64.to_radians();
        // the optical axes (x right, y down, z forward) in base_link
        let r = nalgebra::Matrix3::new(
            0.0,
            -p.sin(),
            p.cos(),
            -1.0,
            0.0,
            0.0,
            0.0,
            -p.cos(),
            -p.sin(),
        );
        let rotation = nalgebra::UnitQuaternion::from_rotation_matrix(
            &nalgebra::Rotation3::from_matrix_unchecked(r),
        );
        let base_from_camera =
            Isometry3::from_parts(nalgebra::Translation3::new(0.0, 0.0, 0.9), rotation);
        let desk = ([2.0, -0.6, 0.0], [2.6, 0.6, 0.75]);
        let low = ([1.45, -0.3, 0.0], [1.6, 0.3, 0.1]);
        let o = base_from_camera.translation.vector;
        let mut d = vec![0.0f32; 160 * 120];
        for v in 0..120 {
            for u in 0..160 {
                let ray = nalgebra::Vector3::new(
                    (u as f64 - 80.0) / 120.0,
                    (v as f64 - 60.0) / 120.0,
                    1.0,
                );
                let dir = base_from_camera.rotation * ray;
                // the nearest hit along the ray (t is the optical depth)
                let mut t_hit = f64::INFINITY;
                if dir.z < 0.0 {
                    t_hit = -o.z / dir.z;
                }
                for (lo, hi) in [desk, low] {
                    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
                    for a in 0..3 {
                        let (ta, tb) = ((lo[a] - o[a]) / dir[a], (hi[a] - o[a]) / dir[a]);
                        t0 = t0.max(ta.min(tb));
                        t1 = t1.min(ta.max(tb));
                    }
                    if t0 <= t1 {
                        t_hit = t_hit.min(t0);
                    }
                }
                if t_hit.is_finite() && t_hit < 10.0 {
                    d[v * 160 + u] = t_hit as f32;
                }
            }
        }
        // the desk's corners in the image, the box run on to row 90
        let (mut u0, mut u1, mut v0) = (f64::MAX, f64::MIN, f64::MAX);
        for x in [desk.0[0], desk.1[0]] {
            for y in [desk.0[1], desk.1[1]] {
                for z in [desk.0[2], desk.1[2]] {
                    let c =
                        base_from_camera.inverse_transform_point(&nalgebra::Point3::new(x, y, z));
                    let (u, v) = (80.0 + 120.0 * c.x / c.z, 60.0 + 120.0 * c.y / c.z);
                    u0 = u0.min(u);
                    u1 = u1.max(u);
                    v0 = v0.min(v);
                }
            }
        }
        let depth = DepthImage::new(160, 120, d).unwrap();
        (
            depth,
            k,
            base_from_camera,
            [u0 as f32, v0 as f32, u1 as f32, 90.0],
        )
    }

    /// Each masked pixel's point in base_link.
    fn mask_points_in_base(
        mask: &Mask,
        depth: &DepthImage,
        base_from_camera: &Isometry3<f64>,
    ) -> Vec<nalgebra::Point3<f64>> {
        mask.pixels()
            .filter_map(|(u, v)| {
                let z = depth.at(u, v)? as f64;
                let c = nalgebra::Point3::new(
                    (u as f64 - 80.0) / 120.0 * z,
                    (v as f64 - 60.0) / 120.0 * z,
                    z,
                );
                Some(base_from_camera * c)
            })
            .collect()
    }

    #[test]
    fn the_floor_is_where_the_camera_sees_it() {
        let (depth, k, base_from_camera, _) = desk_and_low_box();
        let floor = FloorInImage::new(&k, &base_from_camera, 0.0);
        let mut checked = 0;
        for v in 0..120 {
            for u in 0..160 {
                if let Some(z) = depth.at(u, v) {
                    let c = nalgebra::Point3::new(
                        (u as f64 - 80.0) / 120.0 * z as f64,
                        (v as f64 - 60.0) / 120.0 * z as f64,
                        z as f64,
                    );
                    let want = (base_from_camera * c).z;
                    let got = floor.height_m(u, v, z) as f64;
                    assert!(
                        (got - want).abs() < 1e-4,
                        "({u}, {v}): {got} against {want}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 10_000, "{checked}");
    }

    #[test]
    fn the_floor_does_not_join_an_object_to_what_stands_in_front() {
        let (depth, k, base_from_camera, b) = desk_and_low_box();
        let mut seg = DepthBoxSegmenter::default();
        // the floor not known: the desk's mask runs over the floor to the
        // low box (points nearer than the desk's face, 2.0 m)
        let leaked = seg.segment_box(&depth, b);
        let pts = mask_points_in_base(&leaked, &depth, &base_from_camera);
        assert!(
            pts.iter().any(|p| p.x < 1.6 && p.z > 0.05),
            "the low box is not in it"
        );
        assert!(
            pts.iter().any(|p| p.x < 1.9 && p.z.abs() < 0.01),
            "no floor in it"
        );
        // known: the desk alone
        seg.set_floor(Some(FloorInImage::new(&k, &base_from_camera, 0.0)));
        let mask = seg.segment_box(&depth, b);
        let pts = mask_points_in_base(&mask, &depth, &base_from_camera);
        assert!(pts.len() > 1_000, "{} points", pts.len());
        assert!(
            pts.iter().all(|p| p.x > 1.99 && p.z > 0.05),
            "{:?}",
            pts.iter().find(|p| p.x <= 1.99 || p.z <= 0.05)
        );
        // and the desk's face down to its foot's band
        assert!(pts.iter().any(|p| p.z < 0.1), "the desk's foot is cut off");
    }

    /// 40×30 scene: wall at 3 m, a 10×10 box object at 1.5 m at (15..25, 10..20),
    /// a second object at 1.0 m at (0..5, 0..30) outside the prompt box.
    fn scene() -> DepthImage {
        let (w, h) = (40, 30);
        let mut d = vec![3.0f32; w * h];
        for v in 10..20 {
            for u in 15..25 {
                d[v * w + u] = 1.5 + 0.001 * (u as f32 - 15.0);
            }
        }
        for v in 0..30 {
            for u in 0..5 {
                d[v * w + u] = 1.0;
            }
        }
        d[12 * w + 17] = 0.0; // a hole
        DepthImage::new(w, h, d).unwrap()
    }

    #[test]
    fn object_in_front_of_a_wall_is_segmented_exactly() {
        let s = DepthBoxSegmenter::default();
        let d = scene();
        // loose box around the object, reaching into the wall
        let m = s.segment_box(&d, [12.0, 7.0, 28.0, 23.0]);
        assert_eq!(m.count(), 99);
        for (u, v) in m.pixels() {
            assert!((15..25).contains(&u) && (10..20).contains(&v), "({u},{v})");
        }
    }

    /// 80×60: a wall at 4 m; a bookshelf at 2.8 m over (20..60, 5..50);
    /// before it a chair at 1.2 m over (30..50, 15..58), reaching below
    /// the bookshelf to the floor. The detector boxes the bookshelf's
    /// visible pixels: the chair fills the box's middle.
    fn chair_before_a_bookshelf() -> DepthImage {
        let (w, h) = (80, 60);
        let mut d = vec![4.0f32; w * h];
        for v in 0..h {
            for u in 0..w {
                if (30..50).contains(&u) && (15..58).contains(&v) {
                    d[v * w + u] = 1.2;
                } else if (20..60).contains(&u) && (5..50).contains(&v) {
                    d[v * w + u] = 2.8 + 0.001 * (u as f32 - 20.0);
                }
            }
        }
        DepthImage::new(w, h, d).unwrap()
    }

    #[test]
    fn what_stands_before_the_boxed_object_is_not_its_mask() {
        let s = DepthBoxSegmenter::default();
        let d = chair_before_a_bookshelf();
        let bookshelf = [20.0, 5.0, 60.0, 50.0];
        // the central mode is the chair's
        let central = s.central_region(&d, bookshelf).expect("depth in the box");
        assert!(central.pixels().all(|(u, v)| d.at(u, v) == Some(1.2)));
        // the mask is the bookshelf's visible pixels, all of them
        let m = s.segment_box(&d, bookshelf);
        let visible = (20..60)
            .flat_map(|u| (5..50).map(move |v| (u, v)))
            .filter(|&(u, v)| !((30..50).contains(&u) && v >= 15))
            .count();
        assert_eq!(m.count(), visible);
        assert!(m
            .pixels()
            .all(|(u, v)| d.at(u, v).is_some_and(|z| (2.79..2.9).contains(&z))));
        // the chair's own box still gives the chair, within the box
        let m = s.segment_box(&d, [30.0, 15.0, 50.0, 58.0]);
        assert_eq!(m.count(), 20 * 43);
        // a box loose about the chair, into the bookshelf and the wall
        // around it, still gives the chair: the bookshelf runs on past
        // the box's edges
        let m = s.segment_box(&d, [26.0, 10.0, 54.0, 60.0]);
        assert!(m.pixels().all(|(u, v)| d.at(u, v) == Some(1.2)));
        assert_eq!(m.count(), 20 * 43);
    }

    #[test]
    fn growth_stays_inside_the_box() {
        let s = DepthBoxSegmenter::default();
        let d = scene();
        // box over part of the near column: mask is the box ∩ column
        let m = s.segment_box(&d, [0.0, 5.0, 4.0, 15.0]);
        assert_eq!(m.count(), 4 * 10);
    }

    #[test]
    fn box_without_depth_gives_an_empty_mask() {
        let d = DepthImage::new(10, 10, vec![0.0; 100]).unwrap();
        let m = DepthBoxSegmenter::default().segment_box(&d, [1.0, 1.0, 8.0, 8.0]);
        assert_eq!(m.count(), 0);
        let m = DepthBoxSegmenter::default().segment_box(&d, [20.0, 20.0, 30.0, 30.0]);
        assert_eq!(m.count(), 0);
    }

    /// The region growing as first written (a BTreeMap histogram and a
    /// breadth-first queue through the mask's own accessors): the faster
    /// one must give its masks pixel for pixel.
    fn reference_mask(s: &DepthSegmenterSettings, depth: &DepthImage, xyxy: [f32; 4]) -> Mask {
        let (w, h) = (depth.width(), depth.height());
        let mut mask = Mask::for_box(w, h, xyxy);
        let (x0, y0, bw, bh) = mask.region();
        if bw == 0 || bh == 0 {
            return mask;
        }
        let cf = s.center_fraction.clamp(0.05, 1.0);
        let cx0 = x0 + ((bw as f32 * (1.0 - cf) / 2.0) as usize);
        let cy0 = y0 + ((bh as f32 * (1.0 - cf) / 2.0) as usize);
        let cx1 = (x0 + bw - ((bw as f32 * (1.0 - cf) / 2.0) as usize)).max(cx0 + 1);
        let cy1 = (y0 + bh - ((bh as f32 * (1.0 - cf) / 2.0) as usize)).max(cy0 + 1);
        let mut bins: std::collections::BTreeMap<u32, usize> = Default::default();
        for v in cy0..cy1.min(h) {
            for u in cx0..cx1.min(w) {
                if let Some(z) = depth.at(u, v) {
                    *bins.entry((z / s.bin_m) as u32).or_default() += 1;
                }
            }
        }
        let mut best: Option<(u32, usize)> = None;
        for (&b, &n) in &bins {
            if best.is_none_or(|(_, bn)| n > bn) {
                best = Some((b, n));
            }
        }
        let Some((bin, _)) = best else { return mask };
        let mode = (bin as f32 + 0.5) * s.bin_m;
        let mut queue = std::collections::VecDeque::new();
        for v in cy0..cy1.min(h) {
            for u in cx0..cx1.min(w) {
                if let Some(z) = depth.at(u, v) {
                    if (z - mode).abs() <= s.mode_tolerance_m.max(s.bin_m / 2.0)
                        && mask.set(u, v, true)
                    {
                        queue.push_back((u, v, z));
                    }
                }
            }
        }
        while let Some((u, v, z)) = queue.pop_front() {
            let step = s.step_m + s.step_per_m * z;
            let mut visit = |nu: usize, nv: usize| {
                if mask.get(nu, nv) {
                    return;
                }
                if let Some(nz) = depth.at(nu, nv) {
                    if (nz - z).abs() <= step && mask.set(nu, nv, true) {
                        queue.push_back((nu, nv, nz));
                    }
                }
            };
            if u > x0 {
                visit(u - 1, v);
            }
            if u + 1 < x0 + bw {
                visit(u + 1, v);
            }
            if v > y0 {
                visit(u, v - 1);
            }
            if v + 1 < y0 + bh {
                visit(u, v + 1);
            }
        }
        mask
    }

    #[test]
    fn masks_are_the_first_written_growings_pixel_for_pixel() {
        let mut rng = crate::sim::scene::SplitMix64::new(0x5E6_0001);
        for case in 0..300 {
            let (w, h) = (20 + rng.below(60), 15 + rng.below(50));
            // a sloping wall, blobs at other depths, holes and noise
            let mut d: Vec<f32> = (0..w * h)
                .map(|i| 2.0 + 0.01 * (i % w) as f32 + rng.range(-0.01, 0.01) as f32)
                .collect();
            for _ in 0..rng.below(6) {
                let (bu, bv) = (rng.below(w), rng.below(h));
                let (bw, bh) = (1 + rng.below(w / 2), 1 + rng.below(h / 2));
                let z = rng.range(0.3, 6.0) as f32;
                for v in bv..(bv + bh).min(h) {
                    for u in bu..(bu + bw).min(w) {
                        d[v * w + u] = z + rng.range(-0.03, 0.03) as f32;
                    }
                }
            }
            for _ in 0..rng.below(w * h / 10) {
                let i = rng.below(w * h);
                d[i] = if rng.unit() < 0.5 { 0.0 } else { f32::NAN };
            }
            let depth = DepthImage::new(w, h, d).unwrap();
            let settings = DepthSegmenterSettings {
                bin_m: [0.05, 0.2, 1e-6][rng.below(3)] as f32,
                center_fraction: rng.range(0.0, 1.2) as f32,
                mode_tolerance_m: rng.range(0.0, 0.2) as f32,
                step_m: rng.range(0.0, 0.1) as f32,
                step_per_m: rng.range(0.0, 0.05) as f32,
                floor_band_m: 0.05,
            };
            let x0 = rng.range(-5.0, w as f64) as f32;
            let y0 = rng.range(-5.0, h as f64) as f32;
            let b = [
                x0,
                y0,
                x0 + rng.range(0.0, w as f64) as f32,
                y0 + rng.range(0.0, h as f64) as f32,
            ];
            let s = DepthBoxSegmenter::new(settings.clone());
            let got = s
                .central_region(&depth, b)
                .unwrap_or_else(|| Mask::for_box(w, h, b));
            let want = reference_mask(&settings, &depth, b);
            assert_eq!(got.region(), want.region(), "case {case}");
            let (got, want): (Vec<_>, Vec<_>) = (got.pixels().collect(), want.pixels().collect());
            assert_eq!(got, want, "case {case}: box {b:?}, {settings:?}");
        }
    }
}
