//! Cases for the XPBD projections (`crate::models::xpbd`, paper eqs 11-12).

use super::{Case, Measured};
use crate::models::xpbd::{self, Bend, Stretch};
use glam::Vec3;

const MODEL: &str = "xpbd";

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "stretch_compliant_pinned",
            description: "strain left after 10 projections of one edge (rest 10 mm, 100 % \
                          strain, one end pinned, alpha = 1e-4 m/N, dt = 2 ms) vs the XPBD \
                          lambda update in closed form: C = C0 at / (w + at), at = alpha / dt^2 \
                          = 25 (exact from the first projection on, whatever N); tolerance 1e-5 \
                          for f32 lengths of 20 mm",
            unit: "",
            tolerance: 1e-5,
            run: stretch_compliant_pinned,
        },
        Case {
            model: MODEL,
            case: "stretch_compliant_free",
            description: "strain left after 10 projections of one edge with both ends free \
                          (w = 2, alpha = 1e-5 m/N, dt = 2 ms, at = 2.5) vs C0 at / (w + at) \
                          (XPBD lambda update); tolerance 1e-5 for f32 lengths",
            unit: "",
            tolerance: 1e-5,
            run: stretch_compliant_free,
        },
        Case {
            model: MODEL,
            case: "stretch_load_1_substep",
            description: "edge (alpha = 1e-5 m/N) holding a 100 N load on a unit mass, 1 substep \
                          of 2 ms, 2 s, vs Hooke's static stretch F alpha = 1 mm; tolerance \
                          1e-4: each f32 rounding of a position near 11 mm (ulp 9e-10 m) is \
                          scaled by alpha / h^2 at the fixed point: 1e-6 per rounding here, 2e-5 \
                          at 4 substeps, a few roundings a substep",
            unit: "m",
            tolerance: 1e-4,
            run: stretch_load_1_substep,
        },
        Case {
            model: MODEL,
            case: "stretch_load_4_substeps",
            description: "the same load with 4 substeps of 0.5 ms per 2 ms step, 5 s, vs F \
                          alpha = 1 mm: compliance makes the stiffness independent of the \
                          substep; tolerance as for 1 substep",
            unit: "m",
            tolerance: 1e-4,
            run: stretch_load_4_substeps,
        },
        Case {
            model: MODEL,
            case: "bend_rest_dihedral",
            description: "hinge with a 30 deg rest fold, folded to 90 deg and given 100 rigid \
                          projections (eq 12, at most 0.02 rad each), fold measured from the wing \
                          geometry vs the rest fold atan2(5, 8.66); tolerance 1e-4: f32 \
                          positions of 10 mm wings (angle resolution ~1e-5 rad)",
            unit: "rad",
            tolerance: 1e-4,
            run: bend_rest_dihedral,
        },
    ]
}

const DT_S: f32 = 0.002;

/// Projects one edge `iterations` times with XPBD, lambda from zero; returns the strain.
fn project_edge(w: [f32; 2], compliance_m_per_n: f32, iterations: usize) -> f32 {
    let c = Stretch {
        a: 0,
        b: 1,
        rest_m: 0.01,
    };
    let mut x = vec![Vec3::ZERO, Vec3::new(0.02, 0.0, 0.0)];
    let mut lambda = 0.0;
    for _ in 0..iterations {
        lambda += xpbd::project_stretch(&mut x, &w, &c, compliance_m_per_n, DT_S, lambda);
    }
    ((x[1] - x[0]).length() - c.rest_m) / c.rest_m
}

/// XPBD for a single linear constraint: dl = -(C + at lambda) / (w + at) moves C by w dl,
/// so C + at lambda is zero after the first projection and every later dl is zero. What
/// is left is C0 at / (w + at): one implicit Euler step of a spring of stiffness 1 / alpha.
fn xpbd_strain(initial_strain: f64, w: f64, compliance_m_per_n: f64) -> f64 {
    let at = compliance_m_per_n / (DT_S as f64 * DT_S as f64);
    initial_strain * at / (w + at)
}

fn stretch_compliant_pinned() -> Measured {
    let strain = project_edge([1.0, 0.0], 1e-4, 10);
    Measured::at_rest(xpbd_strain(1.0, 1.0, 1e-4), strain as f64)
}

