//! The myotomy as the session, window and headset see every procedure: its registry entry,
//! its build from a scenario (the precomputation read from the cache, or built and cached on
//! the first run), and its score.

use super::anatomy::Esophagus;
use super::procedure::{Metrics, Myotomy, STEPS};
use super::scenario::{self, NAME, Scenario};
use crate::models::bem::cache;
use crate::models::bem::contact::Contacts;
use crate::models::bem::palpation::Palpation;
use crate::procedures::{
    BuildError, MassSpring, ModelReport, Procedure, ProcedureInfo, TaskStatus, ToolInfo, ToolKind,
    Viewpoint,
};
use crate::sim::Hand;
use crate::sim::{completion_share, time_efficiency, weighted_score};
use glam::Vec3;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The registry's entry.
pub const INFO: ProcedureInfo = ProcedureInfo {
    name: NAME,
    title: "Laparoscopic Heller myotomy (esophagogastric junction)",
    paper: "esophageal-myotomy.txt",
    scenario: include_str!("../../../assets/scenarios/myotomy.toml"),
    demo_trace: include_str!("../../../assets/traces/myotomy-demo.toml"),
    steps: &STEPS,
    tools: [
        ToolInfo {
            hand: Hand::Left,
            name: "grasper",
            kind: ToolKind::Grasper,
            // Palpating the sphincter takes a few hundred millinewtons at most.
            full_scale_n: 0.5,
        },
        ToolInfo {
            hand: Hand::Right,
            name: "hook",
            kind: ToolKind::Hook,
            full_scale_n: 0.5,
        },
    ],
    // The laparoscope above the anterior wall of the abdominal esophagus, looking down at
    // the junction, the diaphragm at the top of the view.
    view: Viewpoint {
        eye: Vec3::new(0.0, 0.075, 0.045),
        target: Vec3::new(0.0, 0.008, 0.035),
    },
    // Above the field, to either side.
    desk_park: [Vec3::new(-0.03, 0.04, 0.03), Vec3::new(0.03, 0.04, 0.03)],
    param_tables: scenario::PARAM_TABLES,
    assessment: include_str!("../../../assets/assessment/myotomy.toml"),
    field: super::field::field,
    blank_metrics: || serde_json::to_value(Metrics::default()).unwrap_or_default(),
    plan: scenario::plan,
    build,
    options: crate::sim::Options {
        bench_all_awake_s: 1.0,
        bench_extra: Some(super::bench::extra),
        precompute: Some(&super::PRECOMPUTE),
        ..crate::sim::Options::NONE
    },
};

fn build(file: &str, text: &str) -> Result<Box<dyn Procedure>, BuildError> {
    let s = Scenario::parse(file, text)?;
    Ok(Box::new(build_procedure(s, &cache::default_dir())?))
}

/// The cache file in `dir` for this esophagus (named by its key: esophagi of other sizes or
/// tissues keep their own files).
pub fn cache_file(dir: &Path, e: &Esophagus) -> PathBuf {
    dir.join(format!("myotomy-{:016x}.bem", e.problem.key(&e.field)))
}

/// The procedure for a checked scenario, its precomputation read from (or built into) the
/// cache in `cache_dir`. Building shows its progress on standard error.
pub fn build_procedure(s: Scenario, cache_dir: &Path) -> Result<Myotomy, BuildError> {
    let e = Esophagus::new(&s.esophagus_params());
    let path = cache_file(cache_dir, &e);
    let bar = crate::progress::Bar::new();
    let announced = std::sync::Once::new();
    let progress = |stage: &str, f: f64| {
        announced.call_once(|| {
            eprintln!(
                "myotomy: precomputing the esophagus's responses into {} (once per mesh and \
                 tissue; `vesalius precompute myotomy` does it ahead)",
                path.display()
            );
        });
        bar.show(stage, f);
    };
    let par = faer::Par::rayon(rayon::current_num_threads());
    let (pre, _) = e
        .problem
        .precompute_cached(&e.field, &path, par, &progress)?;
    let base = pre.solution(&e.problem);
    let contacts = Contacts::new(pre, &e.problem.elements, s.prony());
    let palpation = Palpation::new(contacts, &e.problem.elements, &base);
    Ok(Myotomy::new(s, e, palpation))
}

/// Weight of the checklist done, of the speed and of the muscle divided, points.
const COMPLETION_POINTS: f32 = 60.0;
const EFFICIENCY_POINTS: f32 = 20.0;
const DIVISION_POINTS: f32 = 20.0;
/// Points taken off per error (a perforation).
const ERROR_PENALTY: f32 = 20.0;

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScoreParts {
    /// Fraction of the checklist done.
    pub completion: f32,
    /// Target time / completion time, at most 1; zero until completed.
    pub efficiency: f32,
    /// Share of the myotomy's span with its muscle divided.
    pub division: f32,
    pub penalty: f32,
}

