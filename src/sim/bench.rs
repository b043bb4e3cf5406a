//! What `vesalius bench` reports (its lines, a one-off computation's figures, why a
//! benchmark did not run), so that a procedure can add lines of its own; the command line
//! runs the benchmarks.

use super::BuildError;
use crate::scenario::InputError;
use serde::Serialize;

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
    pub mass_spring: super::MassSpring,
    /// A one-off computation's particulars (a precomputation's stages).
    #[serde(flatten)]
    pub once: Once,
    /// Where it ran and what the hardware did, for a line of a GPU compute path.
    #[serde(flatten)]
    pub compute: ComputeFigures,
    /// The snapshots a procedure's line built for renderers, as a live session does.
    #[serde(flatten)]
    pub frames: FrameFigures,
    /// How a procedure's steps kept time.
    #[serde(flatten)]
    pub pace: StepPace,
}

/// The snapshots built for renderers during a procedure's timed pass, one every
/// [`super::Plan::publish_every`] steps, each announced before its step
/// ([`super::ModelSet::read_whole_after_step`]), as a live session builds them: what the
/// procedure reads of the simulation on its thread ([`super::Procedure::snapshot_job`]),
/// the rest on the snapshot bus's builder thread ([`super::SnapshotBus::publish_job`]). The
/// line's rate counts both: the simulation's part as it runs, the builds as they keep the
/// simulation waiting and as the pass waits for the last (each left out of the JSON when
/// absent).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct FrameFigures {
    /// Snapshots built.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frames: Option<u64>,
    /// The mean time the simulation's thread spent on one, milliseconds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_ms: Option<f64>,
    /// The slowest one's, milliseconds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_ms_max: Option<f64>,
    /// The share of the pass's wall time the simulation's thread spent on them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub frame_share: Option<f64>,
    /// The builder thread's mean time on one, milliseconds (none where every snapshot was
    /// built on the simulation's thread).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub build_ms: Option<f64>,
}

impl FrameFigures {
    /// The figures of snapshots whose simulation's part took `seconds` each and whose
    /// builds took `built` on the builder thread, over a pass of `wall_s`.
    pub fn of(seconds: &[f64], built: &[f64], wall_s: f64) -> Self {
        let sum: f64 = seconds.iter().sum();
        let n = seconds.len();
        Self {
            frames: Some(n as u64),
            frame_ms: (n > 0).then(|| 1e3 * sum / n as f64),
            frame_ms_max: seconds.iter().copied().reduce(f64::max).map(|s| 1e3 * s),
            frame_share: Some(sum / wall_s.max(1e-12)),
            build_ms: (!built.is_empty())
                .then(|| 1e3 * built.iter().sum::<f64>() / built.len() as f64),
        }
    }
}

/// A GPU compute line's particulars (each left out of the JSON when absent): the backend and
/// adapter, the substeps and their rate by the wall clock and by the GPU's own clock, the
/// bytes a substep must move at the least and the bandwidth that makes, the latency from
/// submitting a step to having its results on the CPU, and how far the GPU's result is from
/// the CPU's on the same start.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct ComputeFigures {
    #[serde(skip_serializing_if = "Option::is_none")]
    pub backend: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub adapter: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub substeps_per_step: Option<usize>,
    /// Substeps a wall-clock second, submissions and readbacks included.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub substeps_per_s: Option<f64>,
    /// Substeps a second of the GPU's own clock (timestamp queries).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kernel_substeps_per_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bytes_per_substep: Option<u64>,
    /// The bytes moved over the GPU's time, GB/s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gb_per_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kernel_s: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wall_s: Option<f64>,
    /// The 99th percentile of a step's time from its submission to its results on the CPU.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub latency_p99_ms: Option<f64>,
    /// The relative difference from the CPU's result on the same start.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub check_rel_err: Option<f64>,
    /// Compute dispatches a substep (each waits for the one before it).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dispatches_per_substep: Option<usize>,
    /// Device submissions a step, each waited for (fewer than the substeps where a step's
    /// substeps share one).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub submissions_per_step: Option<f64>,
    /// A whole procedure's step with models on the device: the median, mean and 99th
    /// percentile of its time outside the waits for the device (the CPU's part, which 1.5 x
    /// real time leaves 0.67 ms of a 1 ms step on average: the mean is what real time asks
    /// of it), and the median of those waits, ms.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub step_cpu_ms_median: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub step_cpu_ms_mean: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub step_cpu_ms_p99: Option<f64>,
    /// The simulation thread's own CPU time a step on average (its OS clock, the waits
    /// included: wgpu's freeing once the device is done runs there; work a step hands to the
    /// pool's other threads not included), ms. Below the CPU part where the thread was kept
    /// off its core: on a software adapter, by the adapter's own threads.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub step_thread_cpu_ms_mean: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub step_wait_ms_median: Option<f64>,
}

