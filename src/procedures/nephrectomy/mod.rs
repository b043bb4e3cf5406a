//! Laparoscopic partial nephrectomy (the HTC Vive paper): a left kidney with an exophytic
//! tumour tied to its bed, renal artery, renal vein and ureter. The right controller is a
//! laser pointer that identifies, marks and cuts; the left is a grasper that lifts the tumour.

use crate::models::{SimplexMesh, SoftBody, Tie};
use crate::sim::{
    Bleed, Contact, ContactKind, CutStroke, EmissionKind, EmissionLog, EventKind, Hand, InputFrame,
    InstrumentShape, ModelId, SimEvent, Snapshot, SurfaceRole, TissueModel, ToolSnapshot, World,
};
use glam::Vec3;
use serde::Serialize;

mod anatomy;
mod cases;
mod field;
mod plugin;
mod scenario;
mod score;

pub use anatomy::{anatomy, bean_anatomy};
pub use scenario::{Anatomy, Scenario, Task, Tools, Vulnerable, Weights};
pub use score::{ScoreParts, score};

/// The vessels the laser's cut opens (the ureter leaks no blood).
const BLEEDING_VESSELS: [&str; 2] = ["renal_artery", "renal_vein"];
/// A cut within this of an earlier injury widens it rather than opening another, m.
const INJURY_SPACING_M: f32 = 0.005;
/// How much of the grasper's shaft behind its tip tissue meets, m (a capsule of the tip's
/// radius: the shaft dents what it lies on, not only the tip).
const SHAFT_CONTACT_M: f32 = 0.06;
/// The laser probe's radius where tissue meets it: its 5 mm shaft, m.
const LASER_PROBE_RADIUS_M: f32 = 0.0025;
/// How long the laser's beam must rest on the tumour to identify it without a click, s.
const IDENTIFY_DWELL_S: f32 = 1.0;
/// How far the laser must have moved (origin, metres; or turned, radians) from its first pose
/// before a dwell counts.
const LASER_MOVED_M: f32 = 0.005;
const LASER_TURNED_RAD: f32 = 0.05;

/// The name scenarios and traces give this procedure.
pub const NAME: &str = "nephrectomy";

/// The task's steps, in order.
pub const STEPS: [super::TaskStep; 4] = [
    super::TaskStep {
        id: "identify",
        text: "Identify the tumour with the laser",
    },
    super::TaskStep {
        id: "mark",
        text: "Mark the resection margin",
    },
    super::TaskStep {
        id: "cut",
        text: "Cut around the tumour",
    },
    super::TaskStep {
        id: "remove",
        text: "Lift the tumour out",
    },
];

/// The registry's entry.
pub const INFO: super::ProcedureInfo = crate::procedure_info! {
    stem: "nephrectomy", paper: "partial-nephrectomy-vive.txt",
    title: "Laparoscopic partial nephrectomy",
    build: |_, s| Nephrectomy::new(s)?,
    // Left: the top of the 0.5-3.5 N range tissue takes (catheter paper, section 3.1).
    tools: [("grasper", Grasper, 3.5), ("laser", Laser, 1.0)],
    // Above and in front of the kidney's lateral face, where a surgeon's head would be over
    // the port site.
    view: (0.0, 0.07, 0.16) -> (0.005, 0.01, 0.0),
    // Where the demo trace starts the instruments, on the default camera's view.
    desk_park: [
        (-0.03135, 0.04888, 0.14317),
        (0.09865, 0.04888, 0.14317),
    ],
    // Tables 2 and 3 of the paper.
    profile_reference: Some(|| [crate::profiler::paper_cpu(), crate::profiler::paper_gpu()]),
    legacy_tuned_model: Some(TUNED_MODEL),
    cases: cases::cases,
};

/// The model whose parameters the supervisor tunes live.
pub const TUNED_MODEL: &str = "kidney";
pub const REGION_PARENCHYMA: u8 = 0;
pub const REGION_TUMOUR: u8 = 1;
const KIDNEY: ModelId = ModelId(0);
/// Cut samples along the laser's sweep between steps, metres apart.
const SWEEP_SPACING_M: f32 = 5e-4;
/// A laser hit this much deeper than the surface it was on went through a gap (a groove it
/// cut itself): it does not cut there.
const CUT_CONTINUITY_M: f32 = 3e-3;

