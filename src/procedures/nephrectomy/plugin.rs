//! The nephrectomy as the session, window and headset see every procedure.

use super::{INFO, KIDNEY, Nephrectomy, TUNED_MODEL};
use crate::params::{TuneError, check_slider};
use crate::procedures::soft_tissue;
use crate::procedures::{Procedure, ProcedureReport, TaskStatus, Tunable};
use crate::sim::ModelSet;
use glam::Vec3;

/// The scenario table of the instruments, whose laser pressure is tunable too.
const TOOLS: &str = "tools";
/// The laser's pressure on the tissue it cuts, Pa (eq 4): the slider's range, from its table.
const LASER_PRESSURE_PA: (f64, f64) = match super::scenario::LASER_PRESSURE.tune {
    Some(range) => range,
    None => (0.0, 0.0),
};
/// Its key in `[tools]`.
const LASER_PRESSURE: &str = super::scenario::LASER_PRESSURE.key;

impl Procedure for Nephrectomy {
    crate::procedure_basics!(INFO);

    fn snapshot_job(&mut self, step: u64) -> crate::sim::SnapshotJob {
        Nephrectomy::snapshot_job(self, step)
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
        ProcedureReport::of(
            self.is_completed(),
            metrics.vessel_contacts + metrics.ties_torn,
            &metrics,
            &parts,
            score,
        )
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

    fn models(&self) -> Option<&dyn ModelSet> {
        Some(&self.world)
    }

    fn models_mut(&mut self) -> Option<&mut dyn ModelSet> {
        Some(&mut self.world)
    }

    fn tunables(&self) -> Vec<Tunable> {
        let mut t = soft_tissue::tunables(TUNED_MODEL, &self.scenario.kidney);
        t.push(Tunable {
            model: TOOLS.to_string(),
            key: LASER_PRESSURE,
            label: "laser pressure (Pa)",
            min: LASER_PRESSURE_PA.0 as f32,
            max: LASER_PRESSURE_PA.1 as f32,
            scale: 1.0,
            value: self.scenario.tools.laser_pressure_pa,
        });
        t
    }

    fn tune(&mut self, model: &str, values: &[(String, f32)]) -> Result<(), TuneError> {
        match model {
            TOOLS => {
                let mut pressure = self.scenario.tools.laser_pressure_pa;
                for (key, v) in values {
                    if key != LASER_PRESSURE {
                        return Err(TuneError::Fixed {
                            table: model.to_string(),
                            key: key.clone(),
                        });
                    }
                    check_slider(model, key, LASER_PRESSURE_PA, *v)?;
                    pressure = *v;
                }
                self.scenario.tools.laser_pressure_pa = pressure;
                Ok(())
            }
            TUNED_MODEL => soft_tissue::tune(
                model,
                &mut self.scenario.kidney,
                self.world.model_mut(KIDNEY),
                values,
            ),
            _ => Err(TuneError::NoSuchModel(model.to_string())),
        }
    }

    fn is_completed(&self) -> bool {
        Nephrectomy::is_completed(self)
    }
}