/// How a procedure's steps kept time over its pass, on the CPU or with models on a device
/// (each left out of the JSON when absent).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StepPace {
    /// A whole step's time (its CPU part and its waits for a device), 99th percentile, ms:
    /// how long after a step begins its tool forces reach the haptic channel, at worst but
    /// 1 %.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub step_ms_p99: Option<f64>,
    /// The real-time factor of the pass's slowest simulated second (every run of a second's
    /// steps in a row, each step with its snapshot; the whole pass where it is shorter).
    /// Under 1, a person would have waited for the simulation in that second, whatever the
    /// mean says.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub realtime_factor_slowest_s: Option<f64>,
}

impl StepPace {
    /// The real-time factor of the slowest run of `1 / dt_s` steps in a row (all of them
    /// where there are fewer), of steps of `dt_s` that took `wall_s` each; none for none.
    pub fn slowest_second(wall_s: &[f64], dt_s: f64) -> Option<f64> {
        if wall_s.is_empty() || dt_s <= 0.0 {
            return None;
        }
        let n = ((1.0 / dt_s).round() as usize).clamp(1, wall_s.len());
        let mut sum: f64 = wall_s[..n].iter().sum();
        let mut most = sum;
        // Sliding: the window's time plus the step entering it, less the one leaving it.
        for k in n..wall_s.len() {
            sum += wall_s[k] - wall_s[k - n];
            most = most.max(sum);
        }
        Some(n as f64 * dt_s / most.max(1e-12))
    }
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

/// A procedure's benchmarks of its GPU compute path, on the device given.
pub type GpuBench = fn(&crate::gpu::Gpu) -> Result<Vec<BenchLine>, BenchError>;

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
            compute: ComputeFigures::default(),
            frames: FrameFigures::default(),
            pace: StepPace::default(),
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
/// default; each procedure says its own ([`super::ProcedureInfo::bench_all_awake_s`]).
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
    /// A model's own failure.
    #[error(transparent)]
    Model(#[from] super::ModelError),
    /// The GPU refused or lost the work.
    #[error(transparent)]
    Gpu(#[from] crate::gpu::RenderError),
    /// `--compute gpu` for a procedure none of whose models has a GPU path yet.
    #[error("{0} has no GPU compute path yet (run it with --compute cpu)")]
    NoGpuPath(String),
}

#[cfg(test)]
mod tests {
    use super::StepPace;

    #[test]
    fn the_slowest_second_finds_a_slow_stretch_that_the_mean_hides() {
        // Thirty steps of 0.1 s, each taking 0.05 s but three in a row taking 0.5 s: the
        // pass as a whole keeps up (3 s in 2.85 s), the second holding the slow three does
        // not (1 s in 1.85 s).
        let mut wall = vec![0.05; 30];
        wall[12..15].fill(0.5);
        let slowest = StepPace::slowest_second(&wall, 0.1).expect("steps");
        assert!((slowest - 1.0 / 1.85).abs() < 1e-9, "{slowest}");
        let mean = 3.0 / wall.iter().sum::<f64>();
        assert!(mean > 1.0 && slowest < 1.0);
        // Steady steps give the mean; a pass shorter than a second is taken whole.
        let even = StepPace::slowest_second(&[0.05; 30], 0.1).expect("steps");
        assert!((even - 2.0).abs() < 1e-9, "{even}");
        let short = StepPace::slowest_second(&[0.01, 0.03], 0.1).expect("steps");
        assert!((short - 5.0).abs() < 1e-9, "{short}");
        assert_eq!(StepPace::slowest_second(&[], 0.1), None);
    }
}
