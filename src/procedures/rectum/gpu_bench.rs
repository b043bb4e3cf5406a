//! The rectum's lines of `vesalius bench rectum --compute gpu`: the membrane's kernel at the
//! default scenario's size (the paper's 960,000 nodes), every node awake, each 1 ms step in
//! the substeps the CPU takes, checked against the CPU's step and timed on the device.

use super::{Anatomy, Rectum, Scenario};
use crate::gpu::Gpu;
use crate::models::membrane;
use crate::scenario::InputError;
use crate::sim::{BenchError, BenchLine};

/// Wall seconds the kernel is timed for.
const BUDGET_S: f64 = 3.0;

/// The membrane's GPU lines at the default scenario's size, one a workgroup layout.
pub fn lines(gpu: &Gpu) -> Result<Vec<BenchLine>, BenchError> {
    let file = "builtin rectum scenario";
    let s = Scenario::parse(file, super::INFO.scenario)?;
    let anatomy = Anatomy::generate(s.anatomy_params())
        .map_err(|e| InputError::new(file, "anatomy", e.to_string()))?;
    let (dt, safety) = (s.dt_s, s.scene_params().substep_safety);
    let r =
        Rectum::new(s, &anatomy).map_err(|e| InputError::new(file, "membrane", e.to_string()))?;
    // The default layout, then the others for comparison.
    [
        membrane::gpu::Layout::Flat,
        membrane::gpu::Layout::Rows,
        membrane::gpu::Layout::Layers,
    ]
    .into_iter()
    .map(|layout| {
        membrane::gpu::bench_line(gpu, r.scene.membrane(), dt, safety, BUDGET_S, layout)
            .map_err(BenchError::from)
    })
    .collect()
}
