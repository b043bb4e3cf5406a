//! `--profile-trace FILE` writes a Chrome trace of the session's spans that loads as JSON:
//! one span per step of the session and of the world, one per model step naming the model
//! (every model the report lists), each a complete event with a start, a duration and a
//! thread; `--log` refuses a level it cannot read, naming it.

mod common;
use common::{bin, report, run_sandbox, text, tmp};
use std::collections::BTreeMap;

#[test]
fn a_profile_trace_has_a_span_for_each_step_and_each_models_step() {
    let dir = tmp("profile-trace", "sandbox");
    let trace = dir.join("trace.json");
    run_sandbox(
        &dir.join("out"),
        &["--profile-trace".as_ref(), trace.as_os_str()],
    );
    let r = report(&dir.join("out"));
    let steps = r["steps"].as_u64().expect("steps");
    let models: Vec<String> = r["models"]
        .as_array()
        .expect("models")
        .iter()
        .filter_map(|m| m["name"].as_str().map(String::from))
        .collect();
    assert!(!models.is_empty());

    let text = std::fs::read_to_string(&trace).expect("the trace was written");
    let v: serde_json::Value = serde_json::from_str(&text).expect("the trace is JSON");
    let events = v["traceEvents"].as_array().expect("a traceEvents array");
    // Every event is one Chrome reads: a name, a phase, a time, a process and a thread; a
    // complete event has a duration, none negative.
    let mut spans: BTreeMap<String, u64> = BTreeMap::new();
    let mut per_model: BTreeMap<String, u64> = BTreeMap::new();
    for e in events {
        let name = e["name"].as_str().expect("a name");
        let ph = e["ph"].as_str().expect("a phase");
        assert!(ph == "X" || ph == "i", "{e}");
        assert!(e["ts"].as_f64().is_some_and(|t| t >= 0.0), "{e}");
        assert!(
            e["pid"].as_u64().is_some() && e["tid"].as_u64().is_some(),
            "{e}"
        );
        if ph == "X" {
            assert!(e["dur"].as_f64().is_some_and(|d| d >= 0.0), "{e}");
            *spans.entry(name.to_string()).or_default() += 1;
            if name == "model_step" {
                let model = e["args"]["model"].as_str().expect("the model's name");
                *per_model.entry(model.to_string()).or_default() += 1;
            }
        }
    }
    // One span per session step and per world step; one per step of each model.
    assert_eq!(spans.get("session_step"), Some(&steps), "{spans:?}");
    assert_eq!(spans.get("procedure_step"), Some(&steps), "{spans:?}");
    assert_eq!(spans.get("world_step"), Some(&steps), "{spans:?}");
    for m in &models {
        assert_eq!(per_model.get(m), Some(&steps), "{m}: {per_model:?}");
    }
}

#[test]
fn a_log_level_that_cannot_be_read_is_refused_by_name() {
    let o = bin()
        .args(["--log", "loud=[", "check", "assets/scenarios/sandbox.toml"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("--log loud=["), "{err}");
    // A good level runs the command as before.
    let o = bin()
        .args(["--log", "debug", "check", "assets/scenarios/sandbox.toml"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("runs");
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
}
