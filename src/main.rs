//! The `vesalius` command line.
#![forbid(unsafe_code)]

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use vesalius::scenario::{InputError, Scenario, builtin, check_procedure};
use vesalius::session::{self, Input};
use vesalius::sim::Pacing;
use vesalius::trace::{KeyTrace, Recording};

const USAGE: &str = "usage:
  vesalius demo [--out DIR]                 run the demo traces headless, reports under DIR (./vesalius-demo)
  vesalius run <procedure> --headless --trace FILE [--out DIR] [--scenario FILE] [--realtime]
  vesalius replay <recorded input.vtrace> --out DIR
  vesalius check <file>...                  validate scenario, trace and recording files
  vesalius bench [<procedure>] [--json]     model step rates at the scenario's sizes
global: --threads N (rayon worker threads; default: all cores)
procedures: nephrectomy (rectum, cholecystectomy, myotomy, catheter: not yet)";

fn main() -> ExitCode {
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
            let realtime = take_switch(&mut rest, "--realtime");
            if rest.is_empty() {
                return Err(format!("run needs a procedure\n{USAGE}"));
            }
            let procedure = rest.remove(0);
            no_more(&rest)?;
            check_procedure("command line", "procedure", &procedure).map_err(|e| e.to_string())?;
            if !headless {
                return Err(
                    "the desktop window and --xr are not built yet; use --headless --trace FILE"
                        .into(),
                );
            }
            let trace = trace.ok_or("run --headless needs --trace FILE")?;
            run(
                &procedure,
                scenario.as_deref(),
                Path::new(&trace),
                out.as_deref().map(Path::new),
                realtime,
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
        "help" | "--help" | "-h" => {
            println!("{USAGE}");
            Ok(())
        }
        other => Err(format!("unknown command '{other}'\n{USAGE}")),
    }
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

fn run(
    procedure: &str,
    scenario: Option<&str>,
    trace: &Path,
    out: Option<&Path>,
    realtime: bool,
) -> Result<(), String> {
    let (file, text) = match scenario {
        Some(f) => (
            f.to_string(),
            std::fs::read_to_string(f).map_err(|e| format!("{f}: cannot read: {e}"))?,
        ),
        None => (
            format!("builtin {procedure} scenario"),
            builtin(procedure).unwrap_or_default().to_string(),
        ),
    };
    let keys = KeyTrace::load(trace).map_err(|e| e.to_string())?;
    if keys.procedure != procedure {
        return Err(format!(
            "{}: procedure: trace is for '{}', not '{procedure}'",
            trace.display(),
            keys.procedure
        ));
    }
    let pacing = if realtime {
        Pacing::RealTime
    } else {
        Pacing::AsFastAsPossible
    };
    let outcome =
        session::run(&text, &file, Input::Keys(keys), pacing, None).map_err(|e| e.to_string())?;
    finish(&outcome, out)
}

fn replay(recorded: &Path, out: &Path) -> Result<(), String> {
    let rec = Recording::read(recorded).map_err(|e| e.to_string())?;
    let file = format!("{} (embedded scenario)", recorded.display());
    let outcome = session::run(
        &rec.scenario,
        &file,
        Input::Recorded(rec.frames),
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
