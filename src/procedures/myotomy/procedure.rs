//! The `myotomy` procedure: the precomputed esophagus of [`super::anatomy`] under two
//! instruments. The left hand holds a grasper whose closed jaws are a round tip: it palpates,
//! and while the grip is closed it holds what it touched (the wall follows it). The right
//! hand holds the electrosurgical hook, its end a smaller round tip that presses the wall too;
//! with its current on (the trigger) it cuts where it touches, as deep as the pressure it is
//! pressed with: the incision's path divides the surface's polygons (Figs 6-7 of the paper),
//! and a cut through the muscle into the mucosa is a perforation. The task's checklist, the
//! metrics and the events; the drawing is in [`super::drawing`].
//!
//! The cut is drawn and scored; it does not change the tissue's stiffness (the precomputed
//! responses stay those of the whole wall, as in the paper).

use super::anatomy::Esophagus;
use super::drawing::Drawing;
use super::scenario::Scenario;
use crate::models::bem::Palpated;
use crate::models::bem::incision::Incision;
use crate::models::bem::palpation::{Palpation, Tip, Touch};
use crate::procedures::TaskStep;
use crate::sim::Fnv;
use crate::sim::TaskStatus;
use crate::sim::{
    EmissionKind, EmissionLog, EventKind, Hand, InputFrame, InstrumentShape, ProcedureEvent,
    SimEvent, Snapshot, ToolSnapshot,
};
use crate::sim::{ModelId, World};
use glam::{DVec3, Vec3};
use serde::Serialize;
use std::time::Instant;

/// The task, in order.
pub const STEPS: [TaskStep; 3] = [
    TaskStep {
        id: "palpate",
        text: "Press the sphincter with the grasper to feel it",
    },
    TaskStep {
        id: "incise",
        text: "Start the myotomy: the hook's current on against the anterior wall",
    },
    TaskStep {
        id: "divide",
        text: "Divide the muscle from above the junction onto the stomach without cutting \
               through the mucosa",
    },
];

/// The depth record's bands along the tube, m.
pub const BAND_M: f64 = 0.001;
/// The grasper palpates the sphincter when it presses within this distance of the junction
/// along the tube, m.
const SPHINCTER_REACH_M: f64 = 0.010;
/// Where an instrument whose pose is not finite is put: far from the tissue, m.
const AWAY_M: f64 = 10.0;
/// An instrument's shaft (5 mm across) where it meets the wall, from just behind its working
/// end to this far back along it, m.
const SHAFT_RADIUS_M: f64 = 0.0025;
const SHAFT_CONTACT_M: f64 = 0.06;

/// Running metrics of one session.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Metrics {
    pub completion_time_s: Option<f64>,
    pub path_length_left_m: f32,
    pub path_length_right_m: f32,
    pub max_left_force_n: f32,
    pub max_right_force_n: f32,
    /// The hardest the grasper pressed the sphincter, N.
    pub palpation_force_n: f64,
    /// Steps with the hook's current on, and of them those it cut the wall in.
    pub current_steps: u32,
    pub cutting_steps: u32,
    /// Strokes of the live hook on the wall (each a path from contact to lift).
    pub strokes: u32,
    /// The incision's length on the surface, m.
    pub incision_length_m: f64,
    /// How much of the myotomy's span has its muscle divided, m, of how much.
    pub divided_m: f64,
    pub required_m: f64,
    /// `divided_m` over `required_m`, at most 1.
    pub divided_fraction: f64,
    /// The deepest cut, m.
    pub deepest_cut_m: f64,
    /// The surface's triangles now (divided along the incision), and at the start.
    pub triangles: u32,
    pub original_triangles: u32,
    pub perforations: u32,
    /// Contact updates the capacitance solve refused (the instrument felt nothing that step).
    pub contact_failures: u32,
    /// Errors: perforations.
    pub errors: u32,
    pub steps_done: Vec<String>,
}

/// The wall's place in the myotomy's world.
const WALL: ModelId = ModelId(0);

