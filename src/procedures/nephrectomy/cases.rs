//! The nephrectomy's reference cases that need its scenario's kidney: the plain bean (a face
//! of known curvature) pressed by the calibration sphere on its posterior face, against
//! Hertz's law for an ellipsoid's face (`verify::hertz_cases`).

use super::{INFO, Scenario, bean_anatomy};
use crate::models::{SimplexMesh, SoftBody};
use crate::sim::{Case, Contact, ContactKind, Measured, ModelOutput, TissueModel, ToolId};
use crate::verify::hertz_cases::{HOLD_S, SPHERE_R_M, hertz_ellipsoid_n};
use crate::verify::softbody_cases::MODEL;
use glam::Vec3;

/// `vesalius verify`'s rows for the kidney.
pub fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "hertz_kidney_1mm",
            description: "3 mm sphere 1 mm into the posterior face of the nephrectomy's kidney \
                          bean (scenario size and step, 20480 points, without the swells) vs \
                          Hertz with the face's curvature (radii 151 and 45 mm): 0.048 N; \
                          tolerance 20%",
            unit: "N",
            tolerance: 0.2,
            run: || hertz_kidney(0.001),
        },
        Case {
            model: MODEL,
            case: "hertz_kidney_2mm",
            description: "the same at 2 mm (the issue's kidney check) vs Hertz with the \
                          face's curvature: 0.136 N; tolerance 25%",
            unit: "N",
            tolerance: 0.25,
            run: || hertz_kidney(0.002),
        },
        Case {
            model: MODEL,
            case: "hertz_kidney_3mm",
            description: "the same at 3 mm vs Hertz with the face's curvature: 0.250 N; \
                          tolerance 25%",
            unit: "N",
            tolerance: 0.25,
            run: || hertz_kidney(0.003),
        },
    ]
}

/// The force on a 3 mm sphere held `depth_m` into the posterior pole of the kidney (its
/// scenario's mesh, parameters and step) for 0.4 s, N, and the Hertz reference.
fn hertz_kidney(depth_m: f64) -> Measured {
    let nan = Measured {
        reference: f64::NAN,
        measured: f64::NAN,
        simulated_s: 0.0,
        floor: 0.0,
    };
    let Ok(scenario) = Scenario::parse("builtin nephrectomy scenario", INFO.scenario) else {
        return nan;
    };
    // The scenario's bean without the shipped kidney's swells: a face of known curvature.
    let (organ, regions, _, _) = bean_anatomy(&scenario);
    let Ok(mesh) = SimplexMesh::dual(&organ) else {
        return nan;
    };
    let mut kidney = SoftBody::new("kidney", mesh, regions, scenario.kidney);
    let an = &scenario.anatomy;
    let (a, b, c) = (
        an.kidney_half_width_m,
        an.kidney_half_length_m,
        an.kidney_half_thickness_m,
    );
    let r = SPHERE_R_M as f32;
    let n = -Vec3::Z;
    let tip = [Contact {
        tool: ToolId::Right,
        point: n * (c + r - depth_m as f32),
        normal: n,
        kind: ContactKind::Sphere { radius_m: r },
    }];
    let dt = scenario.dt_s;
    let steps = (HOLD_S / dt).round() as usize;
    let mut out = ModelOutput::default();
    let mut force = Vec3::ZERO;
    for _ in 0..steps {
        out.clear();
        kidney.step(dt, &tip, &mut out);
        force = out.reactions.iter().map(|(_, f)| *f).sum();
    }
    Measured {
        reference: hertz_ellipsoid_n(depth_m, a as f64, b as f64, c as f64),
        measured: force.dot(n) as f64,
        simulated_s: (steps as f32 * dt) as f64,
        floor: 0.0,
    }
}
