//! The `vesalius` command line.
#![forbid(unsafe_code)]

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use vesalius::scenario::{InputError, Scenario, builtin, check_procedure};
use vesalius::session::{self, Input};
use vesalius::sim::Pacing;
use vesalius::trace::{KeyTrace, Recording};

/// Counts live heap bytes for the profiler's memory figures.
#[global_allocator]
static GLOBAL: &stats_alloc::StatsAlloc<std::alloc::System> = &stats_alloc::INSTRUMENTED_SYSTEM;

fn heap_bytes() -> u64 {
    // stats_alloc books a realloc's growth under bytes_allocated (and its shrinkage under
    // bytes_deallocated) as well as under bytes_reallocated: adding the latter would count
    // every grown Vec twice.
    let s = GLOBAL.stats();
    s.bytes_allocated.saturating_sub(s.bytes_deallocated) as u64
}

const USAGE: &str = "usage:
  vesalius demo [--out DIR]                 run the demo traces headless, reports under DIR (./vesalius-demo)
  vesalius run <procedure> --headless --trace FILE [--out DIR] [--scenario FILE] [--realtime]
              [--frames N] [--eye-size WxH]  save N stereo frames as DIR/frames/{left,right}_NNNN.png
                                             (default eye 1080x1200, the Vive's) and DIR/profiler.csv
  vesalius run <procedure> [--trace FILE] [--out DIR] [--scenario FILE] [--window-size WxH]
              [--screenshot FILE [--screenshot-at S]]
                                            the desktop window: mouse and keyboard, or a trace;
                                            --screenshot saves the window as PNG at the end (or at
                                            S simulated seconds) and closes it when the session ends
  vesalius run <procedure> --xr [--out DIR] [--scenario FILE] [--eye-size WxH] [--xr-duration S]
              [--no-window | --screenshot FILE [--screenshot-at S]]
                                            in the headset of the active OpenXR runtime (SteamVR,
                                            Monado); ends at the runtime's exit or after S seconds;
                                            the desktop mirror opens where there is a display
  vesalius run <procedure> --xr-sim TRACE --out DIR [--eye-size WxH]
                                            the same under the simulated runtime playing TRACE;
                                            its haptics.jsonl, frames/ and session-states.log go
                                            to DIR/xr-sim/
  vesalius profile [<procedure>] [--json] [--eye-size WxH] [--two-pass]
                                            render the scene and print the Unity-profiler counters
                                            beside the paper's CPU and GPU columns
  vesalius replay <recorded input.vtrace> --out DIR
  vesalius check <file>...                  validate scenario, trace and recording files
  vesalius bench [<procedure>] [--json]     model step rates at the scenario's sizes
  vesalius xr-sim manifest [--out FILE]     write the simulated OpenXR runtime's manifest (default
                                            beside the runtime library) and print its path, for
                                            XR_RUNTIME_JSON
global: --threads N (rayon worker threads; default: all cores)
procedures: nephrectomy (rectum, cholecystectomy, myotomy, catheter: not yet)";

fn main() -> ExitCode {
    vesalius::profiler::set_heap_probe(heap_bytes);
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    if let Some(i) = args.iter().position(|a| a == "--threads") {
        let n = args
            .get(i + 1)
            .and_then(|s| s.parse::<usize>().ok())
            .filter(|&n| n > 0);
        let Some(n) = n else {
            eprintln!("error: --threads needs a positive whole number");
            return ExitCode::from(2);
        };
        args.drain(i..=i + 1);
        if let Err(e) = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
        {
            eprintln!("error: cannot start {n} threads: {e}");
            return ExitCode::from(2);
        }
    }
    match dispatch(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(if e.starts_with("usage") { 2 } else { 1 })
        }
    }
}

