//! The `catheter` procedure: the skeleton-spring catheter of [`crate::models::skeleton`] in
//! its bifurcating vessel, driven from its handle. The right hand holds the handle: where it
//! is along the vessel's entry axis is how far the catheter is in, its trigger bends the tip
//! (0 to the largest bend), its grip twists the catheter (to `device.twist_deg` at full
//! grip), which turns the direction the tip bends to; between them they choose the branch. The
//! force on the catheter (the sum of the wall's contact forces on its balls) is its reaction
//! for the haptic device. The task's checklist, the metrics (time, path, wall contacts, peak
//! force, force-time integral, the force over time as the paper's Fig. 15), the events and
//! what the renderer draws.

use super::fluoroscopy::{Console, Imaging};
use super::scenario::Scenario;
use crate::models::skeleton::catheter::{Drive, any_across};
use crate::models::skeleton::guidewire::WireDrive;
use crate::models::skeleton::in_vessel::CatheterInVessel;
use crate::models::skeleton::vessel::Vessel;
use crate::procedures::TaskStep;
use crate::sim::Fnv;
use crate::sim::TaskStatus;
use crate::sim::{
    EventKind, Hand, InputFrame, ModelSnapshot, ProcedureEvent, SimEvent, Snapshot, SurfaceRole,
    ToolSnapshot,
};
use glam::{DVec3, Vec3};
use serde::Serialize;

/// The task, in order.
pub const STEPS: [TaskStep; 3] = [
    TaskStep {
        id: "advance",
        text: "Advance the catheter 20 mm into the vessel",
    },
    TaskStep {
        id: "bifurcation",
        text: "Bring the tip to the target branch's ostium",
    },
    TaskStep {
        id: "branch",
        text: "Enter the target branch (the catheter's tip bent and twisted into it, or over \
               the guidewire led in first) and advance along it without puncturing the wall",
    },
];

/// The first step's depth into the trunk, m.
const ADVANCE_M: f64 = 0.020;
/// The tip is at the target's ostium within this of it along the tree, m.
const AT_BIFURCATION_M: f64 = 0.005;
/// The tip is in a branch once this far along it, m.
const IN_BRANCH_M: f64 = 0.010;
/// The head is off the wall this long before its next touch counts as a new contact, s.
const CONTACT_GAP_S: f64 = 0.05;
/// The force trace's sample period, s.
const TRACE_EVERY_S: f64 = 0.02;

/// Running metrics of one session.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Metrics {
    pub completion_time_s: Option<f64>,
    /// The handle's and the tip's paths, m.
    pub handle_path_m: f64,
    pub tip_path_m: f64,
    /// Times the head came onto the wall, and the steps it was on it.
    pub wall_contacts: u32,
    pub contact_steps: u32,
    /// The largest force on the catheter, N, and its integral over time, N s.
    pub peak_force_n: f64,
    pub force_time_n_s: f64,
    /// The head's largest normal force, N.
    pub peak_head_normal_n: f64,
    pub punctures: u32,
    /// Times the tip went into the other branch.
    pub wrong_branch: u32,
    /// How far the tip has gone into the target branch at most, m.
    pub reach_m: f64,
    pub errors: u32,
    pub steps_done: Vec<String>,
    /// The force on the catheter over the session (the paper's Fig. 15): `[t s, |F|, Fx, Fy,
    /// Fz]` every 20 ms, N.
    pub force_trace: Vec<[f64; 5]>,
    /// What the interventional console counted: fluoroscopy time, runs, pulses, the dose,
    /// the contrast.
    pub fluoroscopy: Console,
    /// The guidewire's own figures, when the scenario has one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub guidewire: Option<WireMetrics>,
}

