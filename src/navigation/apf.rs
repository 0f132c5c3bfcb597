//! The paper group's shared-dynamics potential field (the shared protocol
//! notes, §4): repellers from the proximity grid, an attractor towards the
//! goal, and a linear speed that falls with the nearest obstacle in the
//! chair's corridor.
//!
//! In the reference, with the heading φ = 0, sector i at distance dᵢ and
//! angle θᵢ:
//!   λᵢ = β₁·exp(−(dᵢ − d_front)/β₂)   (β₁ when dᵢ < d_front)
//!   σᵢ = atan(tan(Δθ/2) + (R + d_lat)/(R + d_lat + dᵢ))
//!   ω_rep = Σᵢ λᵢ(φ − θᵢ)·exp(−(φ − θᵢ)²/(2σᵢ²))
//!   ω_att = γ·sin(φ − ψ_target)
//! and the heading dynamics dφ/dt = −(ω_att − ω_rep) move φ towards the
//! target and away from obstacles. Our turn rate (counter-clockwise
//! positive, REP-103) is that dφ/dt: ω = ω_rep − ω_att, clamped.

use serde::Serialize;

use super::grid::ProximityGrid;

/// The field's parameters (config `[field]`, read directly).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ApfParams {
    /// Chair size (its width), m; R = size / 2.
    pub size_m: f64,
    pub beta1: f64,
    pub beta2_m: f64,
    pub gamma: f64,
    pub d_front_m: f64,
    pub d_lat_m: f64,
    pub v_max_mps: f64,
    /// Speed when something is closer than d_front ahead (negative: back off).
    pub v_close_mps: f64,
    pub decay_m: f64,
    pub omega_max_radps: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ApfOutput {
    pub v_mps: f64,
    pub omega_radps: f64,
    pub omega_attractor: f64,
    pub omega_repeller: f64,
    /// Nearest obstacle ahead inside the corridor, m (+∞ if none).
    pub corridor_distance_m: f64,
}

/// ω_rep of the reference (heading φ = 0).
pub fn repeller(grid: &ProximityGrid, p: &ApfParams) -> f64 {
    let r = p.size_m / 2.0;
    let mut w = 0.0;
    for (i, &d) in grid.ranges_m.iter().enumerate() {
        if !d.is_finite() {
            continue;
        }
        let theta = grid.sector_angle(i);
        let lambda = if d < p.d_front_m {
            p.beta1
        } else {
            p.beta1 * (-(d - p.d_front_m) / p.beta2_m).exp()
        };
        let sigma = ((grid.sector_rad / 2.0).tan() + (r + p.d_lat_m) / (r + p.d_lat_m + d)).atan();
        let dphi = 0.0 - theta;
        w += lambda * dphi * (-(dphi * dphi) / (2.0 * sigma * sigma)).exp();
    }
    w
}

/// The nearest forward distance (d·cos θ) among sectors whose points lie
/// within the chair's half width (|d·sin θ| ≤ size/2), ahead only.
pub fn corridor_distance(grid: &ProximityGrid, p: &ApfParams) -> f64 {
    grid.ranges_m
        .iter()
        .enumerate()
        .filter(|(_, d)| d.is_finite())
        .filter_map(|(i, &d)| {
            let th = grid.sector_angle(i);
            let (x, y) = (d * th.cos(), d * th.sin());
            (x > 0.0 && y.abs() <= p.size_m / 2.0).then_some(x)
        })
        .fold(f64::INFINITY, f64::min)
}

/// One step of the field: `target_bearing_rad` is ψ, the goal's bearing
/// in `base_link` (None: no goal, no attraction).
pub fn apf(grid: &ProximityGrid, target_bearing_rad: Option<f64>, p: &ApfParams) -> ApfOutput {
    let w_rep = repeller(grid, p);
    let w_att = target_bearing_rad.map_or(0.0, |psi| p.gamma * (0.0 - psi).sin());
    let omega = (w_rep - w_att).clamp(-p.omega_max_radps, p.omega_max_radps);
    let x = corridor_distance(grid, p);
    let v = if x > p.d_front_m {
        p.v_max_mps * (1.0 - (-(x - p.d_front_m) / p.decay_m).exp())
    } else {
        p.v_close_mps
    };
    ApfOutput {
        v_mps: if target_bearing_rad.is_some() { v } else { 0.0 },
        omega_radps: omega,
        omega_attractor: w_att,
        omega_repeller: w_rep,
        corridor_distance_m: x,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_with(sector: usize, d: f64) -> ProximityGrid {
        let mut g = ProximityGrid::paper();
        g.ranges_m[sector] = d;
        g
    }

    #[test]
    fn repeller_by_hand() {
        // sector 14 (θ = +8.889°) at 1.5 m
        let p = crate::config::Settings::defaults().field;
        let g = grid_with(14, 1.5);
        let theta = g.sector_angle(14);
        let lambda = 5.0 * (-(1.5 - 0.5) / 1.0f64).exp();
        let sigma = ((g.sector_rad / 2.0).tan() + (0.375 + 0.2) / (0.375 + 0.2 + 1.5)).atan();
        let want = lambda * (-theta) * (-(theta * theta) / (2.0 * sigma * sigma)).exp();
        assert!((repeller(&g, &p) - want).abs() < 1e-12);
        // an obstacle on the left turns the chair right
        let o = apf(&g, Some(0.0), &p);
        assert!(o.omega_radps < 0.0);
        // closer than d_front: λ = β₁
        let g = grid_with(14, 0.3);
        let sigma = ((g.sector_rad / 2.0).tan() + 0.575 / (0.575 + 0.3)).atan();
        let want = 5.0 * (-theta) * (-(theta * theta) / (2.0 * sigma * sigma)).exp();
        assert!((repeller(&g, &p) - want).abs() < 1e-12);
    }

    #[test]
    fn attractor_turns_towards_the_goal() {
        let p = crate::config::Settings::defaults().field;
        let g = ProximityGrid::paper();
        let o = apf(&g, Some(0.4), &p);
        assert!((o.omega_attractor - 0.5 * (-0.4f64).sin()).abs() < 1e-12);
        assert!((o.omega_radps - 0.5 * 0.4f64.sin()).abs() < 1e-12);
        // clamped
        let o = apf(&g, Some(1.5), &p);
        assert_eq!(o.omega_radps, 0.3);
        // open space: v → v_max·(1 − e^{−∞}) = v_max
        assert_eq!(o.v_mps, 0.25);
        assert_eq!(apf(&g, None, &p).v_mps, 0.0);
    }

    #[test]
    fn speed_falls_with_the_nearest_obstacle_in_the_corridor() {
        let p = crate::config::Settings::defaults().field;
        // straight ahead at 1.5 m
        let o = apf(&grid_with(13, 1.5), Some(0.0), &p);
        assert!((o.corridor_distance_m - 1.5).abs() < 1e-12);
        assert!((o.v_mps - 0.25 * (1.0 - (-1.0f64).exp())).abs() < 1e-12);
        // closer than d_front: back off slowly
        assert_eq!(apf(&grid_with(13, 0.4), Some(0.0), &p).v_mps, -0.05);
        // far to the side: not in the corridor
        let o = apf(&grid_with(22, 1.0), Some(0.0), &p);
        assert!(o.corridor_distance_m.is_infinite());
    }
}