/// Value of `--flag VALUE`, removing both from `args`.
fn take_flag(args: &mut Vec<String>, flag: &str) -> Result<Option<String>, String> {
    let Some(i) = args.iter().position(|a| a == flag) else {
        return Ok(None);
    };
    if i + 1 >= args.len() {
        return Err(format!("{flag} needs a value"));
    }
    let v = args.remove(i + 1);
    args.remove(i);
    Ok(Some(v))
}

fn take_switch(args: &mut Vec<String>, flag: &str) -> bool {
    let before = args.len();
    args.retain(|a| a != flag);
    args.len() != before
}

fn no_more(args: &[String]) -> Result<(), String> {
    match args.first() {
        Some(a) => Err(format!("unexpected argument '{a}'\n{USAGE}")),
        None => Ok(()),
    }
}

fn dispatch(args: &[String]) -> Result<(), String> {
    let Some(cmd) = args.first() else {
        return Err(USAGE.to_string());
    };
    let mut rest: Vec<String> = args[1..].to_vec();
    match cmd.as_str() {
        "demo" => {
            let out = take_flag(&mut rest, "--out")?.unwrap_or_else(|| "vesalius-demo".into());
            no_more(&rest)?;
            demo(Path::new(&out))
        }
        "run" => {
            let out = take_flag(&mut rest, "--out")?;
            let trace = take_flag(&mut rest, "--trace")?;
            let scenario = take_flag(&mut rest, "--scenario")?;
            let headless = take_switch(&mut rest, "--headless");
            let xr = take_switch(&mut rest, "--xr");
            let xr_sim = take_flag(&mut rest, "--xr-sim")?;
            let no_window = take_switch(&mut rest, "--no-window");
            let xr_duration = match take_flag(&mut rest, "--xr-duration")? {
                Some(v) => Some(
                    v.parse::<f64>()
                        .ok()
                        .filter(|d| d.is_finite() && *d > 0.0)
                        .ok_or(format!(
                            "--xr-duration: expected seconds greater than 0, got '{v}'"
                        ))?,
                ),
                None => None,
            };
            let eye_given = rest.iter().any(|a| a == "--eye-size");
            let realtime = take_switch(&mut rest, "--realtime");
            let frames = match take_flag(&mut rest, "--frames")? {
                Some(v) => v
                    .parse::<u32>()
                    .ok()
                    .filter(|n| (1..=10_000).contains(n))
                    .ok_or(format!(
                        "--frames: expected a whole number from 1 to 10000, got '{v}'"
                    ))?,
                None => 0,
            };
            let eye_size = eye_size(&mut rest)?;
            let screenshot = take_flag(&mut rest, "--screenshot")?;
            let screenshot_at = match take_flag(&mut rest, "--screenshot-at")? {
                Some(v) => Some(
                    v.parse::<f64>()
                        .ok()
                        .filter(|s| s.is_finite() && *s >= 0.0)
                        .ok_or(format!(
                            "--screenshot-at: expected simulated seconds (0 or more), got '{v}'"
                        ))?,
                ),
                None => None,
            };
            let window_size = match take_flag(&mut rest, "--window-size")? {
                Some(v) => parse_size("--window-size", &v)?,
                None => (1600, 900),
            };
            if rest.is_empty() {
                return Err(format!("run needs a procedure\n{USAGE}"));
            }
            let procedure = rest.remove(0);
            no_more(&rest)?;
            check_procedure("command line", "procedure", &procedure).map_err(|e| e.to_string())?;
            if screenshot_at.is_some() && screenshot.is_none() {
                return Err("--screenshot-at needs --screenshot FILE".into());
            }
            let window = WindowArgs {
                screenshot: screenshot.map(PathBuf::from),
                screenshot_at,
                size: window_size,
                no_window,
            };
            if xr || xr_sim.is_some() {
                if headless || trace.is_some() {
                    return Err(
                        "--xr runs in the headset: drop --headless/--trace (the simulated runtime plays a trace with --xr-sim TRACE)"
                            .into(),
                    );
                }
                let eye = eye_given.then_some(eye_size);
                return match xr_sim {
                    Some(t) => {
                        let out =
                            out.ok_or("--xr-sim needs --out DIR (its outputs go to DIR/xr-sim/)")?;
                        run_xr_sim(
                            &procedure,
                            scenario.as_deref(),
                            (Path::new(&t), Path::new(&out)),
                            eye,
                            &window,
                        )
                    }
                    None => run_xr(
                        &procedure,
                        scenario.as_deref(),
                        out.as_deref().map(Path::new),
                        vesalius::xr::XrOptions {
                            duration_s: xr_duration,
                            eye_size: eye,
                        },
                        window,
                    ),
                };
            }
            if !headless {
                if no_window {
                    return Err("--no-window: without a window, use --headless (or --xr)".into());
                }
                return run_window(
                    &procedure,
                    scenario.as_deref(),
                    trace.as_deref().map(Path::new),
                    out.as_deref().map(Path::new),
                    window,
                    None,
                );
            }
            if window.screenshot.is_some() {
                return Err("--screenshot saves the window: drop --headless".into());
            }
            let trace = trace.ok_or("run --headless needs --trace FILE")?;
            if frames > 0 && out.is_none() {
                return Err("--frames needs --out DIR (frames go to DIR/frames/)".into());
            }
            run(
                &procedure,
                scenario.as_deref(),
                Path::new(&trace),
                out.as_deref().map(Path::new),
                realtime,
                (frames, eye_size),
            )
        }
        "replay" => {
            let out = take_flag(&mut rest, "--out")?.ok_or("replay needs --out DIR")?;
            if rest.len() != 1 {
                return Err(format!("replay needs exactly one recorded trace\n{USAGE}"));
            }
            replay(Path::new(&rest[0]), Path::new(&out))
        }
        "check" => {
            if rest.is_empty() {
                return Err(format!("check needs at least one file\n{USAGE}"));
            }
            check(&rest)
        }
        "bench" => {
            let json = take_switch(&mut rest, "--json");
            let procedure = if rest.is_empty() {
                "nephrectomy".to_string()
            } else {
                rest.remove(0)
            };
            no_more(&rest)?;
            check_procedure("command line", "procedure", &procedure).map_err(|e| e.to_string())?;
            bench(&procedure, json)
        }
        "profile" => {
            let json = take_switch(&mut rest, "--json");
            let two_pass = take_switch(&mut rest, "--two-pass");
            let eye_size = eye_size(&mut rest)?;
            let procedure = if rest.is_empty() {
                "nephrectomy".to_string()
            } else {
                rest.remove(0)
            };
            no_more(&rest)?;
            check_procedure("command line", "procedure", &procedure).map_err(|e| e.to_string())?;
            profile(&procedure, json, eye_size, two_pass)
        }
        "xr-sim" => {
            let out = take_flag(&mut rest, "--out")?;
            if rest.first().map(String::as_str) != Some("manifest") {
                return Err(format!(
                    "usage: vesalius xr-sim manifest [--out FILE]\n{USAGE}"
                ));
            }
            rest.remove(0);
            no_more(&rest)?;
            let path = xr_sim_manifest(out.map(PathBuf::from))?;
            println!("{}", path.display());
            Ok(())
        }
        "help" | "--help" | "-h" => {
            println!("{USAGE}");
            Ok(())
        }
        other => Err(format!("unknown command '{other}'\n{USAGE}")),
    }
}

