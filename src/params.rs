//! Parameters as data: each parameter struct publishes one table of `ParamSpec`s (key, unit,
//! default, range, what it does, and the slider range when a supervisor may tune it live).
//! The table drives scenario validation, the window's sliders, the struct's defaults and the
//! generated `docs/parameters.md`, so a parameter's facts live in one place.

use crate::input_error::InputError;

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

impl ParamSpec {
    /// A number that may take any value in `[min, max]`, fixed for the session.
    pub const fn new(
        key: &'static str,
        unit: &'static str,
        default: f64,
        (min, max): (f64, f64),
        doc: &'static str,
    ) -> Self {
        Self {
            key,
            unit,
            default,
            min,
            max,
            doc,
            whole: false,
            tune: None,
        }
    }

    /// A parameter of a family: `family`'s unit and range (and slider), with its own `key`,
    /// `default` and `doc`. A family is written once as a `ParamSpec` whose key, default and
    /// words are left empty.
    pub const fn of(family: ParamSpec, key: &'static str, default: f64, doc: &'static str) -> Self {
        Self {
            key,
            default,
            doc,
            ..family
        }
    }

    /// The same parameter as a whole number (a count).
    pub const fn whole(self) -> Self {
        Self {
            whole: true,
            ..self
        }
    }

    /// The same parameter with a live slider over `[lo, hi]`.
    pub const fn tune(self, lo: f64, hi: f64) -> Self {
        Self {
            tune: Some((lo, hi)),
            ..self
        }
    }
}

/// The table name in scenario files for the keys above the first `[table]` header.
pub const TOP_LEVEL: &str = "";

/// How errors and documents name `key` of `table`: `table.key`, or `key` at the top level.
pub fn table_key(table: &str, key: &str) -> String {
    if table == TOP_LEVEL {
        key.to_string()
    } else {
        format!("{table}.{key}")
    }
}

/// A value as people read it: a value that is an `f32` (every scenario number is one) with
/// the digits that `f32` needs, so 0.3 reads 0.3, not 0.30000001192092896.
fn shown(v: f64) -> String {
    let single = v as f32;
    if f64::from(single) == v {
        single.to_string()
    } else {
        v.to_string()
    }
}

/// `Params::get` and `Params::set` for a struct whose keys are its field names (numbers:
/// `f32`, or a whole-number type for counts).
#[macro_export]
macro_rules! param_fields {
    ($($field:ident),+ $(,)?) => {
        fn get(&self, key: &str) -> Option<f64> {
            match key {
                $(stringify!($field) => Some(f64::from(self.$field)),)+
                _ => None,
            }
        }

        fn set(&mut self, key: &str, v: f64) -> bool {
            match key {
                $(stringify!($field) => self.$field = v as _,)+
                _ => return false,
            }
            true
        }
    };
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

/// Checks every parameter of `t` against its range; an error names `file` and `table.key`
/// (`key` alone for the [`TOP_LEVEL`]).
pub fn validate<T: Params>(file: &str, table: &str, t: &T) -> Result<(), InputError> {
    for s in T::SPECS {
        let key = table_key(table, s.key);
        let v = t.get(s.key).unwrap_or(f64::NAN);
        if !v.is_finite() {
            return Err(InputError::new(
                file,
                &key,
                format!("must be a finite number, got {}", shown(v)),
            ));
        }
        // A value an f32 holds is compared with the bounds as an f32 holds them: 1e-4 read
        // into an f32 field is slightly below 1e-4 and must still be in range.
        let single = f64::from(v as f32) == v;
        let bound = |b: f64| if single { f64::from(b as f32) } else { b };
        if v < bound(s.min) || v > bound(s.max) || (s.whole && v.fract() != 0.0) {
            let what = if s.whole { "a whole number " } else { "" };
            let range = format!("between {} and {} {}", s.min, s.max, s.unit);
            return Err(InputError::new(
                file,
                &key,
                format!("must be {what}{}, got {}", range.trim_end(), shown(v)),
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

/// A table's heading in `docs/parameters.md`.
pub(crate) fn heading(table: &str) -> String {
    if table == TOP_LEVEL {
        "Top level (the keys before the first `[table]`)".to_string()
    } else {
        format!("`[{table}]`")
    }
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

/// Checks that every key of `T`'s table names its own field of `t`: each key once, a
/// distinct value set through a key reads back through it and leaves the other keys alone,
/// and an unknown key is refused.
#[cfg(test)]
pub(crate) fn assert_round_trip<T: Params + Clone>(t: &T) {
    let mut keys: Vec<&str> = T::SPECS.iter().map(|s| s.key).collect();
    keys.sort_unstable();
    keys.dedup();
    assert_eq!(keys.len(), T::SPECS.len(), "each key once");
    for (i, s) in T::SPECS.iter().enumerate() {
        // Exact in an f32 and a u32, and no shipped value.
        let v = 1000.0 + i as f64 + if s.whole { 0.0 } else { 0.5 };
        let mut u = t.clone();
        assert!(u.set(s.key, v), "{} is not settable", s.key);
        assert_eq!(u.get(s.key), Some(v), "{} does not read back", s.key);
        for o in T::SPECS.iter().filter(|o| o.key != s.key) {
            assert_eq!(
                u.get(o.key),
                t.get(o.key),
                "setting {} changed {}",
                s.key,
                o.key
            );
        }
        assert!(s.min <= s.default && s.default <= s.max, "{}", s.key);
        assert!(!s.whole || s.default.fract() == 0.0, "{}", s.key);
    }
    assert_eq!(t.get("no_such_key"), None);
    assert!(!t.clone().set("no_such_key", 1.0));
}
