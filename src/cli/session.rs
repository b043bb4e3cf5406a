//! `run`, `replay` and `demo`: sessions headless, in the window, in a headset, and under the
//! simulated OpenXR runtime.

use super::{CliError, RunArgs};
use std::path::{Path, PathBuf};
use vesalius::registry::builtin;
use vesalius::session::{self, Input, Options, interrupt};
use vesalius::sim::Pacing;
use vesalius::trace::{KeyTrace, Recording, Tail};

/// The scenario a run uses: the file given, or the procedure's built-in one; with `--preset`,
/// the preset's keys laid over it.
pub(super) fn scenario_text(
    procedure: &str,
    scenario: Option<&Path>,
    preset: Option<super::PresetArg>,
    compute: Option<super::ComputeArg>,
) -> Result<(String, String), CliError> {
    let (file, text) = match scenario {
        Some(f) => (
            f.display().to_string(),
            std::fs::read_to_string(f)
                .map_err(|e| CliError::Failed(format!("{}: cannot read: {e}", f.display())))?,
        ),
        None => (
            format!("builtin {procedure} scenario"),
            builtin(procedure).unwrap_or_default().to_string(),
        ),
    };
    let (file, text) = with_preset(procedure, file, text, preset)?;
    with_compute(file, text, compute)
}

/// `text` (the scenario `file`) with its `compute` key set to `compute`'s choice, where one
/// is given.
pub(super) fn with_compute(
    file: String,
    text: String,
    compute: Option<super::ComputeArg>,
) -> Result<(String, String), CliError> {
    let Some(c) = compute else {
        return Ok((file, text));
    };
    let name = vesalius::scenario::Compute::from(c).name();
    let merged = vesalius::scenario::with_preset(
        &file,
        &text,
        "--compute",
        &format!("compute = \"{name}\""),
    )?;
    Ok((format!("{file} with compute = {name}"), merged))
}

/// `--preset` as given. Where none is, a run of `procedure`'s own scenario (no `--scenario`)
/// whose models choose their device by `auto` (no `--compute` but `auto`, and no other
/// `compute` in the scenario) takes the procedure's CPU preset on a machine without a real
/// GPU, and says so: at the paper's sizes such a procedure does not keep real time on the
/// CPU (`--compute cpu` runs them there all the same). A procedure without a preset, or a
/// machine with a real GPU, runs the scenario as it is.
pub(super) fn preset_for_auto(
    procedure: &str,
    scenario: Option<&Path>,
    preset: Option<super::PresetArg>,
    compute: Option<super::ComputeArg>,
) -> Option<super::PresetArg> {
    if preset.is_some() || scenario.is_some() {
        return preset;
    }
    use vesalius::scenario::Compute;
    let info = vesalius::registry::find(procedure)?;
    info.options.cpu_preset?;
    // `--compute`, else the scenario's own key (`auto` where it has none).
    let chosen = match compute {
        Some(c) => Compute::from(c),
        None => info
            .scenario
            .parse::<toml::Table>()
            .ok()
            .and_then(|t| t.get("compute")?.clone().try_into::<Compute>().ok())
            .unwrap_or_default(),
    };
    if chosen != Compute::Auto || vesalius::gpu::Gpu::real_gpu_present() {
        return None;
    }
    tell!(
        "{procedure}: no GPU here, so `auto` runs its cpu preset \
         (assets/presets/cpu/{procedure}.toml), which keeps real time on the CPU; \
         --compute cpu runs the paper's sizes"
    );
    Some(super::PresetArg::Cpu)
}

/// `text` (the scenario `file`) with `preset`'s keys laid over it; unchanged, with a word on
/// standard error, for a procedure without that preset.
pub(super) fn with_preset(
    procedure: &str,
    file: String,
    text: String,
    preset: Option<super::PresetArg>,
) -> Result<(String, String), CliError> {
    let Some(super::PresetArg::Cpu) = preset else {
        return Ok((file, text));
    };
    match vesalius::registry::find(procedure).and_then(|p| p.options.cpu_preset) {
        Some(overlay) => {
            let name = format!("the {procedure} cpu preset (assets/presets/cpu/{procedure}.toml)");
            let merged = vesalius::scenario::with_preset(&file, &text, &name, overlay)?;
            Ok((format!("{file} with {name}"), merged))
        }
        None => {
            tell!("{procedure}: no cpu preset; it runs at its own sizes");
            Ok((file, text))
        }
    }
}

