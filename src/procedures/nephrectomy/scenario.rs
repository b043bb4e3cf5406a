//! The nephrectomy's scenario file: timing, anatomy, the kidney's and the vessels' soft
//! bodies, the instruments, the task, the vulnerable structures and the score's weights.
//! Every number has its entry in a parameter table (key, unit, default, range, what it does);
//! the tables check the ranges, and the checks that tie values together follow by hand. An
//! error names the file, the key and what is expected.

use super::NAME;
use crate::models::SoftBodyParams;
use crate::params::{ParamSpec, Params};
use crate::scenario::{InputError, MAX_NODES, MIN_DIRECTION_LENGTH};
use serde::Deserialize;
use std::path::Path;

/// The vessels a scenario may call vulnerable.
pub const VULNERABLE_MODELS: [&str; 3] = ["renal_artery", "renal_vein", "ureter"];

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Anatomy {
    /// Icosphere subdivision level of kidney and tumour (5 = full scene, 3 = coarse).
    pub level: u32,
    /// Half the kidney's length along +y (superior), m.
    pub kidney_half_length_m: f32,
    /// Half its width along +x (lateral), m.
    pub kidney_half_width_m: f32,
    /// Half its thickness along +z (anterior), m.
    pub kidney_half_thickness_m: f32,
    /// Depth of the hilum's notch in the medial border, m.
    pub hilum_depth_m: f32,
    /// Tumour radius, m (the paper's case: a 3-5 cm mass).
    pub tumour_radius_m: f32,
    /// Direction from the kidney centre to the tumour site (normalised on load). Its
    /// components are table entries `tumour_direction[0]` to `[2]`.
    pub tumour_direction: [f32; 3],
    /// How far the tumour centre stands out of the surface, in tumour radii (exophytic > 0).
    pub tumour_protrusion: f32,
    /// Points around each vessel.
    pub vessel_segments: u32,
    /// Rings along each vessel.
    pub vessel_rings: u32,
    /// Renal artery radius, m.
    pub renal_artery_radius_m: f32,
    /// Renal vein radius, m.
    pub renal_vein_radius_m: f32,
    /// Ureter radius, m.
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

/// Weights of the score's five components (relative: the score divides by their sum).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Weights {
    pub completion: f32,
    pub margin: f32,
    pub preservation: f32,
    pub safety: f32,
    pub efficiency: f32,
}

/// A vessel's radius: the same range for the three.
const VESSEL_RADIUS: ParamSpec = ParamSpec::new("", "m", 0.0, (5e-4, 0.02), "");

/// A component of the tumour's direction: any finite size (the direction is normalised on
/// load, and a hand check refuses one too short to normalise).
const DIRECTION: ParamSpec = ParamSpec::new("", "", 0.0, (-1e3, 1e3), "");

