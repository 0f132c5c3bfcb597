//! Laser scan matching (pure): point-to-point ICP in 2D on the merged
//! scans (base_link points), with a dense grid for nearest neighbours and
//! trimming of the worst pairs (partial overlap, moving people), and a
//! keyframe matcher that turns each match into an absolute pose for
//! [`PoseEkf::correct`](super::ekf::PoseEkf::correct): the current scan is
//! matched against the last keyframe's, starting from the odometry's guess,
//! so wheel slip on turns is measured by the walls and removed.

use nalgebra::Matrix3;
use serde::Serialize;

use super::ekf::PoseEkf;
use crate::msg::{wrap_angle, Pose2};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpParams {
    pub max_iterations: usize,
    /// Pairs farther apart than this are not correspondences, m (the
    /// first iteration's gate; it shrinks by `gate_decay` per iteration
    /// down to `min_pair_distance_m`, coarse to fine).
    pub max_pair_distance_m: f64,
    pub min_pair_distance_m: f64,
    pub gate_decay: f64,
    /// Keep this fraction of the closest pairs each iteration.
    pub trim_fraction: f64,
    /// Fewer matched pairs than this: no result.
    pub min_pairs: usize,
    /// Stop when an iteration moves less than this (m and rad).
    pub converged_step: f64,
    /// A result with a larger RMS pair distance is rejected, m.
    pub max_rms_m: f64,
    /// Smallest / largest eigenvalue of the translation block of the
    /// information matrix below this: degenerate, rejected.
    pub min_information_ratio: f64,
    /// Cell of the reference's neighbour grid, m: about the points'
    /// spacing on a nearby wall (searches are exact whatever the cell;
    /// it only sets their speed).
    pub grid_cell_m: f64,
}

