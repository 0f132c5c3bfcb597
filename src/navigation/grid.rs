//! Proximity grid (the paper group's `proximity_grid`): polar sectors over
//! the merged scan in `base_link`, each holding the nearest range in it.

use crate::msg::Obstacles;

#[derive(Debug, Clone, PartialEq)]
pub struct ProximityGrid {
    pub angle_min_rad: f64,
    pub sector_rad: f64,
    pub max_range_m: f64,
    /// Nearest range per sector, metres; +∞ when empty.
    pub ranges_m: Vec<f64>,
}

impl ProximityGrid {
    /// Sectors over [−`half_fov_rad`, `half_fov_rad`] of at most
    /// `nominal_sector_rad`, their number forced odd (so one sector looks
    /// straight ahead): 240° at 9° nominal gives 27 sectors of 8.89°.
    pub fn new(half_fov_rad: f64, nominal_sector_rad: f64, max_range_m: f64) -> Self {
        // sectors no wider than nominal, an odd number of them
        let mut n = ((2.0 * half_fov_rad) / nominal_sector_rad - 1e-9)
            .ceil()
            .max(1.0) as usize;
        if n.is_multiple_of(2) {
            n += 1;
        }
        ProximityGrid {
            angle_min_rad: -half_fov_rad,
            sector_rad: 2.0 * half_fov_rad / n as f64,
            max_range_m,
            ranges_m: vec![f64::INFINITY; n],
        }
    }

    /// The paper group's: −120°..+120°, 9° nominal, 0–6 m.
    pub fn paper() -> Self {
        Self::new(120f64.to_radians(), 9f64.to_radians(), 6.0)
    }

    pub fn len(&self) -> usize {
        self.ranges_m.len()
    }

    pub fn is_empty(&self) -> bool {
        self.ranges_m.is_empty()
    }

    /// Centre angle of sector `i`.
    pub fn sector_angle(&self, i: usize) -> f64 {
        self.angle_min_rad + (i as f64 + 0.5) * self.sector_rad
    }

    /// Refills the sectors from obstacle points (base frame).
    pub fn update(&mut self, obstacles: &Obstacles) {
        self.ranges_m.iter_mut().for_each(|r| *r = f64::INFINITY);
        for p in &obstacles.points_base {
            let (x, y) = (p[0] as f64, p[1] as f64);
            let r = x.hypot(y);
            if !(r > 0.0 && r <= self.max_range_m) {
                continue;
            }
            let k = ((y.atan2(x) - self.angle_min_rad) / self.sector_rad).floor();
            if k < 0.0 || k as usize >= self.ranges_m.len() {
                continue;
            }
            let slot = &mut self.ranges_m[k as usize];
            if r < *slot {
                *slot = r;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_grid_is_27_sectors_of_8_89_degrees() {
        let g = ProximityGrid::paper();
        assert_eq!(g.len(), 27);
        assert!((g.sector_rad.to_degrees() - 240.0 / 27.0).abs() < 1e-12);
        assert!(g.sector_angle(13).abs() < 1e-12);
    }

    #[test]
    fn nearest_range_per_sector() {
        let mut g = ProximityGrid::paper();
        g.update(&Obstacles {
            points_base: vec![[2.0, 0.0], [1.0, 0.0], [0.0, 3.0], [7.0, 0.0], [-1.0, 0.0]],
            ..Default::default()
        });
        assert_eq!(g.ranges_m[13], 1.0);
        // 90° left: sector (90 + 120) / 8.889 = 23.6 → 23
        assert_eq!(g.ranges_m[23], 3.0);
        // beyond 6 m and behind (180°, outside ±120°) are ignored
        assert_eq!(g.ranges_m.iter().filter(|r| r.is_finite()).count(), 2);
    }
}
