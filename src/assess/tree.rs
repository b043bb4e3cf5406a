//! Assessment as data: a procedure's hierarchy of metrics (the dissection paper's Table 1 is the
//! model: surgical skill -> efficiency, safety, quality -> their leaves), read from a TOML
//! file (`assets/assessment/<procedure>.toml`). Every leaf is bound to one of the measures a
//! session reports, says whether lower or higher is better, and is normalised between a
//! novice's and an expert's reference values; every node has a weight among its siblings
//! (the paper's Fig. 13). Scoring reads only the session's report, so an old recording is
//! scored again with another tree by replaying it.
//!
//! The file:
//!
//! ```toml
//! procedure = "sandbox"      # the registry name the tree belongs to
//! version = 1                # the tree's own version, kept with every score
//! title = "Surgical skill"   # the root's name, for people
//!
//! [[node]]
//! path = "efficiency"        # an inner node: no metric, its children follow its path
//! weight = 1
//!
//! [[node]]
//! path = "efficiency/time"
//! metric = "completion_time_s"
//! better = "lower"           # or "higher"
//! expert = 5.0               # scores 100 at or beyond this value
//! novice = 20.0              # scores 0 at or beyond this value
//! weight = 2
//! missing = "novice"         # a measure not taken scores 0 ("novice") or is left out ("skip")
//! ```
//!
//! The optional `[levels]` table sets the fuzzy levels of expertise (see [`super::fuzzy`]).

use super::fuzzy::{Levels, Memberships};
use crate::scenario::InputError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Which way a leaf's measure improves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Better {
    Lower,
    Higher,
}

/// What a leaf whose measure was not taken (a completion time of an unfinished task, a
/// ratio with nothing to divide) counts as.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Missing {
    /// As a novice's value: the leaf scores 0.
    #[default]
    Novice,
    /// Left out: its siblings share its weight.
    Skip,
}

/// A leaf's binding to a measure and its normalisation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Leaf {
    /// The measure's name in the session's measures (see [`measures`]).
    pub metric: String,
    pub better: Better,
    /// The expert's and the novice's reference values (100 and 0 points).
    pub expert: f64,
    pub novice: f64,
    pub missing: Missing,
}

/// One node of the tree.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Node {
    /// Its place: the names from the root's child down, joined by `/`.
    pub path: String,
    /// Its weight among its siblings (they are normalised to sum to one).
    pub weight: f64,
    /// What it means, for people (may be empty).
    pub text: String,
    /// Its parent's index (none: a child of the root).
    #[serde(skip)]
    pub parent: Option<usize>,
    /// Its children's indices, in the file's order.
    #[serde(skip)]
    pub children: Vec<usize>,
    /// Set for a leaf.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub leaf: Option<Leaf>,
}

/// A checked tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Tree {
    pub procedure: String,
    pub version: u32,
    pub title: String,
    /// In the file's order; a parent always comes before its children.
    pub nodes: Vec<Node>,
    /// The root's children, in order.
    pub top: Vec<usize>,
    pub levels: Levels,
    /// The dynamic assessment's rules (see [`super::rules`]).
    pub rules: Vec<super::rules::Rule>,
    /// FNV-1a of the file's text, so a score names the exact tree it was made with.
    pub digest: u64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileNode {
    path: String,
    weight: f64,
    #[serde(default)]
    text: String,
    metric: Option<String>,
    better: Option<Better>,
    expert: Option<f64>,
    novice: Option<f64>,
    missing: Option<Missing>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    procedure: String,
    version: u32,
    title: String,
    #[serde(default)]
    node: Vec<FileNode>,
    levels: Option<toml::Table>,
    #[serde(default)]
    rule: Vec<super::rules::FileRule>,
}

/// FNV-1a over bytes.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

