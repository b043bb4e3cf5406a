//! The rectum's scenario file: timing, the anatomy (section length, radii, the membrane's
//! grid), the membrane's tissues, the instruments and the task (the dissection target's
//! extent). Every number has its entry in a parameter table; the checks that tie values
//! together follow by hand. An error names the file, the key and the expected range.

use super::anatomy::AnatomyParams;
use super::scene::{SceneParams, membrane_params};
use crate::models::membrane::{Integrator, LAYERS, LayerMaterial};
use crate::params::{ParamSpec, Params};
use crate::scenario::InputError;
use serde::Deserialize;

/// The name scenarios and traces give this procedure.
pub const NAME: &str = "rectum";

/// The generated anatomy ([`AnatomyParams`]).
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnatomyTable {
    pub length_m: f32,
    pub rectum_radius_m: f32,
    pub pelvis_radius_m: f32,
    pub fat_depth_m: f32,
    pub wall_depth_m: f32,
    pub rows: u32,
    pub cols: u32,
}

/// The membrane's tissues ([`membrane_params`] documents the defaults).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MembraneTable {
    /// `symplectic` or `runge_kutta_4`.
    pub integrator: String,
    pub sheet_modulus_pa: f32,
    pub sheet_thickness_m: f32,
    pub density_kg_per_m3: f32,
    pub fat_modulus_pa: f32,
    pub plane_modulus_pa: f32,
    pub damping_per_s: f32,
    pub spring_damping_ratio: f32,
    /// Optional (files from before it have none: the links then take 0.5).
    #[serde(default = "link_damping_default")]
    pub link_damping_ratio: f32,
    pub residual_strain: f32,
    /// Rows of a tile of the active set (along the bowel).
    #[serde(default = "tile_rows_default")]
    pub tile_rows: u32,
    /// Columns of a tile of the active set (around the bowel).
    #[serde(default = "tile_cols_default")]
    pub tile_cols: u32,
}

fn link_damping_default() -> f32 {
    0.5
}

fn tile_rows_default() -> u32 {
    crate::models::membrane::TILE_ROWS as u32
}

fn tile_cols_default() -> u32 {
    crate::models::membrane::TILE_COLS as u32
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tools {
    /// The hook's penalty on membrane nodes per unit of their area, Pa/m.
    pub hook_stiffness_pa_per_m: f32,
    /// Radius of the sphere at the hook's end whose plane springs a cut removes, m.
    pub cut_radius_m: f32,
    /// Trigger value at or above which the hook's current is on.
    pub cut_threshold: f32,
    /// Grip value at or above which the grasper closes.
    pub grip_threshold: f32,
}

#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Task {
    /// The target's rows: fractions of the section's length from its top end.
    pub target_from: f32,
    pub target_to: f32,
    /// The target's arc, degrees from the front (anterior) towards the patient's left.
    pub target_arc_from_deg: f32,
    pub target_arc_to_deg: f32,
    /// How far the grasper must lift the rectum to expose the plane, m.
    pub expose_lift_m: f32,
    /// A lift past this overexposes the plane (the rectum pulled off its bed), m.
    pub overexposed_lift_m: f32,
    /// A vulnerable structure is "near" an instrument within this distance, m.
    pub near_m: f32,
    /// Time an expert needs, s.
    pub target_time_s: f32,
}

/// Most membrane nodes a scenario may ask for (the paper's 600 x 400 x 4 is 960,000).
pub const MAX_NODES: u64 = 1_000_000;

impl Params for AnatomyTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "length_m",
            "m",
            0.15,
            (0.03, 0.3),
            "length of the rectal section modelled, along its medial axis (on the sacral \
             curve of 12 cm radius)",
        ),
        ParamSpec::new(
            "rectum_radius_m",
            "m",
            0.02,
            (0.005, 0.04),
            "the rectum's outer radius (a 4 cm bowel, distended)",
        ),
        ParamSpec::new(
            "pelvis_radius_m",
            "m",
            0.034,
            (0.01, 0.08),
            "radius of the pelvic tube around it (layer 4 of the membrane)",
        ),
        ParamSpec::new(
            "fat_depth_m",
            "m",
            0.01,
            (0.001, 0.03),
            "depth of the mesorectal fat: layer 2 this far out from layer 1",
        ),
        ParamSpec::new(
            "wall_depth_m",
            "m",
            0.0025,
            (0.0005, 0.02),
            "depth of the presacral tissue: layer 3 this far in from layer 4",
        ),
        ParamSpec::new(
            "rows",
            "nodes",
            600.0,
            (8.0, 2000.0),
            "membrane nodes along the section, per layer (the paper's 600)",
        )
        .whole(),
        ParamSpec::new(
            "cols",
            "nodes",
            400.0,
            (16.0, 2000.0),
            "membrane nodes around it, per layer (the paper's 400)",
        )
        .whole(),
    ];

    crate::param_fields!(
        length_m,
        rectum_radius_m,
        pelvis_radius_m,
        fat_depth_m,
        wall_depth_m,
        rows,
        cols,
    );
}

