//! The catheter tip's active bending (the paper's eqs 11-16): the bending part, `n` balls over
//! an axis of length `L`, bends along an arc of constant curvature whose axis keeps its length,
//! the balls evenly spaced along it. With `theta` the bending angle (half the arc's turning:
//! the chord from the first ball to the last makes `theta` with the straight axis):
//!
//! - `beta = theta / (n - 1)`: the angle between the chords from the first ball to balls
//!   `i - 1` and `i` (eq 11);
//! - `s = 2 R sin(theta / (n - 1))`: the chord between neighbours (eq 12);
//! - `R = L / (2 theta)`: the arc's radius (eq 13);
//! - `D_i = D_(i-1) cos(beta) + sqrt(s^2 - (D_(i-1) sin(beta))^2)`: the distance from the
//!   first ball to ball `i` (eq 14);
//! - `dx_i = D_i sin((i - 1) beta)`, `dy_i = D_i cos((i - 1) beta) - (i - 1) L / (n - 1)`: its
//!   offset from where it is when straight, across and along the axis (eqs 15-16).
//!
//! The balls are numbered from 1 (the first, which stays) to `n` in the paper; here from 0.

/// The arc for `n` balls over axis length `length_m` bent by `theta_rad` (eqs 11-13): `beta`,
/// the neighbours' chord `s` and the radius (infinite when straight).
pub fn arc(n: usize, length_m: f64, theta_rad: f64) -> (f64, f64, f64) {
    let segments = n.saturating_sub(1).max(1) as f64;
    let beta = theta_rad / segments;
    if theta_rad.abs() < 1e-12 {
        return (0.0, length_m / segments, f64::INFINITY);
    }
    let radius = length_m / (2.0 * theta_rad);
    let s = 2.0 * radius * (theta_rad / segments).sin();
    (beta, s, radius)
}

/// Each ball's offset from its straight place, `(dx, dy)` across and along the axis (eqs
/// 14-16), the first ball's `(0, 0)`.
pub fn offsets(n: usize, length_m: f64, theta_rad: f64) -> Vec<(f64, f64)> {
    let (beta, s, _) = arc(n, length_m, theta_rad);
    let segments = n.saturating_sub(1).max(1) as f64;
    let mut out = Vec::with_capacity(n);
    let mut d = 0.0f64;
    for i in 0..n {
        if i > 0 {
            // Eq 14: the triangle first ball, ball i-1, ball i.
            let across = d * beta.sin();
            d = d * beta.cos() + (s * s - across * across).max(0.0).sqrt();
        }
        let k = i as f64;
        out.push((
            d * (k * beta).sin(),
            d * (k * beta).cos() - k * length_m / segments,
        ));
    }
    out
}

/// The turning between neighbouring chords on the arc: the rest angle of each angle spring
/// inside the bending part, rad (twice `beta`: a chord turns by the central angle it spans).
pub fn turn_per_ball(n: usize, theta_rad: f64) -> f64 {
    2.0 * theta_rad / n.saturating_sub(1).max(1) as f64
}
