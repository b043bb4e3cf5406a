//! Cases for what tools and ties do to the simplex soft body: ties tearing at their strength,
//! a tip's reaction against the load the whole body bears, and a press whose total does not
//! depend on the mesh.

use super::softbody_cases::{DT_S, MODEL, ball, ball_of};
use super::{Case, Measured};
use crate::mesh::icosphere;
use crate::models::{SimplexMesh, SoftBody, SoftBodyParams, Tie};
use crate::sim::{Contact, ContactKind, EventKind, ModelOutput, TissueModel, ToolId};
use glam::{DVec3, Vec3};

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "tie_break_displacement",
            description: "relative displacement at which a tie tears (bisection) vs its \
                          strength over its stiffness, 1e4 Pa / 5e6 N/m^3 = 2 mm (per unit \
                          area, so the same at any resolution)",
            unit: "m",
            tolerance: 1e-4,
            run: tie_break_displacement,
        },
        Case {
            model: MODEL,
            case: "tip_reaction_balance",
            description: "3 mm tip held 2 mm into a 3 cm ball for 0.4 s: reported reaction vs \
                          the load the whole body bears (foundation springs and gas pressure \
                          summed over every point; Newton 3 and statics); tolerance 1%",
            unit: "N",
            tolerance: 0.01,
            run: tip_reaction_balance,
        },
        Case {
            model: MODEL,
            case: "press_total_balance",
            description: "press of 1500 Pa on 1 cm^2 held 0.4 s, no gas pressure: reported \
                          reaction vs the load the whole body bears; tolerance 1%",
            unit: "N",
            tolerance: 0.01,
            run: press_total_balance,
        },
        Case {
            model: MODEL,
            case: "press_total_resolution",
            description: "total force of that press on a ball of 1280 points (reference) and \
                          of 5120 points (measured): shared by area, the total does not grow \
                          with resolution; tolerance 5%",
            unit: "N",
            tolerance: 0.05,
            run: press_total_resolution,
        },
    ]
}

/// Cases where the model disagrees with physics: none left here.
pub(super) fn known_failures() -> Vec<Case> {
    Vec::new()
}

/// Two 1 cm balls 3 cm apart joined by one tie between their facing points; the second ball
/// is moved rigidly by `stretch_m` along the tie and one step is taken. Whether the tie
/// survived, or None if the meshes failed to build.
fn tie_survives(stretch_m: f32) -> Option<bool> {
    let mut m = icosphere(1);
    for p in &mut m.positions {
        *p *= 0.01;
    }
    let n0 = m.triangle_count();
    let mut other = m.clone();
    for p in &mut other.positions {
        *p += Vec3::new(0.03, 0.0, 0.0);
    }
    m.append(&other);
    let mut regions = vec![0u8; n0];
    regions.resize(m.triangle_count(), 1);
    let s = SimplexMesh::dual(&m).ok()?;
    let mut b = SoftBody::new("verify", s, regions, SoftBodyParams::default());
    let x = b.positions();
    let a = (0..n0).max_by(|&i, &j| x[i].x.total_cmp(&x[j].x))?;
    let c = (n0..x.len()).min_by(|&i, &j| x[i].x.total_cmp(&x[j].x))?;
    let rest_m = (x[c] - x[a]).length();
    let along = (x[c] - x[a]) / rest_m;
    b.set_ties(vec![Tie {
        a: a as u32,
        b: c as u32,
        rest_m,
        alive: true,
    }]);
    for i in n0..b.positions().len() {
        let p = b.positions()[i] + along * stretch_m;
        b.set_position(i, p);
    }
    let mut out = ModelOutput::default();
    b.step(DT_S, &[], &mut out);
    let broke = out
        .events
        .iter()
        .any(|e| matches!(e, EventKind::TieBroken { .. }));
    let alive = b.ties().first().is_some_and(|t| t.alive);
    (broke != alive).then_some(alive)
}

fn tie_break_displacement() -> Measured {
    let p = SoftBodyParams::default();
    let reference = p.tie_strength_pa as f64 / p.tie_stiffness_pa_per_m as f64;
    // Bisect on the stretch: below `lo` the tie holds, at `hi` it tears.
    let (mut lo, mut hi) = (0.0f64, 2.0 * reference);
    if tie_survives(hi as f32) != Some(false) || tie_survives(lo as f32) != Some(true) {
        return Measured::not_run(reference);
    }
    const HALVINGS: u32 = 30;
    for _ in 0..HALVINGS {
        let mid = 0.5 * (lo + hi);
        match tie_survives(mid as f32) {
            Some(true) => lo = mid,
            Some(false) => hi = mid,
            None => return Measured::not_run(reference),
        }
    }
    Measured {
        reference,
        measured: 0.5 * (lo + hi),
        simulated_s: (2 + HALVINGS) as f64 * DT_S as f64,
        floor: 0.0,
    }
}