/// The score, 0-100: 60 x completion + 20 x efficiency + 20 x division, less 20 per
/// perforation (a flat score until the assessment trees of #12).
pub fn score(s: &Scenario, m: &Metrics) -> (f32, ScoreParts) {
    let parts = ScoreParts {
        completion: completion_share(m.steps_done.len(), STEPS.len()),
        efficiency: time_efficiency(s.task.target_time_s, m.completion_time_s),
        division: if m.required_m > 0.0 {
            (m.divided_m / m.required_m).min(1.0) as f32
        } else {
            1.0
        },
        penalty: ERROR_PENALTY * m.errors as f32,
    };
    let weighted = [
        (COMPLETION_POINTS, parts.completion),
        (EFFICIENCY_POINTS, parts.efficiency),
        (DIVISION_POINTS, parts.division),
    ];
    (weighted_score(&weighted, parts.penalty), parts)
}

impl Procedure for Myotomy {
    crate::procedure_basics!(INFO, report(errors: metrics.errors), models: []);

    fn status(&self, _near_m: f32) -> TaskStatus {
        let m = &self.metrics;
        let (score, _) = score(&self.scenario, m);
        TaskStatus {
            steps_done: m.steps_done.clone(),
            completed: self.is_completed(),
            score,
            errors: m.errors,
            path_m: [m.path_length_left_m, m.path_length_right_m],
            figures: vec![
                (
                    "muscle divided".to_string(),
                    format!("{:.0} of {:.0} mm", 1e3 * m.divided_m, 1e3 * m.required_m),
                ),
                (
                    "deepest cut".to_string(),
                    format!(
                        "{:.1} mm (muscle {:.1}, wall {:.1})",
                        1e3 * m.deepest_cut_m,
                        1e3 * self.scenario.task.muscle_m,
                        1e3 * self.scenario.esophagus.wall_m
                    ),
                ),
                (
                    "polygons".to_string(),
                    format!("{} (from {})", m.triangles, m.original_triangles),
                ),
                (
                    "grasper force".to_string(),
                    format!("{:.3} N", self.reactions()[0].length()),
                ),
                (
                    "hook force".to_string(),
                    format!("{:.3} N", self.reactions()[1].length()),
                ),
            ],
            // Nothing here is a vulnerable structure an instrument may not touch: the mucosa
            // is guarded by the perforation's own alarm.
            touching: [false; 2],
            near: [None, None],
        }
    }

    fn reactions(&self) -> [Vec3; 2] {
        Myotomy::reactions(self)
    }

    fn contacts_now(&self) -> [Option<(Vec3, Vec3)>; 2] {
        let r = Myotomy::reactions(self);
        let tips = [self.tool_tip(0), self.tool_tip(1)];
        [0, 1].map(|k| (r[k].length() > 0.0).then(|| (tips[k], r[k].normalize_or(Vec3::Y))))
    }

    fn model_reports(&self) -> Vec<ModelReport> {
        let e = &self.esophagus;
        let pre = self.palpation().contacts.precomputed();
        vec![
            // Its step is the contact update from the precomputed responses.
            ModelReport {
                name: "esophagus".to_string(),
                kind: "boundary_elements".to_string(),
                vertices: e.surface.vertices.len(),
                triangles: e.surface.triangles.len(),
                // The dense system's unknowns.
                constraints: pre.n,
                mass_spring: MassSpring::default(),
            },
            ModelReport {
                name: "incision".to_string(),
                kind: "surface_subdivision".to_string(),
                vertices: self.incision.vertices.len() - e.surface.vertices.len(),
                // What the incision added to the surface.
                triangles: self.incision.triangles.len() - e.surface.triangles.len(),
                constraints: self.incision.cuts().len(),
                mass_spring: MassSpring::default(),
            },
        ]
    }

    fn model_times(&self) -> Vec<f64> {
        self.times.to_vec()
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        let pre = self.palpation().contacts.precomputed();
        let f3 = 3 * pre.field.len();
        vec![
            ("responses", 8 * (pre.response.len() + pre.y0.len())),
            ("capacitance", 8 * f3 * f3),
            (
                "incision",
                24 * self.incision.vertices.len() + 12 * self.incision.triangles.len(),
            ),
        ]
    }

    fn state_hash(&self) -> u64 {
        Myotomy::state_hash(self)
    }

    fn is_completed(&self) -> bool {
        Myotomy::is_completed(self)
    }
}
