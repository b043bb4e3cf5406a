//! Scoring of a nephrectomy session: five weighted components, each in [0, 1].

use super::Metrics;
use super::Scenario;
use crate::sim::{completion_share, time_efficiency};
use serde::Serialize;

#[derive(Debug, Clone, Serialize)]
pub struct ScoreParts {
    /// Fraction of the four task steps done.
    pub completion: f32,
    /// exp(-mean cut deviation / 2 mm), zero without a cut.
    pub margin: f32,
    /// 1 - excess healthy tissue removed / planned, clamped.
    pub preservation: f32,
    /// 1 / (1 + vessel contacts + torn ties + faces cut into the tumour / 10).
    pub safety: f32,
    /// target time / completion time, clamped; zero if not completed.
    pub efficiency: f32,
}

/// Deviation at which the margin component falls to 1/e, metres.
const MARGIN_SCALE_M: f32 = 0.002;

pub fn score(s: &Scenario, m: &Metrics) -> (f32, ScoreParts) {
    let parts = ScoreParts {
        completion: completion_share(m.steps_done.len(), 4),
        margin: if m.cut_faces > m.cut_into_tumour_faces {
            (-m.cut_deviation_mean_m / MARGIN_SCALE_M).exp()
        } else {
            0.0
        },
        preservation: if m.cut_faces == 0 {
            0.0
        } else {
            let excess = (m.healthy_removed_m2 - m.healthy_planned_m2).max(0.0);
            (1.0 - excess / m.healthy_planned_m2.max(1e-9)).clamp(0.0, 1.0)
        },
        safety: 1.0
            / (1.0
                + m.vessel_contacts as f32
                + m.ties_torn as f32
                + m.cut_into_tumour_faces as f32 / 10.0),
        efficiency: time_efficiency(f64::from(s.task.target_time_s), m.completion_time_s),
    };
    let w = &s.weights;
    let total = w.completion + w.margin + w.preservation + w.safety + w.efficiency;
    let sum = w.completion * parts.completion
        + w.margin * parts.margin
        + w.preservation * parts.preservation
        + w.safety * parts.safety
        + w.efficiency * parts.efficiency;
    ((100.0 * sum / total).clamp(0.0, 100.0), parts)
}
