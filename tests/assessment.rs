//! Assessment through the command line: a session's report carries its tree's score, level
//! and every node; `replay --assessment` scores an old recording with another tree, the same
//! bytes every time and only the scores changed; `check` validates trees and names what is
//! wrong; a tree for another procedure is refused before the session starts.

mod common;
use common::{bin, ok, report, tmp};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use vesalius::assess::questionnaire::{self, Answers, Questionnaire};

fn asset(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn node<'a>(r: &'a serde_json::Value, path: &str) -> &'a serde_json::Value {
    r["assessment"]["nodes"]
        .as_array()
        .and_then(|n| n.iter().find(|n| n["path"] == path))
        .unwrap_or(&serde_json::Value::Null)
}

#[test]
fn a_recording_is_scored_again_with_another_tree_deterministically() {
    let d = tmp("assessment", "rescore");
    let out = d.join("out");
    ok(&bin()
        .args(["run", "sandbox", "--headless", "--trace"])
        .arg(asset("assets/traces/sandbox-demo.toml"))
        .arg("--out")
        .arg(&out)
        .output()
        .expect("runs"));
    let r = report(&out);
    let a = &r["assessment"];
    assert_eq!(a["tree"], "sandbox");
    // The shipped tree: its references and weights are read from its file.
    let shipped = vesalius::assess::Tree::parse(
        "sandbox.toml",
        &std::fs::read_to_string(asset("assets/assessment/sandbox.toml")).expect("tree"),
    )
    .expect("tree");
    assert_eq!(a["tree_version"], shipped.version);
    let leaf = |p: &str| {
        shipped
            .nodes
            .iter()
            .find(|n| n.path == p)
            .and_then(|n| n.leaf.clone())
            .expect("leaf")
    };
    let weight = |p: &str| {
        shipped
            .nodes
            .iter()
            .find(|n| n.path == p)
            .map_or(0.0, |n| n.weight)
    };
    let score = r["score"].as_f64().unwrap_or(f64::NAN);
    assert!(
        (score - a["score"].as_f64().unwrap_or(0.0)).abs() < 1e-4,
        "{r}"
    );
    assert_eq!(r["level"], a["level"]);
    // The demo is done in order with no overload: safety and quality are full.
    assert_eq!(node(&r, "safety")["score"], 100.0, "{a}");
    assert_eq!(node(&r, "quality")["score"], 100.0, "{a}");
    let time = r["metrics"]["completion_time_s"]
        .as_f64()
        .unwrap_or(f64::NAN);
    let t = leaf("efficiency/completion_time");
    let want_time = (100.0 * (time - t.novice) / (t.expert - t.novice)).clamp(0.0, 100.0);
    let got_time = node(&r, "efficiency/completion_time")["score"]
        .as_f64()
        .unwrap_or(f64::NAN);
    assert!(
        (got_time - want_time).abs() < 1e-9,
        "{got_time} vs {want_time}"
    );
    // The grades' weighted mean: efficiency is its one leaf, safety and quality are full,
    // dexterity as scored.
    let dexterity = node(&r, "dexterity")["score"]
        .as_f64()
        .expect("dexterity scored");
    let (we, ws, wq, wd) = (
        weight("efficiency"),
        weight("safety"),
        weight("quality"),
        weight("dexterity"),
    );
    let want = (we * want_time + ws * 100.0 + wq * 100.0 + wd * dexterity) / (we + ws + wq + wd);
    assert!(
        (a["score"].as_f64().unwrap_or(0.0) - want).abs() < 1e-9,
        "{a}"
    );

    // Another tree: efficiency alone, and an expert's time of half the demo's.
    let tree = d.join("strict.toml");
    std::fs::write(
        &tree,
        format!(
            "procedure = \"sandbox\"\nversion = 2\ntitle = \"Speed only\"\n\n[[node]]\n\
             path = \"efficiency\"\nweight = 1\n\n[[node]]\npath = \"efficiency/time\"\n\
             metric = \"completion_time_s\"\nbetter = \"lower\"\nexpert = {}\nnovice = {}\n\
             weight = 1\n\n[[rule]]\nid = \"deep\"\nmetric = \"max_probe_depth_m\"\n\
             above = 0.003\nsay = \"Not so deep\"\n",
            time / 2.0,
            time * 1.5
        ),
    )
    .expect("tree written");
    ok(&bin().arg("check").arg(&tree).output().expect("runs"));
    let again = |name: &str| {
        ok(&bin()
            .arg("replay")
            .arg(out.join("input.vtrace"))
            .arg("--out")
            .arg(d.join(name))
            .arg("--assessment")
            .arg(&tree)
            .output()
            .expect("runs"));
        std::fs::read(d.join(name).join("report.json")).expect("report")
    };
    let (b1, b2) = (again("b1"), again("b2"));
    assert_eq!(b1, b2, "re-scoring is not deterministic");
    let b = report(&d.join("b1"));
    // (1.5 t - t) / (1.5 t - 0.5 t) = 50 points: two thirds intermediate, a third novice.
    assert!(
        (b["score"].as_f64().unwrap_or(0.0) - 50.0).abs() < 1e-3,
        "{b}"
    );
    assert_eq!(b["assessment"]["tree_version"], 2);
    assert_eq!(b["level"], "intermediate");
    // Only the scores changed: the session itself is the same.
    for k in ["metrics", "state_hash", "steps", "completed"] {
        assert_eq!(b[k], r[k], "{k}");
    }
    // The other tree's rule gave one instruction, when the probe passed 3 mm; the session's
    // own events are the same.
    let lines = |p: &Path| -> Vec<String> {
        std::fs::read_to_string(p.join("events.jsonl"))
            .expect("events")
            .lines()
            .map(str::to_string)
            .collect()
    };
    let (mine, theirs) = (lines(&out), lines(&d.join("b1")));
    let told: Vec<&String> = theirs
        .iter()
        .filter(|l| l.contains("\"instruction\""))
        .collect();
    assert_eq!(told.len(), 1, "{told:?}");
    assert!(told[0].contains("\"rule\":\"deep\"") && told[0].contains("Not so deep"));
    assert!(!mine.iter().any(|l| l.contains("\"instruction\"")));
    let rest: Vec<&String> = theirs
        .iter()
        .filter(|l| !l.contains("\"instruction\""))
        .collect();
    assert_eq!(rest, mine.iter().collect::<Vec<_>>());
    assert_eq!(b["events"]["instruction"], 1);
}

