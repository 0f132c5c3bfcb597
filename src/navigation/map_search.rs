//! The map's part in the search (split out of `navigation::map`): what
//! the camera has looked at and what is left for it to look at, the
//! nearest frontier, places with room to turn.

use std::cmp::Ordering::Less;

use super::{GridMap, LOOK_PAST_UNSEEN_M, UNLOOKED_CELLS};
use crate::msg::hypot_cmp;

impl GridMap {
    /// The camera at `origin` (odom) looking along `yaw_rad` with a
    /// horizontal half-angle of `half_fov_rad`, out to `range_m`: the
    /// seen free cells in its view, up to the first blocked or unseen cell
    /// of each ray, and that blocked cell, are looked at (unseen cells
    /// within [`LOOK_PAST_UNSEEN_M`] of the camera are passed over).
    pub fn look(&mut self, origin: [f64; 2], yaw_rad: f64, half_fov_rad: f64, range_m: f64) {
        let r = self.settings.resolution_m;
        // rays one cell apart at the far end
        let rays = ((2.0 * half_fov_rad * range_m / r).ceil() as usize).clamp(2, 4096);
        let mut cells = Vec::new();
        for k in 0..=rays {
            let a = yaw_rad - half_fov_rad + 2.0 * half_fov_rad * k as f64 / rays as f64;
            self.ray_cells(origin, [a.cos(), a.sin()], range_m, &mut cells);
            for &i in &cells {
                if !self.is_known(i) {
                    let p = self.center(i);
                    if hypot_cmp(p[0] - origin[0], p[1] - origin[1], LOOK_PAST_UNSEEN_M)
                        == Some(Less)
                    {
                        continue;
                    }
                    break;
                }
                self.looked[i] = true;
                if self.is_blocked(i) {
                    break;
                }
            }
        }
    }

    /// Looked at by the camera ([`GridMap::look`]).
    /// Per bearing from `origin` (odom; `bins` over a whole turn, bin k
    /// centred on 2πk/`bins` rad): whether the camera looking that way
    /// would see something it has not looked at — beyond `start_m` (the
    /// chair itself) and within `range_m`, [`UNLOOKED_CELLS`] seen cells
    /// not looked at before the first blocked one, or unseen space before
    /// any looked-at cell (nothing seen that way, nothing looked at).
    pub fn unlooked_bearings(
        &self,
        origin: [f64; 2],
        start_m: f64,
        range_m: f64,
        bins: usize,
    ) -> Vec<bool> {
        let mut cells = Vec::new();
        (0..bins)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / bins as f64;
                let d = [a.cos(), a.sin()];
                self.ray_cells(origin, d, range_m, &mut cells);
                let mut unlooked = 0;
                let mut any_looked = false;
                for &i in &cells {
                    let p = self.center(i);
                    if hypot_cmp(p[0] - origin[0], p[1] - origin[1], start_m) == Some(Less) {
                        continue;
                    }
                    if !self.is_known(i) {
                        return !any_looked;
                    }
                    if self.looked[i] {
                        any_looked = true;
                    } else {
                        unlooked += 1;
                        if unlooked >= UNLOOKED_CELLS {
                            return true;
                        }
                    }
                    if self.is_blocked(i) {
                        return false;
                    }
                }
                false
            })
            .collect()
    }

    pub fn is_looked(&self, i: usize) -> bool {
        self.looked[i]
    }

    /// The nearest frontier by path (a seen free cell next to space the
    /// camera has not looked at, laser-unseen space included, with
    /// `room_m` to everything — room to turn there) at least
    /// `min_m` from `from` and farther than `avoid_m` from each of `avoid`
    /// (frontiers already visited). Where none is reached through seen
    /// space (a room looked at all round, its doorway seen only edge-on),
    /// the nearest such place by a way that may cross unseen space: the
    /// chair drives towards it, and the lasers show what is there.
    pub fn frontier(
        &mut self,
        from: [f64; 2],
        min_m: f64,
        room_m: f64,
        avoid: &[[f64; 2]],
        avoid_m: f64,
    ) -> Option<[f64; 2]> {
        self.update_distances();
        let n = self.n;
        let reach = (0.5 / self.settings.resolution_m).round() as i64;
        let samples = ((reach + 1) * (reach + 1)) as usize;
        let is_goal = |i: usize| {
            let p = self.center(i);
            if (self.dist[i] as f64) < room_m
                || (p[0] - from[0]).hypot(p[1] - from[1]) < min_m
                || avoid
                    .iter()
                    .any(|a| (p[0] - a[0]).hypot(p[1] - a[1]) <= avoid_m)
            {
                return false;
            }
            let (x, y) = (i % n, i / n);
            let unseen = |dx: i64, dy: i64| {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                nx >= 0
                    && ny >= 0
                    && (nx as usize) < n
                    && (ny as usize) < n
                    && !self.looked[ny as usize * n + nx as usize]
            };
            if ![(1i64, 0i64), (-1, 0), (0, 1), (0, -1)]
                .iter()
                .any(|(dx, dy)| unseen(*dx, *dy))
            {
                return false;
            }
            // worth going to: a quarter of the square metre about it
            // unseen (not the shadow of a chair leg)
            let mut count = 0;
            for dy in (-reach..=reach).step_by(2) {
                for dx in (-reach..=reach).step_by(2) {
                    count += usize::from(unseen(dx, dy));
                }
            }
            count * 4 >= samples
        };
        let (end, _) = self
            .search(from, &is_goal, &|_| 0.0, false)
            .or_else(|| self.search(from, &is_goal, &|_| 0.0, true))?;
        Some(self.center(end))
    }

    /// The nearest place by path, at least `min_m` from `from`, with
    /// `room_m` to everything (room to turn on the spot), through seen
    /// free space.
    pub fn room_to_turn(&mut self, from: [f64; 2], min_m: f64, room_m: f64) -> Option<[f64; 2]> {
        self.room_to_turn_within(from, min_m, room_m, None)
    }

    /// [`GridMap::room_to_turn`] among the places whose bearing from
    /// `from` lies within `half_angle_rad` of `yaw_rad` (odom) when
    /// `ahead` is `Some((yaw_rad, half_angle_rad))`: a place the chair
    /// reaches without first turning round.
    pub fn room_to_turn_within(
        &mut self,
        from: [f64; 2],
        min_m: f64,
        room_m: f64,
        ahead: Option<(f64, f64)>,
    ) -> Option<[f64; 2]> {
        self.update_distances();
        let is_goal = |i: usize| {
            let p = self.center(i);
            let (dx, dy) = (p[0] - from[0], p[1] - from[1]);
            self.dist[i] as f64 >= room_m
                && self.is_known(i)
                && dx.hypot(dy) >= min_m
                && ahead.is_none_or(|(yaw_rad, half_rad)| {
                    crate::msg::wrap_angle(dy.atan2(dx) - yaw_rad).abs() <= half_rad
                })
        };
        let (end, _) = self.search(from, &is_goal, &|_| 0.0, false)?;
        Some(self.center(end))
    }
}
