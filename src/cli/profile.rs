//! `profile`: a procedure's stereo frame at the headset's size, its counters beside the
//! paper's, and the same frames drawn with the simulation running beside them.

use super::{CliError, ComputeArg, PresetArg};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use vesalius::render::frames::{EyeFrames, Look};
use vesalius::session::Live;
use vesalius::sim::{HapticSlot, Pacing};
use vesalius::trace::KeyTrace;
use vesalius::xr::{Coupling, Stepper};

/// The headset's frame period (the Vive's 90 Hz panel), s.
const FRAME_S: f64 = 1.0 / 90.0;

/// How often the stand-in for a haptic servo looks at the haptic channel.
const SERVO_POLL: Duration = Duration::from_micros(100);

/// What frames drawn with the simulation running beside them measured: the frames' times,
/// how far the simulation kept up with the wall clock, and how often a haptic servo would
/// have found a fresh force.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Beside {
    /// Wall seconds the frames were drawn for.
    pub seconds: f64,
    pub frames: usize,
    /// Each frame from the snapshot's upload to the GPU's finish, ms: mean, 99th percentile,
    /// slowest.
    pub frame_ms: f64,
    pub frame_ms_p99: f64,
    pub frame_ms_max: f64,
    /// Simulated seconds stepped meanwhile, and their share of the wall seconds (1: the
    /// simulation kept real time beside the frames; it is paced, so never above 1).
    pub simulated_s: f64,
    pub realtime_factor: f64,
    /// How far the state a frame drew was behind the time the frame is shown at, ms (99th
    /// percentile).
    pub shown_lag_ms_p99: f64,
    /// The step, s, and the gaps between fresh forces on the haptic channel as a thread
    /// polling it every 0.1 ms saw them, ms (median, 99th percentile, largest); none where no step
    /// published a second force.
    pub dt_s: f64,
    pub force_updates: usize,
    pub force_gap_ms_median: Option<f64>,
    pub force_gap_ms_p99: Option<f64>,
    pub force_gap_ms_max: Option<f64>,
    /// `gpu` where a model stepped on a GPU (its adapter beside), else `cpu`.
    pub compute: &'static str,
    pub adapter: Option<String>,
    /// The models stepped on the frames' own device (`--share-device`), not one of their
    /// own.
    pub shared_device: bool,
}

/// The `q` quantile of `v` (sorted here), none for an empty one.
fn quantile(v: &mut [f64], q: f64) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    vesalius::assess::stats::quantile(v, q)
}

/// Polls `slot` until `stop` and returns the instants at which a new step's force appeared.
fn watch_forces(slot: Arc<HapticSlot>, stop: Arc<AtomicBool>) -> Vec<Instant> {
    let mut seen = Vec::new();
    let mut last = slot.latest().step;
    while !stop.load(Ordering::Relaxed) {
        let step = slot.latest().step;
        if step != last {
            seen.push(Instant::now());
            last = step;
        }
        std::thread::sleep(SERVO_POLL);
    }
    seen
}

