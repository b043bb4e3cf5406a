//! `vesalius bench`: step rates of each model and of the whole procedure at the scenario's
//! sizes, driven by the procedure's demo trace, with the share of points each model kept
//! awake; then the same models with every point kept awake (a sleeping model must never read
//! as fast), over the first seconds of the trace the procedure names
//! (`ProcedureInfo::bench_all_awake_s`).

use std::time::Instant;
use vesalius::registry::CATALOG;
use vesalius::sim::{BenchError, BenchLine, Clock, FrameFigures, Once, Pacing, ProcedureInfo};
use vesalius::trace::KeyTrace;

/// Runs the procedure's demo trace once on `scenario` (its default, or a preset laid over
/// it), timing every model and the whole step; then again over its first seconds (the
/// procedure's `bench_all_awake_s`) with every point awake.
pub fn run(procedure: &str, file: &str, scenario: &str) -> Result<Vec<BenchLine>, BenchError> {
    let info = CATALOG
        .find(procedure)
        .ok_or_else(|| BenchError::NoSuchProcedure(procedure.to_string()))?;
    let trace = KeyTrace::parse(&format!("builtin {procedure} demo trace"), info.demo_trace)?;
    let mut out = pass(info, file, scenario, &trace, trace.duration_s(), false)?;
    out.extend(pass(
        info,
        file,
        scenario,
        &trace,
        info.options.bench_all_awake_s.min(trace.duration_s()),
        true,
    )?);
    if let Some(extra) = info.options.bench_extra {
        out.extend(extra()?);
    }
    Ok(out)
}

/// The lines of the procedure's GPU compute path on `gpu` (an error for a procedure that
/// has none yet).
pub fn run_gpu(procedure: &str, gpu: &vesalius::gpu::Gpu) -> Result<Vec<BenchLine>, BenchError> {
    let info = CATALOG
        .find(procedure)
        .ok_or_else(|| BenchError::NoSuchProcedure(procedure.to_string()))?;
    let lines = info
        .options
        .gpu_bench
        .ok_or_else(|| BenchError::NoGpuPath(procedure.to_string()))?;
    lines(gpu)
}

/// Simulated seconds of the coupled pass on the GPU (`bench --compute gpu`): the demo's
/// first two, where its instruments are at work.
pub const COUPLED_GPU_S: f64 = 2.0;

/// The procedure stepped with its models' GPU path on (`scenario` with `compute = "gpu"`)
/// over the demo trace's first [`COUPLED_GPU_S`] seconds: a line for each model (those on
/// the GPU name its adapter) and the whole procedure's.
pub fn run_coupled(
    procedure: &str,
    file: &str,
    scenario: &str,
) -> Result<Vec<BenchLine>, BenchError> {
    let info = CATALOG
        .find(procedure)
        .ok_or_else(|| BenchError::NoSuchProcedure(procedure.to_string()))?;
    let trace = KeyTrace::parse(&format!("builtin {procedure} demo trace"), info.demo_trace)?;
    pass(
        info,
        file,
        scenario,
        &trace,
        COUPLED_GPU_S.min(trace.duration_s()),
        false,
    )
}