/// The nephrectomy's own events: `tumour_identified` (the laser found it), `margin_marked`
/// (a mark placed, with its distance from the intended margin), `tumour_freed` (no tie or
/// tissue joins it to the kidney), `tumour_removed` (lifted out of its bed).
fn event(name: &'static str, fields: impl Serialize) -> EventKind {
    EventKind::Procedure(crate::sim::ProcedureEvent::new(name, fields))
}

/// A margin mark: where, and how far from the intended margin surface, metres.
#[derive(Serialize)]
struct Marked {
    point: [f32; 3],
    margin_error_m: f32,
}

/// A renal vessel opened by the laser: which, and where, metres.
#[derive(Serialize)]
struct Injury {
    vessel: String,
    point: [f32; 3],
}

/// Running metrics of one session.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Metrics {
    pub completion_time_s: Option<f64>,
    pub path_length_left_m: f32,
    pub path_length_right_m: f32,
    pub cut_length_m: f32,
    pub cut_faces: u32,
    /// Mean distance of cut faces (at rest) from the intended margin surface, metres.
    pub cut_deviation_mean_m: f32,
    pub cut_into_tumour_faces: u32,
    /// Healthy parenchyma removed with the specimen or by the cut, m^2 (at rest).
    pub healthy_removed_m2: f32,
    /// Healthy area the intended margin removes, m^2.
    pub healthy_planned_m2: f32,
    pub vessel_contacts: u32,
    /// Renal vessels opened by the laser's cut (each injury bleeds).
    pub vessel_injuries: u32,
    pub ties_torn: u32,
    pub marks: u32,
    pub marks_on_margin: u32,
    /// Actions taken before the step they follow was done (a mark before the tumour was
    /// identified, a cut before the margin was marked).
    pub out_of_order: u32,
    pub steps_done: Vec<String>,
}

pub struct Nephrectomy {
    pub scenario: Scenario,
    /// The kidney (with its tumour) first, then the vessels.
    world: World<SoftBody>,
    vulnerable: Vec<bool>,
    tumour_center: Vec3,
    tumour_rest_centroid: Vec3,
    tumour_radius: f32,
    pub metrics: Metrics,
    cut_deviation_sum: f64,
    identified: bool,
    /// The laser's first pose (origin, direction), whether it has moved from it since, and
    /// how long its beam has now rested on the tumour: identification is deliberate.
    laser_start: Option<(Vec3, Vec3)>,
    laser_moved: bool,
    dwell_s: f32,
    freed: bool,
    removed: bool,
    last_cut_point: Option<Vec3>,
    /// The plume where the laser vaporises tissue.
    smoke: EmissionLog,
    /// Where the laser opened a renal vessel: each bleeds from then on (no instrument of
    /// this procedure can stop it).
    bleeds: Vec<Bleed>,
    /// Depth along the beam of the surface the laser was last on, metres.
    surface_depth_m: Option<f32>,
    prev_input: Option<InputFrame>,
    vessel_touch: [bool; 2],
    grasp_model: Option<ModelId>,
    tools: [ToolSnapshot; 2],
}

