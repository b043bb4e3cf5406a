//! `vesalius xr-sim manifest` writes a runtime manifest the real Khronos loader accepts: its
//! `openxr_runtime_list` (libopenxr-utils) loads the simulated runtime through it.

use std::process::Command;

#[test]
fn the_manifest_command_points_the_khronos_loader_at_the_simulated_runtime() {
    let dir = std::env::temp_dir().join(format!("vesalius-xr-sim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
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
    assert!(String::from_utf8_lossy(&bad.stderr).contains("xr-sim manifest"));
}
