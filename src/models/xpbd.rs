//! XPBD projections of the paper's constraints: stretch (eq 11) and dihedral bending (eq 12).
//! Compliance (inverse stiffness) makes the stiffness independent of dt and iteration count.
//! Every particle has unit mass (inverse mass 1) unless it is pinned (inverse mass 0).

use glam::Vec3;

/// A distance constraint C = |x1 - x2| - d12 (eq 11).
#[derive(Debug, Clone, Copy)]
pub struct Stretch {
    pub a: u32,
    pub b: u32,
    pub rest_m: f32,
}

/// A dihedral constraint C = acos(n1 . n2) - phi12 (eq 12) over the hinge (a, b) with wings
/// c and d, n1 = (b - a) x (c - a), n2 = (b - a) x (d - a) (Bender's convention: a flat hinge
/// has angle pi).
#[derive(Debug, Clone, Copy)]
pub struct Bend {
    pub a: u32,
    pub b: u32,
    pub c: u32,
    pub d: u32,
    pub rest_rad: f32,
}

/// Projects one stretch constraint; returns the Lagrange multiplier increment. The force the
/// constraint exerts is lambda / dt^2 (newtons with unit mass).
pub fn project_stretch(
    x: &mut [Vec3],
    w: &[f32],
    c: &Stretch,
    compliance_m_per_n: f32,
    dt_s: f32,
    lambda: f32,
) -> f32 {
    let (a, b) = (c.a as usize, c.b as usize);
    let wsum = w[a] + w[b];
    if wsum == 0.0 {
        return 0.0;
    }
    let d = x[a] - x[b];
    let len = d.length();
    if len <= f32::EPSILON {
        return 0.0;
    }
    let n = d / len;
    let alpha = compliance_m_per_n / (dt_s * dt_s);
    let constraint = len - c.rest_m;
    let dl = (-constraint - alpha * lambda) / (wsum + alpha);
    x[a] += n * (w[a] * dl);
    x[b] -= n * (w[b] * dl);
    dl
}

/// The dihedral angle between triangles (a, b, c) and (b, a, d), radians in [0, pi].
pub fn dihedral(x: &[Vec3], c: &Bend) -> f32 {
    let (p1, p2, p3, p4) = (
        x[c.a as usize],
        x[c.b as usize],
        x[c.c as usize],
        x[c.d as usize],
    );
    // Same convention as the projection: flat hinge = pi.
    let n1 = (p2 - p1).cross(p3 - p1).normalize_or_zero();
    let n2 = (p2 - p1).cross(p4 - p1).normalize_or_zero();
    n1.dot(n2).clamp(-1.0, 1.0).acos()
}

