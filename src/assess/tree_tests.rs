//! The assessment tree and the fuzzy levels against values worked out by hand, bad files
//! with the key they are wrong at (every shipped tree against its procedure: the registry's
//! tests).

use super::fuzzy::{LEVELS, Levels};
use super::tree::{Tree, measures};
use std::collections::BTreeMap;

/// Two grades: efficiency (weight 1) of a time (3) and a path (1), safety (3) of errors.
const SMALL: &str = r#"
procedure = "sandbox"
version = 7
title = "Skill"

[[node]]
path = "efficiency"
weight = 1

[[node]]
path = "efficiency/time"
metric = "t"
better = "lower"
expert = 10.0
novice = 50.0
weight = 3

[[node]]
path = "efficiency/path"
metric = "p"
better = "lower"
expert = 1.0
novice = 3.0
weight = PATH_WEIGHT

[[node]]
path = "safety"
weight = 3

[[node]]
path = "safety/errors"
metric = "e"
better = "lower"
expert = 0
novice = 4
weight = 1
"#;

fn small(path_weight: &str) -> Tree {
    let text = SMALL.replace("PATH_WEIGHT", path_weight);
    match Tree::parse("small.toml", &text) {
        Ok(t) => t,
        Err(e) => panic!("{e}"),
    }
}

fn m(pairs: &[(&str, Option<f64>)]) -> BTreeMap<String, Option<f64>> {
    pairs.iter().map(|(k, v)| (k.to_string(), *v)).collect()
}

fn node_score(a: &super::Assessment, path: &str) -> Option<f64> {
    a.nodes
        .iter()
        .find(|n| n.path == path)
        .and_then(|n| n.score)
}

/// By hand: time 20 s is (20 - 50) / (10 - 50) = 75 points, path 2.5 m is 25, efficiency
/// (3 x 75 + 1 x 25) / 4 = 62.5; one error of four is 75, safety 75; the whole
/// (1 x 62.5 + 3 x 75) / 4 = 71.875. On the default levels that lies where intermediate
/// falls (65-75) and proficient rises: (75 - 71.875) / 10 = 0.3125 and 0.6875, proficient.
#[test]
fn a_hand_computed_tree_gives_its_score_and_level() {
    let t = small("1");
    assert_eq!(t.version, 7);
    let a = t.score(&m(&[("t", Some(20.0)), ("p", Some(2.5)), ("e", Some(1.0))]));
    let close = |x: f64, y: f64| (x - y).abs() < 1e-12;
    assert!(close(a.score, 71.875), "{}", a.score);
    assert!(close(
        node_score(&a, "efficiency/time").unwrap_or(-1.0),
        75.0
    ));
    assert!(close(
        node_score(&a, "efficiency/path").unwrap_or(-1.0),
        25.0
    ));
    assert!(close(node_score(&a, "efficiency").unwrap_or(-1.0), 62.5));
    assert!(close(node_score(&a, "safety").unwrap_or(-1.0), 75.0));
    assert!(close(a.memberships.intermediate, 0.3125));
    assert!(close(a.memberships.proficient, 0.6875));
    assert_eq!((a.memberships.novice, a.memberships.expert), (0.0, 0.0));
    assert_eq!(a.level, "proficient");
    // The grades carry their own levels: safety at 75 is wholly proficient.
    let safety = &a.grades[1];
    assert_eq!(safety.path, "safety");
    assert_eq!(safety.memberships.map(|m| m.proficient), Some(1.0));
    // The shares as scored: time 3/4 of efficiency, efficiency 1/4 of the whole.
    let share = |p: &str| a.nodes.iter().find(|n| n.path == p).map(|n| n.weight);
    assert_eq!(share("efficiency/time"), Some(0.75));
    assert_eq!(share("efficiency"), Some(0.25));
}

/// Tripling the path's weight moves only efficiency and the whole: efficiency becomes
/// (3 x 75 + 3 x 25) / 6 = 50, the whole (50 + 225) / 4 = 68.75; every leaf and safety keep
/// their scores.
#[test]
fn changing_a_weight_changes_only_what_it_should() {
    let measures = m(&[("t", Some(20.0)), ("p", Some(2.5)), ("e", Some(1.0))]);
    let a = small("1").score(&measures);
    let b = small("3").score(&measures);
    for p in [
        "efficiency/time",
        "efficiency/path",
        "safety",
        "safety/errors",
    ] {
        assert_eq!(node_score(&a, p), node_score(&b, p), "{p}");
    }
    assert_eq!(node_score(&b, "efficiency"), Some(50.0));
    assert!((b.score - 68.75).abs() < 1e-12, "{}", b.score);
    assert_ne!(a.score, b.score);
}

