//! Questionnaires about the simulator itself (face, content and usability validity), read
//! from data (`assets/questionnaires/*.toml`), and their statistics per item and per group of
//! participants. The papers rate their simulators this way (face and content validity
//! scored 0-9 by groups of students and interns, usability criteria scored 1-5); each shipped
//! form names its paper and table. Where the trainee's skill is scored by the assessment
//! tree, these score the trainer, so a study of a new version can be set beside the papers'
//! own.
//!
//! # File format
//!
//! ```toml
//! id = "face-validity"                 # lowercase letters, digits, '_' or '-'
//! title = "Face and content validity of the simulator"
//! paper = "A Low-cost ..."             # the paper the items come from (or "ours")
//! source = "Table 4"                    # optional: where in the paper
//!
//! [rating]                              # every item is scored on this range
//! min = 0                               # a finite number, below max
//! max = 9
//! min_label = "Poor"                    # what the ends mean
//! max_label = "Excellent"
//!
//! [[scales]]                            # one or more groups of items, each summed into a
//! id = "face"                           # participant's total for Cronbach's alpha
//! title = "Face validity"
//!
//! [[items]]                             # one or more, in the order they are asked
//! id = "realistic_graphics"             # unique in the file
//! scale = "face"                        # one of the [[scales]] ids
//! text = "Realistic graphics"           # the wording put to the participant
//! ```
//!
//! Unknown keys are refused, as are duplicate ids, an item on an unknown scale, a scale with
//! no item, an empty item list and `min >= max`; every error names the file and the key
//! (`items[3].scale`) and says what is expected.
//!
//! # Answers and statistics
//!
//! [`Answers`] are one participant's: an id, a group (such as "students" or "interns") and a
//! score per item id. [`Questionnaire::report`] checks every participant's answers and gives,
//! per group (sorted by name): per item (in file order) the [`Summary`] of its scores, and
//! per scale the summary of each participant's mean over the scale's items and Cronbach's
//! alpha. Scores are in the rating's units; they have no physical unit.

use crate::scenario::InputError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Where the shipped questionnaires are, relative to the repository root.
pub const DIR: &str = "assets/questionnaires";

/// A questionnaire: its items, the scales they belong to and the range they are scored on.
/// Build it with [`Questionnaire::parse`], which checks it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Questionnaire {
    /// Short name, as file names and reports use it.
    pub id: String,
    /// What it measures, for people.
    pub title: String,
    /// The paper the items are taken from.
    pub paper: String,
    /// Where in the paper (a table, a section); may be empty.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub source: String,
    /// The range every item is scored on.
    pub rating: Rating,
    /// The groups of items (face validity, content validity...), in file order.
    pub scales: Vec<Scale>,
    /// The items, in the order they are asked.
    pub items: Vec<Item>,
}

/// The range every item is scored on, ends included, and what the ends mean.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rating {
    /// The lowest score.
    pub min: f64,
    /// The highest score.
    pub max: f64,
    /// What the lowest score means ("Poor").
    pub min_label: String,
    /// What the highest score means ("Excellent").
    pub max_label: String,
}

/// A group of items whose scores are summed for a participant's total on it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scale {
    /// Short name, as items refer to it.
    pub id: String,
    /// What it measures, for people.
    pub title: String,
}

/// One question or criterion.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Item {
    /// Short name, as answers refer to it; unique in the questionnaire.
    pub id: String,
    /// The [`Scale`] it belongs to.
    pub scale: String,
    /// The wording put to the participant.
    pub text: String,
}

/// One participant's answers to a questionnaire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Answers {
    /// Who answered (unique among the answers of one report).
    pub participant: String,
    /// The group the participant is reported in ("students", "interns").
    pub group: String,
    /// A score per item id, on the questionnaire's rating.
    pub scores: BTreeMap<String, f64>,
}

/// Descriptive statistics of some scores.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// How many scores.
    pub n: usize,
    /// Arithmetic mean.
    pub mean: f64,
    /// Sample standard deviation (divisor n - 1); `None` for fewer than two scores.
    pub sd: Option<f64>,
    /// Median (the 0.5 quantile, see [`quantile`]).
    pub median: f64,
    /// First quartile (the 0.25 quantile, see [`quantile`]).
    pub q1: f64,
    /// Third quartile (the 0.75 quantile, see [`quantile`]).
    pub q3: f64,
    /// Interquartile range, `q3 - q1`.
    pub iqr: f64,
    /// Lowest score.
    pub min: f64,
    /// Highest score.
    pub max: f64,
}

