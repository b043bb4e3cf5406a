use super::*;

const TREE: &str = "# A tree to calibrate.
procedure = \"sandbox\"
version = 3
title = \"Surgical skill\"

[[node]]
path = \"efficiency\"
weight = 1

[[node]]
path = \"efficiency/time\"   # the task's time
metric = \"completion_time_s\"
better = \"lower\"
expert = 5.0
novice = 20.0
weight = 1

[[node]]
path = \"efficiency/overloads\"
metric = \"grasper_overloads\"
better = \"lower\"
expert = 0.0
novice = 3.0
weight = 1

[[node]]
path = \"quality\"
weight = 1

[[node]]
path = \"quality/economy\"
metric = \"motion.economy\"
better = \"higher\"
expert = 0.9
novice = 0.5
weight = 1
";

fn session(time_s: f64, overloads: f64, economy: Option<f64>) -> BTreeMap<String, Option<f64>> {
    BTreeMap::from([
        ("completion_time_s".to_string(), Some(time_s)),
        ("grasper_overloads".to_string(), Some(overloads)),
        ("motion.economy".to_string(), economy),
    ])
}

#[test]
fn references_are_the_groups_medians_and_the_table_tests_each_metric() {
    let tree = Tree::parse("t.toml", TREE).expect("tree");
    // Experts: times 5..9 s (median 7), no overloads, economy around 0.85.
    let expert: Vec<_> = [5.0, 6.0, 7.0, 8.0, 9.0]
        .iter()
        .zip([0.80, 0.84, 0.86, 0.88, 0.90])
        .map(|(&t, e)| session(t, 0.0, Some(e)))
        .collect();
    // Novices: times 20..40 s (median 25), also no overloads, economy 0.5-0.7 (median 0.6).
    let novice: Vec<_> = [20.0, 22.0, 25.0, 30.0, 40.0]
        .iter()
        .zip([0.5, 0.55, 0.6, 0.65, 0.7])
        .map(|(&t, e)| session(t, 0.0, Some(e)))
        .collect();
    let c = calibrate(
        &tree,
        "t.toml",
        TREE,
        ("experts", "novices"),
        &expert,
        &novice,
    )
    .expect("calibrated");
    assert_eq!((c.expert_sessions, c.novice_sessions), (5, 5));
    let time = &c.rows[0];
    assert_eq!(time.metric, "completion_time_s");
    assert_eq!(time.now, Some((7.0, 25.0)));
    assert_eq!(time.was, Some((5.0, 20.0)));
    // Every expert faster than every novice: the experts' U is 0; no ties and 5 + 5, so the
    // exact two-sided p is 2 / C(10, 5) = 2 / 252.
    let t = time.test.expect("tested");
    assert_eq!(t.u, 0.0);
    assert!(t.exact && (t.p - 2.0 / 252.0).abs() < 1e-12);
    assert_eq!(time.effect, Some(1.0));
    assert!(time.separates);
    let spread = time.expert.expect("spread");
    assert_eq!((spread.median, spread.q1, spread.q3), (7.0, 6.0, 8.0));
    // All zeros in both groups: nothing to set, the leaf keeps its references.
    let over = &c.rows[1];
    assert_eq!(over.now, Some((0.0, 3.0)));
    assert!(!over.separates);
    assert!(over.note.contains("kept"), "{}", over.note);
    let economy = &c.rows[2];
    assert_eq!(economy.now, Some((0.86, 0.6)));
    assert!(economy.separates);
    // The total score of the calibrated tree, last.
    assert_eq!(c.rows[3].path, "score");
    assert!(c.rows[3].separates);
    // The new file: references and version changed, the rest (comments too) as it was.
    let again = Tree::parse("t2.toml", &c.tree_text).expect("calibrated tree parses");
    assert_eq!(again.version, 4);
    let leaf = |p: &str| {
        again
            .nodes
            .iter()
            .find(|n| n.path == p)
            .and_then(|n| n.leaf.clone())
            .expect("leaf")
    };
    assert_eq!(
        (
            leaf("efficiency/time").expert,
            leaf("efficiency/time").novice
        ),
        (7.0, 25.0)
    );
    assert_eq!(leaf("efficiency/overloads").novice, 3.0);
    assert!(
        c.tree_text
            .contains("path = \"efficiency/time\"   # the task's time")
    );
    assert!(c.tree_text.starts_with("# A tree to calibrate.\n"));
}

