//! The cholecystectomy as the session, window and headset see every procedure: its registry
//! entry, its build from a scenario, and its score.

use super::field;
use super::procedure::{Cholecystectomy, Metrics, STEPS};
use super::scenario::{self, NAME, Scenario};
use super::scene::CholeScene;
use crate::procedures::{ModelReport, Procedure, ProcedureInfo, TaskStatus};
use crate::scenario::InputError;
use crate::sim::{ChecklistScore, Hand, ToolInfo, ToolKind};
use glam::Vec3;

/// The right hand's other instruments, in the order its primary button hands them over
/// after the hook.
const RIGHT_CYCLE: [ToolInfo; 3] = [
    ToolInfo::right("clip applier", ToolKind::Hook, 2.0),
    ToolInfo::right("scissors", ToolKind::Hook, 2.0),
    ToolInfo::right("right grasper", ToolKind::Grasper, 2.0),
];

/// The registry's entry.
pub const INFO: ProcedureInfo = crate::procedure_info! {
    stem: "cholecystectomy", paper: "cholecystectomy.txt",
    title: "Laparoscopic cholecystectomy (clips and cuts in Calot's triangle)",
    build: |file, s| build_procedure(file, s)?,
    // Retracting the fundus until the adhesions tear takes about 0.3 N.
    tools: [("grasper", Grasper, 2.0), ("hook", Hook, 2.0)],
    // The laparoscope through the umbilical port, looking up at Calot's triangle and the
    // gallbladder under the liver's edge, 10 cm away.
    view: (-0.01, -0.02, 0.1) -> (-0.015, 0.005, 0.0),
    // In front of the field, pointing up and away from it.
    desk_park: [(0.03, -0.02, 0.06), (-0.05, -0.02, 0.06)],
    // The paper's camera tool: the left device drives the laparoscope while its primary
    // button is held (the grasper waits where it was).
    scope_hand: Some(Hand::Left),
    swap: &RIGHT_CYCLE,
    cpu_preset: Some(include_str!("../../../assets/presets/cpu/cholecystectomy.toml")),
    gpu_bench: Some(super::gpu_bench::lines),
    preset_cases: super::cases::preset_cases,
};

/// The procedure for a checked scenario (`file` names it in errors): the anatomy generated,
/// the scene built and laid out.
pub fn build_procedure(file: &str, s: Scenario) -> Result<Cholecystectomy, InputError> {
    let anatomy = super::Anatomy::generate(&s.anatomy_with_surfaces(file)?)
        .map_err(|e| InputError::new(file, "anatomy", e.to_string()))?;
    let mut scene = CholeScene::new(anatomy, s.scene_params())
        .map_err(|e| InputError::new(file, "tissue", e.to_string()))?;
    scene.settle(s.solver.settle_s, SETTLE_SWEEPS, SETTLE_DAMPING_PER_S);
    let compute = |e: crate::gpu::RenderError| InputError::new(file, "compute", e.to_string());
    if let Some(gpu) = crate::gpu::Gpu::for_compute(s.compute).map_err(compute)? {
        match scene.solver_mut().use_gpu(&gpu) {
            Ok(()) => {}
            // `auto` stays on the CPU where the device refuses the particles.
            Err(e) if s.compute == crate::scenario::Compute::Auto => {
                tracing::warn!("compute auto: the particles stay on the CPU ({e})");
            }
            Err(e) => return Err(compute(e)),
        }
    }
    Ok(Cholecystectomy::new(s, scene))
}

/// The settling's sweeps per 1 ms step and its damping, 1/s (documented at
/// [`CholeScene::settle`]).
pub const SETTLE_SWEEPS: u32 = 8;
pub const SETTLE_DAMPING_PER_S: f32 = 60.0;

impl Procedure for Cholecystectomy {
    crate::procedure_basics!(INFO, report(errors: metrics.errors), models: [scene]);

    fn instrument_tips(&self) -> Option<[Vec3; 2]> {
        Some([self.tool_tip(0), self.tool_tip(1)])
    }

    fn contacts_now(&self) -> [Option<(Vec3, Vec3)>; 2] {
        let r = Cholecystectomy::reactions(self);
        let at = |k: usize| {
            (r[k].length() > 0.0).then(|| (self.tool_tip(k), -r[k].normalize_or(Vec3::Y)))
        };
        [at(0), at(1)]
    }

