//! The rectum's models coupled in one step: the Cosserat rod (the bowel) and the four-layer
//! membrane around it, in one world (the rod in stage 0, the membrane in stage 1), the skin
//! that carries the membrane's layer 0 on the rod and the instruments (an L-hook and a
//! grasper, generalized cylinders) as the couplings between the stages
//! ([`super::coupling`]). This is the physics the `rectum` procedure steps; it knows no input
//! device, task or score.
//!
//! One step of `dt`:
//! 1. the grasper holds (or takes, or lets go of) the rectum's surface; the hook presses the
//!    rod's bounding spheres; the rod steps (stage 0);
//! 2. layer 0's targets are placed by the skin where the next membrane step needs them (the
//!    awake tiles and those beside them);
//! 3. the membrane's tiles near each instrument wake; the hook's cylinders are tested against
//!    every node of the awake tiles (the paper's two-step test) and push them by penalty
//!    forces scaled by each node's area; with the cut button held, the dissection-plane
//!    springs inside a sphere at the hook's end are cut (eqs 5-6);
//! 4. the membrane's load on layer 0 is handed to the rod for its next step, and the
//!    membrane advances in the explicit substeps its stability needs (stage 1).
//!
//! The hook's reaction is the sum of what the rod and the membrane do to it.

use super::anatomy::Anatomy;
use super::coupling::Joints;
use super::regions::{self, RegionId};
#[cfg(test)]
use crate::collision::Instrument;
use crate::models::cosserat::skinned::{RodModelError, SkinnedRod, SkinnedRodParams};
use crate::models::membrane::{
    ActivityParams, Integrator, LAYERS, LayerMaterial, Membrane, MembraneError, MembraneParams,
};
use crate::sim::{EventKind, ModelId, World};
use glam::{Quat, Vec3};

/// The membrane's tissues (documented choices; the paper gives no values):
/// - sheets (layer 0 on the bowel, layers 1-2 the visceral and parietal fasciae, layer 3 the
///   pelvic side): loose connective tissue, E = 5 kPa, 0.5 mm thick, 1000 kg/m^3. Dense
///   fascia is stiffer (MPa); at the paper's 0.25 mm spacing that would need 6 us explicit
///   steps (`docs/rectum.md`);
/// - links 1-2 and 3-4: mesorectal and presacral fat, E = 2 kPa (adipose tissue is 1-3 kPa in
///   indentation); links 2-3: the areolar tissue of the dissection plane, E = 1 kPa;
/// - damping: half of critical along the springs and 20/s at the nodes (tissue is strongly
///   damped); attachments 1e7 Pa/m (the pelvic wall is muscle on bone: 400 Pa of shear from
///   the fat moves it 40 um); eq 5's residual strain 0.1 (the paper's);
/// - no gravity: the anatomy is generated as it lies, carried by the body, and a sheet of
///   0.5 kg/m^2 on 2 kPa of fat 10 mm thick would sag 25 um, below what the active set
///   resolves (its wake distance is 0.2 mm), but enough to keep tiles from sleeping.
pub fn membrane_params() -> MembraneParams {
    let sheet = LayerMaterial {
        youngs_modulus_pa: 5e3,
        thickness_m: 5e-4,
        density_kg_per_m3: 1000.0,
    };
    MembraneParams {
        layers: [sheet; LAYERS],
        link_modulus_pa: [2e3, 1e3, 2e3],
        damping_per_s: 20.0,
        spring_damping_ratio: 0.5,
        link_damping_ratio: 0.5,
        attach_pa_per_m: 1e7,
        residual_strain: 0.1,
        gravity: Vec3::ZERO,
        integrator: Integrator::Symplectic,
    }
}

/// The scene's figures.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneParams {
    pub membrane: MembraneParams,
    pub rod: SkinnedRodParams,
    pub activity: ActivityParams,
    /// The hook's penalty on membrane nodes, per unit of their area, Pa/m.
    pub hook_stiffness_pa_per_m: f32,
    /// Radius of the sphere at the hook's end whose plane springs a cut removes, m.
    pub cut_radius_m: f32,
    /// Explicit substeps at this fraction of the stability limit.
    pub substep_safety: f32,
    /// The part of each instrument that wakes tissue: this far up from its working end, m.
    pub wake_reach_m: f32,
    /// The dissection target: its rows as fractions of the section's length from the top,
    /// and its arc in degrees from the front towards +z ([`regions::Region`]).
    pub target_rows: (f32, f32),
    pub target_arc_deg: (f32, f32),
    /// How near the hook's end a vulnerable structure counts as near, m (the nearest one is
    /// looked for this far).
    pub near_m: f32,
}

