//! `check`, `bench`, `profile` and `xr-sim manifest`.

use super::{CliError, ComputeArg, PresetArg, bench};
use std::path::{Path, PathBuf};
use vesalius::scenario::InputError;
use vesalius::trace::{KeyTrace, Recording};

/// Finds the simulated runtime library built with this binary (beside it, or in `deps/` where
/// cargo leaves a dependency's cdylib) and writes its runtime manifest.
pub fn xr_sim_manifest(out: Option<PathBuf>) -> Result<PathBuf, CliError> {
    let failed = |m: String| CliError::Failed(m);
    let exe =
        std::env::current_exe().map_err(|e| failed(format!("cannot find this executable: {e}")))?;
    let dir = exe
        .parent()
        .ok_or_else(|| failed(format!("{}: no parent folder", exe.display())))?;
    let name = "libvesalius_sim_runtime.so";
    // The newest build: `cargo build` copies the library up beside the executable, test
    // builds leave theirs in deps/, and either may be stale.
    let modified = |p: &PathBuf| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let lib = [dir.join(name), dir.join("deps").join(name)]
        .into_iter()
        .filter(|p| p.is_file())
        .max_by_key(modified)
        .ok_or_else(|| {
            failed(format!(
                "{name} is not beside {} (build it: cargo build --release --workspace)",
                exe.display()
            ))
        })?;
    let lib = lib
        .canonicalize()
        .map_err(|e| failed(format!("{}: {e}", lib.display())))?;
    let path = out.unwrap_or_else(|| dir.join("vesalius_sim_runtime.json"));
    let text = vesalius_sim_runtime::manifest(&lib.display().to_string());
    let tmp = path.with_extension("json.partial");
    std::fs::write(&tmp, text).map_err(|e| failed(format!("{}: {e}", tmp.display())))?;
    std::fs::rename(&tmp, &path).map_err(|e| failed(format!("{}: {e}", path.display())))?;
    Ok(path)
}

/// Validates each file by its kind; every file is checked, and the command fails if any did.
pub fn check(files: &[PathBuf]) -> Result<(), CliError> {
    let mut failed = 0;
    for f in files {
        match check_one(f) {
            Ok(kind) => say!("{}: ok ({kind})", f.display()),
            Err(e) => {
                failed += 1;
                tell!("{e}");
            }
        }
    }
    if failed > 0 {
        return Err(CliError::Failed(format!(
            "{failed} of {} files failed the check",
            files.len()
        )));
    }
    Ok(())
}

/// The kind of `path` by its content: a binary recording, or TOML that is a keyframed trace,
/// an interaction profile, simulated runtime settings or a scenario.
fn check_one(path: &Path) -> Result<&'static str, InputError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path)
        .map_err(|e| InputError::new(&file, "file", format!("cannot read: {e}")))?;
    if Recording::is_recording(&bytes) {
        let mut rec = Recording::decode(&file, &bytes)?;
        rec.resolve(&vesalius::registry::CATALOG, &file)?;
        vesalius::registry::plan(&format!("{file} (embedded scenario)"), &rec.scenario)?;
        return Ok(match rec.tail {
            vesalius::trace::Tail::Cut { .. } => "recorded trace, stops short: replays up to it",
            vesalius::trace::Tail::Ended { .. } => "recorded trace",
        });
    }
    let text = String::from_utf8(bytes)
        .map_err(|_| InputError::new(&file, "file", "is neither UTF-8 TOML nor a recording"))?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| InputError::toml(&file, &e))?;
    let has = |k: &str| table.contains_key(k);
    if has("left") || has("right") {
        let trace = KeyTrace::parse(&file, &text)?;
        vesalius::registry::CATALOG.lookup(&file, "procedure", &trace.procedure)?;
        Ok("keyframed trace")
    } else if has("items") && has("rating") {
        vesalius::assess::questionnaire::Questionnaire::parse(&file, &text)?;
        Ok("questionnaire")
    } else if has("node") && has("version") {
        vesalius::assess::load(&vesalius::registry::CATALOG, &file, &text)?;
        Ok("assessment tree")
    } else if has("profile") && has("bindings") {
        xr_bindings::profiles::Profile::parse(&file, &text)
            .map_err(|e| InputError::new(&file, "profile", e.to_string()))?;
        Ok("interaction profile")
    } else if has("out_dir") || has("inject") || has("frames_every") || has("trace") {
        vesalius_sim_runtime::Config::parse(&file, &text)
            .map_err(|e| InputError::new(&file, "settings", e.to_string()))?;
        Ok("simulated runtime settings")
    } else {
        vesalius::registry::plan(&file, &text)?;
        Ok("scenario")
    }
}