impl Params for MembraneTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "sheet_modulus_pa",
            "Pa",
            5e3,
            (100.0, 1e6),
            "Young's modulus of the four sheets (loose connective tissue; the stable explicit \
             step shrinks as its square root grows)",
        ),
        ParamSpec::new(
            "sheet_thickness_m",
            "m",
            5e-4,
            (1e-5, 0.005),
            "thickness of each sheet: the nodes' mass and the springs' stiffness",
        ),
        ParamSpec::new(
            "density_kg_per_m3",
            "kg/m^3",
            1000.0,
            (500.0, 2000.0),
            "density of the sheets",
        ),
        ParamSpec::new(
            "fat_modulus_pa",
            "Pa",
            2e3,
            (10.0, 1e6),
            "Young's modulus of the links 1-2 and 3-4 (mesorectal and presacral fat)",
        ),
        ParamSpec::new(
            "plane_modulus_pa",
            "Pa",
            1e3,
            (10.0, 1e6),
            "Young's modulus of the links 2-3, the dissection plane (areolar tissue)",
        ),
        ParamSpec::new(
            "damping_per_s",
            "1/s",
            20.0,
            (0.0, 1e4),
            "point damping of every node (eq 4's damping force over mass)",
        ),
        ParamSpec::new(
            "spring_damping_ratio",
            "",
            0.5,
            (0.0, 2.0),
            "damping along the springs within a layer, as a fraction of critical at the \
             grid's highest mode (a grid s times coarser keeps the tissue's viscosity with 1/s \
             of it)",
        ),
        ParamSpec::new(
            "link_damping_ratio",
            "",
            0.5,
            (0.0, 2.0),
            "damping along the links between layers, as a fraction of critical for a layer \
             bouncing on its links (the same tissue at any spacing)",
        ),
        ParamSpec::new(
            "residual_strain",
            "",
            0.1,
            (0.0, 0.5),
            "eq 5's residual strain: a freed sheet shrinks by this fraction (the paper's 0.1)",
        ),
        ParamSpec::new(
            "tile_rows",
            "nodes",
            8.0,
            (2.0, 32.0),
            "rows of a tile of the active set (only tiles near the instruments step; the GPU's \
             kernels take 8 x 16)",
        )
        .whole(),
        ParamSpec::new(
            "tile_cols",
            "nodes",
            16.0,
            (4.0, 64.0),
            "columns of a tile of the active set",
        )
        .whole(),
    ];

    crate::param_fields!(
        sheet_modulus_pa,
        sheet_thickness_m,
        density_kg_per_m3,
        fat_modulus_pa,
        plane_modulus_pa,
        damping_per_s,
        spring_damping_ratio,
        link_damping_ratio,
        residual_strain,
        tile_rows,
        tile_cols
    );
}

impl Params for Tools {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "hook_stiffness_pa_per_m",
            "Pa/m",
            1e6,
            (1e3, 1e9),
            "the instruments' penalty on the membrane's nodes, per unit of their area",
        ),
        ParamSpec::new(
            "cut_radius_m",
            "m",
            0.002,
            (2e-4, 0.01),
            "radius of the sphere at the hook's end inside which its current cuts the plane's \
             springs",
        ),
        ParamSpec::new(
            "cut_threshold",
            "",
            0.5,
            (0.01, 1.0),
            "trigger value (0 to 1) at or above which the hook's current is on",
        ),
        ParamSpec::new(
            "grip_threshold",
            "",
            0.5,
            (0.01, 1.0),
            "grip value (0 to 1) at or above which the grasper closes",
        ),
    ];

    crate::param_fields!(
        hook_stiffness_pa_per_m,
        cut_radius_m,
        cut_threshold,
        grip_threshold
    );
}

impl Params for Task {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "target_from",
            "",
            0.475,
            (0.0, 1.0),
            "where the target starts along the section (0 the top end, 1 the bottom)",
        ),
        ParamSpec::new(
            "target_to",
            "",
            0.525,
            (0.0, 1.0),
            "where it ends (after target_from)",
        ),
        ParamSpec::new(
            "target_arc_from_deg",
            "deg",
            -40.0,
            (-360.0, 360.0),
            "where the target's arc starts, degrees from the front towards the patient's left",
        ),
        ParamSpec::new(
            "target_arc_to_deg",
            "deg",
            40.0,
            (-360.0, 720.0),
            "where it ends (after target_arc_from_deg, at most a whole turn on)",
        ),
        ParamSpec::new(
            "expose_lift_m",
            "m",
            0.002,
            (5e-4, 0.03),
            "how far the grasper must lift the rectum to expose the plane",
        ),
        ParamSpec::new(
            "overexposed_lift_m",
            "m",
            0.008,
            (1e-3, 0.05),
            "a lift past this overexposes the plane (cutting then counts as overexposed)",
        ),
        ParamSpec::new(
            "near_m",
            "m",
            0.005,
            (1e-4, 0.05),
            "an instrument this close to a vulnerable structure is near it (its forces and \
             speed there are measured)",
        ),
        crate::scenario::Timing::target_time(10.0, crate::scenario::Timing::TARGET_TIME_DOC),
    ];

    crate::param_fields!(
        target_from,
        target_to,
        target_arc_from_deg,
        target_arc_to_deg,
        expose_lift_m,
        overexposed_lift_m,
        near_m,
        target_time_s
    );
}

