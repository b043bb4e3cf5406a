//! Questionnaire statistics against values worked out by hand, bad files and bad answers
//! with the key they are wrong at, and every shipped questionnaire.

use super::questionnaire::{
    Answers, Questionnaire, Report, Summary, cronbach_alpha, quantile, sample_variance,
};
use std::collections::BTreeMap;

/// Two scales on a 1-5 rating: "face" of items a, b, c and "content" of item d alone.
const SMALL: &str = r#"
id = "small"
title = "Small"
paper = "ours"

[rating]
min = 1
max = 5
min_label = "Poor"
max_label = "Excellent"

[[scales]]
id = "face"
title = "Face validity"

[[scales]]
id = "content"
title = "Content validity"

[[items]]
id = "a"
scale = "face"
text = "Item a"

[[items]]
id = "b"
scale = "face"
text = "Item b"

[[items]]
id = "c"
scale = "face"
text = "Item c"

[[items]]
id = "d"
scale = "content"
text = "Item d"
"#;

fn small() -> Questionnaire {
    match Questionnaire::parse("small.toml", SMALL) {
        Ok(q) => q,
        Err(e) => panic!("{e}"),
    }
}

fn answers(participant: &str, group: &str, scores: &[(&str, f64)]) -> Answers {
    Answers {
        participant: participant.to_string(),
        group: group.to_string(),
        scores: scores
            .iter()
            .map(|(k, v)| (k.to_string(), *v))
            .collect::<BTreeMap<_, _>>(),
    }
}

/// Four students and one intern:
///
/// | participant | group    | a | b | c | d |
/// |-------------|----------|---|---|---|---|
/// | p1          | students | 2 | 3 | 1 | 5 |
/// | p2          | students | 4 | 4 | 5 | 4 |
/// | p3          | students | 3 | 5 | 4 | 4 |
/// | p4          | students | 5 | 4 | 4 | 3 |
/// | p5          | interns  | 4 | 4 | 3 | 2 |
fn data() -> Vec<Answers> {
    vec![
        answers(
            "p1",
            "students",
            &[("a", 2.), ("b", 3.), ("c", 1.), ("d", 5.)],
        ),
        answers(
            "p2",
            "students",
            &[("a", 4.), ("b", 4.), ("c", 5.), ("d", 4.)],
        ),
        answers(
            "p5",
            "interns",
            &[("a", 4.), ("b", 4.), ("c", 3.), ("d", 2.)],
        ),
        answers(
            "p3",
            "students",
            &[("a", 3.), ("b", 5.), ("c", 4.), ("d", 4.)],
        ),
        answers(
            "p4",
            "students",
            &[("a", 5.), ("b", 4.), ("c", 4.), ("d", 3.)],
        ),
    ]
}

fn report() -> Report {
    match small().report("answers.json", &data()) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    }
}

fn close(what: &str, got: f64, want: f64) {
    assert!((got - want).abs() < 1e-12, "{what}: got {got}, want {want}");
}

fn close_opt(what: &str, got: Option<f64>, want: f64) {
    match got {
        Some(g) => close(what, g, want),
        None => panic!("{what}: got None, want {want}"),
    }
}

/// Checks a summary against hand values (sd as its square, the variance).
fn check_summary(
    what: &str,
    s: &Summary,
    n: usize,
    mean: f64,
    variance: f64,
    (q1, median, q3): (f64, f64, f64),
    (min, max): (f64, f64),
) {
    assert_eq!(s.n, n, "{what}: n");
    close(&format!("{what} mean"), s.mean, mean);
    close_opt(&format!("{what} sd"), s.sd, variance.sqrt());
    close(&format!("{what} q1"), s.q1, q1);
    close(&format!("{what} median"), s.median, median);
    close(&format!("{what} q3"), s.q3, q3);
    close(&format!("{what} iqr"), s.iqr, q3 - q1);
    close(&format!("{what} min"), s.min, min);
    close(&format!("{what} max"), s.max, max);
}

