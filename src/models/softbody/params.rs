//! The soft body's parameters (every field with its unit) and the values a supervisor tunes live.

use crate::params::{ParamSpec, Params};
use serde::{Deserialize, Serialize};

/// Parameters of the force-based soft body. Every field has its unit in its name.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SoftBodyParams {
    /// Tissue density, kg/m^3: each point's mass is its area's share of the mass of the
    /// volume its part encloses.
    pub density_kg_per_m3: f32,
    /// Winkler modulus of the elastic foundation that holds the surface to its rest shape
    /// (eq 2's spring, per unit area): a point of area A is held with A times this, N/m^3.
    pub foundation_pa_per_m: f32,
    /// Shear modulus of the Pasternak layer that couples neighbouring points' displacements,
    /// N/m: it spreads a load over the surface, the second parameter of the foundation.
    pub shear_layer_n_per_m: f32,
    /// Mass-proportional velocity damping, 1/s (eq 5, integrated implicitly).
    pub damping_per_s: f32,
    /// Area over which a pressing tool applies its pressure, m^2 (the pressure is the tool's).
    pub contact_area_m2: f32,
    /// Lift of the force origin above the contact point along the normal, m.
    pub offset_m: f32,
    /// Distance scale of the falloff F / (1 + (d / l)^2), m.
    pub falloff_m: f32,
    /// Internal pressure per unit relative volume loss, Pa.
    pub volume_stiffness_pa: f32,
    /// XPBD compliance of the stretch constraints (eq 11), m/N.
    pub stretch_compliance_m_per_n: f32,
    /// XPBD compliance of the dihedral bending constraints (eq 12), rad/(N m).
    pub bend_compliance_per_n_m: f32,
    /// Stiffness of the ties between regions per unit of tied area, N/m^3 (a tie from a
    /// point of area A pulls with A times this per metre of relative displacement).
    pub tie_stiffness_pa_per_m: f32,
    /// A tie tears when its force over its area exceeds this, Pa.
    pub tie_strength_pa: f32,
    /// Constraint projections per step.
    pub solver_iterations: u32,
    /// Speed under which a point counts as still, m/s.
    pub sleep_speed_m_per_s: f32,
}

/// The soft body's parameters a supervisor may change while a session runs (the nephrectomy
/// paper lets users tune the soft-body variables live, its Figure 5).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Tuning {
    /// Winkler modulus of the foundation (eq 2's spring per unit area), N/m^3.
    pub foundation_pa_per_m: f32,
    /// Velocity damping, 1/s (eq 5).
    pub damping_per_s: f32,
    /// Lift of the force origin above the contact, m.
    pub offset_m: f32,
}