impl Tree {
    /// Reads and checks a tree (`file` names it in errors).
    pub fn parse(file: &str, text: &str) -> Result<Tree, InputError> {
        let f: File = toml::from_str(text).map_err(|e| InputError::toml(file, &e))?;
        if f.node.is_empty() {
            return Err(InputError::new(
                file,
                "node",
                "a tree needs at least one [[node]] (a leaf bound to a measure)",
            ));
        }
        let mut nodes: Vec<Node> = Vec::with_capacity(f.node.len());
        let mut by_path: BTreeMap<String, usize> = BTreeMap::new();
        let mut top = Vec::new();
        for (k, n) in f.node.into_iter().enumerate() {
            let key = format!("node[{k}] ({})", n.path);
            let bad = |message: String| InputError::new(file, &key, message);
            if n.path.is_empty() || n.path.split('/').any(|s| s.trim().is_empty()) {
                return Err(bad(
                    "'path' must be names joined by '/', none empty (\"safety/forces\")".into(),
                ));
            }
            if by_path.contains_key(&n.path) {
                return Err(bad("this path is listed twice".into()));
            }
            if !(n.weight.is_finite() && n.weight >= 0.0) {
                return Err(bad(format!(
                    "'weight' must be a finite number >= 0, not {}",
                    n.weight
                )));
            }
            let parent = match n.path.rsplit_once('/') {
                None => None,
                Some((up, _)) => match by_path.get(up) {
                    Some(&p) if nodes[p].leaf.is_some() => {
                        return Err(bad(format!(
                            "its parent '{up}' is a leaf (bound to a measure); a leaf has no children"
                        )));
                    }
                    Some(&p) => Some(p),
                    None => {
                        return Err(bad(format!(
                            "its parent '{up}' must be listed before it as a [[node]]"
                        )));
                    }
                },
            };
            let leaf = match n.metric.clone() {
                None => {
                    if n.better.is_some()
                        || n.expert.is_some()
                        || n.novice.is_some()
                        || n.missing.is_some()
                    {
                        return Err(bad(
                            "'better', 'expert', 'novice' and 'missing' belong to a leaf, which \
                             names its 'metric'"
                                .into(),
                        ));
                    }
                    None
                }
                Some(metric) => Some(leaf_of(metric, &n, &bad)?),
            };
            let index = nodes.len();
            match parent {
                Some(p) => nodes[p].children.push(index),
                None => top.push(index),
            }
            by_path.insert(n.path.clone(), index);
            nodes.push(Node {
                path: n.path,
                weight: n.weight,
                text: n.text,
                parent,
                children: Vec::new(),
                leaf,
            });
        }
        for n in &nodes {
            if n.leaf.is_none() && n.children.is_empty() {
                return Err(InputError::new(
                    file,
                    &format!("node ({})", n.path),
                    "an inner node (no 'metric') needs children; a leaf names its 'metric'",
                ));
            }
        }
        check_weights(file, &nodes, &top)?;
        let levels = match &f.levels {
            None => Levels::default(),
            Some(t) => Levels::parse(file, t)?,
        };
        let rules = super::rules::parse(file, f.rule)?;
        Ok(Tree {
            rules,
            procedure: f.procedure,
            version: f.version,
            title: f.title,
            nodes,
            top,
            levels,
            digest: fnv1a(text.as_bytes()),
        })
    }

    /// The leaves' measures, in the file's order.
    pub fn metrics(&self) -> impl Iterator<Item = &str> {
        self.nodes
            .iter()
            .filter_map(|n| n.leaf.as_ref().map(|l| l.metric.as_str()))
    }

    /// Checks that every leaf's measure is one the procedure reports (`known`: the names of
    /// [`measures`] of a report of it).
    pub fn check_measures(&self, file: &str, known: &[String]) -> Result<(), InputError> {
        for n in &self.nodes {
            if let Some(l) = &n.leaf
                && !known.iter().any(|k| k == &l.metric)
            {
                return Err(self.unknown(
                    file,
                    &format!("node ({}).metric", n.path),
                    &l.metric,
                    known,
                ));
            }
        }
        for r in &self.rules {
            if !known.iter().any(|k| k == &r.metric) {
                return Err(self.unknown(
                    file,
                    &format!("rule ({}).metric", r.id),
                    &r.metric,
                    known,
                ));
            }
        }
        Ok(())
    }

    fn unknown(&self, file: &str, key: &str, metric: &str, known: &[String]) -> InputError {
        InputError::new(
            file,
            key,
            format!(
                "'{metric}' is not a measure {} reports; it reports: {}",
                self.procedure,
                known.join(", ")
            ),
        )
    }