/// Draws stereo frames at the headset's rate for `seconds` of wall time (or until the demo's
/// input ends) while `live` steps on its own thread in real time from where it stands, as in
/// a headset session with styluses bound (each step paced to the wall clock, snapshots built
/// beside the simulation); the frames ask for the demo's input at their display times.
pub fn frames_beside(
    frames: &mut EyeFrames<'_>,
    mut live: Live,
    keys: &KeyTrace,
    (seconds, shared_device): (f64, bool),
) -> Result<Beside, CliError> {
    let dt_s = f64::from(live.dt_s());
    let adapter = live.adapter();
    let t0_s = live.time_s();
    let end_s = keys.duration_s();
    // The wall clock from here to the thread's end bounds the steps paced within it.
    let start = Instant::now();
    live.pace_from_now();
    let stop = Arc::new(AtomicBool::new(false));
    let watcher = {
        let (slot, stop) = (live.haptics(), stop.clone());
        std::thread::Builder::new()
            .name("vesalius-servo-watch".into())
            .spawn(move || watch_forces(slot, stop))
            .map_err(|e| CliError::Failed(format!("cannot start the force watch: {e}")))?
    };
    let mut stepper = Stepper::start(live, Coupling::Paced, None)?;
    let mut frame_ms = Vec::new();
    let mut lag_ms = Vec::new();
    let mut drawn: Result<(), CliError> = Ok(());
    for k in 0u32.. {
        // Each frame is begun on the headset's beat, and shown one period later.
        let due = Duration::from_secs_f64(f64::from(k) * FRAME_S);
        if let Some(wait) = due.checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
        let now_s = start.elapsed().as_secs_f64();
        let shown_s = t0_s + now_s + FRAME_S;
        if now_s >= seconds || shown_s >= end_s {
            break;
        }
        // Each frame asks for the steps up to its display time, as a headset's does (a
        // simulation slower than real time works through them in order; those left at the
        // end are passed over).
        if stepper.collect(false).is_err()
            || stepper.frame(shown_s, keys.sample(shown_s).hands).is_err()
        {
            break;
        }
        let snap = stepper.snapshot();
        match frames.draw(&snap) {
            Ok((_, ms)) => frame_ms.push(ms),
            Err(e) => {
                drawn = Err(e.into());
                break;
            }
        }
        lag_ms.push((shown_s - snap.time_s).max(0.0) * 1e3);
    }
    // The steps asked for and not yet done are left undone.
    let live = stepper.finish_now(vesalius::session::ended::CLOSED);
    let wall_s = start.elapsed().as_secs_f64();
    stop.store(true, Ordering::Relaxed);
    let seen = watcher.join().unwrap_or_default();
    let live = live?;
    drawn?;
    let mut gaps: Vec<f64> = seen
        .windows(2)
        .map(|w| (w[1] - w[0]).as_secs_f64() * 1e3)
        .collect();
    let simulated_s = live.time_s() - t0_s;
    let frames_n = frame_ms.len();
    Ok(Beside {
        seconds: wall_s,
        frames: frames_n,
        frame_ms: frame_ms.iter().sum::<f64>() / frames_n.max(1) as f64,
        frame_ms_max: frame_ms.iter().copied().fold(0.0, f64::max),
        frame_ms_p99: quantile(&mut frame_ms, 0.99).unwrap_or(0.0),
        simulated_s,
        realtime_factor: simulated_s / wall_s.max(1e-9),
        shown_lag_ms_p99: quantile(&mut lag_ms, 0.99).unwrap_or(0.0),
        dt_s,
        force_updates: seen.len(),
        force_gap_ms_max: gaps.iter().copied().reduce(f64::max),
        force_gap_ms_median: quantile(&mut gaps, 0.5),
        force_gap_ms_p99: quantile(&mut gaps, 0.99),
        compute: if adapter.is_some() { "gpu" } else { "cpu" },
        adapter,
        shared_device,
    })
}

