//! The catheterisation's scenario file: timing, the vessel, the catheter, the contact law and
//! puncture, the device's mapping and the task. Every number has its entry in a parameter
//! table; an error names the file, the key and the expected range.

use crate::models::skeleton::catheter::CatheterParams;
use crate::models::skeleton::contact::ContactLaw;
use crate::models::skeleton::tree::TubeSpec;
use crate::models::skeleton::vessel::{Branch, VesselParams};
use crate::param_fields;
use crate::params::{ParamSpec, Params};
use crate::scenario::InputError;
use glam::DVec3;
use serde::Deserialize;

/// The name scenarios and traces give this procedure.
pub const NAME: &str = "catheter";

/// The vessel: its wall and materials, and the paper's bifurcation's size (unused when the
/// scenario has a `[tree]`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VesselTable {
    pub diameter_m: f64,
    pub wall_m: f64,
    pub trunk_m: f64,
    pub branch_m: f64,
    pub branch_angle_deg: f64,
    pub around: u32,
    pub ball_mass_kg: f64,
    pub spring_n_per_m: f64,
    pub damping_n_s_per_m: f64,
    pub tether_n_per_m: f64,
    pub section_m: f64,
}

impl Params for VesselTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "diameter_m",
            "m",
            0.020,
            (0.004, 0.05),
            "the vessel's outer diameter",
        ),
        ParamSpec::new(
            "wall_m",
            "m",
            0.002,
            (0.0005, 0.01),
            "the wall's thickness (its balls' diameter)",
        ),
        ParamSpec::new(
            "trunk_m",
            "m",
            0.060,
            (0.02, 1.0),
            "the trunk's length, from the inlet (held) to the bifurcation",
        ),
        ParamSpec::new("branch_m", "m", 0.060, (0.02, 1.0), "each branch's length"),
        ParamSpec::new(
            "branch_angle_deg",
            "deg",
            30.0,
            (10.0, 80.0),
            "each branch's angle to the trunk's axis",
        ),
        ParamSpec::new(
            "around",
            "balls",
            16.0,
            (6.0, 64.0),
            "balls around each ring of the wall's central surface",
        )
        .whole(),
        ParamSpec::new(
            "ball_mass_kg",
            "kg",
            0.002,
            (1e-5, 0.1),
            "each wall ball's mass (the paper's 0.002 kg)",
        ),
        ParamSpec::new(
            "spring_n_per_m",
            "N/m",
            100.0,
            (1.0, 1e5),
            "the wall's springs between neighbouring balls (the paper's elastic coefficient)",
        ),
        ParamSpec::new(
            "damping_n_s_per_m",
            "N s/m",
            0.3,
            (0.0, 100.0),
            "the springs' damping (the paper's 0.3 N/(m/s))",
        ),
        ParamSpec::new(
            "tether_n_per_m",
            "N/m",
            20.0,
            (0.0, 1e5),
            "each wall ball's tie to where it rests: the tissue around the vessel (ours; the paper holds only the inlet)",
        ),
        ParamSpec::new(
            "section_m",
            "m",
            0.010,
            (0.002, 0.1),
            "the collision's sections along each tube",
        ),
    ];
    param_fields!(
        diameter_m,
        wall_m,
        trunk_m,
        branch_m,
        branch_angle_deg,
        around,
        ball_mass_kg,
        spring_n_per_m,
        damping_n_s_per_m,
        tether_n_per_m,
        section_m
    );
}

/// The catheter (the paper gives its size; the materials are ours).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CatheterTable {
    pub length_m: f64,
    pub diameter_m: f64,
    pub density_kg_per_m3: f64,
    pub axial_n_per_m: f64,
    pub damping_n_s_per_m: f64,
    pub bending_n_per_m: f64,
    pub torsion_n_m_per_rad: f64,
    pub torsion_damping: f64,
    pub bend_length_m: f64,
    pub max_bend_deg: f64,
    pub substeps: u32,
}

