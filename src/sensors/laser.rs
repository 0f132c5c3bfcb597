//! Scan fusion: the two lasers' scans into one obstacle set in `base_link`
//! (pure; the poses come from config as `base_from_laser`).

use nalgebra::{Isometry3, Point3};

use crate::msg::{LaserRay, LaserScan, NoReturn, Obstacles, Reading, Stamp, Stamped};

/// The scan's returns as points in `base_link` (x, y).
pub fn scan_to_base(scan: &LaserScan, base_from_laser: &Isometry3<f64>) -> Vec<[f32; 2]> {
    scan.ranges_m
        .iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let r = (*r)? as f64;
            let a = scan.angle_min_rad + i as f64 * scan.angle_increment_rad;
            let p = base_from_laser * Point3::new(r * a.cos(), r * a.sin(), 0.0);
            Some([p.x as f32, p.y as f32])
        })
        .collect()
}

/// Every step of the scan as a ray in `base_link`.
pub fn scan_rays(scan: &LaserScan, base_from_laser: &Isometry3<f64>) -> Vec<LaserRay> {
    let o = base_from_laser.translation.vector;
    scan.readings
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let a = scan.angle_min_rad + i as f64 * scan.angle_increment_rad;
            let d = base_from_laser.rotation * nalgebra::Vector3::new(a.cos(), a.sin(), 0.0);
            LaserRay {
                origin_m: [o.x as f32, o.y as f32],
                dir: [d.x as f32, d.y as f32],
                blind: matches!(r, Reading::NoReturn(n) if *n != NoReturn::NoObject),
                range_m: scan.ranges_m.get(i).copied().flatten(),
            }
        })
        .collect()
}

/// Merges scans (each with its `base_from_laser`) into one obstacle set,
/// stamped with the oldest scan's stamp (the set is as old as its oldest
/// part). None when no scan is given.
pub fn merge_scans(scans: &[(&Stamped<LaserScan>, &Isometry3<f64>)]) -> Option<Stamped<Obstacles>> {
    let stamp: Stamp = scans.iter().map(|(s, _)| s.stamp).min()?;
    let mut points_base = Vec::new();
    let mut rays_base = Vec::new();
    for (s, pose) in scans {
        points_base.extend(scan_to_base(&s.value, pose));
        rays_base.extend(scan_rays(&s.value, pose));
    }
    Some(Stamped::new(
        stamp,
        Obstacles {
            points_base,
            drop_offs_base: Vec::new(),
            drop_offs_unseen_base: Vec::new(),
            floor_unseen_base: Vec::new(),
            rays_base,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensors::scip::SensorParams;

    #[test]
    fn two_lasers_merge_in_the_base_frame() {
        let p = SensorParams::URG_04LX;
        // 1 m at every step, except "no return" at step AMIN
        let mut values = vec![1000u32; 682];
        values[0] = 0;
        let scan = LaserScan::from_values(&p, p.amin, &values, 0);
        assert_eq!(scan.ranges_m[0], None);
        // the step straight ahead is AFRT = 384 → index 340
        let ahead = (p.afrt - p.amin) as usize;
        let left = Isometry3::new(
            nalgebra::Vector3::new(0.33, 0.2, 0.66),
            nalgebra::Vector3::z() * std::f64::consts::FRAC_PI_2,
        );
        let right = Isometry3::new(
            nalgebra::Vector3::new(0.33, -0.2, 0.66),
            nalgebra::Vector3::z() * -std::f64::consts::FRAC_PI_2,
        );
        let a = Stamped::new(Stamp::from_secs_f64(2.0), scan.clone());
        let b = Stamped::new(Stamp::from_secs_f64(1.5), scan);
        let m = merge_scans(&[(&a, &left), (&b, &right)]).unwrap();
        assert_eq!(m.stamp, Stamp::from_secs_f64(1.5));
        assert_eq!(m.value.points_base.len(), 2 * 681);
        // the left laser looks left: its "ahead" return is at (0.33, 1.2)
        let pl = scan_to_base(&a.value, &left)[ahead - 1];
        assert!(
            (pl[0] - 0.33).abs() < 1e-5 && (pl[1] - 1.2).abs() < 1e-5,
            "{pl:?}"
        );
        let pr = scan_to_base(&b.value, &right)[ahead - 1];
        assert!(
            (pr[0] - 0.33).abs() < 1e-5 && (pr[1] + 1.2).abs() < 1e-5,
            "{pr:?}"
        );
        assert!(merge_scans(&[]).is_none());
    }
}
