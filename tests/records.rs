//! The learning centre's records through the command line: a headless session stored for a
//! trainee, listed, shown and exported; `records import` killed with SIGKILL at several
//! moments while it stores sixty sessions leaves the file passing `PRAGMA integrity_check`
//! and every session either absent or whole, and importing again stores each exactly once.

mod common;
use common::{bin, ok, report, tmp};
use std::path::{Path, PathBuf};
use vesalius::records::Records;

/// Every stored session is whole: its nodes' values are all there.
fn assert_whole(db: &Path) -> usize {
    let r = Records::open(db).expect("opens");
    assert_eq!(r.integrity().expect("integrity_check"), "ok");
    let rows = r.sessions(None).expect("list");
    for s in &rows {
        let d = r.session(&s.session_id).expect("query").expect("listed");
        let want = d.report["assessment"]["nodes"]
            .as_array()
            .map_or(0, Vec::len);
        assert!(want > 0);
        assert_eq!(d.nodes.len(), want, "session {} is partial", s.session_id);
    }
    rows.len()
}

#[test]
fn sessions_are_stored_listed_and_survive_a_kill_at_any_moment() {
    let d = tmp("records", "kill");
    let out = d.join("out");
    let db = d.join("centre.sqlite");
    let trace = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/traces/sandbox-demo.toml");
    let said = ok(&bin()
        .args(["run", "sandbox", "--headless", "--trace"])
        .arg(&trace)
        .arg("--out")
        .arg(&out)
        .arg("--records")
        .arg(&db)
        .args(["--trainee", "res-01"])
        .output()
        .expect("runs"));
    let r = report(&out);
    let id = r["session_id"].as_str().unwrap_or_default().to_string();
    assert!(
        said.contains(&format!("stored session {id} for res-01")),
        "{said}"
    );
    let list = ok(&bin()
        .args(["records", "list", "--db"])
        .arg(&db)
        .output()
        .expect("runs"));
    let level = r["level"].as_str().unwrap_or("?");
    let line = list
        .lines()
        .find(|l| l.starts_with(&id))
        .unwrap_or_default();
    assert!(
        line.contains("res-01") && line.contains("sandbox") && line.contains(level),
        "{list}"
    );
    let shown: serde_json::Value = serde_json::from_str(&ok(&bin()
        .args(["records", "show", &id, "--json", "--db"])
        .arg(&db)
        .output()
        .expect("runs")))
    .expect("JSON");
    assert_eq!(shown["report"], r);
    assert_eq!(shown["score"], r["assessment"]["score"]);
    let csv = ok(&bin()
        .args(["records", "export", "--format", "csv", "--db"])
        .arg(&db)
        .output()
        .expect("runs"));
    assert_eq!(csv.lines().count(), 2, "{csv}");
    assert!(
        csv.lines()
            .nth(1)
            .unwrap_or_default()
            .starts_with(&format!("{id},res-01,sandbox,1,"))
    );
    let mode =
        std::os::unix::fs::PermissionsExt::mode(&std::fs::metadata(&db).expect("db").permissions());
    assert_eq!(mode & 0o777, 0o600);

    // Sixty copies of the session under new ids.
    let copies: Vec<PathBuf> = (0..60)
        .map(|k| {
            let c = d.join(format!("copy{k:02}"));
            std::fs::create_dir_all(&c).expect("dir");
            let mut rep = r.clone();
            rep["session_id"] = format!("{k:016x}").into();
            std::fs::write(c.join("report.json"), rep.to_string()).expect("report");
            std::fs::copy(out.join("input.vtrace"), c.join("input.vtrace")).expect("rec");
            c
        })
        .collect();
    let kill_db = d.join("killed.sqlite");
    for (k, after_ms) in [2u64, 9, 17, 28, 40, 60].into_iter().enumerate() {
        let mut child = bin()
            .args(["records", "import", "--trainee", &format!("t{k}"), "--db"])
            .arg(&kill_db)
            .args(&copies)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("spawns");
        std::thread::sleep(std::time::Duration::from_millis(after_ms));
        let _ = child.kill();
        let _ = child.wait();
        if kill_db.exists() {
            let stored = assert_whole(&kill_db);
            eprintln!("killed after {after_ms} ms: {stored} sessions stored, all whole");
        }
    }
    // Imported to the end: each session exactly once, none lost, none doubled.
    ok(&bin()
        .args(["records", "import", "--trainee", "t9", "--db"])
        .arg(&kill_db)
        .args(&copies)
        .output()
        .expect("runs"));
    assert_eq!(assert_whole(&kill_db), 60);
    let levels = ok(&bin()
        .args(["records", "levels", "--db"])
        .arg(&kill_db)
        .output()
        .expect("runs"));
    // All sixty now belong to t9: one trainee, at the session's level.
    let at = |name: &str| -> u64 {
        levels
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|n| n.parse().ok())
            .unwrap_or(u64::MAX)
    };
    assert_eq!(at(level), 1, "{levels}");
    assert!(levels.contains("trainees with a session: 1"), "{levels}");
}

