//! The XR frame loop against the simulated runtime, through the Khronos loader, with scripted
//! controllers: vibration while (and only while) the grasper presses the kidney, growing with
//! depth; a controller that stops tracking freezes its instrument and raises an event; a lost
//! session stops, keeps its record and restarts when the headset returns.
//!
//! These run `vesalius run nephrectomy --xr` itself with `XR_RUNTIME_JSON` and the simulated
//! runtime's settings in the environment, the way a user points the loader at SteamVR.

mod common;
use common::Scratch;
use glam::Vec3;
use serde_json::Value;
use std::path::Path;
use std::process::Command;
use vesalius::procedures::Nephrectomy;
use vesalius::procedures::nephrectomy::{REGION_PARENCHYMA, Scenario};
use vesalius::registry::builtin;
use vesalius::sim::Hand;
use vesalius::trace::Recording;
use vesalius::xr::HapticProfile;

/// The simulated runtime's refresh period (90 Hz), seconds.
const PERIOD_S: f64 = vesalius_sim_runtime::FRAME_PERIOD_NS as f64 / 1e9;
/// Per-eye image size: the frame loop is what is tested here, not the pictures.
const EYE: &str = "64x64";

/// What one run left behind.
struct Run {
    report: Value,
    events: Vec<Value>,
    haptics: Vec<Value>,
    states: Vec<String>,
    recording: Recording,
    stdout: String,
}

fn temp_dir(name: &str) -> Scratch {
    common::tmp("xr-loop", name)
}

fn jsonl(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object a line"))
        .collect()
}

/// Runs the procedure under the simulated runtime playing `trace`, with `inject` appended to
/// its settings, for `duration_s` of simulated time, frame for frame (lockstep).
fn run_xr(dir: &Path, trace: &str, inject: &str, duration_s: f64) -> Run {
    run_xr_coupled(
        dir,
        trace,
        inject,
        duration_s,
        &["--xr-coupling", "lockstep"],
    )
}

/// [`run_xr`] with the frame loop coupled to the simulation as `coupling` (the options of
/// `run --xr` that say so) says.
fn run_xr_coupled(
    dir: &Path,
    trace: &str,
    inject: &str,
    duration_s: f64,
    coupling: &[&str],
) -> Run {
    std::fs::write(dir.join("trace.toml"), trace).expect("trace written");
    let sim = dir.join("xr-sim");
    let settings = format!(
        "out_dir = \"{}\"\ntrace = \"trace.toml\"\nframes_every = 0\n{inject}",
        sim.display()
    );
    std::fs::write(dir.join("settings.toml"), settings).expect("settings written");
    let manifest = dir.join("runtime.json");
    let m = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .args(["xr-sim", "manifest", "--out"])
        .arg(&manifest)
        .output()
        .expect("runs");
    assert!(m.status.success(), "{}", String::from_utf8_lossy(&m.stderr));
    let out = dir.join("out");
    let o = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .args([
            "run",
            "nephrectomy",
            "--xr",
            "--no-window",
            "--eye-size",
            EYE,
            "--out",
        ])
        .arg(&out)
        .args(coupling)
        .args(["--xr-duration", &duration_s.to_string()])
        .env("XR_RUNTIME_JSON", &manifest)
        .env(vesalius_sim_runtime::CONFIG_ENV, dir.join("settings.toml"))
        .output()
        .expect("runs");
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let report = serde_json::from_slice(&std::fs::read(out.join("report.json")).expect("report"))
        .expect("JSON report");
    let haptics = if sim.join("haptics.jsonl").exists() {
        jsonl(&sim.join("haptics.jsonl"))
    } else {
        Vec::new()
    };
    Run {
        report,
        events: jsonl(&out.join("events.jsonl")),
        haptics,
        states: std::fs::read_to_string(sim.join("session-states.log"))
            .expect("state log")
            .lines()
            .map(str::to_string)
            .collect(),
        recording: Recording::read(&out.join("input.vtrace")).expect("recording"),
        stdout: String::from_utf8_lossy(&o.stdout).into_owned(),
    }
}

