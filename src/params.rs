//! Parameters as data: each parameter struct publishes one table of `ParamSpec`s (key, unit,
//! default, range, what it does, and the slider range when a supervisor may tune it live).
//! The table drives scenario validation, the window's sliders, the struct's defaults and the
//! generated `docs/parameters.md`, so a parameter's facts live in one place.

use crate::scenario::InputError;

/// One parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    /// The key in the scenario table.
    pub key: &'static str,
    /// SI unit ("N/m", "1/s", "" for a count or a ratio).
    pub unit: &'static str,
    /// The one default.
    pub default: f64,
    /// Allowed range in a scenario, inclusive.
    pub min: f64,
    pub max: f64,
    /// What it does, and the paper's equation where there is one.
    pub doc: &'static str,
    /// A whole number (a count of iterations).
    pub whole: bool,
    /// The slider's range when it may be tuned live; none: fixed for the session.
    pub tune: Option<(f64, f64)>,
}

/// A parameter struct with its table.
pub trait Params {
    const SPECS: &'static [ParamSpec];
    /// The value of `key`, if it is one of the table's.
    fn get(&self, key: &str) -> Option<f64>;
    /// Sets `key` (no range check); false if it is not one of the table's.
    fn set(&mut self, key: &str, value: f64) -> bool;
}

/// The struct with every parameter at its default.
pub fn defaults<T: Params + Default>() -> T {
    let mut t = T::default();
    for s in T::SPECS {
        t.set(s.key, s.default);
    }
    t
}

/// Checks every parameter of `t` against its range; an error names `file` and `table.key`.
pub fn validate<T: Params>(file: &str, table: &str, t: &T) -> Result<(), InputError> {
    for s in T::SPECS {
        let key = format!("{table}.{}", s.key);
        let v = t.get(s.key).unwrap_or(f64::NAN);
        if !v.is_finite() {
            return Err(InputError::new(
                file,
                &key,
                format!("must be a finite number, got {v}"),
            ));
        }
        if v < s.min || v > s.max || (s.whole && v.fract() != 0.0) {
            let what = if s.whole { "a whole number " } else { "" };
            let range = format!("between {} and {} {}", s.min, s.max, s.unit);
            return Err(InputError::new(
                file,
                &key,
                format!("must be {what}{}, got {v}", range.trim_end()),
            ));
        }
    }
    Ok(())
}

/// Why a live change of parameters was refused (nothing was changed).
#[derive(Debug, thiserror::Error)]
pub enum TuneError {
    #[error("model '{0}' has no tunable parameters")]
    NoSuchModel(String),
    #[error("{table}.{key}: not a parameter of this model")]
    UnknownKey { table: String, key: String },
    #[error("{table}.{key}: fixed for the session, not tunable")]
    Fixed { table: String, key: String },
    #[error("{table}.{key}: must be {min} to {max}, got {value}")]
    OutOfRange {
        table: String,
        key: String,
        min: f64,
        max: f64,
        value: f64,
    },
    #[error("cannot record the tuning: {0}")]
    Record(#[from] std::io::Error),
    #[error("step {step}: {source}")]
    AtStep {
        step: u64,
        #[source]
        source: Box<TuneError>,
    },
}

/// Checks a live value against a slider range `(min, max)`.
pub fn check_slider(
    table: &str,
    key: &str,
    (min, max): (f64, f64),
    v: f32,
) -> Result<(), TuneError> {
    let value = f64::from(v);
    if value.is_finite() && (min..=max).contains(&value) {
        return Ok(());
    }
    Err(TuneError::OutOfRange {
        table: table.to_string(),
        key: key.to_string(),
        min,
        max,
        value,
    })
}

/// Checks live values for `table` against their slider ranges (all or none).
pub fn check_tuning<T: Params>(table: &str, values: &[(String, f32)]) -> Result<(), TuneError> {
    for (key, v) in values {
        let named = || (table.to_string(), key.clone());
        let spec = T::SPECS.iter().find(|s| s.key == key).ok_or_else(|| {
            let (table, key) = named();
            TuneError::UnknownKey { table, key }
        })?;
        let range = spec.tune.ok_or_else(|| {
            let (table, key) = named();
            TuneError::Fixed { table, key }
        })?;
        check_slider(table, key, range, *v)?;
    }
    Ok(())
}

/// `docs/parameters.md`: every registered procedure's parameter tables.
pub fn document() -> String {
    let mut out = String::from(
        "# Scenario parameters\n\nGenerated from the parameter tables in the code (`ParamSpec`); \
         a test fails when this file is stale (`VESALIUS_BLESS=1 cargo test --lib params` \
         rewrites it). Each scenario gives every value; the default is what the model's \
         `Default` holds. A slider is shown in the desktop window for the tables the procedure \
         lets the supervisor tune, and its changes are recorded with the session. Tables not \
         listed here (anatomy, tools, task, weights, geometry) are still checked by each \
         procedure's own code.\n",
    );
    for p in crate::procedures::REGISTRY {
        out += &format!("\n## {} (`{}`)\n", p.title, p.name);
        for (table, specs) in p.param_tables {
            out += &format!("\n### `[{table}]`\n\n{}", markdown(specs));
        }
    }
    out
}

/// A Markdown table of `specs` (for `docs/parameters.md`).
pub fn markdown(specs: &[ParamSpec]) -> String {
    let mut out = String::from(
        "| key | unit | default | range | slider, where the procedure offers one | what it does |\n\
         |---|---|---|---|---|---|\n",
    );
    for s in specs {
        let tune = s
            .tune
            .map_or_else(|| "–".to_string(), |(lo, hi)| format!("{lo} – {hi}"));
        let unit = if s.unit.is_empty() { "–" } else { s.unit };
        out += &format!(
            "| `{}` | {unit} | {} | {} – {} | {tune} | {} |\n",
            s.key, s.default, s.min, s.max, s.doc
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The generated document is in the repository and up to date.
    #[test]
    fn docs_parameters_md_is_current() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/parameters.md");
        let now = document();
        if std::env::var_os("VESALIUS_BLESS").is_some() {
            std::fs::write(&path, &now).expect("docs/parameters.md written");
        }
        let on_disk = std::fs::read_to_string(&path).unwrap_or_default();
        assert!(
            on_disk == now,
            "docs/parameters.md is stale: VESALIUS_BLESS=1 cargo test --lib params rewrites it"
        );
        for p in crate::procedures::REGISTRY {
            for (table, specs) in p.param_tables {
                assert!(now.contains(&format!("`[{table}]`")));
                for s in *specs {
                    assert!(now.contains(&format!("`{}`", s.key)));
                }
            }
        }
    }

    #[test]
    fn live_values_are_checked_against_their_sliders() {
        use crate::models::SoftBodyParams;
        let ok = [("spring_n_per_m".to_string(), 100.0)];
        assert!(check_tuning::<SoftBodyParams>("tissue", &ok).is_ok());
        let high = [("spring_n_per_m".to_string(), 500.0)];
        let e = check_tuning::<SoftBodyParams>("tissue", &high)
            .expect_err("above")
            .to_string();
        assert!(
            e.contains("tissue.spring_n_per_m") && e.contains("400"),
            "{e}"
        );
        let fixed = [("falloff_m".to_string(), 0.01)];
        let e = check_tuning::<SoftBodyParams>("tissue", &fixed).expect_err("fixed");
        assert!(matches!(e, TuneError::Fixed { .. }), "{e}");
    }
}
