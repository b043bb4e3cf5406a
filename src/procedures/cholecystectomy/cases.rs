//! The cholecystectomy's reference cases at its CPU preset's lattices (`vesalius verify
//! --preset cpu`): the hanging column of the shape matching on the preset's liver lattice
//! and on its gallbladder's, with the scenario's tissues.

use crate::sim::{Case, Measured};
use crate::verify::particle_cases::hanging_column_of;

/// `vesalius verify --preset cpu`'s rows.
pub fn preset_cases() -> Vec<Case> {
    vec![
        Case {
            model: "shape matching",
            case: "shape_matching_hanging_column_preset_liver",
            description: "shape_matching_hanging_column on the cpu preset's liver lattice \
                          (assets/presets/cpu/cholecystectomy.toml: 10 mm as shipped), the \
                          scenario's liver (1060 kg/m^3, 5 kPa): its bottom's drop vs the \
                          continuum's rho g H^2 / (2 E); tolerance 10 %",
            unit: "m",
            tolerance: 0.1,
            run: || preset_column(Organ::Liver),
        },
        Case {
            model: "shape matching",
            case: "shape_matching_hanging_column_preset_gallbladder",
            description: "shape_matching_hanging_column on the cpu preset's gallbladder \
                          lattice (5 mm as shipped), the scenario's gallbladder wall \
                          (1030 kg/m^3, 8 kPa): its bottom's drop vs the continuum's; \
                          tolerance 10 %",
            unit: "m",
            tolerance: 0.1,
            run: || preset_column(Organ::Gallbladder),
        },
    ]
}

enum Organ {
    Liver,
    Gallbladder,
}

/// The column of `organ`'s tissue on its lattice in the preset (not run without a preset or
/// with one that does not make a valid scenario).
fn preset_column(organ: Organ) -> Measured {
    let Some(Ok((file, text))) = super::INFO.cpu_preset_scenario() else {
        return Measured::not_run(0.0);
    };
    let Ok(s) = super::Scenario::parse(&file, &text) else {
        return Measured::not_run(0.0);
    };
    let (a, t) = (s.anatomy_params(), s.scene_params());
    let (shape, modulus) = match organ {
        Organ::Liver => (a.liver, t.liver_modulus_pa),
        Organ::Gallbladder => (a.gallbladder, t.gallbladder_modulus_pa),
    };
    hanging_column_of(shape.spacing_m, shape.density_kg_per_m3, modulus)
}
