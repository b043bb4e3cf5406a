//! The scenario's optional `[guidewire]` table: the wire's size and materials, its tip, its
//! hold in the catheter's lumen, its friction on the wall, where it starts and how dark it
//! shows under fluoroscopy. Without the table the catheter goes in alone.

use crate::models::skeleton::contact::ContactLaw;
use crate::models::skeleton::guidewire::GuidewireParams;
use crate::param_fields;
use crate::params::{ParamSpec, Params};
use serde::Deserialize;

/// The guidewire (the catheter paper has none: every figure here is ours, of the order of a
/// 0.035 in diagnostic wire with a nitinol core).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GuidewireTable {
    pub length_m: f64,
    pub diameter_m: f64,
    pub density_kg_per_m3: f64,
    pub spacing_m: f64,
    pub axial_n_per_m: f64,
    pub damping_n_s_per_m: f64,
    pub core_ei_n_m2: f64,
    pub tip_ei_n_m2: f64,
    pub tip_length_m: f64,
    pub j_angle_deg: f64,
    pub lumen_n_per_m: f64,
    pub lumen_damping_n_s_per_m: f64,
    pub friction: f64,
    pub start_m: f64,
    pub mu_per_m: f64,
}

impl Params for GuidewireTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new("length_m", "m", 0.150, (0.02, 2.0), "the wire's length"),
        ParamSpec::new(
            "diameter_m",
            "m",
            0.0009,
            (0.0002, 0.002),
            "its diameter (0.9 mm: a 0.035 in wire)",
        ),
        ParamSpec::new(
            "density_kg_per_m3",
            "kg/m^3",
            6450.0,
            (1000.0, 22000.0),
            "the core's density (nitinol): each ball's mass is its share of the wire",
        ),
        ParamSpec::new(
            "spacing_m",
            "m",
            0.005,
            (0.001, 0.02),
            "the balls' spacing along the wire",
        ),
        ParamSpec::new(
            "axial_n_per_m",
            "N/m",
            100.0,
            (1.0, 1e5),
            "each segment's axial spring",
        ),
        ParamSpec::new(
            "damping_n_s_per_m",
            "N s/m",
            0.002,
            (0.0, 1.0),
            "the axial springs' damping",
        ),
        ParamSpec::new(
            "core_ei_n_m2",
            "N m^2",
            2e-5,
            (1e-8, 1e-2),
            "the core's flexural rigidity EI (each joint's angle spring is EI over the spacing)",
        ),
        ParamSpec::new(
            "tip_ei_n_m2",
            "N m^2",
            2e-6,
            (1e-9, 1e-2),
            "the soft tip's flexural rigidity",
        ),
        ParamSpec::new(
            "tip_length_m",
            "m",
            0.020,
            (0.002, 0.2),
            "the soft tip's length",
        ),
        ParamSpec::new(
            "j_angle_deg",
            "deg",
            45.0,
            (0.0, 180.0),
            "the tip's shape at rest: 0 straight, 30 to 60 angled, 90 to 180 a J; the wrist's roll turns its plane",
        ),
        ParamSpec::new(
            "lumen_n_per_m",
            "N/m",
            50.0,
            (0.1, 1e4),
            "the catheter's lumen's hold on each wire ball inside it, across the catheter",
        ),
        ParamSpec::new(
            "lumen_damping_n_s_per_m",
            "N s/m",
            0.002,
            (0.0, 1.0),
            "its damping",
        ),
        ParamSpec::new(
            "friction",
            "1",
            0.05,
            (0.0, 2.0),
            "mu on the wall (a hydrophilic coating); the normal force is the contact table's stiffness and damping scaled by the wire's width over the catheter's, without its preload",
        ),
        ParamSpec::new(
            "start_m",
            "m",
            -0.005,
            (-0.5, 0.5),
            "where the wire's tip starts past the entry (negative: behind it, in the catheter); the left hand's travel along the entry from its first place feeds it",
        ),
        ParamSpec::new(
            "mu_per_m",
            "1/m",
            700.0,
            (0.0, 1e5),
            "its X-ray attenuation (nitinol near 60 keV: the wire shows dark)",
        ),
    ];
    param_fields!(
        length_m,
        diameter_m,
        density_kg_per_m3,
        spacing_m,
        axial_n_per_m,
        damping_n_s_per_m,
        core_ei_n_m2,
        tip_ei_n_m2,
        tip_length_m,
        j_angle_deg,
        lumen_n_per_m,
        lumen_damping_n_s_per_m,
        friction,
        start_m,
        mu_per_m
    );
}

impl GuidewireTable {
    pub fn params(&self) -> GuidewireParams {
        GuidewireParams {
            length_m: self.length_m,
            diameter_m: self.diameter_m,
            density_kg_per_m3: self.density_kg_per_m3,
            spacing_m: self.spacing_m,
            axial_n_per_m: self.axial_n_per_m,
            damping_n_s_per_m: self.damping_n_s_per_m,
            core_ei_n_m2: self.core_ei_n_m2,
            tip_ei_n_m2: self.tip_ei_n_m2,
            tip_length_m: self.tip_length_m,
            j_angle_deg: self.j_angle_deg,
            lumen_n_per_m: self.lumen_n_per_m,
            lumen_damping_n_s_per_m: self.lumen_damping_n_s_per_m,
        }
    }

    /// The wire's contact law and puncture force: the wall's law for the catheter (`law`,
    /// `puncture_n`) scaled by the wire's width over the catheter's (`catheter_m`): the wall
    /// answers a contact in proportion to the width that presses on it (stiffness, damping),
    /// and tears under a wire at the same force per width as under the catheter. No preload:
    /// the paper's `t` was fitted to its catheter, and on a wire ball (a twentieth of a
    /// catheter ball's mass) a force from zero depth kicks the tip off the wall at metres a
    /// second. The wire's own friction.
    pub fn law(&self, law: &ContactLaw, puncture_n: f64, catheter_m: f64) -> (ContactLaw, f64) {
        let s = self.diameter_m / catheter_m;
        (
            ContactLaw {
                stiffness_n_per_m: law.stiffness_n_per_m * s,
                damping_n_s_per_m: law.damping_n_s_per_m * s,
                preload_n: 0.0,
                friction: self.friction,
            },
            puncture_n * s,
        )
    }
}

#[cfg(test)]
#[path = "wire_tests.rs"]
mod tests;