#[test]
fn questionnaire_answers_through_the_command_line() {
    let d = tmp("records", "answers");
    let db = d.join("study.sqlite");
    let forms = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/questionnaires");
    let mut files: Vec<PathBuf> = std::fs::read_dir(&forms)
        .expect("forms")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    files.sort();
    let o = ok(&bin().arg("check").args(&files).output().expect("runs"));
    assert_eq!(o.matches("ok (questionnaire)").count(), files.len(), "{o}");
    // Two interns and a student rate the nephrectomy's ten measures 0-9.
    let form = forms.join("nephrectomy-validity.toml");
    let q = vesalius::assess::questionnaire::Questionnaire::load_file(&form).expect("form");
    let answers: Vec<serde_json::Value> = [
        ("i1", "interns", 6.0),
        ("i2", "interns", 8.0),
        ("s1", "students", 5.0),
    ]
    .iter()
    .map(|(who, group, first)| {
        let scores: serde_json::Map<String, serde_json::Value> = q
            .items
            .iter()
            .enumerate()
            .map(|(k, i)| (i.id.clone(), if k == 0 { *first } else { 7.0 }.into()))
            .collect();
        serde_json::json!({"participant": who, "group": group, "scores": scores})
    })
    .collect();
    let file = d.join("answers.json");
    std::fs::write(&file, serde_json::to_string(&answers).expect("JSON")).expect("written");
    let store = || {
        bin()
            .args(["records", "answers"])
            .arg(&form)
            .arg(&file)
            .arg("--db")
            .arg(&db)
            .output()
            .expect("runs")
    };
    let said = ok(&store());
    assert!(
        said.contains("stored the answers of 3 participants"),
        "{said}"
    );
    let stats: serde_json::Value = serde_json::from_str(&ok(&bin()
        .args(["records", "stats"])
        .arg(&form)
        .args(["--json", "--db"])
        .arg(&db)
        .output()
        .expect("runs")))
    .expect("JSON");
    // By hand: the interns' first item 6 and 8, mean 7, SD sqrt(2); the students' one
    // answer has no SD.
    let groups = stats["groups"].as_array().cloned().unwrap_or_default();
    assert_eq!(groups.len(), 2);
    assert_eq!(groups[0]["group"], "interns");
    let first = &groups[0]["items"][0]["summary"];
    assert_eq!(first["mean"], 7.0);
    assert!((first["sd"].as_f64().unwrap_or(0.0) - 2f64.sqrt()).abs() < 1e-12);
    assert_eq!(
        groups[1]["items"][0]["summary"]["sd"],
        serde_json::Value::Null
    );
    // Answers without their items are refused, naming the first missing one.
    std::fs::write(
        &file,
        "[{\"participant\": \"x\", \"group\": \"g\", \"scores\": {}}]",
    )
    .expect("w");
    let o = store();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("answers[0].scores."));
}