fn key(hand: &str, t_s: f64, position: Vec3, target: Vec3) -> String {
    format!(
        "[[{hand}]]\nt_s = {t_s}\nposition = [{}, {}, {}]\ntarget = [{}, {}, {}]\n\n",
        position.x, position.y, position.z, target.x, target.y, target.z
    )
}

/// The laser held still off to the side, pointing away from the patient.
fn idle_laser(end_s: f64) -> String {
    let at = Vec3::new(0.12, 0.05, 0.15);
    let away = at + Vec3::new(0.1, 0.05, 0.2);
    key("right", 0.0, at, away) + &key("right", end_s, at, away)
}

/// Simulated time (s) of each event named `kind`.
fn event_times(run: &Run, kind: &str, dt_s: f64) -> Vec<f64> {
    run.events
        .iter()
        .filter(|e| e["kind"] == kind)
        .map(|e| e["step"].as_f64().expect("step") * dt_s)
        .collect()
}

/// The vibration of the nephrectomy's left-hand instrument, the grasper.
fn grasper_haptics() -> HapticProfile {
    HapticProfile::for_tool(vesalius::procedures::nephrectomy::INFO.tool(Hand::Left))
}

/// The grasper's press into the kidney: along the outward normal `d` of the lower pole's
/// lateral face, where the kidney's surface point furthest along `d` is, far from the tumour
/// and the hilum. The tip first touches tissue when it is one tip radius `r` above that point.
struct Press {
    r: f64,
    near: f64,
    deep: f64,
    times: [f64; 6],
    heights: [f64; 6],
    trace: String,
}

fn press(scenario: &Scenario) -> Press {
    let r = f64::from(scenario.grasper.tip_radius_m);
    let rest = Nephrectomy::new(scenario.clone()).expect("anatomy");
    let kidney = &rest.kidney();
    let d = Vec3::new(0.45, -0.85, 0.3).normalize();
    let (top, p) = kidney
        .positions()
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.dot(d).total_cmp(&b.1.dot(d)))
        .map(|(i, p)| (i, *p))
        .expect("kidney points");
    assert_eq!(kidney.regions()[top], REGION_PARENCHYMA);
    // Height of the tip above the point: from 30 mm to 2 mm short of contact by 0.5 s, then
    // slowly (3.3 mm/s) to 3 mm (one tip radius) past first contact at 2 s, held until 2.5 s,
    // back out to 30 mm at 3.5 s.
    let (h0, near, deep) = (0.03f64, r + 0.002, r - 0.003);
    let tip = |h: f64| p + d * h as f32;
    let aim = |h: f64| tip(h) - d * 0.05;
    let times = [0.0, 0.5, 2.0, 2.5, 3.5, 4.0];
    let heights = [h0, near, deep, deep, h0, h0];
    let mut trace = String::from("procedure = \"nephrectomy\"\n\n");
    for (t, h) in times.iter().zip(heights) {
        trace += &key("left", *t, tip(h), aim(h));
    }
    trace += &idle_laser(4.0);
    Press {
        r,
        near,
        deep,
        times,
        heights,
        trace,
    }
}

fn builtin_scenario() -> Scenario {
    Scenario::parse("builtin", builtin("nephrectomy").expect("builtin")).expect("builtin scenario")
}

