//! References from data: a tree's leaves set from two groups' sessions (experts and novices),
//! with the construct-validity table an educator publishes (`vesalius records calibrate`).
//!
//! Each metric is tested with the Mann-Whitney U test (two-sided); it separates the groups
//! when p < 0.05 and the experts' values lie the better way. The rule: where a leaf's measure
//! separates the groups, its expert reference becomes the median of the expert group's values
//! and its novice reference the novice group's median (4 significant digits). Where it does
//! not (the groups overlap, or made none of the errors it counts), the data cannot say where
//! an expert and a novice stand: the leaf keeps its references and the table says so. A
//! measure not taken where the leaf counts that as a novice's value (`missing = "novice"`: a
//! completion time of a task not completed) stands as the worst value either group took, in a
//! group that took it at least once.

use super::stats::{self, MannWhitney, Spread};
use super::tree::{Better, Tree};
use crate::scenario::InputError;
use serde::Serialize;
use std::collections::BTreeMap;

/// A session's measures as its stored report gives them: the procedure's metrics, the
/// session's own (completed, errors, steps fraction with `steps` task steps, simulated
/// time) and the motion analysis (`motion.<key>`).
pub fn report_measures(report: &serde_json::Value, steps: usize) -> BTreeMap<String, Option<f64>> {
    let metrics = report.get("metrics").cloned().unwrap_or_default();
    let steps_done = metrics
        .get("steps_done")
        .and_then(serde_json::Value::as_array)
        .map_or(0, Vec::len);
    let mut m = super::tree::measures(
        &metrics,
        report.get("completed").and_then(serde_json::Value::as_bool) == Some(true),
        report
            .get("errors")
            .and_then(serde_json::Value::as_u64)
            .map_or(0, |e| u32::try_from(e).unwrap_or(u32::MAX)),
        steps_done,
        steps,
        report
            .get("simulated_s")
            .and_then(serde_json::Value::as_f64)
            .unwrap_or(0.0),
    );
    if let Some(o) = report.get("motion").and_then(serde_json::Value::as_object) {
        for (k, v) in o {
            m.insert(format!("motion.{k}"), v.as_f64().filter(|x| x.is_finite()));
        }
    }
    m
}

/// One metric's row of the validation table.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    /// The leaf's path, or `score` for the whole tree's score.
    pub path: String,
    pub metric: String,
    pub better: Better,
    /// Each group's spread of values (none: no session took the measure).
    pub expert: Option<Spread>,
    pub novice: Option<Spread>,
    /// The test of experts against novices (U is the experts').
    pub test: Option<MannWhitney>,
    /// The effect size oriented so that 1 is every expert better than every novice (the
    /// rank-biserial correlation, sign turned for `better = "lower"`).
    pub effect: Option<f64>,
    /// p < [`stats::ALPHA`] with the experts the better way.
    pub separates: bool,
    /// The references before and after (expert, novice).
    pub was: Option<(f64, f64)>,
    pub now: Option<(f64, f64)>,
    /// Why the references were kept, where they were.
    pub note: String,
}

/// What calibrating a tree gave.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Calibration {
    pub procedure: String,
    pub expert_group: String,
    pub novice_group: String,
    pub expert_sessions: usize,
    pub novice_sessions: usize,
    /// One row per leaf (file order), then the calibrated tree's score.
    pub rows: Vec<Row>,
    /// The calibrated tree's file text.
    #[serde(skip)]
    pub tree_text: String,
}

/// A reference value written with 4 significant digits (so a tree reads as people write it).
pub fn rounded(v: f64) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let digits = 3 - v.abs().log10().floor() as i32;
    let scale = 10f64.powi(digits);
    (v * scale).round() / scale
}

fn values(sessions: &[BTreeMap<String, Option<f64>>], metric: &str) -> Vec<f64> {
    sessions
        .iter()
        .filter_map(|m| m.get(metric).copied().flatten())
        .filter(|v| v.is_finite())
        .collect()
}

/// A leaf's values in each group, a measure not taken standing as the worst taken (see the
/// module's rule) where the leaf scores it as a novice's.
fn leaf_values(
    leaf: &super::tree::Leaf,
    expert: &[BTreeMap<String, Option<f64>>],
    novice: &[BTreeMap<String, Option<f64>>],
) -> (Vec<f64>, Vec<f64>) {
    let (e, n) = (values(expert, &leaf.metric), values(novice, &leaf.metric));
    if leaf.missing != super::tree::Missing::Novice {
        return (e, n);
    }
    let all = e.iter().chain(&n).copied();
    let worst = match leaf.better {
        Better::Lower => all.fold(None, |w: Option<f64>, v| Some(w.map_or(v, |w| w.max(v)))),
        Better::Higher => all.fold(None, |w: Option<f64>, v| Some(w.map_or(v, |w| w.min(v)))),
    };
    let fill = |taken: Vec<f64>, of: usize| match worst {
        Some(w) if !taken.is_empty() => {
            let mut v = taken;
            v.resize(of, w);
            v
        }
        _ => taken,
    };
    (fill(e, expert.len()), fill(n, novice.len()))
}

