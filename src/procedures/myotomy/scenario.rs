//! The myotomy's scenario file: timing, the esophagus (its size, resolution, tissue and
//! pressure), the relaxation, the instruments and the task. Every number has its entry in a
//! parameter table; an error names the file, the key and the expected range.

use super::anatomy::EsophagusParams;
use crate::models::bem::contact::Prony;
use crate::param_fields;
use crate::params::{ParamSpec, Params};
use crate::scenario::InputError;
use serde::Deserialize;

/// The name scenarios and traces give this procedure.
pub const NAME: &str = "myotomy";

/// The esophagus's size, resolution, tissue and pressure.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EsophagusTable {
    pub length_m: f64,
    pub outer_radius_m: f64,
    pub wall_m: f64,
    pub around: u32,
    pub along: u32,
    pub young_pa: f64,
    pub poisson: f64,
    pub pressure_mmhg: f64,
    pub field_arc_deg: f64,
}

impl Params for EsophagusTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "length_m",
            "m",
            0.060,
            (0.02, 0.2),
            "the abdominal esophagus and sphincter's length, held at both ends (the diaphragm \
             above, the fundus below)",
        ),
        ParamSpec::new(
            "outer_radius_m",
            "m",
            0.010,
            (0.004, 0.03),
            "the tube's outer radius",
        ),
        ParamSpec::new(
            "wall_m",
            "m",
            0.004,
            (0.001, 0.01),
            "the wall's thickness (muscle and mucosa), below the outer radius",
        ),
        ParamSpec::new(
            "around",
            "divisions",
            30.0,
            (6.0, 64.0),
            "divisions around the tube (30 and 30 along: 3,720 triangles, the paper's size)",
        )
        .whole(),
        ParamSpec::new(
            "along",
            "divisions",
            30.0,
            (2.0, 64.0),
            "divisions along the tube",
        )
        .whole(),
        ParamSpec::new(
            "young_pa",
            "Pa",
            5222.0,
            (100.0, 1e7),
            "Young's modulus (the paper's 5.222 kPa, measured on living pigs)",
        ),
        ParamSpec::new(
            "poisson",
            "1",
            0.49,
            (0.0, 0.499),
            "Poisson's ratio: nearly incompressible tissue (Kelvin's solutions are singular at \
             0.5)",
        ),
        ParamSpec::new(
            "pressure_mmhg",
            "mmHg",
            30.0,
            (0.0, 200.0),
            "the pressure inside the lumen",
        ),
        ParamSpec::new(
            "field_arc_deg",
            "deg",
            90.0,
            (10.0, 360.0),
            "the anterior arc of the outer wall the instruments can touch (its elements' \
             responses are precomputed)",
        ),
    ];
    param_fields!(
        length_m,
        outer_radius_m,
        wall_m,
        around,
        along,
        young_pa,
        poisson,
        pressure_mmhg,
        field_arc_deg
    );
}

/// The one-term Prony series of the relaxation.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RelaxationTable {
    pub g1: f64,
    pub tau_s: f64,
}

impl Params for RelaxationTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "g1",
            "1",
            0.363,
            (0.0, 0.99),
            "the share of the stress that relaxes (0: purely elastic)",
        ),
        ParamSpec::new(
            "tau_s",
            "s",
            6.372,
            (0.01, 1000.0),
            "the relaxation's time constant",
        ),
    ];
    param_fields!(g1, tau_s);
}

/// The instruments.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tools {
    pub grasper_radius_m: f64,
    pub hook_radius_m: f64,
    pub trigger_threshold: f32,
    pub grip_threshold: f32,
    pub cut_depth_m_per_kpa: f64,
}

impl Params for Tools {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "grasper_radius_m",
            "m",
            0.004,
            (0.001, 0.015),
            "the left grasper's closed jaws as a round tip that palpates (and holds what it \
             touches when the grip closes it)",
        ),
        ParamSpec::new(
            "hook_radius_m",
            "m",
            0.002,
            (0.0005, 0.01),
            "the right hand's electrosurgical hook's end as a round tip",
        ),
        ParamSpec::new(
            "trigger_threshold",
            "1",
            0.5,
            (0.05, 1.0),
            "trigger travel that turns the hook's current on",
        ),
        ParamSpec::new(
            "grip_threshold",
            "1",
            0.5,
            (0.05, 1.0),
            "grip travel that closes the grasper",
        ),
        ParamSpec::new(
            "cut_depth_m_per_kpa",
            "m/kPa",
            0.0015,
            (1e-5, 0.05),
            "how deep the live hook cuts per kPa of contact pressure (force over contact area)",
        ),
    ];
    param_fields!(
        grasper_radius_m,
        hook_radius_m,
        trigger_threshold,
        grip_threshold,
        cut_depth_m_per_kpa
    );
}

