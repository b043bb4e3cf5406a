//! Scenario files (`assets/scenarios/*.toml`), the parts every procedure shares: the
//! procedure a file names, its timing (the top-level `dt_s` and `publish_hz`), input errors,
//! range checks, the limits on a session's size and the window's save-back of tuned values.
//! Each procedure reads the rest of its file itself (`procedures/<name>/scenario.rs`); every
//! value is range-checked and an error names the file, the key and what is expected.

use crate::params::{ParamSpec, Params};

pub use crate::input_error::InputError;

/// A scenario's timing: the top-level `dt_s` and `publish_hz` every procedure's file holds
/// (its [`crate::params::TOP_LEVEL`] table).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timing {
    /// Simulation step, s.
    pub dt_s: f32,
    /// Snapshots published for renderers per second, Hz.
    pub publish_hz: f32,
}

impl Timing {
    /// The `dt_s` entry with a procedure's own default (the range is the same for all).
    pub const fn dt_spec(default_s: f64, doc: &'static str) -> ParamSpec {
        ParamSpec::new("dt_s", "s", default_s, DT_RANGE_S, doc)
    }

    /// A task table's `target_time_s` entry, an expert's time against which efficiency is
    /// scored, with a procedure's own default and words (the range is the same for all).
    pub const fn target_time(default_s: f64, doc: &'static str) -> ParamSpec {
        ParamSpec::new("target_time_s", "s", default_s, (1.0, 7200.0), doc)
    }

    /// The words most procedures give their `target_time_s` (see [`Timing::target_time`]).
    pub const TARGET_TIME_DOC: &'static str =
        "time an expert needs: the efficiency component is full at or below it";

    /// The `publish_hz` entry.
    pub const PUBLISH_HZ: ParamSpec = ParamSpec::new(
        "publish_hz",
        "Hz",
        90.0,
        (1.0, 1000.0),
        "snapshots published for renderers per second (the Vive refreshes at 90 Hz)",
    );
}

/// What the trainee sees in a headset (the scenario's optional `[headset]` table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Headset {
    /// `"scope"` (the default): the trainee stands in the field and sees it in the scope's
    /// light, as an immersive trainer does; `"monitor"`: the trainee sees the laparoscope's
    /// image on a monitor across the table, as in the operating room and a box trainer, while
    /// the hands work in the unseen field. Each shipped scenario says which its paper used.
    #[serde(default)]
    pub view: HeadsetView,
}

/// See [`Headset::view`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HeadsetView {
    #[default]
    Scope,
    Monitor,
}

/// Where the models that have a GPU path step (the scenario's optional top-level `compute`;
/// `--compute` on `run` and `demo` sets it). A model without one steps on the CPU whatever it
/// says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Compute {
    /// The GPU where the adapter is a real one; the CPU on a software adapter (lavapipe) or
    /// without any.
    #[default]
    Auto,
    /// The CPU.
    Cpu,
    /// The GPU, on whatever adapter there is, lavapipe included; none is an error.
    Gpu,
}

impl Compute {
    /// The word a scenario and the command line use.
    pub fn name(self) -> &'static str {
        match self {
            Compute::Auto => "auto",
            Compute::Cpu => "cpu",
            Compute::Gpu => "gpu",
        }
    }
}

/// The `[headset]` table of scenario text of any procedure (the default where there is none);
/// an error names `file` and the key.
pub fn headset_of(file: &str, text: &str) -> Result<Headset, InputError> {
    let table: toml::Table = toml::from_str(text).map_err(|e| InputError::toml(file, &e))?;
    match table.get("headset") {
        None => Ok(Headset::default()),
        Some(v) => v.clone().try_into().map_err(|e: toml::de::Error| {
            InputError::new(
                file,
                "headset",
                format!(
                    "{} (expected view = \"scope\" or \"monitor\")",
                    e.message().trim_end()
                ),
            )
        }),
    }
}

/// The steps a scenario may take, s.
const DT_RANGE_S: (f64, f64) = (1e-4, 0.01);

/// The ranges every procedure's timing is checked against; each procedure lists its own
/// default step in its `PARAM_TABLES` (see [`Timing::dt_spec`]).
impl Params for Timing {
    const SPECS: &'static [ParamSpec] = &[
        Timing::dt_spec(0.002, "simulation step (0.002: 500 Hz)"),
        Timing::PUBLISH_HZ,
    ];

    crate::param_fields!(dt_s, publish_hz);
}

