//! The catheterisation as the session, window and headset see every procedure: its registry
//! entry, its build from a scenario, its score and its own benchmark lines.

use super::field;
use super::procedure::{Catheterisation, Metrics, STEPS};
use super::scenario::{self, NAME, Scenario};
use crate::models::skeleton::catheter::Catheter;
use crate::models::skeleton::guidewire::Guidewire;
use crate::models::skeleton::in_vessel::CatheterInVessel;
use crate::models::skeleton::vessel::Vessel;
use crate::procedures::{ModelReport, Procedure, ProcedureInfo};
use crate::sim::{ChecklistScore, DeviceChoice};
use glam::{DVec3, Vec3};

/// The registry's entry.
pub const INFO: ProcedureInfo = crate::procedure_info! {
    stem: "catheter", paper: "interventional-catheter.txt",
    title: "Interventional catheterisation (a vessel tree under fluoroscopy)",
    build: |_, s| build_procedure(s),
    // The catheter's: the Novint Falcon's largest force.
    // The left hand's: the guidewire, when the scenario has one.
    tools: [("guidewire", Probe, 9.0), ("catheter", Steerable, 9.0)],
    // The paper's view: the vessel from the side (+z), the bifurcation in the middle.
    view: (0.055, 0.0, 0.16) -> (0.055, 0.0, 0.0),
    // The handle's hand at the catheter's end, the other aside.
    desk_park: [(-0.05, -0.04, 0.03), (-0.1, 0.0, 0.0)],
    // The paper's Novint Falcon (9 N, 1 kHz).
    haptic_device: DeviceChoice::Falcon,
    // The left hand works the fluoroscope (`fluoroscopy.rs`).
    imaging_hand: Some(crate::sim::Hand::Left),
    bench_extra: Some(super::bench::extra),
};

/// The scene for a checked scenario: the vessel (its ostia weakened when it is a tree), the
/// catheter straight in its introducer with its tip at the inlet, pointing along the first
/// tube, and the guidewire in it when the
/// scenario has one.
pub fn build_scene(s: &Scenario) -> CatheterInVessel {
    let (tubes, branches) = s.vessel_shape();
    let mut vessel = Vessel::of_tubes(&s.vessel_params(), &tubes, branches);
    if let Some(t) = &s.tree {
        vessel.weaken_ostia(t.ostium_m, t.ostium_strength);
    }
    let catheter = Catheter::new(&s.catheter_params(), DVec3::ZERO, DVec3::X);
    let scene = CatheterInVessel::new(
        catheter,
        vessel,
        s.law(),
        s.contact.puncture_n,
        s.catheter.substeps,
    );
    match &s.guidewire {
        Some(w) => {
            let wire = Guidewire::new(&w.params(), DVec3::ZERO, DVec3::X).inserted(w.start_m);
            let (law, puncture_n) = w.law(&s.law(), s.contact.puncture_n, s.catheter.diameter_m);
            scene.with_wire(wire, law, puncture_n)
        }
        None => scene,
    }
}

/// The procedure for a checked scenario.
pub fn build_procedure(s: Scenario) -> Catheterisation {
    let scene = build_scene(&s);
    Catheterisation::new(s, scene)
}

impl Procedure for Catheterisation {
    crate::procedure_basics!(INFO, report(errors: metrics.errors), models: [scene]);

    fn contacts_now(&self) -> [Option<(Vec3, Vec3)>; 2] {
        let r = self.reaction();
        let tip = self.scene.catheter().tip().as_vec3();
        let w = self.wire_reaction();
        let wire = self
            .scene
            .guidewire()
            .filter(|_| w.length() > 0.0)
            .map(|g| (g.tip().as_vec3(), w.normalize_or(DVec3::Y).as_vec3()));
        [
            wire,
            (r.length() > 0.0).then(|| (tip, r.normalize_or(DVec3::Y).as_vec3())),
        ]
    }

    fn model_reports(&self) -> Vec<ModelReport> {
        let s = &self.scene;
        let springs = "semi_implicit_euler";
        vec![
            ModelReport::new(
                "catheter",
                "skeleton_springs",
                s.catheter().balls.len(),
                s.catheter().springs.len() + s.catheter().angles.len(),
            )
            .with_springs(springs),
            ModelReport::new(
                "vessel",
                "skeleton_springs",
                s.vessel().balls.len(),
                s.vessel().springs.len(),
            )
            .with_springs(springs)
            .with_triangles(s.vessel().triangles().len()),
            ModelReport::new("collision", "sphere_sections", 0, 0),
        ]
        .into_iter()
        .chain(s.guidewire().map(|w| {
            ModelReport::new(
                "guidewire",
                "skeleton_springs",
                w.balls.len(),
                w.springs.len() + w.angles.len(),
            )
            .with_springs(springs)
        }))
        .collect()
    }

    fn model_times(&self) -> Vec<f64> {
        self.scene.times()
    }

    fn memory(&self) -> Vec<(&'static str, usize)> {
        let s = &self.scene;
        vec![
            ("catheter", s.catheter().balls.heap_bytes()),
            (
                "guidewire",
                s.guidewire().map_or(0, |w| w.balls.heap_bytes()),
            ),
            (
                "vessel",
                s.vessel().balls.heap_bytes() + s.vessel().springs.capacity() * 40,
            ),
        ]
    }
}

/// Points taken off per puncture and per entry into the wrong branch.
const PUNCTURE_PENALTY: f32 = 30.0;
const WRONG_BRANCH_PENALTY: f32 = 5.0;

/// The score, 0-100: 60 x completion + 20 x efficiency + 20 x gentleness (1 while the
/// largest force stays within the paper's 3.5 N, falling to 0 at the device's largest), less
/// 30 per puncture and 5 per wrong branch (a flat score until the assessment trees of #12).
pub fn score(s: &Scenario, m: &Metrics) -> (f32, ChecklistScore) {
    let time = (s.task.target_time_s, m.completion_time_s);
    let penalty =
        PUNCTURE_PENALTY * m.punctures as f32 + WRONG_BRANCH_PENALTY * m.wrong_branch as f32;
    let most = s.device.max_force_n.max(3.5 + 1e-9);
    let over = ((m.peak_force_n - 3.5) / (most - 3.5)).clamp(0.0, 1.0);
    let gentleness = ("gentleness", (1.0 - over) as f32);
    ChecklistScore::new(&m.steps_done, &STEPS, time, gentleness, penalty).scored()
}