#[test]
fn the_grasper_vibrates_exactly_while_it_presses_the_kidney_and_harder_when_deeper() {
    let scenario = builtin_scenario();
    let dt = f64::from(scenario.dt_s);
    let Press {
        r,
        near,
        deep,
        times,
        heights,
        trace,
    } = press(&scenario);
    let height_at = |t: f64| {
        let k = times.partition_point(|&x| x <= t).clamp(1, times.len() - 1);
        let s = ((t - times[k - 1]) / (times[k] - times[k - 1])).clamp(0.0, 1.0);
        heights[k - 1] + (heights[k] - heights[k - 1]) * s
    };
    let dir = temp_dir("press");
    let run = run_xr(&dir, &trace, "", 4.0);

    // The reference: replay the recorded input through the simulation and take the grasper's
    // contact force at every step.
    let rec = &run.recording;
    assert_eq!(rec.scenario, builtin("nephrectomy").expect("builtin"));
    let mut replay = Nephrectomy::new(scenario.clone()).expect("anatomy");
    let mut events = Vec::new();
    let force: Vec<f32> = rec
        .frames
        .iter()
        .enumerate()
        .map(|(k, f)| {
            replay.step(f, k as u64, &mut events);
            replay.reactions()[Hand::Left.index()].length()
        })
        .collect();
    assert_eq!(
        run.report["state_hash"],
        format!("{:016x}", replay.world().state_hash()),
        "the replay reproduces the run"
    );
    // The app steps up to each frame's display time: step k (centred at (k + 1/2) dt) belongs
    // to the first frame displayed at or after it. Expected: a pulse in every frame whose
    // steps pressed, with the amplitude of the frame's peak force.
    let frames = (rec.frames.len() as f64 * dt / PERIOD_S).ceil() as usize + 1;
    let mut peak = vec![0.0f32; frames];
    for (k, f) in force.iter().enumerate() {
        let j = (((k as f64 + 0.5) * dt / PERIOD_S) - 1e-9).ceil() as usize;
        peak[j] = peak[j].max(*f);
    }
    let expected: Vec<(usize, f32)> = peak
        .iter()
        .enumerate()
        .filter_map(|(j, f)| grasper_haptics().amplitude(*f).map(|a| (j, a)))
        .collect();
    let frame_of = |l: &Value| (l["t_s"].as_f64().expect("t_s") / PERIOD_S).round() as usize;
    let pulses: Vec<(usize, f32)> = run
        .haptics
        .iter()
        .filter(|l| l["hand"] == "left" && l.get("amplitude").is_some())
        .map(|l| {
            (
                frame_of(l),
                l["amplitude"].as_f64().expect("amplitude") as f32,
            )
        })
        .collect();
    assert_eq!(
        pulses.iter().map(|p| p.0).collect::<Vec<_>>(),
        expected.iter().map(|p| p.0).collect::<Vec<_>>(),
        "pulses in exactly the frames that pressed tissue"
    );
    for ((j, got), (_, want)) in pulses.iter().zip(&expected) {
        assert!((got - want).abs() < 1e-6, "frame {j}: {got} vs {want}");
    }
    for l in run.haptics.iter().filter(|l| l["hand"] == "left") {
        if l.get("amplitude").is_some() {
            assert_eq!(l["frequency_hz"], f64::from(grasper_haptics().frequency_hz));
            assert!((l["duration_s"].as_f64().expect("duration") - 0.025).abs() < 1e-9);
        }
    }
    // Contact, in space: the first pulse comes in the frame in which the tip reached one tip
    // radius from the surface, not before; pulses go on at least while the tip goes in and
    // holds (to 2.5 s).
    let touch = 0.5 + 1.5 * (near - r) / (near - deep);
    let held_frames = ((2.5 - touch) / PERIOD_S).floor() as usize;
    assert!(
        pulses.len() >= held_frames,
        "{} grasper pulses for {held_frames} frames of contact",
        pulses.len()
    );
    let first = pulses[0].0 as f64 * PERIOD_S;
    assert!(
        first >= touch - dt && first < touch + PERIOD_S + dt,
        "first pulse at {first:.4} s, tip at one radius at {touch:.4} s"
    );
    // The pulses stop with a stop call, once, after the last; nothing after it.
    let last = pulses.last().expect("pulses").0;
    let stops: Vec<usize> = run
        .haptics
        .iter()
        .filter(|l| l["hand"] == "left" && l["stop"] == true)
        .map(frame_of)
        .collect();
    assert_eq!(
        stops,
        [last + 1],
        "one stop, the frame after the last pulse"
    );
    assert!(
        (last as f64 * PERIOD_S) < 3.5,
        "contact ended before the tip was back out"
    );
    // The laser, pointed away, never buzzed.
    assert!(run.haptics.iter().all(|l| l["hand"] == "left"));
    // Harder when deeper: while the tip goes in, the amplitude rises with depth.
    let pressing: Vec<(f64, f32)> = pulses
        .iter()
        .map(|&(j, a)| (j as f64 * PERIOD_S, a))
        .filter(|&(t, _)| t <= 2.0)
        .map(|(t, a)| (r - height_at(t), a))
        .collect();
    let max_depth = r - deep;
    let mean_in = |lo: f64, hi: f64| {
        let v: Vec<f32> = pressing
            .iter()
            .filter(|p| p.0 >= lo * max_depth && p.0 < hi * max_depth)
            .map(|p| p.1)
            .collect();
        assert!(v.len() >= 5, "{} pulses between {lo} and {hi}", v.len());
        v.iter().sum::<f32>() / v.len() as f32
    };
    let thirds = [
        mean_in(0.0, 1.0 / 3.0),
        mean_in(1.0 / 3.0, 2.0 / 3.0),
        mean_in(2.0 / 3.0, 1.01),
    ];
    assert!(
        thirds[0] < thirds[1] && thirds[1] < thirds[2] && thirds[2] < 1.0,
        "mean amplitude by depth third: {thirds:?}"
    );
    assert!(thirds[2] > 2.0 * thirds[0], "{thirds:?}");
    eprintln!(
        "{} grasper pulses from {first:.3} s (contact at {touch:.3} s); mean amplitude by depth third {thirds:?}",
        pulses.len()
    );
}

