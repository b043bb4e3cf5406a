//! The particle solver's line of `vesalius bench cholecystectomy --compute gpu`: every set the
//! GPU's kernels step (shape matching, the vessels, the ties, the cloth, the strands, the
//! contacts between bodies), at the scene's size, every particle awake, with no instrument
//! (the coupled pass that follows it plays the demo with the instruments on the device).

use super::gpu::Sweeps;
use super::solver::ParticleSolver;
use crate::gpu::{Gpu, RenderError};
use crate::sim::{BenchLine, ComputeFigures, ModelOutput, TissueModel};
use std::time::Instant;

/// Steps the GPU's result is checked against the CPU's over.
const CHECK_STEPS: usize = 20;

/// The line: steps of `dt_s` of a copy of `s` on `gpu` with no instrument, each as a session
/// takes it (its substeps submitted, the particles read back, the strands checked, the pairs
/// searched), for
/// `budget_s` wall seconds (at least 5 steps, at most 5,000); with the adapter, the substep
/// rate by the wall clock and the GPU's, the bytes a substep moves at the least and the
/// bandwidth that makes, the step's latency (p99), and the velocities' relative difference
/// from the CPU's after [`CHECK_STEPS`] steps from the same start, and the dispatches a
/// substep and submissions a step. `sweeps` says how the sweeps are dispatched and `ahead`
/// whether a step's two substeps share a submission (the line named
/// `particles_without_instruments`; `..._by_colour` for a dispatch per colour,
/// `..._unsplit` for a submission a substep).
pub fn bench_line(
    gpu: &Gpu,
    s: &ParticleSolver,
    dt_s: f32,
    budget_s: f64,
    sweeps: Sweeps,
    ahead: bool,
) -> Result<BenchLine, RenderError> {
    let mut cpu = s.copy_without_instruments();
    let mut dev = s.copy_without_instruments();
    dev.use_gpu_with(gpu, sweeps)?;
    dev.gpu_step_ahead(ahead);
    let mut out = ModelOutput::default();
    let lost = |dev: &mut ParticleSolver| match dev.take_device_note() {
        Some(note) => Err(RenderError::Device(note)),
        None => Ok(()),
    };
    for _ in 0..CHECK_STEPS {
        cpu.step(dt_s, &[], &mut out);
        dev.step(dt_s, &[], &mut out);
    }
    lost(&mut dev)?;
    let (mut diff, mut norm) = (0.0f64, 0.0f64);
    for (a, b) in dev.particles.v.iter().zip(&cpu.particles.v) {
        diff += f64::from((*a - *b).length_squared());
        norm += f64::from(b.length_squared());
    }
    let check = (diff / norm.max(f64::MIN_POSITIVE)).sqrt();
    let kernel0 = dev.gpu_kernel_seconds();
    let submissions0 = dev.gpu_submissions();
    let mut latencies = Vec::new();
    let t0 = Instant::now();
    let mut steps = 0u64;
    while steps < 5000 && (steps < 5 || t0.elapsed().as_secs_f64() < budget_s) {
        steps += 1;
        let t = Instant::now();
        dev.step(dt_s, &[], &mut out);
        latencies.push(t.elapsed().as_secs_f64());
    }
    let wall_s = t0.elapsed().as_secs_f64();
    lost(&mut dev)?;
    latencies.sort_by(f64::total_cmp);
    let p99 = latencies
        .get(((latencies.len() as f64 * 0.99).ceil() as usize).saturating_sub(1))
        .copied()
        .unwrap_or(0.0);
    let kernel = dev.gpu_kernel_seconds() - kernel0;
    let kernel_s = (kernel > 0.0).then_some(kernel);
    let n = dev.params.substeps.max(1) as usize;
    let substeps = steps * n as u64;
    let bytes = dev.gpu_bytes_per_substep().unwrap_or(0);
    let moved = bytes as f64 * substeps as f64;
    let sizes = dev.sizes();
    let name = match (sweeps, ahead) {
        (Sweeps::ByColour, _) => "particles_without_instruments_by_colour",
        (Sweeps::Scheduled, true) => "particles_without_instruments",
        (Sweeps::Scheduled, false) => "particles_without_instruments_unsplit",
    };
    let submissions = dev.gpu_submissions() - submissions0;
    let mut line = BenchLine::repeated(name, steps, wall_s);
    line.dt_s = dt_s;
    line.realtime_factor = line.steps_per_s * f64::from(dt_s);
    line.vertices = sizes.vertices;
    line.constraints = sizes.constraints;
    line.threads = 1;
    line.compute = ComputeFigures {
        backend: Some("gpu"),
        adapter: Some(gpu.describe()),
        substeps_per_step: Some(n),
        substeps_per_s: Some(substeps as f64 / wall_s.max(1e-12)),
        bytes_per_substep: Some(bytes),
        kernel_s,
        wall_s: Some(wall_s),
        gb_per_s: kernel_s.map(|k| moved / k.max(1e-12) * 1e-9),
        kernel_substeps_per_s: kernel_s.map(|k| substeps as f64 / k.max(1e-12)),
        latency_p99_ms: Some(1e3 * p99),
        check_rel_err: Some(check),
        dispatches_per_substep: dev.gpu_dispatches_per_substep(),
        submissions_per_step: Some(submissions as f64 / steps.max(1) as f64),
        ..ComputeFigures::default()
    };
    Ok(line)
}
