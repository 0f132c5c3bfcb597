//! Binary masks over a region of the colour image, and the paper's 3×3
//! morphological erosion (step 3).

/// A binary mask stored over its region of interest: pixel (u, v) of the
/// image is `bits[(v - y0) * w + (u - x0)]` inside the region and unset
/// outside it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Mask {
    image_width: usize,
    image_height: usize,
    x0: usize,
    y0: usize,
    w: usize,
    h: usize,
    bits: Vec<bool>,
}

impl Mask {
    /// An empty mask whose region is the box `[x0, x1) × [y0, y1)`, clipped to
    /// the image.
    pub fn empty_in(
        image_width: usize,
        image_height: usize,
        x0: usize,
        y0: usize,
        x1: usize,
        y1: usize,
    ) -> Mask {
        let x0 = x0.min(image_width);
        let y0 = y0.min(image_height);
        let x1 = x1.clamp(x0, image_width);
        let y1 = y1.clamp(y0, image_height);
        let (w, h) = (x1 - x0, y1 - y0);
        Mask {
            image_width,
            image_height,
            x0,
            y0,
            w,
            h,
            bits: vec![false; w * h],
        }
    }

    /// Region covering the pixels of a box in image coordinates
    /// (`[x1, y1, x2, y2]`, pixel edges), clipped.
    pub fn for_box(image_width: usize, image_height: usize, xyxy: [f32; 4]) -> Mask {
        let x0 = xyxy[0].floor().max(0.0) as usize;
        let y0 = xyxy[1].floor().max(0.0) as usize;
        let x1 = xyxy[2].ceil().max(0.0) as usize;
        let y1 = xyxy[3].ceil().max(0.0) as usize;
        Mask::empty_in(image_width, image_height, x0, y0, x1, y1)
    }

    /// A full-image mask from a row-major boolean buffer.
    pub fn from_full(image_width: usize, image_height: usize, bits: Vec<bool>) -> Option<Mask> {
        (bits.len() == image_width * image_height).then_some(Mask {
            image_width,
            image_height,
            x0: 0,
            y0: 0,
            w: image_width,
            h: image_height,
            bits,
        })
    }

    pub fn image_size(&self) -> (usize, usize) {
        (self.image_width, self.image_height)
    }

    /// The region as `(x0, y0, width, height)`.
    pub fn region(&self) -> (usize, usize, usize, usize) {
        (self.x0, self.y0, self.w, self.h)
    }

    #[inline]
    pub fn get(&self, u: usize, v: usize) -> bool {
        if u < self.x0 || v < self.y0 || u >= self.x0 + self.w || v >= self.y0 + self.h {
            return false;
        }
        self.bits[(v - self.y0) * self.w + (u - self.x0)]
    }

    /// Sets a pixel; pixels outside the region are ignored (returns false).
    #[inline]
    pub fn set(&mut self, u: usize, v: usize, on: bool) -> bool {
        if u < self.x0 || v < self.y0 || u >= self.x0 + self.w || v >= self.y0 + self.h {
            return false;
        }
        self.bits[(v - self.y0) * self.w + (u - self.x0)] = on;
        true
    }

    /// The region's pixels, row-major (region coordinates), to set in place.
    #[inline]
    pub fn region_bits_mut(&mut self) -> &mut [bool] {
        &mut self.bits
    }

    /// The region's pixels, row-major (region coordinates).
    #[inline]
    pub fn region_bits(&self) -> &[bool] {
        &self.bits
    }

    /// Row `y` of the region (region coordinates) as booleans.
    #[inline]
    pub fn region_row(&self, y: usize) -> &[bool] {
        &self.bits[y * self.w..(y + 1) * self.w]
    }

    pub fn count(&self) -> usize {
        count_set(&self.bits)
    }

    /// Set pixels as (u, v) image coordinates, row-major.
    pub fn pixels(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.bits
            .iter()
            .enumerate()
            .filter(|(_, &b)| b)
            .map(move |(i, _)| (self.x0 + i % self.w.max(1), self.y0 + i / self.w.max(1)))
    }

