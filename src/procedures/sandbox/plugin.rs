//! The sandbox as the session, window and headset see every procedure, and its score.

use super::{INFO, MODEL, Metrics, STEPS, Sandbox, Scenario};
use crate::params::TuneError;
use crate::procedures::soft_tissue;
use crate::procedures::{Procedure, Tunable};
use crate::sim::{ModelSet, completion_share, time_efficiency};
use glam::Vec3;
use serde::Serialize;

/// Weight of the completed fraction of the checklist in the score, points.
const COMPLETION_POINTS: f32 = 70.0;
/// Weight of the speed (target time over time taken) in the score, points.
const EFFICIENCY_POINTS: f32 = 30.0;

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScoreParts {
    /// Fraction of the four task steps done.
    pub completion: f32,
    /// Target time / completion time, at most 1; zero until completed.
    pub efficiency: f32,
}

/// The score, 0-100: 70 x completion + 30 x efficiency. The sandbox teaches the controls, so
/// doing every step counts most and speed the rest; the grasper's overloads are reported as
/// errors but do not lower the score (there is no tissue to harm).
pub fn score(s: &Scenario, m: &Metrics) -> (f32, ScoreParts) {
    let parts = ScoreParts {
        completion: completion_share(m.steps_done.len(), STEPS.len()),
        efficiency: time_efficiency(f64::from(s.task.target_time_s), m.completion_time_s),
    };
    let weighted = [
        (COMPLETION_POINTS, parts.completion),
        (EFFICIENCY_POINTS, parts.efficiency),
    ];
    (crate::sim::weighted_score(&weighted, 0.0), parts)
}

impl Procedure for Sandbox {
    crate::procedure_basics!(INFO, report(errors: metrics.grasper_overloads));

    fn snapshot_job(&mut self, step: u64) -> crate::sim::SnapshotJob {
        Sandbox::snapshot_job(self, step)
    }

    fn contacts_now(&self) -> [Option<(Vec3, Vec3)>; 2] {
        // Both instruments are tips: the block pushes each out along its normal.
        [0, 1].map(|k| {
            let push = self.reactions()[k];
            (push.length() > 0.0).then(|| (self.tools[k].tip, push.normalize_or_zero()))
        })
    }

    fn models(&self) -> Option<&dyn ModelSet> {
        Some(&self.world)
    }

    fn models_mut(&mut self) -> Option<&mut dyn ModelSet> {
        Some(&mut self.world)
    }

    fn tunables(&self) -> Vec<Tunable> {
        soft_tissue::tunables(MODEL, &self.scenario.block)
    }

    fn tune(&mut self, model: &str, values: &[(String, f32)]) -> Result<(), TuneError> {
        if model != MODEL {
            return Err(TuneError::NoSuchModel(model.to_string()));
        }
        soft_tissue::tune(
            model,
            &mut self.scenario.block,
            self.world.model_mut(super::BLOCK),
            values,
        )
    }
}
