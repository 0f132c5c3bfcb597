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
//!    grows with range), staying inside the box. Seeds chosen by depth
//!    alone can lie on two surfaces apart (a bin's face before a
//!    bookshelf seen obliquely): only the grown surface holding the most
//!    seeds is kept.
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
        // the free pixels' bins counted once; each growth's new pixels
        // are taken off as they join `taken`
        let mut bins = Vec::new();
        let total = self.bins_in(depth, whole, Some(&primary), &mut bins);
        let mut free = BinCounts::of(&bins);
        let mut free_px = bins.len();
        let mut taken = primary.clone();
        let mut best = (primary_fit, primary);
        for _ in 0..OTHER_MODES {
            if (free_px as f64) < OTHER_MODE_SHARE * total as f64 {
                break;
            }
            let Some(bin) = free.fullest() else {
                break;
            };
            let other = self.mode_of(bin);
            let grown = self.grow_where(depth, mask.clone(), whole, other, Some(&taken));
            // (both over the box's region; a grown pixel's depth is valid
            // and above the floor)
            let w = depth.width();
            for y in 0..bh {
                let row = &depth.data()[(y0 + y) * w + x0..][..bw];
                let (t, g) = (
                    &mut taken.region_bits_mut()[y * bw..][..bw],
                    grown.region_row(y),
                );
                for ((t, &g), &z) in t.iter_mut().zip(g).zip(row) {
                    if g && !*t {
                        *t = true;
                        free.remove(self.bin_of(z));
                        free_px -= 1;
                    }
                }
            }
            let better = best.0 + BETTER_BOX_FIT;
            if let Some(fit) = self.box_fit_over(depth, &grown, better) {
                if fit > better {
                    best = (fit, grown);
                }
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
        let mut bins = Vec::new();
        self.bins_in(depth, [cx0, cy0, cx1, cy1], None, &mut bins);
        let bin = BinCounts::of(&bins).fullest()?;
        let mode = self.mode_of(bin);
        let seeds = [cx0, cy0, cx1, cy1];
        // most often every seed lies on the first one's surface: grown
        // from it alone, the region is then that surface (one growth, no
        // labels)
        let seeds_at = self.seeds_at(mode);
        let is_seed = |u: usize, v: usize| depth.at(u, v).is_some_and(|z| seeds_at(u, v, z));
        let (rx1, ry1) = ((x0 + bw).min(cx1), (y0 + bh).min(cy1));
        let mut in_seeds = (cy0..ry1).flat_map(|v| (cx0..rx1).map(move |u| (u, v)));
        let Some((u, v)) = in_seeds.find(|&(u, v)| is_seed(u, v)) else {
            return Some(mask);
        };
        let first = self.grow_where(depth, mask.clone(), [u, v, u + 1, v + 1], mode, None);
        if in_seeds.all(|(u, v)| first.get(u, v) || !is_seed(u, v)) {
            return Some(first);
        }
        Some(self.seeds_surface(depth, mask, seeds, mode))
    }

    /// Steps 2 and 3 with the surfaces told apart: the region grown from
    /// the seeds of `seeds` (image coordinates, clipped to the mask's
    /// region) within the tolerance of `mode`, kept only on the one
    /// surface (its pixels joined by the growth's depth steps) that holds
    /// the most of them. The seeds are chosen by depth alone, and two
    /// surfaces apart can share it (a bin's face before a bookshelf seen
    /// obliquely, both about 1.6 m off at the mode; grown together, the
    /// bin came into the bookshelf's mask and its box).
    ///
    /// One growth does both: each seed not yet reached starts a surface of
    /// its own, grown to all it reaches, and each seed counts for the
    /// surface that holds it. As the growth's step holds either way
    /// between two pixels (up to the step's own slope with depth), the
    /// surfaces are those of the whole region whatever the seeds' order.
    fn seeds_surface(
        &self,
        depth: &DepthImage,
        mut mask: Mask,
        seeds: [usize; 4],
        mode: f32,
    ) -> Mask {
        let (x0, y0, bw, bh) = mask.region();
        let seeds_at = self.seeds_at(mode);
        // each pixel's surface (0: none), and each surface's seeds
        let mut label = vec![0u32; bw * bh];
        let mut seeds_of: Vec<u32> = vec![0];
        let mut stack: Vec<(u32, u32, f32)> = Vec::new();
        for v in seeds[1].max(y0)..seeds[3].min(y0 + bh) {
            for u in seeds[0].max(x0)..seeds[2].min(x0 + bw) {
                let Some(z) = depth.at(u, v) else { continue };
                if !seeds_at(u, v, z) {
                    continue;
                }
                let (x, y) = (u - x0, v - y0);
                let i = y * bw + x;
                if label[i] == 0 {
                    let id = seeds_of.len() as u32;
                    seeds_of.push(0);
                    label[i] = id;
                    stack.push((x as u32, y as u32, z));
                    self.flood::<_, false>(
                        depth,
                        [x0, y0],
                        bw,
                        bh,
                        &mut label,
                        id,
                        &mut stack,
                        usize::MAX,
                    );
                }
                seeds_of[label[i] as usize] += 1;
            }
        }
        // the most seeds (ties: the surface of the first seed, row by row)
        let bits = mask.region_bits_mut();
        if seeds_of.len() <= 2 {
            for (b, &l) in bits.iter_mut().zip(&label) {
                *b = l != 0;
            }
            return mask;
        }
        let mut keep = 1u32;
        for (id, &n) in seeds_of.iter().enumerate().skip(1) {
            if n > seeds_of[keep as usize] {
                keep = id as u32;
            }
        }
        for (b, &l) in bits.iter_mut().zip(&label) {
            *b = l == keep;
        }
        mask
    }

    fn bin_of(&self, z: f32) -> u32 {
        (z / self.settings.bin_m) as u32
    }

    fn mode_of(&self, bin: u32) -> f32 {
        (bin as f32 + 0.5) * self.settings.bin_m
    }

    /// Whether a pixel (`u`, `v`) at depth `z` (valid) seeds a region of
    /// depth `mode`: within the tolerance of the mode, above the floor.
    #[inline]
    fn seeds_at(&self, mode: f32) -> impl Fn(usize, usize, f32) -> bool + '_ {
        let s = &self.settings;
        let tolerance = s.mode_tolerance_m.max(s.bin_m / 2.0);
        move |u, v, z| (z - mode).abs() <= tolerance && self.above(u, v, z)
    }

    /// Above the floor's band (everything when the floor is not known).
    #[inline]
    fn above(&self, u: usize, v: usize, z: f32) -> bool {
        self.floor
            .is_none_or(|f| f.height_m(u, v, z) > self.settings.floor_band_m)
    }

    /// The bins of the valid depths above the floor in `[x0, y0, x1, y1)`
    /// (clipped to the image), row by row, leaving out the pixels `taken`
    /// holds (a mask whose region is that rectangle). Returns how many
    /// valid depths above the floor the rectangle holds, taken or not.
    #[inline(always)]
    fn bins_in(
        &self,
        depth: &DepthImage,
        [x0, y0, x1, y1]: [usize; 4],
        taken: Option<&Mask>,
        out: &mut Vec<u32>,
    ) -> usize {
        let (w, h, data) = (depth.width(), depth.height(), depth.data());
        let (x1, y1) = (x1.min(w), y1.min(h));
        let mut all = 0;
        if x0 >= x1 {
            return all;
        }
        for v in y0..y1 {
            let row = &data[v * w + x0..v * w + x1];
            // (the pixels `taken` holds, or none: the central histogram's
            // row stays the plain loop it was)
            let held = taken.map_or(&[][..], |m| m.region_row(v - y0));
            for (x, &z) in row.iter().enumerate() {
                if crate::msg::is_valid_depth(z) && self.above(x0 + x, v, z) {
                    all += 1;
                    if held.is_empty() || !held[x] {
                        out.push(self.bin_of(z));
                    }
                }
            }
        }
        all
    }

    /// The region grown from the pixels of `seeds` (image coordinates,
    /// clipped to the mask's region) within the tolerance of `mode` and
    /// not held by `taken` (a mask over the same region), over region
    /// indices. A pixel joins once and is grown from once, so the mask is
    /// every pixel reachable from the seeds whatever the order (a stack
    /// here).
    fn grow_where(
        &self,
        depth: &DepthImage,
        mut mask: Mask,
        seeds: [usize; 4],
        mode: f32,
        taken: Option<&Mask>,
    ) -> Mask {
        let (x0, y0, bw, bh) = mask.region();
        debug_assert!(taken.is_none_or(|m| m.region() == mask.region()));
        let seeds_at = self.seeds_at(mode);
        let mut stack: Vec<(u32, u32, f32)> = Vec::new();
        // row by row over slices: the seeds' columns in the region
        let (sx0, sx1) = (seeds[0].max(x0), seeds[2].min(x0 + bw));
        let (w, data) = (depth.width(), depth.data());
        for v in seeds[1].max(y0)..seeds[3].min(y0 + bh) {
            if sx0 >= sx1 {
                break;
            }
            let y = v - y0;
            let row = &data[v * w + sx0..v * w + sx1];
            let held = taken.map_or(&[][..], |m| &m.region_row(y)[sx0 - x0..sx1 - x0]);
            let bits = &mut mask.region_bits_mut()[y * bw + sx0 - x0..y * bw + sx1 - x0];
            for (k, (&z, bit)) in row.iter().zip(bits).enumerate() {
                if crate::msg::is_valid_depth(z)
                    && seeds_at(sx0 + k, v, z)
                    && (held.is_empty() || !held[k])
                    && !*bit
                {
                    *bit = true;
                    stack.push(((sx0 - x0 + k) as u32, y as u32, z));
                }
            }
        }
        self.flood::<_, false>(
            depth,
            [x0, y0],
            bw,
            bh,
            mask.region_bits_mut(),
            true,
            &mut stack,
            usize::MAX,
        );
        mask
    }

    /// The growing itself, over a region of the image (`origin` its top
    /// left pixel, `rw` × `rh`, row-major `marks`): from the pixels on
    /// `stack` (region coordinates, depth), a 4-neighbour joins where it
    /// is not marked yet (`T::default()`), its depth is valid and above the
    /// floor and within the step of the pixel it is reached from; it is
    /// marked `id` and grown from in turn. Returns how many joined; when
    /// `BOUNDED`, stops as soon as more than `at_most` have (the check is
    /// left out of the other floods' inner loop).
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn flood<T: Copy + Default + PartialEq, const BOUNDED: bool>(
        &self,
        depth: &DepthImage,
        [ox, oy]: [usize; 2],
        rw: usize,
        rh: usize,
        marks: &mut [T],
        id: T,
        stack: &mut Vec<(u32, u32, f32)>,
        at_most: usize,
    ) -> usize {
        let s = &self.settings;
        let (stride, data) = (depth.width(), depth.data());
        let unmarked = T::default();
        let mut joined = 0usize;
        while let Some((x, y, z)) = stack.pop() {
            let (x, y) = (x as usize, y as usize);
            let step = s.step_m + s.step_per_m * z;
            each_neighbour!(y * rw + x, x, y, rw, rh, |j, nx, ny| {
                if marks[j] == unmarked {
                    let nz = data[(oy + ny) * stride + ox + nx];
                    if crate::msg::is_valid_depth(nz)
                        && (nz - z).abs() <= step
                        && self.above(ox + nx, oy + ny, nz)
                    {
                        marks[j] = id;
                        joined += 1;
                        stack.push((nx as u32, ny as u32, nz));
                        if BOUNDED && joined > at_most {
                            return joined;
                        }
                    }
                }
            });
        }
        joined
    }

    /// How well a grown mask fits its box, 0–1: the share of the box its
    /// set pixels' bounds span, times the share of a ring around the box
    /// ([`RING_FRACTION`] of the box's smaller side wide) that the same
    /// growth would reach past the box's edges, taken from one. An object
    /// its box hugs spans the box and stops at its edges; what stands in
    /// front spans part of it or runs on past it, and a wall behind runs
    /// on all round.
    fn box_fit(&self, depth: &DepthImage, mask: &Mask) -> f64 {
        self.box_fit_over(depth, mask, f64::NEG_INFINITY)
            .unwrap_or(0.0)
    }

    /// [`Self::box_fit`] where it may exceed `over`; None where it cannot
    /// (the ring's growth stops as soon as it has reached too far).
    fn box_fit_over(&self, depth: &DepthImage, mask: &Mask, over: f64) -> Option<f64> {
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
            return (0.0 > over).then_some(0.0);
        }
        let spans = ((hi[0] - lo[0]) * (hi[1] - lo[1])) as f64 / (bw * bh) as f64;
        // the fit is at most `spans`
        if spans <= over {
            return None;
        }
        // the ring, clipped to the image
        let (w, h) = (depth.width(), depth.height());
        let m = ((RING_FRACTION * bw.min(bh) as f64).ceil() as usize).max(2);
        let (rx0, ry0) = (x0.saturating_sub(m), y0.saturating_sub(m));
        let (rx1, ry1) = ((x0 + bw + m).min(w), (y0 + bh + m).min(h));
        let (rw, rh) = (rx1 - rx0, ry1 - ry0);
        let ring_px = rw * rh - bw * bh;
        if ring_px == 0 {
            return Some(spans);
        }
        // the fit, spans · (1 − reached / ring), exceeds `over` only with
        // reached < ring · (1 − over / spans): one more is never needed
        let at_most = if over.is_finite() {
            ((ring_px as f64 * (1.0 - over / spans)).max(0.0) as usize).saturating_add(1)
        } else {
            usize::MAX
        };
        // the ring's pixels reached, over the ring's bounds; the box's own
        // are marked reached beforehand, so the growth never enters it
        let mut reached = vec![false; rw * rh];
        let (bx, by) = (x0 - rx0, y0 - ry0);
        for y in by..by + bh {
            reached[y * rw + bx..y * rw + bx + bw].fill(true);
        }
        let mut stack: Vec<(u32, u32, f32)> = Vec::new();
        // from the mask's pixels on the box's edges (the region's first
        // and last rows and columns; it holds a pixel, so it is not empty)
        let mut from_edge = |x: usize, y: usize| {
            if mask.region_row(y)[x] {
                if let Some(z) = depth.at(x0 + x, y0 + y) {
                    stack.push(((bx + x) as u32, (by + y) as u32, z));
                }
            }
        };
        for x in 0..bw {
            from_edge(x, 0);
            if bh > 1 {
                from_edge(x, bh - 1);
            }
        }
        for y in 1..bh.saturating_sub(1) {
            from_edge(0, y);
            if bw > 1 {
                from_edge(bw - 1, y);
            }
        }
        // (bounded for the primary too, at usize::MAX: one compare a
        // pixel reached)
        let count = self.flood::<_, true>(
            depth,
            [rx0, ry0],
            rw,
            rh,
            &mut reached,
            true,
            &mut stack,
            at_most,
        );
        (count <= at_most).then(|| spans * (1.0 - count as f64 / ring_px as f64))
    }
}

