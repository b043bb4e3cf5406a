//! The particle solver: every constraint set of one particle world stepped together, as one
//! model of a world. One step of `dt` is `substeps` substeps. One substep: the graspers take
//! or let go; every particle is predicted under gravity; the contact pairs are searched again
//! if something moved far enough; then `iterations` sweeps of, in this order, the
//! shape-matching clusters, the chains, the ties, the cloth, the strand sets, the
//! instruments (a grasp pulls, an open instrument pushes), the contacts between bodies and
//! the floor; then the velocities from the positions, and the strands' weakening and tearing.
//!
//! The owner sets each hand's instrument before a step ([`ParticleSolver::set_tools`]) and
//! reads what the step did after it ([`ParticleSolver::outcome`]); the world gets the
//! instruments' reactions.

use super::Particles;
use super::adhesion::{Adhesion, AdhesionBreak};
use super::chain::Chains;
use super::cloth::Cloth;
use super::contacts::{BodyContacts, Grasp, ToolPush};
use super::shape::ShapeMatching;
use crate::collision::Instrument;
use crate::models::xpbd::{self, Stretch};
use crate::sim::{
    Collider, Contact, Fnv, ModelOutput, ModelSizes, ModelSnapshot, SurfaceRole, TissueModel,
    ToolId,
};
use glam::Vec3;
use std::time::Instant;

/// The solver's figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverParams {
    /// Sweeps per substep, and substeps per step.
    pub iterations: u32,
    pub substeps: u32,
    /// Point damping, 1/s.
    pub damping_per_s: f32,
    pub gravity_m_per_s2: Vec3,
    /// No free particle goes below this height, m.
    pub floor_y_m: f32,
    /// The ties' stiffness, N/m.
    pub tie_stiffness_n_per_m: f32,
    /// A closed grasper takes the particles within this reach of its jaw (at most
    /// `grasp_most`), each by a spring of `grasp_stiffness_n_per_m`.
    pub grasp_reach_m: f32,
    pub grasp_most: u32,
    pub grasp_stiffness_n_per_m: f32,
}

/// The constraint sets over one particle world, built by their owner.
pub struct SolverParts {
    pub particles: Particles,
    pub shape: ShapeMatching,
    pub chains: Chains,
    pub ties: Vec<Stretch>,
    pub cloth: Cloth,
    /// Two sets of breakable strands (projected in this order).
    pub adhesion: Adhesion,
    pub bonds: Adhesion,
    pub contacts: BodyContacts,
    pub contact_radius_m: f32,
}

/// One hand's instrument this step: its cylinders, its jaw (where a grasp takes hold), and
/// whether the jaws are closed.
#[derive(Debug, Clone)]
pub struct HandTool {
    pub instrument: Instrument,
    pub jaw: Vec3,
    pub closed: bool,
}

/// What a cut took.
#[derive(Debug, Clone, Default)]
pub struct Dissection {
    /// Cloth constraints removed.
    pub cloth: usize,
    /// Strands cut, of each set.
    pub adhesions: Vec<AdhesionBreak>,
    pub bonds: Vec<AdhesionBreak>,
}

/// What a step did.
#[derive(Debug, Clone, Default)]
pub struct StepOutcome {
    /// The tissue's force on each hand's instrument, N.
    pub reactions: [Vec3; 2],
    /// Particles each instrument pushed, and each grasp holds.
    pub pushed: [usize; 2],
    pub held: [usize; 2],
    /// Strands torn this step, of each set.
    pub breaks: Vec<AdhesionBreak>,
    pub bond_breaks: Vec<AdhesionBreak>,
}

/// The particles and every constraint set on them.
pub struct ParticleSolver {
    name: String,
    pub params: SolverParams,
    pub particles: Particles,
    pub shape: ShapeMatching,
    pub chains: Chains,
    /// The ties sorted by colour (`colour.rs`), and their colours.
    ties: Vec<Stretch>,
    tie_colours: Vec<u32>,
    tie_lambda: Vec<f32>,
    pub cloth: Cloth,
    pub adhesion: Adhesion,
    pub bonds: Adhesion,
    pub contacts: BodyContacts,
    pushes: [ToolPush; 2],
    grasps: [Option<Grasp>; 2],
    tools: [Option<HandTool>; 2],
    outcome: StepOutcome,
    saved: Particles,
    /// The GPU it steps on, if any (`device.rs`).
    pub(super) device: super::device::Slot,
    /// Wall-clock seconds spent so far in the shape matching, the chains and ties, the
    /// cloth, the strands, and the instruments and contacts (benchmarks only).
    pub times: [f64; 5],
}

impl ParticleSolver {
    pub fn new(name: &str, parts: SolverParts, params: SolverParams) -> ParticleSolver {
        let p = parts.particles;
        let (ties, tie_colours) = super::colour::sorted(&parts.ties, |t| [t.a, t.b]);
        let pushes = [
            ToolPush::new(&p, parts.contact_radius_m),
            ToolPush::new(&p, parts.contact_radius_m),
        ];
        ParticleSolver {
            name: name.to_string(),
            params,
            tie_lambda: vec![0.0; parts.ties.len()],
            ties,
            tie_colours,
            saved: p.clone(),
            particles: p,
            shape: parts.shape,
            chains: parts.chains,
            cloth: parts.cloth,
            adhesion: parts.adhesion,
            bonds: parts.bonds,
            contacts: parts.contacts,
            pushes,
            grasps: [None, None],
            tools: [None, None],
            outcome: StepOutcome::default(),
            device: Default::default(),
            times: [0.0; 5],
        }
    }