/// Values beyond the references are held at 0 and 100; a measure not taken counts as a
/// novice's unless the leaf says skip, when its siblings share its weight.
#[test]
fn references_clamp_and_missing_measures_follow_the_leaf() {
    let t = small("1");
    let a = t.score(&m(&[("t", Some(5.0)), ("p", Some(9.0)), ("e", None)]));
    assert_eq!(node_score(&a, "efficiency/time"), Some(100.0));
    assert_eq!(node_score(&a, "efficiency/path"), Some(0.0));
    assert_eq!(node_score(&a, "safety/errors"), Some(0.0));
    let skip = SMALL
        .replace("PATH_WEIGHT", "1")
        .replace("novice = 3.0\n", "novice = 3.0\nmissing = \"skip\"\n");
    let t = Tree::parse("skip.toml", &skip).expect("parses");
    let a = t.score(&m(&[("t", Some(20.0)), ("e", Some(1.0))]));
    assert_eq!(node_score(&a, "efficiency/path"), None);
    assert_eq!(node_score(&a, "efficiency"), Some(75.0));
    let path = a.nodes.iter().find(|n| n.path == "efficiency/path");
    assert_eq!(path.map(|n| n.weight), Some(0.0));
    assert!((a.score - 75.0).abs() < 1e-12);
}

/// The default levels are a partition: at every score the memberships sum to one, each
/// plateau is its own level, and a score halfway down a slope is an exact tie won by the
/// lower level.
#[test]
fn fuzzy_levels_partition_the_scores() {
    let l = Levels::default();
    assert_eq!(l.check(), Ok(()));
    for k in 0..=1000 {
        let s = f64::from(k) / 10.0;
        let sum: f64 = l.memberships(s).as_array().iter().sum();
        assert!((sum - 1.0).abs() < 1e-12, "{s}: {sum}");
    }
    for (score, level) in [(20.0, 0), (60.0, 1), (78.0, 2), (95.0, 3)] {
        let mem = l.memberships(score);
        assert_eq!(mem.as_array()[level], 1.0, "{score}");
        assert_eq!(l.level_of(&mem), LEVELS[level]);
    }
    let tie = l.memberships(47.5);
    assert_eq!((tie.novice, tie.intermediate), (0.5, 0.5));
    assert_eq!(l.level_of(&tie), "novice");
    // Out-of-range scores are clamped.
    assert_eq!(l.memberships(-5.0).novice, 1.0);
    assert_eq!(l.memberships(140.0).expert, 1.0);
}

/// Levels from a file: read, and refused where they would not sum to one.
#[test]
fn levels_from_a_file_are_checked() {
    let with = |levels: &str| {
        Tree::parse(
            "levels.toml",
            &format!("{}\n[levels]\n{levels}", SMALL.replace("PATH_WEIGHT", "1")),
        )
    };
    let ok = with(
        "novice = [0, 0, 30, 50]\nintermediate = [30, 50, 60, 70]\n\
         proficient = [60, 70, 80, 90]\nexpert = [80, 90, 100, 100]",
    )
    .expect("a partition");
    assert_eq!(ok.levels.memberships(40.0).novice, 0.5);
    let gap = with(
        "novice = [0, 0, 30, 50]\nintermediate = [35, 50, 60, 70]\n\
         proficient = [60, 70, 80, 90]\nexpert = [80, 90, 100, 100]",
    )
    .expect_err("intermediate rises late");
    assert_eq!(gap.key, "levels");
    assert!(gap.message.contains("sum to one"), "{gap}");
    let short = with("novice = [0, 0, 30]").expect_err("three numbers");
    assert_eq!(short.key, "levels.novice");
    let unknown = with("master = [0, 0, 1, 2]").expect_err("no such level");
    assert_eq!(unknown.key, "levels.master");
}

/// Bad trees get errors naming the node and what is expected.
#[test]
fn bad_trees_name_the_node_and_what_is_expected() {
    let base = SMALL.replace("PATH_WEIGHT", "1");
    let cases: [(String, &str, &str); 8] = [
        (
            base.replace(
                "better = \"lower\"\nexpert = 10.0",
                "better = \"higher\"\nexpert = 10.0",
            ),
            "node[1] (efficiency/time)",
            "expert's value must be above",
        ),
        (
            base.replace("metric = \"t\"\nbetter = \"lower\"\n", "metric = \"t\"\n"),
            "node[1] (efficiency/time)",
            "needs 'better'",
        ),
        (
            base.replace(
                "path = \"efficiency\"\nweight = 1",
                "path = \"efficiency\"\nweight = -1",
            ),
            "node[0] (efficiency)",
            "'weight' must be",
        ),
        (
            base.replace(
                "path = \"safety\"\nweight = 3",
                "path = \"safe\"\nweight = 3",
            ),
            "node[4] (safety/errors)",
            "must be listed before it",
        ),
        (
            base.replace("path = \"efficiency/path\"", "path = \"efficiency/time\""),
            "node[2] (efficiency/time)",
            "listed twice",
        ),
        (
            base.replace("path = \"safety/errors\"", "path = \"efficiency/time/x\""),
            "node[4] (efficiency/time/x)",
            "is a leaf",
        ),
        (
            base.replace(
                "path = \"safety\"\nweight = 3",
                "path = \"safety\"\nweight = 3\nexpert = 1",
            ),
            "node[3] (safety)",
            "belong to a leaf",
        ),
        (
            base.replace(
                "path = \"efficiency\"\nweight = 1",
                "path = \"efficiency\"\nwieght = 1",
            ),
            "toml",
            "unknown field",
        ),
    ];
    for (text, key, says) in cases {
        let e = Tree::parse("bad.toml", &text).expect_err(key);
        assert_eq!(e.file, "bad.toml");
        assert_eq!(e.key, key, "{e}");
        assert!(e.message.contains(says), "{e}");
    }
    let empty = "procedure = \"sandbox\"\nversion = 1\ntitle = \"x\"\n";
    assert_eq!(
        Tree::parse("e.toml", empty).expect_err("no nodes").key,
        "node"
    );
    let childless = format!("{empty}[[node]]\npath = \"a\"\nweight = 1\n");
    let e = Tree::parse("c.toml", &childless).expect_err("inner without children");
    assert_eq!(e.key, "node (a)");
    let weightless = base
        .replace("weight = 1\n", "weight = 0\n")
        .replace("weight = 3\n", "weight = 0\n");
    let e = Tree::parse("w.toml", &weightless).expect_err("weighs nothing");
    assert!(e.message.contains("weigh nothing"), "{e}");
}

