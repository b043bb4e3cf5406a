//! The cholecystectomy's scenario file: timing, the anatomy's resolution, the tissues'
//! moduli, the solver, the adhesive fascia, the instruments and the task. Every number has
//! its entry in a parameter table; an error names the file, the key and the expected range.

use super::anatomy::AnatomyParams;
use super::scene::SceneParams;
use crate::models::particles::solver::SolverParams;
use crate::param_fields;
use crate::params::{ParamSpec, Params};
use crate::scenario::InputError;
use serde::Deserialize;

/// The name scenarios and traces give this procedure.
pub const NAME: &str = "cholecystectomy";

/// The `[surfaces]` table: a file for any of the three organs; a relative path is read from
/// the scenario file's folder.
#[derive(Debug, Clone, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Surfaces {
    pub liver: Option<String>,
    pub gallbladder: Option<String>,
    pub fat: Option<String>,
}

/// The generated anatomy's resolution and attachments.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnatomyTable {
    pub liver_spacing_m: f32,
    pub organ_spacing_m: f32,
    pub adhesion_every: u32,
    pub fat_bond_every: u32,
}

impl Params for AnatomyTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "liver_spacing_m",
            "m",
            0.0035,
            (0.002, 0.01),
            "the liver's particle lattice spacing (each particle its cube of tissue)",
        ),
        ParamSpec::new(
            "organ_spacing_m",
            "m",
            0.0025,
            (0.0015, 0.006),
            "the gallbladder's and the fat's lattice spacing (below the gallbladder's \
             half-height of 14 mm)",
        ),
        ParamSpec::new(
            "adhesion_every",
            "particles",
            2.0,
            (1.0, 64.0),
            "an adhesion strand starts at every this many of the gallbladder's upper surface \
             particles",
        )
        .whole(),
        ParamSpec::new(
            "fat_bond_every",
            "particles",
            1.0,
            (1.0, 64.0),
            "a strand of loose tissue binds every this many of the fat's surface particles",
        )
        .whole(),
    ];
    param_fields!(
        liver_spacing_m,
        organ_spacing_m,
        adhesion_every,
        fat_bond_every
    );
}

/// Young's moduli and damping.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TissueTable {
    pub liver_modulus_pa: f32,
    pub gallbladder_modulus_pa: f32,
    pub fat_modulus_pa: f32,
    pub vessel_modulus_pa: f32,
    pub fascia_modulus_pa: f32,
    pub damping_per_s: f32,
}

impl Params for TissueTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "liver_modulus_pa",
            "Pa",
            5000.0,
            (100.0, 1e6),
            "Young's modulus of the liver (its clusters' stiffness)",
        ),
        ParamSpec::new(
            "gallbladder_modulus_pa",
            "Pa",
            8000.0,
            (100.0, 1e6),
            "Young's modulus of the gallbladder",
        ),
        ParamSpec::new(
            "fat_modulus_pa",
            "Pa",
            1000.0,
            (100.0, 1e6),
            "Young's modulus of the fat over Calot's triangle",
        ),
        ParamSpec::new(
            "vessel_modulus_pa",
            "Pa",
            50_000.0,
            (1000.0, 1e7),
            "Young's modulus of the ducts' and the artery's walls (their chains' springs)",
        ),
        ParamSpec::new(
            "fascia_modulus_pa",
            "Pa",
            20_000.0,
            (100.0, 1e7),
            "Young's modulus of the cloth fascia (its edges are springs of modulus x \
             thickness)",
        ),
        ParamSpec::new(
            "damping_per_s",
            "1/s",
            5.0,
            (0.0, 100.0),
            "point damping of every particle",
        ),
    ];
    param_fields!(
        liver_modulus_pa,
        gallbladder_modulus_pa,
        fat_modulus_pa,
        vessel_modulus_pa,
        fascia_modulus_pa,
        damping_per_s
    );
}

/// The position-based solver.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverTable {
    pub substeps: u32,
    pub iterations: u32,
    pub settle_s: f32,
}