/// A keyframed trace, checked to be for `procedure` and no longer than `max_s`.
fn load_trace(path: &Path, procedure: &str, max_s: f64) -> Result<KeyTrace, CliError> {
    let keys = KeyTrace::load_within(path, max_s)?;
    if keys.procedure != procedure {
        return Err(CliError::Failed(format!(
            "{}: procedure: trace is for '{}', not '{procedure}'",
            path.display(),
            keys.procedure
        )));
    }
    Ok(keys)
}

/// After a session: a signal that ended it becomes the exit code.
pub(super) fn interrupted() -> Result<(), CliError> {
    match interrupt::interrupted() {
        Some(signal) => Err(CliError::Interrupted {
            signal,
            name: interrupt::signal_name(signal),
        }),
        None => Ok(()),
    }
}

/// An assessment tree given on the command line, checked to be for `procedure` before the
/// session is built.
fn load_tree(
    path: Option<&Path>,
    procedure: &str,
) -> Result<Option<(String, vesalius::assess::Tree)>, CliError> {
    let Some(path) = path else {
        return Ok(None);
    };
    let tree = vesalius::assess::load_file(&vesalius::registry::CATALOG, path)?;
    if tree.procedure != procedure {
        return Err(CliError::Failed(format!(
            "{}: procedure: the tree is for '{}', not '{procedure}'",
            path.display(),
            tree.procedure
        )));
    }
    Ok(Some((path.display().to_string(), tree)))
}

/// Prints the outcome and writes the output set.
pub(super) fn finish(outcome: &session::Outcome, out: Option<&Path>) -> Result<(), CliError> {
    if let Some(dir) = out {
        session::write_outputs(outcome, dir)?;
    }
    let r = &outcome.report;
    say!(
        "{}: completed={} ended={} steps={} simulated={:.2}s score={:.1} level={} cuts={} wall={:.2}s ({:.2}x real time)",
        r.procedure,
        r.completed,
        r.ended,
        r.steps,
        r.simulated_s,
        r.score,
        r.level,
        r.events.get("cut").copied().unwrap_or(0),
        outcome.wall_s,
        r.simulated_s / outcome.wall_s.max(1e-9)
    );
    if let Some(dir) = out {
        say!("wrote {} (session {})", dir.display(), r.session_id);
    }
    Ok(())
}

/// `run`: picks the window, headless, XR or simulated-XR path.
pub fn run(a: RunArgs) -> Result<(), CliError> {
    // Styluses in the headset go with the XR session below.
    if !a.haptics.is_empty() && !a.xr && a.xr_sim.is_none() {
        return super::haptics::run_with_devices(&a);
    }
    if a.records.is_some() && (a.xr_sim.is_some() || a.no_window) {
        return Err(CliError::Usage(
            "--records: headless and window sessions are stored; not --xr-sim or --no-window \
             (store their output folder with `vesalius records import`)"
                .into(),
        ));
    }
    if a.xr || a.xr_sim.is_some() {
        return match &a.xr_sim {
            Some(trace) => run_xr_sim(&a, trace),
            None => run_xr(&a),
        };
    }
    if a.no_window {
        return Err(CliError::Usage(
            "--no-window: without a window, use --headless (or --xr)".into(),
        ));
    }
    if a.xr_duration.is_some() {
        return Err(CliError::Usage(
            "--xr-duration: only with --xr or --xr-sim".into(),
        ));
    }
    if a.xr_coupling.is_some() {
        return Err(CliError::Usage(
            "--xr-coupling: only with --xr or --xr-sim".into(),
        ));
    }
    if a.xr_max_lag.is_some() {
        return Err(CliError::Usage(
            "--xr-max-lag: only with --xr or --xr-sim".into(),
        ));
    }
    if !a.headless {
        return run_window(&a, None, None);
    }
    let Some(trace) = &a.trace else {
        return Err(CliError::Usage("run --headless needs --trace FILE".into()));
    };
    let preset = preset_for_auto(&a.procedure, a.scenario.as_deref(), a.preset, a.compute);
    let (file, text) = scenario_text(&a.procedure, a.scenario.as_deref(), preset, a.compute)?;
    let keys = load_trace(trace, &a.procedure, a.max_session)?;
    let tree = load_tree(a.assessment.as_deref(), &a.procedure)?;
    let frames = a.frames.unwrap_or(0);
    let opts = Options {
        assessment: tree.as_ref().map(|(f, t)| (f.as_str(), t)),
        pacing: if a.realtime {
            Pacing::RealTime
        } else {
            Pacing::AsFastAsPossible
        },
        bus: None,
        frames_wanted: frames,
        out: a.out.as_deref(),
    };
    let outcome = session::run_with(&text, &file, Input::Keys(keys), &opts)?;
    finish(&outcome, a.out.as_deref())?;
    if let (Some(db), Some(dir), Some(trainee)) = (&a.records, &a.out, &a.trainee) {
        super::records::store(db, dir, trainee)?;
    }
    interrupted()?;
    if let (Some(dir), true) = (&a.out, frames > 0) {
        render_frames(&outcome, dir, a.eye_size)?;
    }
    Ok(())
}

