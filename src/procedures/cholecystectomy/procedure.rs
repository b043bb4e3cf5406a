//! The `cholecystectomy` procedure: the scene of [`super::scene`] driven by the trainee's
//! hands. The left holds a grasper (the grip closes it) to retract the fundus. The right
//! hand's primary button changes its instrument in turn: the L-hook (the trigger is its
//! current: it cuts strands and fascia at its end, and burns the liver where its end touches
//! the capsule), the clip applier (a trigger press places a clip on the vessel within reach),
//! the scissors (a trigger press cuts the vessel within reach, or the strands there) and a
//! second grasper. The task's checklist, the clips and cuts, the metrics and what the
//! renderer draws.

use super::anatomy::body;
use super::clips::{ClipRecord, CutError, PatientEnd};
use super::drawing::{Skin, fascia_mesh, lattice_skin, skin_mesh, tubes};
use super::scenario::Scenario;
use super::scene::{CholeScene, HandTool, StepOutcome};
use crate::collision::Instrument;
use crate::models::particles::adhesion::AdhesionBreak;
use crate::procedures::TaskStep;
use crate::procedures::scope::Scope;
use crate::sim::Fnv;
use crate::sim::{
    Bleed, EmissionKind, EmissionLog, EventKind, Hand, HandInput, InputFrame, InstrumentShape,
    ProcedureEvent, SimEvent, Snapshot, SurfaceRole, ToolSnapshot,
};
use glam::Vec3;
use serde::Serialize;
use std::collections::HashSet;

/// The task, in order.
pub const STEPS: [TaskStep; 6] = [
    TaskStep {
        id: "retract",
        text: "Grasp the fundus with the left grasper and retract it",
    },
    TaskStep {
        id: "expose",
        text: "Clear the fat from Calot's triangle until duct and artery are seen",
    },
    TaskStep {
        id: "clip_duct",
        text: "Place three clips on the cystic duct",
    },
    TaskStep {
        id: "clip_artery",
        text: "Clip the cystic artery",
    },
    TaskStep {
        id: "divide",
        text: "Cut the cystic duct and the cystic artery between the clips",
    },
    TaskStep {
        id: "separate",
        text: "Separate the gallbladder from the liver bed without burning the liver",
    },
];

/// The right hand's instruments, in the order its primary button hands them over.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RightTool {
    #[default]
    Hook,
    ClipApplier,
    Scissors,
    Grasper,
}

impl RightTool {
    pub const ALL: [RightTool; 4] = [
        RightTool::Hook,
        RightTool::ClipApplier,
        RightTool::Scissors,
        RightTool::Grasper,
    ];

    pub fn name(self) -> &'static str {
        match self {
            RightTool::Hook => "hook",
            RightTool::ClipApplier => "clip applier",
            RightTool::Scissors => "scissors",
            RightTool::Grasper => "right grasper",
        }
    }

    fn index(self) -> usize {
        Self::ALL.iter().position(|t| *t == self).unwrap_or(0)
    }

    fn next(self) -> RightTool {
        Self::ALL[(self.index() + 1) % Self::ALL.len()]
    }
}

/// A grasper's jaws' middle lies this far along the shaft from their hinge, m.
const JAW_MID_M: f32 = 0.008;
/// The jaws' opening when open, rad.
const OPEN_RAD: f32 = 0.6;
/// Steps between two measures of Calot's triangle's exposure (it casts a ray per grid point
/// past every fat particle).
const EXPOSURE_EVERY: u64 = 20;

/// The live hook's end off the liver for this long or less, s, is still the same contact (one
/// injury): pressed on, the capsule's particle can spring out of the current's reach and back
/// within a few steps (traced on the coarse lattice: 3 steps out of reach in a press of 30).
const CONTACT_GAP_S: f64 = 0.05;

/// A vessel cut short of its clips: where on it, which end is the patient's, and its bleeding.
#[derive(Debug, Clone, Copy)]
struct Bleeding {
    vessel: &'static str,
    at_m: f32,
    patient: PatientEnd,
    bleed: Bleed,
    /// Seconds the hook's current has been held at its source.
    coagulated_s: f64,
}

