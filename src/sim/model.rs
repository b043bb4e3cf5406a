use super::EventKind;
use glam::{Quat, Vec3};

/// Which instrument: the hand holding it.
pub type ToolId = super::Hand;

/// What a tool does to a model this step. Produced by collision, consumed by the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ContactKind {
    /// A pressed contact: the paper's pressure force P over area dA at a surface point.
    Press { pressure_pa: f32, area_m2: f32 },
    /// A rigid sphere (instrument tip) that tissue may not enter.
    Sphere { radius_m: f32 },
    /// A rigid capsule: an instrument's tip (the contact's point) and the shaft behind it back
    /// to `back`, `radius_m` around that segment, which tissue may not enter. The working end
    /// tents the surface as a `Sphere` does; along the shaft tissue is pushed out radially.
    Capsule { back: Vec3, radius_m: f32 },
    /// Closed grasper jaws at a pose: points within `radius_m` are held and carried.
    Grasp { rotation: Quat, radius_m: f32 },
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    pub tool: ToolId,
    /// Contact point (or sphere centre, or jaw point), metres.
    pub point: Vec3,
    /// Outward surface normal at the contact.
    pub normal: Vec3,
    pub kind: ContactKind,
}

impl Contact {
    /// Closed jaws at `jaws` (their tip and orientation) holding what lies within `radius_m`.
    pub fn grasp(tool: ToolId, jaws: &super::Pose, radius_m: f32) -> Self {
        Self {
            tool,
            point: jaws.position,
            normal: -jaws.forward(),
            kind: ContactKind::Grasp {
                rotation: jaws.orientation,
                radius_m,
            },
        }
    }
}

/// Faces the laser swept this step, to be removed from the surface.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CutStroke {
    pub faces: Vec<u32>,
}

/// Reused every step: reaction forces for the haptic snapshot and events.
#[derive(Debug, Default)]
pub struct ModelOutput {
    pub reactions: Vec<(ToolId, Vec3)>,
    pub events: Vec<EventKind>,
}

impl ModelOutput {
    pub fn clear(&mut self) {
        self.reactions.clear();
        self.events.clear();
    }
}

/// Sizes for reports and benchmarks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct ModelSizes {
    pub vertices: usize,
    pub triangles: usize,
    pub constraints: usize,
}

/// One tissue model. Owns its state; contacts are its only input from the world.
pub trait TissueModel: Send {
    fn name(&self) -> &str;
    fn kind(&self) -> &'static str;
    fn sizes(&self) -> ModelSizes;
    fn step(&mut self, dt_s: f32, contacts: &[Contact], out: &mut ModelOutput);
    fn cut(&mut self, stroke: &CutStroke, out: &mut ModelOutput) {
        let _ = (stroke, out);
    }
    /// What tools, rays and cuts see of the model.
    fn collider(&self) -> super::Collider<'_>;
    /// Render positions, normals and live triangles for a snapshot.
    fn render_mesh(&mut self) -> crate::sim::ModelSnapshot;
    /// [`TissueModel::render_mesh`] as a job: what must be read of the state is read now,
    /// and the rest (normals, drawn vertices, indices) may be built on another thread, the
    /// same mesh either way. By default it is built now.
    fn render_job(&mut self) -> crate::sim::MeshJob {
        crate::sim::MeshJob::ready(self.render_mesh())
    }
    /// Saves the current state as the last good one.
    fn checkpoint(&mut self);
    /// The whole state is read after the next step (its checkpoint, a frame's snapshot): a
    /// model whose state lags on a device brings all of it back with that step (to where it
    /// can be read without a round trip of its own).
    fn read_whole_after_step(&mut self) {}
    /// A checkpoint follows the next step (the world's quarantine). By default the whole
    /// state is read after it ([`TissueModel::read_whole_after_step`]); a model whose state
    /// lags on a device may instead take what the checkpoint needs of it straight from what
    /// that step brings back, without bringing its own copy up to date.
    fn checkpoint_follows(&mut self) {
        self.read_whole_after_step();
    }
    /// Returns to the last checkpoint.
    fn restore(&mut self);
    /// Whether every state value changed since the last check is finite.
    fn state_is_finite(&self) -> bool;
    /// A deterministic digest of the state, for replay and determinism checks.
    fn state_hash(&self) -> u64;
    /// Puts a NaN into the state where the next step will meet it, as a failing solver or a
    /// bad force would (fault injection: the quarantine is tested in every procedure);
    /// false when the model holds no such state now (a contact model touching nothing).
    fn inject_nan(&mut self) -> bool;
    /// Heap bytes by part, for the profiler.
    fn memory(&self) -> Vec<(&'static str, usize)> {
        Vec::new()
    }
    /// A mass-spring model's nodes, springs and integrator, for reports (none otherwise).
    fn mass_spring(&self) -> crate::sim::MassSpring {
        crate::sim::MassSpring::default()
    }
    /// The GPU adapter the model steps on; none on the CPU (most models).
    fn gpu_adapter(&self) -> Option<String> {
        None
    }
    /// The share of the model's points the last step worked on (1 for a model that never
    /// sleeps).
    fn awake_fraction(&self) -> f32 {
        1.0
    }
    /// Keeps every point stepping from now on, never asleep (benchmarks: a sleeping model
    /// must never read as fast).
    fn stay_awake(&mut self) {}
    /// Point `i` (a node, particle or simplex point), metres, for interactions between
    /// models; none if the model has no such point or it was cut away.
    fn point(&self, i: u32) -> Option<Vec3> {
        let _ = i;
        None
    }
    /// Forces other models put on this model's points for the next step only (attachments,
    /// adhesions), newtons; a point that does not exist is ignored.
    fn apply_point_forces(&mut self, forces: &[(u32, Vec3)]) {
        let _ = forces;
    }
}