/// `bench [procedure]`: every registered procedure, or the one named.
pub fn bench(
    procedure: Option<&str>,
    json: bool,
    preset: Option<PresetArg>,
    scenario: Option<&std::path::Path>,
    compute: ComputeArg,
) -> Result<(), CliError> {
    let names: Vec<&str> = match procedure {
        Some(p) => vec![p],
        None => vesalius::registry::names().collect(),
    };
    // One device for every procedure's GPU lines.
    let gpu = match compute {
        ComputeArg::Gpu => Some(vesalius::gpu::Gpu::headless(false)?),
        ComputeArg::Auto => vesalius::gpu::Gpu::for_compute(vesalius::scenario::Compute::Auto)?,
        ComputeArg::Cpu => None,
    };
    for p in names {
        let (file, text) = super::session::scenario_text(p, scenario, preset, None)?;
        let lines = match &gpu {
            None => {
                // The CPU's figures: every model on the CPU, whatever the scenario says.
                let (file, text) = super::session::with_compute(file, text, Some(ComputeArg::Cpu))?;
                bench::run(p, &file, &text)?
            }
            Some(gpu) => match bench::run_gpu(p, gpu) {
                // Benching every procedure: those without a GPU path are passed over.
                Err(vesalius::sim::BenchError::NoGpuPath(name)) if procedure.is_none() => {
                    tell!("{name}: no GPU compute path yet");
                    continue;
                }
                other => {
                    // The kernel's lines, then the procedure with its models' GPU path on.
                    let mut lines = other?;
                    let (file, text) =
                        super::session::with_compute(file, text, Some(ComputeArg::Gpu))?;
                    lines.extend(bench::run_coupled(p, &file, &text)?);
                    lines
                }
            },
        };
        for l in &lines {
            if json {
                say!("{}", serde_json::to_string(l).unwrap_or_default());
            } else {
                let awake = if l.all_awake {
                    "all awake".to_string()
                } else {
                    format!("{:>5.1}% awake", 100.0 * l.awake_fraction)
                };
                say!(
                    "{:<14} {:>9.0} steps/s  dt {:.4} s  real-time x{:>6.2}  {:>12}  {:>6} vertices {:>6} triangles {:>7} constraints  ({} threads)",
                    l.model,
                    l.steps_per_s,
                    l.dt_s,
                    l.realtime_factor,
                    awake,
                    l.vertices,
                    l.triangles,
                    l.constraints,
                    l.threads
                );
                let fr = &l.frames;
                if let (Some(n), Some(mean), Some(max), Some(share)) =
                    (fr.frames, fr.frame_ms, fr.frame_ms_max, fr.frame_share)
                {
                    say!(
                        "{:<14} with {n} snapshots for renderers: {mean:.3} ms each on the simulation's thread (at most {max:.3}), {:.1}% of the time{}",
                        "",
                        100.0 * share,
                        fr.build_ms
                            .map(|b| format!("; built beside it in {b:.3} ms each"))
                            .unwrap_or_default()
                    );
                }
                let c = &l.compute;
                if let (Some(adapter), None) = (&c.adapter, c.substeps_per_s) {
                    // A model of the procedure stepping on the GPU, or the procedure.
                    match (
                        c.step_cpu_ms_median,
                        c.step_cpu_ms_mean,
                        c.step_cpu_ms_p99,
                        c.step_wait_ms_median,
                    ) {
                        (Some(median), Some(mean), Some(p99), Some(wait)) => say!(
                            "{:<14} on {adapter}: a step's CPU part {median:.3} ms median, {mean:.3} ms mean (p99 {p99:.3}; the thread's own CPU time {} ms) outside the device's {wait:.3} ms",
                            "",
                            c.step_thread_cpu_ms_mean
                                .map_or("-".to_string(), |t| format!("{t:.3}"))
                        ),
                        _ => say!("{:<14} on {adapter}", ""),
                    }
                } else if let Some(adapter) = &c.adapter {
                    let or_dash = |v: Option<f64>, f: fn(f64) -> String| v.map_or("-".into(), f);
                    say!(
                        "{:<14} on {adapter}: {} substeps/s by the wall, {} by the GPU's clock, {} GB/s ({} bytes a substep), step latency p99 {} ms, off the CPU by {}, {} dispatches a substep, {} submissions a step",
                        "",
                        or_dash(c.substeps_per_s, |v| format!("{v:.0}")),
                        or_dash(c.kernel_substeps_per_s, |v| format!("{v:.0}")),
                        or_dash(c.gb_per_s, |v| format!("{v:.0}")),
                        c.bytes_per_substep.unwrap_or(0),
                        or_dash(c.latency_p99_ms, |v| format!("{v:.3}")),
                        or_dash(c.check_rel_err, |v| format!("{v:.1e}")),
                        c.dispatches_per_substep
                            .map_or("-".into(), |d| d.to_string()),
                        or_dash(c.submissions_per_step, |v| format!("{v:.2}")),
                    );
                }
            }
        }
    }
    Ok(())
}
pub fn profile(
    procedure: Option<&str>,
    json: bool,
    eye_size: (u32, u32),
    two_pass: bool,
) -> Result<(), CliError> {
    use vesalius::profiler::mb;
    let info = match procedure {
        Some(p) => vesalius::registry::find(p),
        None => vesalius::registry::REGISTRY.first().copied(),
    }
    .ok_or_else(|| CliError::Usage("no such procedure".into()))?;
    let procedure = info.name;
    let text = info.scenario;
    let keys = KeyTrace::parse("builtin demo trace", info.demo_trace)?;
    // Simulate up to 40 % of the demo (mid-task: in the first procedure, the middle of the cut)
    // and render that instant with the simulation still alive, so total memory counts it as
    // Unity's profiler would.
    let file = format!("builtin {procedure} scenario");
    let (_, plan) = vesalius::registry::plan(&file, text)?;
    let dt = f64::from(plan.dt_s);
    let mut sim = (info.build)(&file, text)?;
    let steps = (keys.duration_s() * 0.4 / dt).ceil() as u64;
    let mut events = Vec::new();
    let t0 = std::time::Instant::now();
    for step in 0..steps {
        sim.step(&keys.sample(step as f64 * dt), step, &mut events);
        events.clear();
    }
    let sim_ms = t0.elapsed().as_secs_f64() * 1e3 / steps.max(1) as f64;
    let gpu = vesalius::render::Gpu::headless(!two_pass)?;
    // Five frames of the same instant: the first pays for pipeline warm-up.
    let snap = sim.snapshot(steps.saturating_sub(1));
    // The headset's frame: both eyes, the full operative field, the scope light.
    let look = vesalius::render::frames::Look::headset(info);
    let done = vesalius::render::frames::render_repeated(&gpu, &look, &snap, 5, eye_size, sim_ms)?;
    // Total memory as the last frame measured it: heap (simulation, snapshot, renderer) plus
    // every GPU buffer and texture, while all of them were alive.
    let ours = done.counters.last().cloned().unwrap_or_default();
    let heap = ours.total_memory_bytes.saturating_sub(ours.vram_bytes);
    let sim_parts = sim.memory();
    let sim_bytes: usize = sim_parts.iter().map(|(_, b)| b).sum();
    let steady: Vec<f64> = done.frame_ms.iter().skip(1).copied().collect();
    let frame_ms = steady.iter().sum::<f64>() / steady.len().max(1) as f64;
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
    Ok(())
}

