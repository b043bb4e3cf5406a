//! Fuzzy levels of expertise over a weighted score (the dissection paper's method: fuzzy logic
//! over the hierarchy's scores, its Fig. 14b the distribution of levels). Four levels,
//! novice, intermediate, proficient and expert, each a trapezoid over the 0-100 score:
//! membership 0 below `a`, rising linearly to 1 at `b`, 1 up to `c`, falling to 0 at `d`.
//! Neighbouring levels cross (the next level's `a`, `b` are this one's `c`, `d`), so at every
//! score the memberships sum to one: a score between two plateaus belongs partly to both, in
//! proportion to where it lies. The level named is the one of highest membership (at an exact
//! tie, the lower).
//!
//! The defaults, in points:
//!
//! | level | a | b | c | d |
//! |---|---|---|---|---|
//! | novice | 0 | 0 | 40 | 55 |
//! | intermediate | 40 | 55 | 65 | 75 |
//! | proficient | 65 | 75 | 82 | 92 |
//! | expert | 82 | 92 | 100 | 100 |
//!
//! A tree file may set its own in a `[levels]` table: `novice = [0, 0, 40, 55]` and so on.

use crate::scenario::InputError;
use serde::Serialize;

/// Why levels are not a partition of the scores.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum LevelsError {
    #[error("{level}: [a, b, c, d] must rise (a <= b <= c <= d) within 0-100, not {corners:?}")]
    NotRising {
        level: &'static str,
        corners: [f64; 4],
    },
    #[error("the novice's plateau must start at 0 and the expert's end at 100")]
    Ends,
    #[error(
        "{upper} must rise where {lower} falls ({upper}'s a, b = {lower}'s c, d, with c < d), \
         so the memberships sum to one"
    )]
    NoPartition {
        lower: &'static str,
        upper: &'static str,
    },
}

/// The levels' names, lowest first.
pub const LEVELS: [&str; 4] = ["novice", "intermediate", "proficient", "expert"];

/// The four trapezoids `[a, b, c, d]`, lowest level first.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Levels(pub [[f64; 4]; 4]);

impl Default for Levels {
    fn default() -> Self {
        Levels([
            [0.0, 0.0, 40.0, 55.0],
            [40.0, 55.0, 65.0, 75.0],
            [65.0, 75.0, 82.0, 92.0],
            [82.0, 92.0, 100.0, 100.0],
        ])
    }
}

/// Each level's membership, 0-1, in [`LEVELS`]' order.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Memberships {
    pub novice: f64,
    pub intermediate: f64,
    pub proficient: f64,
    pub expert: f64,
}

impl Memberships {
    pub fn as_array(&self) -> [f64; 4] {
        [self.novice, self.intermediate, self.proficient, self.expert]
    }
}

/// One trapezoid's membership at `x`.
fn trapezoid([a, b, c, d]: [f64; 4], x: f64) -> f64 {
    if x < a || x > d {
        0.0
    } else if x < b {
        (x - a) / (b - a)
    } else if x <= c {
        1.0
    } else {
        (d - x) / (d - c)
    }
}

impl Levels {
    /// Reads a `[levels]` table: every level as `[a, b, c, d]`, checked as a partition.
    pub fn parse(file: &str, t: &toml::Table) -> Result<Levels, InputError> {
        let mut out = [[0.0; 4]; 4];
        for key in t.keys() {
            if !LEVELS.contains(&key.as_str()) {
                return Err(InputError::new(
                    file,
                    &format!("levels.{key}"),
                    format!("unknown level; the levels are {}", LEVELS.join(", ")),
                ));
            }
        }
        for (k, name) in LEVELS.iter().enumerate() {
            let key = format!("levels.{name}");
            let v = t.get(*name).ok_or_else(|| {
                InputError::new(file, &key, "missing: give all four levels as [a, b, c, d]")
            })?;
            let nums: Vec<f64> = v
                .as_array()
                .map(|a| {
                    a.iter()
                        .filter_map(|x| x.as_float().or_else(|| x.as_integer().map(|i| i as f64)))
                        .collect()
                })
                .unwrap_or_default();
            if nums.len() != 4 || v.as_array().map(Vec::len) != Some(4) {
                return Err(InputError::new(
                    file,
                    &key,
                    "expected four numbers [a, b, c, d]: membership rises from a to b, is 1 to c, \
                     falls to 0 at d",
                ));
            }
            out[k] = [nums[0], nums[1], nums[2], nums[3]];
        }
        let l = Levels(out);
        l.check()
            .map_err(|e| InputError::new(file, "levels", e.to_string()))?;
        Ok(l)
    }

    /// That the trapezoids are ordered within 0-100, start at 0, end at 100 and cross their
    /// neighbours so the memberships sum to one.
    pub fn check(&self) -> Result<(), LevelsError> {
        for (k, t) in self.0.iter().enumerate() {
            let ordered = t.windows(2).all(|w| w[0] <= w[1]);
            if !ordered || t[0] < 0.0 || t[3] > 100.0 || t.iter().any(|x| !x.is_finite()) {
                return Err(LevelsError::NotRising {
                    level: LEVELS[k],
                    corners: *t,
                });
            }
        }
        if self.0[0][0] != 0.0 || self.0[0][1] != 0.0 || self.0[3][2] != 100.0 {
            return Err(LevelsError::Ends);
        }
        for k in 0..3 {
            let (lo, hi) = (self.0[k], self.0[k + 1]);
            if hi[0] != lo[2] || hi[1] != lo[3] || lo[2] == lo[3] {
                return Err(LevelsError::NoPartition {
                    lower: LEVELS[k],
                    upper: LEVELS[k + 1],
                });
            }
        }
        Ok(())
    }

    /// Every level's membership at a score (clamped to 0-100).
    pub fn memberships(&self, score: f64) -> Memberships {
        let x = score.clamp(0.0, 100.0);
        let m = self.0.map(|t| trapezoid(t, x));
        Memberships {
            novice: m[0],
            intermediate: m[1],
            proficient: m[2],
            expert: m[3],
        }
    }

    /// The level of highest membership (the lower at a tie).
    pub fn level_of(&self, m: &Memberships) -> &'static str {
        let a = m.as_array();
        let mut best = 0;
        for k in 1..4 {
            if a[k] > a[best] {
                best = k;
            }
        }
        LEVELS[best]
    }
}
