//! The shared world: every tissue model of a procedure, the contacts the tools make with
//! them this step, the interactions between them, and a quarantine per model.
//!
//! A step runs in three phases, always in the same order:
//! 1. interactions (attachments, adhesions), in the order they were added, read every
//!    model's points and leave forces for the models' points;
//! 2. stage by stage (see [`super::coupling`]), the caller's couplings run with mutable
//!    access to the models, then every model of the stage that is not quarantined steps with
//!    its contacts and forces, in parallel (rayon); a model only touches its own slot, so the
//!    thread count cannot change a bit. A stage may take several substeps, the couplings
//!    running before each. After the last stage the couplings run once more;
//! 3. in model order, reactions are summed per tool and events collected.
//!
//! A model whose state goes non-finite is rolled back to its last checkpoint and frozen; it is
//! reported once, and the other models go on.

use super::coupling::{Couplings, Models, Phase, Uncoupled};
use super::{
    Contact, CutStroke, EventKind, ModelOutput, ModelReport, ModelSnapshot, Quarantine,
    SurfaceRole, TissueModel, ToolId,
};
use crate::collision::RayHit;
use glam::Vec3;
use rayon::prelude::*;

/// Steps between checkpoints: a quarantined model loses at most this many steps.
pub const CHECKPOINT_STEPS: u64 = 16;

/// A model's place in its world, in the order models were added.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ModelId(pub u32);

impl ModelId {
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

/// Forces interactions put on models' points this step, newtons.
#[derive(Debug, Default)]
pub struct PointForces {
    per_model: Vec<Vec<(u32, Vec3)>>,
}

impl PointForces {
    /// Empty lists for `models` models (interactions tested apart from a world).
    pub fn for_models(models: usize) -> Self {
        Self {
            per_model: vec![Vec::new(); models],
        }
    }

    /// Adds `force_n` on point `point` of `model`.
    pub fn add(&mut self, model: ModelId, point: u32, force_n: Vec3) {
        if let Some(list) = self.per_model.get_mut(model.index()) {
            list.push((point, force_n));
        }
    }

    /// The forces on `model`'s points so far, in the order they were added.
    pub fn on(&self, model: ModelId) -> &[(u32, Vec3)] {
        self.per_model.get(model.index()).map_or(&[], Vec::as_slice)
    }
}

/// What interactions may read of the models: their points.
pub trait PointSource {
    /// Point `point` of `model`, metres; none if there is no such point (or it was cut away).
    fn point(&self, model: ModelId, point: u32) -> Option<Vec3>;
    /// The model's name, for events.
    fn name(&self, model: ModelId) -> &str;
}

/// Something that couples models: it reads their points before they step and leaves forces
/// on them. Applied in the order added, every step.
pub trait Interaction: Send {
    fn name(&self) -> &str;
    fn apply(
        &mut self,
        dt_s: f32,
        points: &dyn PointSource,
        forces: &mut PointForces,
        events: &mut Vec<EventKind>,
    );
}

pub(super) struct Slot<M> {
    pub(super) model: M,
    pub(super) guard: Quarantine,
    stage: u32,
    contacts: Vec<Contact>,
    output: ModelOutput,
    /// This step's reaction on each tool from this model, newtons.
    reactions: [Vec3; 2],
    time_s: f64,
    /// Sum over the steps taken of the share of points awake, and the steps taken.
    awake_sum: f64,
    stepped: u64,
}

/// The models of one procedure and what couples them. `M` is one model type or an enum of
/// the procedure's model types; `Box<dyn TissueModel>` works too.
pub struct World<M> {
    slots: Vec<Slot<M>>,
    interactions: Vec<Box<dyn Interaction>>,
    forces: PointForces,
    reactions: [Vec3; 2],
    /// Substeps of each stage (1 unless set).
    substeps: Vec<u32>,
    /// Wall-clock seconds in the couplings (benchmarks only).
    coupling_s: f64,
}

impl<M: TissueModel> Default for World<M> {
    fn default() -> Self {
        Self::new()
    }
}

struct Points<'a, M>(&'a [Slot<M>]);