impl Params for SolverTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "substeps",
            "substeps",
            2.0,
            (1.0, 16.0),
            "substeps per step (each a full predict, sweeps and velocity update)",
        )
        .whole(),
        ParamSpec::new(
            "iterations",
            "sweeps",
            2.0,
            (1.0, 32.0),
            "sweeps over every constraint per substep",
        )
        .whole(),
        ParamSpec::new(
            "settle_s",
            "s",
            0.5,
            (0.0, 5.0),
            "heavily damped settling before the session (the bodies come to rest where \
             gravity and their attachments hold them)",
        ),
    ];
    param_fields!(substeps, iterations, settle_s);
}

/// The adhesive fascia's strands and the fat's loose tissue.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdhesionTable {
    pub stiffness_n_per_m: f32,
    pub break_stretch: f32,
    pub tear_strain: f32,
    pub fat_stiffness_n_per_m: f32,
    pub seed: u32,
}

impl Params for AdhesionTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "stiffness_n_per_m",
            "N/m",
            100.0,
            (1.0, 1e5),
            "each segment of an adhesion strand while intact at the shipped lattice (4 segments \
             in series: 25 N/m a strand, the fascia's 20 kPa over the 12.5 mm^2 a strand holds \
             across about 1 cm); scaled by the area a strand holds at other lattices",
        ),
        ParamSpec::new(
            "break_stretch",
            "ratio",
            1.1,
            (1.01, 20.0),
            "a strand whose ends are further apart than this times its rest length is \
             weakened (the paper's break threshold)",
        ),
        ParamSpec::new(
            "tear_strain",
            "strain",
            0.5,
            (0.01, 10.0),
            "a segment stretched past this strain tears (its strand's tension shared by its \
             segments in series)",
        ),
        ParamSpec::new(
            "fat_stiffness_n_per_m",
            "N/m",
            5.0,
            (0.1, 1e4),
            "each segment of the fat's strands (3 in series; they tear at strain 1)",
        ),
        ParamSpec::new(
            "seed",
            "",
            12_846_060.0,
            (0.0, 1e9),
            "the generator that scatters the breakable points along the strands",
        )
        .whole(),
    ];
    param_fields!(
        stiffness_n_per_m,
        break_stretch,
        tear_strain,
        fat_stiffness_n_per_m,
        seed
    );
}

/// The instruments.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tools {
    pub trigger_threshold: f32,
    pub grip_threshold: f32,
    pub clip_reach_m: f32,
    pub cut_reach_m: f32,
    pub dissect_radius_m: f32,
    pub grasp_reach_m: f32,
    pub grasp_stiffness_n_per_m: f32,
    /// Coagulation (optional keys; files from before it have none).
    #[serde(default = "coag_reach_default")]
    pub coag_reach_m: f32,
    #[serde(default = "coag_time_default")]
    pub coag_time_s: f32,
}

const COAG_REACH_M: f32 = 0.004;
const COAG_TIME_S: f32 = 1.5;

fn coag_reach_default() -> f32 {
    COAG_REACH_M
}

fn coag_time_default() -> f32 {
    COAG_TIME_S
}

