//! Cases for the particle solver as a whole, each run on the CPU and (`--compute gpu`) by the
//! GPU's kernels: a tie holding a weight (the ties' and the cloth's stretch projection), a
//! folded hinge of cloth returning to its rest fold (the bending projection), a vessel's chain
//! stretched by the weight below each segment (the chains' exact run solve), a strand
//! pulled until it tears (the strands, their weakening and tearing), and a weight held by a
//! grasp and resting on an instrument (the instruments' springs and pushes, and the
//! reactions summed from them).

use super::particle_cases::{BREAK_STRAND, HANGING_CHAIN, hanging_chain};
use super::{Case, Measured};
use crate::collision::{Instrument, ToolCylinder};
use crate::models::particles::Particles;
use crate::models::particles::adhesion::{Adhesion, AdhesionParams};
use crate::models::particles::chain::Chains;
use crate::models::particles::cloth::{Cloth, ClothParams};
use crate::models::particles::contacts::BodyContacts;
use crate::models::particles::shape::ShapeMatching;
use crate::models::particles::solver::{HandTool, ParticleSolver, SolverParams, SolverParts};
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

const CHAIN_DESCRIPTION: &str = "a vessel's chain of 12 particles of 0.1 g, 3 mm apart, 20 g at \
                                 its end, hanging from its pinned top (segments of 500 N/m), \
                                 1.5 s damped (2 sweeps a step): the end's drop vs the sum \
                                 over segments of the weight below each over 500 N/m; \
                                 tolerance 1e-3";
const STRAND_DESCRIPTION: &str = "adhesion_break_force's strand (1 cm, 5 segments of 1e4 N/m, \
                                  weakened past 1.1 times its length) in a solver of 10 \
                                  sweeps a step, pulled by a force growing 1 N/s: the pull at \
                                  which it tears vs (k / n) 0.1 L = 2 N; tolerance 5 %";
const GRASP_DESCRIPTION: &str = "a 10 g particle taken by a closed grasper's jaw 1 mm above \
                                 it (a spring of 200 N/m) and held 3 s under gravity, damped \
                                 (2 substeps of 4 sweeps a 1 ms step): the tissue's pull on the \
                                 grasper vs the weight m g = 0.0981 N; tolerance 1e-3";
const PUSH_DESCRIPTION: &str = "a 10 g particle (radius 1 mm) dropped 1.5 mm onto a \
                                horizontal 5 mm instrument shaft and left 2 s to rest, damped: \
                                the tissue's push on the instrument (the pushes summed over \
                                the step) vs the weight m g = 0.0981 N; tolerance 1e-3";

pub(super) fn cases() -> Vec<Case> {
    vec![
        Case {
            model: MODEL,
            case: "particle_grasp_weight",
            description: GRASP_DESCRIPTION,
            unit: "N",
            tolerance: 1e-3,
            run: || grasp_weight(false),
        },
        Case {
            model: MODEL,
            case: "particle_push_weight",
            description: PUSH_DESCRIPTION,
            unit: "N",
            tolerance: 1e-3,
            run: || push_weight(false),
        },
        Case {
            model: MODEL,
            case: "particle_chain_stretch",
            description: CHAIN_DESCRIPTION,
            unit: "m",
            tolerance: 1e-3,
            run: || chain_stretch(false),
        },
        Case {
            model: MODEL,
            case: "particle_strand_break_force",
            description: STRAND_DESCRIPTION,
            unit: "N",
            tolerance: 0.05,
            run: || strand_break(false),
        },
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
            case: "particle_grasp_weight_gpu",
            description: GRASP_DESCRIPTION,
            unit: "N",
            tolerance: 1e-3,
            run: || grasp_weight(true),
        },
        Case {
            model: MODEL_GPU,
            case: "particle_push_weight_gpu",
            description: PUSH_DESCRIPTION,
            unit: "N",
            tolerance: 1e-3,
            run: || push_weight(true),
        },
        Case {
            model: MODEL_GPU,
            case: "particle_chain_stretch_gpu",
            description: CHAIN_DESCRIPTION,
            unit: "m",
            tolerance: 1e-3,
            run: || chain_stretch(true),
        },
        Case {
            model: MODEL_GPU,
            case: "particle_strand_break_force_gpu",
            description: STRAND_DESCRIPTION,
            unit: "N",
            tolerance: 0.05,
            run: || strand_break(true),
        },
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
    p: Particles,
    ties: Vec<Stretch>,
    triangles: &[[u32; 3]],
    cloth: ClothParams,
    gravity: Vec3,
) -> Option<ParticleSolver> {
    let parts = Parts {
        ties,
        triangles,
        cloth,
        ..Parts::none()
    };
    solver_with(p, parts, gravity, 4, 20.0)
}

