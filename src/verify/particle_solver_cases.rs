//! Cases for the particle solver as a whole, each run on the CPU and (`--compute gpu`) by the
//! GPU's kernels: a tie holding a weight (the ties' and the cloth's stretch projection), and a
//! folded hinge of cloth returning to its rest fold (the bending projection).

use super::{Case, Measured};
use crate::models::particles::Particles;
use crate::models::particles::adhesion::{Adhesion, AdhesionParams};
use crate::models::particles::chain::Chains;
use crate::models::particles::cloth::{Cloth, ClothParams};
use crate::models::particles::contacts::BodyContacts;
use crate::models::particles::shape::ShapeMatching;
use crate::models::particles::solver::{ParticleSolver, SolverParams, SolverParts};
use crate::models::xpbd::{self, Bend, Stretch};
use crate::sim::{ModelOutput, TissueModel};
use glam::{Quat, Vec3};

const MODEL: &str = "particle solver";
const MODEL_GPU: &str = "particle solver, gpu";
const G: f32 = 9.81;
/// The tie's stiffness, N/m, and the weight's mass, kg.
const TIE_K: f32 = 100.0;
const TIE_MASS: f32 = 0.01;
/// The hinge's rest fold and the fold it starts from, degrees.
const REST_FOLD_DEG: f32 = 30.0;
const START_FOLD_DEG: f32 = 90.0;

const TIE_DESCRIPTION: &str = "a 10 g particle hanging 10 mm below a pinned one by a tie of \
                               100 N/m, 2 s under gravity, damped (2 substeps of 4 sweeps a \
                               1 ms step): its stretch vs Hooke's m g / k = 0.981 mm; \
                               tolerance 1e-3";
const HINGE_DESCRIPTION: &str = "two triangles of cloth (10 mm edges) built with a 30 deg fold \
                                 about their shared edge, held by its ends and one wing, the \
                                 other wing turned to 90 deg and let go, 1 s without gravity, \
                                 damped: the fold vs the rest fold; tolerance 1e-3 (the \
                                 projection turns 0.02 rad at most, so it takes 53 sweeps)";

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "particle_tie_load",
            description: TIE_DESCRIPTION,
            unit: "m",
            tolerance: 1e-3,
            run: || tie_load(false),
        },
        Case {
            model: MODEL,
            case: "particle_hinge_rest_fold",
            description: HINGE_DESCRIPTION,
            unit: "rad",
            tolerance: 1e-3,
            run: || hinge_fold(false),
        },
    ]
}

/// The same cases stepped by the GPU's kernels (`shaders/particles.wgsl`) on the first
/// adapter.
pub(super) fn gpu_cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL_GPU,
            case: "particle_tie_load_gpu",
            description: TIE_DESCRIPTION,
            unit: "m",
            tolerance: 1e-3,
            run: || tie_load(true),
        },
        Case {
            model: MODEL_GPU,
            case: "particle_hinge_rest_fold_gpu",
            description: HINGE_DESCRIPTION,
            unit: "rad",
            tolerance: 1e-3,
            run: || hinge_fold(true),
        },
    ]
}

/// A solver over `p` with `ties` and a cloth of `triangles` (nothing else); None if it could
/// not be built.
fn solver_of(
    mut p: Particles,
    ties: Vec<Stretch>,
    triangles: &[[u32; 3]],
    cloth: ClothParams,
    gravity: Vec3,
) -> Option<ParticleSolver> {
    let strands = AdhesionParams {
        segments: 2,
        strand_mass_kg: 1e-6,
        body: 9,
        stiffness_n_per_m: 1.0,
        weak_stiffness_n_per_m: 1e-3,
        breakable_per_strand: 1,
        break_stretch: 1.1,
        tear_strain: 0.5,
    };
    let adhesion = Adhesion::new(&mut p, &[], strands, 1).ok()?;
    let bonds = Adhesion::new(&mut p, &[], strands, 2).ok()?;
    let parts = SolverParts {
        cloth: Cloth::new(&p, triangles, cloth).ok()?,
        shape: ShapeMatching::new(&p, Vec::new()).ok()?,
        particles: p,
        chains: Chains::default(),
        ties,
        adhesion,
        bonds,
        contacts: BodyContacts::new(Vec::new(), 1e-3, 1e-3),
        contact_radius_m: 1e-3,
    };
    let params = SolverParams {
        iterations: 4,
        substeps: 2,
        damping_per_s: 20.0,
        gravity_m_per_s2: gravity,
        floor_y_m: -1.0,
        tie_stiffness_n_per_m: TIE_K,
        grasp_reach_m: 1e-3,
        grasp_most: 1,
        grasp_stiffness_n_per_m: 1.0,
    };
    Some(ParticleSolver::new(MODEL, parts, params))
}

