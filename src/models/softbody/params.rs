//! The soft body's parameters (every field with its unit) and the values a supervisor tunes live.

use serde::{Deserialize, Serialize};

/// Parameters of the force-based soft body. Every field has its unit in its name.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SoftBodyParams {
    /// Spring pulling each anchored point to its rest position, N/m per unit-mass point.
    pub spring_n_per_m: f32,
    /// Velocity damping d in v (1 - d dt), 1/s.
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
    /// XPBD compliance of the ties, m/N.
    pub tie_compliance_m_per_n: f32,
    /// A tie breaks when its constraint force exceeds this, N.
    pub tie_break_force_n: f32,
    /// Constraint projections per step.
    pub solver_iterations: u32,
    /// Speed under which a point counts as still, m/s.
    pub sleep_speed_m_per_s: f32,
}

/// The soft body's parameters a supervisor may change while a session runs (the nephrectomy
/// paper lets users tune the soft-body variables live, its Figure 5).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Tuning {
    /// Spring to the rest position, N/m per unit-mass point (eq 2).
    pub spring_n_per_m: f32,
    /// Velocity damping, 1/s (eq 5).
    pub damping_per_s: f32,
    /// Lift of the force origin above the contact, m.
    pub offset_m: f32,
}

impl Tuning {
    /// Each value's name and allowed range (the sliders' ends).
    pub const RANGES: [(&'static str, f32, f32); 3] = [
        ("spring_n_per_m", 1.0, 400.0),
        ("damping_per_s", 0.0, 50.0),
        ("offset_m", 0.0, 0.01),
    ];

    pub fn of(p: &SoftBodyParams) -> Tuning {
        Tuning {
            spring_n_per_m: p.spring_n_per_m,
            damping_per_s: p.damping_per_s,
            offset_m: p.offset_m,
        }
    }

    pub fn values(&self) -> [f32; 3] {
        [self.spring_n_per_m, self.damping_per_s, self.offset_m]
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
        p.spring_n_per_m = self.spring_n_per_m;
        p.damping_per_s = self.damping_per_s;
        p.offset_m = self.offset_m;
    }
}

impl Default for SoftBodyParams {
    fn default() -> Self {
        Self {
            spring_n_per_m: 40.0,
            damping_per_s: 8.0,
            contact_area_m2: 1e-4,
            offset_m: 0.002,
            falloff_m: 0.006,
            volume_stiffness_pa: 2000.0,
            stretch_compliance_m_per_n: 1e-3,
            bend_compliance_per_n_m: 0.1,
            tie_compliance_m_per_n: 1e-4,
            tie_break_force_n: 2.0,
            solver_iterations: 1,
            sleep_speed_m_per_s: 1e-4,
        }
    }
}