impl Default for SceneParams {
    fn default() -> Self {
        SceneParams {
            membrane: membrane_params(),
            // The rectum as generated lies where the body holds it: its weight is carried by
            // the mesorectum and the pelvic floor (the membrane's sleeping tiles, which load
            // the rod with nothing), so the rod is weightless here rather than sagging
            // between its clamps.
            rod: SkinnedRodParams {
                gravity_m_per_s2: glam::DVec3::ZERO,
                ..SkinnedRodParams::default()
            },
            activity: ActivityParams::default(),
            hook_stiffness_pa_per_m: 1e6,
            cut_radius_m: 1.5e-3,
            // The bound (stiffness and damping, Gershgorin's) is the grid's at rest; the
            // springs stretched under a grasp are no stiffer along and softer across.
            substep_safety: 0.9,
            wake_reach_m: 0.03,
            target_rows: regions::REGIONS[0].rows,
            target_arc_deg: regions::REGIONS[0].arc_deg,
            near_m: 0.005,
        }
    }
}

/// Why the scene could not be built.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("rectum: {0}")]
    Rod(#[from] RodModelError),
    #[error("membrane: {0}")]
    Membrane(#[from] MembraneError),
    #[error("the membrane's GPU: {0}")]
    Gpu(#[from] crate::gpu::RenderError),
}

/// Where the instruments are this step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToolState {
    /// The L-hook's corner (where the hook leaves the shaft) and orientation (forward -Z, the
    /// hook along +Y).
    pub hook: Option<(Vec3, Quat)>,
    /// The cut button (the hook's current) is held.
    pub cutting: bool,
    /// The left grasper's jaw point and orientation, and whether it is closed.
    pub grasper: Option<(Vec3, Quat, bool)>,
    /// The right hand's grasper when it holds one instead of the hook (the paper's test has
    /// two graspers and a hook): jaw point, orientation, closed.
    pub grasper_right: Option<(Vec3, Quat, bool)>,
}

/// What a step did.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepOutcome {
    /// Force of the tissue on the hook, on the left grasper and on the right one, N.
    pub hook_n: Vec3,
    pub grasper_n: Vec3,
    pub grasper_right_n: Vec3,
    /// Plane springs cut this step, and of them those inside the target.
    pub cut: u32,
    pub cut_in_target: u32,
    /// Membrane nodes the hook touches.
    pub hook_contacts: usize,
    /// Explicit membrane substeps taken.
    pub substeps: usize,
    /// The membrane's load on the rod through layer 0 (awake tiles) in this step: what the
    /// membrane summed at the start of its last step, N.
    pub membrane_on_rod_n: Vec3,
    /// Vulnerable regions the hook touches now: bit `id` for region id `id`
    /// ([`regions::REGIONS`]).
    pub touching: u32,
    /// The hook touches the rectal wall (layer 0).
    pub on_wall: bool,
    /// The vulnerable region nearest the hook's end among the awake nodes, and its distance, m.
    pub near_vulnerable: Option<(RegionId, f32)>,
    /// Alarms raised this step: bit `id` for a vulnerable region the hook has just touched,
    /// [`ALARM_RECTAL_WALL`] when the hook cuts with the rectum's wall (layer 0) under it.
    pub alarms: u32,
}

/// Alarm bit: the hook's current is on while it touches the rectum's wall (a perforation).
pub const ALARM_RECTAL_WALL: u32 = 1 << 7;

crate::tissue_models! {
    /// The rectum's models: the rod (stage 0) and the membrane (stage 1).
    pub enum RectumModel {
        Rod(SkinnedRod),
        Membrane(Membrane),
    }
}

/// The rod's and the membrane's places in the scene's world.
pub const ROD: ModelId = ModelId(0);
pub const MEMBRANE: ModelId = ModelId(1);

/// The rod and the membrane in one world, and the skin between them (the couplings).
pub struct RectumScene {
    pub params: SceneParams,
    world: World<RectumModel>,
    joints: Joints,
}

impl RectumScene {
    /// Builds the scene on the anatomy, the membrane at rest with its active set on.
    pub fn new(anatomy: &Anatomy, params: SceneParams) -> Result<RectumScene, SceneError> {
        let axis: Vec<Vec3> = anatomy.axis.iter().map(|f| f.point).collect();
        let rod = SkinnedRod::new(&axis, &anatomy.rectum, params.rod)?.with_name("rectum");
        let mut membrane = Membrane::new(anatomy.membrane.clone(), params.membrane)?;
        membrane.use_active_set(params.activity);
        membrane.set_substep_safety(params.substep_safety);
        let joints = Joints::new(anatomy, &rod, &mut membrane, params)?;
        let mut world = World::new();
        let rod_id = world.add_to(0, RectumModel::Rod(rod));
        let membrane_id = world.add_to(1, RectumModel::Membrane(membrane));
        debug_assert_eq!((rod_id, membrane_id), (ROD, MEMBRANE));
        Ok(RectumScene {
            params,
            world,
            joints,
        })
    }