/// The session's measures: numbers by key, booleans as 1 or 0, null as not taken, a list's
/// length, an object's numbers, and the session's own.
#[test]
fn measures_flatten_a_report() {
    let metrics = serde_json::json!({
        "time_s": 12.5,
        "done": true,
        "when": null,
        "steps_done": ["a", "b"],
        "clips": {"count": 3, "cuts": [1, 2, 3, 4]},
        "name": "text is no measure",
    });
    let got = measures(&metrics, true, 2, 2, 4, 30.0);
    assert_eq!(got["time_s"], Some(12.5));
    assert_eq!(got["done"], Some(1.0));
    assert_eq!(got["when"], None);
    assert_eq!(got["steps_done.count"], Some(2.0));
    assert_eq!(got["clips.count"], Some(3.0));
    assert_eq!(got["clips.cuts.count"], Some(4.0));
    assert!(!got.contains_key("name"));
    assert_eq!(got["session.completed"], Some(1.0));
    assert_eq!(got["session.errors"], Some(2.0));
    assert_eq!(got["session.steps_fraction"], Some(0.5));
    assert_eq!(got["session.simulated_s"], Some(30.0));
}

/// Rules speak when their condition begins: above and below once per crossing, a rise at
/// every rise; a measure not taken holds nothing; bad rules name themselves.
#[test]
fn rules_speak_when_their_condition_begins() {
    let text = format!(
        "{}\n[[rule]]\nid = \"fast\"\nmetric = \"t\"\nabove = 30\nsay = \"Slow down\"\n\
         \n[[rule]]\nid = \"errors\"\nmetric = \"e\"\nrises = true\nsay = \"Careful\"\n\
         \n[[rule]]\nid = \"short\"\nmetric = \"p\"\nbelow = 1.5\nsay = \"Longer strokes\"\n",
        SMALL.replace("PATH_WEIGHT", "1")
    );
    let t = Tree::parse("rules.toml", &text).expect("parses");
    assert_eq!(t.rules.len(), 3);
    let mut state = Vec::new();
    let mut said = |t_s: Option<f64>, e: f64, p: Option<f64>| -> Vec<String> {
        super::rules::evaluate(
            &t.rules,
            &mut state,
            &m(&[("t", t_s), ("e", Some(e)), ("p", p)]),
        )
        .into_iter()
        .map(|r| r.id.clone())
        .collect()
    };
    assert!(said(Some(10.0), 0.0, None).is_empty());
    assert_eq!(said(Some(31.0), 0.0, Some(2.0)), ["fast"]);
    // Still above: no repeat. An error: a rise.
    assert_eq!(said(Some(40.0), 1.0, Some(1.0)), ["errors", "short"]);
    assert!(said(Some(40.0), 1.0, Some(1.0)).is_empty());
    // Back below, then above again: speaks again; another error: again.
    assert!(said(Some(20.0), 1.0, Some(2.0)).is_empty());
    assert_eq!(said(Some(35.0), 2.0, None), ["fast", "errors"]);
    for (bad, says) in [
        (
            "id = \"a\"\nmetric = \"t\"\nabove = 1\nbelow = 2\nsay = \"s\"",
            "exactly one",
        ),
        (
            "id = \"a\"\nmetric = \"t\"\nrises = false\nsay = \"s\"",
            "exactly one",
        ),
        (
            "id = \"a\"\nmetric = \"t\"\nabove = 1\nsay = \" \"",
            "'say'",
        ),
    ] {
        let text = format!("{}\n[[rule]]\n{bad}\n", SMALL.replace("PATH_WEIGHT", "1"));
        let e = Tree::parse("r.toml", &text).expect_err(says);
        assert_eq!(e.key, "rule[0] (a)", "{e}");
        assert!(e.message.contains(says), "{e}");
    }
}