/// What the guidewire did over a session.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct WireMetrics {
    /// The wire tip's path, m, from its places every 20 ms.
    pub tip_path_m: f64,
    /// Times its tip came onto the wall, and the steps it was on it.
    pub wall_contacts: u32,
    pub contact_steps: u32,
    /// The largest force the wall put on the wire, N, and on its tip alone (normal).
    pub peak_force_n: f64,
    pub peak_tip_normal_n: f64,
    /// Punctures by the wire (counted in the session's punctures too).
    pub punctures: u32,
    /// Times the wire's tip went into the other branch.
    pub wrong_branch: u32,
    /// How far the wire's tip has gone into the target branch at most, m.
    pub reach_m: f64,
    /// How far the wire's tip led the catheter's at most, m (along the path both follow).
    pub lead_m: f64,
}

pub struct Catheterisation {
    pub scenario: Scenario,
    pub scene: CatheterInVessel,
    pub metrics: Metrics,
    reaction: DVec3,
    tool: ToolSnapshot,
    prev: Option<(Vec3, DVec3)>,
    touching: bool,
    /// Steps since the head last touched the wall.
    off_steps: u32,
    /// The tip is in a wrong branch now.
    astray: bool,
    /// The vessel the task asks for, and how far from the inlet its ostium is, m.
    target: usize,
    ostium_m: f64,
    triangles: Vec<[u32; 3]>,
    /// The fluoroscope and the contrast, under the left hand.
    pub imaging: Imaging,
    /// The left hand's place along the entry when it was first seen: its travel from there
    /// feeds the wire.
    wire_origin: Option<f64>,
    wire_reaction: DVec3,
    wire_prev: Option<DVec3>,
    wire_touching_off: u32,
    wire_astray: bool,
}

impl Catheterisation {
    pub fn new(scenario: Scenario, scene: CatheterInVessel) -> Catheterisation {
        let triangles = scene.vessel().triangles();
        let dt = f64::from(scenario.dt_s);
        let mut imaging = Imaging::new(scenario.fluoroscopy, &scene, dt, scenario.head());
        let target = scenario.target_branch();
        let v = scene.vessel();
        let ostium_m = v
            .tubes
            .iter()
            .find(|t| t.vessel == target)
            .map_or(0.0, |t| t.from_inlet_m);
        imaging.wire_mu_per_m = scenario.guidewire.map_or(0.0, |w| w.mu_per_m);
        Catheterisation {
            imaging,
            scenario,
            scene,
            metrics: Metrics::default(),
            reaction: DVec3::ZERO,
            tool: ToolSnapshot::default(),
            prev: None,
            touching: false,
            off_steps: u32::MAX,
            astray: false,
            target,
            ostium_m,
            triangles,
            wire_origin: None,
            wire_reaction: DVec3::ZERO,
            wire_prev: None,
            wire_touching_off: u32::MAX,
            wire_astray: false,
        }
    }

    pub fn is_completed(&self) -> bool {
        self.metrics.steps_done.len() == STEPS.len()
    }

    /// The force on the catheter after the last step, N (the device feels it).
    pub fn reaction(&self) -> DVec3 {
        self.reaction
    }

    pub fn tool(&self) -> &ToolSnapshot {
        &self.tool
    }

    fn time_s(&self, steps: u64) -> f64 {
        steps as f64 * f64::from(self.scenario.dt_s)
    }

    /// The device's drive from the right hand: its handle's travel along the entry axis, its
    /// trigger and grip.
    pub fn drive(&self, input: &InputFrame) -> Drive {
        let h = input.hand(Hand::Right);
        let c = &self.scene.catheter();
        let length = c.params.length_m;
        let p = h.pose.position.as_dvec3();
        let insertion = if p.is_finite() {
            ((p - c.entry).dot(c.axis) + length).clamp(0.0, length)
        } else {
            0.0
        };
        Drive {
            insertion_m: insertion,
            twist_rad: f64::from(h.buttons.grip.clamp(0.0, 1.0))
                * self.scenario.device.twist_deg.to_radians(),
            bend: f64::from(h.buttons.trigger.clamp(0.0, 1.0)),
        }
    }