#[test]
fn groups_are_sorted_and_items_keep_file_order() {
    let r = report();
    assert_eq!(r.questionnaire, "small");
    let groups: Vec<&str> = r.groups.iter().map(|g| g.group.as_str()).collect();
    assert_eq!(groups, ["interns", "students"]);
    let students = &r.groups[1];
    assert_eq!(students.n, 4);
    let items: Vec<&str> = students.items.iter().map(|i| i.item.as_str()).collect();
    assert_eq!(items, ["a", "b", "c", "d"]);
    let scales: Vec<(&str, usize)> = students
        .scales
        .iter()
        .map(|s| (s.scale.as_str(), s.k))
        .collect();
    assert_eq!(scales, [("face", 3), ("content", 1)]);
}

#[test]
fn item_statistics_match_hand_values() {
    let r = report();
    let students = &r.groups[1];
    // Quartiles at position h = (n - 1) p = 3p: q1 at h = 0.75, median at 1.5, q3 at 2.25,
    // each x[floor h] + (h - floor h) (x[floor h + 1] - x[floor h]) of the sorted scores.
    //
    // a: 2 4 3 5, sorted 2 3 4 5. mean = 14 / 4 = 3.5. Deviations -1.5 0.5 -0.5 1.5,
    // squares 2.25 0.25 0.25 2.25, sum 5, variance 5 / 3 (sd 1.2910).
    // q1 = 2 + 0.75 (3 - 2) = 2.75; median = 3 + 0.5 (4 - 3) = 3.5;
    // q3 = 4 + 0.25 (5 - 4) = 4.25; iqr = 1.5.
    check_summary(
        "a",
        &students.items[0].summary,
        4,
        3.5,
        5.0 / 3.0,
        (2.75, 3.5, 4.25),
        (2.0, 5.0),
    );
    // b: 3 4 5 4, sorted 3 4 4 5. mean = 16 / 4 = 4. Deviations -1 0 1 0, sum of squares 2,
    // variance 2 / 3 (sd 0.8165).
    // q1 = 3 + 0.75 (4 - 3) = 3.75; median = 4 + 0.5 (4 - 4) = 4; q3 = 4 + 0.25 (5 - 4) = 4.25;
    // iqr = 0.5.
    check_summary(
        "b",
        &students.items[1].summary,
        4,
        4.0,
        2.0 / 3.0,
        (3.75, 4.0, 4.25),
        (3.0, 5.0),
    );
    // c: 1 5 4 4, sorted 1 4 4 5. mean = 14 / 4 = 3.5. Deviations -2.5 1.5 0.5 0.5, squares
    // 6.25 2.25 0.25 0.25, sum 9, variance 9 / 3 = 3 (sd 1.7321).
    // q1 = 1 + 0.75 (4 - 1) = 3.25; median = 4; q3 = 4 + 0.25 (5 - 4) = 4.25; iqr = 1.
    check_summary(
        "c",
        &students.items[2].summary,
        4,
        3.5,
        3.0,
        (3.25, 4.0, 4.25),
        (1.0, 5.0),
    );
    // d: 5 4 4 3, sorted 3 4 4 5: the same numbers as b, so mean 4, variance 2 / 3,
    // quartiles 3.75 4 4.25.
    check_summary(
        "d",
        &students.items[3].summary,
        4,
        4.0,
        2.0 / 3.0,
        (3.75, 4.0, 4.25),
        (3.0, 5.0),
    );
}