impl Bleeding {
    /// Whether a clip at `at_m` along the vessel lies on the patient's side of the cut (the
    /// side the blood comes from).
    fn upstream(&self, at_m: f32) -> bool {
        match self.patient {
            PatientEnd::First => at_m < self.at_m,
            PatientEnd::Last => at_m > self.at_m,
        }
    }

    /// Stops it at `now_s`, `by` a clip or coagulation: the `bleeding_stopped` event.
    fn stop(&mut self, now_s: f64, by: &'static str) -> EventKind {
        self.bleed.stop_s = Some(now_s);
        EventKind::Procedure(ProcedureEvent::new(
            "bleeding_stopped",
            BleedingStopped {
                vessel: self.vessel,
                bled_s: now_s - self.bleed.start_s,
                by,
            },
        ))
    }
}

/// The `bleeding_stopped` event: the vessel, how long it bled, s, and what stopped it (`clip`
/// or `coagulation`).
#[derive(Debug, Clone, Copy, Serialize)]
struct BleedingStopped {
    vessel: &'static str,
    bled_s: f64,
    by: &'static str,
}

/// Running metrics of one session.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Metrics {
    pub completion_time_s: Option<f64>,
    pub path_length_left_m: f32,
    pub path_length_right_m: f32,
    /// How far the left grasper has moved the gallbladder it holds at most, m.
    pub retraction_m: f32,
    /// The share of Calot's triangle seen past the fat, last measured.
    pub calot_exposure: f32,
    /// Adhesion strands torn by pulling and cut by the hook or scissors; the fat's strands
    /// torn or cut.
    pub adhesions_torn: u32,
    pub adhesions_cut: u32,
    pub fat_strands_broken: u32,
    /// Steps with the hook's current on, and of them those with its end on the liver.
    pub current_steps: u32,
    pub liver_burn_steps: u32,
    /// Times the live hook came onto the liver's capsule.
    pub injuries: u32,
    pub bile_leaks: u32,
    pub bleedings: u32,
    /// Clip applier presses that found no vessel within reach.
    pub missed_clips: u32,
    pub instrument_changes: u32,
    pub max_left_force_n: f32,
    pub max_right_force_n: f32,
    /// Errors: injuries, bile leaks and bleedings.
    pub errors: u32,
    /// Every clip and cut, in order.
    pub clips: ClipRecord,
    pub steps_done: Vec<String>,
}

pub struct Cholecystectomy {
    pub scenario: Scenario,
    pub scene: CholeScene,
    pub metrics: Metrics,
    skins: [Skin; 3],
    tools: [ToolSnapshot; 2],
    right: RightTool,
    /// Last step's primary button and trigger on the right hand (presses act once).
    right_button: bool,
    right_trigger: bool,
    /// When the live hook's end was last on the liver, s (None: not since the current went on).
    burned_at_s: Option<f64>,
    /// Where the left grasp took the gallbladder (its held particles' mean), m.
    grasp_from: Option<Vec3>,
    prev_tools: Option<[Vec3; 2]>,
    last: StepOutcome,
    smoke: EmissionLog,
    /// Vessels cut short of their clips, bleeding until a clip on the patient's side of the
    /// cut stops them.
    bleeds: Vec<Bleeding>,
    /// From Calot's triangle towards the laparoscope's home (the exposure is judged from
    /// the standard view, wherever the trainee has moved the camera).
    towards_camera: Vec3,
    /// The laparoscope the left device drives while its primary button is held.
    scope: Scope,
}

/// The scene's instrument for a pose: a grasper shape (hinge behind the jaws' middle at
/// `at`), open or closed; none for a pose that is not finite.
fn grasper_at(hand: &HandInput, closed: bool, grasps: bool) -> Option<HandTool> {
    let q = hand.pose.orientation;
    let at = hand.pose.position;
    let hinge = at - hand.pose.forward() * JAW_MID_M;
    let opening = if closed { 0.0 } else { OPEN_RAD };
    let instrument = Instrument::grasper(hinge, q, opening).ok()?;
    Some(HandTool {
        instrument,
        jaw: at,
        closed: closed && grasps,
    })
}

