//! The shipped reference sessions (`assets/sessions/<procedure>/`): every procedure's tree
//! rates every shipped novice session at least 15 points below every shipped expert session
//! and none of them expert; the demo still scores expert; `records calibrate` reproduces the
//! shipped trees' references from the shipped sessions (stored in an SQLite file as two
//! groups of trainees); and a session replayed with a calibrated tree is scored by it.

mod common;
use common::{bin, ok, report, tmp};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use vesalius::assess::Tree;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The arguments a procedure's reference sessions run with: the heavy two on their CPU
/// preset (as a trainee without a GPU runs them), the others on their own scenario.
fn scenario_args(procedure: &str) -> &'static [&'static str] {
    match procedure {
        "rectum" | "cholecystectomy" => &["--preset", "cpu"],
        _ => &[],
    }
}

/// The shipped sessions of `procedure`, by persona, in name order.
fn shipped(procedure: &str, persona: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(root().join("assets/sessions").join(procedure))
        .expect("the procedure's sessions")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(&format!("{persona}-")) && n.ends_with(".toml"))
        })
        .collect();
    v.sort();
    v
}

/// Runs `trace` headless into `out` and gives its report.
fn play(procedure: &str, trace: &Path, out: &Path) -> serde_json::Value {
    ok(&bin()
        .args(["run", procedure, "--headless", "--trace"])
        .arg(trace)
        .arg("--out")
        .arg(out)
        .args(scenario_args(procedure))
        .output()
        .expect("runs"));
    report(out)
}

fn score(r: &serde_json::Value) -> f64 {
    r["score"].as_f64().expect("score")
}

/// The leaves' references of a tree file.
fn references(text: &str) -> BTreeMap<String, (f64, f64)> {
    let t = Tree::parse("tree", text).expect("tree");
    t.nodes
        .iter()
        .filter_map(|n| {
            n.leaf
                .as_ref()
                .map(|l| (n.path.clone(), (l.expert, l.novice)))
        })
        .collect()
}

/// Every check for one procedure.
fn check(procedure: &str) {
    let d = tmp("reference-sessions", procedure);
    let (experts, novices) = (shipped(procedure, "expert"), shipped(procedure, "novice"));
    assert!(
        experts.len() >= 5 && novices.len() >= 5,
        "{procedure}: {} expert and {} novice sessions shipped",
        experts.len(),
        novices.len()
    );
    let records = d.join("records.sqlite");
    let mut scores = BTreeMap::new();
    for (persona, list) in [("expert", &experts), ("novice", &novices)] {
        ok(&bin()
            .args([
                "records",
                "trainee",
                persona,
                "--group",
                &format!("{persona}s"),
                "--db",
            ])
            .arg(&records)
            .output()
            .expect("trainee"));
        for trace in list {
            let name = trace
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("x")
                .to_string();
            let out = d.join(&name);
            let r = play(procedure, trace, &out);
            if persona == "expert" {
                assert_eq!(r["completed"], true, "{procedure} {name}: {r}");
            }
            scores.insert(
                name,
                (
                    persona,
                    score(&r),
                    r["level"].as_str().unwrap_or("").to_string(),
                ),
            );
            ok(&bin()
                .args(["records", "import"])
                .arg(&out)
                .args(["--trainee", persona, "--db"])
                .arg(&records)
                .output()
                .expect("import"));
        }
    }
    let lowest_expert = scores
        .values()
        .filter(|s| s.0 == "expert")
        .map(|s| s.1)
        .fold(f64::MAX, f64::min);
    for (name, (persona, s, level)) in &scores {
        if *persona == "novice" {
            assert!(
                *s <= lowest_expert - 15.0,
                "{procedure} {name}: {s:.1} is not 15 points below the lowest expert ({lowest_expert:.1}): {scores:?}"
            );
            assert_ne!(
                level, "expert",
                "{procedure} {name} rated expert: {scores:?}"
            );
        }
    }
    // The demo still scores expert.
    let demo = play(
        procedure,
        &root().join(format!("assets/traces/{procedure}-demo.toml")),
        &d.join("demo"),
    );
    assert_eq!(
        demo["level"], "expert",
        "{procedure} demo: {}",
        demo["assessment"]
    );
    // Calibrating the shipped tree from the shipped sessions gives its own references.
    let out_tree = d.join("calibrated.toml");
    let table = ok(&bin()
        .args([
            "records",
            "calibrate",
            "--tree",
            procedure,
            "--expert",
            "experts",
            "--novice",
            "novices",
            "--db",
        ])
        .arg(&records)
        .arg("--out")
        .arg(&out_tree)
        .arg("--html")
        .arg(d.join("validation.html"))
        .output()
        .expect("calibrate"));
    let shipped_tree =
        std::fs::read_to_string(root().join(format!("assets/assessment/{procedure}.toml")))
            .expect("tree");
    let calibrated = std::fs::read_to_string(&out_tree).expect("calibrated tree");
    assert_eq!(
        references(&calibrated),
        references(&shipped_tree),
        "{procedure}: the shipped references are not what the shipped sessions give\n{table}"
    );
    assert!(table.contains("separates"), "{table}");
    let page = std::fs::read_to_string(d.join("validation.html")).expect("page");
    assert!(
        page.contains("<table>") && page.contains("motion.path_m"),
        "{page}"
    );
    // The total score separates the groups in the table.
    let score_row = table
        .lines()
        .find(|l| l.starts_with("score "))
        .unwrap_or_else(|| panic!("no score row:\n{table}"));
    assert!(score_row.contains(" yes "), "{score_row}");
}

