//! Depth-to-colour registration: a separate depth camera's image moved
//! into the colour camera's pixels.

use nalgebra::Isometry3;

use crate::msg::{is_valid_depth, DepthImage, ImageError, Intrinsics};

/// Registers a depth image into the colour camera: every valid depth pixel
/// is back-projected with the depth intrinsics, moved by `color_from_depth`,
/// and projected into colour pixels (rounded to the nearest), keeping the
/// nearest return per pixel. The result has the colour image's size and
/// carries colour-frame depth (z).
///
/// A pixel's ray in the colour frame is `z · R·[(u−cx)/fx, (v−cy)/fy, 1]`,
/// so `R` times the ray's row and column parts are made once per row and
/// column, and each pixel costs three multiply-adds, the translation and
/// the projection.
pub fn register_depth_to_color(
    depth: &DepthImage,
    depth_intrinsics: &Intrinsics,
    color_from_depth: &Isometry3<f64>,
    color: &Intrinsics,
) -> Result<DepthImage, ImageError> {
    let (cw, ch) = (color.width, color.height);
    let (dw, dh) = (depth.width(), depth.height());
    let mut out = vec![f32::INFINITY; cw * ch];
    let r = color_from_depth.rotation.to_rotation_matrix().into_inner();
    let t = color_from_depth.translation.vector;
    let k = depth_intrinsics;
    // the colour pixel is (a/c, b/c) with [a, b, c] = P·(z·R·ray + t) and
    // P = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]; P·R·ray splits into a
    // column part and a row part, made once per column and per row
    let pr = nalgebra::Matrix3::new(
        color.fx, 0.0, color.cx, 0.0, color.fy, color.cy, 0.0, 0.0, 1.0,
    ) * r;
    let pt = [
        color.fx * t.x + color.cx * t.z,
        color.fy * t.y + color.cy * t.z,
        t.z,
    ];
    // per column: the column part of P·R·ray, one array per row of P·R
    // (so that a row's pixels are worked two or four at a time)
    let column = |i: usize| -> Vec<f64> {
        (0..dw)
            .map(|u| pr[(i, 0)] * ((u as f64 - k.cx) / k.fx))
            .collect()
    };
    let (col_a, col_b, col_c) = (column(0), column(1), column(2));
    let (w_lim, h_lim) = (cw as f64 - 0.5, ch as f64 - 0.5);
    // each pixel's colour index (or NONE) and depth, a row at a time: a
    // loop without branches, then the scatter keeping the nearest
    const NONE: u32 = u32::MAX;
    let mut row_idx = vec![NONE; dw];
    let mut row_z = vec![0f32; dw];
    for (v, row) in depth.data().chunks_exact(dw.max(1)).take(dh).enumerate() {
        let b = (v as f64 - k.cy) / k.fy;
        let row_a = pr[(0, 1)] * b + pr[(0, 2)];
        let row_b = pr[(1, 1)] * b + pr[(1, 2)];
        let row_c = pr[(2, 1)] * b + pr[(2, 2)];
        let columns = col_a.iter().zip(&col_b).zip(&col_c);
        let outs = row_idx.iter_mut().zip(row_z.iter_mut());
        for ((&z32, ((&ca, &cb), &cc)), (idx_out, z_out)) in row.iter().zip(columns).zip(outs) {
            let z = z32 as f64;
            let pz = z * (cc + row_c) + pt[2];
            let inv_pz = 1.0 / pz;
            let uc = (z * (ca + row_a) + pt[0]) * inv_pz;
            let vc = (z * (cb + row_b) + pt[1]) * inv_pz;
            // the nearest pixel: rounding half away from zero, as
            // f64::round, without its library call (in range, the value
            // plus a half truncates to it)
            let inside = (z32 > 0.0)
                & (z32 < f32::INFINITY)
                & (pz > 0.0)
                & (uc > -0.5)
                & (uc < w_lim)
                & (vc > -0.5)
                & (vc < h_lim);
            // SAFETY: max/min bring any value, NaN too, into
            // [0, limit + 1], where the truncation to i32 is defined (a
            // plain `as` would saturate, one pixel at a time)
            let (ui, vi) = unsafe {
                (
                    ((uc + 0.5).max(0.0).min(w_lim + 1.0)).to_int_unchecked::<i32>(),
                    ((vc + 0.5).max(0.0).min(h_lim + 1.0)).to_int_unchecked::<i32>(),
                )
            };
            let idx = vi.wrapping_mul(cw as i32).wrapping_add(ui);
            *idx_out = if inside { idx as u32 } else { NONE };
            *z_out = pz as f32;
        }
        for (&idx, &zc) in row_idx.iter().zip(&row_z) {
            if idx == NONE {
                continue;
            }
            let cell = &mut out[idx as usize];
            if zc < *cell {
                *cell = zc;
            }
        }
    }
    for d in out.iter_mut() {
        if !is_valid_depth(*d) {
            *d = 0.0;
        }
    }
    DepthImage::new(cw, ch, out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::calibration::tests::intr;

    #[test]
    fn identity_registration_keeps_depth() {
        let k = intr();
        let d: Vec<f32> = (0..64 * 48).map(|i| 1.0 + (i % 7) as f32 * 0.1).collect();
        let depth = DepthImage::new(64, 48, d.clone()).unwrap();
        let reg = register_depth_to_color(&depth, &k, &Isometry3::identity(), &k).unwrap();
        for (a, b) in reg.data().iter().zip(&d) {
            assert!((a - b).abs() < 1e-6);
        }
    }

    #[test]
    fn shifted_registration_moves_pixels() {
        // colour camera 0.1 m to the right of depth camera: a point straight
        // ahead of the depth camera at 2 m appears left in colour by
        // fx * 0.1 / 2 = 2.5 px → rounds to u = 32 - 2.5 = 29.5 → 30 (round half away).
        let k = intr();
        let mut d = vec![0.0f32; 64 * 48];
        d[24 * 64 + 32] = 2.0;
        let depth = DepthImage::new(64, 48, d).unwrap();
        let color_from_depth = Isometry3::translation(-0.1, 0.0, 0.0);
        let reg = register_depth_to_color(&depth, &k, &color_from_depth, &k).unwrap();
        let hits: Vec<usize> = reg
            .data()
            .iter()
            .enumerate()
            .filter(|(_, &z)| z > 0.0)
            .map(|(i, _)| i)
            .collect();
        assert_eq!(hits, vec![24 * 64 + 30]);
    }

    /// The registration as first written: each pixel back-projected,
    /// moved by the isometry and projected on its own.
    fn register_pixel_by_pixel(
        depth: &DepthImage,
        dk: &Intrinsics,
        color_from_depth: &Isometry3<f64>,
        color: &Intrinsics,
    ) -> Vec<f32> {
        let (cw, ch) = (color.width, color.height);
        let mut out = vec![f32::INFINITY; cw * ch];
        for v in 0..depth.height() {
            for u in 0..depth.width() {
                let Some(z) = depth.at(u, v) else { continue };
                let p = color_from_depth * dk.back_project(u as f64, v as f64, z as f64);
                let Some((uc, vc)) = color.project(&p) else {
                    continue;
                };
                let (ui, vi) = (uc.round(), vc.round());
                if ui < 0.0 || vi < 0.0 || ui >= cw as f64 || vi >= ch as f64 {
                    continue;
                }
                let idx = vi as usize * cw + ui as usize;
                out[idx] = out[idx].min(p.z as f32);
            }
        }
        out.iter()
            .map(|&d| if is_valid_depth(d) { d } else { 0.0 })
            .collect()
    }

    #[test]
    fn registration_matches_the_pixel_by_pixel_transform() {
        // a turned and shifted rig, depth with holes and steps, colour
        // intrinsics unlike the depth camera's
        let dk = intr();
        let ck = Intrinsics {
            width: 80,
            height: 60,
            fx: 61.0,
            fy: 59.0,
            cx: 40.3,
            cy: 29.1,
        };
        let d: Vec<f32> = (0..64 * 48)
            .map(|i| match i % 13 {
                0 => 0.0,
                1 => f32::NAN,
                _ => 0.8 + ((i * 7919) % 300) as f32 * 0.01,
            })
            .collect();
        let depth = DepthImage::new(64, 48, d).unwrap();
        let color_from_depth = Isometry3::new(
            nalgebra::Vector3::new(-0.05, 0.01, 0.003),
            nalgebra::Vector3::new(0.02, -0.1, 0.05),
        );
        let fast = register_depth_to_color(&depth, &dk, &color_from_depth, &ck).unwrap();
        let slow = register_pixel_by_pixel(&depth, &dk, &color_from_depth, &ck);
        let kept = slow.iter().filter(|&&z| z > 0.0).count();
        assert!(kept > 1000, "{kept}");
        // the same pixels (the two sums differ in their last bits only)
        let mut differ = 0;
        for (a, b) in fast.data().iter().zip(&slow) {
            if (a - b).abs() > 1e-5 {
                differ += 1;
            }
        }
        assert_eq!(differ, 0);
    }
}