    /// The rod.
    pub fn rod(&self) -> &SkinnedRod {
        match self.world.model(ROD) {
            RectumModel::Rod(r) => r,
            RectumModel::Membrane(_) => unreachable!("model 0 is the rod"),
        }
    }

    pub fn rod_mut(&mut self) -> &mut SkinnedRod {
        match self.world.model_mut(ROD) {
            RectumModel::Rod(r) => r,
            RectumModel::Membrane(_) => unreachable!("model 0 is the rod"),
        }
    }

    /// The membrane.
    pub fn membrane(&self) -> &Membrane {
        match self.world.model(MEMBRANE) {
            RectumModel::Membrane(m) => m,
            RectumModel::Rod(_) => unreachable!("model 1 is the membrane"),
        }
    }

    pub fn membrane_mut(&mut self) -> &mut Membrane {
        match self.world.model_mut(MEMBRANE) {
            RectumModel::Membrane(m) => m,
            RectumModel::Rod(_) => unreachable!("model 1 is the membrane"),
        }
    }

    /// The world the rod and the membrane step in (the procedure's model figures).
    pub fn world(&self) -> &World<RectumModel> {
        &self.world
    }

    pub fn world_mut(&mut self) -> &mut World<RectumModel> {
        &mut self.world
    }

    /// Every node where the rod carries it now (before drawing the whole membrane).
    pub fn place_everything(&mut self) {
        let mut models = self.world.coupled();
        if let (Some(RectumModel::Membrane(m)), Some(RectumModel::Rod(r))) =
            models.write_read(MEMBRANE, ROD)
        {
            Joints::pose_targets(r, m);
            m.place_all_targets();
            m.place_sleeping();
        }
    }

    /// One step of `dt_s` (step number `step`); the world's events (a quarantined model)
    /// go to `events`.
    pub fn step(
        &mut self,
        dt_s: f32,
        tools: &ToolState,
        step: u64,
        events: &mut Vec<EventKind>,
    ) -> StepOutcome {
        self.joints.begin(*tools);
        self.world
            .step_coupled(dt_s, step, events, &mut self.joints);
        let mut out = self.joints.out;
        // What the rod's grasps hold back.
        let [left, right] = self.world.reactions_from(ROD);
        out.grasper_n = left;
        if tools.grasper_right.is_some() {
            out.grasper_right_n = right;
        }
        out.substeps = if self.world.is_frozen(MEMBRANE) {
            0
        } else {
            self.membrane().last_substeps()
        };
        out
    }

    /// Wall-clock seconds in the rod, the couplings (the instruments' collision with the
    /// membrane, the skin) and the membrane (benchmarks only).
    pub fn times(&self) -> [f64; 3] {
        let t = self.world.model_times();
        [t[0], self.world.coupling_time(), t[1]]
    }

    /// Layer `l`'s nodes over the top (column 0, the front) of the section's middle row,
    /// `2 half + 1` rows by `2 half + 1` columns (for loads in tests and reference cases).
    pub fn top_patch(&self, l: usize, half: usize) -> Vec<usize> {
        let m = self.membrane();
        let (rows, cols) = (m.rows(), m.cols());
        let mid = rows / 2;
        let (lo, hi) = (mid.saturating_sub(half), (mid + half).min(rows - 1));
        (lo..=hi)
            .flat_map(|i| (0..=2 * half).map(move |k| (i, (k + cols - half % cols) % cols)))
            .map(|(i, j)| m.node(l, i, j))
            .collect()
    }

    /// Plane springs in the target region, and of them cut so far.
    pub fn target_progress(&self) -> (u32, u32) {
        (self.joints.target_cut, self.joints.target_links)
    }

    /// The grid cells (`i * cols + j`) whose plane springs the last step cut.
    pub fn last_cut(&self) -> &[u32] {
        &self.joints.last_cut
    }

    /// The region of membrane node `node` (0: none).
    pub fn region_of(&self, node: usize) -> RegionId {
        self.joints.regions.get(node).copied().unwrap_or(0)
    }

    /// Where the skin binds layer 0's node `node` on the rod: (element, share along it,
    /// angle) (tests).
    #[cfg(test)]
    pub fn skin_binding(&self, node: usize) -> Option<(usize, f32, Vec3)> {
        self.joints.skin.binding(node)
    }

    /// The hook pressed on the membrane now, outside a step (tests): the reaction, N.
    #[cfg(test)]
    pub fn press_membrane(&mut self, hook: &Instrument) -> Vec3 {
        let RectumModel::Membrane(m) = self.world.model_mut(MEMBRANE) else {
            return Vec3::ZERO;
        };
        self.joints.press_membrane(m, hook)
    }
}

#[cfg(test)]
#[path = "scene_gpu_tests.rs"]
mod gpu_tests;
#[cfg(test)]
#[path = "scene_tests.rs"]
mod tests;