    /// The wire's drive from the left hand: its travel along the entry axis since it was
    /// first seen feeds the wire from `guidewire.start_m` (clamped between there, or the
    /// entry if that is further in, and the wire's length), its wrist's roll turns it (one
    /// to one: a wire carries torque to its tip). Zero without a wire.
    pub fn wire_drive(&mut self, input: &InputFrame) -> WireDrive {
        let (Some(w), Some(wire)) = (self.scenario.guidewire, self.scene.guidewire()) else {
            return WireDrive::default();
        };
        let h = input.hand(Hand::Left);
        let p = h.pose.position.as_dvec3();
        let along = (p - wire.entry).dot(wire.axis);
        if !h.pose.is_finite() || !along.is_finite() {
            // An untracked hand leaves the wire where it is.
            return WireDrive {
                insertion_m: (wire.tip() - wire.entry).dot(wire.axis),
                twist_rad: 0.0,
            };
        }
        let origin = *self.wire_origin.get_or_insert(along);
        let least = w.start_m.min(0.0);
        WireDrive {
            insertion_m: (w.start_m + along - origin).clamp(least, w.length_m),
            twist_rad: f64::from(xr_bindings::keyframes::roll_of(h.pose.orientation)),
        }
    }

    /// Both drives for this step's input: the catheter's and the wire's.
    pub fn drives(&mut self, input: &InputFrame) -> (Drive, WireDrive) {
        (self.drive(input), self.wire_drive(input))
    }

