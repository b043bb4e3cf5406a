//! The catheterisation under fluoroscopy: the scenario's `[fluoroscopy]` table, the contrast
//! carried along the bifurcation (trunk and two branches), the X-ray scene a pulse sees (the
//! patient's soft tissue and spine, the lumens as contrast fills them, the radiopaque
//! catheter), the left hand's controls (trigger: the pedal; grip: a puff of contrast through
//! the catheter; primary button: the roadmap on and off) and what the console counts.
//!
//! The patient lies supine with the head towards the trunk's far end (+x, the femoral
//! approach) and the anterior side towards +z (the paper's view), so branch 2 (towards -y)
//! is on the patient's left: on the right of a frontal picture.

use crate::imaging::contrast::{Contrast, Vessel as Flow};
use crate::imaging::fluoro::{Fluoroscope, Patient, Picture, Settings};
use crate::imaging::xray::{Body, Material, Scene};
use crate::models::skeleton::in_vessel::CatheterInVessel;
use crate::models::skeleton::vessel::{Tube, Vessel};
use crate::param_fields;
use crate::params::{ParamSpec, Params};
use crate::sim::{Hand, InputFrame, PadDirection};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// The fluoroscope and the contrast (`[fluoroscopy]`; optional: a scenario without it gets
/// these defaults).
#[derive(Debug, Clone, Copy, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FluoroTable {
    pub pulse_hz: f64,
    pub kerma_ugy_per_pulse: f64,
    pub photons_per_mm2_per_ugy: f64,
    pub pixels: u32,
    pub field_m: f64,
    pub source_to_isocentre_m: f64,
    pub source_to_detector_m: f64,
    pub collimation: f64,
    pub tissue_m: f64,
    pub tissue_mu_per_m: f64,
    pub bone_mu_per_m: f64,
    pub contrast_mu_per_m: f64,
    pub catheter_mu_per_m: f64,
    pub flow_ml_per_s: f64,
    pub injection_ml_per_s: f64,
}

impl Params for FluoroTable {
    const SPECS: &'static [ParamSpec] = &[
        ParamSpec::new(
            "pulse_hz",
            "1/s",
            7.5,
            (0.5, 30.0),
            "pulses a second while the pedal is down",
        ),
        ParamSpec::new(
            "kerma_ugy_per_pulse",
            "uGy",
            20.0,
            (0.1, 1000.0),
            "air kerma a pulse gives at the interventional reference point (ours: a low-dose programme)",
        ),
        ParamSpec::new(
            "photons_per_mm2_per_ugy",
            "1/(mm^2 uGy)",
            3.0e4,
            (100.0, 1e7),
            "photons reaching the detector per mm^2 per uGy there (ours; sets the quantum noise)",
        ),
        ParamSpec::new(
            "pixels",
            "pixels",
            256.0,
            (32.0, 1024.0),
            "the picture's side",
        )
        .whole(),
        ParamSpec::new(
            "field_m",
            "m",
            0.20,
            (0.05, 0.5),
            "the detector's largest field; the zoom steps to 3/4 and 1/2 of it",
        ),
        ParamSpec::new(
            "source_to_isocentre_m",
            "m",
            0.70,
            (0.3, 1.5),
            "the focal spot's distance from the isocentre",
        ),
        ParamSpec::new(
            "source_to_detector_m",
            "m",
            1.00,
            (0.5, 2.0),
            "the focal spot's distance from the detector",
        ),
        ParamSpec::new(
            "collimation",
            "1",
            1.0,
            (0.1, 1.0),
            "the collimated field's share of the picture's width and height",
        ),
        ParamSpec::new(
            "tissue_m",
            "m",
            0.20,
            (0.02, 0.6),
            "the patient's thickness along the beam (soft tissue)",
        ),
        ParamSpec::new(
            "tissue_mu_per_m",
            "1/m",
            20.0,
            (0.0, 500.0),
            "soft tissue's attenuation (about water's at 60 keV)",
        ),
        ParamSpec::new(
            "bone_mu_per_m",
            "1/m",
            45.0,
            (0.0, 2000.0),
            "the spine's attenuation (ours)",
        ),
        ParamSpec::new(
            "contrast_mu_per_m",
            "1/m",
            230.0,
            (1.0, 5000.0),
            "undiluted contrast's attenuation (iodine 300 mg/mL near 60 keV, about 7 cm^2/g x 0.3 g/cm^3, with the water)",
        ),
        ParamSpec::new(
            "catheter_mu_per_m",
            "1/m",
            100.0,
            (1.0, 5000.0),
            "the radiopaque catheter's attenuation (ours: about as dark as the contrast around it)",
        ),
        ParamSpec::new(
            "flow_ml_per_s",
            "mL/s",
            10.0,
            (0.1, 200.0),
            "blood flow into the trunk, split evenly between the branches (ours)",
        ),
        ParamSpec::new(
            "injection_ml_per_s",
            "mL/s",
            4.0,
            (0.1, 50.0),
            "a puff of contrast by hand through the catheter (ours)",
        ),
    ];
    param_fields!(
        pulse_hz,
        kerma_ugy_per_pulse,
        photons_per_mm2_per_ugy,
        pixels,
        field_m,
        source_to_isocentre_m,
        source_to_detector_m,
        collimation,
        tissue_m,
        tissue_mu_per_m,
        bone_mu_per_m,
        contrast_mu_per_m,
        catheter_mu_per_m,
        flow_ml_per_s,
        injection_ml_per_s
    );
}

