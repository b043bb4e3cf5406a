//! The cholecystectomy's physics: every body of [`super::Anatomy`] in one particle world,
//! stepped at the simulator's 1 ms.
//!
//! One step of `dt` is `substeps` substeps. One substep: predict every particle under
//! gravity; search the contact pairs again if something has moved far enough; then
//! `iterations` sweeps of, in this order, the organs' shape-matching clusters, the vessels'
//! chains, the ties, the cloth fascia, the adhesion strands, the graspers, the instruments'
//! surfaces, the contacts between bodies and the floor; then the velocities from the
//! positions, and the adhesion strands' weakening and tearing.
//!
//! Stiffness comes from the tissues' Young's moduli (the scenario's `[tissue]` table):
//! - a shape-matching cluster of radius `r` swings at `omega^2 = C E / (rho r^2)`, `C`
//!   calibrated so that a hanging column stretches as the continuum does
//!   ([`crate::models::particles::shape::MODULUS_FACTOR`]);
//! - a vessel's segment of length `l` and radius `a` is a spring `E pi a^2 / l`, its skip-one
//!   bending spring a twentieth of that;
//! - the fascia's edges are springs `E t` (a square of sheet pulled along one side).

use super::anatomy::{Anatomy, body};
use super::clips::{Clippable, CutError, PatientEnd};
use crate::models::particles::adhesion::{Adhesion, AdhesionParams};
use crate::models::particles::chain::Chains;
use crate::models::particles::cloth::{Cloth, ClothParams};
use crate::models::particles::contacts::BodyContacts;
use crate::models::particles::shape::{ShapeMatching, frequency_for, lattice_clusters};
pub use crate::models::particles::solver::{Dissection, HandTool, StepOutcome};
use crate::models::particles::solver::{ParticleSolver, SolverParams, SolverParts};
use crate::models::xpbd::Stretch;
use crate::sim::{EventKind, ModelId, World};
use glam::Vec3;

/// Young's modulus (Pa) of each tissue, and the other figures of the step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneParams {
    pub liver_modulus_pa: f32,
    pub gallbladder_modulus_pa: f32,
    pub fat_modulus_pa: f32,
    pub vessel_modulus_pa: f32,
    pub fascia_modulus_pa: f32,
    /// Clusters every `cluster_stride` lattice steps, reaching `cluster_reach` lattice steps.
    pub cluster_stride: u32,
    pub cluster_reach: f32,
    /// The solver's sweeps, substeps, damping, gravity, floor, ties and grasps. Substeps
    /// converge far better than sweeps for the same cost (Macklin et al., "Small steps in
    /// physics simulation", 2019): the gallbladder hanging by its strands settles with its
    /// strands strained 0.6 % at 8 sweeps, 36 % at 2 (unconverged: the strands then tear
    /// under a gentle pull), and with 2 sweeps in each of 2 substeps a retraction tears them
    /// where 6 sweeps in one step do. The floor is the field's (the structures behind and
    /// below it: duodenum, colon, retroperitoneum): a body cut or torn free comes to rest on
    /// it. The ties hold the vessels' ends in their organs and the fascia's edges.
    pub solver: SolverParams,
    /// The contacts' particle radius and the Verlet margin, m (pairs closer than two radii and
    /// the margin are listed; a search when a member has moved half the margin).
    pub contact_radius_m: f32,
    pub contact_margin_m: f32,
    pub adhesion: AdhesionParams,
    pub adhesion_seed: u64,
    /// The fat's strands to the organs and vessels (softer: pulling the fat away tears them).
    pub fat_bonds: AdhesionParams,
}

impl Default for SceneParams {
    fn default() -> Self {
        SceneParams {
            liver_modulus_pa: 5000.0,
            gallbladder_modulus_pa: 8000.0,
            fat_modulus_pa: 1000.0,
            vessel_modulus_pa: 50_000.0,
            fascia_modulus_pa: 20_000.0,
            cluster_stride: 3,
            cluster_reach: 2.5,
            solver: SolverParams {
                iterations: 2,
                substeps: 2,
                damping_per_s: 5.0,
                gravity_m_per_s2: Vec3::new(0.0, -9.81, 0.0),
                floor_y_m: -0.08,
                tie_stiffness_n_per_m: 200.0,
                grasp_reach_m: 0.004,
                grasp_most: 12,
                grasp_stiffness_n_per_m: 100.0,
            },
            contact_radius_m: 0.001,
            // 2 mm: a search when a member has moved 1 mm. The cystic artery's swing (0.5 mm
            // in the prediction, docs/cholecystectomy.md) set off a search at 1 mm in 46 % of
            // the substeps while the fat is dragged, at 2 mm in 13 %, for 32 pairs instead of
            // 28 (the median).
            contact_margin_m: 0.002,
            adhesion: AdhesionParams {
                segments: 4,
                strand_mass_kg: 2e-6,
                body: body::ADHESION,
                stiffness_n_per_m: 100.0,
                weak_stiffness_n_per_m: 0.01,
                breakable_per_strand: 1,
                break_stretch: 1.1,
                tear_strain: 0.5,
            },
            adhesion_seed: 0x00c4_07ec,
            fat_bonds: AdhesionParams {
                segments: 3,
                strand_mass_kg: 1e-6,
                body: body::ADHESION,
                stiffness_n_per_m: 5.0,
                weak_stiffness_n_per_m: 0.01,
                breakable_per_strand: 1,
                break_stretch: 3.0,
                tear_strain: 1.0,
            },
        }
    }
}