    /// Advances one step.
    pub fn step(&mut self, input: &InputFrame, step: u64, events: &mut Vec<SimEvent>) {
        let dt = f64::from(self.scenario.dt_s);
        let (drive, wire_drive) = self.drives(input);
        let mut ev: Vec<EventKind> = Vec::new();
        let out = self
            .scene
            .step((&drive, &wire_drive), self.scenario.dt_s, step, &mut ev);
        self.reaction = out.reaction;
        let now_s = self.time_s(step + 1);
        let hand = input.hand(Hand::Right).pose.position;
        let tip = self.scene.catheter().tip();
        let m = &mut self.metrics;
        if let Some((h0, t0)) = self.prev
            && hand.is_finite()
            && h0.is_finite()
        {
            m.handle_path_m += f64::from(hand.distance(h0));
            m.tip_path_m += tip.distance(t0);
        }
        self.prev = Some((hand, tip));
        let force = out.reaction.length();
        m.peak_force_n = m.peak_force_n.max(force);
        m.force_time_n_s += force * dt;
        m.peak_head_normal_n = m.peak_head_normal_n.max(out.head_normal_n);
        // A contact counts once however the head chatters on the wall: a new one only after
        // `CONTACT_GAP_S` off it.
        self.imaging.step(input, &self.scene, dt, step);
        m.fluoroscopy = self.imaging.console;
        let touching = out.head_normal_n > 0.0;
        if touching {
            m.contact_steps += 1;
            if self.off_steps as f64 * dt >= CONTACT_GAP_S {
                m.wall_contacts += 1;
            }
            self.off_steps = 0;
        } else {
            self.off_steps = self.off_steps.saturating_add(1);
        }
        self.touching = touching;
        let every = (TRACE_EVERY_S / dt).round().max(1.0) as u64;
        if (step + 1).is_multiple_of(every) {
            let f = out.reaction;
            m.force_trace.push([now_s, force, f.x, f.y, f.z]);
        }
        for p in &out.punctures {
            m.punctures += 1;
            m.errors += 1;
            let tool = if p.by_wire { "guidewire" } else { "catheter" };
            if p.by_wire
                && let Some(w) = &mut m.guidewire
            {
                w.punctures += 1;
            }
            ev.push(EventKind::Procedure(ProcedureEvent::new(
                "puncture",
                PunctureEvent {
                    position: p.position.as_vec3().to_array(),
                    force_n: p.force_n,
                    wall_ball: p.wall,
                    tool,
                },
            )));
            ev.push(EventKind::Alarm {
                tool: tool.to_string(),
                message: format!("the {tool} has punctured the vessel wall"),
            });
        }
        // Where the tip is: which branch, how far along.
        let target = self.target;
        let v = &self.scene.vessel();
        let astray = (v.astray(target, tip, IN_BRANCH_M), *v);
        m.wrong_branch += entered(&mut self.astray, astray, "catheter", &mut ev);
        if let Some(along) = in_branch_at(v, target, tip) {
            m.reach_m = m.reach_m.max(along);
        }
        if let Some(wire) = self.scene.guidewire() {
            let w = m.guidewire.get_or_insert_with(WireMetrics::default);
            let wo = self.scene.wire_outcome();
            self.wire_reaction = wo.reaction;
            let wtip = wire.tip();
            // The path from the tip's places every `TRACE_EVERY_S`: the light tip's
            // tremble at the substeps' rate is not travel.
            if (step + 1).is_multiple_of(every) {
                if let Some(t0) = self.wire_prev {
                    w.tip_path_m += wtip.distance(t0);
                }
                self.wire_prev = Some(wtip);
            }
            w.peak_force_n = w.peak_force_n.max(wo.reaction.length());
            w.peak_tip_normal_n = w.peak_tip_normal_n.max(wo.tip_normal_n);
            if wo.tip_normal_n > 0.0 {
                w.contact_steps += 1;
                if self.wire_touching_off as f64 * dt >= CONTACT_GAP_S {
                    w.wall_contacts += 1;
                }
                self.wire_touching_off = 0;
            } else {
                self.wire_touching_off = self.wire_touching_off.saturating_add(1);
            }
            let astray = (v.astray(target, wtip, IN_BRANCH_M), *v);
            w.wrong_branch += entered(&mut self.wire_astray, astray, "guidewire", &mut ev);
            if let Some(along) = in_branch_at(v, target, wtip) {
                w.reach_m = w.reach_m.max(along);
            }
            w.lead_m = w.lead_m.max(v.path_m(wtip) - v.path_m(tip));
        }
        let (path, ostium) = (v.path_m(tip), self.ostium_m);
        let done = [
            path >= ADVANCE_M || m.reach_m > 0.0,
            path >= ostium - AT_BIFURCATION_M || m.reach_m > 0.0,
            m.reach_m >= self.scenario.task.reach_m,
        ];
        crate::procedures::tick_off(&STEPS, &done, &mut m.steps_done, &mut ev);
        if m.steps_done.len() == STEPS.len() && m.completion_time_s.is_none() {
            m.completion_time_s = Some(now_s);
        }
        let c = &self.scene.catheter();
        self.tool = ToolSnapshot {
            tip: c.balls.x[0].as_vec3(),
            direction: c.axis.as_vec3(),
            beam_end: None,
            beam_reach: None,
            active: touching,
            instrument: 0,
            shape: Default::default(),
            jaw: 0.0,
            up: Vec3::ZERO,
        };
        events.extend(ev.into_iter().map(|kind| SimEvent { step, kind }));
    }

    pub fn snapshot(&mut self, step: u64) -> Snapshot {
        let time_s = self.time_s(step);
        Snapshot {
            step,
            time_s,
            models: [self.vessel_mesh(), self.catheter_mesh()]
                .into_iter()
                .chain(self.wire_mesh())
                .collect(),
            // The wire is drawn as a model: no instrument shaft for the left hand.
            tools: [ToolSnapshot::default(), self.tool],
            reactions: self.reactions(),
            target_found: true,
            emissions: Vec::new(),
            bleeding: Vec::new(),
            scope: None,
            picture: self.imaging.picture.clone(),
        }
    }