/// Finds the simulated runtime library built with this binary (beside it, or in `deps/` where
/// cargo leaves a dependency's cdylib) and writes its runtime manifest.
fn xr_sim_manifest(out: Option<PathBuf>) -> Result<PathBuf, String> {
    let exe = std::env::current_exe().map_err(|e| format!("cannot find this executable: {e}"))?;
    let dir = exe
        .parent()
        .ok_or_else(|| format!("{}: no parent folder", exe.display()))?;
    let name = "libvesalius_sim_runtime.so";
    // The newest build: `cargo build` copies the library up beside the executable, test
    // builds leave theirs in deps/, and either may be stale.
    let modified = |p: &PathBuf| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    let lib = [dir.join(name), dir.join("deps").join(name)]
        .into_iter()
        .filter(|p| p.is_file())
        .max_by_key(modified)
        .ok_or_else(|| {
            format!(
                "{name} is not beside {} (build it: cargo build --release --workspace)",
                exe.display()
            )
        })?;
    let lib = lib
        .canonicalize()
        .map_err(|e| format!("{}: {e}", lib.display()))?;
    let path = out.unwrap_or_else(|| dir.join("vesalius_sim_runtime.json"));
    let text = vesalius_sim_runtime::manifest(&lib.display().to_string());
    let tmp = path.with_extension("json.partial");
    std::fs::write(&tmp, text).map_err(|e| format!("{}: {e}", tmp.display()))?;
    std::fs::rename(&tmp, &path).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(path)
}

