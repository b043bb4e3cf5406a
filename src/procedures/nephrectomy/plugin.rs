//! The nephrectomy as the session, window and headset see every procedure.

use super::{INFO, KIDNEY, Nephrectomy, TUNED_MODEL};
use crate::models::Tuning;
use crate::procedures::{
    ModelReport, Procedure, ProcedureInfo, ProcedureReport, TaskStatus, Tunable,
};
use crate::sim::{InputFrame, SimEvent, Snapshot, TissueModel};
use glam::Vec3;

/// Slider labels with units, in the order of `Tuning::RANGES`.
const LABELS: [&str; 3] = ["spring (N/m)", "damping (1/s)", "offset (mm)"];
/// The scenario table of the instruments, whose laser pressure is tunable too.
const TOOLS: &str = "tools";
/// The laser's pressure on the tissue it cuts, Pa (eq 4): the slider's range.
const LASER_PRESSURE_PA: (f32, f32) = (0.0, 10_000.0);

impl Procedure for Nephrectomy {
    fn info(&self) -> &'static ProcedureInfo {
        &INFO
    }

    fn dt_s(&self) -> f32 {
        self.scenario.dt_s
    }

    fn step(&mut self, input: &InputFrame, step: u64, events: &mut Vec<SimEvent>) {
        Nephrectomy::step(self, input, step, events);
    }

    fn snapshot(&mut self, step: u64) -> Snapshot {
        Nephrectomy::snapshot(self, step)
    }

    fn status(&self, near_m: f32) -> TaskStatus {
        let m = &self.metrics;
        let (score, _) = super::score(&self.scenario, m);
        TaskStatus {
            steps_done: m.steps_done.clone(),
            completed: self.is_completed(),
            score,
            errors: m.vessel_contacts + m.ties_torn,
            path_m: [m.path_length_left_m, m.path_length_right_m],
            figures: vec![(
                "cut".to_string(),
                format!(
                    "{:.1} mm, {} triangles",
                    m.cut_length_m * 1000.0,
                    m.cut_faces
                ),
            )],
            touching: self.touching_vulnerable(),
            near: self.vulnerable_near(near_m),
        }
    }

    fn report(&self) -> ProcedureReport {
        let mut metrics = self.metrics.clone();
        if !self.is_completed() {
            metrics.healthy_removed_m2 = self.healthy_removed();
        }
        let (score, parts) = super::score(&self.scenario, &metrics);
        ProcedureReport {
            completed: self.is_completed(),
            errors: metrics.vessel_contacts + metrics.ties_torn,
            metrics: serde_json::to_value(&metrics).unwrap_or_default(),
            score_parts: serde_json::to_value(&parts).unwrap_or_default(),
            score,
        }
    }

    fn reactions(&self) -> [Vec3; 2] {
        Nephrectomy::reactions(self)
    }

    fn contacts_now(&self) -> [Option<(Vec3, Vec3)>; 2] {
        let [grasper, laser] = self.tools;
        let [push, _] = Nephrectomy::reactions(self);
        [
            // The tissue pushes the tip out along its normal.
            (push.length() > 0.0).then(|| (grasper.tip, push.normalize_or_zero())),
            laser
                .beam_end
                .filter(|_| laser.active)
                .map(|p| (p, -laser.direction)),
        ]
    }

    fn model_reports(&self) -> Vec<ModelReport> {
        self.models
            .iter()
            .map(|m| {
                let s = m.sizes();
                ModelReport {
                    name: m.name().to_string(),
                    kind: m.kind().to_string(),
                    vertices: s.vertices,
                    triangles: s.triangles,
                    constraints: s.constraints,
                }
            })
            .collect()
    }

    fn model_times(&self) -> Vec<f64> {
        self.model_time_s.clone()
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        Nephrectomy::memory(self)
    }

    fn state_hash(&self) -> u64 {
        Nephrectomy::state_hash(self)
    }

    fn tunables(&self) -> Vec<Tunable> {
        let now = Tuning::of(&self.scenario.kidney).values();
        Tuning::RANGES
            .iter()
            .zip(LABELS)
            .zip(now)
            .map(|(((key, min, max), label), value)| Tunable {
                model: TUNED_MODEL.to_string(),
                key,
                label,
                min: *min,
                max: *max,
                scale: if *key == "offset_m" { 1000.0 } else { 1.0 },
                value,
            })
            .chain(std::iter::once(Tunable {
                model: TOOLS.to_string(),
                key: "laser_pressure_pa",
                label: "laser pressure (Pa)",
                min: LASER_PRESSURE_PA.0,
                max: LASER_PRESSURE_PA.1,
                scale: 1.0,
                value: self.scenario.tools.laser_pressure_pa,
            }))
            .collect()
    }

    fn tune(&mut self, model: &str, values: &[(String, f32)]) -> Result<(), String> {
        if model == TOOLS {
            let mut pressure = self.scenario.tools.laser_pressure_pa;
            for (key, v) in values {
                match key.as_str() {
                    "laser_pressure_pa" => pressure = *v,
                    other => return Err(format!("{model}.{other}: not a tunable parameter")),
                }
            }
            let (lo, hi) = LASER_PRESSURE_PA;
            if !(pressure.is_finite() && (lo..=hi).contains(&pressure)) {
                return Err(format!(
                    "{model}.laser_pressure_pa: must be {lo} to {hi}, got {pressure}"
                ));
            }
            self.scenario.tools.laser_pressure_pa = pressure;
            return Ok(());
        }
        if model != TUNED_MODEL {
            return Err(format!("model '{model}' has no tunable parameters"));
        }
        // The table's slider ranges, all values or none.
        crate::params::check_tuning::<crate::models::SoftBodyParams>(model, values)?;
        let mut t = Tuning::of(&self.scenario.kidney);
        for (key, v) in values {
            match key.as_str() {
                "spring_n_per_m" => t.spring_n_per_m = *v,
                "damping_per_s" => t.damping_per_s = *v,
                "offset_m" => t.offset_m = *v,
                other => return Err(format!("{model}.{other}: not a tunable parameter")),
            }
        }
        t.check()
            .map_err(|(key, m)| format!("{model}.{key}: {m}"))?;
        self.models[KIDNEY].tune(&t);
        t.apply(&mut self.scenario.kidney);
        Ok(())
    }

    fn is_completed(&self) -> bool {
        Nephrectomy::is_completed(self)
    }
}