/// Renders the captured snapshots into DIR/frames/ and DIR/profiler.csv.
fn render_frames(
    outcome: &session::Outcome,
    dir: &Path,
    eye_size: Option<(u32, u32)>,
) -> Result<(), CliError> {
    let eye_size = eye_size.unwrap_or(vesalius::render::camera::VIVE_EYE_SIZE);
    let gpu = vesalius::render::Gpu::headless(true)?;
    let sim_ms = outcome.wall_s * 1e3 / outcome.report.steps.max(1) as f64;
    let info = vesalius::registry::find(&outcome.report.procedure)
        .unwrap_or(vesalius::registry::REGISTRY[0]);
    // The frames show what the procedure's laparoscope shows on its monitor.
    let look = vesalius::render::frames::Look::monitor(info);
    let done = vesalius::render::frames::render_snapshots(
        &gpu,
        &look,
        &outcome.captured,
        1,
        eye_size,
        sim_ms,
        Some(&dir.join("frames")),
    )?;
    vesalius::render::frames::write_profiler_csv(&dir.join("profiler.csv"), &done.counters)?;
    let mean = done.frame_ms.iter().sum::<f64>() / done.frame_ms.len().max(1) as f64;
    say!(
        "rendered {} stereo frames {}x{} per eye on {}: {:.1} ms per frame",
        done.counters.len(),
        eye_size.0,
        eye_size.1,
        done.device,
        mean
    );
    Ok(())
}

/// Whether a window can open here (an X11 or Wayland display is named).
pub(super) fn display_available() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

