//! The rectum as the session, window and headset see every procedure: its registry entry,
//! its build from a scenario, and its score.

use super::field;
use super::procedure::{Metrics, Rectum, STEPS};
use super::scenario::{self, NAME, Scenario};
use crate::procedures::{ModelReport, Procedure, ProcedureInfo};
use crate::scenario::InputError;
use crate::sim::{ChecklistScore, Hand, TissueModel, ToolInfo, ToolKind};
use glam::Vec3;

/// The registry's entry.
pub const INFO: ProcedureInfo = crate::procedure_info! {
    stem: "rectum", paper: "rectum-dissection.txt",
    title: "Laparoscopic rectum dissection (total mesorectal excision drill)",
    build: |file, s| {
        let anatomy = super::Anatomy::generate(s.anatomy_params())
            .map_err(|e| InputError::new(file, "anatomy", e.to_string()))?;
        Rectum::new(s, &anatomy).map_err(|e| InputError::new(file, "membrane", e.to_string()))?
    },
    // Left: lifting the mid section 9 mm takes about 5 N (the rod's documented stiffness).
    // Right: the membrane is soft (millinewtons press it in); the full scale is the force
    // that pushing the rectum itself with the shaft takes, where alarms belong.
    tools: [("grasper", Grasper, 5.0), ("hook", Hook, 3.0)],
    // In front of and above the section's middle, on the line the anterior fascia faces
    // (the bowel's axis runs along +x and curves down with the sacrum), 12 cm away.
    view: (0.16, 0.10, 0.07) -> (0.085, 0.0, 0.0),
    // Over the anterior field, out of the tissue, pointing down.
    desk_park: [(0.05, 0.06, 0.03), (0.1, 0.06, 0.03)],
    // 20 steps: each all-awake step is some 40 explicit steps of all 960,000 nodes.
    bench_all_awake_s: 0.02,
    // The paper: "The left haptic device can also be used as a navigation camera".
    scope_hand: Some(Hand::Left),
    // The paper's test: one L-hook and two graspers; the right hand changes between them.
    swap: &[ToolInfo::right("right grasper", ToolKind::Grasper, 5.0)],
    cases: super::cases::cases,
    gpu_bench: Some(super::gpu_bench::lines),
    cpu_preset: Some(include_str!("../../../assets/presets/cpu/rectum.toml")),
    gpu_cases: super::cases::gpu_cases,
    preset_cases: super::cases::preset_cases,
};

impl Procedure for Rectum {
    crate::procedure_basics!(INFO, report(errors: metrics.alarms), models: [scene]);

    fn snapshot_job(&mut self, step: u64) -> crate::sim::SnapshotJob {
        Rectum::snapshot_job(self, step)
    }

    fn instrument_tips(&self) -> Option<[Vec3; 2]> {
        Some([self.tool_tip(0), self.tool_tip(1)])
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
            ModelReport::new(
                "rectum",
                TissueModel::kind(rod),
                rod.surface().positions.len(),
                rod.params().elements,
            )
            .with_triangles(rod.surface().triangles.len())
            .with_nodes(rod.params().elements + 1),
            ModelReport {
                // Its integrator, and the substeps of a step at its stability limit.
                mass_spring: TissueModel::mass_spring(m),
                ..ModelReport::new("membrane", "mass_spring_4_layer", m.len(), m.springs())
                    .on_gpu(m.gpu_adapter())
            },
            // The membrane's nodes it tests, as `nodes` (not `vertices`: the procedure's
            // totals would count them twice).
            ModelReport::new("collision", "generalized_cylinders", 0, 0).with_nodes(m.len()),
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
}

/// Points taken off per alarm (a vulnerable structure touched, the wall cut).
const ALARM_PENALTY: f32 = 10.0;

/// The score, 0-100: 60 x completion + 20 x efficiency + 20 x precision (plane springs cut
/// in the target over all cut), less 10 per alarm. A flat score until the hierarchy of
/// Table 1 with its weights and fuzzy levels (#12).
pub fn score(s: &Scenario, m: &Metrics) -> (f32, ChecklistScore) {
    let time = (f64::from(s.task.target_time_s), m.completion_time_s);
    let penalty = ALARM_PENALTY * m.alarms as f32;
    let precision = ("precision", m.correct_cut_ratio);
    ChecklistScore::new(&m.steps_done, &STEPS, time, precision, penalty).scored()
}
