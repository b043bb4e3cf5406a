//! Headless sessions end to end: the demo completes, runs are byte-identical, replays match,
//! and 1 and 2 worker threads agree.

mod common;
use common::{Scratch, without_id};
use std::path::Path;
use std::process::Command;
use vesalius::registry::builtin;
use vesalius::session::{self, Input};
use vesalius::sim::{Pacing, SnapshotBus};
use vesalius::trace::KeyTrace;

fn demo_trace() -> KeyTrace {
    KeyTrace::parse("demo", vesalius::procedures::nephrectomy::INFO.demo_trace)
        .expect("demo trace parses")
}

fn scenario() -> &'static str {
    builtin("nephrectomy").expect("builtin scenario")
}

/// The shipped scenario at coarse resolution, for quick determinism runs.
fn coarse() -> String {
    scenario()
        .replace("level = 5", "level = 3")
        .replace("vessel_rings = 64", "vessel_rings = 12")
}

fn tmp(name: &str) -> Scratch {
    common::tmp("test", name)
}

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vesalius"))
}

#[test]
fn the_demo_removes_the_tumour_by_cutting_and_replays_byte_for_byte() {
    let bus = SnapshotBus::new();
    let o = session::run(
        scenario(),
        "nephrectomy.toml",
        Input::Keys(demo_trace()),
        Pacing::AsFastAsPossible,
        Some(&bus),
    )
    .expect("session runs");
    let r = &o.report;
    assert!(r.completed);
    assert!(r.models.iter().map(|m| m.triangles).sum::<usize>() >= 50_000);
    assert!(r.events.get("cut").copied().unwrap_or(0) > 0);
    assert_eq!(r.events.get("tumour_removed"), Some(&1));
    assert_eq!(
        r.events.get("tie_broken"),
        None,
        "freed by the cut, not torn"
    );
    assert_eq!(
        r.events.get("quarantined"),
        None,
        "no model went non-finite (the quarantine is a safety net, not a step of the demo)"
    );
    // Lifting the freed tumour out takes about its weight (a 4 cm ball of tissue, 35 g:
    // 0.34 N), far below the grasper's 3.5 N full scale, and the trace keeps 5 mm from the
    // vessels: the supervisor sees no alarm. (The alarm rules have their own tests.)
    let alarms: Vec<&str> = o
        .events
        .iter()
        .filter_map(|e| match &e.kind {
            vesalius::sim::EventKind::Alarm { message, .. } => Some(message.as_str()),
            _ => None,
        })
        .collect();
    assert!(alarms.is_empty(), "{alarms:?}");
    assert_eq!(r.events.get("alarm"), None);
    let deviation = r.metrics["cut_deviation_mean_m"]
        .as_f64()
        .expect("deviation");
    assert!(deviation < 0.002, "{deviation}");
    assert!(r.score > 50.0 && r.score <= 100.0);
    // A snapshot reached the bus with every model and finite geometry.
    let snap = bus.latest();
    assert_eq!(snap.models.len(), 4);
    assert!(
        snap.models
            .iter()
            .all(|m| m.positions.iter().all(|p| p.is_finite()))
    );

    let dir = tmp("demo");
    session::write_outputs(&o, &dir).expect("outputs written");
    let report = std::fs::read(dir.join("report.json")).expect("report");
    let text = String::from_utf8_lossy(&report);
    for key in [
        "\"procedure\"",
        "\"completed\": true",
        "\"dt_s\"",
        "\"steps\"",
        "\"simulated_s\"",
        "\"models\"",
        "\"metrics\"",
        "\"score\"",
    ] {
        assert!(text.contains(key), "report lacks {key}");
    }
    assert!(
        !text.contains("wall"),
        "no wall-clock fields in report.json"
    );
    let out2 = dir.join("replayed");
    let status = bin()
        .args(["replay"])
        .arg(dir.join("input.vtrace"))
        .arg("--out")
        .arg(&out2)
        .status()
        .expect("runs");
    assert!(status.success());
    assert_eq!(
        std::fs::read(out2.join("report.json")).expect("replayed report"),
        report
    );
    assert_eq!(
        std::fs::read(out2.join("events.jsonl")).expect("events"),
        std::fs::read(dir.join("events.jsonl")).expect("events")
    );
    // Replayed with frames: the same bytes, and two stereo frames of the size asked for.
    let out3 = dir.join("replayed-frames");
    let status = bin()
        .args(["replay"])
        .arg(dir.join("input.vtrace"))
        .args(["--out"])
        .arg(&out3)
        .args(["--frames", "2", "--eye-size", "64x48"])
        .status()
        .expect("runs");
    assert!(status.success());
    assert_eq!(
        std::fs::read(out3.join("report.json")).expect("replayed report"),
        report
    );
    for f in [
        "left_0000.png",
        "right_0000.png",
        "left_0001.png",
        "right_0001.png",
    ] {
        let png = std::fs::read(out3.join("frames").join(f)).expect(f);
        let reader = png::Decoder::new(std::io::Cursor::new(png))
            .read_info()
            .expect("png");
        let info = reader.info();
        assert_eq!((info.width, info.height), (64, 48), "{f}");
    }
    assert!(out3.join("profiler.csv").is_file());
}

