//! The map's ray walk (split out of `navigation::map`): the cells a ray
//! crosses, in order (Amanatides and Woo), for the lasers' update and
//! the search's looks.

use super::GridMap;
use crate::msg::floor_fast;

impl GridMap {
    /// The cells a ray from `o` along the unit `d` crosses up to `len`,
    /// in order (a grid walk, Amanatides and Woo), into `out`; it stops
    /// where the ray leaves the map.
    pub(super) fn ray_cells(&self, o: [f64; 2], d: [f64; 2], len: f64, out: &mut Vec<usize>) {
        out.clear();
        out.extend(self.ray_walk(o, d, len));
    }

    /// [`GridMap::ray_cells`] one cell at a time (borrowing nothing of
    /// the map: a caller may change cells as it walks).
    pub(super) fn ray_walk(&self, o: [f64; 2], d: [f64; 2], len: f64) -> RayWalk {
        let done = RayWalk {
            i: 0,
            step_x: 0,
            step_y: 0,
            left_x: 0,
            left_y: 0,
            t_next_x: f64::INFINITY,
            t_next_y: f64::INFINITY,
            t_delta_x: f64::INFINITY,
            t_delta_y: f64::INFINITY,
            len,
            done: true,
        };
        let r = self.settings.resolution_m;
        let g = [(o[0] - self.origin_m[0]) / r, (o[1] - self.origin_m[1]) / r];
        let n = self.n as i64;
        if !(g[0].is_finite() && g[1].is_finite() && len.is_finite()) {
            return done;
        }
        let c = [floor_fast(g[0]) as i64, floor_fast(g[1]) as i64];
        if c[0] < 0 || c[1] < 0 || c[0] >= n || c[1] >= n {
            return done;
        }
        // per axis: the index's step, the cells left on the map that way,
        // the ray length to the next boundary, and between boundaries
        let mut step = [0isize; 2];
        let mut left = [0i64; 2];
        let mut t_next = [f64::INFINITY; 2];
        let mut t_delta = [f64::INFINITY; 2];
        let row = [1isize, self.n as isize];
        for a in 0..2 {
            if d[a] > 0.0 {
                step[a] = row[a];
                left[a] = n - 1 - c[a];
                t_next[a] = ((c[a] as f64 + 1.0) - g[a]) * r / d[a];
                t_delta[a] = r / d[a];
            } else if d[a] < 0.0 {
                step[a] = -row[a];
                left[a] = c[a];
                t_next[a] = (g[a] - c[a] as f64) * r / -d[a];
                t_delta[a] = r / -d[a];
            }
        }
        RayWalk {
            i: c[1] as usize * self.n + c[0] as usize,
            step_x: step[0],
            step_y: step[1],
            left_x: left[0],
            left_y: left[1],
            t_next_x: t_next[0],
            t_next_y: t_next[1],
            t_delta_x: t_delta[0],
            t_delta_y: t_delta[1],
            len,
            done: false,
        }
    }
}

/// The cells of one ray, in order ([`GridMap::ray_walk`]). Per axis
/// (x, y) in scalars, not arrays: an array indexed by the axis of each
/// step would keep them in memory.
pub(super) struct RayWalk {
    /// The cell to give next (unless `done`).
    i: usize,
    /// Per axis: the index's step, the cells left on the map that way,
    /// the ray length to the next boundary, and between boundaries.
    step_x: isize,
    step_y: isize,
    left_x: i64,
    left_y: i64,
    t_next_x: f64,
    t_next_y: f64,
    t_delta_x: f64,
    t_delta_y: f64,
    len: f64,
    done: bool,
}

impl Iterator for RayWalk {
    type Item = usize;

    fn next(&mut self) -> Option<usize> {
        if self.done {
            return None;
        }
        let i = self.i;
        let x = self.t_next_x < self.t_next_y;
        let (t, left) = if x {
            (self.t_next_x, self.left_x)
        } else {
            (self.t_next_y, self.left_y)
        };
        // past its length, or the next cell off the map
        if t > self.len || left == 0 {
            self.done = true;
        } else if x {
            self.left_x -= 1;
            self.i = i.wrapping_add_signed(self.step_x);
            self.t_next_x += self.t_delta_x;
        } else {
            self.left_y -= 1;
            self.i = i.wrapping_add_signed(self.step_y);
            self.t_next_y += self.t_delta_y;
        }
        Some(i)
    }
}