impl Params for Anatomy {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "level",
            "",
            5.0,
            (1.0, 7.0),
            "icosphere subdivision level of kidney and tumour (5: 20480 triangles each, the \
             full scene; 3: coarse)",
        )
        .whole(),
        ParamSpec::new(
            "kidney_half_length_m",
            "m",
            0.055,
            (0.01, 0.2),
            "half the kidney's length along +y, superior (an adult kidney: 11 cm long)",
        ),
        ParamSpec::new(
            "kidney_half_width_m",
            "m",
            0.03,
            (0.005, 0.2),
            "half its width along +x, lateral (6 cm wide)",
        ),
        ParamSpec::new(
            "kidney_half_thickness_m",
            "m",
            0.02,
            (0.005, 0.2),
            "half its thickness along +z, anterior (4 cm thick)",
        ),
        ParamSpec::new(
            "hilum_depth_m",
            "m",
            0.012,
            (0.0, 0.05),
            "depth of the hilum's notch in the medial border, where the vessels enter",
        ),
        ParamSpec::new(
            "tumour_radius_m",
            "m",
            0.02,
            (0.005, 0.05),
            "tumour radius (the paper's case: a 3-5 cm renal-cell carcinoma; 4 cm here)",
        ),
        ParamSpec::of(
            DIRECTION,
            "tumour_direction[0]",
            0.3,
            "direction from the kidney's centre to the tumour site, x (lateral); the \
             direction is normalised on load and must have a length of at least 1e-6",
        ),
        ParamSpec::of(
            DIRECTION,
            "tumour_direction[1]",
            0.45,
            "its y (superior) component: the default is the anterior surface of the upper pole",
        ),
        ParamSpec::of(
            DIRECTION,
            "tumour_direction[2]",
            0.85,
            "its z (anterior) component",
        ),
        ParamSpec::new(
            "tumour_protrusion",
            "radii",
            0.6,
            (0.0, 0.95),
            "how far the tumour's centre stands out of the kidney's surface, in tumour radii \
             (above 0: exophytic)",
        ),
        ParamSpec::new(
            "vessel_segments",
            "",
            32.0,
            (3.0, 256.0),
            "points around each vessel",
        )
        .whole(),
        ParamSpec::new(
            "vessel_rings",
            "",
            64.0,
            (2.0, 1024.0),
            "rings along each vessel (32 x 64: 4096 triangles a vessel)",
        )
        .whole(),
        ParamSpec::of(
            VESSEL_RADIUS,
            "renal_artery_radius_m",
            0.003,
            "renal artery radius",
        ),
        ParamSpec::of(
            VESSEL_RADIUS,
            "renal_vein_radius_m",
            0.005,
            "renal vein radius",
        ),
        ParamSpec::of(VESSEL_RADIUS, "ureter_radius_m", 0.0025, "ureter radius"),
    ];

    fn get(&self, key: &str) -> Option<f64> {
        Some(match key {
            "level" => self.level.into(),
            "kidney_half_length_m" => self.kidney_half_length_m.into(),
            "kidney_half_width_m" => self.kidney_half_width_m.into(),
            "kidney_half_thickness_m" => self.kidney_half_thickness_m.into(),
            "hilum_depth_m" => self.hilum_depth_m.into(),
            "tumour_radius_m" => self.tumour_radius_m.into(),
            "tumour_direction[0]" => self.tumour_direction[0].into(),
            "tumour_direction[1]" => self.tumour_direction[1].into(),
            "tumour_direction[2]" => self.tumour_direction[2].into(),
            "tumour_protrusion" => self.tumour_protrusion.into(),
            "vessel_segments" => self.vessel_segments.into(),
            "vessel_rings" => self.vessel_rings.into(),
            "renal_artery_radius_m" => self.renal_artery_radius_m.into(),
            "renal_vein_radius_m" => self.renal_vein_radius_m.into(),
            "ureter_radius_m" => self.ureter_radius_m.into(),
            _ => return None,
        })
    }

    fn set(&mut self, key: &str, v: f64) -> bool {
        let f = v as f32;
        // Whole numbers saturate at 0 and u32::MAX (`as` does); the table checks the range.
        let n = v as u32;
        match key {
            "level" => self.level = n,
            "kidney_half_length_m" => self.kidney_half_length_m = f,
            "kidney_half_width_m" => self.kidney_half_width_m = f,
            "kidney_half_thickness_m" => self.kidney_half_thickness_m = f,
            "hilum_depth_m" => self.hilum_depth_m = f,
            "tumour_radius_m" => self.tumour_radius_m = f,
            "tumour_direction[0]" => self.tumour_direction[0] = f,
            "tumour_direction[1]" => self.tumour_direction[1] = f,
            "tumour_direction[2]" => self.tumour_direction[2] = f,
            "tumour_protrusion" => self.tumour_protrusion = f,
            "vessel_segments" => self.vessel_segments = n,
            "vessel_rings" => self.vessel_rings = n,
            "renal_artery_radius_m" => self.renal_artery_radius_m = f,
            "renal_vein_radius_m" => self.renal_vein_radius_m = f,
            "ureter_radius_m" => self.ureter_radius_m = f,
            _ => return false,
        }
        true
    }
}

/// The laser's pressure where it cuts (eq 4); the supervisor may tune it live.
pub const LASER_PRESSURE: ParamSpec = ParamSpec::new(
    "laser_pressure_pa",
    "Pa",
    400.0,
    (0.0, 1e5),
    "pressure the laser applies to the tissue where it cuts (eq 4: P n dA)",
)
.tune(0.0, 10_000.0);

impl Params for Tools {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "laser_range_m",
            "m",
            0.5,
            (0.01, 5.0),
            "reach of the laser pointer's beam",
        ),
        ParamSpec::new(
            "cut_threshold",
            "",
            0.5,
            (0.01, 1.0),
            "trigger value (0 to 1) above which the laser cuts",
        ),
        LASER_PRESSURE,
    ];

    crate::param_fields!(laser_range_m, cut_threshold, laser_pressure_pa);
}