impl Default for IcpParams {
    fn default() -> Self {
        IcpParams {
            max_iterations: 60,
            max_pair_distance_m: 1.0,
            min_pair_distance_m: 0.1,
            gate_decay: 0.85,
            trim_fraction: 0.9,
            min_pairs: 40,
            converged_step: 1e-5,
            max_rms_m: 0.05,
            min_information_ratio: 0.05,
            grid_cell_m: 0.03,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IcpResult {
    /// The current scan's pose in the reference scan's frame.
    pub ref_from_cur: Pose2,
    pub rms_m: f64,
    pub pairs: usize,
    pub iterations: usize,
    pub converged: bool,
    /// Smallest / largest eigenvalue of the translation information.
    pub information_ratio: f64,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScanMatchError {
    #[error("scan matching: {which} scan has {got} points, at least {need} needed")]
    TooFewPoints {
        which: &'static str,
        got: usize,
        need: usize,
    },
    #[error("scan matching: only {pairs} point pairs within {max_m} m (need {need})")]
    TooFewPairs {
        pairs: usize,
        max_m: f64,
        need: usize,
    },
    #[error("scan matching: residual {rms_m:.3} m above {max_m} m")]
    PoorFit { rms_m: f64, max_m: f64 },
    #[error("scan matching: a point is not finite ({point:?})")]
    NotFinite { point: [f64; 2] },
    /// The scene constrains the pose in too few directions (a bare
    /// corridor, one wall): the match would slide.
    #[error("scan matching: degenerate geometry (information ratio {ratio:.1e} below {min:.0e})")]
    Degenerate { ratio: f64, min: f64 },
}

#[path = "scan_match_grid.rs"]
mod grid;
use grid::{Grid, NearestCache};

/// The unit normal of the reference surface at each point (the line
/// through its neighbours within `radius_m`), or None where the
/// neighbourhood is not line-like (corners, clutter, isolated points).
fn normals(pts: &[[f64; 2]], grid: &Grid, radius_m: f64) -> Vec<Option<[f64; 2]>> {
    let r2 = radius_m * radius_m;
    let mut near: Vec<(u32, [f64; 2])> = Vec::new();
    pts.iter()
        .map(|p| {
            near.clear();
            grid.for_each_near(p, radius_m, |i, q, d2| {
                if d2 <= r2 {
                    near.push((i, *q));
                }
            });
            // in index order, as the sums were always taken
            near.sort_unstable_by_key(|(i, _)| *i);
            let n = near.len() as f64;
            let (mx, my) = near
                .iter()
                .fold((0.0, 0.0), |(x, y), (_, q)| (x + q[0], y + q[1]));
            if near.len() < 3 {
                return None;
            }
            let (mx, my) = (mx / n, my / n);
            let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
            for (_, q) in &near {
                let (dx, dy) = (q[0] - mx, q[1] - my);
                sxx += dx * dx;
                sxy += dx * dy;
                syy += dy * dy;
            }
            // eigenvalues of [[sxx, sxy], [sxy, syy]]
            let tr = sxx + syy;
            let det = sxx * syy - sxy * sxy;
            let disc = (tr * tr / 4.0 - det).max(0.0).sqrt();
            let (l_big, l_small) = (tr / 2.0 + disc, tr / 2.0 - disc);
            if l_big <= 0.0 || l_small > 0.05 * l_big {
                return None;
            }
            // direction of the line: eigenvector of l_big; the normal is
            // perpendicular to it
            let (vx, vy) = if sxy.abs() > 1e-15 {
                (l_big - syy, sxy)
            } else if sxx >= syy {
                (1.0, 0.0)
            } else {
                (0.0, 1.0)
            };
            let norm = vx.hypot(vy);
            Some([-vy / norm, vx / norm])
        })
        .collect()
}

fn apply(t: &Pose2, p: &[f64; 2]) -> [f64; 2] {
    apply_turned(t, t.theta_rad.cos(), t.theta_rad.sin(), p)
}

/// [`apply`] with the pose's cosine `c` and sine `s` given.
fn apply_turned(t: &Pose2, c: f64, s: f64, p: &[f64; 2]) -> [f64; 2] {
    [t.x_m + c * p[0] - s * p[1], t.y_m + s * p[0] + c * p[1]]
}

/// Composes `a ∘ b` (b expressed in a's frame).
pub fn compose(a: &Pose2, b: &Pose2) -> Pose2 {
    let p = apply(a, &[b.x_m, b.y_m]);
    Pose2 {
        x_m: p[0],
        y_m: p[1],
        theta_rad: wrap_angle(a.theta_rad + b.theta_rad),
    }
}

/// The inverse transform.
pub fn inverse(a: &Pose2) -> Pose2 {
    let (c, s) = (a.theta_rad.cos(), a.theta_rad.sin());
    Pose2 {
        x_m: -(c * a.x_m + s * a.y_m),
        y_m: s * a.x_m - c * a.y_m,
        theta_rad: wrap_angle(-a.theta_rad),
    }
}

/// (current point moved into the reference frame, its reference point,
/// squared distance, the reference normal there)
type Pair = ([f64; 2], [f64; 2], f64, Option<[f64; 2]>);

/// Aligns `current` to `reference` from `initial` (the current scan's pose
/// in the reference frame, e.g. from odometry).
pub fn icp(
    reference: &[[f64; 2]],
    current: &[[f64; 2]],
    initial: Pose2,
    p: &IcpParams,
) -> Result<IcpResult, ScanMatchError> {
    icp_against(&mut IcpReference::new(reference, p)?, current, initial, p)
}

/// A reference scan prepared for matching (its grid and surface normals),
/// kept while it is the keyframe.
#[derive(Clone)]
pub struct IcpReference {
    points: Vec<[f64; 2]>,
    grid: Grid,
    normals: Vec<Option<[f64; 2]>>,
    /// The searches' candidates, gathered as queries come.
    cache: NearestCache,
}

impl IcpReference {
    pub fn new(points: &[[f64; 2]], p: &IcpParams) -> Result<IcpReference, ScanMatchError> {
        check_points("reference", points, p)?;
        let grid = Grid::new(points, p.grid_cell_m.max(1e-3));
        let normals = normals(points, &grid, 0.3);
        Ok(IcpReference {
            points: points.to_vec(),
            cache: NearestCache::new(&grid),
            grid,
            normals,
        })
    }
}

impl std::fmt::Debug for IcpReference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "IcpReference({} points)", self.points.len())
    }
}

fn check_points(
    which: &'static str,
    pts: &[[f64; 2]],
    p: &IcpParams,
) -> Result<(), ScanMatchError> {
    if pts.len() < p.min_pairs {
        return Err(ScanMatchError::TooFewPoints {
            which,
            got: pts.len(),
            need: p.min_pairs,
        });
    }
    match pts.iter().find(|q| !(q[0].is_finite() && q[1].is_finite())) {
        Some(bad) => Err(ScanMatchError::NotFinite { point: *bad }),
        None => Ok(()),
    }
}

/// The next iteration's gate is at most this many times the farthest pair
/// kept in this one.
const GATE_OVER_KEPT: f64 = 3.0;

/// Aligns `current` to a prepared reference from `initial` (the reference
/// keeps what its searches gathered, for the next scan matched to it).
pub fn icp_against(
    reference: &mut IcpReference,
    current: &[[f64; 2]],
    initial: Pose2,
    p: &IcpParams,
) -> Result<IcpResult, ScanMatchError> {
    check_points("current", current, p)?;
    let IcpReference {
        points: reference,
        grid,
        normals: ref_normals,
        cache,
    } = reference;
    let mut gate = p.max_pair_distance_m;
    let mut t = initial;
    let mut rms = f64::INFINITY;
    let mut pairs_used = 0;
    let mut converged = false;
    let mut iterations = 0;
    let mut info = Matrix3::<f64>::zeros();
    let mut pairs: Vec<Pair> = Vec::with_capacity(current.len());
    for it in 0..p.max_iterations {
        iterations = it + 1;
        let gate_now = gate;
        pairs.clear();
        // the pose's cosine and sine once for all the scan's points
        let (c, s) = (t.theta_rad.cos(), t.theta_rad.sin());
        for q in current {
            let qt = apply_turned(&t, c, s, q);
            if let Some((i, d2)) = cache.nearest(grid, reference, &qt, gate_now) {
                pairs.push((qt, reference[i], d2, ref_normals[i]));
            }
        }
        // the closest `trim_fraction` of the pairs (in no particular order)
        let keep = ((pairs.len() as f64) * p.trim_fraction).round() as usize;
        if keep > 0 && keep < pairs.len() {
            pairs.select_nth_unstable_by(keep - 1, |a, b| a.2.total_cmp(&b.2));
        }
        pairs.truncate(keep);
        // coarse to fine: the gate shrinks by its decay, and at once to a
        // few times the farthest pair kept once the scans lie close
        // (a good odometry guess needs no 15 iterations of shrinking)
        let kept_m = pairs.iter().map(|x| x.2).fold(0.0, f64::max).sqrt();
        gate = (gate * p.gate_decay)
            .min(GATE_OVER_KEPT * kept_m)
            .max(p.min_pair_distance_m);
        if pairs.len() < p.min_pairs {
            return Err(ScanMatchError::TooFewPairs {
                pairs: pairs.len(),
                max_m: p.max_pair_distance_m,
                need: p.min_pairs,
            });
        }
        pairs_used = pairs.len();
        // the residual: distance to the line where there is one
        rms = (pairs
            .iter()
            .map(|(a, b, d2, n)| match n {
                Some(n) => ((a[0] - b[0]) * n[0] + (a[1] - b[1]) * n[1]).powi(2),
                None => *d2,
            })
            .sum::<f64>()
            / pairs.len() as f64)
            .sqrt();
        // point-to-line where the reference has a line-like normal,
        // point-to-point elsewhere: one Gauss-Newton step in (dx, dy, dθ),
        // rotation about the origin of the reference frame
        let mut h = Matrix3::<f64>::zeros();
        let mut g = nalgebra::Vector3::<f64>::zeros();
        for (a, b, _, n) in &pairs {
            let e = [a[0] - b[0], a[1] - b[1]];
            let perp = [-a[1], a[0]];
            let rows: [([f64; 3], f64); 2] = match n {
                Some(n) => [
                    (
                        [n[0], n[1], n[0] * perp[0] + n[1] * perp[1]],
                        n[0] * e[0] + n[1] * e[1],
                    ),
                    ([0.0; 3], 0.0),
                ],
                None => [([1.0, 0.0, perp[0]], e[0]), ([0.0, 1.0, perp[1]], e[1])],
            };
            for (j, r) in rows {
                let jv = nalgebra::Vector3::new(j[0], j[1], j[2]);
                h += jv * jv.transpose();
                g += jv * r;
            }
        }
        info = h;
        h += Matrix3::identity() * 1e-9;
        let Some(delta) = h.lu().solve(&(-g)) else {
            break;
        };
        let dth = delta[2];
        let step = Pose2 {
            x_m: delta[0],
            y_m: delta[1],
            theta_rad: dth,
        };
        t = compose(&step, &t);
        if step.x_m.hypot(step.y_m) < p.converged_step
            && dth.abs() < p.converged_step
            && gate <= p.min_pair_distance_m
        {
            converged = true;
            break;
        }
    }
    if rms > p.max_rms_m {
        return Err(ScanMatchError::PoorFit {
            rms_m: rms,
            max_m: p.max_rms_m,
        });
    }
    // observability of the translation (the rotation is pinned by the
    // lever arms of far points in any scene): a bare corridor leaves the
    // direction along it unconstrained
    let eig = info
        .fixed_view::<2, 2>(0, 0)
        .into_owned()
        .symmetric_eigenvalues();
    let (lo, hi) = (eig.min(), eig.max());
    let ratio = if hi > 0.0 { lo / hi } else { 0.0 };
    if ratio < p.min_information_ratio {
        return Err(ScanMatchError::Degenerate {
            ratio,
            min: p.min_information_ratio,
        });
    }
    Ok(IcpResult {
        ref_from_cur: t,
        rms_m: rms,
        pairs: pairs_used,
        iterations,
        converged,
        information_ratio: ratio,
    })
}

/// Scan-to-keyframe matching feeding the EKF.
#[derive(Debug, Clone)]
pub struct KeyframeMatcher {
    pub icp: IcpParams,
    /// A new keyframe after moving this far, m / turning this much, rad.
    pub keyframe_distance_m: f64,
    pub keyframe_turn_rad: f64,
    /// Measurement standard deviation at zero residual (m, rad); grows
    /// with the residual.
    pub sigma_xy_m: f64,
    pub sigma_theta_rad: f64,
    keyframe: Option<(Pose2, IcpReference)>,
    pub matched: u64,
    pub rejected: u64,
}

impl Default for KeyframeMatcher {
    fn default() -> Self {
        KeyframeMatcher {
            icp: IcpParams::default(),
            keyframe_distance_m: 0.3,
            keyframe_turn_rad: 0.35,
            sigma_xy_m: 0.01,
            sigma_theta_rad: 0.005,
            keyframe: None,
            matched: 0,
            rejected: 0,
        }
    }
}

impl KeyframeMatcher {
    /// A merged scan (points in base_link) taken when the EKF's pose was
    /// its current one: matches it against the keyframe and corrects the
    /// EKF. The keyframes' poses are chained from the matches themselves
    /// (scan odometry), not from the EKF, so a correction the filter only
    /// partly adopted is not baked into the next keyframe. Returns the
    /// match, or why there was none (the chain restarts from the EKF).
    pub fn update(
        &mut self,
        ekf: &mut PoseEkf,
        scan_base: &[[f64; 2]],
    ) -> Option<Result<IcpResult, ScanMatchError>> {
        let Some((key_pose, key_ref)) = &mut self.keyframe else {
            return self.set_keyframe(ekf.pose, scan_base).err().map(Err);
        };
        let key_pose = *key_pose;
        // odometry's guess of the scan's pose in the keyframe
        let guess = compose(&inverse(&key_pose), &ekf.pose);
        let r = icp_against(key_ref, scan_base, guess, &self.icp);
        match &r {
            Ok(m) => {
                self.matched += 1;
                let z = compose(&key_pose, &m.ref_from_cur);
                let grow = 1.0 + m.rms_m / 0.01;
                let (sxy, sth) = (self.sigma_xy_m * grow, self.sigma_theta_rad * grow);
                ekf.correct(
                    z,
                    Matrix3::from_diagonal(&nalgebra::Vector3::new(
                        sxy * sxy,
                        sxy * sxy,
                        sth * sth,
                    )),
                );
                let moved = m.ref_from_cur.x_m.hypot(m.ref_from_cur.y_m);
                if moved >= self.keyframe_distance_m
                    || m.ref_from_cur.theta_rad.abs() >= self.keyframe_turn_rad
                {
                    // a scan that matched has enough finite points
                    self.set_keyframe(z, scan_base).ok();
                }
            }
            Err(_) => {
                self.rejected += 1;
                // start again from here: the old keyframe no longer overlaps
                // (a scan unfit to be one leaves none: the next scan is)
                self.set_keyframe(ekf.pose, scan_base).ok();
            }
        }
        Some(r)
    }

    /// Makes `scan_base` the keyframe at `pose`; a scan that cannot be a
    /// reference (too few or non-finite points) leaves no keyframe.
    fn set_keyframe(&mut self, pose: Pose2, scan_base: &[[f64; 2]]) -> Result<(), ScanMatchError> {
        self.keyframe = None;
        self.keyframe = Some((pose, IcpReference::new(scan_base, &self.icp)?));
        Ok(())
    }
}

#[cfg(test)]
#[path = "scan_match_tests.rs"]
mod tests;
