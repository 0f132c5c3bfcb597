//! The detector's input: the letterbox and bilinear resizing.

use rayon::prelude::*;

use crate::msg::RgbImage;

/// How a letterboxed input maps back to the original image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Letterbox {
    /// Input pixels per original pixel.
    pub scale: f32,
    pub pad_left: f32,
    pub pad_top: f32,
    pub orig_width: usize,
    pub orig_height: usize,
}

impl Letterbox {
    /// Maps a box in letterboxed input pixels to original pixels, clipped to
    /// the image.
    pub fn to_original(&self, xyxy: [f32; 4]) -> [f32; 4] {
        let w = self.orig_width as f32;
        let h = self.orig_height as f32;
        let x1 = ((xyxy[0] - self.pad_left) / self.scale).clamp(0.0, w);
        let y1 = ((xyxy[1] - self.pad_top) / self.scale).clamp(0.0, h);
        let x2 = ((xyxy[2] - self.pad_left) / self.scale).clamp(0.0, w);
        let y2 = ((xyxy[3] - self.pad_top) / self.scale).clamp(0.0, h);
        [x1, y1, x2, y2]
    }
}

/// Letterboxes `img` into a `size`×`size` CHW float tensor (RGB, /255),
/// padding with `pad_value` as Ultralytics' `LetterBox` does (centred,
/// bilinear resize with half-pixel centres as OpenCV's INTER_LINEAR).
pub fn letterbox_chw(img: &RgbImage, size: usize, pad_value: u8) -> (Vec<f32>, Letterbox) {
    let Placed {
        resized,
        row_bytes,
        top,
        left,
        shown_w,
        shown_h,
        letterbox,
    } = place(img, size);
    // each plane written once, row by row: padding, the resized row,
    // padding (the image's own size needs no resize and no copy); byte
    // values through a table of their /255 floats (the same values)
    let lut: [f32; 256] = std::array::from_fn(|b| b as f32 / 255.0);
    let layout = Layout {
        size,
        top,
        left,
        shown_w,
        shown_h,
        row_bytes,
        pad: pad_value as f32 / 255.0,
    };
    let out = if super::pool_is_parallel() {
        planes_by_rows(&resized, &layout, &lut)
    } else {
        planes_in_order(&resized, &layout, &lut)
    };
    (out, letterbox)
}

/// An image placed in the `size`×`size` square: its rows (resized when
/// its size is not the placed size), their bytes, the top-left corner
/// and how much of it shows.
struct Placed<'a> {
    resized: std::borrow::Cow<'a, [u8]>,
    row_bytes: usize,
    top: usize,
    left: usize,
    shown_w: usize,
    shown_h: usize,
    letterbox: Letterbox,
}

fn place(img: &RgbImage, size: usize) -> Placed<'_> {
    let (w, h) = (img.width(), img.height());
    let Placement {
        new_w,
        new_h,
        top,
        left,
        letterbox,
    } = placement(w, h, size);
    let resized: std::borrow::Cow<[u8]> = if new_w == w && new_h == h {
        std::borrow::Cow::Borrowed(img.data())
    } else {
        std::borrow::Cow::Owned(resize_bilinear(img, new_w, new_h))
    };
    Placed {
        resized,
        row_bytes: new_w * 3,
        top,
        left,
        shown_w: new_w.min(size - left),
        shown_h: new_h.min(size - top),
        letterbox,
    }
}

/// Where a `w`×`h` image goes in the `size`×`size` square: resized to
/// `new_w`×`new_h`, its top-left corner at (`left`, `top`).
struct Placement {
    new_w: usize,
    new_h: usize,
    top: usize,
    left: usize,
    letterbox: Letterbox,
}

fn placement(w: usize, h: usize, size: usize) -> Placement {
    let r = (size as f32 / h as f32).min(size as f32 / w as f32);
    let new_w = ((w as f32 * r).round() as usize).clamp(1, size);
    let new_h = ((h as f32 * r).round() as usize).clamp(1, size);
    let dw = (size - new_w) as f32 / 2.0;
    let dh = (size - new_h) as f32 / 2.0;
    let top = (dh - 0.1).round().max(0.0) as usize;
    let left = (dw - 0.1).round().max(0.0) as usize;
    Placement {
        new_w,
        new_h,
        top,
        left,
        letterbox: Letterbox {
            scale: r,
            pad_left: left as f32,
            pad_top: top as f32,
            orig_width: w,
            orig_height: h,
        },
    }
}