impl Params for Task {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "margin_m",
            "m",
            0.005,
            (0.0, 0.03),
            "intended margin of healthy tissue around the tumour (5 mm)",
        ),
        // No range before the table: 0 marks would never complete the marking step.
        ParamSpec::new(
            "marks_required",
            "",
            6.0,
            (1.0, 1000.0),
            "margin marks on the intended margin needed before the marking step is done",
        )
        .whole(),
        ParamSpec::new(
            "mark_tolerance_m",
            "m",
            0.003,
            (1e-4, 0.03),
            "a mark counts if it lies within this distance of the intended margin",
        ),
        ParamSpec::new(
            "removal_distance_m",
            "m",
            0.02,
            (1e-3, 0.3),
            "the freed tumour counts as removed once lifted this far out of its bed",
        ),
        crate::scenario::Timing::target_time(60.0, crate::scenario::Timing::TARGET_TIME_DOC),
    ];

    crate::param_fields!(
        margin_m,
        marks_required,
        mark_tolerance_m,
        removal_distance_m,
        target_time_s
    );
}

/// A score component's weight: relative, 0 leaves the component out.
const WEIGHT: ParamSpec = ParamSpec::new("", "", 0.0, (0.0, 1e3), "");

impl Params for Weights {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::of(
            WEIGHT,
            "completion",
            30.0,
            "weight of the fraction of the four task steps done",
        ),
        ParamSpec::of(
            WEIGHT,
            "margin",
            25.0,
            "weight of exp(-mean cut deviation from the margin / 2 mm)",
        ),
        ParamSpec::of(
            WEIGHT,
            "preservation",
            15.0,
            "weight of 1 - excess healthy tissue removed / planned",
        ),
        ParamSpec::of(
            WEIGHT,
            "safety",
            20.0,
            "weight of 1 / (1 + vessel contacts + torn ties + faces cut into the tumour / 10); \
             at least one weight must be above 0",
        ),
        ParamSpec::of(
            WEIGHT,
            "efficiency",
            10.0,
            "weight of target time / completion time (0 if not completed)",
        ),
    ];

    crate::param_fields!(completion, margin, preservation, safety, efficiency);
}