fn run_cli(dir: &Path, threads: &str) -> Vec<u8> {
    std::fs::create_dir_all(dir).expect("dir");
    let scen = dir.join("coarse.toml");
    std::fs::write(&scen, coarse()).expect("write scenario");
    let trace = dir.join("demo.toml");
    std::fs::write(&trace, vesalius::procedures::nephrectomy::INFO.demo_trace)
        .expect("write trace");
    let out = dir.join("out");
    let o = bin()
        .args([
            "--threads",
            threads,
            "run",
            "nephrectomy",
            "--headless",
            "--trace",
        ])
        .arg(&trace)
        .arg("--scenario")
        .arg(&scen)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read(out.join("report.json")).expect("report")
}

#[test]
fn same_trace_gives_the_same_bytes_on_one_and_two_threads() {
    let (d1, d2) = (tmp("t1a"), tmp("t2"));
    let a = run_cli(&d1, "1");
    let c = run_cli(&d2, "2");
    assert_ne!(a, c, "two sessions, two session ids");
    assert_eq!(without_id(&a), without_id(&c), "1 and 2 threads differ");
    assert!(String::from_utf8_lossy(&a).contains("\"state_hash\""));
    // One recording replayed on 1 and on 2 threads: the same bytes, session id included.
    let replay = |threads: &str, out: &Path| {
        let o = bin()
            .args(["--threads", threads, "replay"])
            .arg(d1.join("out/input.vtrace"))
            .arg("--out")
            .arg(out)
            .output()
            .expect("runs");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(out.join("report.json")).expect("report")
    };
    assert_eq!(replay("1", &d1.join("r1")), a);
    assert_eq!(replay("2", &d1.join("r2")), a);
}

#[test]
fn check_accepts_the_shipped_files_and_bench_prints_json_lines() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let o = bin()
        .arg("check")
        .arg(root.join("assets/scenarios/nephrectomy.toml"))
        .arg(root.join("assets/traces/nephrectomy-demo.toml"))
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(
        s.contains("ok (scenario)") && s.contains("ok (keyframed trace)"),
        "{s}"
    );
}

/// A tunable value of the session's model, now.
fn value(live: &session::Live, key: &str) -> f32 {
    live.tunables()
        .iter()
        .find(|t| t.key == key)
        .map_or(f32::NAN, |t| t.value)
}

