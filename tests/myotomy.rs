//! The myotomy through the command line at the paper's size (3,720 triangles, N = 11,160;
//! the precomputation built into the tests' shared cache the first time, read after): the
//! demo trace palpates the sphincter and divides the muscle across the junction without a
//! perforation, 1 and 2 worker threads give the same bytes, and the recording replays byte
//! for byte.

mod common;
use common::{bin, report, tmp, without_id};
use std::path::Path;

fn run(dir: &Path, threads: &str) -> Vec<u8> {
    std::fs::create_dir_all(dir).expect("dir");
    let trace = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/myotomy-demo.toml");
    let o = bin()
        .args([
            "--threads",
            threads,
            "run",
            "myotomy",
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
fn the_demo_divides_the_muscle_the_same_on_one_and_two_threads_and_replays() {
    let d = tmp("myotomy", "threads");
    let a = run(&d.join("t1"), "1");
    let b = run(&d.join("t2"), "2");
    assert_eq!(without_id(&a), without_id(&b), "1 and 2 threads differ");
    let r = report(&d.join("t1/out"));
    assert_eq!(r["procedure"], "myotomy");
    assert_eq!(r["completed"], true, "{r}");
    assert_eq!(r["errors"], 0, "{r}");
    let m = &r["metrics"];
    assert_eq!(m["perforations"], 0, "{r}");
    let divided = m["divided_m"].as_f64().unwrap_or(0.0);
    let required = m["required_m"].as_f64().unwrap_or(1.0);
    assert!(divided >= required - 0.001, "{r}");
    let deepest = m["deepest_cut_m"].as_f64().unwrap_or(0.0);
    assert!((0.003..0.004).contains(&deepest), "{r}");
    assert!(r["events"]["incision"].as_u64().unwrap_or(0) > 10, "{r}");
    let esophagus = r["models"]
        .as_array()
        .and_then(|m| m.iter().find(|m| m["name"] == "esophagus"))
        .cloned()
        .unwrap_or_default();
    assert_eq!(esophagus["triangles"], 3720, "{r}");
    assert_eq!(esophagus["constraints"], 11160, "{r}");
    // The recording replays to the same bytes, session id included.
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