#[test]
fn paced_frames_record_the_same_session_as_lockstep_and_still_vibrate() {
    let trace = press(&builtin_scenario()).trace;
    let dir = temp_dir("paced");
    let (a, b) = (dir.join("paced"), dir.join("lockstep"));
    for d in [&a, &b] {
        std::fs::create_dir_all(d).expect("temp dir");
    }
    // No bound on the lag: the simulated runtime makes frames far faster than the
    // simulation steps them, and every frame's time is stepped.
    let unbounded = ["--xr-coupling", "paced", "--xr-max-lag", "inf"];
    let paced = run_xr_coupled(&a, &trace, "", 4.0, &unbounded);
    assert!(!paced.stdout.contains("fell behind"), "{}", paced.stdout);
    let lockstep = run_xr(&b, &trace, "", 4.0);
    // The steps depend only on the frames' display times and readings, which the simulated
    // runtime makes the same: the same input, the same session.
    assert_eq!(paced.recording.frames, lockstep.recording.frames);
    assert_eq!(paced.report["state_hash"], lockstep.report["state_hash"]);
    assert_eq!(paced.report["steps"], lockstep.report["steps"]);
    // The frame loop did not wait for the steps, and the grasper's press was still felt.
    let pulses = paced
        .haptics
        .iter()
        .filter(|l| l["hand"] == "left" && l.get("amplitude").is_some())
        .count();
    assert!(pulses >= 10, "{pulses} grasper pulses");
}

