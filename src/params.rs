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

/// `docs/parameters.md`: every registered procedure's parameter tables.
pub fn document() -> String {
    let mut out = String::from(
        "# Scenario parameters\n\nGenerated from the parameter tables in the code (`ParamSpec`); \
         a test fails when this file is stale (`VESALIUS_BLESS=1 cargo test --lib params` \
         rewrites it). Every number a scenario holds is here, with its unit, its one default \
         and the range a scenario may give (inclusive); an error names the file and \
         `table.key`. Each scenario gives every value. The shipped scenarios \
         (`assets/scenarios/`) hold the defaults, a test checks, except in the soft-body \
         tables: one table serves several models, each with its own values, and its default \
         is what the model's `Default` holds. An array's elements are listed as `key[0]`, \
         `key[1]`, ...; a whole number is a count. A slider is shown in the desktop window for \
         the values the procedure lets the supervisor tune, and its changes are recorded with \
         the session. Checks that tie values together (a direction's length, the points a \
         resolution asks for, a sum of weights, a depth within the block) are made by each \
         procedure's code after these ranges.\n",
    );
    for p in crate::procedures::REGISTRY {
        out += &format!("\n## {} (`{}`)\n", p.title, p.name);
        for (table, specs) in p.param_tables {
            out += &format!("\n### {}\n\n{}", heading(table), markdown(specs));
        }
    }
    out
}