/// What a case's solver holds besides its particles.
struct Parts<'a> {
    ties: Vec<Stretch>,
    triangles: &'a [[u32; 3]],
    cloth: ClothParams,
    chains: Chains,
    /// Strands between these pairs, of `strand_params`.
    strands: &'a [(u32, u32)],
    strand_params: AdhesionParams,
}

impl Parts<'_> {
    /// No ties, cloth, vessels or strands.
    fn none() -> Self {
        Parts {
            ties: Vec::new(),
            triangles: &[],
            cloth: ClothParams {
                stretch_stiffness_n_per_m: 1.0,
                bend_stiffness_n_m_per_rad: 1.0,
            },
            chains: Chains::default(),
            strands: &[],
            strand_params: BREAK_STRAND,
        }
    }
}

/// A solver over `p` and `parts` (nothing else), 2 substeps of `sweeps` a step with point
/// damping `damping_per_s`; None if it could not be built.
fn solver_with(
    mut p: Particles,
    parts: Parts,
    gravity: Vec3,
    sweeps: u32,
    damping_per_s: f32,
) -> Option<ParticleSolver> {
    let adhesion = Adhesion::new(&mut p, parts.strands, parts.strand_params, 7).ok()?;
    let bonds = Adhesion::new(&mut p, &[], parts.strand_params, 2).ok()?;
    let parts = SolverParts {
        cloth: Cloth::new(&p, parts.triangles, parts.cloth).ok()?,
        shape: ShapeMatching::new(&p, Vec::new()).ok()?,
        particles: p,
        chains: parts.chains,
        ties: parts.ties,
        adhesion,
        bonds,
        contacts: BodyContacts::new(Vec::new(), 1e-3, 1e-3),
        contact_radius_m: 1e-3,
    };
    let params = SolverParams {
        iterations: sweeps,
        substeps: 2,
        damping_per_s,
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

/// Whether a solver meant for the GPU (`gpu`) left it for the CPU on the way (its case then
/// measured the CPU, and is not run).
fn fell_back(s: &mut ParticleSolver, gpu: bool) -> bool {
    gpu && (s.take_device_note().is_some() || s.gpu_adapter().is_none())
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
    if fell_back(&mut s, gpu) {
        return Measured::not_run(reference);
    }
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
    if fell_back(&mut s, gpu) {
        return Measured::not_run(reference);
    }
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

fn chain_stretch(gpu: bool) -> Measured {
    let (n, k, m, load, _) = HANGING_CHAIN;
    // Segment j carries the particles below it: (n - 1 - j) of m, and the load.
    let reference: f32 = (0..n - 1)
        .map(|j| ((n - 1 - j) as f32 * m + load) * G / k)
        .sum();
    let (p, chains) = hanging_chain();
    let end_rest = p.x[n - 1].y;
    let parts = Parts {
        chains,
        ..Parts::none()
    };
    let gravity = Vec3::new(0.0, -G, 0.0);
    let Some(mut s) = solver_with(p, parts, gravity, 2, 30.0).and_then(|s| on_gpu(s, gpu)) else {
        return Measured::not_run(f64::from(reference));
    };
    let simulated_s = steps(&mut s, 1500);
    if fell_back(&mut s, gpu) {
        return Measured::not_run(f64::from(reference));
    }
    Measured {
        simulated_s,
        ..Measured::at_rest(
            f64::from(reference),
            f64::from(end_rest - s.particles.x[n - 1].y),
        )
    }
}

fn strand_break(gpu: bool) -> Measured {
    let (l, k, n) = (0.01f32, 1e4f32, 5u32);
    let reference = f64::from(k / n as f32 * 0.1 * l);
    let mut p = Particles::new();
    let fixed = p.add(Vec3::ZERO, 0.0, 1);
    let free = p.add(Vec3::new(l, 0.0, 0.0), 1e-3, 2);
    let pairs = [(free, fixed)];
    let parts = Parts {
        strands: &pairs,
        ..Parts::none()
    };
    let Some(mut s) = solver_with(p, parts, Vec3::ZERO, 10, 20.0).and_then(|s| on_gpu(s, gpu))
    else {
        return Measured::not_run(reference);
    };
    let mut out = ModelOutput::default();
    let mut t = 0.0f32;
    while t < 4.0 {
        t += 1e-3;
        s.particles.add_force(free as usize, Vec3::new(t, 0.0, 0.0));
        s.step(1e-3, &[], &mut out);
        if !s.outcome().breaks.is_empty() {
            if fell_back(&mut s, gpu) {
                return Measured::not_run(reference);
            }
            return Measured {
                simulated_s: f64::from(t),
                ..Measured::at_rest(reference, f64::from(t))
            };
        }
    }
    Measured::not_run(reference)
}

/// The mass the instruments' cases hold, kg.
const TOOL_MASS: f32 = 0.01;

/// `steps` steps of `s` with `tool` in the right hand; the tissue's force on it in the last,
/// N, or none where the GPU's run fell back to the CPU.
fn held_steps(s: &mut ParticleSolver, tool: &HandTool, steps: usize, gpu: bool) -> Option<Vec3> {
    let mut out = ModelOutput::default();
    for _ in 0..steps {
        s.set_tools([None, Some(tool.clone())]);
        s.step(1e-3, &[], &mut out);
    }
    (!fell_back(s, gpu)).then(|| s.outcome().reactions[1])
}

fn grasp_weight(gpu: bool) -> Measured {
    let reference = f64::from(TOOL_MASS * G);
    let mut p = Particles::new();
    p.add(Vec3::ZERO, TOOL_MASS, 0);
    let gravity = Vec3::new(0.0, -G, 0.0);
    let Some(mut s) = solver_with(p, Parts::none(), gravity, 4, 10.0) else {
        return Measured::not_run(reference);
    };
    s.params.grasp_reach_m = 3e-3;
    s.params.grasp_most = 8;
    s.params.grasp_stiffness_n_per_m = 200.0;
    let jaw = Vec3::new(0.0, 1e-3, 0.0);
    // A grasper pointing down at the jaw (a grasp that holds does not push).
    let q = Quat::from_rotation_x(-std::f32::consts::FRAC_PI_2);
    let Ok(instrument) = Instrument::grasper(jaw + Vec3::Y * 0.01, q, 0.0) else {
        return Measured::not_run(reference);
    };
    let tool = HandTool {
        instrument,
        jaw,
        closed: true,
    };
    let Some(mut s) = on_gpu(s, gpu) else {
        return Measured::not_run(reference);
    };
    match held_steps(&mut s, &tool, 3000, gpu) {
        // The tissue pulls the grasper down by the weight.
        Some(r) if s.held(1).len() == 1 => Measured {
            simulated_s: 3.0,
            ..Measured::at_rest(reference, f64::from(-r.y))
        },
        _ => Measured::not_run(reference),
    }
}

fn push_weight(gpu: bool) -> Measured {
    let reference = f64::from(TOOL_MASS * G);
    let mut p = Particles::new();
    p.add(Vec3::ZERO, TOOL_MASS, 0);
    let gravity = Vec3::new(0.0, -G, 0.0);
    let Some(s) = solver_with(p, Parts::none(), gravity, 4, 20.0) else {
        return Measured::not_run(reference);
    };
    // A shaft along z whose top is 2.5 mm below the particle's bottom.
    let y = -0.005;
    let shaft = ToolCylinder::constant(Vec3::new(0.0, y, -0.05), Vec3::new(0.0, y, 0.05), 2.5e-3);
    let Some(instrument) = shaft.ok().and_then(|c| Instrument::new(vec![c]).ok()) else {
        return Measured::not_run(reference);
    };
    let tool = HandTool {
        instrument,
        jaw: Vec3::new(0.0, y, 0.0),
        closed: false,
    };
    let Some(mut s) = on_gpu(s, gpu) else {
        return Measured::not_run(reference);
    };
    match held_steps(&mut s, &tool, 2000, gpu) {
        // The tissue pushes the instrument down by the weight.
        Some(r) => Measured {
            simulated_s: 2.0,
            ..Measured::at_rest(reference, f64::from(-r.y))
        },
        None => Measured::not_run(reference),
    }
}