/// The scenario `text` with `values` written into its `[table]`, comments and layout kept:
/// each `key = value` line of the table gets the new value (a missing key is added at the end
/// of the table). The result is checked: `check` (its procedure's reading, given the new
/// text) accepts it, and every value reads back.
pub fn with_values(
    check: &dyn Fn(&str) -> Result<(), InputError>,
    file: &str,
    text: &str,
    table: &str,
    values: &[(String, f32)],
) -> Result<String, InputError> {
    let header = format!("[{table}]");
    let mut out: Vec<String> = Vec::new();
    let mut inside = false;
    let mut seen = vec![false; values.len()];
    let mut table_end = None;
    for line in text.lines() {
        let trimmed = line.trim_start();
        if trimmed.starts_with('[') {
            if inside {
                table_end = Some(out.len());
            }
            inside = trimmed.starts_with(&header);
        }
        let key = trimmed.split('=').next().unwrap_or("").trim();
        match values.iter().position(|(k, _)| k == key) {
            Some(k) if inside && trimmed.contains('=') => {
                let indent = &line[..line.len() - trimmed.len()];
                let comment = line.find('#').map_or("", |c| &line[c..]);
                let pad = if comment.is_empty() { "" } else { "   " };
                out.push(format!("{indent}{key} = {:?}{pad}{comment}", values[k].1));
                seen[k] = true;
            }
            _ => out.push(line.to_string()),
        }
    }
    let at = match (table_end, inside) {
        (Some(e), _) => e,
        (None, true) => out.len(),
        (None, false) => {
            return Err(InputError::new(
                file,
                table,
                format!("no {header} table to write into"),
            ));
        }
    };
    let missing: Vec<String> = values
        .iter()
        .zip(&seen)
        .filter(|(_, seen)| !**seen)
        .map(|((k, v), _)| format!("{k} = {v:?}"))
        .collect();
    out.splice(at..at, missing);
    let mut written = out.join("\n");
    if text.ends_with('\n') {
        written.push('\n');
    }
    check(&written)?;
    let parsed: toml::Table = toml::from_str(&written).map_err(|e| InputError::toml(file, &e))?;
    for (k, v) in values {
        let back = parsed
            .get(table)
            .and_then(|t| t.get(k))
            .and_then(toml::Value::as_float);
        if back.map(|b| b as f32) != Some(*v) {
            return Err(InputError::new(
                file,
                &format!("{table}.{k}"),
                "the tuned value did not read back",
            ));
        }
    }
    Ok(written)
}

/// The scenario `text` with every tuned value, `(model, key, value)`, written into its
/// model's table; `check` as for [`with_values`].
pub fn with_tunables<'a>(
    check: &dyn Fn(&str) -> Result<(), InputError>,
    file: &str,
    text: &str,
    tunables: impl IntoIterator<Item = (&'a str, &'a str, f32)>,
) -> Result<String, InputError> {
    let tunables: Vec<(&str, &str, f32)> = tunables.into_iter().collect();
    let mut text = text.to_string();
    let mut models: Vec<&str> = tunables.iter().map(|t| t.0).collect();
    models.dedup();
    for model in models {
        let values: Vec<(String, f32)> = tunables
            .iter()
            .filter(|t| t.0 == model)
            .map(|t| (t.1.to_string(), t.2))
            .collect();
        text = with_values(check, file, &text, model, &values)?;
    }
    Ok(text)
}

/// The procedure a scenario text names (its top-level `procedure` key), before the
/// procedure's own reading of the rest.
pub fn procedure_of(file: &str, text: &str) -> Result<String, InputError> {
    let table: toml::Table = toml::from_str(text).map_err(|e| InputError::toml(file, &e))?;
    match table.get("procedure") {
        Some(toml::Value::String(s)) => Ok(s.clone()),
        Some(v) => Err(InputError::new(
            file,
            "procedure",
            format!("must be a procedure's name, got {v}"),
        )),
        None => Err(InputError::new(
            file,
            "procedure",
            "missing: every scenario names its procedure",
        )),
    }
}

/// Keys that older scenario files held elsewhere: `(table, key)` then, `(table, key)` now.
/// Recordings embed their scenario, so a session recorded before a key moved still replays.
pub type Moved = [((&'static str, &'static str), (&'static str, &'static str))];

