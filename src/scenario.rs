//! Scenario files (`assets/scenarios/*.toml`): anatomy, model parameters with units, tools,
//! task, vulnerable structures and metric weights. Every value is range-checked; an error names
//! the file, the key and what is expected.

use crate::models::SoftBodyParams;
use serde::Deserialize;
use std::path::Path;

/// The five procedures of the papers the product covers (the registry says which run today;
/// it may hold others, such as the sandbox).
pub const PROCEDURES: [&str; 5] = [
    "nephrectomy",
    "rectum",
    "cholecystectomy",
    "myotomy",
    "catheter",
];

/// An input-file problem, for people: which file, which key or line, what was expected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}: {key}: {message}")]
pub struct InputError {
    pub file: String,
    pub key: String,
    pub message: String,
}

impl InputError {
    pub fn new(file: &str, key: &str, message: impl Into<String>) -> Self {
        Self {
            file: file.to_string(),
            key: key.to_string(),
            message: message.into(),
        }
    }

    /// Wraps a TOML error, keeping its line and column.
    pub fn toml(file: &str, e: &toml::de::Error) -> Self {
        let key = match e.span() {
            Some(_) => "toml".to_string(),
            None => "file".to_string(),
        };
        Self::new(file, &key, e.to_string().trim_end().replace('\n', " | "))
    }
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// A registered procedure's name.
    pub procedure: String,
    /// Simulation step, seconds (1e-4 to 0.01).
    pub dt_s: f32,
    /// Snapshot publication rate for renderers, Hz.
    pub publish_hz: f32,
    pub anatomy: Anatomy,
    pub kidney: SoftBodyParams,
    pub vessels: SoftBodyParams,
    pub tools: Tools,
    pub task: Task,
    pub vulnerable: Vec<Vulnerable>,
    pub weights: Weights,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Anatomy {
    /// Icosphere subdivision level of kidney and tumour (5 = full scene, 3 = coarse).
    pub level: u32,
    pub kidney_half_length_m: f32,
    pub kidney_half_width_m: f32,
    pub kidney_half_thickness_m: f32,
    pub hilum_depth_m: f32,
    /// Tumour radius, m (the paper's case: a 3-5 cm mass).
    pub tumour_radius_m: f32,
    /// Direction from the kidney centre to the tumour site (normalised on load).
    pub tumour_direction: [f32; 3],
    /// How far the tumour centre stands out of the surface, in tumour radii (exophytic > 0).
    pub tumour_protrusion: f32,
    /// Points around each vessel.
    pub vessel_segments: u32,
    /// Rings along each vessel.
    pub vessel_rings: u32,
    pub renal_artery_radius_m: f32,
    pub renal_vein_radius_m: f32,
    pub ureter_radius_m: f32,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tools {
    /// Laser pointer range, m.
    pub laser_range_m: f32,
    /// Trigger value above which the laser cuts, 0..1.
    pub cut_threshold: f32,
    /// Pressure the laser applies where it cuts, Pa.
    pub laser_pressure_pa: f32,
    /// Grasper tip radius (collision sphere), m.
    pub grasper_tip_radius_m: f32,
    /// Reach of the closing jaws, m.
    pub grasp_radius_m: f32,
    /// Grip value above which the jaws close, 0..1.
    pub grip_threshold: f32,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Task {
    /// Intended margin of healthy tissue around the tumour, m.
    pub margin_m: f32,
    /// Margin marks needed before cutting counts as planned.
    pub marks_required: u32,
    /// A mark counts if it lies within this distance of the intended margin, m.
    pub mark_tolerance_m: f32,
    /// The freed tumour counts as removed once lifted this far, m.
    pub removal_distance_m: f32,
    /// Time an expert needs, s (efficiency is full at or below it).
    pub target_time_s: f32,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Vulnerable {
    pub model: String,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Weights {
    pub completion: f32,
    pub margin: f32,
    pub preservation: f32,
    pub safety: f32,
    pub efficiency: f32,
}

/// The scenario `text` with `values` written into its `[table]`, comments and layout kept:
/// each `key = value` line of the table gets the new value (a missing key is added at the end
/// of the table). The result is checked: it still validates as a scenario of its procedure,
/// and every value reads back.
pub fn with_values(
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
    crate::procedures::plan(file, &written)?;
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

/// The scenario `text` with every tunable's value now written into its model's table.
pub fn with_tunables(
    file: &str,
    text: &str,
    tunables: &[crate::procedures::Tunable],
) -> Result<String, InputError> {
    let mut text = text.to_string();
    let mut models: Vec<&str> = tunables.iter().map(|t| t.model.as_str()).collect();
    models.dedup();
    for model in models {
        let values: Vec<(String, f32)> = tunables
            .iter()
            .filter(|t| t.model == model)
            .map(|t| (t.key.to_string(), t.value))
            .collect();
        text = with_values(file, &text, model, &values)?;
    }
    Ok(text)
}

pub fn builtin(procedure: &str) -> Option<&'static str> {
    crate::procedures::find(procedure).map(|p| p.scenario)
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

pub fn check_procedure(file: &str, key: &str, name: &str) -> Result<(), InputError> {
    if crate::procedures::find(name).is_some() {
        return Ok(());
    }
    let available: Vec<&str> = crate::procedures::names().collect();
    let message = if PROCEDURES.contains(&name) {
        format!(
            "procedure '{name}' is not implemented yet (available: {})",
            available.join(", ")
        )
    } else {
        format!(
            "unknown procedure '{name}', expected one of {}",
            available.join(", ")
        )
    };
    Err(InputError::new(file, key, message))
}

struct Ranges<'a> {
    file: &'a str,
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

impl Ranges<'_> {
    fn num(&self, key: &str, v: f32, lo: f32, hi: f32, unit: &str) -> Result<(), InputError> {
        check_number(self.file, key, v, (lo, hi), unit)
    }

    fn params(&self, section: &str, p: &SoftBodyParams) -> Result<(), InputError> {
        crate::params::validate(self.file, section, p)
    }
}

/// A direction shorter than this cannot be normalised safely (its square underflows).
pub const MIN_DIRECTION_LENGTH: f32 = 1e-6;
/// The most simulated points a scenario may ask for (about 40 times the full-size kidney).
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

impl Scenario {
    /// Simulated points the anatomy will have, estimated from its sizes before anything is
    /// built: kidney and tumour (20 x 4^level faces each, one point per face) and three
    /// vessels (two faces per segment and ring).
    pub fn estimated_nodes(&self) -> u64 {
        let a = &self.anatomy;
        let sphere = 20 * 4u64.saturating_pow(a.level);
        let tube = 2 * u64::from(a.vessel_segments) * u64::from(a.vessel_rings);
        2 * sphere + 3 * tube
    }

    /// Parses and validates scenario text; `file` names it in errors.
    pub fn parse(file: &str, text: &str) -> Result<Self, InputError> {
        let s: Scenario = toml::from_str(text).map_err(|e| InputError::toml(file, &e))?;
        s.validate(file)?;
        Ok(s)
    }

    pub fn load(path: &Path) -> Result<Self, InputError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| InputError::new(&file, "file", format!("cannot read: {e}")))?;
        Self::parse(&file, &text)
    }

    pub fn validate(&self, file: &str) -> Result<(), InputError> {
        check_procedure(file, "procedure", &self.procedure)?;
        let r = Ranges { file };
        r.num("dt_s", self.dt_s, 1e-4, 0.01, "s")?;
        r.num("publish_hz", self.publish_hz, 1.0, 1000.0, "Hz")?;
        let a = &self.anatomy;
        if !(1..=7).contains(&a.level) {
            return Err(InputError::new(
                file,
                "anatomy.level",
                format!("must be 1 to 7, got {}", a.level),
            ));
        }
        r.num(
            "anatomy.kidney_half_length_m",
            a.kidney_half_length_m,
            0.01,
            0.2,
            "m",
        )?;
        r.num(
            "anatomy.kidney_half_width_m",
            a.kidney_half_width_m,
            0.005,
            0.2,
            "m",
        )?;
        r.num(
            "anatomy.kidney_half_thickness_m",
            a.kidney_half_thickness_m,
            0.005,
            0.2,
            "m",
        )?;
        r.num("anatomy.hilum_depth_m", a.hilum_depth_m, 0.0, 0.05, "m")?;
        r.num(
            "anatomy.tumour_radius_m",
            a.tumour_radius_m,
            0.005,
            0.05,
            "m",
        )?;
        r.num(
            "anatomy.tumour_protrusion",
            a.tumour_protrusion,
            0.0,
            0.95,
            "radii",
        )?;
        for (i, c) in a.tumour_direction.iter().enumerate() {
            r.num(&format!("anatomy.tumour_direction[{i}]"), *c, -1e3, 1e3, "")?;
        }
        let dir = glam::Vec3::from(a.tumour_direction);
        if dir.length() < MIN_DIRECTION_LENGTH || dir.try_normalize().is_none() {
            return Err(InputError::new(
                file,
                "anatomy.tumour_direction",
                format!(
                    "is a direction (normalised on load): its length must be at least \
                     {MIN_DIRECTION_LENGTH}, got {:?} (length {})",
                    a.tumour_direction,
                    dir.length()
                ),
            ));
        }
        if !(3..=256).contains(&a.vessel_segments) || !(2..=1024).contains(&a.vessel_rings) {
            return Err(InputError::new(
                file,
                "anatomy.vessel_segments",
                "vessel_segments must be 3..256 and vessel_rings 2..1024",
            ));
        }
        r.num(
            "anatomy.renal_artery_radius_m",
            a.renal_artery_radius_m,
            5e-4,
            0.02,
            "m",
        )?;
        r.num(
            "anatomy.renal_vein_radius_m",
            a.renal_vein_radius_m,
            5e-4,
            0.02,
            "m",
        )?;
        r.num(
            "anatomy.ureter_radius_m",
            a.ureter_radius_m,
            5e-4,
            0.02,
            "m",
        )?;
        let nodes = self.estimated_nodes();
        if nodes > MAX_NODES {
            return Err(InputError::new(
                file,
                "anatomy",
                format!(
                    "asks for about {nodes} simulated points (level {}, vessels {} x {}); \
                     at most {MAX_NODES} can be built and stepped: lower anatomy.level or the \
                     vessel segments and rings",
                    a.level, a.vessel_segments, a.vessel_rings
                ),
            ));
        }
        r.params("kidney", &self.kidney)?;
        r.params("vessels", &self.vessels)?;
        let t = &self.tools;
        r.num("tools.laser_range_m", t.laser_range_m, 0.01, 5.0, "m")?;
        r.num("tools.cut_threshold", t.cut_threshold, 0.01, 1.0, "")?;
        r.num(
            "tools.laser_pressure_pa",
            t.laser_pressure_pa,
            0.0,
            1e5,
            "Pa",
        )?;
        r.num(
            "tools.grasper_tip_radius_m",
            t.grasper_tip_radius_m,
            1e-4,
            0.02,
            "m",
        )?;
        r.num("tools.grasp_radius_m", t.grasp_radius_m, 1e-4, 0.05, "m")?;
        r.num("tools.grip_threshold", t.grip_threshold, 0.01, 1.0, "")?;
        let k = &self.task;
        r.num("task.margin_m", k.margin_m, 0.0, 0.03, "m")?;
        r.num("task.mark_tolerance_m", k.mark_tolerance_m, 1e-4, 0.03, "m")?;
        r.num(
            "task.removal_distance_m",
            k.removal_distance_m,
            1e-3,
            0.3,
            "m",
        )?;
        r.num("task.target_time_s", k.target_time_s, 1.0, 7200.0, "s")?;
        let w = &self.weights;
        for (name, v) in [
            ("completion", w.completion),
            ("margin", w.margin),
            ("preservation", w.preservation),
            ("safety", w.safety),
            ("efficiency", w.efficiency),
        ] {
            r.num(&format!("weights.{name}"), v, 0.0, 1e3, "")?;
        }
        if w.completion + w.margin + w.preservation + w.safety + w.efficiency <= 0.0 {
            return Err(InputError::new(
                file,
                "weights",
                "at least one weight must be positive",
            ));
        }
        for (i, v) in self.vulnerable.iter().enumerate() {
            if !["renal_artery", "renal_vein", "ureter"].contains(&v.model.as_str()) {
                return Err(InputError::new(
                    file,
                    &format!("vulnerable[{i}].model"),
                    format!(
                        "unknown model '{}', expected renal_artery, renal_vein or ureter",
                        v.model
                    ),
                ));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::Tuning;

    #[test]
    fn tuned_values_are_written_into_their_table_keeping_comments() {
        let text = builtin("nephrectomy").expect("builtin");
        let before = Scenario::parse("s.toml", text).expect("parses");
        let t = Tuning {
            spring_n_per_m: 55.5,
            damping_per_s: 3.0,
            offset_m: 0.004,
        };
        let vals = |t: &Tuning| -> Vec<(String, f32)> {
            Tuning::RANGES
                .iter()
                .zip(t.values())
                .map(|((k, _, _), v)| ((*k).to_string(), v))
                .collect()
        };
        let out = with_values("s.toml", text, "kidney", &vals(&t)).expect("written");
        let after = Scenario::parse("s.toml", &out).expect("parses");
        assert_eq!(Tuning::of(&after.kidney), t);
        // The vessels keep their own values; every comment line survives; one line a key.
        assert_eq!(after.vessels, before.vessels);
        assert_eq!(out.lines().count(), text.lines().count());
        assert!(out.contains("spring_n_per_m = 55.5   # pull of each point"));
        assert!(out.contains("spring_n_per_m = 120.0"));
        // A missing key is added to the table; no kidney table is an error naming it.
        let short: String = text
            .lines()
            .filter(|l| !l.starts_with("offset_m = 0.002"))
            .map(|l| format!("{l}\n"))
            .collect();
        assert_ne!(short, text);
        let out = with_values("s.toml", &short, "kidney", &vals(&t)).expect("written");
        assert_eq!(
            Tuning::of(&Scenario::parse("s.toml", &out).expect("ok").kidney),
            t
        );
        let e = with_values(
            "s.toml",
            "procedure = \"nephrectomy\"\n",
            "kidney",
            &vals(&t),
        )
        .expect_err("no table");
        assert!(e.to_string().contains("s.toml") && e.to_string().contains("kidney"));
    }
}