/// Why the scene could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("shape matching: {0}")]
    Shape(#[from] crate::models::particles::shape::ShapeError),
    #[error("fascia: {0}")]
    Cloth(#[from] crate::models::particles::cloth::ClothError),
    #[error("adhesion: {0}")]
    Adhesion(#[from] crate::models::particles::adhesion::AdhesionError),
}

/// The one model: every body of the anatomy in one particle solver.
pub const PARTICLES: ModelId = ModelId(0);

pub struct CholeScene {
    pub params: SceneParams,
    pub anatomy: Anatomy,
    world: World<ParticleSolver>,
}

impl CholeScene {
    pub fn new(anatomy: Anatomy, params: SceneParams) -> Result<CholeScene, SceneError> {
        let mut p = anatomy.particles.clone();
        let mut specs = Vec::new();
        for (o, e) in anatomy.organs.iter().zip([
            params.liver_modulus_pa,
            params.gallbladder_modulus_pa,
            params.fat_modulus_pa,
        ]) {
            let members: Vec<u32> = o.range.clone().collect();
            let radius = params.cluster_reach * o.spacing_m;
            let density = o
                .range
                .clone()
                .find(|&i| p.w[i as usize] > 0.0)
                .map_or(1000.0, |i| p.mass(i as usize) / o.spacing_m.powi(3));
            specs.extend(lattice_clusters(
                &p.x,
                &members,
                o.spacing_m,
                params.cluster_stride as usize,
                radius,
                frequency_for(e, density, radius),
            ));
        }
        let shape = ShapeMatching::new(&p, specs)?;
        let mut chains = Chains::new();
        for v in &anatomy.vessels {
            let a = v.radius_m;
            let k = params.vessel_modulus_pa * std::f32::consts::PI * a * a / (2.0 * a);
            chains.add(&p, &v.chain, k, k / 20.0);
        }
        let ties: Vec<Stretch> = anatomy
            .ties
            .iter()
            .map(|&(a, b)| Stretch {
                a,
                b,
                rest_m: p.x[a as usize].distance(p.x[b as usize]),
            })
            .collect();
        let cloth = Cloth::new(
            &p,
            &anatomy.fascia_triangles,
            ClothParams {
                stretch_stiffness_n_per_m: params.fascia_modulus_pa * anatomy.fascia_thickness_m,
                bend_stiffness_n_m_per_rad: 1e-5,
            },
        )?;
        let adhesion = Adhesion::new(
            &mut p,
            &anatomy.adhesion_pairs,
            params.adhesion,
            params.adhesion_seed,
        )?;
        let bonds = Adhesion::new(
            &mut p,
            &anatomy.fat_pairs,
            params.fat_bonds,
            params.adhesion_seed.rotate_left(17),
        )?;
        // Bodies touch one another through their surfaces and the vessels.
        let mut members: Vec<u32> = anatomy
            .organs
            .iter()
            .flat_map(|o| o.surface.iter().copied())
            .collect();
        members.extend(anatomy.vessels.iter().flat_map(|v| v.chain.iter().copied()));
        members.sort_unstable();
        let mut contacts =
            BodyContacts::new(members, params.contact_radius_m, params.contact_margin_m);
        contacts.ignore_present_overlaps(&p);
        let parts = SolverParts {
            particles: p,
            shape,
            chains,
            ties,
            cloth,
            adhesion,
            bonds,
            contacts,
            contact_radius_m: params.contact_radius_m,
        };
        let mut world = World::new();
        let id = world.add(ParticleSolver::new("particles", parts, params.solver));
        debug_assert_eq!(id, PARTICLES);
        Ok(CholeScene {
            params,
            anatomy,
            world,
        })
    }

    /// The particle solver.
    pub fn solver(&self) -> &ParticleSolver {
        self.world.model(PARTICLES)
    }

    pub fn solver_mut(&mut self) -> &mut ParticleSolver {
        self.world.model_mut(PARTICLES)
    }

    /// The world the solver steps in (the procedure's model figures).
    pub fn world(&self) -> &World<ParticleSolver> {
        &self.world
    }

    pub fn world_mut(&mut self) -> &mut World<ParticleSolver> {
        &mut self.world
    }

    /// Lays the patient out (see [`ParticleSolver::settle`]); the largest displacement, m.
    pub fn settle(&mut self, seconds: f32, iterations: u32, damping_per_s: f32) -> f32 {
        self.solver_mut().settle(seconds, iterations, damping_per_s)
    }

    /// The hook's current (or the scissors) at `at`: cuts the fascia's constraints, the
    /// adhesion strands and the fat's strands within `radius_m`.
    pub fn dissect(&mut self, at: Vec3, radius_m: f32) -> Dissection {
        if self.world.is_frozen(PARTICLES) {
            return Dissection::default();
        }
        self.solver_mut().dissect(at, radius_m)
    }

    /// Particles of body `b` within `radius_m` of `at` (the hook on the liver's capsule).
    pub fn touching(&self, b: u16, at: Vec3, radius_m: f32) -> usize {
        self.solver().touching(b, at, radius_m)
    }

    /// The particles hand `h`'s grasp holds.
    pub fn held(&self, h: usize) -> Vec<u32> {
        self.solver().held(h)
    }

    /// The vessels that take clips and cuts: the cystic duct (the patient towards the
    /// junction, its chain's end) and the cystic artery (the patient at the hepatic artery,
    /// its chain's start).
    pub fn clippable(&self) -> [Clippable; 2] {
        [
            Clippable {
                chain: 0,
                name: "cystic_duct",
                patient: PatientEnd::Last,
                error: CutError::BileLeak,
            },
            Clippable {
                chain: 3,
                name: "cystic_artery",
                patient: PatientEnd::First,
                error: CutError::Bleeding,
            },
        ]
    }

    /// How much of Calot's triangle the laparoscope sees: the share of points on a
    /// barycentric grid over the triangle (`n` per side) from which the ray towards the
    /// camera (`towards_camera`, a direction) passes no fat particle closer than
    /// `radius_m`. 1: cleared; the fat as built covers most of it.
    pub fn calot_exposure(&self, towards_camera: Vec3, n: usize, radius_m: f32) -> f32 {
        let Some(dir) = towards_camera.try_normalize() else {
            return 0.0;
        };
        let [a, b, c] = self.anatomy.calot;
        let particles = &self.solver().particles;
        let fat: Vec<Vec3> = particles
            .x
            .iter()
            .zip(&particles.body)
            .filter(|(_, b)| **b == body::FAT)
            .map(|(x, _)| *x)
            .collect();
        let n = n.max(1);
        let (mut seen, mut all) = (0u32, 0u32);
        for i in 0..=n {
            for j in 0..=n - i {
                let (u, v) = (i as f32 / n as f32, j as f32 / n as f32);
                let q = a + (b - a) * u + (c - a) * v;
                all += 1;
                let hidden = fat.iter().any(|f| {
                    let t = (*f - q).dot(dir);
                    t > 0.0 && (*f - q - dir * t).length_squared() < radius_m * radius_m
                });
                seen += u32::from(!hidden);
            }
        }
        seen as f32 / all as f32
    }

    /// One step of `dt_s` (step number `step`) with the hands' instruments `tools`; the
    /// world's events (a quarantined model) go to `events`.
    pub fn step(
        &mut self,
        dt_s: f32,
        tools: [Option<HandTool>; 2],
        step: u64,
        events: &mut Vec<EventKind>,
    ) -> StepOutcome {
        self.solver_mut().set_tools(tools);
        self.world.step(dt_s, step, events);
        if self.world.is_frozen(PARTICLES) {
            return StepOutcome::default();
        }
        self.solver().outcome().clone()
    }

    /// Wall-clock seconds in the shape matching, the vessels and ties, the cloth fascia,
    /// the strands, and the instruments and contacts (benchmarks only).
    pub fn times(&self) -> [f64; 5] {
        self.solver().times
    }

    /// A digest of the particles' state and the adhesions' progress.
    pub fn state_hash(&self) -> u64 {
        self.solver().digest()
    }
}

#[cfg(test)]
#[path = "scene_tests.rs"]
mod tests;