pub struct Myotomy {
    pub scenario: Scenario,
    pub esophagus: Esophagus,
    /// The world the palpated wall steps in.
    world: World<Palpated>,
    pub incision: Incision,
    pub metrics: Metrics,
    /// The deepest cut in each band along the tube, m.
    pub depth_bands: Vec<f64>,
    /// The cut's depth at each incision vertex on a cut edge, m (0: none).
    pub cut_depth: Vec<f64>,
    touches: [Touch; 2],
    reactions: [Vec3; 2],
    tools: [ToolSnapshot; 2],
    prev_tools: Option<[Vec3; 2]>,
    /// The hook's current was on against the wall last step (its stroke continues).
    cutting: bool,
    /// The last cut was through the mucosa.
    perforating: bool,
    palpated: bool,
    smoke: EmissionLog,
    /// The depth the hook cut to in the last step, m (0: it did not cut).
    pub last_cut_m: f64,
    /// Wall-clock seconds in the contact update and in the incision.
    pub times: [f64; 2],
    drawing: Drawing,
}

impl Myotomy {
    pub fn new(scenario: Scenario, esophagus: Esophagus, palpation: Palpation) -> Myotomy {
        let s = &esophagus.surface;
        let incision = Incision::new(s.vertices.clone(), s.triangles.clone());
        let e = &scenario.esophagus;
        let bands = (e.length_m / BAND_M).ceil() as usize;
        let k = &scenario.task;
        let drawing = Drawing::new(&esophagus);
        let mut world = World::new();
        let wall = world.add(Palpated::new("esophagus", palpation));
        debug_assert_eq!(wall, WALL);
        Myotomy {
            metrics: Metrics {
                original_triangles: s.triangles.len() as u32,
                triangles: s.triangles.len() as u32,
                required_m: k.above_m + k.below_m,
                ..Metrics::default()
            },
            depth_bands: vec![0.0; bands],
            cut_depth: vec![0.0; s.vertices.len()],
            scenario,
            esophagus,
            world,
            incision,
            touches: Default::default(),
            reactions: [Vec3::ZERO; 2],
            tools: [ToolSnapshot::default(); 2],
            prev_tools: None,
            cutting: false,
            perforating: false,
            palpated: false,
            smoke: EmissionLog::smoke(),
            last_cut_m: 0.0,
            times: [0.0; 2],
            drawing,
        }
    }

    /// The palpation of the wall.
    pub fn palpation(&self) -> &Palpation {
        self.world.model(WALL).palpation()
    }

    /// The world the wall steps in (the procedure's model figures).
    pub fn world(&self) -> &World<Palpated> {
        &self.world
    }

    pub fn world_mut(&mut self) -> &mut World<Palpated> {
        &mut self.world
    }

    pub fn is_completed(&self) -> bool {
        self.metrics.steps_done.len() == STEPS.len()
    }

    pub fn reactions(&self) -> [Vec3; 2] {
        self.reactions
    }

    /// Where each hand's instrument tip is now.
    pub fn tool_tip(&self, k: usize) -> Vec3 {
        self.tools[k.min(1)].tip
    }

    /// What each instrument touches after the last step.
    pub fn touches(&self) -> &[Touch; 2] {
        &self.touches
    }

    fn time_s(&self, steps: u64) -> f64 {
        steps as f64 * f64::from(self.scenario.dt_s)
    }

