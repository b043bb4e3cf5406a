//! XPBD projections of the paper's constraints: stretch (eq 11) and dihedral bending (eq 12).
//! Compliance (inverse stiffness) makes the stiffness independent of dt and iteration count.
//! Each particle carries its inverse mass (0 when pinned), so lambda / dt^2 is a force in newtons.

use glam::Vec3;

/// A distance constraint C = |x1 - x2| - d12 (eq 11).
#[derive(Debug, Clone, Copy)]
pub struct Stretch {
    pub a: u32,
    pub b: u32,
    pub rest_m: f32,
}

impl AsRef<Stretch> for Stretch {
    fn as_ref(&self) -> &Stretch {
        self
    }
}

/// A dihedral constraint over the hinge (a, b) with wings c and d (triangles (a, b, c) and
/// (a, d, b)). Eq 12 writes it as C = acos(n1 . n2) - phi12; we measure the same angle signed,
/// phi = atan2((n1 x n2) . e, n1 . n2) with e the hinge direction (0 when flat, positive when
/// folded one way, negative the other). acos cannot tell a bump from a dent of the same size
/// and its gradient blows up near flat, which let free bodies (a cut-out tumour) turn inside
/// out; the signed angle has a bounded gradient there.
#[derive(Debug, Clone, Copy)]
pub struct Bend {
    pub a: u32,
    pub b: u32,
    pub c: u32,
    pub d: u32,
    pub rest_rad: f32,
}

/// The most a single bending projection turns a hinge, radians (10 rad/s at dt = 2 ms).
pub const MAX_BEND_CORRECTION_RAD: f32 = 0.02;

/// Projects one stretch constraint; returns the Lagrange multiplier increment. The force the
/// constraint exerts is lambda / dt^2, newtons.
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

/// The hinge's unnormalised triangle normals and its edge, or None when degenerate.
fn hinge(x: &[Vec3], c: &Bend) -> Option<(Vec3, Vec3, Vec3)> {
    let (a, b, pc, pd) = (
        x[c.a as usize],
        x[c.b as usize],
        x[c.c as usize],
        x[c.d as usize],
    );
    let e = b - a;
    let n1 = e.cross(pc - a);
    let n2 = (pd - a).cross(e);
    let tiny = 1e-14 * e.length_squared().max(f32::MIN_POSITIVE);
    if e.length_squared() <= 1e-20 || n1.length_squared() <= tiny || n2.length_squared() <= tiny {
        return None;
    }
    Some((n1, n2, e))
}

/// The signed dihedral angle of a hinge, radians in (-pi, pi]; 0 when flat.
pub fn dihedral(x: &[Vec3], c: &Bend) -> f32 {
    match hinge(x, c) {
        Some((n1, n2, e)) => signed_angle(n1, n2, e),
        None => 0.0,
    }
}

/// atan2 of sine and cosine, both scaled by |n1| |n2| |e| (atan2 needs only their ratio).
fn signed_angle(n1: Vec3, n2: Vec3, e: Vec3) -> f32 {
    n1.cross(n2).dot(e).atan2(n1.dot(n2) * e.length())
}