impl Params for CatheterTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "length_m",
            "m",
            0.100,
            (0.02, 2.0),
            "the catheter's length (the paper's 100 mm)",
        ),
        ParamSpec::new(
            "diameter_m",
            "m",
            0.010,
            (0.001, 0.02),
            "its diameter (the paper's 10 mm; its balls are as wide)",
        ),
        ParamSpec::new(
            "density_kg_per_m3",
            "kg/m^3",
            1100.0,
            (100.0, 10000.0),
            "the polymer's density: each ball's mass is its share of the rod",
        ),
        ParamSpec::new(
            "axial_n_per_m",
            "N/m",
            2000.0,
            (10.0, 1e5),
            "each segment's axial spring",
        ),
        ParamSpec::new(
            "damping_n_s_per_m",
            "N s/m",
            0.3,
            (0.0, 100.0),
            "the axial and bending springs' damping",
        ),
        ParamSpec::new(
            "bending_n_per_m",
            "N/m",
            200.0,
            (1.0, 1e5),
            "the bending stiffness as a sideways force per metre at one segment's length",
        ),
        ParamSpec::new(
            "torsion_n_m_per_rad",
            "N m/rad",
            1e-3,
            (1e-6, 1.0),
            "between neighbouring balls' twist",
        ),
        ParamSpec::new(
            "torsion_damping",
            "N m s/rad",
            1e-5,
            (0.0, 1e-2),
            "of neighbouring balls' relative spin",
        ),
        ParamSpec::new(
            "bend_length_m",
            "m",
            0.030,
            (0.005, 0.5),
            "the tip's part that bends actively",
        ),
        ParamSpec::new(
            "max_bend_deg",
            "deg",
            45.0,
            (1.0, 90.0),
            "its largest bending angle (half the arc's turning)",
        ),
        ParamSpec::new(
            "substeps",
            "substeps",
            10.0,
            (1.0, 64.0),
            "the catheter's sub-steps per step (the vessel steps once)",
        )
        .whole(),
    ];
    param_fields!(
        length_m,
        diameter_m,
        density_kg_per_m3,
        axial_n_per_m,
        damping_n_s_per_m,
        bending_n_per_m,
        torsion_n_m_per_rad,
        torsion_damping,
        bend_length_m,
        max_bend_deg,
        substeps
    );
}

/// The contact law (eqs 8-10) and the wall's puncture.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactTable {
    pub stiffness_n_per_m: f64,
    pub damping_n_s_per_m: f64,
    pub preload_n: f64,
    pub friction: f64,
    pub puncture_n: f64,
}

impl Params for ContactTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "stiffness_n_per_m",
            "N/m",
            500.0,
            (1.0, 1e5),
            "k of F_N = k D + c v + t (the paper's 500 N/m: with t, 0.5 N at first touch to 3.5 N at a full ball's depth, the paper's measured range)",
        ),
        ParamSpec::new(
            "damping_n_s_per_m",
            "N s/m",
            0.3,
            (0.0, 100.0),
            "c of the normal force",
        ),
        ParamSpec::new(
            "preload_n",
            "N",
            0.5,
            (0.0, 5.0),
            "t of the normal force: what a touching wall pushes with at zero depth",
        ),
        ParamSpec::new(
            "friction",
            "1",
            0.1,
            (0.0, 2.0),
            "mu: the friction along the wall is mu |F_N| (a wet vessel wall on a polymer catheter)",
        ),
        ParamSpec::new(
            "puncture_n",
            "N",
            3.0,
            (0.1, 50.0),
            "a wall ball pushed harder than this gives way (a puncture)",
        ),
    ];
    param_fields!(
        stiffness_n_per_m,
        damping_n_s_per_m,
        preload_n,
        friction,
        puncture_n
    );
}

/// How the device drives the catheter.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceTable {
    pub twist_deg: f64,
    pub max_force_n: f64,
}

impl Params for DeviceTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "twist_deg",
            "deg",
            180.0,
            (10.0, 720.0),
            "the twist at full grip (the device's handle travel along the vessel's entry is the insertion; its trigger the bend)",
        ),
        ParamSpec::new(
            "max_force_n",
            "N",
            9.0,
            (0.5, 50.0),
            "the device's largest force (the Novint Falcon's 9 N)",
        ),
    ];
    param_fields!(twist_deg, max_force_n);
}

/// The task: which branch, how far into it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Task {
    pub branch: u32,
    pub reach_m: f64,
    pub target_time_s: f64,
}

impl Params for Task {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new("branch", "1", 2.0, (1.0, 2.0), "the target branch: 1 leaves towards +y, 2 towards -y (the tip bends towards +y untwisted)").whole(),
        ParamSpec::new("reach_m", "m", 0.030, (0.005, 1.0), "how far into the branch the tip must go"),
        crate::scenario::Timing::target_time(10.0, "an expert's time"),
    ];
    param_fields!(branch, reach_m, target_time_s);
}

crate::scenario_tables! {
    dt: (0.001, "the simulation step: the Falcon's 1 kHz servo period"),
    nodes: balls,
    tables: [vessel: VesselTable, catheter: CatheterTable, contact: ContactTable,
        device: DeviceTable, task: Task,
        #[serde(default = "super::fluoroscopy::table_default")]
        fluoroscopy: super::fluoroscopy::FluoroTable],
    extra: [
        /// Optional: a guidewire in the catheter's lumen, under the left hand.
        #[serde(default)]
        guidewire: Option<super::wire_table::GuidewireTable>,
        /// Optional: the vessel tree from centrelines (else the paper's bifurcation).
        #[serde(default)]
        tree: Option<super::tree_table::TreeTable>,
    ],
}