    /// Scores a session's measures.
    pub fn score(&self, measures: &BTreeMap<String, Option<f64>>) -> Assessment {
        let mut scores: Vec<Option<f64>> = vec![None; self.nodes.len()];
        let mut values: Vec<Option<f64>> = vec![None; self.nodes.len()];
        // Children come after their parents: score from the back.
        for i in (0..self.nodes.len()).rev() {
            let n = &self.nodes[i];
            scores[i] = match &n.leaf {
                Some(l) => {
                    let v = measures.get(&l.metric).copied().flatten();
                    values[i] = v;
                    match (v, l.missing) {
                        (Some(v), _) => Some(normalise(l, v)),
                        (None, Missing::Novice) => Some(0.0),
                        (None, Missing::Skip) => None,
                    }
                }
                None => weighted(&self.nodes, &n.children, &scores),
            };
        }
        let total = weighted(&self.nodes, &self.top, &scores).unwrap_or(0.0);
        let grades = self
            .top
            .iter()
            .map(|&i| Grade {
                path: self.nodes[i].path.clone(),
                score: scores[i],
                memberships: scores[i].map(|s| self.levels.memberships(s)),
            })
            .collect();
        let memberships = self.levels.memberships(total);
        Assessment {
            tree: self.procedure.clone(),
            tree_version: self.version,
            tree_digest: format!("{:016x}", self.digest),
            title: self.title.clone(),
            score: total,
            level: self.levels.level_of(&memberships).to_string(),
            memberships,
            grades,
            nodes: self
                .nodes
                .iter()
                .enumerate()
                .map(|(i, n)| Scored {
                    path: n.path.clone(),
                    weight: share(&self.nodes, i, &scores),
                    metric: n.leaf.as_ref().map(|l| l.metric.clone()),
                    value: values[i],
                    expert: n.leaf.as_ref().map(|l| l.expert),
                    novice: n.leaf.as_ref().map(|l| l.novice),
                    score: scores[i],
                })
                .collect(),
        }
    }
}

fn leaf_of(
    metric: String,
    n: &FileNode,
    bad: &dyn Fn(String) -> InputError,
) -> Result<Leaf, InputError> {
    let (Some(better), Some(expert), Some(novice)) = (n.better, n.expert, n.novice) else {
        return Err(bad(
            "a leaf needs 'better' (\"lower\" or \"higher\"), 'expert' and 'novice'".into(),
        ));
    };
    if !(expert.is_finite() && novice.is_finite()) {
        return Err(bad("'expert' and 'novice' must be finite numbers".into()));
    }
    let right_way = match better {
        Better::Lower => expert < novice,
        Better::Higher => expert > novice,
    };
    if !right_way {
        return Err(bad(format!(
            "with better = \"{}\" the expert's value must be {} the novice's (expert {expert}, \
             novice {novice})",
            if better == Better::Lower {
                "lower"
            } else {
                "higher"
            },
            if better == Better::Lower {
                "below"
            } else {
                "above"
            },
        )));
    }
    Ok(Leaf {
        metric,
        better,
        expert,
        novice,
        missing: n.missing.unwrap_or_default(),
    })
}

/// Every set of siblings must have a positive weight in all.
fn check_weights(file: &str, nodes: &[Node], top: &[usize]) -> Result<(), InputError> {
    let sum = |set: &[usize]| set.iter().map(|&i| nodes[i].weight).sum::<f64>();
    if sum(top) <= 0.0 {
        return Err(InputError::new(
            file,
            "node",
            "the root's children weigh nothing in all: give one a weight above 0",
        ));
    }
    for n in nodes {
        if !n.children.is_empty() && sum(&n.children) <= 0.0 {
            return Err(InputError::new(
                file,
                &format!("node ({})", n.path),
                "its children weigh nothing in all: give one a weight above 0",
            ));
        }
    }
    Ok(())
}

/// A leaf's points, 0-100: linear from the novice's value (0) to the expert's (100), held
/// beyond them.
pub fn normalise(l: &Leaf, v: f64) -> f64 {
    (100.0 * (v - l.novice) / (l.expert - l.novice)).clamp(0.0, 100.0)
}