/// Paced with a bound on its lag under a frame's period (6 ms against 11.1): every frame
/// asks for more than the bound past where the simulation stood, so the simulation runs
/// slower than the frames' clock instead of stepping every frame's time. The session still
/// simulates its whole duration, and its recording replays to the same state.
#[test]
fn a_paced_simulation_behind_the_frames_runs_slow_within_its_bound() {
    let trace = press(&builtin_scenario()).trace;
    let dir = temp_dir("paced-bound");
    const { assert!(PERIOD_S > 0.006) };
    let bounded = ["--xr-coupling", "paced", "--xr-max-lag", "0.006"];
    let run = run_xr_coupled(&dir, &trace, "", 1.0, &bounded);
    assert!(run.stdout.contains("fell behind"), "{}", run.stdout);
    // No frame took the simulation more than the bound and half a 4 ms step past where it
    // stood: a second took at least 125 frames, where 90 step it unbounded.
    let frames: u64 = run
        .stdout
        .split(" stereo frames")
        .next()
        .and_then(|l| l.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no frame count in {}", run.stdout));
    assert!(frames >= 125, "{frames} frames");
    let simulated = run.report["simulated_s"]
        .as_f64()
        .expect("simulated seconds");
    assert!((simulated - 1.0).abs() < 0.01, "{simulated}");
    let again = dir.join("replay");
    let o = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .arg("replay")
        .arg(dir.join("out").join("input.vtrace"))
        .arg("--out")
        .arg(&again)
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let back: Value =
        serde_json::from_slice(&std::fs::read(again.join("report.json")).expect("report"))
            .expect("JSON report");
    assert_eq!(back["state_hash"], run.report["state_hash"]);
    assert_eq!(back["steps"], run.report["steps"]);
    // A bound that is not a positive number of seconds is refused, naming the option.
    let bad = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .args([
            "run",
            "nephrectomy",
            "--xr",
            "--no-window",
            "--xr-max-lag",
            "0",
        ])
        .output()
        .expect("runs");
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("--xr-max-lag"));
}

/// The grasper swept through free space (no tissue within 3 cm) from `A` to `B` over 3 s,
/// the laser swept beside the patient, pointing away.
const A: Vec3 = Vec3::new(-0.09, 0.07, 0.12);
const B: Vec3 = Vec3::new(-0.05, 0.09, 0.10);
const R0: Vec3 = Vec3::new(0.12, 0.05, 0.15);
const R1: Vec3 = Vec3::new(0.14, 0.07, 0.15);

fn sweep_trace() -> String {
    let (r0, r1) = (R0, R1);
    let away = Vec3::new(0.1, 0.05, 0.2);
    let mut t = String::from("procedure = \"nephrectomy\"\n\n");
    t += &key("left", 0.0, A, A + Vec3::new(0.0, 0.0, -0.05));
    t += &key("left", 3.0, B, B + Vec3::new(0.0, 0.0, -0.05));
    t += &key("right", 0.0, r0, r0 + away);
    t += &key("right", 3.0, r1, r1 + away);
    t
}

/// Where the trace puts the grasper at `t_s`.
fn swept(t_s: f64) -> Vec3 {
    A.lerp(B, (t_s / 3.0).clamp(0.0, 1.0) as f32)
}

