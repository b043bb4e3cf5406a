//! `vesalius bench`: step rates of each model and of the whole procedure at the scenario's
//! sizes, driven by the procedure's demo trace.

use crate::procedures::Nephrectomy;
use crate::scenario::{Scenario, builtin};
use crate::sim::{Clock, Pacing, TissueModel};
use crate::trace::KeyTrace;
use serde::Serialize;
use std::time::Instant;

/// The nephrectomy's demo trace (kept for callers that predate the registry).
pub const DEMO_TRACE: &str = crate::procedures::nephrectomy::INFO.demo_trace;

#[derive(Debug, Serialize)]
pub struct BenchLine {
    pub model: String,
    pub steps: u64,
    pub steps_per_s: f64,
    pub dt_s: f32,
    pub realtime_factor: f64,
    pub vertices: usize,
    pub triangles: usize,
    pub constraints: usize,
    pub threads: usize,
}

/// Runs the demo trace once, timing every model and the whole step.
pub fn run(procedure: &str) -> Result<Vec<BenchLine>, String> {
    let text = builtin(procedure).ok_or_else(|| format!("no benchmark for '{procedure}' yet"))?;
    let scenario = Scenario::parse("builtin scenario", text).map_err(|e| e.to_string())?;
    let trace = KeyTrace::parse("builtin demo trace", DEMO_TRACE).map_err(|e| e.to_string())?;
    let dt = scenario.dt_s;
    let mut p = Nephrectomy::new(scenario).map_err(|e| e.to_string())?;
    let mut clock = Clock::new(dt, Pacing::AsFastAsPossible);
    let steps = (trace.duration_s() / dt as f64).ceil() as u64;
    let mut events = Vec::new();
    let t0 = Instant::now();
    while clock.step() < steps {
        let f = trace.sample(clock.time_s());
        p.step(&f, clock.step(), &mut events);
        clock.tick();
    }
    let wall = t0.elapsed().as_secs_f64();
    let threads = rayon::current_num_threads();
    let line = |model: String, secs: f64, sizes: crate::sim::ModelSizes| {
        let sps = steps as f64 / secs.max(1e-12);
        BenchLine {
            model,
            steps,
            steps_per_s: sps,
            dt_s: dt,
            realtime_factor: sps * dt as f64,
            vertices: sizes.vertices,
            triangles: sizes.triangles,
            constraints: sizes.constraints,
            threads,
        }
    };
    let mut out: Vec<BenchLine> = p
        .models()
        .iter()
        .zip(&p.model_time_s)
        .map(|(m, &t)| line(m.name().to_string(), t, m.sizes()))
        .collect();
    let total = p.models().iter().fold(
        crate::sim::ModelSizes {
            vertices: 0,
            triangles: 0,
            constraints: 0,
        },
        |a, m| {
            let s = m.sizes();
            crate::sim::ModelSizes {
                vertices: a.vertices + s.vertices,
                triangles: a.triangles + s.triangles,
                constraints: a.constraints + s.constraints,
            }
        },
    );
    out.push(line("procedure".to_string(), wall, total));
    Ok(out)
}