impl Nephrectomy {
    pub fn new(scenario: Scenario) -> Result<Self, crate::mesh::MeshError> {
        let (organ, regions, vessels, tumour_center) = anatomy(&scenario);
        let r_t = scenario.anatomy.tumour_radius_m;
        let a = &scenario.anatomy;
        let mesh = SimplexMesh::dual(&organ)?;
        let rest = mesh.rest.clone();
        let mut body = SoftBody::new("kidney", mesh, regions.clone(), scenario.kidney);
        // The laser cuts: its cuts are seared.
        body.sear_cuts(true);
        // Ties: every tumour point buried in the kidney to its nearest bed point, and every
        // bed point under the tumour to its nearest tumour point.
        let inside_kidney = |p: Vec3| {
            (p.x / a.kidney_half_width_m).powi(2)
                + (p.y / a.kidney_half_length_m).powi(2)
                + (p.z / a.kidney_half_thickness_m).powi(2)
                < 1.0
        };
        let tumour_pts: Vec<usize> = (0..rest.len())
            .filter(|&i| regions[i] == REGION_TUMOUR)
            .collect();
        let bed: Vec<usize> = (0..rest.len())
            .filter(|&i| {
                regions[i] == REGION_PARENCHYMA && (rest[i] - tumour_center).length() < r_t
            })
            .collect();
        let nearest = |p: Vec3, among: &[usize]| {
            among
                .iter()
                .map(|&j| ((rest[j] - p).length(), j))
                .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
        };
        let mut ties: Vec<Tie> = Vec::new();
        for &i in tumour_pts.iter().filter(|&&i| inside_kidney(rest[i])) {
            if let Some((d, j)) = nearest(rest[i], &bed) {
                ties.push(Tie {
                    a: i as u32,
                    b: j as u32,
                    rest_m: d,
                    alive: true,
                });
            }
        }
        for &j in &bed {
            if let Some((d, i)) = nearest(rest[j], &tumour_pts) {
                ties.push(Tie {
                    a: i as u32,
                    b: j as u32,
                    rest_m: d,
                    alive: true,
                });
            }
        }
        ties.sort_by_key(|t| (t.a, t.b));
        ties.dedup_by_key(|t| (t.a, t.b));
        body.set_ties(ties);
        let tumour_rest_centroid =
            tumour_pts.iter().map(|&i| rest[i]).sum::<Vec3>() / tumour_pts.len().max(1) as f32;
        let mut world = World::new();
        world.add(body);
        for (name, m) in vessels {
            let s = SimplexMesh::dual(&m)?;
            let n = s.len();
            world.add(SoftBody::new(&name, s, vec![0; n], scenario.vessels));
        }
        let vulnerable = world
            .models()
            .map(|(_, m)| scenario.vulnerable.iter().any(|v| v.model == m.name()))
            .collect();
        // Healthy area inside the intended margin (what a perfect excision takes).
        let reach = r_t + scenario.task.margin_m;
        let k = world.model(KIDNEY);
        let planned: f32 = (0..k.mesh().len())
            .filter(|&f| {
                k.regions()[f] == REGION_PARENCHYMA
                    && (k.mesh().rest[f] - tumour_center).length() < reach
            })
            .map(|f| k.rest_face_area(f))
            .sum();
        Ok(Self {
            metrics: Metrics {
                healthy_planned_m2: planned,
                ..Default::default()
            },
            scenario,
            world,
            vulnerable,
            tumour_center,
            tumour_rest_centroid,
            tumour_radius: r_t,
            cut_deviation_sum: 0.0,
            identified: false,
            laser_start: None,
            laser_moved: false,
            dwell_s: 0.0,
            freed: false,
            removed: false,
            last_cut_point: None,
            smoke: EmissionLog::smoke(),
            bleeds: Vec::new(),
            surface_depth_m: None,
            prev_input: None,
            vessel_touch: [false; 2],
            grasp_model: None,
            tools: [ToolSnapshot::default(); 2],
        })
    }

    /// The kidney (with its tumour) and the vessels.
    pub fn world(&self) -> &World<SoftBody> {
        &self.world
    }

    /// The kidney with its tumour.
    pub fn kidney(&self) -> &SoftBody {
        self.world.model(KIDNEY)
    }

    /// Whether each tool (left, right) touches a vulnerable structure now.
    pub fn touching_vulnerable(&self) -> [bool; 2] {
        self.vessel_touch
    }