impl Scenario {
    /// The tables' ranges, and the rules between them.
    pub fn validate(&self, file: &str) -> Result<(), InputError> {
        self.validate_tables(file)?;
        let v = &self.vessel;
        let of = "a quarter of the diameter";
        crate::scenario::check_wall(file, "vessel.wall_m", v.wall_m, (0.25, v.diameter_m), of)?;
        let lumen = v.diameter_m - 2.0 * v.wall_m;
        let c = self.catheter.diameter_m;
        InputError::require(c < lumen, file, "catheter.diameter_m", || {
            format!("expected a catheter narrower than the lumen ({lumen} m), got {c} m")
        })?;
        if let Some(w) = &self.guidewire {
            crate::params::validate(file, "guidewire", w)?;
            let d = w.diameter_m;
            InputError::require(d < 0.5 * c, file, "guidewire.diameter_m", || {
                format!("expected a wire narrower than half the catheter ({c} m), got {d} m")
            })?;
            InputError::require(
                w.tip_length_m < w.length_m,
                file,
                "guidewire.tip_length_m",
                || {
                    format!(
                        "expected a soft tip shorter than the wire's {} m, got {} m",
                        w.length_m, w.tip_length_m
                    )
                },
            )?;
        }
        let reach = self.task.reach_m;
        match &self.tree {
            Some(t) => t.validate(file, v.wall_m, c, reach)?,
            None => InputError::require(reach <= v.branch_m, file, "task.reach_m", || {
                format!(
                    "expected a reach within the branch's {} m, got {reach} m",
                    v.branch_m
                )
            })?,
        }
        Ok(())
    }

    /// The vessel's tubes and named vessels: the tree's, else the paper's bifurcation.
    pub fn vessel_shape(&self) -> (Vec<TubeSpec>, Vec<Branch>) {
        match &self.tree {
            Some(t) => t.tubes(),
            None => self.vessel_params().bifurcation(),
        }
    }

    /// The vessel the task asks to cannulate: the tree's named target, else `task.branch`.
    pub fn target_branch(&self) -> usize {
        match &self.tree {
            Some(t) => t.target_index().unwrap_or(1),
            None => self.task.branch as usize,
        }
    }

    /// Where the patient's head lies (+x unless the tree says otherwise).
    pub fn head(&self) -> DVec3 {
        self.tree.as_ref().map_or(DVec3::X, |t| t.head())
    }

    pub fn vessel_params(&self) -> VesselParams {
        let v = &self.vessel;
        VesselParams {
            diameter_m: v.diameter_m,
            wall_m: v.wall_m,
            trunk_m: v.trunk_m,
            branch_m: v.branch_m,
            branch_angle_deg: v.branch_angle_deg,
            around: v.around as usize,
            ball_mass_kg: v.ball_mass_kg,
            spring_n_per_m: v.spring_n_per_m,
            damping_n_s_per_m: v.damping_n_s_per_m,
            tether_n_per_m: v.tether_n_per_m,
            section_m: v.section_m,
        }
    }

    pub fn catheter_params(&self) -> CatheterParams {
        let c = &self.catheter;
        CatheterParams {
            length_m: c.length_m,
            diameter_m: c.diameter_m,
            density_kg_per_m3: c.density_kg_per_m3,
            axial_n_per_m: c.axial_n_per_m,
            damping_n_s_per_m: c.damping_n_s_per_m,
            bending_n_per_m: c.bending_n_per_m,
            torsion_n_m_per_rad: c.torsion_n_m_per_rad,
            torsion_damping: c.torsion_damping,
            bend_length_m: c.bend_length_m,
            max_bend_deg: c.max_bend_deg,
        }
    }

    pub fn law(&self) -> ContactLaw {
        let c = &self.contact;
        ContactLaw {
            stiffness_n_per_m: c.stiffness_n_per_m,
            damping_n_s_per_m: c.damping_n_s_per_m,
            preload_n: c.preload_n,
            friction: c.friction,
        }
    }

    /// Balls the vessel and the catheter will have, roughly (for the cost estimate).
    pub fn balls(&self) -> u64 {
        let v = &self.vessel;
        let spacing = std::f64::consts::PI * (v.diameter_m - v.wall_m) / f64::from(v.around);
        let length = match &self.tree {
            Some(t) => t.centrelines().iter().map(|c| c.length_m()).sum(),
            None => v.trunk_m + 2.0 * v.branch_m,
        };
        let rings = length / spacing;
        let catheter = self.catheter.length_m / (0.5 * self.catheter.diameter_m);
        (rings * f64::from(v.around) + catheter) as u64
    }
}