// The table: one entry per parameter (units, one default, scenario range, live slider).
const DENSITY: ParamSpec = ParamSpec::new(
    "density_kg_per_m3",
    "kg/m^3",
    1050.0,
    (1.0, 2e4),
    "tissue density; a point's mass is its area's share of its part's enclosed mass \
     (soft tissue about 1050: Duck, Physical Properties of Tissue, 1990)",
);
const FOUNDATION: ParamSpec = ParamSpec::new(
    "foundation_pa_per_m",
    "N/m^3",
    1.6e6,
    (0.0, 1e10),
    "Winkler modulus holding the surface to its rest shape (eq 2 per unit area); with the \
     shear layer, calibrated to Hertz for E = 16 kPa (docs/physics.md)",
)
.tune(1e4, 1e7);
const SHEAR: ParamSpec = ParamSpec::new(
    "shear_layer_n_per_m",
    "N/m",
    10.0,
    (0.0, 1e5),
    "Pasternak shear layer coupling neighbours' displacements, spreading a load",
);
const DAMPING: ParamSpec = ParamSpec::new(
    "damping_per_s",
    "1/s",
    600.0,
    (0.0, 1e4),
    "mass-proportional velocity damping (eq 5), integrated implicitly; near critical for \
     the default foundation",
)
.tune(0.0, 2000.0);
const CONTACT_AREA: ParamSpec = ParamSpec::new(
    "contact_area_m2",
    "m^2",
    1e-4,
    (1e-8, 1e-2),
    "area a pressing tool's pressure acts on (eq 4: P n dA)",
);
const OFFSET: ParamSpec = ParamSpec::new(
    "offset_m",
    "m",
    0.002,
    (0.0, 0.05),
    "lift of a contact force's origin above the contact along the normal",
)
.tune(0.0, 0.01);
const FALLOFF: ParamSpec = ParamSpec::new(
    "falloff_m",
    "m",
    0.006,
    (1e-4, 0.1),
    "distance scale l of the falloff F / (1 + (d / l)^2) (eq 6)",
);
const VOLUME: ParamSpec = ParamSpec::new(
    "volume_stiffness_pa",
    "Pa",
    2000.0,
    (0.0, 1e6),
    "internal pressure per unit relative volume loss (eq 3)",
);
const STRETCH: ParamSpec = ParamSpec::new(
    "stretch_compliance_m_per_n",
    "m/N",
    2.0,
    (0.0, 1e3),
    "XPBD compliance of the stretch constraints (eq 11), with the points' real masses; \
     the shear layer carries the surface's stiffness, so this stays soft enough to converge \
     in one projection at 2 ms",
);
const BEND: ParamSpec = ParamSpec::new(
    "bend_compliance_per_n_m",
    "rad/(N m)",
    1e6,
    (0.0, 1e9),
    "XPBD compliance of the dihedral bending constraints (eq 12), with the points' real \
     masses; soft enough to converge in one projection at 2 ms",
);
const TIE_STIFFNESS: ParamSpec = ParamSpec::new(
    "tie_stiffness_pa_per_m",
    "N/m^3",
    5e6,
    (0.0, 1e10),
    "stiffness of the ties between regions per unit of tied area",
);
const TIE_STRENGTH: ParamSpec = ParamSpec::new(
    "tie_strength_pa",
    "Pa",
    1e4,
    (1.0, 1e8),
    "a tie tears when its force over its area exceeds this (5e6 N/m^3 and 1e4 Pa: a tie \
     tears past 2 mm of relative displacement)",
);
const ITERATIONS: ParamSpec = ParamSpec::new(
    "solver_iterations",
    "",
    1.0,
    (1.0, 100.0),
    "constraint projections per step",
)
.whole();
const SLEEP: ParamSpec = ParamSpec::new(
    "sleep_speed_m_per_s",
    "m/s",
    1e-4,
    (0.0, 0.1),
    "speed under which a point at rest counts as still and may sleep",
);

/// A tunable spec's slider range, as the tuning checks it.
const fn slider(s: ParamSpec) -> (&'static str, f32, f32) {
    match s.tune {
        Some((lo, hi)) => (s.key, lo as f32, hi as f32),
        None => (s.key, 0.0, 0.0),
    }
}

impl Params for SoftBodyParams {
    const SPECS: &'static [ParamSpec] = &[
        DENSITY,
        FOUNDATION,
        SHEAR,
        DAMPING,
        CONTACT_AREA,
        OFFSET,
        FALLOFF,
        VOLUME,
        STRETCH,
        BEND,
        TIE_STIFFNESS,
        TIE_STRENGTH,
        ITERATIONS,
        SLEEP,
    ];

    crate::param_fields!(
        density_kg_per_m3,
        foundation_pa_per_m,
        shear_layer_n_per_m,
        damping_per_s,
        contact_area_m2,
        offset_m,
        falloff_m,
        volume_stiffness_pa,
        stretch_compliance_m_per_n,
        bend_compliance_per_n_m,
        tie_stiffness_pa_per_m,
        tie_strength_pa,
        solver_iterations,
        sleep_speed_m_per_s
    );
}