#[test]
fn medians_the_wrong_way_round_keep_the_references() {
    let tree = Tree::parse("t.toml", TREE).expect("tree");
    // The "experts" are slower: the data cannot set the time's references.
    let expert: Vec<_> = (0..5)
        .map(|k| session(30.0 + f64::from(k), 0.0, None))
        .collect();
    let novice: Vec<_> = (0..5)
        .map(|k| session(10.0 + f64::from(k), 1.0, None))
        .collect();
    let c = calibrate(&tree, "t.toml", TREE, ("a", "b"), &expert, &novice).expect("calibrated");
    assert_eq!(c.rows[0].now, Some((5.0, 20.0)));
    assert!(!c.rows[0].separates, "the experts are not the better way");
    assert_eq!(c.rows[0].effect, Some(-1.0));
    // Overloads 0 against 1: set (median 0 and 1), separated.
    assert_eq!(c.rows[1].now, Some((0.0, 1.0)));
    // Economy never taken.
    assert!(c.rows[2].expert.is_none() && c.rows[2].note.contains("never"));
}

#[test]
fn a_group_without_sessions_is_a_clear_error() {
    let tree = Tree::parse("t.toml", TREE).expect("tree");
    let e = calibrate(
        &tree,
        "t.toml",
        TREE,
        ("experts", "novices"),
        &[],
        &[session(1.0, 0.0, None)],
    )
    .expect_err("no experts");
    assert!(e.to_string().contains("0 of 'experts'"), "{e}");
}

#[test]
fn a_stored_report_gives_the_measures_a_live_session_does() {
    let report = serde_json::json!({
        "completed": true, "errors": 2, "simulated_s": 12.5,
        "metrics": {"completion_time_s": 12.0, "steps_done": ["a", "b", "c"]},
        "motion": {"path_m": 0.5, "economy": null, "movements": 7},
    });
    let m = report_measures(&report, 4);
    assert_eq!(m["completion_time_s"], Some(12.0));
    assert_eq!(m["session.completed"], Some(1.0));
    assert_eq!(m["session.errors"], Some(2.0));
    assert_eq!(m["session.steps_fraction"], Some(0.75));
    assert_eq!(m["motion.path_m"], Some(0.5));
    assert_eq!(m["motion.movements"], Some(7.0));
    assert_eq!(m["motion.economy"], None);
}

#[test]
fn references_keep_four_significant_digits() {
    assert_eq!(rounded(0.123456), 0.1235);
    assert_eq!(rounded(123.456), 123.5);
    assert_eq!(rounded(-0.0012346), -0.001235);
    assert_eq!(rounded(0.0), 0.0);
}

#[test]
fn a_task_not_completed_counts_as_the_slowest_completion() {
    let tree = Tree::parse("t.toml", TREE).expect("tree");
    let timed = |t: Option<f64>| {
        let mut s = session(0.0, 0.0, None);
        s.insert("completion_time_s".into(), t);
        s
    };
    let expert: Vec<_> = [8.0, 9.0, 10.0, 11.0, 12.0]
        .map(|t| timed(Some(t)))
        .to_vec();
    // Two novices finished (40 and 50 s), three did not: they stand at 50 s, the slowest
    // time taken, so the novices' median is 50 s.
    let novice = vec![
        timed(Some(40.0)),
        timed(None),
        timed(Some(50.0)),
        timed(None),
        timed(None),
    ];
    let c = calibrate(&tree, "t.toml", TREE, ("e", "n"), &expert, &novice).expect("calibrated");
    assert_eq!(c.rows[0].now, Some((10.0, 50.0)));
    assert_eq!(c.rows[0].novice.expect("spread").n, 5);
    assert!(c.rows[0].separates);
    // A group that never finished says nothing of a novice's time.
    let none = vec![timed(None); 5];
    let c = calibrate(&tree, "t.toml", TREE, ("e", "n"), &expert, &none).expect("calibrated");
    assert_eq!(c.rows[0].now, Some((5.0, 20.0)));
    assert!(c.rows[0].note.contains("never"), "{}", c.rows[0].note);
}