    fn model_reports(&self) -> Vec<ModelReport> {
        let s = &self.scene;
        let organs = s.anatomy.organ_particles();
        let chain_particles: usize = s.anatomy.vessels.iter().map(|v| v.chain.len()).sum();
        let solver = s.solver();
        vec![
            ModelReport::new(
                "shape_matching",
                "shape_matching_clusters",
                organs,
                solver.shape.clusters(),
            ),
            ModelReport::new("vessels", "particle_chains", chain_particles, 0),
            ModelReport::new(
                "fascia",
                "xpbd_cloth",
                s.anatomy.fascia.len(),
                solver.cloth.edges() + solver.cloth.hinges(),
            )
            .with_triangles(s.anatomy.fascia_triangles.len()),
            ModelReport::new(
                "adhesion",
                "breakable_strands",
                solver.adhesion.strands() + solver.bonds.strands(),
                solver.adhesion.segments() + solver.bonds.segments(),
            ),
            // The particles the contacts test (not `vertices`: the totals would count them
            // twice).
            ModelReport::new("contacts", "particle_contacts_and_tools", 0, 0)
                .with_nodes(solver.contacts.members()),
        ]
        .into_iter()
        // One solver steps every part: all on its device, or all on the CPU.
        .map(|m| m.on_gpu(solver.gpu_adapter()))
        .collect()
    }

    fn model_times(&self) -> Vec<f64> {
        self.scene.times().to_vec()
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        let solver = self.scene.solver();
        vec![
            ("particles", solver.particles.heap_bytes()),
            ("shape_matching", solver.shape.heap_bytes()),
            ("contacts", solver.contacts.heap_bytes()),
            ("fascia", solver.cloth.heap_bytes()),
            (
                "adhesion",
                solver.adhesion.heap_bytes() + solver.bonds.heap_bytes(),
            ),
        ]
    }
}

/// Points taken off per error (a liver burn, a bile leak, a bleeding).
const ERROR_PENALTY: f32 = 10.0;

/// The score, 0-100: 60 x completion + 20 x efficiency + 20 x safe cuts (the share of the
/// vessel cuts made with two clips on the patient's side, 0 before any), less 10 per error
/// (a flat score until the assessment trees of #12).
pub fn score(s: &Scenario, m: &Metrics) -> (f32, ChecklistScore) {
    let time = (f64::from(s.task.target_time_s), m.completion_time_s);
    let penalty = ERROR_PENALTY * m.errors as f32;
    let cuts = &m.clips.cuts;
    let safe = cuts.iter().filter(|c| c.error.is_none()).count();
    let safe_cuts = ("safe_cuts", safe as f32 / cuts.len().max(1) as f32);
    ChecklistScore::new(&m.steps_done, &STEPS, time, safe_cuts, penalty).scored()
}

impl Cholecystectomy {
    /// The panel's live part: the paths, the right hand's instrument, Calot's triangle
    /// exposed, the clips, the adhesions, the right force, and whether the right instrument
    /// touches the liver (within `near_m`).
    fn panel(&self, near_m: f32) -> TaskStatus {
        let m = &self.metrics;
        let a = &self.scene.solver().adhesion;
        let liver = self
            .scene
            .touching(super::anatomy::body::LIVER, self.tool_tip(1), near_m)
            > 0;
        TaskStatus {
            path_m: [m.path_length_left_m, m.path_length_right_m],
            figures: vec![
                (
                    "right hand".to_string(),
                    self.right_tool().name().to_string(),
                ),
                (
                    "Calot exposed".to_string(),
                    format!("{:.0} %", 100.0 * m.calot_exposure),
                ),
                (
                    "clips".to_string(),
                    format!(
                        "duct {}, artery {}",
                        m.clips.clips_on("cystic_duct"),
                        m.clips.clips_on("cystic_artery")
                    ),
                ),
                (
                    "adhesions".to_string(),
                    format!("{} of {} intact", a.intact_strands(), a.strands()),
                ),
                (
                    "right force".to_string(),
                    format!("{:.2} N", self.reactions()[1].length()),
                ),
            ],
            touching: [false, liver],
            near: [None, liver.then(|| ("liver".to_string(), 0.0))],
            ..TaskStatus::default()
        }
    }
}
