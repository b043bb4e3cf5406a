//! Dynamic assessment (the dissection paper's Fig. 12: the evaluation feeds back to the trainee
//! during the session, a loop): rules in a tree's file that turn the live measures into
//! instructions. Each rule watches one measure and speaks when its condition begins: the
//! measure rising above a threshold, falling below one, or rising at all (a counter of
//! errors going up). The session evaluates them at a fixed simulated interval, so the
//! instructions are the same on every replay; each is an `instruction` event, and the
//! window's panels show them.
//!
//! ```toml
//! [[rule]]
//! id = "slow_near_vulnerable"
//! metric = "max_speed_near_vulnerable_m_per_s"
//! above = 0.05                # or: below = 0.2, or: rises = true
//! say = "Slow down near the ureter"
//! ```

use crate::scenario::InputError;
use serde::Deserialize;
use std::collections::BTreeMap;

/// When a rule speaks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum When {
    /// The measure goes above the threshold.
    Above(f64),
    /// The measure goes below the threshold.
    Below(f64),
    /// The measure goes up (from its last evaluated value).
    Rises,
}

/// One rule.
#[derive(Debug, Clone, PartialEq)]
pub struct Rule {
    pub id: String,
    pub metric: String,
    pub when: When,
    /// The instruction, in words a surgeon uses.
    pub say: String,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct FileRule {
    id: String,
    metric: String,
    above: Option<f64>,
    below: Option<f64>,
    rises: Option<bool>,
    say: String,
}

/// Checks the file's rules (`k`: the rule's place, for errors).
pub(super) fn parse(file: &str, rules: Vec<FileRule>) -> Result<Vec<Rule>, InputError> {
    let mut out: Vec<Rule> = Vec::with_capacity(rules.len());
    for (k, r) in rules.into_iter().enumerate() {
        let key = format!("rule[{k}] ({})", r.id);
        let bad = |m: &str| InputError::new(file, &key, m);
        if r.id.is_empty() || out.iter().any(|o| o.id == r.id) {
            return Err(bad("'id' must be set and not used by another rule"));
        }
        if r.say.trim().is_empty() {
            return Err(bad("'say' must be the instruction the trainee is given"));
        }
        let when = match (r.above, r.below, r.rises) {
            (Some(t), None, None) if t.is_finite() => When::Above(t),
            (None, Some(t), None) if t.is_finite() => When::Below(t),
            (None, None, Some(true)) => When::Rises,
            _ => {
                return Err(bad(
                    "give exactly one of 'above = N', 'below = N' (finite numbers) or \
                     'rises = true'",
                ));
            }
        };
        out.push(Rule {
            id: r.id,
            metric: r.metric,
            when,
            say: r.say,
        });
    }
    Ok(out)
}

/// What a rule saw at its last evaluation.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RuleState {
    held: bool,
    last: Option<f64>,
}

/// Evaluates `rules` on the measures now; returns the rules whose condition began (in the
/// rules' order). A measure not taken holds no condition.
pub fn evaluate<'a>(
    rules: &'a [Rule],
    state: &mut Vec<RuleState>,
    measures: &BTreeMap<String, Option<f64>>,
) -> Vec<&'a Rule> {
    state.resize(rules.len(), RuleState::default());
    let mut spoke = Vec::new();
    for (r, s) in rules.iter().zip(state.iter_mut()) {
        let v = measures.get(&r.metric).copied().flatten();
        let holds = match (r.when, v) {
            (_, None) => false,
            (When::Above(t), Some(v)) => v > t,
            (When::Below(t), Some(v)) => v < t,
            (When::Rises, Some(v)) => {
                s.last.is_some_and(|l| v > l) || (s.last.is_none() && v > 0.0)
            }
        };
        let begins = match r.when {
            // Every rise speaks (each new error), not only the first.
            When::Rises => holds,
            _ => holds && !s.held,
        };
        if begins {
            spoke.push(r);
        }
        s.held = holds;
        if v.is_some() {
            s.last = v;
        }
    }
    spoke
}
