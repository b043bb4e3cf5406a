//! The cholecystectomy as the session, window and headset see every procedure: its registry
//! entry, its build from a scenario, and its score.

use super::procedure::{Cholecystectomy, Metrics, STEPS};
use super::scenario::{self, NAME, Scenario};
use super::scene::CholeScene;
use crate::procedures::{
    BuildError, MassSpring, ModelReport, Procedure, ProcedureInfo, TaskStatus, ToolInfo, ToolKind,
    Viewpoint,
};
use crate::scenario::InputError;
use crate::sim::Hand;
use crate::sim::{completion_share, time_efficiency, weighted_score};
use glam::Vec3;
use serde::Serialize;

/// The right hand's other instruments, in the order its primary button hands them over
/// after the hook.
const RIGHT_CYCLE: [ToolInfo; 3] = [
    ToolInfo {
        hand: Hand::Right,
        name: "clip applier",
        kind: ToolKind::Hook,
        full_scale_n: 2.0,
    },
    ToolInfo {
        hand: Hand::Right,
        name: "scissors",
        kind: ToolKind::Hook,
        full_scale_n: 2.0,
    },
    ToolInfo {
        hand: Hand::Right,
        name: "right grasper",
        kind: ToolKind::Grasper,
        full_scale_n: 2.0,
    },
];

/// The registry's entry.
pub const INFO: ProcedureInfo = ProcedureInfo {
    name: NAME,
    title: "Laparoscopic cholecystectomy (clips and cuts in Calot's triangle)",
    paper: "cholecystectomy.txt",
    scenario: include_str!("../../../assets/scenarios/cholecystectomy.toml"),
    demo_trace: include_str!("../../../assets/traces/cholecystectomy-demo.toml"),
    steps: &STEPS,
    tools: [
        ToolInfo {
            hand: Hand::Left,
            name: "grasper",
            kind: ToolKind::Grasper,
            // Retracting the fundus until the adhesions tear takes about 0.3 N.
            full_scale_n: 2.0,
        },
        ToolInfo {
            hand: Hand::Right,
            name: "hook",
            kind: ToolKind::Hook,
            full_scale_n: 2.0,
        },
    ],
    // The laparoscope through the umbilical port, looking up at Calot's triangle and the
    // gallbladder under the liver's edge, 10 cm away.
    view: Viewpoint {
        eye: Vec3::new(-0.01, -0.02, 0.1),
        target: Vec3::new(-0.015, 0.005, 0.0),
    },
    // In front of the field, pointing up and away from it.
    desk_park: [Vec3::new(0.03, -0.02, 0.06), Vec3::new(-0.05, -0.02, 0.06)],
    param_tables: scenario::PARAM_TABLES,
    assessment: include_str!("../../../assets/assessment/cholecystectomy.toml"),
    field: super::field::field,
    blank_metrics: || serde_json::to_value(Metrics::default()).unwrap_or_default(),
    plan: scenario::plan,
    build,
    options: crate::sim::Options {
        bench_all_awake_s: 1.0,
        // The paper's camera tool: the left device drives the laparoscope while its primary
        // button is held (the grasper waits where it was).
        scope_hand: Some(Hand::Left),
        swap: &RIGHT_CYCLE,
        ..crate::sim::Options::NONE
    },
};

fn build(file: &str, text: &str) -> Result<Box<dyn Procedure>, BuildError> {
    let s = Scenario::parse(file, text)?;
    Ok(Box::new(build_procedure(file, s)?))
}

/// The procedure for a checked scenario (`file` names it in errors): the anatomy generated,
/// the scene built and laid out.
pub fn build_procedure(file: &str, s: Scenario) -> Result<Cholecystectomy, InputError> {
    let anatomy = super::Anatomy::generate(&s.anatomy_with_surfaces(file)?)
        .map_err(|e| InputError::new(file, "anatomy", e.to_string()))?;
    let mut scene = CholeScene::new(anatomy, s.scene_params())
        .map_err(|e| InputError::new(file, "tissue", e.to_string()))?;
    scene.settle(s.solver.settle_s, SETTLE_SWEEPS, SETTLE_DAMPING_PER_S);
    Ok(Cholecystectomy::new(s, scene))
}

/// The settling's sweeps per 1 ms step and its damping, 1/s (documented at
/// [`CholeScene::settle`]).
pub const SETTLE_SWEEPS: u32 = 8;
pub const SETTLE_DAMPING_PER_S: f32 = 60.0;

