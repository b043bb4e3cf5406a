//! The command line as a user meets it: help, version, typo suggestions, exit codes, a
//! closed pipe, and `check` on every kind of file we ship.

use std::path::Path;
mod common;
use common::{bin, text, tmp};
use std::process::Output;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn version_help_and_typos() {
    let v = bin().arg("--version").output().expect("runs");
    assert_eq!(v.status.code(), Some(0));
    assert_eq!(
        String::from_utf8_lossy(&v.stdout).trim(),
        format!("vesalius {}", env!("CARGO_PKG_VERSION"))
    );
    let h = bin().args(["run", "--help"]).output().expect("runs");
    assert_eq!(h.status.code(), Some(0), "{}", text(&h));
    let help = String::from_utf8_lossy(&h.stdout);
    for p in vesalius::registry::REGISTRY {
        assert!(help.contains(p.name), "run --help lists {}: {help}", p.name);
    }
    assert!(!help.contains("unknown procedure"));
    let typo = bin().arg("rn").output().expect("runs");
    assert_eq!(typo.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&typo.stderr).contains("'run'"),
        "{}",
        text(&typo)
    );
    let unknown = bin().args(["run", "appendectomy"]).output().expect("runs");
    assert_eq!(unknown.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&unknown.stderr).contains("nephrectomy"));
    let none = bin().output().expect("runs");
    assert_eq!(none.status.code(), Some(2));
    // A failure that is not a usage error exits 1.
    let missing = bin()
        .args(["check", "/nonexistent.toml"])
        .output()
        .expect("runs");
    assert_eq!(missing.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("/nonexistent.toml"));
}

#[test]
fn check_accepts_every_kind_of_file_we_ship() {
    let mut files: Vec<std::path::PathBuf> = Vec::new();
    for dir in ["xr-bindings/profiles", "assets/scenarios", "assets/traces"] {
        for e in std::fs::read_dir(root().join(dir)).expect("dir").flatten() {
            files.push(e.path());
        }
    }
    let scratch = tmp("cli", "check");
    let settings = scratch.join("settings.toml");
    std::fs::write(
        &settings,
        "frames_every = 5\n[inject]\nsession_loss_s = 1.0\n",
    )
    .expect("settings");
    files.push(settings.clone());
    let o = bin().arg("check").args(&files).output().expect("runs");
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(out.lines().count(), files.len(), "{out}");
    for kind in [
        "(interaction profile)",
        "(scenario)",
        "(keyframed trace)",
        "(simulated runtime settings)",
    ] {
        assert!(out.contains(kind), "{kind}: {out}");
    }
    // A broken profile is named with its key.
    let bad = scratch.join("bad.toml");
    let vive =
        std::fs::read_to_string(root().join("xr-bindings/profiles/htc_vive.toml")).expect("vive");
    std::fs::write(
        &bad,
        vive.replace("/input/trigger/value", "/input/trigger/valu e"),
    )
    .expect("bad profile");
    let o = bin().arg("check").arg(&bad).output().expect("runs");
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stderr).contains(&bad.display().to_string()));
}

/// Runs the command with its standard output a pipe whose reading end is already closed.
fn into_closed_pipe(args: &[&str]) -> Output {
    let (reader, writer) = std::io::pipe().expect("pipe");
    drop(reader);
    bin()
        .args(args)
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .output()
        .expect("runs")
}

#[test]
fn no_command_panics_when_its_output_is_a_closed_pipe() {
    let vive = root().join("xr-bindings/profiles/htc_vive.toml");
    let scenario = root().join("assets/scenarios/nephrectomy.toml");
    let scratch = tmp("cli", "closed-pipe");
    let manifest = scratch.join("manifest.json");
    let (v, s, m) = (
        vive.display().to_string(),
        scenario.display().to_string(),
        manifest.display().to_string(),
    );
    for args in [
        vec!["check", v.as_str(), s.as_str()],
        vec!["--version"],
        vec!["--help"],
        vec!["run", "--help"],
        vec!["xr-sim", "manifest", "--out", m.as_str()],
    ] {
        let o = into_closed_pipe(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(
            matches!(o.status.code(), Some(0 | 141)),
            "{args:?}: {:?} {err}",
            o.status
        );
    }
    // `check` has something to print: it stops at once, quietly, as if by SIGPIPE.
    let o = into_closed_pipe(&["check", v.as_str(), s.as_str()]);
    assert_eq!(o.status.code(), Some(141));
    assert!(
        o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
fn verify_lists_every_case_within_its_tolerance() {
    let o = bin().args(["verify", "--json"]).output().expect("runs");
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let rows: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object a line"))
        .collect();
    assert_eq!(
        rows.len(),
        vesalius::verify::cases_in(&vesalius::registry::CATALOG).len()
    );
    for r in &rows {
        let (err, tol) = (
            r["rel_error"].as_f64().expect("rel_error"),
            r["tolerance"].as_f64().expect("tolerance"),
        );
        assert!(err <= tol && r["passed"] == true, "{r}");
        for key in ["model", "case", "reference", "measured", "unit"] {
            assert!(!r[key].is_null(), "{key} in {r}");
        }
    }
    let table = bin().arg("verify").output().expect("runs");
    let out = String::from_utf8_lossy(&table.stdout);
    assert!(
        out.trim_end()
            .ends_with(&format!("{} passed, 0 failed", rows.len())),
        "{out}"
    );
}

#[test]
fn bench_on_the_gpu_gives_a_steps_cpu_part_beside_its_wait_for_the_device() {
    // The cholecystectomy's preset on whatever Vulkan adapter there is (CI: lavapipe): the
    // solver's kernel lines, then the procedure stepping with its solver on the device.
    let o = bin()
        .args([
            "bench",
            "cholecystectomy",
            "--compute",
            "gpu",
            "--preset",
            "cpu",
            "--json",
        ])
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect();
    let procedure = lines
        .iter()
        .find(|l| l["model"] == "procedure")
        .expect("a procedure line");
    assert_eq!(procedure["backend"], "gpu", "{procedure}");
    let ms = |key: &str| procedure[key].as_f64().unwrap_or(f64::NAN);
    let (median, mean, p99, wait) = (
        ms("step_cpu_ms_median"),
        ms("step_cpu_ms_mean"),
        ms("step_cpu_ms_p99"),
        ms("step_wait_ms_median"),
    );
    // Every step waits for the device's results, and the CPU does some of the step.
    assert!(wait > 0.0, "{procedure}");
    assert!(median > 0.0 && p99 >= median && mean > 0.0, "{procedure}");
    // The simulation thread's own clock ran in its steps.
    assert!(ms("step_thread_cpu_ms_mean") > 0.0, "{procedure}");
    // The kernel's own lines time the solver alone: no step of a procedure in them.
    for l in lines.iter().filter(|l| l["model"] != "procedure") {
        assert!(l.get("step_cpu_ms_median").is_none(), "{l}");
    }
}