/// `run <p>` without `--headless`: the desktop window, played by a trace or driven by the
/// desktop controls; with `xr`, the mirror of a headset session.
pub(super) fn run_window(
    a: &RunArgs,
    xr: Option<vesalius::xr::XrOptions>,
    devices: Option<vesalius::ui::window::WindowDevices>,
) -> Result<(), CliError> {
    let procedure = a.procedure.as_str();
    let preset = preset_for_auto(procedure, a.scenario.as_deref(), a.preset, a.compute);
    let (file, text) = scenario_text(procedure, a.scenario.as_deref(), preset, a.compute)?;
    let trace = match &a.trace {
        Some(t) => {
            let keys = load_trace(t, procedure, a.max_session)?;
            let name = t
                .file_name()
                .map_or_else(|| t.display().to_string(), |n| n.to_string_lossy().into());
            Some((keys, name))
        }
        None => None,
    };
    if let Some(p) = a.screenshot.as_deref().and_then(Path::parent)
        && !p.as_os_str().is_empty()
        && !p.is_dir()
    {
        return Err(CliError::Usage(format!(
            "--screenshot: folder {} does not exist",
            p.display()
        )));
    }
    if let Some(dir) = &a.out {
        session::prepare(dir)?;
    }
    // The sliders' "save" writes back into the scenario file the session runs; with the
    // built-in scenario, a new file beside the outputs.
    let save_tuning_to = match (&a.scenario, &a.out) {
        (Some(f), _) => f.clone(),
        (None, Some(dir)) => dir.join(format!("{procedure}-tuned.toml")),
        (None, None) => PathBuf::from(format!("{procedure}-tuned.toml")),
    };
    let run = vesalius::ui::window::run(vesalius::ui::window::WindowOptions {
        procedure: procedure.to_string(),
        scenario_text: text,
        scenario_file: file,
        trace,
        out: a.out.clone(),
        screenshot: a.screenshot.clone(),
        screenshot_at_s: a.screenshot_at,
        size: a.window_size,
        save_tuning_to,
        xr,
        devices,
        records: a.records.clone().zip(a.trainee.clone()),
        start_now: a.start,
    })?;
    if let Some((runtime, frames, sessions, (w, h))) = &run.xr {
        say!(
            "XR runtime '{runtime}' on {}: {frames} stereo frames at {w}x{h} per eye, {sessions} session(s)",
            run.device
        );
    }
    if run.xr.is_some() {
        say!(
            "window on {}: {} frames, {} of them drawing the scene (the rest mirrored an eye)",
            run.device,
            run.frames,
            run.scene_renders
        );
    } else {
        say!("window on {}: {} frames", run.device, run.frames);
    }
    if let Some(((w, h), path)) = &run.screenshot {
        say!("screenshot {w}x{h} written to {}", path.display());
    }
    // The window wrote the session's files when it ended; report it here like the others.
    finish(&run.outcome, None)?;
    super::haptics::say_devices(&run.devices)?;
    if let Some(dir) = &a.out {
        say!(
            "wrote {} (session {})",
            dir.display(),
            run.outcome.report.session_id
        );
    }
    interrupted()
}

/// The bound on a paced session's lag that `--xr-max-lag` gives (none for `inf`; 0.1 s by
/// default); a value that is not a positive number of seconds is a usage error.
fn max_lag(given: Option<f64>) -> Result<Option<f64>, CliError> {
    match given {
        None => Ok(Some(DEFAULT_MAX_LAG_S)),
        Some(s) if s == f64::INFINITY => Ok(None),
        Some(s) if s.is_finite() && s > 0.0 => Ok(Some(s)),
        Some(s) => Err(CliError::Usage(format!(
            "--xr-max-lag {s}: a positive number of seconds is expected (or inf for no bound)"
        ))),
    }
}

/// How far a paced headset session's simulation may fall behind its frames by default, s:
/// about nine frames at 90 Hz, well past what a simulation that keeps real time ever lags
/// (a frame or two in flight).
const DEFAULT_MAX_LAG_S: f64 = 0.1;

/// `run <p> --xr`: a session in the headset of whatever OpenXR runtime is active.
fn run_xr(a: &RunArgs) -> Result<(), CliError> {
    if a.headless || a.trace.is_some() {
        return Err(CliError::Usage(
            "--xr runs in the headset: drop --headless/--trace (the simulated runtime plays a trace with --xr-sim TRACE)".into(),
        ));
    }
    let opts = vesalius::xr::XrOptions {
        duration_s: a.xr_duration,
        eye_size: a.eye_size,
        coupling: a
            .xr_coupling
            .map_or(vesalius::xr::Coupling::Paced, Into::into),
        max_lag_s: max_lag(a.xr_max_lag)?,
        assessment: load_tree(a.assessment.as_deref(), &a.procedure)?,
    };
    let devices = super::haptics::xr_devices(a)?;
    // The supervisor's mirror opens beside the headset wherever there is a display.
    if !a.no_window && display_available() {
        let devices = devices.map(|d| vesalius::ui::window::WindowDevices {
            devices: d.devices,
            options: d.options,
            until_s: None,
        });
        return run_window(a, Some(opts), devices);
    }
    if a.screenshot.is_some() {
        return Err(CliError::Usage(
            "--screenshot needs a window: no DISPLAY (try xvfb-run), or drop --no-window".into(),
        ));
    }
    if !a.no_window {
        tell!("no display: running in the headset only (--no-window to say so)");
    }
    if let Some(dir) = &a.out {
        session::prepare(dir)?;
    }
    let preset = preset_for_auto(&a.procedure, a.scenario.as_deref(), a.preset, a.compute);
    let (file, text) = scenario_text(&a.procedure, a.scenario.as_deref(), preset, a.compute)?;
    let run = vesalius::xr::run(&text, &file, opts, a.out.as_deref(), devices)?;
    say!(
        "XR runtime '{}' on {}: {} stereo frames at {}x{} per eye, {} session(s)",
        run.runtime,
        run.device,
        run.frames,
        run.eye_size.0,
        run.eye_size.1,
        run.sessions
    );
    if run.slowed_s > 0.0 {
        say!(
            "the simulation fell behind the headset: it ran {:.2} s of display time slower, \
             to stay within --xr-max-lag of the frames",
            run.slowed_s
        );
    }
    finish(&run.outcome, a.out.as_deref())?;
    super::haptics::say_devices(&run.devices)?;
    // A device's fault, once the session's record is safe.
    if let Some(e) = run.device_error {
        return Err(e.into());
    }
    interrupted()
}