    /// Morphological erosion with a 3×3 square structuring element, applied
    /// `iterations` times: a pixel stays set only if its 8 neighbours and
    /// itself are set. Beyond the image border counts as set (OpenCV's
    /// `erode` default), so an object cut by the frame edge is not eaten
    /// from that side; beyond the mask's region inside the image counts as
    /// unset.
    pub fn eroded(&self, iterations: usize) -> Mask {
        let mut cur = self.clone();
        for _ in 0..iterations {
            cur = cur.erode_once();
        }
        cur
    }

    /// One 3×3 erosion as a horizontal then a vertical 3-wide minimum
    /// (the square element is separable). Neighbours beyond the image count
    /// as set; beyond the region but inside the image, as unset.
    fn erode_once(&self) -> Mask {
        let (w, h) = (self.w, self.h);
        if w == 0 || h == 0 {
            return self.clone();
        }
        // what lies just outside each side of the region
        let left_out = self.x0 == 0;
        let right_out = self.x0 + w >= self.image_width;
        let top_out = self.y0 == 0;
        let bottom_out = self.y0 + h >= self.image_height;
        let mut horiz = vec![false; w * h];
        for y in 0..h {
            let row = &self.bits[y * w..(y + 1) * w];
            let out = &mut horiz[y * w..(y + 1) * w];
            for x in 0..w {
                let l = if x == 0 { left_out } else { row[x - 1] };
                let r = if x + 1 == w { right_out } else { row[x + 1] };
                out[x] = l & row[x] & r;
            }
        }
        let mut bits = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let c = horiz[y * w + x];
                if !c {
                    continue;
                }
                // beyond the image the neighbour row counts as set; a row
                // beyond the region inside the image is unset
                let up = if y == 0 {
                    top_out
                } else {
                    horiz[(y - 1) * w + x]
                };
                let down = if y + 1 == h {
                    bottom_out
                } else {
                    horiz[(y + 1) * w + x]
                };
                bits[y * w + x] = up & down;
            }
        }
        Mask {
            bits,
            ..self.clone_header()
        }
    }

    /// One 3×3 erosion, row by row without the eroded mask: `f(y, row)`
    /// for each row `y` of the region, its eroded bits — exactly
    /// [`eroded`](Self::eroded)`(1)`'s rows (same edge rules), from three
    /// rolling rows of the horizontal pass.
    pub fn for_each_eroded_row(&self, mut f: impl FnMut(usize, &[bool])) {
        let (w, h) = (self.w, self.h);
        if w == 0 || h == 0 {
            return;
        }
        let left_out = self.x0 == 0;
        let right_out = self.x0 + w >= self.image_width;
        let top_out = self.y0 == 0;
        let bottom_out = self.y0 + h >= self.image_height;
        // the interior without a branch per pixel (the compiler vectorises
        // the zipped slices); the two ends with the image's edge rules
        let horiz = |y: usize, out: &mut [bool]| {
            let row = &self.bits[y * w..(y + 1) * w];
            if w == 1 {
                out[0] = left_out & row[0] & right_out;
                return;
            }
            and3(&mut out[1..w - 1], &row[..w - 2], &row[1..w - 1], &row[2..]);
            out[0] = left_out & row[0] & row[1];
            out[w - 1] = row[w - 2] & row[w - 1] & right_out;
        };
        // rows y−1, y, y+1 of the horizontal pass (beyond the image: set;
        // beyond the region inside it: unset)
        let mut up = vec![top_out; w];
        let mut mid = vec![false; w];
        let mut down = vec![false; w];
        let mut out = vec![false; w];
        horiz(0, &mut mid);
        for y in 0..h {
            if y + 1 < h {
                horiz(y + 1, &mut down);
            } else {
                down.fill(bottom_out);
            }
            and3(&mut out, &up, &mid, &down);
            f(y, &out);
            std::mem::swap(&mut up, &mut mid);
            std::mem::swap(&mut mid, &mut down);
        }
    }

    fn clone_header(&self) -> Mask {
        Mask {
            image_width: self.image_width,
            image_height: self.image_height,
            x0: self.x0,
            y0: self.y0,
            w: self.w,
            h: self.h,
            bits: Vec::new(),
        }
    }
}