fn compare(
    path: &str,
    metric: &str,
    better: Better,
    expert: &[f64],
    novice: &[f64],
) -> (Row, Option<(f64, f64)>) {
    let (e, n) = (Spread::of(expert), Spread::of(novice));
    let test = stats::mann_whitney(expert, novice);
    let sign = if better == Better::Lower { -1.0 } else { 1.0 };
    let effect = test.map(|t| sign * t.rank_biserial);
    let separates =
        test.is_some_and(|t| stats::separates(&t, stats::ALPHA)) && effect.is_some_and(|x| x > 0.0);
    let medians = match (e, n) {
        (Some(e), Some(n)) if separates => {
            let (x, y) = (rounded(e.median), rounded(n.median));
            let right_way = match better {
                Better::Lower => x < y,
                Better::Higher => x > y,
            };
            right_way.then_some((x, y))
        }
        _ => None,
    };
    let row = Row {
        path: path.to_string(),
        metric: metric.to_string(),
        better,
        expert: e,
        novice: n,
        test,
        effect,
        separates,
        was: None,
        now: None,
        note: String::new(),
    };
    (row, medians)
}

/// Calibrates `tree` (its file's `text`, `file` naming it in errors) from the measures of the
/// expert and the novice sessions.
pub fn calibrate(
    tree: &Tree,
    file: &str,
    text: &str,
    groups: (&str, &str),
    expert: &[BTreeMap<String, Option<f64>>],
    novice: &[BTreeMap<String, Option<f64>>],
) -> Result<Calibration, InputError> {
    if expert.is_empty() || novice.is_empty() {
        return Err(InputError::new(
            file,
            "sessions",
            format!(
                "calibrating needs sessions of both groups: {} of '{}', {} of '{}' found for {}",
                expert.len(),
                groups.0,
                novice.len(),
                groups.1,
                tree.procedure
            ),
        ));
    }
    let mut rows = Vec::new();
    let mut refs: BTreeMap<String, (f64, f64)> = BTreeMap::new();
    for n in &tree.nodes {
        let Some(l) = &n.leaf else { continue };
        let (e, v) = leaf_values(l, expert, novice);
        let (mut row, medians) = compare(&n.path, &l.metric, l.better, &e, &v);
        row.was = Some((l.expert, l.novice));
        match medians {
            Some(m) => {
                refs.insert(n.path.clone(), m);
                row.now = Some(m);
            }
            None => {
                row.now = row.was;
                row.note = if row.expert.is_none() || row.novice.is_none() {
                    "a group never took this measure: references kept".into()
                } else {
                    "does not separate the groups: references kept".into()
                };
            }
        }
        rows.push(row);
    }
    let tree_text = with_references(text, &refs, tree.version + 1);
    let calibrated = Tree::parse(file, &tree_text)?;
    let score = |s: &BTreeMap<String, Option<f64>>| calibrated.score(s).score;
    let (se, sn): (Vec<f64>, Vec<f64>) = (
        expert.iter().map(score).collect(),
        novice.iter().map(score).collect(),
    );
    let (mut total, _) = compare("score", "score", Better::Higher, &se, &sn);
    total.note = "the calibrated tree's score".into();
    rows.push(total);
    Ok(Calibration {
        procedure: tree.procedure.clone(),
        expert_group: groups.0.to_string(),
        novice_group: groups.1.to_string(),
        expert_sessions: expert.len(),
        novice_sessions: novice.len(),
        rows,
        tree_text,
    })
}

/// `text` with each listed node's `expert` and `novice` lines set and `version` set, every
/// other line (comments included) as it was.
pub fn with_references(text: &str, refs: &BTreeMap<String, (f64, f64)>, version: u32) -> String {
    let mut out = String::with_capacity(text.len());
    let mut node: Option<String> = None;
    let (mut in_node, mut top) = (false, true);
    for line in text.lines() {
        let t = line.trim_start();
        if t.starts_with('[') {
            in_node = t.starts_with("[[node]]");
            node = None;
            top = false;
        }
        let key = t.split('=').next().unwrap_or("").trim();
        let value = t.split_once('=').map(|(_, v)| v.trim());
        let replaced = match (key, value) {
            ("version", Some(_)) if top => Some(format!("version = {version}")),
            ("path", Some(v)) if in_node => {
                node = v
                    .split('#')
                    .next()
                    .map(|s| s.trim().trim_matches('"').to_string());
                None
            }
            ("expert", Some(_)) if in_node => node
                .as_ref()
                .and_then(|n| refs.get(n))
                .map(|r| format!("expert = {}", r.0)),
            ("novice", Some(_)) if in_node => node
                .as_ref()
                .and_then(|n| refs.get(n))
                .map(|r| format!("novice = {}", r.1)),
            _ => None,
        };
        out.push_str(replaced.as_deref().unwrap_or(line));
        out.push('\n');
    }
    out
}

#[cfg(test)]
#[path = "calibrate_tests.rs"]
mod tests;
