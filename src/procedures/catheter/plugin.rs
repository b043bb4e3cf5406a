//! The catheterisation as the session, window and headset see every procedure: its registry
//! entry, its build from a scenario, its score and its own benchmark lines.

use super::procedure::{Catheterisation, Metrics, STEPS};
use super::scenario::{self, NAME, Scenario};
use crate::models::skeleton::catheter::Catheter;
use crate::models::skeleton::in_vessel::CatheterInVessel;
use crate::models::skeleton::vessel::Vessel;
use crate::procedures::{
    BuildError, MassSpring, ModelReport, Procedure, ProcedureInfo, TaskStatus, ToolInfo, ToolKind,
    Viewpoint,
};
use crate::sim::Hand;
use crate::sim::{completion_share, time_efficiency, weighted_score};
use glam::{DVec3, Vec3};
use serde::Serialize;

/// The registry's entry.
pub const INFO: ProcedureInfo = ProcedureInfo {
    name: NAME,
    title: "Interventional catheterisation (a bifurcating vessel)",
    paper: "interventional-catheter.txt",
    scenario: include_str!("../../../assets/scenarios/catheter.toml"),
    demo_trace: include_str!("../../../assets/traces/catheter-demo.toml"),
    steps: &STEPS,
    tools: [
        ToolInfo {
            hand: Hand::Left,
            name: "introducer",
            kind: ToolKind::Probe,
            full_scale_n: 9.0,
        },
        ToolInfo {
            hand: Hand::Right,
            name: "catheter",
            kind: ToolKind::Steerable,
            // The Novint Falcon's largest force.
            full_scale_n: 9.0,
        },
    ],
    // The paper's view: the vessel from the side (+z), the bifurcation in the middle.
    view: Viewpoint {
        eye: Vec3::new(0.055, 0.0, 0.16),
        target: Vec3::new(0.055, 0.0, 0.0),
    },
    // The handle's hand at the catheter's end, the other aside.
    desk_park: [Vec3::new(-0.05, -0.04, 0.03), Vec3::new(-0.1, 0.0, 0.0)],
    param_tables: scenario::PARAM_TABLES,
    assessment: include_str!("../../../assets/assessment/catheter.toml"),
    field: super::field::field,
    blank_metrics: || serde_json::to_value(Metrics::default()).unwrap_or_default(),
    plan: scenario::plan,
    build,
    options: crate::sim::Options {
        bench_all_awake_s: 1.0,
        // The paper's Novint Falcon (9 N, 1 kHz).
        haptic_device: crate::sim::DeviceChoice::Falcon,
        bench_extra: Some(super::bench::extra),
        ..crate::sim::Options::NONE
    },
};

fn build(file: &str, text: &str) -> Result<Box<dyn Procedure>, BuildError> {
    let s = Scenario::parse(file, text)?;
    Ok(Box::new(build_procedure(s)))
}

/// The scene for a checked scenario: the vessel, the catheter straight in its introducer
/// with its tip at the inlet, pointing along the trunk.
pub fn build_scene(s: &Scenario) -> CatheterInVessel {
    let vessel = Vessel::new(&s.vessel_params());
    let catheter = Catheter::new(&s.catheter_params(), DVec3::ZERO, DVec3::X);
    CatheterInVessel::new(
        catheter,
        vessel,
        s.law(),
        s.contact.puncture_n,
        s.catheter.substeps,
    )
}

/// The procedure for a checked scenario.
pub fn build_procedure(s: Scenario) -> Catheterisation {
    let scene = build_scene(&s);
    Catheterisation::new(s, scene)
}

/// Weight of the checklist done, of the speed and of a light touch, points.
const COMPLETION_POINTS: f32 = 60.0;
const EFFICIENCY_POINTS: f32 = 20.0;
const GENTLENESS_POINTS: f32 = 20.0;
/// Points taken off per puncture and per entry into the wrong branch.
const PUNCTURE_PENALTY: f32 = 30.0;
const WRONG_BRANCH_PENALTY: f32 = 5.0;

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScoreParts {
    /// Fraction of the checklist done.
    pub completion: f32,
    /// Target time / completion time, at most 1; zero until completed.
    pub efficiency: f32,
    /// 1 while the largest force stays within the paper's 3.5 N, falling to 0 at the device's
    /// largest.
    pub gentleness: f32,
    pub penalty: f32,
}

