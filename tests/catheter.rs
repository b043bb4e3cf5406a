//! The catheterisation through the command line: the demo trace twists the catheter half a
//! turn, bends its tip and pushes it into the -y branch at 20 mm/s without a puncture, the
//! head's force within the paper's 0.5-3.5 N, the force over time in the report; 1 and 2
//! worker threads give the same bytes, and the recording replays byte for byte.

mod common;
use common::{bin, report, tmp, without_id};
use std::path::Path;

fn run(dir: &Path, threads: &str) -> Vec<u8> {
    std::fs::create_dir_all(dir).expect("dir");
    let trace = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/catheter-demo.toml");
    let o = bin()
        .args([
            "--threads",
            threads,
            "run",
            "catheter",
            "--headless",
            "--trace",
        ])
        .arg(&trace)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read(dir.join("out/report.json")).expect("report")
}

#[test]
fn the_demo_reaches_the_target_branch_the_same_on_one_and_two_threads_and_replays() {
    let d = tmp("catheter", "threads");
    let a = run(&d.join("t1"), "1");
    let b = run(&d.join("t2"), "2");
    assert_eq!(without_id(&a), without_id(&b), "1 and 2 threads differ");
    let r = report(&d.join("t1/out"));
    assert_eq!(r["procedure"], "catheter");
    assert_eq!(r["completed"], true, "{r}");
    let m = &r["metrics"];
    assert_eq!(m["punctures"], 0, "{r}");
    assert_eq!(m["wrong_branch"], 0, "{r}");
    assert!(m["reach_m"].as_f64().unwrap_or(0.0) >= 0.03, "{r}");
    let head = m["peak_head_normal_n"].as_f64().unwrap_or(0.0);
    assert!((0.5..=3.5).contains(&head), "head force {head} N");
    assert!(m["wall_contacts"].as_u64().unwrap_or(0) >= 1, "{r}");
    assert!(m["force_time_n_s"].as_f64().unwrap_or(0.0) > 0.0, "{r}");
    // The force over time: a sample every 20 ms over the 6.5 s session.
    let trace = m["force_trace"].as_array().cloned().unwrap_or_default();
    assert!(trace.len() >= 300, "{} samples", trace.len());
    let models: Vec<&str> = r["models"]
        .as_array()
        .map(|m| m.iter().filter_map(|x| x["name"].as_str()).collect())
        .unwrap_or_default();
    assert_eq!(models, ["catheter", "vessel", "collision"]);
    let o = bin()
        .args(["--threads", "2", "replay"])
        .arg(d.join("t1/out/input.vtrace"))
        .arg("--out")
        .arg(d.join("replay"))
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in ["report.json", "events.jsonl"] {
        assert_eq!(
            std::fs::read(d.join("replay").join(f)).expect("replayed"),
            std::fs::read(d.join("t1/out").join(f)).expect("original"),
            "{f}"
        );
    }
}