#[test]
fn sandbox() {
    check("sandbox");
}

#[test]
fn nephrectomy() {
    check("nephrectomy");
}

#[test]
fn cholecystectomy() {
    check("cholecystectomy");
}

#[test]
fn myotomy() {
    check("myotomy");
}

#[test]
fn catheter() {
    check("catheter");
}

#[test]
fn rectum() {
    check("rectum");
}

#[test]
fn a_calibrated_tree_scores_a_replayed_session() {
    // One novice sandbox session, replayed with a tree whose completion-time references are
    // those of calibration with another version: the report carries that tree and its score
    // is the tree's score of the session's measures.
    let d = tmp("reference-sessions", "replay");
    let trace = root().join("assets/sessions/sandbox/novice-1.toml");
    let first = play("sandbox", &trace, &d.join("a"));
    let shipped =
        std::fs::read_to_string(root().join("assets/assessment/sandbox.toml")).expect("tree");
    let mut refs = BTreeMap::new();
    refs.insert("efficiency/completion_time".to_string(), (60.0, 120.0));
    let tree_text = vesalius::assess::calibrate::with_references(&shipped, &refs, 77);
    let tree_file = d.join("tree.toml");
    std::fs::write(&tree_file, &tree_text).expect("tree");
    ok(&bin()
        .arg("replay")
        .arg(d.join("a/input.vtrace"))
        .arg("--out")
        .arg(d.join("b"))
        .arg("--assessment")
        .arg(&tree_file)
        .output()
        .expect("replay"));
    let again = report(&d.join("b"));
    assert_eq!(again["assessment"]["tree_version"], 77);
    let tree = Tree::parse("tree", &tree_text).expect("tree");
    let steps = vesalius::registry::find("sandbox")
        .expect("sandbox")
        .steps
        .len();
    let measures = vesalius::assess::calibrate::report_measures(&again, steps);
    let expected = tree.score(&measures).score;
    assert!(
        (score(&again) - expected).abs() < 1e-3,
        "{} vs {expected}",
        score(&again)
    );
    // A 60 s expert time: this session (under 60 s) now scores full points on time, more
    // than with the shipped tree.
    assert!(
        score(&again) > score(&first),
        "{} vs {}",
        score(&again),
        score(&first)
    );
}

#[test]
fn the_sessions_play_in_the_simulated_headset_as_they_play_headless() {
    // The sandbox's first expert and novice sessions through the real XR path (the Khronos
    // loader, our simulated runtime playing the trace at 90 Hz): the same levels as headless,
    // the scores within 2 points (the headset samples the hands at its frames, not at every
    // step), and the novice still 15 points below the expert.
    let d = tmp("reference-sessions", "headset");
    let mut scores = Vec::new();
    for name in ["expert-1", "novice-1"] {
        let trace = root().join(format!("assets/sessions/sandbox/{name}.toml"));
        let headless = play("sandbox", &trace, &d.join(format!("{name}-headless")));
        let out = d.join(format!("{name}-headset"));
        ok(&bin()
            .args(["run", "sandbox", "--xr-sim"])
            .arg(&trace)
            .arg("--out")
            .arg(&out)
            .args(["--no-window", "--eye-size", "64x64"])
            .output()
            .expect("runs"));
        let headset = report(&out);
        assert_eq!(headset["level"], headless["level"], "{name}");
        assert!(
            (score(&headset) - score(&headless)).abs() < 2.0,
            "{name}: {} in the headset, {} headless",
            score(&headset),
            score(&headless)
        );
        scores.push(score(&headset));
    }
    assert!(scores[1] <= scores[0] - 15.0, "{scores:?}");
}
