//! Cases for the simplex soft body's mass and implicit step (`crate::models::SoftBody`).
//!
//! The release case moves a whole anchored ball rigidly and lets go. A rigid shift stretches
//! no shear-layer link, violates no stretch or bend constraint and keeps the enclosed volume,
//! and every point's foundation stiffness over its mass is the same, k_w / sigma (both go with
//! the point's area). So every point follows the backward-Euler spring-damper recurrence
//! v' = (v - h w^2 u) / (1 + c h + w^2 h^2), u' = u + h v' on its own; the reference iterates
//! that recurrence in f64.

use super::{Case, Measured};
use crate::mesh::icosphere;
use crate::models::{SimplexMesh, SoftBody, SoftBodyParams};
use crate::sim::{ModelOutput, TissueModel};
use glam::Vec3;

/// The model these cases (and the procedures' soft-body cases) are listed under.
pub const MODEL: &str = "simplex soft body";
const RADIUS_M: f32 = 0.03;
pub(super) const DT_S: f32 = 0.002;

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "mass_from_density",
            description: "total mass of a 3 cm ball (icosphere level 4, 5120 points) vs \
                          1050 kg/m^3 x 4/3 pi r^3 = 0.1188 kg; tolerance 1%: the faceted \
                          ball encloses 0.5% less than the sphere",
            unit: "kg",
            tolerance: 0.01,
            run: mass_from_density,
        },
        Case {
            model: MODEL,
            case: "release_backward_euler",
            description: "ball moved 5 mm and released: mean displacement after 0.1 s vs the \
                          backward-Euler spring-damper recurrence with w^2 = k_w / sigma, \
                          sigma = density x volume / area (f64); tolerance 1e-3 (f32 state, \
                          CG tolerance 1e-6)",
            unit: "m",
            tolerance: 1e-3,
            run: release_backward_euler,
        },
    ]
}

/// Cases where the model follows its paper but not physics: none left for the mass and
/// the step (kept for the shape of the registry).
pub(super) fn known_failures() -> Vec<Case> {
    Vec::new()
}

/// A ball of `RADIUS_M` from icosphere `level`, every point anchored (region 0).
pub(super) fn ball_of(level: u32, params: SoftBodyParams) -> Option<SoftBody> {
    let mut m = icosphere(level);
    for p in &mut m.positions {
        *p *= RADIUS_M;
    }
    let s = SimplexMesh::dual(&m).ok()?;
    let n = s.len();
    Some(SoftBody::new("verify", s, vec![0; n], params))
}

/// The 3 cm ball at level 2 (320 points).
pub(super) fn ball(params: SoftBodyParams) -> Option<SoftBody> {
    ball_of(2, params)
}

fn mass_from_density() -> Measured {
    let p = SoftBodyParams::default();
    let r = RADIUS_M as f64;
    let reference = p.density_kg_per_m3 as f64 * 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
    let measured = ball_of(4, p).map_or(f64::NAN, |b| b.total_mass_kg());
    Measured::at_rest(reference, measured)
}

const RELEASE_M: f32 = 0.005;
const RELEASE_STEPS: usize = 50;

fn release_backward_euler() -> Measured {
    let p = SoftBodyParams::default();
    let Some(mut b) = ball(p) else {
        return Measured::not_run(f64::NAN);
    };
    let dir = Vec3::new(2.0, -1.0, 2.0) / 3.0;
    for i in 0..b.positions().len() {
        let q = b.positions()[i] + dir * RELEASE_M;
        b.set_position(i, q);
    }
    // sigma from the body's own masses and areas, w^2 = k_w / sigma.
    let mass: f64 = b.masses().iter().map(|&m| m as f64).sum();
    let area: f64 = b.rest_areas().iter().map(|&a| a as f64).sum();
    let w2 = p.foundation_pa_per_m as f64 * area / mass;
    let (c, h) = (p.damping_per_s as f64, DT_S as f64);
    let (mut u, mut v) = (RELEASE_M as f64, 0.0f64);
    let mut out = ModelOutput::default();
    for _ in 0..RELEASE_STEPS {
        out.clear();
        b.step(DT_S, &[], &mut out);
        v = (v - h * w2 * u) / (1.0 + c * h + w2 * h * h);
        u += h * v;
    }
    let n = b.positions().len() as f64;
    let measured = b
        .positions()
        .iter()
        .zip(&b.mesh().rest)
        .map(|(x, r)| (*x - *r).dot(dir) as f64)
        .sum::<f64>()
        / n;
    Measured {
        reference: u,
        measured,
        simulated_s: RELEASE_STEPS as f64 * h,
        // The displacement decays toward zero: errors are taken relative to the release.
        floor: RELEASE_M as f64,
    }
}