/// The score, 0-100: 60 x completion + 20 x efficiency + 20 x gentleness, less 30 per
/// puncture and 5 per wrong branch (a flat score until the assessment trees of #12).
pub fn score(s: &Scenario, m: &Metrics) -> (f32, ScoreParts) {
    let most = s.device.max_force_n.max(3.5 + 1e-9);
    let parts = ScoreParts {
        completion: completion_share(m.steps_done.len(), STEPS.len()),
        efficiency: time_efficiency(s.task.target_time_s, m.completion_time_s),
        gentleness: (1.0 - ((m.peak_force_n - 3.5) / (most - 3.5)).clamp(0.0, 1.0)) as f32,
        penalty: PUNCTURE_PENALTY * m.punctures as f32
            + WRONG_BRANCH_PENALTY * m.wrong_branch as f32,
    };
    let weighted = [
        (COMPLETION_POINTS, parts.completion),
        (EFFICIENCY_POINTS, parts.efficiency),
        (GENTLENESS_POINTS, parts.gentleness),
    ];
    (weighted_score(&weighted, parts.penalty), parts)
}

impl Procedure for Catheterisation {
    crate::procedure_basics!(INFO, report(errors: metrics.errors), models: [scene]);

    fn status(&self, _near_m: f32) -> TaskStatus {
        let m = &self.metrics;
        let (score, _) = score(&self.scenario, m);
        TaskStatus {
            steps_done: m.steps_done.clone(),
            completed: self.is_completed(),
            score,
            errors: m.errors,
            path_m: [0.0, m.handle_path_m as f32],
            figures: vec![
                (
                    "force".to_string(),
                    format!("{:.2} N", self.reaction().length()),
                ),
                ("peak force".to_string(), format!("{:.2} N", m.peak_force_n)),
                ("wall contacts".to_string(), m.wall_contacts.to_string()),
                (
                    "into the branch".to_string(),
                    format!("{:.0} mm", 1e3 * m.reach_m),
                ),
            ],
            touching: [false; 2],
            near: [None, None],
        }
    }

    fn reactions(&self) -> [Vec3; 2] {
        [Vec3::ZERO, self.reaction().as_vec3()]
    }

    fn contacts_now(&self) -> [Option<(Vec3, Vec3)>; 2] {
        let r = self.reaction();
        let tip = self.scene.catheter().tip().as_vec3();
        [
            None,
            (r.length() > 0.0).then(|| (tip, r.normalize_or(DVec3::Y).as_vec3())),
        ]
    }

    fn model_reports(&self) -> Vec<ModelReport> {
        let s = &self.scene;
        let report = |name: &str, kind: &str, vertices: usize, constraints: usize| ModelReport {
            name: name.to_string(),
            kind: kind.to_string(),
            vertices,
            triangles: 0,
            constraints,
            mass_spring: MassSpring {
                nodes: Some(vertices),
                springs: Some(constraints),
                integrator: Some("semi_implicit_euler"),
            },
        };
        vec![
            report(
                "catheter",
                "skeleton_springs",
                s.catheter().balls.len(),
                s.catheter().springs.len() + s.catheter().angles.len(),
            ),
            ModelReport {
                triangles: self.scene.vessel().triangles().len(),
                ..report(
                    "vessel",
                    "skeleton_springs",
                    s.vessel().balls.len(),
                    s.vessel().springs.len(),
                )
            },
            ModelReport {
                mass_spring: MassSpring::default(),
                ..report("collision", "sphere_sections", 0, 0)
            },
        ]
    }

    fn model_times(&self) -> Vec<f64> {
        self.scene.times().to_vec()
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        let s = &self.scene;
        vec![
            ("catheter", s.catheter().balls.heap_bytes()),
            (
                "vessel",
                s.vessel().balls.heap_bytes() + s.vessel().springs.capacity() * 40,
            ),
        ]
    }

    fn state_hash(&self) -> u64 {
        Catheterisation::state_hash(self)
    }

    fn is_completed(&self) -> bool {
        Catheterisation::is_completed(self)
    }
}