/// An instrument's shaft alone, ending at the hinge behind the jaws' middle at the hand's
/// position; none for a pose that is not finite.
fn shaft_at(hand: &HandInput) -> Option<HandTool> {
    let at = hand.pose.position;
    let hinge = at - hand.pose.forward() * JAW_MID_M;
    let shaft = crate::collision::ToolCylinder::constant(
        hinge - hand.pose.forward() * SHAFT_M,
        hinge,
        SHAFT_RADIUS_M,
    )
    .ok()?;
    Some(HandTool {
        instrument: Instrument::new(vec![shaft]).ok()?,
        jaw: at,
        closed: false,
    })
}

/// A 5 mm instrument's shaft: its length and radius, m.
const SHAFT_M: f32 = 0.33;
const SHAFT_RADIUS_M: f32 = 0.0025;

impl Cholecystectomy {
    pub fn new(scenario: Scenario, scene: CholeScene) -> Self {
        let a = &scene.anatomy;
        let skins = [0, 1, 2].map(|k| {
            let o = &a.organs[k];
            let members: Vec<u32> = o.range.clone().collect();
            lattice_skin(&a.particles.x, &members, o.spacing_m)
        });
        let centre = (a.calot[0] + a.calot[1] + a.calot[2]) / 3.0;
        let towards_camera = (super::plugin::INFO.view.eye - centre).normalize_or(Vec3::Z);
        Cholecystectomy {
            scenario,
            scene,
            metrics: Metrics::default(),
            skins,
            tools: [ToolSnapshot::default(); 2],
            right: RightTool::Hook,
            right_button: false,
            right_trigger: false,
            burned_at_s: None,
            grasp_from: None,
            prev_tools: None,
            last: StepOutcome::default(),
            smoke: EmissionLog::smoke(),
            bleeds: Vec::new(),
            towards_camera,
            scope: Scope::new(super::plugin::INFO.view),
        }
    }

    pub fn is_completed(&self) -> bool {
        self.metrics.steps_done.len() == STEPS.len()
    }

    pub fn right_tool(&self) -> RightTool {
        self.right
    }

    pub fn reactions(&self) -> [Vec3; 2] {
        self.last.reactions
    }

    /// Where each hand's instrument works now (a jaw, the hook's end).
    pub fn tool_tip(&self, k: usize) -> Vec3 {
        self.tools[k.min(1)].tip
    }

    fn time_s(&self, steps: u64) -> f64 {
        steps as f64 * f64::from(self.scenario.dt_s)
    }