fn stretch_compliant_free() -> Measured {
    let strain = project_edge([1.0, 1.0], 1e-5, 10);
    Measured::at_rest(xpbd_strain(1.0, 2.0, 1e-5), strain as f64)
}

const LOAD_N: f32 = 100.0;
const LOAD_COMPLIANCE_M_PER_N: f32 = 1e-5;

/// A unit mass hanging from a pinned point by one compliant edge, pulled by a constant load,
/// stepped with XPBD (predict with the load, project, velocity from the positions). Without
/// damping the implicit step still dissipates (|amplification| = 1 / sqrt(1 + h^2 / alpha)),
/// so after `duration_s` the oscillation has died below f32 resolution. Returns the stretch
/// and the simulated time.
fn hang(substeps: u32, duration_s: f32) -> (f64, f64) {
    let c = Stretch {
        a: 0,
        b: 1,
        rest_m: 0.01,
    };
    let w = [0.0, 1.0];
    let h = DT_S / substeps as f32;
    let mut x = vec![Vec3::ZERO, Vec3::new(c.rest_m, 0.0, 0.0)];
    let mut v = Vec3::ZERO;
    let steps = (duration_s / DT_S).round() as u32;
    for _ in 0..steps {
        for _ in 0..substeps {
            let before = x[1];
            x[1] += v * h + Vec3::X * (LOAD_N * w[1] * h * h);
            let mut lambda = 0.0;
            for _ in 0..4 {
                lambda += xpbd::project_stretch(&mut x, &w, &c, LOAD_COMPLIANCE_M_PER_N, h, lambda);
            }
            v = (x[1] - before) / h;
        }
    }
    let stretch_m = ((x[1] - x[0]).length() - c.rest_m) as f64;
    (stretch_m, steps as f64 * DT_S as f64)
}

fn stretch_load(substeps: u32, duration_s: f32) -> Measured {
    let (stretch_m, simulated_s) = hang(substeps, duration_s);
    Measured {
        // Hooke: the static stretch of a spring of stiffness 1 / alpha under F.
        reference: LOAD_N as f64 * LOAD_COMPLIANCE_M_PER_N as f64,
        measured: stretch_m,
        simulated_s,
        floor: 0.0,
    }
}

fn stretch_load_1_substep() -> Measured {
    // Decay per step 1 / sqrt(1 + h^2 / alpha) = 1 / sqrt(1.4): 1000 steps, e^-168.
    stretch_load(1, 2.0)
}

fn stretch_load_4_substeps() -> Measured {
    // Decay per substep 1 / sqrt(1.025): 10000 substeps, e^-123.
    stretch_load(4, 5.0)
}

/// The fold of hinge (a, b) with wings c and d, from the geometry alone: the angle, about
/// the hinge, from the extension of wing c to wing d (0 when flat).
fn fold_rad(x: &[Vec3]) -> f64 {
    let p = x.iter().map(|v| v.as_dvec3()).collect::<Vec<_>>();
    let e = (p[1] - p[0]).normalize();
    let across = |q: glam::DVec3| {
        let r = q - p[0];
        r - e * r.dot(e)
    };
    let u = -across(p[2]).normalize();
    let pd = across(p[3]);
    e.dot(pd.cross(u)).atan2(pd.dot(u))
}

fn bend_rest_dihedral() -> Measured {
    // Hinge along +y, wing c flat along -x, wing d raised 30 degrees above +x.
    let rest = [
        Vec3::ZERO,
        Vec3::new(0.0, 0.01, 0.0),
        Vec3::new(-0.01, 0.005, 0.0),
        Vec3::new(0.00866, 0.005, 0.005),
    ];
    let mut c = Bend {
        a: 0,
        b: 1,
        c: 2,
        d: 3,
        rest_rad: 0.0,
    };
    c.rest_rad = xpbd::dihedral(&rest, &c);
    // Folded to 90 degrees the same way, hinge pinned, wings free.
    let mut x = rest.to_vec();
    x[3] = Vec3::new(0.0, 0.005, 0.01);
    let w = [0.0, 0.0, 1.0, 1.0];
    for _ in 0..100 {
        xpbd::project_bend(&mut x, &w, &c, 0.0, DT_S, 0.0);
    }
    Measured::at_rest(0.005f64.atan2(0.00866), fold_rad(&x))
}