/// Reads scenario text of any procedure's type (moving the `moved` keys of an older file to
/// where they are now) and runs its own checks: a TOML error or a failed check names `file`
/// and the key.
pub fn parse_checked<T: serde::de::DeserializeOwned>(
    file: &str,
    text: &str,
    moved: &Moved,
    validate: impl FnOnce(&T, &str) -> Result<(), InputError>,
) -> Result<T, InputError> {
    let s: T = match with_moved_keys(text, moved) {
        // An older file: read from the moved table (its errors name keys, not lines).
        Some(root) => root.try_into().map_err(|e| InputError::toml(file, &e))?,
        None => toml::from_str(text).map_err(|e| InputError::toml(file, &e))?,
    };
    validate(&s, file)?;
    Ok(s)
}

/// The text's tables with every `moved` key that it holds at its old place, and not at its
/// new one, moved; none when nothing moves (or the text is not TOML, which the caller's
/// reading reports).
fn with_moved_keys(text: &str, moved: &Moved) -> Option<toml::Table> {
    if moved.is_empty() {
        return None;
    }
    let mut root: toml::Table = toml::from_str(text).ok()?;
    let mut any = false;
    for &((old_table, old_key), (new_table, new_key)) in moved {
        let taken = match root.get(new_table) {
            Some(toml::Value::Table(t)) if t.contains_key(new_key) => None,
            Some(v) if !v.is_table() => None,
            _ => match root.get_mut(old_table) {
                Some(toml::Value::Table(t)) => t.remove(old_key),
                _ => None,
            },
        };
        if let Some(v) = taken {
            let entry = root
                .entry(new_table)
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            if let toml::Value::Table(t) = entry {
                t.insert(new_key.to_string(), v);
                any = true;
            }
        }
    }
    any.then_some(root)
}

/// A grasper's jaws on a soft body (the scenario's `[grasper]` table), the same for every
/// procedure that has one.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Grasper {
    /// Radius of the open grasper's tip, a rigid collision sphere, m.
    pub tip_radius_m: f32,
    /// Reach of the closing jaws: points this close to the tip are held, m.
    pub grasp_radius_m: f32,
    /// Grip value (0 to 1) at or above which the jaws close.
    pub grip_threshold: f32,
}

impl Grasper {
    /// Where files before the `[grasper]` table held its keys: in `[tools]`.
    pub const MOVED_FROM_TOOLS: &'static Moved = &[
        (
            ("tools", "grasper_tip_radius_m"),
            ("grasper", "tip_radius_m"),
        ),
        (("tools", "grasp_radius_m"), ("grasper", "grasp_radius_m")),
        (("tools", "grip_threshold"), ("grasper", "grip_threshold")),
    ];
}

/// One table serves every procedure with a grasper, each with its own values (the defaults
/// are the nephrectomy's).
impl Params for Grasper {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "tip_radius_m",
            "m",
            0.003,
            (1e-4, 0.02),
            "radius of the open grasper's tip, a rigid collision sphere",
        ),
        ParamSpec::new(
            "grasp_radius_m",
            "m",
            0.008,
            (1e-4, 0.05),
            "reach of the closing jaws: points this close to the tip are held",
        ),
        ParamSpec::new(
            "grip_threshold",
            "",
            0.5,
            (0.01, 1.0),
            "grip value (0 to 1) at or above which the jaws close",
        ),
    ];

    crate::param_fields!(tip_radius_m, grasp_radius_m, grip_threshold);
}

/// That a tube's wall (`key`, `wall_m`) is thinner than `fraction` of a size of the tube
/// (`size_m`, which `of` names, as in "80 % of the outer radius").
pub fn check_wall(
    file: &str,
    key: &str,
    wall_m: f64,
    (fraction, size_m): (f64, f64),
    of: &str,
) -> Result<(), InputError> {
    InputError::require(wall_m < fraction * size_m, file, key, || {
        format!("expected a wall thinner than {of} ({size_m} m), got {wall_m} m")
    })
}

/// That a file read as procedure `expected`'s scenario names it in its `procedure` key.
pub fn expect_procedure(file: &str, got: &str, expected: &str) -> Result<(), InputError> {
    if got == expected {
        return Ok(());
    }
    Err(InputError::new(
        file,
        "procedure",
        format!("must be \"{expected}\", got \"{got}\""),
    ))
}