/// `s` on the first GPU adapter if `gpu`; None if there is none or it refused the solver.
fn on_gpu(mut s: ParticleSolver, gpu: bool) -> Option<ParticleSolver> {
    if gpu {
        let device = crate::gpu::Gpu::headless(false).ok()?;
        s.use_gpu(&device).ok()?;
    }
    Some(s)
}

fn steps(s: &mut ParticleSolver, n: usize) -> f64 {
    let mut out = ModelOutput::default();
    for _ in 0..n {
        s.step(1e-3, &[], &mut out);
    }
    n as f64 * 1e-3
}

fn tie_load(gpu: bool) -> Measured {
    let reference = f64::from(TIE_MASS * G / TIE_K);
    let mut p = Particles::new();
    let top = p.add(Vec3::ZERO, 0.0, 0);
    let weight = p.add(Vec3::new(0.0, -0.01, 0.0), TIE_MASS, 1);
    let tie = Stretch {
        a: weight,
        b: top,
        rest_m: 0.01,
    };
    let cloth = ClothParams {
        stretch_stiffness_n_per_m: 1.0,
        bend_stiffness_n_m_per_rad: 1.0,
    };
    let gravity = Vec3::new(0.0, -G, 0.0);
    let Some(mut s) = solver_of(p, vec![tie], &[], cloth, gravity).and_then(|s| on_gpu(s, gpu))
    else {
        return Measured::not_run(reference);
    };
    let simulated_s = steps(&mut s, 2000);
    let x = &s.particles.x;
    let stretch = x[weight as usize].distance(x[top as usize]) - 0.01;
    Measured {
        simulated_s,
        ..Measured::at_rest(reference, f64::from(stretch))
    }
}

fn hinge_fold(gpu: bool) -> Measured {
    let reference = f64::from(REST_FOLD_DEG.to_radians());
    let l = 0.01f32;
    // The hinge a-b along x; wing c in the x-y plane, wing d turned about the hinge.
    let wing = |fold_deg: f32| {
        let flat = Vec3::new(0.5 * l, -0.866 * l, 0.0);
        Quat::from_rotation_x(fold_deg.to_radians()) * flat
    };
    let corners = |fold: f32| {
        [
            Vec3::ZERO,
            Vec3::new(l, 0.0, 0.0),
            Vec3::new(0.5 * l, 0.866 * l, 0.0),
            wing(fold),
        ]
    };
    let mut p = Particles::new();
    for (k, x) in corners(REST_FOLD_DEG).into_iter().enumerate() {
        p.add(x, if k == 3 { 1e-4 } else { 0.0 }, 0);
    }
    let triangles = [[0, 1, 2], [0, 3, 1]];
    let cloth = ClothParams {
        stretch_stiffness_n_per_m: 1e3,
        bend_stiffness_n_m_per_rad: 1e-3,
    };
    let Some(mut s) = solver_of(p, Vec::new(), &triangles, cloth, Vec3::ZERO) else {
        return Measured::not_run(reference);
    };
    // The rest fold is measured from the built geometry; then the free wing is turned.
    let rest = s.cloth.bend_constraints().first().map(|b| b.rest_rad);
    s.particles.x[3] = corners(START_FOLD_DEG)[3];
    let Some(mut s) = on_gpu(s, gpu) else {
        return Measured::not_run(reference);
    };
    let simulated_s = steps(&mut s, 1000);
    let Some(rest) = rest else {
        return Measured::not_run(reference);
    };
    let hinge = Bend {
        a: 0,
        b: 1,
        c: 2,
        d: 3,
        rest_rad: 0.0,
    };
    let fold = xpbd::dihedral(&s.particles.x, &hinge);
    // The fold as built is the reference's 30 degrees (checked here, so a wrong geometry fails).
    let built = f64::from(rest.abs());
    if (built - reference).abs() > 1e-4 {
        return Measured::at_rest(reference, built);
    }
    Measured {
        simulated_s,
        ..Measured::at_rest(reference, f64::from(fold.abs()))
    }
}