/// Weight of the checklist done, of the speed and of the safety of the cuts, points.
const COMPLETION_POINTS: f32 = 60.0;
const EFFICIENCY_POINTS: f32 = 20.0;
const SAFETY_POINTS: f32 = 20.0;
/// Points taken off per error (a liver burn, a bile leak, a bleeding).
const ERROR_PENALTY: f32 = 10.0;

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScoreParts {
    /// Fraction of the checklist done.
    pub completion: f32,
    /// Target time / completion time, at most 1; zero until completed.
    pub efficiency: f32,
    /// Share of the vessel cuts made with two clips on the patient's side (0 before any).
    pub safe_cuts: f32,
    pub penalty: f32,
}

/// The score, 0-100: 60 x completion + 20 x efficiency + 20 x safe cuts, less 10 per error
/// (a flat score until the assessment trees of #12).
pub fn score(s: &Scenario, m: &Metrics) -> (f32, ScoreParts) {
    let cuts = &m.clips.cuts;
    let parts = ScoreParts {
        completion: completion_share(m.steps_done.len(), STEPS.len()),
        efficiency: time_efficiency(f64::from(s.task.target_time_s), m.completion_time_s),
        safe_cuts: if cuts.is_empty() {
            0.0
        } else {
            cuts.iter().filter(|c| c.error.is_none()).count() as f32 / cuts.len() as f32
        },
        penalty: ERROR_PENALTY * m.errors as f32,
    };
    let weighted = [
        (COMPLETION_POINTS, parts.completion),
        (EFFICIENCY_POINTS, parts.efficiency),
        (SAFETY_POINTS, parts.safe_cuts),
    ];
    (weighted_score(&weighted, parts.penalty), parts)
}

impl Procedure for Cholecystectomy {
    crate::procedure_basics!(INFO, report(errors: metrics.errors), models: [scene]);

    fn status(&self, near_m: f32) -> TaskStatus {
        let m = &self.metrics;
        let (score, _) = score(&self.scenario, m);
        let a = &self.scene.solver().adhesion;
        let liver = self
            .scene
            .touching(super::anatomy::body::LIVER, self.tool_tip(1), near_m)
            > 0;
        TaskStatus {
            steps_done: m.steps_done.clone(),
            completed: self.is_completed(),
            score,
            errors: m.errors,
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
        }
    }

    fn reactions(&self) -> [Vec3; 2] {
        Cholecystectomy::reactions(self)
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
        let report = |name: &str, kind: &str, vertices: usize, constraints: usize| ModelReport {
            name: name.to_string(),
            kind: kind.to_string(),
            vertices,
            triangles: 0,
            constraints,
            mass_spring: MassSpring::default(),
        };
        let chain_particles: usize = s.anatomy.vessels.iter().map(|v| v.chain.len()).sum();
        vec![
            report(
                "shape_matching",
                "shape_matching_clusters",
                organs,
                s.solver().shape.clusters(),
            ),
            report("vessels", "particle_chains", chain_particles, 0),
            ModelReport {
                triangles: s.anatomy.fascia_triangles.len(),
                ..report(
                    "fascia",
                    "xpbd_cloth",
                    s.anatomy.fascia.len(),
                    s.solver().cloth.edges() + s.solver().cloth.hinges(),
                )
            },
            report(
                "adhesion",
                "breakable_strands",
                s.solver().adhesion.strands() + s.solver().bonds.strands(),
                s.solver().adhesion.segments() + s.solver().bonds.segments(),
            ),
            // The particles the contacts test (not `vertices`: the totals would count them
            // twice).
            ModelReport {
                mass_spring: MassSpring {
                    nodes: Some(s.solver().contacts.members()),
                    ..MassSpring::default()
                },
                ..report("contacts", "particle_contacts_and_tools", 0, 0)
            },
        ]
    }

    fn model_times(&self) -> Vec<f64> {
        self.scene.times().to_vec()
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        let s = &self.scene;
        vec![
            ("particles", s.solver().particles.heap_bytes()),
            ("shape_matching", s.solver().shape.heap_bytes()),
            ("contacts", s.solver().contacts.heap_bytes()),
            ("fascia", s.solver().cloth.heap_bytes()),
            (
                "adhesion",
                s.solver().adhesion.heap_bytes() + s.solver().bonds.heap_bytes(),
            ),
        ]
    }

    fn state_hash(&self) -> u64 {
        Cholecystectomy::state_hash(self)
    }

    fn is_completed(&self) -> bool {
        Cholecystectomy::is_completed(self)
    }
}