/// The 4 neighbours of pixel `i`, at (`x`, `y`) in a region `bw` × `bh`
/// (row-major): `body` with `j`, `nx`, `ny` bound to each one's index and
/// coordinates, for each within the region. A macro, not a function
/// taking a closure: the body is written out four times in place (as a
/// closure it was called, not inlined, and the calls were a fifth of the
/// growing's time).
macro_rules! each_neighbour {
    ($i:expr, $x:expr, $y:expr, $bw:expr, $bh:expr, |$j:ident, $nx:ident, $ny:ident| $body:block) => {{
        let (i, x, y, bw, bh): (usize, usize, usize, usize, usize) = ($i, $x, $y, $bw, $bh);
        if x > 0 {
            let ($j, $nx, $ny) = (i - 1, x - 1, y);
            $body
        }
        if x + 1 < bw {
            let ($j, $nx, $ny) = (i + 1, x + 1, y);
            $body
        }
        if y > 0 {
            let ($j, $nx, $ny) = (i - bw, x, y - 1);
            $body
        }
        if y + 1 < bh {
            let ($j, $nx, $ny) = (i + bw, x, y + 1);
            $body
        }
    }};
}
use each_neighbour;

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

/// Counts of depth bins: a flat table, or an ordered map where a bin width
/// so small would make the table huge.
enum BinCounts {
    Flat(Vec<u32>),
    Map(std::collections::BTreeMap<u32, u32>),
}

