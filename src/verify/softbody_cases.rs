//! Cases for the force-based simplex soft body (`crate::models::SoftBody`, paper eqs 1-8 with
//! the XPBD constraints of eqs 11-12).
//!
//! Every case uses the dual of `icosphere(2)` scaled to a 3 cm ball (320 points), anchored.
//! Its update, per awake point of unit mass (eq 7), is semi-implicit Euler with the damping
//! of eq 5: v' = (v + F dt)(1 - d dt), x' = x + v' dt (eq 8), then the constraints are
//! projected and v is taken again from the positions.
//!
//! The release cases isolate the spring: the whole ball is moved rigidly, so no stretch or
//! bend constraint is violated and the enclosed volume does not change (the icosphere's
//! symmetry makes the sum of its area vectors vanish). Each point then follows
//! u' = u + h v', v' = a (v - k h u), a = 1 - d h, on its own: a linear recurrence whose
//! closed form (from the eigenvalues of its 2x2 matrix) is the reference.

use super::{Case, Measured};
use crate::mesh::icosphere;
use crate::models::{SimplexMesh, SoftBody, SoftBodyParams};
use crate::sim::{ModelOutput, TissueModel};
use glam::Vec3;

pub(super) const MODEL: &str = "simplex soft body";
const RADIUS_M: f32 = 0.03;
pub(super) const DT_S: f32 = 0.002;

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "release_damped",
            description: "ball moved 5 mm and released (k = 40 N/m, d = 8 /s): worst point's \
                          displacement after 0.25 s vs the closed form of the eq 5/7/8 update; \
                          tolerance 1e-3: f32 positions round by ~1e-9 m a step, and the \
                          oscillation turns each into a velocity error and amplifies it \
                          1 / (w dt) = 80 times: ~1e-6 m over 125 steps",
            unit: "m",
            tolerance: 1e-3,
            run: release_damped,
        },
        Case {
            model: MODEL,
            case: "release_undamped_frequency",
            description: "ball moved 5 mm and released undamped: angular frequency from the \
                          mean motion's zero crossings over 3 s vs Hooke sqrt(k / m), m = 1 kg (eq 7); \
                          tolerance 3e-5: the update's dispersion k dt^2 / 24 = 7e-6, and f32",
            unit: "rad/s",
            tolerance: 3e-5,
            run: release_undamped_frequency,
        },
        Case {
            model: MODEL,
            case: "release_undamped_energy",
            description: "energy per point (mean motion) after 3 s undamped, \
                          (v^2 + k u^2 - k dt u v) / 2 (exactly \
                          conserved by semi-implicit Euler), vs the initial k u0^2 / 2; \
                          tolerance 2e-4: v from f32 position differences (2e-9 m / 2 ms = \
                          1e-6 of 0.03 m/s), with rounding amplified 1 / (w dt) = 80 times",
            unit: "J",
            tolerance: 2e-4,
            run: release_undamped_energy,
        },
    ]
}

/// Cases where the model follows its paper but not physics.
pub(super) fn known_failures() -> Vec<Case> {
    vec![Case {
        model: MODEL,
        case: "point_mass_tissue_density",
        description: "mass per point from the undamped frequency, k / w^2, vs tissue: \
                      1050 kg/m^3 * (4/3 pi r^3) / 320 points; eq 7 takes m = 1 kg per point",
        unit: "kg",
        tolerance: 0.05,
        run: point_mass_tissue_density,
    }]
}

/// The 3 cm ball, every point anchored (region 0).
pub(super) fn ball(params: SoftBodyParams) -> Option<SoftBody> {
    let mut m = icosphere(2);
    for p in &mut m.positions {
        *p *= RADIUS_M;
    }
    let s = SimplexMesh::dual(&m).ok()?;
    let n = s.len();
    Some(SoftBody::new("verify", s, vec![0; n], params))
}

/// Direction the ball is moved in: (2, -1, 2) / 3, along no symmetry axis.
fn release_dir() -> Vec3 {
    Vec3::new(2.0, -1.0, 2.0) / 3.0
}

const RELEASE_M: f32 = 0.005;

