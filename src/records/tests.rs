//! The records file: created owner-only in WAL mode at the schema's version, sessions stored
//! whole and listed, a stored session replaced (not doubled), the level distribution, bad
//! reports and a newer schema refused with the file named.

use super::*;
use crate::assess::Tree;
use crate::testing::Scratch;
use std::os::unix::fs::PermissionsExt;

fn scratch(name: &str) -> Scratch {
    Scratch::new("records", name)
}

/// A session's output folder: a report scored by the sandbox's own tree at completion time
/// `time_s`, and a recording's bytes.
fn session_dir(root: &Path, id: &str, time_s: f64) -> PathBuf {
    let tree = Tree::parse("sandbox.toml", crate::testing::SANDBOX_TREE).expect("tree");
    let metrics = serde_json::json!({
        "completion_time_s": time_s,
        "grasper_overloads": 0,
        "steps_done": ["touch", "press", "grasp", "lift"],
    });
    let m = crate::assess::tree::measures(&metrics, true, 0, 4, 4, time_s + 0.25);
    let a = tree.score(&m);
    let report = serde_json::json!({
        "procedure": "sandbox",
        "session_id": id,
        "completed": true,
        "simulated_s": time_s + 0.25,
        "metrics": metrics,
        "score": a.score,
        "level": a.level,
        "assessment": a,
        "scenario_digest": "00000000000000aa",
    });
    let d = root.join(id);
    std::fs::create_dir_all(&d).expect("dir");
    std::fs::write(d.join("report.json"), report.to_string()).expect("report");
    std::fs::write(d.join("input.vtrace"), format!("recording of {id}")).expect("rec");
    d
}

#[test]
fn a_new_file_is_owner_only_in_wal_mode_at_the_schemas_version() {
    let d = scratch("new");
    let path = d.join("sub").join("records.sqlite");
    let r = Records::open(&path).expect("opens");
    let mode = std::fs::metadata(&path).expect("file").permissions().mode() & 0o777;
    assert_eq!(mode, 0o600);
    assert_eq!(r.version().expect("version"), SCHEMA_VERSION);
    let journal: String = r
        .conn
        .query_row("PRAGMA journal_mode", [], |x| x.get(0))
        .expect("journal");
    assert_eq!(journal, "wal");
    let fk: i64 = r
        .conn
        .query_row("PRAGMA foreign_keys", [], |x| x.get(0))
        .expect("fk");
    assert_eq!(fk, 1);
    drop(r);
    // Opening again migrates nothing and keeps the version.
    let r = Records::open(&path).expect("opens again");
    assert_eq!(r.version().expect("version"), SCHEMA_VERSION);
    assert_eq!(r.integrity().expect("check"), "ok");
}

#[test]
fn sessions_are_stored_whole_listed_and_replaced_not_doubled() {
    let d = scratch("store");
    let mut r = Records::open(&d.join("records.sqlite")).expect("opens");
    r.put_trainee("t-001", "A. Trainee", "residents")
        .expect("trainee");
    let fast = session_dir(&d, "aaaa000000000001", 8.0);
    let slow = session_dir(&d, "aaaa000000000002", 34.0);
    assert_eq!(
        r.store_dir(&fast, "t-001").expect("stored"),
        "aaaa000000000001"
    );
    r.store_dir(&slow, "t-002").expect("stored");
    let all = r.sessions(None).expect("list");
    assert_eq!(all.len(), 2);
    let mine = r.sessions(Some("t-001")).expect("list");
    assert_eq!(mine.len(), 1);
    // By hand: 8 s is at the expert's 10 s or better: 100 points everywhere.
    assert_eq!(mine[0].score, 100.0);
    assert_eq!(mine[0].level, "expert");
    let shown = r
        .session("aaaa000000000002")
        .expect("query")
        .expect("stored");
    // 34 s: 100 (34 - 40) / (10 - 40) = 20 points of efficiency, 0.3 x 20 + 70 = 76.
    assert!((shown.row.score - 76.0).abs() < 1e-9, "{}", shown.row.score);
    assert_eq!(shown.row.level, "proficient");
    assert_eq!(shown.nodes.len(), 6);
    let time = shown
        .nodes
        .iter()
        .find(|n| n.path == "efficiency/completion_time");
    assert_eq!(time.and_then(|n| n.value), Some(34.0));
    assert_eq!(
        shown.recording_crc32,
        format!("{:08x}", crc32fast::hash(b"recording of aaaa000000000002"))
    );
    assert_eq!(shown.scenario_digest, "00000000000000aa");
    assert_eq!(shown.report["session_id"], "aaaa000000000002");
    // Stored again (a re-scoring): replaced, not doubled.
    r.store_dir(&slow, "t-002").expect("stored again");
    assert_eq!(r.sessions(None).expect("list").len(), 2);
    let rows: i64 = r
        .conn
        .query_row("SELECT COUNT(*) FROM metric_values", [], |x| x.get(0))
        .expect("count");
    assert_eq!(rows, 12);
    let t = r.trainees().expect("trainees");
    assert_eq!(t.len(), 2);
    assert_eq!(
        (
            t[0].pseudonym.as_str(),
            t[0].name.as_str(),
            t[0].group.as_str()
        ),
        ("t-001", "A. Trainee", "residents")
    );
    assert_eq!(t[1].sessions, 1);
    let dist = r.level_distribution(Some("sandbox")).expect("distribution");
    assert_eq!(
        dist,
        [
            ("novice", 0),
            ("intermediate", 0),
            ("proficient", 1),
            ("expert", 1)
        ]
    );
    assert_eq!(r.integrity().expect("check"), "ok");
}