impl Params for Tools {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "trigger_threshold",
            "",
            0.5,
            (0.05, 1.0),
            "trigger at or above this: the hook's current on, the clip applier or the \
             scissors closing, the right grasper closed",
        ),
        ParamSpec::new(
            "grip_threshold",
            "",
            0.5,
            (0.05, 1.0),
            "grip at or above this: a grasper closed",
        ),
        ParamSpec::new(
            "clip_reach_m",
            "m",
            0.004,
            (0.0005, 0.02),
            "a clip lands on a vessel whose centreline passes this close to the applier's jaw",
        ),
        ParamSpec::new(
            "cut_reach_m",
            "m",
            0.004,
            (0.0005, 0.02),
            "the scissors cut a vessel whose centreline passes this close to their jaw",
        ),
        ParamSpec::new(
            "dissect_radius_m",
            "m",
            0.002,
            (0.0002, 0.01),
            "the hook's current and the scissors cut strands and fascia this close to them",
        ),
        ParamSpec::new(
            "grasp_reach_m",
            "m",
            0.004,
            (0.0005, 0.02),
            "a closing grasper takes the particles this close to its jaw",
        ),
        ParamSpec::new(
            "grasp_stiffness_n_per_m",
            "N/m",
            100.0,
            (1.0, 1e5),
            "each held particle's spring to the jaw",
        ),
        ParamSpec::new(
            "coag_reach_m",
            "m",
            COAG_REACH_M as f64,
            (0.0005, 0.02),
            "the hook's current coagulates a bleeding cut whose source is this close to its end",
        ),
        ParamSpec::new(
            "coag_time_s",
            "s",
            COAG_TIME_S as f64,
            (0.1, 10.0),
            "current held there this long in all stops the bleeding (a clip stops it at once)",
        ),
    ];
    param_fields!(
        trigger_threshold,
        grip_threshold,
        clip_reach_m,
        cut_reach_m,
        dissect_radius_m,
        grasp_reach_m,
        grasp_stiffness_n_per_m,
        coag_reach_m,
        coag_time_s
    );
}

/// The task's thresholds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Task {
    pub retract_m: f32,
    pub expose_fraction: f32,
    pub duct_clips: u32,
    pub artery_clips: u32,
    pub separate_fraction: f32,
    pub target_time_s: f32,
}

impl Params for Task {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "retract_m",
            "m",
            0.006,
            (0.0005, 0.05),
            "the left grasper retracts the fundus: it holds the gallbladder and has moved it \
             this far",
        ),
        ParamSpec::new(
            "expose_fraction",
            "fraction",
            0.7,
            (0.05, 1.0),
            "Calot's triangle is exposed when this share of it is seen from the laparoscope \
             past the fat",
        ),
        ParamSpec::new(
            "duct_clips",
            "clips",
            3.0,
            (1.0, 8.0),
            "clips the cystic duct takes (the paper's three)",
        )
        .whole(),
        ParamSpec::new(
            "artery_clips",
            "clips",
            2.0,
            (1.0, 8.0),
            "clips the cystic artery takes",
        )
        .whole(),
        ParamSpec::new(
            "separate_fraction",
            "fraction",
            0.9,
            (0.1, 1.0),
            "the gallbladder is off its bed when this share of the adhesion strands is torn \
             or cut",
        ),
        crate::scenario::Timing::target_time(60.0, "an expert's time for the whole task"),
    ];
    param_fields!(
        retract_m,
        expose_fraction,
        duct_clips,
        artery_clips,
        separate_fraction,
        target_time_s
    );
}

crate::scenario_tables! {
    dt: (0.001, "simulation step (0.001: the haptic rate; the solver's substeps divide it)"),
    nodes: particles,
    tables: [anatomy: AnatomyTable, tissue: TissueTable, solver: SolverTable,
        adhesion: AdhesionTable, tools: Tools, task: Task],
    extra: [
        /// Optional: the organs' closed surfaces from files (OBJ, glTF or GLB; metres, in the
        /// anatomy's frame), replacing the generated ellipsoids.
        #[serde(default)]
        surfaces: Surfaces,
    ],
}

impl Scenario {
    /// The tables' ranges.
    pub fn validate(&self, file: &str) -> Result<(), InputError> {
        self.validate_tables(file)?;
        Ok(())
    }

    /// The anatomy generator's parameters.
    pub fn anatomy_params(&self) -> AnatomyParams {
        let mut a = AnatomyParams::default();
        a.liver.spacing_m = self.anatomy.liver_spacing_m;
        a.gallbladder.spacing_m = self.anatomy.organ_spacing_m;
        a.fat.spacing_m = self.anatomy.organ_spacing_m;
        a.adhesion_every = self.anatomy.adhesion_every;
        a.fat_bond_every = self.anatomy.fat_bond_every;
        a
    }