/// The scenario a run uses: the file given, or the procedure's built-in one.
fn scenario_text(procedure: &str, scenario: Option<&str>) -> Result<(String, String), String> {
    Ok(match scenario {
        Some(f) => (
            f.to_string(),
            std::fs::read_to_string(f).map_err(|e| format!("{f}: cannot read: {e}"))?,
        ),
        None => (
            format!("builtin {procedure} scenario"),
            builtin(procedure).unwrap_or_default().to_string(),
        ),
    })
}

/// The window's flags.
struct WindowArgs {
    screenshot: Option<PathBuf>,
    screenshot_at: Option<f64>,
    size: (u32, u32),
    /// Under XR: the headset only, no desktop mirror.
    no_window: bool,
}

/// Whether a window can open here (an X11 or Wayland display is named).
fn display_available() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

/// `run <p>` without `--headless`: the desktop window, played by a trace or driven by the
/// desktop controls; with `xr`, the mirror of a headset session.
fn run_window(
    procedure: &str,
    scenario: Option<&str>,
    trace: Option<&Path>,
    out: Option<&Path>,
    window: WindowArgs,
    xr: Option<vesalius::xr::XrOptions>,
) -> Result<(), String> {
    let WindowArgs {
        screenshot,
        screenshot_at: screenshot_at_s,
        size,
        ..
    } = window;
    let (file, text) = scenario_text(procedure, scenario)?;
    let trace = match trace {
        Some(t) => {
            let keys = load_trace(t, procedure)?;
            let name = t
                .file_name()
                .map_or_else(|| t.display().to_string(), |n| n.to_string_lossy().into());
            Some((keys, name))
        }
        None => None,
    };
    if let Some(p) = screenshot.as_deref().and_then(Path::parent)
        && !p.as_os_str().is_empty()
        && !p.is_dir()
    {
        return Err(format!(
            "--screenshot: folder {} does not exist",
            p.display()
        ));
    }
    // The sliders' "save" writes back into the scenario file the session runs; with the
    // built-in scenario, a new file beside the outputs.
    let save_tuning_to = match (scenario, out) {
        (Some(f), _) => PathBuf::from(f),
        (None, Some(dir)) => dir.join(format!("{procedure}-tuned.toml")),
        (None, None) => PathBuf::from(format!("{procedure}-tuned.toml")),
    };
    let run = vesalius::ui::window::run(vesalius::ui::window::WindowOptions {
        procedure: procedure.to_string(),
        scenario_text: text,
        scenario_file: file,
        trace,
        out: out.map(Path::to_path_buf),
        screenshot,
        screenshot_at_s,
        size,
        save_tuning_to,
        xr,
    })?;
    if let Some((runtime, frames, sessions, (w, h))) = &run.xr {
        println!(
            "XR runtime '{runtime}' on {}: {frames} stereo frames at {w}x{h} per eye, {sessions} session(s)",
            run.device
        );
    }
    if run.xr.is_some() {
        println!(
            "window on {}: {} frames, {} of them drawing the scene (the rest mirrored an eye)",
            run.device, run.frames, run.scene_renders
        );
    } else {
        println!("window on {}: {} frames", run.device, run.frames);
    }
    if let Some(((w, h), path)) = &run.screenshot {
        println!("screenshot {w}x{h} written to {}", path.display());
    }
    // The window wrote the session's files when it ended; report it here like the others.
    finish(&run.outcome, None)?;
    if let Some(dir) = out {
        println!("wrote {}", dir.display());
    }
    Ok(())
}

