//! The catheterisation's own lines of `vesalius bench`: the collision over the demo's first
//! seconds in the scenario's vessel and in one 4 times longer (`collision_vessel_x1`,
//! `collision_vessel_x4`), with the ball pairs tested a step, to show the sectioned collision
//! does not grow with the vessel's length.

use super::plugin::{INFO, build_scene};
use super::scenario::Scenario;
use crate::sim::bench::{BenchError, BenchLine};
use crate::trace::KeyTrace;

/// Simulated seconds of the demo each vessel is timed over.
const SECONDS: f64 = 3.0;

pub fn extra() -> Result<Vec<BenchLine>, BenchError> {
    let s = Scenario::parse("builtin catheter scenario", INFO.scenario)?;
    let trace = KeyTrace::parse("builtin catheter demo trace", INFO.demo_trace)?;
    let mut out = Vec::new();
    for (name, scale) in [("collision_vessel_x1", 1.0), ("collision_vessel_x4", 4.0)] {
        let mut s = s.clone();
        s.vessel.trunk_m *= scale;
        s.vessel.branch_m *= scale;
        if let Some(t) = &mut s.tree {
            t.scale_lengths(scale);
        }
        let mut p = super::procedure::Catheterisation::new(s.clone(), build_scene(&s));
        let dt = f64::from(s.dt_s);
        let steps = (SECONDS / dt).ceil() as u64;
        let mut tests = 0u64;
        for k in 0..steps {
            let f = trace.sample(k as f64 * dt);
            let (drive, wire) = p.drives(&f);
            let out = p.scene.step((&drive, &wire), s.dt_s, k, &mut Vec::new());
            tests += out.pair_tests;
        }
        out.push(BenchLine {
            vertices: p.scene.vessel().balls.len(),
            constraints: (tests / steps.max(1)) as usize,
            ..BenchLine::repeated(name, steps, p.scene.times()[2])
        });
    }
    Ok(out)
}