    /// The wall through its balls (translucent, as the paper draws it), without the
    /// triangles at punctured balls.
    fn vessel_mesh(&self) -> ModelSnapshot {
        let b = &self.scene.vessel().balls;
        let holes = &self.scene.holes();
        let tris: Vec<[u32; 3]> = self
            .triangles
            .iter()
            .copied()
            .filter(|t| t.iter().all(|&i| !holes[i as usize]))
            .collect();
        let mut normals = vec![DVec3::ZERO; b.len()];
        for t in &tris {
            let [p, q, r] = t.map(|i| b.x[i as usize]);
            let n = (q - p).cross(r - p);
            for &i in t {
                normals[i as usize] += n;
            }
        }
        ModelSnapshot {
            seared: Vec::new(),
            name: "vessel".to_string(),
            positions: b.x.iter().map(|x| x.as_vec3()).collect(),
            normals: normals
                .iter()
                .map(|n| n.normalize_or(DVec3::Z).as_vec3())
                .collect(),
            indices: tris.iter().flatten().copied().collect(),
            regions: vec![0; tris.len()],
            roles: vec![SurfaceRole::Membrane],
            cut_edge: vec![false; b.len()],
        }
    }

    /// The catheter as a tube through its balls (8 sides), closed at the tip.
    fn catheter_mesh(&self) -> ModelSnapshot {
        let c = &self.scene.catheter();
        let r = 0.5 * c.params.diameter_m;
        tube_mesh("catheter", &c.balls.x, Some(&c.up), r, 8, c.axis)
    }

    /// The guidewire as a thin tube (6 sides), when there is one.
    fn wire_mesh(&self) -> Option<ModelSnapshot> {
        let w = self.scene.guidewire()?;
        let r = 0.5 * w.params.diameter_m;
        Some(tube_mesh("guidewire", &w.balls.x, None, r, 6, w.axis))
    }

    /// Digest of the balls, the holes and the task's progress.
    pub fn state_hash(&self) -> u64 {
        let mut h = Fnv(self.scene.state_hash());
        h.write(self.metrics.steps_done.len() as u32);
        h.write(self.metrics.errors);
        let c = &self.metrics.fluoroscopy;
        h.write(c.pulses);
        h.write(c.contrast_runs);
        let dap = c.dap_gy_cm2.to_bits();
        h.write(dap as u32);
        h.write((dap >> 32) as u32);
        for angle in [c.lao_deg, c.cranial_deg] {
            let b = angle.to_bits();
            h.write(b as u32);
            h.write((b >> 32) as u32);
        }
        h.0
    }
}

/// A tip is in a wrong branch of `v` now (`astray`) after it was not (`was`): a
/// `wrong_branch` event naming the branch and the tool; returns the entries (0 or 1) and keeps the state.
fn entered(
    was: &mut bool,
    (astray, v): (Option<usize>, &Vessel),
    tool: &'static str,
    ev: &mut Vec<EventKind>,
) -> u32 {
    let new = astray.is_some() && !*was;
    *was = astray.is_some();
    if let (true, Some(branch)) = (new, astray) {
        let vessel = v.branches.get(branch).map_or("", |b| b.name.as_str());
        ev.push(EventKind::Procedure(ProcedureEvent::new(
            "wrong_branch",
            WrongBranch {
                branch: branch as u32,
                vessel: vessel.to_string(),
                tool,
            },
        )));
    }
    u32::from(new)
}

/// How far `p` is along vessel `k` of `v`, once it is [`IN_BRANCH_M`] into it and inside
/// the wall's central surface.
fn in_branch_at(v: &Vessel, k: usize, p: DVec3) -> Option<f64> {
    v.along_branch(k, p).filter(|&along| along > IN_BRANCH_M)
}

