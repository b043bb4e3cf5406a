//! `vesalius xr-sim manifest` writes a runtime manifest the real Khronos loader accepts: its
//! `openxr_runtime_list` (libopenxr-utils) loads the simulated runtime through it.

mod common;
use std::process::Command;

#[test]
fn the_manifest_command_points_the_khronos_loader_at_the_simulated_runtime() {
    let dir = common::tmp("xr-sim", "manifest");
    let path = dir.join("runtime.json");
    let o = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .args(["xr-sim", "manifest", "--out"])
        .arg(&path)
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        String::from_utf8_lossy(&o.stdout).trim(),
        path.display().to_string()
    );
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&path).expect("manifest written")).expect("JSON");
    assert_eq!(m["file_format_version"], "1.0.0");
    let lib = m["runtime"]["library_path"].as_str().expect("library_path");
    assert!(std::path::Path::new(lib).is_absolute() && std::path::Path::new(lib).is_file());
    let list = Command::new("openxr_runtime_list")
        .env("XR_RUNTIME_JSON", &path)
        .output()
        .expect("openxr_runtime_list (apt-get install libopenxr-utils)");
    let text = String::from_utf8_lossy(&list.stdout);
    assert!(list.status.success(), "{text}");
    assert!(text.contains(vesalius_sim_runtime::SYSTEM_NAME), "{text}");
    // A wrong use is a usage error, not a crash.
    let bad = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .args(["xr-sim", "manifests"])
        .output()
        .expect("runs");
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("'manifest'"));
}

/// `--xr-sim` plays for `--xr-duration` when given (not the whole trace), and keeps the
/// settings of a `VESALIUS_XR_SIM_CONFIG` file the user set (here: a frame dump every 5th
/// frame instead of every 30th).
#[test]
fn xr_sim_honours_the_duration_and_the_users_settings() {
    let dir = common::tmp("xr-sim", "duration");
    let settings = dir.join("mine.toml");
    std::fs::write(&settings, "frames_every = 5\n").expect("settings");
    let trace = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets/traces/nephrectomy-demo.toml");
    let out = dir.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .args(["run", "nephrectomy", "--xr-sim"])
        .arg(&trace)
        .arg("--out")
        .arg(&out)
        .args(["--xr-duration", "0.5", "--no-window", "--eye-size", "64x64"])
        .env(vesalius_sim_runtime::CONFIG_ENV, &settings)
        .output()
        .expect("runs");
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).expect("report"))
            .expect("JSON");
    let simulated = report["simulated_s"].as_f64().expect("simulated_s");
    // One 90 Hz frame of slack past the asked duration; the demo trace is 22.7 s long.
    assert!((0.5..0.5 + 0.012).contains(&simulated), "{simulated}");
    assert_eq!(report["ended"], "xr_exit");
    let written = std::fs::read_to_string(out.join("xr-sim/settings.toml")).expect("settings");
    assert!(written.contains("frames_every = 5"), "{written}");
    let lefts = std::fs::read_dir(out.join("xr-sim/frames"))
        .expect("frames dumped")
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with("_left.png"))
        .count();
    // 0.5 s at 90 Hz is 45 frames: every 5th is 9 (every 30th would be 2).
    assert!((8..=10).contains(&lefts), "{lefts} left-eye dumps");
}
