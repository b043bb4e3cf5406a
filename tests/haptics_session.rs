//! `vesalius run <procedure> --haptics D[,D]`: sessions driven by force-feedback devices.
//! The simulated stylus presses the procedure's tissue; the session is recorded, ends after
//! its `--seconds`, and replays to the same state. Two devices drive both hands. A Phantom
//! (here the fake libHD the build makes) runs the same session through the real FFI path, and
//! two Phantoms share HD's one scheduler. In the headset (the simulated runtime) a stylus
//! drives its hand's instrument while the controller of that hand stays up and away.

mod common;
use common::{bin, report, text, tmp};

fn run(args: &[&str]) -> std::process::Output {
    bin().args(args).output().expect("runs")
}

#[test]
fn one_simulated_stylus_presses_the_block_and_the_session_replays() {
    let d = tmp("haptics-session", "one");
    let out = d.join("run");
    let o = run(&[
        "run",
        "sandbox",
        "--no-window",
        "--haptics",
        "sim",
        "--seconds",
        "2",
        "--out",
        out.to_str().expect("utf-8"),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("simulated stylus on the right hand"),
        "{stdout}"
    );
    let r = report(&out);
    assert_eq!(r["ended"], "time_up", "{r}");
    let dt = r["dt_s"].as_f64().expect("dt");
    let t = r["simulated_s"].as_f64().expect("simulated_s");
    assert!((2.0..2.0 + 2.0 * dt).contains(&t), "{t} s");
    // The stylus came down 26 mm from 15 mm above the block: the probe touched and pushed.
    assert!(r["events"]["contact"].as_u64().unwrap_or(0) >= 1, "{r}");
    let f = r["metrics"]["max_probe_force_n"].as_f64().unwrap_or(0.0);
    let depth = r["metrics"]["max_probe_depth_m"].as_f64().unwrap_or(0.0);
    assert!(f > 0.05 && depth > 0.005, "probe {f} N at {depth} m: {r}");
    // The recording replays to the same state.
    replays_to(&out, &d.join("replay"), &r);
}

/// The recording in `out` replayed into `again` reaches the state and step count of `r`.
fn replays_to(out: &std::path::Path, again: &std::path::Path, r: &serde_json::Value) {
    let o = run(&[
        "replay",
        out.join("input.vtrace").to_str().expect("utf-8"),
        "--out",
        again.to_str().expect("utf-8"),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let back = report(again);
    assert_eq!(back["state_hash"], r["state_hash"]);
    assert_eq!(back["steps"], r["steps"]);
}

#[test]
fn two_styluses_drive_both_hands() {
    let d = tmp("haptics-session", "two");
    let o = run(&[
        "run",
        "sandbox",
        "--no-window",
        "--haptics",
        "sim,sim",
        "--seconds",
        "1.2",
        "--out",
        d.to_str().expect("utf-8"),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("on the left hand") && stdout.contains("on the right hand"));
    let r = report(&d);
    // Each hand's stylus moved its instrument down into its side of the block: both touched
    // and pushed back.
    for hand in ["left", "right"] {
        let path = r["metrics"][format!("path_length_{hand}_m")]
            .as_f64()
            .unwrap_or(0.0);
        assert!(path > 0.02, "{hand}: {path} m: {r}");
    }
    let events = std::fs::read_to_string(d.join("events.jsonl")).expect("events.jsonl");
    for hand in ["left", "right"] {
        let touched = events.lines().any(|l| {
            let e: serde_json::Value = serde_json::from_str(l).expect("JSON");
            e["kind"] == "contact" && e["tool"] == hand
        });
        assert!(touched, "no contact by the {hand} instrument: {events}");
    }
    let grasper = r["metrics"]["max_grasper_force_n"].as_f64().unwrap_or(0.0);
    let probe = r["metrics"]["max_probe_force_n"].as_f64().unwrap_or(0.0);
    assert!(grasper > 0.0 && probe > 0.05, "{grasper} N, {probe} N: {r}");
}

#[test]
fn a_phantom_drives_a_session_through_its_library() {
    let d = tmp("haptics-session", "phantom");
    let o = bin()
        .args(["run", "sandbox", "--no-window", "--haptics", "phantom"])
        .args(["--seconds", "1"])
        .arg("--out")
        .arg(&*d)
        .env("LD_LIBRARY_PATH", xr_bindings::haptics::fake_library_dir())
        .env_remove("VESALIUS_LIBHD")
        // The stylus 16 mm below the device's origin, which is 15 mm above the block's top.
        .env("FAKE_HD_POSITION_MM", "0,-16,0")
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let r = report(&d);
    assert_eq!(r["ended"], "time_up", "{r}");
    // The probe's point is held 1 mm under the top: its ball tip is that plus its radius deep.
    let scenario: toml::Table = vesalius::registry::builtin("sandbox")
        .expect("builtin")
        .parse()
        .expect("TOML");
    let radius = scenario["tools"]["probe_tip_radius_m"]
        .as_float()
        .expect("probe radius");
    let depth = r["metrics"]["max_probe_depth_m"].as_f64().unwrap_or(0.0);
    assert!(
        (depth - (0.001 + radius)).abs() < 2e-4,
        "probe {depth} m deep: {r}"
    );
}

/// The tools that touched tissue, from a session's events.
fn touching_tools(dir: &std::path::Path) -> Vec<String> {
    let events = std::fs::read_to_string(dir.join("events.jsonl")).expect("events.jsonl");
    let mut tools: Vec<String> = events
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|e| e["kind"] == "contact")
        .filter_map(|e| e["tool"].as_str().map(str::to_string))
        .collect();
    tools.sort();
    tools.dedup();
    tools
}

#[test]
fn two_phantoms_share_hds_scheduler_each_driving_its_own_hand() {
    let d = tmp("haptics-session", "two-phantoms");
    let o = bin()
        .args([
            "run",
            "sandbox",
            "--no-window",
            "--haptics",
            "phantom,phantom",
        ])
        .args(["--hd-names", "Left Device,Right Device", "--seconds", "1"])
        .arg("--out")
        .arg(&*d)
        .env("LD_LIBRARY_PATH", xr_bindings::haptics::fake_library_dir())
        .env_remove("VESALIUS_LIBHD")
        // The first (left hand) held 10 mm above its origin, clear of the block; the second
        // (right hand) 16 mm below its origin, 1 mm into the block.
        .env("FAKE_HD_POSITION_MM_0", "0,10,0")
        .env("FAKE_HD_POSITION_MM_1", "0,-16,0")
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    for name in [
        "'Left Device' on the left hand",
        "'Right Device' on the right hand",
    ] {
        assert!(stdout.contains(name), "{name}: {stdout}");
    }
    let r = report(&d);
    assert_eq!(r["ended"], "time_up", "{r}");
    assert_eq!(touching_tools(&d), ["right"], "{r}");
    let probe = r["metrics"]["max_probe_force_n"].as_f64().unwrap_or(0.0);
    let grasper = r["metrics"]["max_grasper_force_n"].as_f64().unwrap_or(-1.0);
    assert!(
        probe > 0.01 && grasper == 0.0,
        "{probe} N, {grasper} N: {r}"
    );
}

#[test]
fn forces_held_off_at_start_up_are_explained_once() {
    let d = tmp("haptics-session", "held-off");
    let o = bin()
        .args(["run", "sandbox", "--no-window", "--haptics", "phantom"])
        .args(["--seconds", "1.5"])
        .arg("--out")
        .arg(&*d)
        .env("LD_LIBRARY_PATH", xr_bindings::haptics::fake_library_dir())
        .env_remove("VESALIUS_LIBHD")
        // A stylus that never holds still (5 cm/s): the start-up ramp never begins.
        .env("FAKE_HD_VELOCITY_MM_S", "50,0,0")
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(
        stderr
            .matches("forces stay off until the stylus is held still")
            .count(),
        1,
        "{stderr}"
    );
    let events = std::fs::read_to_string(d.join("events.jsonl")).expect("events.jsonl");
    let phases: Vec<String> = events
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .filter(|e| e["kind"] == "haptic_ramp")
        .filter_map(|e| e["phase"].as_str().map(str::to_string))
        // The start-up ramp's phases only: a loaded machine may also pause the simulation for
        // over 10 ms, and the stall watchdog's own recovery ramp (`recover`, `recovered`) is
        // a separate gain that says nothing about the start-up.
        .filter(|p| !p.starts_with("recover"))
        .collect();
    assert_eq!(phases, ["held_off"], "{events}");
}

#[test]
fn bad_device_lists_are_usage_errors() {
    for args in [
        &["run", "sandbox", "--haptics", "sim,sim,sim"][..],
        &["run", "sandbox", "--haptics", "omni"],
        &["run", "sandbox", "--haptics", "phantom,phantom"],
        &[
            "run",
            "sandbox",
            "--haptics",
            "phantom,phantom",
            "--hd-names",
            "Left",
        ],
        &["run", "sandbox", "--haptics", "sim", "--hd-names", "Left"],
        &["haptics", "--device", "sim", "--hd-name", "Left"],
        &[
            "run",
            "sandbox",
            "--haptics",
            "sim",
            "--workspace-scale",
            "0",
        ],
        &["run", "sandbox", "--haptics", "sim", "--headless"],
        &["run", "sandbox", "--workspace-scale", "2"],
    ] {
        let o = run(args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o));
        assert!(!text(&o).contains("panicked"), "{args:?}");
    }
}

/// `--haptics default` opens the procedure's own device: for the catheterisation the
/// paper's Novint Falcon (here the fake DHD library), bound to the hand that holds the
/// catheter, whose travel pushes it in.
#[test]
fn the_catheters_default_device_is_a_falcon_on_the_catheters_hand() {
    let d = tmp("haptics-session", "catheter-falcon");
    let o = bin()
        .args(["run", "catheter", "--no-window", "--haptics", "default"])
        .args(["--seconds", "1"])
        .arg("--out")
        .arg(&*d)
        .env("LD_LIBRARY_PATH", xr_bindings::haptics::fake_library_dir())
        .env_remove("VESALIUS_LIBDHD")
        .env("FAKE_DHD_POSITION_M", "0.02,0,0")
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let all = text(&o);
    assert!(
        all.contains("Falcon") && all.contains("right hand"),
        "{all}"
    );
    let r = report(&d);
    assert_eq!(r["procedure"], "catheter", "{r}");
    assert_eq!(r["ended"], "time_up", "{r}");
    assert!(
        r["metrics"]["tip_path_m"].as_f64().unwrap_or(0.0) > 0.01,
        "{r}"
    );
}

#[test]
fn a_stylus_drives_its_instrument_in_the_headset() {
    let d = tmp("haptics-session", "xr");
    let trace = common::controllers_held_away(&d, 2.0);
    let session = |name: &str, stylus: bool| {
        let out = d.join(name);
        let mut args = vec![
            "run",
            "sandbox",
            "--xr-sim",
            trace.to_str().expect("utf-8"),
            "--xr-duration",
            "2",
            "--no-window",
            "--eye-size",
            "64x64",
            "--out",
            out.to_str().expect("utf-8"),
        ];
        if stylus {
            args.extend(["--haptics", "sim"]);
        }
        let o = run(&args);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o));
        (String::from_utf8_lossy(&o.stdout).into_owned(), out)
    };
    // The controller alone touches nothing.
    let (_, alone) = session("controller", false);
    let r = report(&alone);
    assert_eq!(r["events"]["contact"].as_u64().unwrap_or(0), 0, "{r}");
    // With the stylus bound, the probe follows the stylus down into the block (26 mm from
    // 15 mm above it), and the servo loop felt the block push back.
    let (stdout, out) = session("stylus", true);
    assert!(
        stdout.contains("simulated stylus on the right hand"),
        "{stdout}"
    );
    let r = report(&out);
    assert_eq!(r["ended"], "xr_exit", "{r}");
    assert!(r["events"]["contact"].as_u64().unwrap_or(0) >= 1, "{r}");
    let f = r["metrics"]["max_probe_force_n"].as_f64().unwrap_or(0.0);
    let depth = r["metrics"]["max_probe_depth_m"].as_f64().unwrap_or(0.0);
    assert!(f > 0.05 && depth > 0.005, "probe {f} N at {depth} m: {r}");
    let felt = stdout
        .lines()
        .find_map(|l| l.split("max force ").nth(1))
        .and_then(|rest| rest.split(' ').next())
        .and_then(|n| n.parse::<f64>().ok())
        .unwrap_or(0.0);
    assert!(felt > 0.05, "the stylus felt {felt} N: {stdout}");
    // The servo loop's start-up ramp is in the session's events.
    assert!(r["events"]["haptic_ramp"].as_u64().unwrap_or(0) >= 1, "{r}");
    // The recording holds the stylus's input: it replays to the same state.
    replays_to(&out, &d.join("replay"), &r);
}