/// The task: where the esophagogastric junction is, how far the myotomy must reach either
/// side of it, and how deep the muscle is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Task {
    pub junction_m: f64,
    pub above_m: f64,
    pub below_m: f64,
    pub muscle_m: f64,
    pub palpate_force_n: f64,
    pub target_time_s: f64,
}

impl Params for Task {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "junction_m",
            "m",
            0.045,
            (0.0, 0.2),
            "the esophagogastric junction's distance from the diaphragm along the tube",
        ),
        ParamSpec::new(
            "above_m",
            "m",
            0.025,
            (0.0, 0.2),
            "the myotomy reaches this far up the esophagus from the junction",
        ),
        ParamSpec::new(
            "below_m",
            "m",
            0.010,
            (0.0, 0.2),
            "and this far down onto the stomach",
        ),
        ParamSpec::new(
            "muscle_m",
            "m",
            0.003,
            (0.0005, 0.01),
            "the longitudinal and circular muscle's depth: cut to it to divide the muscle; \
             the mucosa lies below it, to the wall's inner surface (cutting that deep \
             perforates)",
        ),
        ParamSpec::new(
            "palpate_force_n",
            "N",
            0.05,
            (0.001, 5.0),
            "the force the grasper presses the sphincter with to feel it",
        ),
        crate::scenario::Timing::target_time(30.0, "an expert's time"),
    ];
    param_fields!(
        junction_m,
        above_m,
        below_m,
        muscle_m,
        palpate_force_n,
        target_time_s
    );
}

crate::scenario_tables! {
    dt: (0.001, "the simulation step: every step updates the contacts from the precomputed responses"),
    nodes: triangles,
    tables: [esophagus: EsophagusTable, relaxation: RelaxationTable, tools: Tools, task: Task],
}

impl Scenario {
    /// The tables' ranges, and the few rules between them.
    pub fn validate(&self, file: &str) -> Result<(), InputError> {
        self.validate_tables(file)?;
        let e = &self.esophagus;
        let (wall, of) = (e.wall_m, "80 % of the outer radius");
        crate::scenario::check_wall(file, "esophagus.wall_m", wall, (0.8, e.outer_radius_m), of)?;
        let k = &self.task;
        InputError::require(k.muscle_m < e.wall_m, file, "task.muscle_m", || {
            format!(
                "expected the muscle thinner than the wall ({} m), got {} m",
                e.wall_m, k.muscle_m
            )
        })?;
        let within = k.junction_m - k.above_m >= 0.0 && k.junction_m + k.below_m <= e.length_m;
        InputError::require(within, file, "task.junction_m", || {
            format!(
                "expected the myotomy ({} m above to {} m below the junction at {} m) within \
                 the esophagus's {} m",
                k.above_m, k.below_m, k.junction_m, e.length_m
            )
        })?;
        Ok(())
    }

    /// The esophagus's parameters.
    pub fn esophagus_params(&self) -> EsophagusParams {
        let e = &self.esophagus;
        EsophagusParams {
            length_m: e.length_m,
            outer_radius_m: e.outer_radius_m,
            wall_m: e.wall_m,
            around: e.around as usize,
            along: e.along as usize,
            young_pa: e.young_pa,
            poisson: e.poisson,
            pressure_mmhg: e.pressure_mmhg,
            field_arc_deg: e.field_arc_deg,
        }
    }

    /// The relaxation (none when `g1` is zero).
    pub fn prony(&self) -> Option<Prony> {
        let r = &self.relaxation;
        (r.g1 > 0.0).then_some(Prony {
            g1: r.g1,
            tau_s: r.tau_s,
        })
    }

    /// The surface's triangles (`2 around along` on the walls, `2 around` on the two end
    /// annuli), for the session's cost estimate.
    pub fn triangles(&self) -> u64 {
        let e = &self.esophagus;
        2 * u64::from(e.around) * (2 * u64::from(e.along) + 2)
    }
}
