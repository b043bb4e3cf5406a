//! Every kind of bad scenario and trace gets a clear error naming the file, the key and what
//! is expected; nothing panics.

mod common;
use common::tmp;
use std::process::Command;
use vesalius::procedures::nephrectomy::Scenario;
use vesalius::registry::builtin;
use vesalius::trace::{KeyTrace, Recording, Tail, TuningRecord};

fn scenario() -> String {
    builtin("nephrectomy").expect("builtin").to_string()
}

fn scenario_error(text: &str) -> String {
    Scenario::parse("bad.toml", text)
        .expect_err("must be rejected")
        .to_string()
}

const TRACE: &str = r#"
procedure = "nephrectomy"
[[left]]
t_s = 0.0
position = [0.0, 0.0, 0.2]
target = [0.0, 0.0, 0.0]
[[right]]
t_s = 0.0
position = [0.05, 0.0, 0.2]
target = [0.0, 0.0, 0.0]
[[right]]
t_s = 1.0
position = [0.05, 0.0, 0.2]
target = [0.0, 0.0, 0.0]
"#;

fn trace_error(text: &str) -> String {
    KeyTrace::parse("bad-trace.toml", text)
        .expect_err("must be rejected")
        .to_string()
}

#[test]
fn the_good_files_parse() {
    assert!(Scenario::parse("ok.toml", &scenario()).is_ok());
    let t = KeyTrace::parse("ok.toml", TRACE).expect("parses");
    assert_eq!(t.duration_s(), 1.0);
}

#[test]
fn a_missing_key_is_named() {
    let e = scenario_error(&scenario().replace("dt_s = 0.004", ""));
    assert!(e.starts_with("bad.toml: ") && e.contains("dt_s"), "{e}");
}

#[test]
fn a_wrong_type_is_named_with_its_line() {
    let e = scenario_error(&scenario().replace(
        "foundation_pa_per_m = 1.6e6",
        "foundation_pa_per_m = \"stiff\"",
    ));
    assert!(
        e.contains("bad.toml") && e.contains("line") && e.contains("foundation_pa_per_m"),
        "{e}"
    );
}

#[test]
fn out_of_range_and_nan_numbers_are_rejected_with_the_expected_range() {
    let e = scenario_error(
        &scenario().replace("foundation_pa_per_m = 1.6e6", "foundation_pa_per_m = -5.0"),
    );
    assert!(
        e.contains("kidney.foundation_pa_per_m") && e.contains("between 0"),
        "{e}"
    );
    let e = scenario_error(&scenario().replace("damping_per_s = 600.0", "damping_per_s = nan"));
    assert!(
        e.contains("kidney.damping_per_s") && e.contains("finite"),
        "{e}"
    );
    let e = scenario_error(&scenario().replace("dt_s = 0.004", "dt_s = 0.5"));
    assert!(e.contains("dt_s") && e.contains("0.01"), "{e}");
    let e = scenario_error(&scenario().replace("margin_m = 0.005", "margin_m = inf"));
    assert!(e.contains("task.margin_m"), "{e}");
}

#[test]
fn unknown_procedures_are_named_with_the_ones_there_are() {
    let text = scenario().replace(
        "procedure = \"nephrectomy\"",
        "procedure = \"appendectomy\"",
    );
    // The registry resolves the name: it lists the ones there are.
    let e = vesalius::registry::plan("bad.toml", &text)
        .expect_err("no such procedure")
        .to_string();
    assert!(
        e.contains("procedure")
            && e.contains("unknown procedure 'appendectomy'")
            && e.contains("nephrectomy")
            && e.contains("catheter"),
        "{e}"
    );
    // A procedure's own reader takes only its own scenarios.
    let e = scenario_error(&text);
    assert!(
        e.contains("bad.toml: procedure: must be \"nephrectomy\""),
        "{e}"
    );
    // All five of the papers' procedures are built: a trace for any of them parses.
    for p in ["rectum", "cholecystectomy", "myotomy", "catheter"] {
        assert!(KeyTrace::parse("t.toml", &TRACE.replace("nephrectomy", p)).is_ok());
    }
}

#[test]
fn an_unknown_key_is_rejected() {
    let e = scenario_error(&scenario().replace("[kidney]", "[kidney]\nstifness = 3.0"));
    assert!(e.contains("stifness"), "{e}");
}

#[test]
fn time_going_backwards_is_named_by_keyframe() {
    let e = trace_error(&TRACE.replace("t_s = 1.0", "t_s = -0.0").replacen(
        "t_s = 0.0\nposition = [0.05",
        "t_s = 0.5\nposition = [0.05",
        1,
    ));
    assert!(
        e.contains("bad-trace.toml: right[1].t_s") && e.contains("backwards"),
        "{e}"
    );
}