#[test]
fn scale_statistics_and_alpha_match_hand_values() {
    let r = report();
    let students = &r.groups[1];
    let face = &students.scales[0];
    // Totals over a, b, c: p1 2+3+1 = 6, p2 4+4+5 = 13, p3 3+5+4 = 12, p4 5+4+4 = 13.
    // Mean total 44 / 4 = 11; deviations -5 2 1 2, squares 25 4 1 4, sum 34, variance 34 / 3.
    // Item variances (above): 5/3 + 2/3 + 9/3 = 16/3.
    // alpha = 3 / (3 - 1) (1 - (16/3) / (34/3)) = 1.5 (1 - 16/34) = 1.5 (18/34) = 27/34
    //       = 0.794117647...
    close_opt("face alpha", face.alpha, 27.0 / 34.0);
    // Each participant's mean over the scale is the total / 3: 2, 13/3, 4, 13/3; sorted
    // 2, 4, 13/3, 13/3. Mean (44/3) / 4 = 11/3; variance is the totals' / 9 = 34/27.
    // q1 = 2 + 0.75 (4 - 2) = 3.5; median = 4 + 0.5 (13/3 - 4) = 25/6;
    // q3 = 13/3 + 0.25 (13/3 - 13/3) = 13/3.
    check_summary(
        "face",
        &face.summary,
        4,
        11.0 / 3.0,
        34.0 / 27.0,
        (3.5, 25.0 / 6.0, 13.0 / 3.0),
        (2.0, 13.0 / 3.0),
    );
    // One item: alpha needs two.
    let content = &students.scales[1];
    assert_eq!(content.alpha, None);
    close("content mean", content.summary.mean, 4.0);
}

#[test]
fn a_single_participant_has_no_sd_and_no_alpha() {
    let r = report();
    let interns = &r.groups[0];
    assert_eq!(interns.n, 1);
    let a = &interns.items[0].summary;
    // One score, 4: every quantile is 4, the iqr 0, and the sd undefined.
    assert_eq!(a.sd, None);
    for (what, v) in [
        ("mean", a.mean),
        ("median", a.median),
        ("q1", a.q1),
        ("q3", a.q3),
        ("min", a.min),
        ("max", a.max),
    ] {
        close(what, v, 4.0);
    }
    close("iqr", a.iqr, 0.0);
    assert_eq!(interns.scales[0].alpha, None);
    assert_eq!(interns.scales[0].summary.sd, None);
    // The JSON says so too (null), groups in order.
    let json = match serde_json::to_string(&r) {
        Ok(j) => j,
        Err(e) => panic!("{e}"),
    };
    assert!(json.contains("\"sd\":null"), "{json}");
    assert!(json.contains("\"alpha\":null"), "{json}");
    let (Some(i), Some(s)) = (json.find("\"interns\""), json.find("\"students\"")) else {
        panic!("{json}");
    };
    assert!(i < s, "{json}");
}

#[test]
fn quantiles_follow_numpy_linear() {
    // numpy.percentile([1, 2, 3, 4, 10], [25, 50, 75]) = [2, 3, 4]: h = 4p = 1, 2, 3 exactly.
    let x = [1.0, 2.0, 3.0, 4.0, 10.0];
    close_opt("q1", quantile(&x, 0.25), 2.0);
    close_opt("median", quantile(&x, 0.5), 3.0);
    close_opt("q3", quantile(&x, 0.75), 4.0);
    // The ends are the extremes; p = 0.9 is at h = 3.6: 4 + 0.6 (10 - 4) = 7.6.
    close_opt("p0", quantile(&x, 0.0), 1.0);
    close_opt("p100", quantile(&x, 1.0), 10.0);
    close_opt("p90", quantile(&x, 0.9), 7.6);
    // An even count's median is the mean of the middle two: [1, 2, 3, 4] at h = 1.5 is 2.5.
    close_opt("even median", quantile(&[1.0, 2.0, 3.0, 4.0], 0.5), 2.5);
    assert_eq!(quantile(&[], 0.5), None);
    assert_eq!(quantile(&x, 1.5), None);
    assert_eq!(quantile(&x, f64::NAN), None);
    assert_eq!(sample_variance(&[3.0]), None);
    // Unsorted input to the summary is sorted first.
    let s = Summary::of(&[10.0, 1.0, 4.0, 3.0, 2.0]);
    close_opt("summary median", s.map(|s| s.median), 3.0);
    assert_eq!(Summary::of(&[]), None);
    assert_eq!(Summary::of(&[1.0, f64::INFINITY]), None);
}

