//! The rectum through the command line on a coarse grid (60 x 48 nodes per layer; the full
//! 960,000-node grid steps in the bench's test, and for 30 ms below): the demo trace cuts the
//! plane, the report counts `spring_cut` events and carries the membrane's nodes and springs, 1 and 2
//! worker threads give the same bytes, and the recording replays byte for byte; with the
//! membrane on the GPU a session cuts, and its replay on the CPU says the bytes may differ.

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
    assert!(report(&d.join("replay")).get("replay_note").is_none());
}

/// The demo trace's first `seconds`, as a trace file in `dir`.
fn first_seconds(dir: &Path, seconds: f64) -> std::path::PathBuf {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/rectum-demo.toml");
    let mut t: toml::Table =
        toml::from_str(&std::fs::read_to_string(path).expect("the demo")).expect("TOML");
    for hand in ["left", "right"] {
        if let Some(toml::Value::Array(keys)) = t.get_mut(hand) {
            keys.retain(|k| k.get("t_s").and_then(toml::Value::as_float).unwrap_or(0.0) <= seconds);
        }
    }
    let out = dir.join("short.toml");
    std::fs::write(&out, toml::to_string(&t).expect("writes")).expect("write trace");
    out
}

#[test]
fn on_the_gpu_a_session_cuts_and_its_cpu_replay_says_the_bytes_may_differ() {
    let d = tmp("rectum", "gpu");
    let trace = first_seconds(&d, 1.5);
    let o = bin()
        .args(["run", "rectum", "--headless", "--compute", "gpu", "--trace"])
        .arg(&trace)
        .arg("--scenario")
        .arg(coarse(&d))
        .arg("--out")
        .arg(d.join("gpu"))
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // On the adapter there is (CI: lavapipe), named in the report and the timing.
    let g = report(&d.join("gpu"));
    assert_eq!(g["compute"], "gpu", "{g}");
    let adapter = g["adapter"].as_str().unwrap_or_default().to_string();
    assert!(!adapter.is_empty(), "{g}");
    let timing: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("gpu/timing.json")).expect("timing"))
            .expect("JSON");
    assert_eq!(
        (timing["compute"].as_str(), timing["adapter"].as_str()),
        (Some("gpu"), Some(adapter.as_str()))
    );
    assert!(g["events"]["spring_cut"].as_u64().unwrap_or(0) > 0, "{g}");
    // Replayed on the CPU: it still runs and cuts, and says why its bytes may differ.
    replay(
        &d.join("gpu/input.vtrace"),
        &d.join("cpu"),
        &["--compute", "cpu"],
    );
    let c = report(&d.join("cpu"));
    assert_eq!(c["compute"], "cpu", "{c}");
    let note = c["replay_note"].as_str().unwrap_or_default();
    assert_eq!(
        note,
        format!(
            "recorded on gpu ({adapter}), replayed on cpu: the replay's bytes may differ from \
             the recording's report (another backend or adapter sums the same forces in \
             another order)"
        )
    );
    assert!(c["events"]["spring_cut"].as_u64().unwrap_or(0) > 0, "{c}");
}

/// `vesalius replay RECORDING --out DIR ARGS...`, which must succeed.
fn replay(recording: &Path, out: &Path, args: &[&str]) {
    let o = bin()
        .arg("replay")
        .arg(recording)
        .arg("--out")
        .arg(out)
        .args(args)
        .output()
        .expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A short trace: both instruments held still above the field for 30 ms.
fn still_trace() -> String {
    let mut t = String::from("procedure = \"rectum\"\n");
    for hand in ["left", "right"] {
        for t_s in ["0.0", "0.03"] {
            t += &format!(
                "\n[[{hand}]]\nt_s = {t_s}\nposition = [0.05, 0.04, 0.0]\ntarget = [0.05, -0.01, 0.0]\n"
            );
        }
    }
    t
}

#[test]
fn auto_without_a_gpu_runs_the_cpu_preset_and_says_so_and_compute_cpu_runs_the_papers_grid() {
    // The rectum's own scenario leaves `compute` to `auto`. On a machine without a real GPU
    // (CI: lavapipe) a run takes the CPU preset's 90 x 60 grid and says why; with a real GPU
    // it takes the paper's grid to the GPU. `--compute cpu` runs the paper's grid either way.
    let d = tmp("rectum", "auto-preset");
    std::fs::create_dir_all(&*d).expect("dir");
    let trace = d.join("still.toml");
    std::fs::write(&trace, still_trace()).expect("trace");
    let run = |more: &[&str], out: &str| {
        let o = bin()
            .args(["run", "rectum", "--headless", "--trace"])
            .arg(&trace)
            .args(more)
            .arg("--out")
            .arg(d.join(out))
            .output()
            .expect("runs");
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let r = report(&d.join(out));
        let nodes = r["models"]
            .as_array()
            .and_then(|m| m.iter().find(|m| m["name"] == "membrane"))
            .and_then(|m| m["nodes"].as_u64())
            .unwrap_or(0);
        (String::from_utf8_lossy(&o.stderr).into_owned(), nodes)
    };
    let said = "no GPU here, so `auto` runs its cpu preset";
    let (err, nodes) = run(&[], "auto");
    if vesalius::gpu::Gpu::real_gpu_present() {
        assert!(!err.contains(said), "{err}");
        assert_eq!(nodes, 4 * 600 * 400);
    } else {
        assert!(
            err.contains(said) && err.contains("assets/presets/cpu/rectum.toml"),
            "{err}"
        );
        assert_eq!(nodes, 4 * 90 * 60);
    }
    let (err, nodes) = run(&["--compute", "cpu"], "cpu");
    assert!(!err.contains(said), "{err}");
    assert_eq!(nodes, 4 * 600 * 400);
    // A preset named is run as it is, without the note.
    let (err, nodes) = run(&["--preset", "cpu"], "preset");
    assert!(!err.contains(said), "{err}");
    assert_eq!(nodes, 4 * 90 * 60);
}