impl<M: TissueModel> PointSource for Points<'_, M> {
    fn point(&self, model: ModelId, point: u32) -> Option<Vec3> {
        self.0.get(model.index())?.model.point(point)
    }

    fn name(&self, model: ModelId) -> &str {
        self.0.get(model.index()).map_or("", |s| s.model.name())
    }
}

impl<M: TissueModel> World<M> {
    pub fn new() -> Self {
        Self {
            slots: Vec::new(),
            interactions: Vec::new(),
            forces: PointForces::default(),
            reactions: [Vec3::ZERO; 2],
            substeps: vec![1],
            coupling_s: 0.0,
        }
    }

    /// Adds a model to stage 0; it steps from the next step on.
    pub fn add(&mut self, model: M) -> ModelId {
        self.add_to(0, model)
    }

    /// Adds a model to stage `stage`: it steps after the models of the stages before it.
    pub fn add_to(&mut self, stage: u32, model: M) -> ModelId {
        let id = ModelId(self.slots.len() as u32);
        if self.substeps.len() <= stage as usize {
            self.substeps.resize(stage as usize + 1, 1);
        }
        self.slots.push(Slot {
            model,
            guard: Quarantine::new(CHECKPOINT_STEPS),
            stage,
            contacts: Vec::new(),
            output: ModelOutput::default(),
            reactions: [Vec3::ZERO; 2],
            time_s: 0.0,
            awake_sum: 0.0,
            stepped: 0,
        });
        self.forces.per_model.push(Vec::new());
        id
    }