impl Tuning {
    /// Each tunable value's name and slider range, from the parameter table.
    pub const RANGES: [(&'static str, f32, f32); 3] =
        [slider(FOUNDATION), slider(DAMPING), slider(OFFSET)];
    pub fn of(p: &SoftBodyParams) -> Tuning {
        Tuning {
            foundation_pa_per_m: p.foundation_pa_per_m,
            damping_per_s: p.damping_per_s,
            offset_m: p.offset_m,
        }
    }

    pub fn values(&self) -> [f32; 3] {
        [self.foundation_pa_per_m, self.damping_per_s, self.offset_m]
    }

    /// `Err(key, message)` for the first value outside its range or not a number.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        for ((key, lo, hi), v) in Tuning::RANGES.iter().zip(self.values()) {
            if !(v.is_finite() && (*lo..=*hi).contains(&v)) {
                return Err((key, format!("must be {lo} to {hi}, got {v}")));
            }
        }
        Ok(())
    }

    /// These values written into `p`.
    pub fn apply(&self, p: &mut SoftBodyParams) {
        p.foundation_pa_per_m = self.foundation_pa_per_m;
        p.damping_per_s = self.damping_per_s;
        p.offset_m = self.offset_m;
    }
}

impl Default for SoftBodyParams {
    /// Every parameter at its table default.
    fn default() -> Self {
        let d = |s: ParamSpec| s.default as f32;
        Self {
            density_kg_per_m3: d(DENSITY),
            foundation_pa_per_m: d(FOUNDATION),
            shear_layer_n_per_m: d(SHEAR),
            damping_per_s: d(DAMPING),
            contact_area_m2: d(CONTACT_AREA),
            offset_m: d(OFFSET),
            falloff_m: d(FALLOFF),
            volume_stiffness_pa: d(VOLUME),
            stretch_compliance_m_per_n: d(STRETCH),
            bend_compliance_per_n_m: d(BEND),
            tie_stiffness_pa_per_m: d(TIE_STIFFNESS),
            tie_strength_pa: d(TIE_STRENGTH),
            solver_iterations: ITERATIONS.default as u32,
            sleep_speed_m_per_s: d(SLEEP),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_covers_every_field_once_and_reads_back() {
        let keys: Vec<&str> = SoftBodyParams::SPECS.iter().map(|s| s.key).collect();
        let mut unique = keys.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), keys.len(), "each key once");
        // Every field appears in the serialised struct under exactly the table's keys.
        let p = SoftBodyParams::default();
        let v = serde_json::to_value(p).unwrap_or_default();
        let fields: Vec<&str> = v
            .as_object()
            .map(|o| o.keys().map(String::as_str).collect())
            .unwrap_or_default();
        let mut sorted = keys.clone();
        sorted.sort_unstable();
        assert_eq!(fields, sorted);
        for s in SoftBodyParams::SPECS {
            assert_eq!(p.get(s.key), Some(f64::from(s.default as f32)), "{}", s.key);
            assert!(s.min <= s.default && s.default <= s.max, "{}", s.key);
            if let Some((lo, hi)) = s.tune {
                assert!(s.min <= lo && hi <= s.max && lo < hi, "{}", s.key);
            }
            let mut q = p;
            assert!(q.set(s.key, s.max));
            assert_eq!(q.get(s.key), Some(f64::from(s.max as f32)));
        }
        assert!(crate::params::validate("t", "tissue", &p).is_ok());
        let mut bad = p;
        bad.solver_iterations = 0;
        let e = crate::params::validate("t.toml", "tissue", &bad).expect_err("0 iterations");
        assert_eq!(e.key, "tissue.solver_iterations");
        let mut nan = p;
        nan.falloff_m = f32::NAN;
        let e = crate::params::validate("t.toml", "tissue", &nan).expect_err("NaN");
        assert!(
            e.to_string()
                .contains("t.toml: tissue.falloff_m: must be a finite number")
        );
        // The live sliders are the table's.
        let sliders: Vec<&str> = Tuning::RANGES.iter().map(|r| r.0).collect();
        let tunable: Vec<&str> = SoftBodyParams::SPECS
            .iter()
            .filter(|s| s.tune.is_some())
            .map(|s| s.key)
            .collect();
        assert_eq!(sliders, tunable);
    }
}