    /// Advances one step.
    pub fn step(&mut self, input: &InputFrame, step: u64, events: &mut Vec<SimEvent>) {
        let t = self.scenario.tools;
        let (left, right) = (input.hand(Hand::Left), input.hand(Hand::Right));
        let mut ev: Vec<EventKind> = Vec::new();
        let places = [left.pose.position, right.pose.position];
        if let Some(prev) = self.prev_tools
            && places.iter().chain(&prev).all(|p| p.is_finite())
        {
            self.metrics.path_length_left_m += places[0].distance(prev[0]);
            self.metrics.path_length_right_m += places[1].distance(prev[1]);
        }
        self.prev_tools = Some(places);
        let centre = |p: Vec3| {
            if p.is_finite() {
                p.as_dvec3()
            } else {
                DVec3::splat(AWAY_M)
            }
        };
        let radii = [t.grasper_radius_m, t.hook_radius_m];
        // Each instrument's working end, then its 5 mm shaft behind it: the whole instrument
        // presses the wall, not only its end.
        let shaft = |k: usize, pose: &crate::sim::Pose| {
            let back = |l: f64| centre(pose.position - pose.forward() * l as f32);
            Tip {
                centre_m: back(radii[k] + SHAFT_RADIUS_M),
                radius_m: SHAFT_RADIUS_M,
                back_m: back(SHAFT_CONTACT_M),
            }
        };
        let tips = [
            Tip::sphere(centre(places[0]), radii[0]),
            Tip::sphere(centre(places[1]), radii[1]),
            shaft(0, &left.pose),
            shaft(1, &right.pose),
        ];
        let grasp = [left.buttons.grip >= t.grip_threshold, false, false, false];
        let owners = [Hand::Left, Hand::Right, Hand::Left, Hand::Right];
        let set: [(Tip, bool, Hand); 4] = std::array::from_fn(|k| (tips[k], grasp[k], owners[k]));
        self.world.model_mut(WALL).set_tips(&set);
        let t0 = Instant::now();
        self.world.step(self.scenario.dt_s, step, &mut ev);
        self.times[0] += t0.elapsed().as_secs_f64();
        let mut shafts = [DVec3::ZERO; 2];
        let frozen = self.world.is_frozen(WALL);
        match self.world.model_mut(WALL).take_touches() {
            Some(touches) if !frozen => {
                for (k, touch) in touches.into_iter().enumerate() {
                    match k {
                        0 | 1 => self.touches[k] = touch,
                        _ => shafts[k - 2] = touch.force_n,
                    }
                }
            }
            Some(_) => self.touches = Default::default(),
            None => {
                self.touches = Default::default();
                self.metrics.contact_failures += 1;
            }
        }
        // The instruments feel minus what the tissue takes from their ends and shafts.
        self.reactions = [0, 1].map(|k| (-(self.touches[k].force_n + shafts[k])).as_vec3());
        let m = &mut self.metrics;
        m.max_left_force_n = m.max_left_force_n.max(self.reactions[0].length());
        m.max_right_force_n = m.max_right_force_n.max(self.reactions[1].length());
        let k = self.scenario.task;
        if (tips[0].centre_m.z - k.junction_m).abs() <= SPHINCTER_REACH_M
            && !self.touches[0].held.is_empty()
        {
            let f = self.touches[0].force_n.length();
            m.palpation_force_n = m.palpation_force_n.max(f);
            self.palpated |= f >= k.palpate_force_n;
        }
        let now_s = self.time_s(step + 1);
        let current = right.buttons.trigger >= t.trigger_threshold;
        let t1 = Instant::now();
        self.last_cut_m = 0.0;
        if current {
            self.metrics.current_steps += 1;
        }
        if current && !self.touches[1].held.is_empty() {
            self.cut(&tips[1], now_s, &mut ev);
        } else if self.cutting {
            self.incision.lift();
            self.cutting = false;
            self.perforating = false;
        }
        self.times[1] += t1.elapsed().as_secs_f64();
        self.smoke.forget_before(now_s);
        self.tools = [
            ToolSnapshot {
                tip: places[0],
                direction: left.pose.forward(),
                beam_end: None,
                beam_reach: None,
                active: !self.touches[0].held.is_empty(),
                instrument: 0,
                shape: InstrumentShape::Grasper,
                jaw: 1.0 - left.buttons.grip,
                up: left.pose.orientation * Vec3::Y,
            },
            ToolSnapshot {
                tip: places[1],
                direction: right.pose.forward(),
                beam_end: None,
                beam_reach: None,
                active: current,
                instrument: 0,
                shape: InstrumentShape::Hook,
                jaw: 0.0,
                up: right.pose.orientation * Vec3::Y,
            },
        ];
        self.checklist(step, &mut ev);
        events.extend(ev.into_iter().map(|kind| SimEvent { step, kind }));
    }