/// `run <p> --xr`: a session in the headset of whatever OpenXR runtime is active.
fn run_xr(
    procedure: &str,
    scenario: Option<&str>,
    out: Option<&Path>,
    opts: vesalius::xr::XrOptions,
    window: WindowArgs,
) -> Result<(), String> {
    // The supervisor's mirror opens beside the headset wherever there is a display.
    if !window.no_window && display_available() {
        return run_window(procedure, scenario, None, out, window, Some(opts));
    }
    if window.screenshot.is_some() {
        return Err(
            "--screenshot needs a window: no DISPLAY (try xvfb-run), or drop --no-window".into(),
        );
    }
    if !window.no_window {
        eprintln!("no display: running in the headset only (--no-window to say so)");
    }
    let (file, text) = scenario_text(procedure, scenario)?;
    let run = vesalius::xr::run(&text, &file, opts)?;
    println!(
        "XR runtime '{}' on {}: {} stereo frames at {}x{} per eye, {} session(s)",
        run.runtime, run.device, run.frames, run.eye_size.0, run.eye_size.1, run.sessions
    );
    finish(&run.outcome, out)
}

/// `run <p> --xr-sim TRACE --out DIR`: the same XR session under the simulated runtime, which
/// plays TRACE as head and controller motion and writes its logs and frames to DIR/xr-sim/.
/// The loader reads the runtime's location from the environment, so the session runs in a
/// child process that has it set.
fn run_xr_sim(
    procedure: &str,
    scenario: Option<&str>,
    (trace, out): (&Path, &Path),
    eye: Option<(u32, u32)>,
    window: &WindowArgs,
) -> Result<(), String> {
    let keys = load_trace(trace, procedure)?;
    let sim_dir = out.join("xr-sim");
    std::fs::create_dir_all(&sim_dir).map_err(|e| format!("{}: {e}", sim_dir.display()))?;
    let abs = |p: &Path| {
        p.canonicalize()
            .map_err(|e| format!("{}: {e}", p.display()))
    };
    let (sim_abs, trace_abs) = (abs(&sim_dir)?, abs(trace)?);
    let manifest = xr_sim_manifest(Some(sim_abs.join("runtime.json")))?;
    let quote = |p: &Path| toml::Value::String(p.display().to_string()).to_string();
    let settings = format!(
        "# Written by `vesalius run --xr-sim`: the simulated runtime's settings.\nout_dir = {}\ntrace = {}\n",
        quote(&sim_abs),
        quote(&trace_abs)
    );
    let config = sim_abs.join("settings.toml");
    std::fs::write(&config, settings).map_err(|e| format!("{}: {e}", config.display()))?;
    let exe = std::env::current_exe().map_err(|e| format!("cannot find this executable: {e}"))?;
    let duration = keys.duration_s() + session::SETTLE_S;
    let mut cmd = std::process::Command::new(exe);
    cmd.args(["run", procedure, "--xr", "--out"])
        .arg(out)
        .args(["--xr-duration", &format!("{duration}")])
        .env("XR_RUNTIME_JSON", &manifest)
        .env(vesalius_sim_runtime::CONFIG_ENV, &config);
    if let Some(f) = scenario {
        cmd.args(["--scenario", f]);
    }
    if let Some((w, h)) = eye {
        cmd.args(["--eye-size", &format!("{w}x{h}")]);
    }
    if window.no_window {
        cmd.arg("--no-window");
    }
    if let Some(s) = &window.screenshot {
        cmd.arg("--screenshot").arg(s);
    }
    if let Some(at) = window.screenshot_at {
        cmd.args(["--screenshot-at", &at.to_string()]);
    }
    let (w, h) = window.size;
    cmd.args(["--window-size", &format!("{w}x{h}")]);
    let status = cmd
        .status()
        .map_err(|e| format!("cannot start the XR session: {e}"))?;
    if !status.success() {
        return Err(format!(
            "the XR session under the simulated runtime failed ({status})"
        ));
    }
    println!("simulated runtime outputs in {}", sim_dir.display());
    Ok(())
}