    /// Advances one step.
    pub fn step(&mut self, input: &InputFrame, step: u64, events: &mut Vec<SimEvent>) {
        let dt = self.scenario.dt_s;
        let t = self.scenario.tools;
        let device = input.hand(Hand::Left);
        // The left device drives the camera while its button is held; the grasper waits.
        let left = &HandInput {
            pose: self.scope.update(&device.pose, device.buttons.mark),
            buttons: device.buttons,
        };
        let right = input.hand(Hand::Right);
        let mut ev: Vec<EventKind> = Vec::new();
        let places = [left.pose.position, right.pose.position];
        if let Some(prev) = self.prev_tools
            && places.iter().chain(&prev).all(|p| p.is_finite())
        {
            self.metrics.path_length_left_m += places[0].distance(prev[0]);
            self.metrics.path_length_right_m += places[1].distance(prev[1]);
        }
        self.prev_tools = Some(places);
        // The primary button hands the right hand its next instrument.
        if right.buttons.mark && !self.right_button {
            self.right = self.right.next();
            self.metrics.instrument_changes += 1;
            ev.push(EventKind::Procedure(ProcedureEvent::new(
                "instrument_change",
                Change {
                    hand: "right",
                    to: self.right.name(),
                },
            )));
        }
        self.right_button = right.buttons.mark;
        let trigger = right.buttons.trigger >= t.trigger_threshold;
        let pressed = trigger && !self.right_trigger;
        self.right_trigger = trigger;
        let now_s = self.time_s(step + 1);
        let left_tool = grasper_at(left, left.buttons.grip >= t.grip_threshold, true);
        let (right_tool, hook_end) = match self.right {
            RightTool::Hook => {
                match Instrument::l_hook(right.pose.position, right.pose.orientation) {
                    Ok(h) => {
                        let end = h.cylinders().get(1).map_or(right.pose.position, |c| c.p1());
                        let tool = HandTool {
                            instrument: h,
                            jaw: end,
                            closed: false,
                        };
                        (Some(tool), Some(end))
                    }
                    Err(_) => (None, None),
                }
            }
            // Their open jaws straddle what they close on: only the shaft pushes tissue.
            RightTool::ClipApplier | RightTool::Scissors => (shaft_at(right), None),
            RightTool::Grasper => {
                let closed = right.buttons.trigger.max(right.buttons.grip) >= t.grip_threshold;
                (grasper_at(right, closed, true), None)
            }
        };
        // The instruments act before the physics step: a clip, a cut, the current.
        let jaw = right.pose.position;
        let mut cut_strands: Vec<AdhesionBreak> = Vec::new();
        let mut fat_cut = 0;
        let holding = self.right;
        match holding {
            RightTool::Hook if trigger => {
                if let Some(end) = hook_end {
                    self.coagulate(end, f64::from(dt), now_s, &mut ev);
                    let d = self.scene.dissect(end, t.dissect_radius_m);
                    cut_strands = d.adhesions;
                    fat_cut = d.bonds.len();
                    self.metrics.current_steps += 1;
                    // The capsule is touched where a liver particle's sphere comes within
                    // the current's reach of the hook's end.
                    let reach = t.dissect_radius_m + self.scene.params.contact_radius_m;
                    let on_liver = self.scene.touching(body::LIVER, end, reach) > 0;
                    if on_liver {
                        self.metrics.liver_burn_steps += 1;
                        let same_contact = self
                            .burned_at_s
                            .is_some_and(|at| now_s - at <= CONTACT_GAP_S);
                        if !same_contact {
                            self.metrics.injuries += 1;
                            self.metrics.errors += 1;
                            ev.push(EventKind::Procedure(ProcedureEvent::new(
                                "injury",
                                Injury {
                                    tissue: "liver",
                                    position: end.to_array(),
                                },
                            )));
                            ev.push(EventKind::Alarm {
                                tool: "hook".to_string(),
                                message: "the hook's current is on against the liver".to_string(),
                            });
                        }
                    }
                    if on_liver {
                        self.burned_at_s = Some(now_s);
                    }
                    if !cut_strands.is_empty() || d.cloth > 0 || fat_cut > 0 {
                        self.smoke.record(now_s, end, EmissionKind::Smoke);
                    }
                }
            }
            RightTool::ClipApplier if pressed => self.clip(jaw, now_s, &mut ev),
            // Scissors that find no vessel cut the strands there.
            RightTool::Scissors if pressed && !self.divide(jaw, now_s, &mut ev) => {
                let d = self.scene.dissect(jaw, t.dissect_radius_m);
                cut_strands = d.adhesions;
                fat_cut = d.bonds.len();
            }
            _ => {}
        }
        if !(self.right == RightTool::Hook && trigger) {
            self.burned_at_s = None;
        }
        let was_held = !self.scene.held(0).is_empty();
        let out = self.scene.step(dt, [left_tool, right_tool], step, &mut ev);
        self.retraction(was_held, &mut ev);
        for b in &cut_strands {
            self.metrics.adhesions_cut += 1;
            ev.push(strand_event(b, "cut"));
        }
        for b in &out.breaks {
            self.metrics.adhesions_torn += 1;
            ev.push(strand_event(b, "torn"));
        }
        self.metrics.fat_strands_broken += (fat_cut + out.bond_breaks.len()) as u32;
        let m = &mut self.metrics;
        m.max_left_force_n = m.max_left_force_n.max(out.reactions[0].length());
        m.max_right_force_n = m.max_right_force_n.max(out.reactions[1].length());
        self.smoke.forget_before(now_s);
        self.tools = [
            ToolSnapshot {
                tip: left.pose.position,
                direction: left.pose.forward(),
                beam_end: None,
                beam_reach: None,
                active: out.held[0] > 0,
                instrument: 0,
                shape: InstrumentShape::Grasper,
                jaw: 1.0 - left.buttons.grip,
                up: left.pose.orientation * Vec3::Y,
            },
            ToolSnapshot {
                tip: hook_end.unwrap_or(right.pose.position),
                direction: right.pose.forward(),
                beam_end: None,
                beam_reach: None,
                active: trigger || out.held[1] > 0,
                instrument: self.right.index() as u8,
                shape: match self.right {
                    RightTool::Hook => InstrumentShape::Hook,
                    RightTool::ClipApplier => InstrumentShape::ClipApplier,
                    RightTool::Scissors => InstrumentShape::Scissors,
                    RightTool::Grasper => InstrumentShape::Grasper,
                },
                // The trigger closes the clip applier and the scissors, the grip the grasper.
                jaw: match self.right {
                    RightTool::Grasper => 1.0 - right.buttons.grip,
                    _ => 1.0 - right.buttons.trigger,
                },
                up: right.pose.orientation * Vec3::Y,
            },
        ];
        self.last = out;
        if step.is_multiple_of(EXPOSURE_EVERY) {
            self.metrics.calot_exposure = self.scene.calot_exposure(self.towards_camera, 12, 0.002);
        }
        self.checklist(step, &mut ev);
        events.extend(ev.into_iter().map(|kind| SimEvent { step, kind }));
    }