    /// The nearest vulnerable structure within `within_m` of each tool's working point (the
    /// grasper's tip; where the laser's beam lands), and how far it is, metres.
    pub fn vulnerable_near(&self, within_m: f32) -> [Option<(String, f32)>; 2] {
        let points = [Some(self.tools[0].tip), self.tools[1].beam_end];
        points.map(|point| {
            let point = point?;
            self.world
                .models()
                .zip(&self.vulnerable)
                .filter(|(_, v)| **v)
                .filter_map(|((_, m), _)| {
                    m.collider()
                        .nearest_within(point, within_m)
                        .first()
                        .map(|&(d, _)| (m.name().to_string(), d))
                })
                .min_by(|a, b| a.1.total_cmp(&b.1))
        })
    }

    pub fn is_completed(&self) -> bool {
        self.removed
    }

    pub fn tumour_center(&self) -> Vec3 {
        self.tumour_center
    }

    /// Distance of a rest point from the intended margin surface (sphere of radius r + margin).
    pub fn margin_error(&self, p: Vec3) -> f32 {
        ((p - self.tumour_center).length() - (self.tumour_radius + self.scenario.task.margin_m))
            .abs()
    }

    fn task_step(&mut self, name: &str, events: &mut Vec<EventKind>) {
        self.metrics.steps_done.push(name.to_string());
        events.push(EventKind::TaskStep {
            name: name.to_string(),
        });
    }

    /// Counts and raises an action of `step` taken before the steps it follows were done.
    fn out_of_order(&mut self, step: &str, events: &mut Vec<EventKind>) {
        if let Some(e) = super::out_of_order(INFO.steps, &self.metrics.steps_done, step) {
            self.metrics.out_of_order += 1;
            events.push(e);
        }
    }

    /// An instrument's end at `tip`, of radius `r`, and [`SHAFT_CONTACT_M`] of its shaft behind
    /// it (along `-forward`): every model it comes within reach of is pressed as a capsule.
    /// Whether one of them is a vulnerable structure.
    fn press_shaft(&mut self, hand: Hand, tip: Vec3, forward: Vec3, r: f32) -> bool {
        let back = tip - forward * SHAFT_CONTACT_M;
        // Balls of 1.5 r every 2 r along the axis cover everything within r of it.
        let samples = (SHAFT_CONTACT_M / (2.0 * r)).ceil() as usize;
        let near: Vec<ModelId> = self
            .world
            .models()
            .filter(|(_, b)| {
                (0..=samples).any(|k| {
                    let at = tip.lerp(back, k as f32 / samples as f32);
                    !b.collider().nearest_within(at, r * 1.5).is_empty()
                })
            })
            .map(|(m, _)| m)
            .collect();
        let mut vulnerable = false;
        for m in near {
            vulnerable |= self.vulnerable[m.index()];
            self.world.contact(
                m,
                Contact {
                    tool: hand,
                    point: tip,
                    normal: -forward,
                    kind: ContactKind::Capsule { back, radius_m: r },
                },
            );
        }
        vulnerable
    }