/// A supervisor's live change of the kidney's parameters is part of the record: the replay
/// makes it at the same step and ends in the same state; without it the state differs.
#[test]
fn a_live_tissue_tuning_is_recorded_and_replayed_at_its_step() {
    let text = coarse();
    let keys = demo_trace();
    let run = |tune_at: Option<u64>| {
        let mut live =
            session::Live::new(&text, "coarse", Pacing::AsFastAsPossible).expect("scenario");
        let steps = live.steps_for(7.0);
        let spring = value(&live, "foundation_pa_per_m") * 4.0;
        let t = vec![
            ("foundation_pa_per_m".to_string(), spring),
            ("damping_per_s".to_string(), 2.0),
        ];
        while live.step_count() < steps {
            if Some(live.step_count()) == tune_at {
                live.tune("kidney", &t).expect("in range");
            }
            let frame = keys.sample(live.time_s());
            live.step(frame).expect("steps");
        }
        assert_eq!(
            value(&live, "foundation_pa_per_m") == spring && value(&live, "damping_per_s") == 2.0,
            tune_at.is_some()
        );
        let o = live.finish(Vec::new()).expect("finishes");
        let session::Recorded::InMemory(rec) = o.recording else {
            panic!("no output folder: the recording is in memory");
        };
        (o.report, rec)
    };
    // The tuning lands 5.4 s in, whatever the scenario's step.
    let at = session::Live::new(&text, "coarse", Pacing::AsFastAsPossible)
        .expect("scenario")
        .steps_for(5.4);
    let (tuned, tuned_rec) = run(Some(at));
    assert_eq!(tuned_rec.tunings.len(), 1);
    assert_eq!(tuned_rec.tunings[0].step, at);
    assert_eq!(tuned_rec.tunings[0].model, "kidney");
    assert_eq!(tuned.events.get("tissue_tuned"), Some(&1));
    let (plain, _) = run(None);
    assert_ne!(tuned.state_hash, plain.state_hash);
    // Through the file and back, then replayed.
    let dir = tmp("tuning");
    let path = dir.join("input.vtrace");
    tuned_rec.write(&path).expect("write");
    let rec = vesalius::trace::Recording::read(&path).expect("read");
    assert_eq!(rec, tuned_rec);
    let scenario = rec.scenario.clone();
    let replayed = session::run(
        &scenario,
        "replay",
        Input::Recorded(rec),
        Pacing::AsFastAsPossible,
        None,
    )
    .expect("replays");
    assert_eq!(replayed.report.state_hash, tuned.state_hash);
    assert_eq!(replayed.report.session_id, tuned.session_id);
    let session::Recorded::InMemory(again) = replayed.recording else {
        panic!("in memory");
    };
    assert_eq!(again.tunings, tuned_rec.tunings);
    // Out of range is refused, and changes nothing.
    let mut live = session::Live::new(&text, "coarse", Pacing::AsFastAsPossible).expect("ok");
    let before = live.tunables();
    let bad = [
        ("foundation_pa_per_m".to_string(), 3.2e6),
        ("offset_m".to_string(), f32::NAN),
    ];
    let e = live
        .tune("kidney", &bad)
        .expect_err("NaN offset")
        .to_string();
    assert!(e.contains("kidney.offset_m"), "{e}");
    assert_eq!(
        live.tunables(),
        before,
        "nothing changed, not even the spring"
    );
    let e = live
        .tune("liver", &bad[..1])
        .expect_err("no such model")
        .to_string();
    assert!(e.contains("liver"), "{e}");
}

/// Every tunable value is live: the laser's pressure (the tools table) changes the session;
/// out of range it is refused and changes nothing.
#[test]
fn the_laser_pressure_is_a_live_tunable() {
    let text = coarse();
    let keys = demo_trace();
    let run = |pressure: Option<f32>| {
        let mut live = session::Live::new(&text, "coarse", Pacing::AsFastAsPossible).expect("ok");
        if let Some(p) = pressure {
            live.tune("tools", &[("laser_pressure_pa".to_string(), p)])
                .expect("in range");
            assert_eq!(value(&live, "laser_pressure_pa"), p);
        }
        let steps = live.steps_for(9.0);
        while live.step_count() < steps {
            let frame = keys.sample(live.time_s());
            live.step(frame).expect("steps");
        }
        live.finish(Vec::new()).expect("finishes").report.state_hash
    };
    assert_ne!(
        run(Some(1200.0)),
        run(None),
        "the pressure changes what the laser does"
    );
    let mut live = session::Live::new(&text, "coarse", Pacing::AsFastAsPossible).expect("ok");
    let before = live.tunables();
    let e = live
        .tune("tools", &[("laser_pressure_pa".to_string(), -5.0)])
        .expect_err("negative")
        .to_string();
    assert!(e.contains("tools.laser_pressure_pa"), "{e}");
    assert_eq!(live.tunables(), before);
}