/// How many of `bits` are set (one add per element, no overflow check:
/// the count cannot pass the slice's length), in a form the compiler
/// vectorises.
#[inline]
pub fn count_set(bits: &[bool]) -> usize {
    bits.iter()
        .fold(0usize, |n, &b| n.wrapping_add(usize::from(b)))
}

/// `out[i] = a[i] & b[i] & c[i]` over `out`'s length (the inputs as long
/// at least), indexed over slices of one length so that the compiler drops
/// the bounds checks and vectorises it.
#[inline]
fn and3(out: &mut [bool], a: &[bool], b: &[bool], c: &[bool]) {
    let n = out.len();
    let (a, b, c) = (&a[..n], &b[..n], &c[..n]);
    for i in 0..n {
        out[i] = a[i] & b[i] & c[i];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from_rows(rows: &[&str]) -> Mask {
        let h = rows.len();
        let w = rows[0].len();
        let bits = rows
            .iter()
            .flat_map(|r| r.chars().map(|c| c == '#'))
            .collect();
        Mask::from_full(w, h, bits).unwrap()
    }

    fn to_rows(m: &Mask) -> Vec<String> {
        let (w, h) = m.image_size();
        (0..h)
            .map(|v| {
                (0..w)
                    .map(|u| if m.get(u, v) { '#' } else { '.' })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn erosion_of_a_square_removes_its_rim() {
        let m = from_rows(&[
            ".......", ".#####.", ".#####.", ".#####.", ".#####.", ".#####.", ".......",
        ]);
        let e = m.eroded(1);
        assert_eq!(
            to_rows(&e),
            vec![".......", ".......", "..###..", "..###..", "..###..", ".......", "......."]
        );
        assert_eq!(m.eroded(2).count(), 1);
        assert_eq!(m.eroded(3).count(), 0);
    }

    #[test]
    fn erosion_removes_thin_lines_and_isolated_pixels() {
        let m = from_rows(&["......", ".#....", "......", "######", "......"]);
        assert_eq!(m.eroded(1).count(), 0);
    }

    #[test]
    fn image_border_does_not_erode() {
        let m = from_rows(&["###.", "###.", "###."]);
        // the left, top and bottom edges are the image border: only the
        // column next to the unset column goes
        assert_eq!(to_rows(&m.eroded(1)), vec!["##..", "##..", "##.."]);
    }

    #[test]
    fn region_edge_inside_the_image_erodes() {
        let mut m = Mask::empty_in(10, 10, 2, 2, 5, 5);
        for v in 2..5 {
            for u in 2..5 {
                assert!(m.set(u, v, true));
            }
        }
        assert!(!m.set(0, 0, true));
        let e = m.eroded(1);
        assert_eq!(e.pixels().collect::<Vec<_>>(), vec![(3, 3)]);
    }

    /// The fused row-by-row erosion is the erosion: random regions
    /// anywhere in the image (touching its edges or not), random bits.
    #[test]
    fn eroded_rows_are_the_eroded_mask() {
        let mut next = crate::perception::test_sequence(12345);
        for _ in 0..300 {
            let (iw, ih) = (1 + next() % 12, 1 + next() % 12);
            let (x0, y0) = (next() % iw, next() % ih);
            let (x1, y1) = (x0 + next() % (iw - x0 + 1), y0 + next() % (ih - y0 + 1));
            let mut m = Mask::empty_in(iw, ih, x0, y0, x1, y1);
            for v in y0..y1 {
                for u in x0..x1 {
                    m.set(u, v, !next().is_multiple_of(4));
                }
            }
            let e = m.eroded(1);
            let (ex0, ey0, ew, _) = e.region();
            let mut rows = 0;
            m.for_each_eroded_row(|y, bits| {
                rows += 1;
                for (x, &b) in bits.iter().enumerate() {
                    assert_eq!(b, e.get(ex0 + x, ey0 + y), "{:?}", to_rows(&m));
                }
                assert_eq!(bits.len(), ew);
            });
            assert_eq!(rows, if x1 > x0 { y1 - y0 } else { 0 });
        }
    }
}