    /// Advances the procedure one step.
    pub fn step(&mut self, input: &InputFrame, step: u64, events: &mut Vec<SimEvent>) {
        let dt = self.scenario.dt_s;
        let tools = self.scenario.tools.clone();
        let jaws = self.scenario.grasper;
        let mut ev: Vec<EventKind> = Vec::new();
        if let Some(prev) = &self.prev_input {
            self.metrics.path_length_left_m += prev.hands[0]
                .pose
                .position
                .distance(input.hands[0].pose.position);
            self.metrics.path_length_right_m += prev.hands[1]
                .pose
                .position
                .distance(input.hands[1].pose.position);
        }
        let mark_pressed = input.hand(Hand::Right).buttons.mark
            && !self
                .prev_input
                .is_some_and(|p| p.hand(Hand::Right).buttons.mark);

        // Laser pointer (right hand).
        let laser = input.hand(Hand::Right);
        let origin = laser.pose.position;
        let dir = laser.pose.forward();
        let hit = self.world.cast_ray(origin, dir, tools.laser_range_m);
        let cutting = laser.buttons.trigger >= tools.cut_threshold;
        self.tools[1] = ToolSnapshot {
            tip: origin,
            direction: dir,
            beam_end: hit.map(|(_, h)| h.point),
            // Missing, the beam still shows, to its range.
            beam_reach: hit.is_none().then(|| origin + dir * tools.laser_range_m),
            active: cutting,
            instrument: 0,
            shape: InstrumentShape::Laser,
            jaw: 0.0,
            up: laser.pose.orientation * Vec3::Y,
        };
        let mut strokes: Vec<(ModelId, CutStroke, f32)> = Vec::new();
        let mut touching_vessel = [false; 2];
        let on_tumour = hit.is_some_and(|(m, h)| {
            m == KIDNEY && self.world.model(m).regions()[h.feature as usize] == REGION_TUMOUR
        });
        if !self.identified {
            // Identified by a deliberate act: a click (the mark button) with the beam on the
            // tumour, or the beam held on it for IDENTIFY_DWELL_S once the laser has left
            // its first pose (so the start pose never identifies it by accident).
            let (o, d) = *self.laser_start.get_or_insert((origin, dir));
            self.laser_moved |=
                origin.distance(o) > LASER_MOVED_M || dir.angle_between(d) > LASER_TURNED_RAD;
            self.dwell_s = if on_tumour && self.laser_moved {
                self.dwell_s + dt
            } else {
                0.0
            };
            if on_tumour && (mark_pressed || self.dwell_s >= IDENTIFY_DWELL_S) {
                self.identified = true;
                ev.push(event("tumour_identified", ()));
                self.task_step("identify", &mut ev);
            }
        }
        if let Some((m, h)) = hit {
            let region = self.world.model(m).regions()[h.feature as usize];
            if mark_pressed && m == KIDNEY && region == REGION_PARENCHYMA {
                self.out_of_order("mark", &mut ev);
                let rest = self.kidney().mesh().rest[h.feature as usize];
                let err = self.margin_error(rest);
                self.metrics.marks += 1;
                if err <= self.scenario.task.mark_tolerance_m {
                    self.metrics.marks_on_margin += 1;
                    if self.metrics.marks_on_margin == self.scenario.task.marks_required {
                        self.task_step("mark", &mut ev);
                    }
                }
                ev.push(event(
                    "margin_marked",
                    Marked {
                        point: h.point.to_array(),
                        margin_error_m: err,
                    },
                ));
            }
            if cutting {
                if self.vulnerable[m.index()] {
                    touching_vessel[1] = true;
                    let vessel = self.world.model(m).name();
                    let opened = self
                        .bleeds
                        .iter()
                        .any(|b| b.position.distance(h.point) < INJURY_SPACING_M);
                    if BLEEDING_VESSELS.contains(&vessel) && !opened {
                        self.metrics.vessel_injuries += 1;
                        ev.push(event(
                            "vessel_injured",
                            Injury {
                                vessel: vessel.to_string(),
                                point: h.point.to_array(),
                            },
                        ));
                        self.bleeds.push(Bleed {
                            position: h.point,
                            start_s: (step + 1) as f64 * f64::from(dt),
                            stop_s: None,
                        });
                    }
                } else if m == KIDNEY {
                    if self.last_cut_point.is_none() {
                        // A stroke begins: before the margin is marked, out of order.
                        self.out_of_order("cut", &mut ev);
                    }
                    self.world.contact(
                        m,
                        Contact {
                            tool: Hand::Right,
                            point: h.point,
                            normal: h.normal,
                            kind: ContactKind::Press {
                                pressure_pa: tools.laser_pressure_pa,
                                area_m2: self.scenario.kidney.contact_area_m2,
                            },
                        },
                    );
                    let on_surface = self
                        .surface_depth_m
                        .is_none_or(|d| h.distance_m < d + CUT_CONTINUITY_M);
                    if on_surface {
                        self.surface_depth_m = Some(h.distance_m);
                    }
                    let continuous = on_surface
                        && self
                            .last_cut_point
                            .is_none_or(|p| p.distance(h.point) < 4.0 * CUT_CONTINUITY_M);
                    if continuous {
                        let from = self.last_cut_point.unwrap_or(h.point);
                        let faces = self.sweep(origin, from, h.point, h.feature);
                        let length = from.distance(h.point);
                        self.metrics.cut_length_m += length;
                        self.last_cut_point = Some(h.point);
                        strokes.push((m, CutStroke { faces }, length));
                        // The beam vaporises tissue where it cuts: a plume rises from there.
                        let now_s = (step + 1) as f64 * f64::from(dt);
                        self.smoke.record(now_s, h.point, EmissionKind::Smoke);
                    }
                }
            } else {
                self.last_cut_point = None;
                self.surface_depth_m = None;
            }
        } else if !cutting {
            self.last_cut_point = None;
            self.surface_depth_m = None;
        }

        // Grasper (left hand).
        let grasper = input.hand(Hand::Left);
        let tip = grasper.pose.position;
        self.tools[0] = ToolSnapshot {
            tip,
            direction: grasper.pose.forward(),
            beam_end: None,
            beam_reach: None,
            active: grasper.buttons.grip >= jaws.grip_threshold,
            instrument: 0,
            shape: InstrumentShape::Grasper,
            jaw: 1.0 - grasper.buttons.grip,
            up: grasper.pose.orientation * Vec3::Y,
        };
        if grasper.buttons.grip >= jaws.grip_threshold {
            if self.grasp_model.is_none() {
                self.grasp_model = self
                    .world
                    .nearest(tip, jaws.grasp_radius_m)
                    .map(|(m, _, _)| m);
            }
            if let Some(m) = self.grasp_model {
                if self.vulnerable[m.index()] {
                    touching_vessel[0] = true;
                }
                self.world.contact(
                    m,
                    Contact::grasp(Hand::Left, &grasper.pose, jaws.grasp_radius_m),
                );
            }
        } else {
            self.grasp_model = None;
            // The tip and the shaft behind it: the whole instrument dents what it presses.
            let forward = grasper.pose.forward();
            touching_vessel[0] |= self.press_shaft(Hand::Left, tip, forward, jaws.tip_radius_m);
        }
        // The laser probe's body (its 5 mm shaft) dents what it is pushed into, as the
        // grasper's does; its beam cuts as above.
        touching_vessel[1] |= self.press_shaft(Hand::Right, origin, dir, LASER_PROBE_RADIUS_M);
        for h in 0..2 {
            if touching_vessel[h] && !self.vessel_touch[h] {
                self.metrics.vessel_contacts += 1;
                ev.push(EventKind::VulnerableContact {
                    tool: Hand::BOTH[h].name().to_string(),
                    model: "vessel".to_string(),
                });
            }
            self.vessel_touch[h] = touching_vessel[h];
        }

        // Cuts, then every model steps (the world steps them in parallel).
        let mut topology_changed = false;
        for (m, stroke, length) in strokes {
            let mut cut_events = Vec::new();
            let before = self.world.model(m).alive().iter().filter(|a| !**a).count();
            self.world.cut(m, &stroke, &mut cut_events);
            let k = self.world.model(m);
            let removed = k.alive().iter().filter(|a| !**a).count() - before;
            if removed > 0 {
                topology_changed = true;
                let mut into_tumour = 0;
                for &f in &stroke.faces {
                    if k.regions()[f as usize] == REGION_TUMOUR {
                        into_tumour += 1;
                    } else {
                        self.cut_deviation_sum +=
                            self.margin_error(k.mesh().rest[f as usize]) as f64;
                    }
                }
                self.metrics.cut_faces += removed as u32;
                self.metrics.cut_into_tumour_faces += into_tumour;
                ev.push(EventKind::Cut {
                    model: k.name().to_string(),
                    faces: removed as u32,
                    length_m: length,
                });
            }
            ev.append(&mut cut_events);
        }
        let mut stepped = Vec::new();
        self.world.step(dt, step, &mut stepped);
        for e in &stepped {
            if matches!(e, EventKind::TieBroken { .. }) {
                self.metrics.ties_torn += 1;
                topology_changed = true;
            }
        }
        ev.append(&mut stepped);

        // Is the tumour free, and has it been lifted out?
        if topology_changed && !self.freed {
            let k = self.world.model_mut(KIDNEY);
            k.refresh_topology();
            let still_held =
                (0..k.mesh().len()).any(|i| k.regions()[i] == REGION_TUMOUR && k.is_anchored(i));
            if !still_held {
                self.freed = true;
                ev.push(event("tumour_freed", ()));
                self.task_step("cut", &mut ev);
            }
        }
        if self.freed && !self.removed {
            let k = self.kidney();
            let (mut sum, mut n) = (Vec3::ZERO, 0);
            for i in 0..k.mesh().len() {
                if k.regions()[i] == REGION_TUMOUR && k.alive()[i] {
                    sum += k.positions()[i];
                    n += 1;
                }
            }
            if n > 0
                && (sum / n as f32).distance(self.tumour_rest_centroid)
                    > self.scenario.task.removal_distance_m
            {
                self.removed = true;
                self.metrics.completion_time_s = Some((step + 1) as f64 * dt as f64);
                self.metrics.healthy_removed_m2 = self.healthy_removed();
                ev.push(event("tumour_removed", ()));
                self.task_step("remove", &mut ev);
            }
        }
        self.metrics.cut_deviation_mean_m =
            if self.metrics.cut_faces > self.metrics.cut_into_tumour_faces {
                (self.cut_deviation_sum
                    / (self.metrics.cut_faces - self.metrics.cut_into_tumour_faces) as f64)
                    as f32
            } else {
                0.0
            };
        self.prev_input = Some(*input);
        events.extend(ev.into_iter().map(|kind| SimEvent { step, kind }));
    }