/// The table's defaults: what a scenario without `[fluoroscopy]` gets.
pub fn table_default() -> FluoroTable {
    crate::params::defaults()
}

/// Concentrations are drawn in this many steps (each its own material: bodies of one
/// material that overlap count once).
const LEVELS: usize = 8;
/// Pieces each lumen is cut into along its axis, each a capsule of its own concentration.
const PIECES: usize = 16;
/// The spine's radius and its place behind the vessel, m.
const SPINE_RADIUS_M: f64 = 0.015;
const SPINE_BEHIND_M: f64 = 0.05;

/// What the interventional console counts, in the report's metrics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Console {
    pub fluoro_time_s: f64,
    pub fluoro_runs: u32,
    pub pulses: u32,
    pub dap_gy_cm2: f64,
    pub reference_kerma_mgy: f64,
    /// Contrast injected, mL, and the puffs.
    pub contrast_ml: f64,
    pub contrast_runs: u32,
    /// Where the arm and the table are: LAO (negative: RAO) and cranial (negative: caudal),
    /// degrees; the table's travel towards the head and the patient's left, cm; the
    /// detector's field, cm.
    pub lao_deg: f64,
    pub cranial_deg: f64,
    pub table_cm: [f64; 2],
    pub field_cm: f64,
}

impl Console {
    /// The console's lines for a live panel: fluoroscopy time and runs, the dose at the
    /// reference point and the dose-area product, the contrast, the arm's angles and the
    /// field.
    pub fn figures(&self) -> Vec<(String, String)> {
        let angle = |deg: f64, plus: &str, minus: &str| {
            format!("{} {:.0}", if deg < 0.0 { minus } else { plus }, deg.abs())
        };
        vec![
            (
                "fluoroscopy".to_string(),
                format!(
                    "{:.1} s, {} run{}",
                    self.fluoro_time_s,
                    self.fluoro_runs,
                    if self.fluoro_runs == 1 { "" } else { "s" }
                ),
            ),
            (
                "dose".to_string(),
                format!(
                    "{:.2} mGy, {:.3} Gy cm2",
                    self.reference_kerma_mgy, self.dap_gy_cm2
                ),
            ),
            (
                "contrast".to_string(),
                format!("{:.1} mL in {}", self.contrast_ml, self.contrast_runs),
            ),
            (
                "C-arm".to_string(),
                format!(
                    "{}, {} deg, {:.0} cm field",
                    angle(self.lao_deg, "LAO", "RAO"),
                    angle(self.cranial_deg, "cran", "caud"),
                    self.field_cm
                ),
            ),
        ]
    }
}