    /// The anatomy's parameters with the `[surfaces]` files read (`file`, the scenario's
    /// path, locates relative ones; errors name `surfaces.<organ>`).
    pub fn anatomy_with_surfaces(&self, file: &str) -> Result<AnatomyParams, InputError> {
        let mut a = self.anatomy_params();
        let folder = std::path::Path::new(file)
            .parent()
            .unwrap_or(std::path::Path::new(""));
        let s = &self.surfaces;
        for (k, (organ, path)) in [
            ("liver", &s.liver),
            ("gallbladder", &s.gallbladder),
            ("fat", &s.fat),
        ]
        .into_iter()
        .enumerate()
        {
            let Some(path) = path else { continue };
            let key = format!("surfaces.{organ}");
            let full = folder.join(path);
            let lower = path.to_ascii_lowercase();
            let mesh = if lower.ends_with(".obj") {
                crate::mesh::obj::load(&full, 1.0).map_err(|e| e.to_string())
            } else if lower.ends_with(".gltf") || lower.ends_with(".glb") {
                crate::mesh::gltf::load(&full, 1.0).map_err(|e| e.to_string())
            } else {
                Err(format!(
                    "expected an .obj, .gltf or .glb file, got \"{path}\""
                ))
            };
            a.surfaces[k] = Some(mesh.map_err(|m| InputError::new(file, &key, m))?);
        }
        Ok(a)
    }

    /// The scene's parameters.
    pub fn scene_params(&self) -> SceneParams {
        let d = SceneParams::default();
        let (t, s, a, k) = (&self.tissue, &self.solver, &self.adhesion, &self.tools);
        SceneParams {
            liver_modulus_pa: t.liver_modulus_pa,
            gallbladder_modulus_pa: t.gallbladder_modulus_pa,
            fat_modulus_pa: t.fat_modulus_pa,
            vessel_modulus_pa: t.vessel_modulus_pa,
            fascia_modulus_pa: t.fascia_modulus_pa,
            solver: SolverParams {
                damping_per_s: t.damping_per_s,
                iterations: s.iterations,
                substeps: s.substeps,
                grasp_reach_m: k.grasp_reach_m,
                grasp_stiffness_n_per_m: k.grasp_stiffness_n_per_m,
                ..d.solver
            },
            adhesion: crate::models::particles::adhesion::AdhesionParams {
                stiffness_n_per_m: a.stiffness_n_per_m * self.strand_area_ratio(),
                break_stretch: a.break_stretch,
                tear_strain: a.tear_strain,
                ..d.adhesion
            },
            fat_bonds: crate::models::particles::adhesion::AdhesionParams {
                stiffness_n_per_m: a.fat_stiffness_n_per_m,
                ..d.fat_bonds
            },
            adhesion_seed: u64::from(a.seed),
            ..d
        }
    }

    /// The bed's area a strand holds (every `adhesion_every`-th particle of the gallbladder's
    /// upper surface, each a square of the lattice's spacing) over the shipped lattice's
    /// (every 2nd at 2.5 mm, 12.5 mm^2): the strands' stiffness is given for the shipped
    /// lattice and grows with the area each holds, so the bed holds the gallbladder alike at
    /// any lattice (the CPU preset's 5 mm lattice has a fifth of the strands).
    pub fn strand_area_ratio(&self) -> f32 {
        let area = self.anatomy.adhesion_every as f32 * self.anatomy.organ_spacing_m.powi(2);
        area / (2.0 * 0.0025f32.powi(2))
    }

    /// Particles the anatomy will have, roughly (the organs' ellipsoid volumes over their
    /// cells), for the session's cost estimate.
    pub fn particles(&self) -> u64 {
        let a = self.anatomy_params();
        let ellipsoid = |o: &super::anatomy::OrganShape| {
            let v = 4.0 / 3.0
                * std::f64::consts::PI
                * f64::from(o.semi_axes_m.x)
                * f64::from(o.semi_axes_m.y)
                * f64::from(o.semi_axes_m.z);
            v / f64::from(o.spacing_m).powi(3)
        };
        (ellipsoid(&a.liver) + ellipsoid(&a.gallbladder) + ellipsoid(&a.fat)) as u64
    }
}