/// That `name` can name a procedure (files name one before anyone knows which are
/// registered; the session resolves it against the registry).
pub fn check_procedure(file: &str, key: &str, name: &str) -> Result<(), InputError> {
    let plain = |c: char| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '_';
    if !name.is_empty() && name.len() <= 64 && name.chars().all(plain) {
        return Ok(());
    }
    Err(InputError::new(
        file,
        key,
        format!(
            "'{name}' is no procedure's name (expected lower-case letters, digits, '-' or '_', \
             at most 64)"
        ),
    ))
}

/// Checks that `v` is a finite number in `[lo, hi]`; the error names `file` and `key`.
pub fn check_number(
    file: &str,
    key: &str,
    v: f32,
    (lo, hi): (f32, f32),
    unit: &str,
) -> Result<(), InputError> {
    if !v.is_finite() {
        return Err(InputError::new(
            file,
            key,
            format!("must be a finite number, got {v}"),
        ));
    }
    if v < lo || v > hi {
        return Err(InputError::new(
            file,
            key,
            format!("must be between {lo} and {hi} {unit}, got {v}"),
        ));
    }
    Ok(())
}

/// A direction shorter than this cannot be normalised safely (its square underflows).
pub const MIN_DIRECTION_LENGTH: f32 = 1e-6;
/// The most simulated points a scenario may ask for (about 40 times the largest shipped scene).
pub const MAX_NODES: u64 = 2_000_000;
/// The most point-steps a scripted session may ask for: about five hours of computing at the
/// 5e7 point-steps per second a 2-core machine manages (a 4-hour session at full size is 4e11).
pub const MAX_POINT_STEPS: f64 = 1e12;
/// Point-steps per second assumed for the estimate in messages.
const POINT_STEPS_PER_S: f64 = 5e7;

/// Refuses a session of `steps` steps over `nodes` simulated points whose cost (points x
/// steps) is absurd, before anything is built.
pub fn check_cost(file: &str, nodes: u64, steps: u64) -> Result<(), InputError> {
    let cost = nodes as f64 * steps as f64;
    if cost > MAX_POINT_STEPS {
        return Err(InputError::new(
            file,
            "anatomy",
            format!(
                "{nodes} points x {steps} steps = {cost:.1e} point-steps, about {:.0} hours of \
                 computing; at most {MAX_POINT_STEPS:.0e} are run: lower the resolution, raise \
                 dt_s or shorten the trace",
                cost / POINT_STEPS_PER_S / 3600.0
            ),
        ));
    }
    Ok(())
}

/// `text` (a scenario, named `file` in errors) with `overlay`'s keys laid over it: a table in
/// both is merged key by key, any other value of the overlay replaces the scenario's. The
/// result is a whole scenario (without the comments), what a session records and replays.
/// `preset` names the overlay in errors.
pub fn with_preset(
    file: &str,
    text: &str,
    preset: &str,
    overlay: &str,
) -> Result<String, InputError> {
    let base: toml::Table = toml::from_str(text).map_err(|e| InputError::toml(file, &e))?;
    let over: toml::Table = toml::from_str(overlay).map_err(|e| InputError::toml(preset, &e))?;
    let merged = merge_tables(base, over);
    toml::to_string(&merged).map_err(|e| InputError::new(preset, "", e.to_string()))
}

/// `over`'s keys laid over `base`, tables merged key by key.
fn merge_tables(mut base: toml::Table, over: toml::Table) -> toml::Table {
    for (key, value) in over {
        let merged = match (base.remove(&key), value) {
            (Some(toml::Value::Table(b)), toml::Value::Table(o)) => {
                toml::Value::Table(merge_tables(b, o))
            }
            (_, v) => v,
        };
        base.insert(key, merged);
    }
    base
}

/// Refuses a scenario that asks for more than `max` of something (`count`, as its simulated
/// points); the error names `file` and `key` and says `asked(count)`.
pub fn check_size(
    file: &str,
    key: &str,
    count: u64,
    max: u64,
    asked: impl FnOnce(u64) -> String,
) -> Result<(), InputError> {
    if count > max {
        return Err(InputError::new(file, key, asked(count)));
    }
    Ok(())
}

