//! Calibration of the soft body against Hertz's contact law: a rigid sphere of radius R
//! pressed d into an elastic half-space of Young's modulus E and Poisson ratio nu takes
//! F = 4/3 E* sqrt(R) d^1.5, E* = E / (1 - nu^2) (Johnson, Contact Mechanics, 1985, eq 4.22).
//! Kidney cortex: E about 16 kPa (the figure; soft-tissue indentation studies give
//! 10-20 kPa), nu = 0.5 (nearly incompressible). The block is the sandbox's at its scenario
//! size; a 3 mm tip is held d into the middle of its top for 0.4 s.
//!
//! The same setup checks what physics asks whatever the model: the force at a given depth
//! does not change with the mesh's resolution or with dt. And the nephrectomy's own kidney, at
//! its scenario's size and step, is pressed by the same sphere on its posterior face.

use super::softbody_cases::MODEL;
use super::{Case, Measured};
use crate::mesh::block::{BlockShape, block, divisions};
use crate::models::{SimplexMesh, SoftBody, SoftBodyParams};
use crate::sim::{Contact, ContactKind, ModelOutput, TissueModel, ToolId};
use glam::Vec3;

/// Young's modulus of kidney cortex the foundation is calibrated to, Pa.
pub const CORTEX_E_PA: f64 = 16e3;
/// Poisson ratio (nearly incompressible tissue).
pub const CORTEX_NU: f64 = 0.5;
/// The calibration sphere's radius, m.
pub const SPHERE_R_M: f64 = 0.003;
const DT_S: f32 = 0.002;
/// How long the sphere is held at its depth before the force is read, s.
pub const HOLD_S: f32 = 0.4;

/// Hertz's force for the calibration sphere pressed `depth_m` into cortex, N.
pub fn hertz_force_n(depth_m: f64) -> f64 {
    let e_star = CORTEX_E_PA / (1.0 - CORTEX_NU * CORTEX_NU);
    4.0 / 3.0 * e_star * SPHERE_R_M.sqrt() * depth_m.powf(1.5)
}

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "hertz_block_1mm",
            description: "3 mm sphere 1 mm into the sandbox block (6 x 3 x 4 cm, 2.5 mm \
                          cells): force vs Hertz, E = 16 kPa, nu = 0.5: 0.049 N; tolerance 20%",
            unit: "N",
            tolerance: 0.2,
            run: || hertz_block(0.001),
        },
        Case {
            model: MODEL,
            case: "hertz_block_2mm",
            description: "the same at 2 mm vs Hertz 0.139 N; tolerance 20%",
            unit: "N",
            tolerance: 0.2,
            run: || hertz_block(0.002),
        },
        Case {
            model: MODEL,
            case: "hertz_block_3mm",
            description: "the same at 3 mm vs Hertz 0.256 N; tolerance 20%",
            unit: "N",
            tolerance: 0.2,
            run: || hertz_block(0.003),
        },
        Case {
            model: MODEL,
            case: "block_force_resolution",
            description: "force at 2 mm with 2.5 mm cells (reference) and 1.25 mm cells \
                          (measured, 4x the points); tolerance 5%",
            unit: "N",
            tolerance: 0.05,
            run: block_force_resolution,
        },
        Case {
            model: MODEL,
            case: "block_force_dt",
            description: "equilibrium force at 2 mm with dt = 2 ms (reference) and 1 ms \
                          (measured); tolerance 5%",
            unit: "N",
            tolerance: 0.05,
            run: block_force_dt,
        },
    ]
}

/// The sandbox block with `cells` along its longest edge, its default parameters.
pub fn sandbox_block(cells: u32, params: SoftBodyParams) -> Option<(SoftBody, BlockShape)> {
    let shape = BlockShape {
        size_m: Vec3::new(0.06, 0.03, 0.04),
    };
    let (mesh, regions) = block(&shape, divisions(shape.size_m, cells));
    let s = SimplexMesh::dual(&mesh).ok()?;
    Some((SoftBody::new("block", s, regions, params), shape))
}

/// The force on a 3 mm sphere held `depth_m` into the middle of the block's top for 0.4 s,
/// N (the reaction's upward component), with `cells` and `dt_s`.
pub fn block_indentation_n(depth_m: f32, cells: u32, dt_s: f32) -> f64 {
    let Some((mut b, shape)) = sandbox_block(cells, SoftBodyParams::default()) else {
        return f64::NAN;
    };
    let r = SPHERE_R_M as f32;
    let tip = [Contact {
        tool: ToolId::Right,
        point: Vec3::new(0.0, shape.top_y() + r - depth_m, 0.0),
        normal: Vec3::Y,
        kind: ContactKind::Sphere { radius_m: r },
    }];
    let steps = (HOLD_S / dt_s).round() as usize;
    let mut out = ModelOutput::default();
    let mut force = Vec3::ZERO;
    for _ in 0..steps {
        out.clear();
        b.step(dt_s, &tip, &mut out);
        force = out.reactions.iter().map(|(_, f)| *f).sum();
    }
    force.y as f64
}

fn hertz_block(depth_m: f64) -> Measured {
    Measured {
        reference: hertz_force_n(depth_m),
        measured: block_indentation_n(depth_m as f32, 24, DT_S),
        simulated_s: HOLD_S as f64,
        floor: 0.0,
    }
}

fn block_force_resolution() -> Measured {
    Measured {
        reference: block_indentation_n(0.002, 24, DT_S),
        measured: block_indentation_n(0.002, 48, DT_S),
        simulated_s: 2.0 * HOLD_S as f64,
        floor: 0.0,
    }
}

fn block_force_dt() -> Measured {
    Measured {
        reference: block_indentation_n(0.002, 24, DT_S),
        measured: block_indentation_n(0.002, 24, 0.5 * DT_S),
        simulated_s: 2.0 * HOLD_S as f64,
        floor: 0.0,
    }
}

/// Hertz's force for the calibration sphere pressed `depth_m` into an ellipsoid at the end of
/// its semi-axis `c`, whose other semi-axes are `a` and `b`: the contact's principal relative
/// radii are 1 / (1/R + c/a^2) and 1 / (1/R + c/b^2), and for a nearly circular contact their
/// geometric mean stands for R (Johnson, Contact Mechanics, section 4.2).
pub fn hertz_ellipsoid_n(depth_m: f64, a: f64, b: f64, c: f64) -> f64 {
    let rel = |axis: f64| 1.0 / (1.0 / SPHERE_R_M + c / (axis * axis));
    let r_e = (rel(a) * rel(b)).sqrt();
    hertz_force_n(depth_m) * (r_e / SPHERE_R_M).sqrt()
}