/// A world may hold models of different kinds behind boxes.
impl TissueModel for Box<dyn TissueModel> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn kind(&self) -> &'static str {
        (**self).kind()
    }
    fn gpu_adapter(&self) -> Option<String> {
        (**self).gpu_adapter()
    }
    fn sizes(&self) -> ModelSizes {
        (**self).sizes()
    }
    fn step(&mut self, dt_s: f32, contacts: &[Contact], out: &mut ModelOutput) {
        (**self).step(dt_s, contacts, out);
    }
    fn cut(&mut self, stroke: &CutStroke, out: &mut ModelOutput) {
        (**self).cut(stroke, out);
    }
    fn collider(&self) -> super::Collider<'_> {
        (**self).collider()
    }
    fn render_mesh(&mut self) -> crate::sim::ModelSnapshot {
        (**self).render_mesh()
    }
    fn render_job(&mut self) -> crate::sim::MeshJob {
        (**self).render_job()
    }
    fn checkpoint(&mut self) {
        (**self).checkpoint();
    }
    fn read_whole_after_step(&mut self) {
        (**self).read_whole_after_step();
    }
    fn checkpoint_follows(&mut self) {
        (**self).checkpoint_follows();
    }
    fn restore(&mut self) {
        (**self).restore();
    }
    fn state_is_finite(&self) -> bool {
        (**self).state_is_finite()
    }
    fn state_hash(&self) -> u64 {
        (**self).state_hash()
    }
    fn inject_nan(&mut self) -> bool {
        (**self).inject_nan()
    }
    fn memory(&self) -> Vec<(&'static str, usize)> {
        (**self).memory()
    }
    fn mass_spring(&self) -> crate::sim::MassSpring {
        (**self).mass_spring()
    }
    fn awake_fraction(&self) -> f32 {
        (**self).awake_fraction()
    }
    fn stay_awake(&mut self) {
        (**self).stay_awake();
    }
    fn point(&self, i: u32) -> Option<Vec3> {
        (**self).point(i)
    }
    fn apply_point_forces(&mut self, forces: &[(u32, Vec3)]) {
        (**self).apply_point_forces(forces);
    }
}

/// An enum of a procedure's model types that is itself a [`TissueModel`], each method
/// forwarded to the variant: `World<M>` holds models of several kinds with no boxing, and a
/// coupling matches on the variants it joins.
///
/// ```ignore
/// tissue_models! {
///     pub enum SceneModel { Solid(SoftBody), Sheet(Sheet) }
/// }
/// ```
#[macro_export]
macro_rules! tissue_models {
    ($(#[$meta:meta])* $vis:vis enum $name:ident { $($variant:ident($ty:ty)),+ $(,)? }) => {
        $(#[$meta])*
        // A world holds a few models, each once: the enum's size costs nothing, and a box
        // would put an indirection on every access in a step.
        #[allow(clippy::large_enum_variant)]
        $vis enum $name {
            $($variant($ty)),+
        }

        impl $crate::sim::TissueModel for $name {
            fn name(&self) -> &str {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::name(m)),+ }
            }
            fn kind(&self) -> &'static str {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::kind(m)),+ }
            }
            fn sizes(&self) -> $crate::sim::ModelSizes {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::sizes(m)),+ }
            }
            fn step(
                &mut self,
                dt_s: f32,
                contacts: &[$crate::sim::Contact],
                out: &mut $crate::sim::ModelOutput,
            ) {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::step(m, dt_s, contacts, out)),+ }
            }
            fn cut(&mut self, stroke: &$crate::sim::CutStroke, out: &mut $crate::sim::ModelOutput) {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::cut(m, stroke, out)),+ }
            }
            fn collider(&self) -> $crate::sim::Collider<'_> {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::collider(m)),+ }
            }
            fn render_mesh(&mut self) -> $crate::sim::ModelSnapshot {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::render_mesh(m)),+ }
            }
            fn render_job(&mut self) -> $crate::sim::MeshJob {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::render_job(m)),+ }
            }
            fn checkpoint(&mut self) {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::checkpoint(m)),+ }
            }
            fn read_whole_after_step(&mut self) {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::read_whole_after_step(m)),+ }
            }
            fn checkpoint_follows(&mut self) {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::checkpoint_follows(m)),+ }
            }
            fn restore(&mut self) {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::restore(m)),+ }
            }
            fn state_is_finite(&self) -> bool {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::state_is_finite(m)),+ }
            }
            fn state_hash(&self) -> u64 {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::state_hash(m)),+ }
            }
            fn inject_nan(&mut self) -> bool {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::inject_nan(m)),+ }
            }
            fn memory(&self) -> Vec<(&'static str, usize)> {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::memory(m)),+ }
            }
            fn mass_spring(&self) -> $crate::sim::MassSpring {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::mass_spring(m)),+ }
            }
            fn awake_fraction(&self) -> f32 {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::awake_fraction(m)),+ }
            }
            fn stay_awake(&mut self) {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::stay_awake(m)),+ }
            }
            fn point(&self, i: u32) -> Option<glam::Vec3> {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::point(m, i)),+ }
            }
            fn apply_point_forces(&mut self, forces: &[(u32, glam::Vec3)]) {
                match self { $(Self::$variant(m) => <$ty as $crate::sim::TissueModel>::apply_point_forces(m, forces)),+ }
            }
        }
    };
}