/// The part of a procedure's scenario reader every procedure writes alike, from its step
/// (`dt: (default, why)`, or `dt: default` for [`Timing::SPECS`]), the method that counts its
/// simulated points (`nodes`) and its tables `field: Type` in file order (each read from the
/// scenario table of its field's name; `extra:` fields have no table of specs): the top-level
/// `TIMING` table, `PARAM_TABLES` (what `ProcedureInfo::param_tables` lists), `plan`, and on
/// `Scenario` `parse` (which runs the procedure's own `validate`), `timing` and
/// `validate_tables` (the name, the timing and every table's ranges), which the procedure's
/// `validate` calls before its rules between values. The procedure's name is the `NAME`
/// beside the call.
#[macro_export]
macro_rules! scenario_tables {
    (dt: ($dt:expr, $why:expr), $($rest:tt)*) => {
        /// The top level: the simulation step and the snapshot rate.
        const TIMING: &[$crate::params::ParamSpec] = &[
            $crate::scenario::Timing::dt_spec($dt, $why),
            $crate::scenario::Timing::PUBLISH_HZ,
        ];
        $crate::scenario_tables!(@rest $($rest)*);
    };
    (dt: default, $($rest:tt)*) => {
        /// The top level: the default step and snapshot rate.
        const TIMING: &[$crate::params::ParamSpec] =
            <$crate::scenario::Timing as $crate::params::Params>::SPECS;
        $crate::scenario_tables!(@rest $($rest)*);
    };
    (
        @rest
        nodes: $nodes:ident,
        tables: [$($(#[$tm:meta])* $field:ident: $ty:ty),* $(,)?],
        $(extra: [$($(#[$em:meta])* $efield:ident: $ety:ty),* $(,)?],)?
        $(moved: $moved:expr,)?
    ) => {
        /// A scenario file: the procedure's name, the timing, what a headset shows, and the
        /// procedure's tables.
        #[derive(Debug, Clone, PartialEq, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct Scenario {
            /// Always the procedure's name.
            pub procedure: String,
            /// Simulation step, s.
            pub dt_s: f32,
            /// Snapshots published for renderers per second, Hz.
            pub publish_hz: f32,
            /// What a headset shows (`[headset]`; optional).
            #[serde(default)]
            pub headset: $crate::scenario::Headset,
            /// Where models with a GPU path step (`compute`; optional, `auto`).
            #[serde(default)]
            pub compute: $crate::scenario::Compute,
            $($(#[$tm])* pub $field: $ty,)*
            $($($(#[$em])* pub $efield: $ety,)*)?
        }

        /// The scenario's tables with specs, as `INFO.param_tables` lists them (file order).
        pub const PARAM_TABLES: &[(&str, &[$crate::params::ParamSpec])] = &[
            ($crate::params::TOP_LEVEL, TIMING),
            $((stringify!($field), <$ty as $crate::params::Params>::SPECS)),*
        ];

        $crate::scenario_plan!($nodes);

        /// Keys older files of this procedure held elsewhere.
        const MOVED: &$crate::scenario::Moved = $crate::scenario_moved!($($moved)?);

        impl Scenario {
            /// Parses and checks scenario text; `file` names it in errors.
            pub fn parse(file: &str, text: &str) -> Result<Self, $crate::scenario::InputError> {
                $crate::scenario::parse_checked(file, text, MOVED, Scenario::validate)
            }

            /// The top-level timing.
            pub fn timing(&self) -> $crate::scenario::Timing {
                $crate::scenario::Timing {
                    dt_s: self.dt_s,
                    publish_hz: self.publish_hz,
                }
            }

            /// The procedure's name, the timing and every table's ranges.
            fn validate_tables(&self, file: &str) -> Result<(), $crate::scenario::InputError> {
                $crate::scenario::expect_procedure(file, &self.procedure, NAME)?;
                $crate::params::validate(file, $crate::params::TOP_LEVEL, &self.timing())?;
                $($crate::params::validate(file, stringify!($field), &self.$field)?;)*
                Ok(())
            }
        }
    };
}

/// The `moved:` keys of [`scenario_tables!`], none when it names none.
#[doc(hidden)]
#[macro_export]
macro_rules! scenario_moved {
    () => {
        &[]
    };
    ($moved:expr) => {
        $moved
    };
}