/// One item's statistics in one group.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ItemStats {
    /// The item's id.
    pub item: String,
    /// The scale it belongs to.
    pub scale: String,
    /// Its scores' statistics.
    pub summary: Summary,
}

/// One scale's statistics in one group.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ScaleStats {
    /// The scale's id.
    pub scale: String,
    /// How many items it has.
    pub k: usize,
    /// Statistics of each participant's mean over the scale's items (in the rating's units,
    /// so they read beside the items').
    pub summary: Summary,
    /// Cronbach's alpha of the scale's items (see [`cronbach_alpha`]); `None` for fewer than
    /// two items or two participants, or when every participant has the same total.
    pub alpha: Option<f64>,
}

/// The statistics of one group of participants.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupStats {
    /// The group's name.
    pub group: String,
    /// How many participants answered in it.
    pub n: usize,
    /// Per item, in file order.
    pub items: Vec<ItemStats>,
    /// Per scale, in file order.
    pub scales: Vec<ScaleStats>,
}

/// A questionnaire's statistics, per group of participants.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// The questionnaire's id.
    pub questionnaire: String,
    /// Per group, sorted by name.
    pub groups: Vec<GroupStats>,
}

/// That `id` is a short name: not empty, of lowercase ASCII letters, digits, '_' or '-'.
fn is_id(id: &str) -> bool {
    !id.is_empty()
        && id
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_' || c == '-')
}

const ID_RULE: &str = "lowercase letters, digits, '_' or '-', not empty";

/// An error unless `id` is a short name.
fn check_id(file: &str, key: &str, id: &str) -> Result<(), InputError> {
    if is_id(id) {
        Ok(())
    } else {
        Err(InputError::new(
            file,
            key,
            format!("'{id}' must be {ID_RULE}"),
        ))
    }
}

/// An error if `text` is empty or blank.
fn check_text(file: &str, key: &str, text: &str) -> Result<(), InputError> {
    if text.trim().is_empty() {
        Err(InputError::new(file, key, "must not be empty"))
    } else {
        Ok(())
    }
}

impl Questionnaire {
    /// Reads and checks a questionnaire (`file` names it in errors).
    pub fn parse(file: &str, text: &str) -> Result<Questionnaire, InputError> {
        let q: Questionnaire = toml::from_str(text).map_err(|e| InputError::toml(file, &e))?;
        check_id(file, "id", &q.id)?;
        check_text(file, "title", &q.title)?;
        check_text(file, "paper", &q.paper)?;
        let r = &q.rating;
        for (key, v) in [("rating.min", r.min), ("rating.max", r.max)] {
            if !v.is_finite() {
                return Err(InputError::new(
                    file,
                    key,
                    format!("must be a finite number, not {v}"),
                ));
            }
        }
        if r.min >= r.max {
            return Err(InputError::new(
                file,
                "rating.max",
                format!("must be above rating.min ({}), not {}", r.min, r.max),
            ));
        }
        check_text(file, "rating.min_label", &r.min_label)?;
        check_text(file, "rating.max_label", &r.max_label)?;
        if q.scales.is_empty() {
            return Err(InputError::new(
                file,
                "scales",
                "a questionnaire needs at least one [[scales]] (an id and a title)",
            ));
        }
        for (k, s) in q.scales.iter().enumerate() {
            check_id(file, &format!("scales[{k}].id"), &s.id)?;
            check_text(file, &format!("scales[{k}].title"), &s.title)?;
            if let Some(j) = q.scales[..k].iter().position(|o| o.id == s.id) {
                return Err(InputError::new(
                    file,
                    &format!("scales[{k}].id"),
                    format!("'{}' is already the id of scales[{j}]", s.id),
                ));
            }
        }
        if q.items.is_empty() {
            return Err(InputError::new(
                file,
                "items",
                "a questionnaire needs at least one [[items]] (an id, a scale and a text)",
            ));
        }
        for (k, item) in q.items.iter().enumerate() {
            check_id(file, &format!("items[{k}].id"), &item.id)?;
            if let Some(j) = q.items[..k].iter().position(|o| o.id == item.id) {
                return Err(InputError::new(
                    file,
                    &format!("items[{k}].id"),
                    format!("'{}' is already the id of items[{j}]", item.id),
                ));
            }
            if !q.scales.iter().any(|s| s.id == item.scale) {
                return Err(InputError::new(
                    file,
                    &format!("items[{k}].scale"),
                    format!(
                        "'{}' is not one of the [[scales]] ({})",
                        item.scale,
                        q.scale_ids().join(", ")
                    ),
                ));
            }
            check_text(file, &format!("items[{k}].text"), &item.text)?;
        }
        for (k, s) in q.scales.iter().enumerate() {
            if !q.items.iter().any(|i| i.scale == s.id) {
                return Err(InputError::new(
                    file,
                    &format!("scales[{k}]"),
                    format!("no item is on scale '{}'; give it items or remove it", s.id),
                ));
            }
        }
        Ok(q)
    }

