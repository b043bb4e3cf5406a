//! `check`, `bench`, `verify` and `xr-sim manifest`.

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