fn finish(outcome: &session::Outcome, out: Option<&Path>) -> Result<(), String> {
    let r = &outcome.report;
    println!(
        "{}: completed={} steps={} simulated={:.2}s score={:.1} cuts={} wall={:.2}s ({:.2}x real time)",
        r.procedure,
        r.completed,
        r.steps,
        r.simulated_s,
        r.score,
        r.events.get("cut").copied().unwrap_or(0),
        outcome.wall_s,
        r.simulated_s / outcome.wall_s.max(1e-9)
    );
    if let Some(dir) = out {
        session::write_outputs(outcome, dir).map_err(|e| e.to_string())?;
        println!("wrote {}", dir.display());
    }
    Ok(())
}

/// `--eye-size WxH`, default the Vive's 1080x1200.
fn eye_size(args: &mut Vec<String>) -> Result<(u32, u32), String> {
    match take_flag(args, "--eye-size")? {
        Some(v) => parse_size("--eye-size", &v),
        None => Ok(vesalius::render::camera::VIVE_EYE_SIZE),
    }
}

/// WIDTHxHEIGHT in pixels, each 16 to 8192.
fn parse_size(flag: &str, v: &str) -> Result<(u32, u32), String> {
    v.split_once('x')
        .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
        .filter(|&(w, h)| (16..=8192).contains(&w) && (16..=8192).contains(&h))
        .ok_or(format!(
            "{flag}: expected WIDTHxHEIGHT in pixels, each 16 to 8192, got '{v}'"
        ))
}

/// A keyframed trace, checked to be for `procedure`.
fn load_trace(path: &Path, procedure: &str) -> Result<KeyTrace, String> {
    let keys = KeyTrace::load(path).map_err(|e| e.to_string())?;
    if keys.procedure != procedure {
        return Err(format!(
            "{}: procedure: trace is for '{}', not '{procedure}'",
            path.display(),
            keys.procedure
        ));
    }
    Ok(keys)
}

fn run(
    procedure: &str,
    scenario: Option<&str>,
    trace: &Path,
    out: Option<&Path>,
    realtime: bool,
    (frames, eye_size): (u32, (u32, u32)),
) -> Result<(), String> {
    let (file, text) = scenario_text(procedure, scenario)?;
    let keys = load_trace(trace, procedure)?;
    let pacing = if realtime {
        Pacing::RealTime
    } else {
        Pacing::AsFastAsPossible
    };
    let outcome = session::run_capturing(&text, &file, Input::Keys(keys), pacing, None, frames)
        .map_err(|e| e.to_string())?;
    finish(&outcome, out)?;
    if let (Some(dir), true) = (out, frames > 0) {
        let gpu = vesalius::render::Gpu::headless(true).map_err(|e| e.to_string())?;
        let sim_ms = outcome.wall_s * 1e3 / outcome.report.steps.max(1) as f64;
        let done = vesalius::render::frames::render_snapshots(
            &gpu,
            &outcome.captured,
            1,
            eye_size,
            sim_ms,
            Some(&dir.join("frames")),
        )
        .map_err(|e| e.to_string())?;
        vesalius::render::frames::write_profiler_csv(&dir.join("profiler.csv"), &done.counters)
            .map_err(|e| e.to_string())?;
        let mean = done.frame_ms.iter().sum::<f64>() / done.frame_ms.len().max(1) as f64;
        println!(
            "rendered {} stereo frames {}x{} per eye on {}: {:.1} ms per frame",
            done.counters.len(),
            eye_size.0,
            eye_size.1,
            done.device,
            mean
        );
    }
    Ok(())
}