/// The weighted mean of the scored among `set` (none if none is scored or they weigh
/// nothing).
fn weighted(nodes: &[Node], set: &[usize], scores: &[Option<f64>]) -> Option<f64> {
    let (mut sum, mut weight) = (0.0, 0.0);
    for &i in set {
        if let Some(s) = scores[i] {
            sum += nodes[i].weight * s;
            weight += nodes[i].weight;
        }
    }
    (weight > 0.0).then(|| sum / weight)
}

/// Node `i`'s share of its parent's score: its weight over its scored siblings' (0 when it
/// is left out).
fn share(nodes: &[Node], i: usize, scores: &[Option<f64>]) -> f64 {
    if scores[i].is_none() {
        return 0.0;
    }
    let siblings: Vec<usize> = match nodes[i].parent {
        Some(p) => nodes[p].children.clone(),
        None => nodes
            .iter()
            .enumerate()
            .filter(|(_, n)| n.parent.is_none())
            .map(|(k, _)| k)
            .collect(),
    };
    let all: f64 = siblings
        .iter()
        .filter(|&&k| scores[k].is_some())
        .map(|&k| nodes[k].weight)
        .sum();
    if all > 0.0 {
        nodes[i].weight / all
    } else {
        0.0
    }
}

/// A grade (a child of the root) with its fuzzy levels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Grade {
    pub path: String,
    pub score: Option<f64>,
    pub memberships: Option<Memberships>,
}

/// One node's part of a score.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Scored {
    pub path: String,
    /// Its share of its parent's score as scored (its siblings' left-out leaves excluded).
    pub weight: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub metric: Option<String>,
    /// The measure's value (leaves; none when not taken).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub value: Option<f64>,
    /// The leaf's expert and novice references (100 and 0 points).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub expert: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub novice: Option<f64>,
    /// 0-100; none when left out.
    pub score: Option<f64>,
}

/// A session scored by a tree: the report's `assessment`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Assessment {
    /// The tree's procedure, version and the digest of its file.
    pub tree: String,
    pub tree_version: u32,
    pub tree_digest: String,
    pub title: String,
    /// The weighted score, 0-100.
    pub score: f64,
    /// The level of expertise with the highest membership, and every level's membership.
    pub level: String,
    pub memberships: Memberships,
    /// The root's children with their own levels.
    pub grades: Vec<Grade>,
    /// Every node as scored, in the file's order.
    pub nodes: Vec<Scored>,
}

/// The measures a session's report offers a tree: each number or boolean (1 or 0) of the
/// procedure's metrics by its key (null: not taken), a list's length as `<key>.count`, an
/// object's numbers as `<key>.<inner>`, and the session's own: `session.completed` (1 or 0),
/// `session.errors`, `session.steps_fraction` (task steps done over the task's steps) and
/// `session.simulated_s`.
pub fn measures(
    metrics: &serde_json::Value,
    completed: bool,
    errors: u32,
    steps_done: usize,
    steps: usize,
    simulated_s: f64,
) -> BTreeMap<String, Option<f64>> {
    let mut out = BTreeMap::new();
    if let Some(obj) = metrics.as_object() {
        for (k, v) in obj {
            flatten(k, v, &mut out, 1);
        }
    }
    out.insert(
        "session.completed".into(),
        Some(f64::from(u8::from(completed))),
    );
    out.insert("session.errors".into(), Some(f64::from(errors)));
    out.insert(
        "session.steps_fraction".into(),
        Some(if steps == 0 {
            1.0
        } else {
            steps_done.min(steps) as f64 / steps as f64
        }),
    );
    out.insert("session.simulated_s".into(), Some(simulated_s));
    out
}

fn flatten(key: &str, v: &serde_json::Value, out: &mut BTreeMap<String, Option<f64>>, depth: u8) {
    use serde_json::Value;
    match v {
        Value::Null => {
            out.insert(key.to_string(), None);
        }
        Value::Bool(b) => {
            out.insert(key.to_string(), Some(f64::from(u8::from(*b))));
        }
        Value::Number(n) => {
            out.insert(key.to_string(), n.as_f64().filter(|x| x.is_finite()));
        }
        Value::Array(a) => {
            out.insert(format!("{key}.count"), Some(a.len() as f64));
        }
        Value::Object(o) if depth > 0 => {
            for (k, inner) in o {
                flatten(&format!("{key}.{k}"), inner, out, depth - 1);
            }
        }
        Value::Object(_) | Value::String(_) => {}
    }
}
