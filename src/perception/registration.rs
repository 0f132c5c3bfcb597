//! Depth-to-colour registration: a separate depth camera's image moved
//! into the colour camera's pixels.

use nalgebra::Isometry3;

use crate::msg::{is_valid_depth, DepthImage, ImageError, Intrinsics};

/// Registers a depth image into the colour camera: every valid depth pixel
/// is back-projected with the depth intrinsics, moved by `color_from_depth`,
/// and projected into colour pixels, keeping the nearest return per pixel.
/// The result has the colour image's size and carries colour-frame depth (z).
pub fn register_depth_to_color(
    depth: &DepthImage,
    depth_intrinsics: &Intrinsics,
    color_from_depth: &Isometry3<f64>,
    color: &Intrinsics,
) -> Result<DepthImage, ImageError> {
    let (cw, ch) = (color.width, color.height);
    let mut out = vec![f32::INFINITY; cw * ch];
    for v in 0..depth.height() {
        for u in 0..depth.width() {
            let Some(z) = depth.at(u, v) else { continue };
            let p_depth = depth_intrinsics.back_project(u as f64, v as f64, z as f64);
            let p_color = color_from_depth * p_depth;
            let Some((uc, vc)) = color.project(&p_color) else {
                continue;
            };
            let (ui, vi) = (uc.round(), vc.round());
            if ui < 0.0 || vi < 0.0 || ui >= cw as f64 || vi >= ch as f64 {
                continue;
            }
            let idx = vi as usize * cw + ui as usize;
            let zc = p_color.z as f32;
            if zc < out[idx] {
                out[idx] = zc;
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
}