/// How fast the arm turns while its pad is held, degrees a second (a motorised C-arm's
/// range), and how fast the table travels, m/s.
pub const ARM_DEG_PER_S: f64 = 15.0;
pub const TABLE_M_PER_S: f64 = 0.05;

/// The fluoroscope, the contrast and the controls' last state.
pub struct Imaging {
    pub table: FluoroTable,
    pub scope: Fluoroscope,
    /// The contrast along the vessel (none if its tree were refused, which the scenario's
    /// checks rule out: then nothing fills).
    pub contrast: Option<Contrast>,
    pub console: Console,
    /// What the monitor shows now (made again after each pulse and roadmap toggle).
    pub picture: Option<Arc<Picture>>,
    injecting: bool,
    /// The clicks at the last step: the imaging hand's (the roadmap), the other's (zoom).
    mark: bool,
    zoom_click: bool,
    /// The guidewire's attenuation, 1/m (the scenario's `guidewire.mu_per_m`; unused
    /// without a wire).
    pub wire_mu_per_m: f64,
}

impl Imaging {
    /// For `scene`'s vessel (the contrast flows along its tubes), at steps of `dt_s`, with
    /// the patient's head towards `head`.
    pub fn new(table: FluoroTable, scene: &CatheterInVessel, dt_s: f64, head: DVec3) -> Imaging {
        let v = scene.vessel();
        let flows: Vec<Flow> = tube_flows(v, table.flow_ml_per_s * 1e-6)
            .into_iter()
            .zip(&v.tubes)
            .map(|(q, t)| Flow {
                parent: t.parent,
                length_m: t.length_m,
                radius_m: t.lumen_m,
                flow_m3_per_s: q,
            })
            .collect();
        // The scenario's ranges keep the lengths and flows positive, and the branches share
        // the trunk's flow exactly: a refused tree would be a bug, logged and drawn empty.
        let contrast = Contrast::new(flows, dt_s)
            .map_err(|e| tracing::error!("the catheter's contrast tree: {e}"))
            .ok();
        let ends: Vec<DVec3> = v
            .tubes
            .iter()
            .map(|t| t.start + t.dir * t.length_m)
            .collect();
        let lo = ends
            .iter()
            .chain(v.tubes.iter().map(|t| &t.start))
            .fold(DVec3::MAX, |a, b| a.min(*b));
        let hi = ends
            .iter()
            .chain(v.tubes.iter().map(|t| &t.start))
            .fold(DVec3::MIN, |a, b| a.max(*b));
        let settings = Settings {
            patient: Patient {
                head,
                anterior: DVec3::Z,
            },
            isocentre: 0.5 * (lo + hi),
            source_to_isocentre_m: table.source_to_isocentre_m,
            source_to_detector_m: table.source_to_detector_m,
            fields_m: vec![table.field_m, 0.75 * table.field_m, 0.5 * table.field_m],
            pixels: table.pixels as usize,
            pulse_hz: table.pulse_hz,
            kerma_ugy_per_pulse: table.kerma_ugy_per_pulse,
            photons_per_mm2_per_ugy: table.photons_per_mm2_per_ugy,
            collimation: [table.collimation; 2],
        };
        Imaging {
            table,
            scope: Fluoroscope::new(settings),
            contrast,
            console: Console::default(),
            picture: None,
            injecting: false,
            mark: false,
            zoom_click: false,
            wire_mu_per_m: 0.0,
        }
    }