    /// Every model as couplings see them, outside a step (a scene placing what its first
    /// step needs).
    pub fn coupled(&mut self) -> Models<'_, M> {
        Models {
            slots: &mut self.slots,
        }
    }

    /// Stage `stage` takes `substeps` substeps of `dt / substeps` a step, its couplings
    /// running before each.
    pub fn set_substeps(&mut self, stage: u32, substeps: u32) {
        if self.substeps.len() <= stage as usize {
            self.substeps.resize(stage as usize + 1, 1);
        }
        self.substeps[stage as usize] = substeps.max(1);
    }

    /// How many stages the world's step runs.
    pub fn stages(&self) -> u32 {
        self.substeps.len() as u32
    }

    /// The couplings' share of the wall-clock time, seconds (benchmarks only): the stages'
    /// time less the models' own steps (so the world's own checks count here too).
    pub fn coupling_time(&self) -> f64 {
        self.coupling_s
    }

    /// Adds an interaction; it applies after those added before it.
    pub fn add_interaction(&mut self, interaction: impl Interaction + 'static) {
        self.interactions.push(Box::new(interaction));
    }

    pub fn len(&self) -> usize {
        self.slots.len()
    }

    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Every model's id, in order.
    pub fn ids(&self) -> impl Iterator<Item = ModelId> + use<M> {
        (0..self.slots.len() as u32).map(ModelId)
    }

    /// The model `id`. Ids come from [`World::add`] of this world.
    pub fn model(&self, id: ModelId) -> &M {
        &self.slots[id.index()].model
    }

    pub fn model_mut(&mut self, id: ModelId) -> &mut M {
        &mut self.slots[id.index()].model
    }

    /// Every model with its id, in order.
    pub fn models(&self) -> impl Iterator<Item = (ModelId, &M)> {
        self.slots
            .iter()
            .enumerate()
            .map(|(i, s)| (ModelId(i as u32), &s.model))
    }

    /// The model called `name`, if there is one.
    pub fn find(&self, name: &str) -> Option<ModelId> {
        self.models()
            .find(|(_, m)| m.name() == name)
            .map(|(id, _)| id)
    }

    /// Whether `id` was quarantined (it no longer steps).
    pub fn is_frozen(&self, id: ModelId) -> bool {
        self.slots[id.index()].guard.is_frozen()
    }

    /// Hands `contact` to model `id` for the next step.
    pub fn contact(&mut self, id: ModelId, contact: Contact) {
        self.slots[id.index()].contacts.push(contact);
    }

    /// The contacts model `id` has for the next step.
    pub fn contacts(&self, id: ModelId) -> &[Contact] {
        &self.slots[id.index()].contacts
    }

    /// Cuts model `id` now (a quarantined model is not cut); its events go to `events`.
    pub fn cut(&mut self, id: ModelId, stroke: &CutStroke, events: &mut Vec<EventKind>) {
        let slot = &mut self.slots[id.index()];
        if slot.guard.is_frozen() {
            return;
        }
        slot.output.clear();
        slot.model.cut(stroke, &mut slot.output);
        events.append(&mut slot.output.events);
    }

    /// Advances every model one step of `dt_s` (see the module's phases); `step` is the
    /// step's number (for checkpoints). Events go to `events` in model order.
    pub fn step(&mut self, dt_s: f32, step: u64, events: &mut Vec<EventKind>) {
        self.step_coupled(dt_s, step, events, &mut Uncoupled);
    }

    /// [`World::step`] with `couplings` run before each stage's substeps and after the last
    /// stage.
    pub fn step_coupled(
        &mut self,
        dt_s: f32,
        step: u64,
        events: &mut Vec<EventKind>,
        couplings: &mut dyn Couplings<M>,
    ) {
        let _span = tracing::debug_span!("world_step", step, models = self.slots.len()).entered();
        for list in &mut self.forces.per_model {
            list.clear();
        }
        let points = Points(&self.slots);
        for interaction in &mut self.interactions {
            let _s = tracing::debug_span!("interaction", name = interaction.name()).entered();
            interaction.apply(dt_s, &points, &mut self.forces, events);
        }
        for slot in &mut self.slots {
            slot.output.clear();
            slot.reactions = [Vec3::ZERO; 2];
        }
        // The couplings' time is the stages' less the models' own (two clock readings a step,
        // not two a phase).
        let t0 = std::time::Instant::now();
        let models_before: f64 = self.slots.iter().map(|s| s.time_s).sum();
        let stages = self.stages();
        for stage in 0..stages {
            let substeps = self.substeps[stage as usize];
            let h = if substeps == 1 {
                dt_s
            } else {
                dt_s / substeps as f32
            };
            for substep in 0..substeps {
                let phase = Phase {
                    stage,
                    substep,
                    substeps,
                };
                self.couple(phase, dt_s, events, couplings);
                let last = substep + 1 == substeps;
                self.step_stage(stage, h, step, last);
            }
        }
        let after = Phase {
            stage: stages,
            substep: 0,
            substeps: 1,
        };
        self.couple(after, dt_s, events, couplings);
        let models_after: f64 = self.slots.iter().map(|s| s.time_s).sum();
        self.coupling_s += (t0.elapsed().as_secs_f64() - (models_after - models_before)).max(0.0);
        self.reactions = [Vec3::ZERO; 2];
        for slot in &mut self.slots {
            let n = self.substeps[slot.stage as usize];
            if n > 1 {
                // The mean over the substeps.
                let share = 1.0 / n as f32;
                slot.reactions = slot.reactions.map(|r| r * share);
            }
            for (sum, r) in self.reactions.iter_mut().zip(slot.reactions) {
                *sum += r;
            }
            events.append(&mut slot.output.events);
            slot.contacts.clear();
        }
    }

    fn couple(
        &mut self,
        phase: Phase,
        dt_s: f32,
        events: &mut Vec<EventKind>,
        couplings: &mut dyn Couplings<M>,
    ) {
        let _s = tracing::debug_span!("coupling", stage = phase.stage, substep = phase.substep)
            .entered();
        let mut models = Models {
            slots: &mut self.slots,
        };
        couplings.couple(phase, dt_s, &mut models, events);
    }

    /// One substep of `h` of stage `stage`'s models, in parallel where the stage has more
    /// than one (a lone model taking ten substeps a step is not worth a
    /// hand-over to the pool); `last`: the step's last substep of the stage (checkpoints are
    /// taken only there).
    fn step_stage(&mut self, stage: u32, h: f32, step: u64, last: bool) {
        let forces = &self.forces.per_model;
        let in_stage = self.slots.iter().filter(|s| s.stage == stage).count();
        let one = |(slot, forces): (&mut Slot<M>, &Vec<(u32, Vec3)>)| {
            step_slot(slot, forces, h, step, last);
        };
        if in_stage > 1 {
            self.slots
                .par_iter_mut()
                .zip(forces.par_iter())
                .filter(|(slot, _)| slot.stage == stage)
                .for_each(one);
        } else {
            self.slots
                .iter_mut()
                .zip(forces.iter())
                .filter(|(slot, _)| slot.stage == stage)
                .for_each(one);
        }
    }

    /// The force the tissue put on each tool (left, right) in the last step, newtons: the sum
    /// over models, in model order.
    pub fn reactions(&self) -> [Vec3; 2] {
        self.reactions
    }

    /// Model `id`'s part of [`World::reactions`].
    pub fn reactions_from(&self, id: ModelId) -> [Vec3; 2] {
        self.slots[id.index()].reactions
    }

    /// The reaction on one tool.
    pub fn reaction(&self, tool: ToolId) -> Vec3 {
        self.reactions[tool.index()]
    }

    /// The nearest surface any model shows along a ray (unit `dir`) within `max_m`; a tie
    /// goes to the model added first.
    pub fn cast_ray(&self, origin: Vec3, dir: Vec3, max_m: f32) -> Option<(ModelId, RayHit)> {
        let mut best: Option<(ModelId, RayHit)> = None;
        for (id, model) in self.models() {
            if let Some(h) = model.collider().cast_ray(origin, dir, max_m)
                && best.is_none_or(|(_, b)| h.distance_m < b.distance_m)
            {
                best = Some((id, h));
            }
        }
        best
    }

    /// The model with a surface feature nearest `point` within `radius_m`: (model, distance,
    /// feature); a tie goes to the model added first.
    pub fn nearest(&self, point: Vec3, radius_m: f32) -> Option<(ModelId, f32, u32)> {
        self.models()
            .filter_map(|(id, m)| {
                m.collider()
                    .nearest_within(point, radius_m)
                    .first()
                    .map(|&(d, f)| (id, d, f))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)))
    }

    /// Every model's render mesh, with its surface roles from `roles`, as a job: each model
    /// reads what it must now ([`TissueModel::render_job`]), and [`MeshesJob::build`] puts
    /// the meshes together on any thread, the same meshes on every one.
    pub fn render_job(&mut self, roles: impl Fn(ModelId, &M) -> Vec<SurfaceRole>) -> MeshesJob {
        MeshesJob(
            self.slots
                .iter_mut()
                .enumerate()
                .map(|(i, s)| {
                    let r = roles(ModelId(i as u32), &s.model);
                    (s.model.render_job(), r)
                })
                .collect(),
        )
    }

    /// Sizes of every model, for reports.
    pub fn model_reports(&self) -> Vec<ModelReport> {
        self.models()
            .map(|(_, m)| {
                let s = m.sizes();
                ModelReport {
                    name: m.name().to_string(),
                    kind: m.kind().to_string(),
                    vertices: s.vertices,
                    triangles: s.triangles,
                    constraints: s.constraints,
                    mass_spring: m.mass_spring(),
                    gpu: m.gpu_adapter(),
                }
            })
            .collect()
    }

    /// Wall-clock seconds each model has spent stepping (benchmarks only; never in reports).
    pub fn model_times(&self) -> Vec<f64> {
        self.slots.iter().map(|s| s.time_s).collect()
    }

    /// The mean share of each model's points awake over the steps it took (benchmarks).
    pub fn awake_fractions(&self) -> Vec<f64> {
        self.slots
            .iter()
            .map(|s| s.awake_sum / s.stepped.max(1) as f64)
            .collect()
    }

    /// Keeps every point of every model stepping from now on (benchmarks).
    pub fn stay_awake(&mut self) {
        for s in &mut self.slots {
            s.model.stay_awake();
        }
    }

    /// Heap bytes by part, summed over the models (parts matched by name).
    pub fn memory(&self) -> Vec<(&'static str, usize)> {
        let mut total: Vec<(&'static str, usize)> = Vec::new();
        for (_, m) in self.models() {
            for (name, bytes) in m.memory() {
                match total.iter_mut().find(|t| t.0 == name) {
                    Some(t) => t.1 += bytes,
                    None => total.push((name, bytes)),
                }
            }
        }
        total
    }

    /// A digest of every model's state, in model order.
    pub fn state_hash(&self) -> u64 {
        let mut h = crate::sim::Fnv::default();
        for (_, m) in self.models() {
            let v = m.state_hash();
            h.write(v as u32);
            h.write((v >> 32) as u32);
        }
        h.0
    }
}