    /// The left grasp's hold on the gallbladder: where it took it, how far it has moved it.
    fn retraction(&mut self, was_held: bool, ev: &mut Vec<EventKind>) {
        let held = self.scene.held(0);
        let on_gallbladder: Vec<Vec3> = held
            .iter()
            .filter(|&&i| self.scene.solver().particles.body[i as usize] == body::GALLBLADDER)
            .map(|&i| self.scene.solver().particles.x[i as usize])
            .collect();
        let mean = (!on_gallbladder.is_empty())
            .then(|| on_gallbladder.iter().sum::<Vec3>() / on_gallbladder.len() as f32);
        if !held.is_empty() && !was_held {
            self.grasp_from = mean;
            ev.push(EventKind::Grasp {
                tool: "grasper".to_string(),
                model: mean.map_or("tissue", |_| "gallbladder").to_string(),
                vertices: held.len() as u32,
            });
        } else if held.is_empty() && was_held {
            self.grasp_from = None;
            ev.push(EventKind::Release {
                tool: "grasper".to_string(),
            });
        }
        if let (Some(from), Some(now)) = (self.grasp_from, mean) {
            let m = &mut self.metrics;
            m.retraction_m = m.retraction_m.max(now.distance(from));
        }
    }

    /// The hook's current on at `end` for a step of `dt`: a bleeding cut whose source lies
    /// within the coagulation reach gathers the time, and stops bleeding once it has had
    /// `coag_time_s` in all (the cystic artery is 1-2 mm across, within what monopolar current
    /// seals; a clip on the patient's side stops it at once).
    fn coagulate(&mut self, end: Vec3, dt: f64, now_s: f64, ev: &mut Vec<EventKind>) {
        let t = &self.scenario.tools;
        let (reach, needed) = (t.coag_reach_m, f64::from(t.coag_time_s));
        for b in self
            .bleeds
            .iter_mut()
            .filter(|b| b.bleed.active(now_s) && b.bleed.position.distance(end) <= reach)
        {
            b.coagulated_s += dt;
            if b.coagulated_s + 1e-9 >= needed {
                ev.push(b.stop(now_s, "coagulation"));
            }
        }
    }

    /// The bleeding sources (for tests and the renderer).
    pub fn bleeding(&self) -> Vec<Bleed> {
        self.bleeds.iter().map(|b| b.bleed).collect()
    }