    /// The live hook on the wall: the incision follows it and cuts as deep as it presses.
    fn cut(&mut self, tip: &Tip, now_s: f64, ev: &mut Vec<EventKind>) {
        let touch = &self.touches[1];
        let e = self.scenario.esophagus;
        // The mean contact pressure, Hertz's for a sphere of the tip's radius on the tissue:
        // the force over the contact disc of radius `a = (3 F R / 4 E*)^(1/3)`,
        // `E* = E / (1 - nu^2)`. It follows the force smoothly (the elements' centroids
        // under the tip would make a disc that jumps as they come and go).
        let f = touch.force_n.length();
        let e_star = e.young_pa / (1.0 - e.poisson * e.poisson);
        let a = (3.0 * f * tip.radius_m / (4.0 * e_star)).cbrt();
        let pressure_pa = if a > 0.0 {
            f / (std::f64::consts::PI * a * a)
        } else {
            0.0
        };
        let depth = pressure_pa * 1e-3 * self.scenario.tools.cut_depth_m_per_kpa;
        self.last_cut_m = depth;
        // Where the tip is over the resting wall: its radial projection onto the outer
        // surface, in the original triangle under it.
        let c = tip.centre_m;
        let radial = DVec3::new(c.x, c.y, 0.0).normalize_or(DVec3::Y);
        let p = DVec3::new(0.0, 0.0, c.z) + radial * e.outer_radius_m;
        let Some(under) = touch.held.iter().copied().min_by(|&a, &b| {
            let da = (self.esophagus.problem.elements[a].centroid - p).length_squared();
            let db = (self.esophagus.problem.elements[b].centroid - p).length_squared();
            da.total_cmp(&db).then(a.cmp(&b))
        }) else {
            return;
        };
        let first = !self.cutting;
        let cuts_before = self.incision.cuts().len();
        let piece = self.incision.piece_at(under, p);
        self.incision.advance(piece, p);
        self.cutting = true;
        self.cut_depth.resize(self.incision.vertices.len(), 0.0);
        for &[a, b] in &self.incision.cuts()[cuts_before..] {
            for v in [a, b] {
                let d = &mut self.cut_depth[v as usize];
                *d = d.max(depth.min(e.wall_m));
            }
        }
        let band = ((p.z / BAND_M).floor().max(0.0) as usize).min(self.depth_bands.len() - 1);
        self.depth_bands[band] = self.depth_bands[band].max(depth);
        let m = &mut self.metrics;
        m.cutting_steps += 1;
        m.deepest_cut_m = m.deepest_cut_m.max(depth);
        m.incision_length_m = self.incision.cut_length_m();
        m.triangles = self.incision.triangles.len() as u32;
        let k = self.scenario.task;
        let (from, to) = (k.junction_m - k.above_m, k.junction_m + k.below_m);
        m.divided_m = self
            .depth_bands
            .iter()
            .enumerate()
            .map(|(i, &d)| {
                let (lo, hi) = (i as f64 * BAND_M, (i + 1) as f64 * BAND_M);
                let overlap = (hi.min(to) - lo.max(from)).max(0.0);
                if d >= k.muscle_m { overlap } else { 0.0 }
            })
            .sum();
        m.divided_fraction = if m.required_m > 0.0 {
            (m.divided_m / m.required_m).min(1.0)
        } else {
            0.0
        };
        // Where the hook is in the field.
        let position = c.as_vec3().to_array();
        if first {
            m.strokes += 1;
        }
        if first || self.incision.cuts().len() > cuts_before {
            ev.push(EventKind::Procedure(ProcedureEvent::new(
                "incision",
                IncisionEvent {
                    position,
                    depth_m: depth,
                    length_m: m.incision_length_m,
                    triangles: m.triangles,
                    stroke: m.strokes,
                },
            )));
        }
        let through = depth >= e.wall_m;
        if through && !self.perforating {
            m.perforations += 1;
            m.errors += 1;
            ev.push(EventKind::Procedure(ProcedureEvent::new(
                "perforation",
                Perforation {
                    position,
                    depth_m: depth,
                    pressure_pa,
                },
            )));
            ev.push(EventKind::Alarm {
                tool: "hook".to_string(),
                message: "the hook has cut through the mucosa: the esophagus is perforated"
                    .to_string(),
            });
        }
        self.perforating = through;
        self.smoke.record(now_s, c.as_vec3(), EmissionKind::Smoke);
    }