/// One model's substep of `h` with its contacts and forces, timed and checked (see
/// [`World::step_stage`]).
fn step_slot<M: TissueModel>(
    slot: &mut Slot<M>,
    forces: &[(u32, Vec3)],
    h: f32,
    step: u64,
    last: bool,
) {
    if slot.guard.is_frozen() {
        return;
    }
    let _s = tracing::debug_span!(
        "model_step",
        model = slot.model.name(),
        kind = slot.model.kind()
    )
    .entered();
    let t0 = std::time::Instant::now();
    let reactions_before = slot.output.reactions.len();
    slot.model.apply_point_forces(forces);
    if last && slot.guard.checkpoint_due(step) {
        slot.model.checkpoint_follows();
    }
    slot.model.step(h, &slot.contacts, &mut slot.output);
    slot.time_s += t0.elapsed().as_secs_f64();
    slot.awake_sum += f64::from(slot.model.awake_fraction());
    slot.stepped += 1;
    let quarantined = {
        let _guard = tracing::debug_span!("model_guard").entered();
        if last {
            slot.guard.after_step(&mut slot.model, step)
        } else {
            slot.guard.check(&mut slot.model)
        }
    };
    if let Some(e) = quarantined {
        tracing::warn!(
            model = slot.model.name(),
            step,
            "a non-finite state: rolled back to the last checkpoint and frozen"
        );
        slot.output.events.push(e);
        // A rolled-back model pushes nothing on the tools.
        slot.output.reactions.clear();
        slot.reactions = [Vec3::ZERO; 2];
        return;
    }
    for (tool, f) in &slot.output.reactions[reactions_before..] {
        slot.reactions[tool.index()] += *f;
    }
}

