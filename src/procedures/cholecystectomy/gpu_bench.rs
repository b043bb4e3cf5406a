//! The cholecystectomy's line of `vesalius bench cholecystectomy --compute gpu`: its particle
//! solver's kernels at the default scenario's size (22,900 particles in organs, 4 sweeps),
//! built and laid out as a session builds it, every particle awake (see
//! `models::particles::gpu_bench`).

use super::Scenario;
use super::plugin::build_procedure;
use crate::gpu::Gpu;
use crate::models::particles;
use crate::models::particles::gpu::Sweeps;
use crate::sim::{BenchError, BenchLine};

/// Wall seconds the kernels are timed for.
const BUDGET_S: f64 = 3.0;

/// The solver's GPU lines at the default scenario's size: its sweeps scheduled and a step's
/// two substeps in one submission (as sessions run), then by colour, then a submission a
/// substep.
pub fn lines(gpu: &Gpu) -> Result<Vec<BenchLine>, BenchError> {
    let file = "builtin cholecystectomy scenario";
    let s = Scenario::parse(file, super::INFO.scenario)?;
    let dt = s.dt_s;
    let p = build_procedure(file, s)?;
    // As sessions run, then each change undone alone beside it (the same bytes each way).
    [
        (Sweeps::Scheduled, true),
        (Sweeps::ByColour, true),
        (Sweeps::Scheduled, false),
    ]
    .into_iter()
    .map(|(w, ahead)| {
        let s = p.scene.solver();
        Ok(particles::gpu_bench::bench_line(
            gpu, s, dt, BUDGET_S, w, ahead,
        )?)
    })
    .collect()
}