    /// One step of `dt_s` under the hands' controls. The left hand's: the contrast moves on
    /// (a puff at the catheter's tip while the grip is held), the pedal's pulses fire and
    /// are exposed (noise seeded by `step`), a click in the pad's centre toggles the roadmap,
    /// and the pad held at an edge turns the arm (right: LAO, left: RAO, up: cranial, down:
    /// caudal). The right hand's pad (its trigger and grip steer the catheter): held at an
    /// edge it moves the table (up: towards the head, right: towards the patient's left),
    /// and a click in its centre steps the zoom.
    pub fn step(&mut self, input: &InputFrame, scene: &CatheterInVessel, dt_s: f64, step: u64) {
        let had_roadmap = self.scope.has_roadmap();
        self.work_the_arm(input, dt_s);
        let lost_roadmap = had_roadmap && !self.scope.has_roadmap();
        let b = input.hand(Hand::Left).buttons;
        let inject = b.grip > 0.5;
        let puff = if inject {
            let rate = self.table.injection_ml_per_s * 1e-6;
            self.console.contrast_ml += self.table.injection_ml_per_s * dt_s;
            if !self.injecting {
                self.console.contrast_runs += 1;
            }
            where_is(scene, scene.catheter().tip()).map(|(k, s)| (k, s, rate))
        } else {
            None
        };
        self.injecting = inject;
        if let Some(c) = &mut self.contrast {
            c.step(puff);
        }
        // A click at the pad's edge is the arm's, not the roadmap's.
        let click = b.mark && b.pad.is_none();
        let toggled = click && !self.mark;
        let mut changed = toggled || lost_roadmap;
        if toggled {
            self.scope.roadmap_on = !self.scope.roadmap_on;
        }
        self.mark = click;
        if self.scope.step(dt_s, b.trigger > 0.5) {
            let (xray, filled) = self.scene(scene);
            self.scope.expose(&xray, filled, step);
            changed = true;
        }
        if changed {
            self.picture = self.scope.picture().map(Arc::new);
        }
        let d = self.scope.dose;
        let c = &mut self.console;
        (c.fluoro_time_s, c.fluoro_runs, c.pulses) = (d.fluoro_time_s, d.runs, d.pulses);
        (c.dap_gy_cm2, c.reference_kerma_mgy) = (d.dap_gy_cm2, d.reference_kerma_mgy);
        let p = self.scope.pose;
        (c.lao_deg, c.cranial_deg) = (p.lao_deg, p.cranial_deg);
        c.table_cm = p.pan_m.map(|m| m * 100.0);
        c.field_cm = self.scope.field_m() * 100.0;
    }

    /// The arm and the table under the pads (see [`Imaging::step`]).
    fn work_the_arm(&mut self, input: &InputFrame, dt_s: f64) {
        let turn = ARM_DEG_PER_S * dt_s;
        let (d_lao, d_cranial) = match input.hand(Hand::Left).buttons.pad {
            Some(PadDirection::Right) => (turn, 0.0),
            Some(PadDirection::Left) => (-turn, 0.0),
            Some(PadDirection::Up) => (0.0, turn),
            Some(PadDirection::Down) => (0.0, -turn),
            None => (0.0, 0.0),
        };
        let r = input.hand(Hand::Right).buttons;
        let travel = TABLE_M_PER_S * dt_s;
        let pan = match r.pad {
            Some(PadDirection::Up) => [travel, 0.0],
            Some(PadDirection::Down) => [-travel, 0.0],
            Some(PadDirection::Right) => [0.0, travel],
            Some(PadDirection::Left) => [0.0, -travel],
            None => [0.0; 2],
        };
        if d_lao != 0.0 || d_cranial != 0.0 || pan != [0.0; 2] {
            self.scope.move_by(d_lao, d_cranial, pan);
        }
        let zoom = r.mark && r.pad.is_none();
        if zoom && !self.zoom_click {
            self.scope.next_zoom();
        }
        self.zoom_click = zoom;
    }