crate::scenario_tables! {
    dt: (0.004, "simulation step (0.004: 250 Hz; a force-feedback servo renders at 1 kHz between steps)"),
    nodes: estimated_nodes,
    tables: [anatomy: Anatomy, kidney: SoftBodyParams, vessels: SoftBodyParams, tools: Tools,
        grasper: crate::scenario::Grasper, task: Task, weights: Weights],
    extra: [
        vulnerable: Vec<Vulnerable>,
    ],
    moved: crate::scenario::Grasper::MOVED_FROM_TOOLS,
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

    pub fn load(path: &Path) -> Result<Self, InputError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| InputError::new(&file, "file", format!("cannot read: {e}")))?;
        Self::parse(&file, &text)
    }

    /// The tables' ranges, then the checks that tie values together.
    pub fn validate(&self, file: &str) -> Result<(), InputError> {
        self.validate_tables(file)?;
        let a = &self.anatomy;
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
        let w = &self.weights;
        if w.completion + w.margin + w.preservation + w.safety + w.efficiency <= 0.0 {
            return Err(InputError::new(
                file,
                "weights",
                "at least one weight must be positive",
            ));
        }
        for (i, v) in self.vulnerable.iter().enumerate() {
            if !VULNERABLE_MODELS.contains(&v.model.as_str()) {
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
    use crate::scenario::{InputError, with_values};

    /// The tuned text is checked as a scenario of this procedure.
    fn own(text: &str) -> Result<(), InputError> {
        (super::super::INFO.plan)("s.toml", text).map(|_| ())
    }

    fn shipped() -> Scenario {
        Scenario::parse("nephrectomy.toml", super::super::INFO.scenario).expect("parses")
    }

    #[test]
    fn tuned_values_are_written_into_their_table_keeping_comments() {
        let text = super::super::INFO.scenario;
        let before = Scenario::parse("s.toml", text).expect("parses");
        let t = Tuning {
            foundation_pa_per_m: 2.5e6,
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
        let out = with_values(&own, "s.toml", text, "kidney", &vals(&t)).expect("written");
        let after = Scenario::parse("s.toml", &out).expect("parses");
        assert_eq!(Tuning::of(&after.kidney), t);
        // The vessels keep their own values; every comment line survives; one line a key.
        assert_eq!(after.vessels, before.vessels);
        assert_eq!(out.lines().count(), text.lines().count());
        assert!(out.contains("foundation_pa_per_m = 2500000.0"));
        assert!(out.contains("# Winkler modulus: eq 2's spring per unit area"));
        assert!(out.contains("foundation_pa_per_m = 4e6           # vessel walls"));
        // A missing key is added to the table; no kidney table is an error naming it.
        let short: String = text
            .lines()
            .filter(|l| !l.starts_with("offset_m = 0.002"))
            .map(|l| format!("{l}\n"))
            .collect();
        assert_ne!(short, text);
        let out = with_values(&own, "s.toml", &short, "kidney", &vals(&t)).expect("written");
        assert_eq!(
            Tuning::of(&Scenario::parse("s.toml", &out).expect("ok").kidney),
            t
        );
        let e = with_values(
            &own,
            "s.toml",
            "procedure = \"nephrectomy\"\n",
            "kidney",
            &vals(&t),
        )
        .expect_err("no table");
        assert!(e.to_string().contains("s.toml") && e.to_string().contains("kidney"));
    }

    /// Every key of every table names its own field: a distinct value set through the key
    /// reads back through it and changes no other key.
    #[test]
    fn every_table_key_reads_and_writes_its_own_field() {
        let s = shipped();
        crate::params::assert_round_trip(&s.timing());
        crate::params::assert_round_trip(&s.anatomy);
        crate::params::assert_round_trip(&s.tools);
        crate::params::assert_round_trip(&s.task);
        crate::params::assert_round_trip(&s.weights);
    }

    #[test]
    fn checks_that_tie_values_together_follow_the_tables() {
        let text = super::super::INFO.scenario;
        let bad = |from: &str, to: &str| {
            assert!(text.contains(from), "{from}");
            Scenario::parse("bad.toml", &text.replacen(from, to, 1)).expect_err(to)
        };
        let e = bad("[0.3, 0.45, 0.85]", "[0.0, 0.0, 1e-9]");
        assert_eq!(e.key, "anatomy.tumour_direction");
        assert!(e.message.contains("length must be at least"), "{e}");
        let e = bad("[0.3, 0.45, 0.85]", "[0.3, nan, 0.85]");
        assert_eq!(e.key, "anatomy.tumour_direction[1]");
        // The finest level and the most vessel points are each in range, together too many.
        let fine = text
            .replacen("level = 5 ", "level = 7 ", 1)
            .replacen("vessel_segments = 32", "vessel_segments = 256", 1)
            .replacen("vessel_rings = 64 ", "vessel_rings = 1024 ", 1);
        let e = Scenario::parse("bad.toml", &fine).expect_err("too many points");
        assert_eq!(e.key, "anatomy", "{e}");
        assert!(e.message.contains("simulated points"), "{e}");
        let zero = [
            "completion",
            "margin",
            "preservation",
            "safety",
            "efficiency",
        ]
        .iter()
        .fold(text.to_string(), |t, k| {
            let line = t
                .lines()
                .find(|l| l.starts_with(&format!("{k} = ")))
                .expect("weight line")
                .to_string();
            t.replacen(&line, &format!("{k} = 0.0"), 1)
        });
        let e = Scenario::parse("bad.toml", &zero).expect_err("no weight");
        assert_eq!(e.key, "weights", "{e}");
        let e = bad("model = \"renal_vein\"", "model = \"liver\"");
        assert_eq!(e.key, "vulnerable[1].model", "{e}");
        // A range error reads like the other scenario readers' ("0.3", not its f64 digits).
        let e = bad("tumour_protrusion = 0.6", "tumour_protrusion = 0.96");
        assert_eq!(
            e.to_string(),
            "bad.toml: anatomy.tumour_protrusion: must be between 0 and 0.95 radii, got 0.96"
        );
        let e = bad("level = 5 ", "level = 0 ");
        assert_eq!(
            e.to_string(),
            "bad.toml: anatomy.level: must be a whole number between 1 and 7, got 0"
        );
    }
}