    /// The checklist: only the next step can be done, so one done early waits its turn.
    fn checklist(&mut self, step: u64, ev: &mut Vec<EventKind>) {
        let m = &self.metrics;
        // Bands cover the span to within half a band at either end.
        let done = [
            self.palpated,
            m.cutting_steps > 0,
            m.divided_m >= m.required_m - BAND_M,
        ];
        let now_s = self.time_s(step + 1);
        let m = &mut self.metrics;
        crate::procedures::tick_off(&STEPS, &done, &mut m.steps_done, ev);
        if m.steps_done.len() == STEPS.len() && m.completion_time_s.is_none() {
            m.completion_time_s = Some(now_s);
        }
    }

    pub fn snapshot(&mut self, step: u64) -> Snapshot {
        let models = self.drawing.models(
            &self.esophagus,
            self.world.model(WALL).palpation(),
            &self.incision,
            &self.cut_depth,
        );
        let time_s = self.time_s(step);
        Snapshot {
            step,
            time_s,
            models,
            tools: self.tools,
            reactions: self.reactions,
            target_found: true,
            emissions: self.smoke.at(time_s),
            bleeding: Vec::new(),
            scope: None,
            picture: None,
        }
    }

    /// Digest of the contact state, the incision and the task's progress.
    pub fn state_hash(&self) -> u64 {
        let mut h = Fnv::default();
        self.palpation().contacts.digest(&mut h);
        for &d in &self.depth_bands {
            h.write(d.to_bits() as u32);
        }
        h.write(self.incision.vertices.len() as u32);
        h.write(self.incision.triangles.len() as u32);
        h.write(self.incision.cuts().len() as u32);
        h.write(self.metrics.steps_done.len() as u32);
        h.write(self.metrics.errors);
        h.0
    }
}

#[derive(Serialize)]
struct IncisionEvent {
    position: [f32; 3],
    depth_m: f64,
    length_m: f64,
    triangles: u32,
    stroke: u32,
}

#[derive(Serialize)]
struct Perforation {
    position: [f32; 3],
    depth_m: f64,
    pressure_pa: f64,
}

#[cfg(test)]
#[path = "procedure_tests.rs"]
mod tests;

impl Myotomy {
    /// The panel's live part: the paths, the muscle divided, the deepest cut, the polygons
    /// and each instrument's force. Nothing here is a vulnerable structure an instrument may
    /// not touch: the mucosa is guarded by the perforation's own alarm.
    pub(super) fn panel(&self, _near_m: f32) -> TaskStatus {
        let m = &self.metrics;
        TaskStatus {
            path_m: [m.path_length_left_m, m.path_length_right_m],
            figures: vec![
                (
                    "muscle divided".to_string(),
                    format!("{:.0} of {:.0} mm", 1e3 * m.divided_m, 1e3 * m.required_m),
                ),
                (
                    "deepest cut".to_string(),
                    format!(
                        "{:.1} mm (muscle {:.1}, wall {:.1})",
                        1e3 * m.deepest_cut_m,
                        1e3 * self.scenario.task.muscle_m,
                        1e3 * self.scenario.esophagus.wall_m
                    ),
                ),
                (
                    "polygons".to_string(),
                    format!("{} (from {})", m.triangles, m.original_triangles),
                ),
                (
                    "grasper force".to_string(),
                    format!("{:.3} N", self.reactions()[0].length()),
                ),
                (
                    "hook force".to_string(),
                    format!("{:.3} N", self.reactions()[1].length()),
                ),
            ],
            ..TaskStatus::default()
        }
    }
}