    /// Faces along the laser's sweep from `from` to `to` (both surface points).
    fn sweep(&self, origin: Vec3, from: Vec3, to: Vec3, face: u32) -> Vec<u32> {
        let mut faces = vec![face];
        let n = (from.distance(to) / SWEEP_SPACING_M).ceil() as usize;
        let k = self.kidney();
        for s in 1..n {
            let p = from.lerp(to, s as f32 / n as f32);
            let d = (p - origin).normalize_or_zero();
            if let Some(h) = k
                .collider()
                .cast_ray(origin, d, self.scenario.tools.laser_range_m)
                && h.point.distance(p) < CUT_CONTINUITY_M
            {
                faces.push(h.feature);
            }
        }
        faces.sort_unstable();
        faces.dedup();
        faces
    }

    /// Reaction force on each tool after the last step, newtons.
    pub fn reactions(&self) -> [Vec3; 2] {
        self.world.reactions()
    }

    /// Healthy parenchyma area (at rest) cut away or carried off with the specimen, m^2.
    pub fn healthy_removed(&self) -> f32 {
        let k = self.kidney();
        (0..k.mesh().len())
            .filter(|&f| {
                k.regions()[f] == REGION_PARENCHYMA && (!k.alive()[f] || !k.is_anchored(f))
            })
            .map(|f| k.rest_face_area(f))
            .sum()
    }

    pub fn snapshot(&mut self, step: u64) -> Snapshot {
        self.snapshot_job(step).build()
    }

    /// The snapshot as a job: the models' state and the scene are read now, the meshes
    /// built by the job (on the snapshot bus's builder, beside the simulation).
    pub fn snapshot_job(&mut self, step: u64) -> crate::sim::SnapshotJob {
        let meshes = self.world.render_job(|_, m| match m.name() {
            "kidney" => vec![SurfaceRole::Tissue, SurfaceRole::Target],
            "renal_artery" => vec![SurfaceRole::Artery],
            "renal_vein" => vec![SurfaceRole::Vein],
            _ => vec![SurfaceRole::Duct],
        });
        let rest = Snapshot {
            step,
            time_s: step as f64 * self.scenario.dt_s as f64,
            models: Vec::new(),
            tools: self.tools,
            reactions: self.world.reactions(),
            target_found: self.identified,
            emissions: self.smoke.at(step as f64 * self.scenario.dt_s as f64),
            bleeding: self.bleeds.clone(),
            scope: None,
            picture: None,
        };
        crate::sim::SnapshotJob::later(move || Snapshot {
            models: meshes.build(),
            ..rest
        })
    }
}
