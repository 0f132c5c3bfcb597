//! Steps 4 and 5: depth isolation under a mask with the z-score filter, and
//! back-projection to 3D.

use nalgebra::{Isometry3, Point3};

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

/// Steps 3–4 fused for one 3×3 erosion: the valid depths within
/// `[min_m, max_m]` under the eroded mask, appended to `out` in the order
/// [`isolate_depth`] gives them (row-major) without making the eroded mask;
/// returns the eroded mask's pixel count.
pub fn isolate_eroded_depth(
    mask: &Mask,
    depth: &DepthImage,
    min_m: f32,
    max_m: f32,
    out: &mut Vec<DepthSample>,
) -> usize {
    let (x0, y0, w, _) = mask.region();
    let dw = depth.width();
    let dh = depth.height();
    let data = depth.data();
    let cols = w.min(dw.saturating_sub(x0));
    // a positive finite range holds only finite positive depths (a NaN
    // fails every comparison): one test per pixel instead of four
    let (lo, hi) = if min_m > 0.0 && max_m.is_finite() {
        (min_m, max_m)
    } else {
        (min_m.max(f32::from_bits(1)), max_m.min(f32::MAX))
    };
    let mut eroded = 0usize;
    mask.for_each_eroded_row(|y, bits| {
        let v = y0 + y;
        let zs: &[f32] = if v < dh {
            &data[v * dw + x0..v * dw + x0 + cols]
        } else {
            &[]
        };
        for (x, &on) in bits.iter().enumerate() {
            eroded += usize::from(on);
            if !on {
                continue;
            }
            if let Some(&z) = zs.get(x) {
                if z >= lo && z <= hi {
                    out.push(DepthSample {
                        u: (x0 + x) as u32,
                        v: v as u32,
                        z_m: z,
                    });
                }
            }
        }
    });
    eroded
}

/// Steps 4 (z-score, τ) and 5 fused: the points of the samples whose
/// depth is within τσ of the mean, back-projected and moved by
/// `target_from_camera` — exactly [`zscore_filter`] then [`back_project`].
pub fn zscore_back_project(
    samples: &[DepthSample],
    tau: f64,
    intrinsics: &Intrinsics,
    target_from_camera: &Isometry3<f64>,
) -> Vec<Point3<f32>> {
    // no spread (or no samples): all kept, as `zscore_filter`
    let (all, mean, limit) = match depth_stats(samples) {
        Some((mean, std)) if std > 1e-9 * mean.abs().max(1.0) => (false, mean, tau * std),
        _ => (true, 0.0, 0.0),
    };
    let keep = |z: f32| all || (z as f64 - mean).abs() < limit;
    let project = projector(intrinsics, target_from_camera);
    // branch-free compaction: every sample is projected into the next
    // slot, which only a kept one claims
    let mut out = vec![Point3::origin(); samples.len()];
    let mut n = 0usize;
    for s in samples {
        if let Some(slot) = out.get_mut(n) {
            *slot = project(s);
        }
        n += usize::from(keep(s.z_m));
    }
    out.truncate(n);
    out
}

/// Mean and population standard deviation (as `scipy.stats.zscore`, ddof 0)
/// of the depths, computed in f64.
pub fn depth_stats(samples: &[DepthSample]) -> Option<(f64, f64)> {
    if samples.is_empty() {
        return None;
    }
    // shifted sums in f64: one pass, no cancellation for depths near each other
    let n = samples.len() as f64;
    let shift = samples[0].z_m as f64;
    let (mut s1, mut s2) = (0.0f64, 0.0f64);
    for s in samples {
        let d = s.z_m as f64 - shift;
        s1 += d;
        s2 += d * d;
    }
    let mean_d = s1 / n;
    let var = (s2 / n - mean_d * mean_d).max(0.0);
    Some((shift + mean_d, var.sqrt()))
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

/// A sample's point in the target frame: p = R·(z·ray(u, v)) + t with
/// ray(u, v) = ((u−cx)/fx, (v−cy)/fy, 1), linear in u and v, so
/// p = z·(a + u·b + v·c) + t with a, b, c, t made once.
fn projector(
    intrinsics: &Intrinsics,
    target_from_camera: &Isometry3<f64>,
) -> impl Fn(&DepthSample) -> Point3<f32> {
    let r = target_from_camera.rotation.to_rotation_matrix();
    let m = r.matrix();
    let col = |j: usize| nalgebra::Vector3::new(m[(0, j)], m[(1, j)], m[(2, j)]);
    let b = col(0) / intrinsics.fx;
    let c = col(1) / intrinsics.fy;
    let a = col(2) - b * intrinsics.cx - c * intrinsics.cy;
    let t = target_from_camera.translation.vector;
    let (a, b, c, t) = (
        a.cast::<f32>(),
        b.cast::<f32>(),
        c.cast::<f32>(),
        t.cast::<f32>(),
    );
    move |s: &DepthSample| {
        let ray = a + b * s.u as f32 + c * s.v as f32;
        Point3::from(ray * s.z_m + t)
    }
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
    samples
        .iter()
        .map(projector(intrinsics, target_from_camera))
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

    /// The fused z-score and back-projection give exactly the points of
    /// the two steps one after the other.
    #[test]
    fn fused_zscore_and_back_projection_are_the_two_steps() {
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
        let mut s = Vec::new();
        for i in 0..500u32 {
            let z = 2.0 + ((i * 37) % 101) as f32 * 0.01 + if i % 50 == 0 { 3.0 } else { 0.0 };
            s.push(DepthSample {
                u: i % 64,
                v: i / 64,
                z_m: z,
            });
        }
        for samples in [s.clone(), vec![s[0]; 7], Vec::new()] {
            let two = back_project(&zscore_filter(samples.clone(), 2.0), &k, &t);
            let fused = zscore_back_project(&samples, 2.0, &k, &t);
            assert_eq!(two, fused);
        }
        // the outliers went
        assert!(zscore_back_project(&s, 2.0, &k, &t).len() < s.len());
    }
}
