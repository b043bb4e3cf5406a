//! The rectum through the command line on a coarse grid (60 x 48 nodes per layer; the full
//! 960,000-node grid runs once, in `vesalius demo`): the demo trace cuts the plane, the
//! report counts `spring_cut` events and carries the membrane's nodes and springs, 1 and 2
//! worker threads give the same bytes, and the recording replays byte for byte.

mod common;
use common::{bin, report, tmp, without_id};
use std::path::Path;

fn coarse(dir: &Path) -> std::path::PathBuf {
    let text = vesalius::procedures::rectum::INFO
        .scenario
        .replace("rows = 600", "rows = 60")
        .replace("cols = 400", "cols = 48");
    let path = dir.join("coarse.toml");
    std::fs::write(&path, text).expect("write scenario");
    path
}

fn run(dir: &Path, threads: &str) -> Vec<u8> {
    std::fs::create_dir_all(dir).expect("dir");
    let scenario = coarse(dir);
    let trace = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/rectum-demo.toml");
    let o = bin()
        .args([
            "--threads",
            threads,
            "run",
            "rectum",
            "--headless",
            "--trace",
        ])
        .arg(&trace)
        .arg("--scenario")
        .arg(&scenario)
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read(dir.join("out/report.json")).expect("report")
}

#[test]
fn the_demo_cuts_the_plane_the_same_on_one_and_two_threads_and_replays() {
    let d = tmp("rectum", "threads");
    let a = run(&d.join("t1"), "1");
    let b = run(&d.join("t2"), "2");
    assert_eq!(without_id(&a), without_id(&b), "1 and 2 threads differ");
    let r = report(&d.join("t1/out"));
    assert_eq!(r["procedure"], "rectum");
    let cuts = r["events"]["spring_cut"].as_u64().unwrap_or(0);
    assert!(cuts > 0, "{r}");
    assert!(
        r["metrics"]["correct_cuts"].as_u64().unwrap_or(0) > 0,
        "{r}"
    );
    let membrane = r["models"]
        .as_array()
        .and_then(|m| m.iter().find(|m| m["name"] == "membrane"))
        .cloned()
        .unwrap_or_default();
    assert_eq!(membrane["nodes"], 4 * 60 * 48, "{r}");
    assert!(
        membrane["springs"].as_u64().unwrap_or(0) > 4 * 60 * 48,
        "{r}"
    );
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