/// The same letterbox as [`letterbox_chw`], as the bytes themselves: a
/// `size`×`size` RGB image (HWC, row by row) whose byte b is the float
/// plane's b/255. For a model that takes bytes and converts them itself.
pub fn letterbox_hwc_u8(img: &RgbImage, size: usize, pad_value: u8) -> (Vec<u8>, Letterbox) {
    let p = place(img, size);
    let (top, left, shown_w) = (p.top, p.left, p.shown_w);
    // rows written in order: padding, the image's row, padding (a copy of
    // bytes: one thread is enough)
    let mut out: Vec<u8> = Vec::with_capacity(3 * size * size);
    out.resize(3 * size * top, pad_value);
    for row in p.resized.chunks_exact(p.row_bytes).take(p.shown_h) {
        out.resize(out.len() + 3 * left, pad_value);
        out.extend_from_slice(&row[..shown_w * 3]);
        out.resize(out.len() + 3 * (size - left - shown_w), pad_value);
    }
    out.resize(3 * size * size, pad_value);
    (out, p.letterbox)
}

/// Where the image lies in the letterboxed square, input pixels.
struct Layout {
    size: usize,
    top: usize,
    left: usize,
    shown_w: usize,
    shown_h: usize,
    /// Bytes of a row of the (resized) RGB image.
    row_bytes: usize,
    pad: f32,
}

/// The three planes written in order, row by row: padding, the image's
/// row, padding (one thread).
fn planes_in_order(rgb: &[u8], l: &Layout, lut: &[f32; 256]) -> Vec<f32> {
    let size = l.size;
    let mut out: Vec<f32> = Vec::with_capacity(3 * size * size);
    for c in 0..3 {
        out.resize(out.len() + l.top * size, l.pad);
        for row in rgb.chunks_exact(l.row_bytes).take(l.shown_h) {
            out.resize(out.len() + l.left, l.pad);
            out.extend(
                row[..l.shown_w * 3]
                    .iter()
                    .skip(c)
                    .step_by(3)
                    .map(|&b| lut[b as usize]),
            );
            out.resize(out.len() + size - l.left - l.shown_w, l.pad);
        }
        out.resize((c + 1) * size * size, l.pad);
    }
    out
}

/// The same planes with each output row (plane c, row y) written on its
/// own, the rows shared out over the pool's threads in runs of 64.
fn planes_by_rows(rgb: &[u8], l: &Layout, lut: &[f32; 256]) -> Vec<f32> {
    let size = l.size;
    let write_row = |r: usize, row: &mut [std::mem::MaybeUninit<f32>]| {
        let (c, y) = (r / size, r % size);
        if y < l.top || y >= l.top + l.shown_h {
            row.iter_mut().for_each(|x| {
                x.write(l.pad);
            });
            return;
        }
        let start = (y - l.top) * l.row_bytes;
        let src = &rgb[start..start + l.shown_w * 3];
        let (head, rest) = row.split_at_mut(l.left);
        let (shown, tail) = rest.split_at_mut(l.shown_w);
        for x in head.iter_mut().chain(tail.iter_mut()) {
            x.write(l.pad);
        }
        for (x, &b) in shown.iter_mut().zip(src.iter().skip(c).step_by(3)) {
            x.write(lut[b as usize]);
        }
    };
    let len = 3 * size * size;
    let mut out: Vec<f32> = Vec::with_capacity(len);
    out.spare_capacity_mut()[..len]
        .par_chunks_mut(size)
        .with_min_len(64)
        .enumerate()
        .for_each(|(r, row)| write_row(r, row));
    // SAFETY: the capacity is `len`, and each of its `len` elements was
    // written above: every row of `size` elements, padding or image,
    // wholly (`left + shown_w + (size - left - shown_w)` for an image row)
    unsafe { out.set_len(len) };
    out
}

