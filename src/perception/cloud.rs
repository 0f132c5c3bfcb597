//! Steps 4 and 5, one step at a time: depth isolation under a mask with the
//! z-score filter, and back-projection to 3D. The reference for the fused
//! path the pipeline runs (`mask_points`).

use nalgebra::{Isometry3, Point3};
use wide::f64x4;

use super::mask_points::Projector;
use super::masks::Mask;
use crate::msg::DepthImage;
use crate::msg::Intrinsics;

/// A depth sample under a mask: pixel and depth in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthSample {
    pub u: u32,
    pub v: u32,
    pub z_m: f32,
}

/// The valid depths under `mask` (step 4, isolation). The mask and depth
/// must share the colour image's size.
pub fn isolate_depth(mask: &Mask, depth: &DepthImage) -> Vec<DepthSample> {
    let (x0, y0, w, h) = mask.region();
    let dw = depth.width();
    let data = depth.data();
    let cols = w.min(dw.saturating_sub(x0));
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h.min(depth.height().saturating_sub(y0)) {
        let v = y0 + y;
        let bits = &mask.region_row(y)[..cols];
        let zs = &data[v * dw + x0..v * dw + x0 + cols];
        for (x, (&on, &z)) in bits.iter().zip(zs).enumerate() {
            if on && z.is_finite() && z > 0.0 {
                out.push(DepthSample {
                    u: (x0 + x) as u32,
                    v: v as u32,
                    z_m: z,
                });
            }
        }
    }
    out
}

/// Mean and population standard deviation (as `scipy.stats.zscore`, ddof 0)
/// of the depths, computed in f64.
pub fn depth_stats(samples: &[DepthSample]) -> Option<(f64, f64)> {
    let zs: Vec<f32> = samples.iter().map(|s| s.z_m).collect();
    depth_stats_of(&zs)
}

/// [`depth_stats`] of the depths themselves. Sums shifted by the first
/// depth (no cancellation for depths near each other), in eight running
/// sums joined pairwise at the end: eight additions in flight rather than
/// one chain.
pub fn depth_stats_of(zs: &[f32]) -> Option<(f64, f64)> {
    let shift = *zs.first()? as f64;
    let (s1, s2) = lane_sums(zs, shift);
    let join = |a: [f64; 8]| ((a[0] + a[1]) + (a[2] + a[3])) + ((a[4] + a[5]) + (a[6] + a[7]));
    let n = zs.len() as f64;
    let mean_d = join(s1) / n;
    let var = (join(s2) / n - mean_d * mean_d).max(0.0);
    Some((shift + mean_d, var.sqrt()))
}

/// The eight running sums of the depths less `shift` and of their
/// squares: depth `i` in sum `i % 8`.
fn lane_sums(zs: &[f32], shift: f64) -> ([f64; 8], [f64; 8]) {
    const L: usize = 8;
    // lanes 0–3 and 4–7 of the running sums as vectors: each lane's
    // operations are the scalar ones
    let zero = f64x4::splat(0.0);
    let (mut s1a, mut s1b, mut s2a, mut s2b) = (zero, zero, zero, zero);
    let shift4 = f64x4::splat(shift);
    let mut chunks = zs.chunks_exact(L);
    for c in &mut chunks {
        let da = f64x4::new([c[0] as f64, c[1] as f64, c[2] as f64, c[3] as f64]) - shift4;
        let db = f64x4::new([c[4] as f64, c[5] as f64, c[6] as f64, c[7] as f64]) - shift4;
        s1a += da;
        s1b += db;
        s2a += da * da;
        s2b += db * db;
    }
    let lanes = |a: f64x4, b: f64x4| -> [f64; L] {
        let (a, b) = (a.to_array(), b.to_array());
        std::array::from_fn(|l| if l < 4 { a[l] } else { b[l - 4] })
    };
    let (mut s1, mut s2) = (lanes(s1a, s1b), lanes(s2a, s2b));
    for (l, &z) in chunks.remainder().iter().enumerate() {
        let d = z as f64 - shift;
        s1[l] += d;
        s2[l] += d * d;
    }
    (s1, s2)
}

/// Keeps the samples whose z-score satisfies |z| < `tau` (step 4). When all
/// depths are equal (σ = 0) every sample has z = 0 and is kept: no division
/// by zero.
pub fn zscore_filter(mut samples: Vec<DepthSample>, tau: f64) -> Vec<DepthSample> {
    let Some((mean, std)) = depth_stats(&samples) else {
        return samples;
    };
    if std <= 1e-9 * mean.abs().max(1.0) {
        return samples;
    }
    // |z − μ| / σ < τ  ⇔  |z − μ| < τσ
    let limit = tau * std;
    samples.retain(|s| (s.z_m as f64 - mean).abs() < limit);
    samples
}