/// Renders the demo mid-cut (laser on, instruments in view) and prints the counters beside the
/// paper's Tables 2 and 3.
fn profile(
    procedure: &str,
    json: bool,
    eye_size: (u32, u32),
    two_pass: bool,
) -> Result<(), String> {
    use vesalius::profiler::{mb, paper_cpu, paper_gpu};
    let text = builtin(procedure).unwrap_or_default();
    let keys = KeyTrace::parse("builtin demo trace", vesalius::bench::DEMO_TRACE)
        .map_err(|e| e.to_string())?;
    // Simulate up to the middle of the cut (40 % of the trace) and render that instant with
    // the simulation still alive, so total memory counts it as Unity's profiler would.
    let scenario =
        Scenario::parse("builtin nephrectomy scenario", text).map_err(|e| e.to_string())?;
    let dt = scenario.dt_s as f64;
    let mut sim = vesalius::procedures::Nephrectomy::new(scenario).map_err(|e| e.to_string())?;
    let steps = (keys.duration_s() * 0.4 / dt).ceil() as u64;
    let mut events = Vec::new();
    let t0 = std::time::Instant::now();
    for step in 0..steps {
        sim.step(&keys.sample(step as f64 * dt), step, &mut events);
        events.clear();
    }
    let sim_ms = t0.elapsed().as_secs_f64() * 1e3 / steps.max(1) as f64;
    let gpu = vesalius::render::Gpu::headless(!two_pass).map_err(|e| e.to_string())?;
    // Five frames of the same instant: the first pays for pipeline warm-up.
    let snap = sim.snapshot(steps.saturating_sub(1));
    let done = vesalius::render::frames::render_repeated(&gpu, &snap, 5, eye_size, sim_ms)
        .map_err(|e| e.to_string())?;
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
            "paper": { "cpu": paper_cpu(), "gpu": paper_gpu() },
        });
        println!("{}", serde_json::to_string_pretty(&v).unwrap_or_default());
        return Ok(());
    }
    let (pc, pg) = (paper_cpu(), paper_gpu());
    println!(
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
    println!(
        "{:<22} {:>12} {:>12} {:>12}",
        "", "vesalius", "paper CPU", "paper GPU"
    );
    let cols = [ours.column(), pc, pg];
    let row = |name: &str, cell: &dyn Fn(&vesalius::profiler::PaperColumn) -> String| {
        let [a, b, c] = cols.each_ref().map(cell);
        println!("{name:<22} {a:>12} {b:>12} {c:>12}")
    };
    let mb1 = |b: u64| format!("{:.1} MB", mb(b));
    let cb =
        |c: vesalius::profiler::CountBytes| format!("{}/{:.0}KB", c.count, c.bytes as f64 / 1e3);
    row("batches", &|c| c.batches.to_string());
    row("draw calls", &|c| c.draw_calls.to_string());
    row("setpass calls", &|c| c.setpass_calls.to_string());
    row("triangles", &|c| c.triangles.to_string());
    row("vertices", &|c| c.vertices.to_string());
    row("VRAM", &|c| mb1(c.vram_bytes));
    row("total memory", &|c| mb1(c.total_memory_bytes));
    row("textures", &|c| cb(c.textures));
    row("meshes", &|c| cb(c.meshes));
    row("materials", &|c| cb(c.materials));
    row("objects", &|c| c.objects.to_string());
    println!(
        "cpu per stage: simulation {:.2} ms/step, render encode {:.2} ms, submit {:.2} ms",
        ours.cpu.simulation_ms, ours.cpu.render_encode_ms, ours.cpu.submit_ms
    );
    let mut parts = sim_parts.clone();
    parts.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(b.0)));
    let top: Vec<String> = parts
        .iter()
        .take(4)
        .map(|(k, b)| format!("{k} {:.1}", mb(*b as u64)))
        .collect();
    println!(
        "heap {:.1} MB, of which simulation {:.1} MB (largest: {})",
        mb(heap),
        mb(sim_bytes as u64),
        top.join(", ")
    );
    Ok(())
}

