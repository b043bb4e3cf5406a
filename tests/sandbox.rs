//! The sandbox runs through every path with no code outside its folder but the registry line:
//! headless (and its replay, byte for byte), the window under Xvfb (same state as headless),
//! the simulated OpenXR runtime, `bench --json`, `profile --json` and `demo`, which plays every
//! registered procedure.

mod common;
use common::{Scratch, bin, ok, report};
use std::path::{Path, PathBuf};
use std::process::Command;

fn trace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/sandbox-demo.toml")
}

/// The task done in order, as the report's metrics and events say.
fn assert_completed(r: &serde_json::Value) {
    assert_eq!(r["procedure"], "sandbox");
    assert_eq!(r["completed"], true, "{r}");
    assert_eq!(r["events"]["task_step"], 4, "{r}");
    assert_eq!(
        r["metrics"]["steps_done"],
        serde_json::json!(["touch", "press", "grasp", "lift"])
    );
    assert_eq!(r["errors"], 0);
}

#[test]
fn headless_run_and_replay_give_the_same_bytes() {
    let dir = tmp("headless");
    let out = dir.join("out");
    ok(&bin()
        .args(["run", "sandbox", "--headless", "--trace"])
        .arg(trace())
        .arg("--out")
        .arg(&out)
        .output()
        .expect("runs"));
    let r = report(&out);
    assert_completed(&r);
    ok(&bin()
        .arg("replay")
        .arg(out.join("input.vtrace"))
        .arg("--out")
        .arg(dir.join("replay"))
        .output()
        .expect("runs"));
    for f in ["report.json", "events.jsonl"] {
        assert_eq!(
            std::fs::read(dir.join("replay").join(f)).expect("replayed"),
            std::fs::read(out.join(f)).expect("original"),
            "{f}"
        );
    }
}

#[test]
fn bench_and_profile_run_the_sandbox() {
    let o = ok(&bin()
        .args(["bench", "sandbox", "--json"])
        .output()
        .expect("runs"));
    let lines: Vec<serde_json::Value> = o
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect();
    let names: Vec<&str> = lines.iter().filter_map(|l| l["model"].as_str()).collect();
    assert_eq!(names, ["block", "procedure", "block", "procedure"]);
    for l in &lines {
        assert!(l["steps_per_s"].as_f64().unwrap_or(0.0) > 0.0, "{l}");
        assert_eq!(l["triangles"], 4172);
        let awake = l["awake_fraction"].as_f64().unwrap_or(f64::NAN);
        if l["all_awake"] == true {
            // Kept awake, every point steps every step.
            assert_eq!(awake, 1.0, "{l}");
        } else {
            // The demo touches the top of the block only: most of it sleeps.
            assert!(awake > 0.0 && awake < 0.5, "{l}");
        }
    }
    assert_eq!(lines[2]["all_awake"], true);
    assert_eq!(lines[0]["all_awake"], false);
    // The procedure's lines build a snapshot every 1 / 90 s of the sandbox's 2 ms steps, as
    // the window does; a model's line builds none.
    for l in &lines {
        let steps = l["steps"].as_u64().expect("steps");
        if l["model"] == "procedure" {
            assert_eq!(l["frames"].as_u64(), Some(steps / 6), "{l}");
            // The procedure's steps, on the CPU here, give their whole time's p99 and
            // their slowest second's pace.
            assert!(l["step_ms_p99"].as_f64().is_some_and(|t| t > 0.0), "{l}");
            let slowest = l["realtime_factor_slowest_s"].as_f64().unwrap_or(0.0);
            assert!(slowest > 0.0 && slowest.is_finite(), "{l}");
            let share = l["frame_share"].as_f64().expect("a share");
            assert!(share > 0.0 && share < 1.0, "{l}");
        } else {
            assert!(
                l["frames"].is_null()
                    && l["step_ms_p99"].is_null()
                    && l["realtime_factor_slowest_s"].is_null(),
                "{l}"
            );
        }
    }
    let p = ok(&bin()
        .args(["profile", "sandbox", "--json", "--eye-size", "64x64"])
        .args(["--beside", "1"])
        .output()
        .expect("runs"));
    let v: serde_json::Value = serde_json::from_str(&p).expect("JSON");
    assert_eq!(v["procedure"], "sandbox");
    // Then frames with the simulation stepping beside them, paced to the wall clock: it
    // stepped, never ran ahead of the wall clock, and its haptic channel took fresh forces.
    let b = &v["beside"];
    let f = |k: &str| b[k].as_f64().unwrap_or_else(|| panic!("no {k} in {b}"));
    assert!(b["frames"].as_u64().unwrap_or(0) >= 1, "{b}");
    assert!(
        f("frame_ms") > 0.0 && f("frame_ms_p99") <= f("frame_ms_max"),
        "{b}"
    );
    assert!(f("simulated_s") > 0.0, "{b}");
    assert!(
        f("simulated_s") <= f("seconds") + 1e-6 && f("realtime_factor") <= 1.0 + 1e-6,
        "{b}"
    );
    assert_eq!(b["compute"], "cpu", "the sandbox has no GPU path: {b}");
    assert_eq!(v["gpu_devices"], 1, "the frames' device alone: {v}");
    assert_eq!(b["shared_device"], false, "{b}");
    // Each fresh force a step apart at the least (the watch may miss some but not see one
    // twice), so no more of them than steps.
    let steps = f("simulated_s") / f("dt_s");
    let seen = b["force_updates"].as_f64().unwrap_or(0.0);
    assert!(
        seen >= 1.0 && seen <= steps + 1.0,
        "{seen} forces, {steps} steps: {b}"
    );
    assert!(
        v["paper"].is_null(),
        "no paper counters for the sandbox: {v}"
    );
    let c = &v["vesalius"];
    let draws = c["draw_calls"].as_u64().expect("draw calls");
    assert!((1..=9).contains(&draws), "{c}");
    assert!(c["triangles"].as_u64().unwrap_or(0) >= 3456, "{c}");
}