/// What a procedure's reports and benchmarks read of its world's models, whatever their
/// type: sizes, step times, heap bytes, awake shares and the state digest.
pub trait ModelSet: Send {
    fn model_reports(&self) -> Vec<ModelReport>;
    fn model_times(&self) -> Vec<f64>;
    fn memory(&self) -> Vec<(&'static str, usize)>;
    fn awake_fractions(&self) -> Vec<f64>;
    fn stay_awake(&mut self);
    fn state_hash(&self) -> u64;
    /// Puts a NaN into model `index` (in the order of [`ModelSet::model_reports`]); false
    /// when there is no such model, or it holds no state the next step would meet now.
    fn inject_nan(&mut self, index: usize) -> bool;
    /// The whole state is read after the next step (a frame's snapshot): see
    /// [`TissueModel::read_whole_after_step`].
    fn read_whole_after_step(&mut self);
}

impl<M: TissueModel> ModelSet for World<M> {
    fn model_reports(&self) -> Vec<ModelReport> {
        World::model_reports(self)
    }
    fn model_times(&self) -> Vec<f64> {
        World::model_times(self)
    }
    fn memory(&self) -> Vec<(&'static str, usize)> {
        World::memory(self)
    }
    fn awake_fractions(&self) -> Vec<f64> {
        World::awake_fractions(self)
    }
    fn stay_awake(&mut self) {
        World::stay_awake(self);
    }
    fn state_hash(&self) -> u64 {
        World::state_hash(self)
    }
    fn inject_nan(&mut self, index: usize) -> bool {
        match self.slots.get_mut(index) {
            Some(slot) => slot.model.inject_nan(),
            None => false,
        }
    }
    fn read_whole_after_step(&mut self) {
        for slot in &mut self.slots {
            slot.model.read_whole_after_step();
        }
    }
}

/// Every model's render mesh still to build, with its surface roles ([`World::render_job`]).
pub struct MeshesJob(Vec<(crate::sim::MeshJob, Vec<SurfaceRole>)>);

impl MeshesJob {
    /// The meshes, in the world's order.
    pub fn build(self) -> Vec<ModelSnapshot> {
        self.0
            .into_iter()
            .map(|(job, roles)| {
                let mut snap = job.build();
                snap.roles = roles;
                snap
            })
            .collect()
    }
}