    /// A copy on the CPU without the instruments' state (benchmarks of the GPU's kernels,
    /// which step everything else).
    pub fn copy_without_instruments(&self) -> ParticleSolver {
        ParticleSolver {
            name: self.name.clone(),
            params: self.params,
            particles: self.particles.clone(),
            shape: self.shape.clone(),
            chains: self.chains.clone(),
            ties: self.ties.clone(),
            tie_colours: self.tie_colours.clone(),
            tie_lambda: self.tie_lambda.clone(),
            cloth: self.cloth.clone(),
            adhesion: self.adhesion.clone(),
            bonds: self.bonds.clone(),
            contacts: self.contacts.clone(),
            pushes: self.pushes.clone(),
            grasps: [None, None],
            tools: [None, None],
            outcome: StepOutcome::default(),
            saved: self.saved.clone(),
            device: Default::default(),
            times: [0.0; 5],
        }
    }

    /// Ties between particles.
    pub fn tie_count(&self) -> usize {
        self.ties.len()
    }

    /// The ties in projection order (by colour), and their colours.
    pub fn ties(&self) -> (&[Stretch], &[u32]) {
        (&self.ties, &self.tie_colours)
    }

    /// Each hand's instrument for the next step.
    pub fn set_tools(&mut self, tools: [Option<HandTool>; 2]) {
        self.tools = tools;
    }

    /// What the last step did.
    pub fn outcome(&self) -> &StepOutcome {
        &self.outcome
    }

    /// Lays the bodies out: `seconds` of steps with no instrument, `iterations` sweeps,
    /// heavy point damping (`damping_per_s`) and no strand weakened or torn, then every
    /// velocity to zero. The bodies start where gravity and their attachments hold them, not
    /// where they were generated. Returns the largest displacement, m.
    pub fn settle(&mut self, seconds: f32, iterations: u32, damping_per_s: f32) -> f32 {
        let start = self.particles.x.clone();
        let keep = self.params;
        self.params.iterations = iterations;
        self.params.damping_per_s = damping_per_s;
        let steps = (seconds / 1e-3).ceil() as usize;
        let none = [None, None];
        for _ in 0..steps {
            self.advance(1e-3, &none, false);
        }
        self.params = keep;
        self.times = [0.0; 5];
        self.particles.v.iter_mut().for_each(|v| *v = Vec3::ZERO);
        self.saved.clone_from(&self.particles);
        self.particles
            .x
            .iter()
            .zip(&start)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f32::max)
    }

    /// A cut at `at`: the cloth's constraints and both strand sets' strands within
    /// `radius_m`.
    pub fn dissect(&mut self, at: Vec3, radius_m: f32) -> Dissection {
        Dissection {
            cloth: self.cloth.cut_near(at, radius_m, &self.particles),
            adhesions: self.adhesion.cut_near(at, radius_m, &self.particles),
            bonds: self.bonds.cut_near(at, radius_m, &self.particles),
        }
    }

    /// Particles of body `b` within `radius_m` of `at`.
    pub fn touching(&self, b: u16, at: Vec3, radius_m: f32) -> usize {
        let r2 = radius_m * radius_m;
        self.particles
            .x
            .iter()
            .zip(&self.particles.body)
            .filter(|(x, body)| **body == b && x.distance_squared(at) <= r2)
            .count()
    }

    /// Each hand's grasp (none while its jaws are open) and push.
    pub(super) fn hand_state(&self, h: usize) -> (Option<&Grasp>, &ToolPush) {
        (self.grasps[h].as_ref(), &self.pushes[h])
    }

    /// The particles hand `h`'s grasp holds.
    pub fn held(&self, h: usize) -> Vec<u32> {
        self.grasps
            .get(h)
            .and_then(|g| g.as_ref())
            .map_or_else(Vec::new, |g| g.particles().collect())
    }

    /// One step of `dt_s` with the tools set: `substeps` substeps. The reactions are their
    /// mean (the force over the step), the breaks all of theirs.
    fn step_all(&mut self, dt_s: f32) -> StepOutcome {
        let n = self.params.substeps.max(1);
        let mut out = StepOutcome::default();
        let tools = std::mem::take(&mut self.tools);
        // The step's external forces act through every substep (each substep's prediction
        // uses them up).
        let p = &self.particles;
        let ext = p
            .ext
            .iter()
            .any(|e| *e != Vec3::ZERO)
            .then(|| p.ext.clone());
        // The substeps the device ran (all, or those before it failed).
        let mut done = 0;
        if super::device::can_step(self, &tools) {
            done = super::device::step(self, dt_s, &tools, ext.as_deref(), &mut out);
        } else {
            super::device::before_cpu_step(self);
        }
        for _ in done..n {
            if let Some(e) = &ext {
                self.particles.ext.copy_from_slice(e);
            }
            let o = self.advance(dt_s / n as f32, &tools, true);
            for h in 0..2 {
                out.reactions[h] += o.reactions[h] / n as f32;
                out.pushed[h] = out.pushed[h].max(o.pushed[h]);
            }
            out.held = o.held;
            out.breaks.extend(o.breaks);
            out.bond_breaks.extend(o.bond_breaks);
        }
        self.tools = tools;
        out
    }

    /// Grasps close on what is within reach and open when the jaws do (at each substep's
    /// start).
    pub(super) fn take_grasps(&mut self, tools: &[Option<HandTool>; 2]) {
        let params = self.params;
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
    }

    fn advance(&mut self, dt_s: f32, tools: &[Option<HandTool>; 2], tearing: bool) -> StepOutcome {
        let params = self.params;
        let mut out = StepOutcome::default();
        self.take_grasps(tools);
        let p = &mut self.particles;
        p.predict(dt_s, params.gravity_m_per_s2);
        let mut clock = Instant::now();
        self.contacts.refresh(p);
        self.shape.begin_step();
        self.chains.begin_step();
        self.tie_lambda.fill(0.0);
        self.cloth.begin_step();
        self.adhesion.begin_step();
        self.bonds.begin_step();
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
            self.chains.project(p, dt_s);
            for (t, l) in self.ties.iter().zip(&mut self.tie_lambda) {
                *l += xpbd::project_stretch(&mut p.x, &p.w, t, tie_compliance, dt_s, *l);
            }
            lap(&mut self.times, 1);
            self.cloth.project(p, dt_s);
            lap(&mut self.times, 2);
            self.adhesion.project(p, dt_s);
            self.bonds.project(p, dt_s);
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
            out.bond_breaks = self.bonds.update(p);
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

    /// A digest of the particles' state and the first strand set's progress.
    pub fn digest(&self) -> u64 {
        let mut h = Fnv(self.particles.state_hash());
        h.write(self.adhesion.torn_segments() as u32);
        h.0
    }
}