/// Back-projects samples with the intrinsics of the image they index
/// (`X = (u−cx)·Z/fx, Y = (v−cy)·Z/fy, Z`), then applies `target_from_camera`
/// (step 5). Pixel centres are at integer coordinates, as in the paper and
/// the RealSense SDK.
pub fn back_project(
    samples: &[DepthSample],
    intrinsics: &Intrinsics,
    target_from_camera: &Isometry3<f64>,
) -> Vec<Point3<f32>> {
    let p = Projector::new(intrinsics, target_from_camera);
    samples
        .iter()
        .map(|s| Point3::from(p.point(s.u as f32, s.v as f32, s.z_m)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(z: &[f32]) -> Vec<DepthSample> {
        z.iter()
            .enumerate()
            .map(|(i, &z_m)| DepthSample {
                u: i as u32,
                v: 0,
                z_m,
            })
            .collect()
    }

    /// Bit for bit the scalar sums (depth `i` into sum `i % 8`, one by
    /// one), for every length's remainder and depths near and far apart.
    #[test]
    fn lane_sums_are_the_scalar_sums() {
        let mut next = crate::perception::test_sequence(5);
        assert_eq!(depth_stats_of(&[]), None);
        for n in 1..300usize {
            let spread = [1e-4f32, 0.01, 3.0][n % 3];
            let zs: Vec<f32> = (0..n)
                .map(|_| 0.5 + spread * (next() % 10_000) as f32 / 10_000.0)
                .collect();
            let shift = zs[0] as f64;
            let (mut s1, mut s2) = ([0.0f64; 8], [0.0f64; 8]);
            for (i, &z) in zs.iter().enumerate() {
                let d = z as f64 - shift;
                s1[i % 8] += d;
                s2[i % 8] += d * d;
            }
            let bits = |a: [f64; 8]| a.map(f64::to_bits);
            let (got1, got2) = lane_sums(&zs, shift);
            assert_eq!(bits(got1), bits(s1), "{n} depths");
            assert_eq!(bits(got2), bits(s2), "{n} depths");
        }
    }

    #[test]
    fn zscore_drops_the_outlier() {
        // nine at 2.0 m and one at 5.0 m: mean 2.3, σ = 0.9 → z(5.0) = 3.0
        let mut z = vec![2.0f32; 9];
        z.push(5.0);
        let s = samples(&z);
        let (mean, std) = depth_stats(&s).unwrap();
        assert!((mean - 2.3).abs() < 1e-6);
        assert!((std - 0.9).abs() < 1e-6);
        let kept = zscore_filter(s.clone(), 2.0);
        assert_eq!(kept.len(), 9);
        assert!(kept.iter().all(|s| s.z_m == 2.0));
        // with τ = 3.5 nothing goes
        assert_eq!(zscore_filter(s, 3.5).len(), 10);
    }

    #[test]
    fn zscore_is_strict_at_tau() {
        // two values: each is exactly 1σ from the mean
        let s = samples(&[1.0, 3.0]);
        assert_eq!(zscore_filter(s.clone(), 1.0).len(), 0);
        assert_eq!(zscore_filter(s, 1.0000001).len(), 2);
    }

    #[test]
    fn zscore_of_constant_depth_keeps_all() {
        let s = samples(&[1.5; 7]);
        assert_eq!(zscore_filter(s.clone(), 2.0), s);
        assert!(zscore_filter(Vec::new(), 2.0).is_empty());
    }

    #[test]
    fn isolation_skips_invalid_depth_and_unmasked_pixels() {
        let depth = DepthImage::new(4, 1, vec![1.0, 0.0, f32::NAN, 2.0]).unwrap();
        let m = Mask::from_full(4, 1, vec![true, true, true, false]).unwrap();
        let s = isolate_depth(&m, &depth);
        assert_eq!(
            s,
            vec![DepthSample {
                u: 0,
                v: 0,
                z_m: 1.0
            }]
        );
    }

    #[test]
    fn back_projection_with_extrinsics_is_exact() {
        let k = Intrinsics {
            width: 640,
            height: 480,
            fx: 500.0,
            fy: 400.0,
            cx: 320.0,
            cy: 240.0,
        };
        // camera optical → base: z forward → x, x right → −y, y down → −z,
        // camera 1 m up
        let rot = nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
            0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0,
        ));
        let base_from_camera = Isometry3::from_parts(
            nalgebra::Translation3::new(0.0, 0.0, 1.0),
            nalgebra::UnitQuaternion::from_rotation_matrix(&rot),
        );
        let s = [DepthSample {
            u: 420,
            v: 140,
            z_m: 2.0,
        }];
        let p = back_project(&s, &k, &base_from_camera);
        // optical: x = 100·2/500 = 0.4, y = −100·2/400 = −0.5, z = 2
        // base: x = 2, y = −0.4, z = 1 + 0.5
        let want = Point3::new(2.0f32, -0.4, 1.5);
        assert!((p[0] - want).norm() < 1e-6, "{:?}", p[0]);
    }
}
