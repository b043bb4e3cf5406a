//! The rectum as the session, window and headset see every procedure: its registry entry,
//! its build from a scenario, and its score.

use super::procedure::{Metrics, Rectum, STEPS};
use super::scenario::{self, NAME, Scenario};
use crate::procedures::{
    BuildError, MassSpring, ModelReport, Procedure, ProcedureInfo, TaskStatus, ToolInfo, ToolKind,
    Viewpoint,
};
use crate::scenario::InputError;
use crate::sim::{Hand, TissueModel};
use crate::sim::{completion_share, time_efficiency, weighted_score};
use glam::Vec3;
use serde::Serialize;

/// The registry's entry.
pub const INFO: ProcedureInfo = ProcedureInfo {
    name: NAME,
    title: "Laparoscopic rectum dissection (total mesorectal excision drill)",
    paper: "rectum-dissection.txt",
    scenario: include_str!("../../../assets/scenarios/rectum.toml"),
    demo_trace: include_str!("../../../assets/traces/rectum-demo.toml"),
    steps: &STEPS,
    tools: [
        ToolInfo {
            hand: Hand::Left,
            name: "grasper",
            kind: ToolKind::Grasper,
            // Lifting the mid section 9 mm takes about 5 N (the rod's documented stiffness).
            full_scale_n: 5.0,
        },
        ToolInfo {
            hand: Hand::Right,
            name: "hook",
            kind: ToolKind::Hook,
            // The membrane is soft (millinewtons press it in); the full scale is the force
            // that pushing the rectum itself with the shaft takes, where alarms belong.
            full_scale_n: 3.0,
        },
    ],
    // In front of and above the section's middle, on the line the anterior fascia faces
    // (the bowel's axis runs along +x and curves down with the sacrum), 12 cm away.
    view: Viewpoint {
        eye: Vec3::new(0.16, 0.10, 0.07),
        target: Vec3::new(0.085, 0.0, 0.0),
    },
    // Over the anterior field, out of the tissue, pointing down.
    desk_park: [Vec3::new(0.05, 0.06, 0.03), Vec3::new(0.1, 0.06, 0.03)],
    param_tables: scenario::PARAM_TABLES,
    assessment: include_str!("../../../assets/assessment/rectum.toml"),
    field: super::field::field,
    blank_metrics: || serde_json::to_value(Metrics::default()).unwrap_or_default(),
    plan: scenario::plan,
    build,
    options: crate::sim::Options {
        // 20 steps: each all-awake step is some 40 explicit steps of all 960,000 nodes.
        bench_all_awake_s: 0.02,
        // The paper: "The left haptic device can also be used as a navigation camera".
        scope_hand: Some(Hand::Left),
        // The paper's test: one L-hook and two graspers; the right hand changes between them.
        swap: &[ToolInfo {
            hand: Hand::Right,
            name: "right grasper",
            kind: ToolKind::Grasper,
            full_scale_n: 5.0,
        }],
        cases: super::cases::cases,
        ..crate::sim::Options::NONE
    },
};

fn build(file: &str, text: &str) -> Result<Box<dyn Procedure>, BuildError> {
    let s = Scenario::parse(file, text)?;
    let anatomy = super::Anatomy::generate(s.anatomy_params())
        .map_err(|e| InputError::new(file, "anatomy", e.to_string()))?;
    let r =
        Rectum::new(s, &anatomy).map_err(|e| InputError::new(file, "membrane", e.to_string()))?;
    Ok(Box::new(r))
}

/// Weight of the checklist done, of the speed and of the share of correct cuts, points.
const COMPLETION_POINTS: f32 = 60.0;
const EFFICIENCY_POINTS: f32 = 20.0;
const PRECISION_POINTS: f32 = 20.0;
/// Points taken off per alarm (a vulnerable structure touched, the wall cut).
const ALARM_PENALTY: f32 = 10.0;

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScoreParts {
    /// Fraction of the checklist done.
    pub completion: f32,
    /// Target time / completion time, at most 1; zero until completed.
    pub efficiency: f32,
    /// Plane springs cut in the target over all cut.
    pub precision: f32,
    /// Points taken off for alarms.
    pub penalty: f32,
}