/// Bilinear resize with half-pixel centres (OpenCV INTER_LINEAR geometry),
/// RGB8 in, RGB8 out.
pub fn resize_bilinear(img: &RgbImage, new_w: usize, new_h: usize) -> Vec<u8> {
    let (w, h) = (img.width(), img.height());
    if new_w == w && new_h == h {
        return img.data().to_vec();
    }
    let sx = w as f32 / new_w as f32;
    let sy = h as f32 / new_h as f32;
    let taps = |dst: usize, scale: f32, len: usize| -> (usize, usize, f32) {
        let s = ((dst as f32 + 0.5) * scale - 0.5).max(0.0);
        let i0 = (s.floor() as usize).min(len - 1);
        let i1 = (i0 + 1).min(len - 1);
        (i0, i1, s - i0 as f32)
    };
    let xs: Vec<(usize, usize, f32)> = (0..new_w).map(|x| taps(x, sx, w)).collect();
    let data = img.data();
    let mut out = vec![0u8; new_w * new_h * 3];
    for y in 0..new_h {
        let (y0, y1, fy) = taps(y, sy, h);
        let r0 = &data[y0 * w * 3..(y0 + 1) * w * 3];
        let r1 = &data[y1 * w * 3..(y1 + 1) * w * 3];
        let orow = &mut out[y * new_w * 3..(y + 1) * new_w * 3];
        for (x, &(x0, x1, fx)) in xs.iter().enumerate() {
            for c in 0..3 {
                let top = r0[x0 * 3 + c] as f32 * (1.0 - fx) + r0[x1 * 3 + c] as f32 * fx;
                let bot = r1[x0 * 3 + c] as f32 * (1.0 - fx) + r1[x1 * 3 + c] as f32 * fx;
                orow[x * 3 + c] = (top * (1.0 - fy) + bot * fy).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn letterbox_of_wide_image_pads_top_and_bottom() {
        let img = RgbImage::filled(1280, 640, [255, 0, 0]).unwrap();
        let (t, lb) = letterbox_chw(&img, 640, 114);
        assert_eq!(lb.scale, 0.5);
        assert_eq!(lb.pad_left, 0.0);
        assert_eq!(lb.pad_top, 160.0);
        // top-left is padding, centre is image
        assert!((t[0] - 114.0 / 255.0).abs() < 1e-6);
        let c = 320 * 640 + 320;
        assert_eq!(t[c], 1.0);
        assert_eq!(t[640 * 640 + c], 0.0);
        // a box maps back
        let b = lb.to_original([0.0, 160.0, 640.0, 480.0]);
        assert_eq!(b, [0.0, 0.0, 1280.0, 640.0]);
    }

    /// Images to letterbox: resized (tall, wide, small) and unresized,
    /// their bytes a pattern of `mul` and `div`.
    fn pattern_images(mul: usize, div: usize) -> impl Iterator<Item = (usize, usize, RgbImage)> {
        [(640, 480), (300, 500), (1000, 330), (640, 640), (17, 9)]
            .into_iter()
            .map(move |(w, h)| {
                let data: Vec<u8> = (0..w * h * 3)
                    .map(|i| ((i * mul + i / div) % 256) as u8)
                    .collect();
                (w, h, RgbImage::new(w, h, data).unwrap())
            })
    }

    #[test]
    fn letterbox_writes_what_pixel_by_pixel_placing_writes() {
        // against the padded tensor filled pixel by pixel
        for (w, h, img) in pattern_images(37, 7) {
            // in order on one thread, and row by row on four
            let pool = |n| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .unwrap()
            };
            let (t, lb) = pool(1).install(|| letterbox_chw(&img, 640, 114));
            let (by_rows, lb_by_rows) = pool(4).install(|| letterbox_chw(&img, 640, 114));
            assert!(by_rows == t && lb_by_rows == lb, "{w}x{h}: rows differ");
            let (nw, nh) = (
                ((w as f32 * lb.scale).round() as usize).clamp(1, 640),
                ((h as f32 * lb.scale).round() as usize).clamp(1, 640),
            );
            let resized = resize_bilinear(&img, nw, nh);
            let mut want = vec![114.0f32 / 255.0; 3 * 640 * 640];
            let (top, left) = (lb.pad_top as usize, lb.pad_left as usize);
            for y in 0..nh {
                for x in 0..nw {
                    for c in 0..3 {
                        want[c * 640 * 640 + (y + top) * 640 + x + left] =
                            resized[(y * nw + x) * 3 + c] as f32 / 255.0;
                    }
                }
            }
            assert!(t == want, "{w}x{h}");
        }
    }

    #[test]
    fn the_byte_letterbox_is_the_float_planes_bytes() {
        // each byte b of the HWC letterbox is the CHW plane's b/255 at the
        // same pixel, and the placement is the same
        for (w, h, img) in pattern_images(53, 11) {
            let (chw, lb) = letterbox_chw(&img, 640, 114);
            let (hwc, lb_bytes) = letterbox_hwc_u8(&img, 640, 114);
            assert_eq!(lb_bytes, lb, "{w}x{h}: placement");
            assert_eq!(hwc.len(), chw.len(), "{w}x{h}: length");
            let plane = 640 * 640;
            for (i, &b) in hwc.iter().enumerate() {
                let (pixel, c) = (i / 3, i % 3);
                assert!(
                    chw[c * plane + pixel] == b as f32 / 255.0,
                    "{w}x{h}: pixel {pixel} channel {c}"
                );
            }
        }
    }

    #[test]
    fn bilinear_resize_halves_a_gradient_exactly() {
        // 4x1 gradient 0, 100, 200, 250 → 2x1: samples at 0.5 and 2.5
        let data = [0u8, 100, 200, 250]
            .iter()
            .flat_map(|&v| [v, v, v])
            .collect();
        let img = RgbImage::new(4, 1, data).unwrap();
        let out = resize_bilinear(&img, 2, 1);
        assert_eq!(out, vec![50, 50, 50, 225, 225, 225]);
    }
}