    /// Reads and checks a questionnaire file.
    pub fn load_file(path: &std::path::Path) -> Result<Questionnaire, InputError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| InputError::new(&file, "file", format!("cannot read: {e}")))?;
        Self::parse(&file, &text)
    }

    /// The scales' ids, in file order.
    fn scale_ids(&self) -> Vec<&str> {
        self.scales.iter().map(|s| s.id.as_str()).collect()
    }

    /// The items of scale `scale`, in file order.
    pub fn items_of<'a>(&'a self, scale: &'a str) -> impl Iterator<Item = &'a Item> + 'a {
        self.items.iter().filter(move |i| i.scale == scale)
    }

    /// Refuses `answers` that lack a score for an item, score an item the questionnaire does
    /// not have, or hold a score that is not a finite number within the rating; also a blank
    /// participant or group. The error's key names the item (`scores.<item id>`).
    pub fn check_answers(&self, file: &str, answers: &Answers) -> Result<(), InputError> {
        self.check_answers_at(file, "", answers)
    }

    /// [`Self::check_answers`] with `prefix` before every key (`answers[2].`).
    fn check_answers_at(&self, file: &str, prefix: &str, a: &Answers) -> Result<(), InputError> {
        check_text(file, &format!("{prefix}participant"), &a.participant)?;
        check_text(file, &format!("{prefix}group"), &a.group)?;
        let (min, max) = (self.rating.min, self.rating.max);
        for item in &self.items {
            let key = format!("{prefix}scores.{}", item.id);
            match a.scores.get(&item.id) {
                None => {
                    return Err(InputError::new(
                        file,
                        &key,
                        format!(
                            "participant '{}' has no score for item '{}' (\"{}\")",
                            a.participant, item.id, item.text
                        ),
                    ));
                }
                Some(&s) if !(s.is_finite() && s >= min && s <= max) => {
                    return Err(InputError::new(
                        file,
                        &key,
                        format!(
                            "participant '{}' scored item '{}' {s}; a score must be a number \
                             from {min} ({}) to {max} ({})",
                            a.participant, item.id, self.rating.min_label, self.rating.max_label
                        ),
                    ));
                }
                Some(_) => {}
            }
        }
        if let Some(id) = a
            .scores
            .keys()
            .find(|id| !self.items.iter().any(|i| &i.id == *id))
        {
            return Err(InputError::new(
                file,
                &format!("{prefix}scores.{id}"),
                format!(
                    "participant '{}' scored '{id}', which is not an item of '{}'",
                    a.participant, self.id
                ),
            ));
        }
        Ok(())
    }

    /// Checks every participant's answers (keys `answers[i]....`, a participant may answer
    /// once) and gives the statistics per group, groups sorted by name. No answers give no
    /// groups.
    pub fn report(&self, file: &str, answers: &[Answers]) -> Result<Report, InputError> {
        let mut seen: BTreeMap<&str, usize> = BTreeMap::new();
        let mut groups: BTreeMap<&str, Vec<&Answers>> = BTreeMap::new();
        for (i, a) in answers.iter().enumerate() {
            let prefix = format!("answers[{i}].");
            self.check_answers_at(file, &prefix, a)?;
            if let Some(j) = seen.insert(a.participant.as_str(), i) {
                return Err(InputError::new(
                    file,
                    &format!("{prefix}participant"),
                    format!(
                        "participant '{}' already answered in answers[{j}]; one set each",
                        a.participant
                    ),
                ));
            }
            groups.entry(a.group.as_str()).or_default().push(a);
        }
        let groups = groups
            .into_iter()
            .map(|(group, members)| self.group_stats(group, &members))
            .collect();
        Ok(Report {
            questionnaire: self.id.clone(),
            groups,
        })
    }

    /// The statistics of one group's (checked) answers.
    fn group_stats(&self, group: &str, members: &[&Answers]) -> GroupStats {
        let items = self
            .items
            .iter()
            .filter_map(|item| {
                let scores: Vec<f64> = members
                    .iter()
                    .filter_map(|a| a.scores.get(&item.id).copied())
                    .collect();
                Some(ItemStats {
                    item: item.id.clone(),
                    scale: item.scale.clone(),
                    summary: Summary::of(&scores)?,
                })
            })
            .collect();
        let scales = self
            .scales
            .iter()
            .filter_map(|scale| {
                let ids: Vec<&str> = self.items_of(&scale.id).map(|i| i.id.as_str()).collect();
                // One row per participant: the scale's item scores, in file order. Answers
                // are checked, so every row is complete; a row that is not is left out.
                let rows: Vec<Vec<f64>> = members
                    .iter()
                    .filter_map(|a| ids.iter().map(|id| a.scores.get(*id).copied()).collect())
                    .collect();
                let means: Vec<f64> = rows
                    .iter()
                    .map(|r| r.iter().sum::<f64>() / ids.len() as f64)
                    .collect();
                Some(ScaleStats {
                    scale: scale.id.clone(),
                    k: ids.len(),
                    summary: Summary::of(&means)?,
                    alpha: cronbach_alpha(&rows),
                })
            })
            .collect();
        GroupStats {
            group: group.to_string(),
            n: members.len(),
            items,
            scales,
        }
    }
}

