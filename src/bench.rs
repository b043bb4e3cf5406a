//! `vesalius bench`: step rates of each model and of the whole procedure at the scenario's
//! sizes, driven by the procedure's demo trace.

use crate::procedures::BuildError;
use crate::scenario::InputError;
use crate::sim::{Clock, Pacing};
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

/// Why a benchmark did not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("no procedure '{0}'")]
    NoSuchProcedure(String),
    /// The procedure's built-in scenario or demo trace is refused (a bug in the build).
    #[error(transparent)]
    Input(#[from] InputError),
    #[error(transparent)]
    Build(#[from] BuildError),
}

/// Runs the procedure's demo trace once on its default scenario, timing every model and the
/// whole step.
pub fn run(procedure: &str) -> Result<Vec<BenchLine>, BenchError> {
    let info = crate::procedures::find(procedure)
        .ok_or_else(|| BenchError::NoSuchProcedure(procedure.to_string()))?;
    let file = format!("builtin {procedure} scenario");
    let (_, plan) = crate::procedures::plan(&file, info.scenario)?;
    let trace = KeyTrace::parse(&format!("builtin {procedure} demo trace"), info.demo_trace)?;
    let dt = plan.dt_s;
    let mut p = (info.build)(&file, info.scenario)?;
    let mut clock = Clock::new(dt, Pacing::AsFastAsPossible);
    let steps = (trace.duration_s() / dt as f64).ceil() as u64;
    let mut events = Vec::new();
    let t0 = Instant::now();
    while clock.step() < steps {
        let f = trace.sample(clock.time_s());
        p.step(&f, clock.step(), &mut events);
        events.clear();
        clock.tick();
    }
    let wall = t0.elapsed().as_secs_f64();
    let threads = rayon::current_num_threads();
    let line = |model: String, secs: f64, sizes: [usize; 3]| {
        let sps = steps as f64 / secs.max(1e-12);
        BenchLine {
            model,
            steps,
            steps_per_s: sps,
            dt_s: dt,
            realtime_factor: sps * dt as f64,
            vertices: sizes[0],
            triangles: sizes[1],
            constraints: sizes[2],
            threads,
        }
    };
    let models = p.model_reports();
    let mut out: Vec<BenchLine> = models
        .iter()
        .zip(p.model_times())
        .map(|(m, t)| line(m.name.clone(), t, [m.vertices, m.triangles, m.constraints]))
        .collect();
    let total = models.iter().fold([0; 3], |a, m| {
        [a[0] + m.vertices, a[1] + m.triangles, a[2] + m.constraints]
    });
    out.push(line("procedure".to_string(), wall, total));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unknown_procedure_is_named() {
        let e = run("appendectomy").expect_err("no such procedure");
        assert!(matches!(&e, BenchError::NoSuchProcedure(p) if p == "appendectomy"));
        assert_eq!(e.to_string(), "no procedure 'appendectomy'");
    }
}