#[test]
fn a_nan_pose_is_named() {
    let e = trace_error(&TRACE.replace("position = [0.0, 0.0, 0.2]", "position = [nan, 0.0, 0.2]"));
    assert!(
        e.contains("left[0].position") && e.contains("finite"),
        "{e}"
    );
    let e = trace_error(&TRACE.replace("t_s = 1.0", "t_s = nan"));
    assert!(e.contains("right[1].t_s"), "{e}");
}

#[test]
fn a_truncated_recording_reads_up_to_it_and_a_corrupt_one_is_rejected() {
    let frame = |x: f32| {
        let mut f = vesalius::sim::InputFrame::default();
        f.hands[0].pose.position.x = x;
        f
    };
    let rec = Recording {
        procedure: "nephrectomy".into(),
        session_id: "0123456789abcdef".into(),
        dt_s: 0.004,
        scenario: scenario(),
        frames: (0..3).map(|i| frame(i as f32 * 0.01)).collect(),
        tunings: vec![TuningRecord {
            step: 1,
            model: "kidney".into(),
            values: vec![
                ("foundation_pa_per_m".into(), 60.0),
                ("damping_per_s".into(), 4.0),
            ],
        }],
        tail: Tail::Ended {
            how: "end_of_input".into(),
        },
    };
    let dir = tmp("bad", "recording");
    let path = dir.join("r.vtrace");
    rec.write(&path).expect("write");
    assert_eq!(Recording::read(&path).expect("reads back"), rec);
    let bytes = std::fs::read(&path).expect("read");
    // Cut inside its last block: what came before reads, and says it stops short.
    let cut = Recording::decode("r.vtrace", &bytes[..bytes.len() - 5]).expect("reads the rest");
    assert!(matches!(cut.tail, Tail::Cut { .. }), "{:?}", cut.tail);
    assert_eq!(cut.frames, rec.frames[..cut.frames.len()]);
    // A changed byte anywhere after the header is an error naming the file and a block.
    for at in (16..bytes.len()).step_by(7) {
        let mut bad = bytes.clone();
        bad[at] ^= 0x01;
        let e = Recording::decode("r.vtrace", &bad).expect_err("corrupt");
        let e = e.to_string();
        assert!(
            e.contains("r.vtrace") && e.contains("block "),
            "byte {at}: {e}"
        );
    }
}

#[test]
fn the_cli_reports_bad_files_and_exits_non_zero() {
    let dir = tmp("bad", "cli");
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        scenario().replace("foundation_pa_per_m = 1.6e6", "foundation_pa_per_m = -1.0"),
    )
    .expect("write");
    let o = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .arg("check")
        .arg(&bad)
        .output()
        .expect("runs");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("bad.toml: kidney.foundation_pa_per_m: must be between"),
        "{err}"
    );
    let o = Command::new(env!("CARGO_BIN_EXE_vesalius"))
        .args(["run", "appendectomy", "--headless"])
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("invalid value 'appendectomy'") && err.contains("nephrectomy"),
        "{err}"
    );
}

#[test]
fn window_flags_without_a_display_or_with_a_bad_path_are_clear_errors() {
    let run = |args: &[&str], no_display: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_vesalius"));
        c.args(args);
        if no_display {
            c.env_remove("DISPLAY").env_remove("WAYLAND_DISPLAY");
        }
        let o = c.output().expect("runs");
        assert!(!o.status.success());
        String::from_utf8_lossy(&o.stderr).to_string()
    };
    let e = run(&["run", "nephrectomy"], true);
    assert!(
        e.contains("cannot open a window") && e.contains("xvfb-run"),
        "{e}"
    );
    let e = run(
        &[
            "run",
            "nephrectomy",
            "--screenshot",
            "/no/such/folder/shot.png",
        ],
        false,
    );
    assert!(
        e.contains("--screenshot: folder /no/such/folder does not exist"),
        "{e}"
    );
    let e = run(&["run", "nephrectomy", "--screenshot-at", "3"], false);
    assert!(
        e.contains("required arguments were not provided") && e.contains("--screenshot <FILE>"),
        "{e}"
    );
    let e = run(
        &[
            "run",
            "nephrectomy",
            "--screenshot",
            "s.png",
            "--screenshot-at",
            "-1",
        ],
        false,
    );
    assert!(
        e.contains("--screenshot-at <S>': expected seconds (0 or more), got '-1'"),
        "{e}"
    );
    let e = run(&["run", "nephrectomy", "--window-size", "12x9000"], false);
    assert!(
        e.contains("--window-size <WxH>': expected WIDTHxHEIGHT"),
        "{e}"
    );
    let e = run(
        &[
            "run",
            "nephrectomy",
            "--headless",
            "--trace",
            "x.toml",
            "--screenshot",
            "s.png",
        ],
        false,
    );
    assert!(
        e.contains("'--headless' cannot be used with '--screenshot <FILE>'"),
        "{e}"
    );
}