/// A tube of `radius` through the points `x` (`sides` sides), closed at the last point; each
/// ring's sides turn with `ups` when given (the catheter's frames), else from any direction
/// across the tube.
fn tube_mesh(
    name: &str,
    x: &[DVec3],
    ups: Option<&[DVec3]>,
    radius: f64,
    sides: usize,
    axis: DVec3,
) -> ModelSnapshot {
    let mut m = ModelSnapshot {
        name: name.to_string(),
        roles: vec![SurfaceRole::Duct],
        ..ModelSnapshot::default()
    };
    if x.len() < 2 {
        return m;
    }
    for i in 0..x.len() {
        let along = if i + 1 < x.len() {
            x[i + 1] - x[i]
        } else {
            x[i] - x[i - 1]
        }
        .normalize_or(axis);
        let up = ups
            .and_then(|u| u.get(i).copied())
            .unwrap_or_else(|| any_across(along));
        let side = up.cross(along).normalize_or(DVec3::Z);
        let up = along.cross(side);
        for k in 0..sides {
            let a = std::f64::consts::TAU * k as f64 / sides as f64;
            let n = side * a.cos() + up * a.sin();
            m.positions.push((x[i] + n * radius).as_vec3());
            m.normals.push(n.as_vec3());
        }
    }
    for i in 0..x.len() - 1 {
        for k in 0..sides {
            let (a, b) = ((i * sides + k) as u32, (i * sides + (k + 1) % sides) as u32);
            let (c2, d) = (a + sides as u32, b + sides as u32);
            m.indices.extend([a, b, c2, b, d, c2]);
            m.regions.extend([0, 0]);
        }
    }
    // The tip's cap.
    let last = x.len() - 1;
    let centre = m.positions.len() as u32;
    let tip_dir = (x[last] - x[last - 1]).normalize_or(axis);
    m.positions.push((x[last] + tip_dir * radius).as_vec3());
    m.normals.push(tip_dir.as_vec3());
    for k in 0..sides {
        let a = (last * sides + k) as u32;
        let b = (last * sides + (k + 1) % sides) as u32;
        m.indices.extend([a, b, centre]);
        m.regions.push(0);
    }
    m.cut_edge = vec![false; m.positions.len()];
    m
}

#[derive(Serialize)]
struct PunctureEvent {
    position: [f32; 3],
    force_n: f64,
    wall_ball: u32,
    tool: &'static str,
}

#[derive(Serialize)]
struct WrongBranch {
    branch: u32,
    vessel: String,
    tool: &'static str,
}

impl Catheterisation {
    /// The panel's live part: the handle's path, the force, the peak force, the wall
    /// contacts and the reach into the branch (nothing here is vulnerable to touch), then
    /// the interventional console's figures.
    pub(super) fn panel(&self, _near_m: f32) -> TaskStatus {
        let m = &self.metrics;
        TaskStatus {
            path_m: [0.0, m.handle_path_m as f32],
            figures: vec![
                (
                    "force".to_string(),
                    format!("{:.2} N", self.reaction().length()),
                ),
                ("peak force".to_string(), format!("{:.2} N", m.peak_force_n)),
                ("wall contacts".to_string(), m.wall_contacts.to_string()),
                (
                    "into the branch".to_string(),
                    format!("{:.0} mm", 1e3 * m.reach_m),
                ),
            ]
            .into_iter()
            .chain(m.guidewire.iter().flat_map(|w| {
                [
                    (
                        "wire force".to_string(),
                        format!("{:.3} N", self.wire_reaction.length()),
                    ),
                    (
                        "wire into the branch".to_string(),
                        format!("{:.0} mm", 1e3 * w.reach_m),
                    ),
                ]
            }))
            .chain(self.imaging.console.figures())
            .collect(),
            ..TaskStatus::default()
        }
    }

    /// Reaction force on each instrument (left, right) after the last step: the vessel's on
    /// the guidewire (zero without one) and on the catheter.
    pub fn reactions(&self) -> [Vec3; 2] {
        [self.wire_reaction.as_vec3(), self.reaction().as_vec3()]
    }

    /// The wall's force on the guidewire after the last step, N.
    pub fn wire_reaction(&self) -> DVec3 {
        self.wire_reaction
    }
}