fn replay(recorded: &Path, out: &Path) -> Result<(), String> {
    let rec = Recording::read(recorded).map_err(|e| e.to_string())?;
    let file = format!("{} (embedded scenario)", recorded.display());
    let scenario = rec.scenario.clone();
    let outcome = session::run(
        &scenario,
        &file,
        Input::Recorded(rec),
        Pacing::AsFastAsPossible,
        None,
    )
    .map_err(|e| e.to_string())?;
    finish(&outcome, Some(out))
}

fn demo(out: &Path) -> Result<(), String> {
    let text = builtin("nephrectomy").unwrap_or_default();
    let keys = KeyTrace::parse("builtin demo trace", vesalius::bench::DEMO_TRACE)
        .map_err(|e| e.to_string())?;
    let outcome = session::run(
        text,
        "builtin nephrectomy scenario",
        Input::Keys(keys),
        Pacing::AsFastAsPossible,
        None,
    )
    .map_err(|e| e.to_string())?;
    finish(&outcome, Some(&out.join("nephrectomy")))
}

/// Validates each file by its kind: a binary recording, a keyframed trace, or a scenario.
fn check(files: &[String]) -> Result<(), String> {
    let mut failed = 0;
    for f in files {
        let result = check_one(&PathBuf::from(f));
        match result {
            Ok(kind) => println!("{f}: ok ({kind})"),
            Err(e) => {
                failed += 1;
                eprintln!("{e}");
            }
        }
    }
    if failed > 0 {
        return Err(format!(
            "{failed} of {} files failed the check",
            files.len()
        ));
    }
    Ok(())
}

fn check_one(path: &Path) -> Result<&'static str, InputError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path)
        .map_err(|e| InputError::new(&file, "file", format!("cannot read: {e}")))?;
    if Recording::is_recording(&bytes) {
        let rec = Recording::decode(&file, &bytes)?;
        Scenario::parse(&format!("{file} (embedded scenario)"), &rec.scenario)?;
        return Ok("recorded trace");
    }
    let text = String::from_utf8(bytes)
        .map_err(|_| InputError::new(&file, "file", "is neither UTF-8 TOML nor a recording"))?;
    let table: toml::Table = toml::from_str(&text).map_err(|e| InputError::toml(&file, &e))?;
    if table.contains_key("left") || table.contains_key("right") {
        KeyTrace::parse(&file, &text)?;
        Ok("keyframed trace")
    } else {
        Scenario::parse(&file, &text)?;
        Ok("scenario")
    }
}

fn bench(procedure: &str, json: bool) -> Result<(), String> {
    let lines = vesalius::bench::run(procedure)?;
    for l in &lines {
        if json {
            println!("{}", serde_json::to_string(l).unwrap_or_default());
        } else {
            println!(
                "{:<14} {:>9.0} steps/s  dt {:.4} s  real-time x{:>6.2}  {:>6} vertices {:>6} triangles {:>7} constraints  ({} threads)",
                l.model,
                l.steps_per_s,
                l.dt_s,
                l.realtime_factor,
                l.vertices,
                l.triangles,
                l.constraints,
                l.threads
            );
        }
    }
    Ok(())
}