/// `verify`: the reference cases as a table or JSON lines; fails when one is out of tolerance.
pub fn verify(
    json: bool,
    known_failures: bool,
    compute: ComputeArg,
    preset: Option<PresetArg>,
) -> Result<(), CliError> {
    use vesalius::verify;
    let on_gpu = match compute {
        ComputeArg::Cpu => false,
        ComputeArg::Gpu => true,
        ComputeArg::Auto => {
            vesalius::gpu::Gpu::for_compute(vesalius::scenario::Compute::Auto)?.is_some()
        }
    };
    let mut results = if on_gpu {
        // A clear error where there is no adapter at all, before the cases say "not run".
        vesalius::gpu::Gpu::headless(false)?;
        verify::run(&verify::gpu_cases_in(&vesalius::registry::CATALOG))
    } else {
        verify::run_all(&vesalius::registry::CATALOG)
    };
    if let Some(PresetArg::Cpu) = preset {
        results.extend(verify::run(&verify::preset_cases_in(
            &vesalius::registry::CATALOG,
        )));
    }
    let print = |results: &[verify::CaseResult]| -> Result<(), CliError> {
        if json {
            for r in results {
                say!("{}", serde_json::to_string(r).unwrap_or_default());
            }
        } else {
            for line in verify::table(results).lines() {
                say!("{line}");
            }
        }
        Ok(())
    };
    print(&results)?;
    if known_failures {
        if !json {
            say!("");
            say!("Known disagreements with physics (open work, not counted above):");
        }
        print(&verify::run(&verify::known_failures()))?;
    }
    let failed = results.iter().filter(|r| !r.passed).count();
    if failed > 0 {
        return Err(CliError::Failed(format!(
            "{failed} of {} reference cases are outside their tolerance",
            results.len()
        )));
    }
    Ok(())
}
