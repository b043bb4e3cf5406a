use super::EventKind;
use crate::models::SimplexMesh;
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

/// What collision and rendering read of a model's surface.
pub struct SurfaceView<'a> {
    pub mesh: &'a SimplexMesh,
    /// Simplex vertex positions, metres.
    pub positions: &'a [Vec3],
    pub normals: &'a [Vec3],
    /// Faces (= simplex vertices) still present.
    pub alive: &'a [bool],
    /// Region index per face (names are the model's).
    pub regions: &'a [u8],
    /// BVH over patches of faces, refit every step.
    pub bvh: &'a crate::collision::FaceBvh,
}

impl SurfaceView<'_> {
    /// The render triangle of face `f`, positions mapped from the simplex mesh.
    pub fn triangle(&self, f: u32) -> [Vec3; 3] {
        self.mesh.corners[f as usize].map(|r| {
            self.mesh
                .render_position(r as usize, self.positions, self.normals)
        })
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
    fn surface(&self) -> SurfaceView<'_>;
    /// Render positions, normals and live triangles for a snapshot.
    fn render_mesh(&mut self) -> crate::sim::ModelSnapshot;
    /// Saves the current state as the last good one.
    fn checkpoint(&mut self);
    /// Returns to the last checkpoint.
    fn restore(&mut self);
    /// Whether every state value changed since the last check is finite.
    fn state_is_finite(&self) -> bool;
    /// A deterministic digest of the state, for replay and determinism checks.
    fn state_hash(&self) -> u64;
}