crate::scenario_tables! {
    dt: (0.001, "simulation step (0.001: the paper's 1 kHz force loop; the membrane takes as many \
         explicit substeps within it as its stability needs)"),
    nodes: nodes,
    tables: [anatomy: AnatomyTable, membrane: MembraneTable, tools: Tools, task: Task],
}

impl Scenario {
    /// Membrane nodes: four layers of rows x columns.
    pub fn nodes(&self) -> u64 {
        LAYERS as u64 * u64::from(self.anatomy.rows) * u64::from(self.anatomy.cols)
    }

    /// The integrator the membrane table names.
    pub fn integrator(&self, file: &str) -> Result<Integrator, InputError> {
        match self.membrane.integrator.as_str() {
            "symplectic" => Ok(Integrator::Symplectic),
            "runge_kutta_4" => Ok(Integrator::RungeKutta4),
            other => Err(InputError::new(
                file,
                "membrane.integrator",
                format!("expected \"symplectic\" or \"runge_kutta_4\", got \"{other}\""),
            )),
        }
    }

    /// The anatomy generator's parameters.
    pub fn anatomy_params(&self) -> AnatomyParams {
        let a = &self.anatomy;
        AnatomyParams {
            length_m: a.length_m,
            rectum_radius_m: a.rectum_radius_m,
            pelvis_radius_m: a.pelvis_radius_m,
            fat_depth_m: a.fat_depth_m,
            wall_depth_m: a.wall_depth_m,
            rows: a.rows,
            cols: a.cols,
            ..AnatomyParams::default()
        }
    }

    /// The scene's parameters.
    pub fn scene_params(&self) -> SceneParams {
        let m = &self.membrane;
        let sheet = LayerMaterial {
            youngs_modulus_pa: m.sheet_modulus_pa,
            thickness_m: m.sheet_thickness_m,
            density_kg_per_m3: m.density_kg_per_m3,
        };
        let mut membrane = membrane_params();
        membrane.layers = [sheet; LAYERS];
        membrane.link_modulus_pa = [m.fat_modulus_pa, m.plane_modulus_pa, m.fat_modulus_pa];
        membrane.damping_per_s = m.damping_per_s;
        membrane.spring_damping_ratio = m.spring_damping_ratio;
        membrane.link_damping_ratio = m.link_damping_ratio;
        membrane.residual_strain = m.residual_strain;
        membrane.integrator = self.integrator("").unwrap_or(Integrator::Symplectic);
        let k = &self.task;
        let activity = crate::models::membrane::ActivityParams {
            tile_rows: m.tile_rows as usize,
            tile_cols: m.tile_cols as usize,
            ..crate::models::membrane::ActivityParams::default()
        };
        SceneParams {
            membrane,
            activity,
            hook_stiffness_pa_per_m: self.tools.hook_stiffness_pa_per_m,
            cut_radius_m: self.tools.cut_radius_m,
            target_rows: (k.target_from, k.target_to),
            target_arc_deg: (k.target_arc_from_deg, k.target_arc_to_deg),
            near_m: k.near_m,
            ..SceneParams::default()
        }
    }

    /// The tables' ranges, then the checks that tie values together.
    pub fn validate(&self, file: &str) -> Result<(), InputError> {
        let err = |key: &str, message: String| InputError::new(file, key, message);
        self.validate_tables(file)?;
        crate::scenario::check_size(file, "anatomy.rows", self.nodes(), MAX_NODES, |n| {
            format!("rows x cols x 4 layers is {n} membrane nodes; at most {MAX_NODES}")
        })?;
        let a = &self.anatomy;
        if a.pelvis_radius_m <= a.rectum_radius_m + a.fat_depth_m + a.wall_depth_m {
            return Err(err(
                "anatomy.pelvis_radius_m",
                format!(
                    "must exceed rectum_radius_m + fat_depth_m + wall_depth_m ({} m): the \
                     plane lies between the fat and the wall",
                    a.rectum_radius_m + a.fat_depth_m + a.wall_depth_m
                ),
            ));
        }
        self.integrator(file)?;
        let k = &self.task;
        if k.target_to <= k.target_from {
            return Err(err(
                "task.target_to",
                format!("must be after target_from ({})", k.target_from),
            ));
        }
        if k.overexposed_lift_m <= k.expose_lift_m {
            return Err(err(
                "task.overexposed_lift_m",
                format!("must exceed expose_lift_m ({})", k.expose_lift_m),
            ));
        }
        let arc = k.target_arc_to_deg - k.target_arc_from_deg;
        if !(arc > 0.0 && arc <= 360.0) {
            return Err(err(
                "task.target_arc_to_deg",
                format!(
                    "must lie after target_arc_from_deg ({}) and at most 360 degrees on",
                    k.target_arc_from_deg
                ),
            ));
        }
        Ok(())
    }
}