/// A table's heading in `docs/parameters.md`.
fn heading(table: &str) -> String {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::procedures::{ProcedureInfo, REGISTRY};

    /// The TOML table `table` of a scenario (the root for the top level).
    fn toml_table<'a>(root: &'a mut toml::Table, table: &str) -> &'a mut toml::Table {
        if table == TOP_LEVEL {
            return root;
        }
        root.get_mut(table)
            .and_then(toml::Value::as_table_mut)
            .unwrap_or_else(|| panic!("no [{table}]"))
    }

    /// The TOML value of a table key: `name` or an array element `name[i]`.
    fn entry<'a>(table: &'a mut toml::Table, key: &str) -> &'a mut toml::Value {
        let (name, index) = match key.split_once('[') {
            Some((name, i)) => (name, i.trim_end_matches(']').parse::<usize>().ok()),
            None => (key, None),
        };
        let v = table
            .get_mut(name)
            .unwrap_or_else(|| panic!("no key {name}"));
        match index {
            Some(i) => v
                .as_array_mut()
                .and_then(|a| a.get_mut(i))
                .unwrap_or_else(|| panic!("no element {key}")),
            None => v,
        }
    }

    fn number(v: &toml::Value) -> Option<f64> {
        v.as_float().or_else(|| v.as_integer().map(|i| i as f64))
    }

    /// The procedure's scenario with `key` of `table` set to `value`, and what its reader
    /// says of it.
    fn plan_with(
        p: &ProcedureInfo,
        table: &str,
        key: &str,
        value: toml::Value,
    ) -> Result<(), InputError> {
        let mut root: toml::Table = toml::from_str(p.scenario).expect("the scenario is TOML");
        *entry(toml_table(&mut root, table), key) = value;
        let text = toml::to_string(&root).expect("writes back");
        (p.plan)("bad.toml", &text).map(|_| ())
    }

    /// One default per parameter: each shipped scenario holds every table's default, and
    /// every number it holds has its table entry. The soft-body tables are the exception:
    /// one table serves several models (kidney, vessels, block), each with its own values.
    #[test]
    fn shipped_scenarios_hold_the_table_defaults() {
        let soft = <crate::models::SoftBodyParams as Params>::SPECS;
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
        let mut seen = Vec::new();
        for file in std::fs::read_dir(&dir).expect("assets/scenarios") {
            let path = file.expect("entry").path();
            if path.extension().is_none_or(|e| e != "toml") {
                continue;
            }
            let name = path.display().to_string();
            let text = std::fs::read_to_string(&path).expect("readable");
            let procedure = crate::scenario::procedure_of(&name, &text).expect("names one");
            let p = crate::procedures::find(&procedure).expect("a registered procedure");
            assert_eq!(p.scenario, text, "{name} is {procedure}'s builtin scenario");
            (p.plan)(&name, &text).expect("the shipped scenario is valid");
            seen.push(p.name);
            let mut root: toml::Table = toml::from_str(&text).expect("TOML");
            for (table, specs) in p.param_tables {
                let t = toml_table(&mut root, table);
                for s in *specs {
                    let v = number(entry(t, s.key)).expect("a number");
                    let at = format!("{name}: {}", table_key(table, s.key));
                    if *specs != soft {
                        assert_eq!(
                            v as f32, s.default as f32,
                            "{at}: the default is {}",
                            s.default
                        );
                    }
                }
                // Every number the table holds is one of its specs.
                for (k, v) in t.iter() {
                    let keys: Vec<String> = match v {
                        toml::Value::Array(a) if a.iter().all(|x| number(x).is_some()) => {
                            (0..a.len()).map(|i| format!("{k}[{i}]")).collect()
                        }
                        v if number(v).is_some() => vec![k.clone()],
                        _ => Vec::new(),
                    };
                    for key in keys {
                        assert!(
                            specs.iter().any(|s| s.key == key),
                            "{name}: {} has no table entry",
                            table_key(table, &key)
                        );
                    }
                }
            }
        }
        let mut all: Vec<&str> = crate::procedures::names().collect();
        all.sort_unstable();
        seen.sort_unstable();
        assert_eq!(seen, all, "one shipped scenario per registered procedure");
    }

    /// A value outside its range, in any table of any procedure, is refused with an error
    /// naming the file, `table.key` and the range.
    #[test]
    fn out_of_range_values_name_file_and_table_key() {
        for p in REGISTRY {
            for (table, specs) in p.param_tables {
                for s in *specs {
                    let mut bad = vec![s.max + s.max.abs() + 1.0];
                    if !s.whole || s.min >= 1.0 {
                        bad.push(if s.whole {
                            s.min - 1.0
                        } else {
                            s.min - s.min.abs() - 1.0
                        });
                    }
                    // The bounds themselves are in range (as an f32 field reads them).
                    for v in [s.min, s.max] {
                        let value = if s.whole {
                            toml::Value::Integer(v as i64)
                        } else {
                            toml::Value::Float(v)
                        };
                        let range = format!("between {} and {}", s.min, s.max);
                        if let Err(e) = plan_with(p, table, s.key, value) {
                            assert!(
                                !(e.key == table_key(table, s.key) && e.message.contains(&range)),
                                "{}: {v} is in range: {e}",
                                p.name
                            );
                        }
                    }
                    for v in bad {
                        let value = if s.whole {
                            toml::Value::Integer(v as i64)
                        } else {
                            toml::Value::Float(v)
                        };
                        let e = plan_with(p, table, s.key, value).expect_err("out of range");
                        assert_eq!(
                            (e.file.as_str(), e.key.as_str()),
                            ("bad.toml", table_key(table, s.key).as_str()),
                            "{}: {e}",
                            p.name
                        );
                        let range = format!("between {} and {}", s.min, s.max);
                        assert!(e.message.contains(&range), "{e}");
                    }
                }
            }
        }
    }

    /// A count given a fraction is refused, and the message shows the line with the key.
    #[test]
    fn a_whole_number_given_a_fraction_is_refused() {
        let mut counted = 0;
        for p in REGISTRY {
            for (table, specs) in p.param_tables {
                for s in specs.iter().filter(|s| s.whole) {
                    let e = plan_with(p, table, s.key, toml::Value::Float(2.5))
                        .expect_err("a fraction");
                    let text = e.to_string();
                    assert_eq!(e.file, "bad.toml");
                    assert!(
                        text.contains(&format!("{} = 2.5", s.key)) && text.contains("u32"),
                        "{}: {text}",
                        p.name
                    );
                    counted += 1;
                }
            }
        }
        assert!(counted >= 5, "{counted}");
    }

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
                assert!(now.contains(&heading(table)));
                for s in *specs {
                    assert!(now.contains(&format!("`{}`", s.key)));
                }
            }
        }
    }

    #[test]
    fn live_values_are_checked_against_their_sliders() {
        use crate::models::SoftBodyParams;
        let ok = [("foundation_pa_per_m".to_string(), 2e6)];
        assert!(check_tuning::<SoftBodyParams>("tissue", &ok).is_ok());
        let high = [("foundation_pa_per_m".to_string(), 2e7)];
        let e = check_tuning::<SoftBodyParams>("tissue", &high)
            .expect_err("above")
            .to_string();
        assert!(
            e.contains("tissue.foundation_pa_per_m") && e.contains("10000000"),
            "{e}"
        );
        let fixed = [("falloff_m".to_string(), 0.01)];
        let e = check_tuning::<SoftBodyParams>("tissue", &fixed).expect_err("fixed");
        assert!(matches!(e, TuneError::Fixed { .. }), "{e}");
    }
}