#[test]
fn check_validates_trees_and_a_tree_for_another_procedure_is_refused() {
    let d = tmp("assessment", "check");
    let mut files: Vec<PathBuf> = std::fs::read_dir(asset("assets/assessment"))
        .expect("assets/assessment")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    files.sort();
    assert!(files.len() >= 6, "{files:?}");
    let o = ok(&bin().arg("check").args(&files).output().expect("runs"));
    assert_eq!(
        o.matches("ok (assessment tree)").count(),
        files.len(),
        "{o}"
    );

    let bad = d.join("bad.toml");
    std::fs::write(
        &bad,
        "procedure = \"sandbox\"\nversion = 1\ntitle = \"x\"\n\n[[node]]\npath = \"a\"\n\
         weight = 1\n\n[[node]]\npath = \"a/b\"\nmetric = \"no_such_measure\"\n\
         better = \"lower\"\nexpert = 1\nnovice = 2\nweight = 1\n",
    )
    .expect("written");
    let o = bin().arg("check").arg(&bad).output().expect("runs");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(
            "bad.toml: node (a/b).metric: 'no_such_measure' is not a measure sandbox reports"
        ),
        "{err}"
    );

    // The rectum's tree for a sandbox session: refused before anything runs.
    let o = bin()
        .args(["run", "sandbox", "--headless", "--trace"])
        .arg(asset("assets/traces/sandbox-demo.toml"))
        .arg("--assessment")
        .arg(asset("assets/assessment/rectum.toml"))
        .arg("--out")
        .arg(d.join("never"))
        .output()
        .expect("runs");
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("the tree is for 'rectum', not 'sandbox'"),
        "{err}"
    );
    assert!(!d.join("never").join("report.json").exists());
}

/// Each scale's id and how many items are on it.
type ScaleCounts = &'static [(&'static str, usize)];

/// The shipped questionnaires: each parses, its id is its file's name, and its rating and
/// items per scale are the papers'.
#[test]
fn every_shipped_questionnaire_parses() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(questionnaire::DIR);
    let entries = match std::fs::read_dir(&dir) {
        Ok(e) => e,
        Err(e) => panic!("{}: {e}", dir.display()),
    };
    let mut found: BTreeMap<String, Questionnaire> = BTreeMap::new();
    for entry in entries.flatten() {
        let path = entry.path();
        if path.extension().and_then(|e| e.to_str()) != Some("toml") {
            continue;
        }
        let q = match Questionnaire::load_file(&path) {
            Ok(q) => q,
            Err(e) => panic!("{e}"),
        };
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        assert_eq!(q.id, stem, "{}: the id is the file's name", path.display());
        found.insert(q.id.clone(), q);
    }
    // (id, rating, items per scale) as the papers give them.
    let expected: [(&str, (f64, f64), ScaleCounts); 4] = [
        (
            "nephrectomy-validity",
            (0.0, 9.0),
            &[("face", 5), ("content", 5)],
        ),
        (
            "cholecystectomy-performance",
            (1.0, 5.0),
            &[("performance", 5)],
        ),
        ("cholecystectomy-usability", (1.0, 5.0), &[("usability", 5)]),
        ("rectum-feedback", (1.0, 5.0), &[("feedback", 9)]),
    ];
    for (id, (min, max), scales) in expected {
        let Some(q) = found.get(id) else {
            panic!("{id} is not in {}", questionnaire::DIR);
        };
        assert_eq!((q.rating.min, q.rating.max), (min, max), "{id}");
        let counts: Vec<(&str, usize)> = q
            .scales
            .iter()
            .map(|s| (s.id.as_str(), q.items_of(&s.id).count()))
            .collect();
        assert_eq!(counts, scales, "{id}");
        // Answers at the top of the rating pass the check; the report has one group.
        let top = Answers {
            participant: "t".into(),
            group: "g".into(),
            scores: q.items.iter().map(|i| (i.id.clone(), max)).collect(),
        };
        match q.report(id, &[top]) {
            Ok(r) => assert_eq!(r.groups.len(), 1, "{id}"),
            Err(e) => panic!("{e}"),
        }
    }
}