const TIP_RADIUS_M: f32 = 0.003;
/// Steps a tool is held for the equilibrium cases: 0.4 s.
const HOLD_STEPS: usize = 1000;

/// Steps `b` with `contacts` for `steps` steps; the summed reaction of the last step.
fn hold(b: &mut SoftBody, contacts: &[Contact], steps: usize) -> Vec3 {
    let mut out = ModelOutput::default();
    let mut reaction = Vec3::ZERO;
    for _ in 0..steps {
        out.clear();
        b.step(DT_S, contacts, &mut out);
        reaction = out.reactions.iter().map(|(_, f)| *f).sum();
    }
    reaction
}

/// The load the body bears where it is: the foundation's pull and the gas pressure summed
/// over every point (shear-layer links, ties and constraints are internal and cancel),
/// computed here from the positions alone.
pub fn body_load_n(b: &SoftBody) -> DVec3 {
    let p = b.params;
    let (mesh, x, alive) = (b.mesh(), b.positions(), b.alive());
    let mut spring = DVec3::ZERO;
    let (mut volume, mut rest_volume) = (0.0, 0.0);
    let mut area_vector = DVec3::ZERO;
    for i in 0..x.len() {
        let k = p.foundation_pa_per_m as f64 * b.rest_areas()[i] as f64;
        spring += (mesh.rest[i] - x[i]).as_dvec3() * k;
        let (n, a) = mesh.normal_area(x, alive, i);
        volume += (x[i].dot(n) * a) as f64 / 3.0;
        area_vector += n.as_dvec3() * a as f64;
        let (n0, a0) = mesh.normal_area(&mesh.rest, alive, i);
        rest_volume += (mesh.rest[i].dot(n0) * a0) as f64 / 3.0;
    }
    let pressure_pa = p.volume_stiffness_pa as f64 * (rest_volume - volume) / rest_volume;
    spring + area_vector * pressure_pa
}

fn top_point(b: &SoftBody) -> Option<usize> {
    let x = b.positions();
    (0..x.len()).max_by(|&i, &j| x[i].z.total_cmp(&x[j].z))
}

fn tip_reaction_balance() -> Measured {
    let Some(mut b) = ball(SoftBodyParams::default()) else {
        return Measured::not_run(f64::NAN);
    };
    let Some(top) = top_point(&b) else {
        return Measured::not_run(f64::NAN);
    };
    let x = b.positions()[top];
    let normal = x.normalize();
    let tip = [Contact {
        tool: ToolId::Left,
        point: x + normal * (TIP_RADIUS_M - 0.002),
        normal,
        kind: ContactKind::Sphere {
            radius_m: TIP_RADIUS_M,
        },
    }];
    let reaction = hold(&mut b, &tip, HOLD_STEPS);
    Measured {
        reference: body_load_n(&b).length(),
        measured: reaction.length() as f64,
        simulated_s: HOLD_STEPS as f64 * DT_S as f64,
        floor: 0.0,
    }
}

/// The pressure the press applies, Pa.
const PRESS_PA: f32 = 1500.0;

/// A press on the top of a ball of `level`, held; the body and the last reaction.
fn held_press(level: u32, p: SoftBodyParams) -> Option<(SoftBody, Vec3)> {
    let mut b = ball_of(level, p)?;
    let top = top_point(&b)?;
    let x = b.positions()[top];
    let press = [Contact {
        tool: ToolId::Right,
        point: x,
        normal: x.normalize(),
        kind: ContactKind::Press {
            pressure_pa: PRESS_PA,
            area_m2: p.contact_area_m2,
        },
    }];
    let reaction = hold(&mut b, &press, HOLD_STEPS);
    Some((b, reaction))
}

fn press_total_balance() -> Measured {
    // Without the gas pressure: a sleeping point is held where it sleeps, so the pressure's
    // share on the sleeping part of the surface (1% here) is borne there, not by the press.
    let p = SoftBodyParams {
        volume_stiffness_pa: 0.0,
        ..SoftBodyParams::default()
    };
    let Some((b, reaction)) = held_press(2, p) else {
        return Measured::not_run(f64::NAN);
    };
    Measured {
        reference: body_load_n(&b).length(),
        measured: reaction.length() as f64,
        simulated_s: HOLD_STEPS as f64 * DT_S as f64,
        floor: 0.0,
    }
}

fn press_total_resolution() -> Measured {
    let p = SoftBodyParams::default();
    let coarse = held_press(3, p).map_or(f64::NAN, |(_, f)| f.length() as f64);
    let fine = held_press(4, p).map_or(f64::NAN, |(_, f)| f.length() as f64);
    Measured {
        reference: coarse,
        measured: fine,
        simulated_s: 2.0 * HOLD_STEPS as f64 * DT_S as f64,
        floor: 0.0,
    }
}