/// Projects one bending constraint with gradients from Bender et al.'s PBD dihedral formula
/// (positions taken relative to the hinge's first point).
pub fn project_bend(
    x: &mut [Vec3],
    w: &[f32],
    c: &Bend,
    compliance: f32,
    dt_s: f32,
    lambda: f32,
) -> f32 {
    let (ia, ib, ic, id) = (c.a as usize, c.b as usize, c.c as usize, c.d as usize);
    let p1 = x[ia];
    let p2 = x[ib] - p1;
    let p3 = x[ic] - p1;
    let p4 = x[id] - p1;
    let c23 = p2.cross(p3);
    let c24 = p2.cross(p4);
    let (l23, l24) = (c23.length(), c24.length());
    if l23 <= 1e-12 || l24 <= 1e-12 {
        return 0.0;
    }
    let n1 = c23 / l23;
    let n2 = c24 / l24;
    let d = n1.dot(n2).clamp(-1.0, 1.0);
    let angle = d.acos();
    let constraint = angle - c.rest_rad;
    let s = (1.0 - d * d).sqrt();
    if s < 1e-6 {
        return 0.0;
    }
    let q3 = (p2.cross(n2) + n1.cross(p2) * d) / l23;
    let q4 = (p2.cross(n1) + n2.cross(p2) * d) / l24;
    let q2 = -(p3.cross(n2) + n1.cross(p3) * d) / l23 - (p4.cross(n1) + n2.cross(p4) * d) / l24;
    let q1 = -q2 - q3 - q4;
    // The q's are the gradients of -d in this convention (the sign the PBD paper's appendix
    // leaves implicit), and d(acos u)/du = -1 / sqrt(1 - u^2).
    let g = [q1, q2, q3, q4].map(|q| q * (1.0 / s));
    let idx = [ia, ib, ic, id];
    let denom: f32 = (0..4).map(|k| w[idx[k]] * g[k].length_squared()).sum();
    let alpha = compliance / (dt_s * dt_s);
    if denom + alpha <= 1e-12 {
        return 0.0;
    }
    let dl = (-constraint - alpha * lambda) / (denom + alpha);
    for k in 0..4 {
        x[idx[k]] += g[k] * (w[idx[k]] * dl);
    }
    dl
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stretched_edge_strain_goes_to_zero_under_a_stiff_constraint() {
        let mut x = vec![Vec3::ZERO, Vec3::new(0.012, 0.0, 0.0)];
        let w = [1.0, 1.0];
        let c = Stretch {
            a: 0,
            b: 1,
            rest_m: 0.01,
        };
        // Zero compliance: one projection removes the 20 % strain exactly.
        project_stretch(&mut x, &w, &c, 0.0, 0.002, 0.0);
        let strain = ((x[1] - x[0]).length() - 0.01) / 0.01;
        assert!(strain.abs() < 1e-5, "strain {strain}");
        // Each end moved by half the excess.
        assert!((x[0].x - 0.001).abs() < 1e-7);
    }

    #[test]
    fn compliant_stretch_converges_over_iterations_independent_of_substeps() {
        let run = |iters: usize| {
            let mut x = vec![Vec3::ZERO, Vec3::new(0.02, 0.0, 0.0)];
            let mut lambda = 0.0;
            let c = Stretch {
                a: 0,
                b: 1,
                rest_m: 0.01,
            };
            for _ in 0..iters {
                lambda += project_stretch(&mut x, &[1.0, 0.0], &c, 1e-4, 0.002, lambda);
            }
            (x[1] - x[0]).length()
        };
        let (l10, l200) = (run(10), run(200));
        // XPBD fixed point: C = -alpha_tilde * lambda, with a pinned end and unit mass the
        // strain left is alpha / (1 + alpha) of the excess; alpha = 1e-4 / 4e-6 = 25.
        let expect = 0.01 + 0.01 * 25.0 / 26.0;
        assert!((l200 - expect).abs() < 1e-5, "{l200} vs {expect}");
        assert!((l10 - 0.02).abs() > 1e-6);
    }

    #[test]
    fn bending_restores_the_rest_dihedral() {
        // A flat hinge folded to 60 degrees, pinned hinge, free wings.
        let rest = vec![
            Vec3::ZERO,
            Vec3::new(0.0, 0.01, 0.0),
            Vec3::new(-0.01, 0.005, 0.0),
            Vec3::new(0.01, 0.005, 0.0),
        ];
        let mut c = Bend {
            a: 0,
            b: 1,
            c: 2,
            d: 3,
            rest_rad: 0.0,
        };
        // A hinge with a 30-degree fold at rest.
        let mut rest = rest;
        rest[3] = Vec3::new(0.00866, 0.005, 0.005);
        c.rest_rad = dihedral(&rest, &c);
        let pi = std::f32::consts::PI;
        assert!((c.rest_rad - 5.0 * pi / 6.0).abs() < 1e-3, "{}", c.rest_rad);
        // Folded to 90 degrees.
        let mut x = rest.clone();
        x[3] = Vec3::new(0.0, 0.005, 0.01);
        assert!((dihedral(&x, &c) - pi / 2.0).abs() < 1e-3);
        let w = [0.0, 0.0, 1.0, 1.0];
        for _ in 0..50 {
            project_bend(&mut x, &w, &c, 0.0, 0.002, 0.0);
        }
        let err = (dihedral(&x, &c) - c.rest_rad).abs();
        assert!(err < 0.01, "{err}");
    }
}