impl TissueModel for ParticleSolver {
    fn name(&self) -> &str {
        &self.name
    }

    fn kind(&self) -> &'static str {
        "position_based_particles"
    }

    fn gpu_adapter(&self) -> Option<String> {
        ParticleSolver::gpu_adapter(self)
    }

    fn sizes(&self) -> ModelSizes {
        ModelSizes {
            vertices: self.particles.x.len(),
            triangles: 0,
            constraints: self.shape.clusters()
                + self.ties.len()
                + self.cloth.edges()
                + self.cloth.hinges()
                + self.adhesion.segments()
                + self.bonds.segments(),
        }
    }

    /// One step with the instruments set for it (the world's contacts are not read: the
    /// instruments carry their cylinders and jaws); each hand's instrument gets its
    /// reaction.
    fn step(&mut self, dt_s: f32, _contacts: &[Contact], out: &mut ModelOutput) {
        self.outcome = self.step_all(dt_s);
        if let Some(reason) = self.take_device_note() {
            out.events.push(crate::sim::EventKind::ComputeFallback {
                model: self.name.clone(),
                reason,
            });
        }
        for (tool, r) in ToolId::BOTH.into_iter().zip(self.outcome.reactions) {
            if r != Vec3::ZERO {
                out.reactions.push((tool, r));
            }
        }
    }

    /// None that rays meet: the owner draws and picks the bodies.
    fn collider(&self) -> Collider<'_> {
        Collider::none()
    }

    /// The particles as points (the owner draws the bodies' surfaces).
    fn render_mesh(&mut self) -> ModelSnapshot {
        let n = self.particles.x.len();
        ModelSnapshot {
            name: self.name.clone(),
            positions: self.particles.x.clone(),
            normals: vec![Vec3::Y; n],
            cut_edge: vec![false; n],
            roles: vec![SurfaceRole::Tissue],
            ..ModelSnapshot::default()
        }
    }

    /// The particles (constraints cut or torn since stay so: a rollback returns the
    /// particles, the state a NaN spoils).
    fn checkpoint(&mut self) {
        self.saved.clone_from(&self.particles);
    }

    fn restore(&mut self) {
        self.particles.clone_from(&self.saved);
        self.device.stale();
        self.grasps = [None, None];
        self.outcome = StepOutcome::default();
    }

    fn state_is_finite(&self) -> bool {
        self.particles.is_finite()
    }

    fn state_hash(&self) -> u64 {
        self.digest()
    }

    /// A NaN speed on the first free particle.
    fn inject_nan(&mut self) -> bool {
        let p = &mut self.particles;
        match p.w.iter().position(|w| *w > 0.0) {
            Some(k) => {
                p.v[k].x = f32::NAN;
                true
            }
            None => false,
        }
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        vec![("particles", self.particles.heap_bytes())]
    }

    fn point(&self, i: u32) -> Option<Vec3> {
        self.particles.x.get(i as usize).copied()
    }
}