#[test]
fn alpha_is_none_when_it_is_undefined() {
    // Totals 1+2+3 = 6 and 3+2+1 = 6: their variance is 0.
    assert_eq!(
        cronbach_alpha(&[vec![1.0, 2.0, 3.0], vec![3.0, 2.0, 1.0]]),
        None
    );
    // Fractional scores with equal totals leave only rounding.
    assert_eq!(cronbach_alpha(&[vec![0.1, 0.2], vec![0.3, 0.0]]), None);
    assert_eq!(cronbach_alpha(&[vec![1.0, 2.0]]), None);
    assert_eq!(cronbach_alpha(&[vec![1.0], vec![2.0]]), None);
    assert_eq!(cronbach_alpha(&[vec![1.0, 2.0], vec![2.0]]), None);
    assert_eq!(cronbach_alpha(&[]), None);
    // Two items in perfect agreement: [1, 1], [3, 3]. Item variances 2 and 2 (deviations
    // +-1, 2 / 1), totals 2 and 6, variance 8; alpha = 2 (1 - 4 / 8) = 1.
    close_opt(
        "agreeing",
        cronbach_alpha(&[vec![1.0, 1.0], vec![3.0, 3.0]]),
        1.0,
    );
}

/// `SMALL` with `from` replaced by `to` must fail at `key`, the message holding `says`.
fn refused(from: &str, to: &str, key: &str, says: &str) {
    assert!(SMALL.contains(from), "{from}");
    let text = SMALL.replacen(from, to, 1);
    match Questionnaire::parse("bad.toml", &text) {
        Ok(_) => panic!("accepted with {to:?}"),
        Err(e) => {
            assert_eq!(e.file, "bad.toml");
            assert_eq!(e.key, key, "{e}");
            assert!(e.message.contains(says), "{e}");
        }
    }
}

#[test]
fn bad_files_name_the_key() {
    refused(
        "id = \"d\"\nscale = \"content\"",
        "id = \"d\"\nscale = \"contents\"",
        "items[3].scale",
        "'contents' is not one of the [[scales]] (face, content)",
    );
    refused(
        "id = \"b\"",
        "id = \"a\"",
        "items[1].id",
        "already the id of items[0]",
    );
    refused(
        "id = \"content\"",
        "id = \"face\"",
        "scales[1].id",
        "already the id of scales[0]",
    );
    refused("max = 5", "max = 1", "rating.max", "above rating.min");
    refused("max = 5", "max = 0.5", "rating.max", "above rating.min");
    refused("max = 5", "max = inf", "rating.max", "finite");
    refused("id = \"small\"", "id = \"Small one\"", "id", "lowercase");
    refused(
        "text = \"Item c\"",
        "text = \"  \"",
        "items[2].text",
        "empty",
    );
    refused(
        "min_label = \"Poor\"",
        "min_label = \"\"",
        "rating.min_label",
        "empty",
    );
    refused(
        "scale = \"content\"",
        "scale = \"face\"",
        "scales[1]",
        "no item is on scale 'content'",
    );
    // An unknown key, at any level, is named by the TOML reader.
    refused(
        "text = \"Item a\"",
        "text = \"Item a\"\ncolour = \"red\"",
        "toml",
        "colour",
    );
    refused(
        "paper = \"ours\"",
        "paper = \"ours\"\nauthor = \"me\"",
        "toml",
        "author",
    );
    refused("min = 1", "min = 1\nmiddle = 3", "toml", "middle");
    // A missing table or key is named too.
    refused("paper = \"ours\"", "", "toml", "paper");
}