impl Summary {
    /// The statistics of `scores`; `None` when there are none or one is not finite.
    pub fn of(scores: &[f64]) -> Option<Summary> {
        if scores.is_empty() || scores.iter().any(|s| !s.is_finite()) {
            return None;
        }
        let mut sorted = scores.to_vec();
        sorted.sort_by(f64::total_cmp);
        let q1 = quantile(&sorted, 0.25)?;
        let q3 = quantile(&sorted, 0.75)?;
        Some(Summary {
            n: sorted.len(),
            mean: mean(&sorted)?,
            sd: sample_variance(&sorted).map(f64::sqrt),
            median: quantile(&sorted, 0.5)?,
            q1,
            q3,
            iqr: q3 - q1,
            min: *sorted.first()?,
            max: *sorted.last()?,
        })
    }
}

/// The arithmetic mean; `None` for no values.
pub fn mean(values: &[f64]) -> Option<f64> {
    if values.is_empty() {
        None
    } else {
        Some(values.iter().sum::<f64>() / values.len() as f64)
    }
}

/// The sample variance, the squared deviations from the mean summed and divided by n - 1;
/// `None` for fewer than two values.
pub fn sample_variance(values: &[f64]) -> Option<f64> {
    if values.len() < 2 {
        return None;
    }
    let m = mean(values)?;
    let ss: f64 = values.iter().map(|v| (v - m) * (v - m)).sum();
    Some(ss / (values.len() - 1) as f64)
}

pub use super::stats::quantile;

/// Cronbach's alpha of a scale's items, `rows` one per participant, each the k item scores:
/// alpha = k / (k - 1) (1 - sum of the items' variances / variance of the participants'
/// totals), every variance a sample variance (n - 1). How consistently the items measure
/// one thing: 1 when they agree perfectly, near 0 (or below) when they do not. `None` for
/// fewer than two items or two participants, rows of unequal length, or totals that are all
/// the same (variance 0, to rounding: the ratio is undefined).
pub fn cronbach_alpha(rows: &[Vec<f64>]) -> Option<f64> {
    let k = rows.first()?.len();
    if k < 2 || rows.len() < 2 || rows.iter().any(|r| r.len() != k) {
        return None;
    }
    let mut item_variances = 0.0;
    for j in 0..k {
        let column: Vec<f64> = rows.iter().filter_map(|r| r.get(j).copied()).collect();
        item_variances += sample_variance(&column)?;
    }
    let totals: Vec<f64> = rows.iter().map(|r| r.iter().sum()).collect();
    let total_variance = sample_variance(&totals)?;
    // Equal totals of fractional scores may leave a variance of rounding, not 0.
    let largest = totals.iter().fold(0.0_f64, |m, t| m.max(t.abs()));
    if !(total_variance.is_finite() && total_variance > 1e-12 * largest * largest) {
        return None;
    }
    let k = k as f64;
    Some(k / (k - 1.0) * (1.0 - item_variances / total_variance))
}