#[test]
fn a_controller_out_of_tracking_freezes_its_instrument_and_raises_an_event() {
    let dir = temp_dir("controller");
    let inject =
        "[inject]\n[[inject.controller_loss]]\nhand = \"left\"\nfrom_s = 0.8\nto_s = 1.3\n";
    let run = run_xr(&dir, &sweep_trace(), inject, 2.0);
    let dt = run.report["dt_s"].as_f64().expect("dt_s");
    // Raised in the first frame at or after each edge, for the left hand only.
    let lost = event_times(&run, "controller_lost", dt);
    let back = event_times(&run, "controller_regained", dt);
    assert_eq!((lost.len(), back.len()), (1, 1), "{:?}", run.events);
    assert!(
        lost[0] >= 0.8 - dt && lost[0] < 0.8 + 2.0 * PERIOD_S,
        "lost at {}",
        lost[0]
    );
    assert!(
        back[0] >= 1.3 - dt && back[0] < 1.3 + 2.0 * PERIOD_S,
        "back at {}",
        back[0]
    );
    assert!(run.events.iter().all(|e| e["hand"] != "right"));
    // While lost, the grasper stays where it was last seen though the hand moved on 6.7 mm;
    // the laser, still tracked, keeps moving.
    let frames = &run.recording.frames;
    let at = |t: f64| &frames[(t / dt).round() as usize];
    let left = |t: f64| at(t).hands[Hand::Left.index()].pose.position;
    let right = |t: f64| at(t).hands[Hand::Right.index()].pose.position;
    let frozen = left(lost[0] + 2.0 * PERIOD_S);
    for k in 0..=20 {
        let t = lost[0] + 2.0 * PERIOD_S + (back[0] - lost[0] - 3.0 * PERIOD_S) * k as f64 / 20.0;
        assert_eq!(left(t), frozen, "the lost grasper moved at {t:.3} s");
    }
    assert!(
        frozen.distance(swept(0.8)) < 2e-4,
        "frozen at {frozen}, lost at {}",
        swept(0.8)
    );
    let laser_moved = right(1.25) - right(0.85);
    assert!(
        laser_moved.distance((R1 - R0) * (0.4 / 3.0)) < 2e-4,
        "the laser kept moving with its hand: {laser_moved}"
    );
    // Tracked again, it follows the hand.
    for t in [1.5, 1.8] {
        assert!(
            left(t).distance(swept(t)) < 2e-4,
            "{t} s: {} vs {}",
            left(t),
            swept(t)
        );
    }
}

#[test]
fn a_lost_session_stops_keeps_its_record_and_restarts_when_the_headset_returns() {
    let dir = temp_dir("session");
    let inject = "[inject]\nsession_loss_s = 1.0\nheadset_back_after_polls = 3\n";
    let run = run_xr(&dir, &sweep_trace(), inject, 2.0);
    let dt = run.report["dt_s"].as_f64().expect("dt_s");
    let lost = event_times(&run, "session_lost", dt);
    let restarted = event_times(&run, "session_restarted", dt);
    assert_eq!((lost.len(), restarted.len()), (1, 1), "{:?}", run.events);
    assert!(
        lost[0] >= 1.0 - dt && lost[0] < 1.0 + 2.0 * PERIOD_S,
        "lost at {}",
        lost[0]
    );
    assert!(restarted[0] >= lost[0], "restarted at {}", restarted[0]);
    // The runtime saw two sessions: the first lost, the second run to a clean exit.
    let of = |n: &str| -> Vec<&str> {
        run.states
            .iter()
            .filter_map(|l| {
                let mut w = l.split(' ').skip(1);
                (w.next() == Some(n)).then(|| w.next().unwrap_or(""))
            })
            .collect()
    };
    assert_eq!(of("1").last(), Some(&"LOSS_PENDING"), "{:?}", run.states);
    assert!(of("1").contains(&"FOCUSED"), "{:?}", run.states);
    assert_eq!(
        of("2"),
        [
            "IDLE",
            "READY",
            "SYNCHRONIZED",
            "VISIBLE",
            "FOCUSED",
            "VISIBLE",
            "SYNCHRONIZED",
            "STOPPING",
            "IDLE",
            "EXITING"
        ]
    );
    // One complete record across both sessions: every step simulated is in the recording and
    // the report, and the run went on to its full length after the restart.
    let steps = run.report["steps"].as_u64().expect("steps");
    assert_eq!(run.recording.frames.len() as u64, steps);
    assert!((run.report["simulated_s"].as_f64().expect("simulated_s") - 2.0).abs() <= dt);
    assert_eq!(run.report["events"]["session_lost"], 1);
    // The grasper follows the hand again in the new session (the sweep is at most a few
    // frames behind where it was: the headset's absence passes no display time).
    let left = run.recording.frames[steps as usize - 1].hands[Hand::Left.index()]
        .pose
        .position;
    assert!(left.distance(swept(2.0)) < 1e-3, "{left} vs {}", swept(2.0));
}