    /// The X-ray scene now, and whether any contrast is in it: the soft tissue (a slab
    /// `tissue_m` thick across the beam), the spine behind the vessel along the patient's
    /// axis, each lumen in pieces of their contrast (levels of `1 / LEVELS` of undiluted),
    /// and the catheter as capsules between its balls.
    pub fn scene(&self, scene: &CatheterInVessel) -> (Scene, bool) {
        let t = &self.table;
        let iso = self.scope.settings.isocentre;
        let mut materials = vec![
            material("tissue", t.tissue_mu_per_m),
            material("bone", t.bone_mu_per_m),
            material("catheter", t.catheter_mu_per_m),
        ];
        materials.extend((1..=LEVELS).map(|k| {
            material(
                &format!("contrast {k}/{LEVELS}"),
                t.contrast_mu_per_m * k as f64 / LEVELS as f64,
            )
        }));
        let half = 0.5 * t.tissue_m;
        let mut bodies = vec![
            (
                Body::Cylinder {
                    a: DVec3::new(iso.x, iso.y, iso.z - half),
                    b: DVec3::new(iso.x, iso.y, iso.z + half),
                    radius: 1.0,
                },
                0,
            ),
            (
                Body::Cylinder {
                    a: DVec3::new(iso.x - 1.0, iso.y, iso.z - SPINE_BEHIND_M),
                    b: DVec3::new(iso.x + 1.0, iso.y, iso.z - SPINE_BEHIND_M),
                    radius: SPINE_RADIUS_M,
                },
                1,
            ),
        ];
        let v = scene.vessel();
        let mut filled = false;
        for (k, tube) in v.tubes.iter().enumerate() {
            let piece = tube.length_m / PIECES as f64;
            for p in 0..PIECES {
                let at = (p as f64 + 0.5) * piece;
                let c = self
                    .contrast
                    .as_ref()
                    .map_or(0.0, |c| c.concentration(k, at));
                let level = (c * LEVELS as f64).round() as usize;
                if level == 0 {
                    continue;
                }
                filled = true;
                let a = tube.start + tube.dir * (p as f64 * piece);
                bodies.push((
                    Body::Capsule {
                        a,
                        b: a + tube.dir * piece,
                        radius: tube.lumen_m,
                    },
                    2 + level.min(LEVELS),
                ));
            }
        }
        let c = scene.catheter();
        bodies.extend(capsules(&c.balls.x, 0.5 * c.params.diameter_m, 2));
        // The guidewire, a material of its own after the contrast levels: inside the
        // catheter its path adds to the catheter's.
        if let Some(wire) = scene.guidewire() {
            let m = materials.len();
            materials.push(material("guidewire", self.wire_mu_per_m));
            bodies.extend(capsules(&wire.balls.x, 0.5 * wire.params.diameter_m, m));
        }
        (Scene { materials, bodies }, filled)
    }
}

/// A chain of balls as capsules of `radius` between neighbours, of material `m`.
fn capsules(x: &[DVec3], radius: f64, m: usize) -> impl Iterator<Item = (Body, usize)> + '_ {
    x.windows(2).map(move |w| {
        (
            Body::Capsule {
                a: w[0],
                b: w[1],
                radius,
            },
            m,
        )
    })
}

fn material(name: &str, mu_per_m: f64) -> Material {
    Material {
        name: name.to_string(),
        mu_per_m,
    }
}

/// Each tube's blood flow, m^3/s: `q` into the inlet's, and each tube's outflow shared
/// among the tubes leaving its end by their lumens' cubes (Murray's law).
pub fn tube_flows(v: &Vessel, q: f64) -> Vec<f64> {
    let mut flows = vec![0.0; v.tubes.len()];
    for k in 0..v.tubes.len() {
        let into = match v.tubes[k].parent {
            None => q,
            Some(p) => {
                let cube = |t: &Tube| t.lumen_m.powi(3);
                let all: f64 = v
                    .tubes
                    .iter()
                    .filter(|t| t.parent == Some(p))
                    .map(cube)
                    .sum();
                flows[p] * cube(&v.tubes[k]) / all
            }
        };
        flows[k] = into;
    }
    flows
}

/// Which tube `p` lies in and how far along it (where tubes meet, the one whose axis is
/// nearer); none outside the lumen.
fn where_is(scene: &CatheterInVessel, p: DVec3) -> Option<(usize, f64)> {
    scene.vessel().locate(p)
}

#[cfg(test)]
#[path = "fluoroscopy_tests.rs"]
mod tests;