/// One timed run of `seconds` of the trace, building a snapshot for renderers at the
/// scenario's `publish_hz` as a live session does (the procedure's line counts them);
/// `all_awake` keeps every point stepping.
fn pass(
    info: &ProcedureInfo,
    file: &str,
    scenario: &str,
    trace: &KeyTrace,
    seconds: f64,
    all_awake: bool,
) -> Result<Vec<BenchLine>, BenchError> {
    let (_, plan) = CATALOG.plan(file, scenario)?;
    let dt = plan.dt_s;
    let mut p = (info.build)(file, scenario)?;
    if all_awake {
        p.stay_awake();
    }
    let mut clock = Clock::new(dt, Pacing::AsFastAsPossible);
    let steps = (seconds / dt as f64).ceil() as u64;
    let mut events = Vec::new();
    let every = plan.publish_every();
    let mut frame_s = Vec::with_capacity((steps / every) as usize);
    // Each step's time outside its waits for a device, and those waits, s.
    let mut step_cpu_s = Vec::with_capacity(steps as usize);
    let mut step_wait_s = Vec::with_capacity(steps as usize);
    // Each step's CPU time on the simulation thread (its own clock), s.
    let mut step_thread_s = Vec::with_capacity(steps as usize);
    // Each step's wall time with its snapshot where it takes one, s.
    let mut step_wall_s = Vec::with_capacity(steps as usize);
    // The snapshots' builds go to the bus's builder thread, as a session's do.
    let bus = std::sync::Arc::new(vesalius::sim::SnapshotBus::new());
    let t0 = Instant::now();
    // On a worker of the pool, as a session steps (see `vesalius::session::on_pool`), with
    // the window's cadence of snapshots (`ui::runner`).
    vesalius::session::on_pool(|| {
        while clock.step() < steps {
            let began = Instant::now();
            let f = trace.sample(clock.time_s());
            if (clock.step() + 1).is_multiple_of(every)
                && let Some(m) = p.models_mut()
            {
                m.read_whole_after_step();
            }
            let (waited, t) = (vesalius::gpu::compute::waited_ns(), Instant::now());
            let ran = vesalius::diagnostics::thread_cpu_s();
            p.step(&f, clock.step(), &mut events);
            let took = t.elapsed().as_secs_f64();
            if let (Some(a), Some(b)) = (ran, vesalius::diagnostics::thread_cpu_s()) {
                step_thread_s.push(b - a);
            }
            let wait = vesalius::gpu::compute::waited_ns().saturating_sub(waited) as f64 * 1e-9;
            step_cpu_s.push((took - wait).max(0.0));
            step_wait_s.push(wait);
            events.clear();
            clock.tick();
            if clock.step().is_multiple_of(every) {
                let t = Instant::now();
                let job = {
                    let _span = tracing::debug_span!("snapshot").entered();
                    p.snapshot_job(clock.step())
                };
                frame_s.push(t.elapsed().as_secs_f64());
                bus.publish_job(job);
            }
            step_wall_s.push(began.elapsed().as_secs_f64());
        }
    });
    // Every snapshot built before the clock stops.
    bus.flush();
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
            compute: Default::default(),
            frames: Default::default(),
            pace: Default::default(),
        }
    };
    let models = p.model_reports();
    let awake = p.awake_fractions();
    let mut out: Vec<BenchLine> = models
        .iter()
        .zip(p.model_times())
        .zip(&awake)
        // A part not timed on its own (the cholecystectomy's parts, one solver on a GPU)
        // has no line: only the procedure's says what it took.
        .filter(|((_, t), _)| *t > 0.0)
        .map(|((m, t), a)| BenchLine {
            mass_spring: m.mass_spring,
            compute: on_gpu(m.gpu.clone()),
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
    let adapter = models.iter().find_map(|m| m.gpu.clone());
    let figures = step_figures(step_cpu_s, step_wait_s, &step_thread_s);
    let steps_on_device = adapter.is_some().then_some(figures);
    out.push(BenchLine {
        compute: vesalius::sim::ComputeFigures {
            step_cpu_ms_median: steps_on_device.map(|s| s.median),
            step_cpu_ms_mean: steps_on_device.map(|s| s.mean),
            step_cpu_ms_p99: steps_on_device.map(|s| s.p99),
            step_thread_cpu_ms_mean: steps_on_device.and_then(|s| s.thread_mean),
            step_wait_ms_median: steps_on_device.map(|s| s.wait_median),
            ..on_gpu(adapter)
        },
        // Every procedure's: on the CPU a step's forces wait for the whole step too.
        pace: vesalius::sim::StepPace {
            step_ms_p99: Some(figures.whole_p99).filter(|t| t.is_finite()),
            realtime_factor_slowest_s: vesalius::sim::StepPace::slowest_second(
                &step_wall_s,
                f64::from(dt),
            ),
        },
        frames: FrameFigures::of(&frame_s, &bus.take_build_seconds(), wall),
        ..line("procedure".to_string(), wall, total, share)
    });
    Ok(out)
}

/// A procedure's steps on a device: their CPU parts' median, mean and 99th percentile, their
/// waits' median, the whole steps' 99th percentile, and the simulation thread's own CPU time
/// a step on average, ms.
#[derive(Clone, Copy)]
struct StepFigures {
    median: f64,
    mean: f64,
    p99: f64,
    wait_median: f64,
    whole_p99: f64,
    thread_mean: Option<f64>,
}

/// The figures of the steps' CPU parts `cpu`, their waits `wait` and the simulation thread's
/// CPU time in each, `thread` (seconds; none where the OS keeps no thread clock).
fn step_figures(mut cpu: Vec<f64>, mut wait: Vec<f64>, thread: &[f64]) -> StepFigures {
    use vesalius::assess::{questionnaire::mean, stats::quantile};
    let mut whole: Vec<f64> = cpu.iter().zip(&wait).map(|(c, w)| c + w).collect();
    whole.sort_by(f64::total_cmp);
    cpu.sort_by(f64::total_cmp);
    wait.sort_by(f64::total_cmp);
    let ms = |v: &[f64], p: f64| quantile(v, p).map_or(f64::NAN, |s| 1e3 * s);
    StepFigures {
        median: ms(&cpu, 0.5),
        mean: mean(&cpu).map_or(f64::NAN, |s| 1e3 * s),
        p99: ms(&cpu, 0.99),
        wait_median: ms(&wait, 0.5),
        whole_p99: ms(&whole, 0.99),
        thread_mean: mean(thread).map(|s| 1e3 * s),
    }
}

/// A line's backend: the GPU `adapter` names, or (none) the CPU, said by leaving it out.
fn on_gpu(adapter: Option<String>) -> vesalius::sim::ComputeFigures {
    vesalius::sim::ComputeFigures {
        backend: adapter.as_ref().map(|_| "gpu"),
        adapter,
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_steps_figures_are_its_cpu_parts_quantiles_and_mean_in_ms() {
        // Nine steps of 1 ms and one of 11 ms: the slow one lifts the mean to 2 ms and the
        // 99th percentile near it, and leaves the median at 1 ms.
        let mut cpu = vec![1e-3; 9];
        cpu.insert(3, 11e-3);
        let wait = vec![5e-3, 1e-3, 3e-3];
        let f = step_figures(cpu, wait, &[2e-3, 4e-3]);
        assert!((f.median - 1.0).abs() < 1e-9, "{}", f.median);
        assert!((f.mean - 2.0).abs() < 1e-9, "{}", f.mean);
        assert!(f.p99 > 10.0 && f.p99 <= 11.0, "{}", f.p99);
        assert!((f.wait_median - 3.0).abs() < 1e-9, "{}", f.wait_median);
        assert!(f.thread_mean.is_some_and(|t| (t - 3.0).abs() < 1e-9));
        // A whole step is its own CPU part and wait: the slowest CPU part and the longest
        // wait fall in different steps here, so the whole steps' 99th percentile is near
        // the slowest whole step (11.5 ms), not their sum (16 ms).
        let f = step_figures(vec![1e-3, 1e-3, 11e-3], vec![5e-3, 1e-3, 0.5e-3], &[]);
        assert!(f.whole_p99 > 11.0 && f.whole_p99 <= 11.5, "{}", f.whole_p99);
        let none = step_figures(Vec::new(), Vec::new(), &[]);
        assert!(none.mean.is_nan() && none.thread_mean.is_none());
    }

    #[test]
    fn an_unknown_procedure_is_named() {
        let e = run("appendectomy", "x.toml", "").expect_err("no such procedure");
        assert!(matches!(&e, BenchError::NoSuchProcedure(p) if p == "appendectomy"));
        assert_eq!(e.to_string(), "no procedure 'appendectomy'");
    }

    /// `bench --scenario FILE`: a bad value is named with the file it came from.
    #[test]
    fn a_bad_scenario_file_is_named_with_its_key() {
        let text = vesalius::registry::builtin("sandbox")
            .unwrap_or_default()
            .replace("dt_s = ", "dt_s = -1.0 #");
        let e = run("sandbox", "tuned.toml", &text).expect_err("a negative step");
        let said = e.to_string();
        assert!(
            said.contains("tuned.toml") && said.contains("dt_s"),
            "{said}"
        );
    }
}
