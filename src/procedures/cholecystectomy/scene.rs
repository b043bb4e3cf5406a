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
use crate::collision::Instrument;
use crate::models::particles::Particles;
use crate::models::particles::adhesion::{Adhesion, AdhesionBreak, AdhesionParams};
use crate::models::particles::chain::Chains;
use crate::models::particles::cloth::{Cloth, ClothParams};
use crate::models::particles::contacts::{BodyContacts, Grasp, ToolPush};
use crate::models::particles::shape::{ShapeMatching, frequency_for, lattice_clusters};
use crate::models::xpbd::{self, Stretch};
use glam::Vec3;
use std::time::Instant;

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
    /// Sweeps per substep, and substeps per step. Substeps converge far better than sweeps
    /// for the same cost (Macklin et al., "Small steps in physics simulation", 2019): the
    /// gallbladder hanging by its strands settles with its strands strained 0.6 % at 8
    /// sweeps, 36 % at 2 (unconverged: the strands then tear under a gentle pull), and with
    /// 2 sweeps in each of 2 substeps a retraction tears them where 6 sweeps in one step do.
    pub iterations: u32,
    pub substeps: u32,
    /// Point damping, 1/s.
    pub damping_per_s: f32,
    pub gravity_m_per_s2: Vec3,
    /// The floor of the field (the structures behind and below it: duodenum, colon,
    /// retroperitoneum), m: no particle goes below this height. A body cut or torn free
    /// comes to rest on it instead of falling for ever.
    pub floor_y_m: f32,
    /// The ties' stiffness (vessel ends in their organs, the fascia's edges), N/m.
    pub tie_stiffness_n_per_m: f32,
    /// The contacts' particle radius and the Verlet margin, m.
    pub contact_radius_m: f32,
    pub contact_margin_m: f32,
    /// A closed grasper takes the particles within this reach of its jaw (at most
    /// `grasp_most`), each by a spring of `grasp_stiffness_n_per_m`.
    pub grasp_reach_m: f32,
    pub grasp_most: u32,
    pub grasp_stiffness_n_per_m: f32,
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
            iterations: 2,
            substeps: 2,
            damping_per_s: 5.0,
            gravity_m_per_s2: Vec3::new(0.0, -9.81, 0.0),
            floor_y_m: -0.08,
            tie_stiffness_n_per_m: 200.0,
            contact_radius_m: 0.001,
            contact_margin_m: 0.001,
            grasp_reach_m: 0.004,
            grasp_most: 12,
            grasp_stiffness_n_per_m: 100.0,
            adhesion: AdhesionParams {
                segments: 4,
                strand_mass_kg: 2e-6,
                body: body::ADHESION,
                stiffness_n_per_m: 400.0,
                weak_stiffness_n_per_m: 0.01,
                breakable_per_strand: 1,
                break_stretch: 3.0,
                tear_strain: 0.5,
            },
            adhesion_seed: 0x00c4_07ec,
            fat_bonds: AdhesionParams {
                segments: 3,
                strand_mass_kg: 1e-6,
                body: body::ADHESION,
                stiffness_n_per_m: 15.0,
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

/// One hand's instrument this step: its cylinders, its jaw (where a grasp takes hold), and
/// whether the jaws are closed.
#[derive(Debug, Clone)]
pub struct HandTool {
    pub instrument: Instrument,
    pub jaw: Vec3,
    pub closed: bool,
}

/// What a cut of the hook or the scissors took.
#[derive(Debug, Clone, Default)]
pub struct Dissection {
    /// Fascia constraints removed.
    pub fascia: usize,
    /// Adhesion strands and fat strands cut.
    pub adhesions: Vec<AdhesionBreak>,
    pub fat_strands: Vec<AdhesionBreak>,
}

/// What a step did.
#[derive(Debug, Clone, Default)]
pub struct StepOutcome {
    /// The tissue's force on each hand's instrument, N.
    pub reactions: [Vec3; 2],
    /// Particles each instrument pushed, and each grasp holds.
    pub pushed: [usize; 2],
    pub held: [usize; 2],
    /// Adhesion strands torn this step, and the fat's strands.
    pub breaks: Vec<AdhesionBreak>,
    pub fat_breaks: Vec<AdhesionBreak>,
}

pub struct CholeScene {
    pub params: SceneParams,
    pub particles: Particles,
    pub anatomy: Anatomy,
    pub shape: ShapeMatching,
    pub vessels: Chains,
    ties: Vec<Stretch>,
    tie_lambda: Vec<f32>,
    pub fascia: Cloth,
    pub adhesion: Adhesion,
    pub fat_bonds: Adhesion,
    pub contacts: BodyContacts,
    pushes: [ToolPush; 2],
    grasps: [Option<Grasp>; 2],
    /// Wall-clock seconds spent so far in the shape matching, the vessels and ties, the
    /// cloth fascia, the adhesion and fat strands, and the instruments and contacts
    /// (benchmarks only).
    pub times: [f64; 5],
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
        let mut vessels = Chains::new();
        for v in &anatomy.vessels {
            let a = v.radius_m;
            let k = params.vessel_modulus_pa * std::f32::consts::PI * a * a / (2.0 * a);
            vessels.add(&p, &v.chain, k, k / 20.0);
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
        let fascia = Cloth::new(
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
        let fat_bonds = Adhesion::new(
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
        let pushes = [
            ToolPush::new(&p, params.contact_radius_m),
            ToolPush::new(&p, params.contact_radius_m),
        ];
        Ok(CholeScene {
            tie_lambda: vec![0.0; ties.len()],
            ties,
            params,
            particles: p,
            anatomy,
            shape,
            vessels,
            fascia,
            adhesion,
            fat_bonds,
            contacts,
            pushes,
            grasps: [None, None],
            times: [0.0; 5],
        })
    }

    /// Lays the patient out: `seconds` of steps with no instrument, `iterations` sweeps,
    /// heavy point damping (`damping_per_s`) and no strand weakened or torn, then every
    /// velocity to zero. The bodies start where gravity and their attachments hold them, not
    /// where the generator put them (a body hanging from others otherwise falls while the
    /// support reaches it through the sweeps, and tears what holds it). Returns the largest
    /// displacement, m.
    pub fn settle(&mut self, seconds: f32, iterations: u32, damping_per_s: f32) -> f32 {
        let start = self.particles.x.clone();
        let keep = self.params;
        self.params.iterations = iterations;
        self.params.damping_per_s = damping_per_s;
        let steps = (seconds / 1e-3).ceil() as usize;
        for _ in 0..steps {
            self.advance(1e-3, &[None, None], false);
        }
        self.params = keep;
        self.times = [0.0; 5];
        self.particles.v.iter_mut().for_each(|v| *v = Vec3::ZERO);
        self.particles
            .x
            .iter()
            .zip(&start)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f32::max)
    }

    /// The hook's current (or the scissors) at `at`: cuts the fascia's constraints, the
    /// adhesion strands and the fat's strands within `radius_m`.
    pub fn dissect(&mut self, at: Vec3, radius_m: f32) -> Dissection {
        Dissection {
            fascia: self.fascia.cut_near(at, radius_m, &self.particles),
            adhesions: self.adhesion.cut_near(at, radius_m, &self.particles),
            fat_strands: self.fat_bonds.cut_near(at, radius_m, &self.particles),
        }
    }

    /// Particles of body `b` within `radius_m` of `at` (the hook on the liver's capsule).
    pub fn touching(&self, b: u16, at: Vec3, radius_m: f32) -> usize {
        let r2 = radius_m * radius_m;
        self.particles
            .x
            .iter()
            .zip(&self.particles.body)
            .filter(|(x, body)| **body == b && x.distance_squared(at) <= r2)
            .count()
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
        let fat: Vec<Vec3> = self
            .particles
            .x
            .iter()
            .zip(&self.particles.body)
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

    /// The particles hand `h`'s grasp holds.
    pub fn held(&self, h: usize) -> Vec<u32> {
        self.grasps
            .get(h)
            .and_then(|g| g.as_ref())
            .map_or_else(Vec::new, |g| g.particles().collect())
    }

    /// One step of `dt_s` with the hands' instruments `tools`: `substeps` substeps. The
    /// reactions are their mean (the force over the step), the breaks all of theirs.
    pub fn step(&mut self, dt_s: f32, tools: &[Option<HandTool>; 2]) -> StepOutcome {
        let n = self.params.substeps.max(1);
        let mut out = StepOutcome::default();
        for _ in 0..n {
            let o = self.advance(dt_s / n as f32, tools, true);
            for h in 0..2 {
                out.reactions[h] += o.reactions[h] / n as f32;
                out.pushed[h] = out.pushed[h].max(o.pushed[h]);
            }
            out.held = o.held;
            out.breaks.extend(o.breaks);
            out.fat_breaks.extend(o.fat_breaks);
        }
        out
    }

    fn advance(&mut self, dt_s: f32, tools: &[Option<HandTool>; 2], tearing: bool) -> StepOutcome {
        let params = self.params;
        let mut out = StepOutcome::default();
        // Grasps close on what is within reach and open when the jaws do.
        for (h, t) in tools.iter().enumerate() {
            match t {
                Some(t) if t.closed => {
                    if self.grasps[h].is_none() {
                        let g = Grasp::take(
                            &self.particles,
                            t.jaw,
                            params.grasp_reach_m,
                            params.grasp_most as usize,
                            params.grasp_stiffness_n_per_m,
                        );
                        self.grasps[h] = Some(g);
                    }
                }
                _ => self.grasps[h] = None,
            }
        }
        let p = &mut self.particles;
        p.predict(dt_s, params.gravity_m_per_s2);
        let mut clock = Instant::now();
        self.contacts.refresh(p);
        self.shape.begin_step();
        self.vessels.begin_step();
        self.tie_lambda.fill(0.0);
        self.fascia.begin_step();
        self.adhesion.begin_step();
        self.fat_bonds.begin_step();
        for push in &mut self.pushes {
            push.begin_step();
        }
        for g in self.grasps.iter_mut().flatten() {
            g.begin_step();
        }
        let tie_compliance = 1.0 / params.tie_stiffness_n_per_m.max(1e-9);
        let mut lap = |times: &mut [f64; 5], k: usize| {
            let now = Instant::now();
            times[k] += now.duration_since(clock).as_secs_f64();
            clock = now;
        };
        // The contacts' refresh and the multipliers' reset are the contacts' part.
        lap(&mut self.times, 4);
        for _ in 0..params.iterations.max(1) {
            self.shape.project(p, dt_s);
            lap(&mut self.times, 0);
            self.vessels.project(p, dt_s);
            for (t, l) in self.ties.iter().zip(&mut self.tie_lambda) {
                *l += xpbd::project_stretch(&mut p.x, &p.w, t, tie_compliance, dt_s, *l);
            }
            lap(&mut self.times, 1);
            self.fascia.project(p, dt_s);
            lap(&mut self.times, 2);
            self.adhesion.project(p, dt_s);
            self.fat_bonds.project(p, dt_s);
            lap(&mut self.times, 3);
            for (h, t) in tools.iter().enumerate() {
                let Some(t) = t else { continue };
                match &mut self.grasps[h] {
                    Some(g) if !g.is_empty() => g.project(p, t.jaw, dt_s),
                    _ => {
                        out.pushed[h] = self.pushes[h].project(&t.instrument, p, dt_s);
                    }
                }
            }
            self.contacts.project(p);
            for (x, w) in p.x.iter_mut().zip(&p.w) {
                if *w > 0.0 && x.y < params.floor_y_m {
                    x.y = params.floor_y_m;
                }
            }
            lap(&mut self.times, 4);
        }
        p.finish(dt_s, params.damping_per_s);
        if tearing {
            out.breaks = self.adhesion.update(p);
            out.fat_breaks = self.fat_bonds.update(p);
        }
        for h in 0..2 {
            let grasp = self.grasps[h]
                .as_ref()
                .map_or(Vec3::ZERO, |g| g.reaction_n(dt_s));
            out.reactions[h] = self.pushes[h].reaction_n() + grasp;
            out.held[h] = self.grasps[h].as_ref().map_or(0, Grasp::len);
        }
        out
    }

    /// A digest of the particles' state and the adhesions' progress.
    pub fn state_hash(&self) -> u64 {
        let mut h = crate::sim::Fnv(self.particles.state_hash());
        h.write(self.adhesion.torn_segments() as u32);
        h.0
    }
}

#[cfg(test)]
#[path = "scene_tests.rs"]
mod tests;