/// `run <p> --xr-sim TRACE --out DIR`: the same XR session under the simulated runtime, which
/// plays TRACE as head and controller motion and writes its logs and frames to DIR/xr-sim/.
/// The settings named by `VESALIUS_XR_SIM_CONFIG`, if set, are kept (faults to inject, frame
/// dumps) with the trace and output folder replaced. The loader reads the runtime's location
/// from the environment, so the session runs in a child process that has it set.
fn run_xr_sim(a: &RunArgs, trace: &Path) -> Result<(), CliError> {
    if a.headless || a.trace.is_some() {
        return Err(CliError::Usage(
            "--xr-sim plays its own trace: drop --headless/--trace".into(),
        ));
    }
    let Some(out) = a.out.as_deref() else {
        return Err(CliError::Usage(
            "--xr-sim needs --out DIR (its outputs go to DIR/xr-sim/)".into(),
        ));
    };
    let keys = load_trace(trace, &a.procedure, a.max_session)?;
    session::prepare(out)?;
    let sim_dir = out.join("xr-sim");
    let failed = |p: &Path, e: std::io::Error| CliError::Failed(format!("{}: {e}", p.display()));
    std::fs::create_dir_all(&sim_dir).map_err(|e| failed(&sim_dir, e))?;
    let sim_abs = sim_dir.canonicalize().map_err(|e| failed(&sim_dir, e))?;
    let trace_abs = trace.canonicalize().map_err(|e| failed(trace, e))?;
    let manifest = super::tools::xr_sim_manifest(Some(sim_abs.join("runtime.json")))?;
    let mut settings = match std::env::var_os(vesalius_sim_runtime::CONFIG_ENV) {
        Some(f) if !f.is_empty() => {
            let f = PathBuf::from(f);
            let text = std::fs::read_to_string(&f).map_err(|e| failed(&f, e))?;
            vesalius_sim_runtime::Config::parse(&f.display().to_string(), &text)?;
            text.parse::<toml::Table>()
                .map_err(|e| CliError::Failed(format!("{}: {e}", f.display())))?
        }
        _ => toml::Table::new(),
    };
    settings.insert("out_dir".into(), sim_abs.display().to_string().into());
    settings.insert("trace".into(), trace_abs.display().to_string().into());
    let config = sim_abs.join("settings.toml");
    let text = format!(
        "# Written by `vesalius run --xr-sim`: the simulated runtime's settings.\n{}",
        toml::to_string(&settings).map_err(|e| CliError::Failed(e.to_string()))?
    );
    std::fs::write(&config, text).map_err(|e| failed(&config, e))?;
    let exe = std::env::current_exe()
        .map_err(|e| CliError::Failed(format!("cannot find this executable: {e}")))?;
    let duration = a
        .xr_duration
        .unwrap_or(keys.duration_s() + session::SETTLE_S);
    let mut cmd = std::process::Command::new(exe);
    cmd.args(["run", &a.procedure, "--xr", "--out"])
        .arg(out)
        .args(["--xr-duration", &format!("{duration}")])
        .args(["--max-session", &format!("{}", a.max_session)])
        .args([
            "--xr-coupling",
            match a.xr_coupling.unwrap_or(super::CouplingArg::Lockstep) {
                super::CouplingArg::Paced => "paced",
                super::CouplingArg::Lockstep => "lockstep",
            },
        ])
        .env("XR_RUNTIME_JSON", &manifest)
        .env(vesalius_sim_runtime::CONFIG_ENV, &config);
    if let Some(s) = a.xr_max_lag {
        cmd.args(["--xr-max-lag", &format!("{s}")]);
    }
    if let Some(f) = &a.scenario {
        cmd.arg("--scenario").arg(f);
    }
    if !a.haptics.is_empty() {
        cmd.args(["--haptics", &super::haptics::device_words(&a.haptics)])
            .args(["--workspace-scale", &a.workspace_scale.to_string()]);
        if !a.hd_names.is_empty() {
            cmd.args(["--hd-names", &a.hd_names.join(",")]);
        }
    }
    if let Some(super::PresetArg::Cpu) = a.preset {
        cmd.args(["--preset", "cpu"]);
    }
    if let Some(c) = a.compute {
        cmd.args(["--compute", vesalius::scenario::Compute::from(c).name()]);
    }
    if let Some(f) = &a.assessment {
        // Checked here, so a bad tree is named before the runtime starts.
        load_tree(Some(f), &a.procedure)?;
        cmd.arg("--assessment").arg(f);
    }
    if let Some((w, h)) = a.eye_size {
        cmd.args(["--eye-size", &format!("{w}x{h}")]);
    }
    if a.no_window {
        cmd.arg("--no-window");
    }
    if let Some(s) = &a.screenshot {
        cmd.arg("--screenshot").arg(s);
    }
    if let Some(at) = a.screenshot_at {
        cmd.args(["--screenshot-at", &at.to_string()]);
    }
    let (w, h) = a.window_size;
    cmd.args(["--window-size", &format!("{w}x{h}")]);
    let mut child = cmd
        .spawn()
        .map_err(|e| CliError::Failed(format!("cannot start the XR session: {e}")))?;
    // A signal for this process is passed on, so the session ends cleanly with its report.
    let mut forwarded = false;
    let status = loop {
        match child.try_wait() {
            Ok(Some(s)) => break s,
            Ok(None) => {}
            Err(e) => return Err(CliError::Failed(format!("waiting for the XR session: {e}"))),
        }
        if let (Some(_), false) = (interrupt::interrupted(), forwarded) {
            let _ = std::process::Command::new("kill")
                .args(["-TERM", &child.id().to_string()])
                .status();
            forwarded = true;
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    interrupted()?;
    if !status.success() {
        return Err(CliError::Failed(format!(
            "the XR session under the simulated runtime failed ({status})"
        )));
    }
    say!("simulated runtime outputs in {}", sim_dir.display());
    Ok(())
}

/// `replay`: the recorded session again into another folder, with `frames` stereo frames of
/// it rendered there if asked.
pub fn replay(
    recorded: &Path,
    out: &Path,
    frames: Option<u32>,
    eye_size: Option<(u32, u32)>,
    assessment: Option<&Path>,
    compute: Option<super::ComputeArg>,
) -> Result<(), CliError> {
    let mut rec = Recording::read(recorded)?;
    rec.resolve(
        &vesalius::registry::CATALOG,
        &recorded.display().to_string(),
    )?;
    let tree = load_tree(assessment, &rec.procedure)?;
    let own = recorded.parent().map(|p| {
        if p.as_os_str().is_empty() {
            Path::new(".")
        } else {
            p
        }
    });
    if let (Some(a), Ok(b)) = (own.and_then(|p| p.canonicalize().ok()), out.canonicalize())
        && a == b
    {
        return Err(CliError::Usage(format!(
            "--out {}: that is the recording's own folder; replay into another one",
            out.display()
        )));
    }
    if let Tail::Cut {
        complete_blocks,
        dropped_bytes,
    } = &rec.tail
    {
        tell!(
            "{}: the recording stops short (its session was killed or crashed): replaying its \
             {} steps in {complete_blocks} complete blocks ({dropped_bytes} trailing bytes dropped)",
            recorded.display(),
            rec.frames.len()
        );
    }
    let file = format!("{} (embedded scenario)", recorded.display());
    let (file, scenario) = with_compute(file, rec.scenario.clone(), compute)?;
    let opts = Options {
        out: Some(out),
        frames_wanted: frames.unwrap_or(0),
        assessment: tree.as_ref().map(|(f, t)| (f.as_str(), t)),
        ..Options::default()
    };
    let mut outcome = session::run_with(&scenario, &file, Input::Recorded(rec), &opts)?;
    if let Some(note) = own.and_then(|dir| backend_note(&dir.join(session::REPORT), &outcome)) {
        tell!("{note}");
        outcome.report.replay_note = Some(note);
    }
    finish(&outcome, Some(out))?;
    interrupted()?;
    if frames.is_some() {
        render_frames(&outcome, out, eye_size)?;
    }
    Ok(())
}

/// Where the recorded session's models stepped (its report beside the recording says; a report
/// from before the GPU path says nothing, and stepped on the CPU) against where the replay's
/// did: a note when they differ, since the bytes then may too.
fn backend_note(recorded_report: &Path, replay: &session::Outcome) -> Option<String> {
    let text = std::fs::read_to_string(recorded_report).ok()?;
    let was: serde_json::Value = serde_json::from_str(&text).ok()?;
    let was_compute = was["compute"].as_str().unwrap_or("cpu");
    let was_adapter = was["adapter"].as_str();
    let now = &replay.report;
    if was_compute == now.compute && was_adapter == now.adapter.as_deref() {
        return None;
    }
    let on = |compute: &str, adapter: Option<&str>| match adapter {
        Some(a) => format!("{compute} ({a})"),
        None => compute.to_string(),
    };
    Some(format!(
        "recorded on {}, replayed on {}: the replay's bytes may differ from the recording's \
         report (another backend or adapter sums the same forces in another order)",
        on(was_compute, was_adapter),
        on(now.compute, now.adapter.as_deref())
    ))
}

/// Stereo frames `vesalius demo` renders of each procedure, evenly spaced over its session.
const DEMO_FRAMES: u32 = 6;
/// Their size per eye: half the Vive's.
const DEMO_EYE_SIZE: (u32, u32) = (540, 600);

/// `demo`: every registered procedure's demo trace, headless, into DIR/<procedure>/, each
/// session stored for trainee 'demo' in the records (`records`, default DIR/records.sqlite).
pub fn demo(
    out: &Path,
    records: Option<&Path>,
    preset: Option<super::PresetArg>,
    compute: Option<super::ComputeArg>,
) -> Result<(), CliError> {
    let db = records.map_or_else(|| out.join("records.sqlite"), Path::to_path_buf);
    for p in vesalius::registry::REGISTRY {
        let keys = KeyTrace::parse(&format!("builtin {} demo trace", p.name), p.demo_trace)?;
        let dir = out.join(p.name);
        let opts = Options {
            out: Some(&dir),
            frames_wanted: DEMO_FRAMES,
            ..Options::default()
        };
        let (file, text) = with_preset(
            p.name,
            format!("builtin {} scenario", p.name),
            p.scenario.to_string(),
            preset_for_auto(p.name, None, preset, compute),
        )?;
        let (file, text) = with_compute(file, text, compute)?;
        let outcome = session::run_with(&text, &file, Input::Keys(keys), &opts)?;
        finish(&outcome, Some(&dir))?;
        interrupted()?;
        // A few stereo frames of the monitor image, and a contact sheet of them for people.
        render_frames(&outcome, &dir, Some(DEMO_EYE_SIZE))?;
        let sheet = dir.join("contact_sheet.png");
        vesalius::render::frames::contact_sheet(&dir.join("frames"), &sheet, 3)?;
        say!("contact sheet: {}", sheet.display());
        super::records::store(&db, &dir, "demo")?;
    }
    Ok(())
}