#[test]
fn empty_item_and_scale_lists_are_refused() {
    let Some((head, _)) = SMALL.split_once("[[items]]") else {
        panic!("SMALL has items");
    };
    match Questionnaire::parse("empty.toml", &format!("items = []\n{head}")) {
        Ok(_) => panic!("accepted no items"),
        Err(e) => assert_eq!(e.key, "items", "{e}"),
    }
    let Some((head, _)) = SMALL.split_once("[[scales]]") else {
        panic!("SMALL has scales");
    };
    match Questionnaire::parse("empty.toml", &format!("scales = []\nitems = []\n{head}")) {
        Ok(_) => panic!("accepted no scales"),
        Err(e) => assert_eq!(e.key, "scales", "{e}"),
    }
}

/// The answers of p1 changed by `edit` must be refused at `key`, the message holding `says`.
fn bad_answers(edit: impl Fn(&mut Answers), key: &str, says: &str) {
    let q = small();
    let mut a = data().swap_remove(0);
    assert!(q.check_answers("p1.json", &a).is_ok());
    edit(&mut a);
    match q.check_answers("p1.json", &a) {
        Ok(()) => panic!("accepted {a:?}"),
        Err(e) => {
            assert_eq!(e.file, "p1.json");
            assert_eq!(e.key, key, "{e}");
            assert!(e.message.contains(says), "{e}");
        }
    }
}

#[test]
fn bad_answers_name_the_item() {
    bad_answers(
        |a| {
            a.scores.remove("c");
        },
        "scores.c",
        "no score for item 'c' (\"Item c\")",
    );
    bad_answers(
        |a| {
            a.scores.insert("z".into(), 3.0);
        },
        "scores.z",
        "'z', which is not an item of 'small'",
    );
    bad_answers(
        |a| {
            a.scores.insert("b".into(), 6.0);
        },
        "scores.b",
        "from 1 (Poor) to 5 (Excellent)",
    );
    bad_answers(
        |a| {
            a.scores.insert("b".into(), 0.0);
        },
        "scores.b",
        "scored item 'b' 0",
    );
    bad_answers(
        |a| {
            a.scores.insert("d".into(), f64::NAN);
        },
        "scores.d",
        "scored item 'd' NaN",
    );
    bad_answers(|a| a.group = " ".into(), "group", "empty");
    bad_answers(|a| a.participant = String::new(), "participant", "empty");
    // The ends of the rating are allowed.
    let q = small();
    let ends = answers("e", "g", &[("a", 1.), ("b", 5.), ("c", 1.), ("d", 5.)]);
    assert!(q.check_answers("e.json", &ends).is_ok());
}

#[test]
fn a_report_names_the_answer_set_at_fault() {
    let q = small();
    let mut all = data();
    all[2].scores.insert("b".into(), 9.0);
    match q.report("answers.json", &all) {
        Ok(_) => panic!("accepted a 9"),
        Err(e) => assert_eq!(e.key, "answers[2].scores.b", "{e}"),
    }
    let mut all = data();
    all[3].participant = "p1".into();
    match q.report("answers.json", &all) {
        Ok(_) => panic!("accepted p1 twice"),
        Err(e) => {
            assert_eq!(e.key, "answers[3].participant", "{e}");
            assert!(e.message.contains("answers[0]"), "{e}");
        }
    }
    match q.report("answers.json", &[]) {
        Ok(r) => assert!(r.groups.is_empty()),
        Err(e) => panic!("{e}"),
    }
}

#[test]
fn answers_read_from_json() {
    let text =
        r#"{"participant": "s1", "group": "students", "scores": {"a": 2, "b": 3, "c": 1, "d": 5}}"#;
    let a: Answers = match serde_json::from_str(text) {
        Ok(a) => a,
        Err(e) => panic!("{e}"),
    };
    assert!(small().check_answers("s1.json", &a).is_ok());
    let extra = text.replace("\"group\"", "\"cohort\": 1, \"group\"");
    assert!(serde_json::from_str::<Answers>(&extra).is_err());
}