    /// The clip applier closed at `jaw`: a clip on the nearest clippable vessel in reach.
    fn clip(&mut self, jaw: Vec3, now_s: f64, ev: &mut Vec<EventKind>) {
        let reach = self.scenario.tools.clip_reach_m;
        let Some(v) = self.nearest_vessel(jaw) else {
            self.metrics.missed_clips += 1;
            return;
        };
        let s = &self.scene;
        match self.metrics.clips.clip(
            &s.solver().chains,
            &s.solver().particles,
            &v,
            jaw,
            reach,
            now_s,
        ) {
            Some(c) => {
                // A clip on the patient's side of a bleeding cut stops it.
                for b in self.bleeds.iter_mut().filter(|b| {
                    b.vessel == c.vessel && b.bleed.stop_s.is_none() && b.upstream(c.at_m)
                }) {
                    ev.push(b.stop(now_s, "clip"));
                }
                let on_vessel = self.metrics.clips.clips_on(v.name) as u32;
                ev.push(EventKind::Procedure(ProcedureEvent::new(
                    "clip",
                    ClipEvent {
                        vessel: c.vessel,
                        at_m: c.at_m,
                        position: c.position,
                        order: self.metrics.clips.clips.len() as u32,
                        on_vessel,
                    },
                )));
            }
            None => self.metrics.missed_clips += 1,
        }
    }

    /// The scissors closed at `jaw`: cuts the nearest clippable vessel in reach. Whether one
    /// was cut.
    fn divide(&mut self, jaw: Vec3, now_s: f64, ev: &mut Vec<EventKind>) -> bool {
        let reach = self.scenario.tools.cut_reach_m;
        let Some(v) = self.nearest_vessel(jaw) else {
            return false;
        };
        let sv = self.scene.solver_mut();
        let Some(c) = self
            .metrics
            .clips
            .cut(&mut sv.chains, &sv.particles, &v, jaw, reach, now_s)
        else {
            return false;
        };
        ev.push(EventKind::Procedure(ProcedureEvent::new("cut", c)));
        if let Some(e) = c.error {
            let m = &mut self.metrics;
            m.errors += 1;
            let (name, message) = match e {
                CutError::BileLeak => {
                    m.bile_leaks += 1;
                    (
                        "bile_leak",
                        "bile leaks: the cystic duct was cut with fewer than two clips on the patient's side",
                    )
                }
                CutError::Bleeding => {
                    m.bleedings += 1;
                    self.bleeds.push(Bleeding {
                        vessel: c.vessel,
                        at_m: c.at_m,
                        patient: v.patient,
                        bleed: Bleed {
                            position: Vec3::from(c.position),
                            start_s: now_s,
                            stop_s: None,
                        },
                        coagulated_s: 0.0,
                    });
                    (
                        "bleeding",
                        "bleeding: the cystic artery was cut with fewer than two clips on the patient's side",
                    )
                }
            };
            ev.push(EventKind::Procedure(ProcedureEvent::new(
                name,
                UncoveredCut {
                    vessel: c.vessel,
                    clips_patient_side: c.clips_patient_side,
                    position: c.position,
                },
            )));
            ev.push(EventKind::Alarm {
                tool: "scissors".to_string(),
                message: message.to_string(),
            });
        }
        true
    }

    /// The clippable vessel whose centreline passes nearest `q`.
    fn nearest_vessel(&self, q: Vec3) -> Option<super::clips::Clippable> {
        let s = &self.scene;
        s.clippable()
            .into_iter()
            .filter_map(|v| {
                s.solver()
                    .chains
                    .nearest_segment(&s.solver().particles, v.chain, q)
                    .map(|(_, d)| (d, v))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, v)| v)
    }

    /// The checklist: only the next step can be done, so one done early waits its turn.
    fn checklist(&mut self, step: u64, ev: &mut Vec<EventKind>) {
        let k = self.scenario.task;
        let m = &self.metrics;
        let [duct, artery] = self.scene.clippable();
        let cut = |name: &str| m.clips.cuts.iter().any(|c| c.vessel == name);
        let a = &self.scene.solver().adhesion;
        let broken = a.strands() - a.intact_strands();
        let done = [
            m.retraction_m >= k.retract_m,
            m.calot_exposure >= k.expose_fraction,
            m.clips.clips_on(duct.name) >= k.duct_clips as usize,
            m.clips.clips_on(artery.name) >= k.artery_clips as usize,
            cut(duct.name) && cut(artery.name),
            broken as f32 >= k.separate_fraction * a.strands() as f32,
        ];
        let now_s = self.time_s(step + 1);
        let m = &mut self.metrics;
        crate::procedures::tick_off(&STEPS, &done, &mut m.steps_done, ev);
        if m.steps_done.len() == STEPS.len() && m.completion_time_s.is_none() {
            m.completion_time_s = Some(now_s);
        }
    }