impl BinCounts {
    fn of(bins: &[u32]) -> BinCounts {
        const FLAT_BINS: u32 = 1 << 16;
        let max = bins.iter().copied().max().unwrap_or(0);
        if max < FLAT_BINS {
            let mut counts = vec![0u32; max as usize + 1];
            for &b in bins {
                counts[b as usize] += 1;
            }
            BinCounts::Flat(counts)
        } else {
            let mut counts = std::collections::BTreeMap::new();
            for &b in bins {
                *counts.entry(b).or_default() += 1;
            }
            BinCounts::Map(counts)
        }
    }

    /// One pixel of `bin` (counted) taken off.
    fn remove(&mut self, bin: u32) {
        let n = match self {
            BinCounts::Flat(counts) => counts.get_mut(bin as usize),
            BinCounts::Map(counts) => counts.get_mut(&bin),
        };
        // (a pixel is taken off only once, and only one that was counted)
        debug_assert!(
            n.as_ref().is_some_and(|n| **n > 0),
            "bin {bin} taken off but not counted"
        );
        if let Some(n) = n {
            *n = n.saturating_sub(1);
        }
    }

    /// The fullest bin (ties: the lowest, the nearer depth); None when
    /// every count is 0.
    fn fullest(&self) -> Option<u32> {
        // near to far: strict > keeps the nearer on ties
        let mut best: Option<(u32, u32)> = None;
        let mut see = |b: u32, n: u32| {
            if n > 0 && best.is_none_or(|(_, bn)| n > bn) {
                best = Some((b, n));
            }
        };
        match self {
            BinCounts::Flat(counts) => {
                for (b, &n) in counts.iter().enumerate() {
                    see(b as u32, n);
                }
            }
            BinCounts::Map(counts) => {
                for (&b, &n) in counts {
                    see(b, n);
                }
            }
        }
        best.map(|(b, _)| b)
    }
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
#[path = "depth_tests.rs"]
mod tests;