#[test]
fn bad_input_is_refused_with_the_file_named_and_nothing_stored() {
    let d = scratch("bad");
    let mut r = Records::open(&d.join("records.sqlite")).expect("opens");
    let s = session_dir(&d, "bbbb000000000001", 8.0);
    let e = r.store_dir(&s, "has space").expect_err("bad pseudonym");
    assert!(e.to_string().contains("a pseudonym is 1-64 letters"), "{e}");
    std::fs::write(s.join("report.json"), "{\"procedure\": \"sandbox\"}").expect("w");
    let e = r.store_dir(&s, "t-1").expect_err("not a report");
    assert!(
        e.to_string().contains("report.json: session_id: missing"),
        "{e}"
    );
    std::fs::write(s.join("report.json"), "not json").expect("w");
    let e = r.store_dir(&s, "t-1").expect_err("not JSON");
    assert!(e.to_string().contains("not a session report"), "{e}");
    let e = r
        .store_dir(&d.join("nowhere"), "t-1")
        .expect_err("no folder");
    assert!(e.to_string().contains("nowhere/report.json"), "{e}");
    assert!(r.sessions(None).expect("list").is_empty());
    // A file from a newer schema is refused and left as it is.
    r.conn
        .pragma_update(None, "user_version", SCHEMA_VERSION + 1)
        .expect("bump");
    drop(r);
    let Err(e) = Records::open(&d.join("records.sqlite")) else {
        panic!("a newer schema opened");
    };
    assert!(
        e.to_string().contains("newer than this Vesalius reads"),
        "{e}"
    );
}

/// A file at schema version 1 (sessions only) is migrated to the current version in place,
/// keeping what it holds.
#[test]
fn a_version_1_file_is_migrated_keeping_its_records() {
    let d = scratch("migrate");
    let path = d.join("old.sqlite");
    {
        let c = Connection::open(&path).expect("opens");
        c.execute_batch(schema::MIGRATIONS[0])
            .expect("version 1 tables");
        c.pragma_update(None, "user_version", 1).expect("version");
        c.execute(
            "INSERT INTO trainees (pseudonym, name) VALUES ('old-1', 'From version 1')",
            [],
        )
        .expect("trainee");
    }
    let r = Records::open(&path).expect("migrates");
    assert_eq!(r.version().expect("version"), SCHEMA_VERSION);
    let t = r.trainees().expect("trainees");
    assert_eq!(t[0].name, "From version 1");
    assert!(
        r.answers("cholecystectomy-usability")
            .expect("new table")
            .is_empty()
    );
}

/// Answers are checked, stored per participant (again: replaced) and their statistics made
/// from what is stored: by hand, ease of use 4, 5, 3 has mean 4, SD 1, median 4, IQR 1
/// (quartiles 3.5 and 4.5).
#[test]
fn questionnaire_answers_are_stored_and_summarised() {
    use crate::assess::questionnaire::{Answers, Questionnaire};
    let d = scratch("answers");
    let mut r = Records::open(&d.join("records.sqlite")).expect("opens");
    let text = include_str!("../../assets/questionnaires/cholecystectomy-usability.toml");
    let q = Questionnaire::parse("usability.toml", text).expect("form");
    let one = |who: &str, group: &str, ease: f64| Answers {
        participant: who.into(),
        group: group.into(),
        scores: q
            .items
            .iter()
            .map(|i| (i.id.clone(), if i.id == "ease_of_use" { ease } else { 3.0 }))
            .collect(),
    };
    let mut all = vec![
        one("s1", "surgeons", 4.0),
        one("s2", "surgeons", 1.0),
        one("s3", "surgeons", 3.0),
    ];
    r.store_answers(&q, "a.json", &all).expect("stored");
    // s2 answers again: replaced, not added.
    all[1] = one("s2", "surgeons", 5.0);
    r.store_answers(&q, "a.json", &all[1..2])
        .expect("stored again");
    let rep = r.questionnaire_report(&q).expect("report");
    assert_eq!(rep.groups.len(), 1);
    let ease = &rep.groups[0].items[0];
    assert_eq!(ease.item, "ease_of_use");
    assert_eq!(ease.summary.n, 3);
    assert_eq!(ease.summary.mean, 4.0);
    assert_eq!(ease.summary.sd, Some(1.0));
    assert_eq!((ease.summary.median, ease.summary.iqr), (4.0, 1.0));
    // An answer off the scale is refused, naming it, and nothing is stored.
    let bad = vec![one("s4", "surgeons", 7.0)];
    let e = r.store_answers(&q, "b.json", &bad).expect_err("7 of 5");
    assert!(
        e.to_string().contains("answers[0].scores.ease_of_use"),
        "{e}"
    );
    assert_eq!(r.answers(&q.id).expect("answers").len(), 3);
}