    pub fn snapshot(&mut self, step: u64) -> Snapshot {
        let s = &self.scene;
        let p = &s.solver().particles;
        let a = &s.anatomy;
        let mut models = vec![
            skin_mesh(p, &self.skins[0], "liver", SurfaceRole::Tissue),
            skin_mesh(p, &self.skins[1], "gallbladder", SurfaceRole::Sac),
            skin_mesh(p, &self.skins[2], "fat", SurfaceRole::Fat),
        ];
        // Vessels: the ducts (region 0) and the artery (region 1), intact segments only.
        let vessels = (0..s.solver().chains.chains()).flat_map(|c| {
            let v = &a.vessels[c];
            let region = u8::from(v.body == body::CYSTIC_ARTERY);
            (0..s.solver().chains.segments(c))
                .filter(move |&k| s.solver().chains.is_intact(c, k))
                .filter_map(move |k| s.solver().chains.segment_ends(c, k))
                .map(move |e| (e, region, v.radius_m))
        });
        models.push(tubes(
            p,
            vessels,
            "vessels",
            vec![SurfaceRole::Duct, SurfaceRole::Artery],
        ));
        let alive: HashSet<(u32, u32)> = s
            .solver()
            .cloth
            .stretch_constraints()
            .iter()
            .map(|c| (c.a.min(c.b), c.a.max(c.b)))
            .collect();
        models.push(fascia_mesh(p, &a.fascia_triangles, &alive));
        let strands = s
            .solver()
            .adhesion
            .segments_for_drawing()
            .chain(s.solver().bonds.segments_for_drawing())
            .map(|e| (e, 0, STRAND_RADIUS_M));
        models.push(tubes(p, strands, "strands", vec![SurfaceRole::Membrane]));
        let time_s = self.time_s(step);
        Snapshot {
            step,
            time_s,
            models,
            tools: self.tools,
            reactions: self.reactions(),
            target_found: true,
            emissions: self.smoke.at(time_s),
            bleeding: self.bleeds.iter().map(|b| b.bleed).collect(),
            scope: self.scope.snapshot_view(),
            picture: None,
        }
    }

    /// Digest of the particles, the strands, the clips and the task's progress.
    pub fn state_hash(&self) -> u64 {
        let mut h = Fnv(self.scene.state_hash());
        let m = &self.metrics;
        h.write(m.clips.clips.len() as u32);
        h.write(m.clips.cuts.len() as u32);
        h.write(m.steps_done.len() as u32);
        h.write(self.right.index() as u32);
        h.0
    }
}

/// Strands are drawn this thick, m.
const STRAND_RADIUS_M: f32 = 0.0003;

fn strand_event(b: &AdhesionBreak, cause: &'static str) -> EventKind {
    EventKind::Procedure(ProcedureEvent::new(
        "adhesion_break",
        StrandBreak {
            strand: b.strand,
            segment: b.segment,
            cause,
            position: b.position.to_array(),
        },
    ))
}

#[derive(Serialize)]
struct Change {
    hand: &'static str,
    to: &'static str,
}

#[derive(Serialize)]
struct Injury {
    tissue: &'static str,
    position: [f32; 3],
}

#[derive(Serialize)]
struct ClipEvent {
    vessel: &'static str,
    at_m: f32,
    position: [f32; 3],
    order: u32,
    on_vessel: u32,
}

#[derive(Serialize)]
struct UncoveredCut {
    vessel: &'static str,
    clips_patient_side: u32,
    position: [f32; 3],
}

#[derive(Serialize)]
struct StrandBreak {
    strand: u32,
    segment: u32,
    cause: &'static str,
    position: [f32; 3],
}

#[cfg(test)]
#[path = "procedure_tests.rs"]
mod tests;

#[cfg(test)]
#[path = "gpu_session_tests.rs"]
mod gpu_session_tests;
