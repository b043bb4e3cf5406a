//! `vesalius bench`: step rates of each model and of the whole procedure at the scenario's
//! sizes, driven by the procedure's demo trace, with the share of points each model kept
//! awake; then the same models with every point kept awake (a sleeping model must never read
//! as fast), over the first [`ALL_AWAKE_S`] simulated seconds of the trace.

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
    /// Mean share of the points stepped each step (1: none asleep).
    pub awake_fraction: f64,
    /// Every point was kept awake for this line.
    pub all_awake: bool,
    /// A mass-spring model's particulars.
    #[serde(flatten)]
    pub mass_spring: crate::procedures::MassSpring,
    /// A one-off computation's particulars (a precomputation's stages).
    #[serde(flatten)]
    pub once: Once,
}

/// A one-off computation's seconds, size and rate, beside the machine's peak (each left out
/// of the JSON when absent).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Once {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seconds: Option<f64>,
    /// The dense system's unknowns.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub n: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gflops: Option<f64>,
    /// The machine's double-precision peak, GFLOP/s (see [`peak_gflops`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peak_gflops: Option<f64>,
}

/// A procedure's own benchmarks, beyond stepping its demo.
pub type ExtraBench = fn() -> Result<Vec<BenchLine>, BenchError>;

impl BenchLine {
    /// A line for `count` repetitions of something that took `seconds` in all (`steps` are
    /// the repetitions, `steps_per_s` their rate; no time step).
    pub fn repeated(model: &str, count: u64, seconds: f64) -> BenchLine {
        BenchLine {
            model: model.to_string(),
            steps: count,
            steps_per_s: count as f64 / seconds.max(1e-12),
            dt_s: 0.0,
            realtime_factor: 0.0,
            vertices: 0,
            triangles: 0,
            constraints: 0,
            threads: rayon::current_num_threads(),
            awake_fraction: 1.0,
            all_awake: true,
            mass_spring: Default::default(),
            once: Once::default(),
        }
    }
}

/// The machine's double-precision peak, GFLOP/s: the cores rayon uses times their clock
/// (`cpu MHz` of `/proc/cpuinfo`, the highest listed) times the flops one core retires a
/// cycle with the widest fused multiply-add it has (AVX-512: 32, but 16 on AMD's family 25,
/// Zen 3 and 4, whose AVX-512 runs as two 256-bit halves; AVX2 with FMA: 16, else 4). An
/// estimate of the ceiling at the listed clock, not a measurement (a boosting core can pass
/// it); none where the clock cannot be read.
pub fn peak_gflops() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/cpuinfo").ok()?;
    let mhz = text
        .lines()
        .filter(|l| l.starts_with("cpu MHz"))
        .filter_map(|l| l.split(':').nth(1)?.trim().parse::<f64>().ok())
        .fold(0.0, f64::max);
    if mhz <= 0.0 {
        return None;
    }
    let amd_family_25 = text
        .lines()
        .any(|l| l.starts_with("vendor_id") && l.contains("AuthenticAMD"))
        && text.lines().any(|l| {
            l.starts_with("cpu family") && l.split(':').nth(1).map(str::trim) == Some("25")
        });
    let per_cycle = if amd_family_25 {
        flops_per_cycle().min(16.0)
    } else {
        flops_per_cycle()
    };
    Some(rayon::current_num_threads() as f64 * mhz * 1e-3 * per_cycle)
}

#[cfg(target_arch = "x86_64")]
fn flops_per_cycle() -> f64 {
    if std::arch::is_x86_feature_detected!("avx512f") {
        32.0
    } else if std::arch::is_x86_feature_detected!("avx2")
        && std::arch::is_x86_feature_detected!("fma")
    {
        16.0
    } else {
        4.0
    }
}

/// Elsewhere: two-wide fused multiply-adds (NEON), a conservative figure.
#[cfg(not(target_arch = "x86_64"))]
fn flops_per_cycle() -> f64 {
    4.0
}

/// Simulated seconds of the all-awake pass (the whole demo all awake would take minutes) by
/// default; each procedure says its own ([`crate::procedures::ProcedureInfo::bench_all_awake_s`]).
pub const ALL_AWAKE_S: f64 = 1.0;

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
    #[error("a contact update: {0}")]
    Contact(#[from] crate::models::bem::contact::ContactError),
}

/// Runs the procedure's demo trace once on its default scenario, timing every model and the
/// whole step; then again over its first seconds (the procedure's `bench_all_awake_s`) with
/// every point awake.
pub fn run(procedure: &str) -> Result<Vec<BenchLine>, BenchError> {
    let info = crate::procedures::find(procedure)
        .ok_or_else(|| BenchError::NoSuchProcedure(procedure.to_string()))?;
    let trace = KeyTrace::parse(&format!("builtin {procedure} demo trace"), info.demo_trace)?;
    let mut out = pass(info, &trace, trace.duration_s(), false)?;
    out.extend(pass(
        info,
        &trace,
        info.bench_all_awake_s.min(trace.duration_s()),
        true,
    )?);
    if let Some(extra) = info.bench_extra {
        out.extend(extra()?);
    }
    Ok(out)
}

/// One timed run of `seconds` of the trace; `all_awake` keeps every point stepping.
fn pass(
    info: &crate::procedures::ProcedureInfo,
    trace: &KeyTrace,
    seconds: f64,
    all_awake: bool,
) -> Result<Vec<BenchLine>, BenchError> {
    let file = format!("builtin {} scenario", info.name);
    let (_, plan) = crate::procedures::plan(&file, info.scenario)?;
    let dt = plan.dt_s;
    let mut p = (info.build)(&file, info.scenario)?;
    if all_awake {
        p.stay_awake();
    }
    let mut clock = Clock::new(dt, Pacing::AsFastAsPossible);
    let steps = (seconds / dt as f64).ceil() as u64;
    let mut events = Vec::new();
    let t0 = Instant::now();
    // On a worker of the pool, as a session steps (see `crate::session::on_pool`).
    crate::session::on_pool(|| {
        while clock.step() < steps {
            let f = trace.sample(clock.time_s());
            p.step(&f, clock.step(), &mut events);
            events.clear();
            clock.tick();
        }
    });
    let wall = t0.elapsed().as_secs_f64();
    let threads = rayon::current_num_threads();
    let line = |model: String, secs: f64, sizes: [usize; 3], awake_fraction: f64| {
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
            awake_fraction,
            all_awake,
            mass_spring: Default::default(),
            once: Once::default(),
        }
    };
    let models = p.model_reports();
    let awake = p.awake_fractions();
    let mut out: Vec<BenchLine> = models
        .iter()
        .zip(p.model_times())
        .zip(&awake)
        .map(|((m, t), a)| BenchLine {
            mass_spring: m.mass_spring,
            ..line(
                m.name.clone(),
                t,
                [m.vertices, m.triangles, m.constraints],
                *a,
            )
        })
        .collect();
    let total = models.iter().fold([0; 3], |a, m| {
        [a[0] + m.vertices, a[1] + m.triangles, a[2] + m.constraints]
    });
    // The whole procedure's share: awake points over all points.
    let awake_points: f64 = models
        .iter()
        .zip(&awake)
        .map(|(m, a)| m.vertices as f64 * a)
        .sum();
    let share = awake_points / (total[0].max(1) as f64);
    out.push(line("procedure".to_string(), wall, total, share));
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