/// Projects one bending constraint; returns the Lagrange multiplier increment. The gradients
/// are those of the signed angle (Bridson et al.'s bending directions): bounded wherever the
/// two triangles are.
pub fn project_bend(
    x: &mut [Vec3],
    w: &[f32],
    c: &Bend,
    compliance: f32,
    dt_s: f32,
    lambda: f32,
) -> f32 {
    let Some((constraint, g)) = bend_gradient(x, c) else {
        return 0.0;
    };
    // Linearisation holds for small corrections only: a nearly rigid hinge asked to turn far
    // in one projection overshoots, and Gauss-Seidel sweeps can then feed the overshoot
    // back (a free piece pushed by a tip blew up this way). Turn at most this far per
    // projection; the rest follows over the next steps.
    let constraint = constraint.clamp(-MAX_BEND_CORRECTION_RAD, MAX_BEND_CORRECTION_RAD);
    let idx = [c.a, c.b, c.c, c.d].map(|i| i as usize);
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

/// A hinge's constraint value (the signed angle from rest, the shorter way round) and its
/// gradients for a, b, c, d (Bridson et al.'s bending directions), or None when degenerate.
pub fn bend_gradient(x: &[Vec3], c: &Bend) -> Option<(f32, [Vec3; 4])> {
    let (n1, n2, e) = hinge(x, c)?;
    let mut constraint = signed_angle(n1, n2, e) - c.rest_rad;
    let tau = std::f32::consts::TAU;
    if constraint > std::f32::consts::PI {
        constraint -= tau;
    } else if constraint < -std::f32::consts::PI {
        constraint += tau;
    }
    let len = e.length();
    let eh = e / len;
    let m1 = n1 / n1.length_squared();
    let m2 = n2 / n2.length_squared();
    let (a, b, pc, pd) = (
        x[c.a as usize],
        x[c.b as usize],
        x[c.c as usize],
        x[c.d as usize],
    );
    Some((
        constraint,
        [
            -((pc - b).dot(eh) * m1 + (pd - b).dot(eh) * m2),
            (pc - a).dot(eh) * m1 + (pd - a).dot(eh) * m2,
            -len * m1,
            -len * m2,
        ],
    ))
}

/// The elastic force a compliant stretch constraint exerts on its ends (a, b) where they are:
/// -C / alpha times its gradient, newtons. Zero for a rigid (alpha = 0) constraint.
pub fn stretch_force(x: &[Vec3], c: &Stretch, compliance_m_per_n: f32) -> [Vec3; 2] {
    let d = x[c.a as usize] - x[c.b as usize];
    let len = d.length();
    if compliance_m_per_n <= 0.0 || len <= f32::EPSILON {
        return [Vec3::ZERO; 2];
    }
    let f = d / len * (-(len - c.rest_m) / compliance_m_per_n);
    [f, -f]
}

/// The elastic forces a compliant hinge exerts on a, b, c, d where they are, newtons.
pub fn bend_force(x: &[Vec3], c: &Bend, compliance: f32) -> [Vec3; 4] {
    match bend_gradient(x, c) {
        Some((constraint, g)) if compliance > 0.0 => g.map(|g| g * (-constraint / compliance)),
        _ => [Vec3::ZERO; 4],
    }
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
        assert!((c.rest_rad.abs() - pi / 6.0).abs() < 1e-3, "{}", c.rest_rad);
        // Folded to 90 degrees the same way.
        let mut x = rest.clone();
        x[3] = Vec3::new(0.0, 0.005, 0.01);
        let folded = dihedral(&x, &c);
        assert!((folded.abs() - pi / 2.0).abs() < 1e-3);
        assert_eq!(folded.signum(), c.rest_rad.signum());
        let w = [0.0, 0.0, 1.0, 1.0];
        // 60 degrees back at most MAX_BEND_CORRECTION_RAD per projection.
        for _ in 0..100 {
            project_bend(&mut x, &w, &c, 0.0, 0.002, 0.0);
        }
        let err = (dihedral(&x, &c) - c.rest_rad).abs();
        assert!(err < 0.01, "{err}");
    }

    #[test]
    fn a_dent_is_not_mistaken_for_a_bump() {
        // The same 30-degree fold up and down: equal and opposite angles, and a hinge pushed
        // through flat is driven back to its own side.
        let mut x = vec![
            Vec3::ZERO,
            Vec3::new(0.0, 0.01, 0.0),
            Vec3::new(-0.01, 0.005, 0.0),
            Vec3::new(0.00866, 0.005, 0.005),
        ];
        let c = Bend {
            a: 0,
            b: 1,
            c: 2,
            d: 3,
            rest_rad: dihedral(
                &x,
                &Bend {
                    a: 0,
                    b: 1,
                    c: 2,
                    d: 3,
                    rest_rad: 0.0,
                },
            ),
        };
        let mut dent = x.clone();
        dent[3].z = -0.005;
        assert!((dihedral(&dent, &c) + c.rest_rad).abs() < 1e-4);
        let w = [0.0, 0.0, 0.0, 1.0];
        for _ in 0..80 {
            project_bend(&mut dent, &w, &c, 0.0, 0.002, 0.0);
        }
        assert!(dent[3].z > 0.004, "wing at z = {}", dent[3].z);
        x[3] = dent[3];
        assert!((dihedral(&x, &c) - c.rest_rad).abs() < 1e-3);
    }

    #[test]
    fn bend_gradient_matches_finite_differences() {
        let x0 = vec![
            Vec3::new(0.001, -0.002, 0.0005),
            Vec3::new(0.0003, 0.011, -0.001),
            Vec3::new(-0.009, 0.004, 0.002),
            Vec3::new(0.008, 0.006, -0.004),
        ];
        let mut c = Bend {
            a: 0,
            b: 1,
            c: 2,
            d: 3,
            rest_rad: 0.0,
        };
        // A small violation (inside the per-projection limit).
        c.rest_rad = dihedral(&x0, &c) - 0.01;
        // One projection with zero compliance and a single free point moves it by
        // -C grad / |grad|^2: compare with the angle's finite-difference gradient.
        for k in 0..4 {
            let mut w = [0.0; 4];
            w[k] = 1.0;
            let mut x = x0.clone();
            let violation = dihedral(&x0, &c) - c.rest_rad;
            project_bend(&mut x, &w, &c, 0.0, 0.002, 0.0);
            let step = x[k] - x0[k];
            let h = 1e-5f32;
            let mut num = Vec3::ZERO;
            for j in 0..3 {
                let mut p = x0.clone();
                p[k][j] += h;
                let f1 = dihedral(&p, &c);
                p[k][j] -= 2.0 * h;
                let f0 = dihedral(&p, &c);
                num[j] = (f1 - f0) / (2.0 * h);
            }
            let expect = num * (-violation / num.length_squared());
            assert!(
                (step - expect).length() < 0.02 * expect.length(),
                "{k}: {step} vs {expect}"
            );
        }
    }
}