/// `profile`: the demo simulated to 40 % (the scenario with `preset` and `compute` laid over
/// it), five stereo frames of that instant with the counters, then `beside_s` seconds of
/// frames with the simulation stepping beside them ([`frames_beside`]; none for 0). With
/// `share`, the models with a GPU path step on the frames' device rather than on one of
/// their own.
pub fn profile(
    procedure: Option<&str>,
    json: bool,
    (eye_size, two_pass, share): ((u32, u32), bool, bool),
    (beside_s, preset, compute): (f64, Option<PresetArg>, Option<ComputeArg>),
) -> Result<(), CliError> {
    use vesalius::profiler::mb;
    let info = match procedure {
        Some(p) => vesalius::registry::find(p),
        None => vesalius::registry::REGISTRY.first().copied(),
    }
    .ok_or_else(|| CliError::Usage("no such procedure".into()))?;
    let procedure = info.name;
    let keys = KeyTrace::parse("builtin demo trace", info.demo_trace)?;
    // Simulate up to 40 % of the demo (mid-task: in the first procedure, the middle of the cut)
    // and render that instant with the simulation still alive, so total memory counts it as
    // Unity's profiler would.
    let (file, text) = super::session::scenario_text(procedure, None, preset, compute)?;
    let gpu = vesalius::render::Gpu::headless(!two_pass)?;
    let mut live = if share {
        gpu.sharing_for_compute(|| Live::new(&text, &file, Pacing::AsFastAsPossible))?
    } else {
        Live::new(&text, &file, Pacing::AsFastAsPossible)?
    };
    let dt = f64::from(live.dt_s());
    let steps = (keys.duration_s() * 0.4 / dt).ceil() as u64;
    let t0 = Instant::now();
    for step in 0..steps {
        live.step(keys.sample(step as f64 * dt))?;
    }
    let sim_ms = t0.elapsed().as_secs_f64() * 1e3 / steps.max(1) as f64;
    // Five frames of the same instant: the first pays for pipeline warm-up.
    let snap = live.snapshot();
    // The headset's frame: both eyes, the full operative field, the scope light.
    let look = Look::headset(info);
    let done = vesalius::render::frames::render_repeated(&gpu, &look, &snap, 5, eye_size, sim_ms)?;
    drop(snap);
    // Total memory as the last frame measured it: heap (simulation, snapshot, renderer) plus
    // every GPU buffer and texture, while all of them were alive.
    let ours = done.counters.last().cloned().unwrap_or_default();
    let heap = ours.total_memory_bytes.saturating_sub(ours.vram_bytes);
    let sim_parts = live.memory();
    let sim_bytes: usize = sim_parts.iter().map(|(_, b)| b).sum();
    let steady: Vec<f64> = done.frame_ms.iter().skip(1).copied().collect();
    let frame_ms = steady.iter().sum::<f64>() / steady.len().max(1) as f64;
    // Then frames at the headset's rate with the simulation going on beside them.
    let beside = if beside_s > 0.0 {
        let mut frames = EyeFrames::new(&gpu, &look, eye_size)?;
        Some(frames_beside(&mut frames, live, &keys, (beside_s, share))?)
    } else {
        None
    };
    if json {
        let v = serde_json::json!({
            "procedure": procedure,
            "device": done.device,
            "eye_size": [eye_size.0, eye_size.1],
            "frame_ms": frame_ms,
            "heap_measured": vesalius::profiler::heap_measured(),
            "heap_bytes": heap,
            "simulation_heap_bytes": sim_parts
                .iter()
                .map(|(k, b)| (k.to_string(), serde_json::json!(b)))
                .collect::<serde_json::Map<_, _>>(),
            "vesalius": ours,
            "paper": info.options.profile_reference.map(|f| {
                let [cpu, gpu] = f();
                serde_json::json!({ "cpu": cpu, "gpu": gpu })
            }),
            "beside": beside,
            "gpu_devices": vesalius::gpu::Gpu::devices_opened(),
        });
        say!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(());
    }
    let paper = info.options.profile_reference.map(|f| f());
    say!(
        "{procedure} on {} ({}x{} per eye, {} pass{}), {frame_ms:.1} ms per stereo frame",
        done.device,
        eye_size.0,
        eye_size.1,
        ours.passes,
        if ours.passes == 1 {
            ", multiview"
        } else {
            "es"
        }
    );
    say!(
        "{:<22} {:>12} {:>12} {:>12}",
        "",
        "vesalius",
        "paper CPU",
        "paper GPU"
    );
    let ours_column = ours.column();
    let row = |name: &str,
               cell: &dyn Fn(&vesalius::profiler::PaperColumn) -> String|
     -> Result<(), CliError> {
        let a = cell(&ours_column);
        // A procedure whose paper gives no counters shows dashes there.
        let [b, c] = paper.as_ref().map_or_else(
            || ["–".to_string(), "–".to_string()],
            |p| p.each_ref().map(cell),
        );
        say!("{name:<22} {a:>12} {b:>12} {c:>12}");
        Ok(())
    };
    let mb1 = |b: u64| format!("{:.1} MB", mb(b));
    let cb =
        |c: vesalius::profiler::CountBytes| format!("{}/{:.0}KB", c.count, c.bytes as f64 / 1e3);
    row("batches", &|c| c.batches.to_string())?;
    row("draw calls", &|c| c.draw_calls.to_string())?;
    row("setpass calls", &|c| c.setpass_calls.to_string())?;
    row("triangles", &|c| c.triangles.to_string())?;
    row("vertices", &|c| c.vertices.to_string())?;
    row("VRAM", &|c| mb1(c.vram_bytes))?;
    row("total memory", &|c| mb1(c.total_memory_bytes))?;
    row("textures", &|c| cb(c.textures))?;
    row("meshes", &|c| cb(c.meshes))?;
    row("materials", &|c| cb(c.materials))?;
    row("objects", &|c| c.objects.to_string())?;
    say!(
        "cpu per stage: simulation {:.2} ms/step, render encode {:.2} ms, submit {:.2} ms",
        ours.cpu.simulation_ms,
        ours.cpu.render_encode_ms,
        ours.cpu.submit_ms
    );
    let mut parts = sim_parts.clone();
    parts.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(b.0)));
    let top: Vec<String> = parts
        .iter()
        .take(4)
        .map(|(k, b)| format!("{k} {:.1}", mb(*b as u64)))
        .collect();
    say!(
        "heap {:.1} MB, of which simulation {:.1} MB (largest: {})",
        mb(heap),
        mb(sim_bytes as u64),
        top.join(", ")
    );
    if let Some(b) = &beside {
        say!(
            "beside the simulation ({}{}{}): {} frames in {:.1} s, {:.1} ms mean, {:.1} ms p99, \
             {:.1} ms slowest; the simulation at {:.2} x real time, the state drawn {:.1} ms \
             behind (p99); fresh forces every {} ms (median; p99 {}; the step is {:.1} ms)",
            b.compute,
            b.adapter
                .as_deref()
                .map_or_else(String::new, |a| format!(" on {a}")),
            if b.shared_device {
                ", the frames' device"
            } else {
                ""
            },
            b.frames,
            b.seconds,
            b.frame_ms,
            b.frame_ms_p99,
            b.frame_ms_max,
            b.realtime_factor,
            b.shown_lag_ms_p99,
            b.force_gap_ms_median
                .map_or_else(|| "-".to_string(), |g| format!("{g:.2}")),
            b.force_gap_ms_p99
                .map_or_else(|| "-".to_string(), |g| format!("{g:.2}")),
            b.dt_s * 1e3
        );
    }
    Ok(())
}