/// The score, 0-100: 60 x completion + 20 x efficiency + 20 x precision, less 10 per alarm.
/// A flat score until the hierarchy of Table 1 with its weights and fuzzy levels (#12).
pub fn score(s: &Scenario, m: &Metrics) -> (f32, ScoreParts) {
    let parts = ScoreParts {
        completion: completion_share(m.steps_done.len(), STEPS.len()),
        efficiency: time_efficiency(f64::from(s.task.target_time_s), m.completion_time_s),
        precision: m.correct_cut_ratio,
        penalty: ALARM_PENALTY * m.alarms as f32,
    };
    let weighted = [
        (COMPLETION_POINTS, parts.completion),
        (EFFICIENCY_POINTS, parts.efficiency),
        (PRECISION_POINTS, parts.precision),
    ];
    (weighted_score(&weighted, parts.penalty), parts)
}

impl Procedure for Rectum {
    crate::procedure_basics!(INFO, report(errors: metrics.alarms), models: [scene]);

    fn status(&self, near_m: f32) -> TaskStatus {
        let m = &self.metrics;
        let (score, _) = score(&self.scenario, m);
        let (cut, total) = self.scene.target_progress();
        let near = self.near_now().filter(|(_, d)| *d <= near_m);
        TaskStatus {
            steps_done: m.steps_done.clone(),
            completed: self.is_completed(),
            score,
            errors: m.alarms,
            path_m: [m.path_length_left_m, m.path_length_right_m],
            figures: vec![
                ("plane cut".to_string(), format!("{cut} of {total} springs")),
                (
                    format!("{} force", self.right_name()),
                    format!("{:.2} N", self.reactions()[1].length()),
                ),
                (
                    "correct cuts".to_string(),
                    format!("{:.0} %", 100.0 * m.correct_cut_ratio),
                ),
                ("right hand".to_string(), self.right_name().to_string()),
            ],
            touching: [false, self.touching_now()],
            near: [None, near.map(|(n, d)| (n.to_string(), d))],
        }
    }

    fn reactions(&self) -> [Vec3; 2] {
        Rectum::reactions(self)
    }

    fn contacts_now(&self) -> [Option<(Vec3, Vec3)>; 2] {
        let [grasper, hook] = Rectum::reactions(self);
        let at = |k: usize, f: Vec3| (f.length() > 0.0).then(|| (self.tool_tip(k), -f.normalize()));
        [at(0, grasper), at(1, hook)]
    }

    fn model_reports(&self) -> Vec<ModelReport> {
        let rod = self.scene.rod();
        let m = self.scene.membrane();
        vec![
            ModelReport {
                name: "rectum".to_string(),
                kind: TissueModel::kind(rod).to_string(),
                vertices: rod.surface().positions.len(),
                triangles: rod.surface().triangles.len(),
                constraints: rod.params().elements,
                mass_spring: MassSpring {
                    nodes: Some(rod.params().elements + 1),
                    ..MassSpring::default()
                },
            },
            ModelReport {
                name: "membrane".to_string(),
                kind: "mass_spring_4_layer".to_string(),
                vertices: m.len(),
                triangles: 0,
                constraints: m.springs(),
                mass_spring: MassSpring {
                    nodes: Some(m.len()),
                    springs: Some(m.springs()),
                    integrator: Some(self.scene.params.membrane.integrator.name()),
                },
            },
            ModelReport {
                // The membrane's nodes it tests, as `nodes` (not `vertices`: the procedure's
                // totals would count them twice).
                name: "collision".to_string(),
                kind: "generalized_cylinders".to_string(),
                vertices: 0,
                triangles: 0,
                constraints: 0,
                mass_spring: MassSpring {
                    nodes: Some(m.len()),
                    ..MassSpring::default()
                },
            },
        ]
    }

    /// The world's (the rod, the membrane), then the couplings' as the collision's.
    fn model_times(&self) -> Vec<f64> {
        let [rod, collision, membrane] = self.scene.times();
        vec![rod, membrane, collision]
    }

    /// The collision works on the membrane's awake tiles.
    fn awake_fractions(&self) -> Vec<f64> {
        let mut a = self.scene.world().awake_fractions();
        a.push(a[1]);
        a
    }

    fn state_hash(&self) -> u64 {
        Rectum::state_hash(self)
    }

    fn is_completed(&self) -> bool {
        Rectum::is_completed(self)
    }
}