/// Every point's displacement from rest along the release direction, after each step (index
/// 0 is the moved ball before the first step).
fn release(params: SoftBodyParams, steps: usize) -> Option<Vec<Vec<f64>>> {
    let mut b = ball(params)?;
    let dir = release_dir();
    for i in 0..b.positions().len() {
        let p = b.positions()[i] + dir * RELEASE_M;
        b.set_position(i, p);
    }
    let along = |b: &SoftBody| -> Vec<f64> {
        b.positions()
            .iter()
            .zip(&b.mesh().rest)
            .map(|(x, r)| (*x - *r).dot(dir) as f64)
            .collect()
    };
    let mut out = ModelOutput::default();
    let mut series = vec![along(&b)];
    for _ in 0..steps {
        out.clear();
        b.step(DT_S, &[], &mut out);
        series.push(along(&b));
    }
    Some(series)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// Displacement after `n` steps of u' = u + h v', v' = a (v - k h u) from (u0, 0), in closed
/// form: u_n = r^n (u0 cos n theta + B sin n theta) with r^2 = det = a and
/// 2 r cos theta = trace = 1 + a - a k h^2. NaN outside the oscillating regime (not used).
fn recurrence_displacement(k: f64, d: f64, h: f64, u0: f64, n: i32) -> f64 {
    let a = 1.0 - d * h;
    let trace = 1.0 + a - a * k * h * h;
    if a <= 0.0 || trace * trace >= 4.0 * a {
        return f64::NAN;
    }
    let r = a.sqrt();
    let theta = (trace / (2.0 * r)).acos();
    let u1 = (1.0 - a * k * h * h) * u0;
    let b = (u1 / r - u0 * theta.cos()) / theta.sin();
    let nt = n as f64 * theta;
    r.powi(n) * (u0 * nt.cos() + b * nt.sin())
}

fn release_damped() -> Measured {
    let p = SoftBodyParams::default();
    let steps = 125;
    let reference = recurrence_displacement(
        p.spring_n_per_m as f64,
        p.damping_per_s as f64,
        DT_S as f64,
        RELEASE_M as f64,
        steps as i32,
    );
    let simulated_s = steps as f64 * DT_S as f64;
    let Some(series) = release(p, steps) else {
        return Measured::not_run(reference);
    };
    // The point farthest from the reference, so no point may stray.
    let last = series.last().map_or(&[][..], |v| &v[..]);
    let worst = last
        .iter()
        .copied()
        .max_by(|x, y| (x - reference).abs().total_cmp(&(y - reference).abs()))
        .unwrap_or(f64::NAN);
    Measured {
        reference,
        measured: worst,
        simulated_s,
        floor: 0.0,
    }
}

fn undamped() -> SoftBodyParams {
    SoftBodyParams {
        damping_per_s: 0.0,
        ..SoftBodyParams::default()
    }
}

const UNDAMPED_STEPS: usize = 1500;

/// Angular frequency of the mean displacement, from its first and last zero crossings
/// (interpolated linearly between steps).
fn frequency_rad_per_s(mean_u: &[f64]) -> f64 {
    let crossings: Vec<f64> = mean_u
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[0] != 0.0 && w[0].signum() != w[1].signum())
        .map(|(n, w)| (n as f64 + w[0] / (w[0] - w[1])) * DT_S as f64)
        .collect();
    match (crossings.first(), crossings.last()) {
        (Some(t0), Some(t1)) if crossings.len() >= 2 => {
            std::f64::consts::PI * (crossings.len() - 1) as f64 / (t1 - t0)
        }
        _ => f64::NAN,
    }
}

fn undamped_means() -> Option<Vec<f64>> {
    let series = release(undamped(), UNDAMPED_STEPS)?;
    Some(series.iter().map(|u| mean(u)).collect())
}

fn release_undamped_frequency() -> Measured {
    let k = undamped().spring_n_per_m as f64;
    // A unit mass (eq 7) on a spring k: w = sqrt(k / m).
    let reference = (k / 1.0).sqrt();
    let measured = undamped_means().map_or(f64::NAN, |u| frequency_rad_per_s(&u));
    Measured {
        reference,
        measured,
        simulated_s: UNDAMPED_STEPS as f64 * DT_S as f64,
        floor: 0.0,
    }
}

fn release_undamped_energy() -> Measured {
    let k = undamped().spring_n_per_m as f64;
    let h = DT_S as f64;
    let u0 = RELEASE_M as f64;
    let reference = 0.5 * k * u0 * u0;
    let measured = undamped_means().map_or(f64::NAN, |u| {
        let n = u.len() - 1;
        // The model's own velocity: it is taken from the positions every step.
        let v = (u[n] - u[n - 1]) / h;
        0.5 * (v * v + k * u[n] * u[n] - k * h * u[n] * v)
    });
    Measured {
        reference,
        measured,
        simulated_s: UNDAMPED_STEPS as f64 * h,
        floor: 0.0,
    }
}

fn point_mass_tissue_density() -> Measured {
    // Kidney and most soft tissue: about 1050 kg/m^3 (ICRP 89 reference values).
    let density_kg_per_m3 = 1050.0;
    let r = RADIUS_M as f64;
    // One simplex point per face of the icosphere.
    let points = icosphere(2).triangle_count() as f64;
    let reference = density_kg_per_m3 * 4.0 / 3.0 * std::f64::consts::PI * r.powi(3) / points;
    let k = undamped().spring_n_per_m as f64;
    let measured = undamped_means().map_or(f64::NAN, |u| k / frequency_rad_per_s(&u).powi(2));
    Measured {
        reference,
        measured,
        simulated_s: UNDAMPED_STEPS as f64 * DT_S as f64,
        floor: 0.0,
    }
}