/// `profile --share-device`: the cholecystectomy's solver (its CPU preset's lattice, on the
/// GPU path: lavapipe here) steps on the frames' own device, so the process opens one device,
/// not two; the frames beside the simulation are drawn and it steps on that device.
#[test]
fn profile_steps_the_models_on_the_frames_device_when_asked() {
    let p = ok(&bin()
        .args([
            "profile",
            "cholecystectomy",
            "--json",
            "--eye-size",
            "64x64",
        ])
        .args(["--preset", "cpu", "--compute", "gpu", "--share-device"])
        .args(["--beside", "0.5"])
        .output()
        .expect("runs"));
    let v: serde_json::Value = serde_json::from_str(&p).expect("JSON");
    let b = &v["beside"];
    assert_eq!(b["compute"], "gpu", "{b}");
    assert_eq!(b["shared_device"], true, "{b}");
    assert_eq!(b["adapter"], v["device"], "{v}");
    assert_eq!(v["gpu_devices"], 1, "one device for frames and steps: {v}");
    assert!(b["frames"].as_u64().unwrap_or(0) >= 1, "{b}");
    assert!(b["simulated_s"].as_f64().unwrap_or(0.0) > 0.0, "{b}");
}

/// `vesalius demo` with the CPU presets: every procedure's demo, and every preset's, plays to
/// the task's end (the rectum's full 960,000-node grid steps in the bench's test run and in
/// `vesalius demo` on a machine with a GPU; without one, `auto` takes the presets there too).
#[test]
fn demo_plays_every_registered_procedure() {
    let dir = tmp("demo");
    let out = ok(&bin()
        .args(["demo", "--preset", "cpu", "--out"])
        .arg(&*dir)
        .output()
        .expect("runs"));
    for p in vesalius::registry::REGISTRY {
        let r = report(&dir.join(p.name));
        assert_eq!(r["procedure"], p.name);
        assert_eq!(r["completed"], true, "{}: {r}", p.name);
        assert!(
            out.contains(&format!("{}: completed=true", p.name)),
            "{out}"
        );
        // Six stereo frames and their contact sheet (3 x 2 thumbnails at half size), showing
        // the field: no one colour covers half the sheet (the black outside the image
        // circles is 29 % of it).
        let frames = dir.join(p.name).join("frames");
        assert!(frames.join("left_0005.png").exists() && frames.join("right_0005.png").exists());
        let (size, px) =
            vesalius::render::gpu::read_png(&dir.join(p.name).join("contact_sheet.png"))
                .expect("contact sheet");
        assert_eq!(size, (3 * 270, 2 * 300), "{}", p.name);
        let mut counts = std::collections::HashMap::new();
        for q in px.chunks_exact(4) {
            *counts.entry([q[0], q[1], q[2]]).or_insert(0usize) += 1;
        }
        let top = counts.values().max().copied().unwrap_or(0);
        assert!(
            top * 2 < px.len() / 4,
            "{}: one colour covers {top} pixels",
            p.name
        );
    }
    // Every session is in the demo's records, for trainee 'demo', with its level.
    let list = ok(&bin()
        .args(["records", "list", "--db"])
        .arg(dir.join("records.sqlite"))
        .output()
        .expect("runs"));
    for p in vesalius::registry::REGISTRY {
        let r = report(&dir.join(p.name));
        let id = r["session_id"].as_str().unwrap_or("?");
        let line = list.lines().find(|l| l.starts_with(id)).unwrap_or_default();
        let level = r["level"].as_str().unwrap_or("?");
        assert!(
            line.contains("demo") && line.contains(p.name) && line.contains(level),
            "{}: {list}",
            p.name
        );
    }
    assert_eq!(list.lines().count(), 1 + vesalius::registry::REGISTRY.len());
}

#[test]
fn the_window_and_the_simulated_headset_run_the_sandbox() {
    let dir = tmp("window");
    ok(&bin()
        .args(["run", "sandbox", "--headless", "--trace"])
        .arg(trace())
        .arg("--out")
        .arg(dir.join("headless"))
        .output()
        .expect("runs"));
    let shot = dir.join("shot.png");
    ok(&Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1920x1080x24"])
        .arg(env!("CARGO_BIN_EXE_vesalius"))
        .args(["run", "sandbox", "--window-size", "1280x720", "--trace"])
        .arg(trace())
        .arg("--screenshot")
        .arg(&shot)
        .arg("--out")
        .arg(dir.join("window"))
        .output()
        .expect("xvfb-run (apt-get install xvfb xauth)"));
    let w = report(&dir.join("window"));
    assert_completed(&w);
    assert_eq!(w["state_hash"], report(&dir.join("headless"))["state_hash"]);
    assert!(shot.is_file());
    ok(&bin()
        .args(["run", "sandbox", "--xr-sim"])
        .arg(trace())
        .arg("--out")
        .arg(dir.join("xr"))
        .args(["--eye-size", "64x64", "--no-window"])
        .output()
        .expect("runs"));
    let x = report(&dir.join("xr"));
    assert_completed(&x);
    assert_eq!(x["ended"], "xr_exit");
}

fn tmp(name: &str) -> Scratch {
    common::tmp("sandbox", name)
}
